//! The output map: which tile of a display model each desktop shows, and where (DESIGN.md §3,
//! the display model; docs/screens.md for labs). A wall is driven by one PC whose desktop spans
//! many monitors or by one PC per group of screens; either way every screen shows exactly its
//! tile's pixels at the tile's native resolution, one canvas pixel per screen pixel.
//!
//! # File format
//!
//! ```json
//! {
//!   "desktops": [
//!     {
//!       "name": "wall-pc-0", "origin": [0, 0], "size": [1920, 2160],
//!       "tiles": [
//!         { "id": "c0r0", "rect": [0, 0, 1920, 1080] },
//!         { "id": "c0r1", "rect": [0, 1080, 1920, 1080] }
//!       ]
//!     }
//!   ]
//! }
//! ```
//!
//! * `name`: the host or rank that drives the desktop; unique in the file.
//! * `origin`, `size`: the desktop in the operating system's physical pixels (`origin` may be
//!   negative, as Windows places monitors left of or above the primary one).
//! * `rect`: `[x, y, w, h]`, the part of the desktop one tile fills, in the same coordinates as
//!   `origin` (what `xrandr` or the display settings report for that monitor). `w`, `h` are the
//!   tile's resolution: a screen shows its tile unscaled.
//!
//! # Validation
//!
//! [`OutputMap::from_json`] checks the map against a model before anything opens, naming the
//! file, the desktop, the tile and the field: JSON syntax and unknown fields (line and column),
//! no desktops, empty or repeated desktop names, empty desktops, sizes ≤ 0, coordinates beyond
//! [`MAX_DESKTOP_PX`], unknown tile ids, a tile shown twice, a rectangle that is not the tile's
//! native size, off its desktop, or overlapping another rectangle of its desktop. A tile may be
//! left out (a screen that is off).

use std::fmt;

use super::DisplayModel;
use super::cut::canvas_pixel_size;

/// The largest output-map file read: a line a tile, some 50 bytes each.
pub const MAX_OUTPUTS_BYTES: u64 = 1 << 20;

/// Largest magnitude of any desktop coordinate or size (pixels): far beyond any desktop, and it
/// keeps the sums of the checks far from overflow.
pub const MAX_DESKTOP_PX: i64 = 1 << 24;

/// A map file: the desktops in order.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputMapSpec {
    pub desktops: Vec<Desktop>,
}

/// One desktop: a host's (or rank's) screen space and the tiles it shows.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Desktop {
    pub name: String,
    /// Top-left corner, physical pixels.
    pub origin: [i64; 2],
    /// `[width, height]`, physical pixels. Signed so that a negative size reaches the
    /// validator, whose error names the desktop.
    pub size: [i64; 2],
    pub tiles: Vec<ShownTile>,
}

/// One tile on a desktop.
#[derive(Clone, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShownTile {
    /// The tile id, as the display model names it.
    pub id: String,
    /// `[x, y, w, h]` in the desktop's coordinates.
    pub rect: [i64; 4],
}

/// Everything that can go wrong reading an output map.
#[derive(Debug, thiserror::Error)]
pub enum OutputMapError {
    #[error("{file}: cannot read the output map: {source}")]
    Io {
        file: String,
        #[source]
        source: std::io::Error,
    },
    /// JSON syntax, a wrong type or an unknown field (1-based line and column).
    #[error("{file}:{line}:{column}: {message}")]
    Json {
        file: String,
        line: usize,
        column: usize,
        message: String,
    },
    /// Well-formed, but not a map of this model's tiles.
    #[error("{file}: {}{}field `{field}`: {problem}", prefix("desktop", .desktop), prefix("tile", .tile))]
    Invalid {
        file: String,
        desktop: Option<String>,
        tile: Option<String>,
        /// The JSON path, e.g. `desktops[1].tiles[0].rect`.
        field: String,
        /// Boxed: the rectangles it names would make every `Result` of the map large.
        problem: Box<OutputProblem>,
    },
}

fn prefix(what: &str, name: &Option<String>) -> String {
    match name {
        Some(n) => format!("{what} {}: ", crate::messages::quote(n)),
        None => String::new(),
    }
}

impl OutputMapError {
    /// The validation problem, when the error is one.
    #[must_use]
    pub fn problem(&self) -> Option<&OutputProblem> {
        match self {
            Self::Invalid { problem, .. } => Some(problem),
            _ => None,
        }
    }
}

/// What is wrong with a field of an output map.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum OutputProblem {
    /// The map has no desktops.
    NoDesktops,
    /// A desktop name is empty.
    EmptyName,
    /// Another desktop has this name.
    DuplicateName,
    /// A desktop shows no tiles.
    EmptyDesktop,
    /// A width or height ≤ 0.
    SizeNotPositive { value: i64 },
    /// A coordinate or size beyond [`MAX_DESKTOP_PX`].
    TooLarge { value: i64 },
    /// The model has no tile of this id.
    UnknownTile { model: String, tiles: String },
    /// The tile is already shown (on this desktop or another).
    ShownTwice { first: String },
    /// The rectangle is not the tile's resolution.
    NotNativeSize { size: [i64; 2], native: [u32; 2] },
    /// The rectangle reaches outside its desktop.
    OffDesktop { rect: [i64; 4], desktop: [i64; 4] },
    /// The rectangle overlaps another tile's on the same desktop.
    Overlap { other: String, overlap: [i64; 2] },
}

impl fmt::Display for OutputProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let r = |r: &[i64; 4]| format!("{}×{} at ({}, {})", r[2], r[3], r[0], r[1]);
        match self {
            Self::NoDesktops => write!(f, "the map lists no desktops"),
            Self::EmptyName => write!(f, "must not be empty (the host or rank of the desktop)"),
            Self::DuplicateName => write!(f, "another desktop already has this name"),
            Self::EmptyDesktop => write!(f, "the desktop shows no tiles"),
            Self::SizeNotPositive { value } => write!(f, "{value} pixels: must be at least 1"),
            Self::TooLarge { value } => {
                write!(f, "{value} pixels is beyond ±{MAX_DESKTOP_PX}")
            }
            Self::UnknownTile { model, tiles } => {
                write!(f, "{model} has no tile of this id (its tiles: {tiles})")
            }
            Self::ShownTwice { first } => write!(f, "the tile is already shown at {first}"),
            Self::NotNativeSize { size, native } => write!(
                f,
                "{}×{} pixels, but the tile is {}×{}: a screen shows its tile at native size",
                size[0], size[1], native[0], native[1]
            ),
            Self::OffDesktop { rect, desktop } => {
                write!(f, "{} reaches outside the desktop, {}", r(rect), r(desktop))
            }
            Self::Overlap { other, overlap } => write!(
                f,
                "overlaps tile {} by {}×{} pixels",
                crate::messages::quote(other),
                overlap[0],
                overlap[1]
            ),
        }
    }
}

/// A checked output map: constructed only by validating against a display model.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OutputMap {
    desktops: Vec<Desktop>,
}

impl OutputMap {
    /// Reads and checks a map file (at most [`MAX_OUTPUTS_BYTES`]) against `model`.
    pub fn load(path: &std::path::Path, model: &DisplayModel) -> Result<Self, OutputMapError> {
        let file = path.display().to_string();
        let text = crate::input::read_text(path, MAX_OUTPUTS_BYTES, "an output map").map_err(
            |source| OutputMapError::Io {
                file: file.clone(),
                source,
            },
        )?;
        Self::from_json(&text, &file, model)
    }

    /// Parses and checks a map; `file` names the text in errors. Never panics.
    pub fn from_json(text: &str, file: &str, model: &DisplayModel) -> Result<Self, OutputMapError> {
        let spec: OutputMapSpec = serde_json::from_str(text).map_err(|e| OutputMapError::Json {
            file: file.to_owned(),
            line: e.line(),
            column: e.column(),
            message: crate::messages::json_message(&e, text),
        })?;
        Self::from_spec(spec, file, model)
    }

    /// Checks a map against `model` (see the module's validation list).
    pub fn from_spec(
        spec: OutputMapSpec,
        file: &str,
        model: &DisplayModel,
    ) -> Result<Self, OutputMapError> {
        let err = |desktop: Option<&str>, tile: Option<&str>, field: String, problem| {
            OutputMapError::Invalid {
                file: file.to_owned(),
                desktop: desktop.map(str::to_owned),
                tile: tile.map(str::to_owned),
                field,
                problem: Box::new(problem),
            }
        };
        if spec.desktops.is_empty() {
            return Err(err(
                None,
                None,
                "desktops".into(),
                OutputProblem::NoDesktops,
            ));
        }
        // Where each model tile is first shown: "desktop NAME (desktops[d].tiles[t])".
        let mut shown: Vec<Option<String>> = vec![None; model.tiles().len()];
        for (d, desk) in spec.desktops.iter().enumerate() {
            let name = desk.name.as_str();
            let at = |field: &str| format!("desktops[{d}].{field}");
            if name.trim().is_empty() {
                return Err(err(None, None, at("name"), OutputProblem::EmptyName));
            }
            if spec.desktops[..d].iter().any(|o| o.name == desk.name) {
                return Err(err(
                    Some(name),
                    None,
                    at("name"),
                    OutputProblem::DuplicateName,
                ));
            }
            for (k, &v) in desk.origin.iter().enumerate() {
                check_coord(v)
                    .map_err(|p| err(Some(name), None, at(&format!("origin[{k}]")), p))?;
            }
            for (k, &v) in desk.size.iter().enumerate() {
                check_size(v).map_err(|p| err(Some(name), None, at(&format!("size[{k}]")), p))?;
            }
            if desk.tiles.is_empty() {
                return Err(err(
                    Some(name),
                    None,
                    at("tiles"),
                    OutputProblem::EmptyDesktop,
                ));
            }
            let bounds = [desk.origin[0], desk.origin[1], desk.size[0], desk.size[1]];
            for (t, shown_tile) in desk.tiles.iter().enumerate() {
                let id = shown_tile.id.as_str();
                let field = |f: &str| format!("desktops[{d}].tiles[{t}].{f}");
                let bad = |f: &str, p| err(Some(name), Some(id), field(f), p);
                let Some(i) = model.tile_index(id) else {
                    return Err(bad(
                        "id",
                        OutputProblem::UnknownTile {
                            model: model.name().to_owned(),
                            tiles: tile_names(model),
                        },
                    ));
                };
                if let Some(first) = &shown[i] {
                    return Err(bad(
                        "id",
                        OutputProblem::ShownTwice {
                            first: first.clone(),
                        },
                    ));
                }
                shown[i] = Some(format!(
                    "desktop {} (desktops[{d}].tiles[{t}])",
                    crate::messages::quote(name)
                ));
                let rect = shown_tile.rect;
                for (k, &v) in rect[..2].iter().enumerate() {
                    check_coord(v).map_err(|p| bad(&format!("rect[{k}]"), p))?;
                }
                for (k, &v) in rect[2..].iter().enumerate() {
                    check_size(v).map_err(|p| bad(&format!("rect[{}]", k + 2), p))?;
                }
                let native = model.tiles()[i].resolution();
                if [rect[2], rect[3]] != native.map(i64::from) {
                    return Err(bad(
                        "rect",
                        OutputProblem::NotNativeSize {
                            size: [rect[2], rect[3]],
                            native,
                        },
                    ));
                }
                let inside = rect[0] >= bounds[0]
                    && rect[1] >= bounds[1]
                    && rect[0] + rect[2] <= bounds[0] + bounds[2]
                    && rect[1] + rect[3] <= bounds[1] + bounds[3];
                if !inside {
                    return Err(bad(
                        "rect",
                        OutputProblem::OffDesktop {
                            rect,
                            desktop: bounds,
                        },
                    ));
                }
                if let Some(other) = desk.tiles[..t]
                    .iter()
                    .find_map(|o| overlap(&o.rect, &rect).map(|a| (o, a)))
                {
                    return Err(bad(
                        "rect",
                        OutputProblem::Overlap {
                            other: other.0.id.clone(),
                            overlap: other.1,
                        },
                    ));
                }
            }
        }
        Ok(Self {
            desktops: spec.desktops,
        })
    }

    /// One desktop spanning the whole canvas at native size ([`canvas_pixel_size`]), origin
    /// (0, 0), every tile at its canvas position (rounded to whole pixels) relative to the
    /// canvas's top-left corner; bezel gaps are covered by no rectangle. Checked like a file,
    /// so a model whose rounded positions would overlap is refused rather than mapped.
    pub fn default_for(model: &DisplayModel) -> Result<Self, OutputMapError> {
        let min = model.canvas_rect().min;
        let size = canvas_pixel_size(model);
        let tiles = model
            .tiles()
            .iter()
            .map(|t| {
                let o = t.canvas_origin() - min;
                let [w, h] = t.resolution();
                ShownTile {
                    id: t.id().to_owned(),
                    rect: [
                        o.x.round() as i64,
                        o.y.round() as i64,
                        i64::from(w),
                        i64::from(h),
                    ],
                }
            })
            .collect();
        let spec = OutputMapSpec {
            desktops: vec![Desktop {
                name: "wall".into(),
                origin: [0, 0],
                size: size.map(i64::from),
                tiles,
            }],
        };
        Self::from_spec(
            spec,
            &format!("the default output map of {}", model.name()),
            model,
        )
    }

    /// The map for a model whose tiles form a `grid` of `[columns, rows]` (by their column and
    /// row; the canvas must agree), one desktop per `block` of `[columns, rows]` tiles, blocks
    /// numbered left to right, then top to bottom, named `rank0`, `rank1`, …. Each desktop has
    /// origin (0, 0) and holds its tiles side by side without gaps; where the grid is not a
    /// multiple of the block, the last blocks of a row or column hold the tiles that remain and
    /// their desktops are that much smaller (HORNET's 7×5 in 2×2 blocks: 1920×2160 desktops
    /// at the right edge, 3840×1080 at the bottom, 1920×1080 in the corner).
    pub fn grid(model: &DisplayModel, grid: [u32; 2], block: [u32; 2]) -> Result<Self, GridError> {
        let cells = grid_cells(model, grid)?;
        if block[0] == 0 || block[1] == 0 || block[0] > grid[0] || block[1] > grid[1] {
            return Err(GridError::Block { grid, block });
        }
        let [cols, rows] = grid.map(|n| n as usize);
        let res = |c: usize, r: usize| model.tiles()[cells[r * cols + c]].resolution();
        // A column's tiles share a width and a row's a height, or side by side is not a grid.
        let widths: Vec<u32> = (0..cols).map(|c| res(c, 0)[0]).collect();
        let heights: Vec<u32> = (0..rows).map(|r| res(0, r)[1]).collect();
        for r in 0..rows {
            for c in 0..cols {
                let [w, h] = res(c, r);
                if w != widths[c] || h != heights[r] {
                    return Err(GridError::Ragged {
                        tile: model.tiles()[cells[r * cols + c]].id().to_owned(),
                        size: [w, h],
                        expected: [widths[c], heights[r]],
                    });
                }
            }
        }
        let [bc, br] = block.map(|n| n as usize);
        let mut desktops = Vec::new();
        for r0 in (0..rows).step_by(br) {
            for c0 in (0..cols).step_by(bc) {
                let (c1, r1) = ((c0 + bc).min(cols), (r0 + br).min(rows));
                let mut tiles = Vec::new();
                let mut y = 0i64;
                for r in r0..r1 {
                    let mut x = 0i64;
                    for c in c0..c1 {
                        let t = &model.tiles()[cells[r * cols + c]];
                        let [w, h] = t.resolution().map(i64::from);
                        tiles.push(ShownTile {
                            id: t.id().to_owned(),
                            rect: [x, y, w, h],
                        });
                        x += w;
                    }
                    y += i64::from(heights[r]);
                }
                let width: i64 = widths[c0..c1].iter().map(|&w| i64::from(w)).sum();
                desktops.push(Desktop {
                    name: format!("rank{}", desktops.len()),
                    origin: [0, 0],
                    size: [width, y],
                    tiles,
                });
            }
        }
        Self::from_spec(
            OutputMapSpec { desktops },
            &format!("the {}x{} output map of {}", grid[0], grid[1], model.name()),
            model,
        )
        .map_err(GridError::Map)
    }

    #[must_use]
    pub fn desktops(&self) -> &[Desktop] {
        &self.desktops
    }

    /// The file form as JSON laid out for people: a line per desktop header and per tile.
    #[must_use]
    pub fn to_json_pretty(&self) -> String {
        fn js(s: &str) -> String {
            serde_json::to_string(s).unwrap_or_default()
        }
        let desktops: Vec<String> = self
            .desktops
            .iter()
            .map(|d| {
                let tiles: Vec<String> = d
                    .tiles
                    .iter()
                    .map(|t| {
                        let [x, y, w, h] = t.rect;
                        format!(
                            "        {{ \"id\": {}, \"rect\": [{x}, {y}, {w}, {h}] }}",
                            js(&t.id)
                        )
                    })
                    .collect();
                format!(
                    "    {{\n      \"name\": {}, \"origin\": [{}, {}], \"size\": [{}, {}],\n      \
                     \"tiles\": [\n{}\n      ]\n    }}",
                    js(&d.name),
                    d.origin[0],
                    d.origin[1],
                    d.size[0],
                    d.size[1],
                    tiles.join(",\n")
                )
            })
            .collect();
        format!("{{\n  \"desktops\": [\n{}\n  ]\n}}\n", desktops.join(",\n"))
    }
}

/// Why a model's tiles do not make the grid asked for, or the block does not fit it.
#[derive(Debug, thiserror::Error)]
pub enum GridError {
    #[error("{model} has {tiles} tiles, not the {} of a {}x{} grid", .grid[0] * .grid[1], .grid[0], .grid[1])]
    Count {
        model: String,
        tiles: usize,
        grid: [u32; 2],
    },
    #[error(
        "tile {tile:?} is at column {column}, row {row}: outside the {}x{} grid", .grid[0], .grid[1]
    )]
    Outside {
        tile: String,
        column: u32,
        row: u32,
        grid: [u32; 2],
    },
    #[error(
        "tile {tile:?} is not {} of tile {other:?} on the canvas, though the grid puts it there \
         (columns run left to right, rows top to bottom)",
        if *.across { "right" } else { "below" }
    )]
    Order {
        tile: String,
        other: String,
        across: bool,
    },
    #[error(
        "tile {tile:?} is {}×{}, but its column and row are {}×{}: tiles side by side on a \
         desktop need one width a column and one height a row",
        .size[0], .size[1], .expected[0], .expected[1]
    )]
    Ragged {
        tile: String,
        size: [u32; 2],
        expected: [u32; 2],
    },
    #[error(
        "a block of {}x{} tiles a desktop does not fit the {}x{} grid",
        .block[0], .block[1], .grid[0], .grid[1]
    )]
    Block { grid: [u32; 2], block: [u32; 2] },
    #[error(transparent)]
    Map(OutputMapError),
}

/// The model's tile index at each grid cell, row-major; checks that the tiles fill the grid
/// exactly and that the canvas agrees with their columns and rows.
fn grid_cells(model: &DisplayModel, grid: [u32; 2]) -> Result<Vec<usize>, GridError> {
    let n = model.tiles().len();
    if u64::from(grid[0]) * u64::from(grid[1]) != n as u64 {
        return Err(GridError::Count {
            model: model.name().to_owned(),
            tiles: n,
            grid,
        });
    }
    let cols = grid[0] as usize;
    let mut cells = vec![usize::MAX; n];
    for (i, t) in model.tiles().iter().enumerate() {
        if t.column() >= grid[0] || t.row() >= grid[1] {
            return Err(GridError::Outside {
                tile: t.id().to_owned(),
                column: t.column(),
                row: t.row(),
                grid,
            });
        }
        // The model's grid positions are unique, and there are as many tiles as cells: every
        // cell gets exactly one tile.
        cells[t.row() as usize * cols + t.column() as usize] = i;
    }
    let rect = |i: usize| model.tiles()[i].active_rect();
    for (k, &i) in cells.iter().enumerate() {
        let (c, r) = (k % cols, k / cols);
        let neighbours = [
            (c > 0).then(|| (cells[k - 1], true)),
            (r > 0).then(|| (cells[k - cols], false)),
        ];
        for (o, across) in neighbours.into_iter().flatten() {
            let ok = if across {
                rect(i).min.x >= rect(o).max.x - super::OVERLAP_TOL_PX
            } else {
                rect(i).min.y >= rect(o).max.y - super::OVERLAP_TOL_PX
            };
            if !ok {
                return Err(GridError::Order {
                    tile: model.tiles()[i].id().to_owned(),
                    other: model.tiles()[o].id().to_owned(),
                    across,
                });
            }
        }
    }
    Ok(cells)
}

fn check_coord(v: i64) -> Result<(), OutputProblem> {
    if v.abs() > MAX_DESKTOP_PX {
        Err(OutputProblem::TooLarge { value: v })
    } else {
        Ok(())
    }
}

fn check_size(v: i64) -> Result<(), OutputProblem> {
    if v <= 0 {
        Err(OutputProblem::SizeNotPositive { value: v })
    } else {
        check_coord(v)
    }
}

/// The overlap of two checked rectangles `[x, y, w, h]`, when it has an area.
fn overlap(a: &[i64; 4], b: &[i64; 4]) -> Option<[i64; 2]> {
    let w = (a[0] + a[2]).min(b[0] + b[2]) - a[0].max(b[0]);
    let h = (a[1] + a[3]).min(b[1] + b[3]) - a[1].max(b[1]);
    (w > 0 && h > 0).then_some([w, h])
}

/// The model's tile ids, the first eight and a count of the rest.
fn tile_names(model: &DisplayModel) -> String {
    let ids: Vec<&str> = model.tiles().iter().map(|t| t.id()).collect();
    if ids.len() <= 8 {
        ids.join(", ")
    } else {
        format!("{}, and {} more", ids[..8].join(", "), ids.len() - 8)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn hornet() -> DisplayModel {
        DisplayModel::open("hornet").unwrap().0
    }

    /// Two HORNET tiles side by side on one desktop, with `edit` applied to the JSON text.
    fn two_tiles(edit: impl Fn(&str) -> String) -> Result<OutputMap, OutputMapError> {
        let text = r#"{
  "desktops": [
    {
      "name": "pc0", "origin": [0, 0], "size": [3840, 1080],
      "tiles": [
        { "id": "c0r0", "rect": [0, 0, 1920, 1080] },
        { "id": "c1r0", "rect": [1920, 0, 1920, 1080] }
      ]
    }
  ]
}"#;
        OutputMap::from_json(&edit(text), "walls.json", &hornet())
    }

    /// The error's text, checked to name the file, the desktop and (when given) the tile.
    fn message(r: Result<OutputMap, OutputMapError>, desktop: &str, tile: Option<&str>) -> String {
        let e = r.unwrap_err().to_string();
        assert!(e.starts_with("walls.json: "), "{e}");
        assert!(e.contains(&format!("desktop \"{desktop}\"")), "{e}");
        if let Some(t) = tile {
            assert!(e.contains(&format!("tile \"{t}\"")), "{e}");
        }
        e
    }

    #[test]
    fn a_good_map_loads() {
        let m = two_tiles(str::to_owned).unwrap();
        assert_eq!(m.desktops().len(), 1);
        assert_eq!(m.desktops()[0].tiles[1].rect, [1920, 0, 1920, 1080]);
    }

    #[test]
    fn an_unknown_tile_is_named_with_the_model_tiles() {
        let e = message(
            two_tiles(|t| t.replace("c1r0", "c9r9")),
            "pc0",
            Some("c9r9"),
        );
        assert!(e.contains("desktops[0].tiles[1].id"), "{e}");
        assert!(
            e.contains("HORNET has no tile of this id (its tiles: c0r0"),
            "{e}"
        );
    }

    #[test]
    fn a_tile_shown_twice_names_where_it_was_first() {
        let e = message(
            two_tiles(|t| t.replace("\"c1r0\"", "\"c0r0\"")),
            "pc0",
            Some("c0r0"),
        );
        assert!(
            e.contains("already shown at desktop \"pc0\" (desktops[0].tiles[0])"),
            "{e}"
        );
        // On a second desktop too.
        let text = two_tiles(str::to_owned).unwrap().to_json_pretty().replace(
            "\n  ]\n}",
            ",\n    { \"name\": \"pc1\", \"origin\": [0, 0], \"size\": [1920, 1080], \"tiles\": \
             [{ \"id\": \"c1r0\", \"rect\": [0, 0, 1920, 1080] }] }\n  ]\n}",
        );
        let e = message(
            OutputMap::from_json(&text, "walls.json", &hornet()),
            "pc1",
            Some("c1r0"),
        );
        assert!(e.contains("desktops[1].tiles[0].id"), "{e}");
    }

    #[test]
    fn overlapping_rectangles_name_both_tiles() {
        let e = message(
            two_tiles(|t| t.replace("[1920, 0, 1920", "[1900, 0, 1920")),
            "pc0",
            Some("c1r0"),
        );
        assert!(
            e.contains("overlaps tile \"c0r0\" by 20×1080 pixels"),
            "{e}"
        );
        // Touching is fine.
        two_tiles(|t| {
            t.replace("[3840, 1080]", "[3840, 2160]")
                .replace("[1920, 0, 1920", "[1920, 1080, 1920")
        })
        .unwrap();
    }

    #[test]
    fn a_rectangle_off_the_desktop_is_refused() {
        let e = message(
            two_tiles(|t| t.replace("[3840, 1080]", "[3839, 1080]")),
            "pc0",
            Some("c1r0"),
        );
        assert!(e.contains("desktops[0].tiles[1].rect"), "{e}");
        assert!(
            e.contains("reaches outside the desktop, 3839×1080 at (0, 0)"),
            "{e}"
        );
        // The desktop's origin counts: rectangles are in the desktop's coordinates.
        message(
            two_tiles(|t| t.replace("\"origin\": [0, 0]", "\"origin\": [-1, 0]")),
            "pc0",
            Some("c1r0"),
        );
        two_tiles(|t| {
            t.replace("\"origin\": [0, 0]", "\"origin\": [-1920, 0]")
                .replace("[0, 0, 1920", "[-1920, 0, 1920")
                .replace("[1920, 0, 1920", "[0, 0, 1920")
        })
        .unwrap();
    }

    #[test]
    fn a_rectangle_not_at_native_size_is_refused() {
        let e = message(
            two_tiles(|t| t.replace("[0, 0, 1920, 1080]", "[0, 0, 1280, 720]")),
            "pc0",
            Some("c0r0"),
        );
        assert!(
            e.contains("1280×720 pixels, but the tile is 1920×1080"),
            "{e}"
        );
    }

    #[test]
    fn zero_and_negative_sizes_name_the_field() {
        let e = message(
            two_tiles(|t| t.replace("[1920, 0, 1920, 1080]", "[1920, 0, 0, 1080]")),
            "pc0",
            Some("c1r0"),
        );
        assert!(
            e.contains("`desktops[0].tiles[1].rect[2]`: 0 pixels: must be at least 1"),
            "{e}"
        );
        let e = message(
            two_tiles(|t| t.replace("[3840, 1080]", "[3840, -1080]")),
            "pc0",
            None,
        );
        assert!(e.contains("`desktops[0].size[1]`: -1080 pixels"), "{e}");
        let e = message(
            two_tiles(|t| t.replace("\"origin\": [0, 0]", "\"origin\": [99999999999, 0]")),
            "pc0",
            None,
        );
        assert!(e.contains("origin[0]") && e.contains("beyond"), "{e}");
    }

    #[test]
    fn empty_desktops_and_names_are_refused() {
        let e = message(
            OutputMap::from_json(
                r#"{"desktops": [{"name": "pc3", "origin": [0, 0], "size": [1, 1], "tiles": []}]}"#,
                "walls.json",
                &hornet(),
            ),
            "pc3",
            None,
        );
        assert!(
            e.contains("desktops[0].tiles`: the desktop shows no tiles"),
            "{e}"
        );
        let e = OutputMap::from_json(r#"{"desktops": []}"#, "walls.json", &hornet())
            .unwrap_err()
            .to_string();
        assert_eq!(e, "walls.json: field `desktops`: the map lists no desktops");
        let e = two_tiles(|t| t.replace("\"pc0\"", "\" \""))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("walls.json: field `desktops[0].name`: must not be empty"),
            "{e}"
        );
    }

    #[test]
    fn malformed_json_gives_line_and_column() {
        let e = two_tiles(|t| t.replace("\"rect\": [1920", "\"rekt\": [1920")).unwrap_err();
        assert!(matches!(e, OutputMapError::Json { line: 7, .. }), "{e}");
        assert!(e.to_string().starts_with("walls.json:7:"), "{e}");
        let e = two_tiles(|t| t.replace("]\n}", "")).unwrap_err();
        assert!(matches!(e, OutputMapError::Json { .. }), "{e}");
    }

    #[test]
    fn the_default_map_shows_every_hornet_tile_at_its_canvas_position() {
        let model = hornet();
        let m = OutputMap::default_for(&model).unwrap();
        let [d] = m.desktops() else {
            panic!("one desktop")
        };
        assert_eq!(d.size, canvas_pixel_size(&model).map(i64::from));
        assert_eq!(d.tiles.len(), 35);
        let min = model.canvas_rect().min;
        for (t, s) in model.tiles().iter().zip(&d.tiles) {
            assert_eq!(s.id, t.id());
            assert_eq!([s.rect[2], s.rect[3]], [1920, 1080]);
            let o = t.canvas_origin() - min;
            assert!((s.rect[0] as f64 - o.x).abs() <= 0.5 && (s.rect[1] as f64 - o.y).abs() <= 0.5);
        }
        for (i, a) in d.tiles.iter().enumerate() {
            for b in &d.tiles[..i] {
                assert_eq!(overlap(&a.rect, &b.rect), None, "{} {}", a.id, b.id);
            }
        }
        // The bezels are gaps: c1r0 starts more than a tile's width right of c0r0.
        assert!(d.tiles[model.tile_index("c1r0").unwrap()].rect[0] > 1920);
    }

    #[test]
    fn hornet_one_desktop_per_column() {
        let model = hornet();
        let m = OutputMap::grid(&model, [7, 5], [1, 5]).unwrap();
        assert_eq!(m.desktops().len(), 7);
        for (c, d) in m.desktops().iter().enumerate() {
            assert_eq!(d.name, format!("rank{c}"));
            assert_eq!(d.size, [1920, 5400]);
            let ids: Vec<&str> = d.tiles.iter().map(|t| t.id.as_str()).collect();
            let want: Vec<String> = (0..5).map(|r| format!("c{c}r{r}")).collect();
            assert_eq!(ids, want);
            assert_eq!(d.tiles[3].rect, [0, 3240, 1920, 1080]);
        }
    }

    #[test]
    fn hornet_in_two_by_two_blocks_with_partial_blocks_at_the_edges() {
        let m = OutputMap::grid(&hornet(), [7, 5], [2, 2]).unwrap();
        // 4 blocks across (the last one column wide), 3 down (the last one row high).
        let sizes: Vec<[i64; 2]> = m.desktops().iter().map(|d| d.size).collect();
        let mut want = Vec::new();
        for h in [2160, 2160, 1080] {
            for w in [3840, 3840, 3840, 1920] {
                want.push([w, h]);
            }
        }
        assert_eq!(sizes, want);
        assert_eq!(
            m.desktops().iter().map(|d| d.tiles.len()).sum::<usize>(),
            35
        );
        let d5 = &m.desktops()[5];
        let ids: Vec<&str> = d5.tiles.iter().map(|t| t.id.as_str()).collect();
        assert_eq!(ids, ["c2r2", "c3r2", "c2r3", "c3r3"]);
        assert_eq!(d5.tiles[3].rect, [1920, 1080, 1920, 1080]);
        // The whole grid on one desktop: no bezel gaps.
        let one = OutputMap::grid(&hornet(), [7, 5], [7, 5]).unwrap();
        assert_eq!(one.desktops()[0].size, [13440, 5400]);
    }

    #[test]
    fn a_grid_the_model_does_not_form_is_refused() {
        let model = hornet();
        let e = OutputMap::grid(&model, [5, 7], [1, 1])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("tile \"c5r0\" is at column 5, row 0: outside the 5x7 grid"),
            "{e}"
        );
        let e = OutputMap::grid(&model, [6, 5], [1, 1])
            .unwrap_err()
            .to_string();
        assert_eq!(e, "HORNET has 35 tiles, not the 30 of a 6x5 grid");
        let e = OutputMap::grid(&model, [7, 5], [8, 1])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("8x1 tiles a desktop does not fit the 7x5 grid"),
            "{e}"
        );
    }

    #[test]
    fn a_grid_whose_canvas_disagrees_with_its_columns_is_refused() {
        // HORNET with the column numbers of c0 and c1 swapped: the grid says c1r* is left.
        let mut spec = hornet().to_spec();
        for t in spec.tiles.as_mut().unwrap() {
            t.column = match t.column {
                0 => 1,
                1 => 0,
                c => c,
            };
        }
        let model = DisplayModel::from_spec(&spec, "swapped").unwrap();
        let e = OutputMap::grid(&model, [7, 5], [1, 5])
            .unwrap_err()
            .to_string();
        assert!(e.contains("is not right of tile"), "{e}");
    }

    #[test]
    fn maps_round_trip_through_their_json() {
        let model = hornet();
        for m in [
            OutputMap::default_for(&model).unwrap(),
            OutputMap::grid(&model, [7, 5], [2, 2]).unwrap(),
        ] {
            let back = OutputMap::from_json(&m.to_json_pretty(), "back.json", &model).unwrap();
            assert_eq!(back, m);
        }
    }
}
