//! The scene packed into flat arrays: exactly what the GPU kernel binds, and what the CPU twin
//! reads, so both integrate the same data.
//!
//! | array | per | layout |
//! |---|---|---|
//! | `nodes` | BVH node | obvhs `CwBvhNode` (80 bytes; see [`super::bvh`]) |
//! | `prims` | BVH primitive | 3 × vec4: `[v0, bits(triangle)]`, `[e1, light density]`, `[e2, flags]` (flags: [`PRIM_CULL`] single-sided and opaque, [`PRIM_ALPHA`] alpha-tested; as a float) |
//! | `shade` | triangle | 4 × vec4: `[n0, uv0.x]`, `[n1, uv0.y]`, `[n2, uv1.x]`, `[uv1.y, uv2, bits(material)]` |
//! | `shade` from `extras_offset` | triangle, only with [`FEAT_EXTRAS`] | 8 × vec4: `[colour0 rgba]`, `[colour1]`, `[colour2]`, `[uv1₀, uv1₁]`, `[uv1₂, 0, 0]`, `[tangent0 xyz, sign]`, `[tangent1]`, `[tangent2]` (the TEXCOORD_1 set, tangents for normal maps) |
//! | `materials` | material | [`MATERIAL_STRIDE`] × vec4: `[base colour rgba]`, `[emission, flags]`, `[metallic, α, specular, alpha cutoff]`, `[specular colour, transmission]`, `[ior, clearcoat, clearcoat α, normal scale]`, then fifteen texture slots (base colour, metallic-roughness, normal, emissive, then the extensions': transmission, specular, specular colour, clear coat, coat roughness, coat normal, sheen colour, sheen roughness, anisotropy, diffuse transmission, diffuse transmission colour) of 2 × vec4 `[uv row 0, bits(texture or !0)]`, `[uv row 1, bits(texCoord set)]`, then `[coat normal scale, absorption σ rgb]`, `[sheen colour, sheen roughness]`, `[anisotropy strength, cos rotation, sin rotation, dispersion]`, `[diffuse transmission colour, diffuse transmission]`; after the last material, where one has a sheen, the sheen's albedo table ([`SHEEN_TABLE_ROWS`] vec4s of [`SHEEN_ALBEDO`]) |
//! | `texels` | texture | header `[offset, width, height, sampler]` per texture (sampler: wrap S in bits 0–1, wrap T in 2–3 — 0 repeat, 1 clamp, 2 mirror — bit 4 nearest, bit 5 sRGB), then RGBA8 words |
//! | `lights` | emissive triangle | 3 × vec4: `[v0, bits(triangle)]`, `[e1, 1 if double-sided]`, `[e2, 0]` |
//! | `lights` from `3 × light_count` | punctual light | 3 × vec4: `[position, or the unit direction towards a directional light, kind (0 point, 1 spot, 2 directional)]`, `[intensity rgb, cos outer cone]`, `[unit spot axis, cos inner cone]` |
//! | `dist` | — | light CDF (L + 1), environment row CDF (H + 1), per-row column CDFs (H × (W + 1)) |
//! | `env` | environment texel | `[rgb, pdf over the unit square]` |
//!
//! Material flags (`materials[34m + 1].w`, a small float): [`MAT_DOUBLE_SIDED`], one bit per
//! core texture slot in use ([`MAT_BASE_TEX`] …), [`MAT_MASK`] / [`MAT_BLEND`] for the alpha
//! mode, [`MAT_EXT_BSDF`] when the material needs the glass / clear-coat / specular-colour
//! terms, [`MAT_EXT_TEX`] when one of the extensions' slots holds a texture (each slot's
//! texture word then says which) and [`MAT_VOLUME`] when the medium it bounds absorbs. The tracer reads a slot, the extras or the extended BSDF only where its flag is set,
//! so a scene without them pays two bit tests per hit ("model only what a scene needs").
//!
//! Empty arrays get one zeroed element: a GPU binding cannot be empty.

use glam::{Vec3, Vec4};

use super::accum::luminance;
use super::bvh::{PRIM_ALPHA, PRIM_CULL, SceneBvh};
use super::shading::{SHEEN_ALBEDO, SHEEN_COLUMNS, SHEEN_ROWS};
use crate::scene::{AlphaMode, Environment, LightKind, Scene, TextureRef, Wrap};

/// GGX α never goes below this: a perfect mirror has a Dirac BSDF that MIS cannot weigh.
pub const MIN_ALPHA: f32 = 1e-3;
/// `texture` word of a material without a texture.
pub const NO_TEXTURE: u32 = u32::MAX;
/// vec4s per material (`MATERIAL_STRIDE` in path.wgsl).
pub const MATERIAL_STRIDE: usize = 39;
/// The material's vec4 after its texture slots: `[coat normal scale, absorption σ rgb]`
/// (`MATERIAL_COAT_ROW` in path.wgsl).
pub const MATERIAL_COAT_ROW: usize = 35;
/// `[sheen colour, sheen roughness]` (`MATERIAL_SHEEN_ROW` in path.wgsl).
pub const MATERIAL_SHEEN_ROW: usize = 36;
/// `[anisotropy strength, cos rotation, sin rotation, dispersion]` (`MATERIAL_ANISO_ROW` in
/// path.wgsl).
pub const MATERIAL_ANISO_ROW: usize = 37;
/// The material's last vec4: `[diffuse transmission colour, diffuse transmission]`
/// (`MATERIAL_DIFFUSE_ROW` in path.wgsl).
pub const MATERIAL_DIFFUSE_ROW: usize = 38;
/// vec4s of the sheen's albedo table after the materials (`SHEEN_TABLE_ROWS` in path.wgsl).
pub const SHEEN_TABLE_ROWS: usize = SHEEN_COLUMNS * SHEEN_ROWS / 4;
/// vec4s of vertex extras per triangle.
pub const EXTRAS_STRIDE: usize = 8;

/// Material flags (see the module doc).
pub const MAT_DOUBLE_SIDED: u32 = 1;
pub const MAT_BASE_TEX: u32 = 2;
pub const MAT_MR_TEX: u32 = 4;
pub const MAT_NORMAL_TEX: u32 = 8;
pub const MAT_EMISSIVE_TEX: u32 = 16;
pub const MAT_MASK: u32 = 32;
pub const MAT_BLEND: u32 = 64;
pub const MAT_EXT_BSDF: u32 = 128;
pub const MAT_EXT_TEX: u32 = 256;
/// KHR_materials_volume: a ray that meets this material from behind has crossed its medium and
/// loses exp(−σt) of its throughput ([`crate::scene::MaterialExt::absorption`]).
pub const MAT_VOLUME: u32 = 512;
/// KHR_materials_dispersion: a path that meets this material follows one colour channel from
/// here on, refracted by that channel's index ([`crate::trace::shading::pick_channel`]).
pub const MAT_DISPERSION: u32 = 1024;

/// Scene features (the `features` parameter): vertex extras are packed; some primitive is
/// alpha-tested (rays then carry a seed for stochastic coverage).
pub const FEAT_EXTRAS: u32 = 1;
pub const FEAT_ALPHA: u32 = 2;

/// Punctual light kinds in `lights`.
pub const LIGHT_POINT: u32 = 0;
pub const LIGHT_SPOT: u32 = 1;
pub const LIGHT_DIRECTIONAL: u32 = 2;

/// Everything the integrator reads, in the GPU's layout.
#[derive(Clone, Debug)]
pub struct PackedScene {
    pub bvh: SceneBvh,
    pub shade: Vec<[f32; 4]>,
    pub materials: Vec<[f32; 4]>,
    pub texels: Vec<u32>,
    pub lights: Vec<[f32; 4]>,
    pub dist: Vec<f32>,
    pub env: Vec<[f32; 4]>,
    pub light_count: u32,
    /// Environment image size; (0, 0) for a constant environment.
    pub env_size: [u32; 2],
    pub env_constant: Vec3,
    /// Offsets of the environment's row CDF and column CDFs in `dist`.
    pub env_marginal: u32,
    pub env_conditional: u32,
    /// Probability that next-event estimation samples the environment rather than an emitter.
    pub env_select: f32,
    /// Probability that it samples a punctual light (each of `punctual_count` equally likely).
    pub punct_select: f32,
    pub punctual_count: u32,
    /// [`FEAT_EXTRAS`] | [`FEAT_ALPHA`].
    pub features: u32,
    /// Where the vertex extras start in `shade` (vec4 index; with [`FEAT_EXTRAS`]).
    pub extras_offset: u32,
    pub triangle_count: usize,
    /// Nothing beyond the core glTF material: no alpha tests, vertex extras, punctual lights,
    /// normal or metallic-roughness maps, extension BSDFs or absorbing media, so the CPU twin
    /// traces with its plain instantiation, from which those branches are compiled out
    /// (DESIGN.md §7: model only what a scene needs).
    pub plain: bool,
}

/// A texture slot's two vec4s (see the module doc).
fn slot(v: &mut Vec<[f32; 4]>, r: Option<TextureRef>) {
    let (rows, tex, set) = match r {
        Some(r) => (r.uv.transform.rows(), r.texture, r.uv.tex_coord),
        None => (
            [Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0)],
            NO_TEXTURE,
            0,
        ),
    };
    v.push([rows[0].x, rows[0].y, rows[0].z, f32::from_bits(tex)]);
    v.push([rows[1].x, rows[1].y, rows[1].z, f32::from_bits(set)]);
}

/// A texture's sampler word (see the module doc).
fn sampler_word(t: &crate::scene::Texture) -> u32 {
    let wrap = |w: Wrap| match w {
        Wrap::Repeat => 0,
        Wrap::ClampToEdge => 1,
        Wrap::MirroredRepeat => 2,
    };
    wrap(t.sampler.wrap_s)
        | (wrap(t.sampler.wrap_t) << 2)
        | (u32::from(t.sampler.nearest) << 4)
        | (u32::from(t.srgb) << 5)
}

fn push3(v: &mut Vec<[f32; 4]>, a: Vec3, aw: f32, b: Vec3, bw: f32, c: Vec3, cw: f32) {
    v.push([a.x, a.y, a.z, aw]);
    v.push([b.x, b.y, b.z, bw]);
    v.push([c.x, c.y, c.z, cw]);
}

/// A CDF over `weights`: `weights.len() + 1` entries from 0 to 1 and the total (0 when all
/// weights are 0, in which case the CDF is uniform).
fn cdf(weights: &[f64]) -> (Vec<f32>, f64) {
    let total: f64 = weights.iter().sum();
    let mut out = Vec::with_capacity(weights.len() + 1);
    out.push(0.0);
    let mut acc = 0.0;
    let n = weights.len() as f64;
    for (i, w) in weights.iter().enumerate() {
        acc += w;
        out.push(if total > 0.0 {
            (acc / total) as f32
        } else {
            ((i + 1) as f64 / n) as f32
        });
    }
    if let Some(last) = out.last_mut() {
        *last = 1.0;
    }
    (out, total)
}

impl PackedScene {
    /// Packs `scene` and builds its BVH.
    #[must_use]
    pub fn new(scene: &Scene) -> Self {
        let tris = &scene.triangles;
        let (light_tris, light_cdf, light_density, mut lights) = emitters(scene);
        let positions: Vec<[Vec3; 3]> = tris.iter().map(|t| t.p).collect();
        let mut features = 0;
        let flags = primitive_flags(scene, &mut features);
        let bvh = SceneBvh::build_flagged(&positions, &light_density, &flags);
        let (shade, extras_offset) = shade_rows(scene, &mut features);
        let materials = material_rows(scene);
        let texels = texel_words(scene);

        let mut dist = light_cdf;
        let env_marginal = dist.len() as u32;
        let (env, env_size, env_constant, env_power) = environment(scene, &mut dist);
        let env_conditional = env_marginal + env_size[1] + 1;
        // Next-event estimation picks the environment, a punctual light or an emissive
        // triangle, each kind the scene has equally likely.
        let kinds = [
            env_power > 0.0,
            !scene.lights.is_empty(),
            !light_tris.is_empty(),
        ];
        let share = 1.0 / kinds.iter().filter(|&&k| k).count().max(1) as f32;
        let env_select = if kinds[0] { share } else { 0.0 };
        let punct_select = if kinds[1] { share } else { 0.0 };
        let light_count = light_tris.len() as u32;
        push_punctual(scene, &mut lights);

        let mut packed = Self {
            bvh,
            shade,
            materials,
            texels,
            lights,
            dist,
            env,
            light_count,
            env_size,
            env_constant,
            env_marginal,
            env_conditional,
            env_select,
            punct_select,
            punctual_count: scene.lights.len() as u32,
            features,
            extras_offset,
            triangle_count: tris.len(),
            plain: false,
        };
        packed.plain = packed.needs_only_the_core();
        // The sheen's albedo table, for the GPU (the CPU twin reads `SHEEN_ALBEDO` itself).
        if scene
            .material_ext
            .iter()
            .any(|e| e.sheen_color != Vec3::ZERO)
        {
            let table = SHEEN_ALBEDO.chunks_exact(4);
            packed
                .materials
                .extend(table.map(|e| [e[0], e[1], e[2], e[3]]));
        }
        packed.pad_empty();
        packed
    }

    /// Whether [`Self::plain`] holds: see there.
    fn needs_only_the_core(&self) -> bool {
        const FULL_ONLY: u32 = MAT_MR_TEX
            | MAT_NORMAL_TEX
            | MAT_MASK
            | MAT_BLEND
            | MAT_EXT_BSDF
            | MAT_VOLUME
            | MAT_DISPERSION;
        self.features == 0
            && self.punctual_count == 0
            && self
                .materials
                .chunks(MATERIAL_STRIDE)
                .all(|m| m[1][3] as u32 & FULL_ONLY == 0)
    }

    fn pad_empty(&mut self) {
        for v in [
            &mut self.shade,
            &mut self.materials,
            &mut self.lights,
            &mut self.env,
            &mut self.bvh.prims,
        ] {
            if v.is_empty() {
                v.push([0.0; 4]);
            }
        }
        if self.texels.is_empty() {
            self.texels.push(0);
        }
        if self.dist.is_empty() {
            self.dist.push(0.0);
        }
    }
}

/// The emissive triangles next-event estimation samples, in proportion to their power: their
/// indices, the CDF over them, each triangle's sampling density per unit area (0 for the
/// others) and their rows of `lights`.
fn emitters(scene: &Scene) -> (Vec<usize>, Vec<f32>, Vec<f32>, Vec<[f32; 4]>) {
    let tris = &scene.triangles;
    // Emitters: next-event estimation picks one in proportion to its power (area × luminance
    // × the faces it emits from).
    let mut light_tris = Vec::new();
    let mut light_weights = Vec::new();
    for (i, t) in tris.iter().enumerate() {
        let m = &scene.materials[t.material as usize];
        let area = 0.5 * (t.p[1] - t.p[0]).cross(t.p[2] - t.p[0]).length();
        let sides = if m.double_sided { 2.0 } else { 1.0 };
        // An emissive texture scales the power by its mean over the triangle (black parts
        // of a texture are no lamps: a triangle that is black all over is not sampled).
        let power = f64::from(area)
            * f64::from(luminance(m.emission))
            * f64::from(scene.emission_scale(i))
            * sides;
        if power > 0.0 && area > 0.0 {
            light_tris.push(i);
            light_weights.push(power);
        }
    }
    let (light_cdf, _) = cdf(&light_weights);
    let mut light_density = vec![0f32; tris.len()];
    let mut lights = Vec::new();
    for (k, &i) in light_tris.iter().enumerate() {
        let t = &tris[i];
        let area = 0.5 * (t.p[1] - t.p[0]).cross(t.p[2] - t.p[0]).length();
        light_density[i] = (light_cdf[k + 1] - light_cdf[k]) / area;
        let double_sided = scene.materials[t.material as usize].double_sided;
        push3(
            &mut lights,
            t.p[0],
            f32::from_bits(i as u32),
            t.p[1] - t.p[0],
            if double_sided { 1.0 } else { 0.0 },
            t.p[2] - t.p[0],
            0.0,
        );
    }
    (light_tris, light_cdf, light_density, lights)
}

/// Each triangle's primitive flags ([`PRIM_CULL`], [`PRIM_ALPHA`]); sets [`FEAT_ALPHA`] in
/// `features` where a triangle is alpha-tested.
fn primitive_flags(scene: &Scene, features: &mut u32) -> Vec<u32> {
    let tris = &scene.triangles;
    tris.iter()
        .map(|t| {
            let m = &scene.materials[t.material as usize];
            let ext = scene.material_ext(t.material);
            let mut f = 0;
            // A transmitting surface bounds a volume: a ray inside must be able to leave,
            // so glass is never culled (nor, as KHR_materials_volume says, a medium's
            // boundary).
            if !m.double_sided && ext.transmission == 0.0 && ext.absorption == Vec3::ZERO {
                f |= PRIM_CULL;
            }
            if ext.alpha != AlphaMode::Opaque {
                f |= PRIM_ALPHA;
                *features |= FEAT_ALPHA;
            }
            f
        })
        .collect()
}

/// The shading rows: four per triangle (normals, UVs, material), then the vertex extras
/// where the scene has any (setting [`FEAT_EXTRAS`] in `features`), and where they start.
fn shade_rows(scene: &Scene, features: &mut u32) -> (Vec<[f32; 4]>, u32) {
    let tris = &scene.triangles;
    let mut shade = Vec::with_capacity(tris.len() * 4);
    for t in tris {
        shade.push([t.n[0].x, t.n[0].y, t.n[0].z, t.uv[0].x]);
        shade.push([t.n[1].x, t.n[1].y, t.n[1].z, t.uv[0].y]);
        shade.push([t.n[2].x, t.n[2].y, t.n[2].z, t.uv[1].x]);
        shade.push([t.uv[1].y, t.uv[2].x, t.uv[2].y, f32::from_bits(t.material)]);
    }
    let extras_offset = shade.len() as u32;
    if !scene.vertex_extras.is_empty() {
        *features |= FEAT_EXTRAS;
        shade.reserve(tris.len() * EXTRAS_STRIDE);
        for i in 0..tris.len() {
            let e = scene.vertex_extras(i);
            for c in e.color {
                shade.push(c.to_array());
            }
            shade.push([e.uv1[0].x, e.uv1[0].y, e.uv1[1].x, e.uv1[1].y]);
            shade.push([e.uv1[2].x, e.uv1[2].y, 0.0, 0.0]);
            for t in e.tangent {
                shade.push(t.to_array());
            }
        }
    }
    (shade, extras_offset)
}

/// The materials' rows, [`MATERIAL_STRIDE`] each.
fn material_rows(scene: &Scene) -> Vec<[f32; 4]> {
    let mut materials = Vec::with_capacity(scene.materials.len() * MATERIAL_STRIDE);
    for (i, m) in scene.materials.iter().enumerate() {
        let ext = scene.material_ext(i as u32);
        let b: Vec4 = m.base_color;
        let base_ref = m.base_color_texture.map(|texture| TextureRef {
            texture,
            uv: ext.base_color_uv,
        });
        let ext_textures = ext.extension_textures().iter().any(Option::is_some);
        let mut flags = 0;
        for (on, bit) in [
            (m.double_sided, MAT_DOUBLE_SIDED),
            (base_ref.is_some(), MAT_BASE_TEX),
            (ext.metallic_roughness_texture.is_some(), MAT_MR_TEX),
            (ext.normal_texture.is_some(), MAT_NORMAL_TEX),
            (ext.emissive_texture.is_some(), MAT_EMISSIVE_TEX),
            (matches!(ext.alpha, AlphaMode::Mask(_)), MAT_MASK),
            (ext.alpha == AlphaMode::Blend, MAT_BLEND),
            (
                ext.transmission > 0.0
                    || ext.clearcoat > 0.0
                    || ext.specular_color != Vec3::ONE
                    || ext.ior != 1.5
                    || ext.sheen_color != Vec3::ZERO
                    || ext.anisotropy_strength > 0.0
                    || ext.diffuse_transmission > 0.0
                    || ext_textures,
                MAT_EXT_BSDF,
            ),
            (ext_textures, MAT_EXT_TEX),
            (ext.absorption != Vec3::ZERO, MAT_VOLUME),
            (
                ext.dispersion > 0.0 && ext.transmission > 0.0,
                MAT_DISPERSION,
            ),
        ] {
            if on {
                flags |= bit;
            }
        }
        let cutoff = match ext.alpha {
            AlphaMode::Mask(c) => c,
            _ => 0.0,
        };
        materials.push([b.x, b.y, b.z, b.w]);
        materials.push([m.emission.x, m.emission.y, m.emission.z, flags as f32]);
        let alpha = (m.roughness * m.roughness).max(MIN_ALPHA);
        materials.push([m.metallic, alpha, m.specular, cutoff]);
        let sc = ext.specular_color;
        materials.push([sc.x, sc.y, sc.z, ext.transmission]);
        let cc_alpha = (ext.clearcoat_roughness * ext.clearcoat_roughness).max(MIN_ALPHA);
        materials.push([ext.ior, ext.clearcoat, cc_alpha, ext.normal_scale]);
        slot(&mut materials, base_ref);
        slot(&mut materials, ext.metallic_roughness_texture);
        slot(&mut materials, ext.normal_texture);
        slot(&mut materials, ext.emissive_texture);
        for t in ext.extension_textures() {
            slot(&mut materials, t);
        }
        debug_assert_eq!(materials.len() % MATERIAL_STRIDE, MATERIAL_COAT_ROW);
        let a = ext.absorption;
        materials.push([ext.clearcoat_normal_scale, a.x, a.y, a.z]);
        let sh = ext.sheen_color;
        materials.push([sh.x, sh.y, sh.z, ext.sheen_roughness]);
        let (sin, cos) = ext.anisotropy_rotation.sin_cos();
        materials.push([ext.anisotropy_strength, cos, sin, ext.dispersion]);
        let dt = ext.diffuse_transmission_color;
        materials.push([dt.x, dt.y, dt.z, ext.diffuse_transmission]);
    }
    materials
}

/// The textures: a header of four words each (offset, width, height, sampler), then their
/// texels.
fn texel_words(scene: &Scene) -> Vec<u32> {
    let mut texels = Vec::new();
    let header = scene.textures.len() * 4;
    let mut offset = header as u32;
    for t in &scene.textures {
        texels.extend_from_slice(&[offset, t.width, t.height, sampler_word(t)]);
        offset += t.width * t.height;
    }
    for t in &scene.textures {
        texels.extend(t.texels.iter().map(|&c| u32::from_le_bytes(c)));
    }
    texels
}

/// The environment's texels (with their sampling weights), size, constant colour and power;
/// a map's marginal and conditional CDFs are appended to `dist`.
fn environment(scene: &Scene, dist: &mut Vec<f32>) -> (Vec<[f32; 4]>, [u32; 2], Vec3, f64) {
    // The environment: a constant, or an image sampled in proportion to luminance × sin θ
    // (the Jacobian of the equirectangular map), piecewise constant per texel.
    match &scene.environment {
        Environment::Constant(c) => (Vec::new(), [0, 0], *c, f64::from(luminance(*c))),
        Environment::Map(map) => {
            let (w, h) = (map.width as usize, map.height as usize);
            let mut rows = Vec::with_capacity(h);
            let mut conditional = Vec::with_capacity(h * (w + 1));
            let mut f = vec![0f64; w * h];
            for j in 0..h {
                let sin_theta = (std::f64::consts::PI * (j as f64 + 0.5) / h as f64).sin();
                for i in 0..w {
                    f[j * w + i] = f64::from(luminance(map.texels[j * w + i]).max(0.0)) * sin_theta;
                }
                let (row_cdf, row_total) = cdf(&f[j * w..(j + 1) * w]);
                conditional.extend(row_cdf);
                rows.push(row_total);
            }
            let (marginal, total) = cdf(&rows);
            dist.extend(marginal);
            dist.extend(conditional);
            let scale = if total > 0.0 {
                (w * h) as f64 / total
            } else {
                0.0
            };
            let env: Vec<[f32; 4]> = map
                .texels
                .iter()
                .zip(&f)
                .map(|(c, fi)| [c.x, c.y, c.z, (fi * scale) as f32])
                .collect();
            (env, [map.width, map.height], Vec3::ZERO, total)
        }
    }
}

/// The punctual lights' rows of `lights`.
fn push_punctual(scene: &Scene, lights: &mut Vec<[f32; 4]>) {
    for l in &scene.lights {
        let (kind, cos_outer, cos_inner) = match l.kind {
            LightKind::Point => (LIGHT_POINT, -1.0, -1.0),
            LightKind::Spot { inner, outer } => (LIGHT_SPOT, outer.cos(), inner.cos()),
            LightKind::Directional => (LIGHT_DIRECTIONAL, -1.0, -1.0),
        };
        let p = if kind == LIGHT_DIRECTIONAL {
            -l.direction
        } else {
            l.position
        };
        push3(
            lights,
            p,
            kind as f32,
            l.intensity,
            cos_outer,
            l.direction,
            cos_inner,
        );
    }
}
