//! The mapping from device input to interaction, loaded from JSON.
//!
//! Defaults (every field may be left out of the file):
//!
//! ```json
//! {
//!   "device": "flystick:0",
//!   "pointing_axis": [0, 0, -1], "right_axis": [1, 0, 0], "up_axis": [0, 1, 0],
//!   "initial_fov_deg": [30, 30], "fov_min_deg": 5, "fov_max_deg": 90,
//!   "stick": { "horizontal_axis": 0, "vertical_axis": 1, "dead_zone": 0.15,
//!              "gain_deg_per_s": 40, "signs": [1, 1], "max_step_s": 0.1 },
//!   "buttons": { "0": "shoot", "1": "reset_fov", "2": "toggle_filter" },
//!   "debounce_s": 0.03,
//!   "image_size": [3840, 2160],
//!   "mouse_ellipse_px": [400, 300],
//!   "cursor": { "smooth": true, "min_cutoff_hz": 1.0, "beta": 0.005, "d_cutoff_hz": 1.0,
//!               "max_extrapolation_s": 0.02, "stale_after_s": 0.25 },
//!   "calibration": "lab-calibration.json"
//! }
//! ```
//!
//! * `calibration` (no default): the tracker→room calibration file (`raygun calibrate` writes
//!   one), relative to this file; its axes for `device` replace the three axes above.
//!
//! * FlyStick2 button 0 is the trigger, so it shoots; 1 and 2 are the next two buttons.
//! * The stick is a rate control: outside the dead zone, deflection a ∈ [−1, 1] is rescaled to
//!   (|a| − dz)/(1 − dz) with a's sign and changes the FOV by `gain_deg_per_s` × that per
//!   second (40°/s: a full deflection crosses the paper's 10°–60° range in 1.25 s). Pushing
//!   the stick right / forward (positive) widens the FOV; `signs` flips that per axis.
//! * `max_step_s` caps the time one stick sample acts for, so a gap in the stream (dropped
//!   frames, a paused sender) cannot make the FOV jump.
//! * Edges of a button within `debounce_s` of its last accepted edge are ignored (FlySticks
//!   bounce for a few milliseconds; 30 ms stays below a deliberate double click).
//! * `cursor`: the drawn ray-gun cursor's smoothing (a 1€ filter; see
//!   [`super::cursor::CursorConfig`]). It changes only what the viewer draws, never the ROI.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use glam::DVec3;
use serde::{Deserialize, Serialize};

use crate::tracking::event::{DeviceId, DeviceKind};

/// What a button does when pressed.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Action {
    /// Freeze the cone at the current pose; the ROI centre becomes the ray's hit.
    Shoot,
    /// Back to the initial FOV.
    ResetFov,
    /// Switch the sparse-sample filter (DESIGN.md §8) on or off.
    ToggleFilter,
}

/// Stick → FOV rate control.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StickConfig {
    pub horizontal_axis: usize,
    pub vertical_axis: usize,
    pub dead_zone: f64,
    pub gain_deg_per_s: f64,
    pub signs: [f64; 2],
    pub max_step_s: f64,
}

impl Default for StickConfig {
    fn default() -> Self {
        Self {
            horizontal_axis: 0,
            vertical_axis: 1,
            dead_zone: 0.15,
            gain_deg_per_s: 40.0,
            signs: [1.0, 1.0],
            max_step_s: 0.1,
        }
    }
}

/// The whole mapping.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct InteractionConfig {
    pub device: DeviceId,
    pub pointing_axis: [f64; 3],
    pub right_axis: [f64; 3],
    pub up_axis: [f64; 3],
    pub initial_fov_deg: [f64; 2],
    pub fov_min_deg: f64,
    pub fov_max_deg: f64,
    pub stick: StickConfig,
    /// Button index (as a string key in JSON) → action.
    pub buttons: BTreeMap<u32, Action>,
    pub debounce_s: f64,
    pub image_size: [u32; 2],
    pub mouse_ellipse_px: [f64; 2],
    pub cursor: super::cursor::CursorConfig,
    /// A tracker→room calibration file (`crate::tracking::calibration`) for live input and
    /// recordings; relative to this file's folder. `--calibration` on the command line wins.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub calibration: Option<PathBuf>,
}

impl Default for InteractionConfig {
    fn default() -> Self {
        Self {
            device: DeviceId::new(DeviceKind::Flystick, 0),
            pointing_axis: [0.0, 0.0, -1.0],
            right_axis: [1.0, 0.0, 0.0],
            up_axis: [0.0, 1.0, 0.0],
            initial_fov_deg: [30.0, 30.0],
            fov_min_deg: 5.0,
            fov_max_deg: 90.0,
            stick: StickConfig::default(),
            buttons: BTreeMap::from([
                (0, Action::Shoot),
                (1, Action::ResetFov),
                (2, Action::ToggleFilter),
            ]),
            debounce_s: 0.03,
            image_size: [3840, 2160],
            mouse_ellipse_px: [400.0, 300.0],
            cursor: super::cursor::CursorConfig::default(),
            calibration: None,
        }
    }
}

/// Why a mapping cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: {message}")]
    Json { path: PathBuf, message: String },
    #[error("interaction config field `{field}`: {reason}")]
    Invalid { field: &'static str, reason: String },
}

/// The largest interaction mapping read: a few dozen fields take a few kilobytes.
pub const MAX_CONFIG_BYTES: u64 = 1 << 20;

impl InteractionConfig {
    /// Reads and validates a JSON mapping.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let text = crate::input::read_text(path, MAX_CONFIG_BYTES, "an interaction mapping")
            .map_err(|source| ConfigError::Io {
                path: path.to_owned(),
                source,
            })?;
        let mut c: Self = serde_json::from_str(&text).map_err(|e| ConfigError::Json {
            path: path.to_owned(),
            message: format!(
                "{} at line {} column {}",
                crate::messages::json_message(&e, &text),
                e.line(),
                e.column()
            ),
        })?;
        if let Some(cal) = &mut c.calibration
            && cal.is_relative()
            && let Some(folder) = path.parent()
        {
            *cal = folder.join(&*cal);
        }
        c.validate()?;
        Ok(c)
    }

    /// Checks ranges and that the three device axes are orthonormal.
    pub fn validate(&self) -> Result<(), ConfigError> {
        let bad = |field, reason: String| Err(ConfigError::Invalid { field, reason });
        let (d, r, u) = self.axes();
        for (field, v) in [("pointing_axis", d), ("right_axis", r), ("up_axis", u)] {
            if !v.is_finite() || (v.length() - 1.0).abs() > 1e-6 {
                return bad(field, format!("{v} is not a unit vector"));
            }
        }
        if d.dot(r).abs() > 1e-6 || d.dot(u).abs() > 1e-6 || r.dot(u).abs() > 1e-6 {
            return bad(
                "right_axis",
                "pointing, right and up axes must be orthogonal".into(),
            );
        }
        if !(self.fov_min_deg > 0.0
            && self.fov_min_deg <= self.fov_max_deg
            && self.fov_max_deg < 180.0)
        {
            return bad(
                "fov_min_deg",
                format!(
                    "need 0 < min ≤ max < 180, have {} and {}",
                    self.fov_min_deg, self.fov_max_deg
                ),
            );
        }
        if !self
            .initial_fov_deg
            .iter()
            .all(|f| (self.fov_min_deg..=self.fov_max_deg).contains(f))
        {
            return bad(
                "initial_fov_deg",
                format!(
                    "{:?} is outside [fov_min_deg, fov_max_deg]",
                    self.initial_fov_deg
                ),
            );
        }
        let s = &self.stick;
        if !(0.0..1.0).contains(&s.dead_zone) {
            return bad(
                "stick.dead_zone",
                format!("{} is not in [0, 1)", s.dead_zone),
            );
        }
        if !(s.gain_deg_per_s.is_finite() && s.gain_deg_per_s >= 0.0) {
            return bad(
                "stick.gain_deg_per_s",
                format!("{} is not a finite non-negative rate", s.gain_deg_per_s),
            );
        }
        if !s.signs.iter().all(|v| *v == 1.0 || *v == -1.0) {
            return bad(
                "stick.signs",
                format!("{:?}: each sign must be 1 or -1", s.signs),
            );
        }
        if !(s.max_step_s.is_finite() && s.max_step_s > 0.0) {
            return bad(
                "stick.max_step_s",
                format!("{} is not a positive time", s.max_step_s),
            );
        }
        if !(self.debounce_s.is_finite() && self.debounce_s >= 0.0) {
            return bad(
                "debounce_s",
                format!("{} is not a non-negative time", self.debounce_s),
            );
        }
        if self.buttons.keys().any(|b| *b >= 32) {
            return bad("buttons", "button indices must be below 32".into());
        }
        if self.image_size.contains(&0) {
            return bad("image_size", "image size must be positive".into());
        }
        if let Err((field, reason)) = self.cursor.validate() {
            return bad(field, reason);
        }
        Ok(())
    }

    /// Takes a calibration's axes for the followed device, if it lists them.
    pub fn use_calibrated_axes(&mut self, calibration: &crate::tracking::calibration::Calibration) {
        if let Some(a) = calibration.devices.get(&self.device) {
            self.pointing_axis = a.pointing_axis;
            self.right_axis = a.right_axis;
            self.up_axis = a.up_axis;
        }
    }

    /// Pointing, right and up axes in the device frame.
    #[must_use]
    pub fn axes(&self) -> (DVec3, DVec3, DVec3) {
        (
            DVec3::from_array(self.pointing_axis),
            DVec3::from_array(self.right_axis),
            DVec3::from_array(self.up_axis),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_an_empty_file_means_defaults() {
        InteractionConfig::default().validate().unwrap();
        let c: InteractionConfig = serde_json::from_str("{}").unwrap();
        assert_eq!(c, InteractionConfig::default());
    }

    #[test]
    fn partial_file_overrides_only_what_it_names() {
        let c: InteractionConfig = serde_json::from_str(
            r#"{"device":"osc:2","stick":{"signs":[-1,1]},"buttons":{"3":"shoot"}}"#,
        )
        .unwrap();
        c.validate().unwrap();
        assert_eq!(c.device, DeviceId::new(DeviceKind::Osc, 2));
        assert_eq!(c.stick.signs, [-1.0, 1.0]);
        assert_eq!(c.stick.dead_zone, 0.15);
        assert_eq!(c.buttons, BTreeMap::from([(3, Action::Shoot)]));
    }

    #[test]
    fn invalid_values_name_their_field() {
        let cases = [
            (r#"{"pointing_axis":[0,0,-2]}"#, "pointing_axis"),
            (r#"{"right_axis":[0,0,-1]}"#, "right_axis"),
            (r#"{"fov_min_deg":50,"fov_max_deg":40}"#, "fov_min_deg"),
            (r#"{"initial_fov_deg":[1,30]}"#, "initial_fov_deg"),
            (r#"{"stick":{"dead_zone":1.0}}"#, "stick.dead_zone"),
            (r#"{"stick":{"signs":[0.5,1]}}"#, "stick.signs"),
            (r#"{"buttons":{"40":"shoot"}}"#, "buttons"),
            (r#"{"cursor":{"beta":-1}}"#, "cursor.beta"),
            (r#"{"cursor":{"stale_after_s":0}}"#, "cursor.stale_after_s"),
        ];
        for (json, field) in cases {
            let c: InteractionConfig = serde_json::from_str(json).unwrap();
            match c.validate() {
                Err(ConfigError::Invalid { field: f, .. }) => assert_eq!(f, field, "{json}"),
                other => panic!("{json}: {other:?}"),
            }
        }
        assert!(serde_json::from_str::<InteractionConfig>(r#"{"typo":1}"#).is_err());
    }
}
