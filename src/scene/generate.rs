//! The paper's scenes (DESIGN.md §7, §9), generated deterministically and written as glTF 2.0
//! binary (GLB), so built-in scenes and files on disk go through the same loader.
//!
//! * [`cornell`]: the Cornell box with an open front (the paper lit it by the environment only),
//!   optionally with its ceiling light as an emissive quad.
//! * [`city`]: a seeded procedural city; [`CityParams::PAPER`] has about 350 000 triangles like
//!   the commercial model the paper used.
//!
//! The same inputs give the same bytes (no clocks, no hash-map order, a counter-based hash for
//! randomness); `tests/data/scenes/` holds goldens that a test compares byte for byte.

use std::borrow::Cow;

use glam::{Mat3, Quat, Vec2, Vec3};
use gltf::json;
use json::validation::{Checked::Valid, USize64};

use super::{Scene, SceneError};
use crate::random::{pcg4d, unit_f32};

/// Names `Scene::builtin` (and `--scene builtin:NAME`) accepts.
pub const BUILTINS: &[&str] = &["cornell", "cornell-light", "city", "city-small"];

/// A generated scene: GLB bytes and the number of triangles in them.
#[derive(Clone, Debug)]
pub struct Generated {
    pub glb: Vec<u8>,
    pub triangles: usize,
}

impl Scene {
    /// A generated scene by name (see [`BUILTINS`]), built in memory and loaded through the same
    /// GLB path as a file.
    pub fn builtin(name: &str) -> Result<Self, SceneError> {
        let generated = match name {
            "cornell" => cornell(false),
            "cornell-light" => cornell(true),
            "city" => city(CityParams::PAPER),
            "city-small" => city(CityParams::SMALL),
            _ => {
                return Err(SceneError::UnknownBuiltin {
                    name: name.into(),
                    known: BUILTINS.join(", "),
                });
            }
        }
        .map_err(|reason| SceneError::Generate {
            name: name.into(),
            reason,
        })?;
        Self::from_glb_bytes(&generated.glb, &format!("builtin:{name}"))
    }
}

// ---------------------------------------------------------------------------------------------
// Geometry and the GLB writer

/// Triangles with per-vertex normals and texture coordinates, indexed.
#[derive(Default)]
struct Geometry {
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    uvs: Vec<Vec2>,
    indices: Vec<u32>,
}

impl Geometry {
    fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// One flat triangle whose front (counter-clockwise) side faces `facing`.
    fn triangle(&mut self, p: [Vec3; 3], facing: Vec3) {
        let mut n = (p[1] - p[0]).cross(p[2] - p[0]).normalize();
        let order = if n.dot(facing) >= 0.0 {
            [0, 1, 2]
        } else {
            n = -n;
            [0, 2, 1]
        };
        let base = self.positions.len() as u32;
        for k in order {
            self.positions.push(p[k]);
            self.normals.push(n);
            self.uvs.push(Vec2::ZERO);
        }
        self.indices.extend([base, base + 1, base + 2]);
    }

    /// A planar quad with corners in order around its edge, front side facing `normal`.
    fn quad(&mut self, c: [Vec3; 4], uv: [Vec2; 4], normal: Vec3) {
        let base = self.positions.len() as u32;
        for k in 0..4 {
            self.positions.push(c[k]);
            self.normals.push(normal);
            self.uvs.push(uv[k]);
        }
        let winding = (c[1] - c[0]).cross(c[2] - c[0]);
        if winding.dot(normal) >= 0.0 {
            self.indices
                .extend([base, base + 1, base + 2, base, base + 2, base + 3]);
        } else {
            self.indices
                .extend([base, base + 2, base + 1, base, base + 3, base + 2]);
        }
    }

    /// The four sides of the axis-aligned box from `lo` to `hi` (tops are added separately,
    /// often to another material; bottoms are never seen). Texture coordinates are metres /
    /// `tile`, u along the wall and v down from the top.
    fn box_sides(&mut self, lo: Vec3, hi: Vec3, tile: Vec2) {
        let (y0, y1) = (lo.y, hi.y);
        let h = (y1 - y0) / tile.y;
        let mut side = |a: Vec2, b: Vec2, n: Vec3| {
            let w = a.distance(b) / tile.x;
            self.quad(
                [
                    Vec3::new(a.x, y0, a.y),
                    Vec3::new(b.x, y0, b.y),
                    Vec3::new(b.x, y1, b.y),
                    Vec3::new(a.x, y1, a.y),
                ],
                [
                    Vec2::new(0.0, h),
                    Vec2::new(w, h),
                    Vec2::new(w, 0.0),
                    Vec2::new(0.0, 0.0),
                ],
                n,
            );
        };
        let (x0, z0, x1, z1) = (lo.x, lo.z, hi.x, hi.z);
        side(Vec2::new(x0, z1), Vec2::new(x1, z1), Vec3::Z);
        side(Vec2::new(x1, z1), Vec2::new(x1, z0), Vec3::X);
        side(Vec2::new(x1, z0), Vec2::new(x0, z0), Vec3::NEG_Z);
        side(Vec2::new(x0, z0), Vec2::new(x0, z1), Vec3::NEG_X);
    }

    /// An upward-facing rectangle at height `y`, texture coordinates x, z / `tile`.
    fn horizontal_quad(&mut self, x0: f32, z0: f32, x1: f32, z1: f32, y: f32, tile: f32) {
        let c = [
            Vec3::new(x0, y, z1),
            Vec3::new(x1, y, z1),
            Vec3::new(x1, y, z0),
            Vec3::new(x0, y, z0),
        ];
        self.quad(c, c.map(|p| Vec2::new(p.x, p.z) / tile), Vec3::Y);
    }
}

/// Builds a glTF document and its binary chunk.
struct Builder {
    root: json::Root,
    bin: Vec<u8>,
    buffer: json::Index<json::Buffer>,
    triangles: usize,
}

impl Builder {
    fn new() -> Self {
        let mut root = json::Root::default();
        root.asset.generator = Some("raygun scene generator".into());
        let buffer = root.push(json::Buffer {
            byte_length: USize64(0),
            name: None,
            uri: None,
            extensions: None,
            extras: Default::default(),
        });
        Self {
            root,
            bin: Vec::new(),
            buffer,
            triangles: 0,
        }
    }

    /// Appends `bytes` to the binary chunk (4-byte aligned) as a buffer view.
    fn view(
        &mut self,
        bytes: &[u8],
        target: Option<json::buffer::Target>,
    ) -> json::Index<json::buffer::View> {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let offset = self.bin.len();
        self.bin.extend_from_slice(bytes);
        self.root.push(json::buffer::View {
            buffer: self.buffer,
            byte_length: USize64::from(bytes.len()),
            byte_offset: Some(USize64::from(offset)),
            byte_stride: None,
            name: None,
            target: target.map(Valid),
            extensions: None,
            extras: Default::default(),
        })
    }

    fn accessor(
        &mut self,
        bytes: &[u8],
        count: usize,
        ty: json::accessor::Type,
        component: json::accessor::ComponentType,
        target: json::buffer::Target,
        bounds: Option<(Vec3, Vec3)>,
    ) -> json::Index<json::Accessor> {
        let view = self.view(bytes, Some(target));
        self.root.push(json::Accessor {
            buffer_view: Some(view),
            byte_offset: None,
            count: USize64::from(count),
            component_type: Valid(json::accessor::GenericComponentType(component)),
            extensions: None,
            extras: Default::default(),
            type_: Valid(ty),
            min: bounds.map(|(lo, _)| json::Value::from(lo.to_array().to_vec())),
            max: bounds.map(|(_, hi)| json::Value::from(hi.to_array().to_vec())),
            name: None,
            normalized: false,
            sparse: None,
        })
    }

    /// A mesh with one primitive per (geometry, material) pair; empty geometries are skipped.
    /// `indexed: false` writes the vertices as a plain triangle list (no index accessor).
    fn mesh(
        &mut self,
        name: &str,
        parts: Vec<(Geometry, json::Index<json::Material>)>,
        indexed: bool,
    ) -> json::Index<json::Mesh> {
        use json::accessor::{ComponentType as C, Type as T};
        use json::buffer::Target::{ArrayBuffer, ElementArrayBuffer};
        let mut primitives = Vec::new();
        for (mut g, material) in parts {
            if g.indices.is_empty() {
                continue;
            }
            if !indexed {
                let flat = |v: &[Vec3], idx: &[u32]| idx.iter().map(|&i| v[i as usize]).collect();
                g.positions = flat(&g.positions, &g.indices);
                g.normals = flat(&g.normals, &g.indices);
                g.uvs = g.indices.iter().map(|&i| g.uvs[i as usize]).collect();
            }
            self.triangles += g.triangle_count();
            let n = g.positions.len();
            let lo = g.positions.iter().fold(Vec3::INFINITY, |a, &p| a.min(p));
            let hi = g
                .positions
                .iter()
                .fold(Vec3::NEG_INFINITY, |a, &p| a.max(p));
            let mut attributes = std::collections::BTreeMap::new();
            let pos = self.accessor(
                bytemuck::cast_slice(&g.positions),
                n,
                T::Vec3,
                C::F32,
                ArrayBuffer,
                Some((lo, hi)),
            );
            let nor = self.accessor(
                bytemuck::cast_slice(&g.normals),
                n,
                T::Vec3,
                C::F32,
                ArrayBuffer,
                None,
            );
            let uv = self.accessor(
                bytemuck::cast_slice(&g.uvs),
                n,
                T::Vec2,
                C::F32,
                ArrayBuffer,
                None,
            );
            attributes.insert(Valid(json::mesh::Semantic::Positions), pos);
            attributes.insert(Valid(json::mesh::Semantic::Normals), nor);
            attributes.insert(Valid(json::mesh::Semantic::TexCoords(0)), uv);
            let indices = indexed.then(|| {
                self.accessor(
                    bytemuck::cast_slice(&g.indices),
                    g.indices.len(),
                    T::Scalar,
                    C::U32,
                    ElementArrayBuffer,
                    None,
                )
            });
            primitives.push(json::mesh::Primitive {
                attributes,
                extensions: None,
                extras: Default::default(),
                indices,
                material: Some(material),
                mode: Valid(json::mesh::Mode::Triangles),
                targets: None,
            });
        }
        self.root.push(json::Mesh {
            extensions: None,
            extras: Default::default(),
            name: Some(name.into()),
            primitives,
            weights: None,
        })
    }

    /// A diffuse material (metallic 0, roughness 1), optionally textured and emissive
    /// (`emission` = radiance; stored as a [0, 1] factor × KHR_materials_emissive_strength).
    /// Double-sided, except an emitter: a lamp shines from its front only (glTF
    /// `doubleSided: false`, so its back neither emits nor is seen).
    #[allow(clippy::field_reassign_with_default)]
    fn material(
        &mut self,
        name: &str,
        base_color: [f32; 3],
        texture: Option<json::Index<json::Texture>>,
        emission: Option<Vec3>,
    ) -> json::Index<json::Material> {
        let mut m = json::Material {
            name: Some(name.into()),
            double_sided: emission.is_none(),
            ..Default::default()
        };
        m.pbr_metallic_roughness.base_color_factor =
            json::material::PbrBaseColorFactor([base_color[0], base_color[1], base_color[2], 1.0]);
        m.pbr_metallic_roughness.metallic_factor = json::material::StrengthFactor(0.0);
        m.pbr_metallic_roughness.roughness_factor = json::material::StrengthFactor(1.0);
        m.pbr_metallic_roughness.base_color_texture = texture.map(|index| json::texture::Info {
            index,
            tex_coord: 0,
            extensions: None,
            extras: Default::default(),
        });
        if let Some(e) = emission {
            let strength = e.max_element();
            m.emissive_factor = json::material::EmissiveFactor((e / strength).to_array());
            // Which other fields this struct has depends on gltf's feature flags, so it is
            // built from its default rather than as a literal (hence the allow on this fn).
            let mut ext = json::extensions::material::Material::default();
            ext.emissive_strength = Some(json::extensions::material::EmissiveStrength {
                emissive_strength: json::extensions::material::EmissiveStrengthFactor(strength),
            });
            m.extensions = Some(ext);
            let ext = "KHR_materials_emissive_strength".to_string();
            if !self.root.extensions_used.contains(&ext) {
                self.root.extensions_used.push(ext);
            }
        }
        self.root.push(m)
    }

    /// An RGBA8 texture stored as PNG in the binary chunk, sampled with glTF's default
    /// (repeat) wrapping.
    fn texture(&mut self, name: &str, image: &image::RgbaImage) -> json::Index<json::Texture> {
        use image::ImageEncoder;
        let mut png = Vec::new();
        image::codecs::png::PngEncoder::new(&mut png)
            .write_image(
                image.as_raw(),
                image.width(),
                image.height(),
                image::ExtendedColorType::Rgba8,
            )
            .expect("encoding a PNG into memory cannot fail");
        let view = self.view(&png, None);
        let source = self.root.push(json::Image {
            buffer_view: Some(view),
            mime_type: Some(json::image::MimeType("image/png".into())),
            name: Some(name.into()),
            uri: None,
            extensions: None,
            extras: Default::default(),
        });
        let sampler = self.root.push(json::texture::Sampler {
            mag_filter: Some(Valid(json::texture::MagFilter::Linear)),
            min_filter: Some(Valid(json::texture::MinFilter::Linear)),
            ..Default::default()
        });
        self.root.push(json::Texture {
            name: Some(name.into()),
            sampler: Some(sampler),
            source,
            extensions: None,
            extras: Default::default(),
        })
    }

    /// A node holding a perspective camera at `position` looking at `target` (+Y up).
    fn camera(
        &mut self,
        name: &str,
        position: Vec3,
        target: Vec3,
        yfov: f32,
    ) -> json::Index<json::Node> {
        let camera = self.root.push(json::Camera {
            name: Some(name.into()),
            orthographic: None,
            perspective: Some(json::camera::Perspective {
                aspect_ratio: None,
                yfov,
                zfar: None,
                znear: 0.01,
                extensions: None,
                extras: Default::default(),
            }),
            type_: Valid(json::camera::Type::Perspective),
            extensions: None,
            extras: Default::default(),
        });
        // glTF cameras look down their node's −Z with +Y up.
        let back = (position - target).normalize();
        let right = Vec3::Y.cross(back).normalize();
        let up = back.cross(right);
        let rotation = Quat::from_mat3(&Mat3::from_cols(right, up, back)).normalize();
        self.root.push(json::Node {
            camera: Some(camera),
            name: Some(name.into()),
            rotation: Some(json::scene::UnitQuaternion(rotation.to_array())),
            translation: Some(position.to_array()),
            ..Default::default()
        })
    }

    fn finish(mut self, nodes: Vec<json::Index<json::Node>>) -> Generated {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        self.root.buffers[self.buffer.value()].byte_length = USize64::from(self.bin.len());
        let scene = self.root.push(json::Scene {
            extensions: None,
            extras: Default::default(),
            name: None,
            nodes,
        });
        self.root.scene = Some(scene);
        let json = json::serialize::to_vec(&self.root).expect("a glTF document serializes");
        let glb = gltf::binary::Glb {
            header: gltf::binary::Header {
                magic: *b"glTF",
                version: 2,
                length: 0, // to_vec computes the real length
            },
            json: Cow::Owned(json),
            bin: Some(Cow::Owned(self.bin)),
        }
        .to_vec()
        .expect("writing GLB into memory cannot fail");
        Generated {
            glb,
            triangles: self.triangles,
        }
    }
}

// ---------------------------------------------------------------------------------------------
// The Cornell box

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
pub fn cornell(light: bool) -> Result<Generated, String> {
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

// ---------------------------------------------------------------------------------------------
// The procedural city

/// The city's size and seed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CityParams {
    /// Blocks along each side of the square city.
    pub blocks: u32,
    /// Different seeds give different cities of about the same size.
    pub seed: u32,
}

impl CityParams {
    /// 343 740 triangles, about the size of the paper's city model (DESIGN.md §7).
    pub const PAPER: Self = Self {
        blocks: 41,
        seed: 1,
    };
    /// About 3 900 triangles, for tests.
    pub const SMALL: Self = Self { blocks: 4, seed: 1 };
    /// The largest `blocks` accepted (≈ 2 million triangles).
    pub const MAX_BLOCKS: u32 = 100;
}

/// Street width (kerb to kerb) and block size, metres.
const STREET_M: f32 = 14.0;
const BLOCK_M: f32 = 64.0;
const SIDEWALK_M: f32 = 3.0;
const KERB_M: f32 = 0.15;
/// One facade texture tile: a window bay 4 m wide and one 3.5 m storey high.
const FACADE_TILE: Vec2 = Vec2::new(4.0, 3.5);
/// One asphalt texture tile, metres.
const ASPHALT_TILE: f32 = 6.0;

/// Uniform in [0, 1) from the seed and three counters (the shared counter-based hash).
fn rand(seed: u32, a: u32, b: u32, salt: u32) -> f32 {
    unit_f32(pcg4d([seed, a, b, salt])[0])
}

/// A procedural city: `blocks × blocks` blocks separated by streets, each block a raised
/// sidewalk with a grid of lots; each lot a building of one to three setback tiers (taller
/// towards the centre), with flat or hipped roofs and rooftop plant rooms. Materials: asphalt
/// (textured), sidewalk, roof, and four facades (one textured with windows). Cameras "street"
/// (eye height, looking down the central avenue) and "aerial".
pub fn city(params: CityParams) -> Result<Generated, String> {
    if params.blocks == 0 || params.blocks > CityParams::MAX_BLOCKS {
        return Err(format!(
            "--blocks must be in 1..={}, got {}",
            CityParams::MAX_BLOCKS,
            params.blocks
        ));
    }
    let seed = params.seed;
    let mut b = Builder::new();
    let asphalt_tex = b.texture("asphalt", &asphalt_texture(seed));
    let windows_tex = b.texture("windows", &windows_texture(seed));
    let asphalt = b.material("asphalt", [1.0, 1.0, 1.0], Some(asphalt_tex), None);
    let sidewalk = b.material("sidewalk", [0.55, 0.54, 0.52], None, None);
    let roof = b.material("roof", [0.28, 0.28, 0.30], None, None);
    let facades = [
        b.material("brick", [0.62, 0.36, 0.28], Some(windows_tex), None),
        b.material("concrete", [0.60, 0.58, 0.55], None, None),
        b.material("glass", [0.16, 0.21, 0.26], None, None),
        b.material("sandstone", [0.72, 0.62, 0.45], None, None),
    ];

    let n = params.blocks;
    let pitch = BLOCK_M + STREET_M;
    let extent = n as f32 * pitch;
    let half = extent / 2.0;
    let mut ground = Geometry::default();
    let mut walks = Geometry::default();
    let mut roofs = Geometry::default();
    let mut walls: Vec<Geometry> = facades.iter().map(|_| Geometry::default()).collect();

    // The ground: asphalt under the whole city and one street width around it.
    let g = half + STREET_M;
    ground.horizontal_quad(-g, -g, g, g, 0.0, ASPHALT_TILE);

    for bi in 0..n {
        for bj in 0..n {
            let block_id = bi * n + bj;
            let x0 = -half + bi as f32 * pitch + STREET_M / 2.0;
            let z0 = -half + bj as f32 * pitch + STREET_M / 2.0;
            let lo = Vec3::new(x0, 0.0, z0);
            walks.box_sides(
                lo,
                lo + Vec3::new(BLOCK_M, KERB_M, BLOCK_M),
                Vec2::splat(ASPHALT_TILE),
            );
            walks.horizontal_quad(x0, z0, x0 + BLOCK_M, z0 + BLOCK_M, KERB_M, ASPHALT_TILE);
            // Taller towards the centre: a Gaussian "downtown" on top of a low base.
            let centre = Vec2::new(x0 + BLOCK_M / 2.0, z0 + BLOCK_M / 2.0);
            let downtown = (-2.5 * (centre.length() / half.max(pitch)).powi(2)).exp();
            let lots_x = 2 + (rand(seed, block_id, 0, 1) * 3.0) as u32;
            let lots_z = 2 + (rand(seed, block_id, 0, 2) * 3.0) as u32;
            let inner = BLOCK_M - 2.0 * SIDEWALK_M;
            let (lot_w, lot_d) = (inner / lots_x as f32, inner / lots_z as f32);
            for lx in 0..lots_x {
                for lz in 0..lots_z {
                    let lot = lx * 8 + lz;
                    let r = |salt: u32| rand(seed, block_id, lot, salt);
                    let margin = 0.5 + 1.5 * r(3);
                    let lot_lo = Vec2::new(
                        x0 + SIDEWALK_M + lx as f32 * lot_w + margin,
                        z0 + SIDEWALK_M + lz as f32 * lot_d + margin,
                    );
                    let lot_hi = lot_lo + Vec2::new(lot_w, lot_d) - 2.0 * margin;
                    let height = 6.0 + r(4).powi(2) * (14.0 + 110.0 * downtown);
                    let facade = ((r(5) * facades.len() as f32) as usize).min(facades.len() - 1);
                    let tiers = if height > 30.0 {
                        1 + (r(6) * 3.0) as u32
                    } else {
                        1
                    };
                    building(
                        &mut walls[facade],
                        &mut roofs,
                        (lot_lo, lot_hi),
                        height,
                        tiers,
                        &r,
                    );
                }
            }
        }
    }

    let mut parts = vec![(ground, asphalt), (walks, sidewalk), (roofs, roof)];
    parts.extend(walls.into_iter().zip(facades));
    let mesh = b.mesh("city", parts, true);
    let city_node = b.root.push(json::Node {
        mesh: Some(mesh),
        name: Some("city".into()),
        ..Default::default()
    });
    // The street camera stands in the street nearest the centre, in its right-hand lane,
    // one block back from the middle, looking down the avenue and slightly up.
    let street_x = -half + (n / 2) as f32 * pitch + STREET_M * 0.25;
    let eye = Vec3::new(street_x, 1.7, (pitch * 1.5).min(half));
    let street = b.camera(
        "street",
        eye,
        eye + Vec3::new(0.0, 0.12, -1.0),
        50f32.to_radians(),
    );
    let aerial_pos = Vec3::new(0.75 * extent, 0.55 * extent, 0.75 * extent);
    let aerial = b.camera("aerial", aerial_pos, Vec3::ZERO, 40f32.to_radians());
    Ok(b.finish(vec![city_node, street, aerial]))
}

/// One building on the lot `(lo, hi)` (x, z): `tiers` stacked boxes, each inset from the one
/// below (setbacks), most with a cornice (a ledge 0.6 m tall, 0.4 m proud) at the top; the top
/// tier gets a hipped roof (low buildings, sometimes) or a flat roof with a plant room
/// (sometimes). Tier tops are roofs.
fn building(
    walls: &mut Geometry,
    roofs: &mut Geometry,
    (mut lo, mut hi): (Vec2, Vec2),
    height: f32,
    tiers: u32,
    r: &dyn Fn(u32) -> f32,
) {
    const CORNICE_HEIGHT: f32 = 0.6;
    const CORNICE_OUT: f32 = 0.4;
    let mut base = KERB_M;
    for tier in 0..tiers {
        let last = tier + 1 == tiers;
        let share = if last {
            1.0
        } else {
            0.45 + 0.25 * r(10 + tier)
        };
        let top = base + (height + KERB_M - base) * share;
        let size = hi - lo;
        let hipped = last && height < 16.0 && r(20) < 0.5;
        let cornice = !hipped && r(40 + tier) < 0.7;
        walls.box_sides(
            Vec3::new(lo.x, base, lo.y),
            Vec3::new(hi.x, top, hi.y),
            FACADE_TILE,
        );
        if cornice {
            // The ledge's top covers the tier's, so it is the roof.
            let (clo, chi) = (lo - CORNICE_OUT, hi + CORNICE_OUT);
            walls.box_sides(
                Vec3::new(clo.x, top - CORNICE_HEIGHT, clo.y),
                Vec3::new(chi.x, top, chi.y),
                FACADE_TILE,
            );
            roofs.horizontal_quad(clo.x, clo.y, chi.x, chi.y, top, FACADE_TILE.x);
        } else if !hipped {
            roofs.horizontal_quad(lo.x, lo.y, hi.x, hi.y, top, FACADE_TILE.x);
        }
        if hipped {
            let ridge = top + 0.35 * size.min_element();
            let c = [
                Vec3::new(lo.x, top, hi.y),
                Vec3::new(hi.x, top, hi.y),
                Vec3::new(hi.x, top, lo.y),
                Vec3::new(lo.x, top, lo.y),
            ];
            let apex = Vec3::new((lo.x + hi.x) / 2.0, ridge, (lo.y + hi.y) / 2.0);
            for k in 0..4 {
                let (a, b) = (c[k], c[(k + 1) % 4]);
                roofs.triangle([a, b, apex], (a + b) / 2.0 - apex.with_y(top));
            }
        } else if last && r(21) < 0.6 && size.min_element() > 8.0 {
            // A plant room: 15–30 % of the roof, 2–4 m tall, somewhere on it.
            let s = size * (0.15 + 0.15 * r(22));
            let at = lo + (size - s) * Vec2::new(r(23), r(24));
            let h = 2.0 + 2.0 * r(25);
            let (plo, phi) = (
                Vec3::new(at.x, top, at.y),
                Vec3::new(at.x + s.x, top + h, at.y + s.y),
            );
            roofs.box_sides(plo, phi, FACADE_TILE);
            roofs.horizontal_quad(plo.x, plo.z, phi.x, phi.z, phi.y, FACADE_TILE.x);
        }
        // The next tier sets back 8–20 % of this one's size on each side.
        let inset = size * (0.08 + 0.12 * r(30 + tier));
        lo += inset;
        hi -= inset;
        base = top;
    }
}

/// 64×64 asphalt: grey noise with sparse light specks.
fn asphalt_texture(seed: u32) -> image::RgbaImage {
    image::RgbaImage::from_fn(64, 64, |x, y| {
        let v = pcg4d([seed, x, y, 0xa5f]);
        let grey = 70.0 + 40.0 * unit_f32(v[0]) + if v[1].is_multiple_of(23) { 60.0 } else { 0.0 };
        let g = grey as u8;
        image::Rgba([g, g, (grey * 1.03).min(255.0) as u8, 255])
    })
}

/// 64×64 facade bay: a light wall with one dark window (frame, sill), a little noise.
fn windows_texture(seed: u32) -> image::RgbaImage {
    image::RgbaImage::from_fn(64, 64, |x, y| {
        let noise = unit_f32(pcg4d([seed, x, y, 0xb1d])[0]) * 16.0;
        let window = (14..50).contains(&x) && (12..44).contains(&y);
        let frame = (12..52).contains(&x) && (10..46).contains(&y) && !window;
        let sill = (10..54).contains(&x) && (46..49).contains(&y);
        let rgb = if window {
            let pane = if x == 32 { 90.0 } else { 38.0 };
            [
                pane + noise * 0.5,
                pane + 8.0 + noise * 0.5,
                pane + 18.0 + noise * 0.5,
            ]
        } else if frame || sill {
            [200.0, 200.0, 196.0]
        } else {
            [215.0 + noise, 210.0 + noise, 200.0 + noise]
        };
        image::Rgba([rgb[0] as u8, rgb[1] as u8, rgb[2] as u8, 255])
    })
}
