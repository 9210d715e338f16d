//! The render camera: a pinhole, or an orthographic window, with a box pixel filter (uniform
//! jitter inside the pixel).

use glam::Vec3;

use crate::scene::{Camera, OrthographicCamera, Scene};

/// A camera resolved for an image size.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderCamera {
    pub position: Vec3,
    pub forward: Vec3,
    pub right: Vec3,
    pub up: Vec3,
    /// tan(yfov / 2) of a pinhole (0 for an orthographic camera).
    pub tan_half_y: f32,
    pub aspect: f32,
    /// Half the window height of an orthographic camera, metres (0 for a pinhole).
    pub ortho_half_y: f32,
}

/// A viewpoint from the command line (`--look-from`, `--look-at`, `--yfov`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LookAt {
    pub from: Vec3,
    pub at: Vec3,
    /// Vertical field of view, degrees.
    pub yfov_deg: f32,
}

/// Why a camera could not be chosen.
#[derive(Debug, thiserror::Error)]
pub enum CameraError {
    #[error("the scene has no camera named '{wanted}' (it has: {found})")]
    NotFound { wanted: String, found: String },
    #[error(
        "camera '{0}' is degenerate (zero or parallel forward/up vectors, or a field of view outside (0°, 180°))"
    )]
    Degenerate(String),
}

impl RenderCamera {
    /// Resolves `cam` for a `width × height` image.
    pub fn new(cam: &Camera, width: u32, height: u32) -> Result<Self, CameraError> {
        let forward = cam.forward.normalize_or_zero();
        let right = forward.cross(cam.up).normalize_or_zero();
        let up = right.cross(forward);
        if forward == Vec3::ZERO
            || right == Vec3::ZERO
            || !(cam.yfov > 0.0 && cam.yfov < std::f32::consts::PI)
            || !cam.position.is_finite()
        {
            return Err(CameraError::Degenerate(cam.name.clone()));
        }
        Ok(Self {
            position: cam.position,
            forward,
            right,
            up,
            tan_half_y: (0.5 * cam.yfov).tan(),
            aspect: width as f32 / height as f32,
            ortho_half_y: 0.0,
        })
    }

    /// Resolves an orthographic camera for a `width × height` image (the window's width is
    /// `2·ymag·width/height`: the image's aspect ratio, as for a pinhole).
    pub fn orthographic(
        cam: &OrthographicCamera,
        width: u32,
        height: u32,
    ) -> Result<Self, CameraError> {
        let forward = cam.forward.normalize_or_zero();
        let right = forward.cross(cam.up).normalize_or_zero();
        let up = right.cross(forward);
        if forward == Vec3::ZERO
            || right == Vec3::ZERO
            || !(cam.ymag > 0.0 && cam.ymag.is_finite())
            || !cam.position.is_finite()
        {
            return Err(CameraError::Degenerate(cam.name.clone()));
        }
        Ok(Self {
            position: cam.position,
            forward,
            right,
            up,
            tan_half_y: 0.0,
            aspect: width as f32 / height as f32,
            ortho_half_y: cam.ymag,
        })
    }

    /// A pinhole at `look.from` looking at `look.at`, +Y up (+Z where the view is vertical).
    pub fn look_at(look: &LookAt, width: u32, height: u32) -> Result<Self, CameraError> {
        let forward = (look.at - look.from).normalize_or_zero();
        let up = if forward.cross(Vec3::Y).length_squared() > 1e-8 {
            Vec3::Y
        } else {
            Vec3::Z
        };
        Self::new(
            &Camera {
                name: "--look-from".into(),
                position: look.from,
                forward,
                up,
                yfov: look.yfov_deg.to_radians(),
            },
            width,
            height,
        )
    }

    /// The command line's viewpoint if it gives one, else [`Self::choose`].
    pub fn choose_or_look_at(
        scene: &Scene,
        name: Option<&str>,
        look: Option<&LookAt>,
        width: u32,
        height: u32,
    ) -> Result<Self, CameraError> {
        match look {
            Some(l) => Self::look_at(l, width, height),
            None => Self::choose(scene, name, width, height),
        }
    }

    /// The camera named `name` (perspective or orthographic), else the scene's first
    /// perspective camera, else its first orthographic one, else one that frames the scene's
    /// bounds from +Z with a 45° vertical field of view ([`framing_camera`]).
    pub fn choose(
        scene: &Scene,
        name: Option<&str>,
        width: u32,
        height: u32,
    ) -> Result<Self, CameraError> {
        if let Some(wanted) = name {
            if let Some(c) = scene.cameras.iter().find(|c| c.name == wanted) {
                return Self::new(c, width, height);
            }
            if let Some(c) = scene.orthographic_camera(wanted) {
                return Self::orthographic(c, width, height);
            }
            let names: Vec<String> = scene
                .cameras
                .iter()
                .map(|c| format!("'{}'", c.name))
                .chain(
                    scene
                        .orthographic_cameras
                        .iter()
                        .map(|c| format!("'{}' (orthographic)", c.name)),
                )
                .collect();
            return Err(CameraError::NotFound {
                wanted: wanted.into(),
                found: if names.is_empty() {
                    "no cameras".into()
                } else {
                    names.join(", ")
                },
            });
        }
        if let Some(c) = scene.cameras.first() {
            return Self::new(c, width, height);
        }
        if let Some(c) = scene.orthographic_cameras.first() {
            return Self::orthographic(c, width, height);
        }
        Self::new(
            &framing_camera(scene, width as f32 / height as f32),
            width,
            height,
        )
    }

    /// The primary ray (origin, unit direction) through image point (`x`, `y`) in pixels
    /// (y down): from the pinhole, or parallel to `forward` from the orthographic window.
    #[inline]
    #[must_use]
    pub fn ray(&self, x: f32, y: f32, width: u32, height: u32) -> (Vec3, Vec3) {
        if self.ortho_half_y > 0.0 {
            let sx = (2.0 * x / width as f32 - 1.0) * self.ortho_half_y * self.aspect;
            let sy = (1.0 - 2.0 * y / height as f32) * self.ortho_half_y;
            return (self.position + self.right * sx + self.up * sy, self.forward);
        }
        (self.position, self.direction(x, y, width, height))
    }

    /// The primary ray direction through image point (`x`, `y`) in pixels (y down).
    #[inline]
    #[must_use]
    pub fn direction(&self, x: f32, y: f32, width: u32, height: u32) -> Vec3 {
        let sx = (2.0 * x / width as f32 - 1.0) * self.tan_half_y * self.aspect;
        let sy = (1.0 - 2.0 * y / height as f32) * self.tan_half_y;
        (self.forward + self.right * sx + self.up * sy).normalize()
    }
}

/// A camera looking along −Z at the centre of the scene's bounds, with a 45° vertical field of
/// view, as near as it can be while every corner of the bounds is in an image of `aspect`
/// (width / height), with a tenth to spare: the side of the bounds that fills more of the
/// image fills 1/1.1 of it (a viewer's "frame all"). The distance is measured from the bounds'
/// front face, which the image sees widest.
#[must_use]
pub fn framing_camera(scene: &Scene, aspect: f32) -> Camera {
    let yfov = 45f32.to_radians();
    let (lo, hi) = scene
        .bounds()
        .map_or((Vec3::splat(-1.0), Vec3::splat(1.0)), |b| (b.min, b.max));
    let (centre, half) = ((lo + hi) * 0.5, (hi - lo) * 0.5);
    let tan_y = (0.5 * yfov).tan();
    let tan_x = tan_y
        * if aspect.is_finite() && aspect > 0.0 {
            aspect
        } else {
            1.0
        };
    let distance = (half.x / tan_x).max(half.y / tan_y).max(1e-3) * 1.1;
    Camera {
        name: "framing".into(),
        position: Vec3::new(centre.x, centre.y, hi.z + distance),
        forward: Vec3::NEG_Z,
        up: Vec3::Y,
        yfov,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Without a camera, every corner of the scene's bounds is in the image, and the one
    /// nearest its edge is near it (the framing is tight), for wide, square and tall images
    /// and scenes wider or taller than the image.
    #[test]
    fn the_framing_camera_fits_the_bounds() {
        for name in ["city-small", "cornell-light"] {
            let mut scene = Scene::builtin(name).unwrap();
            scene.cameras.clear();
            scene.orthographic_cameras.clear();
            let (lo, hi) = scene.bounds().map(|b| (b.min, b.max)).unwrap();
            for (w, h) in [(1920, 1080), (64, 64), (300, 900)] {
                let cam = RenderCamera::choose(&scene, None, w, h).unwrap();
                assert_eq!(cam.forward, Vec3::NEG_Z);
                let mut widest = 0f32;
                for k in 0..8 {
                    let pick = |bit: u32, a: f32, b: f32| if k & bit == 0 { a } else { b };
                    let corner = Vec3::new(
                        pick(1, lo.x, hi.x),
                        pick(2, lo.y, hi.y),
                        pick(4, lo.z, hi.z),
                    );
                    let v = corner - cam.position;
                    let depth = v.dot(cam.forward);
                    assert!(
                        depth > 0.0,
                        "{name} {w}x{h}: corner {corner} behind the camera"
                    );
                    let sx = v.dot(cam.right) / (depth * cam.tan_half_y * cam.aspect);
                    let sy = v.dot(cam.up) / (depth * cam.tan_half_y);
                    assert!(
                        sx.abs() <= 1.0 && sy.abs() <= 1.0,
                        "{name} {w}x{h}: {corner} out"
                    );
                    widest = widest.max(sx.abs()).max(sy.abs());
                }
                assert!(
                    (0.85..=0.95).contains(&widest),
                    "{name} {w}x{h}: the bounds reach {widest} of the half-image"
                );
            }
        }
    }

    /// A scene without triangles still gets a camera (framing the unit box about the origin).
    #[test]
    fn an_empty_scene_gets_a_camera() {
        let cam = RenderCamera::choose(&Scene::default(), None, 32, 16).unwrap();
        assert!(cam.position.is_finite() && cam.position.z > 1.0);
    }
}
