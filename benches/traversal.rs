//! `cargo bench --bench traversal [-- SCENE [ROUNDS]]`: the CPU tree's walks alone, in
//! nanoseconds per ray, on the rays a path tracer casts — the camera's (eight at a time, and
//! sixteen at a time as hybrid packets), the bounces' and the shadow rays' (one at a time, and
//! sixteen at a time) — recorded once from the scene (default `builtin:city-small`, the peer
//! benchmark's small city), a bounce at a time in pixel order as the renderer's batches trace
//! them, and replayed `ROUNDS` times (default 9). The sixteen-ray rows are hybrid packets, in
//! AVX-512 lanes where the processor has them, else in pairs of AVX2 registers;
//! `RAYGUN_CPU_PACKETS=0`, `avx2` or `avx512` chooses (the header says which). The "by octant" rows
//! group each 4096 rays (a batch's paths) by their direction's octant first, as the batches do
//! past the camera (the recorded shadow rays are cosine-distributed about the normal, not aimed
//! at a light). Without
//! the shading around them, a change to the walk shows in a second with less of the noise of a
//! whole render: the minimum over the rounds is the figure to compare; the median says how noisy
//! the machine was.

use std::hint::black_box;
use std::time::Instant;

use glam::Vec3;
use raygun::random::{pcg4d, unit_f32};
use raygun::scene::Scene;
use raygun::trace::bvh::CpuPackets;
use raygun::trace::camera::RenderCamera;
use raygun::trace::pack::PackedScene;

/// The camera's resolution for the recorded rays: one sample a pixel.
const WIDTH: u32 = 320;
const HEIGHT: u32 = 180;
/// Diffuse bounces followed from each camera hit.
const BOUNCES: u32 = 3;

struct Rays {
    camera: Vec<(Vec3, Vec3)>,
    bounce: Vec<(Vec3, Vec3)>,
    shadow: Vec<(Vec3, Vec3)>,
}

/// A cosine-weighted direction about `n` from two uniforms.
fn cosine(n: Vec3, u1: f32, u2: f32) -> Vec3 {
    let (t, b) = n.any_orthonormal_pair();
    let r = u1.sqrt();
    let phi = std::f32::consts::TAU * u2;
    (t * (r * phi.cos()) + b * (r * phi.sin()) + n * (1.0 - u1).max(0.0).sqrt()).normalize()
}

fn record(sc: &PackedScene, camera: &RenderCamera) -> Rays {
    let mut rays = Rays {
        camera: Vec::new(),
        bounce: Vec::new(),
        shadow: Vec::new(),
    };
    // The paths advance a bounce at a time, as the renderer's batches trace them: each
    // bounce's rays in pixel order.
    let mut paths = Vec::new();
    for pixel in 0..WIDTH * HEIGHT {
        let j = pcg4d([pixel, 0, 0x7261_7973, 0]).map(unit_f32);
        let (x, y) = ((pixel % WIDTH) as f32 + j[0], (pixel / WIDTH) as f32 + j[1]);
        let (o, d) = camera.ray(x, y, WIDTH, HEIGHT);
        rays.camera.push((o, d));
        paths.push((pixel, o, d));
    }
    for bounce in 0..=BOUNCES {
        let mut next = Vec::new();
        for (pixel, o, d) in paths {
            let Some(hit) = sc.bvh.closest_hit(o, d, f32::INFINITY) else {
                continue;
            };
            let prim = sc.bvh.hit_prim(hit.prim);
            let e1 = Vec3::from_slice(&prim[1][..3]);
            let e2 = Vec3::from_slice(&prim[2][..3]);
            let mut n = e1.cross(e2).normalize();
            if n.dot(d) > 0.0 {
                n = -n;
            }
            let p = o + d * hit.t + n * 1e-4;
            let u = pcg4d([pixel, 1 + bounce, 0x7261_7973, 0]).map(unit_f32);
            rays.shadow.push((p, cosine(n, u[0], u[1])));
            if bounce < BOUNCES {
                let d = cosine(n, u[2], u[3]);
                rays.bounce.push((p, d));
                next.push((pixel, p, d));
            }
        }
        paths = next;
    }
    rays
}

/// Nanoseconds per item of `f` over `n` items: the minimum and the median of `rounds`.
fn time(rounds: usize, n: usize, mut f: impl FnMut() -> usize) -> (f64, f64, usize) {
    let mut ns: Vec<f64> = Vec::new();
    let mut found = 0;
    for _ in 0..rounds {
        let start = Instant::now();
        found = black_box(f());
        ns.push(start.elapsed().as_secs_f64() * 1e9 / n as f64);
    }
    ns.sort_by(f64::total_cmp);
    (ns[0], ns[ns.len() / 2], found)
}

fn main() {
    // `cargo bench` passes `--bench`; the scene and rounds are the other arguments.
    let args: Vec<String> = std::env::args()
        .skip(1)
        .filter(|a| a != "--bench")
        .collect();
    let name = args.first().map_or("builtin:city-small", String::as_str);
    let walks = CpuPackets::from_env().unwrap_or_else(|e| {
        eprintln!("traversal: {e}");
        std::process::exit(2)
    });
    let rounds = match args.get(1).map_or(Ok(9), |r| r.parse::<usize>()) {
        Ok(rounds) if rounds > 0 => rounds,
        _ => {
            eprintln!("traversal: ROUNDS must be a whole number of at least 1");
            std::process::exit(2)
        }
    };
    let scene = Scene::open(name).unwrap_or_else(|e| {
        eprintln!("traversal: {e}");
        std::process::exit(2)
    });
    let sc = PackedScene::new(&scene);
    let camera = RenderCamera::choose(&scene, None, WIDTH, HEIGHT).unwrap_or_else(|e| {
        eprintln!("traversal: {e}");
        std::process::exit(2)
    });
    let rays = record(&sc, &camera);
    let bvh = &sc.bvh;
    let camera_rays = || {
        rays.camera
            .chunks(8)
            .map(|group| {
                let origins = std::array::from_fn(|i| group[i.min(group.len() - 1)].0);
                let dirs = std::array::from_fn(|i| group[i.min(group.len() - 1)].1);
                let active = (1 << group.len()) - 1;
                let hits = bvh.closest_hits8(black_box(&origins), black_box(&dirs), active);
                hits.iter().filter(|h| h.is_some()).count()
            })
            .sum()
    };
    // Closest hits sixteen at a time (hybrid packets where the processor has AVX-512): how
    // many rays hit.
    let sixteen = |rays: &[(Vec3, Vec3)]| -> usize {
        rays.chunks(16)
            .map(|group| {
                let origins = std::array::from_fn(|i| group[i.min(group.len() - 1)].0);
                let dirs = std::array::from_fn(|i| group[i.min(group.len() - 1)].1);
                let active = (1u32 << group.len()) - 1;
                let hits = bvh.closest_hits16(black_box(&origins), black_box(&dirs), active as u16);
                hits.iter().filter(|h| h.is_some()).count()
            })
            .sum()
    };
    // Rays as the batches trace them past the camera: each batch's (4096 paths', the
    // renderer's `BATCH`) by the octant of their direction, stable.
    let by_octant = |rays: &[(Vec3, Vec3)]| -> Vec<(Vec3, Vec3)> {
        let octant =
            |d: Vec3| u8::from(d.x < 0.0) | u8::from(d.y < 0.0) << 1 | u8::from(d.z < 0.0) << 2;
        rays.chunks(4096)
            .flat_map(|batch| {
                let mut batch = batch.to_vec();
                batch.sort_by_key(|&(_, d)| octant(d));
                batch
            })
            .collect()
    };
    let (bounce_by_octant, shadow_by_octant) = (by_octant(&rays.bounce), by_octant(&rays.shadow));
    // Shadow rays sixteen at a time: how many are blocked.
    let occluded16 = |rays: &[(Vec3, Vec3)]| -> usize {
        rays.chunks(16)
            .map(|group| {
                let origins = std::array::from_fn(|i| group[i.min(group.len() - 1)].0);
                let dirs = std::array::from_fn(|i| group[i.min(group.len() - 1)].1);
                let active = (1u32 << group.len()) - 1;
                let tmax = [f32::INFINITY; 16];
                let blocked =
                    bvh.occluded16(black_box(&origins), black_box(&dirs), &tmax, active as u16);
                blocked.count_ones() as usize
            })
            .sum()
    };
    let rows = [
        (
            "camera, 8 at a time",
            rays.camera.len(),
            time(rounds, rays.camera.len(), camera_rays),
        ),
        (
            "camera, 16 at a time",
            rays.camera.len(),
            time(rounds, rays.camera.len(), || sixteen(&rays.camera)),
        ),
        (
            "bounces, closest hit",
            rays.bounce.len(),
            time(rounds, rays.bounce.len(), || {
                rays.bounce
                    .iter()
                    .filter(|&&(o, d)| {
                        bvh.closest_hit(black_box(o), black_box(d), f32::INFINITY)
                            .is_some()
                    })
                    .count()
            }),
        ),
        (
            "bounces, 16 at a time",
            rays.bounce.len(),
            time(rounds, rays.bounce.len(), || sixteen(&rays.bounce)),
        ),
        (
            "bounces, 16 at a time by octant",
            rays.bounce.len(),
            time(rounds, rays.bounce.len(), || sixteen(&bounce_by_octant)),
        ),
        (
            "shadow rays, any hit",
            rays.shadow.len(),
            time(rounds, rays.shadow.len(), || {
                rays.shadow
                    .iter()
                    .filter(|&&(o, d)| bvh.occluded(black_box(o), black_box(d), f32::INFINITY))
                    .count()
            }),
        ),
        (
            "shadow rays, 16 at a time",
            rays.shadow.len(),
            time(rounds, rays.shadow.len(), || occluded16(&rays.shadow)),
        ),
        (
            "shadow rays, 16 at a time by octant",
            rays.shadow.len(),
            time(rounds, rays.shadow.len(), || occluded16(&shadow_by_octant)),
        ),
    ];
    println!(
        "{name}: {} triangles, {rounds} rounds, one thread, {}",
        scene.triangles.len(),
        walks.describe()
    );
    println!("| rays | count | hit | ns per ray, min | median |");
    println!("|---|---|---|---|---|");
    for (what, n, (min, median, found)) in rows {
        println!("| {what} | {n} | {found} | {min:.1} | {median:.1} |");
    }
}
