//! The wgpu context: adapter choice and the CPU fallback.
//!
//! "Make a device" is separate from "do the work with this device" (as in wgpu's examples): every
//! GPU stage takes a `&GpuContext`, so tests inject theirs and the binary picks one with
//! [`Backend::select`]. When no adapter exists, `--backend auto` falls back to the CPU twins; the
//! program must run on a machine with no GPU and no Vulkan driver.

use std::fmt;

#[cfg(feature = "kernel-lab")]
pub mod variant;
pub mod wgsl;

/// What the user asked for on the command line (`--backend gpu|cpu|auto`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum BackendChoice {
    /// The best GPU adapter (a software one too); an error when there is none.
    Gpu,
    /// The CPU versions of every stage, on all cores (the path tracer in 32-bit floats like
    /// the GPU's, the distance-guide image in 64-bit).
    Cpu,
    /// The GPU when a hardware one exists, else the CPU (a software GPU such as lavapipe runs
    /// slower than the CPU versions; `--backend gpu` uses it anyway).
    #[default]
    Auto,
}

/// The backend a command computes on, after [`Backend::select`].
pub enum Backend {
    Gpu(Box<GpuContext>),
    Cpu,
}

impl Backend {
    /// Resolves the user's choice into a backend. `Auto` falls back to the CPU (and says so on
    /// standard error) when no hardware adapter can be created; `Gpu` takes any adapter and
    /// turns having none into an error. Both refuse a `RAYGUN_TRACE_KERNEL` that a build
    /// without the kernel lab cannot honour.
    pub fn select(choice: BackendChoice) -> Result<Self, GpuError> {
        let (backend, note) = Self::choose(choice)?;
        if let Some(note) = note {
            eprintln!("raygun: {note}");
        }
        Ok(backend)
    }

    /// [`Self::select`] that returns what it would say (why `auto` took the CPU) instead of
    /// printing it, for a command that prints only when it is not `--quiet`.
    pub fn choose(choice: BackendChoice) -> Result<(Self, Option<String>), GpuError> {
        match choice {
            BackendChoice::Cpu => Ok((Self::Cpu, None)),
            BackendChoice::Gpu => Ok((Self::Gpu(Box::new(GpuContext::new()?)), None)),
            BackendChoice::Auto => match GpuContext::new() {
                // A software rasteriser (lavapipe) runs our kernels several times slower than
                // the CPU twins on the same cores (the exact DGI at 3840×2160: 13–26× the f64
                // twin's time on 2 cores; BENCHMARKS.md, *Distance-guide image*), so `auto`
                // takes the twins.
                Ok(ctx) if ctx.info.device_type == wgpu::DeviceType::Cpu => Ok((
                    Self::Cpu,
                    Some(format!(
                        "the only adapter is a software rasteriser ({}); using the CPU backend \
                         (--backend gpu forces it)",
                        ctx.info.name
                    )),
                )),
                Ok(ctx) => Ok((Self::Gpu(Box::new(ctx)), None)),
                // A kernel asked for that this build does not have is the user's error, not a
                // missing GPU.
                #[cfg(not(feature = "kernel-lab"))]
                Err(e @ GpuError::NoKernelLab { .. }) => Err(e),
                Err(e) => Ok((
                    Self::Cpu,
                    Some(format!(
                        "no usable GPU adapter ({e}); using the CPU backend"
                    )),
                )),
            },
        }
    }

    /// The GPU's largest storage binding in bytes (what one buffer a kernel reads may hold);
    /// `None` on the CPU backend.
    #[must_use]
    pub fn max_binding(&self) -> Option<u64> {
        match self {
            Self::Gpu(ctx) => Some(ctx.max_binding()),
            Self::Cpu => None,
        }
    }

    /// Whether this is the GPU backend.
    #[must_use]
    pub fn is_gpu(&self) -> bool {
        matches!(self, Self::Gpu(_))
    }

    /// Whether the GPU backend runs on an NVIDIA adapter (PCI vendor 0x10de).
    #[must_use]
    pub fn is_nvidia(&self) -> bool {
        matches!(self, Self::Gpu(ctx) if ctx.info.vendor == 0x10de)
    }

    /// The adapter's description on the GPU backend; `None` on the CPU twins.
    #[must_use]
    pub fn adapter(&self) -> Option<String> {
        match self {
            Self::Gpu(ctx) => Some(ctx.describe()),
            Self::Cpu => None,
        }
    }

    /// A human-readable name: the adapter's name and API, or the CPU twin with its thread count.
    #[must_use]
    pub fn describe(&self) -> String {
        match self {
            Self::Gpu(ctx) => ctx.describe(),
            Self::Cpu => format!(
                "CPU twins (rayon, {} threads)",
                rayon::current_num_threads()
            ),
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum GpuError {
    #[error(
        "no GPU adapter found (on Linux without a GPU, install Mesa's software Vulkan driver: \
         `apt-get install mesa-vulkan-drivers`)"
    )]
    NoAdapter,
    #[error("no adapter's name contains {wanted:?} (RAYGUN_ADAPTER); found: {found}")]
    NoMatchingAdapter { wanted: String, found: String },
    #[error("could not create a device on {adapter}: {source}")]
    RequestDevice {
        adapter: String,
        #[source]
        source: wgpu::RequestDeviceError,
    },
    #[error("{what} needs {bytes} bytes in one binding; this adapter allows {max}")]
    TooLarge {
        what: &'static str,
        bytes: u64,
        max: u64,
    },
    #[error("RAYGUN_MAX_BINDING={value:?}: expected a number of bytes, at least 4")]
    BadMaxBinding { value: String },
    #[cfg(feature = "kernel-lab")]
    #[error("RAYGUN_TRACE_KERNEL={value:?}: {why}")]
    BadTraceKernel { value: String, why: String },
    #[cfg(feature = "kernel-lab")]
    #[error("trace kernel {variant}: {why}")]
    TraceVariant { variant: String, why: String },
    #[cfg(not(feature = "kernel-lab"))]
    #[error(
        "RAYGUN_TRACE_KERNEL={value:?}: this build has the one trace kernel raygun ships; the \
         kernel's variants are in builds with the kernel-lab feature (cargo build --features \
         kernel-lab), or unset RAYGUN_TRACE_KERNEL"
    )]
    NoKernelLab { value: String },
    #[error(
        "the scene's BVH needs {needs} entries on the trace kernel's traversal stack, which \
         holds {holds}: render it with --backend cpu"
    )]
    TraceStack { needs: u32, holds: u32 },
    #[error("GPU buffer read-back failed: {0}")]
    Map(#[from] wgpu::BufferAsyncError),
    #[error("GPU poll failed: {0}")]
    Poll(#[from] wgpu::PollError),
}

/// A band of image rows: the part of a frame one set of GPU buffers holds when the whole
/// frame does not fit the adapter's storage bindings (DESIGN.md §11). Kernels index their
/// buffers by the band's pixel `p` and draw random numbers, cameras and guides for the image
/// pixel `row0 · width + p`, so a frame split into bands computes the whole frame's values.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Band {
    pub row0: u32,
    pub rows: u32,
}

impl Band {
    /// All `height` rows: the frame unsplit.
    #[must_use]
    pub fn whole(height: u32) -> Self {
        Self {
            row0: 0,
            rows: height,
        }
    }

    /// The image index of the band's pixel 0 in a `width`-wide image.
    #[must_use]
    pub fn pixel_base(&self, width: u32) -> u32 {
        self.row0 * width
    }

    /// The bands of a `width × height` image whose every buffer holds at most
    /// `bytes_per_pixel` bytes a pixel and must fit `max_binding` bytes: as few as can be, of
    /// equal height but the last; `None` when not even one row fits.
    #[must_use]
    pub fn split(
        width: u32,
        height: u32,
        bytes_per_pixel: u64,
        max_binding: u64,
    ) -> Option<Vec<Self>> {
        let row_bytes = u64::from(width.max(1)) * bytes_per_pixel;
        let fit = max_binding / row_bytes;
        if fit == 0 {
            return None;
        }
        let count = u64::from(height).div_ceil(fit).max(1) as u32;
        let rows = height.div_ceil(count).max(1);
        Some(
            (0..count)
                .map(|i| {
                    let row0 = i * rows;
                    Self {
                        row0,
                        rows: rows.min(height - row0),
                    }
                })
                .filter(|b| b.rows > 0)
                .collect(),
        )
    }
}

/// A device and queue on the chosen adapter, with what the stages need to know about it. A
/// clone shares the device and queue (wgpu's handles): a second user of the same GPU.
#[derive(Clone)]
pub struct GpuContext {
    /// The instance and the adapter the device was made from: a window that draws with the
    /// same device needs them (`raygun view`, where the picture then never leaves the GPU).
    pub instance: wgpu::Instance,
    pub adapter: wgpu::Adapter,
    pub device: wgpu::Device,
    pub queue: wgpu::Queue,
    pub info: wgpu::AdapterInfo,
    pub limits: wgpu::Limits,
    /// Whether GPU timestamp queries are enabled (benchmarks use them for per-kernel times).
    pub timestamps: bool,
    /// What the adapter supports (not all of it is enabled).
    pub supported: wgpu::Features,
    /// Mappable buffers kept between read-backs ([`STAGING_KEEP_BYTES`] in all; clones share
    /// them): a viewer reads the same buffers back for every picture, and on a discrete GPU
    /// each fresh mappable buffer is a fresh host allocation the driver must map for the GPU.
    staging: std::sync::Arc<std::sync::Mutex<Vec<wgpu::Buffer>>>,
    /// The trace kernel's variant ([`variant::TraceVariant`]): the default unless
    /// `RAYGUN_TRACE_KERNEL` or [`Self::with_trace_variant`] chose another.
    #[cfg(feature = "kernel-lab")]
    trace_variant: variant::TraceVariant,
    /// What [`Self::kept`] made for this device, by type and key (clones share it).
    kept: std::sync::Arc<std::sync::Mutex<KeptMap>>,
}

/// [`GpuContext::kept`]'s values: one per type and key.
type KeptMap = std::collections::HashMap<
    (std::any::TypeId, String),
    std::sync::Arc<dyn std::any::Any + Send + Sync>,
>;

/// The most bytes of read-back staging buffers a context keeps for reuse (a 3840×2160
/// picture's accumulation, counts, DGI and filtered image are 366 MB; a larger read-back
/// still works, through a buffer of its own).
pub const STAGING_KEEP_BYTES: u64 = 1 << 30;

impl fmt::Debug for GpuContext {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.describe())
    }
}

/// Every adapter wgpu finds, as "NAME (API, TYPE, driver DRIVER INFO)".
#[must_use]
pub fn list_adapters() -> Vec<String> {
    pollster::block_on(async {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        instance
            .enumerate_adapters(wgpu::Backends::all())
            .await
            .iter()
            .map(|a| {
                let i = a.get_info();
                format!(
                    "{} ({:?}, {:?}, driver {} {})",
                    i.name, i.backend, i.device_type, i.driver, i.driver_info
                )
            })
            .collect()
    })
}

/// Ranks adapters: real GPUs first, then virtual, then software rasterisers; among equals the
/// native APIs (Vulkan, Metal, DX12) before GL, whose compute support is the weakest.
fn adapter_rank(device_type: wgpu::DeviceType, backend: wgpu::Backend) -> (u8, u8) {
    let kind = match device_type {
        wgpu::DeviceType::DiscreteGpu => 0,
        wgpu::DeviceType::IntegratedGpu => 1,
        wgpu::DeviceType::VirtualGpu => 2,
        wgpu::DeviceType::Other => 3,
        wgpu::DeviceType::Cpu => 4,
    };
    let api = match backend {
        wgpu::Backend::Vulkan | wgpu::Backend::Metal | wgpu::Backend::Dx12 => 0,
        _ => 1,
    };
    (kind, api)
}

impl GpuContext {
    /// The largest storage binding in bytes (what one buffer a kernel reads may hold): the
    /// binding limit the device was created with, or the largest buffer if that is smaller.
    #[must_use]
    pub fn max_binding(&self) -> u64 {
        self.limits
            .max_storage_buffer_binding_size
            .min(self.limits.max_buffer_size)
    }

    /// A clear error where `bytes` of `what` would not fit one storage binding.
    pub fn check_binding(&self, what: &'static str, bytes: u64) -> Result<(), GpuError> {
        let max = self.max_binding();
        if bytes > max {
            return Err(GpuError::TooLarge { what, bytes, max });
        }
        Ok(())
    }

    /// A WGSL shader module.
    #[must_use]
    pub fn shader_module(&self, label: &str, source: &str) -> wgpu::ShaderModule {
        self.device
            .create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some(label),
                source: wgpu::ShaderSource::Wgsl(source.into()),
            })
    }

    /// The compute pipeline of `entry` in `module`, its layout taken from the shader.
    #[must_use]
    pub fn compute_pipeline_in(
        &self,
        module: &wgpu::ShaderModule,
        label: &str,
        entry: &str,
    ) -> wgpu::ComputePipeline {
        self.device
            .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(label),
                layout: None,
                module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
    }

    /// The compute pipeline of `entry` in the WGSL `source` (one module per pipeline).
    #[must_use]
    pub fn compute_pipeline(
        &self,
        label: &str,
        source: &str,
        entry: &str,
    ) -> wgpu::ComputePipeline {
        self.compute_pipeline_in(&self.shader_module(label, source), label, entry)
    }

    /// Picks the best adapter (see `adapter_rank`); the environment variable `RAYGUN_ADAPTER`
    /// restricts the choice to adapters whose name contains its value.
    ///
    /// `RAYGUN_MAX_BINDING=BYTES` caps the storage binding the device is created with (wgpu
    /// then enforces it): a frame larger than one binding is split into bands of rows
    /// (DESIGN.md §11), and this exercises that split on an adapter whose own limit is large.
    ///
    /// `RAYGUN_TRACE_KERNEL=VARIANT` compiles the trace kernel as another variant of the same
    /// function in a build with the `kernel-lab` feature (`variant::TraceVariant`: `function`,
    /// `private` or `workgroup`, then the options its `FromStr` names), for timing them on a
    /// GPU; a build without the feature refuses it.
    pub fn new() -> Result<Self, GpuError> {
        let cap = match std::env::var("RAYGUN_MAX_BINDING") {
            Ok(v) => Some(
                v.trim()
                    .parse::<u64>()
                    .ok()
                    .filter(|&b| b >= 4)
                    .ok_or(GpuError::BadMaxBinding { value: v })?,
            ),
            Err(_) => None,
        };
        let kernel = std::env::var("RAYGUN_TRACE_KERNEL").ok();
        #[cfg(not(feature = "kernel-lab"))]
        if let Some(value) = kernel {
            return Err(GpuError::NoKernelLab { value });
        }
        #[cfg(feature = "kernel-lab")]
        let kernel = kernel
            .map(|value| {
                value
                    .parse::<variant::TraceVariant>()
                    .map_err(|why| GpuError::BadTraceKernel { value, why })
            })
            .transpose()?;
        let ctx = pollster::block_on(Self::new_async(cap))?;
        #[cfg(feature = "kernel-lab")]
        if let Some(variant) = kernel {
            return ctx.with_trace_variant(variant);
        }
        Ok(ctx)
    }

    /// [`Self::new`] with the storage binding capped at `max_binding` bytes (rounded down to a
    /// multiple of 4; the adapter's own limit if smaller), whatever `RAYGUN_MAX_BINDING` says:
    /// for tests of the split into bands.
    pub fn with_max_binding(max_binding: u64) -> Result<Self, GpuError> {
        pollster::block_on(Self::new_async(Some(max_binding)))
    }

    async fn new_async(max_binding: Option<u64>) -> Result<Self, GpuError> {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let mut adapters = instance.enumerate_adapters(wgpu::Backends::all()).await;
        // GL adapters cannot run our storage-buffer compute kernels reliably; keep them only
        // when nothing else exists.
        if adapters
            .iter()
            .any(|a| a.get_info().backend != wgpu::Backend::Gl)
        {
            adapters.retain(|a| a.get_info().backend != wgpu::Backend::Gl);
        }
        if let Ok(wanted) = std::env::var("RAYGUN_ADAPTER") {
            let found: Vec<String> = adapters.iter().map(|a| a.get_info().name).collect();
            adapters.retain(|a| a.get_info().name.contains(&wanted));
            if adapters.is_empty() {
                return Err(GpuError::NoMatchingAdapter {
                    wanted,
                    found: found.join(", "),
                });
            }
        }
        adapters.sort_by_key(|a| {
            let info = a.get_info();
            adapter_rank(info.device_type, info.backend)
        });
        let adapter = adapters.into_iter().next().ok_or(GpuError::NoAdapter)?;
        let info = adapter.get_info();
        let supported = adapter.features();
        let timestamps = supported.contains(wgpu::Features::TIMESTAMP_QUERY);
        let mut features = wgpu::Features::empty();
        if timestamps {
            features |= wgpu::Features::TIMESTAMP_QUERY;
        }
        // Subgroup operations where the adapter has them, in a kernel-lab build: the trace
        // kernel's `+vote` variants use them (raygun's kernels do not).
        #[cfg(feature = "kernel-lab")]
        {
            features |= supported & wgpu::Features::SUBGROUP;
        }
        // Ask for everything the adapter offers: big images need big storage bindings
        // (3840×2160 RGBA f32 is 133 MB, over lavapipe's 128 MiB binding limit but far under
        // an H100's 2 GiB), and stages check the limits they need themselves.
        let mut limits = adapter.limits();
        if let Some(cap) = max_binding {
            limits.max_storage_buffer_binding_size =
                limits.max_storage_buffer_binding_size.min(cap / 4 * 4);
        }
        let (device, queue) = adapter
            .request_device(&wgpu::DeviceDescriptor {
                label: Some("raygun"),
                required_features: features,
                required_limits: limits.clone(),
                ..Default::default()
            })
            .await
            .map_err(|source| GpuError::RequestDevice {
                adapter: info.name.clone(),
                source,
            })?;
        Ok(Self {
            instance,
            adapter,
            device,
            queue,
            info,
            limits,
            timestamps,
            supported,
            staging: std::sync::Arc::default(),
            #[cfg(feature = "kernel-lab")]
            trace_variant: variant::TraceVariant::default(),
            kept: std::sync::Arc::default(),
        })
    }

    /// The name reports give the trace kernel renderers made on this context compile: `private`
    /// (its traversal stack in private memory, the kernel as written) where it is the one raygun
    /// ships, else the kernel lab's variant.
    #[must_use]
    pub fn trace_kernel_name(&self) -> String {
        #[cfg(feature = "kernel-lab")]
        if self.trace_variant != variant::TraceVariant::default() {
            return self.trace_variant.to_string();
        }
        "private".to_string()
    }

    /// The trace kernel's variant renderers made on this context compile.
    #[cfg(feature = "kernel-lab")]
    #[must_use]
    pub fn trace_variant(&self) -> variant::TraceVariant {
        self.trace_variant
    }

    /// This context (the same device, queue and kept buffers) with the trace kernel compiled
    /// as `variant`; an error naming the variant where the adapter's limits do not allow it.
    #[cfg(feature = "kernel-lab")]
    pub fn with_trace_variant(&self, variant: variant::TraceVariant) -> Result<Self, GpuError> {
        variant.check(&self.limits, self.device.features())?;
        Ok(Self {
            trace_variant: variant,
            ..self.clone()
        })
    }

    /// The value `make` gives for `key`, made once for this device and handed out again to
    /// every later call with the same type and key on this context or its clones: compiled
    /// pipelines, which every renderer needs and whose creation costs a driver far more than a
    /// frame (a report makes dozens of renderers). `make` runs without the map locked, so it may
    /// use the context; where two threads make the same value at once, the first one kept wins.
    pub fn kept<T: Clone + Send + Sync + 'static>(&self, key: &str, make: impl FnOnce() -> T) -> T {
        let id = (std::any::TypeId::of::<T>(), key.to_string());
        let lock = || {
            self.kept
                .lock()
                .unwrap_or_else(std::sync::PoisonError::into_inner)
        };
        let found = lock().get(&id).cloned();
        let value = match found {
            Some(v) => v,
            None => {
                let made: std::sync::Arc<dyn std::any::Any + Send + Sync> =
                    std::sync::Arc::new(make());
                lock().entry(id).or_insert(made).clone()
            }
        };
        value
            .downcast_ref::<T>()
            .expect("kept values are stored under their own type")
            .clone()
    }

    /// For tests: the context, or a panic that says how to get an adapter. A GPU test never
    /// passes silently without one.
    #[must_use]
    pub fn for_tests() -> Self {
        match Self::new() {
            Ok(ctx) => ctx,
            Err(e) => panic!(
                "GPU tests need a wgpu adapter: {e}. `bash .ci/run` installs Mesa's software \
                 Vulkan driver (lavapipe) and runs every test; or install it alone with \
                 `apt-get install mesa-vulkan-drivers`."
            ),
        }
    }

    /// What a benchmark run should record about the adapter: name, API, driver, subgroup
    /// sizes, the limits raygun's kernels depend on and the features that matter to them.
    #[must_use]
    pub fn report(&self) -> serde_json::Value {
        let l = &self.limits;
        let has = |f: wgpu::Features| self.supported.contains(f);
        serde_json::json!({
            "name": self.info.name,
            "backend": format!("{:?}", self.info.backend),
            "device_type": format!("{:?}", self.info.device_type),
            "driver": self.info.driver,
            "driver_info": self.info.driver_info,
            "vendor": self.info.vendor,
            "device": self.info.device,
            "subgroup_min_size": self.info.subgroup_min_size,
            "subgroup_max_size": self.info.subgroup_max_size,
            "limits": {
                "max_storage_buffer_binding_size": l.max_storage_buffer_binding_size,
                "max_buffer_size": l.max_buffer_size,
                "max_storage_buffers_per_shader_stage": l.max_storage_buffers_per_shader_stage,
                "max_compute_workgroup_size_x": l.max_compute_workgroup_size_x,
                "max_compute_invocations_per_workgroup": l.max_compute_invocations_per_workgroup,
                "max_compute_workgroups_per_dimension": l.max_compute_workgroups_per_dimension,
                "max_compute_workgroup_storage_size": l.max_compute_workgroup_storage_size,
            },
            "features": {
                "timestamp_query": has(wgpu::Features::TIMESTAMP_QUERY),
                "timestamp_query_inside_passes": has(wgpu::Features::TIMESTAMP_QUERY_INSIDE_PASSES),
                "subgroup": has(wgpu::Features::SUBGROUP),
                "shader_f64": has(wgpu::Features::SHADER_F64),
                "shader_f16": has(wgpu::Features::SHADER_F16),
                "shader_int64": has(wgpu::Features::SHADER_INT64),
            },
            "timestamps_enabled": self.timestamps,
            "trace_kernel": self.trace_kernel_name(),
        })
    }

    /// "NAME (API, driver DRIVER INFO)", and in a kernel-lab build ", trace kernel VARIANT"
    /// where the trace kernel is not the default one (so that every figure it measured says
    /// which).
    #[must_use]
    pub fn describe(&self) -> String {
        let s = format!(
            "{} ({:?}, {:?}, driver {} {})",
            self.info.name,
            self.info.backend,
            self.info.device_type,
            self.info.driver,
            self.info.driver_info
        );
        #[cfg(feature = "kernel-lab")]
        if self.trace_variant != variant::TraceVariant::default() {
            return format!("{s}, trace kernel {}", self.trace_variant);
        }
        s
    }

    /// Blocks until all submitted work is done.
    pub fn wait(&self) -> Result<(), GpuError> {
        self.device.poll(wgpu::PollType::wait_indefinitely())?;
        Ok(())
    }

    /// A 2D texture of `size` (one layer, one mip level, no multisampling) in `format` with
    /// `usage`: a picture's texture (the window's, and the benchmarks' and tests').
    pub fn picture_texture(
        &self,
        label: &str,
        [width, height]: [u32; 2],
        format: wgpu::TextureFormat,
        usage: wgpu::TextureUsages,
    ) -> wgpu::Texture {
        self.device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage,
            view_formats: &[],
        })
    }

    /// The texels of a four-byte-a-texel 2D `texture` (which needs `COPY_SRC`), row-major
    /// without padding: copied into a buffer whose rows are padded to
    /// [`wgpu::COPY_BYTES_PER_ROW_ALIGNMENT`], read back, and the padding dropped.
    pub fn read_texture(&self, texture: &wgpu::Texture) -> Result<Vec<u8>, GpuError> {
        let (w, h) = (texture.width(), texture.height());
        let pitch = (4 * w).next_multiple_of(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT);
        let buffer = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("texture read-back"),
            size: u64::from(pitch) * u64::from(h),
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let mut enc = self.device.create_command_encoder(&Default::default());
        enc.copy_texture_to_buffer(
            texture.as_image_copy(),
            wgpu::TexelCopyBufferInfo {
                buffer: &buffer,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(pitch),
                    rows_per_image: Some(h),
                },
            },
            texture.size(),
        );
        self.queue.submit([enc.finish()]);
        let padded: Vec<u8> = self.read_buffer(&buffer)?;
        Ok(padded
            .chunks_exact(pitch as usize)
            .flat_map(|row| row[..4 * w as usize].iter().copied())
            .collect())
    }

    /// Copies `src` (which needs `COPY_SRC`) into a fresh mappable buffer and reads it back.
    pub fn read_buffer<T: bytemuck::Pod>(&self, src: &wgpu::Buffer) -> Result<Vec<T>, GpuError> {
        self.read_prefix(src, src.size())
    }

    /// [`Self::read_buffer`] of the first `size` bytes of `src` alone (a multiple of 4).
    pub fn read_prefix<T: bytemuck::Pod>(
        &self,
        src: &wgpu::Buffer,
        size: u64,
    ) -> Result<Vec<T>, GpuError> {
        if size == 0 {
            return Ok(Vec::new());
        }
        let staging = self.take_staging(size);
        let mut enc = self
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("raygun read-back"),
            });
        enc.copy_buffer_to_buffer(src, 0, &staging, 0, size);
        self.queue.submit([enc.finish()]);
        let slice = staging.slice(..size);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        self.wait()?;
        rx.recv()
            .expect("map_async callback runs during poll")
            .map_err(GpuError::Map)?;
        let data = {
            let view = slice
                .get_mapped_range()
                .expect("buffer was just mapped for reading");
            bytemuck::cast_slice(&view).to_vec()
        };
        staging.unmap();
        self.keep_staging(staging);
        Ok(data)
    }

    /// A mappable buffer of at least `size` bytes: the smallest kept one that holds it, else a
    /// new one.
    fn take_staging(&self, size: u64) -> wgpu::Buffer {
        let mut kept = self
            .staging
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        let best = kept
            .iter()
            .enumerate()
            .filter(|(_, b)| b.size() >= size)
            .min_by_key(|(_, b)| b.size())
            .map(|(i, _)| i);
        match best {
            Some(i) => kept.swap_remove(i),
            None => self.device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("raygun read-back"),
                size,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
        }
    }

    /// Keeps an unmapped read-back buffer for the next read-back, the oldest kept ones
    /// dropped past [`STAGING_KEEP_BYTES`] (a buffer larger than that alone is dropped).
    fn keep_staging(&self, buffer: wgpu::Buffer) {
        if buffer.size() > STAGING_KEEP_BYTES {
            return;
        }
        let mut kept = self
            .staging
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        kept.push(buffer);
        while kept.iter().map(wgpu::Buffer::size).sum::<u64>() > STAGING_KEEP_BYTES {
            kept.remove(0);
        }
    }

    /// Drops the kept read-back buffers (the next read-back makes a fresh one: what every
    /// read-back did before they were kept; `raygun bench readback` compares the two).
    pub fn clear_staging(&self) {
        self.staging
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner)
            .clear();
    }

    /// Bytes of read-back buffers kept for reuse now.
    #[must_use]
    pub fn staging_kept_bytes(&self) -> u64 {
        let kept = self
            .staging
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        kept.iter().map(wgpu::Buffer::size).sum()
    }
}

/// The 2D dispatch grid `[gx, gy]` of `groups` workgroups with at most `max_per_dim` along a
/// dimension (65 535 in WebGPU's defaults): gx·gy ≥ groups with fewer than gy idle groups, and
/// `[0, 1]` for no groups. A kernel indexes its group as `wg.y · gx + wg.x`. Every 2D grid
/// raygun dispatches comes from here (the tracer's indirect one through
/// [`crate::schedule::indirect_grid`], its CPU twin).
#[must_use]
pub fn grid_2d(groups: u32, max_per_dim: u32) -> [u32; 2] {
    if groups == 0 {
        return [0, 1];
    }
    let gy = groups.div_ceil(max_per_dim.max(1));
    [groups.div_ceil(gy), gy]
}

impl GpuContext {
    /// [`grid_2d`] within this adapter's per-dimension limit.
    #[must_use]
    pub fn grid_2d(&self, groups: u32) -> [u32; 2] {
        grid_2d(groups, self.limits.max_compute_workgroups_per_dimension)
    }
}

/// Loads a WGSL module from `shaders/`, concatenating the given files in order (our shaders
/// share functions by concatenation: WGSL has no includes). The sources are embedded at build
/// time so the binary runs from any directory.
#[must_use]
pub fn shader_source(parts: &[&str]) -> String {
    parts.join("\n")
}

/// GPU time of compute passes from timestamp queries, where the adapter has them.
///
/// Each measured pass writes a begin and an end timestamp; [`PassTimer::read_ms`] resolves
/// them after the work has been submitted and returns one duration per pass in milliseconds.
pub struct PassTimer {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    passes: u32,
    period_ns: f64,
}

impl PassTimer {
    /// `None` when the adapter has no timestamp queries (callers then time on the CPU).
    #[must_use]
    pub fn new(ctx: &GpuContext, passes: u32) -> Option<Self> {
        if !ctx.timestamps || passes == 0 {
            return None;
        }
        let count = passes * 2;
        let set = ctx.device.create_query_set(&wgpu::QuerySetDescriptor {
            label: Some("raygun pass timer"),
            ty: wgpu::QueryType::Timestamp,
            count,
        });
        let resolve = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("raygun pass timer resolve"),
            size: u64::from(count) * 8,
            usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        Some(Self {
            set,
            resolve,
            passes,
            period_ns: f64::from(ctx.queue.get_timestamp_period()),
        })
    }

    /// The timestamp writes for pass number `pass`.
    #[must_use]
    pub fn writes(&self, pass: u32) -> wgpu::ComputePassTimestampWrites<'_> {
        assert!(pass < self.passes, "pass {pass} out of {}", self.passes);
        wgpu::ComputePassTimestampWrites {
            query_set: &self.set,
            beginning_of_pass_write_index: Some(2 * pass),
            end_of_pass_write_index: Some(2 * pass + 1),
        }
    }

    /// The timestamp writes of one part of pass number `pass`, a stage recorded as several
    /// compute passes (one per band of rows): the first part writes the begin stamp, the last
    /// the end stamp, so the pass's time spans them all; the parts between write none.
    #[must_use]
    pub fn writes_part(
        &self,
        pass: u32,
        first: bool,
        last: bool,
    ) -> Option<wgpu::ComputePassTimestampWrites<'_>> {
        let w = self.writes(pass);
        (first || last).then(|| wgpu::ComputePassTimestampWrites {
            beginning_of_pass_write_index: w.beginning_of_pass_write_index.filter(|_| first),
            end_of_pass_write_index: w.end_of_pass_write_index.filter(|_| last),
            ..w
        })
    }

    /// Resolves the queries into the read-back buffer (record after the measured passes).
    pub fn resolve(&self, encoder: &mut wgpu::CommandEncoder) {
        encoder.resolve_query_set(&self.set, 0..self.passes * 2, &self.resolve, 0);
    }

    /// Reads the pass durations (ms) after the encoder with [`Self::resolve`] was submitted.
    pub fn read_ms(&self, ctx: &GpuContext) -> Result<Vec<f64>, GpuError> {
        let ticks: Vec<u64> = ctx.read_buffer(&self.resolve)?;
        Ok(ticks
            .chunks_exact(2)
            .map(|p| p[1].wrapping_sub(p[0]) as f64 * self.period_ns * 1e-6)
            .collect())
    }
}

#[cfg(test)]
mod tests;
