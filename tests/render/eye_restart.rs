//! The restart rule of a moving eye (DESIGN.md §11): head motion below the threshold keeps
//! the accumulation (sample counts keep growing), motion past it restarts it (counts back to
//! zero) and the ROI and its DGI survive — on the CPU twin and the GPU kernel (lavapipe in CI).
//! A restarted render is the render a fresh renderer at the new eye makes, bit for bit.

use glam::DVec3;
use raygun::display::DisplayModel;
use raygun::frame::{EyeFollow, FrameError, GuideConfig, Render, Renderer};
use raygun::gpu::{Backend, GpuContext};
use raygun::roi::cone::Cone;
use raygun::roi::dgi::Roi;
use raygun::scene::Scene;
use raygun::trace::camera::RenderCamera;
use raygun::trace::path::TraceSettings;
use raygun::trace::wall::{WallCamera, WorldFromRoom};
use raygun::tracking::head::DEFAULT_EYE_THRESHOLD_M;

const SIZE: [u32; 2] = [124, 50];

fn settings(scene: &Scene) -> TraceSettings {
    TraceSettings {
        width: SIZE[0],
        height: SIZE[1],
        seed: 3,
        max_depth: 2,
        camera: RenderCamera::choose(scene, None, SIZE[0], SIZE[1]).unwrap(),
    }
}

/// A 20° cone from 1 m in front of the centre at the middle column.
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

fn total(r: &Renderer) -> u64 {
    r.accumulation()
        .unwrap()
        .count
        .iter()
        .map(|&c| u64::from(c))
        .sum()
}

fn check(backend: &Backend, name: &str) {
    let model = DisplayModel::open("hornet").unwrap().0;
    let scene = Scene::builtin("cornell").unwrap();
    let s = settings(&scene);
    let c = &s.camera;
    let start = DVec3::new(0.0, 0.0, 1.0);
    let wall = WallCamera::new(
        &model,
        SIZE,
        start,
        &WorldFromRoom::Auto,
        (c.position.as_dvec3(), c.forward.as_dvec3(), c.up.as_dvec3()),
    )
    .unwrap();
    let config = GuideConfig {
        p_min: 0.1,
        ..GuideConfig::default()
    };
    let mut r =
        Renderer::guided_wall(backend, &scene, s, &model, config, Some(wall.clone())).unwrap();
    r.set_roi(Some(roi())).unwrap();
    r.iterate(3).unwrap();
    let dgi = r.dgi().unwrap();
    let before = total(&r);
    assert!(before > 0, "{name}");

    // 6 mm: below the threshold — kept, and the counts keep growing.
    let small = start + DVec3::new(0.006, 0.0, 0.0);
    assert!(matches!(
        r.follow_eye(small, DEFAULT_EYE_THRESHOLD_M).unwrap(),
        EyeFollow::Kept
    ));
    assert_eq!(r.iteration(), 3, "{name}");
    assert_eq!(r.wall().unwrap().eye_room, start, "{name}: the eye stays");
    r.iterate(2).unwrap();
    assert!(total(&r) > before, "{name}: the accumulation goes on");

    // Another 6 mm the same way: 12 mm from the eye the accumulation started with — restart.
    let far = start + DVec3::new(0.012, 0.0, 0.0);
    assert!(matches!(
        r.follow_eye(far, DEFAULT_EYE_THRESHOLD_M).unwrap(),
        EyeFollow::Restarted
    ));
    assert_eq!(r.iteration(), 0, "{name}");
    assert_eq!(r.wall().unwrap().eye_room, far, "{name}");
    assert_eq!(total(&r), 0, "{name}: the counts start again from zero");
    assert_eq!(r.roi(), Some(&roi()), "{name}: the ROI survives");
    assert_eq!(r.dgi().unwrap(), dgi, "{name}: the DGI survives");
    r.iterate(4).unwrap();
    let dgi_after = r.dgi().unwrap();
    assert_eq!(dgi_after, dgi, "{name}: no DGI recomputed");
    let acc = r.accumulation().unwrap();
    // Every ROI pixel (d = 0, p = 1) was sampled by each of the 4 frames since the restart.
    let roi_px: Vec<usize> = (0..dgi.len())
        .filter(|&p| dgi[p] == 0.0 && wall.is_shown(p as u32))
        .collect();
    assert!(!roi_px.is_empty(), "{name}");
    assert!(roi_px.iter().all(|&p| acc.count[p] == 4), "{name}");

    // Bit for bit the render of a fresh renderer at the new eye with the same placement.
    let fresh_wall = WallCamera::placed(&model, SIZE, far, wall.scene_from_room).unwrap();
    let mut fresh =
        Renderer::guided_wall(backend, &scene, s, &model, config, Some(fresh_wall)).unwrap();
    fresh.set_roi(Some(roi())).unwrap();
    fresh.iterate(4).unwrap();
    let want = fresh.accumulation().unwrap();
    assert_eq!(acc.count, want.count, "{name}: counts");
    assert!(
        acc.sum == want.sum,
        "{name}: sums differ from a fresh render at the new eye"
    );

    // An eye behind the wall is refused and changes nothing.
    let behind = DVec3::new(0.0, 0.0, -1.0);
    assert!(matches!(
        r.follow_eye(behind, DEFAULT_EYE_THRESHOLD_M).unwrap(),
        EyeFollow::Refused(_)
    ));
    assert_eq!(r.iteration(), 4, "{name}");
    assert_eq!(r.wall().unwrap().eye_room, far, "{name}");
}

#[test]
fn eye_motion_below_the_threshold_keeps_and_above_restarts_on_the_cpu_twin() {
    check(&Backend::Cpu, "CPU");
}

#[test]
fn eye_motion_below_the_threshold_keeps_and_above_restarts_on_the_gpu() {
    check(&Backend::Gpu(Box::new(GpuContext::for_tests())), "GPU");
}

/// A pinhole camera that moves restarts the accumulation too, the ROI kept; a renderer without
/// a wall camera has no eye to follow.
#[test]
fn a_moved_pinhole_camera_restarts_and_keeps_the_roi() {
    let model = DisplayModel::open("hornet").unwrap().0;
    let scene = Scene::builtin("cornell").unwrap();
    let s = settings(&scene);
    for (backend, name) in [
        (Backend::Cpu, "CPU"),
        (Backend::Gpu(Box::new(GpuContext::for_tests())), "GPU"),
    ] {
        let mut r = Renderer::guided(&backend, &scene, s, &model, GuideConfig::default()).unwrap();
        r.set_roi(Some(roi())).unwrap();
        r.iterate(2).unwrap();
        assert!(total(&r) > 0);
        let mut cam = s.camera;
        cam.position += glam::Vec3::new(0.05, 0.0, 0.0);
        r.set_camera(cam).unwrap();
        assert_eq!(total(&r), 0, "{name}");
        assert_eq!(r.roi(), Some(&roi()), "{name}");
        r.iterate(3).unwrap();
        let mut fresh = Renderer::guided(
            &backend,
            &scene,
            TraceSettings { camera: cam, ..s },
            &model,
            GuideConfig::default(),
        )
        .unwrap();
        fresh.set_roi(Some(roi())).unwrap();
        fresh.iterate(3).unwrap();
        assert!(
            r.accumulation().unwrap().sum == fresh.accumulation().unwrap().sum,
            "{name}"
        );
        assert!(matches!(
            r.follow_eye(DVec3::ZERO, 0.01),
            Err(FrameError::NoWall)
        ));
    }
}
