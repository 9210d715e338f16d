//! Scenes: glTF 2.0 loading, the generated paper scenes, and the environment light.
//!
//! A [`Scene`] is what the path tracer needs and nothing more (DESIGN.md §7): world-space
//! triangles with shading normals and texture coordinates, glTF metallic-roughness materials,
//! base-colour textures, cameras and the environment. Everything a file uses that raygun does
//! not model is listed by name in [`Scene::unsupported`] instead of being dropped silently.
//!
//! Frames and units follow glTF: right-handed, +Y up, metres.
//!
//! * [`load`]: `.gltf` / `.glb` files and in-memory GLB bytes → [`Scene`].
//! * [`environment`]: the `--env` argument (a constant colour, `.hdr` or `.exr`).
//! * [`generate`]: the deterministic paper scenes (Cornell box, procedural city) as GLB.

mod accessor;
pub mod environment;
pub mod generate;
pub mod load;

use glam::{Vec2, Vec3, Vec4};

pub use environment::EnvironmentError;
pub use load::{MAX_COORDINATE, SceneError};

/// One triangle in world space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Triangle {
    /// Vertex positions.
    pub p: [Vec3; 3],
    /// Shading normals (unit length; the geometric normal where the file has none).
    pub n: [Vec3; 3],
    /// Texture coordinates (TEXCOORD_0; zero where the file has none).
    pub uv: [Vec2; 3],
    /// Index into [`Scene::materials`].
    pub material: u32,
}

/// A glTF metallic-roughness material, reduced to what the integrator shades.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    pub name: String,
    /// Linear RGBA base colour factor (alpha is ignored by the integrator: opaque only).
    pub base_color: Vec4,
    /// Index into [`Scene::textures`] multiplying `base_color`, if any.
    pub base_color_texture: Option<u32>,
    pub metallic: f32,
    /// Perceptual roughness in [0, 1].
    pub roughness: f32,
    /// KHR_materials_specular's `specularFactor` (1 without the extension): scales the
    /// dielectric Fresnel reflectance; 0 makes a non-metal a pure Lambertian reflector.
    pub specular: f32,
    /// Emitted radiance (W·sr⁻¹·m⁻² in linear RGB): emissive factor × KHR_materials_emissive_strength.
    pub emission: Vec3,
    /// glTF's `doubleSided`: seen, lit and (for an emitter) emitting from both faces, the back
    /// shaded with the normal reversed. Single-sided (glTF's default) triangles do not exist from
    /// behind: rays pass through their back face, and an emitter's back neither emits nor is
    /// sampled.
    pub double_sided: bool,
}

impl Default for Material {
    /// glTF's default material: white, fully metallic, fully rough, not emissive.
    fn default() -> Self {
        Self {
            name: "default".into(),
            base_color: Vec4::ONE,
            base_color_texture: None,
            metallic: 1.0,
            roughness: 1.0,
            specular: 1.0,
            emission: Vec3::ZERO,
            double_sided: false,
        }
    }
}

/// A base-colour texture: 8-bit sRGB-encoded RGBA texels, row 0 at the top (v = 0), sampled
/// bilinearly with wrap-around (glTF's default sampler).
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    pub name: String,
    pub width: u32,
    pub height: u32,
    /// `width * height` texels, row-major.
    pub texels: Vec<[u8; 4]>,
}

/// A perspective pinhole camera.
#[derive(Clone, Debug, PartialEq)]
pub struct Camera {
    pub name: String,
    pub position: Vec3,
    /// Unit viewing direction (glTF: the node's −Z).
    pub forward: Vec3,
    /// Unit up vector, orthogonal to `forward` (glTF: the node's +Y).
    pub up: Vec3,
    /// Vertical field of view in radians.
    pub yfov: f32,
}

/// An equirectangular environment image in linear RGB.
///
/// Direction ↔ image: with +Y up, u = 0.5 + atan2(d.x, −d.z) / 2π and v = acos(d.y) / π,
/// pixel (u·width, v·height), row 0 at the top (the zenith).
#[derive(Clone, Debug, PartialEq)]
pub struct EnvironmentMap {
    pub name: String,
    pub width: u32,
    pub height: u32,
    /// `width * height` linear RGB texels, row-major.
    pub texels: Vec<Vec3>,
}

/// The light arriving from infinitely far away.
#[derive(Clone, Debug, PartialEq)]
pub enum Environment {
    /// The same radiance from every direction.
    Constant(Vec3),
    /// An equirectangular image.
    Map(EnvironmentMap),
}

impl Default for Environment {
    /// A white sky of radiance 1: the paper lit both scenes by the environment only.
    fn default() -> Self {
        Self::Constant(Vec3::ONE)
    }
}

/// Everything the renderer needs to draw one picture.
#[derive(Clone, Debug, Default)]
pub struct Scene {
    pub triangles: Vec<Triangle>,
    pub materials: Vec<Material>,
    pub textures: Vec<Texture>,
    pub cameras: Vec<Camera>,
    pub environment: Environment,
    /// Features the file uses that raygun does not model, by name, each once
    /// (e.g. "KHR_materials_transmission", "orthographic camera 'top'", "skin 'arm'").
    pub unsupported: Vec<String>,
    /// Problems with the file's data that the loader repaired, each once, e.g.
    /// "mesh 'Tower': dropped 3 zero-area triangles" or "image 'bricks': cannot decode (…);
    /// materials use their base colour factor".
    pub warnings: Vec<String>,
}

/// An axis-aligned box in world space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bounds {
    pub min: Vec3,
    pub max: Vec3,
}

impl Bounds {
    /// The box's extent along each axis.
    #[must_use]
    pub fn size(&self) -> Vec3 {
        self.max - self.min
    }

    #[must_use]
    pub fn center(&self) -> Vec3 {
        0.5 * (self.min + self.max)
    }
}

impl Scene {
    /// The world-space box around every triangle, `None` for a scene without triangles.
    #[must_use]
    pub fn bounds(&self) -> Option<Bounds> {
        let mut it = self.triangles.iter().flat_map(|t| t.p);
        let first = it.next()?;
        let (min, max) = it.fold((first, first), |(lo, hi), p| (lo.min(p), hi.max(p)));
        Some(Bounds { min, max })
    }

    /// How many triangles carry a material with non-zero emission (the scene's area lights).
    #[must_use]
    pub fn emissive_triangle_count(&self) -> usize {
        self.triangles
            .iter()
            .filter(|t| {
                self.materials
                    .get(t.material as usize)
                    .is_some_and(|m| m.emission.max_element() > 0.0)
            })
            .count()
    }

    /// The camera called `name`, if the scene has one.
    #[must_use]
    pub fn camera(&self, name: &str) -> Option<&Camera> {
        self.cameras.iter().find(|c| c.name == name)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri(p: [Vec3; 3], material: u32) -> Triangle {
        Triangle {
            p,
            n: [Vec3::Z; 3],
            uv: [Vec2::ZERO; 3],
            material,
        }
    }

    #[test]
    fn bounds_cover_every_vertex_and_empty_scenes_have_none() {
        assert_eq!(Scene::default().bounds(), None);
        let scene = Scene {
            triangles: vec![
                tri([Vec3::ZERO, Vec3::X, Vec3::Y], 0),
                tri(
                    [
                        Vec3::new(-2.0, 5.0, 1.0),
                        Vec3::X,
                        Vec3::new(0.0, 0.0, -3.0),
                    ],
                    0,
                ),
            ],
            ..Default::default()
        };
        let b = scene.bounds().unwrap();
        assert_eq!(b.min, Vec3::new(-2.0, 0.0, -3.0));
        assert_eq!(b.max, Vec3::new(1.0, 5.0, 1.0));
        assert_eq!(b.size(), Vec3::new(3.0, 5.0, 4.0));
        assert_eq!(b.center(), Vec3::new(-0.5, 2.5, -1.0));
    }

    #[test]
    fn emissive_triangles_are_those_with_any_positive_emission() {
        let lamp = Material {
            emission: Vec3::new(0.0, 0.0, 2.0),
            ..Default::default()
        };
        let t = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let scene = Scene {
            triangles: vec![tri(t, 0), tri(t, 1), tri(t, 1), tri(t, 0)],
            materials: vec![Material::default(), lamp],
            ..Default::default()
        };
        assert_eq!(scene.emissive_triangle_count(), 2);
    }
}
