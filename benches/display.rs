//! `cargo bench --bench display [-- W,H [ROUNDS]]`: the viewer's conversion of a linear picture
//! to the 8-bit sRGB RGBA it shows (default 3840×2160, 9 rounds), three ways side by side in
//! each round — the sRGB curve by `powf` per channel on one thread (the conversion before the
//! table), the table (`output::srgb8::linear_to_srgb8`) on one thread, and
//! `output::srgb8::display_rgba` (the table on all cores, what the viewer runs) — in ms per
//! picture (minimum and median over the rounds) and as ratios of the minima. The three give the
//! same bytes (checked before timing). Then two of the passes the viewer makes over every shown
//! picture besides: the noise image (each pixel's standard error) and the ROI's outline, one
//! thread (the code before, kept here) against `viewer::diagnostics` on all cores, again checked
//! equal first. Last, a window picture under the sample-count overlay on the CPU twin and, where
//! there is one, the GPU (a guided Cornell box at a quarter of the size, 960×540 by default): with the filtered image made as
//! the window did before (`ViewerCore::picture`) against without it
//! (`ViewerCore::window_picture`, which no longer filters for an overlay that does not show the
//! image), the same bytes checked first; and before it the window's loop without a window
//! (30 ms of rendering a UI frame, then a picture every UI frame or only when one is due:
//! iterations and pictures per second).

use std::hint::black_box;
use std::time::Instant;

use glam::Vec3;
use raygun::output::srgb8::{display_rgba, linear_to_srgb8};
use raygun::output::{linear_to_srgb, unit_to_u8};
use raygun::trace::accum::Accumulation;
use raygun::viewer::diagnostics::{noise_image, roi_outline};

/// The noise image on one thread (the code before it ran on all cores).
fn noise_one_thread(acc: &Accumulation) -> Vec<f32> {
    (0..acc.count.len())
        .map(|i| {
            acc.luminance_variance_of_mean(i)
                .map_or(f32::NAN, f32::sqrt)
        })
        .collect()
}

/// The ROI outline on one thread (the code before it ran on all cores).
fn outline_one_thread(dgi: &[f32], (w, h): (usize, usize)) -> Vec<usize> {
    let mut out = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            if dgi[i] != 0.0 {
                continue;
            }
            let outside = |j: usize| dgi[j] > 0.0;
            if (x > 0 && outside(i - 1))
                || (x + 1 < w && outside(i + 1))
                || (y > 0 && outside(i - w))
                || (y + 1 < h && outside(i + w))
            {
                out.push(i);
            }
        }
    }
    out
}

fn by_powf(image: &[Vec3], scale: f32) -> Vec<u8> {
    image
        .iter()
        .flat_map(|p| {
            let s = |v: f32| unit_to_u8(linear_to_srgb(v * scale));
            [s(p.x), s(p.y), s(p.z), 255]
        })
        .collect()
}

fn by_table(image: &[Vec3], scale: f32) -> Vec<u8> {
    image
        .iter()
        .flat_map(|p| {
            let s = |v: f32| linear_to_srgb8(v * scale);
            [s(p.x), s(p.y), s(p.z), 255]
        })
        .collect()
}

fn main() {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| !a.starts_with("--"))
        .collect();
    let (w, h) = match args.first().and_then(|s| s.split_once(',')) {
        Some((w, h)) => (
            w.parse().expect("W,H: width"),
            h.parse().expect("W,H: height"),
        ),
        None => (3840usize, 2160usize),
    };
    let rounds: usize = args.get(1).map_or(9, |r| r.parse().expect("ROUNDS"));
    // A rendered picture's spread of values: mostly in [0, 1], some above (lights), a few
    // below zero and NaN-free, from a fixed hash.
    let image: Vec<Vec3> = (0..w * h)
        .map(|i| {
            let u = |k: u32| {
                let x = (i as u32).wrapping_mul(0x9E37_79B9) ^ k.wrapping_mul(0x85EB_CA6B);
                let x = (x ^ (x >> 15)).wrapping_mul(0x2C1B_3C6D);
                (x ^ (x >> 12)) as f32 / u32::MAX as f32
            };
            Vec3::new(u(1) * 1.2, u(2) * u(2), u(3) * 3.0 - 0.1)
        })
        .collect();
    let exposure = 0.0f32;
    let scale = exposure.exp2();
    let reference = by_powf(&image, scale);
    assert!(
        by_table(&image, scale) == reference,
        "table differs from powf"
    );
    assert!(
        display_rgba(&image, exposure) == reference,
        "display_rgba differs from powf"
    );
    let threads = rayon::current_num_threads();
    let mut ms = [Vec::new(), Vec::new(), Vec::new()];
    for _ in 0..rounds {
        let t = Instant::now();
        black_box(by_powf(black_box(&image), scale));
        ms[0].push(t.elapsed().as_secs_f64() * 1e3);
        let t = Instant::now();
        black_box(by_table(black_box(&image), scale));
        ms[1].push(t.elapsed().as_secs_f64() * 1e3);
        let t = Instant::now();
        black_box(display_rgba(black_box(&image), exposure));
        ms[2].push(t.elapsed().as_secs_f64() * 1e3);
    }
    let stat = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        (v[0], v[v.len() / 2])
    };
    let rows = ["powf, one thread", "table, one thread"];
    let mins: Vec<(f64, f64)> = ms.iter_mut().map(stat).collect();
    println!(
        "display conversion, {w}×{h} RGBA8, {rounds} rounds, {threads} threads for the last row"
    );
    println!("| conversion | ms min | ms median | ÷ powf (minima) |");
    println!("|---|---|---|---|");
    for (i, (min, med)) in mins.iter().enumerate() {
        let name = rows
            .get(i)
            .map_or(format!("display_rgba: table, {threads} threads"), |s| {
                (*s).to_string()
            });
        println!("| {name} | {min:.2} | {med:.2} | ×{:.3} |", min / mins[0].0);
    }

    // The statistics passes, on an accumulation of 0–19 samples a pixel and a DGI whose ROI is
    // a disc of a third of the height.
    let hash = |i: usize, k: u32| {
        let x = (i as u32).wrapping_mul(0x9E37_79B9) ^ k.wrapping_mul(0x85EB_CA6B);
        ((x ^ (x >> 15)).wrapping_mul(0x2C1B_3C6D) >> 8) as f32 / (1 << 24) as f32
    };
    let count: Vec<u32> = (0..w * h).map(|i| (hash(i, 1) * 20.0) as u32).collect();
    let acc = Accumulation {
        width: w as u32,
        height: h as u32,
        sum: (0..w * h)
            .map(|i| {
                let c = count[i] as f32;
                [
                    hash(i, 2) * c,
                    hash(i, 3) * c,
                    hash(i, 4) * c,
                    2.0 * hash(i, 5) * c,
                ]
            })
            .collect(),
        count,
    };
    let dgi: Vec<f32> = (0..w * h)
        .map(|i| {
            let (x, y) = (
                (i % w) as f32 - w as f32 / 2.0,
                (i / w) as f32 - h as f32 / 2.0,
            );
            ((x.hypot(y) - h as f32 / 6.0) / h as f32).clamp(0.0, 1.0)
        })
        .collect();
    let same_noise = noise_image(&acc)
        .iter()
        .zip(noise_one_thread(&acc))
        .all(|(a, b)| a.to_bits() == b.to_bits());
    assert!(same_noise, "noise images differ");
    assert!(
        roi_outline(&dgi, [w as u32, h as u32]) == outline_one_thread(&dgi, (w, h)),
        "outlines differ"
    );
    let mut st = [Vec::new(), Vec::new(), Vec::new(), Vec::new()];
    for _ in 0..rounds {
        let t = Instant::now();
        black_box(noise_one_thread(black_box(&acc)));
        st[0].push(t.elapsed().as_secs_f64() * 1e3);
        let t = Instant::now();
        black_box(noise_image(black_box(&acc)));
        st[1].push(t.elapsed().as_secs_f64() * 1e3);
        let t = Instant::now();
        black_box(outline_one_thread(black_box(&dgi), (w, h)));
        st[2].push(t.elapsed().as_secs_f64() * 1e3);
        let t = Instant::now();
        black_box(roi_outline(black_box(&dgi), [w as u32, h as u32]));
        st[3].push(t.elapsed().as_secs_f64() * 1e3);
    }
    let st: Vec<(f64, f64)> = st.iter_mut().map(stat).collect();
    println!();
    println!("the viewer's statistics passes, {w}×{h}, {rounds} rounds");
    println!(
        "| pass | one thread: ms min / median | {threads} threads: ms min / median | ÷ one thread (minima) |"
    );
    println!("|---|---|---|---|");
    for (name, one, all) in [("noise image", st[0], st[1]), ("ROI outline", st[2], st[3])] {
        println!(
            "| {name} | {:.2} / {:.2} | {:.2} / {:.2} | ×{:.3} |",
            one.0,
            one.1,
            all.0,
            all.1,
            all.0 / one.0
        );
    }
    overlay_window(&raygun::gpu::Backend::Cpu, w / 4, h / 4, rounds);
    // And on the GPU where there is one (its host path: the filter's round trip).
    if let Ok(ctx) = raygun::gpu::GpuContext::new() {
        overlay_window(
            &raygun::gpu::Backend::Gpu(Box::new(ctx)),
            w / 4,
            h / 4,
            rounds,
        );
    }
}

/// A window picture under the sample-count overlay on `backend`, with and without the filtered
/// image.
fn overlay_window(backend: &raygun::gpu::Backend, w: usize, h: usize, rounds: usize) {
    use raygun::display::DisplayModel;
    use raygun::scene::Scene;
    use raygun::trace::camera::RenderCamera;
    use raygun::trace::path::TraceSettings;
    use raygun::viewer::core::ViewerCore;
    use raygun::viewer::state::{Overlay, RoiSource, ViewerState};
    let model = DisplayModel::open("hornet")
        .expect("the builtin HORNET model")
        .0;
    let scene = Scene::open("builtin:cornell").expect("the builtin Cornell box");
    let (w, h) = (w as u32, h as u32);
    let base = TraceSettings {
        width: w,
        height: h,
        seed: 5,
        max_depth: 3,
        camera: RenderCamera::choose(&scene, None, w, h).expect("a camera"),
    };
    let mut state = ViewerState::new(RoiSource::Mouse, 3);
    state.click(
        &model,
        glam::DVec2::new(f64::from(w) / 2.0, f64::from(h) / 2.0),
        [w, h],
    );
    state.overlay = Overlay::Counts;
    let mut core = ViewerCore::new(backend, &scene, &model, base, state).expect("a viewer");
    for _ in 0..2 {
        core.step(std::time::Duration::ZERO).expect("a frame");
    }
    assert!(
        core.window_picture().expect("window").rgba == core.picture().expect("picture").rgba,
        "window and picture differ"
    );
    ui_loop(&mut core, w, h, backend);
    let mut ms = [Vec::new(), Vec::new()];
    for _ in 0..rounds {
        let t = Instant::now();
        black_box(core.picture().expect("picture"));
        ms[0].push(t.elapsed().as_secs_f64() * 1e3);
        let t = Instant::now();
        black_box(core.window_picture().expect("window"));
        ms[1].push(t.elapsed().as_secs_f64() * 1e3);
    }
    let stat = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        (v[0], v[v.len() / 2])
    };
    let (before, after) = (stat(&mut ms[0]), stat(&mut ms[1]));
    println!();
    println!(
        "a window picture under the sample-count overlay, guided Cornell box {w}×{h}, default filter, {rounds} rounds; {}",
        backend.describe()
    );
    println!("| window picture | ms min | ms median |");
    println!("|---|---|---|");
    println!(
        "| with the filtered image (before) | {:.2} | {:.2} |",
        before.0, before.1
    );
    println!(
        "| without it (`window_picture`) | {:.2} | {:.2} |",
        after.0, after.1
    );
}

/// The window's loop without a window, under the image overlay: each UI frame renders for 30 ms
/// (`viewer::app::FRAME_BUDGET`), then makes a picture — every UI frame (before) or only when
/// one is due (`ViewerCore::picture_due`, after), 4 s each, twice alternating: iterations
/// rendered and pictures made per second.
fn ui_loop(
    core: &mut raygun::viewer::core::ViewerCore,
    w: u32,
    h: u32,
    backend: &raygun::gpu::Backend,
) {
    use raygun::viewer::state::Overlay;
    let overlay = core.state.overlay;
    core.state.overlay = Overlay::Image;
    let budget = std::time::Duration::from_millis(30);
    let mut rows = [(0.0, 0.0, 0.0), (0.0, 0.0, 0.0)];
    for round in 0..4 {
        let when_due = round % 2 == 1;
        let start_iterations = core.stats.iterations;
        let (t0, mut pictures) = (Instant::now(), 0u32);
        while t0.elapsed().as_secs_f64() < 4.0 {
            core.step(budget).expect("frames");
            if !when_due || core.picture_due() {
                black_box(core.window_picture().expect("picture"));
                pictures += 1;
            }
        }
        let secs = t0.elapsed().as_secs_f64();
        let r = &mut rows[usize::from(when_due)];
        r.0 += f64::from(core.stats.iterations - start_iterations) / secs / 2.0;
        r.1 += f64::from(pictures) / secs / 2.0;
        r.2 += core.picture_took().map_or(0.0, |d| d.as_secs_f64() * 1e3) / 2.0;
    }
    core.state.overlay = overlay;
    println!();
    println!(
        "the window's loop, image overlay, guided Cornell box {w}×{h}, 30 ms of rendering a UI frame, 2 × 4 s each, alternating; {}",
        backend.describe()
    );
    println!("| pictures | iterations/s | pictures/s | ms a picture (last) |");
    println!("|---|---|---|---|");
    for (name, r) in ["every UI frame (before)", "when due (`picture_due`)"]
        .iter()
        .zip(rows)
    {
        println!("| {name} | {:.1} | {:.1} | {:.1} |", r.0, r.1, r.2);
    }
}
