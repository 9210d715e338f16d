//! The ROI's statistics of a renderer (`Renderer::roi_stats`): on a GPU renderer of one band
//! (lavapipe in CI) they are measured where the accumulation lives and must be what the CPU
//! twin (`RoiStats::measure`) measures on the same accumulation read back — totals exactly,
//! medians within `SE_TOLERANCE` — for guided and wall-camera renders, across frames and a
//! moved ROI; the stop conditions' progress is the same measurement (every pixel's without an
//! ROI). Without an ROI the statistics measure nothing; the CPU twin and a banded frame measure
//! the read-back accumulation.

use crate::roi_stats_support as roi_stats;

use glam::DVec3;
use raygun::display::DisplayModel;
use raygun::frame::stop::RoiProgress;
use raygun::frame::{GuideConfig, Render, Renderer};
use raygun::gpu::{Backend, GpuContext};
use raygun::output::gpu::SE_TOLERANCE;
use raygun::output::stats::RoiStats;
use raygun::roi::cone::Cone;
use raygun::roi::dgi::Roi;
use raygun::scene::Scene;
use raygun::trace::camera::RenderCamera;
use raygun::trace::path::TraceSettings;
use raygun::trace::wall::{WallCamera, WorldFromRoom};

use roi_stats::same;

fn settings(scene: &Scene, [w, h]: [u32; 2]) -> TraceSettings {
    TraceSettings {
        width: w,
        height: h,
        seed: 5,
        max_depth: 3,
        camera: RenderCamera::choose(scene, None, w, h).unwrap(),
    }
}

fn cone(x: f64, degrees: f64) -> Roi {
    Roi::Cone(
        Cone::from_pose(
            DVec3::new(x, 0.0, 1.0),
            DVec3::NEG_Z,
            DVec3::Y,
            degrees,
            degrees,
        )
        .unwrap(),
    )
}

const P_MIN: f32 = 0.5;

fn config() -> GuideConfig {
    GuideConfig {
        p_min: P_MIN,
        ..GuideConfig::default()
    }
}

fn gpu() -> Backend {
    Backend::Gpu(Box::new(GpuContext::for_tests()))
}

/// The renderer's statistics against the CPU twin's on its read-back accumulation and DGI.
fn check(r: &mut Renderer, shown: impl Fn(usize) -> bool, what: &str) -> RoiStats {
    let measured = r.roi_stats().unwrap();
    let cpu = RoiStats::measure(&r.accumulation().unwrap(), &r.dgi().unwrap(), P_MIN, shown);
    same(what, &cpu, &measured);
    assert_eq!(r.roi_progress().unwrap(), measured.progress, "{what}");
    measured
}

#[test]
fn a_guided_gpu_render_measures_its_statistics_in_place() {
    let backend = gpu();
    let model = DisplayModel::open("hornet").unwrap().0;
    let scene = Scene::builtin("cornell").unwrap();
    let mut r = Renderer::guided(
        &backend,
        &scene,
        settings(&scene, [96, 40]),
        &model,
        config(),
    )
    .unwrap();
    assert!(r.measures_stats_on_gpu());
    // No ROI yet: the window's statistics measure nothing, while the progress `render
    // --until` judges is every pixel's (the DGI is 0 everywhere), measured on the GPU too.
    r.iterate(2).unwrap();
    assert_eq!(r.roi_stats().unwrap(), RoiStats::default());
    let whole = RoiProgress::measure(&r.accumulation().unwrap(), &r.dgi().unwrap()).unwrap();
    let measured = r.roi_progress().unwrap().unwrap();
    assert_eq!(
        (measured.pixels, measured.min_samples),
        (whole.pixels, whole.min_samples)
    );
    assert_eq!(whole.pixels, 96 * 40);
    assert!((measured.median_se - whole.median_se).abs() <= SE_TOLERANCE * whole.median_se);
    r.set_roi(Some(cone(0.0, 60.0))).unwrap();
    r.iterate(4).unwrap();
    let first = check(&mut r, |_| true, "4 frames");
    assert!(
        first.contrast.is_some() && first.roi_pixels > 100,
        "{first:?}"
    );
    // More frames into the same bindings.
    r.iterate(3).unwrap();
    let later = check(&mut r, |_| true, "7 frames");
    assert_eq!(later.roi_pixels, first.roi_pixels);
    assert!(later.roi_samples > first.roi_samples);
    // A moved, smaller ROI: the next frame installs its DGI, the accumulation restarts.
    r.set_roi(Some(cone(-0.5, 25.0))).unwrap();
    r.iterate(3).unwrap();
    let moved = check(&mut r, |_| true, "moved ROI");
    assert!(moved.roi_pixels < first.roi_pixels, "{moved:?}");
}

#[test]
fn a_wall_camera_render_measures_the_pixels_its_display_shows() {
    let backend = gpu();
    let model = DisplayModel::open("hornet").unwrap().0;
    let scene = Scene::builtin("cornell").unwrap();
    // Large enough that image pixels lie wholly on the bezels: at 845 × 341 and below every
    // pixel is some tile's (DESIGN.md §11), and nothing would be left unshown to leave out.
    let size = [1352, 546];
    let s = settings(&scene, size);
    let c = &s.camera;
    let wall = WallCamera::new(
        &model,
        size,
        DVec3::new(0.0, 0.0, 1.0),
        &WorldFromRoom::Auto,
        (c.position.as_dvec3(), c.forward.as_dvec3(), c.up.as_dvec3()),
    )
    .unwrap();
    let mut r =
        Renderer::guided_wall(&backend, &scene, s, &model, config(), Some(wall.clone())).unwrap();
    assert!(r.measures_stats_on_gpu());
    r.set_roi(Some(cone(0.0, 60.0))).unwrap();
    r.iterate(3).unwrap();
    let measured = check(&mut r, |i| wall.is_shown(i as u32), "wall camera");
    // Unshown ROI pixels are never sampled: counted, the fewest samples would be 0.
    let all = RoiStats::measure(&r.accumulation().unwrap(), &r.dgi().unwrap(), P_MIN, |_| {
        true
    });
    assert!(all.roi_pixels > measured.roi_pixels, "{all:?} {measured:?}");
    assert_eq!(all.progress.unwrap().min_samples, 0);
    assert!(measured.progress.unwrap().min_samples > 0, "{measured:?}");
}

#[test]
fn full_frames_measure_nothing_and_other_engines_read_back() {
    let scene = Scene::builtin("cornell").unwrap();
    let model = DisplayModel::open("hornet").unwrap().0;
    let s = settings(&scene, [96, 40]);
    // A full frame has no ROI: nothing to measure, nothing read.
    let backend = gpu();
    let mut full = Renderer::full(&backend, &scene, s).unwrap();
    full.iterate(1).unwrap();
    assert!(!full.measures_stats_on_gpu());
    assert_eq!(full.roi_stats().unwrap(), RoiStats::default());
    // The CPU twin and a frame in bands of rows measure their accumulation read back: the
    // same statistics as one band on the GPU (the accumulations are the same bit for bit).
    let cpu = Backend::Cpu;
    let banded = Backend::Gpu(Box::new(
        GpuContext::with_max_binding(16 * 96 * 10).unwrap(),
    ));
    let mut measured = Vec::new();
    for (backend, on_gpu) in [(&backend, true), (&banded, false), (&cpu, false)] {
        let mut r = Renderer::guided(backend, &scene, s, &model, config()).unwrap();
        assert_eq!(r.measures_stats_on_gpu(), on_gpu);
        r.set_roi(Some(cone(0.3, 25.0))).unwrap();
        r.iterate(3).unwrap();
        let stats = r.roi_stats().unwrap();
        if !on_gpu {
            let twin =
                RoiStats::measure(&r.accumulation().unwrap(), &r.dgi().unwrap(), P_MIN, |_| {
                    true
                });
            assert_eq!(stats, twin, "a read-back measurement is the twin's");
        }
        measured.push(stats);
    }
    same("one band against bands", &measured[1], &measured[0]);
}
