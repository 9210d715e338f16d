//! The Cornell box (the paper's scene; geometry after the Cornell data, metres).

use glam::Vec3;
use gltf::json;

use super::glb::{Builder, Geometry};
use super::*;

/// The Cornell box's measured geometry (millimetres, the original data's frame: camera at
/// z = −800 looking along +z, so +x points to the viewer's left) from
/// <https://www.graphics.cornell.edu/online/box/data.html>: each entry is a quad.
const CORNELL_FLOOR: [[f32; 3]; 4] = [
    [552.8, 0.0, 0.0],
    [0.0, 0.0, 0.0],
    [0.0, 0.0, 559.2],
    [549.6, 0.0, 559.2],
];
const CORNELL_CEILING: [[f32; 3]; 4] = [
    [556.0, 548.8, 0.0],
    [556.0, 548.8, 559.2],
    [0.0, 548.8, 559.2],
    [0.0, 548.8, 0.0],
];
const CORNELL_BACK: [[f32; 3]; 4] = [
    [549.6, 0.0, 559.2],
    [0.0, 0.0, 559.2],
    [0.0, 548.8, 559.2],
    [556.0, 548.8, 559.2],
];
const CORNELL_GREEN: [[f32; 3]; 4] = [
    [0.0, 0.0, 559.2],
    [0.0, 0.0, 0.0],
    [0.0, 548.8, 0.0],
    [0.0, 548.8, 559.2],
];
const CORNELL_RED: [[f32; 3]; 4] = [
    [552.8, 0.0, 0.0],
    [549.6, 0.0, 559.2],
    [556.0, 548.8, 559.2],
    [556.0, 548.8, 0.0],
];
/// The light: the data's quad at y = 548.8, lowered 1 mm so it does not coincide with the
/// ceiling (coplanar surfaces would flicker between the two materials).
const CORNELL_LIGHT: [[f32; 3]; 4] = [
    [343.0, 547.8, 227.0],
    [343.0, 547.8, 332.0],
    [213.0, 547.8, 332.0],
    [213.0, 547.8, 227.0],
];
/// Top corners of the short (165 mm) and tall (330 mm) blocks, in order around the top face.
const CORNELL_SHORT: ([[f32; 2]; 4], f32) = (
    [[130.0, 65.0], [82.0, 225.0], [240.0, 272.0], [290.0, 114.0]],
    165.0,
);
const CORNELL_TALL: ([[f32; 2]; 4], f32) = (
    [
        [423.0, 247.0],
        [265.0, 296.0],
        [314.0, 456.0],
        [472.0, 406.0],
    ],
    330.0,
);

/// Linear reflectances and the light's radiance as in B. Bitterli's rendering resources
/// (the usual RGB fit to the measured Cornell spectra).
const CORNELL_WHITE: [f32; 3] = [0.725, 0.71, 0.68];
const CORNELL_RED_RGB: [f32; 3] = [0.63, 0.065, 0.05];
const CORNELL_GREEN_RGB: [f32; 3] = [0.14, 0.45, 0.091];
const CORNELL_LIGHT_RADIANCE: Vec3 = Vec3::new(17.0, 12.0, 4.0);
const CORNELL_LIGHT_ALBEDO: [f32; 3] = [0.78, 0.78, 0.78];

/// The original camera: (278, 273, −800) mm, 35 mm lens on a 25 mm film → yfov = 2·atan(12.5/35).
pub const CORNELL_CAMERA_POSITION: Vec3 = Vec3::new(0.0, 0.273, 0.8);

#[must_use]
pub fn cornell_camera_yfov() -> f32 {
    2.0 * (12.5f32 / 35.0).atan()
}

/// The Cornell box, front open (the paper's scene, lit by the environment alone), with the
/// ceiling light as an emissive quad when `light`.
///
/// The data stay in the original millimetres and frame; the root node's transform (scale
/// 0.001, 180° about +Y, x shifted by 0.278 m) takes them to glTF's metres with the opening at
/// z = 0 facing +Z, the room centred on x = 0, the floor at y = 0 and the back wall at
/// z = −0.5592. The camera "front" looks in through the opening along −Z.
pub fn cornell(light: bool) -> Result<Generated, GenerateError> {
    let mut b = Builder::new();
    let white = b.material("white", CORNELL_WHITE, None, None);
    let red = b.material("red", CORNELL_RED_RGB, None, None);
    let green = b.material("green", CORNELL_GREEN_RGB, None, None);
    let room_centre = Vec3::new(278.0, 274.4, 279.6);
    let wall = |q: [[f32; 3]; 4]| {
        let mut g = Geometry::default();
        let c = q.map(Vec3::from_array);
        // The measured walls are not exactly planar: two flat triangles, each facing the room.
        g.triangle([c[0], c[1], c[2]], room_centre - c[0]);
        g.triangle([c[0], c[2], c[3]], room_centre - c[0]);
        g
    };
    let block = |(top, height): ([[f32; 2]; 4], f32)| {
        let mut g = Geometry::default();
        let t = top.map(|[x, z]| Vec3::new(x, height, z));
        let centre = t.iter().sum::<Vec3>() / 4.0 - Vec3::new(0.0, height / 2.0, 0.0);
        g.triangle([t[0], t[1], t[2]], Vec3::Y);
        g.triangle([t[0], t[2], t[3]], Vec3::Y);
        for k in 0..4 {
            let (a, b) = (t[k], t[(k + 1) % 4]);
            let (a0, b0) = (a.with_y(0.0), b.with_y(0.0));
            let out = (a + b0) / 2.0 - centre;
            g.triangle([a0, b0, b], out);
            g.triangle([a0, b, a], out);
        }
        g
    };
    let mut meshes = vec![
        ("floor", vec![(wall(CORNELL_FLOOR), white)]),
        ("ceiling", vec![(wall(CORNELL_CEILING), white)]),
        ("back wall", vec![(wall(CORNELL_BACK), white)]),
        ("red wall", vec![(wall(CORNELL_RED), red)]),
        ("green wall", vec![(wall(CORNELL_GREEN), green)]),
        ("short block", vec![(block(CORNELL_SHORT), white)]),
        ("tall block", vec![(block(CORNELL_TALL), white)]),
    ];
    if light {
        let emitter = b.material(
            "light",
            CORNELL_LIGHT_ALBEDO,
            None,
            Some(CORNELL_LIGHT_RADIANCE),
        );
        let mut g = Geometry::default();
        let c = CORNELL_LIGHT.map(Vec3::from_array);
        g.triangle([c[0], c[1], c[2]], Vec3::NEG_Y);
        g.triangle([c[0], c[2], c[3]], Vec3::NEG_Y);
        meshes.push(("light", vec![(g, emitter)]));
    }
    let children: Vec<_> = meshes
        .into_iter()
        .map(|(name, parts)| {
            // The Cornell data are a plain triangle list: the non-indexed path of the loader.
            let mesh = b.mesh(name, parts, false);
            b.root.push(json::Node {
                mesh: Some(mesh),
                name: Some(name.into()),
                ..Default::default()
            })
        })
        .collect();
    let room = b.root.push(json::Node {
        name: Some("cornell box".into()),
        children: Some(children),
        scale: Some([0.001; 3]),
        rotation: Some(json::scene::UnitQuaternion([0.0, 1.0, 0.0, 0.0])),
        translation: Some([0.278, 0.0, 0.0]),
        ..Default::default()
    });
    let camera = b.camera(
        "front",
        CORNELL_CAMERA_POSITION,
        CORNELL_CAMERA_POSITION + Vec3::NEG_Z,
        cornell_camera_yfov(),
    );
    Ok(b.finish(vec![room, camera]))
}
