// A pixel indexes several parallel arrays (records, accumulations, references) at once.
#![allow(clippy::needless_range_loop)]

use glam::{DVec3, Vec2, Vec3};

use super::*;
use crate::display::DisplayModel;
use crate::scene::{Environment, Material, Scene, Triangle};
use crate::trace::camera::LookAt;
use crate::trace::features::hit_records_cpu;
use crate::trace::pack::PackedScene;
use crate::trace::path::TraceSettings;
use crate::trace::wall::WorldFromRoom;

/// A square of side `2 h` centred on `c` facing +Z.
fn quad(c: Vec3, h: f32, material: u32) -> [Triangle; 2] {
    let p = [
        c + Vec3::new(-h, -h, 0.0),
        c + Vec3::new(h, -h, 0.0),
        c + Vec3::new(h, h, 0.0),
        c + Vec3::new(-h, h, 0.0),
    ];
    let t = |a: usize, b: usize, cc: usize| Triangle {
        p: [p[a], p[b], p[cc]],
        n: [Vec3::Z; 3],
        uv: [Vec2::ZERO; 3],
        material,
    };
    [t(0, 1, 2), t(0, 2, 3)]
}

fn material(metallic: f32, roughness: f32) -> Material {
    Material {
        base_color: Vec3::splat(0.6).extend(1.0),
        metallic,
        roughness,
        double_sided: true,
        ..Default::default()
    }
}

/// A small occluder (material 1) half a unit in front of a large background (material 0),
/// both diffuse, seen from +Z.
fn occluder_scene(background: Material) -> PackedScene {
    let mut triangles = quad(Vec3::ZERO, 50.0, 0).to_vec();
    triangles.extend(quad(Vec3::new(0.0, 0.0, 0.5), 0.4, 1));
    PackedScene::new(&Scene {
        triangles,
        materials: vec![background, material(0.0, 1.0)],
        environment: Environment::Constant(Vec3::splat(0.5)),
        ..Default::default()
    })
}

fn settings(w: u32, h: u32, from: Vec3) -> TraceSettings {
    let look = LookAt {
        from,
        at: Vec3::new(from.x, from.y, 0.0),
        yfov_deg: 40.0,
    };
    TraceSettings {
        width: w,
        height: h,
        seed: 0,
        max_depth: 4,
        camera: RenderCamera::look_at(&look, w, h).unwrap(),
    }
}

fn pinhole(s: &TraceSettings) -> View<'static> {
    View::Pinhole {
        camera: s.camera,
        width: s.width,
        height: s.height,
    }
}

/// An accumulation whose pixel `p` holds one sample whose red sum is the x coordinate of its
/// anchor (the surface point it shows), so that carrying it can be checked against where it
/// should have gone.
fn tagged(records: &[[[f32; 4]; 2]], w: u32, h: u32) -> Accumulation {
    let mut acc = Accumulation::new(w, h);
    for (p, r) in records.iter().enumerate() {
        acc.sum[p] = [r[0][0], r[0][1], 0.0, 0.0];
        acc.count[p] = 1;
    }
    acc
}

/// Without a move, every shown pixel is its own source, with all its samples (the surfaces are
/// rough) but on the occluder's outline, whose history is an edge's: reuse is the identity.
#[test]
fn a_still_view_carries_every_pixel_onto_itself() {
    let sc = occluder_scene(material(0.0, 1.0));
    let s = settings(48, 32, Vec3::new(0.0, 0.0, 3.0));
    let records = hit_records_cpu(&sc, &s, None);
    let v = pinhole(&s);
    let word_of = |i: u32| word(&records[i as usize]);
    let mut edges = 0;
    for (p, r) in records.iter().enumerate() {
        let got = reuse_source(&v, &v, (r, p as u32, word_of), |q| records[q as usize]);
        let (q, cap) = got.unwrap_or_else(|| panic!("pixel {p} restarted"));
        assert_eq!(q, p as u32, "pixel {p}");
        // Around the occluder's outline the history is an edge's.
        assert!(cap == u32::MAX || cap == EDGE_HISTORY, "pixel {p}: {cap}");
        edges += usize::from(cap == EDGE_HISTORY);
    }
    assert!(
        edges > 0 && edges < records.len() / 4,
        "{edges} edge pixels"
    );
}

/// The camera steps sideways: the background the occluder hid from the old eye is
/// disoccluded and restarts, but for pixels at the band's edge that take background seen
/// within [`MAX_MISREGISTRATION_PX`]; every carried pixel came from an old pixel that saw the
/// same surface within a pixel of where the new pixel sees it (never the occluder's light on
/// the background: no ghost); the share carried is what the step leaves in view.
#[test]
fn a_step_restarts_the_disoccluded_and_carries_the_rest_in_register() {
    let sc = occluder_scene(material(0.0, 1.0));
    let (w, h) = (64u32, 48u32);
    let s0 = settings(w, h, Vec3::new(0.0, 0.0, 3.0));
    // The occluder (depth 2.5) shifts ~2.6 pixels against the background (depth 3).
    let s1 = settings(w, h, Vec3::new(0.6, 0.0, 3.0));
    let old = hit_records_cpu(&sc, &s0, None);
    let mut new = hit_records_cpu(&sc, &s1, None);
    let fresh = new.clone();
    let acc = tagged(&old, w, h);
    let (carried, stats) = reuse_cpu(&pinhole(&s1), &pinhole(&s0), &mut new, &old, &acc);
    assert_eq!(stats.shown, u64::from(w * h));
    // The background moves 13 of the 64 columns: those came into view.
    assert!(stats.share() > 0.72, "{stats:?}");
    let e0 = s0.camera.position;
    let (mut disoccluded, mut restarted) = (0, 0);
    for p in 0..(w * h) as usize {
        let r = fresh[p];
        let a = Vec3::new(r[0][0], r[0][1], r[0][2]);
        let footprint =
            (a - s1.camera.position).length() * 2.0 * 20f32.to_radians().tan() / h as f32;
        let seen_old = sc.bvh.closest_hit(e0, (a - e0).normalize(), f32::INFINITY);
        if word(&r) == 0 && seen_old.is_some_and(|hit| hit.t < (a - e0).length() * 0.99) {
            disoccluded += 1;
            if carried.count[p] == 0 {
                restarted += 1;
            }
        }
        if carried.count[p] > 0 {
            // The carried sample's anchor is the new record's, it is the same surface, and it
            // lies within a pixel's footprint of the point the new pixel sees.
            let tag = Vec3::new(carried.sum[p][0], carried.sum[p][1], 0.0);
            assert_eq!(tag.x, new[p][0][0]);
            assert!(
                (tag.truncate() - a.truncate()).abs().max_element() <= footprint,
                "pixel {p}: {tag} vs {a}"
            );
        }
    }
    assert!(
        disoccluded > 40,
        "the step disoccludes {disoccluded} pixels"
    );
    assert!(
        restarted * 2 > disoccluded,
        "{restarted} of {disoccluded} disoccluded restarted"
    );
}

/// Forty steps of a third of a pixel each way: the anchors keep each carried pixel within a
/// pixel of the surface it shows — the picture does not drift with the rounding of each step.
#[test]
fn many_small_steps_do_not_drift() {
    let sc = occluder_scene(material(0.0, 1.0));
    let (w, h) = (64u32, 48u32);
    let s0 = settings(w, h, Vec3::new(0.0, 0.0, 3.0));
    // One pixel at the background's depth is 3 · 2 tan 20° / 48 ≈ 0.045 units.
    let step = 0.015;
    let mut view = s0;
    let mut records = hit_records_cpu(&sc, &view, None);
    let mut acc = tagged(&records, w, h);
    let mut carried_all_along = 0;
    for k in 1..=40 {
        let next = settings(w, h, Vec3::new(step * k as f32, 0.0, 3.0));
        let mut new = hit_records_cpu(&sc, &next, None);
        let fresh = new.clone();
        let (a, _) = reuse_cpu(&pinhole(&next), &pinhole(&view), &mut new, &records, &acc);
        acc = a;
        // A restarted pixel starts tagged with its own anchor again.
        for p in 0..(w * h) as usize {
            if acc.count[p] == 0 {
                acc.sum[p] = [fresh[p][0][0], fresh[p][0][1], 0.0, 0.0];
                acc.count[p] = 1;
            }
        }
        records = new;
        view = next;
    }
    let footprint = 3.0 * 2.0 * 20f32.to_radians().tan() / h as f32;
    let fresh = hit_records_cpu(&sc, &view, None);
    for p in 0..(w * h) as usize {
        if word(&fresh[p]) != 0 {
            continue;
        }
        let dx = (acc.sum[p][0] - fresh[p][0][0]).abs();
        assert!(
            dx <= 1.5 * footprint,
            "pixel {p} drifted {:.2} px",
            dx / footprint
        );
        if acc.sum[p][0] != fresh[p][0][0] {
            carried_all_along += 1;
        }
    }
    assert!(
        carried_all_along > (w * h / 2) as usize,
        "{carried_all_along}"
    );
}

/// Mirrors and glass restart; a glossy surface carries at most HISTORY_LENGTH samples, the
/// mean kept; a glossy surface seen from too far round restarts.
#[test]
fn mirrors_restart_and_glossy_surfaces_carry_a_capped_history() {
    let (w, h) = (32u32, 24u32);
    let s0 = settings(w, h, Vec3::new(0.0, 0.0, 3.0));
    let s1 = settings(w, h, Vec3::new(0.05, 0.0, 3.0));
    let mirror = occluder_scene(material(1.0, 0.0));
    let old = hit_records_cpu(&mirror, &s0, None);
    let mut new = hit_records_cpu(&mirror, &s1, None);
    let acc = tagged(&old, w, h);
    let (carried, _) = reuse_cpu(&pinhole(&s1), &pinhole(&s0), &mut new, &old, &acc);
    for p in 0..(w * h) as usize {
        if word(&new[p]) & NEVER_REUSE != 0 {
            assert_eq!(carried.count[p], 0);
        }
    }
    assert!(new.iter().any(|r| word(r) & NEVER_REUSE != 0));
    // Roughness 0.4: α = 0.16 < DIFFUSE_ALPHA; the step turns the view by ~1°.
    let glossy = occluder_scene(material(1.0, 0.4));
    let old = hit_records_cpu(&glossy, &s0, None);
    let mut new = hit_records_cpu(&glossy, &s1, None);
    let mut acc = Accumulation::new(w, h);
    acc.sum.fill([100.0, 50.0, 25.0, 10.0]);
    acc.count.fill(100);
    let (carried, stats) = reuse_cpu(&pinhole(&s1), &pinhole(&s0), &mut new, &old, &acc);
    assert!(stats.carried > 0);
    for p in 0..(w * h) as usize {
        if carried.count[p] > 0 && word(&new[p]) == 0 {
            // Capped at the glossy history, or an edge's beside the occluder.
            assert!([HISTORY_LENGTH, EDGE_HISTORY].contains(&carried.count[p]));
            let mean = carried.sum[p][0] / carried.count[p] as f32;
            assert!((mean - 1.0).abs() < 1e-6, "{mean}");
        }
    }
    // A step of a quarter of the distance turns the view by ~14°: more than 0.5 × 0.16 rad.
    let far = settings(w, h, Vec3::new(0.7, 0.0, 3.0));
    let mut new = hit_records_cpu(&glossy, &far, None);
    let (carried, _) = reuse_cpu(&pinhole(&far), &pinhole(&s0), &mut new, &old, &acc);
    for p in 0..(w * h) as usize {
        if word(&new[p]) == 0 {
            assert_eq!(
                carried.count[p], 0,
                "pixel {p}: background seen 14° round carried"
            );
        }
    }
}

/// Through the wall camera: projecting each shown pixel's centre ray finds that pixel again
/// (the inverse of `WallCamera::ray`), and a still eye carries every shown pixel onto itself.
#[test]
fn the_wall_camera_projects_its_own_rays_back() {
    let model = DisplayModel::open("hornet").unwrap().0;
    let (w, h) = (331u32, 134u32);
    let cam = (DVec3::new(0.0, 1.0, 4.0), DVec3::NEG_Z, DVec3::Y);
    let wall = WallCamera::new(
        &model,
        [w, h],
        DVec3::new(0.1, 0.0, 1.2),
        &WorldFromRoom::Auto,
        cam,
    )
    .unwrap();
    let mut found = 0;
    for p in 0..w * h {
        let (x, y) = (p % w, p / w);
        let Some(t) = wall.tile_of(x, y) else {
            continue;
        };
        let (_, d) = wall.ray(t, x, y, 0.5, 0.5);
        let (at, q) = wall.project(d, None).expect("a shown pixel's ray projects");
        assert_eq!(
            wall.project(d, Some(t)),
            Some((at, q)),
            "the pixel's own entry first"
        );
        assert_eq!(q, p, "pixel ({x}, {y}) at {at:?}");
        assert!((at[0] - x as f32 - 0.5).abs() < 1e-2 && (at[1] - y as f32 - 0.5).abs() < 1e-2);
        found += 1;
    }
    assert!(found > (w * h / 2) as usize);
    let sc = occluder_scene(material(0.0, 1.0));
    let s = TraceSettings {
        width: w,
        height: h,
        seed: 0,
        max_depth: 4,
        camera: settings(w, h, Vec3::new(0.0, 1.0, 4.0)).camera,
    };
    let records = hit_records_cpu(&sc, &s, Some(&wall));
    let v = View::Wall(&wall);
    let mut shown = 0;
    let word_of = |i: u32| word(&records[i as usize]);
    for (p, r) in records.iter().enumerate() {
        let got = reuse_source(&v, &v, (r, p as u32, word_of), |q| records[q as usize]);
        if wall.is_shown(p as u32) && wall.tile_of(p as u32 % w, p as u32 / w).is_some() {
            shown += 1;
            assert_eq!(got.map(|g| g.0), Some(p as u32), "pixel {p}");
        } else {
            assert_eq!(got, None);
        }
    }
    assert!(shown > 0);
}
