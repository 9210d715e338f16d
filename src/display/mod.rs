//! Display models: tiles, the unrolled canvas, and the mappings between canvas, tile, 3D point
//! and image pixel (DESIGN.md §3).
//!
//! # Frames
//!
//! * **Room frame** (DESIGN.md §2): right-handed, metres, +X right when facing the wall, +Y up,
//!   +Z from the wall towards the viewer.
//! * **Tile pixels**: (0, 0) at the active area's top-left corner, x right, y down, as seen from
//!   the front; pixel `(i, j)` has its centre at `(i + 0.5, j + 0.5)`.
//! * **Canvas**: the display surface unrolled into a plane, in pixels at the physical pixel pitch
//!   (x right, y down). Each tile's active area covers exactly its resolution on the canvas, so
//!   canvas and tile pixels differ by a translation; bezels take `bezel / pitch` canvas pixels.
//!   For walls of planar tiles hinged along vertical edges the unrolling is exact: distance on
//!   the canvas is distance along the wall.
//! * **Image**: the rendered image (e.g. 3840×2160) covers the canvas bounding rectangle, each
//!   axis scaled on its own; image pixel `(i, j)` has its centre at `(i + 0.5, j + 0.5)`.
//!
//! # File format (`display-models/*.json`)
//!
//! ```json
//! {
//!   "name": "HORNET",
//!   "notes": "where the numbers come from; which ones are assumptions",
//!   "tiles": [
//!     {
//!       "id": "c0r0", "column": 0, "row": 0,
//!       "resolution": [1920, 1080],
//!       "top_left": [-3.6, 1.5, 0.6], "top_right": [...], "bottom_left": [...],
//!       "bezel": { "left": 0.003, "right": 0.003, "top": 0.003, "bottom": 0.003 },
//!       "canvas": [5.66, 5.66]
//!     }
//!   ]
//! }
//! ```
//!
//! * `resolution`: pixels `[width, height]`.
//! * `top_left`, `top_right`, `bottom_left`: corners of the *active area* (lit pixels), room
//!   frame, metres, as seen from the front. The tile's front (its normal, towards the viewer) is
//!   `(bottom_left − top_left) × (top_right − top_left)`.
//! * `bezel`: frame widths around the active area, metres, each ≥ 0.
//! * `canvas`: canvas position `[x, y]` of the active area's top-left corner, canvas pixels
//!   (fractional values are fine: bezels are rarely a whole number of pixels).
//!
//! Instead of `tiles` a model may give a `generator` (see [`GeneratorSpec`] and
//! `generator.rs` for the construction):
//!
//! ```json
//! "generator": {
//!   "columns": 7, "rows": 5, "resolution": [1920, 1080],
//!   "active_size": [1.0181, 0.5727],
//!   "bezel": { "left": 0.003, "right": 0.003, "top": 0.003, "bottom": 0.003 },
//!   "yaw_step_deg": 10.0,
//!   "center": [0, 0, 0], "normal": [0, 0, 1], "up": [0, 1, 0]
//! }
//! ```
//!
//! Columns are hinged along the outer edges of their bezels and turned by `yaw_step_deg`
//! against each other (positive: curving towards the viewer); `center` is where the 3D point of
//! the canvas centre goes, `normal` the direction the wall faces there. Tiles get ids
//! `c{column}r{row}`, column 0 leftmost and row 0 on top. `raygun display expand FILE` prints the
//! explicit form, which loads back into the same model.
//!
//! # Validation
//!
//! The loader rejects, naming the file, the tile and the field: JSON syntax and type errors
//! (with line and column), unknown fields, non-finite or absurdly large numbers, resolutions
//! ≤ 0, degenerate corners (an edge shorter than [`MIN_EDGE_M`], or top and left edges not
//! perpendicular within [`PERPENDICULAR_COS_TOL`]), a pixel pitch that differs between a tile's
//! axes or from the model pitch by more than [`PITCH_REL_TOL`], duplicate ids or grid positions,
//! overlapping canvas rectangles (active area + bezels, beyond [`OVERLAP_TOL_PX`]), and canvas
//! placements that contradict the 3D geometry: where two canvas rectangles share an edge, the 3D
//! points of that edge computed from each tile must agree within [`SEAM_TOL_M`]. Tiles that
//! overlap in the room (beyond [`OVERLAP_3D_TOL_M`]) and tile ids that cannot be plain file
//! names ([`check_file_name`]: `render --tiles` writes `<id>.<ext>`) are rejected too.

pub mod cut;
mod error;
mod generator;
mod intersect;
pub mod outputs;
mod overlap;
mod rect;
mod spec;
mod tile;
mod validate;

use std::path::Path;

use glam::{DVec2, DVec3};

pub use error::{DisplayModelError, Problem};
pub use intersect::{EDGE_SLACK_PX, Hit, PARALLEL_COS, T_MIN_M, T_TIE_M};
pub use overlap::OVERLAP_3D_TOL_M;
pub use rect::Rect;
pub use spec::{Bezel, DisplayModelSpec, GeneratorSpec, TileSpec};
pub use tile::Tile;
pub use validate::{MAX_TILE_ID_CHARS, check_file_name};

/// Relative tolerance on pixel pitch, between a tile's two axes and between a tile and the model.
/// Panel datasheets give active sizes to 0.1 mm; on edges of 300 mm or more that rounding is at
/// most 1.7e-4 (HORNET's assumed panel: 3.3e-5, the 27-inch monitor: 5.6e-5), while a
/// resolution that is one pixel off on an edge of up to 3840 pixels is at least 2.6e-4.
pub const PITCH_REL_TOL: f64 = 2.5e-4;
/// How far apart (metres) the two tiles' 3D points of a shared canvas edge may be. A 1 mm error
/// is under two pixels at HORNET's 0.53 mm pitch and well inside a bezel, and it accepts corner
/// coordinates written to the millimetre.
pub const SEAM_TOL_M: f64 = 1e-3;
/// Canvas rectangles within this many pixels of each other along a common stretch count as
/// sharing an edge (and get the 3D check), so a slightly-off placement cannot dodge the check.
pub const SEAM_GAP_TOL_PX: f64 = 0.5;
/// Overlap (canvas pixels, on both axes) that still counts as touching: the rounding of
/// summing bezel and panel widths in f64 is about 1e-11 px on a 15 000 px canvas.
pub const OVERLAP_TOL_PX: f64 = 1e-6;
/// Largest |cos| of the angle between a tile's top and left edges: corners written to 0.1 mm on
/// edges of 100 mm or more skew them by at most 1e-3.
pub const PERPENDICULAR_COS_TOL: f64 = 1e-3;
/// Shortest active-area edge, metres (1 µm: far below any real pixel, far above zero).
pub const MIN_EDGE_M: f64 = 1e-6;
/// Largest magnitude of any coordinate (metres, canvas pixels): 1000 km or 1e6 pixels would be a
/// unit mistake, and the bound keeps squared lengths far from overflow.
pub const MAX_COORD: f64 = 1e6;
/// Largest number of tiles in a model (the validator compares every pair).
pub const MAX_TILES: usize = 4096;

/// A finite number of sane magnitude.
fn check_number(v: f64) -> Result<(), Problem> {
    if !v.is_finite() {
        Err(Problem::NonFinite)
    } else if v.abs() > MAX_COORD {
        Err(Problem::TooLarge { value: v })
    } else {
        Ok(())
    }
}

/// A pixel count from the file's signed integer.
fn resolution_u32(v: i64) -> Result<u32, Problem> {
    u32::try_from(v)
        .ok()
        .filter(|&n| n > 0)
        .ok_or(Problem::ResolutionOutOfRange { value: v })
}

/// A validated display model. Construct with [`DisplayModel::load`], [`DisplayModel::from_json`]
/// or [`DisplayModel::from_spec`]. Serde goes through the file form: serialising writes the
/// explicit form, deserialising validates (errors then name the source `<serde>`), so a model can
/// sit inside another configuration file.
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(into = "DisplayModelSpec", try_from = "DisplayModelSpec")]
pub struct DisplayModel {
    name: String,
    notes: String,
    tiles: Vec<Tile>,
    pitch_m: f64,
    // Cached: tiles' canvas rectangles at the model pitch, and their bounding box.
    rects: Vec<Rect>,
    canvas: Rect,
}

/// The models shipped in `display-models/`, built into the binary so that every command works
/// from any folder: (name, file name, JSON).
pub const BUILTIN_MODELS: [(&str, &str, &str); 3] = [
    (
        "hornet",
        "hornet.json",
        include_str!("../../display-models/hornet.json"),
    ),
    (
        "desktop-27in-4k",
        "desktop-27in-4k.json",
        include_str!("../../display-models/desktop-27in-4k.json"),
    ),
    (
        "projection-4m-4k",
        "projection-4m-4k.json",
        include_str!("../../display-models/projection-4m-4k.json"),
    ),
];

/// The largest display-model file read: an explicit model takes about 600 bytes a tile, so
/// this holds some 100 000 tiles.
pub const MAX_MODEL_BYTES: u64 = 64 << 20;

/// The display model commands use when none is given: the paper's HORNET wall.
pub const DEFAULT_MODEL: &str = "hornet";

/// Where a model opened by [`DisplayModel::open`] came from.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum ModelOrigin {
    /// A file, as named.
    File(std::path::PathBuf),
    /// A built-in model, by name.
    Builtin(&'static str),
}

impl std::fmt::Display for ModelOrigin {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::File(p) => write!(f, "{}", p.display()),
            Self::Builtin(name) => write!(f, "the built-in {name} model"),
        }
    }
}

impl DisplayModel {
    /// Opens a model named on the command line or in a file header: `builtin:NAME` or a bare
    /// built-in name (`hornet`, `desktop-27in-4k`, `projection-4m-4k`) is the built-in model; any
    /// other text is a file path. A path to a shipped model's file name that does not exist here
    /// (`display-models/hornet.json` run from another folder) falls back to the built-in copy,
    /// which is byte-identical to the shipped file.
    pub fn open(spec: &str) -> Result<(Self, ModelOrigin), DisplayModelError> {
        let builtin = |name: &str| BUILTIN_MODELS.iter().find(|(n, _, _)| *n == name);
        let from_builtin = |(name, _, json): &(&'static str, &str, &str)| {
            Self::from_json(json, &format!("builtin:{name}"))
                .map(|m| (m, ModelOrigin::Builtin(name)))
        };
        if let Some(name) = spec.strip_prefix("builtin:") {
            return builtin(name).map_or_else(
                || {
                    Err(DisplayModelError::Io {
                        file: spec.to_owned(),
                        source: std::io::Error::new(
                            std::io::ErrorKind::NotFound,
                            format!(
                                "no built-in display model of that name ({})",
                                builtin_names()
                            ),
                        ),
                    })
                },
                from_builtin,
            );
        }
        let path = Path::new(spec);
        if path.exists() {
            return Self::load(path).map(|m| (m, ModelOrigin::File(path.to_owned())));
        }
        if let Some(b) = builtin(spec) {
            return from_builtin(b);
        }
        let file_name = path.file_name().and_then(|n| n.to_str());
        if let Some(b) = BUILTIN_MODELS
            .iter()
            .find(|(_, file, _)| Some(*file) == file_name)
        {
            return from_builtin(b);
        }
        Err(DisplayModelError::Io {
            file: spec.to_owned(),
            source: std::io::Error::new(
                std::io::ErrorKind::NotFound,
                format!(
                    "no such file, and not a built-in display model ({})",
                    builtin_names()
                ),
            ),
        })
    }

    /// Reads and validates a model file.
    pub fn load(path: impl AsRef<Path>) -> Result<Self, DisplayModelError> {
        let path = path.as_ref();
        let file = path.display().to_string();
        let text = crate::input::read_text(path, MAX_MODEL_BYTES, "a display model").map_err(
            |source| DisplayModelError::Io {
                file: file.clone(),
                source,
            },
        )?;
        Self::from_json(&text, &file)
    }

    /// Parses and validates a model; `source_name` names the text in errors (a path, or e.g.
    /// `"<stdin>"`). Never panics, whatever the input.
    pub fn from_json(text: &str, source_name: &str) -> Result<Self, DisplayModelError> {
        let spec: DisplayModelSpec =
            serde_json::from_str(text).map_err(|e| json_error(&e, text, source_name))?;
        Self::from_spec(&spec, source_name)
    }

    /// Validates a spec (expanding a generator).
    pub fn from_spec(
        spec: &DisplayModelSpec,
        source_name: &str,
    ) -> Result<Self, DisplayModelError> {
        let invalid =
            |tile: Option<String>, field: String, problem: Problem| DisplayModelError::Invalid {
                file: source_name.to_owned(),
                tile,
                field,
                problem,
            };
        if spec.name.trim().is_empty() {
            return Err(invalid(None, "name".into(), Problem::Empty));
        }
        let expanded;
        let tile_specs: &[TileSpec] = match (&spec.tiles, &spec.generator) {
            (Some(tiles), None) => tiles,
            (None, Some(g)) => {
                expanded = generator::expand(g).map_err(|(f, p)| invalid(None, f, p))?;
                &expanded
            }
            (tiles, _) => {
                return Err(invalid(
                    None,
                    "tiles".into(),
                    Problem::FormAmbiguous {
                        both: tiles.is_some(),
                    },
                ));
            }
        };
        let (tiles, pitch_m) = validate::validate(tile_specs).map_err(|(t, f, p)| {
            // A generator's tiles overlap because of its yaw step: name the field to change.
            let f = if spec.generator.is_some() && matches!(p, Problem::RoomOverlap { .. }) {
                "generator.yaw_step_deg".to_owned()
            } else {
                f
            };
            invalid(t, f, p)
        })?;
        let rects: Vec<Rect> = tiles.iter().map(|t| t.canvas_rect(pitch_m)).collect();
        let canvas = rects[1..].iter().fold(rects[0], |acc, r| acc.union(r));
        Ok(Self {
            name: spec.name.clone(),
            notes: spec.notes.clone(),
            tiles,
            pitch_m,
            rects,
            canvas,
        })
    }

    /// The explicit file form (generators expanded).
    #[must_use]
    pub fn to_spec(&self) -> DisplayModelSpec {
        DisplayModelSpec {
            name: self.name.clone(),
            notes: self.notes.clone(),
            tiles: Some(self.tiles.iter().map(Tile::to_spec).collect()),
            generator: None,
        }
    }

    /// The explicit form as JSON laid out for people (one line per field of a tile, numbers
    /// in serde_json's shortest round-trip form), so [`Self::from_json`] gives back exactly this
    /// model.
    #[must_use]
    pub fn to_json_pretty(&self) -> String {
        // Serialising strings, integers and finite floats cannot fail.
        fn js<T: serde::Serialize + ?Sized>(v: &T) -> String {
            serde_json::to_string(v).unwrap_or_default()
        }
        let tiles: Vec<String> = self
            .tiles
            .iter()
            .map(|t| {
                let s = t.to_spec();
                format!(
                    "    {{\n      \"id\": {}, \"column\": {}, \"row\": {}, \"resolution\": {},\n      \
                     \"top_left\": {},\n      \"top_right\": {},\n      \"bottom_left\": {},\n      \
                     \"bezel\": {},\n      \"canvas\": {}\n    }}",
                    js(&s.id),
                    s.column,
                    s.row,
                    js(&s.resolution),
                    js(&s.top_left),
                    js(&s.top_right),
                    js(&s.bottom_left),
                    js(&s.bezel),
                    js(&s.canvas),
                )
            })
            .collect();
        format!(
            "{{\n  \"name\": {},\n  \"notes\": {},\n  \"tiles\": [\n{}\n  ]\n}}",
            js(&self.name),
            js(&self.notes),
            tiles.join(",\n")
        )
    }

    #[must_use]
    pub fn name(&self) -> &str {
        &self.name
    }

    #[must_use]
    pub fn notes(&self) -> &str {
        &self.notes
    }

    #[must_use]
    pub fn tiles(&self) -> &[Tile] {
        &self.tiles
    }

    /// The tile with this id.
    #[must_use]
    pub fn tile_index(&self, id: &str) -> Option<usize> {
        self.tiles.iter().position(|t| t.id() == id)
    }

    /// Metres per canvas pixel: the median of the tiles' pitches (all within
    /// [`PITCH_REL_TOL`] of it).
    #[must_use]
    pub fn pitch_m(&self) -> f64 {
        self.pitch_m
    }

    /// Bounding box of all tiles' canvas rectangles (with bezels).
    #[must_use]
    pub fn canvas_rect(&self) -> Rect {
        self.canvas
    }

    /// Canvas rectangle (with bezels) of tile `i`, at the model pitch.
    #[must_use]
    pub fn tile_canvas_rect(&self, i: usize) -> Rect {
        self.rects[i]
    }

    /// The tile whose canvas rectangle (with bezels) holds `c`; on an edge shared by two tiles,
    /// the one listed first. `None` outside every tile (off the canvas, or in a gap of a wall
    /// that is not a full grid).
    #[must_use]
    pub fn tile_at_canvas(&self, c: DVec2) -> Option<usize> {
        self.rects.iter().position(|r| r.contains(c))
    }

    /// The tile whose canvas rectangle is nearest to `c` (first listed on ties): the tile whose
    /// plane extends the surface to canvas points outside every tile.
    #[must_use]
    pub fn nearest_tile(&self, c: DVec2) -> usize {
        let mut best = (f64::INFINITY, 0);
        for (i, r) in self.rects.iter().enumerate() {
            let d = r.distance_to(c);
            if d < best.0 {
                best = (d, i);
            }
        }
        best.1
    }

    /// The room-frame point of a canvas point (bezels included); `None` outside every tile.
    #[must_use]
    pub fn canvas_to_point(&self, c: DVec2) -> Option<DVec3> {
        self.tile_at_canvas(c)
            .map(|i| self.tiles[i].canvas_to_point(c))
    }

    /// Image pixel coordinates (pixel centres at `i + 0.5`) → canvas point. Each axis is scaled
    /// on its own so the image covers the canvas bounding rectangle.
    #[must_use]
    pub fn image_to_canvas(&self, image_px: DVec2, image_size: [u32; 2]) -> DVec2 {
        let size = DVec2::new(f64::from(image_size[0]), f64::from(image_size[1]));
        self.canvas.min + image_px * (self.canvas.size() / size)
    }

    /// Canvas point → image pixel coordinates; the inverse of [`Self::image_to_canvas`].
    #[must_use]
    pub fn canvas_to_image(&self, c: DVec2, image_size: [u32; 2]) -> DVec2 {
        let size = DVec2::new(f64::from(image_size[0]), f64::from(image_size[1]));
        (c - self.canvas.min) * (size / self.canvas.size())
    }
}

/// "built-in models: hornet, desktop-27in-4k, projection-4m-4k".
fn builtin_names() -> String {
    let names: Vec<&str> = BUILTIN_MODELS.iter().map(|(n, _, _)| *n).collect();
    format!("built-in models: {}", names.join(", "))
}

impl TryFrom<DisplayModelSpec> for DisplayModel {
    type Error = DisplayModelError;

    fn try_from(spec: DisplayModelSpec) -> Result<Self, Self::Error> {
        Self::from_spec(&spec, "<serde>")
    }
}

impl From<DisplayModel> for DisplayModelSpec {
    fn from(m: DisplayModel) -> Self {
        m.to_spec()
    }
}

/// serde_json's message without its " at line L column C" suffix (we print the position first,
/// compiler style).
fn json_error(e: &serde_json::Error, text: &str, file: &str) -> DisplayModelError {
    let message = crate::messages::json_message(e, text);
    DisplayModelError::Json {
        file: file.to_owned(),
        line: e.line(),
        column: e.column(),
        message,
    }
}
