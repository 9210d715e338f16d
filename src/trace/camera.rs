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
    /// bounds from +Z with a 45° vertical field of view.
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
        Self::new(&framing_camera(scene), width, height)
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
