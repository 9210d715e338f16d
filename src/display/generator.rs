//! Expansion of the compact generator form into explicit tiles.
//!
//! Construction, in a local frame where the wall centre is the origin, faces +Z and +Y is up:
//! seen from above, the columns form a chain of segments, each as wide as a panel with its left
//! and right bezels; neighbouring segments share their end point (the hinge along the outer bezel
//! edges) and turn by the yaw step. Column `j` of `C` is yawed by `((C−1)/2 − j)·step` about +Y,
//! so a positive step brings the outer columns forward (towards the viewer) symmetrically. Rows
//! are stacked in each column's plane, bezel edge on bezel edge. The chain is then shifted so the
//! 3D point of the canvas centre is the origin, and finally rotated and moved to the requested
//! `center`/`normal`/`up`.
//!
//! The canvas is the same wall unrolled: columns side by side, each `left/p + width + right/p`
//! canvas pixels wide (p: the model pitch), so neighbouring canvas rectangles share their edges
//! exactly and the shared edges are the hinges.

use glam::{DVec2, DVec3};

use super::error::Problem;
use super::spec::{GeneratorSpec, TileSpec};
use super::{MAX_TILES, PITCH_REL_TOL, check_number, resolution_u32};

/// A generator field at fault and what is wrong with it.
pub(crate) type FieldError = (String, Problem);

fn field(name: &str, problem: Problem) -> FieldError {
    (format!("generator.{name}"), problem)
}

fn finite3(name: &str, v: [f64; 3]) -> Result<DVec3, FieldError> {
    for x in v {
        check_number(x).map_err(|p| field(name, p))?;
    }
    Ok(DVec3::from_array(v))
}

fn positive(name: &str, v: f64, allow_zero: bool) -> Result<f64, FieldError> {
    check_number(v).map_err(|p| field(name, p))?;
    if v < 0.0 || (v == 0.0 && !allow_zero) {
        return Err(field(
            name,
            Problem::Negative {
                value: v,
                zero_allowed: allow_zero,
            },
        ));
    }
    Ok(v)
}

/// Expands `g` into explicit tiles with ids `c{column}r{row}` (column 0 leftmost, row 0 top, as
/// seen from the front), in row-major order.
pub(crate) fn expand(g: &GeneratorSpec) -> Result<Vec<TileSpec>, FieldError> {
    if g.columns == 0 {
        return Err(field("columns", Problem::CountZero));
    }
    if g.rows == 0 {
        return Err(field("rows", Problem::CountZero));
    }
    let count = u64::from(g.columns) * u64::from(g.rows);
    if count > MAX_TILES as u64 {
        return Err(field("columns", Problem::TooManyTiles { count }));
    }
    let res = [
        resolution_u32(g.resolution[0]).map_err(|p| field("resolution", p))?,
        resolution_u32(g.resolution[1]).map_err(|p| field("resolution", p))?,
    ];
    let size = DVec2::new(
        positive("active_size", g.active_size[0], false)?,
        positive("active_size", g.active_size[1], false)?,
    );
    for (name, v) in g.bezel.named() {
        positive(name, v, true)?;
    }
    let b = g.bezel;
    if !g.yaw_step_deg.is_finite() {
        return Err(field("yaw_step_deg", Problem::NonFinite));
    }
    if g.yaw_step_deg.abs() >= 180.0 {
        return Err(field(
            "yaw_step_deg",
            Problem::YawStepTooLarge {
                deg: g.yaw_step_deg,
            },
        ));
    }
    let center = finite3("center", g.center)?;
    let normal = finite3("normal", g.normal)?;
    let up = finite3("up", g.up)?;
    let z_axis = normal
        .try_normalize()
        .ok_or_else(|| field("normal", Problem::DegenerateDirection))?;
    // Up may lean (it is made perpendicular to the normal) but must not be (nearly) parallel.
    let up_rejected = up - z_axis * up.dot(z_axis);
    if up_rejected.length() <= 1e-9 * up.length() {
        return Err(field("up", Problem::DegenerateDirection));
    }
    let y_axis = up_rejected.normalize();
    let x_axis = y_axis.cross(z_axis);

    let res_f = DVec2::new(f64::from(res[0]), f64::from(res[1]));
    let pitch = size / res_f;
    if ((pitch.x - pitch.y) / pitch.x.max(pitch.y)).abs() > PITCH_REL_TOL {
        return Err(field(
            "active_size",
            Problem::PitchAxes {
                x_m: pitch.x,
                y_m: pitch.y,
            },
        ));
    }
    // The model pitch the validator will compute (every tile has the same one).
    let p = (pitch.x + pitch.y) * 0.5;
    let cell_canvas = DVec2::new(
        (b.left + b.right) / p + res_f.x,
        (b.top + b.bottom) / p + res_f.y,
    );
    let cell_m = DVec2::new(b.left + size.x + b.right, b.top + size.y + b.bottom);

    // Plan view: left outer edge and rightward unit vector of every column.
    let step = g.yaw_step_deg.to_radians();
    let half = (f64::from(g.columns) - 1.0) * 0.5;
    let mut columns = Vec::with_capacity(g.columns as usize);
    let mut a = DVec3::ZERO;
    for j in 0..g.columns {
        let yaw = (half - f64::from(j)) * step;
        let u = DVec3::new(yaw.cos(), 0.0, -yaw.sin());
        columns.push((a, u));
        a += u * cell_m.x;
    }
    // Local (before centring) active top-left of tile (j, r): the wall's top outer edge is y = 0.
    let top_left = |j: usize, r: u32| {
        let (a, u) = columns[j];
        a + u * b.left - DVec3::Y * (f64::from(r) * cell_m.y + b.top)
    };
    // The 3D point of the canvas centre, through the tile map of the tile holding it.
    let canvas_size = cell_canvas * DVec2::new(f64::from(g.columns), f64::from(g.rows));
    let mid = canvas_size * 0.5;
    let kc = ((mid.x / cell_canvas.x).floor() as u32).min(g.columns - 1);
    let kr = ((mid.y / cell_canvas.y).floor() as u32).min(g.rows - 1);
    let off_px = mid
        - cell_canvas * DVec2::new(f64::from(kc), f64::from(kr))
        - DVec2::new(b.left, b.top) / p;
    let u_c = columns[kc as usize].1;
    let centre_local =
        top_left(kc as usize, kr) + u_c * (off_px.x * pitch.x) - DVec3::Y * (off_px.y * pitch.y);
    let place = |local: DVec3| {
        let l = local - centre_local;
        center + x_axis * l.x + y_axis * l.y + z_axis * l.z
    };

    let mut tiles = Vec::with_capacity(count as usize);
    for r in 0..g.rows {
        for j in 0..g.columns {
            let (_, u) = columns[j as usize];
            let tl = top_left(j as usize, r);
            let canvas = cell_canvas * DVec2::new(f64::from(j), f64::from(r))
                + DVec2::new(b.left, b.top) / p;
            tiles.push(TileSpec {
                id: format!("c{j}r{r}"),
                column: j,
                row: r,
                resolution: g.resolution,
                top_left: place(tl).to_array(),
                top_right: place(tl + u * size.x).to_array(),
                bottom_left: place(tl - DVec3::Y * size.y).to_array(),
                bezel: b,
                canvas: canvas.to_array(),
            });
        }
    }
    Ok(tiles)
}
