//! Iterations and time per call of the closest-point solvers (f64 and the f32 mirror of the
//! WGSL), on the hard-case set and on a 3840×2160 grid of pixel centres around a typical
//! ellipse. Run with `cargo run --release --example ellipse_bench` on an otherwise idle core;
//! `--worst` also lists the cases that need the most iterations.

use std::hint::black_box;
use std::time::Instant;

use glam::DVec2;
use raygun::roi::ellipse::{
    closest_point_on_ellipse, closest_point_on_ellipse_f32, distance_to_filled_ellipse,
    distance_to_filled_ellipse_f32,
};

fn reference_distances() -> Vec<f64> {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/ellipse_hard_cases.csv"
    );
    let text = std::fs::read_to_string(path).expect("hard-case file");
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with("a,"))
        .map(|l| l.split(',').nth(4).expect("d_ref").parse().expect("number"))
        .collect()
}

fn hard_cases() -> Vec<(String, [f64; 4])> {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/ellipse_hard_cases.csv"
    );
    let text = std::fs::read_to_string(path).expect("hard-case file");
    text.lines()
        .filter(|l| !l.starts_with('#') && !l.starts_with("a,"))
        .map(|l| {
            let f: Vec<&str> = l.split(',').collect();
            let v = |k: usize| f[k].parse::<f64>().expect("number");
            (f[9].to_owned(), [v(0), v(1), v(2), v(3)])
        })
        .collect()
}

struct Stats {
    mean_iterations: f64,
    max_iterations: u32,
    ns_per_call: f64,
}

/// `iterations` gives the solver's iteration count for a case (0 where it does not run);
/// `timed` is the call whose time is measured.
fn measure<I: Fn(&[f64; 4]) -> u32, T: Fn(&[f64; 4]) -> f64>(
    cases: &[[f64; 4]],
    repeats: usize,
    iterations: I,
    timed: T,
) -> Stats {
    let (mut sum, mut max) = (0u64, 0u32);
    for c in cases {
        let it = iterations(c);
        sum += u64::from(it);
        max = max.max(it);
    }
    let t = Instant::now();
    for _ in 0..repeats {
        for c in cases {
            black_box(timed(black_box(c)));
        }
    }
    let ns = t.elapsed().as_nanos() as f64 / (repeats * cases.len()) as f64;
    Stats {
        mean_iterations: sum as f64 / cases.len() as f64,
        max_iterations: max,
        ns_per_call: ns,
    }
}

fn print(name: &str, s: &Stats) {
    println!(
        "{name:<44} mean {:>5.2} max {:>3} iterations  {:>7.1} ns/call",
        s.mean_iterations, s.max_iterations, s.ns_per_call
    );
}

fn main() {
    let worst = std::env::args().any(|a| a == "--worst");
    let cases = hard_cases();
    let refs = reference_distances();
    if worst {
        let mut v: Vec<(u32, &String, [f64; 4])> = cases
            .iter()
            .map(|(cat, c)| {
                let r = closest_point_on_ellipse(c[0], c[1], DVec2::new(c[2], c[3]));
                (r.iterations, cat, *c)
            })
            .collect();
        v.sort_by_key(|e| std::cmp::Reverse(e.0));
        for (it, cat, c) in v.iter().take(8) {
            println!("f64 {it:>3} {cat:<32} {c:?}");
        }
        let mut v: Vec<(u32, &String, [f32; 4])> = cases
            .iter()
            .map(|(cat, c)| {
                let c = c.map(|v| v as f32);
                let r = closest_point_on_ellipse_f32(c[0], c[1], [c[2], c[3]]);
                (r.iterations, cat, c)
            })
            .collect();
        v.sort_by_key(|e| std::cmp::Reverse(e.0));
        for (it, cat, c) in v.iter().take(8) {
            println!("f32 {it:>3} {cat:<32} {c:?}");
        }
    }
    let hard: Vec<[f64; 4]> = cases.iter().map(|(_, c)| *c).collect();
    // Accuracy of the f32 mirror against f64 on its own (f32-rounded) inputs, relative to scale.
    let mut worst32 = 0.0_f64;
    for c in &hard {
        let v = c.map(|x| x as f32);
        if !v
            .iter()
            .all(|&x| x == 0.0 || (x.is_normal() && x.abs() < 1e30))
        {
            continue;
        }
        let w = v.map(f64::from);
        let d64 = closest_point_on_ellipse(w[0], w[1], DVec2::new(w[2], w[3])).distance;
        let d32 = closest_point_on_ellipse_f32(v[0], v[1], [v[2], v[3]]).distance;
        let scale = w[0].max(w[1]).max(w[2].hypot(w[3]));
        worst32 = worst32.max((f64::from(d32) - d64).abs() / scale);
    }
    println!("f32 mirror: max |d32 - d64| / scale on the hard cases = {worst32:.2e}");
    // Accuracy of the f64 solver against the 80-digit reference (column d_ref), normal range.
    let (mut worst64, mut worst_rel) = (0.0_f64, 0.0_f64);
    for (c, d_ref) in cases.iter().map(|(_, c)| c).zip(&refs) {
        if c[0].max(c[1]) < f64::MIN_POSITIVE * 1e20 {
            continue;
        }
        let d = closest_point_on_ellipse(c[0], c[1], DVec2::new(c[2], c[3])).distance;
        let scale = c[0].max(c[1]).max(c[2].hypot(c[3]));
        worst64 = worst64.max((d - d_ref).abs() / scale);
        if scale <= 1e3 * d_ref {
            worst_rel = worst_rel.max((d - d_ref).abs() / d_ref);
        }
    }
    println!(
        "f64: max |d - d_ref| / scale = {worst64:.2e}, max relative error (scale/d <= 1e3) = {worst_rel:.2e}"
    );
    let hard32: Vec<[f64; 4]> = hard
        .iter()
        .copied()
        .filter(|c| c.iter().all(|&v| v == 0.0 || (v as f32).is_normal()))
        .collect();
    println!(
        "hard-case set: {} cases ({} f32-representable)",
        hard.len(),
        hard32.len()
    );
    let it64 =
        |c: &[f64; 4]| closest_point_on_ellipse(c[0], c[1], DVec2::new(c[2], c[3])).iterations;
    let d64 = |c: &[f64; 4]| closest_point_on_ellipse(c[0], c[1], DVec2::new(c[2], c[3])).distance;
    let f32s = |c: &[f64; 4]| (c[0] as f32, c[1] as f32, [c[2] as f32, c[3] as f32]);
    let it32 = |c: &[f64; 4]| {
        let (a, b, p) = f32s(c);
        closest_point_on_ellipse_f32(a, b, p).iterations
    };
    let d32 = |c: &[f64; 4]| {
        let (a, b, p) = f32s(c);
        f64::from(closest_point_on_ellipse_f32(a, b, p).distance)
    };
    // The filled variants run the curve solver only outside; inside points cost 0 iterations.
    let filled_it64 = |c: &[f64; 4]| {
        let r = closest_point_on_ellipse(c[0], c[1], DVec2::new(c[2], c[3]));
        if r.inside { 0 } else { r.iterations }
    };
    let filled64 = |c: &[f64; 4]| distance_to_filled_ellipse(c[0], c[1], DVec2::new(c[2], c[3]));
    let filled_it32 = |c: &[f64; 4]| {
        let (a, b, p) = f32s(c);
        if distance_to_filled_ellipse_f32(a, b, p) == 0.0 {
            0
        } else {
            it32(c)
        }
    };
    let filled32 = |c: &[f64; 4]| {
        let (a, b, p) = f32s(c);
        f64::from(distance_to_filled_ellipse_f32(a, b, p))
    };
    print(
        "f64 closest point, hard cases",
        &measure(&hard, 200, it64, d64),
    );
    print(
        "f32 closest point, hard cases",
        &measure(&hard32, 200, it32, d32),
    );
    // The class of inside points a tiny or subnormal distance off an axis: its arithmetic is on
    // subnormal numbers, which x86 cores run some hundred times slower than normal ones, so it
    // is timed apart from the rest (the DGI never meets it: it solves outside points only).
    let (tiny, rest): (Vec<_>, Vec<_>) = cases
        .iter()
        .partition(|(cat, _)| cat.starts_with("tiny-off-axis"));
    let (tiny, rest): (Vec<[f64; 4]>, Vec<[f64; 4]>) = (
        tiny.iter().map(|(_, c)| *c).collect(),
        rest.iter().map(|(_, c)| *c).collect(),
    );
    print(
        &format!("f64, hard cases without that class ({})", rest.len()),
        &measure(&rest, 200, it64, d64),
    );
    print(
        &format!("f64, tiny-off-axis inside class ({})", tiny.len()),
        &measure(&tiny, 200, it64, d64),
    );

    // A typical mouse ROI on a 4K canvas: semi-axes 600 × 250 px centred at (1700, 1000); the
    // points are pixel centres relative to the ellipse centre.
    let (w, h) = (3840usize, 2160usize);
    let (cx, cy, a, b) = (1700.0, 1000.0, 600.0, 250.0);
    let grid: Vec<[f64; 4]> = (0..w * h)
        .map(|i| {
            let (px, py) = ((i % w) as f64 + 0.5, (i / w) as f64 + 0.5);
            [a, b, px - cx, py - cy]
        })
        .collect();
    println!("grid: {w}×{h} pixel centres around a {a}×{b} px ellipse");
    print(
        "f64 closest point (curve), grid",
        &measure(&grid, 1, it64, d64),
    );
    print(
        "f64 filled distance, grid",
        &measure(&grid, 1, filled_it64, filled64),
    );
    print(
        "f32 closest point (curve), grid",
        &measure(&grid, 1, it32, d32),
    );
    print(
        "f32 filled distance, grid",
        &measure(&grid, 1, filled_it32, filled32),
    );
}
