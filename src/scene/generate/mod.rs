//! The paper's scenes (DESIGN.md §7, §9), generated deterministically and written as glTF 2.0
//! binary (GLB), so built-in scenes and files on disk go through the same loader.
//!
//! * [`cornell`]: the Cornell box with an open front (the paper lit it by the environment only),
//!   optionally with its ceiling light as an emissive quad.
//! * [`city`]: a seeded procedural city; [`CityParams::PAPER`] has about 350 000 triangles like
//!   the commercial model the paper used.
//!
//! The same inputs give the same bytes (no clocks, no hash-map order, a counter-based hash for
//! randomness); `tests/data/scenes/` holds goldens that a test compares byte for byte.
//!
//! The files: this one names the built-ins; `glb.rs` holds the geometry builder and the GLB
//! writer both scenes use, `cornell.rs` and `city.rs` the scenes.

mod city;
mod cornell;
mod glb;

pub use super::GenerateError;
use super::{Scene, SceneError};

pub use city::{CityParams, city};
pub use cornell::{CORNELL_CAMERA_POSITION, cornell, cornell_camera_yfov};

/// Names `Scene::builtin` (and `--scene builtin:NAME`) accepts.
pub const BUILTINS: &[&str] = &["cornell", "cornell-light", "city", "city-small"];

/// A generated scene: GLB bytes and the number of triangles in them.
#[derive(Clone, Debug)]
pub struct Generated {
    pub glb: Vec<u8>,
    pub triangles: usize,
}

impl Scene {
    /// A generated scene by name (see [`BUILTINS`]), built in memory and loaded through the same
    /// GLB path as a file.
    pub fn builtin(name: &str) -> Result<Self, SceneError> {
        let generated = match name {
            "cornell" => cornell(false),
            "cornell-light" => cornell(true),
            "city" => city(CityParams::PAPER),
            "city-small" => city(CityParams::SMALL),
            _ => {
                return Err(SceneError::UnknownBuiltin {
                    name: name.into(),
                    known: BUILTINS.join(", "),
                });
            }
        }
        .map_err(|reason| SceneError::Generate {
            name: name.into(),
            reason,
        })?;
        Self::from_glb_bytes(&generated.glb, &format!("builtin:{name}"))
    }
}
