//! Which walks the sixteen-ray walks take ([`CpuPackets`]): packets in AVX-512 or AVX2 lanes,
//! or one ray at a time, chosen once a process.

use glam::Vec3;

#[cfg(target_arch = "x86_64")]
use super::hybrid;
use super::{CpuPackets, CpuTree, INLINE_STACK, TraceHit};

/// How the sixteen-ray walks ([`CpuTree::closest_hits16`], [`CpuTree::occluded16`]) walk, once
/// a process: `RAYGUN_CPU_PACKETS` ([`CpuPackets::from_env`]; `raygun` refuses a bad value at
/// start), else the widest this processor runs.
static PACKETS: std::sync::LazyLock<CpuPackets> =
    std::sync::LazyLock::new(|| CpuPackets::from_env().unwrap_or_else(|_| CpuPackets::widest()));

#[cfg(test)]
thread_local! {
    /// This thread's walks in a test ([`CpuPackets::during`]).
    static CHOSEN: std::cell::Cell<Option<CpuPackets>> = const { std::cell::Cell::new(None) };
}

/// Why a `RAYGUN_CPU_PACKETS` value names no walks this processor and build run.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum CpuPacketsError {
    #[error(
        "expected 0 (one ray at a time), avx2 or avx512 (packets of sixteen rays in those lanes)"
    )]
    Unknown,
    #[error("packets of sixteen rays are walked in x86-64 lanes; this build is for {arch}: use 0")]
    NotX86_64 { arch: &'static str },
    #[error("AVX2 packets need a build for AVX2 and FMA (.cargo/config.toml)")]
    NoAvx2Build,
    #[error("AVX-512 packets need a processor with AVX-512 F and DQ")]
    NoAvx512Processor,
}

/// Why `RAYGUN_CPU_PACKETS` names no walks: the variable and its value, and why.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
pub enum CpuPacketsEnvError {
    #[error("RAYGUN_CPU_PACKETS={value:?}: {why}")]
    Value { value: String, why: CpuPacketsError },
    #[error("RAYGUN_CPU_PACKETS={value:?}: not UTF-8")]
    NotUnicode { value: std::ffi::OsString },
}

impl CpuPackets {
    /// The fastest walks this processor and build run: packets in AVX-512 where the processor
    /// has AVX-512 F and DQ, else in AVX2 where the build targets AVX2 and FMA (every x86-64
    /// build by default), else one ray at a time.
    #[must_use]
    pub fn widest() -> Self {
        #[cfg(target_arch = "x86_64")]
        if hybrid::available() {
            return Self::Avx512;
        }
        if cfg!(all(target_feature = "avx2", target_feature = "fma")) {
            Self::Avx2
        } else {
            Self::One
        }
    }

    /// The walks `value` names: `0` one ray at a time, `avx2` or `avx512` packets in those
    /// lanes; an error says why where this processor or build cannot.
    pub fn parse(value: &str) -> Result<Self, CpuPacketsError> {
        let want = match value.trim() {
            "0" => return Ok(Self::One),
            "avx2" => Self::Avx2,
            "avx512" => Self::Avx512,
            _ => return Err(CpuPacketsError::Unknown),
        };
        match (want, Self::widest()) {
            _ if !cfg!(target_arch = "x86_64") => Err(CpuPacketsError::NotX86_64 {
                arch: std::env::consts::ARCH,
            }),
            (Self::Avx2, Self::One) => Err(CpuPacketsError::NoAvx2Build),
            (Self::Avx512, Self::One | Self::Avx2) => Err(CpuPacketsError::NoAvx512Processor),
            _ => Ok(want),
        }
    }

    /// `RAYGUN_CPU_PACKETS` ([`Self::parse`]; unset: [`Self::widest`]), the error naming the
    /// variable and its value.
    pub fn from_env() -> Result<Self, CpuPacketsEnvError> {
        match std::env::var("RAYGUN_CPU_PACKETS") {
            Ok(v) => Self::parse(&v).map_err(|why| CpuPacketsEnvError::Value { value: v, why }),
            Err(std::env::VarError::NotPresent) => Ok(Self::widest()),
            Err(std::env::VarError::NotUnicode(value)) => {
                Err(CpuPacketsEnvError::NotUnicode { value })
            }
        }
    }

    /// The walks this process takes (in tests, this thread's: `CpuPackets::during`).
    #[must_use]
    pub fn current() -> Self {
        #[cfg(test)]
        if let Some(walks) = CHOSEN.get() {
            return walks;
        }
        *PACKETS
    }

    /// `f` with this thread's walks `self` instead of the process's, for tests of every width
    /// on one processor; panics where the processor cannot run `self`.
    #[cfg(test)]
    pub(crate) fn during<R>(self, f: impl FnOnce() -> R) -> R {
        assert!(
            self <= Self::widest(),
            "{self:?} on a processor that runs up to {:?}",
            Self::widest()
        );
        let before = CHOSEN.replace(Some(self));
        let out = f();
        CHOSEN.set(before);
        out
    }

    /// In words, for a report's hardware line.
    #[must_use]
    pub fn describe(self) -> &'static str {
        match self {
            Self::One => "rays one at a time",
            Self::Avx2 => "rays in packets of 16 (AVX2)",
            Self::Avx512 => "rays in packets of 16 (AVX-512)",
        }
    }
}

impl CpuTree {
    /// Which packets the sixteen-ray walks use: [`CpuPackets::current`] for a tree with nodes,
    /// no alpha-tested primitives and a stack within [`INLINE_STACK`], else none.
    pub(in crate::trace::bvh) fn packet_walks(&self) -> CpuPackets {
        if self.nodes.is_empty() || self.lanes.alpha || self.stack_size > INLINE_STACK {
            CpuPackets::One
        } else {
            CpuPackets::current()
        }
    }

    /// Whether the sixteen-ray walks use packets ([`Self::packet_walks`]).
    pub(in crate::trace::bvh) fn packets(&self) -> bool {
        self.packet_walks() != CpuPackets::One
    }

    /// The closest hits of sixteen rays (`0 < t < ∞`) for the lanes set in `active` (the
    /// others get `None`): `closest_hit`'s hits to the bit. Walked as [`Self::packet_walks`]
    /// says: a hybrid packet (`hybrid.rs`: together while more than [`hybrid::SWITCH`] rays
    /// enter a node, then one at a time) in AVX-512 or AVX2 lanes, or one ray at a time.
    pub(in crate::trace::bvh) fn closest_hits16(
        &self,
        origins: &[Vec3; 16],
        dirs: &[Vec3; 16],
        active: u16,
    ) -> [Option<TraceHit>; 16] {
        match self.packet_walks() {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `packet_walks` takes AVX-512 only where the processor has AVX-512 F and
            // DQ ([`CpuPackets::widest`]), and packets only for a tree with no alpha-tested
            // primitives and a stack bound within `INLINE_STACK`.
            CpuPackets::Avx512 => unsafe { self.hybrid16(origins, dirs, active, hybrid::SWITCH) },
            #[cfg(all(
                target_arch = "x86_64",
                target_feature = "avx2",
                target_feature = "fma"
            ))]
            CpuPackets::Avx2 => self.hybrid16_avx2(origins, dirs, active, hybrid::SWITCH),
            _ => self.closest_hits16_alone(origins, dirs, active),
        }
    }

    /// [`Self::closest_hits16`] one ray at a time (without packets).
    pub(super) fn closest_hits16_alone(
        &self,
        origins: &[Vec3; 16],
        dirs: &[Vec3; 16],
        active: u16,
    ) -> [Option<TraceHit>; 16] {
        std::array::from_fn(|i| {
            if active & (1 << i) == 0 {
                return None;
            }
            self.closest_hit_filtered(origins[i], dirs[i], f32::INFINITY, |_, _, _| true)
        })
    }

    /// Whether something blocks each of sixteen shadow rays `origins[i] + t·dirs[i]`, `0 < t <
    /// tmax[i]`, for the lanes set in `active`: a bit set per blocked ray, `occluded`'s
    /// answers. Walked as a hybrid packet where [`Self::packets`] says so, elsewhere one ray at
    /// a time.
    pub(in crate::trace::bvh) fn occluded16(
        &self,
        origins: &[Vec3; 16],
        dirs: &[Vec3; 16],
        tmax: &[f32; 16],
        active: u16,
    ) -> u16 {
        match self.packet_walks() {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: as in `closest_hits16`.
            CpuPackets::Avx512 => unsafe {
                self.hybrid_occluded16(origins, dirs, tmax, active, hybrid::SWITCH)
            },
            #[cfg(all(
                target_arch = "x86_64",
                target_feature = "avx2",
                target_feature = "fma"
            ))]
            CpuPackets::Avx2 => {
                self.hybrid_occluded16_avx2(origins, dirs, tmax, active, hybrid::SWITCH)
            }
            _ => self.occluded16_alone(origins, dirs, tmax, active),
        }
    }

    /// [`Self::occluded16`] one ray at a time (without packets).
    pub(super) fn occluded16_alone(
        &self,
        origins: &[Vec3; 16],
        dirs: &[Vec3; 16],
        tmax: &[f32; 16],
        active: u16,
    ) -> u16 {
        (0..16)
            .filter(|&i| {
                active & (1 << i) != 0
                    && self.occluded_filtered(origins[i], dirs[i], tmax[i], |_, _, _| true)
            })
            .fold(0, |m, i| m | (1 << i))
    }
}
