//! Scenes built in code for the path-tracer tests (tests/render/trace.rs, tests/twins/trace.rs).

#![allow(dead_code)]

use glam::{Vec2, Vec3, Vec4};
use raygun::scene::{Camera, Environment, Material, Scene, Triangle};

/// A pure Lambertian reflector (KHR_materials_specular factor 0) of albedo `rho`.
pub fn lambert(rho: f32, emission: Vec3) -> Material {
    Material {
        name: "lambert".into(),
        base_color: Vec4::new(rho, rho, rho, 1.0),
        base_color_texture: None,
        metallic: 0.0,
        roughness: 1.0,
        specular: 0.0,
        emission,
        double_sided: true,
    }
}

pub fn flat(p: [Vec3; 3], material: u32) -> Triangle {
    let n = (p[1] - p[0]).cross(p[2] - p[0]).normalize();
    Triangle {
        p,
        n: [n; 3],
        uv: [Vec2::ZERO; 3],
        material,
    }
}

/// An icosahedron of circumradius `r` at `c` with outward faces: convex, so a ray leaving a
/// face never meets the object again.
pub fn icosahedron(c: Vec3, r: f32, material: u32) -> Vec<Triangle> {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let v: Vec<Vec3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| c + Vec3::new(x, y, z).normalize() * r)
    .collect();
    let f = [
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    f.iter()
        .map(|t| {
            let mut tri = flat([v[t[0]], v[t[1]], v[t[2]]], material);
            if tri.n[0].dot(v[t[0]] - c) < 0.0 {
                tri = flat([v[t[0]], v[t[2]], v[t[1]]], material);
            }
            tri
        })
        .collect()
}

/// The inside of a sphere: an icosahedron subdivided `levels` times, faces pointing inwards.
pub fn sphere_inside(c: Vec3, r: f32, levels: u32, material: u32) -> Vec<Triangle> {
    let mut faces: Vec<[Vec3; 3]> = icosahedron(Vec3::ZERO, 1.0, 0)
        .iter()
        .map(|t| t.p)
        .collect();
    for _ in 0..levels {
        faces = faces
            .iter()
            .flat_map(|&[a, b, d]| {
                let (ab, bd, da) = (
                    (a + b).normalize(),
                    (b + d).normalize(),
                    (d + a).normalize(),
                );
                [[a, ab, da], [ab, b, bd], [da, bd, d], [ab, bd, da]]
            })
            .collect();
    }
    faces
        .iter()
        .map(|f| flat([c + f[0] * r, c + f[2] * r, c + f[1] * r], material))
        .collect()
}

/// The inside of an axis-aligned box (faces pointing inwards).
pub fn box_inside(lo: Vec3, hi: Vec3, material: u32) -> Vec<Triangle> {
    let c =
        |x: usize, y: usize, z: usize| Vec3::new([lo.x, hi.x][x], [lo.y, hi.y][y], [lo.z, hi.z][z]);
    let quads = [
        [c(0, 0, 0), c(1, 0, 0), c(1, 1, 0), c(0, 1, 0)],
        [c(0, 0, 1), c(0, 1, 1), c(1, 1, 1), c(1, 0, 1)],
        [c(0, 0, 0), c(0, 1, 0), c(0, 1, 1), c(0, 0, 1)],
        [c(1, 0, 0), c(1, 0, 1), c(1, 1, 1), c(1, 1, 0)],
        [c(0, 0, 0), c(0, 0, 1), c(1, 0, 1), c(1, 0, 0)],
        [c(0, 1, 0), c(1, 1, 0), c(1, 1, 1), c(0, 1, 1)],
    ];
    let centre = (lo + hi) * 0.5;
    quads
        .iter()
        .flat_map(|q| {
            let mut a = flat([q[0], q[1], q[2]], material);
            let mut b = flat([q[0], q[2], q[3]], material);
            if a.n[0].dot(centre - q[0]) < 0.0 {
                a = flat([q[0], q[2], q[1]], material);
                b = flat([q[0], q[3], q[2]], material);
            }
            [a, b]
        })
        .collect()
}

pub fn camera(position: Vec3, target: Vec3, yfov_deg: f32) -> Camera {
    Camera {
        name: "test".into(),
        position,
        forward: (target - position).normalize(),
        up: Vec3::Y,
        yfov: yfov_deg.to_radians(),
    }
}

pub fn material(name: &str, rgb: Vec3, metallic: f32, roughness: f32, emission: Vec3) -> Material {
    Material {
        name: name.into(),
        base_color: rgb.extend(1.0),
        base_color_texture: None,
        metallic,
        roughness,
        specular: 1.0,
        emission,
        double_sided: true,
    }
}

/// A Cornell-like room built here (open front, a ceiling light, an environment, a diffuse
/// block and a glossy metal icosahedron) so the twin test covers both BSDF lobes, both light
/// kinds and MIS.
pub fn twin_scene() -> Scene {
    let mut tris = Vec::new();
    // Room interior without its front (+Z) face: five walls, 10 triangles.
    let room = box_inside(Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 2.0, 1.0), 0);
    for (k, t) in room.into_iter().enumerate() {
        let face = k / 2;
        if face == 1 {
            continue; // the open front
        }
        let m = match face {
            2 => 1, // left, red
            3 => 2, // right, green
            _ => 0,
        };
        tris.push(Triangle { material: m, ..t });
    }
    // Ceiling light, facing down.
    let (a, b, c, d) = (
        Vec3::new(-0.3, 1.99, -0.3),
        Vec3::new(0.3, 1.99, -0.3),
        Vec3::new(0.3, 1.99, 0.3),
        Vec3::new(-0.3, 1.99, 0.3),
    );
    tris.push(flat([a, b, c], 3));
    tris.push(flat([a, c, d], 3));
    // A diffuse block (its outside) and a metal icosahedron.
    for t in box_inside(Vec3::new(-0.7, 0.0, -0.6), Vec3::new(-0.1, 1.2, 0.0), 0) {
        tris.push(flat([t.p[0], t.p[2], t.p[1]], 0));
    }
    tris.extend(icosahedron(Vec3::new(0.45, 0.4, 0.2), 0.4, 4));
    Scene {
        triangles: tris,
        materials: vec![
            material("white", Vec3::splat(0.73), 0.0, 1.0, Vec3::ZERO),
            material("red", Vec3::new(0.65, 0.05, 0.05), 0.0, 1.0, Vec3::ZERO),
            material("green", Vec3::new(0.12, 0.45, 0.15), 0.0, 1.0, Vec3::ZERO),
            // One-sided, as a ceiling lamp is: the twins must agree on that path too.
            Material {
                double_sided: false,
                ..material(
                    "light",
                    Vec3::splat(0.78),
                    0.0,
                    1.0,
                    Vec3::new(17.0, 12.0, 4.0),
                )
            },
            material("gold", Vec3::new(1.0, 0.77, 0.34), 1.0, 0.3, Vec3::ZERO),
        ],
        cameras: vec![camera(
            Vec3::new(0.0, 1.0, 3.4),
            Vec3::new(0.0, 1.0, 0.0),
            40.0,
        )],
        environment: Environment::Constant(Vec3::splat(0.5)),
        ..Default::default()
    }
}
