//! Intel Open Image Denoise 2.x (`--denoise oidn`), the denoiser users know from Cycles, Arnold,
//! VRED and OSPRay, loaded at run time.
//!
//! raygun neither builds nor links OIDN: [`Oidn::load`] opens `libOpenImageDenoise.so.2` when a
//! picture is to be denoised with it, so a raygun without the library runs as before and
//! `--denoise oidn` says how to get it ([`OidnError::NotFound`]). `tools/oidn.sh install` puts
//! Intel's prebuilt 2.5.1 libraries (the core, its CPU and CUDA devices and TBB, carried by PyPI's
//! `pyoidn` wheel) where [`Oidn::load`] looks first.
//!
//! Where it looks ([`candidates`]): `$OIDN_DIR/lib` alone when `OIDN_DIR` is set (a user who
//! names an installation means that one); otherwise `$XDG_DATA_HOME/raygun/oidn/lib` (by default
//! `~/.local/share/raygun/oidn/lib`, where `tools/oidn.sh` installs), then the dynamic linker's
//! search path.
//!
//! The filter is OIDN's `RT` filter on HDR linear RGB with optional albedo and normal images of
//! the same size, each three `f32` a pixel, row by row from the top. OIDN takes per-pixel means
//! only: the caller fills pixels without a sample first.

use std::ffi::{CStr, CString, c_char, c_int, c_void};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::Vec3;
use libloading::Library;

use crate::trace::accum::Accumulation;

/// The library's file name (the 2.x ABI).
pub const LIBRARY: &str = "libOpenImageDenoise.so.2";

/// OIDN's quality setting for the `RT` filter.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Quality {
    /// For interactive previews (the viewer).
    Fast,
    /// Between the two.
    Balanced,
    /// For final frames (saved images).
    High,
}

impl Quality {
    fn raw(self) -> c_int {
        match self {
            Quality::Fast => 4,
            Quality::Balanced => 5,
            Quality::High => 6,
        }
    }
}

/// Which OIDN device to ask for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DeviceChoice {
    /// The CPU device.
    Cpu,
    /// The CUDA device on GPU 0; an error where the driver or GPU has no CUDA.
    Cuda,
    /// The CUDA device when the render's adapter is NVIDIA's and OIDN finds CUDA on it,
    /// otherwise the CPU device.
    Auto {
        /// Whether the render's adapter is an NVIDIA GPU.
        nvidia: bool,
    },
}

/// The device that ran, as OIDN reports it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DeviceKind {
    Cpu,
    Sycl,
    Cuda,
    Hip,
    Metal,
}

impl DeviceKind {
    fn from_raw(raw: c_int) -> Option<Self> {
        Some(match raw {
            1 => DeviceKind::Cpu,
            2 => DeviceKind::Sycl,
            3 => DeviceKind::Cuda,
            4 => DeviceKind::Hip,
            5 => DeviceKind::Metal,
            _ => return None,
        })
    }

    fn raw(self) -> c_int {
        match self {
            DeviceKind::Cpu => 1,
            DeviceKind::Sycl => 2,
            DeviceKind::Cuda => 3,
            DeviceKind::Hip => 4,
            DeviceKind::Metal => 5,
        }
    }

    /// The device's name as OIDN's own tools spell it.
    pub fn name(self) -> &'static str {
        match self {
            DeviceKind::Cpu => "CPU",
            DeviceKind::Sycl => "SYCL",
            DeviceKind::Cuda => "CUDA",
            DeviceKind::Hip => "HIP",
            DeviceKind::Metal => "Metal",
        }
    }
}

impl std::fmt::Display for DeviceKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// What went wrong loading or running OIDN.
#[derive(Debug, thiserror::Error)]
pub enum OidnError {
    /// No OIDN 2 library where raygun looks.
    #[error(
        "Intel Open Image Denoise 2 was not found ({tried}); install Intel's prebuilt 2.5 \
         libraries with `bash tools/oidn.sh install`, or set OIDN_DIR to an OIDN 2.x \
         installation"
    )]
    NotFound {
        /// Each place looked in, with what the dynamic loader said.
        tried: String,
    },
    /// The library was opened but is not OIDN 2.x.
    #[error("{path}: {message}")]
    NotOidn2 { path: PathBuf, message: String },
    /// An error OIDN reported.
    #[error("Open Image Denoise ({device}): {message}")]
    Device { device: String, message: String },
    /// An image whose length does not match the size.
    #[error(
        "Open Image Denoise: the {image} image holds {got} values, expected {expected} (RGB of {width} × {height} pixels)"
    )]
    ImageSize {
        image: &'static str,
        got: usize,
        expected: usize,
        width: u32,
        height: u32,
    },
}

type NewDevice = unsafe extern "C" fn(c_int) -> *mut c_void;
type DeviceFn = unsafe extern "C" fn(*mut c_void);
type GetDeviceInt = unsafe extern "C" fn(*mut c_void, *const c_char) -> c_int;
type GetError = unsafe extern "C" fn(*mut c_void, *mut *const c_char) -> c_int;
type IsCudaSupported = unsafe extern "C" fn(c_int) -> bool;
type NewBuffer = unsafe extern "C" fn(*mut c_void, usize) -> *mut c_void;
type BufferIo = unsafe extern "C" fn(*mut c_void, usize, usize, *mut c_void);
type BufferWrite = unsafe extern "C" fn(*mut c_void, usize, usize, *const c_void);
type NewFilter = unsafe extern "C" fn(*mut c_void, *const c_char) -> *mut c_void;
type SetFilterImage = unsafe extern "C" fn(
    *mut c_void,
    *const c_char,
    *mut c_void,
    c_int,
    usize,
    usize,
    usize,
    usize,
    usize,
);
type SetFilterBool = unsafe extern "C" fn(*mut c_void, *const c_char, bool);
type SetFilterInt = unsafe extern "C" fn(*mut c_void, *const c_char, c_int);

/// OIDN's C functions raygun calls, resolved once.
struct Api {
    new_device: NewDevice,
    commit_device: DeviceFn,
    release_device: DeviceFn,
    get_device_int: GetDeviceInt,
    get_device_error: GetError,
    is_cuda_supported: IsCudaSupported,
    new_buffer: NewBuffer,
    read_buffer: BufferIo,
    write_buffer: BufferWrite,
    release_buffer: DeviceFn,
    new_filter: NewFilter,
    set_filter_image: SetFilterImage,
    set_filter_bool: SetFilterBool,
    set_filter_int: SetFilterInt,
    commit_filter: DeviceFn,
    execute_filter: DeviceFn,
    release_filter: DeviceFn,
}

/// A loaded OIDN library.
pub struct Oidn {
    api: Api,
    path: PathBuf,
    // Last: the functions above point into it.
    _library: Library,
}

impl std::fmt::Debug for Oidn {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Oidn").field("path", &self.path).finish()
    }
}

/// Where [`Oidn::load`] looks, in order: a path with a folder is opened as it is, a bare file
/// name through the dynamic linker's search.
pub fn candidates() -> Vec<PathBuf> {
    candidates_from(
        std::env::var_os("OIDN_DIR").map(PathBuf::from),
        std::env::var_os("XDG_DATA_HOME").map(PathBuf::from),
        std::env::var_os("HOME").map(PathBuf::from),
    )
}

fn candidates_from(
    oidn_dir: Option<PathBuf>,
    data_home: Option<PathBuf>,
    home: Option<PathBuf>,
) -> Vec<PathBuf> {
    if let Some(dir) = oidn_dir {
        return vec![dir.join("lib").join(LIBRARY)];
    }
    let mut out = Vec::new();
    let data = data_home
        .filter(|d| d.is_absolute())
        .or_else(|| home.map(|h| h.join(".local/share")));
    if let Some(data) = data {
        out.push(data.join("raygun/oidn/lib").join(LIBRARY));
    }
    out.push(PathBuf::from(LIBRARY));
    out
}

impl Oidn {
    /// Opens the first OIDN 2 library of [`candidates`].
    pub fn load() -> Result<Arc<Oidn>, OidnError> {
        Self::load_first(&candidates())
    }

    /// Opens the first of `paths` that the dynamic loader opens.
    pub fn load_first(paths: &[PathBuf]) -> Result<Arc<Oidn>, OidnError> {
        let mut tried = Vec::new();
        for path in paths {
            // A path with a folder that does not exist is not worth the loader's message.
            if path.parent().is_some_and(|p| !p.as_os_str().is_empty()) && !path.exists() {
                tried.push(format!("{}: no such file", path.display()));
                continue;
            }
            // SAFETY: loading a library runs its initialisers; OIDN's are its own static set-up.
            match unsafe { Library::new(path) } {
                Ok(library) => return Self::from_library(library, path.clone()).map(Arc::new),
                Err(e) => tried.push(format!("{}: {e}", path.display())),
            }
        }
        Err(OidnError::NotFound {
            tried: tried.join("; "),
        })
    }

    fn from_library(library: Library, path: PathBuf) -> Result<Oidn, OidnError> {
        fn symbol<T: Copy>(library: &Library, path: &Path, name: &str) -> Result<T, OidnError> {
            // SAFETY: each type above is the C declaration of the symbol it is looked up for
            // (OpenImageDenoise/oidn.h, 2.x), and the pointer is used only while `library`
            // lives (the `Oidn` holds both).
            unsafe {
                library
                    .get::<T>(name.as_bytes())
                    .map(|s| *s)
                    .map_err(|e| OidnError::NotOidn2 {
                        path: path.to_owned(),
                        message: format!("not Open Image Denoise 2.x: {e}"),
                    })
            }
        }
        let l = &library;
        let p = path.as_path();
        let api = Api {
            new_device: symbol(l, p, "oidnNewDevice")?,
            commit_device: symbol(l, p, "oidnCommitDevice")?,
            release_device: symbol(l, p, "oidnReleaseDevice")?,
            get_device_int: symbol(l, p, "oidnGetDeviceInt")?,
            get_device_error: symbol(l, p, "oidnGetDeviceError")?,
            is_cuda_supported: symbol(l, p, "oidnIsCUDADeviceSupported")?,
            new_buffer: symbol(l, p, "oidnNewBuffer")?,
            read_buffer: symbol(l, p, "oidnReadBuffer")?,
            write_buffer: symbol(l, p, "oidnWriteBuffer")?,
            release_buffer: symbol(l, p, "oidnReleaseBuffer")?,
            new_filter: symbol(l, p, "oidnNewFilter")?,
            set_filter_image: symbol(l, p, "oidnSetFilterImage")?,
            set_filter_bool: symbol(l, p, "oidnSetFilterBool")?,
            set_filter_int: symbol(l, p, "oidnSetFilterInt")?,
            commit_filter: symbol(l, p, "oidnCommitFilter")?,
            execute_filter: symbol(l, p, "oidnExecuteFilter")?,
            release_filter: symbol(l, p, "oidnReleaseFilter")?,
        };
        Ok(Oidn {
            api,
            path,
            _library: library,
        })
    }

    /// The library file that was opened.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// A committed device of the kind `choice` asks for.
    pub fn device(self: &Arc<Self>, choice: DeviceChoice) -> Result<Device, OidnError> {
        let kind = match choice {
            DeviceChoice::Cpu => DeviceKind::Cpu,
            DeviceChoice::Cuda => DeviceKind::Cuda,
            // SAFETY: a query without arguments beyond the device index.
            DeviceChoice::Auto { nvidia } => {
                if nvidia && unsafe { (self.api.is_cuda_supported)(0) } {
                    DeviceKind::Cuda
                } else {
                    DeviceKind::Cpu
                }
            }
        };
        // SAFETY: the device type is one of OIDN's enumerators; a null device is checked.
        let raw = unsafe { (self.api.new_device)(kind.raw()) };
        if raw.is_null() {
            return Err(self
                .error(std::ptr::null_mut(), kind.name())
                .unwrap_or_else(|| OidnError::Device {
                    device: kind.name().to_owned(),
                    message: "no such device".to_owned(),
                }));
        }
        let mut device = Device {
            oidn: Arc::clone(self),
            raw,
            kind,
            version: 0,
        };
        // SAFETY: `raw` is a live device.
        unsafe { (self.api.commit_device)(raw) };
        device.check()?;
        let version = device.int(c"version");
        device.version = version;
        if version < 20000 {
            return Err(OidnError::NotOidn2 {
                path: self.path.clone(),
                message: format!("Open Image Denoise version {version}, raygun needs 2.x"),
            });
        }
        device.kind = DeviceKind::from_raw(device.int(c"type")).unwrap_or(kind);
        Ok(device)
    }

    /// The error OIDN holds for `device` (null: the calling thread's error without a device).
    fn error(&self, device: *mut c_void, name: &str) -> Option<OidnError> {
        let mut message: *const c_char = std::ptr::null();
        // SAFETY: `device` is live or null, as the function allows; the message is a
        // NUL-terminated string valid until the next call on the device, copied at once.
        let code = unsafe { (self.api.get_device_error)(device, &mut message) };
        (code != 0).then(|| OidnError::Device {
            device: name.to_owned(),
            message: if message.is_null() {
                format!("error {code}")
            } else {
                unsafe { CStr::from_ptr(message) }
                    .to_string_lossy()
                    .into_owned()
            },
        })
    }
}

/// An OIDN device, committed and ready to filter.
#[derive(Debug)]
pub struct Device {
    oidn: Arc<Oidn>,
    raw: *mut c_void,
    kind: DeviceKind,
    /// OIDN's version as it reports it: 10000 · major + 100 · minor + patch.
    version: c_int,
}

// SAFETY: OIDN's API is thread-safe; calls on one device are serialised by the library.
unsafe impl Send for Device {}

/// Pictures for OIDN's `RT` filter: RGB, three `f32` a pixel, row by row from the top.
#[derive(Debug, Clone, Copy)]
pub struct Images<'a> {
    /// Width and height in pixels.
    pub size: [u32; 2],
    /// The per-pixel mean radiance (HDR, linear).
    pub color: &'a [f32],
    /// The first non-specular hit's albedo, in [0, 1].
    pub albedo: Option<&'a [f32]>,
    /// The first non-specular hit's shading normal, in [-1, 1]; only with an albedo.
    pub normal: Option<&'a [f32]>,
}

impl Device {
    /// The device that runs the filter.
    pub fn kind(&self) -> DeviceKind {
        self.kind
    }

    /// What runs the filter, for messages: "Intel Open Image Denoise 2.5.1 on its CPU device".
    pub fn describe(&self) -> String {
        let v = self.version;
        format!(
            "Intel Open Image Denoise {}.{}.{} on its {} device",
            v / 10000,
            v / 100 % 100,
            v % 100,
            self.kind
        )
    }

    fn int(&self, name: &CStr) -> c_int {
        // SAFETY: a live device and a NUL-terminated parameter name.
        unsafe { (self.oidn.api.get_device_int)(self.raw, name.as_ptr()) }
    }

    fn check(&self) -> Result<(), OidnError> {
        match self.oidn.error(self.raw, self.kind.name()) {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }

    /// The `RT` filter on `images` at `quality`: the denoised RGB, three `f32` a pixel.
    pub fn denoise(&self, images: Images, quality: Quality) -> Result<Vec<f32>, OidnError> {
        let [w, h] = images.size;
        let expected = w as usize * h as usize * 3;
        let named = [
            ("color", Some(images.color)),
            ("albedo", images.albedo),
            ("normal", images.normal.filter(|_| images.albedo.is_some())),
        ];
        for (image, data) in named {
            if let Some(data) = data
                && data.len() != expected
            {
                return Err(OidnError::ImageSize {
                    image,
                    got: data.len(),
                    expected,
                    width: w,
                    height: h,
                });
            }
        }
        if expected == 0 {
            return Ok(Vec::new());
        }
        let api = &self.oidn.api;
        let bytes = expected * 4;
        let mut buffers = Vec::new();
        // SAFETY (this block): every handle passed is live (created above on this device and
        // released by the guards after use); buffer sizes are `bytes`, and every read and
        // write moves exactly `bytes` from or into a slice of `expected` f32.
        let filter = unsafe {
            let filter = Guard {
                raw: (api.new_filter)(self.raw, c"RT".as_ptr()),
                release: api.release_filter,
            };
            self.check()?;
            for (name, data) in named.iter().filter_map(|(n, d)| d.map(|d| (n, d))) {
                let buffer = Guard {
                    raw: (api.new_buffer)(self.raw, bytes),
                    release: api.release_buffer,
                };
                self.check()?;
                (api.write_buffer)(buffer.raw, 0, bytes, data.as_ptr().cast());
                let name = CString::new(*name).expect("no NUL in an image name");
                (api.set_filter_image)(
                    filter.raw,
                    name.as_ptr(),
                    buffer.raw,
                    3,
                    w as usize,
                    h as usize,
                    0,
                    12,
                    w as usize * 12,
                );
                buffers.push(buffer);
            }
            let output = Guard {
                raw: (api.new_buffer)(self.raw, bytes),
                release: api.release_buffer,
            };
            self.check()?;
            (api.set_filter_image)(
                filter.raw,
                c"output".as_ptr(),
                output.raw,
                3,
                w as usize,
                h as usize,
                0,
                12,
                w as usize * 12,
            );
            (api.set_filter_bool)(filter.raw, c"hdr".as_ptr(), true);
            (api.set_filter_int)(filter.raw, c"quality".as_ptr(), quality.raw());
            (api.commit_filter)(filter.raw);
            self.check()?;
            (api.execute_filter)(filter.raw);
            self.check()?;
            buffers.push(output);
            filter
        };
        let mut out = vec![0f32; expected];
        let output = buffers.last().expect("the output buffer");
        // SAFETY: as above; the execution finished (oidnExecuteFilter is synchronous).
        unsafe { (api.read_buffer)(output.raw, 0, bytes, out.as_mut_ptr().cast()) };
        self.check()?;
        drop(filter);
        Ok(out)
    }
}

/// OIDN's colour input from a render: each sampled pixel's own mean, and for a pixel without a
/// usable mean (no sample yet, or a non-finite sum) the `filled` picture's value — today's
/// filter, which fills it from its sampled neighbours. OIDN takes per-pixel means only; the
/// sparse pixels' noise is what it removes, so the filter's blur is not passed on. Returns the
/// RGB values and how many pixels were filled.
pub fn colour_input(acc: &Accumulation, filled: &[Vec3]) -> (Vec<f32>, usize) {
    assert_eq!(acc.count.len(), filled.len(), "one filled value a pixel");
    let mut out = Vec::with_capacity(filled.len() * 3);
    let mut fills = 0;
    for ((sum, &n), f) in acc.sum.iter().zip(&acc.count).zip(filled) {
        let mean = Vec3::new(sum[0], sum[1], sum[2]) / n as f32;
        let v = if n > 0 && mean.is_finite() {
            mean
        } else {
            fills += 1;
            if f.is_finite() { *f } else { Vec3::ZERO }
        };
        out.extend_from_slice(&v.to_array());
    }
    (out, fills)
}

/// OIDN's albedo and normal images from the denoiser's features: three floats a pixel each.
#[must_use]
pub fn auxiliary(features: &super::denoise::Features) -> (Vec<f32>, Vec<f32>) {
    let rgb = |v: &[[f32; 4]]| v.iter().flat_map(|a| [a[0], a[1], a[2]]).collect();
    (rgb(&features.albedo), rgb(&features.normal_depth))
}

/// A render's picture denoised by OIDN: `filled` is the filter's picture (DESIGN.md §8), whose
/// values OIDN sees only where a pixel has no usable mean of its own ([`colour_input`]); with
/// `features`, their albedo and shading normal guide it (OIDN keeps the edges and textures they
/// show). The result is linear RGB like `filled`.
pub fn denoise_picture(
    device: &Device,
    acc: &Accumulation,
    filled: &[Vec3],
    features: Option<&super::denoise::Features>,
    quality: Quality,
) -> Result<Vec<Vec3>, OidnError> {
    let (color, _) = colour_input(acc, filled);
    let (albedo, normal) = features.map(auxiliary).unzip();
    let out = device.denoise(
        Images {
            size: [acc.width, acc.height],
            color: &color,
            albedo: albedo.as_deref(),
            normal: normal.as_deref(),
        },
        quality,
    )?;
    Ok(out.chunks_exact(3).map(Vec3::from_slice).collect())
}

impl Drop for Device {
    fn drop(&mut self) {
        // SAFETY: the device is live and released once; its filters and buffers are gone.
        unsafe { (self.oidn.api.release_device)(self.raw) };
    }
}

/// Releases an OIDN object when dropped.
struct Guard {
    raw: *mut c_void,
    release: DeviceFn,
}

impl Drop for Guard {
    fn drop(&mut self) {
        if !self.raw.is_null() {
            // SAFETY: a live object of the kind `release` releases, released once.
            unsafe { (self.release)(self.raw) };
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn oidn_dir_alone_is_searched_when_it_is_set() {
        let c = candidates_from(
            Some("/opt/oidn".into()),
            Some("/data".into()),
            Some("/home/u".into()),
        );
        assert_eq!(c, vec![PathBuf::from("/opt/oidn/lib").join(LIBRARY)]);
    }

    #[test]
    fn without_oidn_dir_the_install_folder_then_the_linker() {
        let c = candidates_from(None, None, Some("/home/u".into()));
        assert_eq!(
            c,
            vec![
                PathBuf::from("/home/u/.local/share/raygun/oidn/lib").join(LIBRARY),
                PathBuf::from(LIBRARY)
            ]
        );
        // A relative XDG_DATA_HOME is ignored, as the XDG specification says.
        let c = candidates_from(None, Some("rel".into()), Some("/home/u".into()));
        assert_eq!(
            c[0],
            PathBuf::from("/home/u/.local/share/raygun/oidn/lib").join(LIBRARY)
        );
        let c = candidates_from(None, Some("/d".into()), None);
        assert_eq!(c[0], PathBuf::from("/d/raygun/oidn/lib").join(LIBRARY));
    }

    #[test]
    fn a_missing_library_says_how_to_get_it() {
        let dir = std::env::temp_dir().join(format!("raygun-no-oidn-{}", std::process::id()));
        let e = Oidn::load_first(&[dir.join("lib").join(LIBRARY)]).unwrap_err();
        let text = e.to_string();
        assert!(matches!(e, OidnError::NotFound { .. }), "{text}");
        assert!(text.contains("tools/oidn.sh install"), "{text}");
        assert!(text.contains("OIDN_DIR"), "{text}");
        assert!(text.contains(&dir.display().to_string()), "{text}");
    }

    #[test]
    fn a_library_that_is_not_oidn_is_refused_by_name() {
        // libm is on every Linux system and has none of OIDN's functions.
        let e = Oidn::load_first(&[PathBuf::from("libm.so.6")]).unwrap_err();
        assert!(matches!(e, OidnError::NotOidn2 { .. }), "{e}");
        assert!(e.to_string().contains("oidnNewDevice"), "{e}");
    }

    #[test]
    fn the_colour_input_is_each_mean_or_the_filled_value() {
        let acc = Accumulation {
            width: 4,
            height: 1,
            sum: vec![
                [2.0, 4.0, 6.0, 0.0],
                [0.0; 4],
                [f32::NAN, 0.0, 0.0, 0.0],
                [f32::INFINITY, 1.0, 1.0, 0.0],
            ],
            count: vec![2, 0, 3, 1],
        };
        let filled = [
            Vec3::splat(9.0),
            Vec3::splat(0.5),
            Vec3::splat(0.25),
            Vec3::splat(f32::NAN),
        ];
        let (rgb, fills) = colour_input(&acc, &filled);
        assert_eq!(
            rgb,
            [
                1.0, 2.0, 3.0, 0.5, 0.5, 0.5, 0.25, 0.25, 0.25, 0.0, 0.0, 0.0
            ]
        );
        assert_eq!(fills, 3);
    }

    /// The installed library (`tools/oidn.sh install`): these tests fail, never skip, without it.
    fn installed() -> Arc<Oidn> {
        Oidn::load().unwrap_or_else(|e| panic!("{e}"))
    }

    /// A noisy picture: a lit gradient with a dark square, each pixel's mean disturbed.
    /// The noise-free picture: a lit gradient with a dark square, RGB.
    fn clean(w: u32, h: u32) -> Vec<f32> {
        let mut out = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let inside = (w / 4..3 * w / 4).contains(&x) && (h / 4..3 * h / 4).contains(&y);
                let base = if inside {
                    0.05
                } else {
                    0.2 + 0.6 * x as f32 / w as f32
                };
                out.extend_from_slice(&[base; 3]);
            }
        }
        out
    }

    /// [`clean`] with each value disturbed by a factor in [0.25, 1.75).
    fn noisy(w: u32, h: u32) -> Vec<f32> {
        use crate::random::{pcg4d, unit_f32};
        let mut out = clean(w, h);
        for (i, v) in out.iter_mut().enumerate() {
            let (p, c) = (i as u32 / 3, i as u32 % 3);
            let u = unit_f32(pcg4d([p % w, p / w, c, 7])[0]);
            *v *= 0.25 + 1.5 * u;
        }
        out
    }

    #[test]
    fn a_flat_picture_stays_flat() {
        let device = installed().device(DeviceChoice::Cpu).unwrap();
        assert_eq!(device.kind(), DeviceKind::Cpu);
        assert_eq!(
            device.describe(),
            "Intel Open Image Denoise 2.5.1 on its CPU device"
        );
        let (w, h) = (48, 32);
        let color = vec![0.5f32; (w * h * 3) as usize];
        let out = device
            .denoise(
                Images {
                    size: [w, h],
                    color: &color,
                    albedo: None,
                    normal: None,
                },
                Quality::High,
            )
            .unwrap();
        let mean = out.iter().map(|&v| v as f64).sum::<f64>() / out.len() as f64;
        assert!((mean - 0.5).abs() < 0.005, "mean {mean}");
        assert!(out.iter().all(|v| (v - 0.5).abs() < 0.05), "{out:?}");
    }

    #[test]
    fn a_noisy_picture_comes_closer_to_its_mean() {
        let device = installed()
            .device(DeviceChoice::Auto { nvidia: false })
            .unwrap();
        let (w, h) = (64, 48);
        let color = noisy(w, h);
        let clean = clean(w, h);
        let images = Images {
            size: [w, h],
            color: &color,
            albedo: None,
            normal: None,
        };
        let out = device.denoise(images, Quality::Fast).unwrap();
        let mse = |a: &[f32]| {
            a.iter()
                .zip(&clean)
                .map(|(a, b)| ((a - b) as f64).powi(2))
                .sum::<f64>()
                / a.len() as f64
        };
        assert!(
            mse(&out) < 0.25 * mse(&color),
            "{} vs {}",
            mse(&out),
            mse(&color)
        );
    }

    #[test]
    fn images_of_the_wrong_size_are_refused() {
        let device = installed().device(DeviceChoice::Cpu).unwrap();
        let color = vec![0.5f32; 10];
        let e = device
            .denoise(
                Images {
                    size: [2, 2],
                    color: &color,
                    albedo: None,
                    normal: None,
                },
                Quality::Fast,
            )
            .unwrap_err();
        assert_eq!(
            e.to_string(),
            "Open Image Denoise: the color image holds 10 values, expected 12 (RGB of 2 × 2 pixels)"
        );
    }

    fn write_pfm(path: &Path, [w, h]: [u32; 2], rgb: &[f32]) {
        let mut bytes = format!("PF\n{w} {h}\n-1.0\n").into_bytes();
        // PFM rows run from the bottom.
        for y in (0..h as usize).rev() {
            for v in &rgb[y * w as usize * 3..(y + 1) * w as usize * 3] {
                bytes.extend_from_slice(&v.to_le_bytes());
            }
        }
        std::fs::write(path, bytes).unwrap();
    }

    fn read_pfm(path: &Path, [w, h]: [u32; 2]) -> Vec<f32> {
        let bytes = std::fs::read(path).unwrap();
        let header = format!("PF\n{w} {h}\n-1.0\n");
        assert!(bytes.starts_with(header.as_bytes()), "{}", path.display());
        let data: Vec<f32> = bytes[header.len()..]
            .chunks_exact(4)
            .map(|b| f32::from_le_bytes(b.try_into().unwrap()))
            .collect();
        let row = w as usize * 3;
        (0..h as usize)
            .rev()
            .flat_map(|y| data[y * row..(y + 1) * row].to_vec())
            .collect()
    }

    #[test]
    fn raygun_denoises_as_intels_own_command_does() {
        let oidn = installed();
        // `oidnDenoise` beside the library, as Intel's release and tools/oidn.sh lay them out.
        let tool = oidn.path().parent().unwrap().join("../bin/oidnDenoise");
        assert!(tool.exists(), "{} is missing", tool.display());
        let dir = std::env::temp_dir().join(format!("raygun-oidn-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let size = [40, 30];
        let color = noisy(size[0], size[1]);
        // Albedo and normal as the tracer writes them: a flat grey, two facing directions.
        let albedo: Vec<f32> = (0..color.len())
            .map(|i| if i % 3 == 0 { 0.8 } else { 0.5 })
            .collect();
        let normal: Vec<f32> = (0..color.len() / 3)
            .flat_map(|p| {
                if p % size[0] as usize > 20 {
                    [0.0, 0.0, 1.0]
                } else {
                    [1.0, 0.0, 0.0]
                }
            })
            .collect();
        for (name, data) in [("color", &color), ("albedo", &albedo), ("normal", &normal)] {
            write_pfm(&dir.join(format!("{name}.pfm")), size, data);
        }
        let run = std::process::Command::new(&tool)
            .args(["-d", "cpu", "-q", "high", "-v", "0"])
            .arg("--hdr")
            .arg(dir.join("color.pfm"))
            .arg("--alb")
            .arg(dir.join("albedo.pfm"))
            .arg("--nrm")
            .arg(dir.join("normal.pfm"))
            .arg("-o")
            .arg(dir.join("out.pfm"))
            .output()
            .unwrap();
        assert!(
            run.status.success(),
            "{} failed: {}",
            tool.display(),
            String::from_utf8_lossy(&run.stderr)
        );
        let theirs = read_pfm(&dir.join("out.pfm"), size);
        let ours = oidn
            .device(DeviceChoice::Cpu)
            .unwrap()
            .denoise(
                Images {
                    size,
                    color: &color,
                    albedo: Some(&albedo),
                    normal: Some(&normal),
                },
                Quality::High,
            )
            .unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
        // The same library, device and inputs: the same picture. OIDN's CPU device is
        // deterministic for a given machine; a rounding's worth of room is left for its choice
        // of kernels by thread count.
        let worst = ours
            .iter()
            .zip(&theirs)
            .map(|(a, b)| (a - b).abs() / b.abs().max(1e-3))
            .fold(0f32, f32::max);
        assert!(worst < 1e-4, "largest relative difference {worst}");
    }
}
