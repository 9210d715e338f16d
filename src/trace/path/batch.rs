//! The integrator on batches of paths: a wavefront of up to [`BATCH`] paths advanced one vertex
//! at a time, each vertex's shading done for sixteen paths at once in lanes
//! ([`crate::trace::lanes`], a pair of AVX2 registers each) — the same function as
//! [`trace_path`], path by path to the bit (tests below and in `tests/twins/trace.rs`), only
//! faster (BENCHMARKS.md, *CPU twin against Mitsuba 3*).
//!
//! A vertex of the batch: every live path's ray is traced (sixteen neighbouring paths' rays at
//! a time as hybrid packets, in AVX-512 lanes where the processor has them, else in pairs of
//! AVX2 registers, `bvh/cpu/hybrid.rs` — past the camera those of one direction octant together,
//! [`by_octant`]; with `RAYGUN_CPU_PACKETS=0`, a pinhole's camera rays eight at a time, the
//! others one at a time); the paths that leave the scene take the
//! environment, one at a time as `trace_path` does; the others are shaded in
//! groups of sixteen: geometry, emission with its MIS weight, the BSDF, next-event estimation
//! (with packets, the shadow rays queued and traced sixteen at a time once every group is
//! shaded, [`ShadowRays`]; elsewhere one at a time), the BSDF sample and Russian roulette. What
//! reads per-triangle or per-texel data — emission and base colour with their textures, the
//! environment map, the light's pick — and what only some materials and scenes have — normal
//! and metallic-roughness maps, the extensions' BSDF (glass, clear coat), punctual lights,
//! alpha-tested triangles — is `trace_path`'s own code, called for the lanes that need it. Like
//! `trace_path`, the batches come in two instantiations: the plain one for a
//! [`PackedScene::plain`] scene, with those branches compiled out, and the full one.

use super::*;
use crate::trace::bvh::TraceHit;
use crate::trace::lanes::{self, F, LANES, U, V3};

/// The paths advanced together: enough that a vertex's survivors, sorted into eight direction
/// octants after Russian roulette has thinned them, still fill packets of sixteen rays and
/// groups of sixteen, few enough that their state (about 450 kB: paths, hits, the shadow queue)
/// stays in a core's second-level cache. Measured on an Intel Xeon against 256 paths: small
/// city ×0.945 per sample, Cornell boxes ×0.96–0.97 (256 against 64: ×0.90–1.04;
/// BENCHMARKS.md, *CPU shading and batches*). The paths' indices are 16-bit.
pub(super) const BATCH: usize = 4096;
const _: () = assert!(BATCH <= 1 << 16, "a path's index is an Idx");

/// A path's index in its batch.
type Idx = u16;

/// One path's state between vertices.
#[derive(Clone, Copy)]
struct Path {
    pixel: u32,
    sample: u32,
    o: Vec3,
    d: Vec3,
    throughput: Vec3,
    radiance: Vec3,
    prev_pdf: f32,
    rays: u32,
}

impl Path {
    /// A path before its first vertex (its pixel, sample and ray still to be set).
    const START: Self = Self {
        pixel: 0,
        sample: 0,
        o: Vec3::ZERO,
        d: Vec3::ZERO,
        throughput: Vec3::ONE,
        radiance: Vec3::ZERO,
        prev_pdf: 0.0,
        rays: 0,
    };
}

/// A batch's arrays, on the heap (at [`BATCH`] paths they are too large for a thread's
/// stack), made once a thread ([`WORK`]) and used by each of its batches in turn.
struct Work {
    paths: Box<[Path; BATCH]>,
    hits: Box<[Option<TraceHit>; BATCH]>,
    live: Box<[Idx; BATCH]>,
    shade: Box<[Idx; BATCH]>,
    sorted: Box<[Idx; BATCH]>,
    shadows: ShadowRays,
}

/// Every index of a batch, in order.
static EVERY: [Idx; BATCH] = {
    let mut every = [0; BATCH];
    let mut k = 0;
    while k < BATCH {
        every[k] = k as Idx;
        k += 1;
    }
    every
};

/// `BATCH` copies of `value`, allocated on the heap directly.
fn boxed<T: Clone>(value: T) -> Box<[T; BATCH]> {
    vec![value; BATCH]
        .into_boxed_slice()
        .try_into()
        .unwrap_or_else(|_| unreachable!("a vector of BATCH values"))
}

impl Work {
    fn new() -> Self {
        Self {
            paths: boxed(Path::START),
            hits: boxed(None),
            live: boxed(0),
            shade: boxed(0),
            sorted: boxed(0),
            shadows: ShadowRays::new(),
        }
    }
}

/// Traces sample `samples[i]` of pixel `pixels[i]` for every `i`, through `wall`'s primary rays
/// when given, and writes its (radiance, rays) into `out[i]`: `None` for a pixel the wall
/// camera's display does not show. The same results as [`trace_counted_with`] per pixel.
pub(super) fn trace_batch(
    sc: &PackedScene,
    s: &TraceSettings,
    wall: Option<&WallCamera>,
    pixels: &[u32],
    samples: &[u32],
    out: &mut [Option<(Vec3, u32)>],
) {
    assert!(pixels.len() == samples.len() && pixels.len() == out.len());
    // This thread's arrays (a fresh set if they are in use further up its stack).
    WORK.with(|cell| {
        let (mut kept, mut fresh) = (cell.try_borrow_mut(), None);
        let work = match &mut kept {
            Ok(kept) => kept.get_or_insert_with(Work::new),
            Err(_) => fresh.insert(Work::new()),
        };
        if sc.plain {
            batches::<false>(work, sc, s, wall, pixels, samples, out);
        } else {
            batches::<true>(work, sc, s, wall, pixels, samples, out);
        }
    });
}

thread_local! {
    /// A thread's batch arrays, made on its first batch and kept: made a call at a time, their
    /// half a megabyte was allocated, faulted in and filled again for every band of rows
    /// (measured ×1.09–1.14 per sample on the Cornell boxes).
    static WORK: std::cell::RefCell<Option<Work>> = const { std::cell::RefCell::new(None) };
}

/// [`trace_batch`] in `trace_path`'s instantiation `FULL`, in the arrays `work`.
fn batches<const FULL: bool>(
    work: &mut Work,
    sc: &PackedScene,
    s: &TraceSettings,
    wall: Option<&WallCamera>,
    pixels: &[u32],
    samples: &[u32],
    out: &mut [Option<(Vec3, u32)>],
) {
    let alpha_scene = FULL && sc.features & FEAT_ALPHA != 0;
    let packets = sc.bvh.packets();
    let Work {
        paths,
        hits,
        live,
        shade,
        sorted,
        shadows,
    } = work;
    let (paths, hits, live) = (&mut **paths, &mut **hits, &mut **live);
    // With packets, a vertex's shadow rays wait until every group is shaded and go sixteen at
    // a time (neighbouring paths' shadow rays leave from nearby points).
    let mut shadows = (packets && !alpha_scene).then_some(shadows);
    for ((pixels, samples), out) in pixels
        .chunks(BATCH)
        .zip(samples.chunks(BATCH))
        .zip(out.chunks_mut(BATCH))
    {
        let mut n_live = camera_paths(s, wall, pixels, samples, paths, live, out);
        for depth in 0..s.max_depth {
            if n_live == 0 {
                break;
            }
            // Trace (the camera's rays eight at a time: they travel together), and let the
            // paths that leave the scene take the environment.
            trace_live(
                sc,
                s,
                depth,
                alpha_scene,
                packets,
                paths,
                &live[..n_live],
                hits,
                sorted,
            );
            let mut n_shade = 0;
            for &k in &live[..n_live] {
                let path = &mut paths[k as usize];
                path.rays += 1;
                match hits[k as usize] {
                    None => {
                        let (le, pdf_env) = env_eval(sc, path.d);
                        let w = if path.prev_pdf == 0.0 {
                            1.0
                        } else {
                            mis(path.prev_pdf, sc.env_select * pdf_env)
                        };
                        path.radiance += path.throughput * le * w;
                    }
                    Some(_) => {
                        shade[n_shade] = k;
                        n_shade += 1;
                    }
                }
            }
            n_live = 0;
            let groups = shade[..n_shade].chunks(LANES);
            for (group, next) in groups.clone().zip(groups.skip(1).map(Some).chain([None])) {
                if let Some(next) = next {
                    prefetch_rows(sc, hits, next);
                }
                let shaded = Shaded {
                    paths: &mut *paths,
                    live: &mut *live,
                    n_live: &mut n_live,
                    shadows: shadows.as_deref_mut(),
                };
                shade_lanes::<FULL>(sc, s, depth, group, hits, shaded);
            }
            if let Some(shadows) = &mut shadows {
                shadows.trace(sc, paths, sorted);
            }
        }
        for (k, out) in out.iter_mut().enumerate() {
            if let Some(out) = out {
                let p = &paths[k];
                let radiance = if p.radiance.is_finite() {
                    p.radiance
                } else {
                    Vec3::ZERO
                };
                *out = (radiance, p.rays);
            }
        }
    }
}

/// Starts a path for each of `pixels`' `samples` that has a camera ray (`out[k]` is `None` for
/// the others): its index into `paths` goes to `live`; how many did.
fn camera_paths(
    s: &TraceSettings,
    wall: Option<&WallCamera>,
    pixels: &[u32],
    samples: &[u32],
    paths: &mut [Path; BATCH],
    live: &mut [Idx; BATCH],
    out: &mut [Option<(Vec3, u32)>],
) -> usize {
    let mut n_live = 0;
    if wall.is_none() && s.camera.ortho_half_y == 0.0 {
        // A pinhole's rays, sixteen at a time.
        for (group, (pixels, samples)) in
            pixels.chunks(LANES).zip(samples.chunks(LANES)).enumerate()
        {
            let lane = |v: &[u32], i: usize| v[i.min(v.len() - 1)];
            let rays = pinhole(
                s,
                std::array::from_fn(|i| lane(pixels, i)),
                std::array::from_fn(|i| lane(samples, i)),
            );
            for (i, (&pixel, &sample)) in pixels.iter().zip(samples).enumerate() {
                let k = LANES * group + i;
                paths[k] = Path {
                    pixel,
                    sample,
                    o: s.camera.position,
                    d: rays[i],
                    ..Path::START
                };
                out[k] = Some((Vec3::ZERO, 0));
                live[n_live] = k as Idx;
                n_live += 1;
            }
        }
    } else {
        for (k, (&pixel, &sample)) in pixels.iter().zip(samples).enumerate() {
            out[k] = None;
            let (x, y) = (pixel % s.width, pixel / s.width);
            let r0 = rand4(pixel, sample, s.seed, 0);
            let ray = match wall {
                None => Some(
                    s.camera
                        .ray(x as f32 + r0[0], y as f32 + r0[1], s.width, s.height),
                ),
                Some(wall) => wall
                    .tile_of(x, y)
                    .map(|tile| wall.ray(tile, x, y, r0[0], r0[1])),
            };
            if let Some((o, d)) = ray {
                paths[k] = Path {
                    pixel,
                    sample,
                    o,
                    d,
                    ..Path::START
                };
                out[k] = Some((Vec3::ZERO, 0));
                live[n_live] = k as Idx;
                n_live += 1;
            }
        }
    }
    n_live
}

/// The closest hit of each `live` path's ray into `hits`: with the alpha test per hit where the
/// scene has alpha-tested triangles, else sixteen at a time where `packets` (the walks take
/// packets), else the camera's rays eight at a time and later rays one at a time.
#[allow(clippy::too_many_arguments)]
fn trace_live(
    sc: &PackedScene,
    s: &TraceSettings,
    depth: u32,
    alpha_scene: bool,
    packets: bool,
    paths: &[Path; BATCH],
    live: &[Idx],
    hits: &mut [Option<TraceHit>; BATCH],
    sorted: &mut [Idx; BATCH],
) {
    if alpha_scene {
        // Alpha-tested triangles are asked per hit whether they are there, each ray
        // with its own coverage seed.
        for &k in live {
            let path = &paths[k as usize];
            let seed = ray_seed(path.pixel, path.sample, s.seed, depth, 0);
            hits[k as usize] =
                sc.bvh
                    .closest_hit_filtered(path.o, path.d, f32::INFINITY, |tri, u, v| {
                        alpha_covered(sc, tri, u, v, seed)
                    });
        }
    } else if packets {
        // Sixteen neighbouring paths' rays at a time: they leave from nearby points
        // (hybrid packets, in AVX-512 or AVX2 lanes); past the camera,
        // those of one direction octant together (they cross the boxes' planes in one
        // order).
        let order = if depth == 0 {
            live
        } else {
            by_octant(live, |k| paths[k as usize].d, sorted)
        };
        for group in order.chunks(16) {
            let lane = |i: usize| &paths[group[i.min(group.len() - 1)] as usize];
            let origins = std::array::from_fn(|i| lane(i).o);
            let dirs = std::array::from_fn(|i| lane(i).d);
            let active = (1u32 << group.len()) - 1;
            let found = sc.bvh.closest_hits16(&origins, &dirs, active as u16);
            for (&k, hit) in group.iter().zip(found) {
                hits[k as usize] = hit;
            }
        }
    } else if depth == 0 {
        for group in live.chunks(8) {
            let lane = |i: usize| &paths[group[i.min(group.len() - 1)] as usize];
            let origins = std::array::from_fn(|i| lane(i).o);
            let dirs = std::array::from_fn(|i| lane(i).d);
            let found = sc
                .bvh
                .closest_hits8(&origins, &dirs, (1 << group.len()) - 1);
            for (&k, hit) in group.iter().zip(found) {
                hits[k as usize] = hit;
            }
        }
    } else {
        for &k in live {
            let path = &paths[k as usize];
            hits[k as usize] = sc.bvh.closest_hit(path.o, path.d, f32::INFINITY);
        }
    }
}

/// A vertex's shadow rays, queued while its groups are shaded and traced sixteen at a time
/// once they all are: per ray its path, origin, direction, length and the contribution it
/// carries if nothing blocks it. Adding the contribution later changes no value: nothing else
/// adds to the path's radiance between its vertex's shading and its next trace, and a path
/// casts one shadow ray a vertex, so each path's sums are the same, in the same order,
/// whatever order the rays are traced in (by octant, [`by_octant`]).
struct ShadowRays {
    path: Box<[Idx; BATCH]>,
    origin: Box<[Vec3; BATCH]>,
    dir: Box<[Vec3; BATCH]>,
    tmax: Box<[f32; BATCH]>,
    contrib: Box<[Vec3; BATCH]>,
    len: usize,
}

impl ShadowRays {
    fn new() -> Self {
        Self {
            path: boxed(0),
            origin: boxed(Vec3::ZERO),
            dir: boxed(Vec3::ZERO),
            tmax: boxed(0.0),
            contrib: boxed(Vec3::ZERO),
            len: 0,
        }
    }

    /// Queues path `path`'s shadow ray (a path casts at most one a vertex).
    #[inline(always)]
    fn push(&mut self, path: Idx, origin: Vec3, dir: Vec3, tmax: f32, contrib: Vec3) {
        let k = self.len;
        (self.path[k], self.origin[k], self.dir[k]) = (path, origin, dir);
        (self.tmax[k], self.contrib[k]) = (tmax, contrib);
        self.len += 1;
    }

    /// Traces the queued rays, adds each unblocked ray's contribution to its path's radiance,
    /// and empties the queue (`sorted`: room for their order).
    fn trace(&mut self, sc: &PackedScene, paths: &mut [Path; BATCH], sorted: &mut [Idx; BATCH]) {
        // Those of one direction octant together, as the bounces.
        let order = by_octant(&EVERY[..self.len], |k| self.dir[k as usize], sorted);
        for start in (0..self.len).step_by(16) {
            let n = (self.len - start).min(16);
            let at = |i: usize| order[start + i.min(n - 1)] as usize;
            let origins = std::array::from_fn(|i| self.origin[at(i)]);
            let dirs = std::array::from_fn(|i| self.dir[at(i)]);
            let tmax = std::array::from_fn(|i| self.tmax[at(i)]);
            let active = (1u32 << n) - 1;
            let blocked = sc.bvh.occluded16(&origins, &dirs, &tmax, active as u16);
            for i in (0..n).filter(|&i| blocked & (1 << i) == 0) {
                paths[self.path[at(i)] as usize].radiance += self.contrib[at(i)];
            }
        }
        self.len = 0;
    }
}

/// `items` in the order of their direction's octant (`dir`; which of x, y and z are below
/// zero), each octant's in their order in `items` (a counting sort), written into `out`.
#[inline(always)]
fn by_octant<'a>(items: &[Idx], dir: impl Fn(Idx) -> Vec3, out: &'a mut [Idx; BATCH]) -> &'a [Idx] {
    let octant = |k: Idx| {
        let d = dir(k);
        usize::from(d.x < 0.0) | usize::from(d.y < 0.0) << 1 | usize::from(d.z < 0.0) << 2
    };
    // Each item's octant, read once (the directions are scattered over the batch's paths).
    let mut octants = [0u8; BATCH];
    let mut start = [0usize; 9];
    for (o, &k) in octants.iter_mut().zip(items) {
        *o = octant(k) as u8;
        start[usize::from(*o) + 1] += 1;
    }
    for o in 0..8 {
        start[o + 1] += start[o];
    }
    for (&o, &k) in octants.iter().zip(items) {
        let o = usize::from(o);
        out[start[o]] = k;
        start[o] += 1;
    }
    &out[..items.len()]
}

/// Asks the processor to bring the rows that shading `group` reads first — each hit's
/// triangle (`hit_prim`) and shading row — into the cache while the group before it is shaded:
/// they are scattered over the scene's arrays, and their first touch was the shading's largest
/// stall (BENCHMARKS.md, *CPU shading and batches*). A hint only: nothing is read, so results
/// cannot change.
#[inline(always)]
fn prefetch_rows(sc: &PackedScene, hits: &[Option<TraceHit>; BATCH], group: &[Idx]) {
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (sc, hits, group);
    #[cfg(target_arch = "x86_64")]
    for &k in group {
        if let Some(hit) = &hits[k as usize] {
            let prim = sc.bvh.hit_prim(hit.prim);
            let shade = &sc.shade[4 * hit.triangle as usize..4 * hit.triangle as usize + 4];
            for row in [prim, shade] {
                let first = row.as_ptr().cast::<i8>();
                let last = first.wrapping_add(std::mem::size_of_val(row) - 1);
                // SAFETY: `_mm_prefetch` is a hint: it reads nothing and cannot fault.
                unsafe {
                    use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
                    _mm_prefetch::<_MM_HINT_T0>(first);
                    _mm_prefetch::<_MM_HINT_T0>(last);
                }
            }
        }
    }
}

/// The directions of a pinhole camera's primary rays for [`LANES`] (pixel, sample) pairs:
/// [`RenderCamera::ray`]'s, jitter included, in lanes (the same operations, so the same bits).
#[inline(always)]
fn pinhole(s: &TraceSettings, pixel: [u32; LANES], sample: [u32; LANES]) -> [Vec3; LANES] {
    let r = lanes::pcg4d([
        U::from(pixel),
        U::from(sample),
        U::splat(s.seed),
        U::splat(stream::TRACE),
    ])
    .map(lanes::unit_f32);
    let x = fl(pixel.map(|p| (p % s.width) as f32)) + r[0];
    let y = fl(pixel.map(|p| (p / s.width) as f32)) + r[1];
    let c = &s.camera;
    let (w, h) = (F::splat(s.width as f32), F::splat(s.height as f32));
    let (two, one, tan) = (F::splat(2.0), F::ONE, F::splat(c.tan_half_y));
    let sx = (two * x / w - one) * tan * F::splat(c.aspect);
    let sy = (one - two * y / h) * tan;
    (V3::splat(c.forward) + V3::splat(c.right) * sx + V3::splat(c.up) * sy)
        .normalize()
        .lanes()
}

/// The lanes of a scalar each.
#[inline(always)]
fn fl(v: [f32; LANES]) -> F {
    F::from(v)
}

/// `Vec3`s in lanes, from their components.
#[inline(always)]
fn vl(c: &[[f32; LANES]; 3]) -> V3 {
    V3 {
        x: fl(c[0]),
        y: fl(c[1]),
        z: fl(c[2]),
    }
}

/// What a group's shading reads per lane (per path and per hit), gathered in one pass.
#[derive(Default)]
struct Lanes {
    v0: [[f32; LANES]; 3],
    e1: [[f32; LANES]; 3],
    e2: [[f32; LANES]; 3],
    n: [[[f32; LANES]; 3]; 3],
    light_density: [f32; LANES],
    t: [f32; LANES],
    u: [f32; LANES],
    v: [f32; LANES],
    d: [[f32; LANES]; 3],
    throughput: [[f32; LANES]; 3],
    radiance: [[f32; LANES]; 3],
    emission: [[f32; LANES]; 3],
    base: [[f32; LANES]; 3],
    /// Metallic, alpha (the metallic-roughness map applied) and KHR_materials_specular.
    m2: [[f32; LANES]; 3],
    prev_pdf: [f32; LANES],
    pixel: [u32; LANES],
    sample: [u32; LANES],
    /// The material's base (vec4 index) and flags, and the hit as a surface point.
    mb: [usize; LANES],
    flags: [u32; LANES],
    sp: [Option<SurfacePoint>; LANES],
}

/// The mask of lanes whose bit is set in `bits`.
#[inline(always)]
fn lanes_of(bits: u32) -> F {
    let slot = U::from(std::array::from_fn::<u32, LANES, _>(|i| 1 << i));
    bytemuck::cast((U::splat(bits) & slot).simd_eq(slot))
}

/// What shading one vertex writes: the paths (radiance, throughput, next ray), the survivors,
/// appended to `live` after its first `n_live`, and the shadow rays left for a packet trace
/// (`None`: each traced at once).
struct Shaded<'a> {
    paths: &'a mut [Path; BATCH],
    live: &'a mut [Idx; BATCH],
    n_live: &'a mut usize,
    shadows: Option<&'a mut ShadowRays>,
}

/// One vertex of the paths in `group` (one to [`LANES`], each with its hit in `hits`): the body of
/// `trace_path::<FULL>`'s loop after the trace, in lanes. What only some materials or scenes
/// have — normal maps, metallic-roughness maps, the extensions' BSDF (glass, coat), punctual
/// lights, cut-out emitters, alpha-tested shadow rays — is `trace_path`'s own code, run for
/// the lanes that need it. Lanes past the group's end repeat its last path: they compute along
/// and are never written back. The survivors are appended to `shaded.live`.
// Long: the CPU renderer's hot loop, trace_path's loop body in SIMD lanes step for step in its
// order (the two must give the same bits), kept whole to be read against trace_path.
#[inline(never)]
fn shade_lanes<const FULL: bool>(
    sc: &PackedScene,
    s: &TraceSettings,
    depth: u32,
    group: &[Idx],
    hits: &[Option<TraceHit>; BATCH],
    shaded: Shaded<'_>,
) {
    let Shaded {
        paths,
        live,
        n_live,
        mut shadows,
    } = shaded;
    let bvh = &sc.bvh;
    let tri_select = 1.0 - sc.env_select - sc.punct_select;
    let alpha_scene = FULL && sc.features & FEAT_ALPHA != 0;
    let mut g = Lanes::default();
    for i in 0..LANES {
        let k = group[i.min(group.len() - 1)] as usize;
        let hit = hits[k].expect("a shaded path has a hit");
        let path = &paths[k];
        let prim = bvh.hit_prim(hit.prim);
        let sh = &sc.shade[4 * hit.triangle as usize..4 * hit.triangle as usize + 4];
        let mb = MATERIAL_STRIDE * sh[3][3].to_bits() as usize;
        let flags = sc.materials[mb + 1][3] as u32;
        let sp = SurfacePoint {
            tri: hit.triangle,
            u: hit.u,
            v: hit.v,
        };
        let emission = emission_at(sc, mb, flags, sp);
        let base = base_color(sc, mb, flags, sp);
        let m2 = sc.materials[mb + 2];
        let (mut metallic, mut alpha) = (m2[0], m2[1]);
        if FULL && flags & MAT_MR_TEX != 0 {
            let mr = slot(sc, mb, 1, sp);
            alpha = (alpha * mr.y * mr.y).max(MIN_ALPHA);
            metallic *= mr.z;
        }
        for c in 0..3 {
            g.v0[c][i] = prim[0][c];
            g.e1[c][i] = prim[1][c];
            g.e2[c][i] = prim[2][c];
            for (n, row) in g.n.iter_mut().zip(sh) {
                n[c][i] = row[c];
            }
            g.d[c][i] = path.d[c];
            g.throughput[c][i] = path.throughput[c];
            g.radiance[c][i] = path.radiance[c];
            g.emission[c][i] = emission[c];
            g.base[c][i] = base[c];
        }
        (g.m2[0][i], g.m2[1][i], g.m2[2][i]) = (metallic, alpha, m2[2]);
        g.light_density[i] = prim[1][3];
        (g.t[i], g.u[i], g.v[i]) = (hit.t, hit.u, hit.v);
        g.prev_pdf[i] = path.prev_pdf;
        (g.pixel[i], g.sample[i]) = (path.pixel, path.sample);
        (g.mb[i], g.flags[i], g.sp[i]) = (mb, flags, Some(sp));
    }
    let sp = g.sp.map(|sp| sp.expect("every lane is gathered"));
    let (v0, e1, e2) = (vl(&g.v0), vl(&g.e1), vl(&g.e2));
    let light_density = fl(g.light_density);
    let (t, u, v) = (fl(g.t), fl(g.u), fl(g.v));
    let mut ng = e1.cross(e2).normalize();
    let p = v0 + e1 * u + e2 * v;
    let b0 = F::ONE - u - v;
    let mut ns = (vl(&g.n[0]) * b0 + vl(&g.n[1]) * u + vl(&g.n[2]) * v).normalize();
    ns = V3::select(ns.is_finite(), ns, ng);
    let ns_interpolated = ns;
    let d = vl(&g.d);
    let wo = -d;
    let cos_hit = ng.dot(d).abs();
    let front = ng.dot(wo).simd_ge(F::ZERO);
    ng = V3::select(front, ng, -ng);
    let has = |flag: u32| {
        (0..LANES)
            .filter(|&i| g.flags[i] & flag != 0)
            .fold(0u32, |m, i| m | 1 << i)
    };
    let normal_mapped_lanes = if FULL { has(MAT_NORMAL_TEX) } else { 0 };
    if normal_mapped_lanes != 0 {
        let mut n = ns.lanes();
        for i in (0..LANES).filter(|&i| normal_mapped_lanes & (1 << i) != 0) {
            n[i] = normal_mapped(sc, g.mb[i], sp[i], n[i]);
        }
        ns = V3::from_lanes(&n);
    }
    ns = V3::select(ns.dot(ng).simd_lt(F::ZERO), -ns, ns);

    let mut throughput = vl(&g.throughput);
    // The lanes that leave an absorbing medium (`trace_path`'s `absorbed`, lane by lane).
    let volume_lanes = if FULL {
        has(MAT_VOLUME) & !front.to_bitmask()
    } else {
        0
    };
    if volume_lanes != 0 {
        let mut lanes = throughput.lanes();
        for i in (0..LANES).filter(|&i| volume_lanes & (1 << i) != 0) {
            lanes[i] *= absorbed(sc, g.mb[i], g.t[i]);
        }
        throughput = V3::from_lanes(&lanes);
    }
    let mut radiance = vl(&g.radiance);
    let prev_pdf = fl(g.prev_pdf);
    let emission = vl(&g.emission);
    let emits = emission.nonzero();
    if emits.any() {
        let pdf_light = F::splat(tri_select) * light_density * t * t / cos_hit;
        let w = prev_pdf
            .simd_eq(F::ZERO)
            .select(F::ONE, lanes::mis(prev_pdf, pdf_light));
        radiance = V3::select(emits, radiance + throughput * emission * w, radiance);
    }
    let bsdf = lanes::Bsdf {
        base: vl(&g.base),
        metallic: fl(g.m2[0]),
        alpha: fl(g.m2[1]),
        specular: fl(g.m2[2]),
    };
    let key = |dim: u32| {
        lanes::pcg4d([
            U::from(g.pixel),
            U::from(g.sample),
            U::splat(s.seed),
            U::splat(stream::TRACE.wrapping_add(dim)),
        ])
        .map(lanes::unit_f32)
    };
    let r2 = key(2 + 2 * depth);
    // The lanes on a dispersive surface follow one channel from here on (`trace_path`'s
    // `pick_channel`, lane by lane).
    let dispersion_lanes = if FULL { has(MAT_DISPERSION) } else { 0 };
    let mut channel = [ALL_CHANNELS; LANES];
    if dispersion_lanes != 0 {
        let (mut lanes, u) = (throughput.lanes(), r2[3].to_array());
        for i in (0..LANES).filter(|&i| dispersion_lanes & (1 << i) != 0) {
            (channel[i], lanes[i]) = pick_channel(lanes[i], u[i]);
        }
        throughput = V3::from_lanes(&lanes);
    }
    // The extensions' BSDF, for the lanes whose material has one (`trace_path`'s `BsdfExt`).
    let ext_lanes = if FULL { has(MAT_EXT_BSDF) } else { 0 };
    let front_bits = front.to_bitmask();
    // (Built only where some lane has one: a call per lane returning a large `Option` cost the
    // plain scenes' shading 2 % of their time for nothing.)
    let ext: [Option<BsdfExt>; LANES] = if ext_lanes == 0 {
        [None; LANES]
    } else {
        std::array::from_fn(|i| {
            (ext_lanes & (1 << i) != 0).then(|| {
                let core = Bsdf {
                    base: Vec3::new(g.base[0][i], g.base[1][i], g.base[2][i]),
                    metallic: g.m2[0][i],
                    alpha: g.m2[1][i],
                    specular: g.m2[2][i],
                };
                let front = front_bits & (1 << i) != 0;
                let lane =
                    |v: V3| Vec3::new(v.x.to_array()[i], v.y.to_array()[i], v.z.to_array()[i]);
                let (n, ng) = (lane(ns_interpolated), lane(ng));
                let (mb, flags) = (g.mb[i], g.flags[i]);
                let surface = ExtSurface {
                    front,
                    sp: sp[i],
                    ns: n,
                    ng,
                };
                ext_bsdf(sc, mb, flags, core, surface, channel[i])
            })
        })
    };
    let transmits_bits = (0..LANES)
        .filter(|&i| ext[i].is_some_and(|e| e.transmits()))
        .fold(0u32, |m, i| m | 1 << i);
    let transmits = lanes_of(transmits_bits);
    // The core BSDF's lobe probability, shared by its two evaluations and its sample (0 where
    // the extensions' BSDF decides).
    let ps = lanes_of(ext_lanes).select(F::ZERO, bsdf.specular_probability(ns.dot(wo)));
    let (ns_l, wo_l) = (ns.lanes(), wo.lanes());
    let eval = |wi: V3| {
        let (f, pdf) = bsdf.eval_with(ps, ns, wo, wi);
        if ext_lanes == 0 {
            return (f, pdf);
        }
        let (mut f, mut pdf, wi) = (f.lanes(), pdf.to_array(), wi.lanes());
        for i in 0..LANES {
            if let Some(e) = &ext[i] {
                (f[i], pdf[i]) = e.eval(ns_l[i], wo_l[i], wi[i]);
            }
        }
        (V3::from_lanes(&f), fl(pdf))
    };
    let r1 = key(1 + 2 * depth);
    let po = lanes::offset_ray(p, ng);
    // Below the surface (through glass): the origin offset the other way.
    let below = if transmits_bits != 0 {
        lanes::offset_ray(p, -ng)
    } else {
        po
    };

    // Next-event estimation: the environment, a punctual light or one emissive triangle.
    let mut radiance = radiance.lanes();
    let mut rays: [u32; LANES] =
        std::array::from_fn(|i| paths[group[i.min(group.len() - 1)] as usize].rays);
    if sc.env_select > 0.0 || sc.light_count > 0 || (FULL && sc.punctual_count > 0) {
        let to_env = r1[0].simd_lt(F::splat(sc.env_select));
        let (r1a, r1b, r1c) = (r1[0].to_array(), r1[1].to_array(), r1[2].to_array());
        let to_env_bits = to_env.to_bitmask();
        let punctual_bits = if FULL && sc.punctual_count > 0 {
            (0..LANES)
                .filter(|&i| {
                    to_env_bits & (1 << i) == 0 && r1a[i] < sc.env_select + sc.punct_select
                })
                .fold(0u32, |m, i| m | 1 << i)
        } else {
            0
        };
        // The environment's sample (direction, radiance, pdf).
        let (env_wi, env_le, env_pdf) = if to_env_bits == 0 {
            (V3::ZERO, V3::ZERO, F::ZERO)
        } else if sc.env_size[0] == 0 {
            (
                lanes::uniform_sphere(r1[1], r1[2]),
                V3::splat(sc.env_constant),
                F::splat(1.0 / (4.0 * PI)),
            )
        } else {
            let env: [(Vec3, Vec3, f32); LANES] = std::array::from_fn(|i| {
                if to_env_bits & (1 << i) != 0 {
                    sample_env(sc, r1b[i], r1c[i])
                } else {
                    (Vec3::ZERO, Vec3::ZERO, 0.0)
                }
            });
            (
                V3::from_lanes(&env.map(|e| e.0)),
                V3::from_lanes(&env.map(|e| e.1)),
                fl(env.map(|e| e.2)),
            )
        };
        let env_pdf = F::splat(sc.env_select) * env_pdf;
        // The emissive triangle's sample, for the lanes that pick one.
        let (mut wi, mut le, mut pdf_l, mut tmax) = (env_wi, env_le, env_pdf, F::INFINITY);
        if to_env_bits | punctual_bits != (1 << LANES) - 1 && sc.light_count > 0 {
            // The light's pick, point and emission per lane; its geometry in lanes.
            let mut l = [[[0f32; LANES]; 3]; 3];
            let (mut a, mut b, mut two_sided, mut density) =
                ([0f32; LANES], [0f32; LANES], [0f32; LANES], [0f32; LANES]);
            let mut tri_le = [[0f32; LANES]; 3];
            for i in 0..LANES {
                let u = ((r1a[i] - sc.env_select - sc.punct_select) / tri_select).min(0.99999994);
                let k = sample_cdf(&sc.dist, 0, sc.light_count, u) as usize;
                (a[i], b[i]) = (r1b[i], r1c[i]);
                if a[i] + b[i] > 1.0 {
                    a[i] = 1.0 - a[i];
                    b[i] = 1.0 - b[i];
                }
                let light = &sc.lights[3 * k..3 * k + 3];
                for (j, row) in light.iter().enumerate() {
                    for c in 0..3 {
                        l[j][c][i] = row[c];
                    }
                }
                two_sided[i] = light[1][3];
                density[i] = sc.dist[k + 1] - sc.dist[k];
                let tri = light[0][3].to_bits();
                let lmb = material_base(sc, tri);
                let lflags = sc.materials[lmb + 1][3] as u32;
                let lsp = SurfacePoint {
                    tri,
                    u: a[i],
                    v: b[i],
                };
                let mut e = emission_at(sc, lmb, lflags, lsp);
                // A cut-out emitter emits only where it is there (BSDF rays see the same).
                if FULL && lflags & MAT_MASK != 0 {
                    if base_color(sc, lmb, lflags, lsp).w < sc.materials[lmb + 2][3] {
                        e = Vec3::ZERO;
                    }
                } else if FULL && lflags & MAT_BLEND != 0 {
                    e *= base_color(sc, lmb, lflags, lsp).w;
                }
                for c in 0..3 {
                    tri_le[c][i] = e[c];
                }
            }
            let (lv0, le1, le2) = (vl(&l[0]), vl(&l[1]), vl(&l[2]));
            let (a, b) = (fl(a), fl(b));
            let q = lv0 + le1 * a + le2 * b;
            let to = q - po;
            let dist2 = to.length_squared();
            let dist = dist2.sqrt();
            let tri_wi = to / dist;
            let n_l = le1.cross(le2);
            let area2 = n_l.length();
            let facing = -n_l.dot(tri_wi) / area2;
            let two_sided = fl(two_sided).simd_ne(F::ZERO);
            let cos_l = two_sided.select(facing.abs(), facing.max(F::ZERO));
            let (tri_le, density) = (vl(&tri_le), fl(density));
            let tri_pdf = cos_l.simd_gt(F::ZERO).select(
                F::splat(tri_select) * density / (F::splat(0.5) * area2) * dist2 / cos_l,
                F::ZERO,
            );
            wi = V3::select(to_env, wi, tri_wi);
            le = V3::select(to_env, le, tri_le);
            pdf_l = to_env.select(pdf_l, tri_pdf);
            tmax = to_env.select(tmax, dist * F::splat(1.0 - 1e-4));
        }
        // A punctual light's sample (a delta light), for the lanes that pick one.
        if punctual_bits != 0 {
            let (mut w, mut l, mut pdf, mut t) =
                (wi.lanes(), le.lanes(), pdf_l.to_array(), tmax.to_array());
            let po = po.lanes();
            for i in (0..LANES).filter(|&i| punctual_bits & (1 << i) != 0) {
                (w[i], l[i], pdf[i], t[i], _) = sample_punctual(sc, po[i], r1a[i]);
            }
            (wi, le, pdf_l, tmax) = (V3::from_lanes(&w), V3::from_lanes(&l), fl(pdf), fl(t));
        }
        let side = wi.dot(ng);
        let usable = pdf_l.simd_gt(F::ZERO)
            & pdf_l.is_finite()
            & (side.simd_gt(F::ZERO) | (transmits & side.simd_lt(F::ZERO)));
        if usable.any() {
            let (f, pdf_b) = eval(wi);
            // At the last vertex no BSDF ray follows to find this light, so its sample carries
            // the whole estimate; a delta light cannot be hit at all.
            let w = if depth + 1 == s.max_depth {
                F::ONE
            } else {
                lanes_of(punctual_bits).select(F::ONE, lanes::mis(pdf_l, pdf_b))
            };
            let contrib = throughput * f * le * (ns.dot(wi).abs() / pdf_l) * w;
            let shadow = (usable & contrib.nonzero()).to_bitmask();
            let from = V3::select(side.simd_gt(F::ZERO), po, below);
            let (contrib, wi, from, tmax) =
                (contrib.lanes(), wi.lanes(), from.lanes(), tmax.to_array());
            for i in 0..group.len() {
                if shadow & (1 << i) != 0 {
                    rays[i] += 1;
                    if let Some(shadows) = &mut shadows {
                        shadows.push(group[i], from[i], wi[i], tmax[i], contrib[i]);
                        continue;
                    }
                    let blocked = if FULL {
                        let shadow_seed = if alpha_scene {
                            ray_seed(g.pixel[i], g.sample[i], s.seed, depth, 1)
                        } else {
                            0
                        };
                        bvh.occluded_filtered(from[i], wi[i], tmax[i], |tri, u, v| {
                            alpha_covered(sc, tri, u, v, shadow_seed)
                        })
                    } else {
                        bvh.occluded(from[i], wi[i], tmax[i])
                    };
                    if !blocked {
                        radiance[i] += contrib[i];
                    }
                }
            }
        }
    }

    // Continue the path by sampling the BSDF.
    let mut wi = bsdf.sample_with(ps, ns, wo, r1[3], r2[0], r2[1]);
    if ext_lanes != 0 {
        let (mut w, u1, u2, u3) = (
            wi.lanes(),
            r1[3].to_array(),
            r2[0].to_array(),
            r2[1].to_array(),
        );
        for i in 0..LANES {
            if let Some(e) = &ext[i] {
                w[i] = e.sample(ns_l[i], wo_l[i], u1[i], u2[i], u3[i]);
            }
        }
        wi = V3::from_lanes(&w);
    }
    let side = wi.dot(ng);
    // Below the surface only through a transmitting one, and on the same side of the shading
    // normal as of the geometric one (no light leaks).
    let above = side.simd_gt(F::ZERO);
    let mut go = above | (transmits & side.simd_lt(F::ZERO) & ns.dot(wi).simd_lt(F::ZERO));
    let (f, pdf) = eval(wi);
    go &= pdf.simd_gt(F::ZERO);
    let mut throughput = throughput * (f * (ns.dot(wi).abs() / pdf));
    if depth >= 3 {
        let q = throughput.max_element().min(F::splat(0.95));
        go &= !r2[2].simd_ge(q);
        throughput = throughput / q;
    }
    let go = go.to_bitmask();
    let origin = V3::select(above, po, below);
    let (throughput, pdf, origin, wi) = (
        throughput.lanes(),
        pdf.to_array(),
        origin.lanes(),
        wi.lanes(),
    );
    for (i, &k) in group.iter().enumerate() {
        let path = &mut paths[k as usize];
        path.radiance = radiance[i];
        path.rays = rays[i];
        if go & (1 << i) != 0 {
            path.throughput = throughput[i];
            path.prev_pdf = pdf[i];
            path.o = origin[i];
            path.d = wi[i];
            live[*n_live] = k;
            *n_live += 1;
        }
    }
}

#[cfg(test)]
mod tests;
