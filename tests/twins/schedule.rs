//! The GPU schedule against its CPU twin (lavapipe in CI): the same pixels, the same count, each
//! block's run in the twin's order, indirect arguments that cover the list, and a stand-in
//! tracer that the indirect dispatch drives over exactly the listed pixels.

use std::collections::HashMap;

use raygun::gpu::GpuContext;
use raygun::random::pcg4d;
use raygun::schedule::gpu::{SELECT_WGSL, ScheduleConfig, ScheduleKernel, ScheduleRun};
use raygun::schedule::{
    Order, indirect_grid, probability, schedule_cpu, schedule_cpu_blocks, selected,
};
use wgpu::util::DeviceExt;

fn storage_buffer(ctx: &GpuContext, label: &str, data: &[u8]) -> wgpu::Buffer {
    ctx.device
        .create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: data,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
        })
}

/// A DGI with values spread over [0, 1], exact 0s and 1s included (every 8th pixel).
fn mixed_dgi(width: u32, height: u32, salt: u32) -> Vec<f32> {
    (0..width * height)
        .map(|i| {
            let h = pcg4d([i, salt, 0, 0])[0];
            match h % 8 {
                0 => 0.0,
                1 => 1.0,
                _ => (h >> 8) as f32 / 16_777_216.0,
            }
        })
        .collect()
}

fn prepare(
    ctx: &GpuContext,
    kernel: &ScheduleKernel,
    dgi: &wgpu::Buffer,
    (width, height): (u32, u32),
    p_min: f32,
    order: Order,
    trace_workgroup_size: u32,
) -> ScheduleRun {
    kernel
        .prepare(
            ctx,
            dgi,
            &ScheduleConfig {
                width,
                height,
                p_min,
                order,
                trace_workgroup_size,
                trace_max_groups: 0,
            },
        )
        .expect("valid schedule configuration")
}

fn run_once(
    ctx: &GpuContext,
    run: &ScheduleRun,
    iteration: u32,
    seed: u32,
) -> (Vec<u32>, [u32; 4]) {
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    run.record(&mut enc, iteration, seed, None);
    ctx.queue.submit([enc.finish()]);
    (run.read_list(ctx).unwrap(), run.read_args(ctx).unwrap())
}

/// The GPU list is the twin's non-empty block runs, each unchanged, in some order: the same
/// set, the same count, and every block contiguous in Morton (or slot) order.
fn assert_same_runs(gpu: &[u32], cpu_blocks: &[Vec<u32>], what: &str) {
    let block_of: HashMap<u32, usize> = cpu_blocks
        .iter()
        .enumerate()
        .flat_map(|(b, run)| run.iter().map(move |&px| (px, b)))
        .collect();
    let expected_len: usize = cpu_blocks.iter().map(Vec::len).sum();
    assert_eq!(gpu.len(), expected_len, "{what}: count");
    let mut seen = vec![false; cpu_blocks.len()];
    let mut i = 0;
    while i < gpu.len() {
        let b = *block_of
            .get(&gpu[i])
            .unwrap_or_else(|| panic!("{what}: pixel {} listed but not selected", gpu[i]));
        assert!(!seen[b], "{what}: block {b} appears in two runs");
        seen[b] = true;
        let run = &cpu_blocks[b];
        assert_eq!(
            &gpu[i..(i + run.len()).min(gpu.len())],
            &run[..],
            "{what}: block {b} at list position {i}"
        );
        i += run.len();
    }
    let mut sorted_gpu = gpu.to_vec();
    sorted_gpu.sort_unstable();
    let mut sorted_cpu = cpu_blocks.concat();
    sorted_cpu.sort_unstable();
    assert_eq!(sorted_gpu, sorted_cpu, "{what}: sets");
}

#[test]
fn gpu_list_equals_the_cpu_twin_for_seeds_iterations_sizes_and_orders() {
    let ctx = GpuContext::for_tests();
    let kernel = ScheduleKernel::new(&ctx);
    // Sizes: several tiles with ragged edges, one tile exactly, single rows and columns, one
    // pixel.
    let sizes = [(130, 70), (64, 32), (97, 1), (1, 45), (1, 1)];
    let mut checked = 0;
    for (w, h) in sizes {
        let n = (w * h) as usize;
        let dgis = [
            ("mixed", mixed_dgi(w, h, w ^ h)),
            ("all-zero", vec![0.0; n]),
            ("all-one", vec![1.0; n]),
        ];
        for (name, dgi) in &dgis {
            let buf = storage_buffer(&ctx, "test dgi", bytemuck::cast_slice(dgi));
            for order in [Order::Coherent, Order::Scattered] {
                for p_min in [0.0, 0.25] {
                    let run = prepare(&ctx, &kernel, &buf, (w, h), p_min, order, 64);
                    for (iteration, seed) in [(0, 0), (1, 0), (7, 12345), (u32::MAX, 99)] {
                        let what = format!(
                            "{w}×{h} {name} {order:?} p_min {p_min} iteration {iteration} seed {seed}"
                        );
                        let (gpu, args) = run_once(&ctx, &run, iteration, seed);
                        let cpu =
                            schedule_cpu_blocks(dgi, w, h, p_min, iteration, seed, order).unwrap();
                        assert_same_runs(&gpu, &cpu, &what);
                        assert_eq!(args[3] as usize, gpu.len(), "{what}: args count");
                        assert_eq!(
                            args[..3],
                            indirect_grid(
                                args[3],
                                64,
                                0,
                                ctx.limits.max_compute_workgroups_per_dimension
                            ),
                            "{what}: grid"
                        );
                        checked += 1;
                    }
                }
            }
        }
    }
    assert_eq!(checked, 5 * 3 * 2 * 2 * 4);
}

#[test]
fn all_zero_and_all_one_dgis_select_everything_and_nothing() {
    let ctx = GpuContext::for_tests();
    let kernel = ScheduleKernel::new(&ctx);
    let (w, h) = (130, 70);
    let n = w * h;
    let zero = storage_buffer(
        &ctx,
        "zero",
        bytemuck::cast_slice(&vec![0.0f32; n as usize]),
    );
    let one = storage_buffer(&ctx, "one", bytemuck::cast_slice(&vec![1.0f32; n as usize]));
    for order in [Order::Coherent, Order::Scattered] {
        let all = prepare(&ctx, &kernel, &zero, (w, h), 0.0, order, 64);
        let none = prepare(&ctx, &kernel, &one, (w, h), 0.0, order, 64);
        let floor = prepare(&ctx, &kernel, &one, (w, h), 1.0, order, 64);
        for iteration in 0..3 {
            let (mut list, args) = run_once(&ctx, &all, iteration, 5);
            assert_eq!(args[3], n, "{order:?}: d = 0 lists every pixel");
            list.sort_unstable();
            assert_eq!(list, (0..n).collect::<Vec<_>>());
            let (list, args) = run_once(&ctx, &none, iteration, 5);
            assert_eq!(
                (list.len(), args),
                (0, [0, 1, 1, 0]),
                "{order:?}: d = 1 lists none"
            );
            let (_, args) = run_once(&ctx, &floor, iteration, 5);
            assert_eq!(args[3], n, "{order:?}: p_min = 1 lists every pixel");
        }
    }
}

#[test]
fn coherent_runs_are_morton_ordered_tiles() {
    // A full selection makes each run a whole tile: the list starts with tile (0, 0)'s 2 × 2
    // quads in Z order, wherever in the list that tile landed.
    let ctx = GpuContext::for_tests();
    let kernel = ScheduleKernel::new(&ctx);
    let (w, h) = (64, 64);
    let dgi = storage_buffer(&ctx, "zero", bytemuck::cast_slice(&vec![0.0f32; 64 * 64]));
    let run = prepare(&ctx, &kernel, &dgi, (w, h), 0.0, Order::Coherent, 64);
    let (list, _) = run_once(&ctx, &run, 0, 0);
    let start = list.iter().position(|&p| p == 0).expect("pixel 0 listed");
    assert_eq!(start % 1024, 0, "tile (0, 0) starts a run");
    assert_eq!(
        &list[start..start + 8],
        &[0, 1, w, w + 1, 2, 3, w + 2, w + 3]
    );
    // Every 64 consecutive entries (one tracer workgroup) lie in an 8 × 8 pixel square.
    for chunk in list.chunks(64) {
        let xs = chunk.iter().map(|p| p % w);
        let ys = chunk.iter().map(|p| p / w);
        let span = |v: Vec<u32>| v.iter().max().unwrap() - v.iter().min().unwrap();
        assert!(span(xs.collect()) < 8 && span(ys.collect()) < 8);
    }
}

/// A WGSL stand-in for the tracer: one thread per listed pixel through the indirect dispatch,
/// counting visits per pixel. It reads the schedule's buffers exactly as the module
/// documentation of `raygun::schedule::gpu` tells the tracer to.
const STAND_IN: &str = "
@group(0) @binding(0) var<storage, read> schedule_args: array<u32, 4>;
@group(0) @binding(1) var<storage, read> schedule_list: array<u32>;
@group(0) @binding(2) var<storage, read_write> visits: array<atomic<u32>>;

override WG: u32 = 64u;

@compute @workgroup_size(WG)
fn main(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let i = (wg.y * schedule_args[0] + wg.x) * WG + li;
    if i >= schedule_args[3] {
        return;
    }
    atomicAdd(&visits[schedule_list[i]], 1u);
}
";

fn stand_in(
    ctx: &GpuContext,
    run: &ScheduleRun,
    visits: &wgpu::Buffer,
) -> (wgpu::ComputePipeline, wgpu::BindGroup) {
    let module = ctx
        .device
        .create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("stand-in tracer"),
            source: wgpu::ShaderSource::Wgsl(STAND_IN.into()),
        });
    let pipeline = ctx
        .device
        .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("stand-in tracer"),
            layout: None,
            module: &module,
            entry_point: Some("main"),
            compilation_options: wgpu::PipelineCompilationOptions {
                constants: &[("WG", f64::from(run.trace_workgroup_size()))],
                ..Default::default()
            },
            cache: None,
        });
    let bind = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("stand-in tracer"),
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: run.args().as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: run.list().as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 2,
                resource: visits.as_entire_binding(),
            },
        ],
    });
    (pipeline, bind)
}

/// Several iterations recorded into one encoder, each followed by the indirect stand-in: every
/// pixel is visited once per iteration that selected it (so each iteration saw its own
/// parameters, and the 2D grid reaches every entry).
#[test]
fn the_indirect_dispatch_visits_each_listed_pixel_once_per_iteration() {
    let ctx = GpuContext::for_tests();
    let kernel = ScheduleKernel::new(&ctx);
    // (size, DGI, tracer workgroup size): 256 × 256 fully selected with one-thread workgroups
    // needs 65 536 groups, past one dimension's 65 535 (gy = 2).
    let cases = [
        (
            130u32,
            70u32,
            mixed_dgi(130, 70, 3),
            64u32,
            0.1f32,
            Order::Coherent,
            5u32,
        ),
        (
            130,
            70,
            mixed_dgi(130, 70, 4),
            128,
            0.0,
            Order::Scattered,
            5,
        ),
        (256, 256, vec![0.0; 256 * 256], 1, 0.0, Order::Coherent, 1),
    ];
    for (w, h, dgi, wg, p_min, order, iterations) in cases {
        let dgi_buf = storage_buffer(&ctx, "dgi", bytemuck::cast_slice(&dgi));
        let run = prepare(&ctx, &kernel, &dgi_buf, (w, h), p_min, order, wg);
        let visits = storage_buffer(&ctx, "visits", &vec![0u8; (w * h * 4) as usize]);
        let (pipeline, bind) = stand_in(&ctx, &run, &visits);
        let seed = 31;
        let mut enc = ctx.device.create_command_encoder(&Default::default());
        for iteration in 0..iterations {
            run.record(&mut enc, iteration, seed, None);
            let mut pass = enc.begin_compute_pass(&Default::default());
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, &bind, &[]);
            pass.dispatch_workgroups_indirect(run.args(), 0);
        }
        ctx.queue.submit([enc.finish()]);
        let got: Vec<u32> = ctx.read_buffer(&visits).unwrap();
        let mut expected = vec![0u32; (w * h) as usize];
        for iteration in 0..iterations {
            for px in schedule_cpu(&dgi, w, h, p_min, iteration, seed, order).unwrap() {
                expected[px as usize] += 1;
            }
        }
        assert_eq!(got, expected, "{w}×{h} workgroup {wg} {order:?}");
        let args = run.read_args(&ctx).unwrap();
        if wg == 1 {
            assert_eq!(args, [32_768, 2, 1, 65_536], "a 2D grid");
        }
    }
}

#[test]
fn indirect_args_cover_tiny_and_synthetic_large_counts() {
    let ctx = GpuContext::for_tests();
    let kernel = ScheduleKernel::new(&ctx);
    let max_per_dim = ctx.limits.max_compute_workgroups_per_dimension;
    let counter = storage_buffer(&ctx, "synthetic counter", &[0; 4]);
    // No cap (a thread an entry), then a regenerating tracer's caps: one group, a few, and
    // more than one grid row holds.
    for (wg, max_groups) in [
        (64u32, 0u32),
        (128, 0),
        (256, 0),
        (64, 1),
        (32, 3),
        (256, 2112),
        (64, 65_535),
    ] {
        let args = kernel
            .prepare_args(&ctx, &counter, wg, max_groups, u32::MAX)
            .expect("u32::MAX entries fit a 2D grid of these workgroups");
        for count in [
            0u32,
            1,
            wg - 1,
            wg,
            wg + 1,
            3 * wg + 1,
            65_535 * wg,
            65_535 * wg + 1,
            3840 * 2160,
            7680 * 4320 * 2,
            u32::MAX,
        ] {
            ctx.queue
                .write_buffer(&counter, 0, bytemuck::bytes_of(&count));
            let mut enc = ctx.device.create_command_encoder(&Default::default());
            args.record(&mut enc);
            ctx.queue.submit([enc.finish()]);
            let [gx, gy, gz, got] = args.read(&ctx).unwrap();
            let what = format!("{count} entries, {wg} threads a group, at most {max_groups}");
            assert_eq!(got, count, "{what}");
            assert_eq!(
                [gx, gy, gz],
                indirect_grid(count, wg, max_groups, max_per_dim),
                "{what}"
            );
            assert!(gx <= max_per_dim && gy <= max_per_dim && gz == 1, "{what}");
            let groups = u64::from(gx) * u64::from(gy);
            let needed = u64::from(count).div_ceil(u64::from(wg));
            if max_groups == 0 || needed <= u64::from(max_groups) {
                assert!(groups >= needed, "{what}: {gx}×{gy} cover the list");
                assert!(groups < needed + u64::from(gy), "{what}: {gx}×{gy}");
            } else {
                // Capped: the threads each trace several entries (the stride is the launch).
                assert!(
                    groups >= u64::from(max_groups) && groups < u64::from(max_groups + gy),
                    "{what}: {gx}×{gy}"
                );
            }
            let reset: Vec<u32> = ctx.read_buffer(&counter).unwrap();
            assert_eq!(reset, [0], "the arguments pass resets the counter");
        }
    }
    let err = kernel
        .prepare_args(&ctx, &counter, 0, 0, 10)
        .err()
        .expect("rejected");
    assert!(err.to_string().contains("workgroup size 0"), "{err}");
}

#[test]
fn bad_configurations_are_rejected_with_the_field_named() {
    let ctx = GpuContext::for_tests();
    let kernel = ScheduleKernel::new(&ctx);
    let dgi = storage_buffer(&ctx, "dgi", &[0; 16]);
    let config = ScheduleConfig {
        width: 2,
        height: 2,
        p_min: 0.0,
        order: Order::Coherent,
        trace_workgroup_size: 64,
        trace_max_groups: 0,
    };
    assert!(kernel.prepare(&ctx, &dgi, &config).is_ok());
    let bad_p = kernel.prepare(
        &ctx,
        &dgi,
        &ScheduleConfig {
            p_min: 2.0,
            ..config
        },
    );
    assert!(bad_p.err().unwrap().to_string().contains("p_min 2"));
    let too_big = kernel.prepare(&ctx, &dgi, &ScheduleConfig { width: 3, ..config });
    assert!(
        too_big
            .err()
            .unwrap()
            .to_string()
            .contains("DGI buffer has 16 bytes")
    );
    let mut run = kernel.prepare(&ctx, &dgi, &config).unwrap();
    assert!(run.set_p_min(-1.0).is_err());
    run.set_p_min(0.5).unwrap();
    assert_eq!(run.gpu_params(3, 4).p_min, 0.5);
}

/// `probability` and `selected` in WGSL, evaluated on the GPU for edge values, bit for bit
/// against the CPU twin.
#[test]
fn wgsl_probability_and_selection_equal_the_cpu_bitwise_at_edge_values() {
    let ctx = GpuContext::for_tests();
    let one_minus_eps = 1.0 - f32::EPSILON / 2.0; // the largest f32 below 1
    let ds = [
        0.0f32,
        1.0,
        1e-8,
        f32::MIN_POSITIVE,
        1e-40, // subnormal: 1 − d rounds to 1 whether or not the GPU flushes it
        f32::EPSILON,
        one_minus_eps,
        1.0 - f32::EPSILON,
        0.5,
        0.1,
        1.0 / 3.0,
        0.95,
        0.05,
    ];
    let p_mins = [
        0.0f32,
        f32::MIN_POSITIVE,
        1e-8,
        0.05,
        0.5,
        one_minus_eps,
        1.0,
    ];
    let pairs: Vec<[f32; 2]> = ds
        .iter()
        .flat_map(|&d| p_mins.iter().map(move |&p| [d, p]))
        .chain(p_mins.iter().map(|&p| [1.0 - p, p])) // d with 1 − d = p_min exactly
        .collect();
    let source = format!(
        "{SELECT_WGSL}
@group(0) @binding(0) var<storage, read> pairs: array<vec2<f32>>;
@group(0) @binding(1) var<storage, read_write> prob: array<u32>;
@group(0) @binding(2) var<storage, read_write> picks: array<u32>;
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) id: vec3<u32>) {{
    let i = id.x;
    if i < arrayLength(&pairs) {{
        prob[i] = bitcast<u32>(probability(pairs[i].x, pairs[i].y));
    }}
    // Selection at the thresholds where rounding matters: p = 2^-24, 1 − 2^-24, 0.5, 1, 0.
    if i < arrayLength(&picks) {{
        let ps = array<f32, 5>(5.9604645e-8, 0.99999994, 0.5, 1.0, 0.0);
        picks[i] = select(0u, 1u, selected(i / 5u, 3u, 17u, ps[i % 5u]));
    }}
}}"
    );
    let module = ctx
        .device
        .create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("probe"),
            source: wgpu::ShaderSource::Wgsl(source.into()),
        });
    let pipeline = ctx
        .device
        .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some("probe"),
            layout: None,
            module: &module,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
    let picks_n = 5 * 20_000u32;
    let pairs_buf = storage_buffer(&ctx, "pairs", bytemuck::cast_slice(&pairs));
    let prob_buf = storage_buffer(&ctx, "prob", &vec![0u8; pairs.len() * 4]);
    let picks_buf = storage_buffer(&ctx, "picks", &vec![0u8; picks_n as usize * 4]);
    let bind = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("probe"),
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[
            wgpu::BindGroupEntry {
                binding: 0,
                resource: pairs_buf.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 1,
                resource: prob_buf.as_entire_binding(),
            },
            wgpu::BindGroupEntry {
                binding: 2,
                resource: picks_buf.as_entire_binding(),
            },
        ],
    });
    let mut enc = ctx.device.create_command_encoder(&Default::default());
    {
        let mut pass = enc.begin_compute_pass(&Default::default());
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &bind, &[]);
        pass.dispatch_workgroups(picks_n.div_ceil(64), 1, 1);
    }
    ctx.queue.submit([enc.finish()]);
    let prob: Vec<u32> = ctx.read_buffer(&prob_buf).unwrap();
    for (&[d, p_min], &bits) in pairs.iter().zip(&prob) {
        assert_eq!(
            bits,
            probability(d, p_min).to_bits(),
            "probability({d:e}, {p_min:e}): GPU {:e}",
            f32::from_bits(bits)
        );
    }
    let picks: Vec<u32> = ctx.read_buffer(&picks_buf).unwrap();
    let ps = [2f32.powi(-24), one_minus_eps, 0.5, 1.0, 0.0];
    assert_eq!(ps[1].to_bits(), 0.99999994f32.to_bits());
    assert_eq!(ps[0], 5.9604645e-8);
    for (i, &pick) in picks.iter().enumerate() {
        let i = i as u32;
        let cpu = selected(i / 5, 3, 17, ps[(i % 5) as usize]);
        assert_eq!(pick == 1, cpu, "pixel {} p {}", i / 5, ps[(i % 5) as usize]);
    }
}

/// The block masks drawn on the GPU are the CPU twin's, bit for bit, for every block: ragged
/// edges, a one-pixel image, DGIs of every kind, p_min 0 and 0.25, several iterations and seeds,
/// with and without a shown mask; and a new DGI is drawn from once it is set.
#[test]
fn gpu_block_masks_equal_the_cpu_twin() {
    use raygun::schedule::gpu::BlockMasksRun;
    use raygun::schedule::{DrawInput, schedule_cpu_block_masks};
    let ctx = GpuContext::for_tests();
    let mut checked = 0;
    for (w, h) in [(130u32, 70u32), (64, 32), (97, 1), (1, 45), (1, 1)] {
        let n = (w * h) as usize;
        let blocks: Vec<u32> = (0..w.div_ceil(32) * h.div_ceil(32)).collect();
        // Every third pixel hidden.
        let shown: Vec<u32> = (0..n.div_ceil(32))
            .map(|k| {
                (0..32)
                    .filter(|b| (32 * k + b) % 3 != 0)
                    .fold(0u32, |m, b| m | 1 << b)
            })
            .collect();
        for shown in [None, Some(&shown[..])] {
            for p_min in [0.0, 0.25] {
                let run = BlockMasksRun::new(&ctx, w, h, p_min, shown).unwrap();
                for (name, dgi) in [
                    ("mixed", mixed_dgi(w, h, w ^ h)),
                    ("all-zero", vec![0.0; n]),
                    ("all-one", vec![1.0; n]),
                ] {
                    run.set_dgi(&ctx, &dgi);
                    for (iteration, seed) in [(0, 0), (7, 12345), (u32::MAX, 99)] {
                        let what = format!(
                            "{w}×{h} {name} p_min {p_min} shown {} iteration {iteration}",
                            shown.is_some()
                        );
                        let gpu = run.masks(&ctx, iteration, seed).unwrap();
                        let input = DrawInput {
                            dgi: &dgi,
                            shown,
                            width: w,
                            height: h,
                            p_min,
                            iteration,
                            seed,
                        };
                        let cpu = schedule_cpu_block_masks(&input, &blocks).unwrap();
                        assert_eq!(gpu, cpu, "{what}");
                        checked += 1;
                    }
                }
            }
        }
    }
    assert_eq!(checked, 5 * 2 * 2 * 3 * 3);
}
