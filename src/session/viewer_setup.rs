//! The viewer's set-up (DESIGN.md §10): the display, the interaction mapping and its
//! calibration, a replay collected into a timeline, the wall camera and a live tracking source,
//! gathered step by step by [`ViewerSetupBuilder`] and joined with the scene into one
//! [`ViewerSetup`]. The command line drives the steps from its arguments; the viewer's own state
//! (its ROI source, sliders and cursor) is the front end's to make from the result.

use std::path::Path;

use glam::DVec3;

use crate::display::DisplayModel;
use crate::interaction::InteractionConfig;
use crate::interaction::config::ConfigError;
use crate::scene::Scene;
use crate::session::live::{LiveError, LiveTracking};
use crate::session::replay::{ReplayOptions, ReplayPlanError};
use crate::session::timeline::Timeline;
use crate::trace::path::TraceSettings;
use crate::trace::wall::{WallCamera, WallCameraError, WallSpec};
use crate::tracking::calibration::{Calibration, CalibrationError};
use crate::tracking::event::DeviceId;
use crate::tracking::head::HeadConfig;
use crate::tracking::ingest::Protocol;
use crate::tracking::vrpn::VrpnAddress;

/// Why a step of the viewer's set-up failed; each names its file or source.
#[derive(Debug, thiserror::Error)]
pub enum ViewerSetupError {
    #[error(transparent)]
    Interaction(#[from] ConfigError),
    #[error(transparent)]
    Calibration(#[from] CalibrationError),
    #[error(transparent)]
    Replay(#[from] ReplayPlanError),
    #[error(transparent)]
    WallCamera(#[from] WallCameraError),
    #[error(transparent)]
    Live(#[from] LiveError),
}

/// Where live tracking comes from.
#[derive(Clone, Debug)]
pub enum LiveInput {
    /// A VRPN server, loopback unless `allow_network`.
    Vrpn {
        address: VrpnAddress,
        allow_network: bool,
    },
    /// DTrack or OSC datagrams on a loopback port (0: any free one).
    Udp { port: u16, protocol: Protocol },
}

/// Everything the viewer shows and follows, loaded and started before its renderer exists.
pub struct ViewerSetup {
    pub scene: Scene,
    pub model: DisplayModel,
    /// The renderer's settings: the image size and the scene's camera.
    pub base: TraceSettings,
    pub wall: Option<WallCamera>,
    /// The interaction mapping, with a calibration's device axes in it.
    pub interaction: InteractionConfig,
    pub calibration: Option<Calibration>,
    pub timeline: Option<Timeline>,
    pub live: Option<LiveTracking>,
}

impl ViewerSetup {
    /// The set-up of an image of `size` pixels covering `model`'s canvas.
    #[must_use]
    pub fn builder(model: DisplayModel, size: [u32; 2]) -> ViewerSetupBuilder {
        ViewerSetupBuilder {
            model,
            size,
            interaction: InteractionConfig::default(),
            calibration: None,
            timeline: None,
            wall: None,
            live: None,
        }
    }
}

/// The steps of a [`ViewerSetup`], each checked where it is taken; the caller takes them in
/// the order its errors should come (the files before the scene loads, the sockets last).
pub struct ViewerSetupBuilder {
    model: DisplayModel,
    size: [u32; 2],
    interaction: InteractionConfig,
    calibration: Option<Calibration>,
    timeline: Option<Timeline>,
    wall: Option<WallCamera>,
    live: Option<LiveTracking>,
}

impl ViewerSetupBuilder {
    /// The interaction mapping of the `config` file (default: the built-in one) for `device`
    /// (default: the file's), and the tracker→room `calibration` (default: the one the file
    /// names) whose device axes it then uses.
    pub fn interaction(
        mut self,
        config: Option<&Path>,
        device: Option<DeviceId>,
        calibration: Option<&Path>,
    ) -> Result<Self, ViewerSetupError> {
        let mut interaction = match config {
            Some(p) => InteractionConfig::load(p)?,
            None => InteractionConfig::default(),
        };
        if let Some(d) = device {
            interaction.device = d;
        }
        let calibration = match calibration.or(interaction.calibration.as_deref()) {
            Some(p) => Some(Calibration::load(p)?),
            None => None,
        };
        if let Some(c) = &calibration {
            interaction.use_calibrated_axes(c);
            interaction.validate()?;
        }
        self.interaction = interaction;
        self.calibration = calibration;
        Ok(self)
    }

    /// A recorded session, collected into the viewer's timeline (none: no replay).
    pub fn replay(mut self, replay: Option<&ReplayOptions>) -> Result<Self, ViewerSetupError> {
        self.timeline = replay.map(Timeline::collect).transpose()?;
        Ok(self)
    }

    /// The display the image covers.
    #[must_use]
    pub fn model(&self) -> &DisplayModel {
        &self.model
    }

    /// The replay's tracked head's first eye: the wall camera's eye where none is given.
    #[must_use]
    pub fn first_eye(&self) -> Option<DVec3> {
        self.timeline
            .as_ref()
            .and_then(|t| t.eyes.first().map(|e| e.1))
    }

    /// The wall camera of `spec` (none: the scene's camera) for the image, `auto` placing
    /// `scene_camera` at the eye.
    pub fn wall(
        mut self,
        spec: Option<&WallSpec>,
        scene_camera: &crate::trace::camera::RenderCamera,
    ) -> Result<Self, ViewerSetupError> {
        self.wall = spec
            .map(|s| s.camera(self.size, scene_camera))
            .transpose()?;
        Ok(self)
    }

    /// Starts following `input` (none: no live tracking).
    pub fn live(mut self, input: Option<LiveInput>) -> Result<Self, ViewerSetupError> {
        let (interaction, model, calibration) = (
            self.interaction.clone(),
            self.model.clone(),
            self.calibration.as_ref(),
        );
        self.live = match input {
            Some(LiveInput::Vrpn {
                address,
                allow_network,
            }) => Some(LiveTracking::start_vrpn(
                address,
                allow_network,
                interaction,
                model,
                calibration,
            )?),
            Some(LiveInput::Udp { port, protocol }) => Some(LiveTracking::start_calibrated(
                port,
                protocol,
                interaction,
                model,
                calibration,
            )?),
            None => None,
        };
        Ok(self)
    }

    /// The wall camera's eye follows `head` on the live source; whether there is one to follow.
    pub fn follow_head(&self, head: HeadConfig) -> bool {
        match &self.live {
            Some(l) => {
                l.follow_head(head);
                true
            }
            None => false,
        }
    }

    /// The set-up, with the `scene` and the renderer's `base` settings.
    #[must_use]
    pub fn build(self, scene: Scene, base: TraceSettings) -> ViewerSetup {
        ViewerSetup {
            scene,
            model: self.model,
            base,
            wall: self.wall,
            interaction: self.interaction,
            calibration: self.calibration,
            timeline: self.timeline,
            live: self.live,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model() -> DisplayModel {
        DisplayModel::open(crate::display::DEFAULT_MODEL).unwrap().0
    }

    #[test]
    fn without_files_or_sources_the_setup_is_the_mouse_viewers() {
        let b = ViewerSetup::builder(model(), [64, 26])
            .interaction(None, None, None)
            .unwrap()
            .replay(None)
            .unwrap();
        assert_eq!(b.first_eye(), None);
        let b = b.live(None).unwrap();
        assert!(b.timeline.is_none() && b.live.is_none() && b.calibration.is_none());
        assert_eq!(b.interaction.device, InteractionConfig::default().device);
    }

    #[test]
    fn a_missing_calibration_or_replay_names_its_file() {
        let Err(e) = ViewerSetup::builder(model(), [64, 26]).interaction(
            None,
            None,
            Some(Path::new("no/such/calibration.json")),
        ) else {
            panic!("a missing calibration was taken");
        };
        assert!(e.to_string().contains("no/such/calibration.json"), "{e}");
        let replay = ReplayOptions::of("no/such/replay.jsonl".into());
        let Err(e) = ViewerSetup::builder(model(), [64, 26]).replay(Some(&replay)) else {
            panic!("a missing replay was taken");
        };
        assert!(e.to_string().contains("no/such/replay.jsonl"), "{e}");
    }
}
