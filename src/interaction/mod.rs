//! The interaction state machine (DESIGN.md §4): device events → ROI changes.
//!
//! * A press of the button mapped to [`Action::Shoot`] freezes the device pose into a cone
//!   (apex O, axis D, horizontal/vertical axes R, U); the ROI centre is the first hit of the
//!   ray (O, D) on the display. A press while the ray misses, or while the device is not
//!   tracked, leaves the ROI unchanged and is reported ([`ChangeCause::Miss`],
//!   [`ChangeCause::Untracked`]).
//! * A mouse (device kind `mouse`) shoots at its canvas pointer instead; its ROI is an ellipse
//!   on the canvas with semi-axes from the configuration (DESIGN.md §4: no viewer distance).
//! * The stick changes the horizontal and vertical FOV by rate control ([`config`]).
//!
//! Everything is driven by event times, never the wall clock, so a replay gives the same ROI
//! sequence however fast it is played.
//!
//! [`synth`] runs the other way: a simulated person aiming the FlyStick (or a mouse) at the wall
//! under this stage's own mapping, written as the trackers would send it — the synthetic
//! sessions of `tracking-replays/` (`raygun synth-replays`). It needs this stage's wall and
//! stick mapping, so it lives here and not with the parsers it writes for.

pub mod config;
pub mod cursor;
pub mod surface;
pub mod synth;

use glam::{DVec2, DVec3};
use serde::Serialize;

pub use config::{Action, InteractionConfig};
pub use cursor::{CursorConfig, CursorMark, CursorSmoother};
pub use surface::{HingedWall, RaySurface, SurfaceHit};

use crate::tracking::event::{DeviceKind, Pose, Tracking, TrackingEvent};

/// The device's frame frozen by a shot (room frame, unit vectors): the apex and axes of the
/// ray-gun cone. Its opening comes from the current FOV, which the stick keeps changing;
/// [`RoiState::to_roi`] combines the two into a [`crate::roi::cone::Cone`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShotFrame {
    pub apex: DVec3,
    pub axis: DVec3,
    pub right: DVec3,
    pub up: DVec3,
}

/// Where the ROI is centred.
#[derive(Clone, Debug, PartialEq)]
pub struct RoiCentre {
    pub point: DVec3,
    pub canvas_px: DVec2,
    pub image_px: DVec2,
    pub tile_id: String,
}

/// The ROI as the rest of the pipeline needs it: one immutable snapshot per change.
#[derive(Clone, Debug, PartialEq)]
pub struct RoiState {
    /// `None` before the first shot, and for mouse ROIs.
    pub cone: Option<ShotFrame>,
    /// `None` before the first successful shot.
    pub centre: Option<RoiCentre>,
    /// Full opening angles (horizontal, vertical), degrees.
    pub fov_deg: [f64; 2],
    /// Semi-axes of a mouse ROI on the canvas, pixels.
    pub ellipse_px: Option<[f64; 2]>,
    /// Whether the sparse-sample filter is on.
    pub filter: bool,
}

impl RoiState {
    /// The region the DGI stage measures distances to: the frozen cone with the current FOV
    /// (ray gun), or the canvas ellipse (mouse); `None` before the first shot or click.
    pub fn to_roi(&self) -> Result<Option<crate::roi::dgi::Roi>, crate::roi::cone::ConeError> {
        use crate::roi::dgi::Roi;
        if let (Some(centre), Some([a, b])) = (&self.centre, self.ellipse_px) {
            return Ok(Some(Roi::CanvasEllipse {
                center: centre.canvas_px,
                semi_axes: DVec2::new(a, b),
            }));
        }
        let (Some(cone), Some(_)) = (&self.cone, &self.centre) else {
            return Ok(None);
        };
        crate::roi::cone::Cone::from_pose(
            cone.apex,
            cone.axis,
            cone.up,
            self.fov_deg[0],
            self.fov_deg[1],
        )
        .map(|c| Some(Roi::Cone(c)))
    }
}

/// Why a change was reported.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum ChangeCause {
    Shoot,
    Fov,
    ResetFov,
    ToggleFilter,
    /// A shot whose ray missed the display: the ROI is unchanged.
    Miss,
    /// A shot while the device was not tracked: the ROI is unchanged.
    Untracked,
}

/// One ROI change (or a reported failed shot).
#[derive(Clone, Debug, PartialEq)]
pub struct RoiChange {
    pub t: f64,
    pub cause: ChangeCause,
    pub roi: RoiState,
}

/// The printed form of a change (`raygun replay`): rounded so that golden files do not depend
/// on the last bits of libm.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct RoiReport {
    /// Seconds since the first event of the session.
    pub t: f64,
    pub kind: ChangeCause,
    pub centre_canvas_px: Option<[f64; 2]>,
    pub centre_image_px: Option<[f64; 2]>,
    pub fov_deg: [f64; 2],
    pub tile: Option<String>,
    pub filter: bool,
}

/// `v` rounded to `decimals` places, as the f64 nearest that decimal (so it prints short).
fn round_to(v: f64, decimals: usize) -> f64 {
    let r: f64 = format!("{v:.decimals$}").parse().unwrap_or(v);
    // Avoid printing "-0.0".
    if r == 0.0 { 0.0 } else { r }
}

impl RoiChange {
    /// The printed form, with times relative to `t_origin`.
    #[must_use]
    pub fn report(&self, t_origin: f64) -> RoiReport {
        let px = |v: DVec2| [round_to(v.x, 3), round_to(v.y, 3)];
        RoiReport {
            t: round_to(self.t - t_origin, 6),
            kind: self.cause,
            centre_canvas_px: self.roi.centre.as_ref().map(|c| px(c.canvas_px)),
            centre_image_px: self.roi.centre.as_ref().map(|c| px(c.image_px)),
            fov_deg: self.roi.fov_deg.map(|f| round_to(f, 4)),
            tile: self.roi.centre.as_ref().map(|c| c.tile_id.clone()),
            filter: self.roi.filter,
        }
    }
}

/// The state machine.
#[derive(Clone, Debug)]
pub struct Interaction {
    config: InteractionConfig,
    roi: RoiState,
    pose: Option<Pose>,
    pointer: Option<DVec2>,
    /// Debounced button state and the time of each button's last accepted edge.
    buttons: u32,
    last_edge: [f64; 32],
    /// Last stick sample and its time (zero-order hold between samples).
    axes: Vec<f64>,
    axes_t: Option<f64>,
}

impl Interaction {
    /// A state machine for a validated configuration.
    #[must_use]
    pub fn new(config: InteractionConfig) -> Self {
        let roi = RoiState {
            cone: None,
            centre: None,
            fov_deg: config.initial_fov_deg,
            ellipse_px: None,
            filter: true,
        };
        Self {
            config,
            roi,
            pose: None,
            pointer: None,
            buttons: 0,
            last_edge: [f64::NEG_INFINITY; 32],
            axes: Vec::new(),
            axes_t: None,
        }
    }

    #[must_use]
    pub fn roi(&self) -> &RoiState {
        &self.roi
    }

    #[must_use]
    pub fn config(&self) -> &InteractionConfig {
        &self.config
    }

    fn emit(&self, t: f64, cause: ChangeCause, out: &mut Vec<RoiChange>) {
        out.push(RoiChange {
            t,
            cause,
            roi: self.roi.clone(),
        });
    }

    /// Deflection after the dead zone, rescaled to [−1, 1].
    fn shaped(&self, a: f64) -> f64 {
        let dz = self.config.stick.dead_zone;
        let m = a.abs().min(1.0);
        if m <= dz {
            0.0
        } else {
            a.signum() * (m - dz) / (1.0 - dz)
        }
    }

    fn clamp_fov(&self, f: f64) -> f64 {
        f.clamp(self.config.fov_min_deg, self.config.fov_max_deg)
    }

    /// Feeds one event; changes it causes are appended to `out`. Events of other devices and
    /// invalid events are ignored.
    pub fn handle(
        &mut self,
        e: &TrackingEvent,
        surface: &dyn RaySurface,
        out: &mut Vec<RoiChange>,
    ) {
        if e.device != self.config.device || !e.is_valid() {
            return;
        }
        match e.pose {
            Some(Tracking::Tracked(p)) => self.pose = Some(p),
            Some(Tracking::Lost) => self.pose = None,
            None => {}
        }
        if let Some(c) = e.canvas {
            self.pointer = Some(c);
        }
        if let Some(axes) = &e.axes {
            self.stick(e.t, axes, out);
        }
        if let Some([h, v]) = e.fov_deg {
            let fov = [self.clamp_fov(h), self.clamp_fov(v)];
            if fov != self.roi.fov_deg {
                self.roi.fov_deg = fov;
                self.emit(e.t, ChangeCause::Fov, out);
            }
        }
        if let Some(raw) = e.buttons {
            self.buttons(e.t, raw, surface, out);
        }
    }

    fn stick(&mut self, t: f64, axes: &[f64], out: &mut Vec<RoiChange>) {
        if let Some(t_prev) = self.axes_t {
            let s = &self.config.stick;
            let dt = (t - t_prev).clamp(0.0, s.max_step_s);
            let held = |i: usize| self.axes.get(i).copied().unwrap_or(0.0);
            let rate = [
                s.signs[0] * s.gain_deg_per_s * self.shaped(held(s.horizontal_axis)),
                s.signs[1] * s.gain_deg_per_s * self.shaped(held(s.vertical_axis)),
            ];
            let fov = [
                self.clamp_fov(self.roi.fov_deg[0] + rate[0] * dt),
                self.clamp_fov(self.roi.fov_deg[1] + rate[1] * dt),
            ];
            if fov != self.roi.fov_deg {
                self.roi.fov_deg = fov;
                self.emit(t, ChangeCause::Fov, out);
            }
        }
        self.axes.clear();
        self.axes.extend_from_slice(axes);
        self.axes_t = Some(t);
    }

    fn buttons(&mut self, t: f64, raw: u32, surface: &dyn RaySurface, out: &mut Vec<RoiChange>) {
        let changed = raw ^ self.buttons;
        for bit in 0..32 {
            if changed & (1 << bit) == 0 || t - self.last_edge[bit] < self.config.debounce_s {
                continue;
            }
            self.last_edge[bit] = t;
            self.buttons ^= 1 << bit;
            let pressed = raw & (1 << bit) != 0;
            if let (true, Some(action)) = (pressed, self.config.buttons.get(&(bit as u32))) {
                self.act(t, *action, surface, out);
            }
        }
    }

    fn act(&mut self, t: f64, action: Action, surface: &dyn RaySurface, out: &mut Vec<RoiChange>) {
        match action {
            Action::Shoot => self.shoot(t, surface, out),
            Action::ResetFov => {
                self.roi.fov_deg = self.config.initial_fov_deg;
                self.emit(t, ChangeCause::ResetFov, out);
            }
            Action::ToggleFilter => {
                self.roi.filter = !self.roi.filter;
                self.emit(t, ChangeCause::ToggleFilter, out);
            }
        }
    }

    fn centre_of(&self, hit: &SurfaceHit, surface: &dyn RaySurface) -> RoiCentre {
        RoiCentre {
            point: hit.point,
            canvas_px: hit.canvas_px,
            image_px: surface.canvas_to_image(hit.canvas_px, self.config.image_size),
            tile_id: hit.tile_id.clone(),
        }
    }

    fn shoot(&mut self, t: f64, surface: &dyn RaySurface, out: &mut Vec<RoiChange>) {
        if self.config.device.kind == DeviceKind::Mouse {
            match self.pointer.and_then(|c| surface.locate(c)) {
                Some(hit) => {
                    self.roi.centre = Some(self.centre_of(&hit, surface));
                    self.roi.cone = None;
                    self.roi.ellipse_px = Some(self.config.mouse_ellipse_px);
                    self.emit(t, ChangeCause::Shoot, out);
                }
                None => self.emit(t, ChangeCause::Miss, out),
            }
            return;
        }
        let Some(pose) = self.pose else {
            self.emit(t, ChangeCause::Untracked, out);
            return;
        };
        let (d, r, u) = self.config.axes();
        let q = pose.orientation;
        let cone = ShotFrame {
            apex: pose.position,
            axis: q * d,
            right: q * r,
            up: q * u,
        };
        match surface.hit(cone.apex, cone.axis) {
            Some(hit) => {
                self.roi.centre = Some(self.centre_of(&hit, surface));
                self.roi.cone = Some(cone);
                self.roi.ellipse_px = None;
                self.emit(t, ChangeCause::Shoot, out);
            }
            None => self.emit(t, ChangeCause::Miss, out),
        }
    }
}

#[cfg(test)]
mod tests;
