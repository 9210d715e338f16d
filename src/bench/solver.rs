//! The closest-point solver on the hard-case set (DESIGN.md §5): iterations, time per
//! solve and accuracy for the f64 CPU solver, its f32 CPU mirror and the f32 WGSL on the GPU.
//!
//! The set is `tests/data/ellipse_hard_cases.csv` (80-digit mpmath references; its header
//! documents the columns), embedded in the binary so the benchmark runs anywhere. Accuracy is
//! `max |d − d_ref| / scale` with `scale = max(a, b, |p|)` (the backward-stability measure of
//! `tests/display/ellipse_hard_cases.rs`). The f64 solver is judged against the CSV's reference; the f32
//! solvers, like in that test, against the f64 solver on the f32-rounded inputs, so the rounding
//! of the inputs to f32 does not count against them. They run on the subset whose inputs are
//! f32-normal (the GPU on the further subset whose intermediate values stay normal, since GPUs
//! may flush subnormals) — the same subsets the tests check.
//!
//! The class of inside points a tiny or subnormal distance off an axis (categories
//! `tiny-off-axis-*`) is left out of this benchmark ([`timed_cases`]): the DGI asks the solver
//! about points outside the ROI only, and that class's arithmetic on subnormal numbers, which
//! x86 cores run about a hundred times slower, would dominate the time per solve.
//! `tests/display/ellipse_hard_cases.rs` holds it to the accuracy bounds, and
//! `examples/ellipse_bench.rs` times it apart.

use std::hint::black_box;
use std::time::Instant;

use glam::DVec2;
use serde::Serialize;

use crate::gpu::{Backend, GpuContext, GpuError, PassTimer};
use crate::roi::ellipse::{
    self, F32_DISTANCE_BOUND, closest_point_on_ellipse, closest_point_on_ellipse_f32,
};

/// The hard-case set, as checked in.
pub const HARD_CASES_CSV: &str = include_str!("../../tests/data/ellipse_hard_cases.csv");
/// Its path in the repository (for messages and the report).
pub const HARD_CASES_PATH: &str = "tests/data/ellipse_hard_cases.csv";
/// The f64 solver's accuracy bound (DESIGN.md §5): distance error ≤ this share of the scale.
pub const F64_DISTANCE_BOUND: f64 = 1e-14;
/// The spacing of subnormal doubles (2⁻¹⁰⁷⁴): a subnormal result cannot be closer to the truth
/// than half of it, and each rounding on the way may cost one. Errors up to four of them are not
/// counted (as in `tests/display/ellipse_hard_cases.rs`), else cases with a subnormal scale would report
/// a relative error of order 1 that no floating-point method can avoid.
pub const SUBNORMAL_SLACK: f64 = 4.0 * f64::from_bits(1);

/// One case of the set.
#[derive(Clone, Debug)]
pub struct HardCase {
    /// Line in the file (1-based).
    pub line: usize,
    pub a: f64,
    pub b: f64,
    pub p: DVec2,
    pub d_ref: f64,
    pub category: String,
}

impl HardCase {
    #[must_use]
    pub fn scale(&self) -> f64 {
        self.a.max(self.b).max(self.p.x.hypot(self.p.y))
    }
}

/// A malformed line of the hard-case file.
#[derive(Debug, thiserror::Error)]
#[error("{file}:{line}: {reason}")]
pub struct HardCaseError {
    pub file: String,
    pub line: usize,
    pub reason: String,
}

/// Parses the hard-case CSV (`#` comments, a header line starting `a,`, ten columns).
pub fn parse_cases(text: &str, file: &str) -> Result<Vec<HardCase>, HardCaseError> {
    const COLUMNS: [&str; 10] = [
        "a", "b", "x", "y", "d_ref", "cx_ref", "cy_ref", "unique", "kappa", "category",
    ];
    let mut cases = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let err = |reason: String| HardCaseError {
            file: file.to_string(),
            line: i + 1,
            reason,
        };
        if line.starts_with('#') || line.starts_with("a,") || line.trim().is_empty() {
            continue;
        }
        let f: Vec<&str> = line.split(',').collect();
        if f.len() != COLUMNS.len() {
            return Err(err(format!(
                "{} fields, expected {} ({})",
                f.len(),
                COLUMNS.len(),
                COLUMNS.join(",")
            )));
        }
        let num = |k: usize| -> Result<f64, HardCaseError> {
            f[k].trim()
                .parse()
                .map_err(|_| err(format!("field '{}': not a number: {:?}", COLUMNS[k], f[k])))
        };
        cases.push(HardCase {
            line: i + 1,
            a: num(0)?,
            b: num(1)?,
            p: DVec2::new(num(2)?, num(3)?),
            d_ref: num(4)?,
            category: f[9].trim().to_string(),
        });
    }
    Ok(cases)
}

/// The f32-rounded inputs `[a, b, x, y]` of the cases whose inputs stay f32-normal (or zero).
#[must_use]
pub fn f32_inputs(cases: &[HardCase]) -> Vec<[f32; 4]> {
    let ok = |v: f32| v == 0.0 || (v.is_normal() && v.abs() < 1e30);
    cases
        .iter()
        .map(|c| [c.a as f32, c.b as f32, c.p.x as f32, c.p.y as f32])
        .filter(|v| v.iter().all(|&x| ok(x)))
        .collect()
}

/// Whether the GPU solver can run f32 case `[a, b, x, y]` faithfully: `b/a` and `(b/a)·(y/a)`
/// stay normal, since GPUs may flush subnormal intermediate values.
#[must_use]
pub fn gpu_safe(v: &[f32; 4]) -> bool {
    let (lo, hi) = (v[0].min(v[1]), v[0].max(v[1]));
    lo == 0.0
        || ((lo / hi).is_normal() && lo / hi * (v[2].abs().max(v[3].abs()) / hi) >= 1e-30)
        || (v[2] == 0.0 && v[3] == 0.0)
}

/// The subset of [`f32_inputs`] that the GPU runs ([`gpu_safe`]).
#[must_use]
pub fn gpu_inputs(f32_cases: &[[f32; 4]]) -> Vec<[f32; 4]> {
    f32_cases.iter().filter(|v| gpu_safe(v)).copied().collect()
}

/// The f64 solver's distance for f32 inputs (the f32 solvers' reference) and the scale.
fn f64_for(v: [f32; 4]) -> (f64, f64) {
    let (a, b) = (f64::from(v[0]), f64::from(v[1]));
    let p = DVec2::new(f64::from(v[2]), f64::from(v[3]));
    let scale = a.max(b).max(p.length());
    (closest_point_on_ellipse(a, b, p).distance, scale)
}

/// `|d − d_ref|` beyond the subnormal slack, as a share of `scale` (0 for a zero scale).
fn rel_err(d: f64, d_ref: f64, scale: f64) -> f64 {
    let e = ((d - d_ref).abs() - SUBNORMAL_SLACK).max(0.0);
    if scale > 0.0 { e / scale } else { e }
}

/// The closest-point kernel of the WGSL library, one case `[a, b, x, y]` per invocation, two
/// vec4 per case: `(distance, filled distance, iterations as bits, 0)` and `(closest x, closest
/// y, 0, 0)`.
const KERNEL: &str = r"
@group(0) @binding(0) var<storage, read> cases: array<vec4<f32>>;
@group(0) @binding(1) var<storage, read_write> results: array<vec4<f32>>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i >= arrayLength(&cases)) {
        return;
    }
    let c = cases[i];
    let r = ellipse_closest_point(c.x, c.y, c.zw);
    let filled = ellipse_filled_distance(c.x, c.y, c.zw);
    results[2u * i] = vec4<f32>(r.distance, filled, bitcast<f32>(r.iterations), 0.0);
    results[2u * i + 1u] = vec4<f32>(r.point, 0.0, 0.0);
}
";

/// The WGSL closest-point solver (`shaders/roi/ellipse.wgsl`) as a batch kernel, for the
/// benchmark and the hard-case test (the DGI kernel inlines the same functions).
pub struct GpuEllipseSolver {
    pipeline: wgpu::ComputePipeline,
}

/// What one GPU batch returned.
pub struct GpuSolveResult {
    /// Per case: distance, distance to the filled ellipse (0 inside), iterations, closest point.
    pub distance: Vec<f32>,
    pub filled: Vec<f32>,
    pub iterations: Vec<u32>,
    pub point: Vec<[f32; 2]>,
    /// Time of each timed dispatch over the whole batch (ms).
    pub ms: Vec<f64>,
    /// Whether `ms` came from GPU timestamps (else submit-to-done wall clock).
    pub gpu_timestamps: bool,
}

impl GpuEllipseSolver {
    /// The kernel's whole WGSL source (the library and the batch entry point `main`).
    #[must_use]
    pub fn source() -> String {
        format!("{}\n{KERNEL}", ellipse::WGSL)
    }

    #[must_use]
    pub fn new(ctx: &GpuContext) -> Self {
        let pipeline = ctx.compute_pipeline("ellipse solver bench", &Self::source(), "main");
        Self { pipeline }
    }

    /// Solves every case once for the results (untimed, also the warm-up), then `reps` more
    /// times, timed.
    pub fn solve(
        &self,
        ctx: &GpuContext,
        cases: &[[f32; 4]],
        reps: u32,
    ) -> Result<GpuSolveResult, GpuError> {
        use wgpu::util::DeviceExt;
        if cases.is_empty() {
            return Ok(GpuSolveResult {
                distance: Vec::new(),
                filled: Vec::new(),
                iterations: Vec::new(),
                point: Vec::new(),
                ms: Vec::new(),
                gpu_timestamps: false,
            });
        }
        let device = &ctx.device;
        let input = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("ellipse cases"),
            contents: bytemuck::cast_slice(cases),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let output = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("ellipse results"),
            size: (cases.len() * 32) as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("ellipse solver bench"),
            layout: &self.pipeline.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: input.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: output.as_entire_binding(),
                },
            ],
        });
        let groups = cases.len().div_ceil(64) as u32;
        let record = |enc: &mut wgpu::CommandEncoder, timer: Option<(&PassTimer, u32)>| {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("ellipse solver bench"),
                timestamp_writes: timer.map(|(t, i)| t.writes(i)),
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups(groups, 1, 1);
        };
        let mut enc = device.create_command_encoder(&Default::default());
        record(&mut enc, None);
        ctx.queue.submit([enc.finish()]);
        let out: Vec<[f32; 4]> = ctx.read_buffer(&output)?;
        let reps = reps.max(1);
        let (ms, gpu_timestamps) = if let Some(timer) = PassTimer::new(ctx, reps) {
            let mut enc = device.create_command_encoder(&Default::default());
            for i in 0..reps {
                record(&mut enc, Some((&timer, i)));
            }
            timer.resolve(&mut enc);
            ctx.queue.submit([enc.finish()]);
            (timer.read_ms(ctx)?, true)
        } else {
            let mut ms = Vec::new();
            for _ in 0..reps {
                let t = Instant::now();
                let mut enc = device.create_command_encoder(&Default::default());
                record(&mut enc, None);
                ctx.queue.submit([enc.finish()]);
                ctx.wait()?;
                ms.push(t.elapsed().as_secs_f64() * 1e3);
            }
            (ms, false)
        };
        let (head, point): (Vec<_>, Vec<_>) = out.chunks_exact(2).map(|r| (r[0], r[1])).unzip();
        Ok(GpuSolveResult {
            distance: head.iter().map(|r| r[0]).collect(),
            filled: head.iter().map(|r| r[1]).collect(),
            iterations: head.iter().map(|r| r[2].to_bits()).collect(),
            point: point.iter().map(|r| [r[0], r[1]]).collect(),
            ms,
            gpu_timestamps,
        })
    }
}

/// One solver's figures.
#[derive(Clone, Debug, Serialize)]
pub struct SolverRow {
    /// "f64 CPU", "f32 CPU mirror" or "f32 WGSL (GPU)".
    pub solver: String,
    /// What the distance is compared with.
    pub reference: String,
    pub cases: usize,
    pub iterations_max: u32,
    pub iterations_mean: f64,
    /// Time per solve: median and minimum over the repetitions of the whole set (ns). CPU: one
    /// thread; GPU: one dispatch over the set divided by the case count.
    pub ns_per_solve_median: f64,
    pub ns_per_solve_min: f64,
    /// max |d − d_ref| / scale (errors within [`SUBNORMAL_SLACK`] not counted).
    pub max_err_of_scale: f64,
    /// The stated bound on it.
    pub bound_of_scale: f64,
    pub gpu_timestamps: bool,
}

/// The solver section of the report.
#[derive(Clone, Debug, Serialize)]
pub struct SolverReport {
    pub file: String,
    pub cases: usize,
    pub reps: u32,
    pub rows: Vec<SolverRow>,
    /// Why the GPU row is missing, when it is.
    pub gpu_not_run: Option<String>,
}

#[derive(Debug, thiserror::Error)]
pub enum SolverBenchError {
    #[error(transparent)]
    Cases(#[from] HardCaseError),
    #[error(transparent)]
    Gpu(#[from] GpuError),
}

fn ns_stats(ms: &[f64], n: usize) -> (f64, f64) {
    let per = |v: f64| v * 1e6 / n.max(1) as f64;
    (
        per(super::median(ms.to_vec())),
        per(ms.iter().copied().fold(f64::INFINITY, f64::min)),
    )
}

/// Times `reps` passes of `f` over every case on this thread (ms per pass).
fn time_cpu<T: Copy>(cases: &[T], reps: u32, mut f: impl FnMut(T)) -> Vec<f64> {
    (0..reps.max(1))
        .map(|_| {
            let t = Instant::now();
            for &c in cases {
                f(black_box(c));
            }
            t.elapsed().as_secs_f64() * 1e3
        })
        .collect()
}

/// The cases the benchmark times: every case but the inside tiny-off-axis class (module docs).
#[must_use]
pub fn timed_cases(cases: Vec<HardCase>) -> Vec<HardCase> {
    cases
        .into_iter()
        .filter(|c| !c.category.starts_with(TINY_OFF_AXIS))
        .collect()
}

/// The category prefix of the class left out of the timing.
pub const TINY_OFF_AXIS: &str = "tiny-off-axis";

/// Runs the three solvers over the embedded hard-case set ([`timed_cases`]), `reps` timed
/// passes each.
pub fn run(
    backend: &Backend,
    reps: u32,
    mut progress: impl FnMut(&str),
) -> Result<SolverReport, SolverBenchError> {
    let cases = timed_cases(parse_cases(HARD_CASES_CSV, HARD_CASES_PATH)?);
    let mut rows = Vec::new();

    progress("closest-point solver: f64 CPU");
    let (mut it_max, mut it_sum, mut err) = (0u32, 0u64, 0f64);
    for c in &cases {
        let r = closest_point_on_ellipse(c.a, c.b, c.p);
        it_max = it_max.max(r.iterations);
        it_sum += u64::from(r.iterations);
        err = err.max(rel_err(r.distance, c.d_ref, c.scale()));
    }
    let inputs: Vec<(f64, f64, DVec2)> = cases.iter().map(|c| (c.a, c.b, c.p)).collect();
    let ms = time_cpu(&inputs, reps, |(a, b, p)| {
        black_box(closest_point_on_ellipse(a, b, p));
    });
    let (med, min) = ns_stats(&ms, cases.len());
    rows.push(SolverRow {
        solver: "f64 CPU".into(),
        reference: "80-digit reference (d_ref)".into(),
        cases: cases.len(),
        iterations_max: it_max,
        iterations_mean: it_sum as f64 / cases.len().max(1) as f64,
        ns_per_solve_median: med,
        ns_per_solve_min: min,
        max_err_of_scale: err,
        bound_of_scale: F64_DISTANCE_BOUND,
        gpu_timestamps: false,
    });

    progress("closest-point solver: f32 CPU mirror");
    let f32_cases = f32_inputs(&cases);
    let (mut it_max, mut it_sum, mut err) = (0u32, 0u64, 0f64);
    for v in &f32_cases {
        let r = closest_point_on_ellipse_f32(v[0], v[1], [v[2], v[3]]);
        let (d_ref, scale) = f64_for(*v);
        it_max = it_max.max(r.iterations);
        it_sum += u64::from(r.iterations);
        err = err.max(rel_err(f64::from(r.distance), d_ref, scale));
    }
    let ms = time_cpu(&f32_cases, reps, |v| {
        black_box(closest_point_on_ellipse_f32(v[0], v[1], [v[2], v[3]]));
    });
    let (med, min) = ns_stats(&ms, f32_cases.len());
    let f32_reference = "f64 solver on the f32-rounded inputs";
    rows.push(SolverRow {
        solver: "f32 CPU mirror".into(),
        reference: f32_reference.into(),
        cases: f32_cases.len(),
        iterations_max: it_max,
        iterations_mean: it_sum as f64 / f32_cases.len().max(1) as f64,
        ns_per_solve_median: med,
        ns_per_solve_min: min,
        max_err_of_scale: err,
        bound_of_scale: F32_DISTANCE_BOUND,
        gpu_timestamps: false,
    });

    let gpu_not_run = match backend {
        Backend::Gpu(ctx) => {
            progress("closest-point solver: f32 WGSL on the GPU");
            let gpu_cases = gpu_inputs(&f32_cases);
            let r = GpuEllipseSolver::new(ctx).solve(ctx, &gpu_cases, reps)?;
            let mut err = 0f64;
            for (v, &d) in gpu_cases.iter().zip(&r.distance) {
                let (d_ref, scale) = f64_for(*v);
                // A NaN must not vanish in max().
                err = if d.is_finite() {
                    err.max(rel_err(f64::from(d), d_ref, scale))
                } else {
                    f64::INFINITY
                };
            }
            let (med, min) = ns_stats(&r.ms, gpu_cases.len());
            rows.push(SolverRow {
                solver: "f32 WGSL (GPU)".into(),
                reference: f32_reference.into(),
                cases: gpu_cases.len(),
                iterations_max: r.iterations.iter().copied().max().unwrap_or(0),
                iterations_mean: r.iterations.iter().map(|&i| f64::from(i)).sum::<f64>()
                    / gpu_cases.len().max(1) as f64,
                ns_per_solve_median: med,
                ns_per_solve_min: min,
                max_err_of_scale: err,
                bound_of_scale: F32_DISTANCE_BOUND,
                gpu_timestamps: r.gpu_timestamps,
            });
            None
        }
        Backend::Cpu => Some("not run: no GPU adapter (CPU backend)".to_string()),
    };
    Ok(SolverReport {
        file: HARD_CASES_PATH.to_string(),
        cases: cases.len(),
        reps: reps.max(1),
        rows,
        gpu_not_run,
    })
}

/// The solver table as Markdown.
#[must_use]
pub fn markdown(r: &SolverReport) -> String {
    let mut s = format!(
        "Hard-case set `{}` ({} cases, 80-digit references; the inside tiny-off-axis class, which the DGI never meets, is timed apart by `examples/ellipse_bench.rs`); time per solve from {} passes over the set (CPU: one thread). Accuracy = max |d − d_ref| / max(a, b, |p|); the f32 solvers are judged against the f64 solver on their f32-rounded inputs, on the cases whose inputs are f32-normal (GPU: whose intermediate values stay normal too).\n\n| solver | cases | iterations max | iterations mean | ns/solve (median) | ns/solve (min) | max error / scale | bound | reference |\n|---|---|---|---|---|---|---|---|---|\n",
        r.file, r.cases, r.reps
    );
    for row in &r.rows {
        s += &format!(
            "| {}{} | {} | {} | {:.2} | {:.1} | {:.1} | {:.2e} | {:.0e} | {} |\n",
            row.solver,
            if row.gpu_timestamps {
                " (timestamps)"
            } else {
                ""
            },
            row.cases,
            row.iterations_max,
            row.iterations_mean,
            row.ns_per_solve_median,
            row.ns_per_solve_min,
            row.max_err_of_scale,
            row.bound_of_scale,
            row.reference,
        );
    }
    if let Some(why) = &r.gpu_not_run {
        s += &format!("| f32 WGSL (GPU) | {why} | | | | | | | |\n");
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn embedded_set_parses_and_bad_lines_name_the_file_line_and_field() {
        let cases = parse_cases(HARD_CASES_CSV, HARD_CASES_PATH).unwrap();
        assert!(cases.len() > 1500, "only {} cases", cases.len());
        assert!(f32_inputs(&cases).len() > 1000);
        let e = parse_cases(
            "# c\na,b\n1,2,3,4,5,6,7,1,1,x\n1,2,oops,4,5,6,7,1,1,x\n",
            "f.csv",
        )
        .unwrap_err();
        assert_eq!((e.file.as_str(), e.line), ("f.csv", 4));
        assert!(e.to_string().contains("field 'x'"), "{e}");
        let e = parse_cases("1,2,3\n", "g.csv").unwrap_err();
        assert!(e.to_string().starts_with("g.csv:1: 3 fields"), "{e}");
    }

    #[test]
    fn rel_err_ignores_subnormal_noise_only() {
        assert_eq!(rel_err(1.0, 1.0, 1.0), 0.0);
        assert_eq!(rel_err(f64::from_bits(3), 0.0, f64::from_bits(8)), 0.0);
        // (1 + 1e-10) − 1 is 1e-10 to about 1e-6 relative (the spacing of doubles near 1).
        assert!((rel_err(1.0 + 1e-10, 1.0, 2.0) / 0.5e-10 - 1.0).abs() < 1e-6);
    }
}
