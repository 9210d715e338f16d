//! State machine tests against an analytic plane: the wall z = 0, 4 m × 2 m, 1000 px/m.

use glam::{DQuat, DVec2, DVec3};
use proptest::prelude::*;

use super::*;
use crate::tracking::event::{DeviceId, DeviceKind, Pose, Tracking, TrackingEvent};

fn plane() -> HingedWall {
    HingedWall::new(1, 1, 4.0, 2.0, 0.0, 1000.0)
}

fn stick() -> DeviceId {
    DeviceId::new(DeviceKind::Flystick, 0)
}

fn pose_at(x: f64, y: f64, z: f64, q: DQuat) -> Option<Tracking> {
    Some(Tracking::Tracked(Pose {
        position: DVec3::new(x, y, z),
        orientation: q,
    }))
}

fn ev(t: f64, pose: Option<Tracking>, buttons: u32, axes: [f64; 2]) -> TrackingEvent {
    TrackingEvent {
        pose,
        buttons: Some(buttons),
        axes: Some(axes.to_vec()),
        ..TrackingEvent::empty(t, stick())
    }
}

fn run(events: &[TrackingEvent], config: InteractionConfig) -> (Interaction, Vec<RoiChange>) {
    let mut m = Interaction::new(config);
    let mut out = Vec::new();
    let s = plane();
    for e in events {
        m.handle(e, &s, &mut out);
    }
    (m, out)
}

#[test]
fn trigger_press_centres_the_roi_on_the_ray_hit() {
    // 1 m in front of the plane at x = 0.5, turned 45° to the left: hits x = 0.5 − 1 = −0.5.
    let q = DQuat::from_rotation_y(std::f64::consts::FRAC_PI_4);
    let p = pose_at(0.5, 0.2, 1.0, q);
    let (m, out) = run(
        &[ev(0.0, p, 0, [0.0; 2]), ev(0.1, p, 1, [0.0; 2])],
        InteractionConfig::default(),
    );
    assert_eq!(out.len(), 1);
    assert_eq!(out[0].cause, ChangeCause::Shoot);
    let c = m.roi().centre.clone().unwrap();
    assert!((c.point - DVec3::new(-0.5, 0.2, 0.0)).length() < 1e-12);
    // Canvas: x = (−0.5 + 2) m · 1000, y = (1 − 0.2) m · 1000.
    assert!((c.canvas_px - DVec2::new(1500.0, 800.0)).length() < 1e-9);
    assert!(
        (c.image_px - DVec2::new(1500.0 / 4000.0 * 3840.0, 800.0 / 2000.0 * 2160.0)).length()
            < 1e-9
    );
    let cone = m.roi().cone.unwrap();
    assert!((cone.axis - q * DVec3::NEG_Z).length() < 1e-15);
    assert!(cone.right.dot(cone.axis).abs() < 1e-15);
}

#[test]
fn holding_the_trigger_does_not_shoot_again() {
    let p = pose_at(0.0, 0.0, 1.0, DQuat::IDENTITY);
    let evs: Vec<_> = (0..10)
        .map(|i| ev(f64::from(i) * 0.1, p, 1, [0.0; 2]))
        .collect();
    let (_, out) = run(&evs, InteractionConfig::default());
    assert_eq!(out.len(), 1);
}

#[test]
fn miss_leaves_the_roi_unchanged_and_is_reported() {
    let p = pose_at(0.0, 0.0, 1.0, DQuat::IDENTITY);
    let away = pose_at(0.0, 0.0, 1.0, DQuat::from_rotation_y(std::f64::consts::PI));
    let (m, out) = run(
        &[
            ev(0.0, p, 1, [0.0; 2]),
            ev(0.5, away, 0, [0.0; 2]),
            ev(1.0, away, 1, [0.0; 2]),
        ],
        InteractionConfig::default(),
    );
    let causes: Vec<_> = out.iter().map(|c| c.cause).collect();
    assert_eq!(causes, vec![ChangeCause::Shoot, ChangeCause::Miss]);
    assert_eq!(out[1].roi, out[0].roi);
    assert!((m.roi().centre.as_ref().unwrap().point).length() < 1e-12);
}

#[test]
fn untracked_press_is_reported_and_never_uses_a_stale_pose() {
    let p = pose_at(0.0, 0.0, 1.0, DQuat::IDENTITY);
    let (_, out) = run(
        &[
            ev(0.0, p, 0, [0.0; 2]),
            ev(0.5, Some(Tracking::Lost), 0, [0.0; 2]),
            ev(1.0, Some(Tracking::Lost), 1, [0.0; 2]),
        ],
        InteractionConfig::default(),
    );
    assert_eq!(out.len(), 1);
    assert_eq!(out[0].cause, ChangeCause::Untracked);
    assert!(out[0].roi.centre.is_none());
}

#[test]
fn trigger_bounce_within_the_debounce_time_shoots_once() {
    let p = pose_at(0.0, 0.0, 1.0, DQuat::IDENTITY);
    // 1, 0, 1 within 20 ms: one press. Then a release 0, 1, 0 bounce, then a real press.
    let pattern = [
        (0.0, 1),
        (0.01, 0),
        (0.02, 1),
        (0.5, 0),
        (0.51, 1),
        (0.52, 0),
        (1.0, 1),
    ];
    let evs: Vec<_> = pattern
        .iter()
        .map(|&(t, b)| ev(t, p, b, [0.0; 2]))
        .collect();
    let (_, out) = run(&evs, InteractionConfig::default());
    let times: Vec<f64> = out.iter().map(|c| c.t).collect();
    assert_eq!(times, vec![0.0, 1.0]);
}

#[test]
fn a_short_click_is_released_once_the_debounce_time_has_passed() {
    let p = pose_at(0.0, 0.0, 1.0, DQuat::IDENTITY);
    // Press for 10 ms only: the release is seen at the next sample after 30 ms, so the next
    // press at 0.2 s shoots again.
    let pattern = [(0.0, 1), (0.01, 0), (0.05, 0), (0.2, 1)];
    let evs: Vec<_> = pattern
        .iter()
        .map(|&(t, b)| ev(t, p, b, [0.0; 2]))
        .collect();
    let (_, out) = run(&evs, InteractionConfig::default());
    assert_eq!(out.len(), 2);
}

#[test]
fn full_stick_deflection_changes_fov_at_the_gain_rate() {
    let p = pose_at(0.0, 0.0, 1.0, DQuat::IDENTITY);
    // 60 Hz, 1 s of full deflection right/forward: +40° on both axes from 30°, capped at 90°.
    let evs: Vec<_> = (0..=60)
        .map(|i| ev(f64::from(i) / 60.0, p, 0, [1.0, 1.0]))
        .collect();
    let (m, _) = run(&evs, InteractionConfig::default());
    for f in m.roi().fov_deg {
        assert!((f - 70.0).abs() < 1e-9, "{f}");
    }
}

#[test]
fn dead_zone_swallows_small_deflections_and_rescales_the_rest() {
    let p = pose_at(0.0, 0.0, 1.0, DQuat::IDENTITY);
    let evs: Vec<_> = (0..=60)
        .map(|i| ev(f64::from(i) / 60.0, p, 0, [0.14, -0.575]))
        .collect();
    let (m, _) = run(&evs, InteractionConfig::default());
    // Horizontal inside the dead zone; vertical (0.575 − 0.15)/0.85 = 0.5 → −20° in 1 s.
    assert_eq!(m.roi().fov_deg[0], 30.0);
    assert!((m.roi().fov_deg[1] - 10.0).abs() < 1e-9);
}

#[test]
fn fov_is_clamped_to_its_limits_and_signs_flip_axes() {
    let p = pose_at(0.0, 0.0, 1.0, DQuat::IDENTITY);
    let mut config = InteractionConfig::default();
    config.stick.signs = [-1.0, 1.0];
    let evs: Vec<_> = (0..=600)
        .map(|i| ev(f64::from(i) / 60.0, p, 0, [1.0, 1.0]))
        .collect();
    let (m, out) = run(&evs, config);
    assert_eq!(m.roi().fov_deg, [5.0, 90.0]);
    // Once both are at their limits nothing changes any more, so nothing is reported.
    assert!(out.len() < 120, "{}", out.len());
}

#[test]
fn a_gap_in_the_stream_cannot_make_the_fov_jump() {
    let p = pose_at(0.0, 0.0, 1.0, DQuat::IDENTITY);
    let (m, _) = run(
        &[ev(0.0, p, 0, [1.0, 0.0]), ev(10.0, p, 0, [1.0, 0.0])],
        InteractionConfig::default(),
    );
    // One step is capped at 0.1 s: +4°.
    assert!((m.roi().fov_deg[0] - 34.0).abs() < 1e-9);
}

#[test]
fn reset_and_toggle_buttons_do_their_documented_actions() {
    let p = pose_at(0.0, 0.0, 1.0, DQuat::IDENTITY);
    let evs = vec![
        ev(0.0, p, 0, [1.0, 0.0]),
        ev(0.5, p, 0, [0.0, 0.0]),
        ev(1.0, p, 0b10, [0.0, 0.0]),
        ev(1.5, p, 0b100, [0.0, 0.0]),
    ];
    let (m, out) = run(&evs, InteractionConfig::default());
    let causes: Vec<_> = out.iter().map(|c| c.cause).collect();
    assert_eq!(
        causes,
        vec![
            ChangeCause::Fov,
            ChangeCause::ResetFov,
            ChangeCause::ToggleFilter
        ]
    );
    assert_eq!(m.roi().fov_deg, [30.0, 30.0]);
    assert!(!m.roi().filter);
}

#[test]
fn other_devices_and_invalid_events_are_ignored() {
    let p = pose_at(0.0, 0.0, 1.0, DQuat::IDENTITY);
    let mut other = ev(0.0, p, 1, [1.0, 1.0]);
    other.device = DeviceId::new(DeviceKind::Flystick, 1);
    let mut nan = ev(0.1, p, 1, [f64::NAN, 0.0]);
    nan.device = stick();
    let (_, out) = run(&[other, nan], InteractionConfig::default());
    assert!(out.is_empty());
}

#[test]
fn mouse_click_centres_on_the_pointer_with_the_configured_ellipse() {
    let mouse = DeviceId::new(DeviceKind::Mouse, 0);
    let config = InteractionConfig {
        device: mouse,
        ..InteractionConfig::default()
    };
    let mk = |t, b, c: DVec2| TrackingEvent {
        buttons: Some(b),
        canvas: Some(c),
        ..TrackingEvent::empty(t, mouse)
    };
    let (m, out) = run(
        &[
            mk(0.0, 0, DVec2::new(100.0, 200.0)),
            mk(0.1, 1, DVec2::new(300.0, 400.0)),
            mk(0.2, 0, DVec2::new(-5.0, 0.0)),
            mk(0.3, 1, DVec2::new(-5.0, 0.0)),
        ],
        config,
    );
    let causes: Vec<_> = out.iter().map(|c| c.cause).collect();
    assert_eq!(causes, vec![ChangeCause::Shoot, ChangeCause::Miss]);
    let c = m.roi().centre.clone().unwrap();
    assert_eq!(c.canvas_px, DVec2::new(300.0, 400.0));
    assert_eq!(m.roi().ellipse_px, Some([400.0, 300.0]));
    assert!(m.roi().cone.is_none());
}

#[test]
fn report_is_relative_to_the_origin_and_rounded() {
    let p = pose_at(0.1234567, 0.0, 1.0, DQuat::IDENTITY);
    let (_, out) = run(
        &[ev(100.0, p, 0, [0.0; 2]), ev(100.25, p, 1, [0.0; 2])],
        InteractionConfig::default(),
    );
    let r = out[0].report(100.0);
    assert_eq!(r.t, 0.25);
    assert_eq!(r.centre_canvas_px, Some([2123.457, 1000.0]));
    assert_eq!(r.tile.as_deref(), Some("c0r0"));
    let json = serde_json::to_string(&r).unwrap();
    assert!(json.contains("\"kind\":\"shoot\""), "{json}");
}

proptest! {
    #[test]
    fn fov_stays_within_limits_for_any_stick_input(
        samples in proptest::collection::vec((0.0f64..0.5, -1.0f64..=1.0, -1.0f64..=1.0), 1..200)
    ) {
        let p = pose_at(0.0, 0.0, 1.0, DQuat::IDENTITY);
        let mut t = 0.0;
        let evs: Vec<_> = samples.iter().map(|&(dt, a, b)| { t += dt; ev(t, p, 0, [a, b]) }).collect();
        let (m, out) = run(&evs, InteractionConfig::default());
        for c in out.iter().map(|c| c.roi.fov_deg).chain(std::iter::once(m.roi().fov_deg)) {
            prop_assert!(c.iter().all(|f| (5.0..=90.0).contains(f)));
        }
    }

    #[test]
    fn a_shot_centre_lies_on_the_pointing_ray(yaw in -0.9f64..0.9, pitch in -0.5f64..0.5, x in -1.0f64..1.0) {
        let q = DQuat::from_euler(glam::EulerRot::YXZ, yaw, pitch, 0.0);
        let p = pose_at(x, 0.0, 1.0, q);
        let (m, out) = run(&[ev(0.0, p, 0, [0.0; 2]), ev(0.1, p, 1, [0.0; 2])], InteractionConfig::default());
        prop_assert_eq!(out.len(), 1);
        if let Some(c) = &m.roi().centre {
            let d = q * DVec3::NEG_Z;
            let v = c.point - DVec3::new(x, 0.0, 1.0);
            prop_assert!(v.cross(d).length() < 1e-9 && v.dot(d) > 0.0);
            prop_assert!(c.point.z.abs() < 1e-12);
        } else {
            prop_assert_eq!(out[0].cause, ChangeCause::Miss);
        }
    }
}

#[test]
fn roi_state_hands_the_dgi_stage_the_shot_cone_with_the_current_fov() {
    assert_eq!(
        Interaction::new(InteractionConfig::default())
            .roi()
            .to_roi(),
        Ok(None)
    );
    let q = DQuat::from_rotation_y(std::f64::consts::FRAC_PI_4);
    let p = pose_at(0.5, 0.2, 1.0, q);
    let (m, _) = run(
        &[ev(0.0, p, 0, [0.0; 2]), ev(0.1, p, 1, [0.0; 2])],
        InteractionConfig::default(),
    );
    let Some(crate::roi::dgi::Roi::Cone(cone)) = m.roi().to_roi().unwrap() else {
        panic!("a shot gives a cone ROI");
    };
    assert!((cone.apex - DVec3::new(0.5, 0.2, 1.0)).length() < 1e-15);
    assert!((cone.axis - q * DVec3::NEG_Z).length() < 1e-12);
    let (h, v) = cone.fov_deg();
    let [fh, fv] = m.roi().fov_deg;
    assert!((h - fh).abs() < 1e-9 && (v - fv).abs() < 1e-9);
    // The ROI centre the interaction found is inside the cone it hands over.
    assert!(cone.contains(m.roi().centre.clone().unwrap().point));
}
