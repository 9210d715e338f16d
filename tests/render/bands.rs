//! A frame larger than the adapter's storage bindings is split into bands of rows
//! (DESIGN.md §11): on a device created with a small binding limit (wgpu enforces it), a
//! guided render through the wall camera — ROI changes, both pixel orders, a moved eye, timed
//! frames — and a full-frame render give bit for bit the accumulation, DGI and counts of the
//! same render in one band. lavapipe in CI.

use glam::DVec3;
use raygun::display::DisplayModel;
use raygun::filter::FilterParams;
use raygun::frame::{FrameStats, GuideConfig, Render, Renderer};
use raygun::gpu::{Backend, Band, GpuContext, GpuError};
use raygun::roi::cone::Cone;
use raygun::roi::dgi::{DgiParams, Guide, Metric, Roi, Surface};
use raygun::roi::gpu::DgiKernel;
use raygun::scene::Scene;
use raygun::schedule::Order;
use raygun::trace::accum::Accumulation;
use raygun::trace::camera::RenderCamera;
use raygun::trace::gpu::GpuAccum;
use raygun::trace::path::TraceSettings;
use raygun::trace::wall::{WallCamera, WorldFromRoom};

const SIZE: [u32; 2] = [61, 37];
/// Seven rows of the accumulation (16 bytes a pixel) and a little: 6 bands of 7 rows and one
/// of 2, the schedule's 32 × 32 blocks and the tracer's 8 × 8 tiles cut across band edges.
const SMALL_BINDING: u64 = 16 * 61 * 7 + 20;

fn settings(scene: &Scene) -> TraceSettings {
    TraceSettings {
        width: SIZE[0],
        height: SIZE[1],
        seed: 11,
        max_depth: 3,
        camera: RenderCamera::choose(scene, None, SIZE[0], SIZE[1]).unwrap(),
    }
}

fn cone(x: f64, deg: f64) -> Roi {
    Roi::Cone(Cone::from_pose(DVec3::new(x, 0.0, 1.0), DVec3::NEG_Z, DVec3::Y, deg, deg).unwrap())
}

fn small_device() -> Backend {
    let ctx = GpuContext::with_max_binding(SMALL_BINDING).unwrap_or_else(|e| {
        panic!("GPU tests need a wgpu adapter ({e}); `bash .ci/run` installs lavapipe")
    });
    assert_eq!(
        ctx.limits.max_storage_buffer_binding_size,
        SMALL_BINDING / 4 * 4,
        "the device is created with the capped limit"
    );
    // The whole frame's accumulation does not fit one binding on it: the split is needed.
    assert!(matches!(
        GpuAccum::new(&ctx, SIZE[0], SIZE[1]),
        Err(GpuError::TooLarge { .. })
    ));
    Backend::Gpu(Box::new(ctx))
}

/// What a render leaves: the accumulation, the DGI and each frame's scheduled pixels and rays.
struct Run {
    acc: Accumulation,
    dgi: Vec<f32>,
    stats: Vec<(Option<u32>, Option<u64>, bool)>,
}

fn frames(r: &mut Renderer, n: u32, stats: &mut Vec<(Option<u32>, Option<u64>, bool)>) {
    for _ in 0..n {
        let s: FrameStats = r.run_frame(true).unwrap();
        assert!(
            s.ms_trace.is_some_and(f64::is_finite),
            "a timed frame is timed"
        );
        stats.push((s.pixels, s.rays, s.dgi_recomputed));
    }
}

fn guided(backend: &Backend, order: Order) -> Run {
    let model = DisplayModel::open("hornet").unwrap().0;
    let scene = Scene::builtin("cornell").unwrap();
    let s = settings(&scene);
    let c = &s.camera;
    let wall = WallCamera::new(
        &model,
        SIZE,
        DVec3::new(0.0, 0.0, 1.0),
        &WorldFromRoom::Auto,
        (c.position.as_dvec3(), c.forward.as_dvec3(), c.up.as_dvec3()),
    )
    .unwrap();
    let config = GuideConfig {
        p_min: 0.05,
        order,
        ..GuideConfig::default()
    };
    let mut r = Renderer::guided_wall(backend, &scene, s, &model, config, Some(wall)).unwrap();
    let mut stats = Vec::new();
    frames(&mut r, 1, &mut stats);
    r.set_roi(Some(cone(0.0, 15.0))).unwrap();
    frames(&mut r, 3, &mut stats);
    r.set_roi(Some(cone(0.8, 25.0))).unwrap();
    frames(&mut r, 2, &mut stats);
    r.set_wall_eye(DVec3::new(0.05, 0.02, 1.1)).unwrap();
    frames(&mut r, 2, &mut stats);
    r.set_roi(None).unwrap();
    frames(&mut r, 1, &mut stats);
    r.set_roi(Some(cone(-0.5, 10.0))).unwrap();
    frames(&mut r, 2, &mut stats);
    Run {
        acc: r.accumulation().unwrap(),
        dgi: r.dgi().unwrap(),
        stats,
    }
}

fn same(name: &str, banded: &Run, whole: &Run) {
    assert_eq!(
        banded.stats, whole.stats,
        "{name}: pixels and rays per frame"
    );
    assert_eq!(banded.acc.count, whole.acc.count, "{name}: sample counts");
    assert!(
        banded.acc.sum == whole.acc.sum,
        "{name}: the banded accumulation differs from the whole frame's"
    );
    assert_eq!(banded.dgi, whole.dgi, "{name}: DGI");
    assert!(
        banded.acc.count.iter().any(|&c| c > 0),
        "{name}: something was traced"
    );
}

#[test]
fn a_guided_wall_render_in_bands_is_the_whole_frames_render_bit_for_bit() {
    let small = small_device();
    let whole = Backend::Gpu(Box::new(GpuContext::for_tests()));
    for order in [Order::Coherent, Order::Scattered] {
        let b = guided(&small, order);
        let w = guided(&whole, order);
        same(&format!("{order:?}"), &b, &w);
        // The ROI steers both: its pixels (d = 0) have more samples than the rest on average.
        let (mut roi, mut rest) = ((0u64, 0u64), (0u64, 0u64));
        for (i, &d) in b.dgi.iter().enumerate() {
            let c = u64::from(b.acc.count[i]);
            let slot = if d == 0.0 { &mut roi } else { &mut rest };
            *slot = (slot.0 + c, slot.1 + 1);
        }
        assert!(roi.1 > 0 && rest.1 > 0);
        assert!(
            roi.0 * rest.1 > rest.0 * roi.1,
            "{order:?}: the ROI is sampled more"
        );
    }
}

#[test]
fn a_full_frame_in_bands_and_its_picture_are_the_whole_frames() {
    let small = small_device();
    let whole = Backend::Gpu(Box::new(GpuContext::for_tests()));
    let scene = Scene::builtin("cornell").unwrap();
    let run = |backend: &Backend| {
        let mut r = Renderer::full(backend, &scene, settings(&scene)).unwrap();
        let mut stats = Vec::new();
        frames(&mut r, 3, &mut stats);
        let acc = r.accumulation().unwrap();
        // The picture is larger than the small device's bindings.
        let picture = r.picture(&FilterParams::default()).unwrap();
        (acc, stats, picture)
    };
    let (acc_b, stats_b, picture_b) = run(&small);
    let (acc_w, stats_w, picture_w) = run(&whole);
    assert_eq!(stats_b, stats_w);
    assert_eq!(acc_b.count, acc_w.count);
    assert!(acc_b.sum == acc_w.sum, "full frame: banded sums differ");
    assert!(acc_b.count.iter().all(|&c| c == 3));
    // The default filter (fast, k_max 32) reaches 72 rows, more than this device's binding
    // holds: the CPU twin filters the picture (tests/twins/filter.rs tests the bands).
    let cpu = Renderer::full(&Backend::Cpu, &scene, settings(&scene)).unwrap();
    let want = cpu
        .picture_of(
            &FilterParams::default(),
            &acc_b,
            &vec![0.0; acc_b.sum.len()],
        )
        .unwrap();
    assert_eq!(
        picture_b, want,
        "the CPU twin's filter of the same accumulation"
    );
    assert_eq!(picture_w.len(), want.len());
}

#[test]
fn the_dgi_kernel_computes_a_large_image_in_bands() {
    let Backend::Gpu(small) = small_device() else {
        unreachable!()
    };
    let whole = GpuContext::for_tests();
    let model = DisplayModel::open("hornet").unwrap().0;
    let surface = Surface::from_model(&model);
    // 4 bytes a pixel: 200 × 120 needs 96 kB, more than the small device's one binding.
    let params = DgiParams {
        width: 200,
        height: 120,
        falloff_px: Some(40.0),
    };
    for metric in [Metric::Exact, Metric::Angular] {
        let guide = Guide::new(&surface, &cone(0.3, 20.0), metric).unwrap();
        let kernel_b = DgiKernel::new(&small);
        let kernel_w = DgiKernel::new(&whole);
        let b = kernel_b.compute(&small, &surface, &guide, &params).unwrap();
        let w = kernel_w.compute(&whole, &surface, &guide, &params).unwrap();
        assert_eq!(b.len(), 200 * 120);
        assert_eq!(b, w, "{metric:?}: banded DGI");
        assert!(b.contains(&0.0) && b.iter().any(|&d| d > 0.5));
    }
}

#[test]
fn bands_cover_the_image_and_fit_the_binding() {
    for (w, h, bpp, max) in [
        (61, 37, 16, SMALL_BINDING),
        (13519, 5457, 16, 128 << 20),
        (13519, 5457, 16, (2 << 30) - 4),
        (1, 1, 16, 16),
        (7, 100, 4, 28),
    ] {
        let bands = Band::split(w, h, bpp, max).unwrap();
        assert_eq!(bands[0].row0, 0);
        for pair in bands.windows(2) {
            assert_eq!(pair[0].row0 + pair[0].rows, pair[1].row0);
        }
        let last = bands.last().unwrap();
        assert_eq!(last.row0 + last.rows, h);
        assert!(
            bands
                .iter()
                .all(|b| b.rows > 0 && u64::from(w) * u64::from(b.rows) * bpp <= max)
        );
        // As few as fit: one band fewer would need more rows than a binding holds.
        let fit = max / (u64::from(w) * bpp);
        assert_eq!(bands.len() as u64, u64::from(h).div_ceil(fit));
    }
    assert_eq!(
        Band::split(13519, 5457, 16, (2 << 30) - 4).unwrap().len(),
        1
    );
    assert_eq!(Band::split(13519, 5457, 16, 128 << 20).unwrap().len(), 9);
    assert!(Band::split(100, 10, 16, 1599).is_none(), "not one row fits");
}

/// `RAYGUN_MAX_BINDING` caps the binding a `raygun` process asks its adapter for: a guided
/// render split into bands writes the files of the unsplit render byte for byte (the tracer's
/// and the exact filter's bands are bit-exact); a malformed value is refused by name.
#[test]
fn raygun_max_binding_splits_a_render_and_changes_none_of_its_files() {
    let dir = std::env::temp_dir().join(format!("raygun-bands-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let render = |name: &str, max: Option<&str>| {
        let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_raygun"));
        c.args([
            "render",
            "--scene",
            "builtin:cornell-light",
            "--backend",
            "gpu",
        ])
        .args(["--size", "96,54", "--iterations", "4"])
        .args(["--filter", "exact", "--k-max", "8"])
        .args(["--guide", "pose:0,0,1:0,0,-1:20", "--display", "hornet"])
        .arg("--out")
        .arg(dir.join(name));
        if let Some(m) = max {
            c.env("RAYGUN_MAX_BINDING", m);
        }
        c.output().unwrap()
    };
    let whole = render("whole.exr", None);
    assert!(
        whole.status.success(),
        "{}",
        String::from_utf8_lossy(&whole.stderr)
    );
    // 30 rows of the accumulation: the tracer's frame in two bands, the filter's (a window of
    // 8 rows, 9 of halo on each side) in five.
    let banded = render("banded.exr", Some(&(16 * 96 * 30).to_string()));
    assert!(
        banded.status.success(),
        "{}",
        String::from_utf8_lossy(&banded.stderr)
    );
    let mut compared = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let name = entry.unwrap().file_name().into_string().unwrap();
        if let Some(rest) = name.strip_prefix("whole") {
            let other = dir.join(format!("banded{rest}"));
            assert!(
                std::fs::read(dir.join(&name)).unwrap() == std::fs::read(&other).unwrap(),
                "{name} differs from its banded render"
            );
            compared += 1;
        }
    }
    assert!(
        compared >= 3,
        "the image, the DGI and the counts: {compared} files"
    );
    let bad = render("bad.exr", Some("lots"));
    assert!(!bad.status.success());
    let err = String::from_utf8_lossy(&bad.stderr);
    assert!(err.contains("RAYGUN_MAX_BINDING=\"lots\""), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}

/// The renderer's feature buffers (DESIGN.md §8) through the wall camera: in bands they are the
/// whole frame's bit for bit, the GPU's agree with the CPU twin's (the kernel's own twin test
/// names the tolerance: 1e-3, ≥ 98 % of pixels), pixels no tile shows have none (at this size
/// every pixel is some tile's: `bezel_pixels_have_no_features` looks at a larger one), and a
/// moved eye changes them.
#[test]
fn wall_features_in_bands_are_the_whole_frames_and_the_cpu_twins() {
    let model = DisplayModel::open("hornet").unwrap().0;
    let scene = Scene::builtin("cornell").unwrap();
    let s = settings(&scene);
    let c = &s.camera;
    let camera = (c.position.as_dvec3(), c.forward.as_dvec3(), c.up.as_dvec3());
    let wall_at =
        |eye: DVec3| WallCamera::new(&model, SIZE, eye, &WorldFromRoom::Auto, camera).unwrap();
    let features = |backend: &Backend, eye: DVec3| {
        let r = Renderer::guided_wall(
            backend,
            &scene,
            s,
            &model,
            GuideConfig::default(),
            Some(wall_at(eye)),
        )
        .unwrap();
        r.features().unwrap().clone()
    };
    let eye = DVec3::new(0.0, 0.0, 1.0);
    let banded = features(&small_device(), eye);
    let whole = features(&Backend::Gpu(Box::new(GpuContext::for_tests())), eye);
    let cpu = features(&Backend::Cpu, eye);
    assert!(
        banded.albedo == whole.albedo && banded.normal_depth == whole.normal_depth,
        "the banded features differ from the whole frame's"
    );
    let wall = wall_at(eye);
    let n = (SIZE[0] * SIZE[1]) as usize;
    let (mut close, mut hits) = (0, 0);
    for p in 0..n {
        let (ga, gn) = (whole.albedo[p], whole.normal_depth[p]);
        let (ca, cn) = (cpu.albedo[p], cpu.normal_depth[p]);
        if !wall.is_shown(p as u32) {
            assert_eq!(
                (ga, gn, ca, cn),
                ([0.0; 4], [0.0; 4], [0.0; 4], [0.0; 4]),
                "pixel {p}"
            );
            continue;
        }
        hits += usize::from(cn[3] > 0.0);
        let tol = 1e-3 * cn[3].abs().max(1.0);
        let near =
            |a: [f32; 4], b: [f32; 4], t: f32| a.iter().zip(b).all(|(x, y)| (x - y).abs() <= t);
        close += usize::from(near(ga, ca, 1e-3) && near(gn, cn, tol));
    }
    let shown = wall.shown_count() as usize;
    // The wall's wide view shows the box in its middle (63 pixels at this size).
    assert!(hits > 50, "{hits} of {shown} shown pixels hit the scene");
    assert!(
        close as f64 >= 0.98 * shown as f64,
        "{close} of {shown} shown pixels agree with the CPU twin"
    );
    let moved = features(&Backend::Cpu, DVec3::new(0.1, 0.05, 1.2));
    assert_ne!(
        moved.normal_depth, cpu.normal_depth,
        "a moved eye sees other depths"
    );
}

/// At 1352×546 some pixels of HORNET's canvas are on bezels: their features are those of a
/// miss (0), a shown pixel's come from its wall point.
#[test]
fn bezel_pixels_have_no_features() {
    let model = DisplayModel::open("hornet").unwrap().0;
    let scene = Scene::builtin("cornell").unwrap();
    let size = [1352, 546];
    let mut s = settings(&scene);
    (s.width, s.height) = (size[0], size[1]);
    let c = &s.camera;
    let camera = (c.position.as_dvec3(), c.forward.as_dvec3(), c.up.as_dvec3());
    let wall = WallCamera::new(
        &model,
        size,
        DVec3::new(0.0, 0.0, 1.0),
        &WorldFromRoom::Auto,
        camera,
    )
    .unwrap();
    let packed = raygun::trace::pack::PackedScene::new(&scene);
    let at = |p: u32| raygun::trace::features::pixel_features(&packed, &s, Some(&wall), p);
    let n = size[0] * size[1];
    let bezel = (0..n).find(|&p| !wall.is_shown(p)).expect("a bezel pixel");
    assert_eq!(at(bezel), ([0.0; 4], [0.0; 4]), "pixel {bezel}");
    let centre = size[1] / 2 * size[0] + size[0] / 2;
    assert!(wall.is_shown(centre));
    let (albedo, nd) = at(centre);
    assert!(
        nd[3] > 0.0 && albedo[..3].iter().any(|&a| a > 0.0),
        "{albedo:?} {nd:?}"
    );
}
