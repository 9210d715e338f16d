//! glTF mesh primitives → world-space [`Triangle`]s (and their [`VertexExtras`]).

use glam::{Mat3, Mat4, Vec2, Vec3, Vec4};
use gltf::accessor::Dimensions;
use gltf::mesh::{Mode, Semantic};

use super::super::accessor::{read_floats, read_indices};
use super::super::report::{SceneError, label};
use super::super::{Triangle, VertexExtras};
use super::{Converted, Loader, MAX_COORDINATE, unit};

/// A primitive's vertex attributes and indices ([`Loader::attributes`]): per vertex, 3
/// floats of a position or normal, 2 of a UV, `color_n` (3 or 4) of a colour, 4 of a tangent.
struct Attributes {
    positions: Vec<f32>,
    normals: Option<Vec<f32>>,
    uvs: Option<Vec<f32>>,
    uvs1: Option<Vec<f32>>,
    colors: Option<Vec<f32>>,
    color_n: usize,
    tangents: Option<Vec<f32>>,
    indices: Vec<u32>,
}

impl Loader<'_> {
    pub(super) fn mesh(&mut self, mesh: &gltf::Mesh, world: Mat4) -> Result<(), SceneError> {
        let mesh_label = label("mesh", mesh.name(), mesh.index());
        let linear = Mat3::from_mat4(world);
        let det = linear.determinant();
        // Normals transform with the inverse transpose; a singular matrix flattens the mesh, whose
        // triangles then have zero area and are dropped below.
        let normal_matrix = (det != 0.0 && det.is_finite()).then(|| linear.inverse().transpose());
        let flip = det < 0.0;
        for prim in mesh.primitives() {
            let element = format!("{mesh_label} primitive {}", prim.index());
            if !matches!(
                prim.mode(),
                Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
            ) {
                self.report.unsupported(format!(
                    "primitive mode {} ({mesh_label})",
                    mode_name(prim.mode())
                ));
                continue;
            }
            if prim.morph_targets().next().is_some() {
                self.report
                    .unsupported(format!("morph targets ({mesh_label})"));
            }
            let converted = self.material(prim.material())?;
            let Attributes {
                positions,
                normals,
                uvs,
                uvs1,
                colors,
                color_n,
                tangents,
                indices,
            } = self.attributes(&prim, &element, converted)?;
            if prim.mode() == Mode::Triangles && indices.len() % 3 != 0 {
                self.report.warn(format!(
                    "{element}: {} indices are not a multiple of 3; the last {} are ignored",
                    indices.len(),
                    indices.len() % 3
                ));
            }
            let material = converted.index;
            // Vertex extras are kept only for scenes that have any.
            let wants_extras = colors.is_some() || uvs1.is_some() || converted.normal_uv.is_some();
            if wants_extras && !self.extras {
                self.extras = true;
                self.scene
                    .vertex_extras
                    .resize(self.scene.triangles.len(), VertexExtras::default());
            }
            let stats = self.stats.entry(mesh.index()).or_default();
            let vec3 = |d: &[f32], i: u32| {
                let i = i as usize * 3;
                Vec3::new(d[i], d[i + 1], d[i + 2])
            };
            let vec2 = |d: &[f32], i: u32, bad: &mut usize| {
                let v = Vec2::new(d[i as usize * 2], d[i as usize * 2 + 1]);
                if v.is_finite() {
                    v
                } else {
                    *bad += 1;
                    Vec2::ZERO
                }
            };
            for tri in triangle_indices(prim.mode(), &indices) {
                let mut idx = tri;
                if flip {
                    // A mirroring transform turns counter-clockwise (front) faces clockwise:
                    // swapping two vertices keeps the geometric normal on the front side.
                    idx.swap(1, 2);
                }
                let p = idx.map(|i| world.transform_point3(vec3(&positions, i)));
                if !p.iter().all(|v| v.is_finite()) {
                    stats.non_finite += 1;
                    continue;
                }
                if p.iter().any(|v| v.abs().max_element() > MAX_COORDINATE) {
                    stats.too_far += 1;
                    continue;
                }
                let Some(geometric) = geometric_normal(p) else {
                    stats.zero_area += 1;
                    continue;
                };
                let n = match (&normals, normal_matrix) {
                    (Some(ns), Some(m)) => idx.map(|i| {
                        unit(m * vec3(ns, i)).unwrap_or_else(|| {
                            stats.bad_normals += 1;
                            geometric
                        })
                    }),
                    _ => [geometric; 3],
                };
                let uv = match &uvs {
                    Some(t) => idx.map(|i| vec2(t, i, &mut stats.bad_uvs)),
                    None => [Vec2::ZERO; 3],
                };
                self.scene.triangles.push(Triangle { p, n, uv, material });
                if !self.extras {
                    continue;
                }
                let mut extra = VertexExtras::default();
                if let Some(t) = &uvs1 {
                    extra.uv1 = idx.map(|i| vec2(t, i, &mut stats.bad_uvs));
                }
                if let Some(c) = &colors {
                    extra.color = idx.map(|i| {
                        let k = i as usize * color_n;
                        let v = Vec4::new(
                            c[k],
                            c[k + 1],
                            c[k + 2],
                            if color_n == 4 { c[k + 3] } else { 1.0 },
                        );
                        if v.is_finite() {
                            v.clamp(Vec4::ZERO, Vec4::ONE)
                        } else {
                            stats.bad_colors += 1;
                            Vec4::ONE
                        }
                    });
                }
                if let Some(set) = converted.normal_uv {
                    let uvn = if set == 1 { extra.uv1 } else { uv };
                    extra.tangent = match (&tangents, normal_matrix) {
                        (Some(ts), Some(_)) => {
                            let mut out = [Vec4::ZERO; 3];
                            for (c, &i) in idx.iter().enumerate() {
                                let k = i as usize * 4;
                                let t =
                                    world.transform_vector3(Vec3::new(ts[k], ts[k + 1], ts[k + 2]));
                                // A mirroring transform flips the handedness of the frame.
                                let w = if ts[k + 3] < 0.0 { -1.0 } else { 1.0 } * det.signum();
                                out[c] = tangent_for(t, w, n[c]);
                            }
                            out
                        }
                        _ => uv_tangents(p, uvn, n),
                    };
                }
                self.scene.vertex_extras.push(extra);
            }
        }
        Ok(())
    }

    /// A primitive's vertex attributes (tangents only for a material with a normal map) and
    /// its indices (or 0, 1, 2, … without), checked: as many of each attribute as positions,
    /// no index past the vertices.
    fn attributes(
        &self,
        prim: &gltf::Primitive,
        element: &str,
        converted: Converted,
    ) -> Result<Attributes, SceneError> {
        let buffers = &self.res.buffers;
        let read = |semantic: Semantic, what: &str, dims: Dimensions| {
            prim.get(&semantic)
                .map(|acc| {
                    read_floats(&acc, buffers, dims)
                        .map_err(|e| self.element_error(element.to_owned(), format!("{what}: {e}")))
                })
                .transpose()
        };
        let positions = read(Semantic::Positions, "POSITION", Dimensions::Vec3)?
            .expect("precheck: every primitive has POSITION");
        let normals = read(Semantic::Normals, "NORMAL", Dimensions::Vec3)?;
        let uvs = read(Semantic::TexCoords(0), "TEXCOORD_0", Dimensions::Vec2)?;
        let uvs1 = read(Semantic::TexCoords(1), "TEXCOORD_1", Dimensions::Vec2)?;
        let color_dims = prim
            .get(&Semantic::Colors(0))
            .map(|a| a.dimensions())
            .filter(|d| *d == Dimensions::Vec3)
            .map_or(Dimensions::Vec4, |d| d);
        let colors = read(Semantic::Colors(0), "COLOR_0", color_dims)?;
        let color_n = if color_dims == Dimensions::Vec3 { 3 } else { 4 };
        let tangents = match converted.normal_uv {
            Some(_) => read(Semantic::Tangents, "TANGENT", Dimensions::Vec4)?,
            None => None,
        };
        let vertex_count = positions.len() / 3;
        for (what, data, n) in [
            ("NORMAL", &normals, 3),
            ("TEXCOORD_0", &uvs, 2),
            ("TEXCOORD_1", &uvs1, 2),
            ("COLOR_0", &colors, color_n),
            ("TANGENT", &tangents, 4),
        ] {
            if let Some(d) = data
                && d.len() / n != vertex_count
            {
                return Err(self.element_error(
                    element.to_owned(),
                    format!(
                        "{what} has {} elements, POSITION has {vertex_count}",
                        d.len() / n
                    ),
                ));
            }
        }
        let indices = match prim.indices() {
            Some(acc) => read_indices(&acc, &self.res.buffers)
                .map_err(|e| self.element_error(element.to_owned(), e.to_string()))?,
            None => (0..vertex_count as u32).collect(),
        };
        if let Some((k, &i)) = indices
            .iter()
            .enumerate()
            .find(|&(_, &i)| i as usize >= vertex_count)
        {
            return Err(self.element_error(
                element.to_owned(),
                format!("index {i} at position {k} is past the {vertex_count} vertices"),
            ));
        }
        Ok(Attributes {
            positions,
            normals,
            uvs,
            uvs1,
            colors,
            color_n,
            tangents,
            indices,
        })
    }
}

/// The triangles of a primitive's index list (glTF 2.0 §3.7.2.1): lists as they are, strips
/// and fans unrolled with the specification's winding; other modes have none.
pub(super) fn triangle_indices(mode: Mode, idx: &[u32]) -> Vec<[u32; 3]> {
    match mode {
        Mode::Triangles => idx.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect(),
        // p_i = {v_i, v_(i + (1 + i % 2)), v_(i + (2 − i % 2))}
        Mode::TriangleStrip => (0..idx.len().saturating_sub(2))
            .map(|i| {
                let odd = i % 2;
                [idx[i], idx[i + 1 + odd], idx[i + 2 - odd]]
            })
            .collect(),
        // p_i = {v_(i+1), v_(i+2), v_0}
        Mode::TriangleFan => (0..idx.len().saturating_sub(2))
            .map(|i| [idx[i + 1], idx[i + 2], idx[0]])
            .collect(),
        Mode::Points | Mode::Lines | Mode::LineLoop | Mode::LineStrip => Vec::new(),
    }
}

/// A unit tangent orthogonal to `n` with bitangent sign `w`, or a zero vector where `t` is
/// unusable (the tracer then builds a frame from the normal alone).
fn tangent_for(t: Vec3, w: f32, n: Vec3) -> Vec4 {
    match unit(t - n * n.dot(t)) {
        Some(t) => t.extend(w),
        None => Vec4::ZERO,
    }
}

/// Per-corner tangents from the positions and the normal map's texture coordinates (the
/// triangle's dP/du), with the sign that makes the normal map's +Y the direction of decreasing
/// v (glTF's images have v = 0 at the top, normal maps +Y up).
pub(super) fn uv_tangents(p: [Vec3; 3], uv: [Vec2; 3], n: [Vec3; 3]) -> [Vec4; 3] {
    let (dp1, dp2) = (p[1] - p[0], p[2] - p[0]);
    let (d1, d2) = (uv[1] - uv[0], uv[2] - uv[0]);
    let r = d1.x * d2.y - d1.y * d2.x;
    if r == 0.0 || !r.is_finite() {
        return [Vec4::ZERO; 3];
    }
    let dpdu = (dp1 * d2.y - dp2 * d1.y) / r;
    let dpdv = (dp2 * d1.x - dp1 * d2.x) / r;
    n.map(|n| {
        let t = tangent_for(dpdu, 1.0, n);
        let w = if n.cross(t.truncate()).dot(-dpdv) < 0.0 {
            -1.0
        } else {
            1.0
        };
        t.truncate().extend(if t == Vec4::ZERO { 0.0 } else { w })
    })
}

/// The unit normal of a counter-clockwise triangle, or `None` where the triangle is too small
/// for the tracer to form it: |e1 × e2|² below the smallest normal f32 would be flushed to
/// zero on a GPU (subnormals are not guaranteed in WGSL), making its `normalize` divide by
/// zero. Such triangles have areas under 1e-19 m² and are dropped as zero-area.
fn geometric_normal(p: [Vec3; 3]) -> Option<Vec3> {
    let c = (p[1] - p[0]).cross(p[2] - p[0]);
    let len2 = c.length_squared();
    (len2 >= f32::MIN_POSITIVE && len2.is_finite()).then(|| c / len2.sqrt())
}

/// A primitive mode as the glTF specification spells it.
fn mode_name(mode: Mode) -> &'static str {
    match mode {
        Mode::Points => "POINTS",
        Mode::Lines => "LINES",
        Mode::LineLoop => "LINE_LOOP",
        Mode::LineStrip => "LINE_STRIP",
        Mode::Triangles => "TRIANGLES",
        Mode::TriangleStrip => "TRIANGLE_STRIP",
        Mode::TriangleFan => "TRIANGLE_FAN",
    }
}
