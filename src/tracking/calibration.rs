//! The tracker→room calibration (DESIGN.md §2, §10): one file for every live source, carried in
//! the header of every recording so that a replay reproduces the live session exactly.
//!
//! ```json
//! {
//!   "raygun_calibration": 1,
//!   "rotation_rows": [[1, 0, 0], [0, 0, 1], [0, -1, 0]],
//!   "translation_m": [0.0, -1.2, 2.5],
//!   "units": "mm",
//!   "devices": { "flystick:0": { "pointing_axis": [0, 0, -1], "right_axis": [1, 0, 0], "up_axis": [0, 1, 0] } },
//!   "solved": { "points": 3, "rms_mm": 0.4, "max_mm": 0.6, "scale": 1.0002 }
//! }
//! ```
//!
//! * A tracker position `p` (in the tracker's units) maps to `R · (p · metres_per_unit) + t`,
//!   with `R` = `rotation_rows` (row by row, as one reads a matrix) and `t` = `translation_m`
//!   (metres); orientations map by `R` too.
//! * `units` (`"mm"`, `"cm"` or `"m"`) is what the tracker's numbers mean. Left out, each
//!   protocol's own unit applies: DTrack sends millimetres; raygun's OSC address space, VMC and
//!   VRPN send metres. Give it only for a tracker that does otherwise.
//! * `devices`: per device, the axes of its own frame that point, and that are the ROI's right
//!   and up; they replace the interaction mapping's axes for that device. Devices not listed
//!   keep the mapping's.
//! * `solved`: written by `raygun calibrate` (how well the measured points fit); informational.
//!
//! Every field but `raygun_calibration` may be left out (the identity). Unknown fields are an
//! error, so a misspelt `rotation_row` cannot silently mean "identity".

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use glam::{DMat3, DQuat, DVec3};
use serde::{Deserialize, Serialize};

use super::dtrack::{DtrackConfig, TrackerToRoom};
use super::event::DeviceId;
use super::osc::OscConfig;

/// The format version written into calibration files.
pub const FORMAT_VERSION: u32 = 1;
/// DTrack sends millimetres.
pub const DTRACK_METRES_PER_UNIT: f64 = 1e-3;

/// What a tracker's position numbers mean.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Units {
    #[serde(rename = "mm")]
    Millimetres,
    #[serde(rename = "cm")]
    Centimetres,
    #[serde(rename = "m")]
    Metres,
}

impl Units {
    #[must_use]
    pub fn metres_per_unit(self) -> f64 {
        match self {
            Self::Millimetres => 1e-3,
            Self::Centimetres => 1e-2,
            Self::Metres => 1.0,
        }
    }
}

/// A `--units` value that is none of mm, cm or m.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{0:?}: the units are mm, cm or m")]
pub struct UnitsError(pub String);

impl std::str::FromStr for Units {
    type Err = UnitsError;

    fn from_str(s: &str) -> Result<Self, UnitsError> {
        match s {
            "mm" => Ok(Self::Millimetres),
            "cm" => Ok(Self::Centimetres),
            "m" => Ok(Self::Metres),
            _ => Err(UnitsError(s.to_owned())),
        }
    }
}

/// A device's own axes: which way it points, and the ROI's right and up.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DeviceAxes {
    pub pointing_axis: [f64; 3],
    pub right_axis: [f64; 3],
    pub up_axis: [f64; 3],
}

/// How well `raygun calibrate`'s measured points fit the solved transform.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SolveReport {
    /// Point pairs used.
    pub points: usize,
    /// Root-mean-square and largest distance between a mapped tracker point and its room point.
    pub rms_mm: f64,
    pub max_mm: f64,
    /// The scale that would fit the points best, relative to the stated units (1 when the units
    /// are right; 1000 or 0.001 says millimetres and metres were mixed up).
    pub scale: f64,
}

/// The calibration file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Calibration {
    pub raygun_calibration: u32,
    #[serde(default = "identity_rows")]
    pub rotation_rows: [[f64; 3]; 3],
    #[serde(default)]
    pub translation_m: [f64; 3],
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub units: Option<Units>,
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub devices: BTreeMap<DeviceId, DeviceAxes>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub solved: Option<SolveReport>,
}

fn identity_rows() -> [[f64; 3]; 3] {
    [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
}

impl Default for Calibration {
    fn default() -> Self {
        Self {
            raygun_calibration: FORMAT_VERSION,
            rotation_rows: identity_rows(),
            translation_m: [0.0; 3],
            units: None,
            devices: BTreeMap::new(),
            solved: None,
        }
    }
}

/// Why a calibration cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum CalibrationError {
    #[error("{path}: cannot read the calibration: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}:{line}:{column}: {message}")]
    Json {
        path: PathBuf,
        line: usize,
        column: usize,
        message: String,
    },
    #[error(
        "{path}: calibration format version {found} is not supported (this raygun reads {FORMAT_VERSION})"
    )]
    Version { path: PathBuf, found: u32 },
    #[error("{path}: field `{field}`: {reason}")]
    Invalid {
        path: PathBuf,
        field: String,
        reason: String,
    },
}

/// The largest calibration file read: a transform and a few devices take a few kilobytes.
pub const MAX_CALIBRATION_BYTES: u64 = 1 << 20;

impl Calibration {
    /// Reads and validates a calibration file.
    pub fn load(path: &Path) -> Result<Self, CalibrationError> {
        let text = crate::input::read_text(path, MAX_CALIBRATION_BYTES, "a calibration").map_err(
            |source| CalibrationError::Io {
                path: path.to_owned(),
                source,
            },
        )?;
        Self::from_json(&text, path)
    }

    /// Parses and validates; `path` names the text in errors.
    pub fn from_json(text: &str, path: &Path) -> Result<Self, CalibrationError> {
        let c: Self = serde_json::from_str(text).map_err(|e| CalibrationError::Json {
            path: path.to_owned(),
            line: e.line(),
            column: e.column(),
            message: crate::messages::json_message(&e, text),
        })?;
        c.validate(path)?;
        Ok(c)
    }

    /// Checks the version, that the rotation is a proper rotation, the numbers are finite and
    /// each device's axes are orthonormal.
    pub fn validate(&self, path: &Path) -> Result<(), CalibrationError> {
        let invalid = |field: String, reason: String| CalibrationError::Invalid {
            path: path.to_owned(),
            field,
            reason,
        };
        if self.raygun_calibration != FORMAT_VERSION {
            return Err(CalibrationError::Version {
                path: path.to_owned(),
                found: self.raygun_calibration,
            });
        }
        self.tracker_to_room(1.0)
            .validate()
            .map_err(|e| invalid("rotation_rows".into(), e.to_string()))?;
        if !self.translation_m.iter().all(|v| v.is_finite()) {
            return Err(invalid(
                "translation_m".into(),
                "holds a non-finite number".into(),
            ));
        }
        for (device, axes) in &self.devices {
            check_axes(axes)
                .map_err(|(field, reason)| invalid(format!("devices.{device}.{field}"), reason))?;
        }
        Ok(())
    }

    /// The transform for a protocol whose own unit is `native_metres_per_unit` (DTrack 1e-3,
    /// OSC and VRPN 1), unless the file states `units`.
    #[must_use]
    pub fn tracker_to_room(&self, native_metres_per_unit: f64) -> TrackerToRoom {
        TrackerToRoom {
            rotation_rows: self.rotation_rows,
            translation_m: self.translation_m,
            metres_per_unit: self
                .units
                .map_or(native_metres_per_unit, Units::metres_per_unit),
        }
    }

    /// Puts the transform into the decoders' configurations, each with its protocol's own unit
    /// unless `units` says otherwise.
    pub fn apply(&self, dtrack: &mut DtrackConfig, osc: &mut OscConfig) {
        dtrack.tracker_to_room = self.tracker_to_room(DTRACK_METRES_PER_UNIT);
        osc.tracker_to_room = self.tracker_to_room(1.0);
    }

    /// The file form, laid out for people.
    #[must_use]
    pub fn to_json_pretty(&self) -> String {
        serde_json::to_string_pretty(self).unwrap_or_default()
    }
}

/// The axes must be unit vectors and orthogonal, like the interaction mapping's.
fn check_axes(a: &DeviceAxes) -> Result<(), (&'static str, String)> {
    let (d, r, u) = (
        DVec3::from_array(a.pointing_axis),
        DVec3::from_array(a.right_axis),
        DVec3::from_array(a.up_axis),
    );
    for (field, v) in [("pointing_axis", d), ("right_axis", r), ("up_axis", u)] {
        if !v.is_finite() || (v.length() - 1.0).abs() > 1e-6 {
            return Err((field, format!("{v} is not a unit vector")));
        }
    }
    if d.dot(r).abs() > 1e-6 || d.dot(u).abs() > 1e-6 || r.dot(u).abs() > 1e-6 {
        return Err((
            "right_axis",
            "pointing, right and up axes must be orthogonal".into(),
        ));
    }
    Ok(())
}

impl TrackerToRoom {
    /// The identity in metres: for protocols that send room-like metres (OSC, VRPN).
    #[must_use]
    pub fn identity_metres() -> Self {
        Self {
            metres_per_unit: 1.0,
            ..Self::default()
        }
    }

    /// Whether the transform changes nothing (identity rotation, no offset, metres).
    #[must_use]
    pub fn is_identity_metres(&self) -> bool {
        *self == Self::identity_metres()
    }

    /// A tracker pose (position in tracker units, orientation as a rotation matrix) in the room.
    #[must_use]
    pub fn map_pose(&self, position: DVec3, rotation: DMat3) -> super::event::Pose {
        let room_rot = self.rotation();
        super::event::Pose {
            position: self.map_point(position),
            orientation: DQuat::from_mat3(&(room_rot * rotation)).normalize(),
        }
    }

    /// A tracker position (tracker units) in the room (metres).
    #[must_use]
    pub fn map_point(&self, position: DVec3) -> DVec3 {
        self.rotation() * (position * self.metres_per_unit) + DVec3::from_array(self.translation_m)
    }
}

/// Why `raygun calibrate`'s points do not determine a transform.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SolveError {
    #[error("{0} point pairs: at least 3 not on one line are needed")]
    TooFew(usize),
    #[error("a point is not finite")]
    NotFinite,
    #[error(
        "the room points are (nearly) on one line (spread across it {spread_mm:.2} mm): the rotation about that line is undetermined; use points spread over the wall"
    )]
    Collinear { spread_mm: f64 },
}

/// Tracker→room rotation and translation that best map `tracker` points (in tracker units,
/// times `metres_per_unit`) onto `room` points (metres), in the least-squares sense (Horn's
/// closed form with unit quaternions), and how well they fit. Needs three or more pairs whose
/// room points are not on one line.
pub fn solve(
    tracker: &[DVec3],
    room: &[DVec3],
    metres_per_unit: f64,
) -> Result<(TrackerToRoom, SolveReport), SolveError> {
    let n = tracker.len().min(room.len());
    if n < 3 {
        return Err(SolveError::TooFew(n));
    }
    let p: Vec<DVec3> = tracker[..n].iter().map(|&v| v * metres_per_unit).collect();
    let q = &room[..n];
    if !p.iter().chain(q).all(|v| v.is_finite()) {
        return Err(SolveError::NotFinite);
    }
    let centroid = |v: &[DVec3]| v.iter().copied().sum::<DVec3>() / n as f64;
    let (pc, qc) = (centroid(&p), centroid(q));
    // The room points must span a plane: the second eigenvalue of their scatter.
    let scatter = |v: &[DVec3], c: DVec3| {
        let mut m = [[0.0f64; 3]; 3];
        for x in v {
            let d = (*x - c).to_array();
            for (i, row) in m.iter_mut().enumerate() {
                for (j, cell) in row.iter_mut().enumerate() {
                    *cell += d[i] * d[j];
                }
            }
        }
        m
    };
    let mut eig = symmetric_eigenvalues3(scatter(q, qc));
    eig.sort_by(f64::total_cmp);
    let spread_mm = (eig[1].max(0.0) / n as f64).sqrt() * 1e3;
    if spread_mm < 1.0 {
        return Err(SolveError::Collinear { spread_mm });
    }
    // Horn (1987): the rotation's quaternion is the eigenvector of the largest eigenvalue of
    // the 4×4 matrix built from the cross-covariance S = Σ p' q'ᵀ.
    let mut s = [[0.0f64; 3]; 3];
    for (a, b) in p.iter().zip(q) {
        let (a, b) = ((*a - pc).to_array(), (*b - qc).to_array());
        for (i, row) in s.iter_mut().enumerate() {
            for (j, cell) in row.iter_mut().enumerate() {
                *cell += a[i] * b[j];
            }
        }
    }
    let [[sxx, sxy, sxz], [syx, syy, syz], [szx, szy, szz]] = s;
    let nmat = [
        [sxx + syy + szz, syz - szy, szx - sxz, sxy - syx],
        [syz - szy, sxx - syy - szz, sxy + syx, szx + sxz],
        [szx - sxz, sxy + syx, -sxx + syy - szz, syz + szy],
        [sxy - syx, szx + sxz, syz + szy, -sxx - syy + szz],
    ];
    let (values, vectors) = jacobi_eigen4(nmat);
    let best = (0..4)
        .max_by(|&a, &b| values[a].total_cmp(&values[b]))
        .unwrap_or(0);
    let v = [
        vectors[0][best],
        vectors[1][best],
        vectors[2][best],
        vectors[3][best],
    ];
    // Horn's quaternion is (w, x, y, z).
    let rot = DQuat::from_xyzw(v[1], v[2], v[3], v[0]).normalize();
    let r = DMat3::from_quat(rot);
    let t = qc - r * pc;
    let rows = r.transpose().to_cols_array_2d();
    let transform = TrackerToRoom {
        rotation_rows: rows,
        translation_m: t.to_array(),
        metres_per_unit,
    };
    let errors: Vec<f64> = tracker[..n]
        .iter()
        .zip(q)
        .map(|(a, b)| transform.map_point(*a).distance(*b))
        .collect();
    let rms = (errors.iter().map(|e| e * e).sum::<f64>() / n as f64).sqrt();
    let max = errors.iter().copied().fold(0.0, f64::max);
    // The best scale (Umeyama): Σ q'·R p' / Σ |p'|².
    let (num, den) = p.iter().zip(q).fold((0.0, 0.0), |(num, den), (a, b)| {
        let (a, b) = (*a - pc, *b - qc);
        (num + b.dot(r * a), den + a.length_squared())
    });
    let scale = if den > 0.0 { num / den } else { f64::NAN };
    Ok((
        transform,
        SolveReport {
            points: n,
            rms_mm: rms * 1e3,
            max_mm: max * 1e3,
            scale,
        },
    ))
}

/// Eigenvalues of a symmetric 3×3 matrix (by the 4×4 Jacobi solver on a padded matrix).
fn symmetric_eigenvalues3(m: [[f64; 3]; 3]) -> [f64; 3] {
    let mut p = [[0.0; 4]; 4];
    for i in 0..3 {
        for j in 0..3 {
            p[i][j] = m[i][j];
        }
    }
    // The zero padding row and column are never rotated into the rest (their off-diagonal
    // entries are zero), so the first three diagonal entries are the 3×3 eigenvalues.
    let (values, _) = jacobi_eigen4(p);
    [values[0], values[1], values[2]]
}

/// Eigenvalues and eigenvectors (columns) of a symmetric 4×4 matrix by cyclic Jacobi rotations:
/// unconditionally convergent, accurate to rounding, and a few dozen sweeps at most for 4×4.
fn jacobi_eigen4(mut a: [[f64; 4]; 4]) -> ([f64; 4], [[f64; 4]; 4]) {
    let mut v = [[0.0; 4]; 4];
    for (i, row) in v.iter_mut().enumerate() {
        row[i] = 1.0;
    }
    for _sweep in 0..64 {
        let off: f64 = (0..4)
            .flat_map(|i| (0..4).filter(move |&j| j != i).map(move |j| (i, j)))
            .map(|(i, j)| a[i][j] * a[i][j])
            .sum();
        let diag: f64 = (0..4).map(|i| a[i][i] * a[i][i]).sum();
        if off <= 1e-30 * diag.max(f64::MIN_POSITIVE) {
            break;
        }
        for p in 0..3 {
            for q in p + 1..4 {
                if a[p][q] == 0.0 {
                    continue;
                }
                let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
                let t = theta.signum() / (theta.abs() + (theta * theta + 1.0).sqrt());
                let t = if theta == 0.0 { 1.0 } else { t };
                let c = 1.0 / (t * t + 1.0).sqrt();
                let s = t * c;
                for row in &mut a {
                    let (akp, akq) = (row[p], row[q]);
                    row[p] = c * akp - s * akq;
                    row[q] = s * akp + c * akq;
                }
                let (rp, rq) = (a[p], a[q]);
                a[p] = std::array::from_fn(|k| c * rp[k] - s * rq[k]);
                a[q] = std::array::from_fn(|k| s * rp[k] + c * rq[k]);
                for row in &mut v {
                    let (vkp, vkq) = (row[p], row[q]);
                    row[p] = c * vkp - s * vkq;
                    row[q] = s * vkp + c * vkq;
                }
            }
        }
    }
    ([a[0][0], a[1][1], a[2][2], a[3][3]], v)
}

/// ‖RᵀR − I‖ of the rotation, for tests and messages.
#[must_use]
pub fn rotation_error(t: &TrackerToRoom) -> f64 {
    let r = t.rotation();
    let e = r.transpose() * r - DMat3::IDENTITY;
    e.to_cols_array().iter().fold(0.0f64, |m, v| m.max(v.abs()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn transform() -> TrackerToRoom {
        // DTrack's factory "Z up" frame, turned 30° about room Y and offset.
        let r = DMat3::from_rotation_y(30f64.to_radians()) * TrackerToRoom::z_up().rotation();
        TrackerToRoom {
            rotation_rows: r.transpose().to_cols_array_2d(),
            translation_m: [0.4, -1.1, 2.3],
            metres_per_unit: 1e-3,
        }
    }

    /// Tracker points (mm) whose room images are `room`.
    fn tracker_points(t: &TrackerToRoom, room: &[DVec3]) -> Vec<DVec3> {
        let inv = t.rotation().transpose();
        room.iter()
            .map(|q| inv * (*q - DVec3::from_array(t.translation_m)) / t.metres_per_unit)
            .collect()
    }

    #[test]
    fn three_exact_points_give_back_the_transform() {
        let t = transform();
        let room = [
            DVec3::new(-3.5, 1.4, 0.6),
            DVec3::new(3.5, 1.4, 0.6),
            DVec3::new(0.0, -1.4, 0.0),
        ];
        let (got, report) = solve(&tracker_points(&t, &room), &room, 1e-3).unwrap();
        let diff = (got.rotation() - t.rotation())
            .to_cols_array()
            .iter()
            .fold(0.0f64, |m, v| m.max(v.abs()));
        assert!(diff < 1e-12, "{diff}");
        let dt = DVec3::from_array(got.translation_m) - DVec3::from_array(t.translation_m);
        assert!(dt.length() < 1e-12, "{dt}");
        assert!(report.rms_mm < 1e-9 && report.max_mm < 1e-9, "{report:?}");
        assert!((report.scale - 1.0).abs() < 1e-12);
        assert!(rotation_error(&got) < 1e-14);
    }

    #[test]
    fn noisy_points_give_a_residual_of_the_noise_and_wrong_units_show_in_the_scale() {
        let t = transform();
        let room: Vec<DVec3> = (0..8)
            .map(|k| {
                let a = f64::from(k) * 0.8;
                DVec3::new(3.0 * a.cos(), 1.2 * a.sin(), 0.3 * (a * 0.5).cos())
            })
            .collect();
        let mut tracker = tracker_points(&t, &room);
        // ±0.5 mm, deterministic.
        for (k, p) in tracker.iter_mut().enumerate() {
            let s = if k % 2 == 0 { 0.5 } else { -0.5 };
            *p += DVec3::new(s, -s, s * 0.5);
        }
        let (_, report) = solve(&tracker, &room, 1e-3).unwrap();
        assert!(report.rms_mm > 0.1 && report.rms_mm < 1.0, "{report:?}");
        // The same numbers read as metres: the best scale is 1/1000.
        let (_, wrong) = solve(&tracker, &room, 1.0).unwrap();
        assert!((wrong.scale - 1e-3).abs() < 1e-5, "{wrong:?}");
        assert!(wrong.rms_mm > 100.0, "{wrong:?}");
    }

    #[test]
    fn points_on_a_line_or_too_few_are_refused() {
        let line = [DVec3::ZERO, DVec3::X, DVec3::X * 2.0, DVec3::X * 3.0];
        assert!(matches!(
            solve(&line, &line, 1.0),
            Err(SolveError::Collinear { .. })
        ));
        assert_eq!(
            solve(&line[..2], &line[..2], 1.0),
            Err(SolveError::TooFew(2))
        );
        let bad = [DVec3::ZERO, DVec3::X, DVec3::new(f64::NAN, 0.0, 0.0)];
        assert_eq!(solve(&bad, &bad, 1.0), Err(SolveError::NotFinite));
    }

    #[test]
    fn a_file_names_the_field_at_fault() {
        let p = Path::new("lab.json");
        let c = Calibration::from_json(r#"{"raygun_calibration":1}"#, p).unwrap();
        assert_eq!(c, Calibration::default());
        assert_eq!(c.tracker_to_room(1e-3), TrackerToRoom::default());
        let e =
            Calibration::from_json(r#"{"raygun_calibration":1,"rotation_row":[]}"#, p).unwrap_err();
        assert!(e.to_string().contains("rotation_row"), "{e}");
        assert!(e.to_string().starts_with("lab.json:1:"), "{e}");
        let e = Calibration::from_json(
            r#"{"raygun_calibration":1,"rotation_rows":[[1,0,0],[0,1,0],[0,0,-1]]}"#,
            p,
        )
        .unwrap_err();
        assert!(e.to_string().contains("rotation_rows"), "{e}");
        let e = Calibration::from_json(
            r#"{"raygun_calibration":1,"devices":{"flystick:0":{"pointing_axis":[0,0,-2],"right_axis":[1,0,0],"up_axis":[0,1,0]}}}"#,
            p,
        )
        .unwrap_err();
        assert!(
            e.to_string().contains("devices.flystick:0.pointing_axis"),
            "{e}"
        );
        let e = Calibration::from_json(r#"{"raygun_calibration":2}"#, p).unwrap_err();
        assert!(matches!(e, CalibrationError::Version { found: 2, .. }));
        let c = Calibration::from_json(r#"{"raygun_calibration":1,"units":"cm"}"#, p).unwrap();
        assert_eq!(c.tracker_to_room(1e-3).metres_per_unit, 1e-2);
        let round: Calibration = serde_json::from_str(&c.to_json_pretty()).unwrap();
        assert_eq!(round, c);
    }
}
