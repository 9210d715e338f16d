//! Motion reuse (DESIGN.md §11): with `EyeMove::Reuse` a moving eye carries the accumulation
//! over instead of restarting it — on the CPU twin, the GPU kernel and a GPU frame in bands
//! (lavapipe in CI). The ROI and its DGI stay; the carried picture is as close to the new
//! eye's reference as a fresh render with as many samples (a statistical test: no ghost, no
//! smear).

use glam::DVec3;
use raygun::display::DisplayModel;
use raygun::frame::{EyeFollow, EyeMove, GuideConfig, Render, Renderer};
use raygun::gpu::{Backend, GpuContext};
use raygun::roi::cone::Cone;
use raygun::roi::dgi::Roi;
use raygun::scene::Scene;
use raygun::trace::accum::Accumulation;
use raygun::trace::camera::RenderCamera;
use raygun::trace::path::TraceSettings;
use raygun::trace::wall::{WallCamera, WorldFromRoom};
use raygun::tracking::head::DEFAULT_EYE_THRESHOLD_M;

const SIZE: [u32; 2] = [124, 50];

fn settings(scene: &Scene, seed: u32) -> TraceSettings {
    TraceSettings {
        width: SIZE[0],
        height: SIZE[1],
        seed,
        max_depth: 2,
        camera: RenderCamera::choose(scene, None, SIZE[0], SIZE[1]).unwrap(),
    }
}

fn wall(model: &DisplayModel, s: &TraceSettings, eye: DVec3) -> WallCamera {
    let c = &s.camera;
    WallCamera::new(
        model,
        SIZE,
        eye,
        &WorldFromRoom::Auto,
        (c.position.as_dvec3(), c.forward.as_dvec3(), c.up.as_dvec3()),
    )
    .unwrap()
}

fn roi() -> Roi {
    Roi::Cone(
        Cone::from_pose(
            DVec3::new(0.0, 0.0, 1.0),
            DVec3::NEG_Z,
            DVec3::Y,
            20.0,
            20.0,
        )
        .unwrap(),
    )
}

/// A guided render moves its eye 2 cm with reuse: most shown pixels keep their samples, the
/// iteration count goes on, the ROI and its DGI stay, and a move back carries again.
fn check(backend: &Backend, name: &str) {
    let model = DisplayModel::open("hornet").unwrap().0;
    let scene = Scene::builtin("cornell").unwrap();
    let s = settings(&scene, 3);
    let start = DVec3::new(0.0, 0.0, 1.0);
    let config = GuideConfig {
        p_min: 0.1,
        ..GuideConfig::default()
    };
    let w0 = wall(&model, &s, start);
    let mut r = Renderer::guided_wall(backend, &scene, s, &model, config, Some(w0)).unwrap();
    r.set_on_eye_move(EyeMove::Reuse);
    r.set_roi(Some(roi())).unwrap();
    r.iterate(6).unwrap();
    let dgi = r.dgi().unwrap();
    let before = r.accumulation().unwrap();
    let moved = start + DVec3::new(0.02, 0.0, 0.0);
    let EyeFollow::Reused(stats) = r.follow_eye(moved, DEFAULT_EYE_THRESHOLD_M).unwrap() else {
        panic!("{name}: a 2 cm move with reuse did not reuse");
    };
    assert!(stats.share() > 0.8, "{name}: {stats:?}");
    assert_eq!(r.iteration(), 6, "{name}: the iterations go on");
    assert_eq!(r.wall().unwrap().eye_room, moved, "{name}");
    assert_eq!(r.dgi().unwrap(), dgi, "{name}: the DGI survives");
    assert_eq!(r.roi(), Some(&roi()), "{name}");
    let after = r.accumulation().unwrap();
    let carried = after.count.iter().filter(|&&c| c > 0).count() as u64;
    let total = |a: &Accumulation| a.count.iter().map(|&c| u64::from(c)).sum::<u64>();
    assert!(carried <= stats.carried, "{name}");
    assert!(
        total(&after) * 10 >= total(&before) * 7,
        "{name}: most samples carried"
    );
    r.iterate(2).unwrap();
    let EyeFollow::Reused(back) = r.follow_eye(start, DEFAULT_EYE_THRESHOLD_M).unwrap() else {
        panic!("{name}: the move back did not reuse");
    };
    assert!(back.share() > 0.8, "{name}: {back:?}");
    assert_eq!(r.last_reuse(), Some(back));
}

#[test]
fn a_moving_eye_carries_the_accumulation_on_the_cpu_twin() {
    check(&Backend::Cpu, "CPU");
}

#[test]
fn a_moving_eye_carries_the_accumulation_on_the_gpu() {
    check(&Backend::Gpu(Box::new(GpuContext::for_tests())), "GPU");
}

/// A frame in bands (a device whose storage bindings hold a third of the frame): the move is
/// carried through the host and equals the one-band GPU's, count for count.
#[test]
fn a_frame_in_bands_carries_what_one_band_carries() {
    let model = DisplayModel::open("hornet").unwrap().0;
    let scene = Scene::builtin("cornell").unwrap();
    let s = settings(&scene, 5);
    let start = DVec3::new(0.0, 0.0, 1.0);
    let moved = start + DVec3::new(0.0, 0.015, 0.0);
    let binding = u64::from(SIZE[0]) * u64::from(SIZE[1]) * 16 / 3;
    let small = GpuContext::with_max_binding(binding).unwrap();
    let run = |backend: &Backend| {
        let w0 = wall(&model, &s, start);
        let mut r = Renderer::full_wall(backend, &scene, s, w0).unwrap();
        r.set_on_eye_move(EyeMove::Reuse);
        r.iterate(3).unwrap();
        let EyeFollow::Reused(stats) = r.follow_eye(moved, DEFAULT_EYE_THRESHOLD_M).unwrap() else {
            panic!("no reuse");
        };
        (r.accumulation().unwrap(), stats, r.gpu_bands())
    };
    let (banded, bs, nb) = run(&Backend::Gpu(Box::new(small)));
    let (one, os, n1) = run(&Backend::Gpu(Box::new(GpuContext::for_tests())));
    assert!(nb.unwrap() > 1 && n1 == Some(1), "{nb:?} {n1:?}");
    assert!(
        bs.carried.abs_diff(os.carried) * 100 <= os.carried,
        "{bs:?} vs {os:?}"
    );
    let same = (0..banded.count.len())
        .filter(|&p| banded.count[p] == one.count[p])
        .count();
    assert!(same * 100 >= banded.count.len() * 99, "{same}");
}

/// The mean of `acc` against `reference` over `pixels`: relative MSE (Rec. 709 luminance,
/// 0.01 added to the reference's square).
fn rel_mse(acc: &Accumulation, reference: &Accumulation, pixels: &[usize]) -> f64 {
    let lum = |a: &Accumulation, p: usize| {
        let m = a.mean(p);
        f64::from(0.2126 * m.x + 0.7152 * m.y + 0.0722 * m.z)
    };
    pixels
        .iter()
        .map(|&p| {
            let (x, y) = (lum(acc, p), lum(reference, p));
            (x - y).powi(2) / (y * y + 0.01)
        })
        .sum::<f64>()
        / pixels.len() as f64
}

/// 32 samples a pixel at one eye, then a 3 cm move with reuse: over the carried pixels, the
/// carried picture is no further from a 512-sample reference at the new eye than a fresh
/// 32-sample render there (×1.25 with the seeds' spread); over every shown pixel, one more
/// iteration after the move leaves the reused picture nearer the reference than the
/// restarted one by far.
#[test]
fn the_carried_picture_is_as_good_as_a_fresh_render_with_as_many_samples() {
    let model = DisplayModel::open("hornet").unwrap().0;
    let scene = Scene::builtin("cornell").unwrap();
    let start = DVec3::new(0.0, 0.0, 1.0);
    let moved = start + DVec3::new(0.03, 0.0, 0.0);
    let cpu = Backend::Cpu;
    let full = |seed: u32, eye: DVec3, n: u32| {
        let s = settings(&scene, seed);
        let mut r = Renderer::full_wall(&cpu, &scene, s, wall(&model, &s, eye)).unwrap();
        r.iterate(n).unwrap();
        r
    };
    let reference = full(100, moved, 512).accumulation().unwrap();
    let fresh = full(7, moved, 32).accumulation().unwrap();
    let mut reused = full(9, start, 32);
    reused.set_on_eye_move(EyeMove::Reuse);
    let EyeFollow::Reused(stats) = reused.follow_eye(moved, DEFAULT_EYE_THRESHOLD_M).unwrap()
    else {
        panic!("no reuse");
    };
    let carried_acc = reused.accumulation().unwrap();
    let carried: Vec<usize> = (0..carried_acc.count.len())
        .filter(|&p| carried_acc.count[p] > 0)
        .collect();
    assert_eq!(carried.len() as u64, stats.carried);
    let (e_carried, e_fresh) = (
        rel_mse(&carried_acc, &reference, &carried),
        rel_mse(&fresh, &reference, &carried),
    );
    assert!(
        e_carried <= 1.25 * e_fresh,
        "carried relMSE {e_carried:.5} vs fresh {e_fresh:.5} at 32 samples"
    );
    let shown: Vec<usize> = (0..reference.count.len())
        .filter(|&p| reference.count[p] > 0)
        .collect();
    reused.iterate(1).unwrap();
    let mut restarted = full(9, start, 32);
    restarted
        .follow_eye(moved, DEFAULT_EYE_THRESHOLD_M)
        .unwrap();
    restarted.iterate(1).unwrap();
    let (e_reuse, e_restart) = (
        rel_mse(&reused.accumulation().unwrap(), &reference, &shown),
        rel_mse(&restarted.accumulation().unwrap(), &reference, &shown),
    );
    assert!(
        e_reuse * 4.0 < e_restart,
        "one iteration after the move: reuse {e_reuse:.5}, restart {e_restart:.5}"
    );
}
