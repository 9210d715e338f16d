//! The render camera: a pinhole with a box pixel filter (uniform jitter inside the pixel).

use glam::Vec3;

use crate::scene::{Camera, Scene};

/// A camera resolved for an image size.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RenderCamera {
    pub position: Vec3,
    pub forward: Vec3,
    pub right: Vec3,
    pub up: Vec3,
    pub tan_half_y: f32,
    pub aspect: f32,
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
        })
    }

    /// The camera named `name`, else the scene's first camera, else one that frames the
    /// scene's bounds from +Z with a 45° vertical field of view.
    pub fn choose(
        scene: &Scene,
        name: Option<&str>,
        width: u32,
        height: u32,
    ) -> Result<Self, CameraError> {
        if let Some(wanted) = name {
            return match scene.cameras.iter().find(|c| c.name == wanted) {
                Some(c) => Self::new(c, width, height),
                None => Err(CameraError::NotFound {
                    wanted: wanted.into(),
                    found: if scene.cameras.is_empty() {
                        "no cameras".into()
                    } else {
                        scene
                            .cameras
                            .iter()
                            .map(|c| format!("'{}'", c.name))
                            .collect::<Vec<_>>()
                            .join(", ")
                    },
                }),
            };
        }
        if let Some(c) = scene.cameras.first() {
            return Self::new(c, width, height);
        }
        Self::new(&framing_camera(scene), width, height)
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

/// A camera looking along −Z at the centre of the scene's bounds, far enough to see all of it.
#[must_use]
pub fn framing_camera(scene: &Scene) -> Camera {
    let yfov = 45f32.to_radians();
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    for t in &scene.triangles {
        for p in t.p {
            lo = lo.min(p);
            hi = hi.max(p);
        }
    }
    let (centre, radius) = if lo.x <= hi.x {
        ((lo + hi) * 0.5, ((hi - lo).length() * 0.5).max(1e-3))
    } else {
        (Vec3::ZERO, 1.0)
    };
    Camera {
        name: "framing".into(),
        position: centre + Vec3::Z * (radius / (0.5 * yfov).tan() * 1.1 + radius),
        forward: Vec3::NEG_Z,
        up: Vec3::Y,
        yfov,
    }
}
