//! glTF 2.0 (`.gltf`, `.glb`, in-memory GLB) → [`Scene`].
//!
//! The loader walks the default scene's node tree (the first scene where the file names none),
//! bakes node transforms into world-space triangles and keeps only what the integrator shades
//! (DESIGN.md §7). Features it does not model go to [`Scene::unsupported`] by name; data it
//! had to repair go to [`Scene::warnings`]. It never hands the tracer a non-finite or
//! degenerate triangle: such triangles are dropped and counted per mesh.
//!
//! `Scene::materials` holds the materials the drawn triangles use, in order of first use (glTF's
//! default material — white, metallic 1, roughness 1 — where a primitive names none);
//! `Scene::textures` the base-colour textures those materials use.
//!
//! Resources are resolved here rather than with `gltf::import`, which is all-or-nothing: one
//! undecodable image would fail the whole scene, where raygun falls back to the material's
//! base colour factor and says so. A missing file, though, is an error naming its URI.

use std::collections::{BTreeMap, HashMap, HashSet};
use std::io::Cursor;
use std::path::{Path, PathBuf};

use glam::{Mat3, Mat4, Vec2, Vec3, Vec4};
use gltf::accessor::Dimensions;
use gltf::json::validation::Checked;
use gltf::mesh::{Mode, Semantic};

use super::accessor::{read_floats, read_indices};
use super::{Camera, Environment, Material, Scene, Texture, Triangle};

/// The largest coordinate magnitude (metres) a triangle vertex or camera may have.
///
/// Ray–triangle tests multiply three coordinate differences (Möller–Trumbore's `t = e2·(s×e1)`
/// / det); with |coordinates| ≤ 1e9 such a product stays below (2e9)³·3 ≈ 2.4e28, ten orders
/// of magnitude under f32::MAX ≈ 3.4e38, so the tracer never sees inf or NaN from geometry.
/// (At 1e9 m an f32 resolves about 64 m, so nothing sensible lives out there anyway.)
/// Triangles beyond it are dropped and reported in [`Scene::warnings`].
pub const MAX_COORDINATE: f32 = 1.0e9;

/// glTF extensions the loader implements; every other one in `extensionsUsed` is reported.
pub const SUPPORTED_EXTENSIONS: &[&str] =
    &["KHR_materials_emissive_strength", "KHR_materials_specular"];

/// Images larger than this (bytes of decoded RGBA8) are refused by the decoder: a 16k × 8k
/// texture is 512 MiB, more than any base-colour texture the tracer can bind.
const MAX_IMAGE_BYTES: u64 = 512 << 20;

/// A scene that cannot be loaded. Every message names the file and the element at fault.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    #[error("{file}: cannot read the file")]
    Read {
        file: String,
        #[source]
        source: std::io::Error,
    },
    #[error("{file}: not a glTF 2.0 file: {reason}")]
    Parse { file: String, reason: String },
    #[error("{file}: invalid glTF: {problems}")]
    Invalid { file: String, problems: String },
    #[error("{file}: requires extension {extension}, which raygun does not implement")]
    RequiredExtension { file: String, extension: String },
    #[error("{file}: {element}: cannot read '{uri}': {reason}")]
    Resource {
        file: String,
        element: String,
        uri: String,
        reason: String,
    },
    #[error("{file}: {element}: {problem}")]
    Element {
        file: String,
        element: String,
        problem: String,
    },
    #[error("unknown built-in scene '{name}' (built-ins: {known})")]
    UnknownBuiltin { name: String, known: String },
    #[error("cannot generate built-in scene '{name}': {reason}")]
    Generate { name: String, reason: String },
}

impl Scene {
    /// Loads a `.gltf` (with its external or data-URI resources) or `.glb` file.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, SceneError> {
        let path = path.as_ref();
        let file = path.display().to_string();
        let bytes = std::fs::read(path).map_err(|source| SceneError::Read {
            file: file.clone(),
            source,
        })?;
        let base = path.parent().unwrap_or(Path::new("."));
        load_bytes(&bytes, &file, Some(base))
    }

    /// Loads glTF from memory (GLB, or JSON with data URIs only); `name` labels errors.
    /// External file references are an error: there is no directory to resolve them in.
    pub fn from_glb_bytes(bytes: &[u8], name: &str) -> Result<Self, SceneError> {
        load_bytes(bytes, name, None)
    }

    /// A file path, or `builtin:NAME` for a generated scene (see [`Scene::builtin`]).
    pub fn open(arg: &str) -> Result<Self, SceneError> {
        match arg.strip_prefix("builtin:") {
            Some(name) => Self::builtin(name),
            None => Self::load(arg),
        }
    }
}

/// `mesh 'Tower'` or `mesh 3`.
fn label(kind: &str, name: Option<&str>, index: usize) -> String {
    match name {
        Some(n) => format!("{kind} '{n}'"),
        None => format!("{kind} {index}"),
    }
}

/// What one load found, besides the triangles.
#[derive(Default)]
struct Report {
    unsupported: Vec<String>,
    seen: HashSet<String>,
    warnings: Vec<String>,
}

impl Report {
    fn unsupported(&mut self, what: String) {
        if self.seen.insert(what.clone()) {
            self.unsupported.push(what);
        }
    }

    fn warn(&mut self, what: String) {
        if self.seen.insert(what.clone()) {
            self.warnings.push(what);
        }
    }
}

/// Triangles a mesh lost or had repaired, summed over its instances.
#[derive(Default)]
struct MeshStats {
    zero_area: usize,
    non_finite: usize,
    too_far: usize,
    bad_normals: usize,
    bad_uvs: usize,
}

struct Loader<'a> {
    file: &'a str,
    base: Option<&'a Path>,
    doc: &'a gltf::Document,
    buffers: Vec<Vec<u8>>,
    report: Report,
    scene: Scene,
    /// glTF material index (None: the default material) → index in `scene.materials`.
    materials: HashMap<Option<usize>, u32>,
    /// glTF texture index → index in `scene.textures` (None: could not be decoded).
    textures: HashMap<usize, Option<u32>>,
    stats: BTreeMap<usize, MeshStats>,
}

fn load_bytes(bytes: &[u8], file: &str, base: Option<&Path>) -> Result<Scene, SceneError> {
    check_glb_header(bytes, file)?;
    let gltf::Gltf { document, blob } =
        gltf::Gltf::from_slice_without_validation(bytes).map_err(|e| SceneError::Parse {
            file: file.into(),
            reason: e.to_string(),
        })?;
    let root = document.into_json();
    precheck(&root, file)?;
    let doc = gltf::Document::from_json(root).map_err(|e| match e {
        gltf::Error::Validation(problems) => SceneError::Invalid {
            file: file.into(),
            problems: problems
                .iter()
                .map(|(path, err)| format!("{path}: {err}"))
                .collect::<Vec<_>>()
                .join("; "),
        },
        other => SceneError::Parse {
            file: file.into(),
            reason: other.to_string(),
        },
    })?;
    let buffers = load_buffers(&doc, blob.as_deref(), file, base)?;
    let mut loader = Loader {
        file,
        base,
        doc: &doc,
        buffers,
        report: Report::default(),
        scene: Scene::default(),
        materials: HashMap::new(),
        textures: HashMap::new(),
        stats: BTreeMap::new(),
    };
    loader.run()?;
    Ok(loader.finish())
}

/// The GLB header's declared length must cover the header itself: `gltf::binary::Glb` subtracts
/// 12 from it unchecked (an overflow panic, found by fuzzing).
fn check_glb_header(bytes: &[u8], file: &str) -> Result<(), SceneError> {
    let Some(rest) = bytes.strip_prefix(b"glTF") else {
        return Ok(());
    };
    let declared = rest
        .get(4..8)
        .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]));
    match declared {
        Some(n) if n >= 12 => Ok(()),
        _ => Err(SceneError::Parse {
            file: file.into(),
            reason: "the GLB header is truncated or declares less than its own 12 bytes".into(),
        }),
    }
}

/// Checks made before the `gltf` crate's validation, for clearer messages than its
/// JSON-path reports (unsupported required extensions, primitives without positions) and
/// because that validation panics on a POSITION index past the accessors.
fn precheck(root: &gltf::json::Root, file: &str) -> Result<(), SceneError> {
    if let Some(ext) = root
        .extensions_required
        .iter()
        .find(|e| !SUPPORTED_EXTENSIONS.contains(&e.as_str()))
    {
        return Err(SceneError::RequiredExtension {
            file: file.into(),
            extension: ext.clone(),
        });
    }
    for (mi, mesh) in root.meshes.iter().enumerate() {
        for (pi, prim) in mesh.primitives.iter().enumerate() {
            let key = Checked::Valid(gltf::json::mesh::Semantic::Positions);
            let problem = match prim.attributes.get(&key) {
                None => "POSITION accessor is missing".to_string(),
                // gltf-json's own validation indexes this accessor unchecked (a panic).
                Some(i) if i.value() >= root.accessors.len() => {
                    format!("POSITION accessor {} does not exist", i.value())
                }
                Some(_) => continue,
            };
            return Err(SceneError::Element {
                file: file.into(),
                element: format!("{} primitive {pi}", label("mesh", mesh.name.as_deref(), mi)),
                problem,
            });
        }
    }
    Ok(())
}

fn load_buffers(
    doc: &gltf::Document,
    blob: Option<&[u8]>,
    file: &str,
    base: Option<&Path>,
) -> Result<Vec<Vec<u8>>, SceneError> {
    let mut out = Vec::new();
    for buffer in doc.buffers() {
        let element = label("buffer", buffer.name(), buffer.index());
        let data = match buffer.source() {
            gltf::buffer::Source::Bin => {
                blob.map(<[u8]>::to_vec)
                    .ok_or_else(|| SceneError::Element {
                        file: file.into(),
                        element: element.clone(),
                        problem: "refers to the GLB binary chunk, but the file has none".into(),
                    })?
            }
            gltf::buffer::Source::Uri(uri) => {
                read_uri(uri, base).map_err(|reason| SceneError::Resource {
                    file: file.into(),
                    element: element.clone(),
                    uri: short_uri(uri),
                    reason,
                })?
            }
        };
        if data.len() < buffer.length() {
            return Err(SceneError::Element {
                file: file.into(),
                element,
                problem: format!(
                    "has {} bytes, but its byteLength is {}",
                    data.len(),
                    buffer.length()
                ),
            });
        }
        out.push(data);
    }
    Ok(out)
}

/// A URI for messages: data URIs are cut to their media type.
fn short_uri(uri: &str) -> String {
    match uri.strip_prefix("data:") {
        Some(rest) => format!("data:{}…", rest.split([',', ';']).next().unwrap_or("")),
        None => uri.to_string(),
    }
}

/// The bytes behind a glTF URI: `data:…;base64,…`, `file:` or a path relative to `base`.
fn read_uri(uri: &str, base: Option<&Path>) -> Result<Vec<u8>, String> {
    if let Some(rest) = uri.strip_prefix("data:") {
        let (_, payload) = rest
            .split_once(";base64,")
            .ok_or("a data URI must be base64-encoded (';base64,')")?;
        return base64::decode(payload).map_err(|e| format!("bad base64: {e}"));
    }
    let path = if let Some(rest) = uri.strip_prefix("file:") {
        PathBuf::from(percent_decode(rest.strip_prefix("//").unwrap_or(rest))?)
    } else if uri.contains(':') {
        return Err("only data: URIs and relative paths are supported".into());
    } else {
        let base = base.ok_or("an in-memory scene cannot refer to external files")?;
        base.join(percent_decode(uri)?)
    };
    if base.is_none() {
        return Err("an in-memory scene cannot refer to external files".into());
    }
    std::fs::read(&path).map_err(|e| format!("{} ({e})", path.display()))
}

/// RFC 3986 percent-decoding into UTF-8.
fn percent_decode(s: &str) -> Result<String, String> {
    let bytes = s.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = bytes
                .get(i + 1..i + 3)
                .and_then(|h| std::str::from_utf8(h).ok())
                .and_then(|h| u8::from_str_radix(h, 16).ok())
                .ok_or_else(|| format!("bad percent-escape in URI '{s}'"))?;
            out.push(hex);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    String::from_utf8(out).map_err(|_| format!("URI '{s}' does not decode to UTF-8"))
}

impl Loader<'_> {
    fn element_error(&self, element: String, problem: impl Into<String>) -> SceneError {
        SceneError::Element {
            file: self.file.into(),
            element,
            problem: problem.into(),
        }
    }

    fn run(&mut self) -> Result<(), SceneError> {
        let doc = self.doc;
        for ext in doc.extensions_used() {
            if !SUPPORTED_EXTENSIONS.contains(&ext) {
                self.report.unsupported(ext.to_string());
            }
        }
        for anim in doc.animations() {
            self.report
                .unsupported(label("animation", anim.name(), anim.index()));
        }
        let Some(scene) = doc.default_scene().or_else(|| doc.scenes().next()) else {
            self.report
                .warn("the file has no scene: nothing to draw but the environment".into());
            return Ok(());
        };
        let mut visited = vec![false; doc.nodes().len()];
        let mut stack: Vec<(gltf::Node, Mat4)> =
            scene.nodes().map(|n| (n, Mat4::IDENTITY)).collect();
        stack.reverse();
        while let Some((node, parent)) = stack.pop() {
            let element = label("node", node.name(), node.index());
            if std::mem::replace(&mut visited[node.index()], true) {
                return Err(self.element_error(
                    element,
                    "is reached twice: the node hierarchy must be a tree",
                ));
            }
            let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
            if let Some(skin) = node.skin() {
                self.report
                    .unsupported(label("skin", skin.name(), skin.index()));
            }
            if let Some(camera) = node.camera() {
                self.camera(&node, &camera, world)?;
            }
            if let Some(mesh) = node.mesh() {
                self.mesh(&mesh, world)?;
            }
            let mut children: Vec<_> = node.children().map(|c| (c, world)).collect();
            children.reverse();
            stack.extend(children);
        }
        Ok(())
    }

    fn camera(
        &mut self,
        node: &gltf::Node,
        camera: &gltf::Camera,
        world: Mat4,
    ) -> Result<(), SceneError> {
        let name = node
            .name()
            .or(camera.name())
            .map_or_else(|| format!("camera {}", node.index()), str::to_string);
        let element = format!("camera '{name}'");
        let yfov = match camera.projection() {
            gltf::camera::Projection::Perspective(p) => p.yfov(),
            gltf::camera::Projection::Orthographic(_) => {
                self.report
                    .unsupported(format!("orthographic camera '{name}'"));
                return Ok(());
            }
        };
        if !(yfov > 0.0 && yfov < std::f32::consts::PI) {
            return Err(self.element_error(element, format!("yfov {yfov} is not in (0, π)")));
        }
        let position = world.transform_point3(Vec3::ZERO);
        if !position.is_finite() || position.abs().max_element() > MAX_COORDINATE {
            return Err(self.element_error(
                element,
                format!("position {position} is not finite or beyond ±{MAX_COORDINATE} m"),
            ));
        }
        let forward = unit(world.transform_vector3(Vec3::NEG_Z));
        let up = forward.and_then(|f| {
            let u = world.transform_vector3(Vec3::Y);
            unit(u - f * u.dot(f))
        });
        let (Some(forward), Some(up)) = (forward, up) else {
            return Err(self.element_error(
                element,
                "its node transform is degenerate (no viewing direction or up vector)",
            ));
        };
        self.scene.cameras.push(Camera {
            name,
            position,
            forward,
            up,
            yfov,
        });
        Ok(())
    }

    fn mesh(&mut self, mesh: &gltf::Mesh, world: Mat4) -> Result<(), SceneError> {
        let mesh_label = label("mesh", mesh.name(), mesh.index());
        let linear = Mat3::from_mat4(world);
        let det = linear.determinant();
        // Normals transform with the inverse transpose; a singular matrix flattens the mesh, whose
        // triangles then have zero area and are dropped below.
        let normal_matrix = (det != 0.0 && det.is_finite()).then(|| linear.inverse().transpose());
        let flip = det < 0.0;
        for prim in mesh.primitives() {
            let element = format!("{mesh_label} primitive {}", prim.index());
            if prim.mode() != Mode::Triangles {
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
            if prim.get(&Semantic::Colors(0)).is_some() {
                self.report
                    .unsupported(format!("vertex colours COLOR_0 ({mesh_label})"));
            }
            let read = |semantic: Semantic, what: &str, dims: Dimensions| {
                prim.get(&semantic)
                    .map(|acc| {
                        read_floats(&acc, &self.buffers, dims).map_err(|e| {
                            self.element_error(element.clone(), format!("{what}: {e}"))
                        })
                    })
                    .transpose()
            };
            let positions = read(Semantic::Positions, "POSITION", Dimensions::Vec3)?
                .expect("precheck: every primitive has POSITION");
            let normals = read(Semantic::Normals, "NORMAL", Dimensions::Vec3)?;
            let uvs = read(Semantic::TexCoords(0), "TEXCOORD_0", Dimensions::Vec2)?;
            let vertex_count = positions.len() / 3;
            for (what, data, n) in [("NORMAL", &normals, 3), ("TEXCOORD_0", &uvs, 2)] {
                if let Some(d) = data
                    && d.len() / n != vertex_count
                {
                    return Err(self.element_error(
                        element,
                        format!(
                            "{what} has {} elements, POSITION has {vertex_count}",
                            d.len() / n
                        ),
                    ));
                }
            }
            let indices = match prim.indices() {
                Some(acc) => read_indices(&acc, &self.buffers)
                    .map_err(|e| self.element_error(element.clone(), e))?,
                None => (0..vertex_count as u32).collect(),
            };
            if let Some((k, &i)) = indices
                .iter()
                .enumerate()
                .find(|&(_, &i)| i as usize >= vertex_count)
            {
                return Err(self.element_error(
                    element,
                    format!("index {i} at position {k} is past the {vertex_count} vertices"),
                ));
            }
            if indices.len() % 3 != 0 {
                self.report.warn(format!(
                    "{element}: {} indices are not a multiple of 3; the last {} are ignored",
                    indices.len(),
                    indices.len() % 3
                ));
            }
            let material = self.material(prim.material())?;
            let stats = self.stats.entry(mesh.index()).or_default();
            let vec3 = |d: &[f32], i: u32| {
                let i = i as usize * 3;
                Vec3::new(d[i], d[i + 1], d[i + 2])
            };
            for tri in indices.chunks_exact(3) {
                let mut idx = [tri[0], tri[1], tri[2]];
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
                    Some(t) => idx.map(|i| {
                        let v = Vec2::new(t[i as usize * 2], t[i as usize * 2 + 1]);
                        if v.is_finite() {
                            v
                        } else {
                            stats.bad_uvs += 1;
                            Vec2::ZERO
                        }
                    }),
                    None => [Vec2::ZERO; 3],
                };
                self.scene.triangles.push(Triangle { p, n, uv, material });
            }
        }
        Ok(())
    }

    /// The scene material for a glTF material (None: glTF's default material), converted once.
    fn material(&mut self, m: gltf::Material) -> Result<u32, SceneError> {
        let key = m.index();
        if let Some(&i) = self.materials.get(&key) {
            return Ok(i);
        }
        let converted = match key {
            Some(_) => self.convert_material(&m)?,
            None => Material::default(),
        };
        let i = self.scene.materials.len() as u32;
        self.scene.materials.push(converted);
        self.materials.insert(key, i);
        Ok(i)
    }

    fn convert_material(&mut self, m: &gltf::Material) -> Result<Material, SceneError> {
        let index = m.index().unwrap_or(0);
        let element = label("material", m.name(), index);
        let name = m
            .name()
            .map_or_else(|| format!("material {index}"), str::to_string);
        let pbr = m.pbr_metallic_roughness();
        let mut factor = |what: &str, v: f32| -> Result<f32, SceneError> {
            if !v.is_finite() {
                return Err(
                    self.element_error(element.clone(), format!("{what} {v} is not finite"))
                );
            }
            let c = v.clamp(0.0, 1.0);
            if c != v {
                self.report
                    .warn(format!("{element}: {what} {v} clamped to [0, 1]"));
            }
            Ok(c)
        };
        let bc = pbr.base_color_factor();
        let base_color = Vec4::new(
            factor("baseColorFactor", bc[0])?,
            factor("baseColorFactor", bc[1])?,
            factor("baseColorFactor", bc[2])?,
            factor("baseColorFactor", bc[3])?,
        );
        let metallic = factor("metallicFactor", pbr.metallic_factor())?;
        let roughness = factor("roughnessFactor", pbr.roughness_factor())?;
        let ef = m.emissive_factor();
        let emissive = Vec3::new(
            factor("emissiveFactor", ef[0])?,
            factor("emissiveFactor", ef[1])?,
            factor("emissiveFactor", ef[2])?,
        );
        let strength = m.emissive_strength().unwrap_or(1.0);
        if !(strength >= 0.0 && strength.is_finite()) {
            return Err(self.element_error(
                element,
                format!("emissiveStrength {strength} is not a finite number ≥ 0"),
            ));
        }
        let alpha = match m.alpha_mode() {
            gltf::material::AlphaMode::Opaque => None,
            gltf::material::AlphaMode::Blend => Some("BLEND"),
            gltf::material::AlphaMode::Mask => Some("MASK"),
        };
        if let Some(mode) = alpha {
            self.report
                .unsupported(format!("alphaMode {mode} ({element}; drawn opaque)"));
        }
        if m.normal_texture().is_some() {
            self.report
                .unsupported(format!("normalTexture ({element})"));
        }
        if m.occlusion_texture().is_some() {
            self.report
                .unsupported(format!("occlusionTexture ({element})"));
        }
        if m.emissive_texture().is_some() {
            self.report
                .unsupported(format!("emissiveTexture ({element})"));
        }
        if pbr.metallic_roughness_texture().is_some() {
            self.report
                .unsupported(format!("metallicRoughnessTexture ({element})"));
        }
        let base_color_texture = match pbr.base_color_texture() {
            Some(info) if info.tex_coord() != 0 => {
                self.report.unsupported(format!(
                    "texCoord {} ({element} baseColorTexture; the factor is used)",
                    info.tex_coord()
                ));
                None
            }
            Some(info) => self.texture(&info.texture())?,
            None => None,
        };
        // KHR_materials_specular: the scalar factor scales the dielectric Fresnel term (the
        // tracer's BSDF); a coloured factor or textures are not modelled.
        let mut specular = 1.0;
        if let Some(sp) = m.specular() {
            let f = sp.specular_factor();
            specular = if f.is_finite() {
                f.clamp(0.0, 1.0)
            } else {
                1.0
            };
            if sp.specular_color_factor() != [1.0; 3] {
                self.report.unsupported(format!(
                    "KHR_materials_specular specularColorFactor ({element}; white is used)"
                ));
            }
            if sp.specular_texture().is_some() || sp.specular_color_texture().is_some() {
                self.report
                    .unsupported(format!("KHR_materials_specular textures ({element})"));
            }
        }
        Ok(Material {
            name,
            base_color,
            base_color_texture,
            metallic,
            roughness,
            specular,
            emission: emissive * strength,
            double_sided: m.double_sided(),
        })
    }

    /// Decodes a texture's image once; `None` (reported) where it cannot be decoded.
    fn texture(&mut self, tex: &gltf::Texture) -> Result<Option<u32>, SceneError> {
        if let Some(&t) = self.textures.get(&tex.index()) {
            return Ok(t);
        }
        let image = tex.source();
        let name = tex
            .name()
            .or(image.name())
            .map_or_else(|| format!("texture {}", tex.index()), str::to_string);
        let element = format!("texture '{name}'");
        let sampler = tex.sampler();
        for wrap in [sampler.wrap_s(), sampler.wrap_t()] {
            if wrap != gltf::texture::WrappingMode::Repeat {
                let wrap = match wrap {
                    gltf::texture::WrappingMode::ClampToEdge => "CLAMP_TO_EDGE",
                    gltf::texture::WrappingMode::MirroredRepeat => "MIRRORED_REPEAT",
                    gltf::texture::WrappingMode::Repeat => "REPEAT",
                };
                self.report.unsupported(format!(
                    "sampler wrap mode {wrap} ({element}; sampled with REPEAT)"
                ));
            }
        }
        let (bytes, mime, uri_ext) = match image.source() {
            gltf::image::Source::View { view, mime_type } => {
                let start = view.offset();
                let bytes = start
                    .checked_add(view.length())
                    .and_then(|end| self.buffers.get(view.buffer().index())?.get(start..end))
                    .ok_or_else(|| {
                        self.element_error(
                            element.clone(),
                            format!("buffer view {} runs past its buffer", view.index()),
                        )
                    })?;
                (bytes.to_vec(), Some(mime_type.to_string()), None)
            }
            gltf::image::Source::Uri { uri, mime_type } => {
                let bytes = read_uri(uri, self.base).map_err(|reason| SceneError::Resource {
                    file: self.file.into(),
                    element: element.clone(),
                    uri: short_uri(uri),
                    reason,
                })?;
                let data_mime = uri
                    .strip_prefix("data:")
                    .and_then(|r| r.split(';').next())
                    .filter(|m| !m.is_empty());
                let mime = mime_type.or(data_mime).map(str::to_string);
                let ext = (!uri.starts_with("data:"))
                    .then(|| uri.rsplit('.').next().map(str::to_ascii_lowercase))
                    .flatten();
                (bytes, mime, ext)
            }
        };
        let format = match (mime.as_deref(), uri_ext.as_deref()) {
            (Some("image/png"), _) | (None, Some("png")) => Some(image::ImageFormat::Png),
            (Some("image/jpeg"), _) | (None, Some("jpg" | "jpeg")) => {
                Some(image::ImageFormat::Jpeg)
            }
            _ => image::guess_format(&bytes)
                .ok()
                .filter(|f| matches!(f, image::ImageFormat::Png | image::ImageFormat::Jpeg)),
        };
        let Some(format) = format else {
            let what = mime.or(uri_ext).unwrap_or_else(|| "unknown".into());
            self.report.unsupported(format!(
                "image format {what} ({element}; its materials use the base colour factor)"
            ));
            self.textures.insert(tex.index(), None);
            return Ok(None);
        };
        let decoded = decode_rgba8(&bytes, format);
        let t = match decoded {
            Ok(texture) => {
                self.scene.textures.push(Texture {
                    name,
                    width: texture.width(),
                    height: texture.height(),
                    texels: texture.pixels().map(|p| p.0).collect(),
                });
                Some(self.scene.textures.len() as u32 - 1)
            }
            Err(e) => {
                self.report.warn(format!(
                    "{element}: cannot decode the {format:?} image ({e}); its materials use the base colour factor"
                ));
                None
            }
        };
        self.textures.insert(tex.index(), t);
        Ok(t)
    }

    fn finish(mut self) -> Scene {
        for (mesh_index, s) in std::mem::take(&mut self.stats) {
            let mesh = self
                .doc
                .meshes()
                .nth(mesh_index)
                .expect("a mesh of this document");
            let l = label("mesh", mesh.name(), mesh_index);
            for (n, what) in [
                (s.zero_area, "zero-area triangles dropped"),
                (s.non_finite, "triangles with non-finite vertices dropped"),
                (
                    s.too_far,
                    "triangles beyond the coordinate limit (MAX_COORDINATE) dropped",
                ),
                (
                    s.bad_normals,
                    "unusable vertex normals replaced by the face normal",
                ),
                (
                    s.bad_uvs,
                    "non-finite texture coordinates replaced by (0, 0)",
                ),
            ] {
                if n > 0 {
                    self.report.warn(format!("{l}: {n} {what}"));
                }
            }
        }
        self.scene.unsupported = self.report.unsupported;
        self.scene.warnings = self.report.warnings;
        self.scene.environment = Environment::default();
        self.scene
    }
}

/// Decodes PNG or JPEG into RGBA8 (grey, grey-alpha, RGB and 16-bit images are expanded the way
/// the `image` crate does: 16-bit channels are rounded to 8 bits, missing alpha is opaque).
fn decode_rgba8(bytes: &[u8], format: image::ImageFormat) -> Result<image::RgbaImage, String> {
    let mut reader = image::ImageReader::with_format(Cursor::new(bytes), format);
    let mut limits = image::Limits::default();
    limits.max_alloc = Some(MAX_IMAGE_BYTES);
    reader.limits(limits);
    let img = reader.decode().map_err(|e| e.to_string())?;
    let (w, h) = (u64::from(img.width()), u64::from(img.height()));
    if w * h * 4 > MAX_IMAGE_BYTES {
        return Err(format!(
            "{w}×{h} is larger than {MAX_IMAGE_BYTES} bytes of RGBA8"
        ));
    }
    if w == 0 || h == 0 {
        return Err("the image is empty".into());
    }
    Ok(img.to_rgba8())
}

/// `v` scaled to unit length, or `None` for a zero or non-finite vector. Dividing by the largest
/// component first keeps tiny vectors exact: glam's `try_normalize` squares them into
/// subnormals and returns vectors up to a few per cent off unit length (found by fuzzing).
fn unit(v: Vec3) -> Option<Vec3> {
    let m = v.abs().max_element();
    (m > 0.0 && m.is_finite()).then(|| (v / m).normalize())
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percent_decoding_accepts_utf8_and_rejects_broken_escapes() {
        assert_eq!(percent_decode("a%20b%C3%A9.png").unwrap(), "a bé.png");
        assert_eq!(percent_decode("plain.bin").unwrap(), "plain.bin");
        // The gltf crate unwraps this decoding and panics; here it is an error.
        assert!(percent_decode("%FF.png").unwrap_err().contains("UTF-8"));
        assert!(
            percent_decode("%G1")
                .unwrap_err()
                .contains("percent-escape")
        );
        assert!(percent_decode("end%2").is_err());
    }

    #[test]
    fn uris_resolve_data_and_relative_paths_and_refuse_the_rest() {
        assert_eq!(
            read_uri("data:application/octet-stream;base64,AAEC", None).unwrap(),
            [0, 1, 2]
        );
        assert!(
            read_uri("data:text/plain,hello", None)
                .unwrap_err()
                .contains("base64")
        );
        assert!(read_uri("https://example.com/a.bin", Some(Path::new("."))).is_err());
        assert!(read_uri("a.bin", None).unwrap_err().contains("in-memory"));
        assert!(
            read_uri("file:///etc/hostname", None)
                .unwrap_err()
                .contains("in-memory")
        );
        assert_eq!(short_uri("data:image/png;base64,AAAA"), "data:image/png…");
    }
}
