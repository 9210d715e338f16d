//! Which image pixel each tile pixel shows: the map from a rendered image that covers the
//! canvas to the tiles' own pixels, shared by the wall output (`output::tiles`), the cluster's
//! owners and the wall camera (which traces every image pixel a tile shows).

use glam::DVec2;

use super::DisplayModel;

/// The canvas bounding rectangle in whole pixels (each axis rounded to nearest, at least 1):
/// the render size at which tile output is a cut without resampling.
#[must_use]
pub fn canvas_pixel_size(model: &DisplayModel) -> [u32; 2] {
    let s = model.canvas_rect().size();
    [(s.x.round() as u32).max(1), (s.y.round() as u32).max(1)]
}

/// For tile `tile`, the image column of each tile column and the image row of each tile row:
/// the mapping is separable. At the canvas resolution ([`canvas_pixel_size`]) the first pixel is
/// the nearest one and the rest follow by translation, a plain cut (the rounded canvas size
/// differs from the exact one by under half a pixel, so a tile's pixels drift by at most
/// `tile size × that / canvas size`, 0.03 px on HORNET, from the image pixels they take);
/// at other sizes every tile pixel takes the image pixel holding its centre.
#[must_use]
pub fn tile_axes(
    model: &DisplayModel,
    tile: usize,
    image_size: [u32; 2],
) -> (Vec<usize>, Vec<usize>) {
    let t = &model.tiles()[tile];
    let [tw, th] = t.resolution();
    let exact = image_size == canvas_pixel_size(model);
    let nearest = |px: DVec2| {
        let img = model.canvas_to_image(t.tile_px_to_canvas(px + DVec2::splat(0.5)), image_size);
        let clamp = |v: f64, n: u32| (v.floor().max(0.0) as usize).min(n as usize - 1);
        (clamp(img.x, image_size[0]), clamp(img.y, image_size[1]))
    };
    let axis = |n: u32, limit: u32, pick: &dyn Fn(u32) -> usize| -> Vec<usize> {
        if exact {
            let first = pick(0);
            (0..n as usize)
                .map(|i| (first + i).min(limit as usize - 1))
                .collect()
        } else {
            (0..n).map(pick).collect()
        }
    };
    let xs = axis(tw, image_size[0], &|i| {
        nearest(DVec2::new(f64::from(i), 0.0)).0
    });
    let ys = axis(th, image_size[1], &|j| {
        nearest(DVec2::new(0.0, f64::from(j))).1
    });
    (xs, ys)
}
