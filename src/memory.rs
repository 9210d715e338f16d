//! The memory a run needs, computed before anything is allocated (DESIGN.md §11: each stage
//! states its memory per megapixel), and checked against what the machine has: a size that
//! cannot fit is a clear error naming the size and the bytes, not an allocator abort minutes
//! into the run; a size that fits but is large gets a note first.
//!
//! The per-pixel figures are what each stage holds at its peak, in bytes per image pixel, on
//! the host (the CPU twins, and read-backs and file encoding on either backend) and on the GPU.
//! `tests/memory.rs` measures the host's peak heap of real runs with a counting allocator and
//! holds these figures to it.

use crate::filter::{DenoiseKind, FilterKind};

/// Host bytes per pixel of the accumulation: RGB sum and Σ luminance² (4 × f32), count (u32).
pub const ACCUMULATION_BPP: u64 = 20;
/// The DGI (one f32).
pub const DGI_BPP: u64 = 4;
/// The CPU scheduler's pixel list at its largest (every pixel listed, one u32 each).
pub const SCHEDULE_BPP: u64 = 4;
/// The picture: the mean or filtered image (f32 RGB).
pub const PICTURE_BPP: u64 = 12;
/// The exact filter twin's working set: its f64 RGB output before it becomes the picture, and
/// its per-pixel weights.
pub const EXACT_FILTER_BPP: u64 = 32;
/// The fast filter twin's working set: the pyramid of normalised convolutions (RGB and weight
/// per level, 4/3 of the image in all, f64), the half-octave blend inputs and its f64 output.
pub const FAST_FILTER_BPP: u64 = 152;
/// A full-frame render reads its accumulation out as a copy before the mean image is made.
pub const READ_BACK_BPP: u64 = 20;
/// Writing an image file: the EXR channels copied out (f32 each) and the encoder's buffers, per
/// channel.
pub const ENCODE_BPP_PER_CHANNEL: u64 = 4;
/// The GPU's buffers: accumulation (16), counts (4), the frame's DGI (4) and the DGI kernel's
/// output (4), the pixel list (4), and the filter's output (16) and pyramid (22).
pub const DEVICE_BPP: u64 = 70;
/// The feature buffers (DESIGN.md §8): albedo and normal/depth, an f32 vec4 each, on the host
/// (computed there, or read back) and, while the kernel writes them, per band on the GPU.
pub const FEATURES_BPP: u64 = 32;
/// raygun's denoiser's output as it comes back (f32 RGBA) and the picture made from it (RGB).
pub const DENOISED_BPP: u64 = 28;
/// OIDN's images a pixel: colour, albedo, normal and its output, f32 RGB each, and the picture
/// made from its output (OIDN's own scratch memory is allocated by the library, not counted).
pub const OIDN_BPP: u64 = 60;
/// Motion reuse at a move of the eye (DESIGN.md §11): the old and the new view's primary-hit
/// records (32 bytes each) and the old accumulation kept beside the new one (20).
pub const REUSE_BPP: u64 = 2 * 32 + 20;
/// Motion reuse of a GPU frame in bands, which carries through the host: both views' records,
/// the accumulation read back and the one carried.
pub const REUSE_BANDS_HOST_BPP: u64 = 2 * 32 + 2 * 20;
/// Host memory that does not grow with the image (scene, BVH and libraries are counted apart):
/// allocator slack, thread stacks, small tables.
pub const FIXED_BYTES: u64 = 64 << 20;
/// A note is printed above this much (or above a quarter of what is available).
pub const NOTE_BYTES: u64 = 4 << 30;
/// Largest image: pixel indices are 32-bit on the GPU (and in the files' counts).
pub const MAX_PIXELS: u64 = u32::MAX as u64;

/// What a command will hold, by stage.
#[derive(Clone, Debug, PartialEq)]
pub struct Budget {
    /// Image size.
    pub size: [u32; 2],
    /// (stage, host bytes).
    pub host: Vec<(&'static str, u64)>,
    /// (stage, GPU bytes); empty on the CPU backend.
    pub device: Vec<(&'static str, u64)>,
}

/// What a run needs to do.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Work {
    /// A guided render (`render --guide`, `view`, `demo`): accumulation, DGI, schedule, the
    /// filtered picture.
    Render { gpu: bool, filter: FilterKind },
    /// `render` without a guide: the accumulation, its read-back and the mean image.
    FullFrame { gpu: bool },
    /// `dgi`: the DGI and its file.
    Dgi { gpu: bool },
}

impl Budget {
    /// The budget of `work` at `size` (pixels of the image): what the largest phase of the run
    /// holds at once, by stage. `tests/memory.rs` measures the host side.
    #[must_use]
    pub fn of(work: Work, size: [u32; 2]) -> Self {
        let px = u64::from(size[0]) * u64::from(size[1]);
        let mut host = vec![("fixed", FIXED_BYTES)];
        let mut device = Vec::new();
        match work {
            Work::Render { gpu, filter } => {
                // On the GPU the accumulation lives on the device; the picture reads it back,
                // which holds a host copy as large, and the filter's output comes back too.
                host.push(("accumulation", ACCUMULATION_BPP * px));
                host.push(("DGI", DGI_BPP * px));
                host.push(("picture", PICTURE_BPP * px));
                if gpu {
                    // The filter's f32 RGBA output comes back, then becomes RGB.
                    host.push(("filter read-back", 20 * px));
                    device.push(("accumulation, DGI, list, filter", DEVICE_BPP * px));
                } else {
                    host.push(("schedule", SCHEDULE_BPP * px));
                    match filter {
                        FilterKind::Off => {}
                        FilterKind::Exact => host.push(("exact filter", EXACT_FILTER_BPP * px)),
                        FilterKind::Fast => host.push(("fast filter", FAST_FILTER_BPP * px)),
                    }
                }
            }
            Work::FullFrame { gpu } => {
                host.push(("accumulation", ACCUMULATION_BPP * px));
                host.push(("read-back", READ_BACK_BPP * px));
                host.push(("picture", PICTURE_BPP * px));
                host.push(("file encoding", 3 * ENCODE_BPP_PER_CHANNEL * px));
                if gpu {
                    device.push(("accumulation", (ACCUMULATION_BPP) * px));
                }
            }
            Work::Dgi { gpu } => {
                host.push(("DGI", DGI_BPP * px));
                // One channel: its copy and the encoder's buffers.
                host.push(("file encoding", 2 * ENCODE_BPP_PER_CHANNEL * px));
                if gpu {
                    device.push(("DGI", DGI_BPP * px));
                }
            }
        }
        Self { size, host, device }
    }

    #[must_use]
    pub fn pixels(&self) -> u64 {
        u64::from(self.size[0]) * u64::from(self.size[1])
    }

    #[must_use]
    pub fn host_bytes(&self) -> u64 {
        self.host.iter().map(|(_, b)| b).sum()
    }

    #[must_use]
    pub fn device_bytes(&self) -> u64 {
        self.device.iter().map(|(_, b)| b).sum()
    }

    /// The budget with the GPU buffers of the kernel lab's trace kernel `variant` beyond the
    /// per-pixel figures, on an adapter whose largest binding is `max_binding` bytes: the wavefront
    /// split's path buffers ([`crate::trace::gpu::split_bytes`]), one set a band of the frame,
    /// where the work traces full frames on the GPU (a guided render's iterations trace the
    /// scheduler's lists, which keep the one kernel).
    #[cfg(feature = "kernel-lab")]
    #[must_use]
    pub fn with_trace_kernel(
        mut self,
        work: Work,
        variant: crate::gpu::variant::TraceVariant,
        max_binding: u64,
    ) -> Self {
        if !matches!(work, Work::FullFrame { gpu: true }) || variant.split == 0 {
            return self;
        }
        let [w, h] = self.size;
        let bands = crate::gpu::Band::split(w, h, 16, max_binding).unwrap_or_default();
        let split = bands
            .iter()
            .map(|b| crate::trace::gpu::split_bytes(variant, w, b.rows, max_binding))
            .sum();
        self.device.push(("trace split paths", split));
        self
    }

    /// The budget with the denoiser `kind` of the picture (DESIGN.md §8): the feature buffers,
    /// the denoiser's working set (raygun's on the backend, `gpu` or its CPU twin; OIDN on the
    /// host) and the picture it makes.
    #[must_use]
    pub fn with_denoise(mut self, kind: DenoiseKind, gpu: bool) -> Self {
        let px = self.pixels();
        match kind {
            DenoiseKind::Off => return self,
            DenoiseKind::Interactive => {
                self.host.push(("features", FEATURES_BPP * px));
                self.host.push(("denoised picture", DENOISED_BPP * px));
                if gpu {
                    self.device.push(("features", FEATURES_BPP * px));
                    self.device
                        .push(("denoiser", crate::filter::denoise::DEVICE_BPP * px));
                } else {
                    // Its classes and two (x, c) images, and a band's output before it joins
                    // the picture.
                    self.host
                        .push(("denoiser", (crate::filter::denoise::HOST_BPP + 16) * px));
                }
            }
            DenoiseKind::Oidn => {
                self.host.push(("features", FEATURES_BPP * px));
                self.host.push(("OIDN images", OIDN_BPP * px));
                if gpu {
                    self.device.push(("features", FEATURES_BPP * px));
                }
            }
        }
        self
    }

    /// The budget with motion reuse's working set at a move of the eye (DESIGN.md §11): on the
    /// GPU whose largest storage binding is `gpu_binding` (a frame larger than one binding
    /// carries through the host), else on the host.
    #[must_use]
    pub fn with_reuse(mut self, gpu_binding: Option<u64>) -> Self {
        let px = self.pixels();
        match gpu_binding {
            Some(max) => {
                self.device.push(("motion reuse", REUSE_BPP * px));
                if px * 16 > max {
                    self.host
                        .push(("motion reuse (frame in bands)", REUSE_BANDS_HOST_BPP * px));
                }
            }
            None => self.host.push(("motion reuse", REUSE_BPP * px)),
        }
        self
    }

    /// "accumulation 20 GB, DGI 4 GB, …" (largest first).
    #[must_use]
    pub fn breakdown(&self) -> String {
        let mut lines = self.host.clone();
        lines.sort_by_key(|l| std::cmp::Reverse(l.1));
        lines
            .iter()
            .map(|(stage, b)| format!("{stage} {}", bytes(*b)))
            .collect::<Vec<_>>()
            .join(", ")
    }

    /// Checks the budget against `available_host` bytes (None: unknown) and the GPU's largest
    /// storage binding `max_buffer` (None: CPU backend). `Ok(Some(note))` for a large run that
    /// fits.
    pub fn check(
        &self,
        available_host: Option<u64>,
        max_buffer: Option<u64>,
    ) -> Result<Option<String>, MemoryError> {
        let [w, h] = self.size;
        if self.pixels() > MAX_PIXELS {
            return Err(MemoryError::TooManyPixels {
                width: w,
                height: h,
                pixels: self.pixels(),
            });
        }
        let need = self.host_bytes();
        if let Some(have) = available_host
            && need > have
        {
            return Err(MemoryError::Host {
                width: w,
                height: h,
                need,
                have,
                breakdown: self.breakdown(),
            });
        }
        if let Some(max) = max_buffer {
            // The frame is split into bands of rows to fit the bindings (DESIGN.md §11): the
            // largest buffer is then one row of the accumulation's 16 bytes per pixel at least.
            // (A picture larger than one binding is filtered in bands with halos.)
            let row = 16 * u64::from(w);
            if !self.device.is_empty() && crate::gpu::Band::split(w, h, 16, max).is_none() {
                return Err(MemoryError::DeviceBuffer {
                    width: w,
                    height: h,
                    need: row,
                    max,
                });
            }
        }
        let large = need > NOTE_BYTES || available_host.is_some_and(|have| need > have / 4);
        Ok(large.then(|| {
            format!(
                "{w}×{h} ({:.1} megapixels) needs about {} of memory ({}){}; this will take a while",
                self.pixels() as f64 / 1e6,
                bytes(need),
                self.breakdown(),
                available_host.map_or(String::new(), |have| format!(", of {} available", bytes(have))),
            )
        }))
    }
}

/// Why a size cannot be run here.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MemoryError {
    #[error(
        "--size {width},{height}: {pixels} pixels is more than the {MAX_PIXELS} an image can have (pixel indices are 32-bit)"
    )]
    TooManyPixels {
        width: u32,
        height: u32,
        pixels: u64,
    },
    #[error(
        "--size {width},{height}: this run needs about {} of memory ({breakdown}), and this machine has {} available",
        bytes(*need),
        bytes(*have)
    )]
    Host {
        width: u32,
        height: u32,
        need: u64,
        have: u64,
        breakdown: String,
    },
    #[error(
        "--size {width},{height}: one row of the accumulation needs a GPU buffer of {}, and this adapter's largest is {}; use a smaller size or --backend cpu",
        bytes(*need),
        bytes(*max)
    )]
    DeviceBuffer {
        width: u32,
        height: u32,
        need: u64,
        max: u64,
    },
}

pub use crate::messages::bytes;

/// Memory available to this process now (Linux: `MemAvailable` of /proc/meminfo); `None` where
/// that cannot be read.
#[must_use]
pub fn available_host_bytes() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemAvailable:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

#[cfg(test)]
mod tests {
    use super::*;
    #[cfg(feature = "kernel-lab")]
    use crate::gpu::variant::TraceVariant;

    const GB: u64 = 1 << 30;

    /// The wavefront split's path buffers join the GPU's budget of full-frame renders on the GPU,
    /// a set a band of the frame: 88 bytes a path of a chunk (2¹⁸ paths by default), of the
    /// frame's threads (8 × 8 tiles) where the frame has fewer than a chunk, of what one
    /// binding holds of path states where that is less; nothing for the default kernel, a
    /// guided render (lists), the DGI or the CPU.
    /// Motion reuse adds its working set where it runs: on the GPU, and on the host too for a
    /// frame larger than one binding (it carries through the host); on the CPU, on the host.
    #[test]
    fn motion_reuse_is_counted_where_it_runs() {
        let work = Work::Render {
            gpu: true,
            filter: FilterKind::Exact,
        };
        let size = [1000, 500];
        let px = 500_000;
        let base = Budget::of(work, size);
        let gpu = base.clone().with_reuse(Some(1 << 30));
        assert_eq!(gpu.device_bytes(), base.device_bytes() + REUSE_BPP * px);
        assert_eq!(gpu.host_bytes(), base.host_bytes());
        let banded = base.clone().with_reuse(Some(px * 16 - 1));
        assert_eq!(
            banded.host_bytes(),
            base.host_bytes() + REUSE_BANDS_HOST_BPP * px
        );
        let cpu = base.clone().with_reuse(None);
        assert_eq!(cpu.host_bytes(), base.host_bytes() + REUSE_BPP * px);
        assert!(cpu.breakdown().contains("motion reuse"));
    }

    #[cfg(feature = "kernel-lab")]
    #[test]
    fn the_split_kernels_paths_are_in_the_gpu_budget() {
        let render = Work::Render {
            gpu: true,
            filter: FilterKind::Fast,
        };
        let kernel = |s: &str| s.parse::<TraceVariant>().unwrap();
        let split = |b: &Budget| {
            b.device
                .iter()
                .find(|(stage, _)| *stage == "trace split paths")
                .map(|l| l.1)
        };
        let of = |work: Work, size: [u32; 2], variant: &str, binding: u64| {
            Budget::of(work, size).with_trace_kernel(work, kernel(variant), binding)
        };
        let full = Work::FullFrame { gpu: true };
        let uhd = of(full, [3840, 2160], "private+split", 2 * GB);
        assert_eq!(split(&uhd), Some(88 << 18));
        assert_eq!(
            uhd.device_bytes(),
            Budget::of(full, [3840, 2160]).device_bytes() + (88 << 18)
        );
        let small = of(full, [320, 180], "private+split1048576", 2 * GB);
        assert_eq!(split(&small), Some(88 * 320 * 184));
        // A binding of 1 MiB: 16 384 path states a chunk, and the frame in bands of rows.
        let bands = crate::gpu::Band::split(3840, 2160, 16, 1 << 20)
            .unwrap()
            .len() as u64;
        assert!(bands > 1);
        let banded = of(full, [3840, 2160], "private+split", 1 << 20);
        assert_eq!(split(&banded), Some(bands * 88 * 16_384));
        for none in [
            of(render, [3840, 2160], "private+split", 2 * GB),
            of(full, [3840, 2160], "private", 2 * GB),
            of(full, [3840, 2160], "private+regen528", 2 * GB),
            of(
                Work::Dgi { gpu: true },
                [3840, 2160],
                "private+split",
                2 * GB,
            ),
            of(
                Work::FullFrame { gpu: false },
                [3840, 2160],
                "private+split",
                2 * GB,
            ),
        ] {
            assert_eq!(split(&none), None, "{none:?}");
        }
    }

    #[test]
    fn a_size_beyond_the_machine_is_an_error_naming_size_and_bytes() {
        let b = Budget::of(
            Work::Render {
                gpu: false,
                filter: FilterKind::Fast,
            },
            [60_000, 60_000],
        );
        let e = b.check(Some(24 * GB), None).unwrap_err();
        let text = e.to_string();
        assert!(text.contains("--size 60000,60000"), "{text}");
        assert!(text.contains("GB"), "{text}");
        assert!(text.contains("accumulation"), "{text}");
        let e = Budget::of(Work::Dgi { gpu: false }, [100_000, 100_000])
            .check(None, None)
            .unwrap_err();
        assert!(matches!(e, MemoryError::TooManyPixels { .. }), "{e}");
    }

    #[test]
    fn a_large_size_that_fits_gets_a_note_and_a_small_one_none() {
        let work = Work::Render {
            gpu: false,
            filter: FilterKind::Fast,
        };
        let note = Budget::of(work, [20_000, 20_000])
            .check(Some(256 * GB), None)
            .unwrap()
            .expect("a note");
        assert!(note.contains("400.0 megapixels"), "{note}");
        assert!(
            Budget::of(work, [1280, 720])
                .check(Some(24 * GB), None)
                .unwrap()
                .is_none()
        );
    }

    #[test]
    fn the_gpu_buffer_limit_is_checked_for_gpu_runs_only() {
        let gpu = Work::Render {
            gpu: true,
            filter: FilterKind::Fast,
        };
        // lavapipe: 128 MiB (134.2 MB) per binding; 4096×2160 × 16 B = 141.6 MB.
        assert!(
            Budget::of(gpu, [3840, 2160])
                .check(Some(24 * GB), Some(128 << 20))
                .is_ok()
        );
        // Larger than one binding: split into bands of rows; only a row too wide is refused.
        assert!(
            Budget::of(gpu, [4096, 2160])
                .check(Some(24 * GB), Some(128 << 20))
                .is_ok()
        );
        let e = Budget::of(gpu, [4096, 2160])
            .check(Some(24 * GB), Some(4096 * 16 - 1))
            .unwrap_err();
        assert!(matches!(e, MemoryError::DeviceBuffer { .. }), "{e}");
        let cpu = Work::Render {
            gpu: false,
            filter: FilterKind::Fast,
        };
        assert!(
            Budget::of(cpu, [4096, 2160])
                .check(Some(24 * GB), Some(128 << 20))
                .is_ok()
        );
    }

    #[test]
    fn bytes_read_like_people_write_them() {
        assert_eq!(bytes(160_000_000_000), "160.0 GB");
        assert_eq!(bytes(640_000_000), "640 MB");
        assert_eq!(bytes(12_000), "12 kB");
    }
}
