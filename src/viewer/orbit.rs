//! Moving the viewpoint from a desktop, the way glTF viewers do: drag to orbit about a target,
//! shift- or middle-drag to pan, the wheel to dolly (and the arrow keys, shift + arrows and
//! +/− or Page Up/Down for the same). One [`Orbit`] moves either the wall camera's eye (room
//! frame, about the wall's centre) or the pinhole camera (scene frame, about a point in front of
//! it); the viewer applies the result under the restart rule of a moving eye
//! ([`crate::tracking::head::eye_moved`]; for a pinhole [`camera_moved`]).

use glam::{DVec2, DVec3};

use crate::display::DisplayModel;
use crate::trace::camera::RenderCamera;
use crate::tracking::head::eye_moved;

/// Radians of orbit per pointer pixel (half a turn across a 630-pixel image).
pub const ORBIT_RAD_PER_PX: f64 = 0.005;
/// Pan per pointer pixel, as a share of the distance to the target.
pub const PAN_PER_PX: f64 = 0.0015;
/// Dolly per wheel point: the distance is multiplied by exp(−this × points) (a 50-point notch
/// is about 10 %).
pub const DOLLY_PER_POINT: f64 = 0.002;
/// What one key press moves, in pointer pixels (orbit, pan) or wheel points (dolly).
pub const KEY_STEP_PX: f64 = 20.0;
pub const KEY_STEP_POINTS: f64 = 50.0;
/// The orbit's pitch stays this far (radians) from straight up or down, where the view's
/// right-hand direction would be undefined.
const PITCH_LIMIT: f64 = 1.5;

/// A desktop user's gesture on the picture.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Gesture {
    /// A plain drag, pointer pixels (x right, y down).
    Orbit(DVec2),
    /// A shift- or middle-button drag, pointer pixels.
    Pan(DVec2),
    /// The wheel, points (positive: away from the user, towards the target).
    Dolly(f64),
}

/// A key that moves the viewpoint: the arrows and the two dolly keys (+/− or Page Up/Down).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ViewKey {
    Left,
    Right,
    Up,
    Down,
    /// Towards the target.
    In,
    Out,
}

/// What a key does: the arrows orbit (with shift: pan) by [`KEY_STEP_PX`], the dolly keys dolly
/// by [`KEY_STEP_POINTS`] — the drag or wheel of that size.
#[must_use]
pub fn key_gesture(key: ViewKey, shift: bool) -> Gesture {
    let px = match key {
        ViewKey::Left => DVec2::new(-KEY_STEP_PX, 0.0),
        ViewKey::Right => DVec2::new(KEY_STEP_PX, 0.0),
        ViewKey::Up => DVec2::new(0.0, -KEY_STEP_PX),
        ViewKey::Down => DVec2::new(0.0, KEY_STEP_PX),
        ViewKey::In => return Gesture::Dolly(KEY_STEP_POINTS),
        ViewKey::Out => return Gesture::Dolly(-KEY_STEP_POINTS),
    };
    if shift {
        Gesture::Pan(px)
    } else {
        Gesture::Orbit(px)
    }
}

/// A viewpoint orbiting a target: `position = target + distance · (cos pitch · (sin yaw · side
/// + cos yaw · back) + sin pitch · up)`, looking at the target.
#[derive(Clone, Debug, PartialEq)]
pub struct Orbit {
    pub target: DVec3,
    pub distance: f64,
    /// Radians about `up`, 0 along the first viewpoint's horizontal direction.
    pub yaw: f64,
    /// Radians above the plane normal to `up`.
    pub pitch: f64,
    /// The world's up (unit).
    up: DVec3,
    /// Horizontal unit vectors: target → first viewpoint, and `up × back`.
    back: DVec3,
    side: DVec3,
    /// The closest the viewpoint comes to the target.
    pub min_distance: f64,
}

impl Orbit {
    /// An orbit about `target` through `position`, `up` being the world's up; `None` where the
    /// two points coincide, a value is not finite or `up` is zero.
    #[must_use]
    pub fn new(position: DVec3, target: DVec3, up: DVec3) -> Option<Self> {
        let up = up.try_normalize()?;
        let offset = position - target;
        let distance = offset.length();
        if !(distance.is_finite() && distance > 0.0 && target.is_finite()) {
            return None;
        }
        let flat = offset - up * offset.dot(up);
        // Straight above or below the target: any horizontal direction will do.
        let back = flat
            .try_normalize()
            .or_else(|| up.any_orthonormal_vector().try_normalize())?;
        let side = up.cross(back);
        let pitch = (offset.dot(up) / distance).clamp(-1.0, 1.0).asin();
        Some(Self {
            target,
            distance,
            yaw: 0.0,
            pitch: pitch.clamp(-PITCH_LIMIT, PITCH_LIMIT),
            up,
            back,
            side,
            min_distance: distance * 1e-3,
        })
    }

    /// The unit vector from the target to the viewpoint.
    #[must_use]
    pub fn direction(&self) -> DVec3 {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        (self.side * sy + self.back * cy) * cp + self.up * sp
    }

    #[must_use]
    pub fn position(&self) -> DVec3 {
        self.target + self.direction() * self.distance
    }

    /// The view's right and up (unit), looking at the target.
    #[must_use]
    pub fn right_up(&self) -> (DVec3, DVec3) {
        let forward = -self.direction();
        let right = forward.cross(self.up).normalize();
        (right, right.cross(forward))
    }

    /// Moves the viewpoint to `position`, the target kept (nothing where it is the target or
    /// not finite).
    pub fn set_position(&mut self, position: DVec3) {
        let offset = position - self.target;
        let distance = offset.length();
        if !(distance.is_finite() && distance > 0.0) {
            return;
        }
        let d = offset / distance;
        self.distance = distance;
        self.pitch = d
            .dot(self.up)
            .clamp(-1.0, 1.0)
            .asin()
            .clamp(-PITCH_LIMIT, PITCH_LIMIT);
        self.yaw = d.dot(self.side).atan2(d.dot(self.back));
    }

    /// Applies a gesture: a drag of `px` pointer pixels orbits (dragging right turns the
    /// viewpoint to the left of the target, as glTF viewers do: the scene turns with the
    /// pointer) or pans (the scene follows the pointer); the wheel dollies.
    pub fn apply(&mut self, gesture: Gesture) {
        match gesture {
            Gesture::Orbit(px) => {
                self.yaw -= px.x * ORBIT_RAD_PER_PX;
                self.pitch =
                    (self.pitch + px.y * ORBIT_RAD_PER_PX).clamp(-PITCH_LIMIT, PITCH_LIMIT);
            }
            Gesture::Pan(px) => {
                let (right, up) = self.right_up();
                let step = self.distance * PAN_PER_PX;
                self.target += (-right * px.x + up * px.y) * step;
            }
            Gesture::Dolly(points) => {
                self.distance =
                    (self.distance * (-points * DOLLY_PER_POINT).exp()).max(self.min_distance);
            }
        }
    }

    /// The pinhole (or orthographic) camera at the viewpoint looking at the target, with
    /// `like`'s field of view and aspect.
    #[must_use]
    pub fn camera(&self, like: &RenderCamera) -> RenderCamera {
        let forward = -self.direction();
        let (right, up) = self.right_up();
        RenderCamera {
            position: self.position().as_vec3(),
            forward: forward.as_vec3(),
            right: right.as_vec3(),
            up: up.as_vec3(),
            ..*like
        }
    }
}

/// The orbit of a pinhole camera: about the point `focus` in front of it (scene units), its
/// own up as the world's.
#[must_use]
pub fn camera_orbit(camera: &RenderCamera, focus: f64) -> Option<Orbit> {
    let p = camera.position.as_dvec3();
    Orbit::new(
        p,
        p + camera.forward.as_dvec3() * focus,
        camera.up.as_dvec3(),
    )
}

/// The orbit of the wall camera's eye (room frame): about the wall's centre, +Y up.
#[must_use]
pub fn eye_orbit(model: &DisplayModel, eye: DVec3) -> Option<Orbit> {
    Orbit::new(eye, crate::trace::wall::wall_centre(model), DVec3::Y)
}

/// The restart rule for a pinhole: the camera moved more than `threshold` (scene units) from
/// `started`, or turned more than `threshold` radians (as far as a point 1 unit away moves).
#[must_use]
pub fn camera_moved(started: &RenderCamera, camera: &RenderCamera, threshold: f64) -> bool {
    let turned = f64::from(started.forward.angle_between(camera.forward));
    eye_moved(
        started.position.as_dvec3(),
        camera.position.as_dvec3(),
        threshold,
    ) || turned > threshold
}

/// The wall seen from above (room frame x, z): each tile's bottom edge, for the panel's
/// sketch of the wall and the eye.
#[must_use]
pub fn wall_plan(model: &DisplayModel) -> Vec<[DVec2; 2]> {
    model
        .tiles()
        .iter()
        .map(|t| {
            let c = t.corners();
            // The two corners of the lower edge (any edge's x, z span the tile's plan).
            let (a, b) = (c[0], c[1]);
            [DVec2::new(a.x, a.z), DVec2::new(b.x, b.z)]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn orbit() -> Orbit {
        Orbit::new(DVec3::new(0.0, 0.0, 2.0), DVec3::ZERO, DVec3::Y).unwrap()
    }

    #[test]
    fn a_new_orbit_starts_at_its_position() {
        let p = DVec3::new(0.3, 0.7, 1.9);
        let o = Orbit::new(p, DVec3::new(0.1, 0.0, 0.0), DVec3::Y).unwrap();
        assert!(o.position().abs_diff_eq(p, 1e-12), "{}", o.position());
        assert!(Orbit::new(DVec3::ONE, DVec3::ONE, DVec3::Y).is_none());
    }

    #[test]
    fn orbit_keeps_the_distance_and_pan_moves_target_and_viewpoint_together() {
        let mut o = orbit();
        o.apply(Gesture::Orbit(DVec2::new(100.0, -40.0)));
        assert!((o.position().length() - 2.0).abs() < 1e-12);
        // Dragging right: the viewpoint goes left (−X) round the target.
        assert!(o.position().x < 0.0, "{}", o.position());
        let before = o.position();
        let t = o.target;
        o.apply(Gesture::Pan(DVec2::new(10.0, 0.0)));
        let moved = o.position() - before;
        assert!(moved.abs_diff_eq(o.target - t, 1e-12));
        assert!(moved.length() > 0.0);
        // Pitch stops short of the pole.
        o.apply(Gesture::Orbit(DVec2::new(0.0, 1e6)));
        assert!(o.pitch <= PITCH_LIMIT);
        assert!(o.right_up().0.is_finite());
    }

    #[test]
    fn dolly_moves_towards_the_target_and_stops_short_of_it() {
        let mut o = orbit();
        o.apply(Gesture::Dolly(50.0));
        assert!(o.distance < 2.0 && o.distance > 1.7, "{}", o.distance);
        o.apply(Gesture::Dolly(-50.0));
        assert!((o.distance - 2.0).abs() < 1e-12);
        o.apply(Gesture::Dolly(1e9));
        assert_eq!(o.distance, o.min_distance);
    }

    #[test]
    fn set_position_round_trips() {
        let mut o = orbit();
        let p = DVec3::new(-0.4, 0.5, 1.2);
        o.set_position(p);
        assert!(o.position().abs_diff_eq(p, 1e-12));
    }

    #[test]
    fn the_camera_looks_at_the_target_and_the_rule_sees_moves_and_turns() {
        let like = RenderCamera {
            position: glam::Vec3::ZERO,
            forward: glam::Vec3::NEG_Z,
            right: glam::Vec3::X,
            up: glam::Vec3::Y,
            tan_half_y: 0.5,
            aspect: 2.0,
            ortho_half_y: 0.0,
        };
        let o = camera_orbit(&like, 3.0).unwrap();
        let c = o.camera(&like);
        assert!(c.position.abs_diff_eq(like.position, 1e-6));
        assert!(c.forward.abs_diff_eq(like.forward, 1e-6));
        assert!(!camera_moved(&like, &c, 0.01));
        let mut o2 = o.clone();
        o2.apply(Gesture::Orbit(DVec2::new(1.0, 0.0)));
        // 0.005 rad about a target 3 away: 1.5 cm of travel.
        assert!(camera_moved(&like, &o2.camera(&like), 0.01));
    }
}
