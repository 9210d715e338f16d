//! Motion reuse (DESIGN.md §11): when the eye moves, each pixel of the new view keeps the
//! accumulation of the old pixel that saw the same surface, instead of starting from nothing.
//! This is the CPU definition and the twin of the kernel `shaders/trace/reuse.wgsl`
//! (dispatch: [`crate::trace::gpu::ReuseKernel`]).
//!
//! # The primary-hit record
//!
//! Per pixel, two vec4s ([`crate::trace::features::hit_record`]): `[a.x, a.y, a.z, α]` and
//! `[ng.x, ng.y, ng.z, word]`. The *anchor* `a` is the scene point the pixel's accumulation
//! shows: for a fresh pixel the hit of its centre ray (or, for a miss, the ray's unit
//! direction), for a carried one the anchor it was carried with — so the picture never drifts
//! however many moves it is carried through (each move picks the old pixel whose anchor is
//! nearest; the anchor itself is never rounded to a pixel). `ng` is the hit's geometric normal
//! turned to the eye, α the material's roughness² at the hit, `word` (u32 bits) the material's
//! index, [`MISS`] for a ray that left the scene or [`NOTHING`] for a pixel no tile shows;
//! bit [`NEVER_REUSE`] marks mirrors and glass (what the features look through, and every
//! transmitting surface).
//!
//! # Reuse, exactly
//!
//! Pixel `p` of the new view (record `n`, eye `e1`) takes old pixel `q` (old record `o`, eye
//! `e0`) when:
//!
//! 1. `p` is shown, not [`NEVER_REUSE`], and the eye moved at most [`MAX_JUMP`] × the distance
//!    from `e0` to `p`'s anchor (misses: any move);
//! 2. `q` is one of the 3 × 3 old pixels around the old view's pixel of `p`'s anchor (seen
//!    from `e0`: the hit point, or for a miss the direction) — the one whose *old anchor*,
//!    seen from `e1`, falls nearest `p`'s centre (Chebyshev, in new pixels; ties: the first in
//!    row-major order), and at most [`LOOSE_MISREGISTRATION_PX`] from it;
//! 3. `q`'s word is `p`'s (same material, or both misses); for a hit, the normals agree
//!    (`n.ng · o.ng ≥` [`COS_NORMAL`]) and `q`'s anchor lies within
//!    [`PLANE_TOLERANCE`] × `p`'s depth of `p`'s tangent plane;
//! 4. for a hit, the angle between the directions to the two eyes is at most
//!    [`ANGLE_PER_ALPHA`] × α (a rough surface may be seen from further round; a glossy one
//!    barely).
//!
//! A carried pixel takes `q`'s sums and count and its anchor (`n.a ← o.a`). A surface with
//! α < [`DIFFUSE_ALPHA`] is partly view-dependent: its count is capped at [`HISTORY_LENGTH`]
//! (the sums scaled by cap / count, so the mean stays and new samples weigh more). A source
//! further than [`MAX_MISREGISTRATION_PX`] is a loose match (a surface seen at a grazing angle,
//! whose centre point moves far along it): it carries at most [`LOOSE_HISTORY`] samples, a
//! first estimate in place of black that new samples soon replace. A pixel on an edge — one of
//! its eight neighbours in the new view has another word — carries at most [`EDGE_HISTORY`]:
//! its footprint straddles the edge, and the nearest old pixel covered it in another
//! proportion (a sky-bright pixel would otherwise stay bright where a building's edge now
//! is: a ghost). Every other pixel starts again from nothing. The ROI and its DGI are not
//! touched.

use glam::Vec3;
use rayon::prelude::*;

use super::accum::Accumulation;
use super::camera::RenderCamera;
use super::wall::WallCamera;

/// The record's word for a pixel no tile shows.
pub const NOTHING: u32 = u32::MAX;
/// The record's word for a centre ray that left the scene (the anchor is its direction).
pub const MISS: u32 = u32::MAX - 1;
/// The record word's bit for a surface never carried over (mirrors, glass).
pub const NEVER_REUSE: u32 = 1 << 31;

/// Normals of the same surface seen from two eyes agree within 10°.
pub const COS_NORMAL: f32 = 0.984_807_8;
/// The old anchor lies within this fraction of the new depth of the new tangent plane.
pub const PLANE_TOLERANCE: f32 = 0.01;
/// The view direction may turn by at most this many radians per unit of α.
pub const ANGLE_PER_ALPHA: f32 = 0.5;
/// Below this α (roughness 0.5) a carried pixel's count is capped at [`HISTORY_LENGTH`].
pub const DIFFUSE_ALPHA: f32 = 0.25;
/// The most samples a partly view-dependent pixel carries through a move.
pub const HISTORY_LENGTH: u32 = 32;
/// The most samples a pixel on an edge carries through a move (a neighbour of another
/// material, or a miss beside a hit): its footprint straddles the edge, and a shift of a
/// fraction of a pixel changes what it covers.
pub const EDGE_HISTORY: u32 = 4;
/// The most an old anchor may lie from the new pixel's centre, in new pixels (Chebyshev).
pub const MAX_MISREGISTRATION_PX: f32 = 0.75;
/// An old anchor this far from the new pixel's centre (in new pixels, Chebyshev) still carries,
/// but at most [`LOOSE_HISTORY`] samples: a rough first estimate that new samples soon replace.
pub const LOOSE_MISREGISTRATION_PX: f32 = 1.5;
/// The most samples a loosely registered pixel carries.
pub const LOOSE_HISTORY: u32 = 4;
/// The eye may move at most this fraction of the distance to a pixel's surface.
pub const MAX_JUMP: f32 = 0.25;

/// A view a record was made in: the wall camera (its eye and tiles) or a pinhole camera with
/// its image size. Orthographic views carry nothing over (their move is a pan of every pixel).
#[derive(Clone, Copy, Debug)]
pub enum View<'a> {
    Wall(&'a WallCamera),
    Pinhole {
        camera: RenderCamera,
        width: u32,
        height: u32,
    },
}

impl View<'_> {
    /// Where the rays start (scene frame).
    #[must_use]
    pub fn eye(&self) -> Vec3 {
        match self {
            Self::Wall(w) => w.eye,
            Self::Pinhole { camera, .. } => camera.position,
        }
    }

    /// The image point (in pixels, y down) whose primary ray runs along `toward` from the
    /// eye, with the pixel holding it; `None` where no shown pixel's ray does (behind the
    /// camera, outside the image, on no tile). Through the wall camera, the tile entry of
    /// pixel `near` is tried first ([`WallCamera::project`]). The twin of `project` in
    /// reuse.wgsl.
    #[must_use]
    pub fn project(&self, toward: Vec3, near: u32) -> Option<([f32; 2], u32)> {
        match *self {
            Self::Wall(w) => w.project(toward, w.tile_of(near % w.width, near / w.width)),
            Self::Pinhole {
                camera,
                width,
                height,
            } => {
                if camera.ortho_half_y > 0.0 {
                    return None;
                }
                let z = toward.dot(camera.forward);
                if !(z > 0.0) {
                    return None;
                }
                let sx = toward.dot(camera.right) / (z * camera.tan_half_y * camera.aspect);
                let sy = toward.dot(camera.up) / (z * camera.tan_half_y);
                let fx = (sx + 1.0) * 0.5 * width as f32;
                let fy = (1.0 - sy) * 0.5 * height as f32;
                if !(fx >= 0.0 && fy >= 0.0 && fx < width as f32 && fy < height as f32) {
                    return None;
                }
                Some(([fx, fy], fy as u32 * width + fx as u32))
            }
        }
    }

    fn width(&self) -> u32 {
        match self {
            Self::Wall(w) => w.width,
            Self::Pinhole { width, .. } => *width,
        }
    }

    fn height(&self) -> u32 {
        match self {
            Self::Wall(w) => w.height,
            Self::Pinhole { height, .. } => *height,
        }
    }
}

/// The record's word.
#[inline]
fn word(r: &[[f32; 4]; 2]) -> u32 {
    r[1][3].to_bits()
}

/// The old pixel whose accumulation pixel `p` of the new view takes, and the most samples it
/// carries (`u32::MAX`: all), as the module docs define it. `new`/`old` are the records of the
/// two views (old: any pixel of the image, indexed by its pixel number).
#[must_use]
pub fn reuse_source(
    new_view: &View<'_>,
    old_view: &View<'_>,
    (new, p, new_word): (&[[f32; 4]; 2], u32, impl Fn(u32) -> u32),
    old: impl Fn(u32) -> [[f32; 4]; 2],
) -> Option<(u32, u32)> {
    let w = word(new);
    if w == NOTHING || (w != MISS && w & NEVER_REUSE != 0) {
        return None;
    }
    let miss = w == MISS;
    let (e0, e1) = (old_view.eye(), new_view.eye());
    let a = Vec3::new(new[0][0], new[0][1], new[0][2]);
    if !miss && (e1 - e0).length() > MAX_JUMP * (a - e0).length() {
        return None;
    }
    let toward_old = if miss { a } else { a - e0 };
    let (_, q0) = old_view.project(toward_old, p)?;
    let width = old_view.width();
    let (qx, qy) = (q0 % width, q0 / width);
    let height = old_view.height();
    let nw = new_view.width();
    let centre = [(p % nw) as f32 + 0.5, (p / nw) as f32 + 0.5];
    let mut best: Option<(f32, u32)> = None;
    for dy in -1i32..=1 {
        for dx in -1i32..=1 {
            let (x, y) = (qx as i32 + dx, qy as i32 + dy);
            if x < 0 || y < 0 || x >= width as i32 || y >= height as i32 {
                continue;
            }
            let q = y as u32 * width + x as u32;
            let o = old(q);
            if word(&o) != w {
                continue;
            }
            let b = Vec3::new(o[0][0], o[0][1], o[0][2]);
            let Some(([fx, fy], _)) = new_view.project(if miss { b } else { b - e1 }, p) else {
                continue;
            };
            let dist = (fx - centre[0]).abs().max((fy - centre[1]).abs());
            if dist <= LOOSE_MISREGISTRATION_PX && best.is_none_or(|(d, _)| dist < d) {
                best = Some((dist, q));
            }
        }
    }
    let (dist, q) = best?;
    let mut loose = if dist > MAX_MISREGISTRATION_PX {
        LOOSE_HISTORY
    } else {
        u32::MAX
    };
    if on_edge(p, w, nw, new_view.height(), &new_word) {
        loose = loose.min(EDGE_HISTORY);
    }
    if miss {
        return Some((q, loose));
    }
    let o = old(q);
    let (nn, on) = (
        Vec3::new(new[1][0], new[1][1], new[1][2]),
        Vec3::new(o[1][0], o[1][1], o[1][2]),
    );
    let b = Vec3::new(o[0][0], o[0][1], o[0][2]);
    let depth = (a - e1).length();
    if nn.dot(on) < COS_NORMAL || nn.dot(b - a).abs() > PLANE_TOLERANCE * depth {
        return None;
    }
    let alpha = new[0][3];
    let cos = (e0 - a)
        .normalize()
        .dot((e1 - a).normalize())
        .clamp(-1.0, 1.0);
    if cos.acos() > ANGLE_PER_ALPHA * alpha {
        return None;
    }
    let cap = if alpha < DIFFUSE_ALPHA {
        HISTORY_LENGTH
    } else {
        u32::MAX
    };
    Some((q, cap.min(loose)))
}

/// Whether one of the eight neighbours of pixel `p` (in a `width × height` view) has a word
/// other than `w`: the twin of `on_edge` in reuse.wgsl.
fn on_edge(p: u32, w: u32, width: u32, height: u32, word_of: &impl Fn(u32) -> u32) -> bool {
    let (x, y) = ((p % width) as i32, (p / width) as i32);
    for dy in -1i32..=1 {
        for dx in -1i32..=1 {
            let (nx, ny) = (x + dx, y + dy);
            if (dx, dy) == (0, 0) || nx < 0 || ny < 0 || nx >= width as i32 || ny >= height as i32 {
                continue;
            }
            if word_of(ny as u32 * width + nx as u32) != w {
                return true;
            }
        }
    }
    false
}

/// A pixel's sums and count carried with at most `cap` samples (the sums scaled by
/// cap / count where the count is larger): the twin of `carry` in reuse.wgsl.
#[inline]
#[must_use]
pub fn carry(sum: [f32; 4], count: u32, cap: u32) -> ([f32; 4], u32) {
    if count <= cap {
        return (sum, count);
    }
    let f = cap as f32 / count as f32;
    (sum.map(|s| s * f), cap)
}

/// What a move did to the accumulation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct ReuseStats {
    /// Pixels whose accumulation was carried over.
    pub carried: u64,
    /// Pixels the new view shows.
    pub shown: u64,
}

impl ReuseStats {
    /// The share of shown pixels carried over (0 when none is shown).
    #[must_use]
    pub fn share(&self) -> f64 {
        if self.shown == 0 {
            0.0
        } else {
            self.carried as f64 / self.shown as f64
        }
    }
}

/// The accumulation of the new view from `old_acc` (the old view's) by [`reuse_source`] for
/// every pixel, and `new` with each carried pixel's anchor taken from its source: the CPU twin
/// of the reuse kernel. `new` and `old` are whole-image records.
pub fn reuse_cpu(
    new_view: &View<'_>,
    old_view: &View<'_>,
    new: &mut [[[f32; 4]; 2]],
    old: &[[[f32; 4]; 2]],
    old_acc: &Accumulation,
) -> (Accumulation, ReuseStats) {
    let sources: Vec<Option<(u32, u32)>> = new
        .par_iter()
        .enumerate()
        .map(|(p, r)| {
            let new_word = |i: u32| word(&new[i as usize]);
            reuse_source(new_view, old_view, (r, p as u32, new_word), |q| {
                old[q as usize]
            })
        })
        .collect();
    let mut acc = Accumulation::new(old_acc.width, old_acc.height);
    let mut stats = ReuseStats::default();
    for (p, src) in sources.into_iter().enumerate() {
        if word(&new[p]) != NOTHING {
            stats.shown += 1;
        }
        let Some((q, cap)) = src else { continue };
        let q = q as usize;
        let (sum, count) = carry(old_acc.sum[q], old_acc.count[q], cap);
        acc.sum[p] = sum;
        acc.count[p] = count;
        new[p][0] = [old[q][0][0], old[q][0][1], old[q][0][2], new[p][0][3]];
        stats.carried += 1;
    }
    (acc, stats)
}

#[cfg(test)]
mod tests;
