//! The filter's command-line settings (`#[command(flatten)]` them into `render`, `view`, …) and
//! `raygun bench filter`.

use std::path::PathBuf;

use crate::bench::filter::{self as bench, FilterBenchConfig};
use crate::display::DisplayModel;
use crate::filter::denoise::DenoiseParams;
use crate::filter::{
    Blend, DenoiseKind, Denoiser, FilterKind, FilterParams, FilterParamsError, oidn, synth,
};
use crate::gpu::Backend;
use crate::roi::dgi::Surface;

/// Sparse-sample filter settings (DESIGN.md §8; definitions in `src/filter/mod.rs`).
#[derive(Clone, Debug, clap::Args)]
pub struct FilterArgs {
    /// Filter of the sparsely sampled pixels: off, exact (the paper's, slow at large k-max) or
    /// fast (pyramid approximation, interactive).
    #[arg(long = "filter", value_enum, default_value_t = FilterKind::Fast)]
    pub filter: FilterKind,
    /// How the filtered value gives way to the pixel's own: count (the paper, w = 1 − s/c) or
    /// variance (its estimated variance of the mean against --variance-threshold).
    #[arg(long = "filter-blend", value_enum, default_value_t = Blend::Count)]
    pub blend: Blend,
    /// Largest kernel radius, pixels (0 to 64); a pixel's radius is w · k-max · d.
    #[arg(long = "k-max", value_name = "PX", default_value_t = FilterParams::DEFAULT_K_MAX)]
    pub k_max: f32,
    /// Samples at which the count blend shows the pixel's own value only.
    #[arg(long = "filter-c", value_name = "SAMPLES", default_value_t = FilterParams::DEFAULT_C)]
    pub c: f32,
    /// Variance of the mean luminance at and under which the variance blend shows the pixel's
    /// own value only.
    #[arg(long = "variance-threshold", value_name = "VAR",
          default_value_t = FilterParams::DEFAULT_VARIANCE_THRESHOLD)]
    pub variance_threshold: f32,
}

impl FilterArgs {
    /// The validated parameters.
    pub fn params(&self) -> Result<FilterParams, FilterParamsError> {
        let p = FilterParams {
            kind: self.filter,
            blend: self.blend,
            k_max: self.k_max,
            c: self.c,
            variance_threshold: self.variance_threshold,
        };
        p.validate()?;
        Ok(p)
    }
}

/// Denoising of the picture a command writes (DESIGN.md §8).
#[derive(Clone, Debug, clap::Args)]
pub struct DenoiseArgs {
    /// Denoise the picture: off (the filter's picture), interactive (raygun's own edge-avoiding
    /// denoiser, steered by each pixel's albedo, normal and depth, on the render's backend) or
    /// oidn (Intel Open Image Denoise 2 with the same albedo and normal, at its high quality, on
    /// the CUDA device with an NVIDIA GPU, else the CPU; install it with
    /// `bash tools/oidn.sh install`, or set OIDN_DIR).
    #[arg(long, value_enum, default_value_t = DenoiseKind::Off)]
    pub denoise: DenoiseKind,
}

impl DenoiseArgs {
    /// The OIDN device `--denoise oidn` asks for, opened now so that a missing library is an
    /// error before any work; `None` for the others.
    pub fn device(&self, backend: &Backend) -> Result<Option<oidn::Device>, DenoiseArgsError> {
        match self.denoise {
            DenoiseKind::Off | DenoiseKind::Interactive => Ok(None),
            DenoiseKind::Oidn => {
                let choice = oidn::DeviceChoice::Auto {
                    nvidia: backend.is_nvidia(),
                };
                Ok(Some(oidn::Oidn::load()?.device(choice)?))
            }
        }
    }

    /// What denoises the picture: raygun's denoiser with the filter's variance threshold (a
    /// pixel the filter leaves as it is passes through it too), or OIDN on `device` (opened by
    /// [`Self::device`]) at `quality`; `None` for `off`.
    #[must_use]
    pub fn denoiser<'d>(
        &self,
        device: Option<&'d oidn::Device>,
        filter: &FilterParams,
        quality: oidn::Quality,
    ) -> Option<Denoiser<'d>> {
        match self.denoise {
            DenoiseKind::Off => None,
            DenoiseKind::Interactive => Some(Denoiser::Interactive(DenoiseParams {
                variance_threshold: filter.variance_threshold,
                ..DenoiseParams::default()
            })),
            DenoiseKind::Oidn => device.map(|d| Denoiser::Oidn(d, quality)),
        }
    }

    /// What the command says about its denoiser (`None` for `off`).
    #[must_use]
    pub fn describe(&self, device: Option<&oidn::Device>, backend: &Backend) -> Option<String> {
        match (self.denoise, device) {
            (DenoiseKind::Off, _) => None,
            (DenoiseKind::Interactive, _) => Some(match backend {
                Backend::Gpu(ctx) => {
                    format!(
                        "denoise: raygun's interactive denoiser on {}",
                        ctx.describe()
                    )
                }
                Backend::Cpu => "denoise: raygun's interactive denoiser on the CPU".to_owned(),
            }),
            (DenoiseKind::Oidn, Some(d)) => Some(format!("denoise: {}", d.describe())),
            (DenoiseKind::Oidn, None) => None,
        }
    }
}

/// `--denoise oidn` could not open OIDN.
#[derive(Debug, thiserror::Error)]
#[error("--denoise oidn: {0}")]
pub struct DenoiseArgsError(#[from] oidn::OidnError);

#[derive(Clone, Debug, clap::Args)]
pub struct FilterBenchArgs {
    /// Display model (the paper's setup: HORNET).
    #[arg(long, value_name = "MODEL", default_value = crate::display::DEFAULT_MODEL)]
    pub display: String,
    /// Image size in pixels, W,H.
    #[arg(allow_hyphen_values = true, long, value_name = "W,H", value_parser = crate::cli::args::parse_size, default_value = "3840,2160")]
    pub size: [u32; 2],
    /// Fields of view, degrees (square cones).
    #[arg(
        long,
        value_name = "DEG,…",
        value_delimiter = ',',
        default_value = "10,60"
    )]
    pub fov: Vec<f64>,
    /// k_max values to time.
    #[arg(
        long = "time-k-max",
        value_name = "PX,…",
        value_delimiter = ',',
        default_value = "8,16,32"
    )]
    pub time_k_max: Vec<f32>,
    /// Repetitions per timing (median reported; the CPU twins run at most 3).
    #[arg(long, default_value_t = 20)]
    pub reps: u32,
    /// Rounds of the synthetic render.
    #[arg(long, default_value_t = 16)]
    pub rounds: u32,
    /// Reference image of the synthetic render.
    #[arg(long, value_enum, default_value_t = synth::Pattern::Edges)]
    pub pattern: synth::Pattern,
    /// Judge the filters on guided renders of this scene (file or builtin:NAME; `--rounds`
    /// guided iterations each) instead of synthetic renders.
    #[arg(long, value_name = "SCENE")]
    pub scene: Option<String>,
    #[command(flatten)]
    pub access: crate::cli::scene::SceneAccess,
    /// Samples per pixel of the full-frame reference of `--scene`.
    #[arg(long, value_name = "N", default_value_t = 256)]
    pub reference_spp: u32,
    /// Filter settings of the error table (--filter and --filter-blend are ignored: every
    /// filter and blend is measured).
    #[command(flatten)]
    pub filter: FilterArgs,
    #[command(flatten)]
    pub backend: crate::cli::args::BackendArgs,
    /// Print JSON instead of Markdown tables.
    #[arg(long)]
    pub json: bool,
    /// Also write the output to this file.
    #[arg(long, value_name = "FILE")]
    pub out: Option<PathBuf>,
}

/// `raygun bench filter`.
pub fn run_bench(args: &FilterBenchArgs) -> anyhow::Result<()> {
    let error_params = args.filter.params()?;
    for &k in &args.time_k_max {
        FilterParams {
            k_max: k,
            ..error_params
        }
        .validate()?;
    }
    let model = DisplayModel::open(&args.display)?.0;
    let surface = Surface::from_model(&model);
    let backend = args.backend.select()?;
    let config = FilterBenchConfig {
        size: args.size,
        fovs_deg: args.fov.clone(),
        k_maxes: args.time_k_max.clone(),
        reps: args.reps.max(1),
        rounds: args.rounds,
        pattern: args.pattern,
        error_params,
        ..FilterBenchConfig::default()
    };
    // Per FOV: the input, exact and fast per k_max, the error table.
    let steps = config.fovs_deg.len() * (2 + 2 * config.k_maxes.len());
    let (bar, progress) = crate::cli::progress::bench_progress(args.json, steps as u64);
    let report = match &args.scene {
        None => bench::run(&surface, model.name(), &backend, &config, progress)?,
        Some(scene_arg) => {
            let scene = crate::cli::scene::load_scene(scene_arg, None, args.access)?;
            let name = scene_arg.trim_start_matches("builtin:");
            bench::run_with_inputs(
                &surface,
                model.name(),
                &backend,
                &config,
                progress,
                |fov, _| {
                    let subject = crate::bench::paper::Subject {
                        backend: &backend,
                        display: &model,
                        name,
                        scene: &scene,
                    };
                    let shot = crate::bench::paper::Shot {
                        size: args.size,
                        fov,
                        iterations: args.rounds,
                        seed: config.seed,
                    };
                    crate::bench::guided::filter_input(&subject, shot, args.reference_spp)
                        .map_err(|e| bench::FilterBenchError::Render(e.to_string()))
                },
            )?
        }
    };
    bar.finish_and_clear();
    let text = if args.json {
        serde_json::to_string_pretty(&report)?
    } else {
        report.to_markdown()
    };
    crate::cli::progress::print_and_save(&text, args.out.as_deref())
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cli {
        #[command(flatten)]
        filter: FilterArgs,
    }

    #[test]
    fn flags_become_validated_parameters() {
        let p = Cli::parse_from(["x"]).filter.params().unwrap();
        assert_eq!(p, FilterParams::default());
        let p = Cli::parse_from([
            "x",
            "--filter",
            "exact",
            "--filter-blend",
            "variance",
            "--k-max",
            "32",
            "--filter-c",
            "8",
            "--variance-threshold",
            "0.5",
        ])
        .filter
        .params()
        .unwrap();
        assert_eq!(
            p,
            FilterParams {
                kind: FilterKind::Exact,
                blend: Blend::Variance,
                k_max: 32.0,
                c: 8.0,
                variance_threshold: 0.5
            }
        );
        let e = Cli::parse_from(["x", "--k-max", "100"])
            .filter
            .params()
            .unwrap_err();
        assert!(e.to_string().contains("--k-max"), "{e}");
        assert!(Cli::try_parse_from(["x", "--filter", "paper"]).is_err());
    }
}
