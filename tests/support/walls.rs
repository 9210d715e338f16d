//! The shipped HORNET wall and pointing cones, for the tests that need a real wall.

#![allow(dead_code)]

use glam::DVec3;
use raygun::display::DisplayModel;
use raygun::roi::cone::Cone;

/// The shipped model of HORNET (35 tiles in 7 hinged columns).
pub const HORNET: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/display-models/hornet.json");

pub fn hornet() -> DisplayModel {
    DisplayModel::load(HORNET).unwrap()
}

/// A ray-gun cone from `origin` along `direction` (room frame, up +Y) with horizontal and
/// vertical field of view `fov_h`, `fov_v` (degrees).
pub fn cone(origin: [f64; 3], direction: [f64; 3], fov_h: f64, fov_v: f64) -> Cone {
    Cone::from_pose(
        DVec3::from_array(origin),
        DVec3::from_array(direction),
        DVec3::Y,
        fov_h,
        fov_v,
    )
    .unwrap()
}
