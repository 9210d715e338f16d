//! Geometry and the GLB writer the generated scenes share.

use std::borrow::Cow;

use glam::{Mat3, Quat, Vec2, Vec3};
use gltf::json;
use json::validation::{Checked::Valid, USize64};

use super::*;

/// Triangles with per-vertex normals and texture coordinates, indexed.
#[derive(Default)]
pub(super) struct Geometry {
    pub(super) positions: Vec<Vec3>,
    pub(super) normals: Vec<Vec3>,
    pub(super) uvs: Vec<Vec2>,
    pub(super) indices: Vec<u32>,
}

impl Geometry {
    pub(super) fn triangle_count(&self) -> usize {
        self.indices.len() / 3
    }

    /// One flat triangle whose front (counter-clockwise) side faces `facing`.
    pub(super) fn triangle(&mut self, p: [Vec3; 3], facing: Vec3) {
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
    pub(super) fn quad(&mut self, c: [Vec3; 4], uv: [Vec2; 4], normal: Vec3) {
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
    pub(super) fn box_sides(&mut self, lo: Vec3, hi: Vec3, tile: Vec2) {
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
    pub(super) fn horizontal_quad(
        &mut self,
        x0: f32,
        z0: f32,
        x1: f32,
        z1: f32,
        y: f32,
        tile: f32,
    ) {
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
pub(super) struct Builder {
    pub(super) root: json::Root,
    pub(super) bin: Vec<u8>,
    pub(super) buffer: json::Index<json::Buffer>,
    pub(super) triangles: usize,
}

impl Builder {
    pub(super) fn new() -> Self {
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
    pub(super) fn view(
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

    pub(super) fn accessor(
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
    pub(super) fn mesh(
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
    pub(super) fn material(
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
    pub(super) fn texture(
        &mut self,
        name: &str,
        image: &image::RgbaImage,
    ) -> json::Index<json::Texture> {
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
    pub(super) fn camera(
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

    pub(super) fn finish(mut self, nodes: Vec<json::Index<json::Node>>) -> Generated {
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
