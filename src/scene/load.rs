//! glTF 2.0 (`.gltf`, `.glb`, in-memory GLB) → [`Scene`]: the scene walk.
//!
//! The loader walks the default scene's node tree (the first scene where the file names none),
//! bakes node transforms into world-space triangles, cameras and lights, and keeps only what
//! the integrator shades (DESIGN.md §7). Features it does not model go to
//! [`Scene::unsupported`] by name; data it had to repair go to [`Scene::warnings`]; what a path
//! tracer does not need (occlusion maps) to [`Scene::notes`]. It never hands the tracer a
//! non-finite or degenerate triangle: such triangles are dropped and counted per mesh.
//!
//! `Scene::materials` holds the materials the drawn triangles use, in order of first use (glTF's
//! default material — white, metallic 1, roughness 1 — where a primitive names none);
//! `Scene::textures` the textures those materials use (buffers, images, textures and samplers
//! are resolved in `resources.rs`). Vertex colours, TEXCOORD_1 and tangents go to
//! `Scene::vertex_extras` and material features beyond the core factors to
//! `Scene::material_ext`, both only when some primitive or material has them.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use glam::{Mat3, Mat4, Vec2, Vec3, Vec4};
use gltf::accessor::Dimensions;
use gltf::json::validation::Checked;
use gltf::mesh::{Mode, Semantic};

use super::accessor::{read_floats, read_indices};
use super::report::{Report, SceneError, label};
use super::resources::{Resources, UriAccess, check_glb_header, load_buffers};
use super::{
    AlphaMode, Camera, Environment, LightKind, Material, MaterialExt, OrthographicCamera,
    PunctualLight, Scene, TextureRef, Triangle, UvMap, UvTransform, VertexExtras,
};

/// The largest coordinate magnitude (metres) a triangle vertex or camera may have.
///
/// Ray–triangle tests multiply three coordinate differences (the test's `t = c·(e1×e2) /
/// d·(e1×e2)`, `c` the origin to a vertex); with |coordinates| ≤ 1e9 such a product stays below (2e9)³·3 ≈ 2.4e28, ten orders
/// of magnitude under f32::MAX ≈ 3.4e38, so the tracer never sees inf or NaN from geometry.
/// (At 1e9 m an f32 resolves about 64 m, so nothing sensible lives out there anyway.)
/// Triangles beyond it are dropped and reported in [`Scene::warnings`].
pub const MAX_COORDINATE: f32 = 1.0e9;

/// The largest absorption coefficient a material gets (per unit length): a black
/// attenuationColor or a vanishing attenuationDistance is capped here, where light is gone
/// after 10⁻²⁰ of a unit, instead of reaching the shaders as infinity.
pub const MAX_ABSORPTION: f32 = 1.0e22;

/// glTF extensions the loader implements; every other one in `extensionsUsed` is reported, and
/// one in `extensionsRequired` is an error. KHR_mesh_quantization needs nothing beyond the
/// core accessor reads (normalized and integer attributes are read as glTF defines them).
pub const SUPPORTED_EXTENSIONS: &[&str] = &[
    "KHR_materials_emissive_strength",
    "KHR_materials_specular",
    "KHR_materials_transmission",
    "KHR_materials_ior",
    "KHR_materials_clearcoat",
    "KHR_materials_volume",
    "KHR_materials_sheen",
    "KHR_materials_anisotropy",
    "KHR_materials_dispersion",
    "KHR_materials_diffuse_transmission",
    "KHR_texture_transform",
    "KHR_lights_punctual",
    "KHR_mesh_quantization",
    "EXT_meshopt_compression",
    "KHR_texture_basisu",
];

/// The largest scene file read: a GLB's length is a 32-bit number, so no binary glTF is larger,
/// and a `.gltf` JSON of that size would hold nothing a tracer could bind.
pub const MAX_SCENE_FILE_BYTES: u64 = u32::MAX as u64;

impl Scene {
    /// Loads a `.gltf` (with its external or data-URI resources) or `.glb` file; its URIs may
    /// name files in its own folder and below only ([`UriAccess::Confined`]).
    pub fn load(path: impl AsRef<Path>) -> Result<Self, SceneError> {
        Self::load_with(path, UriAccess::Confined)
    }

    /// [`Scene::load`] with the files its URIs may name chosen by `access`.
    pub fn load_with(path: impl AsRef<Path>, access: UriAccess) -> Result<Self, SceneError> {
        let path = path.as_ref();
        let file = path.display().to_string();
        let bytes = crate::input::read_file(path, MAX_SCENE_FILE_BYTES, "a glTF file").map_err(
            |source| SceneError::Read {
                file: file.clone(),
                source,
            },
        )?;
        let base = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        load_bytes(&bytes, &file, Some(base), access)
    }

    /// Loads glTF from memory (GLB, or JSON with data URIs only); `name` labels errors.
    /// External file references are an error: there is no directory to resolve them in.
    pub fn from_glb_bytes(bytes: &[u8], name: &str) -> Result<Self, SceneError> {
        load_bytes(bytes, name, None, UriAccess::Confined)
    }

    /// A file path, or `builtin:NAME` for a generated scene (see [`Scene::builtin`]).
    pub fn open(arg: &str) -> Result<Self, SceneError> {
        Self::open_with(arg, UriAccess::Confined)
    }

    /// [`Scene::open`] with the files a file's URIs may name chosen by `access`.
    pub fn open_with(arg: &str, access: UriAccess) -> Result<Self, SceneError> {
        match arg.strip_prefix("builtin:") {
            Some(name) => Self::builtin(name),
            None => Self::load_with(arg, access),
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
    bad_colors: usize,
}

/// A converted material and what its primitives must provide.
#[derive(Clone, Copy)]
struct Converted {
    index: u32,
    /// The texture coordinate set of its normal map (tangents are needed), if it has one.
    normal_uv: Option<u32>,
}

struct Loader<'a> {
    file: &'a str,
    doc: &'a gltf::Document,
    res: Resources<'a>,
    report: Report,
    scene: Scene,
    /// glTF material index (None: the default material) → converted material.
    materials: HashMap<Option<usize>, Converted>,
    /// `scene.material_ext` in step with `scene.materials` while loading (emptied at the end
    /// when no material uses any extended feature).
    material_ext: Vec<MaterialExt>,
    /// Whether some triangle has vertex extras (`scene.vertex_extras` is then kept in step
    /// with `scene.triangles`).
    extras: bool,
    stats: BTreeMap<usize, MeshStats>,
}

fn load_bytes(
    bytes: &[u8],
    file: &str,
    base: Option<&Path>,
    access: UriAccess,
) -> Result<Scene, SceneError> {
    check_glb_header(bytes, file)?;
    let gltf::Gltf { document, blob } =
        gltf::Gltf::from_slice_without_validation(bytes).map_err(|e| SceneError::Parse {
            file: file.into(),
            reason: e.to_string(),
        })?;
    let mut root = document.into_json();
    precheck(&root, file)?;
    // Every required extension is one raygun implements (precheck); the gltf crate's
    // validation would reject those it has no types for (KHR_mesh_quantization,
    // KHR_materials_clearcoat), so the list has done its job.
    root.extensions_required.clear();
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
    let buffers = load_buffers(&doc, blob.as_deref(), file, base, access)?;
    let mut loader = Loader {
        file,
        doc: &doc,
        res: Resources::new(file, base, access, buffers),
        report: Report::default(),
        scene: Scene::default(),
        materials: HashMap::new(),
        material_ext: Vec::new(),
        extras: false,
        stats: BTreeMap::new(),
    };
    loader.run()?;
    Ok(loader.finish())
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
    // glTF 2.0 §5.18: an image has a uri or a bufferView, and a bufferView needs a
    // mimeType; the gltf crate's `Image::source` unwraps both (a panic otherwise).
    for (ii, image) in root.images.iter().enumerate() {
        let problem = match (&image.uri, &image.buffer_view, &image.mime_type) {
            (None, None, _) => "has neither a uri nor a bufferView",
            (_, Some(_), None) => "has a bufferView but no mimeType",
            _ => continue,
        };
        return Err(SceneError::Element {
            file: file.into(),
            element: label("image", image.name.as_deref(), ii),
            problem: problem.into(),
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

/// The triangles of a primitive's index list (glTF 2.0 §3.7.2.1): lists as they are, strips
/// and fans unrolled with the specification's winding; other modes have none.
fn triangle_indices(mode: Mode, idx: &[u32]) -> Vec<[u32; 3]> {
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

/// A texture info's texture coordinates: its texCoord, or KHR_texture_transform's override,
/// and the transform (non-finite values are the identity's).
fn info_uv(info: &gltf::texture::Info) -> UvMap {
    let Some(t) = info.texture_transform() else {
        return UvMap {
            tex_coord: info.tex_coord(),
            transform: UvTransform::default(),
        };
    };
    let finite2 = |v: [f32; 2], d: Vec2| {
        let v = Vec2::from_array(v);
        if v.is_finite() { v } else { d }
    };
    UvMap {
        tex_coord: t.tex_coord().unwrap_or(info.tex_coord()),
        transform: UvTransform {
            offset: finite2(t.offset(), Vec2::ZERO),
            rotation: if t.rotation().is_finite() {
                t.rotation()
            } else {
                0.0
            },
            scale: finite2(t.scale(), Vec2::ONE),
        },
    }
}

/// KHR_texture_transform of a texture reference (its JSON), and the texCoord it overrides.
fn texture_transform(ext: Option<&serde_json::Value>, tex_coord: u32) -> UvMap {
    let Some(t) = ext else {
        return UvMap {
            tex_coord,
            transform: UvTransform::default(),
        };
    };
    let pair = |key: &str, default: Vec2| {
        t.get(key)
            .and_then(|v| v.as_array())
            .and_then(|a| {
                Some(Vec2::new(
                    a.first()?.as_f64()? as f32,
                    a.get(1)?.as_f64()? as f32,
                ))
            })
            .filter(|v| v.is_finite())
            .unwrap_or(default)
    };
    let rotation = t
        .get("rotation")
        .and_then(serde_json::Value::as_f64)
        .map(|r| r as f32)
        .filter(|r| r.is_finite())
        .unwrap_or(0.0);
    UvMap {
        tex_coord: t
            .get("texCoord")
            .and_then(serde_json::Value::as_u64)
            .map_or(tex_coord, |c| c.min(u64::from(u32::MAX)) as u32),
        transform: UvTransform {
            offset: pair("offset", Vec2::ZERO),
            rotation,
            scale: pair("scale", Vec2::ONE),
        },
    }
}

impl Loader<'_> {
    fn element_error(&self, element: String, problem: impl Into<String>) -> SceneError {
        SceneError::Element {
            file: self.file.into(),
            element,
            problem: problem.into(),
        }
    }

    /// Number `key` of an extension given as JSON (`default` where absent); anything else is
    /// an error naming the material and the key.
    fn json_number(
        &self,
        element: &str,
        ext: &serde_json::Value,
        key: &str,
        default: f64,
    ) -> Result<f64, SceneError> {
        match ext.get(key) {
            None => Ok(default),
            Some(v) => v.as_f64().ok_or_else(|| {
                self.element_error(element.to_string(), format!("{key} {v} is not a number"))
            }),
        }
    }

    /// Three numbers `key` of an extension given as JSON (`default` where absent); anything
    /// else is an error naming the element.
    fn json_rgb(
        &self,
        element: &str,
        ext: &serde_json::Value,
        key: &str,
        default: [f64; 3],
    ) -> Result<[f64; 3], SceneError> {
        let Some(v) = ext.get(key) else {
            return Ok(default);
        };
        let numbers: Option<Vec<f64>> = v
            .as_array()
            .filter(|a| a.len() == 3)
            .and_then(|a| a.iter().map(serde_json::Value::as_f64).collect());
        numbers.map(|c| [c[0], c[1], c[2]]).ok_or_else(|| {
            self.element_error(
                element.to_string(),
                format!("{key} {v} is not three numbers"),
            )
        })
    }

    /// KHR_materials_volume's absorption coefficient (`MaterialExt::absorption`): the medium
    /// behind a surface of thickness > 0 absorbs −ln(attenuationColor) / attenuationDistance per
    /// unit length; a thin-walled one (thicknessFactor 0, the default) bounds no medium. The
    /// thickness itself is for renderers that cannot trace the mesh: a path tracer measures the
    /// distance a ray travels inside, so thicknessTexture is noted and not used.
    fn absorption(
        &mut self,
        element: &str,
        v: &gltf::material::Volume<'_>,
    ) -> Result<Vec3, SceneError> {
        let problem = |what: String| {
            self.element_error(element.to_string(), format!("KHR_materials_volume: {what}"))
        };
        let thickness = v.thickness_factor();
        if !(thickness.is_finite() && thickness >= 0.0) {
            return Err(problem(format!(
                "thicknessFactor {thickness} is not a finite number ≥ 0"
            )));
        }
        let distance = v.attenuation_distance();
        if !(distance > 0.0) {
            return Err(problem(format!(
                "attenuationDistance {distance} is not a number > 0"
            )));
        }
        // (JSON numbers beyond f32's range are refused by the parser, so these are finite.)
        let given = v.attenuation_color();
        let color = given.map(|c| c.clamp(0.0, 1.0));
        if color != given {
            self.report.warn(format!(
                "{element}: KHR_materials_volume attenuationColor {given:?} clamped to [0, 1]"
            ));
        }
        if v.thickness_texture().is_some() {
            self.report.note(format!(
                "thicknessTexture ({element}) not used: the path tracer measures the distance \
                 light travels inside the mesh"
            ));
        }
        let absorbs = distance < f32::INFINITY && color.iter().any(|&c| c < 1.0);
        if thickness == 0.0 {
            if absorbs {
                self.report.note(format!(
                    "{element}: KHR_materials_volume with thicknessFactor 0 is thin-walled: \
                     its attenuation does not apply"
                ));
            }
            return Ok(Vec3::ZERO);
        }
        // σ = −ln(c)/d per channel; a black channel absorbs everything within any length
        // (capped to stay finite for the shaders: exp(−σt) is 0 for every t a hit can have).
        Ok(Vec3::from(color.map(|c| {
            if c >= 1.0 || distance == f32::INFINITY {
                0.0
            } else {
                (-c.ln() / distance).min(MAX_ABSORPTION)
            }
        })))
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
            if let Some(light) = node.light() {
                self.light(&light, world)?;
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

    /// A node's world position and its unit −Z (forward) and +Y (up) axes.
    fn frame(&self, element: &str, world: Mat4) -> Result<(Vec3, Vec3, Vec3), SceneError> {
        let position = world.transform_point3(Vec3::ZERO);
        if !position.is_finite() || position.abs().max_element() > MAX_COORDINATE {
            return Err(self.element_error(
                element.to_string(),
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
                element.to_string(),
                "its node transform is degenerate (no viewing direction or up vector)",
            ));
        };
        Ok((position, forward, up))
    }

    /// A camera is named after its node, else itself, else its index in the file's cameras
    /// (what `--camera` takes).
    fn camera(
        &mut self,
        node: &gltf::Node,
        camera: &gltf::Camera,
        world: Mat4,
    ) -> Result<(), SceneError> {
        let name = node
            .name()
            .or(camera.name())
            .map_or_else(|| format!("camera {}", camera.index()), str::to_string);
        let element = format!("camera '{name}'");
        match camera.projection() {
            gltf::camera::Projection::Perspective(p) => {
                let yfov = p.yfov();
                if !(yfov > 0.0 && yfov < std::f32::consts::PI) {
                    return Err(
                        self.element_error(element, format!("yfov {yfov} is not in (0, π)"))
                    );
                }
                let (position, forward, up) = self.frame(&element, world)?;
                self.scene.cameras.push(Camera {
                    name,
                    position,
                    forward,
                    up,
                    yfov,
                });
            }
            gltf::camera::Projection::Orthographic(o) => {
                // The node's scale scales the window (glTF: cameras are affected by it).
                let ymag = o.ymag().abs() * world.transform_vector3(Vec3::Y).length();
                if !(ymag > 0.0 && ymag.is_finite() && ymag <= MAX_COORDINATE) {
                    return Err(self.element_error(
                        element,
                        format!("ymag {} is not a positive finite size", o.ymag()),
                    ));
                }
                let (position, forward, up) = self.frame(&element, world)?;
                self.scene.orthographic_cameras.push(OrthographicCamera {
                    name,
                    position,
                    forward,
                    up,
                    ymag,
                });
            }
        }
        Ok(())
    }

    fn light(
        &mut self,
        light: &gltf::khr_lights_punctual::Light,
        world: Mat4,
    ) -> Result<(), SceneError> {
        let name = light
            .name()
            .map_or_else(|| format!("light {}", light.index()), str::to_string);
        let element = format!("light '{name}'");
        let (position, direction, _) = self.frame(&element, world)?;
        let color = Vec3::from_array(light.color());
        let intensity = light.intensity();
        let usable = color.is_finite()
            && color.min_element() >= 0.0
            && intensity >= 0.0
            && intensity.is_finite();
        if !usable {
            return Err(self.element_error(
                element,
                format!("color {color} × intensity {intensity} is not finite and ≥ 0"),
            ));
        }
        let kind = match light.kind() {
            gltf::khr_lights_punctual::Kind::Point => LightKind::Point,
            gltf::khr_lights_punctual::Kind::Directional => LightKind::Directional,
            gltf::khr_lights_punctual::Kind::Spot {
                inner_cone_angle,
                outer_cone_angle,
            } => {
                let half_pi = std::f32::consts::FRAC_PI_2;
                if !(0.0 <= inner_cone_angle
                    && inner_cone_angle < outer_cone_angle
                    && outer_cone_angle <= half_pi)
                {
                    return Err(self.element_error(
                        element,
                        format!(
                            "cone angles {inner_cone_angle}, {outer_cone_angle} are not 0 ≤ inner < outer ≤ π/2"
                        ),
                    ));
                }
                LightKind::Spot {
                    inner: inner_cone_angle,
                    outer: outer_cone_angle,
                }
            }
        };
        if light.range().is_some() {
            self.report.note(format!(
                "{element}: range ignored (the light falls off with the inverse square everywhere)"
            ));
        }
        self.scene.lights.push(PunctualLight {
            name,
            kind,
            position,
            direction,
            intensity: color * intensity,
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
            let buffers = &self.res.buffers;
            let read = |semantic: Semantic, what: &str, dims: Dimensions| {
                prim.get(&semantic)
                    .map(|acc| {
                        read_floats(&acc, buffers, dims).map_err(|e| {
                            self.element_error(element.clone(), format!("{what}: {e}"))
                        })
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
                        element,
                        format!(
                            "{what} has {} elements, POSITION has {vertex_count}",
                            d.len() / n
                        ),
                    ));
                }
            }
            let indices = match prim.indices() {
                Some(acc) => read_indices(&acc, &self.res.buffers)
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

    /// The scene material for a glTF material (None: glTF's default material), converted once.
    fn material(&mut self, m: gltf::Material) -> Result<Converted, SceneError> {
        let key = m.index();
        if let Some(&c) = self.materials.get(&key) {
            return Ok(c);
        }
        let (converted, ext) = match key {
            Some(_) => self.convert_material(&m)?,
            None => (Material::default(), MaterialExt::default()),
        };
        let c = Converted {
            index: self.scene.materials.len() as u32,
            // Tangents for the base's normal map, else for the coat's, else for the anisotropy
            // texture's (on its set), else TEXCOORD_0's for an anisotropy without one.
            normal_uv: ext
                .normal_texture
                .or(ext.clearcoat_normal_texture)
                .or(ext.anisotropy_texture)
                .map(|t| t.uv.tex_coord)
                .or((ext.anisotropy_strength > 0.0).then_some(0)),
        };
        self.scene.materials.push(converted);
        self.material_ext.push(ext);
        self.materials.insert(key, c);
        Ok(c)
    }

    /// A texture reference: its scene texture (None where it cannot be used, reported) and UVs.
    fn texture_ref(
        &mut self,
        element: &str,
        what: &str,
        tex: &gltf::Texture,
        uv: UvMap,
        srgb: bool,
    ) -> Result<Option<TextureRef>, SceneError> {
        if uv.tex_coord > 1 {
            self.report.unsupported(format!(
                "texCoord {} ({element} {what}; only TEXCOORD_0 and TEXCOORD_1 are read, the factor is used)",
                uv.tex_coord
            ));
            return Ok(None);
        }
        let texture = self.res.texture(
            self.doc,
            tex,
            srgb,
            &mut self.scene.textures,
            &mut self.report,
        )?;
        Ok(texture.map(|texture| TextureRef { texture, uv }))
    }

    /// [`Self::texture_ref`] for a glTF texture info, where there is one.
    fn info_ref(
        &mut self,
        element: &str,
        what: &str,
        info: Option<gltf::texture::Info>,
        srgb: bool,
    ) -> Result<Option<TextureRef>, SceneError> {
        match info {
            Some(info) => self.texture_ref(element, what, &info.texture(), info_uv(&info), srgb),
            None => Ok(None),
        }
    }

    /// A texture reference an extension gives as JSON (`{"index", "texCoord", "extensions":
    /// {"KHR_texture_transform"}}`: the gltf crate has no typed form for it), read as data
    /// (colour data in sRGB where `srgb`). None where `info` is absent or the texture cannot be
    /// used (reported); an index that names no texture is an error naming the material and the
    /// key.
    fn json_texture_ref(
        &mut self,
        element: &str,
        what: &str,
        info: Option<&serde_json::Value>,
        srgb: bool,
    ) -> Result<Option<TextureRef>, SceneError> {
        let Some(info) = info else {
            return Ok(None);
        };
        let count = self.doc.textures().len();
        let index = info.get("index").and_then(serde_json::Value::as_u64);
        let Some(tex) = index.and_then(|i| self.doc.textures().nth(usize::try_from(i).ok()?))
        else {
            let index = info
                .get("index")
                .map_or("missing".into(), ToString::to_string);
            return Err(self.element_error(
                element.to_string(),
                format!("{what}: index {index} names no texture (the file has {count})"),
            ));
        };
        let tex_coord = match info.get("texCoord") {
            None => 0,
            Some(v) => match v.as_u64() {
                Some(c) => c.min(u64::from(u32::MAX)) as u32,
                None => {
                    return Err(self.element_error(
                        element.to_string(),
                        format!("{what}: texCoord {v} is not a number ≥ 0"),
                    ));
                }
            },
        };
        let uv = texture_transform(
            info.get("extensions")
                .and_then(|e| e.get("KHR_texture_transform")),
            tex_coord,
        );
        self.texture_ref(element, what, &tex, uv, srgb)
    }

    fn convert_material(
        &mut self,
        m: &gltf::Material,
    ) -> Result<(Material, MaterialExt), SceneError> {
        let index = m.index().unwrap_or(0);
        let element = label("material", m.name(), index);
        let name = m
            .name()
            .map_or_else(|| format!("material {index}"), str::to_string);
        let pbr = m.pbr_metallic_roughness();
        let file = self.file;
        let factor = |report: &mut Report, what: &str, v: f32| -> Result<f32, SceneError> {
            if !v.is_finite() {
                return Err(SceneError::Element {
                    file: file.into(),
                    element: element.clone(),
                    problem: format!("{what} {v} is not finite"),
                });
            }
            let c = v.clamp(0.0, 1.0);
            if c != v {
                report.warn(format!("{element}: {what} {v} clamped to [0, 1]"));
            }
            Ok(c)
        };
        let r = &mut self.report;
        let bc = pbr.base_color_factor();
        let base_color = Vec4::new(
            factor(r, "baseColorFactor", bc[0])?,
            factor(r, "baseColorFactor", bc[1])?,
            factor(r, "baseColorFactor", bc[2])?,
            factor(r, "baseColorFactor", bc[3])?,
        );
        let metallic = factor(r, "metallicFactor", pbr.metallic_factor())?;
        let roughness = factor(r, "roughnessFactor", pbr.roughness_factor())?;
        let ef = m.emissive_factor();
        let emissive = Vec3::new(
            factor(r, "emissiveFactor", ef[0])?,
            factor(r, "emissiveFactor", ef[1])?,
            factor(r, "emissiveFactor", ef[2])?,
        );
        let mut ext = MaterialExt::default();
        if let Some(c) = m.extension_value("KHR_materials_clearcoat") {
            let get = |key: &str| c.get(key).and_then(serde_json::Value::as_f64);
            ext.clearcoat = factor(
                r,
                "clearcoatFactor",
                get("clearcoatFactor").unwrap_or(0.0) as f32,
            )?;
            ext.clearcoat_roughness = factor(
                r,
                "clearcoatRoughnessFactor",
                get("clearcoatRoughnessFactor").unwrap_or(0.0) as f32,
            )?;
            ext.clearcoat_texture = self.json_texture_ref(
                &element,
                "clearcoatTexture",
                c.get("clearcoatTexture"),
                false,
            )?;
            ext.clearcoat_roughness_texture = self.json_texture_ref(
                &element,
                "clearcoatRoughnessTexture",
                c.get("clearcoatRoughnessTexture"),
                false,
            )?;
            let normal = c.get("clearcoatNormalTexture");
            ext.clearcoat_normal_texture =
                self.json_texture_ref(&element, "clearcoatNormalTexture", normal, false)?;
            let scale = normal.and_then(|n| n.get("scale"));
            ext.clearcoat_normal_scale = match scale {
                None => 1.0,
                Some(v) => match v.as_f64().map(|s| s as f32).filter(|s| s.is_finite()) {
                    Some(s) => s,
                    None => {
                        return Err(self.element_error(
                            element,
                            format!("clearcoatNormalTexture: scale {v} is not a finite number"),
                        ));
                    }
                },
            };
        }
        if let Some(sh) = m.extension_value("KHR_materials_sheen") {
            // (JSON to the gltf crate, as the clear coat is.)
            let colour = self.json_rgb(&element, sh, "sheenColorFactor", [0.0; 3])?;
            let roughness = self.json_number(&element, sh, "sheenRoughnessFactor", 0.0)?;
            let r = &mut self.report;
            ext.sheen_color = Vec3::new(
                factor(r, "sheenColorFactor", colour[0] as f32)?,
                factor(r, "sheenColorFactor", colour[1] as f32)?,
                factor(r, "sheenColorFactor", colour[2] as f32)?,
            );
            ext.sheen_roughness = factor(r, "sheenRoughnessFactor", roughness as f32)?;
            ext.sheen_color_texture = self.json_texture_ref(
                &element,
                "sheenColorTexture",
                sh.get("sheenColorTexture"),
                true,
            )?;
            ext.sheen_roughness_texture = self.json_texture_ref(
                &element,
                "sheenRoughnessTexture",
                sh.get("sheenRoughnessTexture"),
                false,
            )?;
        }
        if let Some(dt) = m.extension_value("KHR_materials_diffuse_transmission") {
            // (JSON to the gltf crate, as the clear coat is.)
            let strength = self.json_number(&element, dt, "diffuseTransmissionFactor", 0.0)?;
            let colour = self.json_rgb(&element, dt, "diffuseTransmissionColorFactor", [1.0; 3])?;
            let r = &mut self.report;
            ext.diffuse_transmission = factor(r, "diffuseTransmissionFactor", strength as f32)?;
            ext.diffuse_transmission_color = Vec3::new(
                factor(r, "diffuseTransmissionColorFactor", colour[0] as f32)?,
                factor(r, "diffuseTransmissionColorFactor", colour[1] as f32)?,
                factor(r, "diffuseTransmissionColorFactor", colour[2] as f32)?,
            );
            ext.diffuse_transmission_texture = self.json_texture_ref(
                &element,
                "diffuseTransmissionTexture",
                dt.get("diffuseTransmissionTexture"),
                false,
            )?;
            ext.diffuse_transmission_color_texture = self.json_texture_ref(
                &element,
                "diffuseTransmissionColorTexture",
                dt.get("diffuseTransmissionColorTexture"),
                true,
            )?;
        }
        if let Some(an) = m.extension_value("KHR_materials_anisotropy") {
            // (JSON to the gltf crate, as the clear coat is.)
            let strength = self.json_number(&element, an, "anisotropyStrength", 0.0)?;
            let rotation = self.json_number(&element, an, "anisotropyRotation", 0.0)? as f32;
            if !rotation.is_finite() {
                return Err(self.element_error(
                    element,
                    format!("anisotropyRotation {rotation} is not finite"),
                ));
            }
            ext.anisotropy_strength =
                factor(&mut self.report, "anisotropyStrength", strength as f32)?;
            ext.anisotropy_rotation = rotation;
            ext.anisotropy_texture = self.json_texture_ref(
                &element,
                "anisotropyTexture",
                an.get("anisotropyTexture"),
                false,
            )?;
        }
        if let Some(t) = m.transmission() {
            ext.transmission = factor(
                &mut self.report,
                "transmissionFactor",
                t.transmission_factor(),
            )?;
            ext.transmission_texture = self.info_ref(
                &element,
                "transmissionTexture",
                t.transmission_texture(),
                false,
            )?;
        }
        if let Some(ior) = m.ior() {
            // glTF: ior ≥ 1, or 0 for "reflects like a metal" (F0 = 1); raygun needs a
            // refracting interface, so 0 and values under 1 are clamped and said.
            ext.ior = if ior.is_finite() && ior >= 1.0 {
                ior.min(10.0)
            } else {
                self.report
                    .warn(format!("{element}: ior {ior} replaced by 1.5"));
                1.5
            };
        }
        if let Some(v) = m.volume() {
            ext.absorption = self.absorption(&element, &v)?;
        }
        if let Some(dp) = m.extension_value("KHR_materials_dispersion") {
            // (JSON to the gltf crate, as the clear coat is.) raygun refracts every
            // transmitting surface, with or without KHR_materials_volume, so the dispersion
            // applies wherever light is transmitted.
            let d = self.json_number(&element, dp, "dispersion", 0.0)? as f32;
            if !(d.is_finite() && d >= 0.0) {
                // (The file's own number: beyond f32's range it would read "inf".)
                let given = &dp["dispersion"];
                return Err(self.element_error(
                    element,
                    format!(
                        "KHR_materials_dispersion: dispersion {given} is not a finite number ≥ 0"
                    ),
                ));
            }
            if d > 0.0 && ext.transmission == 0.0 {
                self.report.note(format!(
                    "{element}: KHR_materials_dispersion without transmission changes nothing \
                     (only refracted light is dispersed)"
                ));
            } else {
                ext.dispersion = d;
            }
        }
        let strength = m.emissive_strength().unwrap_or(1.0);
        if !(strength >= 0.0 && strength.is_finite()) {
            return Err(self.element_error(
                element,
                format!("emissiveStrength {strength} is not a finite number ≥ 0"),
            ));
        }
        ext.alpha = match m.alpha_mode() {
            gltf::material::AlphaMode::Opaque => AlphaMode::Opaque,
            gltf::material::AlphaMode::Blend => AlphaMode::Blend,
            gltf::material::AlphaMode::Mask => {
                let cutoff = m.alpha_cutoff().unwrap_or(0.5);
                if !cutoff.is_finite() || cutoff < 0.0 {
                    return Err(self.element_error(
                        element,
                        format!("alphaCutoff {cutoff} is not a finite number ≥ 0"),
                    ));
                }
                AlphaMode::Mask(cutoff)
            }
        };
        if let Some(t) = m.normal_texture() {
            // The gltf crate has no typed transform for normal textures: read its JSON.
            let uv = texture_transform(t.extension_value("KHR_texture_transform"), t.tex_coord());
            ext.normal_texture =
                self.texture_ref(&element, "normalTexture", &t.texture(), uv, false)?;
            let s = t.scale();
            ext.normal_scale = if s.is_finite() { s } else { 1.0 };
        }
        if m.occlusion_texture().is_some() {
            self.report.note(format!(
                "occlusionTexture ({element}) not used: the path tracer computes occlusion"
            ));
        }
        if let Some(t) = m.emissive_texture() {
            ext.emissive_texture =
                self.texture_ref(&element, "emissiveTexture", &t.texture(), info_uv(&t), true)?;
            if ext.emissive_texture.is_none() {
                // The factor alone would turn the whole mesh into a lamp; what the texture
                // leaves dark is the usual case (exporters write factor 1 beside the texture).
                self.report.warn(format!(
                    "{element}: its emissive texture cannot be used; the material does not emit"
                ));
            }
        }
        ext.metallic_roughness_texture = self.info_ref(
            &element,
            "metallicRoughnessTexture",
            pbr.metallic_roughness_texture(),
            false,
        )?;
        let base_color_texture = match pbr.base_color_texture() {
            Some(info) => {
                let r = self.texture_ref(
                    &element,
                    "baseColorTexture",
                    &info.texture(),
                    info_uv(&info),
                    true,
                )?;
                if let Some(r) = r {
                    ext.base_color_uv = r.uv;
                }
                r.map(|r| r.texture)
            }
            None => None,
        };
        // KHR_materials_specular: the factor scales the dielectric Fresnel term, the colour
        // tints its F0 (the tracer's BSDF); its textures multiply them (A and RGB).
        let mut specular = 1.0;
        if let Some(sp) = m.specular() {
            let f = sp.specular_factor();
            specular = if f.is_finite() {
                f.clamp(0.0, 1.0)
            } else {
                1.0
            };
            let c = Vec3::from_array(sp.specular_color_factor());
            ext.specular_color = if c.is_finite() {
                c.clamp(Vec3::ZERO, Vec3::splat(10.0))
            } else {
                Vec3::ONE
            };
            ext.specular_texture =
                self.info_ref(&element, "specularTexture", sp.specular_texture(), false)?;
            ext.specular_color_texture = self.info_ref(
                &element,
                "specularColorTexture",
                sp.specular_color_texture(),
                true,
            )?;
        }
        let emission = if m.emissive_texture().is_some() && ext.emissive_texture.is_none() {
            Vec3::ZERO
        } else {
            emissive * strength
        };
        Ok((
            Material {
                name,
                base_color,
                base_color_texture,
                metallic,
                roughness,
                specular,
                emission,
                double_sided: m.double_sided(),
            },
            ext,
        ))
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
                (s.bad_colors, "non-finite vertex colours replaced by white"),
            ] {
                if n > 0 {
                    self.report.warn(format!("{l}: {n} {what}"));
                }
            }
        }
        if self
            .material_ext
            .iter()
            .any(|e| *e != MaterialExt::default())
        {
            self.scene.material_ext = self.material_ext;
        }
        self.scene.unsupported = self.report.unsupported;
        self.scene.warnings = self.report.warnings;
        self.scene.notes = self.report.notes;
        self.scene.environment = Environment::default();
        self.scene
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
fn uv_tangents(p: [Vec3; 3], uv: [Vec2; 3], n: [Vec3; 3]) -> [Vec4; 3] {
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
mod tests;
