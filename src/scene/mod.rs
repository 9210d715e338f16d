//! Scenes: glTF 2.0 loading, the generated paper scenes, and the environment light.
//!
//! A [`Scene`] is what the path tracer needs and nothing more (DESIGN.md §7): world-space
//! triangles with shading normals and texture coordinates, glTF metallic-roughness materials,
//! textures, cameras, punctual lights and the environment. Everything a file uses that raygun
//! does not model is listed by name in [`Scene::unsupported`] instead of being dropped silently.
//!
//! "Model only what a scene needs": the core records ([`Triangle`], [`Material`], [`Camera`])
//! hold what every scene has; what only some files use lives in side tables that are empty
//! otherwise — [`Scene::vertex_extras`] (vertex colours, a second texture coordinate set,
//! tangents), [`Scene::material_ext`] (texture maps beyond base colour, alpha modes, glass,
//! clear coat, specular colour), [`Scene::lights`] and [`Scene::orthographic_cameras`] — and
//! the tracer reads them only where a per-scene or per-material flag says they are there.
//!
//! Frames and units follow glTF: right-handed, +Y up, metres.
//!
//! * [`load`]: `.gltf` / `.glb` files and in-memory GLB bytes → [`Scene`] (the scene walk;
//!   its buffers, images, textures and samplers come from `resources`).
//! * [`environment`]: the `--env` argument (a constant colour, `.hdr` or `.exr`).
//! * [`generate`]: the deterministic paper scenes (Cornell box, procedural city) as GLB.

mod accessor;
pub mod environment;
pub mod generate;
pub mod ktx2;
pub mod load;
mod report;
mod resources;

use glam::{Vec2, Vec3, Vec4};

pub use environment::EnvironmentError;
pub use load::{MAX_ABSORPTION, MAX_COORDINATE, MAX_SCENE_FILE_BYTES, SUPPORTED_EXTENSIONS};
pub use report::{GenerateError, SceneError, UriError};
pub use resources::UriAccess;

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

/// A texture: 8-bit RGBA texels, row 0 at the top (v = 0), and its glTF sampler.
#[derive(Clone, Debug, PartialEq)]
pub struct Texture {
    pub name: String,
    pub width: u32,
    pub height: u32,
    /// `width * height` texels, row-major.
    pub texels: Vec<[u8; 4]>,
    pub sampler: Sampler,
    /// Whether the RGB channels are sRGB-encoded colour (base colour, emissive) rather than
    /// linear data (metallic-roughness, normals). Alpha is always linear.
    pub srgb: bool,
}

/// A glTF sampler's wrap mode along one texture axis.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Wrap {
    #[default]
    Repeat,
    ClampToEdge,
    MirroredRepeat,
}

/// How a texture is read: wrap modes per axis and the magnification filter (raygun has no
/// mipmaps: a path tracer's per-pixel jitter already averages the texels a pixel covers, so
/// the minification filter is not needed).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Sampler {
    pub wrap_s: Wrap,
    pub wrap_t: Wrap,
    /// glTF magFilter NEAREST (else bilinear, glTF's default).
    pub nearest: bool,
}

/// KHR_texture_transform: `uv' = T(offset) · R(rotation) · S(scale) · uv`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UvTransform {
    pub offset: Vec2,
    /// Radians, counter-clockwise in UV space (clockwise in the image, whose v points down).
    pub rotation: f32,
    pub scale: Vec2,
}

impl Default for UvTransform {
    fn default() -> Self {
        Self {
            offset: Vec2::ZERO,
            rotation: 0.0,
            scale: Vec2::ONE,
        }
    }
}

impl UvTransform {
    /// The two rows of the 2 × 3 matrix: `u' = r0 · (u, v, 1)`, `v' = r1 · (u, v, 1)`.
    #[must_use]
    pub fn rows(&self) -> [Vec3; 2] {
        let (s, c) = self.rotation.sin_cos();
        [
            Vec3::new(c * self.scale.x, s * self.scale.y, self.offset.x),
            Vec3::new(-s * self.scale.x, c * self.scale.y, self.offset.y),
        ]
    }

    #[must_use]
    pub fn apply(&self, uv: Vec2) -> Vec2 {
        let [r0, r1] = self.rows();
        Vec2::new(r0.dot(uv.extend(1.0)), r1.dot(uv.extend(1.0)))
    }
}

/// Which texture coordinates a texture reads: the set (0 = TEXCOORD_0, 1 = TEXCOORD_1) and the
/// transform applied to them.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct UvMap {
    pub tex_coord: u32,
    pub transform: UvTransform,
}

/// A material's use of a texture.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TextureRef {
    /// Index into [`Scene::textures`].
    pub texture: u32,
    pub uv: UvMap,
}

/// glTF's alphaMode.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum AlphaMode {
    #[default]
    Opaque,
    /// There where alpha ≥ the cutoff, absent elsewhere (cut-out leaves, fences).
    Mask(f32),
    /// Partly there: rays pass with probability 1 − alpha (stochastic coverage, the expected
    /// value of glTF's "over" blending for a ray).
    Blend,
}

/// Material features beyond [`Material`]'s, for the materials that use any
/// ([`Scene::material_ext`]); the default is "none of them".
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MaterialExt {
    /// Texture coordinates of [`Material::base_color_texture`].
    pub base_color_uv: UvMap,
    /// glTF metallicRoughnessTexture: roughness × G, metallic × B (linear).
    pub metallic_roughness_texture: Option<TextureRef>,
    /// Tangent-space normal map (linear; needs [`VertexExtras::tangent`]).
    pub normal_texture: Option<TextureRef>,
    pub normal_scale: f32,
    /// Emission × this texture (sRGB).
    pub emissive_texture: Option<TextureRef>,
    pub alpha: AlphaMode,
    /// KHR_materials_transmission's factor: the share of the non-metallic, non-reflected light
    /// that passes through the surface (refracted by `ior`) instead of being diffused.
    pub transmission: f32,
    /// KHR_materials_ior (1.5 by default): the dielectric Fresnel reflectance at normal
    /// incidence is ((ior − 1)/(ior + 1))², 0.04 at 1.5.
    pub ior: f32,
    /// KHR_materials_specular's specularColorFactor (linear RGB).
    pub specular_color: Vec3,
    /// KHR_materials_clearcoat: the coat's strength and perceptual roughness.
    pub clearcoat: f32,
    pub clearcoat_roughness: f32,
    /// The extensions' textures, each multiplying its factor where the material has one
    /// (linear data unless said): transmissionTexture's R, specularTexture's A,
    /// specularColorTexture's RGB (sRGB), clearcoatTexture's R, clearcoatRoughnessTexture's G.
    pub transmission_texture: Option<TextureRef>,
    pub specular_texture: Option<TextureRef>,
    pub specular_color_texture: Option<TextureRef>,
    pub clearcoat_texture: Option<TextureRef>,
    pub clearcoat_roughness_texture: Option<TextureRef>,
    /// The coat's own tangent-space normal map (linear; needs [`VertexExtras::tangent`]) and
    /// its scale. Without it the coat takes the interpolated normal: the base's normal map
    /// does not bend the coat (KHR_materials_clearcoat).
    pub clearcoat_normal_texture: Option<TextureRef>,
    pub clearcoat_normal_scale: f32,
    /// KHR_materials_volume: the absorption coefficient σ of the medium inside the closed mesh
    /// this material bounds, per unit of scene length and RGB channel, −ln(attenuationColor) /
    /// attenuationDistance — light that crosses a length x of it keeps exp(−σx) (Beer–Lambert).
    /// Zero without the extension, for a thin-walled material (thicknessFactor 0) and for a
    /// clear medium.
    pub absorption: Vec3,
    /// KHR_materials_sheen (fabrics, velvet): the sheen's colour (linear; zero: no sheen) and
    /// perceptual roughness, beneath the clear coat and over the base.
    pub sheen_color: Vec3,
    pub sheen_roughness: f32,
    /// sheenColorTexture's RGB (sRGB) and sheenRoughnessTexture's A (linear), each multiplying
    /// its factor.
    pub sheen_color_texture: Option<TextureRef>,
    pub sheen_roughness_texture: Option<TextureRef>,
    /// KHR_materials_anisotropy (brushed metal): the strength (0: isotropic) and the rotation
    /// (radians, counter-clockwise from the tangent) of the direction along which the
    /// roughness grows to mix(α, 1, strength²); the texture's RG is a direction in the tangent
    /// frame (linear, [−1, 1]) rotated likewise, its B multiplies the strength. Needs
    /// [`VertexExtras::tangent`].
    pub anisotropy_strength: f32,
    pub anisotropy_rotation: f32,
    pub anisotropy_texture: Option<TextureRef>,
    /// KHR_materials_dispersion: 20 / the Abbe number V_d of the medium behind a transmitting
    /// surface (0: none; 1 is V_d = 20, the lowest of ordinary glass; diamond 0.36). Each
    /// channel refracts with its own index of refraction ([`crate::trace::shading::dispersed_ior`]).
    pub dispersion: f32,
    /// KHR_materials_diffuse_transmission (leaves, paper, lamp shades, curtains): the share of
    /// the diffuse (non-specular) light that passes through the surface to its other side,
    /// Lambertian, tinted by the colour (linear), instead of being reflected. Specular
    /// transmission ([`Self::transmission`]) takes precedence where both are given.
    pub diffuse_transmission: f32,
    pub diffuse_transmission_color: Vec3,
    /// diffuseTransmissionTexture's A (linear) and diffuseTransmissionColorTexture's RGB (sRGB),
    /// each multiplying its factor.
    pub diffuse_transmission_texture: Option<TextureRef>,
    pub diffuse_transmission_color_texture: Option<TextureRef>,
}

impl MaterialExt {
    /// The extensions' textures in the order of their slots in the packed material
    /// (`trace::pack`): transmission, specular, specular colour, clear coat, coat roughness,
    /// coat normal, sheen colour, sheen roughness, anisotropy, diffuse transmission, diffuse
    /// transmission colour.
    #[must_use]
    pub fn extension_textures(&self) -> [Option<TextureRef>; 11] {
        [
            self.transmission_texture,
            self.specular_texture,
            self.specular_color_texture,
            self.clearcoat_texture,
            self.clearcoat_roughness_texture,
            self.clearcoat_normal_texture,
            self.sheen_color_texture,
            self.sheen_roughness_texture,
            self.anisotropy_texture,
            self.diffuse_transmission_texture,
            self.diffuse_transmission_color_texture,
        ]
    }
}

impl Default for MaterialExt {
    fn default() -> Self {
        Self {
            base_color_uv: UvMap::default(),
            metallic_roughness_texture: None,
            normal_texture: None,
            normal_scale: 1.0,
            emissive_texture: None,
            alpha: AlphaMode::Opaque,
            transmission: 0.0,
            ior: 1.5,
            specular_color: Vec3::ONE,
            clearcoat: 0.0,
            clearcoat_roughness: 0.0,
            transmission_texture: None,
            specular_texture: None,
            specular_color_texture: None,
            clearcoat_texture: None,
            clearcoat_roughness_texture: None,
            clearcoat_normal_texture: None,
            clearcoat_normal_scale: 1.0,
            absorption: Vec3::ZERO,
            sheen_color: Vec3::ZERO,
            sheen_roughness: 0.0,
            sheen_color_texture: None,
            sheen_roughness_texture: None,
            anisotropy_strength: 0.0,
            anisotropy_rotation: 0.0,
            anisotropy_texture: None,
            dispersion: 0.0,
            diffuse_transmission: 0.0,
            diffuse_transmission_color: Vec3::ONE,
            diffuse_transmission_texture: None,
            diffuse_transmission_color_texture: None,
        }
    }
}

/// Per-vertex data beyond [`Triangle`]'s ([`Scene::vertex_extras`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct VertexExtras {
    /// COLOR_0 in linear RGBA (white where a primitive has none); multiplies the base colour.
    pub color: [Vec4; 3],
    /// TEXCOORD_1 (zero where a primitive has none).
    pub uv1: [Vec2; 3],
    /// Unit tangent (xyz) and bitangent sign (w) for normal maps: glTF's TANGENT, or derived
    /// from the normal map's texture coordinates; zero where the material has no normal map.
    pub tangent: [Vec4; 3],
}

impl Default for VertexExtras {
    fn default() -> Self {
        Self {
            color: [Vec4::ONE; 3],
            uv1: [Vec2::ZERO; 3],
            tangent: [Vec4::ZERO; 3],
        }
    }
}

/// KHR_lights_punctual: a light with no area (a delta light for next-event estimation).
#[derive(Clone, Debug, PartialEq)]
pub struct PunctualLight {
    pub name: String,
    pub kind: LightKind,
    /// World position (point and spot lights).
    pub position: Vec3,
    /// Unit direction the light points in (the node's −Z; spot and directional lights).
    pub direction: Vec3,
    /// Colour × intensity, linear: radiant intensity (W·sr⁻¹, glTF's candela) of point and spot
    /// lights, irradiance (W·m⁻², glTF's lux) of directional ones, in the units in which an
    /// emissive factor of 1 is a radiance of 1.
    pub intensity: Vec3,
}

/// The kind of a [`PunctualLight`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum LightKind {
    Point,
    /// Full intensity inside `inner` (radians from the axis), none outside `outer`, glTF's
    /// recommended smooth falloff between.
    Spot {
        inner: f32,
        outer: f32,
    },
    Directional,
}

/// An orthographic camera: parallel rays along `forward` from a `2·ymag`-high window (its
/// width follows the image's aspect ratio, as a perspective camera's does).
#[derive(Clone, Debug, PartialEq)]
pub struct OrthographicCamera {
    pub name: String,
    pub position: Vec3,
    pub forward: Vec3,
    pub up: Vec3,
    /// Half the window's height, metres (glTF ymag).
    pub ymag: f32,
}

/// A perspective pinhole camera (orthographic ones: [`OrthographicCamera`]).
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
    /// Things a file has that a path tracer does not need, each once (e.g. occlusion maps:
    /// the tracer computes occlusion).
    pub notes: Vec<String>,
    /// Per triangle (same order as `triangles`), for scenes that have any vertex colours,
    /// second texture coordinates or normal maps; empty otherwise. Triangles past its end
    /// have the defaults.
    pub vertex_extras: Vec<VertexExtras>,
    /// Per material (same order as `materials`), for scenes whose materials use any feature
    /// beyond [`Material`]; empty otherwise. Materials past its end have the defaults.
    pub material_ext: Vec<MaterialExt>,
    /// KHR_lights_punctual lights.
    pub lights: Vec<PunctualLight>,
    pub orthographic_cameras: Vec<OrthographicCamera>,
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

    /// How many triangles emit light (the scene's area lights): a non-zero emission whose
    /// emissive texture, if any, is not black under the triangle (checked at 16 points).
    #[must_use]
    pub fn emissive_triangle_count(&self) -> usize {
        (0..self.triangles.len())
            .filter(|&i| self.emission_scale(i) > 0.0)
            .count()
    }

    /// The extended features of material `i` (the defaults where it has none).
    #[must_use]
    pub fn material_ext(&self, i: u32) -> MaterialExt {
        self.material_ext
            .get(i as usize)
            .copied()
            .unwrap_or_default()
    }

    /// The extra vertex data of triangle `i` (the defaults where it has none).
    #[must_use]
    pub fn vertex_extras(&self, i: usize) -> VertexExtras {
        self.vertex_extras.get(i).copied().unwrap_or_default()
    }

    /// Triangle `i`'s texture coordinates in `uv` (its set and transform).
    #[must_use]
    pub fn triangle_uv(&self, i: usize, uv: &UvMap) -> [Vec2; 3] {
        let raw = if uv.tex_coord == 1 {
            self.vertex_extras(i).uv1
        } else {
            self.triangles[i].uv
        };
        raw.map(|t| uv.transform.apply(t))
    }

    /// The mean luminance of triangle `i`'s emissive texture over the triangle relative to
    /// white (1 without a texture, 0 for a non-emitter), from nearest-texel reads at 16
    /// stratified points: what next-event estimation weighs emitters by, and what
    /// [`Self::emissive_triangle_count`] counts.
    #[must_use]
    pub fn emission_scale(&self, i: usize) -> f32 {
        let t = &self.triangles[i];
        let Some(m) = self.materials.get(t.material as usize) else {
            return 0.0;
        };
        if m.emission.max_element() <= 0.0 {
            return 0.0;
        }
        let ext = self.material_ext(t.material);
        let Some(tex) = ext
            .emissive_texture
            .and_then(|r| Some((self.textures.get(r.texture as usize)?, r.uv)))
        else {
            return 1.0;
        };
        let (texture, uv_map) = tex;
        let uv = self.triangle_uv(i, &uv_map);
        let mut sum = 0.0;
        for k in 0..16 {
            let (mut a, mut b) = ((k % 4) as f32 * 0.25 + 0.125, (k / 4) as f32 * 0.25 + 0.125);
            if a + b > 1.0 {
                (a, b) = (1.0 - a, 1.0 - b);
            }
            let p = uv[0] * (1.0 - a - b) + uv[1] * a + uv[2] * b;
            sum += texture.nearest_luminance(p);
        }
        sum / 16.0
    }

    /// The camera called `name`, if the scene has one.
    #[must_use]
    pub fn camera(&self, name: &str) -> Option<&Camera> {
        self.cameras.iter().find(|c| c.name == name)
    }

    /// The orthographic camera called `name`, if the scene has one.
    #[must_use]
    pub fn orthographic_camera(&self, name: &str) -> Option<&OrthographicCamera> {
        self.orthographic_cameras.iter().find(|c| c.name == name)
    }
}

impl Texture {
    /// The luminance of the texel nearest to `uv` (linear, sRGB decoded where the texture is
    /// colour), with the sampler's wrap modes; for light-selection weights, not for shading.
    #[must_use]
    pub fn nearest_luminance(&self, uv: Vec2) -> f32 {
        let axis = |c: f32, n: u32, wrap: Wrap| -> usize {
            let n = n as i64;
            let i = if c.is_finite() {
                (c * n as f32).floor() as i64
            } else {
                0
            };
            (match wrap {
                Wrap::Repeat => i.rem_euclid(n),
                Wrap::ClampToEdge => i.clamp(0, n - 1),
                Wrap::MirroredRepeat => {
                    let k = i.rem_euclid(2 * n);
                    if k >= n { 2 * n - 1 - k } else { k }
                }
            }) as usize
        };
        let x = axis(uv.x, self.width, self.sampler.wrap_s);
        let y = axis(uv.y, self.height, self.sampler.wrap_t);
        let c = self.texels[y * self.width as usize + x];
        let ch = |v: u8| {
            let f = f32::from(v) / 255.0;
            if self.srgb { srgb_to_linear(f) } else { f }
        };
        0.2126 * ch(c[0]) + 0.7152 * ch(c[1]) + 0.0722 * ch(c[2])
    }
}

/// sRGB-encoded channel in [0, 1] to linear (IEC 61966-2-1), as colour textures are stored.
#[inline]
#[must_use]
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
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
