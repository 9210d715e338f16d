//! The scene packed into flat arrays: exactly what the GPU kernel binds, and what the CPU twin
//! reads, so both integrate the same data.
//!
//! | array | per | layout |
//! |---|---|---|
//! | `nodes` | BVH node | obvhs `CwBvhNode` (80 bytes; see [`super::bvh`]) |
//! | `prims` | BVH primitive | 3 × vec4: `[v0, bits(triangle)]`, `[e1, light density]`, `[e2, 1 if single-sided]` |
//! | `shade` | triangle | 4 × vec4: `[n0, uv0.x]`, `[n1, uv0.y]`, `[n2, uv1.x]`, `[uv1.y, uv2, bits(material)]` |
//! | `materials` | material | 3 × vec4: `[base colour rgba]`, `[emission, bits(texture or !0)]`, `[metallic, α, specular, 1 if double-sided]` |
//! | `texels` | texture | header `[offset, width, height, 0]` per texture, then RGBA8 (sRGB) words |
//! | `lights` | emissive triangle | 3 × vec4: `[v0, bits(triangle)]`, `[e1, 1 if double-sided]`, `[e2, 0]` |
//! | `dist` | — | light CDF (L + 1), environment row CDF (H + 1), per-row column CDFs (H × (W + 1)) |
//! | `env` | environment texel | `[rgb, pdf over the unit square]` |
//!
//! Empty arrays get one zeroed element: a GPU binding cannot be empty.

use glam::{Vec3, Vec4};

use super::accum::luminance;
use super::bvh::SceneBvh;
use crate::scene::{Environment, Scene};

/// GGX α never goes below this: a perfect mirror has a Dirac BSDF that MIS cannot weigh.
pub const MIN_ALPHA: f32 = 1e-3;
/// `texture` word of a material without a texture.
pub const NO_TEXTURE: u32 = u32::MAX;

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
    pub triangle_count: usize,
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
        // Emitters: next-event estimation picks one in proportion to its power (area × luminance
        // × the faces it emits from).
        let mut light_tris = Vec::new();
        let mut light_weights = Vec::new();
        for (i, t) in tris.iter().enumerate() {
            let m = &scene.materials[t.material as usize];
            let area = 0.5 * (t.p[1] - t.p[0]).cross(t.p[2] - t.p[0]).length();
            let sides = if m.double_sided { 2.0 } else { 1.0 };
            let power = f64::from(area) * f64::from(luminance(m.emission)) * sides;
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
        let positions: Vec<[Vec3; 3]> = tris.iter().map(|t| t.p).collect();
        let single_sided: Vec<bool> = tris
            .iter()
            .map(|t| !scene.materials[t.material as usize].double_sided)
            .collect();
        let bvh = SceneBvh::build_sided(&positions, &light_density, &single_sided);

        let mut shade = Vec::with_capacity(tris.len() * 4);
        for t in tris {
            shade.push([t.n[0].x, t.n[0].y, t.n[0].z, t.uv[0].x]);
            shade.push([t.n[1].x, t.n[1].y, t.n[1].z, t.uv[0].y]);
            shade.push([t.n[2].x, t.n[2].y, t.n[2].z, t.uv[1].x]);
            shade.push([t.uv[1].y, t.uv[2].x, t.uv[2].y, f32::from_bits(t.material)]);
        }

        let mut materials = Vec::with_capacity(scene.materials.len() * 3);
        for m in &scene.materials {
            let b: Vec4 = m.base_color;
            materials.push([b.x, b.y, b.z, b.w]);
            let tex = m.base_color_texture.unwrap_or(NO_TEXTURE);
            materials.push([
                m.emission.x,
                m.emission.y,
                m.emission.z,
                f32::from_bits(tex),
            ]);
            let alpha = (m.roughness * m.roughness).max(MIN_ALPHA);
            materials.push([
                m.metallic,
                alpha,
                m.specular,
                if m.double_sided { 1.0 } else { 0.0 },
            ]);
        }

        let mut texels = Vec::new();
        let header = scene.textures.len() * 4;
        let mut offset = header as u32;
        for t in &scene.textures {
            texels.extend_from_slice(&[offset, t.width, t.height, 0]);
            offset += t.width * t.height;
        }
        for t in &scene.textures {
            texels.extend(t.texels.iter().map(|&c| u32::from_le_bytes(c)));
        }

        // The environment: a constant, or an image sampled in proportion to luminance × sin θ
        // (the Jacobian of the equirectangular map), piecewise constant per texel.
        let mut dist = light_cdf;
        let env_marginal = dist.len() as u32;
        let (env, env_size, env_constant, env_power) = match &scene.environment {
            Environment::Constant(c) => (Vec::new(), [0, 0], *c, f64::from(luminance(*c))),
            Environment::Map(map) => {
                let (w, h) = (map.width as usize, map.height as usize);
                let mut rows = Vec::with_capacity(h);
                let mut conditional = Vec::with_capacity(h * (w + 1));
                let mut f = vec![0f64; w * h];
                for j in 0..h {
                    let sin_theta = (std::f64::consts::PI * (j as f64 + 0.5) / h as f64).sin();
                    for i in 0..w {
                        f[j * w + i] =
                            f64::from(luminance(map.texels[j * w + i]).max(0.0)) * sin_theta;
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
        };
        let env_conditional = env_marginal + env_size[1] + 1;
        let env_select = match (env_power > 0.0, !light_tris.is_empty()) {
            (true, true) => 0.5,
            (true, false) => 1.0,
            (false, _) => 0.0,
        };

        let mut packed = Self {
            bvh,
            shade,
            materials,
            texels,
            lights,
            dist,
            env,
            light_count: light_tris.len() as u32,
            env_size,
            env_constant,
            env_marginal,
            env_conditional,
            env_select,
            triangle_count: tris.len(),
        };
        packed.pad_empty();
        packed
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
