//! The ray-gun cone (DESIGN.md §4): apex O, axis D, horizontal and vertical axes R and U, full
//! opening angles α_h and α_v. A room point P is in the cone when (P−O)·D > 0 and
//! (x/tan(α_h/2))² + (y/tan(α_v/2))² ≤ 1 with x = (P−O)·R / (P−O)·D, y = (P−O)·U / (P−O)·D.

use glam::{DQuat, DVec3};

/// Why a cone cannot be built from a pose.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum ConeError {
    #[error("{field} is not finite: {value:?}")]
    NotFinite { field: &'static str, value: DVec3 },
    #[error("the pointing direction is the zero vector")]
    ZeroDirection,
    #[error("the up vector is zero or parallel to the pointing direction")]
    UpParallel,
    #[error(
        "the {which} field of view, {}°, is outside {FOV_MIN_DEG:e}° to {FOV_MAX_DEG}°: {}",
        crate::messages::number(*deg),
        if *deg < FOV_MIN_DEG {
            "a narrower cone covers far less than a pixel of any wall"
        } else {
            "a cone of 180° or more is a half-space, not a region on the wall"
        }
    )]
    FovOutOfRange { which: &'static str, deg: f64 },
}

/// The frozen ray-gun cone in the room frame (metres).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Cone {
    pub apex: DVec3,
    /// Unit pointing direction D.
    pub axis: DVec3,
    /// Unit horizontal axis R (perpendicular to D).
    pub right: DVec3,
    /// Unit vertical axis U = R × D, completing the right-handed frame (R, U, −D).
    pub up: DVec3,
    /// tan(α_h / 2).
    pub tan_h: f64,
    /// tan(α_v / 2).
    pub tan_v: f64,
}

/// Smallest and largest full opening angle accepted, in degrees. Below 1e-6° the cone's tangent
/// underflows nothing but the projected region is far below a pixel; at 180° the cone is a
/// half-space.
pub const FOV_MIN_DEG: f64 = 1e-6;
pub const FOV_MAX_DEG: f64 = 179.999;

impl Cone {
    /// Builds the cone from an origin, a pointing direction and an up hint (any vector not
    /// parallel to `dir`; it is orthogonalised), and full FOVs in degrees.
    pub fn from_pose(
        origin: DVec3,
        dir: DVec3,
        up_hint: DVec3,
        fov_h_deg: f64,
        fov_v_deg: f64,
    ) -> Result<Self, ConeError> {
        for (field, value) in [("origin", origin), ("dir", dir), ("up", up_hint)] {
            if !value.is_finite() {
                return Err(ConeError::NotFinite { field, value });
            }
        }
        for (which, deg) in [("horizontal", fov_h_deg), ("vertical", fov_v_deg)] {
            if !(FOV_MIN_DEG..=FOV_MAX_DEG).contains(&deg) {
                return Err(ConeError::FovOutOfRange { which, deg });
            }
        }
        let axis = dir.try_normalize().ok_or(ConeError::ZeroDirection)?;
        let right = axis
            .cross(up_hint)
            .try_normalize()
            .filter(|r| r.is_finite())
            .ok_or(ConeError::UpParallel)?;
        let up = right.cross(axis);
        Ok(Self {
            apex: origin,
            axis,
            right,
            up,
            tan_h: (fov_h_deg.to_radians() / 2.0).tan(),
            tan_v: (fov_v_deg.to_radians() / 2.0).tan(),
        })
    }

    /// The cone of a tracked device with orientation `q`: pointing q·(0,0,−1), horizontal axis
    /// q·(1,0,0), vertical q·(0,1,0) (DESIGN.md §2 defaults).
    pub fn from_device(
        origin: DVec3,
        q: DQuat,
        fov_h_deg: f64,
        fov_v_deg: f64,
    ) -> Result<Self, ConeError> {
        Self::from_pose(origin, q * DVec3::NEG_Z, q * DVec3::Y, fov_h_deg, fov_v_deg)
    }

    /// Full opening angles in degrees.
    #[must_use]
    pub fn fov_deg(&self) -> (f64, f64) {
        (
            2.0 * self.tan_h.atan().to_degrees(),
            2.0 * self.tan_v.atan().to_degrees(),
        )
    }

    /// The cone's implicit function at a room point: ≤ 0 inside the double cone. Scaled so that
    /// it is (P−O)·D² times the normalised elliptical radius² minus one.
    #[must_use]
    pub fn implicit(&self, p: DVec3) -> f64 {
        let w = p - self.apex;
        let x = w.dot(self.right) / self.tan_h;
        let y = w.dot(self.up) / self.tan_v;
        let z = w.dot(self.axis);
        x * x + y * y - z * z
    }

    /// Whether a room point lies in the (forward) cone.
    #[must_use]
    pub fn contains(&self, p: DVec3) -> bool {
        let w = p - self.apex;
        let z = w.dot(self.axis);
        if z <= 0.0 {
            return false;
        }
        let x = w.dot(self.right) / (z * self.tan_h);
        let y = w.dot(self.up) / (z * self.tan_v);
        x * x + y * y <= 1.0
    }

    /// The angle (radians) between the direction from the apex to `p` and the cone: 0 inside,
    /// else how far the direction lies outside the cone's boundary in its own azimuth. For a
    /// circular cone this is exactly the angle to the nearest cone direction; for an elliptical
    /// one it is the radial (same-azimuth) angle, the cheap "angular metric" of DESIGN.md §5.
    #[must_use]
    pub fn angular_excess(&self, p: DVec3) -> f64 {
        let w = p - self.apex;
        let x = w.dot(self.right);
        let y = w.dot(self.up);
        let z = w.dot(self.axis);
        let lateral = x.hypot(y);
        // Angle of w from the axis, in [0, π].
        let rho = lateral.atan2(z);
        if lateral == 0.0 {
            return if z >= 0.0 { 0.0 } else { std::f64::consts::PI };
        }
        let (c, s) = (x / lateral, y / lateral);
        // The boundary's polar angle in this azimuth: tan ρ_b = 1 / sqrt(c²/th² + s²/tv²).
        let inv = ((c / self.tan_h).powi(2) + (s / self.tan_v).powi(2)).sqrt();
        let rho_b = (1.0 / inv).atan();
        (rho - rho_b).max(0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn straight(fov: f64) -> Cone {
        Cone::from_pose(DVec3::new(0.0, 0.0, 1.0), DVec3::NEG_Z, DVec3::Y, fov, fov).unwrap()
    }

    #[test]
    fn frame_is_right_handed_and_orthonormal() {
        let c = Cone::from_pose(
            DVec3::ZERO,
            DVec3::new(0.3, -0.2, -1.0),
            DVec3::Y,
            30.0,
            20.0,
        )
        .unwrap();
        assert!((c.axis.length() - 1.0).abs() < 1e-15);
        assert!(c.axis.dot(c.right).abs() < 1e-15);
        assert!(c.axis.dot(c.up).abs() < 1e-15);
        assert!(c.right.dot(c.up).abs() < 1e-15);
        // (R, U, −D) is right-handed like the room's (X, Y, Z).
        assert!((c.right.cross(c.up) - (-c.axis)).length() < 1e-15);
        let (h, v) = c.fov_deg();
        assert!((h - 30.0).abs() < 1e-12 && (v - 20.0).abs() < 1e-12);
    }

    #[test]
    fn device_default_axes() {
        let c = Cone::from_device(DVec3::ZERO, DQuat::IDENTITY, 10.0, 10.0).unwrap();
        assert_eq!(c.axis, DVec3::NEG_Z);
        assert_eq!(c.right, DVec3::X);
        assert_eq!(c.up, DVec3::Y);
    }

    #[test]
    fn boundary_of_a_circular_cone_on_a_plane_at_distance_one() {
        let c = straight(60.0);
        let r = (30f64).to_radians().tan();
        assert!(c.contains(DVec3::new(r * 0.999, 0.0, 0.0)));
        assert!(!c.contains(DVec3::new(r * 1.001, 0.0, 0.0)));
        assert!(!c.contains(DVec3::new(0.0, 0.0, 2.0)), "behind the apex");
        assert!(c.angular_excess(DVec3::new(0.0, 0.5 * r, 0.0)) == 0.0);
        let p = DVec3::new(0.0, 1.0, 0.0); // 45° off axis
        assert!((c.angular_excess(p) - 15f64.to_radians()).abs() < 1e-14);
        assert!((c.angular_excess(DVec3::new(0.0, 0.0, 3.0)) - std::f64::consts::PI).abs() < 1e-15);
    }

    #[test]
    fn bad_poses_are_errors() {
        let o = DVec3::ZERO;
        assert_eq!(
            Cone::from_pose(o, DVec3::ZERO, DVec3::Y, 10.0, 10.0),
            Err(ConeError::ZeroDirection)
        );
        assert_eq!(
            Cone::from_pose(o, DVec3::Y, DVec3::Y, 10.0, 10.0),
            Err(ConeError::UpParallel)
        );
        assert!(matches!(
            Cone::from_pose(o, DVec3::NEG_Z, DVec3::Y, 180.0, 10.0),
            Err(ConeError::FovOutOfRange { .. })
        ));
        assert!(matches!(
            Cone::from_pose(o, DVec3::NEG_Z, DVec3::Y, 10.0, 0.0),
            Err(ConeError::FovOutOfRange { .. })
        ));
        assert!(matches!(
            Cone::from_pose(
                DVec3::new(f64::NAN, 0.0, 0.0),
                DVec3::NEG_Z,
                DVec3::Y,
                10.0,
                10.0
            ),
            Err(ConeError::NotFinite { .. })
        ));
    }
}
