//! `raygun scene …`: write the generated paper scenes as GLB, and summarise any scene.

use std::path::PathBuf;

use serde_json::{Value, json};

use crate::scene::generate::{self, CityParams, Generated};
use crate::scene::{AlphaMode, Environment, Material, MaterialExt, Scene, UriAccess};

#[derive(Clone, Debug, clap::Subcommand)]
pub enum SceneCommand {
    /// Write the Cornell box with an open front (lit by the environment only, as in the paper).
    Cornell(GenerateArgs),
    /// Write the Cornell box with its ceiling light (emission 17, 12, 4), front still open.
    CornellLight(GenerateArgs),
    /// Write the procedural city (about 350 000 triangles at the default size).
    City(CityArgs),
    /// Summarise a scene: counts, bounds, cameras, the material features understood (by
    /// material), unsupported features and warnings, and the one-time work a render of it
    /// starts with (`timing`: `load_seconds` to read and decode it, `build_seconds` to pack it
    /// and build its BVH).
    Info(InfoArgs),
}

#[derive(Clone, Debug, clap::Args)]
pub struct GenerateArgs {
    /// Output file (.glb).
    #[arg(long, value_name = "FILE.glb")]
    pub out: PathBuf,
}

#[derive(Clone, Debug, clap::Args)]
pub struct CityArgs {
    /// Blocks along each side of the square city (4 gives about 3 900 triangles, 41 about 344 000).
    #[arg(long, default_value_t = CityParams::PAPER.blocks)]
    pub blocks: u32,
    /// Seed of the procedural layout.
    #[arg(long, default_value_t = CityParams::PAPER.seed)]
    pub seed: u32,
    /// Output file (.glb).
    #[arg(long, value_name = "FILE.glb")]
    pub out: PathBuf,
}

#[derive(Clone, Debug, clap::Args)]
pub struct InfoArgs {
    /// A .gltf / .glb file, or builtin:NAME (cornell, cornell-light, city, city-small).
    #[arg(value_name = "SCENE")]
    pub scene: String,
    #[command(flatten)]
    pub access: crate::cli::scene::SceneAccess,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
}

/// Runs a `scene` command; returns what to print on stdout.
pub fn run(cmd: &SceneCommand) -> anyhow::Result<String> {
    let (generated, out) = match cmd {
        SceneCommand::Cornell(a) => (generate::cornell(false), &a.out),
        SceneCommand::CornellLight(a) => (generate::cornell(true), &a.out),
        SceneCommand::City(a) => (
            generate::city(CityParams {
                blocks: a.blocks,
                seed: a.seed,
            }),
            &a.out,
        ),
        SceneCommand::Info(a) => {
            let t0 = std::time::Instant::now();
            let scene = Scene::open_with(&a.scene, a.access.uris())?;
            let load_seconds = t0.elapsed().as_secs_f64();
            let t0 = std::time::Instant::now();
            let packed = crate::trace::pack::PackedScene::new(&scene);
            let build_seconds = t0.elapsed().as_secs_f64();
            drop(packed);
            let mut summary = info(&a.scene, &scene);
            summary["timing"] = json!({
                "load_seconds": load_seconds,
                "build_seconds": build_seconds,
            });
            return Ok(if a.json {
                summary.to_string()
            } else {
                info_text(&summary)
            });
        }
    };
    if !out
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("glb"))
    {
        anyhow::bail!(
            "{}: the generated scenes are binary glTF: name the file .glb",
            out.display()
        );
    }
    crate::output::check_writable(out)?;
    let Generated { glb, triangles } = generated?;
    crate::output::write_bytes(out, &glb)?;
    Ok(format!(
        "{}: {}, {} bytes",
        out.display(),
        crate::messages::count(triangles, "triangle"),
        glb.len()
    ))
}

/// The summary `scene info --json` prints.
#[must_use]
pub fn info(name: &str, scene: &Scene) -> Value {
    let v3 = |v: glam::Vec3| json!([v.x, v.y, v.z]);
    json!({
        "scene": name,
        "triangles": scene.triangles.len(),
        "emissive_triangles": scene.emissive_triangle_count(),
        "materials": scene.materials.len(),
        "textures": scene.textures.len(),
        "cameras": scene.cameras.iter().map(|c| json!({
            "name": c.name,
            "position": v3(c.position),
            "forward": v3(c.forward),
            "up": v3(c.up),
            "yfov_deg": c.yfov.to_degrees(),
        })).collect::<Vec<_>>(),
        "orthographic_cameras": scene.orthographic_cameras.iter().map(|c| json!({
            "name": c.name,
            "position": v3(c.position),
            "forward": v3(c.forward),
            "ymag": c.ymag,
        })).collect::<Vec<_>>(),
        "lights": scene.lights.iter().map(|l| json!({
            "name": l.name,
            "kind": format!("{:?}", l.kind),
            "position": v3(l.position),
            "intensity": v3(l.intensity),
        })).collect::<Vec<_>>(),
        "bounds": scene.bounds().map(|b| json!({ "min": v3(b.min), "max": v3(b.max) })),
        "material_features": material_features(scene)
            .into_iter()
            .map(|(feature, names)| (feature.to_string(), json!(names)))
            .collect::<serde_json::Map<_, _>>(),
        "unsupported": scene.unsupported,
        "warnings": scene.warnings,
        "notes": scene.notes,
    })
}

/// The material features the loader understood, each with the names of the materials that use
/// it (what a user checks an export against): only those some material uses.
fn material_features(scene: &Scene) -> Vec<(&'static str, Vec<&str>)> {
    type Uses = fn(&Material, &MaterialExt) -> bool;
    let features: [(&str, Uses); 15] = [
        ("emission", |m, _| m.emission != glam::Vec3::ZERO),
        ("base colour texture", |m, _| m.base_color_texture.is_some()),
        ("metallic-roughness texture", |_, e| {
            e.metallic_roughness_texture.is_some()
        }),
        ("normal map", |_, e| e.normal_texture.is_some()),
        ("alpha mask", |_, e| matches!(e.alpha, AlphaMode::Mask(_))),
        ("alpha blend", |_, e| e.alpha == AlphaMode::Blend),
        ("specular", |m, e| {
            m.specular != 1.0
                || e.specular_color != glam::Vec3::ONE
                || e.specular_texture.is_some()
                || e.specular_color_texture.is_some()
        }),
        ("ior", |_, e| e.ior != 1.5),
        ("transmission", |_, e| e.transmission > 0.0),
        ("volume", |_, e| e.absorption != glam::Vec3::ZERO),
        ("clearcoat", |_, e| e.clearcoat > 0.0),
        ("sheen", |_, e| e.sheen_color != glam::Vec3::ZERO),
        ("anisotropy", |_, e| e.anisotropy_strength > 0.0),
        ("dispersion", |_, e| e.dispersion > 0.0),
        ("diffuse transmission", |_, e| e.diffuse_transmission > 0.0),
    ];
    features
        .into_iter()
        .filter_map(|(feature, uses)| {
            let names: Vec<&str> = (0u32..)
                .zip(&scene.materials)
                .filter(|&(i, m)| uses(m, &scene.material_ext(i)))
                .map(|(_, m)| m.name.as_str())
                .collect();
            (!names.is_empty()).then_some((feature, names))
        })
        .collect()
}

/// A vector of the summary as the text prints it: each number as the `f32` it was (`-1.2`,
/// not the `f64` widening's `-1.2000000476837158`).
fn short(v: &Value) -> String {
    match v.as_array() {
        Some(xs) => {
            let xs: Vec<String> = xs
                .iter()
                .map(|x| {
                    x.as_f64()
                        .map_or_else(|| x.to_string(), |x| (x as f32).to_string())
                })
                .collect();
            format!("[{}]", xs.join(", "))
        }
        None => v.to_string(),
    }
}

fn info_text(s: &Value) -> String {
    let n = |key: &str| s[key].as_u64().unwrap_or(0) as usize;
    let mut out = format!(
        "{}: {} ({} emissive), {}, {}\n",
        s["scene"].as_str().unwrap_or(""),
        crate::messages::count(n("triangles"), "triangle"),
        n("emissive_triangles"),
        crate::messages::count(n("materials"), "material"),
        crate::messages::count(n("textures"), "texture"),
    );
    match s["bounds"].as_object() {
        Some(b) => out += &format!("bounds: {} .. {}\n", short(&b["min"]), short(&b["max"])),
        None => out += "bounds: none (no triangles)\n",
    }
    for c in s["cameras"].as_array().into_iter().flatten() {
        out += &format!(
            "camera '{}': position {}, forward {}, yfov {:.2}°\n",
            c["name"].as_str().unwrap_or(""),
            short(&c["position"]),
            short(&c["forward"]),
            c["yfov_deg"].as_f64().unwrap_or(f64::NAN)
        );
    }
    for c in s["orthographic_cameras"].as_array().into_iter().flatten() {
        out += &format!(
            "camera '{}' (orthographic): position {}, forward {}, ymag {}\n",
            c["name"].as_str().unwrap_or(""),
            short(&c["position"]),
            short(&c["forward"]),
            c["ymag"]
        );
    }
    let none = |key: &str| s[key].as_array().is_none_or(Vec::is_empty);
    if none("cameras") && none("orthographic_cameras") {
        out += "cameras: none (renders frame the bounds from +Z; --look-from and --look-at \
                choose a viewpoint)\n";
    }
    for l in s["lights"].as_array().into_iter().flatten() {
        out += &format!(
            "light '{}': {} at {}, intensity {}\n",
            l["name"].as_str().unwrap_or(""),
            l["kind"].as_str().unwrap_or(""),
            short(&l["position"]),
            short(&l["intensity"])
        );
    }
    for (feature, names) in s["material_features"].as_object().into_iter().flatten() {
        let names: Vec<String> = names
            .as_array()
            .into_iter()
            .flatten()
            .map(|n| format!("'{}'", n.as_str().unwrap_or("")))
            .collect();
        let shown = match names.len() {
            0..=4 => names.join(", "),
            n => format!("{} and {} more", names[..4].join(", "), n - 4),
        };
        out += &format!("{feature}: {shown}\n");
    }
    for (key, title) in [
        ("unsupported", "unsupported"),
        ("warnings", "warning"),
        ("notes", "note"),
    ] {
        for item in s[key].as_array().into_iter().flatten() {
            out += &format!("{title}: {}\n", item.as_str().unwrap_or(""));
        }
    }
    if let Some(t) = s["timing"].as_object() {
        let secs = |key: &str| t[key].as_f64().unwrap_or(f64::NAN);
        out += &format!(
            "one-time work: scene load {:.3} s, BVH build {:.3} s\n",
            secs("load_seconds"),
            secs("build_seconds")
        );
    }
    out.trim_end().to_string()
}

/// `--trust-scene`: which files a scene's URIs may name.
#[derive(Clone, Copy, Debug, Default, clap::Args)]
pub struct SceneAccess {
    /// Let the scene's buffer and image URIs name files outside the scene's own folder
    /// (absolute paths, `file:` URIs, `../` out of it). Without it a scene reads only files in
    /// its folder and below: for scenes you trust.
    #[arg(long)]
    pub trust_scene: bool,
}

impl SceneAccess {
    #[must_use]
    pub fn uris(self) -> UriAccess {
        if self.trust_scene {
            UriAccess::Anywhere
        } else {
            UriAccess::Confined
        }
    }
}

/// Loads the scene named by `--scene`, with `--env` applied and its unsupported features
/// reported on standard error.
pub fn load_scene(scene: &str, env: Option<&str>, access: SceneAccess) -> anyhow::Result<Scene> {
    Ok(load_scene_timed(scene, env, access)?.0)
}

/// [`load_scene`] and the seconds it took (reading and decoding the file or generating the
/// built-in, its textures and the environment image): one-time work, reported apart from
/// the sampling time.
pub fn load_scene_timed(
    scene: &str,
    env: Option<&str>,
    access: SceneAccess,
) -> anyhow::Result<(Scene, f64)> {
    let t0 = std::time::Instant::now();
    let mut s = Scene::open_with(scene, access.uris())?;
    if let Some(env) = env {
        s.environment = Environment::parse(env)?;
    }
    let seconds = t0.elapsed().as_secs_f64();
    for u in &s.unsupported {
        eprintln!("raygun: {scene}: not supported, ignored: {u}");
    }
    Ok((s, seconds))
}

/// Loads each of `scenes` with [`load_scene`], named by its argument without `builtin:`.
pub fn load_scenes(
    scenes: &[String],
    env: Option<&str>,
    access: SceneAccess,
) -> anyhow::Result<Vec<(String, Scene)>> {
    scenes
        .iter()
        .map(|s| {
            Ok((
                s.trim_start_matches("builtin:").to_string(),
                load_scene(s, env, access)?,
            ))
        })
        .collect()
}
