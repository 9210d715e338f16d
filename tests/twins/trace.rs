//! The path tracer (`shaders/trace/*.wgsl`) against its CPU twin (`src/trace/path.rs`): the
//! same image in distribution with different seeds (`render::BLOCK_Z`), the same samples to
//! rounding with the same seed (`render::SAME_SEED_REL`), on scenes that cover every BSDF lobe,
//! light kind and glTF feature the tracer models.

use glam::Vec3;
use raygun::gpu::GpuContext;
use raygun::scene::{Environment, Scene};
use raygun::trace::accum::luminance;
use raygun::trace::pack::PackedScene;

use crate::gltf_scenes::everything;
use crate::render::{render_gpu, render_on_cpu, renders_agree, same_seed_share, settings};
use crate::scenes::twin_scene;

/// Same seed, same paths: the share of pixels whose first samples must agree to rounding on
/// the plain scenes. The rest diverge where rounding flips a Russian-roulette or lobe choice.
const SAME_SEED_SHARE: f64 = 0.95;
/// The same on the scene with every glTF feature, whose alpha tests, glass and coat add choices
/// that rounding can flip.
const SAME_SEED_SHARE_EVERY_FEATURE: f64 = 0.90;

#[test]
fn gpu_and_cpu_twin_converge_to_the_same_image() {
    let ctx = GpuContext::for_tests();
    let scene = twin_scene();
    let spp = 64;
    let cpu = render_on_cpu(&scene, &settings(&scene, 32, 32, 11, 8), spp);
    let gpu = render_gpu(&ctx, &scene, &settings(&scene, 32, 32, 12, 8), spp);
    renders_agree(&gpu, &cpu, "GPU (seed 12) vs CPU (seed 11)").unwrap();
    // The test has power: a 10 % brighter image is told apart.
    let mut brighter = cpu.clone();
    for s in &mut brighter.sum {
        for v in &mut s[..3] {
            *v *= 1.1;
        }
        s[3] *= 1.21;
    }
    assert!(renders_agree(&gpu, &brighter, "GPU vs CPU × 1.1").is_err());
    // Nothing non-finite, and the room is lit.
    assert!(gpu.sum.iter().all(|s| s.iter().all(|v| v.is_finite())));
    assert!(gpu.mean_image().iter().map(|c| luminance(*c)).sum::<f32>() > 0.0);
}

/// With the same seed both backends trace the same paths: most pixels' first samples agree to
/// float rounding (a few paths diverge where rounding flips a Russian-roulette or lobe choice).
#[test]
fn same_seed_gives_the_same_samples_on_both_backends() {
    let ctx = GpuContext::for_tests();
    let scene = twin_scene();
    let s = settings(&scene, 32, 32, 5, 8);
    let cpu = render_on_cpu(&scene, &s, 1);
    let gpu = render_gpu(&ctx, &scene, &s, 1);
    let share = same_seed_share(&cpu, &gpu);
    assert!(
        share >= SAME_SEED_SHARE,
        "only {:.1} % of the pixels agree",
        100.0 * share
    );
}

/// Textures, many materials and a 3 900-triangle BVH: the small city agrees on both backends,
/// under a non-uniform environment map with a sun.
#[test]
fn gpu_and_cpu_agree_on_the_textured_city_under_an_environment_map() {
    use raygun::scene::EnvironmentMap;
    let mut scene = Scene::load(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/scenes/city-small.glb"
    ))
    .unwrap();
    assert!(!scene.textures.is_empty(), "the small city has textures");
    let (w, h) = (32u32, 16u32);
    scene.environment = Environment::Map(EnvironmentMap {
        name: "sun".into(),
        width: w,
        height: h,
        texels: (0..w * h)
            .map(|i| {
                if i == 3 * w + 20 {
                    Vec3::splat(300.0)
                } else {
                    Vec3::new(0.3, 0.4, 0.6)
                }
            })
            .collect(),
    });
    let ctx = GpuContext::for_tests();
    let cpu = render_on_cpu(&scene, &settings(&scene, 32, 32, 21, 5), 48);
    let gpu = render_gpu(&ctx, &scene, &settings(&scene, 32, 32, 22, 5), 48);
    renders_agree(&gpu, &cpu, "city: GPU (seed 22) vs CPU (seed 21)").unwrap();
    let same = render_gpu(&ctx, &scene, &settings(&scene, 32, 32, 21, 5), 1);
    let cpu1 = render_on_cpu(&scene, &settings(&scene, 32, 32, 21, 5), 1);
    let share = same_seed_share(&cpu1, &same);
    assert!(
        share >= SAME_SEED_SHARE,
        "same seed: only {:.1} % of the pixels agree",
        100.0 * share
    );
}

/// The paper's scene itself: the generated Cornell box (open front, environment light) and its
/// ceiling-light variant converge to the same image on both backends.
/// Of hits at the same distance the GPU reports the one on the higher triangle, as the CPU
/// twin does: random triangles each given twice, every copy's hit an exact tie — the first
/// copies glowing red, the second green, neither reflecting — show green wherever they are
/// seen, in the kernel raygun ships and, in a kernel-lab build, in one whose vote reorders the
/// triangle tests.
#[test]
fn ties_go_to_the_higher_triangle_on_the_gpu_as_on_the_cpu() {
    use crate::scenes::{camera, flat, lambert};
    let mut seed = 0x9e37_79b9_u32;
    let mut r = move || {
        seed ^= seed << 13;
        seed ^= seed >> 17;
        seed ^= seed << 5;
        seed as f32 / u32::MAX as f32
    };
    let mut tris = Vec::new();
    for _ in 0..600 {
        let c = Vec3::new(r() * 2.0 - 1.0, r() * 2.0 - 1.0, r() * 2.0 - 1.0);
        let mut corner = || c + (Vec3::new(r(), r(), r()) - 0.5) * 0.6;
        tris.push(flat([corner(), corner(), corner()], 0));
    }
    let copies: Vec<_> = tris
        .iter()
        .map(|t| raygun::scene::Triangle { material: 1, ..*t })
        .collect();
    tris.extend(copies);
    let scene = Scene {
        triangles: tris,
        materials: vec![
            lambert(0.0, Vec3::new(1.0, 0.0, 0.0)),
            lambert(0.0, Vec3::new(0.0, 1.0, 0.0)),
        ],
        cameras: vec![camera(Vec3::new(0.0, 0.0, 4.0), Vec3::ZERO, 40.0)],
        environment: Environment::Constant(Vec3::ZERO),
        ..Default::default()
    };
    let ctx = GpuContext::for_tests();
    let s = settings(&scene, 48, 48, 3, 1);
    let cpu = render_on_cpu(&scene, &s, 2);
    let cpu_red = cpu.sum.iter().filter(|p| p[0] != 0.0).count();
    assert_eq!(cpu_red, 0, "the CPU twin reports the lower triangle");
    #[cfg_attr(not(feature = "kernel-lab"), allow(unused_mut))]
    let mut contexts = vec![ctx.clone()];
    #[cfg(feature = "kernel-lab")]
    {
        let vote = raygun::trace::gpu::TraceVariant::default().with_vote(100);
        contexts.push(ctx.with_trace_variant(vote).unwrap());
    }
    for c in contexts {
        let gpu = render_gpu(&c, &scene, &s, 2);
        let red = gpu.sum.iter().filter(|p| p[0] != 0.0).count();
        let green = gpu.sum.iter().filter(|p| p[1] > 0.0).count();
        let v = c.trace_kernel_name();
        assert_eq!(red, 0, "{v}: pixels where a tie went to the lower triangle");
        assert!(
            green > 48 * 48 / 2,
            "{v}: only {green} pixels see the triangles"
        );
    }
}

/// A tree deeper than obvhs' own traversal allows (a disc of 20 000 slivers, as CAD
/// tessellates a fine circle: 48 levels, where obvhs asserts under 32 in debug builds, which
/// panicked on loading it): it loads, its walks need fewer entries than the kernel's stack
/// holds, and the GPU sees every sliver the CPU twin sees; a tree whose walks could need more
/// is refused by name.
#[test]
fn a_tree_deeper_than_obvhs_traversal_allows_is_traced_whole() {
    use crate::scenes::{camera, flat, lambert};
    let n = 20_000;
    let at = |i: usize| {
        let a = i as f32 / n as f32 * std::f32::consts::TAU;
        Vec3::new(a.cos(), a.sin(), 0.0) * 100.0
    };
    let scene = Scene {
        triangles: (0..n)
            .map(|i| flat([Vec3::ZERO, at(i), at(i + 1)], 0))
            .collect(),
        materials: vec![lambert(0.0, Vec3::ONE)],
        cameras: vec![camera(Vec3::new(30.0, 10.0, 260.0), Vec3::ZERO, 50.0)],
        environment: Environment::Constant(Vec3::ZERO),
        ..Default::default()
    };
    let needs = PackedScene::new(&scene).bvh.stack_entries();
    assert!(
        needs <= raygun::trace::gpu::STACK_ENTRIES,
        "{needs} entries"
    );
    let ctx = GpuContext::for_tests();
    let s = settings(&scene, 48, 48, 9, 1);
    let cpu = render_on_cpu(&scene, &s, 1);
    let gpu = render_gpu(&ctx, &scene, &s, 1);
    let lit = |a: &raygun::trace::accum::Accumulation| -> Vec<bool> {
        a.sum.iter().map(|p| p[1] > 0.0).collect()
    };
    let (seen, want) = (lit(&gpu), lit(&cpu));
    assert!(
        want.iter().filter(|&&l| l).count() > 48 * 48 / 2,
        "the disc fills the view"
    );
    let missed = seen.iter().zip(&want).filter(|(g, c)| **c && !**g).count();
    assert_eq!(
        missed, 0,
        "pixels where the GPU missed the disc the CPU twin sees"
    );
    // A tree whose walks could push more than the stack holds is refused, not traced with
    // pushes dropped: a spine of 34 nodes, each but the last with two inner children.
    use obvhs::cwbvh::node::CwBvhNode;
    use raygun::trace::gpu::{GpuScene, STACK_ENTRIES, TraceKernel};
    let mut packed = PackedScene::new(&scene);
    let k = STACK_ENTRIES as usize + 2;
    packed.bvh.cwbvh.nodes = vec![CwBvhNode::default(); 2 * k - 1];
    for j in 0..k - 1 {
        packed.bvh.cwbvh.nodes[2 * j].imask = 0b11;
        packed.bvh.cwbvh.nodes[2 * j].child_base_idx = 2 * j as u32 + 1;
    }
    assert_eq!(packed.bvh.stack_entries(), STACK_ENTRIES + 1);
    let err = GpuScene::upload(&ctx, &TraceKernel::new(&ctx), &packed)
        .err()
        .expect("refused")
        .to_string();
    assert!(
        err.contains("needs 33 entries") && err.contains("holds 32"),
        "{err}"
    );
}

#[test]
fn gpu_and_cpu_agree_on_the_cornell_box() {
    let ctx = GpuContext::for_tests();
    for file in ["cornell.glb", "cornell-light.glb"] {
        let path = format!("{}/tests/data/scenes/{file}", env!("CARGO_MANIFEST_DIR"));
        let scene = Scene::load(&path).unwrap();
        let cpu = render_on_cpu(&scene, &settings(&scene, 32, 32, 31, 8), 64);
        let gpu = render_gpu(&ctx, &scene, &settings(&scene, 32, 32, 32, 8), 64);
        renders_agree(&gpu, &cpu, &format!("{file}: GPU vs CPU")).unwrap();
        assert!(gpu.sum.iter().all(|s| s.iter().all(|v| v.is_finite())));
    }
}

#[test]
fn gpu_and_cpu_twin_agree_on_a_scene_with_every_feature() {
    let ctx = GpuContext::for_tests();
    let scene = everything();
    let packed = PackedScene::new(&scene);
    assert_eq!(packed.features, 3, "extras and alpha");
    assert!(packed.light_count > 0 && packed.punctual_count == 3);
    let cpu = render_on_cpu(&scene, &settings(&scene, 32, 32, 11, 6), 64);
    let gpu = render_gpu(&ctx, &scene, &settings(&scene, 32, 32, 12, 6), 64);
    renders_agree(&gpu, &cpu, "every feature: GPU (seed 12) vs CPU (seed 11)").unwrap();
    let mut brighter = cpu.clone();
    for s in &mut brighter.sum {
        for v in &mut s[..3] {
            *v *= 1.1;
        }
        s[3] *= 1.21;
    }
    assert!(renders_agree(&gpu, &brighter, "GPU vs CPU × 1.1").is_err());
    // Same seed, same paths: most first samples agree to rounding.
    let s = settings(&scene, 32, 32, 5, 6);
    let (c1, g1) = (
        render_on_cpu(&scene, &s, 1),
        render_gpu(&ctx, &scene, &s, 1),
    );
    let share = same_seed_share(&c1, &g1);
    assert!(
        share >= SAME_SEED_SHARE_EVERY_FEATURE,
        "same seed: only {:.1} % of the pixels agree",
        100.0 * share
    );
}

/// Every variant of the trace kernel (where its traversal stack lives, wgpu's run-time checks
/// on or off, its workgroup's size, paths regenerated, triangle tests postponed by vote) is the same function: the same
/// accumulation to the bit as the default kernel — full frames and a scheduler's list — on the
/// small city (a tree deep enough that walks push and pop), the Cornell box with its ceiling
/// light and the scene with every feature (alpha-tested shadow rays, glass, punctual lights);
/// and the same samples in the compact mode a cluster rank runs (its own dispatch grid,
/// counted in the variant's workgroups). A kernel-lab test: lavapipe compiles each variant in
/// tens of seconds.
#[cfg(feature = "kernel-lab")]
#[test]
fn every_trace_kernel_variant_renders_the_default_kernels_bits() {
    use raygun::trace::gpu::{
        GpuAccum, GpuScene, SampleRun, TraceKernel, TraceRun, TraceStack, TraceVariant,
    };
    use raygun::trace::path::TraceSettings;
    type Bits = (Vec<[u32; 4]>, Vec<u32>, Vec<[u32; 4]>, Vec<[u32; 4]>);
    /// Two frames' accumulation; then `pixels` listed as the scheduler lists them (one more
    /// sample each, launched from the indirect arguments the scheduler computes for this
    /// kernel); then a rank's samples (index 1) of `pixels`, as bits.
    fn run(
        c: &GpuContext,
        kernel: &TraceKernel,
        scene: &Scene,
        s: &TraceSettings,
        pixels: &[u32],
    ) -> Bits {
        use wgpu::util::DeviceExt;
        let packed = PackedScene::new(scene);
        let gs = GpuScene::upload(c, kernel, &packed).unwrap();
        let acc = GpuAccum::new(c, s.width, s.height).unwrap();
        let frames = TraceRun::new(c, kernel, &packed, s, &acc, None);
        let mut enc = c.device.create_command_encoder(&Default::default());
        acc.clear(&mut enc);
        frames.record(&mut enc, &gs, None);
        frames.record(&mut enc, &gs, None);
        c.queue.submit([enc.finish()]);
        let a = acc.read(c).unwrap();
        let len = pixels.len() as u32;
        let [gx, gy, gz] = raygun::schedule::indirect_grid(
            len,
            kernel.workgroup(),
            kernel.max_list_groups(),
            c.limits.max_compute_workgroups_per_dimension,
        );
        let buffer = |label, contents: &[u32], usage| {
            c.device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents: bytemuck::cast_slice(contents),
                    usage,
                })
        };
        let list = buffer("list", pixels, wgpu::BufferUsages::STORAGE);
        let args = buffer(
            "args",
            &[gx, gy, gz, len],
            wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::INDIRECT,
        );
        let listed = TraceRun::new(c, kernel, &packed, s, &acc, Some((&list, &args)));
        let mut enc = c.device.create_command_encoder(&Default::default());
        listed.record(&mut enc, &gs, None);
        c.queue.submit([enc.finish()]);
        let l = acc.read(c).unwrap();
        // Every listed pixel, and no other, took one sample more.
        let mut want = vec![2u32; l.count.len()];
        for &p in pixels {
            want[p as usize] = 3;
        }
        assert!(l.count == want, "{}: the listed samples", c.describe());
        let listed_sums = l.sum.iter().map(|v| v.map(f32::to_bits)).collect();
        let mut ranks = SampleRun::new(c, kernel, &packed, s, None);
        let got = ranks
            .samples(c, &gs, pixels, &vec![1; pixels.len()])
            .unwrap();
        let sums = a.sum.iter().map(|v| v.map(f32::to_bits)).collect();
        let samples = got
            .iter()
            .map(|(c, r)| [c.x.to_bits(), c.y.to_bits(), c.z.to_bits(), *r])
            .collect();
        (sums, a.count, listed_sums, samples)
    }
    let ctx = GpuContext::for_tests();
    let data = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/data/scenes");
    let scenes = [
        (
            "city-small",
            Scene::load(format!("{data}/city-small.glb")).unwrap(),
        ),
        (
            "cornell-light",
            Scene::load(format!("{data}/cornell-light.glb")).unwrap(),
        ),
        ("every feature", everything()),
    ];
    // 700 of the 960 pixels, backwards: 22 groups of 32, 3 of 256, none of them full.
    let pixels: Vec<u32> = (0..700).rev().collect();
    let kernel = TraceKernel::new(&ctx);
    let reference: Vec<_> = scenes
        .iter()
        .map(|(name, scene)| {
            let s = settings(scene, 40, 24, 7, 6);
            let r = run(&ctx, &kernel, scene, &s, &pixels);
            assert!(r.1.iter().all(|&c| c == 2));
            assert!(r.0.iter().any(|v| v[1] != 0), "{name} is lit");
            r
        })
        .collect();
    assert_eq!(TraceVariant::ALL[0], TraceVariant::default());
    let mut variants = TraceVariant::ALL[1..].to_vec();
    for n in [32, 128, 256] {
        variants.push(TraceVariant::default().with_workgroup(n));
    }
    // A workgroup stack of 128 threads needs 32 772 bytes: over lavapipe's 32 KiB.
    variants.push(TraceVariant::new(TraceStack::Workgroup, true).with_workgroup(32));
    // Launches regenerated in 1 to 3 workgroups: 5 to 30 paths a thread (960 pixels), 3 to 22
    // (the list's 700).
    variants.push(TraceVariant::default().with_regen(1));
    variants.push(
        TraceVariant::new(TraceStack::Function, false)
            .with_workgroup(32)
            .with_regen(3),
    );
    variants.push(
        TraceVariant::new(TraceStack::Workgroup, true)
            .with_workgroup(32)
            .with_regen(2),
    );
    // Full frames in the wavefront split: chunks of 64 paths (fifteen for 960 pixels), and one
    // chunk; lists and a rank's samples in its `trace` kernel, bound through its explicit
    // layout.
    variants.push(TraceVariant::default().with_split(64));
    variants.push(
        TraceVariant::new(TraceStack::Workgroup, true)
            .with_workgroup(32)
            .with_split(TraceVariant::SPLIT_CHUNK),
    );
    // Triangle tests postponed by subgroup vote (lavapipe's subgroups are 8 lanes): at the
    // default 20 %, and at 100 % — whenever any traversing lane is not testing triangles —
    // with the workgroup stack, regenerated paths and the split's kernels.
    variants.push(TraceVariant::default().with_vote(TraceVariant::VOTE_PERCENT));
    variants.push(
        TraceVariant::new(TraceStack::Workgroup, true)
            .with_workgroup(32)
            .with_vote(100),
    );
    variants.push(TraceVariant::default().with_regen(1).with_vote(100));
    variants.push(TraceVariant::default().with_split(64).with_vote(100));
    for v in &variants {
        let vctx = ctx.with_trace_variant(*v).unwrap();
        assert_eq!(vctx.trace_variant(), *v);
        let kernel = TraceKernel::new(&vctx);
        for ((name, scene), want) in scenes.iter().zip(&reference) {
            let s = settings(scene, 40, 24, 7, 6);
            let (sums, counts, listed, samples) = run(&vctx, &kernel, scene, &s, &pixels);
            assert!(counts == want.1, "{name}, {v}: counts");
            let differing = sums.iter().zip(&want.0).filter(|(a, b)| a != b).count();
            assert_eq!(
                differing, 0,
                "{name}, {v}: pixels whose sums differ from the default's"
            );
            let differing = listed.iter().zip(&want.2).filter(|(a, b)| a != b).count();
            assert_eq!(
                differing, 0,
                "{name}, {v}: pixels whose sums after the listed samples differ"
            );
            assert!(
                samples == want.3,
                "{name}, {v}: a rank's samples differ from the default's"
            );
        }
    }
}

/// A cluster rank's samples (the kernel's compact mode, `SampleRun`, DESIGN.md §12): the very
/// bits the accumulating kernel adds, in any list order, and the CPU twin's samples
/// (`samples_cpu`) to rounding, rays included — for the sample index asked, not another.
#[test]
fn a_ranks_samples_are_the_bits_the_accumulating_kernel_adds() {
    use raygun::trace::gpu::{GpuScene, SampleRun, TraceKernel};
    use raygun::trace::path::samples_cpu;
    let ctx = GpuContext::for_tests();
    let scene = twin_scene();
    let s = settings(&scene, 32, 24, 5, 8);
    let packed = PackedScene::new(&scene);
    let kernel = TraceKernel::new(&ctx);
    let gs = GpuScene::upload(&ctx, &kernel, &packed).unwrap();
    let mut run = SampleRun::new(&ctx, &kernel, &packed, &s, None);
    let n = s.width * s.height;
    // Every third pixel first, then the rest backwards: no order the image has.
    let mut pixels: Vec<u32> = (0..n).step_by(3).collect();
    pixels.extend((0..n).rev().filter(|p| p % 3 != 0));
    let first = render_gpu(&ctx, &scene, &s, 1);
    let got = run
        .samples(&ctx, &gs, &pixels, &vec![0; pixels.len()])
        .unwrap();
    assert_eq!(got.len(), pixels.len());
    for (&p, (rgb, _)) in pixels.iter().zip(&got) {
        let want = first.sum[p as usize];
        assert!(
            rgb.to_array() == [want[0], want[1], want[2]],
            "pixel {p}: {rgb} against the accumulated {want:?}"
        );
    }
    // Against the CPU twin, at sample index 7 (a list half as long: the buffers are reused).
    let half = &pixels[..pixels.len() / 2];
    let sevens = vec![7; half.len()];
    let gpu = run.samples(&ctx, &gs, half, &sevens).unwrap();
    let cpu = samples_cpu(&packed, &s, None, half, &sevens);
    let close = |a: &(Vec3, u32), b: &(Vec3, u32)| {
        (a.0 - b.0).abs().max_element()
            <= crate::render::SAME_SEED_REL * a.0.abs().max_element().max(1.0)
            && a.1 == b.1
    };
    let share = |a: &[(Vec3, u32)], b: &[(Vec3, u32)]| {
        a.iter().zip(b).filter(|(x, y)| close(x, y)).count() as f64 / a.len() as f64
    };
    let agree = share(&gpu, &cpu);
    assert!(agree >= SAME_SEED_SHARE, "{:.1} % agree", 100.0 * agree);
    assert!(
        gpu.iter().all(|g| g.1 >= 1),
        "every path casts its camera ray"
    );
    // The index is the one asked for: sample 0's paths are other paths.
    let zeros = samples_cpu(&packed, &s, None, half, &vec![0; half.len()]);
    let other = share(&gpu, &zeros);
    assert!(other < 0.5, "{:.1} % agree with sample 0", 100.0 * other);
    // On a device whose bindings hold 400 samples the list goes in pieces: the same bits.
    let cornell = Scene::builtin("cornell").unwrap();
    let packed = PackedScene::new(&cornell);
    let s = settings(&cornell, 32, 24, 5, 8);
    let whole = {
        let gs = GpuScene::upload(&ctx, &kernel, &packed).unwrap();
        SampleRun::new(&ctx, &kernel, &packed, &s, None)
            .samples(&ctx, &gs, &pixels, &vec![2; pixels.len()])
            .unwrap()
    };
    let small = GpuContext::with_max_binding(16 * 400).unwrap();
    let k = TraceKernel::new(&small);
    let gs = GpuScene::upload(&small, &k, &packed).unwrap();
    let pieces = SampleRun::new(&small, &k, &packed, &s, None)
        .samples(&small, &gs, &pixels, &vec![2; pixels.len()])
        .unwrap();
    assert!(pixels.len() > 400);
    let bits = |v: &[(Vec3, u32)]| -> Vec<[u32; 4]> {
        v.iter()
            .map(|(c, r)| [c.x.to_bits(), c.y.to_bits(), c.z.to_bits(), *r])
            .collect()
    };
    assert!(bits(&pieces) == bits(&whole), "in pieces as whole");
}

/// The CPU twin's batches (`samples_cpu`: paths a vertex at a time, eight shaded at once in
/// lanes) are its one-path-at-a-time code (`trace_counted_with`) to the bit, radiance and
/// rays, on the scene with every feature — alpha MASK and BLEND (in traversal and in shadow
/// rays), normal and metallic-roughness maps, rough and smooth glass, clear coat, specular
/// colour, punctual lights, textures, vertex colours, TEXCOORD_1 — at several depths, and on
/// the builtin plain scenes; and the paths see light, so the comparison means something.
#[test]
fn the_cpu_twins_batches_are_its_one_path_code_to_the_bit() {
    use raygun::trace::path::{samples_cpu, trace_counted_with};
    let builtin = |name: &str| Scene::builtin(name).unwrap();
    let cases = [
        (everything(), 1),
        (everything(), 3),
        (everything(), 8),
        (builtin("cornell-light"), 8),
        (builtin("city-small"), 5),
    ];
    for (i, (scene, max_depth)) in cases.iter().enumerate() {
        let s = settings(scene, 40, 30, 21 + i as u32, *max_depth);
        let packed = PackedScene::new(scene);
        let n = s.width * s.height;
        // Every pixel, in an order that is not the image's, some twice with other samples.
        let pixels: Vec<u32> = (0..n + 200).map(|k| (k * 7919) % n).collect();
        let counts: Vec<u32> = (0..n + 200).map(|k| k % 4).collect();
        let batch = samples_cpu(&packed, &s, None, &pixels, &counts);
        let mut lit = 0;
        for ((&p, &k), got) in pixels.iter().zip(&counts).zip(&batch) {
            let want = trace_counted_with(&packed, &s, None, p, k).unwrap();
            assert_eq!(
                (got.0.to_array().map(f32::to_bits), got.1),
                (want.0.to_array().map(f32::to_bits), want.1),
                "case {i} (max depth {max_depth}), pixel {p} sample {k}: {got:?} against {want:?}"
            );
            lit += usize::from(luminance(got.0) > 0.0);
        }
        assert!(
            lit > pixels.len() / 4,
            "case {i}: only {lit} samples saw light"
        );
    }
}

/// A cluster rank's owned sums on its GPU (`shaders/trace/accum.wgsl`) against the CPU twins:
/// the kept samples' rays per block equal `block_rays`, and the sums after adding kept and
/// other ranks' samples equal `accumulate_sums` on the CPU — exactly: the same IEEE
/// operations in the same order per pixel (one sample per pixel and frame; a driver that fused
/// `lum`'s multiply-adds would differ in Σ lum²'s last bits, as the one-process kernel's own
/// accumulation would, which uses the same expression), over three frames
/// with the exchange overlapped (a frame keeps its samples before the last one's are added)
/// and a frame dropped unadded.
#[test]
fn owned_sums_on_the_gpu_equal_the_cpu_twins() {
    use raygun::trace::accum::{accumulate_sums, block_rays};
    use raygun::trace::gpu::OwnedSums;
    use wgpu::util::DeviceExt;
    let ctx = GpuContext::for_tests();
    let entries = 4 * 1024u32;
    let mut owned = OwnedSums::new(&ctx, u64::from(entries)).expect("fits one binding");
    let mut cpu = vec![[0f32; 4]; entries as usize];
    let hash = |i: u32, k: u32| {
        let x = i.wrapping_mul(0x9E37_79B9) ^ k.wrapping_mul(0x85EB_CA6B);
        ((x ^ (x >> 15)).wrapping_mul(0x2C1B_3C6D) >> 8) as f32 / (1 << 24) as f32
    };
    // Per frame: `out` as a trace leaves it (the first `read` entries other owners' samples,
    // then own samples), destinations for the own and for other ranks' samples.
    let frame = |f: u32| {
        let (read, own, foreign) = (37u32 + f, 900u32 + 50 * f, 300u32);
        let out: Vec<[f32; 4]> = (0..read + own)
            .map(|i| {
                let v = |k| hash(i + 7919 * f, k) * 3.0;
                [v(1), v(2), v(3), f32::from_bits(1 + (i * 13 + f) % 17)]
            })
            .collect();
        // Distinct destinations: a permutation's prefix, own ones first.
        let mut dst: Vec<u32> = (0..entries).collect();
        for i in (1..entries as usize).rev() {
            let j = (hash(i as u32, 40 + f) * (i + 1) as f32) as usize % (i + 1);
            dst.swap(i, j);
        }
        let own_dst = dst[..own as usize].to_vec();
        let foreign_dst = dst[own as usize..(own + foreign) as usize].to_vec();
        let foreign: Vec<f32> = (0..3 * foreign).map(|i| hash(i, 90 + f) * 2.0).collect();
        (read, own, out, own_dst, foreign, foreign_dst)
    };
    let segments = |own: u32| -> Vec<[u32; 2]> {
        let mut s = Vec::new();
        let mut at = 0;
        while at < own {
            let n = (own - at).min(300);
            s.push([at, n]);
            at += n;
        }
        s
    };
    let keep = |owned: &mut OwnedSums, f: u32| {
        let (read, own, out, ..) = frame(f);
        let buffer = ctx
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: None,
                contents: bytemuck::cast_slice(&out),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            });
        let segs = segments(own);
        let rays = owned
            .keep(&ctx, Some(&buffer), u64::from(read), own, &segs)
            .unwrap();
        assert_eq!(rays, block_rays(&out[read as usize..], &segs), "frame {f}");
    };
    let add_cpu = |cpu: &mut Vec<[f32; 4]>, f: u32| {
        let (read, _, out, own_dst, foreign, foreign_dst) = frame(f);
        for (s, &d) in out[read as usize..].iter().zip(&own_dst) {
            accumulate_sums(&mut cpu[d as usize], glam::Vec3::new(s[0], s[1], s[2]));
        }
        for (c, &d) in foreign.chunks_exact(3).zip(&foreign_dst) {
            accumulate_sums(&mut cpu[d as usize], glam::Vec3::new(c[0], c[1], c[2]));
        }
    };
    // Frame 0 kept; frame 1 kept before frame 0 is added; frame 1 dropped; frame 2 kept and
    // added; then other ranks' samples alone.
    keep(&mut owned, 0);
    keep(&mut owned, 1);
    let (_, _, _, own_dst, foreign, foreign_dst) = frame(0);
    owned
        .add(&ctx, Some(&own_dst), &foreign, &foreign_dst)
        .unwrap();
    add_cpu(&mut cpu, 0);
    owned.drop_kept();
    keep(&mut owned, 2);
    let (_, _, _, own_dst, foreign, foreign_dst) = frame(2);
    owned
        .add(&ctx, Some(&own_dst), &foreign, &foreign_dst)
        .unwrap();
    add_cpu(&mut cpu, 2);
    let (_, _, _, _, foreign, foreign_dst) = frame(3);
    owned.add(&ctx, None, &foreign, &foreign_dst).unwrap();
    for (c, &d) in foreign.chunks_exact(3).zip(&foreign_dst) {
        accumulate_sums(&mut cpu[d as usize], glam::Vec3::new(c[0], c[1], c[2]));
    }
    let gpu = owned.read(&ctx).unwrap();
    assert_eq!(gpu.len(), cpu.len());
    assert!(
        cpu.iter().filter(|s| s[0] != 0.0).count() > 1500,
        "most pixels got samples"
    );
    for (i, (g, c)) in gpu.iter().zip(&cpu).enumerate() {
        assert_eq!(
            g.map(f32::to_bits),
            c.map(f32::to_bits),
            "entry {i}: GPU {g:?} CPU {c:?}"
        );
    }
}
