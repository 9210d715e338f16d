//! The picture as a window shows it (`Renderer::shown_picture`): on the GPU (lavapipe in CI) it
//! stays there — the filter reads the renderer's own buffers and the display kernel converts —
//! and must give the bytes of the host path it replaces (read back, filter, convert on the CPU:
//! `display_rgba(picture(..))`, the ROI's outline painted from the DGI read back), byte for
//! byte, for guided, full-frame and wall-camera renders, across frames, filter settings,
//! exposures and with and without the outline. The unfiltered mean divides on the GPU
//! instead of the CPU (WGSL's division need not round as the CPU's does), so it may differ by
//! one code where the mean lies on a step.

use glam::DVec3;
use raygun::display::DisplayModel;
use raygun::filter::{Blend, FilterKind, FilterParams};
use raygun::frame::{GuideConfig, Render, Renderer};
use raygun::gpu::{Backend, GpuContext};
use raygun::output::srgb8::{OUTLINE, display_rgba, paint_outline, roi_outline};
use raygun::roi::cone::Cone;
use raygun::roi::dgi::Roi;
use raygun::scene::Scene;
use raygun::trace::camera::RenderCamera;
use raygun::trace::path::TraceSettings;
use raygun::trace::wall::{WallCamera, WorldFromRoom};

const SIZE: [u32; 2] = [96, 40];

fn settings(scene: &Scene) -> TraceSettings {
    settings_of(scene, SIZE)
}

fn settings_of(scene: &Scene, [w, h]: [u32; 2]) -> TraceSettings {
    TraceSettings {
        width: w,
        height: h,
        seed: 11,
        max_depth: 3,
        camera: RenderCamera::choose(scene, None, w, h).unwrap(),
    }
}

/// HORNET at a tenth of its canvas: its bezels hide some pixels (at 845 × 341 and below every
/// pixel is some tile's, DESIGN.md §11).
const WALL_SIZE: [u32; 2] = [1352, 546];

fn roi() -> Roi {
    Roi::Cone(
        Cone::from_pose(
            DVec3::new(0.3, 0.0, 1.0),
            DVec3::NEG_Z,
            DVec3::Y,
            25.0,
            25.0,
        )
        .unwrap(),
    )
}

fn params() -> Vec<FilterParams> {
    vec![
        FilterParams::default(),
        FilterParams {
            kind: FilterKind::Exact,
            k_max: 6.0,
            ..FilterParams::default()
        },
        FilterParams {
            kind: FilterKind::Fast,
            blend: Blend::Variance,
            k_max: 32.0,
            ..FilterParams::default()
        },
        FilterParams {
            kind: FilterKind::Off,
            ..FilterParams::default()
        },
    ]
}

/// The shown picture equals the host path's bytes (within one code, on few pixels, for the
/// unfiltered mean), and is not a flat picture; with `outline` (and an ROI) the outline is
/// painted over both.
fn check_same(r: &Renderer, p: &FilterParams, exposure: f32, outline: bool, what: &str) {
    let shown = r.shown_picture(p, exposure, outline, false).unwrap();
    let size = [r.settings.width, r.settings.height];
    assert_eq!(shown.size, size);
    let mut host = display_rgba(&r.picture(p).unwrap(), exposure);
    if outline && r.roi().is_some() {
        let pixels = roi_outline(&r.dgi().unwrap(), size);
        assert!(!pixels.is_empty(), "{what}: an outline to paint");
        paint_outline(&mut host, &pixels);
    }
    assert_eq!(shown.rgba.len(), host.len(), "{what}");
    let distinct: std::collections::BTreeSet<u8> = shown.rgba.iter().copied().collect();
    assert!(distinct.len() > 20, "{what}: a flat picture proves nothing");
    if p.kind == FilterKind::Off {
        let off: Vec<usize> = (0..host.len())
            .filter(|&i| shown.rgba[i] != host[i])
            .collect();
        assert!(
            off.iter().all(|&i| shown.rgba[i].abs_diff(host[i]) <= 1),
            "{what}: the mean differs by more than a code"
        );
        assert!(
            off.len() * 100 <= host.len(),
            "{what}: {} codes off",
            off.len()
        );
    } else if let Some(i) = (0..host.len()).find(|&i| shown.rgba[i] != host[i]) {
        panic!(
            "{what}: byte {i} (pixel {}, channel {}): shown {} host {}",
            i / 4,
            i % 4,
            shown.rgba[i],
            host[i]
        );
    }
}

fn gpu() -> Backend {
    Backend::Gpu(Box::new(GpuContext::for_tests()))
}

#[test]
fn a_guided_render_shows_the_host_paths_bytes_across_frames_settings_and_exposures() {
    let backend = gpu();
    let model = DisplayModel::open("hornet").unwrap().0;
    let scene = Scene::builtin("cornell").unwrap();
    let mut r = Renderer::guided(
        &backend,
        &scene,
        settings(&scene),
        &model,
        GuideConfig {
            p_min: 0.05,
            ..GuideConfig::default()
        },
    )
    .unwrap();
    assert!(r.shows_on_gpu(&FilterParams::default()));
    r.set_roi(Some(roi())).unwrap();
    r.iterate(2).unwrap();
    for (k, p) in params().iter().enumerate() {
        check_same(&r, p, 0.0, k % 2 == 0, &format!("settings {k}"));
    }
    // More frames into the same bindings: the shown picture follows the accumulation.
    let before = r
        .shown_picture(&params()[0], 0.0, false, false)
        .unwrap()
        .rgba;
    r.iterate(3).unwrap();
    let after = r
        .shown_picture(&params()[0], 0.0, false, false)
        .unwrap()
        .rgba;
    assert_ne!(before, after, "the shown picture is of the latest frames");
    check_same(&r, &params()[0], 0.0, false, "after more frames");
    // Exposure and the outline change on kept bindings.
    for e in [1.5, -2.0] {
        check_same(&r, &params()[0], e, true, &format!("exposure {e}, outline"));
        check_same(&r, &params()[0], e, false, &format!("exposure {e}"));
    }
    let outlined = r
        .shown_picture(&params()[0], 0.0, true, false)
        .unwrap()
        .rgba;
    let painted = outlined.chunks_exact(4).filter(|p| *p == OUTLINE).count();
    assert!(painted > 10, "{painted} outline pixels");
    // A moved ROI (a new DGI installed by the next frame) is filtered with the new DGI.
    r.set_roi(Some(Roi::Cone(
        Cone::from_pose(
            DVec3::new(-0.8, 0.2, 1.0),
            DVec3::NEG_Z,
            DVec3::Y,
            10.0,
            10.0,
        )
        .unwrap(),
    )))
    .unwrap();
    r.iterate(1).unwrap();
    check_same(&r, &params()[1], 0.0, false, "moved ROI");
    // The outline follows the new DGI on the GPU.
    check_same(&r, &params()[1], 0.0, true, "moved ROI, outline");
    let moved = r
        .shown_picture(&params()[1], 0.0, true, false)
        .unwrap()
        .rgba;
    let at = |rgba: &[u8]| -> Vec<usize> {
        (0..rgba.len() / 4)
            .filter(|&i| rgba[4 * i..4 * i + 4] == OUTLINE)
            .collect()
    };
    assert_ne!(at(&moved), at(&outlined), "the outline moved with the ROI");
    // Timing reports the resident path and positive stage times.
    let t = r
        .shown_picture(&params()[0], 0.0, true, true)
        .unwrap()
        .times
        .unwrap();
    assert!(t.resident);
    assert!(
        t.filter_ms > 0.0 && t.display_ms > 0.0 && t.wall_ms > 0.0,
        "{t:?}"
    );
}

#[test]
fn a_full_frame_render_shows_the_host_paths_bytes() {
    let backend = gpu();
    let scene = Scene::builtin("cornell").unwrap();
    let mut r = Renderer::full(&backend, &scene, settings(&scene)).unwrap();
    r.iterate(2).unwrap();
    for (k, p) in params().iter().enumerate() {
        // No ROI: nothing outlined either way.
        check_same(&r, p, 0.5, k % 2 == 1, &format!("full frame, settings {k}"));
    }
}

#[test]
fn a_wall_camera_render_shows_its_unshown_pixels_black() {
    let backend = gpu();
    let model = DisplayModel::open("hornet").unwrap().0;
    let scene = Scene::builtin("cornell").unwrap();
    let s = settings_of(&scene, WALL_SIZE);
    let c = &s.camera;
    let wall = WallCamera::new(
        &model,
        WALL_SIZE,
        DVec3::new(0.0, 0.0, 1.0),
        &WorldFromRoom::Auto,
        (c.position.as_dvec3(), c.forward.as_dvec3(), c.up.as_dvec3()),
    )
    .unwrap();
    let unshown = (0..WALL_SIZE[0] * WALL_SIZE[1])
        .filter(|&p| !wall.is_shown(p))
        .count();
    assert!(unshown > 0, "HORNET's bezels hide some pixels");
    let mut r = Renderer::guided_wall(
        &backend,
        &scene,
        s,
        &model,
        GuideConfig::default(),
        Some(wall.clone()),
    )
    .unwrap();
    r.set_roi(Some(roi())).unwrap();
    r.iterate(2).unwrap();
    for (k, p) in params().iter().enumerate() {
        check_same(
            &r,
            p,
            0.0,
            k % 2 == 1,
            &format!("wall camera, settings {k}"),
        );
    }
    let shown = r
        .shown_picture(&params()[0], 0.0, false, false)
        .unwrap()
        .rgba;
    for p in 0..WALL_SIZE[0] * WALL_SIZE[1] {
        if !wall.is_shown(p) {
            let i = 4 * p as usize;
            assert_eq!(shown[i..i + 4], [0, 0, 0, 255], "unshown pixel {p}");
        }
    }
}

/// The CPU twin takes the host path: the same function, its bytes exactly.
#[test]
fn the_cpu_twin_shows_its_picture_converted() {
    let backend = Backend::Cpu;
    let model = DisplayModel::open("hornet").unwrap().0;
    let scene = Scene::builtin("cornell").unwrap();
    let mut r = Renderer::guided(
        &backend,
        &scene,
        settings(&scene),
        &model,
        GuideConfig::default(),
    )
    .unwrap();
    assert!(!r.shows_on_gpu(&FilterParams::default()));
    r.set_roi(Some(roi())).unwrap();
    r.iterate(2).unwrap();
    let p = FilterParams::default();
    let shown = r.shown_picture(&p, 0.25, false, true).unwrap();
    assert_eq!(shown.rgba, display_rgba(&r.picture(&p).unwrap(), 0.25));
    check_same(&r, &p, 0.25, true, "CPU twin, outline");
    assert!(!shown.times.unwrap().resident);
}

/// A frame split into bands of rows (an adapter whose binding holds less than the frame) takes
/// the host path, and shows what one band shows on the resident path: the accumulation is the
/// same bit for bit, and the exact filter's bands are the whole image's values.
#[test]
fn a_banded_frame_takes_the_host_path_and_shows_the_same_picture() {
    let scene = Scene::builtin("cornell").unwrap();
    let whole = gpu();
    // 96 × 40 × 16 bytes = 61 440: a quarter of it per binding.
    let cap = 16 * 96 * 10;
    let banded = Backend::Gpu(Box::new(GpuContext::with_max_binding(cap).unwrap()));
    let p = FilterParams {
        kind: FilterKind::Exact,
        k_max: 3.0,
        ..FilterParams::default()
    };
    let mut pictures = Vec::new();
    for backend in [&whole, &banded] {
        let mut r = Renderer::full(backend, &scene, settings(&scene)).unwrap();
        r.iterate(2).unwrap();
        pictures.push((
            r.gpu_bands(),
            r.shows_on_gpu(&p),
            r.shown_picture(&p, 0.0, false, false).unwrap().rgba,
        ));
    }
    assert_eq!((pictures[0].0, pictures[0].1), (Some(1), true));
    assert!(
        pictures[1].0.unwrap() > 1 && !pictures[1].1,
        "{:?}",
        (pictures[1].0, pictures[1].1)
    );
    assert!(
        pictures[0].2 == pictures[1].2,
        "banded and whole pictures differ"
    );
}

/// A texture of `size` that a picture can be written into and read back from.
fn picture_texture(
    ctx: &GpuContext,
    [w, h]: [u32; 2],
    format: wgpu::TextureFormat,
) -> wgpu::Texture {
    ctx.picture_texture(
        "test picture",
        [w, h],
        format,
        wgpu::TextureUsages::COPY_DST | wgpu::TextureUsages::COPY_SRC,
    )
}

/// The picture written into a texture on the GPU (what a window drawing with the renderer's
/// device shows: nothing read back) is the shown picture's bytes, for a width whose rows copy
/// at once (128: 512 bytes a row) and one whose rows are padded for the copy (96: 384 bytes, 512 apart), in both 8-bit
/// formats, and follows the frames; a texture of another size or format, a CPU renderer and a
/// frame in bands are refused with errors that say why.
#[test]
fn a_picture_written_into_a_texture_is_the_shown_pictures_bytes() {
    let backend = gpu();
    let Backend::Gpu(ctx) = &backend else {
        unreachable!("a GPU backend")
    };
    let model = DisplayModel::open("hornet").unwrap().0;
    let scene = Scene::builtin("cornell").unwrap();
    let p = FilterParams::default();
    for size in [[128, 40], SIZE] {
        let mut r = Renderer::guided(
            &backend,
            &scene,
            settings_of(&scene, size),
            &model,
            GuideConfig::default(),
        )
        .unwrap();
        r.set_roi(Some(roi())).unwrap();
        r.iterate(2).unwrap();
        for format in [
            wgpu::TextureFormat::Rgba8UnormSrgb,
            wgpu::TextureFormat::Rgba8Unorm,
        ] {
            let texture = picture_texture(ctx, size, format);
            r.shown_picture_into(&p, 0.5, true, &texture).unwrap();
            let shown = r.shown_picture(&p, 0.5, true, false).unwrap().rgba;
            let got = ctx.read_texture(&texture).unwrap();
            assert!(got == shown, "{size:?} {format:?}: the texture differs");
            assert!(
                got.chunks_exact(4).any(|t| t == OUTLINE),
                "{size:?}: no outline"
            );
        }
        // The next frames reach the same texture.
        let texture = picture_texture(ctx, size, wgpu::TextureFormat::Rgba8UnormSrgb);
        r.shown_picture_into(&p, 0.0, false, &texture).unwrap();
        let before = ctx.read_texture(&texture).unwrap();
        r.iterate(2).unwrap();
        r.shown_picture_into(&p, 0.0, false, &texture).unwrap();
        let after = ctx.read_texture(&texture).unwrap();
        assert_ne!(
            before, after,
            "{size:?}: the texture shows the latest frames"
        );
        assert!(after == r.shown_picture(&p, 0.0, false, false).unwrap().rgba);
        // Timed: waited for, the stages' times inside the call's.
        r.iterate(1).unwrap();
        let t = r.shown_picture_into_timed(&p, 0.0, true, &texture).unwrap();
        assert!(
            t.resident && t.filter_ms > 0.0 && t.display_ms > 0.0,
            "{t:?}"
        );
        // (GPU timestamps and the CPU's clock differ by the timestamp period's calibration.)
        assert!(
            t.wall_ms * 1.01 + 0.05 >= t.filter_ms.max(t.display_ms),
            "{t:?}"
        );
        assert!(
            ctx.read_texture(&texture).unwrap()
                == r.shown_picture(&p, 0.0, true, false).unwrap().rgba
        );
        // Refused: another size, a format of other texels.
        for (tsize, format) in [
            ([size[0] + 1, size[1]], wgpu::TextureFormat::Rgba8UnormSrgb),
            (size, wgpu::TextureFormat::Bgra8Unorm),
        ] {
            let wrong = picture_texture(ctx, tsize, format);
            let e = r.shown_picture_into(&p, 0.0, false, &wrong).unwrap_err();
            let message = e.to_string();
            assert!(
                message.contains(&format!("{}×{}", size[0], size[1]))
                    && message.contains(&format!("{format:?}")),
                "{message}"
            );
        }
    }
    // A CPU renderer and a frame in bands keep their pictures on the host.
    let texture = picture_texture(ctx, SIZE, wgpu::TextureFormat::Rgba8UnormSrgb);
    let cpu = Backend::Cpu;
    let banded = Backend::Gpu(Box::new(
        GpuContext::with_max_binding(16 * 96 * 10).unwrap(),
    ));
    for backend in [&cpu, &banded] {
        let mut r = Renderer::full(backend, &scene, settings(&scene)).unwrap();
        r.iterate(1).unwrap();
        let e = r.shown_picture_into(&p, 0.0, false, &texture).unwrap_err();
        assert!(e.to_string().contains("does not stay on a GPU"), "{e}");
    }
}
