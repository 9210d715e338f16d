//! Deterministic synthetic FlyStick and mouse sessions (the files in `tracking-replays/`).
//!
//! These are *synthetic*: made by this generator, not recorded from people. The motion model:
//!
//! * **Aimed pointing movements.** The user points at a sequence of targets on the wall. Each
//!   movement turns the pointing direction from the previous target to the next along a great
//!   circle with a minimum-jerk profile s(τ) = 10τ³ − 15τ⁴ + 6τ⁵ (Flash & Hogan 1985), lasting
//!   by Fitts' law T = 0.30 s + 0.15 s · log2(1 + A/2°) for an angular amplitude A.
//! * **Hand tremor.** Physiological tremor, 8–12 Hz: two sinusoids per axis (yaw, pitch) with
//!   frequencies drawn from that band and amplitudes 0.08° and 0.05°, plus 0.3 mm of positional
//!   tremor and a slow body sway (≈1 cm, 0.1–0.25 Hz).
//! * **Tracker noise.** Gaussian, σ = 0.15 mm per position axis, 0.03° of rotation.
//! * **Dropouts.** Intervals of 0.15–0.6 s where the stick is untracked (DTrack: quality −1
//!   and a zero rotation; OSC: `/raygun/0/lost`). Buttons keep working.
//! * **Trigger presses with bounce.** After arriving, the user dwells, then presses for
//!   0.1–0.25 s; with probability 0.6 the contact bounces (the sampled state reads 1, 0, 1 at
//!   press and 0, 1, 0 at release, one frame each).
//! * **Stick sweeps.** After some shots the stick is pushed diagonally (both FOVs) with a
//!   0.12 s linear ramp, held, and released so that, integrated exactly as the default
//!   interaction mapping does, the FOV goes 30° → 10°, then 10° → 60°, 60° → 10°, …
//!   At rest the stick reads small noise inside the dead zone.
//!
//! Geometry: HORNET (`display-models/hornet.json`; the generator aims with the identical
//! analytic [`HingedWall::hornet`]: 7 columns of 1.024 m, 10° apart, 2.9 m high, centred at the
//! origin, middle column in z = 0) with the viewer 1 m in front of the centre; the stick is held 25 cm right of, 35 cm below and 25 cm in front of the eyes.
//! DTrack datagrams are written in a Z-up tracker frame whose origin is on the floor 1.45 m
//! below the wall centre (the header carries the matching tracker→room transform).

use std::fmt::Write as _;
use std::io;
use std::path::{Path, PathBuf};

use glam::{DMat3, DQuat, DVec2, DVec3};

use crate::tracking::dtrack::{DtrackConfig, TrackerToRoom, format_flystick_block};
use crate::tracking::event::{DeviceId, DeviceKind, Pose, TrackingEvent};
use crate::tracking::head::HeadConfig;
use crate::tracking::ingest::Protocol;
use crate::tracking::osc::encode;
use crate::tracking::replay::{ReplayHeader, ReplayWriter};

use super::{HingedWall, InteractionConfig, RaySurface};

/// SplitMix64: tiny, fast and fully specified, so sessions are identical on every platform.
#[derive(Clone, Debug)]
pub struct Rng(u64);

impl Rng {
    #[must_use]
    pub fn new(seed: u64) -> Self {
        Self(seed)
    }

    #[must_use]
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    #[must_use]
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    #[must_use]
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    /// Standard normal (Box–Muller).
    #[must_use]
    pub fn gauss(&mut self) -> f64 {
        let u1 = self.unit().max(1e-300);
        let u2 = self.unit();
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

/// Where the targets of a session lie.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Targets {
    /// The middle three columns.
    Centre,
    /// Anywhere on the wall.
    Wide,
    /// Mostly on the wall, one in three above it or past its edge (misses).
    SomeOffWall,
}

/// One FlyStick session.
#[derive(Clone, Debug, PartialEq)]
pub struct SessionSpec {
    pub name: &'static str,
    pub seed: u64,
    pub duration_s: f64,
    pub rate_hz: f64,
    /// FlyStick2+ (8 buttons, 3 axes) instead of FlyStick2 (6, 2).
    pub flystick_plus: bool,
    /// `ts` value of the first frame (seconds since midnight).
    pub ts_start: f64,
    /// Write `ts2` instead of `ts`.
    pub ts2: bool,
    pub targets: Targets,
    pub dropouts: u32,
    /// Also track a head body (`6d`, id 3) and a second, untracked FlyStick (id 1).
    pub extra_devices: bool,
    /// DTrack line ending.
    pub crlf: bool,
    /// Also track a walking head (DTrack `6d` body 3, OSC `osc:1`) named in the header as the
    /// head that moves the wall camera's eye ([`head_pose`]).
    pub head_walk: bool,
}

/// The six FlyStick sessions shipped in `tracking-replays/`.
#[must_use]
pub fn flystick_sessions() -> Vec<SessionSpec> {
    let base = SessionSpec {
        name: "",
        seed: 0,
        duration_s: 20.0,
        rate_hz: 60.0,
        flystick_plus: false,
        ts_start: 36_000.0,
        ts2: false,
        targets: Targets::Centre,
        dropouts: 1,
        extra_devices: false,
        crlf: false,
        head_walk: false,
    };
    vec![
        SessionSpec {
            name: "flystick-1-centre-sweeps",
            seed: 1,
            ..base.clone()
        },
        SessionSpec {
            name: "flystick-2-wall-scan",
            seed: 2,
            targets: Targets::Wide,
            ts2: true,
            ..base.clone()
        },
        SessionSpec {
            name: "flystick-3-dropouts",
            seed: 3,
            dropouts: 5,
            targets: Targets::Wide,
            ..base.clone()
        },
        SessionSpec {
            name: "flystick-4-misses",
            seed: 4,
            targets: Targets::SomeOffWall,
            crlf: true,
            ..base.clone()
        },
        SessionSpec {
            name: "flystick-5-plus-extra-devices",
            seed: 5,
            flystick_plus: true,
            extra_devices: true,
            ..base.clone()
        },
        SessionSpec {
            name: "flystick-6-120hz-midnight",
            seed: 6,
            rate_hz: 120.0,
            ts_start: 86_390.0,
            targets: Targets::Wide,
            ..base
        },
    ]
}

/// The session with a tracked head shipped in `tracking-replays/` (`head-1-walk`): the
/// centre-sweeps FlyStick script (seed 7) while the viewer steps right, in, left and back
/// ([`head_pose`]).
#[must_use]
pub fn head_sessions() -> Vec<SessionSpec> {
    vec![SessionSpec {
        name: "head-1-walk",
        seed: 7,
        duration_s: 20.0,
        rate_hz: 60.0,
        flystick_plus: false,
        ts_start: 36_000.0,
        ts2: false,
        targets: Targets::Centre,
        dropouts: 1,
        extra_devices: false,
        crlf: false,
        head_walk: true,
    }]
}

/// The head's DTrack body id and OSC device number in the head sessions.
pub const HEAD_BODY: u32 = 3;
pub const HEAD_OSC: u32 = 1;
/// Where the eye sits on the head's marker tree (its body frame, metres): 8 cm below and 6 cm
/// in front of the tree's origin.
pub const HEAD_EYE_OFFSET_M: [f64; 3] = [0.0, -0.08, -0.06];

/// The walking viewer's eye over a head session: standing 1 m in front of the centre with a
/// 2 mm sway (below the restart threshold), then minimum-jerk steps — 35 cm right (3.0–4.2 s),
/// 25 cm in (7.0–8.0 s), to 40 cm left of the centre and 1.2 m out (11.0–12.5 s) and back
/// (15.0–16.0 s) — with an untracked interval at 13.5–13.9 s (`None`).
#[must_use]
pub fn head_eye(t: f64) -> Option<DVec3> {
    if (13.5..13.9).contains(&t) {
        return None;
    }
    let steps = [
        (3.0, 1.2, DVec3::new(0.35, 0.0, 1.0)),
        (7.0, 1.0, DVec3::new(0.35, 0.0, 0.75)),
        (11.0, 1.5, DVec3::new(-0.4, 0.05, 1.2)),
        (15.0, 1.0, EYE),
    ];
    let mut at = EYE;
    for (start, dur, to) in steps {
        at = at.lerp(to, min_jerk((t - start) / dur));
    }
    let sway = 0.002 * (std::f64::consts::TAU * 0.3 * t).sin();
    Some(at + DVec3::new(sway, 0.5 * sway, 0.0))
}

/// The head body's pose in a head session (room frame): the eye of [`head_eye`] less the eye
/// offset, facing the wall's centre, with `rng`'s tracker noise (σ = 0.15 mm).
#[must_use]
pub fn head_pose(t: f64, rng: &mut Rng) -> Option<Pose> {
    let eye = head_eye(t)?;
    let q = aim(-eye);
    let noise = DVec3::new(rng.gauss(), rng.gauss(), rng.gauss()) * 0.15e-3;
    Some(Pose {
        position: eye - q * DVec3::from_array(HEAD_EYE_OFFSET_M) + noise,
        orientation: q,
    })
}

/// The head a head session's header names.
fn head_header(device: DeviceId) -> HeadConfig {
    HeadConfig {
        eye_offset_m: HEAD_EYE_OFFSET_M,
        ..HeadConfig::new(device)
    }
}

/// One simulated tracker sample of the stick (room frame).
#[derive(Clone, Debug, PartialEq)]
pub struct Sample {
    pub t: f64,
    pub pose: Option<Pose>,
    pub buttons: u32,
    pub axes: Vec<f64>,
}

fn min_jerk(tau: f64) -> f64 {
    let x = tau.clamp(0.0, 1.0);
    x * x * x * (10.0 - 15.0 * x + 6.0 * x * x)
}

/// Orientation whose −Z axis points along `d` with no roll (its X axis horizontal).
fn aim(d: DVec3) -> DQuat {
    let d = d.normalize();
    let r = d.cross(DVec3::Y).normalize();
    let u = r.cross(d);
    DQuat::from_mat3(&DMat3::from_cols(r, u, -d)).normalize()
}

/// The eye point, the stick's rest position, and the tracker→room transform of the sessions.
pub const EYE: DVec3 = DVec3::new(0.0, 0.0, 1.0);
const HAND: DVec3 = DVec3::new(0.25, -0.35, 0.75);

/// The tracker→room transform written into every synthetic DTrack header.
#[must_use]
pub fn session_tracker_to_room() -> TrackerToRoom {
    TrackerToRoom {
        translation_m: [0.0, -1.45, 0.0],
        ..TrackerToRoom::z_up()
    }
}

#[derive(Clone, Copy)]
enum Phase {
    Move {
        from: DVec3,
        to: DVec3,
        start: f64,
        dur: f64,
    },
    Hold {
        dir: DVec3,
    },
}

/// A button press interval with optional bounce.
struct Press {
    bit: u32,
    start: f64,
    end: f64,
    bounce: bool,
}

/// Simulates one session at its frame rate.
///
/// One function of some 240 lines on purpose: every draw from the session's generator happens
/// in one fixed order — the targets, the presses, then frame by frame the motion, tremor, noise
/// and stick — and the shipped files depend on that order byte for byte; read top to bottom,
/// the function is that order.
// Long: one fixed order of draws from the session's generator, which the shipped files depend
// on byte for byte (see above).
#[must_use]
pub fn simulate(spec: &SessionSpec) -> Vec<Sample> {
    let mut rng = Rng::new(spec.seed.wrapping_mul(0x2545_F491_4F6C_DD1D) ^ 0x5EED);
    let wall = HingedWall::hornet();
    let size = wall.canvas_size();
    let frame_dt = 1.0 / spec.rate_hz;
    let n = (spec.duration_s * spec.rate_hz).round() as usize;

    // --- the script: targets, movements, presses, sweeps --------------------------------
    let target_point = |rng: &mut Rng, k: usize| -> DVec3 {
        let (x0, x1, y0, y1) = match spec.targets {
            Targets::Centre => (2.0 / 7.0, 5.0 / 7.0, 0.2, 0.8),
            Targets::Wide | Targets::SomeOffWall => (0.03, 0.97, 0.1, 0.9),
        };
        if spec.targets == Targets::SomeOffWall && k % 3 == 2 {
            // Above the top edge, or past the left end of the wall.
            return if k.is_multiple_of(2) {
                DVec3::new(rng.range(-1.0, 1.0), rng.range(1.8, 2.3), 0.0)
            } else {
                DVec3::new(-4.5, rng.range(-0.5, 0.5), 1.5)
            };
        }
        let c = DVec2::new(rng.range(x0, x1) * size.x, rng.range(y0, y1) * size.y);
        wall.locate(c).map_or(DVec3::ZERO, |h| h.point)
    };
    let mut phases: Vec<Phase> = Vec::new();
    let mut presses: Vec<Press> = Vec::new();
    // Stick sweeps: (start time, target FOV).
    let mut sweeps: Vec<(f64, f64)> = Vec::new();
    let mut dir = (DVec3::new(0.0, 0.0, 0.0) - HAND).normalize();
    let mut t = 0.5;
    let mut k = 0;
    let mut sweep_to = 10.0;
    phases.push(Phase::Hold { dir });
    while t < spec.duration_s - 1.0 {
        let target = target_point(&mut rng, k);
        let to = (target - HAND).normalize();
        let amp = dir.angle_between(to).to_degrees();
        let dur = 0.30 + 0.15 * (1.0 + amp / 2.0).log2();
        phases.push(Phase::Move {
            from: dir,
            to,
            start: t,
            dur,
        });
        t += dur;
        dir = to;
        let dwell = rng.range(0.4, 1.0);
        let press_at = t + dwell * 0.5;
        let hold = rng.range(0.1, 0.25);
        presses.push(Press {
            bit: 0,
            start: press_at,
            end: press_at + hold,
            bounce: rng.unit() < 0.6,
        });
        t += dwell + hold;
        if k % 2 == 0 {
            sweeps.push((t, sweep_to));
            sweep_to = if sweep_to == 10.0 { 60.0 } else { 10.0 };
            t += 2.0;
        }
        k += 1;
    }
    // Reset the FOV near the end; sessions with extra devices also toggle the filter twice.
    presses.push(Press {
        bit: 1,
        start: spec.duration_s - 0.8,
        end: spec.duration_s - 0.6,
        bounce: false,
    });
    if spec.extra_devices {
        presses.push(Press {
            bit: 2,
            start: 2.0,
            end: 2.15,
            bounce: true,
        });
        presses.push(Press {
            bit: 2,
            start: 6.0,
            end: 6.2,
            bounce: false,
        });
    }
    let mut dropouts: Vec<(f64, f64)> = (0..spec.dropouts)
        .map(|i| {
            let slot = spec.duration_s / f64::from(spec.dropouts + 1);
            let s = slot * f64::from(i + 1) + rng.range(-0.3, 0.3) * slot;
            (s, s + rng.range(0.15, 0.6))
        })
        .collect();
    if spec.dropouts >= 3 {
        // Make sure one press happens while the stick is untracked.
        if let Some(p) = presses.iter().find(|p| p.bit == 0 && p.start > 3.0) {
            dropouts.push((p.start - 0.1, p.end + 0.1));
        }
    }

    // --- tremor and noise parameters ------------------------------------------------------
    let tremor: Vec<(f64, f64, f64)> = [0.08, 0.05, 0.08, 0.05]
        .iter()
        .map(|amp| {
            (
                rng.range(8.0, 12.0),
                rng.range(0.0, std::f64::consts::TAU),
                *amp,
            )
        })
        .collect();
    let sway: Vec<(f64, f64)> = (0..3)
        .map(|_| (rng.range(0.1, 0.25), rng.range(0.0, 6.3)))
        .collect();

    // --- sample the stick -------------------------------------------------------------------
    let defaults = InteractionConfig::default();
    let stick = &defaults.stick;
    let shaped = |a: f64| {
        let m = a.abs();
        if m <= stick.dead_zone {
            0.0
        } else {
            a.signum() * (m - stick.dead_zone) / (1.0 - stick.dead_zone)
        }
    };
    let ramp_frames = (0.12 * spec.rate_hz).round() as usize;
    let deflection = 0.8;
    // FOV change contributed by a ramp-down from full `deflection`, integrated as the state
    // machine does (each sample held for one frame).
    let ramp_down_gain: f64 = (0..ramp_frames)
        .map(|i| {
            stick.gain_deg_per_s
                * shaped(deflection * (1.0 - i as f64 / ramp_frames as f64))
                * frame_dt
        })
        .sum();
    let mut fov = defaults.initial_fov_deg[0];
    let mut sweep_i = 0;
    let mut sweep_state: Option<(f64, f64, usize, bool)> = None; // (sign, target, frame, releasing)
    let mut held_axis = 0.0;
    let mut out = Vec::with_capacity(n);
    let mut phase_i = 0;
    for i in 0..n {
        let t = i as f64 * frame_dt;
        // Direction.
        while phase_i + 1 < phases.len()
            && matches!(phases[phase_i + 1], Phase::Move { start, .. } if start <= t)
        {
            phase_i += 1;
        }
        let d = match phases[phase_i] {
            Phase::Hold { dir } => dir,
            Phase::Move {
                from,
                to,
                start,
                dur,
            } => {
                let s = min_jerk((t - start) / dur);
                DQuat::from_rotation_arc(from, to).slerp(DQuat::IDENTITY, 1.0 - s) * from
            }
        };
        let tr = |j: usize| {
            let (f, ph, a) = tremor[j];
            a.to_radians() * (std::f64::consts::TAU * f * t + ph).sin()
        };
        let yaw = tr(0) + tr(1) + 0.03_f64.to_radians() * rng.gauss();
        let pitch = tr(2) + tr(3) + 0.03_f64.to_radians() * rng.gauss();
        let q = aim(d) * DQuat::from_euler(glam::EulerRot::YXZ, yaw, pitch, 0.0);
        let sw = |j: usize, a: f64| a * (std::f64::consts::TAU * sway[j].0 * t + sway[j].1).sin();
        let pos = HAND
            + DVec3::new(sw(0, 0.01), sw(1, 0.008), sw(2, 0.01))
            + DVec3::new(rng.gauss(), rng.gauss(), rng.gauss()) * 0.15e-3
            + DVec3::new(tr(0), tr(2), 0.0) * 0.3e-3 / 0.08_f64.to_radians();
        let tracked = !dropouts.iter().any(|&(a, b)| (a..b).contains(&t));
        // Buttons.
        let mut buttons = 0u32;
        for p in &presses {
            let mut on = (p.start..p.end).contains(&t);
            if p.bounce {
                let f = ((t - p.start) / frame_dt).floor();
                let g = ((t - p.end) / frame_dt).floor();
                if f == 1.0 || g == 1.0 {
                    on = !on;
                }
            }
            if on {
                buttons |= 1 << p.bit;
            }
        }
        // Stick.
        if sweep_state.is_none() && sweep_i < sweeps.len() && t >= sweeps[sweep_i].0 {
            let target = sweeps[sweep_i].1;
            sweep_state = Some((if target > fov { 1.0 } else { -1.0 }, target, 0, false));
            sweep_i += 1;
        }
        let mut axis = 0.02 * rng.gauss().clamp(-3.0, 3.0);
        if let Some((sign, target, frame, releasing)) = sweep_state.as_mut() {
            let remaining = (*target - fov) * *sign;
            if !*releasing && remaining <= ramp_down_gain {
                *releasing = true;
                *frame = 0;
            }
            let a = if *releasing {
                deflection * (1.0 - *frame as f64 / ramp_frames as f64)
            } else {
                deflection * ((*frame + 1) as f64 / ramp_frames as f64).min(1.0)
            };
            axis = *sign * a;
            *frame += 1;
            if *releasing && *frame > ramp_frames {
                sweep_state = None;
            }
        }
        // Predict the FOV as the state machine will integrate it (previous sample held).
        if i > 0 {
            fov = (fov + stick.gain_deg_per_s * shaped(held_axis) * frame_dt)
                .clamp(defaults.fov_min_deg, defaults.fov_max_deg);
        }
        held_axis = axis;
        // Reset FOV button: the prediction follows.
        if buttons & 2 != 0 {
            fov = defaults.initial_fov_deg[0];
        }
        let mut axes = vec![axis, axis];
        if spec.flystick_plus {
            axes.push(0.02 * rng.gauss().clamp(-3.0, 3.0));
        }
        let axes = axes
            .into_iter()
            .map(|a: f64| (a * 1e6).round() / 1e6)
            .map(|a| a.clamp(-1.0, 1.0))
            .collect();
        out.push(Sample {
            t,
            pose: tracked.then_some(Pose {
                position: pos,
                orientation: q,
            }),
            buttons,
            axes,
        });
    }
    out
}

/// The generator as the shipped sessions' descriptions name it: the module path it had when
/// they were made. The text is part of the files, which must stay byte for byte what this
/// generator makes, so it does not follow the module.
const MADE_BY: &str = "raygun::session::synth";

fn header(spec: &SessionSpec, device: DeviceId, form: &str) -> ReplayHeader {
    let mut h = ReplayHeader::new(format!(
        "SYNTHETIC session `{}` ({form}), made by {MADE_BY} (seed {}): {} s at {} Hz, \
         {}, targets {:?}, {} dropouts. Not recorded from a person.",
        spec.name,
        spec.seed,
        spec.duration_s,
        spec.rate_hz,
        if spec.flystick_plus {
            "FlyStick2+ (8 buttons, 3 axes)"
        } else {
            "FlyStick2 (6 buttons, 2 axes)"
        },
        spec.targets,
        spec.dropouts
    ));
    h.synthetic = true;
    h.display = Some("display-models/hornet.json".into());
    h.device = Some(device);
    if spec.head_walk {
        h.description.push_str(
            " A tracked head walks (right, in, left and out, back; one untracked interval): the header's `head`.",
        );
    }
    h
}

/// The tracker-frame form of a room pose (millimetres, tracker rotation).
fn to_tracker(pose: &Pose, t: &TrackerToRoom) -> (DVec3, DMat3) {
    let r = t.rotation();
    let p =
        r.transpose() * (pose.position - DVec3::from_array(t.translation_m)) / t.metres_per_unit;
    (p, r.transpose() * DMat3::from_quat(pose.orientation))
}

/// The DTrack form of a session as replay text.
pub fn dtrack_replay(spec: &SessionSpec, samples: &[Sample]) -> io::Result<Vec<u8>> {
    let to_room = session_tracker_to_room();
    let mut h = header(
        spec,
        DeviceId::new(DeviceKind::Flystick, 0),
        "raw DTrack ASCII",
    );
    h.dtrack = Some(DtrackConfig {
        tracker_to_room: to_room.clone(),
        ..DtrackConfig::default()
    });
    if spec.head_walk {
        h.head = Some(head_header(DeviceId::new(DeviceKind::Body, HEAD_BODY)));
    }
    let mut w = ReplayWriter::new(Vec::new(), &h)?;
    let eol = if spec.crlf { "\r\n" } else { "\n" };
    let (nb, seconds0) = (if spec.flystick_plus { 8 } else { 6 }, spec.ts_start);
    let head = Pose {
        position: EYE + DVec3::new(0.0, 0.05, 0.0),
        orientation: DQuat::IDENTITY,
    };
    let mut head_rng = Rng::new(spec.seed ^ 0x4EAD);
    for (i, s) in samples.iter().enumerate() {
        let mut text = String::with_capacity(400);
        let _ = write!(text, "fr {}{eol}", 1000 + i);
        let ts = seconds0 + s.t;
        if spec.ts2 {
            let unix = 1_795_000_000.0 + ts;
            let _ = write!(
                text,
                "ts2 {} {}{eol}",
                unix.floor() as u64,
                ((unix - unix.floor()) * 1e6).round().min(999_999.0) as u32
            );
        } else {
            let _ = write!(text, "ts {:.6}{eol}", ts % 86_400.0);
        }
        let _ = write!(
            text,
            "6dcal {}{eol}",
            if spec.extra_devices || spec.head_walk {
                4
            } else {
                1
            }
        );
        if spec.head_walk {
            let block = match head_pose(s.t, &mut head_rng) {
                Some(p) => {
                    let (p, r) = to_tracker(&p, &to_room);
                    let rc: Vec<String> = r
                        .to_cols_array()
                        .iter()
                        .map(|v| format!("{v:.6}"))
                        .collect();
                    format!(
                        "[{HEAD_BODY} 0.980][{:.3} {:.3} {:.3}][{}]",
                        p.x,
                        p.y,
                        p.z,
                        rc.join(" ")
                    )
                }
                None => format!(
                    "[{HEAD_BODY} -1.000][0.000 0.000 0.000][0.000000 0.000000 0.000000 0.000000 0.000000 0.000000 0.000000 0.000000 0.000000]"
                ),
            };
            let _ = write!(text, "6d 1 {block}{eol}");
        }
        if spec.extra_devices {
            let (p, r) = to_tracker(&head, &to_room);
            let rc = r.to_cols_array();
            let _ = write!(
                text,
                "6d 1 [3 0.980][{:.3} {:.3} {:.3}][{}]{eol}",
                p.x,
                p.y,
                p.z,
                rc.iter()
                    .map(|v| format!("{v:.6}"))
                    .collect::<Vec<_>>()
                    .join(" ")
            );
        }
        let pose = s.pose.as_ref().map(|p| to_tracker(p, &to_room));
        let stick = format_flystick_block(0, pose, nb, s.buttons, &s.axes);
        if spec.extra_devices {
            let other = format_flystick_block(1, None, nb, 0, &vec![0.0; s.axes.len()]);
            let _ = write!(text, "6df2 2 2 {stick} {other}{eol}");
        } else {
            let _ = write!(text, "6df2 1 1 {stick}{eol}");
        }
        w.datagram(s.t, Protocol::Dtrack, text.as_bytes())?;
    }
    Ok(w.into_inner())
}

/// OSC bundles carry the session time as NTP seconds from this base (2025-12-31 or so), so
/// their time tags look like a real sender's.
pub const OSC_TIME_BASE: f64 = 3_976_000_000.0;

/// The OSC form of a session as replay text.
pub fn osc_replay(spec: &SessionSpec, samples: &[Sample]) -> io::Result<Vec<u8>> {
    let mut h = header(
        spec,
        DeviceId::new(DeviceKind::Osc, 0),
        "OSC bundles, raygun address space",
    );
    if spec.head_walk {
        h.head = Some(head_header(DeviceId::new(DeviceKind::Osc, HEAD_OSC)));
    }
    let mut w = ReplayWriter::new(Vec::new(), &h)?;
    let mut head_rng = Rng::new(spec.seed ^ 0x4EAD);
    for s in samples {
        let mut content = vec![match &s.pose {
            Some(p) => encode::pose(0, p),
            None => encode::lost(0),
        }];
        if spec.head_walk {
            content.push(match head_pose(s.t, &mut head_rng) {
                Some(p) => encode::pose(HEAD_OSC, &p),
                None => encode::lost(HEAD_OSC),
            });
        }
        content.push(encode::buttons(0, s.buttons));
        content.push(encode::axes(0, &s.axes));
        let b = encode::bundle(OSC_TIME_BASE + s.t, content);
        w.datagram(s.t, Protocol::Osc, &encode::bytes(&b))?;
    }
    Ok(w.into_inner())
}

/// The mouse session on the desktop stand-in, as normalised events: min-jerk pointer moves
/// between targets, clicks with no bounce (the OS debounces mice).
pub fn mouse_replay() -> io::Result<Vec<u8>> {
    let mut rng = Rng::new(77);
    let device = DeviceId::new(DeviceKind::Mouse, 0);
    let mut h = ReplayHeader::new(format!(
        "SYNTHETIC mouse session on display-models/desktop-27in-4k.json (27-inch 3840x2160), made by \
         {MADE_BY}: 12 s at 60 Hz, min-jerk pointer moves, 8 clicks. Not recorded from a person."
    ));
    h.synthetic = true;
    h.display = Some("display-models/desktop-27in-4k.json".into());
    h.device = Some(device);
    let mut w = ReplayWriter::new(Vec::new(), &h)?;
    let size = HingedWall::desktop().canvas_size();
    let mut from = size / 2.0;
    let mut segments = Vec::new();
    let mut t = 0.3;
    for _ in 0..8 {
        let to = DVec2::new(
            rng.range(0.05, 0.95) * size.x,
            rng.range(0.05, 0.95) * size.y,
        );
        let dur = 0.25 + 0.1 * (1.0 + from.distance(to) / 40.0).log2();
        let click = t + dur + rng.range(0.1, 0.3);
        segments.push((t, dur, from, to, click));
        t = click + 0.2;
        from = to;
    }
    let n = (12.0 * 60.0) as usize;
    for i in 0..n {
        let t = i as f64 / 60.0;
        let mut pos = segments[0].2;
        let mut buttons = 0;
        for &(start, dur, a, b, click) in &segments {
            if t >= start {
                pos = a.lerp(b, min_jerk((t - start) / dur));
            }
            if (click..click + 0.1).contains(&t) {
                buttons = 1;
            }
        }
        let pos = DVec2::new((pos.x * 8.0).round() / 8.0, (pos.y * 8.0).round() / 8.0);
        let e = TrackingEvent {
            buttons: Some(buttons),
            canvas: Some(pos),
            ..TrackingEvent::empty(t, device)
        };
        w.event(t, &e)?;
    }
    Ok(w.into_inner())
}

/// Every shipped replay: (file name, contents).
pub fn all_replays() -> io::Result<Vec<(String, Vec<u8>)>> {
    let mut v = Vec::new();
    for spec in flystick_sessions().into_iter().chain(head_sessions()) {
        let samples = simulate(&spec);
        v.push((
            format!("{}.dtrack.jsonl", spec.name),
            dtrack_replay(&spec, &samples)?,
        ));
        v.push((
            format!("{}.osc.jsonl", spec.name),
            osc_replay(&spec, &samples)?,
        ));
    }
    v.push(("mouse-1-desktop.events.jsonl".to_owned(), mouse_replay()?));
    Ok(v)
}

/// Writes every shipped replay into `dir`.
pub fn write_all(dir: &Path) -> io::Result<Vec<PathBuf>> {
    crate::output::check_folder(dir).map_err(io::Error::other)?;
    all_replays()?
        .into_iter()
        .map(|(name, bytes)| {
            let p = dir.join(name);
            crate::output::write_bytes(&p, &bytes).map_err(io::Error::other)?;
            Ok(p)
        })
        .collect()
}

/// Whether the ray of a sample's pose hits the wall (used by tests of the generator).
#[must_use]
pub fn sample_hits_wall(s: &Sample) -> bool {
    s.pose.is_some_and(|p| {
        HingedWall::hornet()
            .hit(p.position, p.orientation * DVec3::NEG_Z)
            .is_some()
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rng_is_deterministic_and_roughly_uniform_and_normal() {
        let a: Vec<u64> = {
            let mut r = Rng::new(9);
            (0..5).map(|_| r.next_u64()).collect()
        };
        let b: Vec<u64> = {
            let mut r = Rng::new(9);
            (0..5).map(|_| r.next_u64()).collect()
        };
        assert_eq!(a, b);
        let mut r = Rng::new(1);
        let n = 20_000;
        let (mut s, mut s2, mut u) = (0.0, 0.0, 0.0);
        for _ in 0..n {
            let g = r.gauss();
            s += g;
            s2 += g * g;
            u += r.unit();
        }
        let n = f64::from(n);
        // Mean of n normals has σ = 1/√n ≈ 0.007; 5σ bounds.
        assert!((s / n).abs() < 0.036);
        assert!((s2 / n - 1.0).abs() < 0.05);
        assert!((u / n - 0.5).abs() < 0.011);
    }

    #[test]
    fn min_jerk_profile_starts_and_ends_at_rest() {
        assert_eq!(min_jerk(0.0), 0.0);
        assert_eq!(min_jerk(1.0), 1.0);
        assert!((min_jerk(0.5) - 0.5).abs() < 1e-15);
        // Zero velocity at both ends: finite difference ~ h².
        let h = 1e-4;
        assert!(min_jerk(h) < 1e-10 && 1.0 - min_jerk(1.0 - h) < 1e-10);
    }

    #[test]
    fn aim_points_minus_z_along_the_direction_without_roll() {
        let d = DVec3::new(0.3, -0.2, -1.0).normalize();
        let q = aim(d);
        assert!((q * DVec3::NEG_Z - d).length() < 1e-12);
        assert!((q * DVec3::X).y.abs() < 1e-12);
    }

    #[test]
    fn sessions_contain_what_the_model_promises() {
        for spec in flystick_sessions() {
            let s = simulate(&spec);
            assert_eq!(s.len(), (spec.duration_s * spec.rate_hz).round() as usize);
            let lost = s.iter().filter(|x| x.pose.is_none()).count();
            assert!(lost > 0, "{}: no dropout", spec.name);
            let presses = s
                .windows(2)
                .filter(|w| w[1].buttons & 1 != 0 && w[0].buttons & 1 == 0)
                .count();
            assert!(presses >= 5, "{}: {presses} trigger edges", spec.name);
            assert!(s.iter().all(|x| x.pose.is_none_or(|p| p.is_valid())));
            assert!(
                s.iter()
                    .all(|x| x.axes.iter().all(|a| (-1.0..=1.0).contains(a)))
            );
            let hits = s.iter().filter(|x| sample_hits_wall(x)).count();
            assert!(
                hits > s.len() / 2,
                "{}: stick mostly off the wall",
                spec.name
            );
        }
    }

    #[test]
    fn tremor_shows_up_in_the_8_to_12_hz_band() {
        // Yaw of the stick while holding still, projected on 10 Hz vs 3 Hz probes: the tremor
        // band must dominate.
        let spec = &flystick_sessions()[0];
        let s = simulate(spec);
        let yaw: Vec<f64> = s[..25]
            .iter()
            .map(|x| {
                let d = x.pose.unwrap().orientation * DVec3::NEG_Z;
                d.x.atan2(-d.z)
            })
            .collect();
        let mean = yaw.iter().sum::<f64>() / yaw.len() as f64;
        let power = |f: f64| {
            let (mut c, mut sn) = (0.0, 0.0);
            for (i, y) in yaw.iter().enumerate() {
                let a = std::f64::consts::TAU * f * i as f64 / spec.rate_hz;
                c += (y - mean) * a.cos();
                sn += (y - mean) * a.sin();
            }
            c * c + sn * sn
        };
        let band = (8..=12).map(|f| power(f64::from(f))).fold(0.0, f64::max);
        assert!(
            band > 3.0 * power(3.0),
            "band {band} vs 3 Hz {}",
            power(3.0)
        );
    }

    #[test]
    fn the_head_walks_past_the_threshold_and_sways_below_it() {
        // Standing: the sway stays within 1 cm of the start.
        for i in 0..180 {
            let e = head_eye(f64::from(i) / 60.0).unwrap();
            assert!(e.distance(EYE) < 0.005, "{e}");
        }
        assert!(head_eye(4.5).unwrap().distance(EYE) > 0.3);
        assert!(head_eye(13.7).is_none());
        assert!(head_eye(19.0).unwrap().distance(EYE) < 0.005);
        // Every eye is in front of every HORNET tile (z ≥ 0.7 m, within the wall's width).
        for i in 0..1200 {
            if let Some(e) = head_eye(f64::from(i) / 60.0) {
                assert!(e.z >= 0.7 && e.x.abs() < 0.5, "{e}");
            }
        }
        let mut rng = Rng::new(1);
        let p = head_pose(5.0, &mut rng).unwrap();
        let eye = p.position + p.orientation * DVec3::from_array(HEAD_EYE_OFFSET_M);
        assert!(eye.distance(head_eye(5.0).unwrap()) < 1e-3);
    }

    #[test]
    fn generator_is_deterministic() {
        let spec = &flystick_sessions()[3];
        assert_eq!(simulate(spec), simulate(spec));
    }
}
