//! `--head KIND:N [--eye-offset X,Y,Z] [--eye-threshold METRES] [--on-eye-move reuse|restart]`:
//! the tracked head that moves
//! the wall camera's eye ([`crate::tracking::head`], DESIGN.md §11), shared by `view`, `record`,
//! `replay` and `render --guide`.
//!
//! The head is named like the ray gun (`--device KIND:N`): a DTrack `6d` body is `body:N`, a
//! body of raygun's OSC address space `osc:N` (`/raygun/N/pose`), a VRPN tracker sensor the
//! device the VRPN mapping gives it (`vrpn_Tracker_DTrack`'s sensor 0 is `body:0`). It comes
//! through the same source (`--dtrack`, `--osc`, `--vrpn`, a replay) and the same calibration
//! as the ray gun.

use anyhow::Context;
use glam::DVec3;

use crate::frame::EyeMove;
use crate::tracking::event::DeviceId;
use crate::tracking::head::{DEFAULT_EYE_THRESHOLD_M, HeadConfig, HeadOverride};

/// The head's flags.
#[derive(Clone, Debug, Default, clap::Args)]
pub struct HeadArgs {
    /// The tracked head that moves `--camera wall`'s eye: a DTrack 6d body `body:N`, an OSC
    /// body `osc:N` (/raygun/N/pose) or a VRPN sensor's device (vrpn_Tracker_DTrack's sensor 0
    /// is body:0); through the same source and calibration as the ray gun. Default: the
    /// replay's header's head, if any.
    #[arg(long, value_name = "KIND:N")]
    pub head: Option<DeviceId>,
    /// The eye in the head body's own frame, metres (default 0,0,0: the body's origin).
    #[arg(long, value_name = "X,Y,Z", value_parser = crate::cli::args::parse_vec3, allow_hyphen_values = true)]
    pub eye_offset: Option<DVec3>,
    /// Restart the accumulation when the eye (or a viewer's pinhole camera) moves more than
    /// this many metres from where it started (default 0.01).
    #[arg(long, value_name = "METRES", allow_hyphen_values = true)]
    pub eye_threshold: Option<f64>,
    /// What a move past --eye-threshold does to the accumulation: `reuse` carries each
    /// pixel's samples over from the old pixel that saw the same surface (mirrors, glass,
    /// disoccluded surfaces and pixels newly in view start again; docs/wall-camera.md); `restart`
    /// starts every pixel again. Default: reuse (with --cluster: restart, the only one it has).
    #[arg(long, value_name = "reuse|restart")]
    pub on_eye_move: Option<EyeMove>,
}

impl HeadArgs {
    /// What the flags change of a replay header's head.
    #[must_use]
    pub fn overrides(&self) -> HeadOverride {
        HeadOverride {
            device: self.head,
            eye_offset_m: self.eye_offset.map(|v| v.to_array()),
            eye_threshold_m: self.eye_threshold,
        }
    }

    /// The head the flags name on their own (live input, recordings), checked.
    pub fn head(&self) -> anyhow::Result<Option<HeadConfig>> {
        self.check()?;
        if self.head.is_none() && self.eye_offset.is_some() {
            anyhow::bail!("--eye-offset places the eye on a tracked head: it needs --head KIND:N");
        }
        let head = self.overrides().apply(None);
        if let Some(h) = &head {
            h.validate().context("the tracked head")?;
        }
        Ok(head)
    }

    /// The restart threshold, metres.
    #[must_use]
    pub fn threshold_m(&self) -> f64 {
        self.eye_threshold.unwrap_or(DEFAULT_EYE_THRESHOLD_M)
    }

    /// What a move does (`--on-eye-move`; reuse unless asked otherwise).
    #[must_use]
    pub fn on_eye_move(&self) -> EyeMove {
        self.on_eye_move.unwrap_or(EyeMove::Reuse)
    }

    /// `--on-eye-move` for a render across ranks: restart (they carry nothing yet); reuse
    /// asked for is an error.
    pub fn cluster_on_eye_move(&self) -> anyhow::Result<EyeMove> {
        match self.on_eye_move {
            Some(EyeMove::Reuse) => anyhow::bail!(
                "--on-eye-move reuse: a render across ranks (--cluster) restarts the accumulation when the eye moves; leave --on-eye-move out or say restart"
            ),
            _ => Ok(EyeMove::Restart),
        }
    }

    /// Checks the numbers before any work.
    pub fn check(&self) -> anyhow::Result<()> {
        if let Some(t) = self.eye_threshold
            && !(t.is_finite() && t >= 0.0)
        {
            anyhow::bail!("--eye-threshold must be a finite number of metres, 0 or more, not {t}");
        }
        Ok(())
    }
}
