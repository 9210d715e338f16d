//! The wall camera (DESIGN.md §11): each pixel's primary ray from the eye through its own point
//! on the display (DESIGN.md §3), on the CPU twin and the GPU kernel (lavapipe in CI).
//!
//! The analytic test needs no geometry: the environment map stores its own texel index in each
//! texel, so a camera ray that escapes says exactly which texel it met. The jitter is the
//! tracer's own random number (pixel, sample, seed, trace stream), so the expected direction is
//! the one from the eye to the exact wall point of the jittered image point, computed here in
//! f64 through the display module; rendered and expected texels must agree to one texel (the
//! map's resolution: f32 rounding can tip a direction across a texel edge).

use crate::support as cli;

use glam::{DVec2, DVec3, Vec2, Vec3, Vec4};
use raygun::display::DisplayModel;
use raygun::frame::{GuideConfig, Render, Renderer};
use raygun::gpu::{Backend, GpuContext};
use raygun::random::{pcg4d, stream, unit_f32};
use raygun::scene::{Environment, EnvironmentMap, Material, Scene, Triangle};
use raygun::schedule::{DrawInput, Order, schedule_cpu_shown};
use raygun::trace::accum::Accumulation;
use raygun::trace::camera::RenderCamera;
use raygun::trace::gpu::{GpuAccum, GpuScene, TraceKernel, TraceRun};
use raygun::trace::pack::PackedScene;
use raygun::trace::path::{TraceSettings, render_cpu_with};
use raygun::trace::shading::direction_to_equirect;
use raygun::trace::wall::{SceneFromRoom, WallCamera, WorldFromRoom};

const IDENTITY: SceneFromRoom = SceneFromRoom {
    rotation: glam::DMat3::IDENTITY,
    translation: DVec3::ZERO,
};

/// The index map's size: 2048 × 1024 texels of 0.18°, 3 mm at a metre (32 MiB packed, inside
/// lavapipe's 128 MiB binding).
const MAP: [u32; 2] = [2048, 1024];

/// Each texel's radiance is (column, row, 1).
fn index_scene() -> Scene {
    let [w, h] = MAP;
    let texels = (0..w * h)
        .map(|i| Vec3::new((i % w) as f32, (i / w) as f32, 1.0))
        .collect();
    Scene {
        environment: Environment::Map(EnvironmentMap {
            name: "index".into(),
            width: w,
            height: h,
            texels,
        }),
        ..Default::default()
    }
}

fn models() -> Vec<(DisplayModel, Vec<DVec3>)> {
    let open = |n: &str| DisplayModel::open(n).unwrap().0;
    vec![
        // The paper's viewer 1 m in front of the centre, one off to the left and low, one close
        // to the right-hand columns.
        (
            open("hornet"),
            vec![
                DVec3::new(0.0, 0.0, 1.0),
                DVec3::new(-1.2, -0.4, 1.8),
                DVec3::new(1.5, 0.3, 0.6),
            ],
        ),
        (
            open("desktop-27in-4k"),
            vec![DVec3::new(0.0, 0.0, 0.6), DVec3::new(0.25, -0.1, 0.35)],
        ),
        (
            open("projection-4m-4k"),
            vec![DVec3::new(0.0, 0.0, 3.0), DVec3::new(-1.5, 0.8, 1.2)],
        ),
    ]
}

/// An image `1 / shrink` of the canvas on each axis (bezels of HORNET's 5.7 canvas px then
/// hold some pixel centres, and pixels next to them are checked too).
fn size_of(model: &DisplayModel, shrink: f64) -> [u32; 2] {
    let s = model.canvas_rect().size() / shrink;
    [s.x.round() as u32, s.y.round() as u32]
}

fn settings(w: u32, h: u32, seed: u32) -> TraceSettings {
    TraceSettings {
        width: w,
        height: h,
        seed,
        max_depth: 1,
        camera: RenderCamera::choose(&Scene::default(), None, w, h).unwrap(),
    }
}

fn wall(model: &DisplayModel, size: [u32; 2], eye: DVec3) -> WallCamera {
    WallCamera::new(
        model,
        size,
        eye,
        &WorldFromRoom::Identity,
        (DVec3::ZERO, DVec3::NEG_Z, DVec3::Y),
    )
    .unwrap()
}

/// The tile whose active area holds canvas point `c` (half-open, first listed), in f64.
fn active_tile(model: &DisplayModel, c: DVec2) -> Option<usize> {
    model.tiles().iter().position(|t| {
        let a = t.active_rect();
        c.x >= a.min.x && c.x < a.max.x && c.y >= a.min.y && c.y < a.max.y
    })
}

/// The texel the direction from `eye` to the wall point of image point `(x + jx, y + jy)`
/// meets (f64 geometry), for the pixel `(x, y)` on tile `tile`.
fn expected_texel(
    model: &DisplayModel,
    size: [u32; 2],
    eye: DVec3,
    xf: &SceneFromRoom,
    tile: usize,
    p: DVec2,
) -> (i64, i64) {
    let c = model.image_to_canvas(p, size);
    let point = model.tiles()[tile].canvas_to_point(c);
    let d = (xf.point(point) - xf.point(eye)).normalize().as_vec3();
    let (u, v) = direction_to_equirect(d);
    (
        ((u * MAP[0] as f32) as i64).min(i64::from(MAP[0]) - 1),
        ((v * MAP[1] as f32) as i64).min(i64::from(MAP[1]) - 1),
    )
}

/// For each image pixel, the tiles whose own pixels show it (the wall output's cut).
fn shown_by(model: &DisplayModel, size: [u32; 2]) -> Vec<Vec<usize>> {
    let mut by = vec![Vec::new(); (size[0] * size[1]) as usize];
    for t in 0..model.tiles().len() {
        for p in raygun::output::tiles::tile_source_indices(model, t, size) {
            if by[p].last() != Some(&t) {
                by[p].push(t);
            }
        }
    }
    by
}

/// The wall camera an image was traced through: the display, the camera, the image size, the
/// eye (room frame) and where the room sits in the scene.
struct Traced<'a> {
    model: &'a DisplayModel,
    wc: &'a WallCamera,
    size: [u32; 2],
    eye: DVec3,
    xf: &'a SceneFromRoom,
}

/// Checks one sample per pixel against the geometry: a pixel is shown when its centre lies on
/// a tile's active area (traced through that tile) or when a tile's own pixels show it (traced
/// through one of those tiles); unshown pixels have no sample, shown ones met the texel of
/// their jittered wall point (±1 texel, columns wrapping).
fn check_image(acc: &Accumulation, traced: &Traced, seed: u32, label: &str) {
    let Traced {
        model,
        wc,
        size,
        eye,
        xf,
    } = *traced;
    let [w, h] = size;
    let by = shown_by(model, size);
    let mut checked = 0;
    for y in 0..h {
        for x in 0..w {
            let pixel = y * w + x;
            let centre =
                model.image_to_canvas(DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5), size);
            let count = acc.count[pixel as usize];
            let candidates = match active_tile(model, centre) {
                Some(t) => vec![t],
                None => by[pixel as usize].clone(),
            };
            if candidates.is_empty() {
                assert_eq!(count, 0, "{label}: no tile shows pixel ({x}, {y})");
                continue;
            }
            assert_eq!(
                count, 1,
                "{label}: pixel ({x}, {y}) on tiles {candidates:?}"
            );
            let tile = wc.model_tile(wc.tile_of(x, y).expect("a shown pixel has a tile"));
            assert!(
                candidates.contains(&tile),
                "{label}: pixel ({x}, {y}) is traced through tile {tile}, not one of {candidates:?}"
            );
            let r = pcg4d([pixel, 0, seed, stream::TRACE]).map(unit_f32);
            let p = DVec2::new(
                f64::from(x) + f64::from(r[0]),
                f64::from(y) + f64::from(r[1]),
            );
            let (ec, er) = expected_texel(model, size, eye, xf, tile, p);
            let s = acc.sum[pixel as usize];
            let (gc, gr) = (s[0] as i64, s[1] as i64);
            let dc = (gc - ec).rem_euclid(i64::from(MAP[0]));
            let dc = dc.min(i64::from(MAP[0]) - dc);
            assert!(
                dc <= 1 && (gr - er).abs() <= 1 && s[2] == 1.0,
                "{label}: pixel ({x}, {y}) on tile {} met texel ({gc}, {gr}); the ray from the eye through its wall point meets ({ec}, {er})",
                model.tiles()[tile].id()
            );
            checked += 1;
        }
    }
    assert!(checked > 0, "{label}: no pixel checked");
}

/// Every pixel a tile's own pixels show is traced, at any image size: a pixel at a tile's edge
/// whose centre falls on the bezel (HORNET at 1352 × 546, ten canvas pixels an image pixel,
/// where the outer bezels hold the first and last columns' centres) is what the tile's
/// outermost pixels show, and would otherwise leave a black line along the tile's edge.
#[test]
fn every_pixel_a_tile_shows_is_traced_at_sizes_that_do_not_divide_the_canvas() {
    let model = DisplayModel::open("hornet").unwrap().0;
    let eye = DVec3::new(0.0, 0.0, 1.0);
    for size in [[1352, 546], [845, 341], [992, 400], [1690, 682]] {
        let wc = wall(&model, size, eye);
        let by = shown_by(&model, size);
        let mut edge = 0;
        for (p, tiles) in by.iter().enumerate() {
            let (x, y) = ((p % size[0] as usize) as u32, (p / size[0] as usize) as u32);
            if tiles.is_empty() {
                continue;
            }
            assert!(
                wc.is_shown(p as u32),
                "{size:?}: pixel ({x}, {y}) of tiles {tiles:?}"
            );
            let centre =
                model.image_to_canvas(DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5), size);
            if active_tile(&model, centre).is_none() {
                edge += 1;
                let tile = wc.model_tile(wc.tile_of(x, y).unwrap());
                assert!(
                    tiles.contains(&tile),
                    "{size:?}: ({x}, {y}) through tile {tile}"
                );
            }
        }
        // Nothing else is shown: a pixel is shown only when its centre is on a tile or a tile
        // shows it.
        let shown = by
            .iter()
            .enumerate()
            .filter(|(p, tiles)| {
                let (x, y) = (*p % size[0] as usize, *p / size[0] as usize);
                let c = model.image_to_canvas(DVec2::new(x as f64 + 0.5, y as f64 + 0.5), size);
                !tiles.is_empty() || active_tile(&model, c).is_some()
            })
            .count();
        assert_eq!(wc.shown_count() as usize, shown, "{size:?}");
        if size == [1352, 546] {
            // The outer bezels hold the centres of the first and last column and row.
            assert!(edge >= 2 * (1352 + 546) - 4, "{size:?}: {edge} edge pixels");
        }
    }
}

/// HORNET at 1/8 of its canvas: 1690 × 682 pixels, each 8 canvas pixels (4.2 mm) wide.
const SHRINK: f64 = 8.0;

#[test]
fn cpu_twin_rays_pass_through_every_pixels_wall_point_on_every_shipped_model() {
    let scene = index_scene();
    let packed = PackedScene::new(&scene);
    for (model, eyes) in models() {
        let size = size_of(&model, SHRINK);
        for (k, &eye) in eyes.iter().enumerate() {
            let seed = 7 + k as u32;
            let s = settings(size[0], size[1], seed);
            let wc = wall(&model, size, eye);
            let mut acc = Accumulation::new(size[0], size[1]);
            render_cpu_with(&packed, &s, Some(&wc), &mut acc, None);
            check_image(
                &acc,
                &Traced {
                    model: &model,
                    wc: &wc,
                    size,
                    eye,
                    xf: &IDENTITY,
                },
                seed,
                &format!("CPU, {}, eye {eye}", model.name()),
            );
        }
    }
}

#[test]
fn gpu_rays_pass_through_every_pixels_wall_point_on_every_shipped_model() {
    let ctx = GpuContext::for_tests();
    let scene = index_scene();
    let packed = PackedScene::new(&scene);
    let kernel = TraceKernel::new(&ctx);
    let gs = GpuScene::upload(&ctx, &kernel, &packed).unwrap();
    for (model, eyes) in models() {
        let size = size_of(&model, SHRINK);
        for (k, &eye) in eyes.iter().enumerate() {
            let seed = 7 + k as u32;
            let s = settings(size[0], size[1], seed);
            let wc = wall(&model, size, eye);
            let acc = GpuAccum::new(&ctx, size[0], size[1]).unwrap();
            let run = TraceRun::with_wall(&ctx, &kernel, &packed, &s, Some(&wc), &acc, None);
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            acc.clear(&mut enc);
            run.record(&mut enc, &gs, None);
            ctx.queue.submit([enc.finish()]);
            let acc = acc.read(&ctx).unwrap();
            check_image(
                &acc,
                &Traced {
                    model: &model,
                    wc: &wc,
                    size,
                    eye,
                    xf: &IDENTITY,
                },
                seed,
                &format!("GPU, {}, eye {eye}", model.name()),
            );
        }
    }
}

/// `--world-from-room X,Y,Z,YAW_DEG,SCALE` and `auto` turn the rays into the scene's frame: the
/// texel met is the one in the turned direction (the translation and scale move the eye, not
/// the directions), and `auto` looks along the scene camera's forward at the wall's centre.
#[test]
fn world_from_room_turns_the_rays_into_the_scene() {
    let scene = index_scene();
    let packed = PackedScene::new(&scene);
    let model = DisplayModel::open("hornet").unwrap().0;
    let size = size_of(&model, 32.0);
    let eye = DVec3::new(0.4, -0.2, 1.3);
    let camera = (
        DVec3::new(5.0, 1.0, -2.0),
        DVec3::new(1.0, -0.2, 0.3),
        DVec3::Y,
    );
    for placement in [
        WorldFromRoom::Explicit {
            translation: DVec3::new(3.0, -1.0, 2.0),
            yaw_deg: 35.0,
            scale: 2.5,
        },
        WorldFromRoom::Auto,
    ] {
        let wc = WallCamera::new(&model, size, eye, &placement, camera).unwrap();
        if placement == WorldFromRoom::Auto {
            assert!(wc.eye.as_dvec3().abs_diff_eq(camera.0, 1e-5));
            let centre = model.canvas_to_point(model.canvas_rect().center()).unwrap();
            let f = wc.scene_from_room.vector(centre - eye).normalize();
            assert!(
                f.abs_diff_eq(camera.1.normalize(), 1e-9),
                "auto looks along {f}"
            );
        }
        let s = settings(size[0], size[1], 11);
        let mut acc = Accumulation::new(size[0], size[1]);
        render_cpu_with(&packed, &s, Some(&wc), &mut acc, None);
        check_image(
            &acc,
            &Traced {
                model: &model,
                wc: &wc,
                size,
                eye,
                xf: &wc.scene_from_room,
            },
            11,
            &format!("CPU, {placement:?}"),
        );
    }
}

/// A black occluder with a slanted straight edge, in front of a white sky.
fn edge_scene(a: Vec3, b: Vec3) -> Scene {
    let black = Material {
        name: "black".into(),
        base_color: Vec4::new(0.0, 0.0, 0.0, 1.0),
        base_color_texture: None,
        metallic: 0.0,
        roughness: 1.0,
        specular: 0.0,
        emission: Vec3::ZERO,
        double_sided: true,
    };
    // The occluder lies below the edge a–b in the plane z = a.z, 20 m deep.
    let down = Vec3::new(0.0, -20.0, 0.0);
    let tri = |p: [Vec3; 3]| Triangle {
        p,
        n: [Vec3::Z; 3],
        uv: [Vec2::ZERO; 3],
        material: 0,
    };
    Scene {
        triangles: vec![tri([a, a + down, b]), tri([b, a + down, b + down])],
        materials: vec![black],
        environment: Environment::Constant(Vec3::ONE),
        ..Default::default()
    }
}

/// A straight edge stays straight in 3D: where the image crosses from sky to occluder, the
/// wall points are coplanar with the eye and the edge — on all seven columns of HORNET, so
/// across its six hinges. The edge's height in a pixel column is the sum of the sky coverage of
/// the pixels around the crossing (exact for a box filter and a straight edge); 64 samples a
/// pixel put it within about 0.06 px (one standard deviation). Tolerance: half an image pixel's
/// footprint on the wall, 6.4 mm here (an image stretched over the wall instead kinks by
/// centimetres at each hinge).
#[test]
fn a_straight_edge_is_coplanar_with_the_eye_across_hinges() {
    let model = DisplayModel::open("hornet").unwrap().0;
    let shrink = 24.0;
    let size = size_of(&model, shrink);
    let [w, h] = size;
    let eye = DVec3::new(0.3, 0.1, 2.0);
    let (a, b) = (Vec3::new(-40.0, -2.0, -3.0), Vec3::new(40.0, 3.0, -3.0));
    let scene = edge_scene(a, b);
    let packed = PackedScene::new(&scene);
    let s = settings(w, h, 3);
    let wc = wall(&model, size, eye);
    let mut acc = Accumulation::new(w, h);
    for _ in 0..64 {
        render_cpu_with(&packed, &s, Some(&wc), &mut acc, None);
    }
    let img = acc.mean_image();
    let n = (a.as_dvec3() - eye).cross(b.as_dvec3() - eye).normalize();
    let tolerance_m = 0.5 * shrink * model.pitch_m();
    let mut columns = std::collections::BTreeSet::new();
    let (mut worst, mut measured): (f64, usize) = (0.0, 0);
    let at = |x: u32, y: u32| (y * w + x) as usize;
    for x in 0..w {
        // The first occluded pixel centre below sky (bezel pixels have no samples: skipped).
        let Some(y) = (1..h).find(|&y| {
            let (p, q) = (at(x, y - 1), at(x, y));
            acc.count[p] > 0 && acc.count[q] > 0 && img[p].x >= 0.5 && img[q].x < 0.5
        }) else {
            continue;
        };
        let (top, bottom) = (y.saturating_sub(3), (y + 3).min(h));
        let window: Vec<usize> = (top..bottom).map(|r| at(x, r)).collect();
        if window.iter().any(|&p| acc.count[p] == 0)
            || img[window[0]].x < 1.0
            || img[*window.last().unwrap()].x > 0.0
        {
            continue; // a bezel or the image's edge in the window
        }
        let y_edge = f64::from(top) + window.iter().map(|&p| f64::from(img[p].x)).sum::<f64>();
        let c = model.image_to_canvas(DVec2::new(f64::from(x) + 0.5, y_edge), size);
        let Some(tile) = active_tile(&model, c) else {
            continue;
        };
        let point = model.tiles()[tile].canvas_to_point(c);
        let dist = (point - eye).dot(n).abs();
        worst = worst.max(dist);
        measured += 1;
        assert!(
            dist < tolerance_m,
            "column {x}: the edge's wall point on tile {} is {:.2} mm off the plane through the eye and the edge (tolerance {:.2} mm)",
            model.tiles()[tile].id(),
            dist * 1e3,
            tolerance_m * 1e3
        );
        columns.insert(model.tiles()[tile].column());
    }
    assert_eq!(
        columns.len(),
        7,
        "the edge was measured on columns {columns:?} only ({measured} pixel columns, worst {:.3} mm)",
        worst * 1e3
    );
    assert!(
        measured as u32 > w / 2,
        "{measured} of {w} pixel columns measured"
    );
}

/// Bezel pixels cost nothing: the schedule never lists them (probability 0, CPU twin and GPU),
/// the tracer never samples them, and the picture shows them black.
#[test]
fn bezel_pixels_are_never_scheduled_or_traced_on_either_backend() {
    let model = DisplayModel::open("hornet").unwrap().0;
    // 1/8 of the canvas: an image pixel is 8 canvas pixels, narrower than HORNET's gaps
    // (11.3), so some pixels lie in a gap where no tile shows them.
    let size = size_of(&model, SHRINK);
    let [w, h] = size;
    let eye = DVec3::new(0.0, 0.0, 1.0);
    let scene = Scene {
        environment: Environment::Constant(Vec3::ONE),
        ..Default::default()
    };
    let wc = wall(&model, size, eye);
    let n = (w * h) as usize;
    let hidden = (0..n).filter(|&p| !wc.is_shown(p as u32)).count();
    assert!(hidden > 0, "a 1/8 HORNET image has pixels in its gaps");
    assert_eq!(wc.shown_count() as usize, n - hidden);
    // With d = 0 everywhere every shown pixel has p = 1, every hidden one p = 0.
    let dgi = vec![0.0f32; n];
    let input = DrawInput {
        dgi: &dgi,
        shown: Some(wc.shown_mask()),
        width: w,
        height: h,
        p_min: 0.5,
        iteration: 0,
        seed: 1,
    };
    let list = schedule_cpu_shown(&input, Order::Coherent).unwrap();
    assert_eq!(list.len() as u64, wc.shown_count());
    assert!(list.iter().all(|&p| wc.is_shown(p)));
    let iterations = 3;
    let cpu = Backend::Cpu;
    let ctx = GpuContext::for_tests();
    let gpu = Backend::Gpu(Box::new(ctx));
    for (backend, name) in [(&cpu, "CPU"), (&gpu, "GPU")] {
        let s = settings(w, h, 5);
        let config = GuideConfig {
            p_min: 0.25,
            ..GuideConfig::default()
        };
        let mut r =
            Renderer::guided_wall(backend, &scene, s, &model, config, Some(wc.clone())).unwrap();
        let mut scheduled = 0;
        for _ in 0..iterations {
            scheduled += r.run_frame(true).unwrap().pixels.unwrap();
        }
        assert_eq!(
            u64::from(scheduled),
            wc.shown_count() * u64::from(iterations),
            "{name}: the schedule's count is the shown pixels'"
        );
        let acc = r.accumulation().unwrap();
        for p in 0..n {
            let want = if wc.is_shown(p as u32) { iterations } else { 0 };
            assert_eq!(acc.count[p], want, "{name}: pixel {p}");
        }
        // The filter spreads light into unsampled pixels; the wall's picture keeps them black.
        let params = raygun::filter::FilterParams::default();
        let pic = r.picture(&params).unwrap();
        for (p, v) in pic.iter().enumerate() {
            if !wc.is_shown(p as u32) {
                assert_eq!(*v, Vec3::ZERO, "{name}: bezel pixel {p} is black");
            } else {
                assert!(v.x > 0.5, "{name}: shown pixel {p} sees the sky");
            }
        }
    }
}

/// Full frames through the wall camera with path regeneration (a thread's next slots may be
/// bezel pixels, which it skips): the default kernel's accumulation to the bit, every shown
/// pixel traced once a frame and no bezel pixel (the kernel lab's `+regenG`).
#[cfg(feature = "kernel-lab")]
#[test]
fn regenerated_wall_frames_skip_the_bezels_and_match_the_default_kernel() {
    use raygun::trace::gpu::TraceVariant;
    let model = DisplayModel::open("hornet").unwrap().0;
    let size = size_of(&model, 32.0);
    let [w, h] = size;
    let wc = wall(&model, size, DVec3::new(-0.3, 0.1, 1.2));
    let scene = index_scene();
    let ctx = GpuContext::for_tests();
    let regen = TraceVariant::default().with_regen(3);
    let mut accs = Vec::new();
    for c in [ctx.clone(), ctx.with_trace_variant(regen).unwrap()] {
        let backend = Backend::Gpu(Box::new(c));
        let mut r = Renderer::full_wall(&backend, &scene, settings(w, h, 3), wc.clone()).unwrap();
        r.iterate(2).unwrap();
        accs.push(r.accumulation().unwrap());
    }
    let (one, regenerated) = (&accs[0], &accs[1]);
    for p in 0..(w * h) as usize {
        let want = if wc.is_shown(p as u32) { 2 } else { 0 };
        assert_eq!(regenerated.count[p], want, "pixel {p}");
    }
    assert!(regenerated.count == one.count);
    let bits =
        |a: &Accumulation| -> Vec<[u32; 4]> { a.sum.iter().map(|v| v.map(f32::to_bits)).collect() };
    assert!(bits(regenerated) == bits(one), "the default kernel's sums");
}

fn err_of(args: &[&str]) -> String {
    let o = cli::raygun(args);
    assert!(!o.status.success(), "{args:?} succeeded");
    cli::stderr(&o)
}

#[test]
fn bad_wall_camera_input_is_a_clear_error_naming_the_flag() {
    let dir = cli::tmp_dir("wall-bad");
    let out = dir.join("x.exr");
    let out = out.to_str().unwrap();
    let base = [
        "render",
        "--scene",
        "builtin:cornell",
        "--size",
        "32,16",
        "--spp",
        "1",
        "--out",
        out,
        "--camera",
        "wall",
    ];
    let with = |extra: &[&str]| {
        let mut a: Vec<&str> = base.to_vec();
        a.extend_from_slice(extra);
        err_of(&a)
    };
    let e = with(&["--eye", "0,0,1"]);
    assert!(e.contains("--display"), "{e}");
    let e = with(&["--display", "hornet"]);
    assert!(e.contains("--eye"), "{e}");
    // Behind the wall, and on its plane.
    for eye in ["0,0,-1", "0,0,0"] {
        let e = with(&["--display", "hornet", "--eye", eye]);
        assert!(e.contains("--eye") && e.contains("tile"), "{e}");
    }
    let e = with(&["--display", "hornet", "--eye", "1,2"]);
    assert!(e.contains("--eye"), "{e}");
    let e = with(&["--display", "hornet", "--eye", "0,0,nan"]);
    assert!(e.contains("--eye"), "{e}");
    for wfr in ["1,2,3", "1,2,3,x", "1,2,3,4,-1", "sideways"] {
        let e = with(&[
            "--display",
            "hornet",
            "--eye",
            "0,0,1",
            "--world-from-room",
            wfr,
        ]);
        assert!(e.contains("--world-from-room"), "{wfr}: {e}");
    }
    let e = err_of(&[
        "render",
        "--scene",
        "builtin:cornell",
        "--size",
        "32,16",
        "--out",
        out,
        "--eye",
        "0,0,1",
    ]);
    assert!(e.contains("--camera wall"), "{e}");
    assert!(!std::path::Path::new(out).exists());
}

/// `render --camera wall` end to end on the CPU: the EXR has black bezel pixels and lit ones.
#[test]
fn render_with_the_wall_camera_writes_black_bezels() {
    let dir = cli::tmp_dir("wall-render");
    let out = dir.join("wall.exr");
    let o = cli::raygun(&[
        "render",
        "--scene",
        "builtin:cornell",
        "--display",
        "hornet",
        "--camera",
        "wall",
        "--eye",
        "0,0,1",
        "--world-from-room",
        "auto",
        "--size",
        "1690,682",
        "--spp",
        "1",
        "--max-depth",
        "1",
        "--backend",
        "cpu",
        "--quiet",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", cli::stderr(&o));
    let img = exr::prelude::read_first_flat_layer_from_file(&out).unwrap();
    let ch = &img.layer_data.channel_data.list;
    let r: Vec<f32> = ch[2].sample_data.values_as_f32().collect();
    let model = DisplayModel::open("hornet").unwrap().0;
    let wc = wall(&model, [1690, 682], DVec3::new(0.0, 0.0, 1.0));
    let hidden: Vec<usize> = (0..r.len()).filter(|&p| !wc.is_shown(p as u32)).collect();
    assert!(!hidden.is_empty());
    assert!(hidden.iter().all(|&p| r[p] == 0.0));
    let lit = (0..r.len()).filter(|&p| r[p] > 0.0).count();
    assert!(lit > r.len() / 4, "{lit} lit pixels of {}", r.len());
}
