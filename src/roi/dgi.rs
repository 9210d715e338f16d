//! The distance-guide image (DESIGN.md §5), CPU twin of `shaders/roi/dgi.wgsl`.
//!
//! One value per image pixel: d = clamp(d_raw / L, 0, 1), where d_raw is the canvas distance (in
//! canvas pixels) from the pixel centre's canvas point to the projected ROI region, under one of
//! three metrics:
//! * `Exact`: the region is the cone's exact projection on every tile ([`super::conic`]);
//! * `Ellipse`: the paper's approximation, one canvas ellipse through the projected centre and
//!   the projected ends of the horizontal and vertical FOV;
//! * `Angular`: the angle between the direction apex→P and the cone, converted to canvas pixels
//!   at the ROI centre's viewing distance.
//!
//! Both backends consume the same [`Guide`], built once per ROI change in f64 on the CPU.

use glam::{DVec2, DVec3};
use rayon::prelude::*;

use super::cone::Cone;
use super::conic::{ConicKind, Patch, Piece, PlacedConic, Prepared, Rect, section};
use super::ellipse::{LANES, lane_mask};
use wide::f64x4;

/// Which distance the DGI measures.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Metric {
    /// Exact canvas distance to the cone's projection on the exact wall geometry.
    #[default]
    Exact,
    /// The paper-style canvas ellipse through the projected centre and FOV ends.
    Ellipse,
    /// Angle to the cone, scaled to canvas pixels at the ROI centre's distance.
    Angular,
}

impl Metric {
    /// The name the command line and the reports use (`exact`, `ellipse`, `angular`).
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::Exact => "exact",
            Self::Ellipse => "ellipse",
            Self::Angular => "angular",
        }
    }
}

/// The region of interest, as the interaction stage hands it over.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Roi {
    /// The ray gun's frozen cone.
    Cone(Cone),
    /// The mouse fallback: an axis-aligned ellipse on the canvas (orthogonal projection, no
    /// viewer distance known), centre and semi-axes in canvas pixels.
    CanvasEllipse { center: DVec2, semi_axes: DVec2 },
}

/// The display surface as the DGI sees it: planar patches covering the canvas, one per tile.
#[derive(Clone, Debug, PartialEq)]
pub struct Surface {
    pub canvas: Rect,
    pub patches: Vec<Patch>,
    /// Metres per canvas pixel (for the angular metric's conversion).
    pub pitch_m: f64,
    /// The model the patches come from (ray hits use its intersection).
    model: crate::display::DisplayModel,
}

impl Surface {
    /// The planar patches of a display model: one per tile, its active area and bezels.
    #[must_use]
    pub fn from_model(model: &crate::display::DisplayModel) -> Self {
        let patches = model
            .tiles()
            .iter()
            .enumerate()
            .map(|(i, tile)| {
                // Built from the corners rather than by differencing mapped points: exact to
                // rounding of the corner coordinates.
                let [tl, tr, bl] = tile.corners();
                let [w, h] = tile.resolution();
                let ex = (tr - tl) / f64::from(w);
                let ey = (bl - tl) / f64::from(h);
                let c0 = tile.canvas_origin();
                Patch {
                    rect: model.tile_canvas_rect(i),
                    origin: tl - c0.x * ex - c0.y * ey,
                    ex,
                    ey,
                }
            })
            .collect();
        Self {
            canvas: model.canvas_rect(),
            patches,
            pitch_m: model.pitch_m(),
            model: model.clone(),
        }
    }

    /// The patch containing canvas point `c` (the first, on shared edges).
    #[must_use]
    pub fn patch_at(&self, c: DVec2) -> Option<&Patch> {
        self.patches.iter().find(|p| p.rect.contains(c))
    }

    /// The first hit of a ray on the display, as (canvas point, distance along the ray in
    /// metres): the display model's own intersection, so the DGI agrees with `raygun pick` and
    /// the interaction stage (backs of panels block the ray).
    #[must_use]
    pub fn hit(&self, origin: DVec3, dir: DVec3) -> Option<(DVec2, f64)> {
        self.model
            .intersect(origin, dir)
            .map(|h| (h.canvas_px, h.t))
    }
}

/// Where the ray meets the *unbounded* plane of `patch` in front of its origin, as a canvas
/// point of that plane's parametrisation.
fn ray_plane(patch: &Patch, origin: DVec3, dir: DVec3) -> Option<DVec2> {
    let n = patch.ex.cross(patch.ey);
    let denom = dir.dot(n);
    let t = (patch.origin - origin).dot(n) / denom;
    if !(t > 0.0) || !t.is_finite() {
        return None;
    }
    // origin + t·dir = patch.origin + cx·ex + cy·ey, solved by the 2×2 normal equations (ex and
    // ey are perpendicular up to the model's tolerance).
    let r = origin + t * dir - patch.origin;
    let (exx, exy, eyy) = (
        patch.ex.dot(patch.ex),
        patch.ex.dot(patch.ey),
        patch.ey.dot(patch.ey),
    );
    let (bx, by) = (r.dot(patch.ex), r.dot(patch.ey));
    let det = exx * eyy - exy * exy;
    Some(DVec2::new(
        (bx * eyy - by * exy) / det,
        (by * exx - bx * exy) / det,
    ))
}

/// The image the DGI is computed for and its normalisation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DgiParams {
    pub width: u32,
    pub height: u32,
    /// Falloff length L in canvas pixels; `None` writes the raw distance d_raw instead.
    pub falloff_px: Option<f64>,
}

impl DgiParams {
    /// Canvas pixels per image pixel along x and y (the image covers the canvas).
    #[must_use]
    pub fn scale(&self, canvas: &Rect) -> DVec2 {
        (canvas.max - canvas.min) / DVec2::new(f64::from(self.width), f64::from(self.height))
    }

    /// Canvas point of image pixel (i, j)'s centre.
    #[must_use]
    pub fn pixel_to_canvas(&self, canvas: &Rect, i: u32, j: u32) -> DVec2 {
        canvas.min + (DVec2::new(f64::from(i), f64::from(j)) + 0.5) * self.scale(canvas)
    }
}

/// The falloff length L of the DGI normalisation d = clamp(d_raw / L, 0, 1).
///
/// The paper normalises to [0, 1] without saying how. DESIGN.md §5 asks that the default draws
/// about 2–4 % of the pixels per iteration at 10° FOV and 35–45 % at 60° in the paper's setup
/// (HORNET, viewer 1 m from the centre), as its speed-ups imply. No single length does both:
/// on HORNET a fixed L = 0.63 m gives 2.9 % at 10° but only 12.5 % at 60°, and L proportional
/// to the ROI's size gives 40 % at 60° but 1.2 % at 10°. So L grows with the ROI:
/// L = base + scale · ρ, with ρ the ROI's radius on the wall (metres; for the ray gun the
/// distance to the wall along the axis times √(tan(α_h/2)·tan(α_v/2)), for the mouse √(a·b)).
/// The defaults were fitted on HORNET; the calibration test in `tests/display/dgi_properties.rs`
/// (`default_falloff_meets_the_papers_implied_shares_on_hornet`) checks the shares they give.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Falloff {
    /// Metres along the wall.
    pub base_m: f64,
    /// Multiple of the ROI radius.
    pub scale: f64,
}

impl Default for Falloff {
    fn default() -> Self {
        Self {
            base_m: Self::DEFAULT_BASE_M,
            scale: Self::DEFAULT_SCALE,
        }
    }
}

/// A falloff setting that cannot give a positive length.
#[derive(Clone, Copy, Debug, thiserror::Error, PartialEq)]
#[error(
    "falloff base {} m and scale {} must be finite and non-negative, with a positive base",
    crate::messages::number(*base_m),
    crate::messages::number(*scale)
)]
pub struct FalloffError {
    pub base_m: f64,
    pub scale: f64,
}

impl Falloff {
    pub const DEFAULT_BASE_M: f64 = 0.33;
    pub const DEFAULT_SCALE: f64 = 3.4;

    pub fn new(base_m: f64, scale: f64) -> Result<Self, FalloffError> {
        if base_m.is_finite() && scale.is_finite() && base_m > 0.0 && scale >= 0.0 {
            Ok(Self { base_m, scale })
        } else {
            Err(FalloffError { base_m, scale })
        }
    }

    /// L in canvas pixels for an ROI of radius `roi_radius_m` on a wall of pitch `pitch_m`.
    #[must_use]
    pub fn length_px(&self, roi_radius_m: f64, pitch_m: f64) -> f64 {
        (self.base_m + self.scale * roi_radius_m) / pitch_m
    }
}

/// The ROI's radius on the wall in metres (see [`Falloff`]); 0 when the ray gun's axis misses.
#[must_use]
pub fn roi_radius_m(surface: &Surface, roi: &Roi) -> f64 {
    match roi {
        Roi::Cone(cone) => surface
            .hit(cone.apex, cone.axis)
            .map_or(0.0, |(_, t)| t * (cone.tan_h * cone.tan_v).sqrt()),
        Roi::CanvasEllipse { semi_axes, .. } => {
            (semi_axes.x.abs() * semi_axes.y.abs()).sqrt() * surface.pitch_m
        }
    }
}

/// Why a guide cannot be built.
#[derive(Clone, Copy, Debug, thiserror::Error, PartialEq)]
pub enum GuideError {
    #[error("the {metric:?} metric needs the pointing ray to hit the display, and it misses")]
    CentreMisses { metric: Metric },
    #[error("the angular metric needs a ray-gun cone; the mouse ROI has no viewer position")]
    AngularNeedsCone,
}

/// Everything a backend needs to compute a DGI, precomputed in f64 once per ROI change.
#[derive(Clone, Debug, PartialEq)]
pub enum Guide {
    /// Distance to a union of clipped conic pieces (exact and ellipse metrics, mouse ROI).
    Pieces(Vec<Piece>),
    /// Angular distance to the cone, `px_per_radian` canvas pixels per radian.
    Angular { cone: Cone, px_per_radian: f64 },
}

impl Guide {
    /// Builds the guide for `roi` on `surface` under `metric`.
    pub fn new(surface: &Surface, roi: &Roi, metric: Metric) -> Result<Self, GuideError> {
        match (roi, metric) {
            (Roi::CanvasEllipse { center, semi_axes }, Metric::Exact | Metric::Ellipse) => {
                let conic = PlacedConic {
                    kind: ConicKind::Ellipse {
                        a: semi_axes.x.abs(),
                        b: semi_axes.y.abs(),
                    },
                    origin: *center,
                    axis_u: DVec2::X,
                };
                Ok(Self::Pieces(
                    Piece::new(surface.canvas, conic).into_iter().collect(),
                ))
            }
            (Roi::CanvasEllipse { .. }, Metric::Angular) => Err(GuideError::AngularNeedsCone),
            (Roi::Cone(cone), Metric::Exact) => Ok(Self::Pieces(
                surface
                    .patches
                    .iter()
                    .filter_map(|p| Piece::new(p.rect, section(cone, p)))
                    .collect(),
            )),
            (Roi::Cone(cone), Metric::Ellipse) => Ok(Self::Pieces(
                paper_ellipse(surface, cone)?.into_iter().collect(),
            )),
            (Roi::Cone(cone), Metric::Angular) => {
                let (_, t) = surface
                    .hit(cone.apex, cone.axis)
                    .ok_or(GuideError::CentreMisses { metric })?;
                Ok(Self::Angular {
                    cone: *cone,
                    px_per_radian: t / surface.pitch_m,
                })
            }
        }
    }

    /// The raw canvas distance d_raw at canvas point `c` (f64 reference; `+∞` when the region
    /// is empty).
    #[must_use]
    pub fn distance(&self, surface: &Surface, c: DVec2) -> f64 {
        self.distance_capped(surface, c, f64::INFINITY)
    }

    /// min(d_raw, cap): pieces whose bounding box is `cap` or farther away are skipped (with
    /// cap = L every such pixel has d = 1 anyway).
    ///
    /// The piece with the nearest bounding box is solved first: it usually holds the nearest
    /// point (or the pixel itself), and its distance then prunes the other pieces by their
    /// boxes. Measured on HORNET at 60° (5 pieces): 1.73 solves per pixel in the falloff band.
    #[must_use]
    pub fn distance_capped(&self, surface: &Surface, c: DVec2, cap: f64) -> f64 {
        match self {
            Self::Pieces(pieces) => {
                let mut first = None;
                let mut first_box = cap;
                for (k, p) in pieces.iter().enumerate() {
                    let b = p.bounds.distance_to(c);
                    if b < first_box {
                        (first, first_box) = (Some(k), b);
                    }
                }
                let Some(first) = first else {
                    return cap;
                };
                let mut best = cap.min(pieces[first].distance(c));
                if best == 0.0 {
                    return 0.0;
                }
                for (k, p) in pieces.iter().enumerate() {
                    if k == first || p.bounds.distance_to(c) >= best {
                        continue;
                    }
                    best = best.min(p.distance(c));
                    if best == 0.0 {
                        break;
                    }
                }
                best
            }
            Self::Angular {
                cone,
                px_per_radian,
            } => match surface.patch_at(c) {
                Some(p) => (cone.angular_excess(p.point(c)) * px_per_radian).min(cap),
                None => cap,
            },
        }
    }
}

/// The paper's canvas ellipse: centred at the projected ROI centre, with semi-axes reaching the
/// projected ends of the horizontal and vertical FOV (the mean of each pair, since the two ends
/// are not symmetric on an oblique or curved wall), its major direction along the projected
/// horizontal FOV. The FOV ends are projected onto the plane of the tile the centre hits.
fn paper_ellipse(surface: &Surface, cone: &Cone) -> Result<Option<Piece>, GuideError> {
    let miss = GuideError::CentreMisses {
        metric: Metric::Ellipse,
    };
    let (centre, _) = surface.hit(cone.apex, cone.axis).ok_or(miss)?;
    let patch = surface.patch_at(centre).ok_or(miss)?;
    let on_plane = |dir: DVec3| ray_plane(patch, cone.apex, dir);
    let end = |along: DVec3, tan: f64| -> f64 {
        let reach = |sign: f64| {
            on_plane(cone.axis + sign * tan * along)
                .map_or(f64::INFINITY, |c| (c - centre).length())
        };
        0.5 * (reach(1.0) + reach(-1.0))
    };
    let a = end(cone.right, cone.tan_h);
    let b = end(cone.up, cone.tan_v);
    // Direction of the projected horizontal axis on the canvas.
    let axis_u = on_plane(cone.axis + 1e-3 * cone.tan_h * cone.right)
        .and_then(|c| (c - centre).try_normalize())
        .unwrap_or(DVec2::X);
    // A FOV end that misses the plane (very wide cones at grazing angles) makes the ellipse
    // unbounded: cap it at the canvas size, which covers every pixel anyway.
    let cap = (surface.canvas.max - surface.canvas.min).length();
    let conic = PlacedConic {
        kind: ConicKind::Ellipse {
            a: a.min(cap),
            b: b.min(cap),
        },
        origin: centre,
        axis_u,
    };
    Ok(Piece::new(surface.canvas, conic))
}

/// Computes the DGI on the CPU (f64, rayon): row-major, `width × height` values.
///
/// The exact and ellipse metrics run block by block ([`BLOCK`]² pixels), using that the
/// distance to each piece is 1-Lipschitz and each piece is convex: whole blocks that are `cap`
/// or farther from every piece are filled with d = 1 without a solve, whole blocks inside one
/// piece with 0, and in the other blocks a pixel solves only the pieces that a lower bound (the
/// piece's box, or its distance from the block centre minus the pixel's offset) cannot rule
/// out, nearest first. The values agree with the per-pixel [`compute_cpu_reference`] to the
/// solvers' rounding (a pruned piece is provably no nearer than the result, with a margin far
/// above that rounding); `tests/display/dgi_blocks.rs` checks it on many poses.
#[must_use]
pub fn compute_cpu(surface: &Surface, guide: &Guide, params: &DgiParams) -> Vec<f32> {
    compute_cpu_bands(surface, guide, params, 0, 1)
}

/// [`compute_cpu`] of the bands of [`BLOCK`] rows `k`, `k + n`, `k + 2n`, … alone (0
/// elsewhere): each band is computed on its own, so its values are the whole image's, bit for
/// bit — how N ranks split the DGI (DESIGN.md §12).
#[must_use]
pub fn compute_cpu_bands(
    surface: &Surface,
    guide: &Guide,
    params: &DgiParams,
    k: usize,
    n: usize,
) -> Vec<f32> {
    let mut out = vec![0f32; params.width as usize * params.height as usize];
    compute_into(surface, guide, params, &mut out, (k, n.max(1)), |d| {
        d as f32
    });
    out
}

/// [`compute_cpu`] without the final rounding to f32: the f64 values of d (or d_raw).
#[must_use]
pub fn compute_cpu_f64(surface: &Surface, guide: &Guide, params: &DgiParams) -> Vec<f64> {
    let mut out = vec![0f64; params.width as usize * params.height as usize];
    compute_into(surface, guide, params, &mut out, (0, 1), |d| d);
    out
}

/// The straightforward per-pixel DGI: [`Guide::distance_capped`] at every pixel centre, the
/// reference [`compute_cpu`] is tested against (f64 values).
#[must_use]
pub fn compute_cpu_reference(surface: &Surface, guide: &Guide, params: &DgiParams) -> Vec<f64> {
    let w = params.width as usize;
    let mut out = vec![0f64; w * params.height as usize];
    let (min, scale) = (surface.canvas.min, params.scale(&surface.canvas));
    let cap = params.falloff_px.unwrap_or(f64::INFINITY);
    out.par_chunks_mut(w).enumerate().for_each(|(j, row)| {
        for (i, v) in row.iter_mut().enumerate() {
            let c = min + (DVec2::new(i as f64, j as f64) + 0.5) * scale;
            *v = normalise(guide.distance_capped(surface, c, cap), params.falloff_px);
        }
    });
    out
}

/// Side of the square pixel blocks [`compute_cpu`] prunes by. Measured on HORNET at 60°: 16
/// balances the per-block work (one solve per nearby piece at the centre) against the pixels
/// near a boundary between two pieces' zones, which must solve both.
pub const BLOCK: usize = 16;

fn compute_into<T: Send>(
    surface: &Surface,
    guide: &Guide,
    params: &DgiParams,
    out: &mut [T],
    (k, n): (usize, usize),
    store: impl Fn(f64) -> T + Sync,
) {
    let (w, h) = (params.width as usize, params.height as usize);
    if w == 0 || h == 0 {
        return;
    }
    let (min, scale) = (surface.canvas.min, params.scale(&surface.canvas));
    // Pixel-centre coordinates, by the same arithmetic as `pixel_to_canvas` (bit-identical).
    let xs: Vec<f64> = (0..w).map(|i| min.x + (i as f64 + 0.5) * scale.x).collect();
    let ys: Vec<f64> = (0..h).map(|j| min.y + (j as f64 + 0.5) * scale.y).collect();
    let cap = params.falloff_px.unwrap_or(f64::INFINITY);
    let fill = |d: f64| store(normalise(d, params.falloff_px));
    let prepared: Vec<Prepared<'_>> = match guide {
        Guide::Pieces(pieces) => pieces.iter().map(Piece::prepare).collect(),
        Guide::Angular { .. } => Vec::new(),
    };
    out.par_chunks_mut(w * BLOCK)
        .enumerate()
        .filter(|(band, _)| band % n == k)
        .for_each(|(band, rows)| {
            let j0 = band * BLOCK;
            let ys = &ys[j0..(j0 + BLOCK).min(h)];
            match guide {
                Guide::Pieces(_) => {
                    let mut blocks = BlockPruner::new(&prepared, surface.canvas, cap);
                    for i0 in (0..w).step_by(BLOCK) {
                        let xs = &xs[i0..(i0 + BLOCK).min(w)];
                        blocks.run(xs, ys, i0, |i, j, d| rows[j * w + i0 + i] = fill(d));
                    }
                }
                Guide::Angular { .. } => {
                    for (j, &y) in ys.iter().enumerate() {
                        for (i, &x) in xs.iter().enumerate() {
                            let d = guide.distance_capped(surface, DVec2::new(x, y), cap);
                            rows[j * w + i] = fill(d);
                        }
                    }
                }
            }
        });
}

/// (1 + 1e-12)²: the relative margin of the Lipschitz bound from the block centre, squared.
const OFFSET_FACTOR2: f64 = (1.0 + 1e-12) * (1.0 + 1e-12);
/// 1 + 4ε: a box distance whose square exceeds best² by this factor is above best despite the
/// rounding of both squares.
const BOX_FACTOR2: f64 = 1.0 + 4.0 * f64::EPSILON;

/// The per-block pruning of [`compute_cpu`] for a union of pieces, for the blocks of one band of
/// [`BLOCK`] rows from left to right, [`LANES`] rows at a time: one per lane of
/// [`Prepared::distance_hinted_lanes`]. Each pixel's Newton iterations are a chain of dependent
/// divisions and square roots, and the warm start chains it to the pixel before it in its row,
/// so one row at a time leaves the core waiting on that chain; rows side by side run their
/// chains in the same vector instructions (every lane's value is the one its row alone gives).
struct BlockPruner<'a> {
    pieces: &'a [Prepared<'a>],
    cap: f64,
    /// Margin against the solvers' rounding in the Lipschitz bounds (canvas px): far above the
    /// ~1e-14 of the canvas scale they reach, far below a pixel.
    slack: f64,
    /// Candidate pieces of the current block, nearest to its centre first.
    near: Vec<Near>,
    /// Per piece and group of [`LANES`] rows of the band, the ellipse solver's last roots along
    /// those rows (warm starts, carried from block to block).
    warm: Vec<[Warm; BLOCK / LANES]>,
}

/// A piece near a block: its distance `dc` from the block centre, and the supporting half-plane
/// there. The piece is convex, so it lies in the half-plane {x : (x − q)·n ≤ 0} through its
/// nearest point q to the centre with normal n = (centre − q)/dc, and (c − q)·n bounds its
/// distance from any pixel c from below. Across a block that bound is far tighter than the
/// Lipschitz one (dc − |c − centre|): it loses only about |offset along the piece|²/(2·dc)
/// instead of the whole offset. Measured on HORNET at 60°, most of the second solves near the
/// seams between pieces were within 10 px of the first, which the Lipschitz bound over a
/// 16-pixel block cannot rule out and this one can.
#[derive(Clone, Copy)]
struct Near {
    dc: f64,
    k: usize,
    q: DVec2,
    /// Zero when the centre is too close to the piece for a well-defined normal (the bound is
    /// then (c − q)·0 = 0, which prunes nothing).
    n: DVec2,
}

/// The block centre's distance below which [`Near::n`] is not used: the normal's direction
/// error grows as the solvers' point error over dc.
const MIN_NORMAL_DC: f64 = 1.0;

/// How many [`BlockPruner::slack`]s the half-plane bound keeps as margin: the solvers' point
/// error η moves the bound by at most about |c − q|·2η/dc + η ≤ 26η for dc ≥ 1 px and pixel
/// offsets up to a block's half-diagonal (11.3 px), and η is far below one slack.
const HALF_PLANE_SLACKS: f64 = 32.0;

/// The last two secular roots of one piece along [`LANES`] rows: the next pixel's root is
/// predicted by linear extrapolation from two consecutive pixels, else taken from the last one
/// (a pixel further left: any hint is safe, a close one saves evaluations).
#[derive(Clone, Copy)]
struct Warm {
    last: f64x4,
    before: f64x4,
    /// Image column of `last`, −∞ before the first.
    at: f64x4,
    /// Mask: `before` and `last` are finite roots of two consecutive columns.
    consecutive: f64x4,
}

impl Warm {
    const NONE: Self = Self {
        last: f64x4::splat(f64::NAN),
        before: f64x4::splat(f64::NAN),
        at: f64x4::splat(f64::NEG_INFINITY),
        consecutive: f64x4::ZERO,
    };

    /// The hints for column `col`.
    fn hint(&self, col: f64) -> f64x4 {
        let fresh = self.at.simd_eq(f64x4::splat(col - 1.0));
        (fresh & self.consecutive).select(f64x4::splat(2.0) * self.last - self.before, self.last)
    }

    /// Takes the roots of column `col` in the lanes of `solved`.
    fn record(&mut self, col: f64, root: f64x4, solved: f64x4) {
        let fresh = self.at.simd_eq(f64x4::splat(col - 1.0));
        let consecutive = fresh & root.is_finite() & self.last.is_finite();
        self.consecutive = solved.select(consecutive, self.consecutive);
        self.before = solved.select(self.last, self.before);
        self.last = solved.select(root, self.last);
        self.at = solved.select(f64x4::splat(col), self.at);
    }
}

impl<'a> BlockPruner<'a> {
    fn new(pieces: &'a [Prepared<'a>], canvas: Rect, cap: f64) -> Self {
        let mag = canvas.min.abs().max(canvas.max.abs()).max_element();
        Self {
            pieces,
            cap,
            slack: 1e-9 * (1.0 + if mag.is_finite() { mag } else { 0.0 }),
            near: Vec::with_capacity(pieces.len()),
            warm: vec![[Warm::NONE; BLOCK / LANES]; pieces.len()],
        }
    }

    /// Computes the block of pixel centres `xs × ys` (`xs[0]` is image column `col0`), handing
    /// each (i, j, distance) to `put`.
    fn run(&mut self, xs: &[f64], ys: &[f64], col0: usize, mut put: impl FnMut(usize, usize, f64)) {
        let mut fill = |d: f64| {
            for j in 0..ys.len() {
                for i in 0..xs.len() {
                    put(i, j, d);
                }
            }
        };
        let (lo, hi) = (
            DVec2::new(xs[0], ys[0]),
            DVec2::new(xs[xs.len() - 1], ys[ys.len() - 1]),
        );
        let block = Rect { min: lo, max: hi };
        // Pieces whose box is `cap` or farther from the whole block are skipped for every
        // pixel of it by `distance_capped` too; the box-to-box gap is below each pixel's
        // box distance also in floating point (subtraction and the norm are monotone).
        self.near.clear();
        let centre = 0.5 * (lo + hi);
        for (k, p) in self.pieces.iter().map(|p| p.piece).enumerate() {
            let gap = (p.bounds.min - block.max)
                .max(block.min - p.bounds.max)
                .max(DVec2::ZERO)
                .length();
            if gap < self.cap {
                let (dc, q) = p.closest(centre);
                let n = if dc >= MIN_NORMAL_DC {
                    (centre - q) / dc
                } else {
                    DVec2::ZERO
                };
                self.near.push(Near { dc, k, q, n });
            }
        }
        if self.near.is_empty() {
            return fill(self.cap);
        }
        self.near.sort_by(|a, b| a.dc.total_cmp(&b.dc));
        // Every pixel centre is within `radius` of the block centre.
        let radius = 0.5 * (hi - lo).length() * (1.0 + 1e-12);
        if self.near[0].dc - radius - self.slack >= self.cap {
            return fill(self.cap);
        }
        // A convex piece holding the block's four corners holds all of it.
        let corners = block.corners();
        if self.near.iter().any(|&Near { dc, k, .. }| {
            dc == 0.0 && {
                let p = self.pieces[k].piece;
                corners
                    .iter()
                    .all(|&c| p.rect.contains(c) && p.conic.contains_local(p.conic.to_local(c)))
            }
        }) {
            return fill(0.0);
        }
        let splat = f64x4::splat;
        let (cap, slack) = (splat(self.cap), splat(self.slack));
        for (group, j0) in (0..ys.len()).step_by(LANES).enumerate() {
            // Lanes past the block's last row repeat it and are switched off.
            let rows = (ys.len() - j0).min(LANES);
            let live = lane_mask(std::array::from_fn(|l| l < rows));
            let y = f64x4::new(std::array::from_fn(|l| ys[j0 + l.min(rows - 1)]));
            let dy = y - splat(centre.y);
            for (i, &x) in xs.iter().enumerate() {
                let col = (col0 + i) as f64;
                let x = splat(x);
                let dx = x - splat(centre.x);
                // The bounds below compare squares (no square root per pixel and piece): the
                // factors (1 + 1e-12)² and 1 + 4ε cover the squares' rounding, so a piece is
                // skipped only when it is provably no nearer than `best`.
                let offset2 = (dx * dx + dy * dy) * splat(OFFSET_FACTOR2);
                let mut best = cap;
                // Lanes still looking for a nearer piece.
                let mut open = live;
                for near in &self.near {
                    // dc − |c − centre|·(1 + 1e-12) − slack ≥ best: no nearer than best, and
                    // neither is any later piece (sorted by dc).
                    let gap = splat(near.dc) - best - slack;
                    open &= !(gap.simd_ge(f64x4::ZERO) & (gap * gap).simd_ge(offset2));
                    if open.none() {
                        break;
                    }
                    let p = &self.pieces[near.k];
                    let b = p.piece.bounds;
                    let to_box = |v: f64x4, lo: f64, hi: f64| {
                        (splat(lo) - v).max(v - splat(hi)).max(f64x4::ZERO)
                    };
                    let (bx, by) = (to_box(x, b.min.x, b.max.x), to_box(y, b.min.y, b.max.y));
                    let half_plane = (x - splat(near.q.x)) * splat(near.n.x)
                        + (y - splat(near.q.y)) * splat(near.n.y)
                        - splat(HALF_PLANE_SLACKS * self.slack);
                    let need = open
                        & (bx * bx + by * by).simd_lt(best * best * splat(BOX_FACTOR2))
                        & half_plane.simd_lt(best);
                    if need.none() {
                        continue;
                    }
                    let warm = &mut self.warm[near.k][group];
                    let mut roots = warm.hint(col);
                    let d = p.distance_hinted_lanes(x, y, &mut roots, need);
                    warm.record(col, roots, need);
                    best = need.select(best.min(d), best);
                    open &= !best.simd_eq(f64x4::ZERO);
                }
                for (l, &d) in best.to_array().iter().enumerate().take(rows) {
                    put(i, j0 + l, d);
                }
            }
        }
    }
}

/// d = clamp(d_raw / L, 0, 1), or d_raw itself when no falloff is given.
#[must_use]
pub fn normalise(d_raw: f64, falloff_px: Option<f64>) -> f64 {
    match falloff_px {
        Some(l) => (d_raw / l).clamp(0.0, 1.0),
        None => d_raw,
    }
}
