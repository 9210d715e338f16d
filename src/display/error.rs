//! Loader errors. Every error names the file; validation errors also name the tile (by id, or by
//! its position in the list when the id itself is the problem) and the JSON field at fault, so a
//! person editing a model can go straight to the line.

use std::fmt;

/// Everything that can go wrong loading a display model.
#[derive(Debug, thiserror::Error)]
pub enum DisplayModelError {
    #[error("{file}: cannot read the display model: {source}")]
    Io {
        file: String,
        #[source]
        source: std::io::Error,
    },
    /// JSON syntax, a wrong type or an unknown field, with serde_json's position (1-based line
    /// and column).
    #[error("{file}:{line}:{column}: {message}")]
    Json {
        file: String,
        line: usize,
        column: usize,
        message: String,
    },
    /// The JSON is well-formed but describes an impossible or self-contradicting display.
    #[error("{file}: {}field `{field}`: {problem}", tile_prefix(.tile))]
    Invalid {
        file: String,
        /// The tile id (`None` for model-level and generator fields).
        tile: Option<String>,
        /// The JSON field, e.g. `top_right`, `bezel.left`, `generator.columns`.
        field: String,
        problem: Problem,
    },
}

fn tile_prefix(tile: &Option<String>) -> String {
    match tile {
        Some(id) => format!("tile {}: ", crate::messages::quote(id)),
        None => String::new(),
    }
}

impl DisplayModelError {
    /// The file (or source name) the error is about.
    #[must_use]
    pub fn file(&self) -> &str {
        match self {
            Self::Io { file, .. } | Self::Json { file, .. } | Self::Invalid { file, .. } => file,
        }
    }

    /// The validation problem, when the error is one.
    #[must_use]
    pub fn problem(&self) -> Option<&Problem> {
        match self {
            Self::Invalid { problem, .. } => Some(problem),
            _ => None,
        }
    }
}

/// What is wrong with a field. The tolerances these refer to are the `*_TOL*` constants of
/// [`crate::display`].
#[derive(Clone, Debug, PartialEq)]
pub enum Problem {
    /// NaN or ±∞ (from arithmetic on huge inputs; JSON itself cannot spell them).
    NonFinite,
    /// Finite but beyond [`crate::display::MAX_COORD`] in magnitude: almost surely a unit
    /// mistake, and large enough to overflow the geometry's squared lengths.
    TooLarge { value: f64 },
    /// Empty where text is required (name, tile id).
    Empty,
    /// Neither or both of `tiles` and `generator`.
    FormAmbiguous { both: bool },
    /// More tiles than [`crate::display::MAX_TILES`].
    TooManyTiles { count: u64 },
    /// A pixel count ≤ 0 or above `u32::MAX`.
    ResolutionOutOfRange { value: i64 },
    /// A count that must be at least 1 (generator columns/rows).
    CountZero,
    /// A length that must be > 0 (active size) or ≥ 0 (bezel).
    Negative { value: f64, zero_allowed: bool },
    /// An edge of the active area shorter than [`crate::display::MIN_EDGE_M`].
    DegenerateEdge { length_m: f64 },
    /// The top and left edges are not perpendicular: |cos| above
    /// [`crate::display::PERPENDICULAR_COS_TOL`].
    NotPerpendicular { cos: f64 },
    /// Up parallel to the normal, or a zero vector, in the generator placement.
    DegenerateDirection,
    /// |yaw step| ≥ 180°: neighbouring columns would fold onto each other.
    YawStepTooLarge { deg: f64 },
    /// The tile's horizontal and vertical pixel pitch differ (relative difference above
    /// [`crate::display::PITCH_REL_TOL`]).
    PitchAxes { x_m: f64, y_m: f64 },
    /// The tile's pitch differs from the model pitch (the mean over all tiles).
    PitchModel { tile_m: f64, model_m: f64 },
    /// Another tile already has this id.
    DuplicateId,
    /// Another tile already has this (column, row).
    DuplicateGridPosition { other: String },
    /// The canvas rectangles (active area + bezels) of two tiles overlap.
    CanvasOverlap { other: String, overlap_px: [f64; 2] },
    /// The two tiles touch on the canvas, but the 3D points of the shared edge computed from each
    /// tile are `gap_m` apart (more than [`crate::display::SEAM_TOL_M`]).
    SeamMismatch { other: String, gap_m: f64 },
    /// The tile id cannot be a file name (see `check_file_name`).
    BadTileId { reason: &'static str },
    /// The two tiles (active area and bezels) pass through or lie on each other in the room.
    RoomOverlap { other: String },
}

impl fmt::Display for Problem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        use crate::display::{PERPENDICULAR_COS_TOL, PITCH_REL_TOL, SEAM_TOL_M};
        match self {
            Self::NonFinite => write!(f, "is not a finite number"),
            Self::TooLarge { value } => write!(
                f,
                "{value:e} is beyond ±{:e} (metres or canvas pixels; a unit mistake?)",
                crate::display::MAX_COORD
            ),
            Self::Empty => write!(f, "must not be empty"),
            Self::FormAmbiguous { both: true } => {
                write!(f, "give either `tiles` or `generator`, not both")
            }
            Self::FormAmbiguous { both: false } => {
                write!(f, "missing: give either `tiles` or `generator`")
            }
            Self::TooManyTiles { count } => write!(
                f,
                "{count} tiles is more than the supported {}",
                crate::display::MAX_TILES
            ),
            Self::ResolutionOutOfRange { value } => {
                write!(f, "{value} pixels: must be between 1 and {}", u32::MAX)
            }
            Self::CountZero => write!(f, "must be at least 1"),
            Self::Negative {
                value,
                zero_allowed: true,
            } => write!(f, "{value} m is negative: it must be 0 or more"),
            Self::Negative {
                value,
                zero_allowed: false,
            } => write!(f, "{value} m: it must be more than 0"),
            Self::DegenerateEdge { length_m } => write!(
                f,
                "gives an active-area edge {length_m:e} m long (degenerate corners)"
            ),
            Self::NotPerpendicular { cos } => write!(
                f,
                "top and left edges are not perpendicular (cos = {cos:.3e}, tolerance \
                 {PERPENDICULAR_COS_TOL:e})"
            ),
            Self::DegenerateDirection => write!(
                f,
                "is zero or parallel to the normal, so it does not define an orientation"
            ),
            Self::YawStepTooLarge { deg } => write!(
                f,
                "{deg}° between columns: must be below 180° or the columns fold onto each other"
            ),
            Self::PitchAxes { x_m, y_m } => write!(
                f,
                "pixel pitch differs between the axes: {} mm across, {} mm down \
                 (relative tolerance {PITCH_REL_TOL:e}); check the resolution and the corners",
                crate::messages::number(x_m * 1e3),
                crate::messages::number(y_m * 1e3)
            ),
            Self::PitchModel { tile_m, model_m } => write!(
                f,
                "pixel pitch {} mm differs from the model's {} mm (relative tolerance \
                 {PITCH_REL_TOL:e}): one canvas needs one pitch",
                crate::messages::number(tile_m * 1e3),
                crate::messages::number(model_m * 1e3)
            ),
            Self::DuplicateId => write!(f, "another tile already has this id"),
            Self::DuplicateGridPosition { other } => {
                write!(f, "tile {other:?} already has this column and row")
            }
            Self::CanvasOverlap { other, overlap_px } => write!(
                f,
                "canvas rectangle (active area + bezels) overlaps tile {other:?} by {:.4} × {:.4} \
                 px",
                overlap_px[0], overlap_px[1]
            ),
            Self::SeamMismatch { other, gap_m } => write!(
                f,
                "placement touches tile {other:?} on the canvas, but the shared edge is {:.3} mm \
                 apart in 3D (tolerance {:.3} mm): the canvas contradicts the corners",
                gap_m * 1e3,
                SEAM_TOL_M * 1e3
            ),
            Self::BadTileId { reason } => write!(
                f,
                "{reason}: tile ids name the files of `render --tiles`, so they must be plain \
                 file names (letters, digits, `-`, `_`, `.`)"
            ),
            Self::RoomOverlap { other } => write!(
                f,
                "the tile overlaps tile {} in the room (they pass through or lie on each other, \
                 beyond {} mm): check the corners",
                crate::messages::quote(other),
                super::overlap::OVERLAP_3D_TOL_M * 1e3
            ),
        }
    }
}
