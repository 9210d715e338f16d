//! The eframe window: a side panel of controls and statistics, and the picture as a texture,
//! re-uploaded each frame. The renderer runs on its own [`crate::gpu::Backend`] (its own wgpu
//! device, or the CPU twins), not on eframe's device: the picture reaches the screen as an
//! egui texture uploaded from host memory. All logic lives in [`ViewerCore`].

use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use eframe::egui;
use glam::DVec2;

use super::core::{Picture, ViewerCore, WindowPicture};
use super::orbit::{Gesture, ViewKey, key_gesture, wall_plan};
use super::save::save_picture;
use super::state::{Overlay, RoiSource};
use crate::filter::{Blend, DenoiseKind, FilterKind};
use crate::frame::EyeMove;
use crate::interaction::CursorMark;
use crate::session::live::LiveTracking;
use crate::session::timeline::Timeline;

/// How long one UI frame may spend rendering before it draws.
pub const FRAME_BUDGET: Duration = Duration::from_millis(30);

/// The ray-gun cursor's colours: tracked, and stale (untracked, off the wall, no data).
pub const CURSOR_LIVE: egui::Color32 = egui::Color32::from_rgb(0, 230, 255);
pub const CURSOR_STALE: egui::Color32 = egui::Color32::from_rgb(128, 128, 128);

/// Where the screenshot callback leaves the window's pixels.
type ShotSlot = Arc<Mutex<Option<Arc<egui::ColorImage>>>>;

/// The fewest pixels the console's picture is reduced to, however small the window (a
/// minimised one shows none): 640 × 360.
const MIN_CONSOLE_PIXELS: u64 = 640 * 360;

/// A picture on the renderer's GPU that egui draws: the texture and egui's name for it.
struct GpuPicture {
    texture: wgpu::Texture,
    id: egui::TextureId,
    size: [u32; 2],
}

pub struct ViewerApp<'a> {
    pub core: ViewerCore<'a>,
    pub timeline: Option<Timeline>,
    pub live: Option<LiveTracking>,
    pub save_dir: PathBuf,
    /// Save the picture after this many iterations and close.
    pub screenshot_after: Option<u32>,
    texture: Option<egui::TextureHandle>,
    /// Where the window draws with the renderer's own device: the texture on that GPU the
    /// renderer writes each picture into ([`ViewerCore::window_picture_into`]), and egui's name
    /// for it.
    gpu_picture: Option<GpuPicture>,
    /// Whether the last picture made is `gpu_picture`'s (else `texture`'s).
    showing_gpu: bool,
    /// Whether the window was given the renderer's device to draw with (`raygun view
    /// --window-gpu shared`, eframe's `WgpuSetup::Existing`): only then can it draw a texture
    /// the renderer writes. (wgpu's handles of two instances can compare equal: ids restart
    /// per instance.)
    pub shares_gpu: bool,
    /// The size of the picture the texture shows (clicks map through it).
    picture_size: [u32; 2],
    /// The screen pixels the picture filled in the last UI frame: across ranks, the console's
    /// picture need not have more ([`ViewerCore::console_pixels`]).
    shown_pixels: u64,
    /// The window screenshot asked for after `screenshot_after` iterations, when it arrives,
    /// and the frames waited for it.
    window_shot: Option<(ShotSlot, u32)>,
    last: Instant,
    saves: u32,
    /// Recording: every UI frame's picture goes to `<save dir>/recording/frame-NNNNN.png`.
    recording: bool,
    recorded: u32,
    message: String,
    error: Option<String>,
    /// A save the command line asked for (`--screenshot-after`) that failed: the command then
    /// exits with this error once the window closes.
    pub failure: Arc<Mutex<Option<String>>>,
}

impl<'a> ViewerApp<'a> {
    #[must_use]
    pub fn new(
        core: ViewerCore<'a>,
        timeline: Option<Timeline>,
        live: Option<LiveTracking>,
        save_dir: PathBuf,
        screenshot_after: Option<u32>,
    ) -> Self {
        Self {
            core,
            timeline,
            live,
            save_dir,
            screenshot_after,
            texture: None,
            gpu_picture: None,
            showing_gpu: false,
            shares_gpu: false,
            picture_size: [1, 1],
            shown_pixels: crate::cluster::CONSOLE_PIXELS,
            window_shot: None,
            last: Instant::now(),
            saves: 0,
            recording: false,
            recorded: 0,
            message: String::new(),
            error: None,
            failure: Arc::new(Mutex::new(None)),
        }
    }

    /// Records a failure of a save the command line asked for; the window closes.
    fn fail(&mut self, ctx: &egui::Context, message: String) {
        eprintln!("raygun view: {message}");
        if let Ok(mut f) = self.failure.lock() {
            f.get_or_insert(message);
        }
        ctx.send_viewport_cmd(egui::ViewportCommand::Close);
    }

    /// The picture written into the window's texture on the renderer's GPU, where the window
    /// draws with the renderer's device and the picture stays on it
    /// ([`ViewerCore::window_picture_into`]); `Ok(false)`: not here (make the bytes).
    fn picture_on_gpu(&mut self, frame: &eframe::Frame) -> Result<bool, super::ViewerError> {
        let Some(rs) = frame.wgpu_render_state().filter(|_| self.shares_gpu) else {
            return Ok(false);
        };
        let size = self.core.size();
        let Some(ctx) = self.core.gpu() else {
            return Ok(false);
        };
        let max = ctx.limits.max_texture_dimension_2d;
        if size[0] > max || size[1] > max {
            return Ok(false);
        }
        if self.gpu_picture.as_ref().is_none_or(|g| g.size != size) {
            // egui's own textures: sRGB-encoded bytes in an Rgba8Unorm texture.
            let texture = ctx.picture_texture(
                "raygun picture",
                size,
                wgpu::TextureFormat::Rgba8Unorm,
                wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            );
            let view = texture.create_view(&Default::default());
            let mut renderer = rs.renderer.write();
            let nearest = wgpu::FilterMode::Nearest;
            let id = match &self.gpu_picture {
                Some(old) => {
                    renderer
                        .update_egui_texture_from_wgpu_texture(&rs.device, &view, nearest, old.id);
                    old.id
                }
                None => {
                    eprintln!(
                        "raygun view: the window draws with the renderer's GPU ({}): its pictures stay there",
                        ctx.info.name
                    );
                    renderer.register_native_texture(&rs.device, &view, nearest)
                }
            };
            self.gpu_picture = Some(GpuPicture { texture, id, size });
        }
        let g = self.gpu_picture.as_ref().expect("made above");
        self.core.window_picture_into(&g.texture)
    }

    fn save(
        &mut self,
        stem: &str,
        picture: &super::core::Picture,
    ) -> Result<(), super::ViewerError> {
        match save_picture(&self.save_dir, stem, picture, self.core.state.exposure) {
            Ok(files) => {
                self.message =
                    format!("saved {} files to {}", files.len(), self.save_dir.display());
                eprintln!("raygun view: {}", self.message);
                Ok(())
            }
            Err(e) => {
                self.message = save_failed(&e);
                Err(e)
            }
        }
    }

    /// The statistics, first in the panel so that no window is too small to show them.
    fn statistics(&mut self, ui: &mut egui::Ui) {
        let picture_took = self.core.picture_took();
        let s = &mut self.core.state;
        ui.heading("Statistics");
        let st = &self.core.stats;
        ui.label(format!("iterations {}", st.iterations));
        ui.label(format!("{:.1} iterations/s", st.iterations_per_s));
        if let Some(share) = st.sampled_share {
            ui.label(format!("pixels sampled {:.1} %", 100.0 * share));
        }
        if let Some(t) = st.last_timed {
            let ms = |v: Option<f64>| v.map_or("–".to_owned(), |v| format!("{v:.2}"));
            ui.label(format!(
                "ms: DGI {} · schedule {} · trace {}",
                ms(st.ms_dgi),
                ms(t.ms_schedule),
                ms(t.ms_trace)
            ));
        }
        if let Some(took) = picture_took {
            // A picture at most every `took` of rendering (ViewerCore::picture_due).
            let way = if self.showing_gpu {
                " (on the GPU, nothing read back)"
            } else {
                ""
            };
            ui.label(format!("picture {:.1} ms{way}", took.as_secs_f64() * 1e3));
        }
        match st.denoised_by {
            Some(super::core::ShownDenoiser::Interactive) => {
                ui.label("denoised by raygun's interactive denoiser");
            }
            Some(super::core::ShownDenoiser::Oidn) => {
                ui.label("denoised by Intel Open Image Denoise (still)");
            }
            None => {}
        }
        if st.denoise_dropped > 0 {
            ui.label(format!(
                "denoiser: {} with NaN or infinite samples dropped",
                crate::messages::count(st.denoise_dropped as usize, "pixel")
            ));
        }
        if st.console_every > 1 {
            let k = st.console_every;
            ui.label(format!(
                "picture: every {k}th pixel of every {k}th row (saves are whole)"
            ));
        }
        if st.roi_pixels > 0 {
            ui.label(format!(
                "ROI: {} samples, {:.1} per pixel",
                st.roi_samples,
                st.roi_samples as f64 / st.roi_pixels as f64
            ));
        }
        if let (Some(roi), Some(far)) = (st.roi_noise, st.periphery_noise) {
            ui.label(format!(
                "noise (median SE of luminance): ROI {roi:.2e}, periphery {far:.2e}"
            ));
        }
        if let Some(p) = st.roi_progress {
            ui.label(format!(
                "ROI now: median SE {:.2e} over all {} pixels, fewest samples {}",
                p.median_se, p.pixels, p.min_samples
            ));
        }
        let mut want_target = s.target_se.is_some();
        ui.horizontal(|ui| {
            ui.checkbox(&mut want_target, "ROI target SE");
            let mut t = s.target_se.unwrap_or(1e-2);
            ui.add_enabled(
                want_target,
                egui::DragValue::new(&mut t)
                    .range(1e-6..=1.0)
                    .speed(1e-4)
                    .max_decimals(6),
            );
            s.target_se = want_target.then_some(t);
        });
        if let Some(target) = s.target_se {
            ui.label(match st.seconds_to_target(target) {
                Some(t) if t <= 0.0 => "target reached".to_owned(),
                Some(t) => format!("about {t:.0} s to the target at this rate"),
                None => "time to the target: not yet known (pixels need two samples)".to_owned(),
            });
        }
        ui.label(self.core.backend_name());
        if !self.message.is_empty() {
            ui.label(&self.message);
        }
        if let Some(e) = &self.error {
            ui.colored_label(egui::Color32::RED, e);
        }
    }

    fn controls(&mut self, ui: &mut egui::Ui) -> bool {
        let has_oidn = self.core.has_oidn();
        let s = &mut self.core.state;
        let mut save = false;
        ui.heading("ROI");
        ui.horizontal(|ui| {
            ui.radio_value(&mut s.source, RoiSource::Mouse, "mouse");
            if self.timeline.is_some() {
                ui.radio_value(&mut s.source, RoiSource::Replay, "replay");
            }
            if self.live.is_some() {
                ui.radio_value(&mut s.source, RoiSource::Live, "live");
            }
        });
        ui.add(
            egui::Slider::new(&mut s.mouse_radius_px, 20.0..=4000.0)
                .logarithmic(true)
                .text("mouse ROI radius (canvas px)"),
        );
        if let Some(t) = &self.timeline {
            ui.horizontal(|ui| {
                if ui
                    .button(if s.playing { "pause" } else { "play" })
                    .clicked()
                {
                    if !s.playing && s.replay_t >= t.duration {
                        s.replay_t = 0.0;
                    }
                    s.playing = !s.playing;
                }
                ui.add(egui::Slider::new(&mut s.replay_t, 0.0..=t.duration).text("s"));
            });
        }
        let mut fov_override = s.fov_override_deg.is_some();
        ui.horizontal(|ui| {
            ui.checkbox(&mut fov_override, "FOV override");
            let mut f = s.fov_override_deg.unwrap_or(30.0);
            ui.add_enabled(
                fov_override,
                egui::Slider::new(&mut f, 1.0..=120.0).text("FOV (°)"),
            );
            s.fov_override_deg = fov_override.then_some(f);
        });
        if self.timeline.is_some() || self.live.is_some() {
            let c = &mut s.cursor.config;
            ui.checkbox(&mut c.smooth, "smooth the cursor (1€ filter)");
            ui.add_enabled(
                c.smooth,
                egui::Slider::new(&mut c.min_cutoff_hz, 0.05..=10.0)
                    .logarithmic(true)
                    .text("cursor cutoff at rest (Hz)"),
            );
            ui.add_enabled(
                c.smooth,
                egui::Slider::new(&mut c.beta, 0.0..=0.1)
                    .logarithmic(true)
                    .smallest_positive(1e-4)
                    .text("cursor speed gain β (Hz per px/s)"),
            );
            ui.add_enabled(
                c.smooth,
                egui::Slider::new(&mut c.max_extrapolation_s, 0.0..=0.1)
                    .text("cursor extrapolation (s)"),
            );
        }
        if let Some(r) = &s.tracked {
            ui.label(format!(
                "tracked FOV {:.1}°×{:.1}°, filter {}",
                r.fov_deg[0],
                r.fov_deg[1],
                if r.filter { "on" } else { "off" }
            ));
        }
        ui.separator();
        ui.heading("Guide");
        ui.add(egui::Slider::new(&mut s.falloff_base_m, 0.01..=2.0).text("falloff base (m)"));
        ui.add(egui::Slider::new(&mut s.falloff_scale, 0.0..=4.0).text("falloff scale"));
        ui.add(egui::Slider::new(&mut s.p_min, 0.0..=1.0).text("p_min"));
        ui.add(egui::Slider::new(&mut s.max_depth, 1..=16).text("max path depth"));
        if ui.button("reset accumulation").clicked() {
            s.reset = true;
        }
        ui.separator();
        ui.heading("Filter");
        ui.horizontal(|ui| {
            ui.radio_value(&mut s.filter.kind, FilterKind::Off, "off");
            ui.radio_value(&mut s.filter.kind, FilterKind::Fast, "fast");
            ui.radio_value(&mut s.filter.kind, FilterKind::Exact, "exact");
        });
        ui.add(egui::Slider::new(&mut s.filter.k_max, 0.0..=64.0).text("k_max (px)"));
        ui.horizontal(|ui| {
            ui.radio_value(&mut s.filter.blend, Blend::Count, "count");
            ui.radio_value(&mut s.filter.blend, Blend::Variance, "variance");
        });
        ui.add(
            egui::Slider::new(&mut s.filter.c, 1.0..=1024.0)
                .logarithmic(true)
                .text("c (samples)"),
        );
        ui.add(
            egui::Slider::new(&mut s.filter.variance_threshold, 1e-7..=1e-1)
                .logarithmic(true)
                .text("variance threshold"),
        );
        ui.separator();
        ui.heading("Denoise");
        ui.horizontal(|ui| {
            ui.radio_value(&mut s.denoise, DenoiseKind::Off, "off");
            ui.radio_value(&mut s.denoise, DenoiseKind::Interactive, "interactive");
            ui.add_enabled_ui(has_oidn, |ui| {
                ui.radio_value(&mut s.denoise, DenoiseKind::Oidn, "OIDN when still")
                    .on_disabled_hover_text(
                        "start the viewer with --denoise oidn (Intel Open Image Denoise installed)",
                    );
            });
        });
        ui.separator();
        ui.heading("View");
        ui.horizontal(|ui| {
            ui.radio_value(&mut s.overlay, Overlay::Image, "image");
            ui.radio_value(&mut s.overlay, Overlay::Dgi, "DGI");
            ui.radio_value(&mut s.overlay, Overlay::Counts, "samples");
            ui.radio_value(&mut s.overlay, Overlay::Noise, "noise");
        });
        ui.checkbox(&mut s.roi_outline, "ROI outline");
        ui.checkbox(&mut s.wall_view, "wall view (bezels)");
        ui.add(egui::Slider::new(&mut s.exposure, -6.0..=6.0).text("exposure (EV)"));
        if ui.button("save image + overlays").clicked() {
            save = true;
        }
        ui.checkbox(&mut self.recording, "record (a PNG per frame)");
        ui.separator();
        save
    }

    /// The eye (wall camera) or the pinhole camera: where it is, the restart threshold, and a
    /// sketch of the wall and the eye from above.
    fn eye_panel(&mut self, ui: &mut egui::Ui) {
        let eye = self.core.eye();
        let restarts = self.core.restarts;
        let (reused, last_reuse) = (self.core.moves_reused, self.core.last_reuse);
        let local = self.core.is_local();
        // Across ranks every move restarts.
        let mut policy = if local {
            self.core.state.on_eye_move
        } else {
            EyeMove::Restart
        };
        let refused = self.core.eye_refused.clone();
        let camera_at = self.core.settings().camera.position;
        let model = self.core.model;
        let s = &mut self.core.state;
        ui.heading(if eye.is_some() {
            "Eye (wall camera)"
        } else {
            "Camera"
        });
        match eye {
            Some(e) => {
                ui.label(format!(
                    "eye (room frame) {:+.3}, {:+.3}, {:+.3} m",
                    e.x, e.y, e.z
                ));
                if let Some(h) = s.head {
                    ui.label(format!(
                        "tracked head's eye {:+.3}, {:+.3}, {:+.3} m",
                        h.x, h.y, h.z
                    ));
                    ui.checkbox(&mut s.follow_head, "follow the tracked head");
                }
            }
            None => {
                let p = camera_at;
                ui.label(format!(
                    "camera (scene frame) {:+.3}, {:+.3}, {:+.3}",
                    p.x, p.y, p.z
                ));
            }
        }
        let mut mm = s.eye_threshold_m * 1e3;
        ui.add(egui::Slider::new(&mut mm, 0.0..=100.0).text("restart when moved (mm)"));
        s.eye_threshold_m = mm * 1e-3;
        ui.add_enabled_ui(local, |ui| {
            ui.horizontal(|ui| {
                ui.label("on a move:");
                ui.radio_value(&mut policy, EyeMove::Reuse, "reuse the picture");
                ui.radio_value(&mut policy, EyeMove::Restart, "restart");
            });
        });
        ui.label(format!(
            "moves carried {reused} · restarts {restarts} · drag: orbit · shift/middle drag: pan · wheel: dolly (or arrows, shift+arrows, +/−)"
        ));
        if let Some(r) = last_reuse {
            ui.label(format!(
                "the last move carried {:.0} % of the shown pixels",
                100.0 * r.share()
            ));
        }
        if let Some(r) = refused {
            ui.colored_label(egui::Color32::YELLOW, format!("eye refused: {r}"));
        }
        if let Some(e) = eye {
            let plan = wall_plan(model);
            let (response, painter) = ui.allocate_painter(
                egui::vec2(ui.available_width().min(260.0), 140.0),
                egui::Sense::hover(),
            );
            let rect = response.rect;
            painter.rect_filled(rect, 2.0, egui::Color32::from_gray(24));
            let eye2 = DVec2::new(e.x, e.z);
            let head2 = s.head.map(|h| DVec2::new(h.x, h.z));
            let pts: Vec<DVec2> = plan
                .iter()
                .flatten()
                .copied()
                .chain([eye2])
                .chain(head2)
                .collect();
            let lo = pts
                .iter()
                .copied()
                .fold(DVec2::splat(f64::INFINITY), DVec2::min);
            let hi = pts
                .iter()
                .copied()
                .fold(DVec2::splat(f64::NEG_INFINITY), DVec2::max);
            let span = (hi - lo).max(DVec2::splat(1e-3));
            let inner = rect.shrink(10.0);
            let scale = (f64::from(inner.width()) / span.x).min(f64::from(inner.height()) / span.y);
            let mid = (lo + hi) * 0.5;
            let to = |p: DVec2| {
                let q = (p - mid) * scale;
                egui::pos2(inner.center().x + q.x as f32, inner.center().y + q.y as f32)
            };
            let ends = plan.iter().flatten().copied();
            let left = ends.clone().fold(None::<DVec2>, |a, p| {
                Some(a.map_or(p, |a| if p.x < a.x { p } else { a }))
            });
            let right = ends.fold(None::<DVec2>, |a, p| {
                Some(a.map_or(p, |a| if p.x > a.x { p } else { a }))
            });
            for end in [left, right].into_iter().flatten() {
                painter.line_segment(
                    [to(eye2), to(end)],
                    egui::Stroke::new(1.0, egui::Color32::from_gray(90)),
                );
            }
            for [a, b] in &plan {
                painter.line_segment(
                    [to(*a), to(*b)],
                    egui::Stroke::new(2.0, egui::Color32::LIGHT_GRAY),
                );
            }
            if let Some(h) = head2 {
                painter.circle_stroke(to(h), 5.0, egui::Stroke::new(1.5, CURSOR_LIVE));
            }
            painter.circle_filled(to(eye2), 4.0, egui::Color32::YELLOW);
            painter.text(
                rect.left_top() + egui::vec2(4.0, 2.0),
                egui::Align2::LEFT_TOP,
                "from above: wall, eye (yellow), head (cyan)",
                egui::FontId::proportional(10.0),
                egui::Color32::GRAY,
            );
        }
        ui.separator();
        if local && policy != self.core.state.on_eye_move {
            self.core.set_on_eye_move(policy);
        }
    }
}

/// The keys that move the viewpoint, pressed this frame (none while a widget has the focus).
fn view_keys(ui: &egui::Ui) -> Vec<Gesture> {
    if ui.ctx().memory(|m| m.focused().is_some()) {
        return Vec::new();
    }
    ui.input(|i| {
        let shift = i.modifiers.shift;
        [
            (egui::Key::ArrowLeft, ViewKey::Left),
            (egui::Key::ArrowRight, ViewKey::Right),
            (egui::Key::ArrowUp, ViewKey::Up),
            (egui::Key::ArrowDown, ViewKey::Down),
            (egui::Key::Plus, ViewKey::In),
            (egui::Key::Equals, ViewKey::In),
            (egui::Key::PageUp, ViewKey::In),
            (egui::Key::Minus, ViewKey::Out),
            (egui::Key::PageDown, ViewKey::Out),
        ]
        .into_iter()
        .filter(|(k, _)| i.key_pressed(*k))
        .map(|(_, v)| key_gesture(v, shift))
        .collect()
    })
}

impl eframe::App for ViewerApp<'_> {
    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        let dt = self.last.elapsed().as_secs_f64();
        self.last = Instant::now();
        if let Some(t) = &self.timeline
            && self.core.state.source == RoiSource::Replay
        {
            self.core.state.advance(dt, t);
        }
        if let Some(l) = &mut self.live
            && self.core.state.source == RoiSource::Live
        {
            self.core.state.apply_live(l.update());
        }
        let save = self.side_panel(ui);
        let stepped = self.core.step(FRAME_BUDGET);
        // Across ranks, no more of the picture than the window shows (at least a small
        // window's, at most a 4K monitor's): the owners send those pixels only.
        self.core.console_pixels = self
            .shown_pixels
            .clamp(MIN_CONSOLE_PIXELS, crate::cluster::CONSOLE_PIXELS);
        // Files take the whole picture with its data (the window's has only its bytes, and
        // across ranks it may be reduced to the console's size: then the owners send every
        // pixel for these frames only). A recording takes the window's bytes where they are
        // the whole picture's.
        let shot_due = self
            .screenshot_after
            .is_some_and(|n| self.core.stats.iterations >= n);
        // A new picture when one is due (`ViewerCore::picture_due`: at most half of the time
        // goes to pictures) or a file or the recording wants one; else the last stays shown.
        let shown = if self.showing_gpu {
            self.gpu_picture.is_some()
        } else {
            self.texture.is_some()
        };
        let wanted = save || shot_due || self.recording || !shown || self.core.picture_due();
        // On the renderer's own device the picture goes into the window's texture on the GPU
        // and nothing comes back (saves and screenshots take the whole picture below, on their
        // own); a recording wants the window's bytes.
        let on_gpu = match &stepped {
            Ok(()) if wanted && !self.recording => self.picture_on_gpu(frame),
            _ => Ok(false),
        };
        let on_gpu = match on_gpu {
            Ok(done) => done,
            Err(e) => {
                self.error = Some(crate::messages::chain(&e));
                ui.ctx().request_repaint_after(Duration::from_millis(200));
                return;
            }
        };
        if on_gpu {
            self.error = None;
            self.showing_gpu = true;
            self.picture_size = self.core.size();
        }
        let picture = stepped.and_then(|()| {
            if wanted && !on_gpu {
                self.core.window_picture().map(Some)
            } else {
                Ok(None)
            }
        });
        let picture = match picture {
            Ok(p) => {
                self.error = None;
                p
            }
            Err(e) => {
                self.error = Some(crate::messages::chain(&e));
                ui.ctx().request_repaint_after(Duration::from_millis(200));
                return;
            }
        };
        if let Some(picture) = &picture {
            let max_side = ui.ctx().input(|i| i.max_texture_side) as u32;
            let (texels, [tw, th]) =
                super::texture::fit_texture(&picture.rgba, picture.size, max_side);
            let image =
                egui::ColorImage::from_rgba_unmultiplied([tw as usize, th as usize], &texels);
            self.showing_gpu = false;
            match &mut self.texture {
                Some(t) => t.set(image, egui::TextureOptions::NEAREST),
                None => {
                    self.texture = Some(ui.ctx().load_texture(
                        "raygun picture",
                        image,
                        egui::TextureOptions::NEAREST,
                    ));
                }
            }
            self.picture_size = picture.size;
        }
        let whole_view = self.core.console_every() == 1;
        let whole = if save || shot_due || (self.recording && !whole_view) {
            match self.core.whole_picture() {
                Ok(p) => Some(p),
                Err(e) => {
                    self.error = Some(crate::messages::chain(&e));
                    ui.ctx().request_repaint_after(Duration::from_millis(200));
                    return;
                }
            }
        } else {
            None
        };
        // Recording makes a picture every UI frame (`wanted` above).
        if let Some(picture) = picture.as_ref().filter(|_| self.recording) {
            self.record(picture, whole.as_ref());
        }
        if let (true, Some(whole)) = (save, &whole) {
            self.saves += 1;
            let stem = format!("view-{:03}", self.saves);
            let _ = self.save(&stem, whole);
        }
        if let Some(n) = self.screenshot_after
            && self.core.stats.iterations >= n
        {
            // The picture files now; the whole window once the integration has read it back.
            let whole = whole
                .as_ref()
                .expect("taken above when a screenshot is due");
            if let Err(e) = self.save("screenshot", whole) {
                self.fail(ui.ctx(), save_failed(&e));
                return;
            }
            self.request_window_screenshot(ui);
        }
        self.poll_window_screenshot(ui);
        // The cursor at the display's frame time on the events' clock.
        let cursor = match self.core.state.source {
            RoiSource::Mouse => None,
            RoiSource::Replay => self.core.state.cursor_mark(self.core.state.replay_t),
            RoiSource::Live => self
                .live
                .as_ref()
                .and_then(LiveTracking::now)
                .and_then(|t| self.core.state.cursor_mark(t)),
        };
        egui::CentralPanel::default_margins().show(ui, |ui| self.picture_panel(ui, cursor));
        ui.ctx().request_repaint();
    }
}

impl ViewerApp<'_> {
    /// The panel of statistics, eye and controls on the left, scrolled; whether a save was
    /// asked for.
    fn side_panel(&mut self, ui: &mut egui::Ui) -> bool {
        egui::Panel::left("controls")
            .show(ui, |ui| {
                // A scroll bar that is always drawn, not one that appears on hover only: the
                // panel is taller than a 700-pixel window.
                let mut scroll = egui::style::ScrollStyle::solid();
                scroll.dormant_handle_opacity = scroll.active_handle_opacity;
                scroll.dormant_background_opacity = scroll.active_background_opacity;
                ui.style_mut().spacing.scroll = scroll;
                egui::ScrollArea::vertical()
                    .auto_shrink([false, false])
                    .scroll_bar_visibility(egui::scroll_area::ScrollBarVisibility::AlwaysVisible)
                    .show(ui, |ui| {
                        self.statistics(ui);
                        ui.separator();
                        self.eye_panel(ui);
                        self.controls(ui)
                    })
                    .inner
            })
            .inner
    }

    /// The next frame of the recording: `whole` where the picture was taken whole, else the
    /// window's `picture`.
    fn record(&mut self, picture: &WindowPicture, whole: Option<&Picture>) {
        let dir = self.save_dir.join("recording");
        let path = dir.join(format!("frame-{:05}.png", self.recorded));
        let (size, rgba) = match whole {
            Some(p) => (p.size, &p.rgba),
            None => (picture.size, &picture.rgba),
        };
        let saved = std::fs::create_dir_all(&dir)
            .map_err(|error| super::ViewerError::CreateDir {
                dir: dir.clone(),
                error,
            })
            .and_then(|()| super::save::save_rgba_png(&path, size, rgba));
        match saved {
            Ok(()) => {
                self.recorded += 1;
                self.message = format!("recording: {} frames in {}", self.recorded, dir.display());
            }
            Err(e) => {
                self.recording = false;
                self.message = format!("recording stopped: {}", crate::messages::chain(&e));
            }
        }
    }

    /// Asks for a screenshot of the whole window (the picture's files are saved): it arrives
    /// in a later UI frame ([`Self::poll_window_screenshot`]).
    fn request_window_screenshot(&mut self, ui: &mut egui::Ui) {
        let slot = Arc::new(Mutex::new(None));
        let (s, ctx) = (Arc::clone(&slot), ui.ctx().clone());
        ui.ctx().request_screenshot(move |img| {
            if let Ok(mut g) = s.lock() {
                *g = Some(img);
            }
            ctx.request_repaint();
        });
        self.window_shot = Some((slot, 0));
        self.screenshot_after = None;
    }

    /// Waits for the window screenshot asked for with the picture's (up to 300 UI frames),
    /// saves it and closes the window.
    fn poll_window_screenshot(&mut self, ui: &mut egui::Ui) {
        if let Some((slot, waited)) = &mut self.window_shot {
            *waited += 1;
            let shot = slot.lock().ok().and_then(|mut g| g.take());
            if let Some(img) = shot {
                let path = self.save_dir.join("screenshot.window.png");
                let [sw, sh] = img.size;
                let saved = image::RgbaImage::from_raw(sw as u32, sh as u32, img.as_raw().to_vec())
                    .map(|i| {
                        crate::output::replace_with(&path, |tmp| {
                            i.save_with_format(tmp, image::ImageFormat::Png)
                                .map_err(|error| super::ViewerError::Png {
                                    path: path.clone(),
                                    error,
                                })
                        })
                    });
                match saved {
                    Some(Ok(())) => {
                        eprintln!("raygun view: saved {}", path.display());
                        ui.ctx().send_viewport_cmd(egui::ViewportCommand::Close);
                    }
                    _ => {
                        let ctx = ui.ctx().clone();
                        self.fail(&ctx, format!("could not save {}", path.display()));
                    }
                }
            } else if *waited > 300 {
                eprintln!("raygun view: no window screenshot arrived; closing");
                ui.ctx().send_viewport_cmd(egui::ViewportCommand::Close);
            }
        }
    }

    /// The picture, fitted to the panel, with the camera's gestures, the clicks that move the
    /// region of interest and the ray gun's `cursor` drawn over it.
    fn picture_panel(&mut self, ui: &mut egui::Ui, cursor: Option<CursorMark>) {
        let model = self.core.model;
        // The window shows the window's picture (a reduced one across ranks: clicks map by it).
        let [w, h] = self.picture_size;
        let size = [w, h];
        let tex = if self.showing_gpu {
            self.gpu_picture
                .as_ref()
                .map(|g| egui::load::SizedTexture::new(g.id, [g.size[0] as f32, g.size[1] as f32]))
        } else {
            self.texture
                .as_ref()
                .map(egui::load::SizedTexture::from_handle)
        };
        let Some(tex) = tex else { return };
        let avail = ui.available_size();
        let aspect = w as f32 / h as f32;
        let fit = if avail.x / aspect <= avail.y {
            egui::vec2(avail.x, avail.x / aspect)
        } else {
            egui::vec2(avail.y * aspect, avail.y)
        };
        let ppp = ui.ctx().pixels_per_point();
        self.shown_pixels = (fit.x * ppp).max(0.0) as u64 * (fit.y * ppp).max(0.0) as u64;
        let r = ui.add(
            egui::Image::new(tex)
                .fit_to_exact_size(fit)
                .sense(egui::Sense::click_and_drag()),
        );
        // Orbit (drag), pan (shift- or middle-drag, or the right button), dolly (wheel),
        // and the keys: the eye of a wall camera or the pinhole camera, under the restart
        // rule (applied by the core's next sync).
        let d = r.drag_delta();
        if d != egui::Vec2::ZERO {
            let px = DVec2::new(f64::from(d.x), f64::from(d.y));
            let shift = ui.input(|i| i.modifiers.shift);
            if r.dragged_by(egui::PointerButton::Middle)
                || r.dragged_by(egui::PointerButton::Secondary)
                || (shift && r.dragged_by(egui::PointerButton::Primary))
            {
                self.core.state.gesture(Gesture::Pan(px));
            } else if r.dragged_by(egui::PointerButton::Primary) {
                self.core.state.gesture(Gesture::Orbit(px));
            }
        }
        if r.hovered() {
            let wheel = ui.input(|i| i.smooth_scroll_delta.y);
            if wheel != 0.0 {
                self.core.state.gesture(Gesture::Dolly(f64::from(wheel)));
            }
        }
        for g in view_keys(ui) {
            self.core.state.gesture(g);
        }
        let to_image = |p: egui::Pos2| {
            DVec2::new(
                f64::from((p.x - r.rect.min.x) / r.rect.width() * w as f32),
                f64::from((p.y - r.rect.min.y) / r.rect.height() * h as f32),
            )
        };
        let to_screen = |canvas: DVec2| {
            let px = model.canvas_to_image(canvas, size);
            egui::pos2(
                r.rect.min.x + px.x as f32 / w as f32 * r.rect.width(),
                r.rect.min.y + px.y as f32 / h as f32 * r.rect.height(),
            )
        };
        if r.clicked()
            && let Some(p) = r.interact_pointer_pos()
        {
            self.core.state.click(model, to_image(p), size);
        }
        let painter = ui.painter_at(r.rect);
        let cross = |c: egui::Pos2, colour: egui::Color32| {
            let stroke = egui::Stroke::new(2.0, colour);
            painter.line_segment(
                [c - egui::vec2(10.0, 0.0), c + egui::vec2(10.0, 0.0)],
                stroke,
            );
            painter.line_segment(
                [c - egui::vec2(0.0, 10.0), c + egui::vec2(0.0, 10.0)],
                stroke,
            );
            painter.circle_stroke(c, 6.0, stroke);
        };
        // The ray gun's aim (tracked sources): cyan while tracked, grey where it was last
        // seen while untracked, off the wall or silent.
        match cursor {
            Some(CursorMark::Live(a)) => cross(to_screen(a), CURSOR_LIVE),
            Some(CursorMark::Stale(a)) => cross(to_screen(a), CURSOR_STALE),
            None => {}
        }
    }
}

/// The status line, and the failure, of a save that failed.
fn save_failed(e: &super::ViewerError) -> String {
    format!("save failed: {}", crate::messages::chain(e))
}
