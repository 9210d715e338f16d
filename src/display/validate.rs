//! Validation of explicit tiles: each tile on its own, then the model's pitch, then every pair
//! of tiles on the canvas (overlap, and shared edges against the 3D geometry).

use std::collections::HashMap;

use glam::{DVec2, DVec3};

use super::error::Problem;
use super::rect::Rect;
use super::spec::TileSpec;
use super::tile::Tile;
use super::{
    MAX_TILES, MIN_EDGE_M, OVERLAP_TOL_PX, PERPENDICULAR_COS_TOL, PITCH_REL_TOL, SEAM_GAP_TOL_PX,
    SEAM_TOL_M, check_number, resolution_u32,
};

/// A validation failure before the file name is attached: tile id (if any), field, problem.
pub(crate) type Failure = (Option<String>, String, Problem);

fn fail(tile: &str, field: &str, problem: Problem) -> Failure {
    (Some(tile.to_owned()), field.to_owned(), problem)
}

/// Checks `specs` and builds the tiles and the model pitch (metres per canvas pixel).
pub(crate) fn validate(specs: &[TileSpec]) -> Result<(Vec<Tile>, f64), Failure> {
    if specs.is_empty() {
        return Err((None, "tiles".into(), Problem::Empty));
    }
    if specs.len() > MAX_TILES {
        return Err((
            None,
            "tiles".into(),
            Problem::TooManyTiles {
                count: specs.len() as u64,
            },
        ));
    }
    let mut ids: HashMap<&str, usize> = HashMap::new();
    let mut grid: HashMap<(u32, u32), &str> = HashMap::new();
    let mut tiles = Vec::with_capacity(specs.len());
    for (i, s) in specs.iter().enumerate() {
        if s.id.is_empty() {
            // No id to name: name the tile by its place in the list.
            return Err((Some(format!("#{i}")), "id".into(), Problem::Empty));
        }
        if let Err(reason) = check_file_name(&s.id) {
            return Err(fail(&s.id, "id", Problem::BadTileId { reason }));
        }
        if ids.insert(&s.id, i).is_some() {
            return Err(fail(&s.id, "id", Problem::DuplicateId));
        }
        if let Some(other) = grid.insert((s.column, s.row), &s.id) {
            return Err(fail(
                &s.id,
                "column",
                Problem::DuplicateGridPosition {
                    other: other.to_owned(),
                },
            ));
        }
        tiles.push(check_tile(s)?);
    }

    // One canvas, one pitch. The median (not the mean) is the reference so that the odd tile out
    // is the one blamed; for a uniform wall all three agree exactly.
    let mut pitches: Vec<f64> = tiles
        .iter()
        .map(|t| t.pitch().element_sum() * 0.5)
        .collect();
    pitches.sort_by(f64::total_cmp);
    let n = pitches.len();
    let pitch = if n % 2 == 1 {
        pitches[n / 2]
    } else {
        (pitches[n / 2 - 1] + pitches[n / 2]) * 0.5
    };
    for t in &tiles {
        for tile_m in t.pitch().to_array() {
            if ((tile_m - pitch) / pitch).abs() > PITCH_REL_TOL {
                return Err(fail(
                    t.id(),
                    "resolution",
                    Problem::PitchModel {
                        tile_m,
                        model_m: pitch,
                    },
                ));
            }
        }
    }

    let rects: Vec<Rect> = tiles.iter().map(|t| t.canvas_rect(pitch)).collect();
    for j in 0..tiles.len() {
        for i in 0..j {
            check_pair(&tiles[i], &rects[i], &tiles[j], &rects[j])?;
            if super::overlap::tiles_overlap(&tiles[i], &rects[i], &tiles[j], &rects[j], pitch) {
                return Err(fail(
                    tiles[j].id(),
                    "top_left",
                    Problem::RoomOverlap {
                        other: tiles[i].id().to_owned(),
                    },
                ));
            }
        }
    }
    Ok((tiles, pitch))
}

/// Longest tile id: `render --tiles` names files after ids, and 64 characters stay far inside
/// every file system's 255-byte limit with an extension added.
pub const MAX_TILE_ID_CHARS: usize = 64;

/// Why `id` cannot be a file name inside the output folder (`render --tiles DIR` writes
/// `DIR/<id>.<ext>`): path separators and `..` would leave the folder, and control characters,
/// the characters Windows forbids, its device names (`NUL`, `COM1`, …), and leading dots or
/// spaces (hidden files, names that shells and file managers mangle) make names a file system
/// or a person cannot handle.
pub fn check_file_name(id: &str) -> Result<(), &'static str> {
    if id.chars().count() > MAX_TILE_ID_CHARS {
        return Err("is longer than 64 characters");
    }
    if id.contains(['/', '\\']) {
        return Err("contains a path separator");
    }
    if id == "." || id == ".." || id.starts_with('.') {
        return Err("starts with a dot (`..` would leave the output folder; others hide the file)");
    }
    if id.chars().any(char::is_control) {
        return Err("contains a control character");
    }
    if id.contains(['<', '>', ':', '"', '|', '?', '*']) {
        return Err("contains one of < > : \" | ? * (not allowed in Windows file names)");
    }
    if id.starts_with(char::is_whitespace) || id.ends_with(char::is_whitespace) || id.ends_with('.')
    {
        return Err("starts or ends with a space, or ends with a dot");
    }
    let stem = id.split('.').next().unwrap_or(id).to_ascii_uppercase();
    let reserved = ["CON", "PRN", "AUX", "NUL"].contains(&stem.as_str())
        || (stem.len() == 4
            && (stem.starts_with("COM") || stem.starts_with("LPT"))
            && stem.as_bytes()[3].is_ascii_digit());
    if reserved {
        return Err("is a reserved device name on Windows");
    }
    Ok(())
}

fn check_tile(s: &TileSpec) -> Result<Tile, Failure> {
    let id = s.id.as_str();
    let res = [
        resolution_u32(s.resolution[0]).map_err(|p| fail(id, "resolution", p))?,
        resolution_u32(s.resolution[1]).map_err(|p| fail(id, "resolution", p))?,
    ];
    for (name, v) in [
        ("top_left", s.top_left),
        ("top_right", s.top_right),
        ("bottom_left", s.bottom_left),
    ] {
        for x in v {
            check_number(x).map_err(|p| fail(id, name, p))?;
        }
    }
    for x in s.canvas {
        check_number(x).map_err(|p| fail(id, "canvas", p))?;
    }
    for (name, v) in s.bezel.named() {
        check_number(v).map_err(|p| fail(id, name, p))?;
        if v < 0.0 {
            return Err(fail(
                id,
                name,
                Problem::Negative {
                    value: v,
                    zero_allowed: true,
                },
            ));
        }
    }
    let tl = DVec3::from_array(s.top_left);
    let top = DVec3::from_array(s.top_right) - tl;
    let left = DVec3::from_array(s.bottom_left) - tl;
    for (name, edge) in [("top_right", top), ("bottom_left", left)] {
        let length_m = edge.length();
        if length_m < MIN_EDGE_M {
            return Err(fail(id, name, Problem::DegenerateEdge { length_m }));
        }
    }
    let cos = top.dot(left) / (top.length() * left.length());
    if cos.abs() > PERPENDICULAR_COS_TOL {
        return Err(fail(id, "bottom_left", Problem::NotPerpendicular { cos }));
    }
    let pitch = DVec2::new(
        top.length() / f64::from(res[0]),
        left.length() / f64::from(res[1]),
    );
    if ((pitch.x - pitch.y) / pitch.max_element()).abs() > PITCH_REL_TOL {
        return Err(fail(
            id,
            "resolution",
            Problem::PitchAxes {
                x_m: pitch.x,
                y_m: pitch.y,
            },
        ));
    }
    Ok(Tile::from_checked(s, res))
}

/// Overlap and shared-edge checks for one pair; errors name the later tile `b`.
fn check_pair(a: &Tile, ra: &Rect, b: &Tile, rb: &Rect) -> Result<(), Failure> {
    let ov = ra.overlap(rb);
    if ov.x > OVERLAP_TOL_PX && ov.y > OVERLAP_TOL_PX {
        return Err(fail(
            b.id(),
            "canvas",
            Problem::CanvasOverlap {
                other: a.id().to_owned(),
                overlap_px: ov.to_array(),
            },
        ));
    }
    // Touching (or within half a pixel of touching, so a placement that is slightly off is still
    // compared in 3D rather than silently treated as "not neighbours") along a stretch of
    // positive length: the shared edge must be the same line in the room.
    let vertical_edge =
        ov.x <= OVERLAP_TOL_PX && ov.x >= -SEAM_GAP_TOL_PX && ov.y > SEAM_GAP_TOL_PX;
    let horizontal_edge =
        ov.y <= OVERLAP_TOL_PX && ov.y >= -SEAM_GAP_TOL_PX && ov.x > SEAM_GAP_TOL_PX;
    let endpoints: [(DVec2, DVec2); 2] = if vertical_edge {
        // a left of b: a's right edge against b's left edge, or the other way round.
        let (xa, xb) = if ra.center().x < rb.center().x {
            (ra.max.x, rb.min.x)
        } else {
            (ra.min.x, rb.max.x)
        };
        let (y0, y1) = (ra.min.y.max(rb.min.y), ra.max.y.min(rb.max.y));
        [
            (DVec2::new(xa, y0), DVec2::new(xb, y0)),
            (DVec2::new(xa, y1), DVec2::new(xb, y1)),
        ]
    } else if horizontal_edge {
        let (ya, yb) = if ra.center().y < rb.center().y {
            (ra.max.y, rb.min.y)
        } else {
            (ra.min.y, rb.max.y)
        };
        let (x0, x1) = (ra.min.x.max(rb.min.x), ra.max.x.min(rb.max.x));
        [
            (DVec2::new(x0, ya), DVec2::new(x0, yb)),
            (DVec2::new(x1, ya), DVec2::new(x1, yb)),
        ]
    } else {
        return Ok(());
    };
    // Both maps are affine, so their difference along the edge is largest at an end point.
    let gap_m = endpoints
        .iter()
        .map(|&(ca, cb)| a.canvas_to_point(ca).distance(b.canvas_to_point(cb)))
        .fold(0.0, f64::max);
    if gap_m.is_nan() || gap_m > SEAM_TOL_M {
        return Err(fail(
            b.id(),
            "canvas",
            Problem::SeamMismatch {
                other: a.id().to_owned(),
                gap_m,
            },
        ));
    }
    Ok(())
}
