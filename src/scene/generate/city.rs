//! The procedural city: seeded blocks of textured buildings on streets.

use glam::{Vec2, Vec3};
use gltf::json;

use crate::random::{pcg4d, unit_f32};

use super::glb::{Builder, Geometry};
use super::*;

/// The city's size and seed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CityParams {
    /// Blocks along each side of the square city.
    pub blocks: u32,
    /// Different seeds give different cities of about the same size.
    pub seed: u32,
}

impl CityParams {
    /// 343 740 triangles, about the size of the paper's city model (DESIGN.md §7).
    pub const PAPER: Self = Self {
        blocks: 41,
        seed: 1,
    };
    /// About 3 900 triangles, for tests.
    pub const SMALL: Self = Self { blocks: 4, seed: 1 };
    /// The largest `blocks` accepted (≈ 2 million triangles).
    pub const MAX_BLOCKS: u32 = 100;
}

/// Street width (kerb to kerb) and block size, metres.
const STREET_M: f32 = 14.0;
const BLOCK_M: f32 = 64.0;
const SIDEWALK_M: f32 = 3.0;
const KERB_M: f32 = 0.15;
/// One facade texture tile: a window bay 4 m wide and one 3.5 m storey high.
const FACADE_TILE: Vec2 = Vec2::new(4.0, 3.5);
/// One asphalt texture tile, metres.
const ASPHALT_TILE: f32 = 6.0;

/// Uniform in [0, 1) from the seed and three counters (the shared counter-based hash).
fn rand(seed: u32, a: u32, b: u32, salt: u32) -> f32 {
    unit_f32(pcg4d([seed, a, b, salt])[0])
}

/// A procedural city: `blocks × blocks` blocks separated by streets, each block a raised
/// sidewalk with a grid of lots; each lot a building of one to three setback tiers (taller
/// towards the centre), with flat or hipped roofs and rooftop plant rooms. Materials: asphalt
/// (textured), sidewalk, roof, and four facades (one textured with windows). Cameras "street"
/// (eye height, looking down the central avenue) and "aerial".
pub fn city(params: CityParams) -> Result<Generated, GenerateError> {
    if params.blocks == 0 || params.blocks > CityParams::MAX_BLOCKS {
        return Err(GenerateError::Blocks {
            max: CityParams::MAX_BLOCKS,
            got: params.blocks,
        });
    }
    let seed = params.seed;
    let mut b = Builder::new();
    let asphalt_tex = b.texture("asphalt", &asphalt_texture(seed));
    let windows_tex = b.texture("windows", &windows_texture(seed));
    let asphalt = b.material("asphalt", [1.0, 1.0, 1.0], Some(asphalt_tex), None);
    let sidewalk = b.material("sidewalk", [0.55, 0.54, 0.52], None, None);
    let roof = b.material("roof", [0.28, 0.28, 0.30], None, None);
    let facades = [
        b.material("brick", [0.62, 0.36, 0.28], Some(windows_tex), None),
        b.material("concrete", [0.60, 0.58, 0.55], None, None),
        b.material("glass", [0.16, 0.21, 0.26], None, None),
        b.material("sandstone", [0.72, 0.62, 0.45], None, None),
    ];

    let n = params.blocks;
    let pitch = BLOCK_M + STREET_M;
    let extent = n as f32 * pitch;
    let half = extent / 2.0;
    let mut ground = Geometry::default();
    let mut walks = Geometry::default();
    let mut roofs = Geometry::default();
    let mut walls: Vec<Geometry> = facades.iter().map(|_| Geometry::default()).collect();

    // The ground: asphalt under the whole city and one street width around it.
    let g = half + STREET_M;
    ground.horizontal_quad(-g, -g, g, g, 0.0, ASPHALT_TILE);

    for bi in 0..n {
        for bj in 0..n {
            let block_id = bi * n + bj;
            let x0 = -half + bi as f32 * pitch + STREET_M / 2.0;
            let z0 = -half + bj as f32 * pitch + STREET_M / 2.0;
            let lo = Vec3::new(x0, 0.0, z0);
            walks.box_sides(
                lo,
                lo + Vec3::new(BLOCK_M, KERB_M, BLOCK_M),
                Vec2::splat(ASPHALT_TILE),
            );
            walks.horizontal_quad(x0, z0, x0 + BLOCK_M, z0 + BLOCK_M, KERB_M, ASPHALT_TILE);
            // Taller towards the centre: a Gaussian "downtown" on top of a low base.
            let centre = Vec2::new(x0 + BLOCK_M / 2.0, z0 + BLOCK_M / 2.0);
            let downtown = (-2.5 * (centre.length() / half.max(pitch)).powi(2)).exp();
            let lots_x = 2 + (rand(seed, block_id, 0, 1) * 3.0) as u32;
            let lots_z = 2 + (rand(seed, block_id, 0, 2) * 3.0) as u32;
            let inner = BLOCK_M - 2.0 * SIDEWALK_M;
            let (lot_w, lot_d) = (inner / lots_x as f32, inner / lots_z as f32);
            for lx in 0..lots_x {
                for lz in 0..lots_z {
                    let lot = lx * 8 + lz;
                    let r = |salt: u32| rand(seed, block_id, lot, salt);
                    let margin = 0.5 + 1.5 * r(3);
                    let lot_lo = Vec2::new(
                        x0 + SIDEWALK_M + lx as f32 * lot_w + margin,
                        z0 + SIDEWALK_M + lz as f32 * lot_d + margin,
                    );
                    let lot_hi = lot_lo + Vec2::new(lot_w, lot_d) - 2.0 * margin;
                    let height = 6.0 + r(4).powi(2) * (14.0 + 110.0 * downtown);
                    let facade = ((r(5) * facades.len() as f32) as usize).min(facades.len() - 1);
                    let tiers = if height > 30.0 {
                        1 + (r(6) * 3.0) as u32
                    } else {
                        1
                    };
                    building(
                        &mut walls[facade],
                        &mut roofs,
                        (lot_lo, lot_hi),
                        height,
                        tiers,
                        &r,
                    );
                }
            }
        }
    }

    let mut parts = vec![(ground, asphalt), (walks, sidewalk), (roofs, roof)];
    parts.extend(walls.into_iter().zip(facades));
    let mesh = b.mesh("city", parts, true);
    let city_node = b.root.push(json::Node {
        mesh: Some(mesh),
        name: Some("city".into()),
        ..Default::default()
    });
    // The street camera stands in the street nearest the centre, in its right-hand lane,
    // one block back from the middle, looking down the avenue and slightly up.
    let street_x = -half + (n / 2) as f32 * pitch + STREET_M * 0.25;
    let eye = Vec3::new(street_x, 1.7, (pitch * 1.5).min(half));
    let street = b.camera(
        "street",
        eye,
        eye + Vec3::new(0.0, 0.12, -1.0),
        50f32.to_radians(),
    );
    let aerial_pos = Vec3::new(0.75 * extent, 0.55 * extent, 0.75 * extent);
    let aerial = b.camera("aerial", aerial_pos, Vec3::ZERO, 40f32.to_radians());
    Ok(b.finish(vec![city_node, street, aerial]))
}

/// One building on the lot `(lo, hi)` (x, z): `tiers` stacked boxes, each inset from the one
/// below (setbacks), most with a cornice (a ledge 0.6 m tall, 0.4 m proud) at the top; the top
/// tier gets a hipped roof (low buildings, sometimes) or a flat roof with a plant room
/// (sometimes). Tier tops are roofs.
fn building(
    walls: &mut Geometry,
    roofs: &mut Geometry,
    (mut lo, mut hi): (Vec2, Vec2),
    height: f32,
    tiers: u32,
    r: &dyn Fn(u32) -> f32,
) {
    const CORNICE_HEIGHT: f32 = 0.6;
    const CORNICE_OUT: f32 = 0.4;
    let mut base = KERB_M;
    for tier in 0..tiers {
        let last = tier + 1 == tiers;
        let share = if last {
            1.0
        } else {
            0.45 + 0.25 * r(10 + tier)
        };
        let top = base + (height + KERB_M - base) * share;
        let size = hi - lo;
        let hipped = last && height < 16.0 && r(20) < 0.5;
        let cornice = !hipped && r(40 + tier) < 0.7;
        walls.box_sides(
            Vec3::new(lo.x, base, lo.y),
            Vec3::new(hi.x, top, hi.y),
            FACADE_TILE,
        );
        if cornice {
            // The ledge's top covers the tier's, so it is the roof.
            let (clo, chi) = (lo - CORNICE_OUT, hi + CORNICE_OUT);
            walls.box_sides(
                Vec3::new(clo.x, top - CORNICE_HEIGHT, clo.y),
                Vec3::new(chi.x, top, chi.y),
                FACADE_TILE,
            );
            roofs.horizontal_quad(clo.x, clo.y, chi.x, chi.y, top, FACADE_TILE.x);
        } else if !hipped {
            roofs.horizontal_quad(lo.x, lo.y, hi.x, hi.y, top, FACADE_TILE.x);
        }
        if hipped {
            let ridge = top + 0.35 * size.min_element();
            let c = [
                Vec3::new(lo.x, top, hi.y),
                Vec3::new(hi.x, top, hi.y),
                Vec3::new(hi.x, top, lo.y),
                Vec3::new(lo.x, top, lo.y),
            ];
            let apex = Vec3::new((lo.x + hi.x) / 2.0, ridge, (lo.y + hi.y) / 2.0);
            for k in 0..4 {
                let (a, b) = (c[k], c[(k + 1) % 4]);
                roofs.triangle([a, b, apex], (a + b) / 2.0 - apex.with_y(top));
            }
        } else if last && r(21) < 0.6 && size.min_element() > 8.0 {
            // A plant room: 15–30 % of the roof, 2–4 m tall, somewhere on it.
            let s = size * (0.15 + 0.15 * r(22));
            let at = lo + (size - s) * Vec2::new(r(23), r(24));
            let h = 2.0 + 2.0 * r(25);
            let (plo, phi) = (
                Vec3::new(at.x, top, at.y),
                Vec3::new(at.x + s.x, top + h, at.y + s.y),
            );
            roofs.box_sides(plo, phi, FACADE_TILE);
            roofs.horizontal_quad(plo.x, plo.z, phi.x, phi.z, phi.y, FACADE_TILE.x);
        }
        // The next tier sets back 8–20 % of this one's size on each side.
        let inset = size * (0.08 + 0.12 * r(30 + tier));
        lo += inset;
        hi -= inset;
        base = top;
    }
}

/// 64×64 asphalt: grey noise with sparse light specks.
fn asphalt_texture(seed: u32) -> image::RgbaImage {
    image::RgbaImage::from_fn(64, 64, |x, y| {
        let v = pcg4d([seed, x, y, 0xa5f]);
        let grey = 70.0 + 40.0 * unit_f32(v[0]) + if v[1].is_multiple_of(23) { 60.0 } else { 0.0 };
        let g = grey as u8;
        image::Rgba([g, g, (grey * 1.03).min(255.0) as u8, 255])
    })
}

/// 64×64 facade bay: a light wall with one dark window (frame, sill), a little noise.
fn windows_texture(seed: u32) -> image::RgbaImage {
    image::RgbaImage::from_fn(64, 64, |x, y| {
        let noise = unit_f32(pcg4d([seed, x, y, 0xb1d])[0]) * 16.0;
        let window = (14..50).contains(&x) && (12..44).contains(&y);
        let frame = (12..52).contains(&x) && (10..46).contains(&y) && !window;
        let sill = (10..54).contains(&x) && (46..49).contains(&y);
        let rgb = if window {
            let pane = if x == 32 { 90.0 } else { 38.0 };
            [
                pane + noise * 0.5,
                pane + 8.0 + noise * 0.5,
                pane + 18.0 + noise * 0.5,
            ]
        } else if frame || sill {
            [200.0, 200.0, 196.0]
        } else {
            [215.0 + noise, 210.0 + noise, 200.0 + noise]
        };
        image::Rgba([rgb[0] as u8, rgb[1] as u8, rgb[2] as u8, 255])
    })
}
