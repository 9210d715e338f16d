//! The file form of a display model: plain serde types, exactly what `display-models/*.json`
//! holds. Nothing here is validated; [`super::DisplayModel::from_spec`] turns a spec into a
//! checked model. Numbers stay plain arrays (`[f64; 3]`, not glam types) so the JSON reads the
//! same whether it was written by hand or by `raygun display expand`.

use serde::{Deserialize, Serialize};

/// A whole model file: either explicit `tiles` or a `generator`, never both.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DisplayModelSpec {
    /// Short name, e.g. "HORNET".
    pub name: String,
    /// Free text: where the numbers come from and which of them are assumptions.
    #[serde(default)]
    pub notes: String,
    /// The explicit form.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub tiles: Option<Vec<TileSpec>>,
    /// The compact form, expanded by the loader.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub generator: Option<GeneratorSpec>,
}

/// One tile in the explicit form. Corners are the corners of the *active area* (the lit pixels)
/// in the room frame, metres; `canvas` is where that active area's top-left corner sits on the
/// canvas, in canvas pixels.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TileSpec {
    pub id: String,
    pub column: u32,
    pub row: u32,
    /// Pixels `[width, height]`. Signed so that a negative value reaches the validator, whose
    /// error names the tile, instead of failing inside serde with only a line number.
    pub resolution: [i64; 2],
    pub top_left: [f64; 3],
    pub top_right: [f64; 3],
    pub bottom_left: [f64; 3],
    pub bezel: Bezel,
    /// Canvas position `[x, y]` (pixels, x right, y down) of the active area's top-left corner.
    pub canvas: [f64; 2],
}

/// Frame widths around the active area, metres. A single display's frame does not interrupt the
/// picture, so single-tile models use zeros.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Bezel {
    pub left: f64,
    pub right: f64,
    pub top: f64,
    pub bottom: f64,
}

impl Bezel {
    /// The four widths with their field names, for validation messages.
    #[must_use]
    pub fn named(&self) -> [(&'static str, f64); 4] {
        [
            ("bezel.left", self.left),
            ("bezel.right", self.right),
            ("bezel.top", self.top),
            ("bezel.bottom", self.bottom),
        ]
    }
}

/// The compact form: a grid of identical planar panels, `columns` × `rows`, neighbouring columns
/// hinged along the outer edges of their bezels and turned by `yaw_step_deg` against each other.
/// A positive step curves the wall towards the viewer (the outer columns come forward), like
/// HORNET. Rows of one column share one plane.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GeneratorSpec {
    pub columns: u32,
    pub rows: u32,
    /// Pixels per panel `[width, height]` (signed for the same reason as [`TileSpec`]).
    pub resolution: [i64; 2],
    /// Active area per panel `[width, height]`, metres.
    pub active_size: [f64; 2],
    pub bezel: Bezel,
    /// Angle between neighbouring columns, degrees; |step| < 180.
    #[serde(default)]
    pub yaw_step_deg: f64,
    /// Where the wall centre goes in the room frame. The wall centre is the 3D point of the
    /// canvas centre (with an odd number of columns and rows and symmetric bezels: the centre of
    /// the central tile).
    #[serde(default)]
    pub center: [f64; 3],
    /// The direction the wall faces at its centre (towards the viewer). Default +Z.
    #[serde(default = "default_normal")]
    pub normal: [f64; 3],
    /// Up at the wall centre; made perpendicular to `normal`. Default +Y.
    #[serde(default = "default_up")]
    pub up: [f64; 3],
}

fn default_normal() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

fn default_up() -> [f64; 3] {
    [0.0, 1.0, 0.0]
}
