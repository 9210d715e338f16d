//! The viewer's denoised picture (DESIGN.md §8): raygun's interactive denoiser on every picture,
//! Intel Open Image Denoise's once the ROI and the eye have been still, closer to a converged
//! reference than the filter's picture, and on a GPU the host path with the same bytes in the
//! window as in the picture.

use std::time::{Duration, Instant};

use glam::{DVec2, Vec3};
use raygun::filter::DenoiseKind;
use raygun::filter::oidn::{DeviceChoice, Oidn};
use raygun::frame::Renderer;
use raygun::gpu::Backend;
use raygun::scene::{Environment, Scene};
use raygun::trace::camera::RenderCamera;
use raygun::trace::path::TraceSettings;
use raygun::viewer::core::{ShownDenoiser, ViewerCore};
use raygun::viewer::state::{RoiSource, STILL_SECONDS, ViewerState};

use crate::walls::hornet;

const W: u32 = 64;
const H: u32 = 26;

fn scene() -> Scene {
    let mut s = Scene::open("builtin:cornell-light").unwrap();
    s.environment = Environment::Constant(Vec3::splat(0.5));
    s
}

fn base(scene: &Scene) -> TraceSettings {
    TraceSettings {
        width: W,
        height: H,
        seed: 3,
        max_depth: 4,
        camera: RenderCamera::choose(scene, None, W, H).unwrap(),
    }
}

fn state(denoise: DenoiseKind) -> ViewerState {
    let mut state = ViewerState::new(RoiSource::Mouse, 4);
    state.mouse_radius_px = 1200.0;
    state.click(&hornet(), DVec2::new(32.5, 13.5), [W, H]);
    state.denoise = denoise;
    state
}

fn mse(a: &[Vec3], b: &[Vec3]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(a, b)| f64::from((*a - *b).length_squared()))
        .sum::<f64>()
        / a.len() as f64
}

#[test]
fn the_viewer_denoises_every_picture_and_shows_oidns_once_still() {
    let (model, scene, backend) = (hornet(), scene(), Backend::Cpu);
    let mut reference = Renderer::full(&backend, &scene, base(&scene)).unwrap();
    reference.iterate(256).unwrap();
    let reference = reference.accumulation().unwrap().mean_image();

    let mut core = ViewerCore::new(
        &backend,
        &scene,
        &model,
        base(&scene),
        state(DenoiseKind::Off),
    )
    .unwrap();
    for _ in 0..6 {
        core.step(Duration::ZERO).unwrap();
    }
    let off = core.picture().unwrap();
    assert_eq!(core.stats.denoised_by, None);
    core.state.denoise = DenoiseKind::Interactive;
    assert!(core.picture_due(), "a changed denoiser is shown at once");
    let interactive = core.picture().unwrap();
    assert_eq!(core.stats.denoised_by, Some(ShownDenoiser::Interactive));
    assert!(interactive.image.iter().all(|v| v.is_finite()));
    let (e_off, e_int) = (
        mse(&off.image, &reference),
        mse(&interactive.image, &reference),
    );
    assert!(
        e_int < e_off,
        "interactive MSE {e_int} against the filter's {e_off}"
    );

    // Asked for OIDN without it: the interactive denoiser all the same.
    core.state.denoise = DenoiseKind::Oidn;
    assert_eq!(core.shown_denoiser(), Some(ShownDenoiser::Interactive));
    core.set_oidn(Oidn::load().unwrap().device(DeviceChoice::Cpu).unwrap());
    // The ROI moves: the interactive denoiser while it has not been still for a second.
    core.state.mouse_radius_px += 50.0;
    let t = Instant::now();
    core.step(Duration::ZERO).unwrap();
    let moving = core.shown_denoiser();
    if t.elapsed().as_secs_f64() < STILL_SECONDS {
        assert_eq!(moving, Some(ShownDenoiser::Interactive));
    }
    std::thread::sleep(Duration::from_secs_f64(STILL_SECONDS));
    assert_eq!(core.shown_denoiser(), Some(ShownDenoiser::Oidn));
    assert!(
        core.picture_due(),
        "OIDN's picture is shown as soon as it is due"
    );
    let still = core.picture().unwrap();
    assert_eq!(core.stats.denoised_by, Some(ShownDenoiser::Oidn));
    let e_oidn = mse(&still.image, &reference);
    assert!(
        e_oidn < e_off,
        "OIDN MSE {e_oidn} against the filter's {e_off}"
    );
    // Off again: the filter's picture, bit for bit as before the denoisers.
    core.state.denoise = DenoiseKind::Off;
    let again = core.picture().unwrap();
    assert_eq!(core.stats.denoised_by, None);
    assert_ne!(again.image, still.image);
}

/// On a GPU a denoised picture takes the host path (its features and the denoiser's buffers are
/// not the renderer's): the window shows the picture's bytes.
#[test]
fn a_denoised_gpu_window_picture_is_the_pictures_bytes() {
    let (model, scene) = (hornet(), scene());
    let backend = Backend::Gpu(Box::new(raygun::gpu::GpuContext::for_tests()));
    let mut core = ViewerCore::new(
        &backend,
        &scene,
        &model,
        base(&scene),
        state(DenoiseKind::Interactive),
    )
    .unwrap();
    for _ in 0..4 {
        core.step(Duration::ZERO).unwrap();
    }
    let window = core.window_picture().unwrap();
    assert!(
        !window.resident,
        "a denoised picture is made on the host path"
    );
    assert_eq!(core.stats.denoised_by, Some(ShownDenoiser::Interactive));
    let picture = core.picture().unwrap();
    assert_eq!(window.rgba, picture.rgba);
    core.state.denoise = DenoiseKind::Off;
    assert!(
        core.window_picture().unwrap().resident,
        "off: on the GPU as before"
    );
}
