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

use glam::{Mat4, Vec3};
use gltf::json::validation::Checked;

use super::report::{Report, SceneError, label};
use super::resources::{Resources, UriAccess, check_glb_header, load_buffers};
use super::{
    Camera, Environment, LightKind, MaterialExt, OrthographicCamera, PunctualLight, Scene,
};

mod material;
mod mesh;

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

/// `v` scaled to unit length, or `None` for a zero or non-finite vector. Dividing by the largest
/// component first keeps tiny vectors exact: glam's `try_normalize` squares them into
/// subnormals and returns vectors up to a few per cent off unit length (found by fuzzing).
fn unit(v: Vec3) -> Option<Vec3> {
    let m = v.abs().max_element();
    (m > 0.0 && m.is_finite()).then(|| (v / m).normalize())
}

#[cfg(test)]
mod tests;
