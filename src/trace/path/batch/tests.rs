use super::*;
use crate::scene::Scene;
use crate::trace::bvh::CpuPackets;

/// The octant order is a permutation of its items, grouped by their direction's octant
/// (x's sign the lowest bit, z's the highest), each octant's in their order (a stable
/// sort's); a zero component, of either sign, counts as not negative.
#[test]
fn by_octant_groups_in_order() {
    let dirs: Vec<Vec3> = (0..3000u32)
        .map(|k| {
            let c = |shift: u32| match k.wrapping_mul(2_654_435_761) >> shift & 3 {
                0 => -1.0,
                1 => 0.5,
                2 => 0.0,
                _ => -0.0,
            };
            Vec3::new(c(3), c(9), c(17))
        })
        .collect();
    let items: Vec<Idx> = (0..3000).map(|k| (2999 - k) as Idx).collect();
    let mut out = [0 as Idx; BATCH];
    let order = by_octant(&items, |k| dirs[k as usize], &mut out);
    let octant = |k: Idx| {
        let d = dirs[k as usize];
        (d.x < 0.0) as u8 | ((d.y < 0.0) as u8) << 1 | ((d.z < 0.0) as u8) << 2
    };
    let mut want = items.clone();
    want.sort_by_key(|&k| octant(k));
    assert_eq!(order, &want[..]);
    assert!((0..8).all(|o| items.iter().any(|&k| octant(k) == o)));
}

/// Every path of a batch is `trace_counted_with`'s to the bit — radiance and rays — on the
/// builtin plain scenes (area light, environment, textures), through the pinhole and the
/// wall camera, over several depths (the last vertex's MIS, Russian roulette) and sample
/// indices; and the batches see light, so the comparison means something.
#[test]
fn batches_equal_the_scalar_paths() {
    for (name, max_depth) in [
        ("cornell-light", 8),
        ("cornell", 3),
        ("city-small", 5),
        ("cornell-light", 1),
    ] {
        let scene = Scene::builtin(name).unwrap();
        let sc = PackedScene::new(&scene);
        assert!(sc.plain, "builtin:{name}");
        // The first case over a batch's paths, so that a second batch starts from fresh
        // paths in the same arrays.
        let (width, height) = if (name, max_depth) == ("cornell-light", 8) {
            (80, 52)
        } else {
            (40, 24)
        };
        let camera = RenderCamera::choose(&scene, None, width, height).unwrap();
        let s = TraceSettings {
            width,
            height,
            seed: 11,
            max_depth,
            camera,
        };
        // Pixels in an order that is not the image's, some twice with other samples.
        let n = width * height;
        let pixels: Vec<u32> = (0..n + 100).map(|i| (i * 7919) % n).collect();
        assert!(width != 80 || pixels.len() > BATCH, "two batches");
        let samples: Vec<u32> = (0..n + 100).map(|i| i % 5).collect();
        // Every walk this processor runs: one ray at a time, packets in AVX2, in AVX-512.
        let walks = [CpuPackets::One, CpuPackets::Avx2, CpuPackets::Avx512];
        for walks in walks.into_iter().filter(|&w| w <= CpuPackets::widest()) {
            let mut out = vec![None; pixels.len()];
            walks.during(|| trace_batch(&sc, &s, None, &pixels, &samples, &mut out));
            let mut lit = 0;
            for (i, (&p, &k)) in pixels.iter().zip(&samples).enumerate() {
                let want = trace_counted_with(&sc, &s, None, p, k).unwrap();
                let got = out[i].unwrap();
                assert_eq!(
                    (got.0.to_array().map(f32::to_bits), got.1),
                    (want.0.to_array().map(f32::to_bits), want.1),
                    "builtin:{name}, {walks:?}: pixel {p} sample {k}: {got:?} against {want:?}"
                );
                lit += usize::from(got.0 != Vec3::ZERO);
            }
            assert!(lit > pixels.len() / 4, "builtin:{name}: {lit} lit samples");
        }
    }
}
