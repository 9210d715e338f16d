//! `view --cluster --show-tiles` on every rank but 0: a window showing the display tiles this
//! rank owns, laid out as they hang on the wall, each tile its own picture filtered where it
//! is owned (DESIGN.md §12) — on a wall, the window a PC shows on its screens. Each UI frame
//! follows rank 0's steps (on the thread MPI was started on) up to the next picture rank 0
//! asks for, shows it, and the window closes when rank 0's does.

use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use eframe::egui;

use crate::cluster::picture::TilePicture;
use crate::display::DisplayModel;
use crate::session::cluster::{Applied, ClusterView};

pub struct TilesApp<'a> {
    view: ClusterView<'a>,
    /// Per owned tile: its index and texture.
    textures: Vec<(usize, egui::TextureHandle)>,
    /// Whether `last` is newer than the textures.
    fresh: bool,
    stopped: bool,
    /// With `--screenshot-after`: where the last pictures go when rank 0 stops.
    screenshot_dir: Option<PathBuf>,
    /// The latest pictures received.
    last: Option<(Vec<TilePicture>, f32)>,
    /// Why the window closed early, for the caller to report.
    pub failure: Arc<Mutex<Option<String>>>,
}

impl<'a> TilesApp<'a> {
    #[must_use]
    pub fn new(view: ClusterView<'a>, screenshot_dir: Option<PathBuf>) -> Self {
        Self {
            view,
            textures: Vec::new(),
            fresh: false,
            stopped: false,
            screenshot_dir,
            last: None,
            failure: Arc::new(Mutex::new(None)),
        }
    }

    /// Rank 0's steps up to its next picture (or its stop).
    fn follow(&mut self) -> Result<(), crate::cluster::ClusterError> {
        loop {
            match self.view.next_step()? {
                Some((_, Applied::Tiles(pictures, exposure))) => {
                    // Drawn by the next `ui` (a hidden window keeps only the latest).
                    self.last = Some((pictures, exposure));
                    self.fresh = true;
                    return Ok(());
                }
                Some(_) => {}
                None => {
                    self.stopped = true;
                    return Ok(());
                }
            }
        }
    }

    /// The tiles' pictures as textures (sRGB at `exposure` stops, as the viewer shows).
    fn show(&mut self, ctx: &egui::Context, pictures: &[TilePicture], exposure: f32) {
        let model = self.view.model();
        self.textures = pictures
            .iter()
            .map(|p| {
                let [w, h] = model.tiles()[p.tile].resolution();
                let rgba = crate::output::srgb8::display_rgba(&p.pixels, exposure);
                let image =
                    egui::ColorImage::from_rgba_unmultiplied([w as usize, h as usize], &rgba);
                let name = format!("tile {}", model.tiles()[p.tile].id());
                (
                    p.tile,
                    ctx.load_texture(name, image, egui::TextureOptions::LINEAR),
                )
            })
            .collect();
    }

    /// After rank 0 stopped: with `--screenshot-after`, the tiles this window showed last as
    /// PNG files (`rankN-tiles/ID.png`, as `render --tiles` names them); then close.
    fn finish(&mut self, ctx: &egui::Context) {
        if let (Some(dir), Some((pictures, exposure))) = (&self.screenshot_dir, &self.last) {
            let dir = dir.join(format!("rank{}-tiles", self.view.rank()));
            let model = self.view.model();
            let written: Result<Vec<_>, _> = pictures
                .iter()
                .map(|p| {
                    crate::output::tiles::write_tile(
                        &dir,
                        model,
                        p.tile,
                        &p.pixels,
                        crate::output::Format::Png,
                        *exposure,
                    )
                })
                .collect();
            match written {
                Ok(files) => eprintln!(
                    "raygun view: rank {}: saved the {} it showed to {}",
                    self.view.rank(),
                    crate::messages::count(files.len(), "tile"),
                    dir.display()
                ),
                Err(e) => self.fail(format!(
                    "could not save its tiles: {}",
                    crate::messages::chain(&e)
                )),
            }
        }
        self.screenshot_dir = None;
        ctx.send_viewport_cmd(egui::ViewportCommand::Close);
    }

    fn fail(&mut self, message: String) {
        eprintln!("raygun view: rank {}: {message}", self.view.rank());
        if let Ok(mut f) = self.failure.lock() {
            f.get_or_insert(message);
        }
    }
}

/// Where each owned tile goes in a `size` window: the tiles' canvas rectangles (their active
/// areas) scaled together to fit, centred, as they hang.
#[must_use]
pub fn layout(model: &DisplayModel, tiles: &[usize], size: egui::Vec2) -> Vec<egui::Rect> {
    let rects: Vec<_> = tiles
        .iter()
        .map(|&i| model.tiles()[i].active_rect())
        .collect();
    let Some(first) = rects.first() else {
        return Vec::new();
    };
    let (mut min, mut max) = (first.min, first.max);
    for r in &rects {
        min = min.min(r.min);
        max = max.max(r.max);
    }
    let extent = (max - min).max(glam::DVec2::splat(1e-9));
    let scale = (f64::from(size.x) / extent.x).min(f64::from(size.y) / extent.y);
    let offset = (glam::DVec2::new(f64::from(size.x), f64::from(size.y)) - extent * scale) / 2.0;
    let at = |c: glam::DVec2| {
        let p = offset + (c - min) * scale;
        egui::pos2(p.x as f32, p.y as f32)
    };
    rects
        .iter()
        .map(|r| egui::Rect::from_min_max(at(r.min), at(r.max)))
        .collect()
}

impl eframe::App for TilesApp<'_> {
    /// Following rank 0 is logic, not drawing: eframe runs it while the window is covered or
    /// hidden too (a wall's window the console covers must not stall the job).
    fn logic(&mut self, ctx: &egui::Context, _frame: &mut eframe::Frame) {
        // The job needs this rank until rank 0 stops: a wall's window is not closed by hand.
        if !self.stopped && ctx.input(|i| i.viewport().close_requested()) {
            eprintln!(
                "raygun view: rank {}: this window closes with rank 0's",
                self.view.rank()
            );
            ctx.send_viewport_cmd(egui::ViewportCommand::CancelClose);
        }
        if !self.stopped
            && let Err(e) = self.follow()
        {
            self.fail(crate::messages::chain(&e));
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
            return;
        }
        if self.stopped {
            self.finish(ctx);
            return;
        }
        ctx.request_repaint();
    }

    fn ui(&mut self, ui: &mut egui::Ui, _frame: &mut eframe::Frame) {
        if self.fresh {
            self.fresh = false;
            if let Some((pictures, exposure)) = self.last.take() {
                self.show(ui.ctx(), &pictures, exposure);
                self.last = Some((pictures, exposure));
            }
        }
        let size = ui.available_size();
        let origin = ui.min_rect().min.to_vec2();
        let tiles: Vec<usize> = self.textures.iter().map(|t| t.0).collect();
        let places = layout(self.view.model(), &tiles, size);
        let painter = ui.painter();
        painter.rect_filled(ui.max_rect(), 0.0, egui::Color32::BLACK);
        for ((_, texture), place) in self.textures.iter().zip(places) {
            painter.image(
                texture.id(),
                place.translate(origin),
                egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0)),
                egui::Color32::WHITE,
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn owned_tiles_are_laid_out_as_they_hang_and_fit_the_window() {
        let model = DisplayModel::open("hornet").unwrap().0;
        // Columns 5 and 6 (tiles c5r0…c6r4): two columns, five rows.
        let tiles: Vec<usize> = (0..model.tiles().len())
            .filter(|&i| model.tiles()[i].column() >= 5)
            .collect();
        assert_eq!(tiles.len(), 10);
        let size = egui::vec2(800.0, 600.0);
        let places = layout(&model, &tiles, size);
        let bounds = places.iter().fold(places[0], |a, b| a.union(*b));
        // Fits, touching two opposite sides (centred on the other axis).
        assert!(bounds.min.x >= -1e-3 && bounds.min.y >= -1e-3);
        assert!(bounds.max.x <= 800.0 + 1e-3 && bounds.max.y <= 600.0 + 1e-3);
        assert!(
            (bounds.width() - 800.0).abs() < 1e-2 || (bounds.height() - 600.0).abs() < 1e-2,
            "{bounds:?}"
        );
        // Column 6 right of column 5, row 0 above row 4; no two tiles overlap.
        let at = |c: u32, r: u32| {
            let k = tiles
                .iter()
                .position(|&i| model.tiles()[i].column() == c && model.tiles()[i].row() == r)
                .unwrap();
            places[k]
        };
        assert!(at(6, 0).min.x >= at(5, 0).max.x - 1e-3);
        assert!(at(5, 4).min.y >= at(5, 0).max.y - 1e-3);
        for (a, pa) in places.iter().enumerate() {
            for pb in &places[a + 1..] {
                assert!(!pa.shrink(0.01).intersects(pb.shrink(0.01)));
            }
        }
    }
}
