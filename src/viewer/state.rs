//! The viewer panel's settings and what they mean for the renderer ([`ViewerState`]).

use glam::{DVec2, DVec3};

use crate::display::DisplayModel;
use crate::filter::{DenoiseKind, FilterKind, FilterParams};
use crate::frame::GuideConfig;
use crate::interaction::{CursorMark, CursorSmoother, RoiState};
use crate::roi::dgi::{Falloff, Metric, Roi};
use crate::schedule::Order;

use crate::session::timeline::Timeline;

use super::ViewerError;
use super::orbit::{Gesture, Orbit};

/// Where the ROI comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RoiSource {
    /// A click on the image; its size from the panel.
    Mouse,
    /// A replay, played / paused / scrubbed in the panel.
    Replay,
    /// Live DTrack or OSC traffic.
    Live,
}

/// What the image shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Overlay {
    /// The (filtered) render.
    Image,
    /// The distance-guide image, d in [0, 1] as grey.
    Dgi,
    /// Samples per pixel as a heat map (0 black … most samples white).
    Counts,
    /// The standard error of each pixel's mean luminance ([`noise_image`](super::diagnostics::noise_image)) as grey, scaled so
    /// the 99th percentile is white; pixels with fewer than two samples (undefined) dark blue.
    Noise,
}

/// How long the ROI and the eye stay still before the viewer shows OIDN's picture (with
/// `denoise` = `oidn`): the paper's "static viewpoint".
pub const STILL_SECONDS: f64 = 1.0;

/// Every setting of the panel.
#[derive(Clone, Debug, PartialEq)]
pub struct ViewerState {
    pub source: RoiSource,
    /// Centre of the mouse ROI, canvas pixels.
    pub mouse_centre: Option<DVec2>,
    /// Radius of the (circular) mouse ROI, canvas pixels.
    pub mouse_radius_px: f64,
    pub falloff_base_m: f64,
    pub falloff_scale: f64,
    pub p_min: f32,
    pub metric: Metric,
    pub order: Order,
    pub filter: FilterParams,
    /// What denoises the shown picture (DESIGN.md §8): off, raygun's interactive denoiser, or
    /// `oidn` — the interactive denoiser while anything moves and OIDN's picture once the ROI
    /// and the eye have been still for [`STILL_SECONDS`] (where OIDN was opened).
    pub denoise: DenoiseKind,
    pub max_depth: u32,
    pub overlay: Overlay,
    pub roi_outline: bool,
    /// Show the canvas as the wall shows it (pixels behind bezels black).
    pub wall_view: bool,
    pub exposure: f32,
    /// A full opening angle (degrees, both axes) replacing the tracked ROI's own (the stick's).
    pub fov_override_deg: Option<f64>,
    /// Replay clock, seconds, and whether it runs.
    pub replay_t: f64,
    pub playing: bool,
    /// The latest tracked ROI (replay or live) and the ray gun's raw aim, canvas pixels.
    pub tracked: Option<RoiState>,
    pub aim: Option<DVec2>,
    /// The drawn cursor: the aim smoothed over the events' times (the ROI keeps the raw pose
    /// of the trigger press), and the replay time up to which it has been fed.
    pub cursor: CursorSmoother,
    cursor_fed_t: Option<f64>,
    /// Set by the "reset accumulation" button; cleared when the renderer has been rebuilt.
    pub reset: bool,
    /// The ROI's target standard error (`view --target-se`): the panel shows the time to it.
    pub target_se: Option<f64>,
    /// The desktop user's viewpoint (orbit, pan, dolly): the wall camera's eye (room frame)
    /// or the pinhole camera (scene frame); set up by the core when `None`.
    pub view: Option<Orbit>,
    /// The tracked head's eye (room frame, metres; replay or live), and whether the wall
    /// camera follows it (a desktop gesture stops that; the panel turns it back on).
    pub head: Option<DVec3>,
    pub follow_head: bool,
    /// The restart rule's threshold (`--eye-threshold`): the accumulation restarts when the
    /// eye (or the pinhole) moves more than this many metres from where it started (a pinhole
    /// also when it turns by more than this many radians).
    pub eye_threshold_m: f64,
    /// What a move past the threshold does to the accumulation (`--on-eye-move`).
    pub on_eye_move: crate::frame::EyeMove,
}

impl ViewerState {
    /// The defaults of `render` (guide and filter) with a mouse ROI of 600 canvas pixels
    /// (about 32 cm on HORNET) not yet placed.
    #[must_use]
    pub fn new(source: RoiSource, max_depth: u32) -> Self {
        let falloff = Falloff::default();
        Self {
            source,
            mouse_centre: None,
            mouse_radius_px: 600.0,
            falloff_base_m: falloff.base_m,
            falloff_scale: falloff.scale,
            p_min: 0.0,
            metric: Metric::Exact,
            order: Order::Coherent,
            filter: FilterParams::default(),
            denoise: DenoiseKind::Off,
            max_depth,
            overlay: Overlay::Image,
            roi_outline: true,
            wall_view: false,
            exposure: 0.0,
            fov_override_deg: None,
            replay_t: 0.0,
            playing: true,
            tracked: None,
            aim: None,
            cursor: CursorSmoother::new(crate::interaction::CursorConfig::default()),
            cursor_fed_t: None,
            reset: false,
            target_se: None,
            view: None,
            head: None,
            follow_head: true,
            eye_threshold_m: crate::tracking::head::DEFAULT_EYE_THRESHOLD_M,
            on_eye_move: crate::frame::EyeMove::Restart,
        }
    }

    /// A desktop gesture moves the viewpoint (and stops following a tracked head).
    pub fn gesture(&mut self, g: Gesture) {
        if let Some(v) = &mut self.view {
            v.apply(g);
            self.follow_head = false;
        }
    }

    /// The wall camera's eye the state asks for: the tracked head's while following it, else
    /// the desktop viewpoint's.
    #[must_use]
    pub fn wanted_eye(&self) -> Option<DVec3> {
        match (self.follow_head, self.head) {
            (true, Some(h)) => Some(h),
            _ => self.view.as_ref().map(Orbit::position),
        }
    }

    /// A click at image pixel `image_px` (centres at `i + 0.5`) of a `size` image: centres the
    /// mouse ROI there (canvas coordinates) and makes the mouse the ROI source.
    pub fn click(&mut self, model: &DisplayModel, image_px: DVec2, size: [u32; 2]) {
        self.mouse_centre = Some(model.image_to_canvas(image_px, size));
        self.source = RoiSource::Mouse;
    }

    /// The ROI the renderer should use.
    #[must_use]
    pub fn roi(&self) -> Option<Roi> {
        match self.source {
            RoiSource::Mouse => self.mouse_centre.map(|c| Roi::CanvasEllipse {
                center: c,
                semi_axes: DVec2::splat(self.mouse_radius_px),
            }),
            RoiSource::Replay | RoiSource::Live => {
                let mut r = self.tracked.clone()?;
                if let Some(f) = self.fov_override_deg {
                    r.fov_deg = [f, f];
                }
                r.to_roi().ok().flatten()
            }
        }
    }

    /// The guide configuration the renderer gets (errors name the bad setting).
    pub fn guide_config(&self) -> Result<GuideConfig, ViewerError> {
        crate::schedule::validate_p_min(self.p_min)?;
        Ok(GuideConfig {
            metric: self.metric,
            falloff: Falloff::new(self.falloff_base_m, self.falloff_scale)?,
            p_min: self.p_min,
            order: self.order,
        })
    }

    /// The filter the picture uses: the panel's, off while a tracked device has toggled the
    /// filter off.
    #[must_use]
    pub fn filter_params(&self) -> FilterParams {
        let tracked_off =
            self.source != RoiSource::Mouse && self.tracked.as_ref().is_some_and(|r| !r.filter);
        FilterParams {
            kind: if tracked_off {
                FilterKind::Off
            } else {
                self.filter.kind
            },
            ..self.filter
        }
    }

    /// Takes live tracking's news: the ROI when it changed, the aim samples into the cursor
    /// and the latest aim.
    pub fn apply_live(&mut self, update: crate::session::live::LiveUpdate) {
        if let Some(roi) = update.roi {
            self.tracked = roi;
        }
        for &(t, aim) in &update.aim {
            self.cursor.observe(t, aim);
        }
        if let Some(&(_, aim)) = update.aim.last() {
            self.aim = aim;
        }
        if let Some(eye) = update.eye {
            self.head = Some(eye);
        }
    }

    /// Advances the replay clock by `dt` seconds while playing (stops at the end).
    pub fn advance(&mut self, dt: f64, timeline: &Timeline) {
        if self.playing {
            self.replay_t = (self.replay_t + dt).min(timeline.duration);
            if self.replay_t >= timeline.duration {
                self.playing = false;
            }
        }
        self.tracked = timeline.roi_at(self.replay_t).cloned();
        self.aim = timeline.aim_at(self.replay_t);
        if let Some(eye) = timeline.eye_at(self.replay_t) {
            self.head = Some(eye);
        }
        self.feed_cursor(timeline);
    }

    /// Feeds the cursor the replay's aim samples up to the replay clock: those since the last
    /// call, or, after a scrub back or a jump ahead, the [`CURSOR_WARM_UP_S`] before the clock
    /// into a fresh filter.
    fn feed_cursor(&mut self, timeline: &Timeline) {
        let t = self.replay_t;
        let from = match self.cursor_fed_t {
            Some(fed) if fed <= t && t - fed <= self.cursor.config.stale_after_s => fed,
            _ => {
                self.cursor.reset();
                t - CURSOR_WARM_UP_S
            }
        };
        for &(ts, aim) in timeline.aim_after(from, t) {
            self.cursor.observe(ts, aim);
        }
        self.cursor_fed_t = Some(t);
    }

    /// The cursor to draw at display time `t` (replay: the replay clock; live: the events'
    /// clock now); `None` before the device was first seen on the wall.
    #[must_use]
    pub fn cursor_mark(&self, t: f64) -> Option<CursorMark> {
        self.cursor.at(t)
    }
}

/// How much of a replay a scrubbed cursor replays to settle its filter, seconds (several time
/// constants of the 1 Hz resting cutoff: 1/(2π·1 Hz) = 0.16 s).
pub const CURSOR_WARM_UP_S: f64 = 1.0;
