//! The tracker → room transform of DTrack's millimetre frame (DESIGN.md §2, §10).

use super::*;

/// Tolerance of ‖RᵀR − I‖ (max norm) for a rotation matrix: DTrack prints 6 decimals, so an
/// honest matrix is off by ~1e-6; 1e-3 rejects garbage without rejecting rounding.
pub const ROTATION_TOLERANCE: f64 = 1e-3;

/// The tracker→room transform (DESIGN.md §2: configuration, never guessed). A tracker point
/// `p` (tracker units) maps to `rotation · (p · metres_per_unit) + translation_m`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TrackerToRoom {
    /// Rotation tracker → room, written row by row (as one reads a matrix).
    pub rotation_rows: [[f64; 3]; 3],
    /// Room-frame offset of the tracker origin, metres.
    pub translation_m: [f64; 3],
    /// Metres per tracker unit: DTrack sends millimetres.
    pub metres_per_unit: f64,
}

impl Default for TrackerToRoom {
    /// Identity rotation and offset, millimetres: right for a DTrack room calibrated with
    /// "Y up, Z towards the viewer", as DESIGN.md §2's room frame is.
    fn default() -> Self {
        Self {
            rotation_rows: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
            translation_m: [0.0; 3],
            metres_per_unit: 1e-3,
        }
    }
}

/// Why a tracker→room transform cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TransformError {
    #[error(
        "tracker_to_room.rotation_rows is not a rotation (‖RᵀR − I‖ = {error:.3e}, det = {det:.6})"
    )]
    NotRotation { error: f64, det: f64 },
    #[error("tracker_to_room.{field} holds a non-finite or non-positive value")]
    BadValue { field: &'static str },
}

impl TrackerToRoom {
    /// DTrack's factory room calibration has Z up; this maps it onto Y up (x stays, tracker
    /// Z → room Y, tracker Y → room −Z).
    #[must_use]
    pub fn z_up() -> Self {
        Self {
            rotation_rows: [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]],
            ..Self::default()
        }
    }

    /// The rotation as a matrix.
    #[must_use]
    pub fn rotation(&self) -> DMat3 {
        DMat3::from_cols_array_2d(&self.rotation_rows).transpose()
    }

    /// Checks that the rotation is a proper rotation and the numbers are usable.
    pub fn validate(&self) -> Result<(), TransformError> {
        if !(self.metres_per_unit.is_finite() && self.metres_per_unit > 0.0) {
            return Err(TransformError::BadValue {
                field: "metres_per_unit",
            });
        }
        if !self.translation_m.iter().all(|v| v.is_finite()) {
            return Err(TransformError::BadValue {
                field: "translation_m",
            });
        }
        let r = self.rotation();
        let error = orthonormality_error(&r);
        let det = r.determinant();
        if !(error < ROTATION_TOLERANCE && det > 0.0) {
            return Err(TransformError::NotRotation { error, det });
        }
        Ok(())
    }
}

pub(super) fn orthonormality_error(r: &DMat3) -> f64 {
    let e = r.transpose() * *r - DMat3::IDENTITY;
    e.to_cols_array()
        .iter()
        .fold(0.0_f64, |m, v| m.max(v.abs()))
}
