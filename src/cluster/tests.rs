//! N in-process ranks against the one-process renderer, bit for bit; the deadlines.

use std::time::Duration;

use glam::DVec3;

use std::sync::Arc;

use glam::{DVec2, Vec3};

use super::codec::{decode_masks, encode_masks};
use super::exchange::{Exchange, InProcess};
use super::owners::{TileOwners, block_pixels};
use super::*;
use crate::display::DisplayModel;
use crate::filter::FilterParams;
use crate::filter::denoise::DenoiseParams;
use crate::frame::stop::RoiProgress;
use crate::frame::{EyeFollow, GuideConfig, Render, Renderer};
use crate::gpu::{Backend, GpuContext};
use crate::roi::cone::Cone;
use crate::scene::Scene;
use crate::schedule::{BLOCK_PIXELS, Order};
use crate::trace::accum::{Accumulation, every, every_size};
use crate::trace::wall::{WallSpec, WorldFromRoom};

const SIZE: [u32; 2] = [96, 40];

fn scene() -> Scene {
    Scene::builtin("cornell").unwrap()
}

fn hornet() -> DisplayModel {
    DisplayModel::open("hornet").unwrap().0
}

fn settings(scene: &Scene) -> TraceSettings {
    crate::trace::path::TraceSettings {
        width: SIZE[0],
        height: SIZE[1],
        seed: 5,
        max_depth: 4,
        camera: crate::trace::camera::RenderCamera::choose(scene, None, SIZE[0], SIZE[1]).unwrap(),
    }
}

fn cone(fov: f64, x: f64) -> Roi {
    Roi::Cone(Cone::from_pose(DVec3::new(x, 0.0, 1.0), DVec3::NEG_Z, DVec3::Y, fov, fov).unwrap())
}

/// The ROI of iteration `k`: none first, then one cone, then another.
fn roi_at(k: u32) -> Option<Option<Roi>> {
    match k {
        0 => Some(None),
        2 => Some(Some(cone(20.0, 0.0))),
        5 => Some(Some(cone(40.0, -1.0))),
        _ => None,
    }
}

const ITERATIONS: u32 = 8;

fn config(order: Order) -> GuideConfig {
    GuideConfig {
        p_min: 0.05,
        order,
        ..GuideConfig::default()
    }
}

fn wall(scene: &Scene) -> WallCamera {
    WallSpec {
        model: hornet(),
        eye: DVec3::new(0.0, 0.0, 1.5),
        placement: WorldFromRoom::Auto,
    }
    .camera(SIZE, &settings(scene).camera)
    .unwrap()
}

/// One process: the renderer every command uses.
fn single(guided: Option<Order>, with_wall: bool) -> (Accumulation, Vec<f32>) {
    single_on(&Backend::Cpu, guided, with_wall)
}

/// [`single`] on backend `b`.
fn single_on(b: &Backend, guided: Option<Order>, with_wall: bool) -> (Accumulation, Vec<f32>) {
    let s = scene();
    let w = with_wall.then(|| wall(&s));
    let mut r = match guided {
        Some(o) => Renderer::guided_wall(b, &s, settings(&s), &hornet(), config(o), w).unwrap(),
        None => match w {
            Some(w) => Renderer::full_wall(b, &s, settings(&s), w).unwrap(),
            None => Renderer::full(b, &s, settings(&s)).unwrap(),
        },
    };
    for k in 0..ITERATIONS {
        if guided.is_some()
            && let Some(roi) = roi_at(k)
        {
            r.set_roi(roi).unwrap();
        }
        r.run_frame(false).unwrap();
    }
    r.finish().unwrap()
}

/// `n` in-process ranks, rank 0 broadcasting the ROI each frame; then `after` on every rank
/// (rank order).
fn ranks_then<T: Send>(
    n: usize,
    guided: Option<Order>,
    with_wall: bool,
    mode: DgiMode,
    owners: impl Fn(usize) -> BlockOwners + Sync,
    after: impl Fn(&mut ClusterRenderer, &[ClusterFrameStats]) -> T + Sync,
) -> Vec<T> {
    ranks_on_then(n, guided, with_wall, mode, owners, None, after)
}

/// [`ranks_then`] with every rank tracing on `gpu` when given.
fn ranks_on_then<T: Send>(
    n: usize,
    guided: Option<Order>,
    with_wall: bool,
    mode: DgiMode,
    owners: impl Fn(usize) -> BlockOwners + Sync,
    gpu: Option<&Arc<GpuContext>>,
    after: impl Fn(&mut ClusterRenderer, &[ClusterFrameStats]) -> T + Sync,
) -> Vec<T> {
    std::thread::scope(|sc| {
        let handles: Vec<_> = InProcess::job(n)
            .into_iter()
            .map(|end| {
                let (owners, after) = (&owners, &after);
                sc.spawn(move || {
                    let mut c = Cluster::new(Box::new(end), Duration::from_secs(30));
                    let s = scene();
                    let w = with_wall.then(|| wall(&s));
                    let model = hornet();
                    let setup = ClusterSetup {
                        settings: settings(&s),
                        guide: guided.map(|o| (&model, config(o))),
                        wall: w,
                        owners: owners(n),
                        dgi_mode: mode,
                    };
                    let mut r = ClusterRenderer::new(&mut c, &s, setup).unwrap();
                    if let Some(ctx) = gpu {
                        r.trace_on_gpu(Arc::clone(ctx)).unwrap();
                    }
                    let mut frames = Vec::new();
                    for k in 0..ITERATIONS {
                        let control = FrameControl {
                            iteration: k,
                            stop: false,
                            measure: false,
                            roi: if guided.is_some() { roi_at(k) } else { None },
                            eye: None,
                        };
                        let got = r
                            .cluster_mut()
                            .broadcast("control", control.encode())
                            .unwrap();
                        let got = FrameControl::decode(&got).unwrap();
                        assert_eq!(got, control);
                        if let Some(roi) = got.roi {
                            r.set_roi(roi).unwrap();
                        }
                        let st = r.run_frame(false).unwrap();
                        assert_eq!(st.iteration, k);
                        frames.push(st);
                    }
                    // The render's end: the last frame's samples reach their owners.
                    r.finish().unwrap();
                    after(&mut r, &frames)
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    })
}

/// `ranks` in-process ranks, rank 0 broadcasting the ROI each frame; rank 0's gathered
/// accumulation.
fn ranks(
    n: usize,
    guided: Option<Order>,
    with_wall: bool,
    mode: DgiMode,
    owners: impl Fn(usize) -> BlockOwners + Sync,
) -> (Accumulation, Vec<f32>) {
    let results = ranks_then(n, guided, with_wall, mode, owners, |r, _| {
        let progress = r.roi_progress().unwrap();
        let g = r.gather().unwrap();
        if let Some(g) = &g {
            // Measured from the owners' sums of the pixels of d = 0 a display shows, as one
            // process measures its whole accumulation.
            let wall = r.wall();
            let shown = |i: usize| wall.is_none_or(|w| w.is_shown(i as u32));
            assert_eq!(progress, RoiProgress::measure_where(&g.0, &g.1, shown));
            assert!(progress.is_some());
        }
        g
    });
    let mut it = results.into_iter();
    let root = it.next().unwrap().expect("rank 0 gathers");
    assert!(it.all(|r| r.is_none()), "only rank 0 gathers");
    root
}

fn assert_bits_equal(a: &(Accumulation, Vec<f32>), b: &(Accumulation, Vec<f32>), what: &str) {
    assert_eq!(a.0.count, b.0.count, "{what}: counts");
    let bits = |acc: &Accumulation| -> Vec<u32> {
        acc.sum.iter().flatten().map(|v| v.to_bits()).collect()
    };
    assert!(bits(&a.0) == bits(&b.0), "{what}: sums differ");
    let dgi = |d: &[f32]| -> Vec<u32> { d.iter().map(|v| v.to_bits()).collect() };
    assert!(dgi(&a.1) == dgi(&b.1), "{what}: DGI differs");
    assert!(
        a.0.count.iter().any(|&c| c > 0),
        "{what}: nothing was sampled"
    );
}

fn columns(n: usize) -> BlockOwners {
    let m = hornet();
    BlockOwners::of_display(&m, &TileOwners::columns(&m, n), SIZE)
}

#[test]
fn guided_ranks_give_the_one_process_accumulation_bit_for_bit() {
    for order in [Order::Coherent, Order::Scattered] {
        let one = single(Some(order), false);
        for n in 1..=3 {
            let got = ranks(n, Some(order), false, DgiMode::Compute, columns);
            assert_bits_equal(&got, &one, &format!("{n} ranks, {order:?}"));
        }
    }
}

/// Rank 0's console gathers every k-th pixel of every k-th row: the one process's
/// accumulation and DGI reduced by [`Accumulation::every`], bit for bit, on 1–3 ranks and
/// with the wall camera; and rank 0 receives 1/k² of the whole gather's bytes (those pixels,
/// [`PIXEL_BYTES`] each).
#[test]
fn the_console_gathers_every_kth_pixel_and_its_bytes_only() {
    let steps = [1, 3, 4, 40];
    for with_wall in [false, true] {
        let one = single(Some(Order::Scattered), with_wall);
        for n in 1..=3 {
            let per_rank = ranks_then(
                n,
                Some(Order::Scattered),
                with_wall,
                DgiMode::Compute,
                columns,
                |r, _| {
                    steps.map(|step| {
                        let before = r.cluster().traffic();
                        let g = r.gather_every(step).unwrap();
                        (g, r.cluster().traffic().since(&before).bytes_received)
                    })
                },
            );
            for (k, &step) in steps.iter().enumerate() {
                let what = format!("{n} ranks, every {step}, wall {with_wall}");
                let (got, received) = per_rank[0][k].clone();
                let want = (one.0.every(step), every(&one.1, SIZE, step));
                let got = got.expect("rank 0 gathers");
                assert_eq!(
                    [got.0.width, got.0.height],
                    every_size(SIZE, step),
                    "{what}"
                );
                assert_bits_equal(&got, &want, &what);
                assert!(per_rank[1..].iter().all(|r| r[k].0.is_none()), "{what}");
                // Rank 0's own pixels do not cross the link.
                let own: u64 = columns(n)
                    .owned_by(0)
                    .into_iter()
                    .flat_map(|b| block_pixels(b, SIZE, columns(n).tiles[0]))
                    .filter(|p| {
                        (p % SIZE[0]).is_multiple_of(step) && (p / SIZE[0]).is_multiple_of(step)
                    })
                    .count() as u64;
                let kept = u64::from(every_size(SIZE, step)[0] * every_size(SIZE, step)[1]);
                assert_eq!(received, PIXEL_BYTES as u64 * (kept - own), "{what}");
            }
        }
    }
}

/// A rank's work per iteration is its share: it expands only the scheduled pixels of the
/// blocks it traces or owns (coherent order on several ranks; the whole list otherwise) and
/// keeps sums and counts only for its own blocks — and the images stay the one process's (the
/// test above).
#[test]
fn a_rank_holds_only_the_blocks_it_traces_or_owns() {
    for (order, n) in [
        (Order::Coherent, 3),
        (Order::Coherent, 1),
        (Order::Scattered, 3),
    ] {
        let per_rank = ranks_then(n, Some(order), false, DgiMode::Compute, columns, |r, f| {
            let owned = r.owners.owned_by(r.rank).len() * BLOCK_PIXELS as usize;
            assert_eq!((r.counts.len(), r.sums.len()), (owned, owned));
            f.to_vec()
        });
        for k in 0..ITERATIONS as usize {
            let pixels = per_rank[0][k].pixels;
            let held: Vec<u64> = per_rank.iter().map(|f| f[k].pixels_held).collect();
            let traced: Vec<u64> = per_rank.iter().map(|f| f[k].pixels_traced).collect();
            let what = format!("{order:?}, {n} ranks, iteration {k}: held {held:?} of {pixels}");
            assert_eq!(traced.iter().sum::<u64>(), pixels, "{what}");
            assert!(held.iter().zip(&traced).all(|(h, t)| h >= t), "{what}");
            if order == Order::Coherent && n > 1 {
                assert!(held.iter().all(|&h| h < pixels), "{what}");
            } else {
                assert!(held.iter().all(|&h| h == pixels), "{what}");
            }
        }
    }
}

#[test]
fn the_dgi_broadcast_and_any_tile_map_change_nothing() {
    let one = single(Some(Order::Coherent), false);
    let got = ranks(3, Some(Order::Coherent), false, DgiMode::Broadcast, columns);
    assert_bits_equal(&got, &one, "broadcast DGI");
    // The DGI split in bands of 16 rows (SIZE's 40 rows: 3 bands, one each on 3 ranks, two
    // on one of 2, the last band short), through the wall camera too.
    for n in [2, 3] {
        let got = ranks(n, Some(Order::Coherent), false, DgiMode::Split, columns);
        assert_bits_equal(&got, &one, &format!("split DGI, {n} ranks"));
    }
    let wall_one = single(Some(Order::Coherent), true);
    let got = ranks(3, Some(Order::Coherent), true, DgiMode::Split, columns);
    assert_bits_equal(&got, &wall_one, "split DGI, wall camera");
    // Every tile owned by the last rank; then strips that ignore the display.
    let m = hornet();
    let last = |n: usize| {
        BlockOwners::of_display(
            &m,
            &TileOwners {
                ranks: vec![n - 1; m.tiles().len()],
            },
            SIZE,
        )
    };
    assert_bits_equal(
        &ranks(2, Some(Order::Coherent), false, DgiMode::Compute, last),
        &one,
        "one owner",
    );
    let strips = |n| BlockOwners::strips(SIZE, n);
    assert_bits_equal(
        &ranks(3, Some(Order::Coherent), false, DgiMode::Compute, strips),
        &one,
        "strips",
    );
}

/// The ROI's progress across ranks is one process's through a wall camera whose display leaves
/// pixels of the ROI unshown: those are never sampled, and counted they would hold the fewest
/// samples at 0 for ever (a `--until roi-spp:N` that never stops).
#[test]
fn the_rois_progress_counts_only_the_pixels_a_display_shows() {
    let (s, model) = (scene(), hornet());
    // Large enough that image pixels lie wholly on the bezels (at 845 × 341 and below every
    // pixel is some tile's: DESIGN.md §11).
    let size = [1352, 546];
    let camera = crate::trace::camera::RenderCamera::choose(&s, None, size[0], size[1]).unwrap();
    let settings = TraceSettings {
        width: size[0],
        height: size[1],
        max_depth: 1,
        camera,
        ..settings(&s)
    };
    let wall = WallSpec {
        model: model.clone(),
        eye: DVec3::new(0.0, 0.0, 1.0),
        placement: WorldFromRoom::Auto,
    }
    .camera(size, &camera)
    .unwrap();
    let roi = Some(cone(60.0, 0.0));
    let config = config(Order::Coherent);
    let mut one = Renderer::guided_wall(
        &Backend::Cpu,
        &s,
        settings,
        &model,
        config,
        Some(wall.clone()),
    )
    .unwrap();
    one.set_roi(roi).unwrap();
    one.iterate(2).unwrap();
    let want = one.roi_progress().unwrap();
    assert!(want.is_some_and(|p| p.min_samples == 2), "{want:?}");
    let dgi = one.dgi().unwrap();
    assert!(
        (0..size[0] * size[1]).any(|p| dgi[p as usize] == 0.0 && !wall.is_shown(p)),
        "the ROI holds pixels no tile shows"
    );
    let owners = BlockOwners::of_display(&model, &TileOwners::columns(&model, 2), size);
    let got: Vec<_> = std::thread::scope(|sc| {
        let handles: Vec<_> = InProcess::job(2)
            .into_iter()
            .map(|end| {
                let (s, model, wall, owners) = (&s, &model, &wall, &owners);
                sc.spawn(move || {
                    let mut c = Cluster::new(Box::new(end), Duration::from_secs(30));
                    let setup = ClusterSetup {
                        settings,
                        guide: Some((model, config)),
                        wall: Some(wall.clone()),
                        owners: owners.clone(),
                        dgi_mode: DgiMode::Compute,
                    };
                    let mut r = ClusterRenderer::new(&mut c, s, setup).unwrap();
                    r.set_roi(roi).unwrap();
                    for _ in 0..2 {
                        r.run_frame(false).unwrap();
                    }
                    r.roi_progress().unwrap()
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    assert_eq!(got, [want, None], "rank 0 measures; rank 1 only sends");
}

#[test]
fn full_frames_and_the_wall_camera_match_too() {
    let strips = |n| BlockOwners::strips(SIZE, n);
    let one = single(None, false);
    assert_bits_equal(
        &ranks(2, None, false, DgiMode::Compute, strips),
        &one,
        "full frame",
    );
    let one = single(None, true);
    let got = ranks(3, None, true, DgiMode::Compute, columns);
    assert_bits_equal(&got, &one, "full frame, wall camera");
    // Pixels no tile shows are never traced (at this size no bezel covers a pixel centre;
    // tests/render/wall_camera.rs covers the bezels).
    let w = wall(&scene());
    assert!((0..SIZE[0] * SIZE[1]).all(|p| w.is_shown(p) || got.0.count[p as usize] == 0));
    let one = single(Some(Order::Coherent), true);
    let got = ranks(2, Some(Order::Coherent), true, DgiMode::Compute, columns);
    assert_bits_equal(&got, &one, "guided, wall camera");
}

#[test]
fn the_control_message_round_trips_and_rejects_other_bytes() {
    for c in [
        FrameControl {
            iteration: 7,
            stop: false,
            measure: true,
            roi: Some(Some(cone(30.0, 0.5))),
            eye: Some(DVec3::new(0.1, -0.2, 1.5)),
        },
        FrameControl {
            iteration: 0,
            stop: true,
            measure: false,
            roi: Some(None),
            eye: None,
        },
        FrameControl {
            iteration: u32::MAX,
            stop: false,
            measure: true,
            roi: Some(Some(Roi::CanvasEllipse {
                center: DVec2::new(3.0, 4.0),
                semi_axes: DVec2::new(5.0, 6.5),
            })),
            eye: None,
        },
        FrameControl {
            iteration: 3,
            stop: false,
            measure: false,
            roi: None,
            eye: None,
        },
    ] {
        let b = c.encode();
        assert_eq!(FrameControl::decode(&b), Some(c));
        assert_eq!(FrameControl::decode(&b[..b.len() - 1]), None);
    }
    assert_eq!(FrameControl::decode(&[0, 0, 0, 0, 16, 0]), None);
    assert_eq!(FrameControl::decode(&[0, 0, 0, 0, 0, 3]), None);
}

/// A rank that stops answering ends the others' frame with an error naming it, within the
/// deadline; one that ends is named at once.
#[test]
fn a_silent_or_ended_rank_is_named_within_the_deadline() {
    for hang in [true, false] {
        let errors: Vec<Option<String>> = std::thread::scope(|sc| {
            let handles: Vec<_> = InProcess::job(3)
                .into_iter()
                .map(|end| {
                    sc.spawn(move || {
                        let rank = end.rank();
                        let mut c = Cluster::new(Box::new(end), Duration::from_millis(300));
                        let s = scene();
                        let setup = ClusterSetup {
                            settings: settings(&s),
                            guide: None,
                            wall: None,
                            owners: BlockOwners::strips(SIZE, 3),
                            dgi_mode: DgiMode::Compute,
                        };
                        let mut r = ClusterRenderer::new(&mut c, &s, setup).unwrap();
                        for k in 0..4 {
                            if rank == 2 && k == 2 {
                                if hang {
                                    std::thread::sleep(Duration::from_secs(4));
                                }
                                return None;
                            }
                            if let Err(e) = r.run_frame(false) {
                                // A rank that failed stays until rank 0 has seen what it sees
                                // (under MPI it lives until the job is ended): dropped at
                                // once, it would be the first gone rank rank 0 meets.
                                if rank != 0 {
                                    std::thread::sleep(Duration::from_secs(2));
                                }
                                return Some(e.to_string());
                            }
                        }
                        Some("no error".into())
                    })
                })
                .collect();
            handles.into_iter().map(|h| h.join().unwrap()).collect()
        });
        let root = errors[0].as_deref().unwrap();
        let want = if hang { "did not answer" } else { "is gone" };
        assert!(
            root.contains("rank 2") && root.contains(want),
            "hang {hang}: {errors:?}"
        );
        assert!(root.contains("iteration 2"), "{root}");
    }
}

#[test]
fn the_broadcast_tree_reaches_every_rank_once_and_sends_at_most_log2_copies() {
    for n in 1..=40usize {
        let mut reached = vec![0u32; n];
        reached[0] = 1;
        for me in 0..n {
            let (parent, children) = binomial_tree(me, n);
            assert_eq!(parent.is_none(), me == 0);
            if let Some(p) = parent {
                assert!(
                    p < me && binomial_tree(p, n).1.contains(&me),
                    "{n}: {me} ← {p}"
                );
            }
            assert!(children.len() <= n.next_power_of_two().trailing_zeros() as usize);
            for c in children {
                reached[c] += 1;
            }
        }
        assert!(reached.iter().all(|&r| r == 1), "{n} ranks: {reached:?}");
    }
    assert_eq!(binomial_tree(0, 8), (None, vec![4, 2, 1]));
    assert_eq!(binomial_tree(6, 8), (Some(4), vec![7]));
}

/// Tile `i` to rank `i mod n`: every owner's tiles scattered over the wall.
fn round_robin(n: usize) -> TileOwners {
    TileOwners {
        ranks: (0..hornet().tiles().len()).map(|t| t % n).collect(),
    }
}

/// Every rank's tile pictures against the one-process picture cut into tiles: every tile made
/// once, by its owner, bit for bit. `halo`: the margin used (`None`: the filter's own).
fn owners_pictures_match(
    n: usize,
    guided: bool,
    with_wall: bool,
    params: &FilterParams,
    map: &(dyn Fn(usize) -> TileOwners + Sync),
    halo: Option<(u32, u32)>,
    denoise: Option<&DenoiseParams>,
) -> Result<(), TileDiffers> {
    let m = hornet();
    let order = guided.then_some(Order::Coherent);
    let one = single(order, with_wall);
    let mut image = crate::filter::Filter::new(&Backend::Cpu)
        .image(params, &one.0, &one.1)
        .unwrap();
    if let Some(d) = denoise {
        // One process's denoised picture: the render's features on the CPU.
        let s = scene();
        let w = with_wall.then(|| wall(&s));
        let f = crate::trace::features::features_cpu(
            &crate::trace::pack::PackedScene::new(&s),
            &settings(&s),
            w.as_ref(),
        );
        let features = crate::filter::denoise::Features {
            width: SIZE[0],
            height: SIZE[1],
            albedo: f.albedo,
            normal_depth: f.normal_depth,
        };
        let denoiser = crate::filter::Denoiser::Interactive(*d);
        (image, _) = crate::frame::denoise_picture(
            &Backend::Cpu,
            denoiser,
            &one.0,
            &features,
            &image,
            w.as_ref(),
        )
        .unwrap();
    }
    if guided && with_wall {
        wall(&scene()).blank_unshown(&mut image);
    }
    let tiles = map(n);
    let pictures = ranks_then(
        n,
        order,
        with_wall,
        DgiMode::Compute,
        |n| BlockOwners::of_display(&m, &map(n), SIZE),
        |r, _| {
            let before = r.cluster().traffic();
            let pictures = match halo {
                Some(h) => r
                    .tile_pictures_with(&m, &map(n), params, denoise, h)
                    .unwrap(),
                None => r.tile_pictures(&m, &map(n), params, denoise).unwrap(),
            };
            let after = r.cluster().traffic();
            let traffic = (
                after.bytes_sent - before.bytes_sent,
                after.bytes_received - before.bytes_received,
            );
            (pictures, traffic)
        },
    );
    // The bytes counted from the geometry are the bytes that went.
    let h = halo.unwrap_or_else(|| {
        let (h, align) = crate::filter::halo(params);
        let d = denoise.map_or(0, crate::filter::denoise::halo);
        (h.max(d), align)
    });
    let counted =
        picture::margin_traffic(&m, &tiles, &BlockOwners::of_display(&m, &tiles, SIZE), h, n);
    let moved: Vec<(u64, u64)> = pictures.iter().map(|p| p.1).collect();
    assert_eq!(moved, counted);
    assert_eq!(n > 1, moved.iter().any(|t| t.0 > 0));
    let pictures: Vec<Vec<picture::TilePicture>> = pictures.into_iter().map(|p| p.0).collect();
    let mut made = vec![0; m.tiles().len()];
    for (rank, mine) in pictures.iter().enumerate() {
        for p in mine {
            assert_eq!(
                tiles.ranks[p.tile], rank,
                "tile {} made by a non-owner",
                p.tile
            );
            made[p.tile] += 1;
            let want = crate::output::tiles::cut_tile(&m, p.tile, &image, SIZE);
            let bits = |v: &[Vec3]| -> Vec<u32> {
                v.iter()
                    .flat_map(|p| p.to_array())
                    .map(f32::to_bits)
                    .collect()
            };
            if bits(&p.pixels) != bits(&want) {
                return Err(TileDiffers {
                    ranks: n,
                    kind: params.kind,
                    tile: m.tiles()[p.tile].id().to_string(),
                });
            }
        }
    }
    assert!(made.iter().all(|&k| k == 1), "{made:?}");
    assert!(image.iter().any(|p| p.max_element() > 0.0));
    Ok(())
}

/// A tile an owner made that differs from the one-process picture's.
#[derive(Debug, thiserror::Error)]
#[error("{ranks} ranks, {kind:?}: tile {tile} differs")]
struct TileDiffers {
    ranks: usize,
    kind: crate::filter::FilterKind,
    tile: String,
}

fn filter_params(kind: crate::filter::FilterKind) -> FilterParams {
    FilterParams {
        kind,
        k_max: 12.0,
        c: 16.0,
        ..FilterParams::default()
    }
}

#[test]
fn owners_filter_their_own_tiles_as_one_process_filters_the_image() {
    use crate::filter::FilterKind::{Exact, Fast, Off};
    let columns = |n| TileOwners::columns(&hornet(), n);
    for kind in [Fast, Exact] {
        for n in 1..=3 {
            owners_pictures_match(n, true, false, &filter_params(kind), &columns, None, None)
                .unwrap();
        }
        owners_pictures_match(
            3,
            true,
            false,
            &filter_params(kind),
            &round_robin,
            None,
            None,
        )
        .unwrap();
    }
    // Through the wall camera (pixels no tile shows stay black) and a full frame's mean image.
    owners_pictures_match(
        2,
        true,
        true,
        &filter_params(Fast),
        &round_robin,
        None,
        None,
    )
    .unwrap();
    owners_pictures_match(3, false, true, &filter_params(Off), &columns, None, None).unwrap();
}

/// With `--denoise interactive` every owner denoises its tiles with the features of their
/// rectangles, the margin grown to the denoiser's reach (62 pixels): the one process's denoised
/// picture, bit for bit — guided, through the wall camera (its bezel pixels black) and a full
/// frame; with only the filter's margin the tiles beside another owner's differ.
#[test]
fn owners_denoise_their_own_tiles_as_one_process_denoises_the_image() {
    use crate::filter::FilterKind::{Exact, Fast, Off};
    let columns = |n| TileOwners::columns(&hornet(), n);
    let d = DenoiseParams::default();
    owners_pictures_match(
        2,
        true,
        false,
        &filter_params(Fast),
        &columns,
        None,
        Some(&d),
    )
    .unwrap();
    owners_pictures_match(
        3,
        true,
        true,
        &filter_params(Fast),
        &round_robin,
        None,
        Some(&d),
    )
    .unwrap();
    owners_pictures_match(
        2,
        false,
        true,
        &filter_params(Off),
        &columns,
        None,
        Some(&d),
    )
    .unwrap();
    let params = filter_params(Exact);
    let short = Some(crate::filter::halo(&params));
    let e = owners_pictures_match(3, true, false, &params, &round_robin, short, Some(&d));
    assert!(e.unwrap_err().to_string().contains("differs"));
}

/// The margin is what makes them equal: cut to a third, or off the pyramid's grid, the tiles
/// beside another owner's differ.
#[test]
fn a_margin_cut_short_changes_the_owners_tiles() {
    use crate::filter::FilterKind::{Exact, Fast};
    for kind in [Fast, Exact] {
        let params = filter_params(kind);
        let (halo, align) = crate::filter::halo(&params);
        let cut = Some((halo / 3, align));
        let e =
            owners_pictures_match(3, true, false, &params, &round_robin, cut, None).unwrap_err();
        assert!(e.to_string().contains("differs"), "{e}");
    }
    // The fast filter's regions must also start on its coarsest level's grid.
    let params = filter_params(crate::filter::FilterKind::Fast);
    let (halo, align) = crate::filter::halo(&params);
    assert!(align > 1);
    let e = owners_pictures_match(3, true, false, &params, &round_robin, Some((halo, 1)), None);
    assert!(e.unwrap_err().to_string().contains("differs"));
}

#[test]
fn a_regions_margin_is_aligned_and_the_union_of_pixels_is_counted_once() {
    use picture::{Rect, pixels_owned_by};
    let r = Rect {
        x0: 37,
        y0: 5,
        x1: 60,
        y1: 20,
    };
    assert_eq!(
        r.grown(10, 8, [64, 24]),
        Rect {
            x0: 24,
            y0: 0,
            x1: 64,
            y1: 24
        }
    );
    let owners = BlockOwners::strips([64, 40], 2);
    let a = Rect {
        x0: 0,
        y0: 0,
        x1: 40,
        y1: 2,
    };
    let b = Rect {
        x0: 30,
        y0: 1,
        x1: 64,
        y1: 3,
    };
    let left = pixels_owned_by(&[a, b], &owners, 0);
    let right = pixels_owned_by(&[a, b], &owners, 1);
    // Row 0: x 0..40; rows 1: 0..64; row 2: 30..64, split at the strips' edge x = 32.
    assert_eq!(left.len() + right.len(), 40 + 64 + 34);
    assert!(left.windows(2).all(|w| w[0] < w[1]) && right.windows(2).all(|w| w[0] < w[1]));
    assert!(left.iter().all(|p| p % 64 < 32) && right.iter().all(|p| p % 64 >= 32));
}

/// GPU ranks (the trace kernel's compact mode) give one GPU process's accumulation bit for
/// bit through the wall camera, a moved eye included: every rank's GPU traces from the new
/// eye after the restart (2 in-process ranks sharing the test's adapter).
#[test]
fn gpu_ranks_give_the_one_gpu_process_accumulation_and_follow_a_moved_eye() {
    let s = scene();
    let moved = DVec3::new(0.4, -0.1, 1.2);
    let ctx = Arc::new(GpuContext::for_tests());
    let b = Backend::Gpu(Box::new(GpuContext::for_tests()));
    let mut one = Renderer::full_wall(&b, &s, settings(&s), wall(&s)).unwrap();
    for k in 0..5 {
        if k == 2 {
            assert!(matches!(
                one.follow_eye(moved, 0.0).unwrap(),
                EyeFollow::Restarted
            ));
        }
        one.run_frame(false).unwrap();
    }
    let one = one.finish().unwrap();
    let got: Vec<_> = std::thread::scope(|sc| {
        let handles: Vec<_> = InProcess::job(2)
            .into_iter()
            .map(|end| {
                let (s, ctx) = (&s, &ctx);
                sc.spawn(move || {
                    let mut c = Cluster::new(Box::new(end), Duration::from_secs(30));
                    let setup = ClusterSetup {
                        settings: settings(s),
                        guide: None,
                        wall: Some(wall(s)),
                        owners: columns(2),
                        dgi_mode: DgiMode::Compute,
                    };
                    let mut r = ClusterRenderer::new(&mut c, s, setup).unwrap();
                    r.trace_on_gpu(ctx.clone()).unwrap();
                    assert!(r.gpu().is_some());
                    for k in 0..5 {
                        if k == 2 {
                            r.move_eye(moved).unwrap();
                        }
                        r.run_frame(false).unwrap();
                    }
                    r.gather().unwrap()
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    let root = got.into_iter().next().unwrap().expect("rank 0 gathers");
    assert_eq!(root.0.count.iter().max(), Some(&3), "restarted at frame 2");
    assert_bits_equal(&root, &one, "2 GPU ranks, the eye moved");
}

/// Guided GPU ranks give one GPU process's accumulation and DGI bit for bit, the ROI moving
/// between frames: the ranks compute the DGI on their GPUs as the one process does (the CPU
/// twin's f64 solves agree with it only to rounding), whichever way it reaches them — each
/// rank computing it, rank 0 broadcasting it, or the split, which on GPUs is the compute (the
/// same bytes received as there: no band crosses the link).
#[test]
fn guided_gpu_ranks_give_the_one_gpu_process_accumulation_and_dgi() {
    let ctx = Arc::new(GpuContext::for_tests());
    let order = Order::Scattered;
    let one = single_on(
        &Backend::Gpu(Box::new(GpuContext::for_tests())),
        Some(order),
        false,
    );
    let mut traffic = Vec::new();
    for (n, mode) in [
        (2, DgiMode::Compute),
        (3, DgiMode::Broadcast),
        (2, DgiMode::Split),
    ] {
        // Each rank's gathered accumulation (rank 0's) and the bytes it received over the
        // frames.
        let got = ranks_on_then(n, Some(order), false, mode, columns, Some(&ctx), |r, f| {
            let received: u64 = f.iter().map(|s| s.traffic.bytes_received).sum();
            (r.gather().unwrap(), received)
        });
        let received: Vec<u64> = got.iter().map(|g| g.1).collect();
        let root = got.into_iter().next().unwrap().0.expect("rank 0 gathers");
        assert_bits_equal(&root, &one, &format!("{n} GPU ranks, DGI {mode:?}"));
        traffic.push((mode, received));
    }
    // On GPU ranks the split is the compute: no band crosses the link.
    assert_eq!(traffic[2], (DgiMode::Split, traffic[0].1.clone()));
}

/// Guided GPU ranks in coherent order draw each iteration's whole schedule on their GPUs (the
/// block masks' kernel; no masks cross the link) and give one GPU process's accumulation and
/// DGI bit for bit, through the wall camera's shown mask too.
#[test]
fn gpu_ranks_draw_the_coherent_schedule_on_their_gpus() {
    let ctx = Arc::new(GpuContext::for_tests());
    let order = Order::Coherent;
    for with_wall in [false, true] {
        let gpu = Backend::Gpu(Box::new(GpuContext::for_tests()));
        let one = single_on(&gpu, Some(order), with_wall);
        for n in [2, 3] {
            let got = ranks_on_then(
                n,
                Some(order),
                with_wall,
                DgiMode::Compute,
                columns,
                Some(&ctx),
                |r, _| {
                    assert!(
                        r.gpu.as_ref().is_some_and(|g| g.masks.is_some()),
                        "the schedule is drawn on the GPU"
                    );
                    r.gather().unwrap()
                },
            );
            let root = got.into_iter().next().unwrap().expect("rank 0 gathers");
            let what = format!("{n} GPU ranks, coherent, wall {with_wall}");
            assert_bits_equal(&root, &one, &what);
        }
    }
}

/// The split schedule's bytes: a flag byte a block and 128 bytes a non-empty one, read back
/// exactly; anything else is refused with what is wrong.
#[test]
fn schedule_masks_survive_their_bytes_and_bad_bytes_are_refused() {
    let mut a = [0u32; 32];
    a[3] = 0x8000_0001;
    let masks = vec![[0u32; 32], a, [u32::MAX; 32]];
    let b = encode_masks(&masks);
    assert_eq!(b.len(), 1 + 2 * 129);
    assert_eq!(decode_masks(&b, 3).unwrap(), masks);
    let refusal = |b: &[u8], blocks| decode_masks(b, blocks).unwrap_err().to_string();
    assert_eq!(refusal(&b, 4), "259 bytes for 4 blocks");
    assert_eq!(refusal(&b, 2), "259 bytes for 2 blocks, 129 past them");
    assert_eq!(refusal(&b[..100], 3), "block 1 of 3: its mask is cut short");
    let mut bad = b.clone();
    bad[0] = 2;
    assert_eq!(refusal(&bad, 3), "block 0 of 3: flag 2, not 0 or 1");
}

/// A frame's samples travel while the next frame is traced: after each frame an owner holds
/// them in flight (the frame within which they are collected without the overlap), and the next
/// frame — or a gather — brings them. Overlapped or not, on 2 and 3 ranks, the gathered
/// accumulation is one process's bit for bit, also when the camera moves with samples in flight
/// (a restart: they arrive and are dropped, as the one process drops what it had).
#[test]
fn samples_in_flight_arrive_with_the_next_frame_and_a_restart_drops_them() {
    const MOVE_AT: u32 = 4;
    let s = scene();
    let mut moved = settings(&s).camera;
    moved.position += glam::Vec3::new(0.05, 0.02, 0.0);
    let order = Order::Scattered;
    let mut one = Renderer::guided_wall(
        &Backend::Cpu,
        &s,
        settings(&s),
        &hornet(),
        config(order),
        None,
    )
    .unwrap();
    for k in 0..ITERATIONS {
        if let Some(roi) = roi_at(k) {
            one.set_roi(roi).unwrap();
        }
        if k == MOVE_AT {
            one.set_camera(moved).unwrap();
        }
        one.run_frame(false).unwrap();
    }
    let one = one.finish().unwrap();
    for n in 2..=3 {
        for overlap in [true, false] {
            let got = std::thread::scope(|sc| {
                let handles: Vec<_> = InProcess::job(n)
                    .into_iter()
                    .map(|end| {
                        sc.spawn(move || {
                            let mut c = Cluster::new(Box::new(end), Duration::from_secs(30));
                            let s = scene();
                            let model = hornet();
                            let setup = ClusterSetup {
                                settings: settings(&s),
                                guide: Some((&model, config(order))),
                                wall: None,
                                owners: columns(n),
                                dgi_mode: DgiMode::Compute,
                            };
                            let mut r = ClusterRenderer::new(&mut c, &s, setup).unwrap();
                            r.set_overlap(overlap);
                            for k in 0..ITERATIONS {
                                if let Some(roi) = roi_at(k) {
                                    r.set_roi(roi).unwrap();
                                }
                                if k == MOVE_AT {
                                    r.set_camera(moved).unwrap();
                                }
                                r.run_frame(false).unwrap();
                                assert_eq!(r.in_flight.is_some(), overlap, "after frame {k}");
                            }
                            r.gather().unwrap()
                        })
                    })
                    .collect();
                handles
                    .into_iter()
                    .map(|h| h.join().unwrap())
                    .next()
                    .unwrap()
            });
            let got = got.expect("rank 0 gathers");
            assert_bits_equal(&got, &one, &format!("{n} ranks, overlap {overlap}"));
        }
    }
}
