//! `cargo bench --bench display [-- W,H [ROUNDS]]`: the viewer's conversion of a linear picture
//! to the 8-bit sRGB RGBA it shows (default 3840×2160, 9 rounds), three ways side by side in
//! each round — the sRGB curve by `powf` per channel on one thread (the conversion before the
//! table), the table (`output::srgb8::linear_to_srgb8`) on one thread, and
//! `output::srgb8::display_rgba` (the table on all cores, what the viewer runs) — in ms per
//! picture (minimum and median over the rounds) and as ratios of the minima. The three give the
//! same bytes (checked before timing).

use std::hint::black_box;
use std::time::Instant;

use glam::Vec3;
use raygun::output::srgb8::{display_rgba, linear_to_srgb8};
use raygun::output::{linear_to_srgb, unit_to_u8};

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
}
