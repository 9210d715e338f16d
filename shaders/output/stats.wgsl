// The ROI's statistics as the window and the stop conditions report them, measured where the
// accumulation lives (DESIGN.md §1, output): the samples and pixels of the ROI, the median
// standard error of the mean luminance over the ROI's and the periphery's noisy pixels, and
// the ROI's progress (its fewest samples and median SE). Only the totals and five selected
// values come back (a few dozen bytes) instead of the accumulation and the DGI (24 bytes a
// pixel). CPU twin: `RoiStats::measure` in src/output/stats.rs; dispatch:
// src/output/stats/gpu.rs.
//
// The medians are exact order statistics of the per-pixel values: a radix select over the
// values' IEEE patterns (all values are ≥ 0, so their patterns order as the values do), eight
// bits a round from the top, four rounds. Each round `histogram` counts, per selection, the
// values that agree with the selection's prefix so far by their next eight bits, and `pick`
// walks the counts to the bin that holds the selection's rank. Entries in dispatch order:
// `totals`, `ranks`, then (`histogram`, `pick`) four times.

// Mirrors `GpuStatsParams` in src/output/stats/gpu.rs (16 bytes).
struct StatsParams {
    pixels: u32,
    // 1: a pixel whose bit in `shown` is 0 is no ROI pixel of the totals and the progress.
    masked: u32,
    // 1 − p_min, as the CPU computes it: the periphery is d > 0 and d ≥ floor.
    floor: f32,
    _pad: u32,
}

// A selection: the value of rank `rank` (from 0, ascending) of set `group`; after round r the
// top 8·(r + 1) bits of its pattern are `prefix` (the bits of `mask`).
struct Selection {
    group: u32,
    rank: u32,
    prefix: u32,
    mask: u32,
    wanted: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

// The sets: the ROI's noisy pixels, the periphery's noisy pixels, the ROI's shown pixels.
const SET_ROI_NOISY: u32 = 0u;
const SET_PERIPHERY_NOISY: u32 = 1u;
const SET_PROGRESS: u32 = 2u;
const SELECTIONS: u32 = 5u;
const BINS: u32 = 256u;

// Indices of `Stats::totals`.
const T_ROI_NOISY: u32 = 0u;
const T_PERIPHERY_NOISY: u32 = 1u;
const T_ROI_PIXELS: u32 = 2u;
const T_SAMPLES_LO: u32 = 3u;
const T_SAMPLES_HI: u32 = 4u;
const T_MIN_SAMPLES: u32 = 5u;

// Mirrors `GpuStatsHead` in src/output/stats/gpu.rs (the part read back), then the histograms.
struct Stats {
    totals: array<atomic<u32>, 8>,
    rounds_done: u32,
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
    sel: array<Selection, 5>,
    hist: array<atomic<u32>, 1280>,
}

const WORKGROUP: u32 = 256u;
// Pixels a thread visits per dispatch (fewer workgroups, fewer global atomics).
const PER_THREAD: u32 = 16u;
const INF_BITS: u32 = 0x7F800000u;

@group(0) @binding(0) var<uniform> cfg: StatsParams;
// The renderer's accumulation: RGB sum and Σ luminance² per pixel, and the sample counts.
@group(0) @binding(1) var<storage, read> accum: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> counts: array<u32>;
@group(0) @binding(3) var<storage, read> dgi: array<f32>;
// Bit p % 32 of word p / 32: whether some tile shows pixel p (read only with `masked`).
@group(0) @binding(4) var<storage, read> shown: array<u32>;
@group(0) @binding(5) var<storage, read_write> stats: Stats;

fn luminance(rgb: vec3<f32>) -> f32 {
    return 0.2126 * rgb.x + 0.7152 * rgb.y + 0.0722 * rgb.z;
}

// What a pixel contributes: its sets (bit s: member of set s), the pattern of its SE (the
// progress's value: +inf below two samples) and its count.
struct Pixel {
    sets: u32,
    bits: u32,
    count: u32,
}

// √(s²/n) of the mean luminance, as `Accumulation::luminance_variance_of_mean`: the CPU takes
// (Σ L² − n·mean²)/(n − 1) in f64; here L²/n is carried as two floats (an exact product by
// FMA, the division's remainder by FMA), so the difference that cancels is exact to the
// float's last bits and only the final roundings differ from the CPU's.
fn se_bits(s: vec4<f32>, n: u32) -> u32 {
    let nf = f32(n);
    let l = luminance(s.xyz);
    let p = l * l;
    let e = fma(l, l, -p);
    let q1 = p / nf;
    let r = fma(-q1, nf, p);
    let q2 = (r + e) / nf;
    let num = (s.w - q1) - q2;
    let nb = bitcast<u32>(num);
    // Negative, −0 and NaN: variance 0 (the CPU's `max(0.0)`, which takes 0 for NaN too).
    if (nb & 0x80000000u) != 0u || (nb & 0x7FFFFFFFu) > INF_BITS || nb == 0u {
        return 0u;
    }
    let var_mean = (num / (nf - 1.0)) / nf;
    return bitcast<u32>(sqrt(var_mean)) & 0x7FFFFFFFu;
}

fn pixel(i: u32) -> Pixel {
    var out = Pixel(0u, INF_BITS, counts[i]);
    let d = dgi[i];
    let is_shown = cfg.masked == 0u || (shown[i / 32u] & (1u << (i % 32u))) != 0u;
    let roi = d == 0.0;
    let periphery = d > 0.0 && d >= cfg.floor;
    if !roi && !periphery {
        return out;
    }
    if out.count >= 2u {
        out.bits = se_bits(accum[i], out.count);
    }
    // Noisy: an SE that is defined, finite and above 0.
    let noisy = out.count >= 2u && out.bits != 0u && out.bits < INF_BITS;
    if roi && noisy {
        out.sets |= 1u << SET_ROI_NOISY;
    }
    if periphery && noisy {
        out.sets |= 1u << SET_PERIPHERY_NOISY;
    }
    if roi && is_shown {
        out.sets |= 1u << SET_PROGRESS;
    }
    return out;
}

// The workgroup's index on the 2D grid and the first pixel its threads visit.
fn group_index(wg: vec3<u32>, groups: vec3<u32>) -> u32 {
    return wg.x + wg.y * groups.x;
}

var<workgroup> wg_totals: array<atomic<u32>, 8>;

// Adds `v` to the 64-bit count (lo, hi) held in two workgroup atomics.
fn add_wg_u64(v_lo: u32, v_hi: u32) {
    let old = atomicAdd(&wg_totals[T_SAMPLES_LO], v_lo);
    let carry = select(0u, 1u, old + v_lo < old);
    if v_hi + carry != 0u {
        atomicAdd(&wg_totals[T_SAMPLES_HI], v_hi + carry);
    }
}

@compute @workgroup_size(256)
fn totals(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    if lid < 8u {
        atomicStore(&wg_totals[lid], select(0u, 0xFFFFFFFFu, lid == T_MIN_SAMPLES));
    }
    workgroupBarrier();
    let first = group_index(wg, groups) * WORKGROUP * PER_THREAD;
    var noisy_roi = 0u;
    var noisy_periphery = 0u;
    var roi_pixels = 0u;
    var lo = 0u;
    var hi = 0u;
    var fewest = 0xFFFFFFFFu;
    for (var k = 0u; k < PER_THREAD; k++) {
        let i = first + k * WORKGROUP + lid;
        if i >= cfg.pixels {
            break;
        }
        let p = pixel(i);
        noisy_roi += (p.sets >> SET_ROI_NOISY) & 1u;
        noisy_periphery += (p.sets >> SET_PERIPHERY_NOISY) & 1u;
        if (p.sets & (1u << SET_PROGRESS)) != 0u {
            roi_pixels += 1u;
            let sum = lo + p.count;
            hi += select(0u, 1u, sum < lo);
            lo = sum;
            fewest = min(fewest, p.count);
        }
    }
    if noisy_roi != 0u {
        atomicAdd(&wg_totals[T_ROI_NOISY], noisy_roi);
    }
    if noisy_periphery != 0u {
        atomicAdd(&wg_totals[T_PERIPHERY_NOISY], noisy_periphery);
    }
    if roi_pixels != 0u {
        atomicAdd(&wg_totals[T_ROI_PIXELS], roi_pixels);
        add_wg_u64(lo, hi);
        atomicMin(&wg_totals[T_MIN_SAMPLES], fewest);
    }
    workgroupBarrier();
    if lid == 0u {
        let n_roi = atomicLoad(&wg_totals[T_ROI_NOISY]);
        let n_far = atomicLoad(&wg_totals[T_PERIPHERY_NOISY]);
        let n_px = atomicLoad(&wg_totals[T_ROI_PIXELS]);
        if n_roi != 0u {
            atomicAdd(&stats.totals[T_ROI_NOISY], n_roi);
        }
        if n_far != 0u {
            atomicAdd(&stats.totals[T_PERIPHERY_NOISY], n_far);
        }
        if n_px != 0u {
            atomicAdd(&stats.totals[T_ROI_PIXELS], n_px);
            let s_lo = atomicLoad(&wg_totals[T_SAMPLES_LO]);
            let s_hi = atomicLoad(&wg_totals[T_SAMPLES_HI]);
            let old = atomicAdd(&stats.totals[T_SAMPLES_LO], s_lo);
            let carry = select(0u, 1u, old + s_lo < old);
            if s_hi + carry != 0u {
                atomicAdd(&stats.totals[T_SAMPLES_HI], s_hi + carry);
            }
            atomicMin(&stats.totals[T_MIN_SAMPLES], atomicLoad(&wg_totals[T_MIN_SAMPLES]));
        }
    }
}

// The five selections from the totals: each noise median needs the values of rank n/2 and,
// for an even n, n/2 − 1 (their mean, as `median_finite`); the progress's median is the value
// of rank n/2 (as `RoiProgress::measure_where`).
@compute @workgroup_size(1)
fn ranks() {
    let n = vec3<u32>(
        atomicLoad(&stats.totals[T_ROI_NOISY]),
        atomicLoad(&stats.totals[T_PERIPHERY_NOISY]),
        atomicLoad(&stats.totals[T_ROI_PIXELS]),
    );
    for (var s = 0u; s < SELECTIONS; s++) {
        // Selections 0, 1: the ROI's noise; 2, 3: the periphery's; 4: the progress.
        let group = s / 2u;
        let count = n[group];
        let even_lower = s < 4u && (s % 2u) == 1u && count % 2u == 0u && count > 0u;
        stats.sel[s] = Selection(
            group,
            count / 2u - select(0u, 1u, even_lower),
            0u,
            0u,
            select(0u, 1u, count > 0u),
            0u,
            0u,
            0u,
        );
    }
    stats.rounds_done = 0u;
}

var<workgroup> wg_hist: array<atomic<u32>, 1280>;

@compute @workgroup_size(256)
fn histogram(
    @builtin(local_invocation_index) lid: u32,
    @builtin(workgroup_id) wg: vec3<u32>,
    @builtin(num_workgroups) groups: vec3<u32>,
) {
    for (var b = lid; b < SELECTIONS * BINS; b += WORKGROUP) {
        atomicStore(&wg_hist[b], 0u);
    }
    workgroupBarrier();
    let shift = 24u - 8u * stats.rounds_done;
    var sel: array<Selection, 5>;
    for (var s = 0u; s < SELECTIONS; s++) {
        sel[s] = stats.sel[s];
    }
    let first = group_index(wg, groups) * WORKGROUP * PER_THREAD;
    for (var k = 0u; k < PER_THREAD; k++) {
        let i = first + k * WORKGROUP + lid;
        if i >= cfg.pixels {
            break;
        }
        let p = pixel(i);
        if p.sets == 0u {
            continue;
        }
        for (var s = 0u; s < SELECTIONS; s++) {
            if sel[s].wanted != 0u && (p.sets & (1u << sel[s].group)) != 0u
                && (p.bits & sel[s].mask) == sel[s].prefix {
                atomicAdd(&wg_hist[s * BINS + ((p.bits >> shift) & 0xFFu)], 1u);
            }
        }
    }
    workgroupBarrier();
    for (var b = lid; b < SELECTIONS * BINS; b += WORKGROUP) {
        let c = atomicLoad(&wg_hist[b]);
        if c != 0u {
            atomicAdd(&stats.hist[b], c);
        }
    }
}

// One thread a selection: the bin that holds its rank becomes the next 8 bits of its prefix,
// the rank becomes the rank within that bin; the selection's histogram is cleared for the next
// round.
@compute @workgroup_size(8)
fn pick(@builtin(local_invocation_index) lid: u32) {
    let rounds_done = stats.rounds_done;
    if lid < SELECTIONS && stats.sel[lid].wanted != 0u {
        let shift = 24u - 8u * rounds_done;
        var rank = stats.sel[lid].rank;
        var bin = 0u;
        for (var b = 0u; b < BINS; b++) {
            let c = atomicLoad(&stats.hist[lid * BINS + b]);
            if rank < c {
                bin = b;
                break;
            }
            rank -= c;
        }
        stats.sel[lid].rank = rank;
        stats.sel[lid].prefix |= bin << shift;
        stats.sel[lid].mask |= 0xFFu << shift;
    }
    if lid < SELECTIONS {
        for (var b = 0u; b < BINS; b++) {
            atomicStore(&stats.hist[lid * BINS + b], 0u);
        }
    }
    storageBarrier();
    if lid == 0u {
        stats.rounds_done = rounds_done + 1u;
    }
}
