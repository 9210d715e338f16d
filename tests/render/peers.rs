//! raygun against Mitsuba 3, the peer renderer: the references in `tests/data/peers/` (made by
//! `tools/peers/make_refs.py`; its README says how, with which variant and material mapping)
//! are Mitsuba's renders of raygun's test scenes, K = 8 independent renders each, with the mean
//! and standard error of every region (the whole image, a 4 × 4 grid, named boxes). Each
//! comparable reference is rendered here by the CPU twin and by the GPU kernel (lavapipe in
//! CI), K independent seeds each, and every region and channel must agree:
//!
//! |raygun − ref| ≤ σ·√(se_ref² + se_raygun²) + rel·|ref|,
//!
//! with σ and rel from the reference (σ = 4; rel = 2 % for the image, 3 % per region): the
//! Monte-Carlo error of both plus a stated model tolerance. CI needs no Mitsuba.

use std::path::Path;

use glam::Vec3;
use raygun::frame::Renderer;
use raygun::gpu::{Backend, GpuContext};
use raygun::scene::{Environment, Scene};
use raygun::trace::camera::RenderCamera;
use raygun::trace::path::TraceSettings;
use serde_json::Value;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// Independent raygun renders per reference: the SE of a region comes from their spread.
const RENDERS: u32 = 4;

struct Reference {
    name: String,
    json: Value,
}

fn comparable_references() -> Vec<Reference> {
    let dir = Path::new(ROOT).join("tests/data/peers");
    let mut v: Vec<Reference> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| {
            let p = e.unwrap().path();
            (p.extension()? == "json").then_some(p)
        })
        .map(|p| {
            let json: Value = serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
            Reference {
                name: json["name"].as_str().unwrap().to_owned(),
                json,
            }
        })
        .filter(|r| r.json["comparable"].as_bool() == Some(true))
        .collect();
    v.sort_by(|a, b| a.name.cmp(&b.name));
    v
}

/// Per region: the mean RGB over `renders` independent renders and its standard error.
fn raygun_regions(backend: &Backend, r: &Reference, spp: u32) -> Vec<([f64; 3], [f64; 3])> {
    raygun_regions_edited(backend, r, spp, |_| {})
}

/// [`raygun_regions`] of the reference's scene changed by `edit` first.
fn raygun_regions_edited(
    backend: &Backend,
    r: &Reference,
    spp: u32,
    edit: impl Fn(&mut Scene),
) -> Vec<([f64; 3], [f64; 3])> {
    let j = &r.json;
    let mut scene = Scene::open(
        Path::new(ROOT)
            .join(j["scene"].as_str().unwrap())
            .to_str()
            .unwrap(),
    )
    .unwrap();
    let env = j["env"]["raygun"].as_str().unwrap();
    let env = if env.contains(',') {
        env.to_owned()
    } else {
        Path::new(ROOT).join(env).display().to_string()
    };
    scene.environment = Environment::parse(&env).unwrap();
    edit(&mut scene);
    let (w, h) = (
        j["size"][0].as_u64().unwrap() as u32,
        j["size"][1].as_u64().unwrap() as u32,
    );
    let camera = RenderCamera::choose(&scene, j["camera"].as_str(), w, h).unwrap();
    let max_depth = j["max_depth"]["raygun"].as_u64().unwrap() as u32;
    let regions = j["regions"].as_array().unwrap();
    let mut per_render: Vec<Vec<[f64; 3]>> = Vec::new();
    for seed in 1..=RENDERS {
        let settings = TraceSettings {
            width: w,
            height: h,
            seed,
            max_depth,
            camera,
        };
        let mut renderer = Renderer::full(backend, &scene, settings).unwrap();
        renderer.iterate(spp).unwrap();
        let image = renderer.accumulation().unwrap().mean_image();
        per_render.push(
            regions
                .iter()
                .map(|g| {
                    let [x0, x1, y0, y1] =
                        ["x0", "x1", "y0", "y1"].map(|k| g[k].as_u64().unwrap() as u32);
                    let mut sum = [0f64; 3];
                    for y in y0..y1 {
                        for x in x0..x1 {
                            let c = image[(y * w + x) as usize];
                            for (k, s) in sum.iter_mut().enumerate() {
                                *s += f64::from(c[k]);
                            }
                        }
                    }
                    let n = f64::from((x1 - x0) * (y1 - y0));
                    sum.map(|s| s / n)
                })
                .collect(),
        );
    }
    let k = f64::from(RENDERS);
    (0..regions.len())
        .map(|g| {
            let mut mean = [0f64; 3];
            let mut se = [0f64; 3];
            for c in 0..3 {
                let v: Vec<f64> = per_render.iter().map(|r| r[g][c]).collect();
                let m = v.iter().sum::<f64>() / k;
                let var = v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (k - 1.0);
                mean[c] = m;
                se[c] = (var / k).sqrt();
            }
            (mean, se)
        })
        .collect()
}

/// Every region and channel within the reference's tolerance; the failures listed otherwise.
fn compare(r: &Reference, got: &[([f64; 3], [f64; 3])], label: &str) -> Result<f64, String> {
    let tol = &r.json["tolerance"];
    let sigma = tol["sigma"].as_f64().unwrap();
    let (image_rel, region_rel) = (
        tol["image_rel"].as_f64().unwrap(),
        tol["region_rel"].as_f64().unwrap(),
    );
    let mut failures = Vec::new();
    let mut image_ratio = f64::NAN;
    for (g, (mean, se)) in r.json["regions"].as_array().unwrap().iter().zip(got) {
        let name = g["name"].as_str().unwrap();
        let rel = if name == "image" {
            image_rel
        } else {
            region_rel
        };
        for c in 0..3 {
            let (m_ref, se_ref) = (g["mean"][c].as_f64().unwrap(), g["se"][c].as_f64().unwrap());
            let bound = sigma * (se_ref * se_ref + se[c] * se[c]).sqrt() + rel * m_ref.abs();
            if (mean[c] - m_ref).abs() > bound {
                failures.push(format!(
                    "{name} channel {c}: raygun {:.5} ± {:.5}, Mitsuba {m_ref:.5} ± {se_ref:.5} ({:+.2} %, bound {:.5})",
                    mean[c],
                    se[c],
                    100.0 * (mean[c] / m_ref - 1.0),
                    bound
                ));
            }
        }
        if name == "image" {
            let lum = |v: [f64; 3]| 0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2];
            let m_ref: Vec<f64> = (0..3).map(|c| g["mean"][c].as_f64().unwrap()).collect();
            image_ratio = lum(*mean) / lum([m_ref[0], m_ref[1], m_ref[2]]);
        }
    }
    if failures.is_empty() {
        Ok(image_ratio)
    } else {
        Err(format!(
            "{label} vs Mitsuba, {}:\n{}",
            r.name,
            failures.join("\n")
        ))
    }
}

#[test]
fn the_cpu_twin_matches_mitsuba_on_every_comparable_reference() {
    let refs = comparable_references();
    let names: Vec<&str> = refs.iter().map(|r| r.name.as_str()).collect();
    // The done-when scenes of the peer comparison are among them.
    for must in ["cornell-light-lambert", "cornell-lambert-env"] {
        assert!(names.contains(&must), "{must} missing from {names:?}");
    }
    let mut failures = Vec::new();
    for r in &refs {
        match compare(r, &raygun_regions(&Backend::Cpu, r, 64), "CPU twin") {
            Ok(ratio) => eprintln!("{}: CPU twin image / Mitsuba = {ratio:.4}", r.name),
            Err(e) => failures.push(e),
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}

#[test]
fn the_gpu_kernel_matches_mitsuba_on_the_cornell_boxes() {
    let backend = Backend::Gpu(Box::new(GpuContext::for_tests()));
    let mut failures = Vec::new();
    for r in comparable_references()
        .iter()
        .filter(|r| r.name.starts_with("cornell"))
    {
        match compare(r, &raygun_regions(&backend, r, 32), "GPU") {
            Ok(ratio) => eprintln!("{}: GPU image / Mitsuba = {ratio:.4}", r.name),
            Err(e) => failures.push(e),
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n\n"));
}

/// The comparison has power: the old two-sided light (the back face emitting into the gap
/// above it) is told apart from Mitsuba's one-sided one.
#[test]
fn a_light_that_emits_from_both_faces_fails_against_the_one_sided_reference() {
    let refs = comparable_references();
    let one_sided = refs
        .iter()
        .find(|r| r.name == "cornell-light-lambert")
        .unwrap();
    let two_sided = refs
        .iter()
        .find(|r| r.name == "cornell-light-lambert-twosided")
        .unwrap();
    // raygun on the two-sided scene, judged against the one-sided reference.
    let got = raygun_regions(&Backend::Cpu, two_sided, 64);
    assert!(compare(one_sided, &got, "two-sided raygun").is_err());
}

/// The comparison has power for absorbing media too: the coloured glass spheres rendered clear
/// (their KHR_materials_volume dropped) are told apart from Mitsuba's absorbing ones.
#[test]
fn clear_glass_fails_against_the_coloured_glass_reference() {
    let refs = comparable_references();
    let coloured = refs.iter().find(|r| r.name == "coloured-glass").unwrap();
    let got = raygun_regions_edited(&Backend::Cpu, coloured, 64, |scene| {
        assert!(
            scene
                .material_ext
                .iter()
                .any(|e| e.absorption != Vec3::ZERO)
        );
        for e in &mut scene.material_ext {
            e.absorption = Vec3::ZERO;
        }
    });
    assert!(compare(coloured, &got, "clear glass").is_err());
}
