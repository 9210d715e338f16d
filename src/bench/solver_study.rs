//! The closest-point solvers' iteration counts and time per call, by class of case and on a
//! 4K grid (DESIGN.md §5): the study behind BENCHMARKS.md, *Closest-point solver*, run with
//! `cargo run --release --example ellipse_bench [-- --worst]` on an otherwise idle core.
//!
//! Unlike [`super::solver`] (the report's solver table: accuracy against the 80-digit
//! references, GPU included) this study times the f64 solver and the f32 mirror of the WGSL on
//! the whole hard-case set, on the set without the inside tiny-off-axis class (whose subnormal
//! arithmetic x86 cores run some hundred times slower; the DGI never meets it, as it solves
//! outside points only) and on that class alone, and on the pixel centres of a 3840×2160 canvas
//! around a typical mouse ROI, curve and filled distance. `worst` also lists the eight cases
//! each solver needs the most iterations for.

use std::fmt::Write as _;
use std::hint::black_box;
use std::time::Instant;

use glam::DVec2;

use super::solver::{HARD_CASES_CSV, HARD_CASES_PATH, HardCase, TINY_OFF_AXIS, parse_cases};
use crate::roi::ellipse::{
    closest_point_on_ellipse, closest_point_on_ellipse_f32, distance_to_filled_ellipse,
    distance_to_filled_ellipse_f32,
};

/// Iterations and time per call of one solver on one set of cases.
#[derive(Clone, Copy, Debug)]
pub struct Stats {
    pub mean_iterations: f64,
    pub max_iterations: u32,
    pub ns_per_call: f64,
}

/// Runs `iterations` once per case (0 where the solver does not run) and times `repeats`
/// passes of `timed` over the cases.
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
    let ns = t.elapsed().as_nanos() as f64 / (repeats * cases.len()).max(1) as f64;
    Stats {
        mean_iterations: sum as f64 / cases.len().max(1) as f64,
        max_iterations: max,
        ns_per_call: ns,
    }
}

fn line(out: &mut String, name: &str, s: &Stats) {
    let _ = writeln!(
        out,
        "{name:<44} mean {:>5.2} max {:>3} iterations  {:>7.1} ns/call",
        s.mean_iterations, s.max_iterations, s.ns_per_call
    );
}

fn quad(c: &HardCase) -> [f64; 4] {
    [c.a, c.b, c.p.x, c.p.y]
}

fn f32s(c: &[f64; 4]) -> (f32, f32, [f32; 2]) {
    (c[0] as f32, c[1] as f32, [c[2] as f32, c[3] as f32])
}

fn it64(c: &[f64; 4]) -> u32 {
    closest_point_on_ellipse(c[0], c[1], DVec2::new(c[2], c[3])).iterations
}

fn d64(c: &[f64; 4]) -> f64 {
    closest_point_on_ellipse(c[0], c[1], DVec2::new(c[2], c[3])).distance
}

fn it32(c: &[f64; 4]) -> u32 {
    let (a, b, p) = f32s(c);
    closest_point_on_ellipse_f32(a, b, p).iterations
}

fn d32(c: &[f64; 4]) -> f64 {
    let (a, b, p) = f32s(c);
    f64::from(closest_point_on_ellipse_f32(a, b, p).distance)
}

/// The study as text, one line per measurement (see the module documentation).
///
/// # Panics
/// If the embedded hard-case file does not parse (a test holds it parseable).
#[must_use]
pub fn run(worst: bool) -> String {
    let cases = parse_cases(HARD_CASES_CSV, HARD_CASES_PATH).expect("the embedded hard-case set");
    let mut out = String::new();
    if worst {
        let mut v: Vec<(u32, &HardCase)> = cases.iter().map(|c| (it64(&quad(c)), c)).collect();
        v.sort_by_key(|e| std::cmp::Reverse(e.0));
        for (it, c) in v.iter().take(8) {
            let _ = writeln!(out, "f64 {it:>3} {:<32} {:?}", c.category, quad(c));
        }
        let mut v: Vec<(u32, &HardCase)> = cases.iter().map(|c| (it32(&quad(c)), c)).collect();
        v.sort_by_key(|e| std::cmp::Reverse(e.0));
        for (it, c) in v.iter().take(8) {
            let _ = writeln!(
                out,
                "f32 {it:>3} {:<32} {:?}",
                c.category,
                quad(c).map(|x| x as f32)
            );
        }
    }
    let hard: Vec<[f64; 4]> = cases.iter().map(quad).collect();
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
        let scale = w[0].max(w[1]).max(w[2].hypot(w[3]));
        worst32 = worst32.max((d32(&w) - d64(&w)).abs() / scale);
    }
    let _ = writeln!(
        out,
        "f32 mirror: max |d32 - d64| / scale on the hard cases = {worst32:.2e}"
    );
    // Accuracy of the f64 solver against the 80-digit reference, normal range.
    let (mut worst64, mut worst_rel) = (0.0_f64, 0.0_f64);
    for c in &cases {
        if c.a.max(c.b) < f64::MIN_POSITIVE * 1e20 {
            continue;
        }
        let err = (d64(&quad(c)) - c.d_ref).abs();
        let scale = c.scale();
        worst64 = worst64.max(err / scale);
        if scale <= 1e3 * c.d_ref {
            worst_rel = worst_rel.max(err / c.d_ref);
        }
    }
    let _ = writeln!(
        out,
        "f64: max |d - d_ref| / scale = {worst64:.2e}, max relative error (scale/d <= 1e3) = {worst_rel:.2e}"
    );
    let hard32: Vec<[f64; 4]> = hard
        .iter()
        .copied()
        .filter(|c| c.iter().all(|&v| v == 0.0 || (v as f32).is_normal()))
        .collect();
    let _ = writeln!(
        out,
        "hard-case set: {} cases ({} f32-representable)",
        hard.len(),
        hard32.len()
    );
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
    line(
        &mut out,
        "f64 closest point, hard cases",
        &measure(&hard, 200, it64, d64),
    );
    line(
        &mut out,
        "f32 closest point, hard cases",
        &measure(&hard32, 200, it32, d32),
    );
    let (tiny, rest): (Vec<&HardCase>, Vec<&HardCase>) = cases
        .iter()
        .partition(|c| c.category.starts_with(TINY_OFF_AXIS));
    let tiny: Vec<[f64; 4]> = tiny.into_iter().map(quad).collect();
    let rest: Vec<[f64; 4]> = rest.into_iter().map(quad).collect();
    line(
        &mut out,
        &format!("f64, hard cases without that class ({})", rest.len()),
        &measure(&rest, 200, it64, d64),
    );
    line(
        &mut out,
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
    let _ = writeln!(
        out,
        "grid: {w}×{h} pixel centres around a {a}×{b} px ellipse"
    );
    line(
        &mut out,
        "f64 closest point (curve), grid",
        &measure(&grid, 1, it64, d64),
    );
    line(
        &mut out,
        "f64 filled distance, grid",
        &measure(&grid, 1, filled_it64, filled64),
    );
    line(
        &mut out,
        "f32 closest point (curve), grid",
        &measure(&grid, 1, it32, d32),
    );
    line(
        &mut out,
        "f32 filled distance, grid",
        &measure(&grid, 1, filled_it32, filled32),
    );
    out
}
