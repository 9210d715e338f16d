//! `raygun bench picture`: what showing one picture costs, by the three paths a GPU renderer has.
//!
//! * **host** — what the viewer did before the picture stayed on the GPU: read the
//!   accumulation and the DGI back, upload them again as the filter's inputs, filter, read the
//!   filtered picture back, convert it to 8-bit sRGB on the CPU ([`Renderer::picture`], then
//!   [`display_rgba`]) and paint the ROI's outline from the DGI read back.
//! * **GPU-resident** — [`Renderer::shown_picture`]: the filter reads the renderer's own
//!   buffers, the display kernel converts and paints the outline, and only the 8-bit picture
//!   comes back.
//! * **into a texture** — [`Renderer::shown_picture_into`]: the same kernels, then a copy into
//!   a texture on the GPU; nothing comes back (what a window drawing with the renderer's own
//!   device would show).
//!
//! A window shows a picture from the host by uploading its bytes into a texture: the first two
//! paths' *upload* is that (`Queue::write_texture` of the picture into an `Rgba8UnormSrgb`
//! texture, waited for), outside their ms; the window's whole cost of a picture is ms + upload.
//! egui adds its own copy of the bytes into an image before its upload (not measured here).
//!
//! Each path also measures the ROI's statistics the window shows under the picture (every
//! 0.5 s there, [`crate::viewer::core::STATS_PERIOD`]): the host path with the CPU twin
//! ([`RoiStats::measure`]) on the accumulation it read back, the resident path where the
//! accumulation lives ([`Renderer::roi_stats`]: 208 bytes back).
//!
//! A guided render of the paper's setup runs one more frame before each round (the picture
//! changes every time, as in a viewer); each round times the three paths on that accumulation,
//! in a rotating order, and the first round checks that they give the same bytes (the texture
//! read back) and the same statistics (the medians within [`SE_TOLERANCE`]).

use std::time::Instant;

use serde::Serialize;

use crate::display::DisplayModel;
use crate::filter::{FilterKind, FilterParams};
use crate::frame::{FrameError, GuideConfig, Render, Renderer};
use crate::gpu::{Backend, GpuContext, GpuError};
use crate::output::gpu::SE_TOLERANCE;
use crate::output::srgb8::{display_rgba, paint_outline, roi_outline};
use crate::output::stats::RoiStats;
use crate::scene::Scene;

/// One path over the rounds (ms, medians unless said).
#[derive(Clone, Debug, Serialize)]
pub struct PicturePathRow {
    pub path: &'static str,
    pub ms_min: f64,
    pub ms_median: f64,
    /// Host: the accumulation's and the DGI's read-back. Resident: 0 (nothing read back but
    /// the picture).
    pub readback_ms: f64,
    /// Host: the filter call's wall clock (inputs' upload, kernels, picture's read-back).
    /// Resident: the filter's kernels (timestamps where the adapter has them).
    pub filter_ms: f64,
    /// Host: the CPU's conversion. Resident: the display kernel.
    pub display_ms: f64,
    /// Bytes that cross between host and GPU per picture, by construction of the path.
    pub bytes_moved: u64,
    /// The ROI's statistics, outside `ms_*`. Host: the CPU twin on the accumulation read back
    /// (the read-back is `readback_ms`; without a picture it would be read for them alone).
    /// Resident: [`Renderer::roi_stats`]'s wall clock (submit, kernels, read-back).
    pub stats_ms: f64,
    /// The window's upload of the picture's bytes into a texture, outside `ms_*` (0 for the
    /// picture written into a texture on the GPU: it has no bytes on the host).
    pub upload_ms: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct PictureReport {
    pub device: String,
    pub scene: String,
    pub size: [u32; 2],
    pub fov_deg: f64,
    pub filter: FilterParams,
    pub rounds: u32,
    /// Frames rendered before the first round.
    pub warmup_frames: u32,
    /// Whether the resident path's stage times came from GPU timestamps.
    pub gpu_timestamps: bool,
    pub rows: Vec<PicturePathRow>,
}

#[derive(Debug, thiserror::Error)]
pub enum PictureBenchError {
    #[error(
        "bench picture compares a GPU renderer's three paths; the CPU twin has one (pick a GPU)"
    )]
    NoGpu,
    #[error(
        "{w}×{h} does not fit one band on this adapter: its frames and pictures take the host path alone"
    )]
    NotResident { w: u32, h: u32 },
    #[error(
        "the GPU-resident picture differs from the host path's at byte {byte} (pixel {pixel}): {resident} against {host}"
    )]
    Differs {
        byte: usize,
        pixel: usize,
        resident: u8,
        host: u8,
    },
    #[error("the statistics measured on the GPU differ from the CPU twin's: {0}")]
    StatsDiffer(crate::output::stats::StatsMismatch),
    #[error("the picture written into a texture differs from the GPU-resident bytes at byte {0}")]
    TextureDiffers(usize),
    #[error(transparent)]
    Gpu(#[from] crate::gpu::GpuError),
    #[error(transparent)]
    Frame(#[from] FrameError),
    #[error(transparent)]
    Cone(#[from] crate::roi::cone::ConeError),
    #[error(transparent)]
    Camera(#[from] crate::trace::camera::CameraError),
}

/// What to measure.
#[derive(Clone, Debug)]
pub struct PictureConfig {
    pub size: [u32; 2],
    pub fov_deg: f64,
    pub rounds: u32,
    pub filter: FilterParams,
    pub exposure: f32,
    pub seed: u32,
}

const WARMUP_FRAMES: u32 = 2;

/// Times the three paths on `scene` in the paper's setup on `display`.
pub fn run(
    backend: &Backend,
    display: &DisplayModel,
    name: &str,
    scene: &Scene,
    cfg: &PictureConfig,
) -> Result<PictureReport, PictureBenchError> {
    let Backend::Gpu(ctx) = backend else {
        return Err(PictureBenchError::NoGpu);
    };
    let [w, h] = cfg.size;
    let settings = crate::bench::paper::settings(
        scene,
        cfg.size,
        cfg.seed,
        crate::trace::path::DEFAULT_MAX_DEPTH,
    )?;
    let roi = crate::bench::paper::roi(cfg.fov_deg)?;
    let mut g = crate::bench::paper::guided(
        backend,
        scene,
        settings,
        display,
        GuideConfig::default(),
        roi,
    )?;
    if !g.shows_on_gpu(&cfg.filter) {
        return Err(PictureBenchError::NotResident { w, h });
    }
    g.iterate(WARMUP_FRAMES)?;
    let rounds = cfg.rounds.max(1);
    // The texture the window's upload and the into-texture path write.
    let texture = ctx.picture_texture(
        "bench picture texture",
        cfg.size,
        wgpu::TextureFormat::Rgba8UnormSrgb,
        wgpu::TextureUsages::COPY_DST
            | wgpu::TextureUsages::COPY_SRC
            | wgpu::TextureUsages::TEXTURE_BINDING,
    );
    let (mut host, mut resident, mut into) = (Vec::new(), Vec::new(), Vec::new());
    let mut stamps = false;
    for round in 0..rounds {
        g.iterate(1)?;
        // The three paths in a rotating order.
        let (mut a, mut b, mut c) = (None, None, None);
        for k in 0..3 {
            match (round as usize + k) % 3 {
                0 => a = Some(time_host(&g, cfg, ctx, &texture)?),
                1 => b = Some(time_resident(&g, cfg, ctx, &texture)?),
                _ => c = Some(time_into(&g, cfg, ctx, &texture)?),
            }
        }
        let (a, b, c) = (a.expect("timed"), b.expect("timed"), c.expect("timed"));
        if round == 0 {
            same_bytes(&b.1, &a.1, cfg.filter.kind)?;
            a.2.matches(&b.3, SE_TOLERANCE)
                .map_err(PictureBenchError::StatsDiffer)?;
            g.shown_picture_into(&cfg.filter, cfg.exposure, true, &texture)?;
            let texels = ctx.read_texture(&texture)?;
            if let Some(i) = (0..texels.len().max(b.1.len())).find(|&i| texels.get(i) != b.1.get(i))
            {
                return Err(PictureBenchError::TextureDiffers(i));
            }
        }
        stamps = b.2;
        host.push(a.0);
        resident.push(b.0);
        into.push(c);
    }
    let n = u64::from(w) * u64::from(h);
    Ok(PictureReport {
        device: super::device(backend),
        scene: name.to_string(),
        size: cfg.size,
        fov_deg: cfg.fov_deg,
        filter: cfg.filter,
        rounds,
        warmup_frames: WARMUP_FRAMES,
        gpu_timestamps: stamps,
        rows: vec![
            // Read back: sums 16 + counts 4 + DGI 4; uploaded again: 24; picture back: 16.
            row(
                "host (read back, filter, convert on the CPU)",
                &host,
                64 * n,
            ),
            row(
                "GPU-resident (filter and convert on the GPU)",
                &resident,
                4 * n,
            ),
            row(
                "into a texture (filter, convert and copy on the GPU)",
                &into,
                0,
            ),
        ],
    })
}

/// One round's times: [whole, read-back, filter, display, statistics, upload].
type Times = [f64; 6];

/// The window's upload of a picture's bytes into `texture`, waited for (ms).
fn upload(ctx: &GpuContext, texture: &wgpu::Texture, rgba: &[u8]) -> Result<f64, GpuError> {
    let t = Instant::now();
    ctx.queue.write_texture(
        texture.as_image_copy(),
        rgba,
        wgpu::TexelCopyBufferLayout {
            offset: 0,
            bytes_per_row: Some(4 * texture.width()),
            rows_per_image: Some(texture.height()),
        },
        texture.size(),
    );
    ctx.queue.submit([]);
    ctx.wait()?;
    Ok(t.elapsed().as_secs_f64() * 1e3)
}

fn time_host(
    g: &Renderer,
    cfg: &PictureConfig,
    ctx: &GpuContext,
    texture: &wgpu::Texture,
) -> Result<(Times, Vec<u8>, RoiStats), FrameError> {
    let t0 = Instant::now();
    let acc = g.accumulation()?;
    let dgi = g.dgi()?;
    let readback = t0.elapsed().as_secs_f64() * 1e3;
    let t = Instant::now();
    let image = g.picture_of(&cfg.filter, &acc, &dgi)?;
    let filter = t.elapsed().as_secs_f64() * 1e3;
    let t = Instant::now();
    let mut rgba = display_rgba(&image, cfg.exposure);
    paint_outline(&mut rgba, &roi_outline(&dgi, [acc.width, acc.height]));
    let display = t.elapsed().as_secs_f64() * 1e3;
    let whole = t0.elapsed().as_secs_f64() * 1e3;
    let t = Instant::now();
    let p_min = g.guide_config().map_or(0.0, |c| c.p_min);
    let wall = g.wall();
    let stats = RoiStats::measure(&acc, &dgi, p_min, |i| {
        wall.is_none_or(|w| w.is_shown(i as u32))
    });
    let stats_ms = t.elapsed().as_secs_f64() * 1e3;
    let upload_ms = upload(ctx, texture, &rgba)?;
    Ok((
        [whole, readback, filter, display, stats_ms, upload_ms],
        rgba,
        stats,
    ))
}

fn time_resident(
    g: &Renderer,
    cfg: &PictureConfig,
    ctx: &GpuContext,
    texture: &wgpu::Texture,
) -> Result<(Times, Vec<u8>, bool, RoiStats), FrameError> {
    let t0 = Instant::now();
    let p = g.shown_picture(&cfg.filter, cfg.exposure, true, true)?;
    let whole = t0.elapsed().as_secs_f64() * 1e3;
    let t = p.times.expect("timed");
    let s = Instant::now();
    let stats = g.roi_stats()?;
    let stats_ms = s.elapsed().as_secs_f64() * 1e3;
    let upload_ms = upload(ctx, texture, &p.rgba)?;
    Ok((
        [whole, 0.0, t.filter_ms, t.display_ms, stats_ms, upload_ms],
        p.rgba,
        t.gpu_timestamps,
        stats,
    ))
}

/// The picture written into `texture` on the GPU and waited for: the whole is the call and the
/// wait (no stage times: the kernels are the resident path's); the statistics as there.
fn time_into(
    g: &Renderer,
    cfg: &PictureConfig,
    ctx: &GpuContext,
    texture: &wgpu::Texture,
) -> Result<Times, FrameError> {
    let t0 = Instant::now();
    g.shown_picture_into(&cfg.filter, cfg.exposure, true, texture)?;
    ctx.wait()?;
    let whole = t0.elapsed().as_secs_f64() * 1e3;
    let s = Instant::now();
    g.roi_stats()?;
    let stats_ms = s.elapsed().as_secs_f64() * 1e3;
    Ok([whole, 0.0, f64::NAN, f64::NAN, stats_ms, 0.0])
}

/// The paths must agree: byte for byte, but for the unfiltered mean (the GPU divides there,
/// the host path's CPU mean divides on the CPU) within one code.
fn same_bytes(resident: &[u8], host: &[u8], kind: FilterKind) -> Result<(), PictureBenchError> {
    let slack = u8::from(kind == FilterKind::Off);
    let n = resident.len().min(host.len());
    match (0..n).find(|&i| resident[i].abs_diff(host[i]) > slack) {
        None if resident.len() == host.len() => Ok(()),
        found => {
            let byte = found.unwrap_or(n);
            Err(PictureBenchError::Differs {
                byte,
                pixel: byte / 4,
                resident: resident.get(byte).copied().unwrap_or(0),
                host: host.get(byte).copied().unwrap_or(0),
            })
        }
    }
}

fn row(path: &'static str, rounds: &[Times], bytes_moved: u64) -> PicturePathRow {
    let part = |k: usize| crate::bench::median(rounds.iter().map(|t| t[k]).collect());
    PicturePathRow {
        path,
        ms_min: rounds.iter().map(|t| t[0]).fold(f64::INFINITY, f64::min),
        ms_median: part(0),
        readback_ms: part(1),
        filter_ms: part(2),
        display_ms: part(3),
        bytes_moved,
        stats_ms: part(4),
        upload_ms: part(5),
    }
}

/// The report as Markdown, with the resident path's median over the host path's.
#[must_use]
pub fn markdown(r: &PictureReport) -> String {
    let f = &r.filter;
    let mut s = format!(
        "One shown picture of a guided render ({}, {}×{}, {}° ROI, filter {:?} k_max {}), {} rounds after {} frames, a frame before each round, the three paths in each (in a rotating order); device: {}. Medians in ms; *bytes moved* between host and GPU per picture, by construction of the path. Resident stage times from {}. *statistics*: the ROI's statistics the window shows (every 0.5 s), outside the picture's ms: host, the CPU twin on the accumulation read back for the picture; resident, measured on the GPU (208 bytes back). *upload*: the window's upload of the picture's bytes into a texture, waited for, outside ms; *window*: ms + upload, what a window pays for a picture (egui's own copy of the bytes before its upload not included). The texture path's filter and display are the resident path's kernels (not timed apart).\n\n| path | ms min | ms median | read-back | filter | display | bytes moved | statistics | upload | window |\n|---|---|---|---|---|---|---|---|---|---|\n",
        r.scene,
        r.size[0],
        r.size[1],
        r.fov_deg,
        f.kind,
        f.k_max,
        r.rounds,
        r.warmup_frames,
        r.device,
        if r.gpu_timestamps {
            "GPU timestamps"
        } else {
            "the wall clock around each stage (no timestamps)"
        }
    );
    let ms = |v: f64| {
        if v.is_nan() {
            "—".to_string()
        } else {
            format!("{v:.3}")
        }
    };
    for row in &r.rows {
        s += &format!(
            "| {} | {:.3} | {:.3} | {:.3} | {} | {} | {:.1} MB | {:.3} | {:.3} | {:.3} |\n",
            row.path,
            row.ms_min,
            row.ms_median,
            row.readback_ms,
            ms(row.filter_ms),
            ms(row.display_ms),
            row.bytes_moved as f64 / 1e6,
            row.stats_ms,
            row.upload_ms,
            row.ms_median + row.upload_ms
        );
    }
    if let [host, resident, into] = &r.rows[..] {
        s += &format!(
            "\nGPU-resident ÷ host (medians): picture ×{:.3}, statistics ×{:.3} (host with its read-back: ×{:.3}); the window's picture into a texture ÷ resident with its upload: ×{:.3}\n",
            resident.ms_median / host.ms_median,
            resident.stats_ms / host.stats_ms,
            resident.stats_ms / (host.stats_ms + host.readback_ms),
            into.ms_median / (resident.ms_median + resident.upload_ms)
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Both paths run and agree (checked inside `run`), and the table names both with their
    /// stage times inside the whole.
    #[test]
    fn both_paths_agree_and_are_reported() {
        let backend = Backend::Gpu(Box::new(crate::gpu::GpuContext::for_tests()));
        let display = DisplayModel::open("hornet").unwrap().0;
        let scene = Scene::open("builtin:cornell").unwrap();
        let cfg = PictureConfig {
            size: [64, 36],
            fov_deg: 30.0,
            rounds: 3,
            filter: FilterParams::default(),
            exposure: 0.0,
            seed: 1,
        };
        let r = run(&backend, &display, "cornell", &scene, &cfg).unwrap();
        assert_eq!(r.rows.len(), 3);
        for row in &r.rows {
            assert!(row.ms_min > 0.0 && row.ms_min <= row.ms_median, "{row:?}");
            assert!(row.stats_ms > 0.0, "{row:?}");
        }
        for row in &r.rows[..2] {
            assert!(row.filter_ms > 0.0 && row.display_ms > 0.0, "{row:?}");
            assert!(row.upload_ms > 0.0, "{row:?}");
        }
        assert!(r.rows[0].readback_ms > 0.0 && r.rows[1].readback_ms == 0.0);
        assert_eq!(r.rows[0].bytes_moved, 16 * r.rows[1].bytes_moved);
        assert_eq!((r.rows[2].bytes_moved, r.rows[2].upload_ms), (0, 0.0));
        let md = markdown(&r);
        assert!(md.contains("| host (read back"), "{md}");
        assert!(md.contains("| into a texture"), "{md}");
        assert!(md.contains("GPU-resident ÷ host"), "{md}");
        assert!(
            md.contains("into a texture ÷ resident with its upload"),
            "{md}"
        );
        assert!(matches!(
            run(&Backend::Cpu, &display, "cornell", &scene, &cfg),
            Err(PictureBenchError::NoGpu)
        ));
    }

    #[test]
    fn a_differing_byte_is_named() {
        assert!(same_bytes(&[1, 2, 3], &[1, 2, 3], FilterKind::Fast).is_ok());
        assert!(same_bytes(&[1, 2, 4], &[1, 2, 3], FilterKind::Off).is_ok());
        let e = same_bytes(&[1, 2, 4, 0, 9], &[1, 2, 3, 0, 9], FilterKind::Fast).unwrap_err();
        assert!(
            matches!(
                e,
                PictureBenchError::Differs {
                    byte: 2,
                    pixel: 0,
                    resident: 4,
                    host: 3
                }
            ),
            "{e}"
        );
        assert!(same_bytes(&[1, 2], &[1, 2, 3], FilterKind::Fast).is_err());
    }
}
