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

fn measure<F: Fn(&[f64; 4]) -> u32>(cases: &[[f64; 4]], repeats: usize, f: F) -> Stats {
    let (mut sum, mut max) = (0u64, 0u32);
    for c in cases {
        let it = f(c);
        sum += u64::from(it);
        max = max.max(it);
    }
    let t = Instant::now();
    for _ in 0..repeats {
        for c in cases {
            black_box(f(black_box(c)));
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
    if worst {
        let mut v: Vec<(u32, &String, [f64; 4])> = cases
            .iter()
            .map(|(cat, c)| {
                let r = closest_point_on_ellipse(c[0], c[1], DVec2::new(c[2], c[3]));
                (r.iterations, cat, *c)
            })
            .collect();
        v.sort_by(|a, b| b.0.cmp(&a.0));
        for (it, cat, c) in v.iter().take(15) {
            println!("{it:>3} {cat:<32} {c:?}");
        }
    }
    let hard: Vec<[f64; 4]> = cases.iter().map(|(_, c)| *c).collect();
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
    print(
        "f64 closest point, hard cases",
        &measure(&hard, 200, |c| {
            closest_point_on_ellipse(c[0], c[1], DVec2::new(c[2], c[3])).iterations
        }),
    );
    print(
        "f32 closest point, hard cases",
        &measure(&hard32, 200, |c| {
            closest_point_on_ellipse_f32(c[0] as f32, c[1] as f32, [c[2] as f32, c[3] as f32])
                .iterations
        }),
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
        &measure(&grid, 1, |c| {
            closest_point_on_ellipse(c[0], c[1], DVec2::new(c[2], c[3])).iterations
        }),
    );
    print(
        "f64 filled distance, grid",
        &measure(&grid, 1, |c| {
            u32::from(distance_to_filled_ellipse(c[0], c[1], DVec2::new(c[2], c[3])) > 0.0)
        }),
    );
    print(
        "f32 closest point (curve), grid",
        &measure(&grid, 1, |c| {
            closest_point_on_ellipse_f32(c[0] as f32, c[1] as f32, [c[2] as f32, c[3] as f32])
                .iterations
        }),
    );
    print(
        "f32 filled distance, grid",
        &measure(&grid, 1, |c| {
            u32::from(
                distance_to_filled_ellipse_f32(
                    c[0] as f32,
                    c[1] as f32,
                    [c[2] as f32, c[3] as f32],
                ) > 0.0,
            )
        }),
    );
}
