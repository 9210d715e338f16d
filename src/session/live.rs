//! Live DTrack / OSC / VRPN input for the viewer: the receive loop on its own thread, feeding
//! the tracking pipeline; the window reads the latest ROI, the device's aim and a tracked head's
//! eye ([`LiveTracking::follow_head`]) each frame.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::Instant;

use glam::{DVec2, DVec3};

use super::pipeline::Pipeline;
use super::udp::{ListenerConfig, Live, UdpSource, run_live};
use super::vrpn::{VrpnClientConfig, VrpnSource};
use crate::display::DisplayModel;
use crate::interaction::{Interaction, InteractionConfig, RaySurface};
use crate::interaction::{RoiChange, RoiState};
use crate::tracking::calibration::Calibration;
use crate::tracking::dtrack::TimeSource;
use crate::tracking::event::{DeviceId, Tracking, TrackingEvent};
use crate::tracking::head::HeadConfig;
use crate::tracking::ingest::{Ingest, Protocol};
use crate::tracking::vrpn::{VrpnAddress, VrpnConfig};

/// Why live tracking could not start.
#[derive(Debug, thiserror::Error)]
pub enum LiveError {
    #[error(transparent)]
    Udp(#[from] super::udp::UdpError),
    #[error(transparent)]
    Vrpn(#[from] super::vrpn::VrpnClientError),
    #[error(transparent)]
    VrpnConfig(#[from] crate::tracking::vrpn::VrpnConfigError),
    #[error("starting the live tracking thread: {0}")]
    Io(#[from] std::io::Error),
}

/// What live tracking delivered since the last [`LiveTracking::update`].
#[derive(Clone, Debug, Default)]
pub struct LiveUpdate {
    /// The latest ROI, when it changed (`Some(None)`: the ROI went away).
    pub roi: Option<Option<RoiState>>,
    /// (event time, canvas point or `None` while untracked or aiming off the wall).
    pub aim: Vec<(f64, Option<DVec2>)>,
    /// The tracked head's latest eye (room frame), when a new one arrived.
    pub eye: Option<DVec3>,
}

/// Aim samples of the followed device: (event time, canvas point or `None` while untracked or
/// aiming off the wall).
type AimQueue = Arc<Mutex<Vec<(f64, Option<DVec2>)>>>;

/// The tracked head and its latest eye (taken by [`LiveTracking::update`]).
type HeadSlot = Arc<Mutex<(Option<HeadConfig>, Option<DVec3>)>>;

/// A running listener; stops and joins its thread when dropped.
pub struct LiveTracking {
    live: Arc<Live>,
    aim: AimQueue,
    head: HeadSlot,
    /// The newest sample's event time and when the window took it: the events' clock now is
    /// that time plus the time since.
    clock: Option<(f64, Instant)>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<std::io::Result<()>>>,
    version: u64,
    pub port: u16,
}

impl LiveTracking {
    /// Listens on loopback `port` for `protocol`, following `device` with the default mapping.
    pub fn start(
        port: u16,
        protocol: Protocol,
        device: DeviceId,
        model: DisplayModel,
    ) -> Result<Self, LiveError> {
        let config = InteractionConfig {
            device,
            ..InteractionConfig::default()
        };
        Self::start_with(port, protocol, config, model)
    }

    /// Listens on loopback `port` for `protocol` with the mapping `config` (its device).
    pub fn start_with(
        port: u16,
        protocol: Protocol,
        config: InteractionConfig,
        model: DisplayModel,
    ) -> Result<Self, LiveError> {
        Self::start_calibrated(port, protocol, config, model, None)
    }

    /// [`Self::start_with`] with the tracker→room `calibration` applied to the decoders (its
    /// device axes are the caller's to put into `config`).
    pub fn start_calibrated(
        port: u16,
        protocol: Protocol,
        config: InteractionConfig,
        model: DisplayModel,
        calibration: Option<&Calibration>,
    ) -> Result<Self, LiveError> {
        let mut source = UdpSource::bind(ListenerConfig::loopback(port))?;
        let port = source.local_addr()?.port();
        let mut pipeline = Pipeline::quiet_live(config.device);
        if let Some(c) = calibration {
            pipeline.ingest.calibrate(c);
        }
        Self::spawn(
            pipeline,
            config,
            model,
            port,
            move |p, m, stop, live, on| run_live(&mut source, protocol, p, m, stop, live, on),
        )
    }

    /// Follows a VRPN server (`DEVICE@HOST[:PORT]`, loopback unless `allow_network`),
    /// reconnecting when it goes away, with the default mapping for `vrpn_Tracker_DTrack`
    /// and `calibration` (VRPN sends metres).
    pub fn start_vrpn(
        address: VrpnAddress,
        allow_network: bool,
        config: InteractionConfig,
        model: DisplayModel,
        calibration: Option<&Calibration>,
    ) -> Result<Self, LiveError> {
        let mut source = VrpnSource::new(VrpnClientConfig {
            allow_non_loopback: allow_network,
            ..VrpnClientConfig::new(address.clone())
        })?;
        let mut ingest =
            Ingest::vrpn_only(&address.device, VrpnConfig::default(), TimeSource::Tracker)?;
        ingest.problems.quiet = true;
        if let Some(c) = calibration {
            ingest.calibrate(c);
        }
        let pipeline = Pipeline::new(ingest, Interaction::new(config.clone()));
        Self::spawn(
            pipeline,
            config,
            model,
            address.port,
            move |p, m, stop, live, on| super::vrpn::run_live(&mut source, p, m, stop, live, on),
        )
    }

    /// Runs `receive` (a source's live loop) on its own thread with `pipeline` following
    /// `config`'s device, collecting the device's aim for the cursor.
    fn spawn(
        mut pipeline: Pipeline,
        config: InteractionConfig,
        model: DisplayModel,
        port: u16,
        receive: impl FnOnce(
            &mut Pipeline,
            &DisplayModel,
            &AtomicBool,
            &Live,
            &mut dyn FnMut(&[TrackingEvent], &[RoiChange]),
        ) -> std::io::Result<()>
        + Send
        + 'static,
    ) -> Result<Self, LiveError> {
        let live = Arc::new(Live::default());
        let aim: AimQueue = Arc::new(Mutex::new(Vec::new()));
        let head: HeadSlot = Arc::new(Mutex::new((None, None)));
        let stop = Arc::new(AtomicBool::new(false));
        let device = config.device;
        pipeline.interaction = Interaction::new(config);
        let (pointing, _, _) = pipeline.interaction.config().axes();
        let (l, a, s) = (Arc::clone(&live), Arc::clone(&aim), Arc::clone(&stop));
        let hd = Arc::clone(&head);
        let thread = std::thread::Builder::new()
            .name("raygun live tracking".into())
            .spawn(move || {
                let mut on = |events: &[TrackingEvent], _: &[RoiChange]| {
                    if let Ok(mut g) = hd.lock()
                        && let Some(h) = g.0
                        && let Some(eye) = events.iter().rev().find_map(|e| h.eye_of(e))
                    {
                        g.1 = Some(eye);
                    }
                    for e in events.iter().filter(|e| e.device == device) {
                        let new = match e.pose {
                            Some(Tracking::Tracked(p)) => model
                                .hit(p.position, p.orientation * pointing)
                                .map(|h| h.canvas_px),
                            Some(Tracking::Lost) => None,
                            None => continue,
                        };
                        if let Ok(mut g) = a.lock() {
                            g.push((e.t, new));
                        }
                    }
                };
                receive(&mut pipeline, &model, &s, &l, &mut on)
            })?;
        Ok(Self {
            live,
            aim,
            head,
            clock: None,
            stop,
            thread: Some(thread),
            version: 0,
            port,
        })
    }

    /// What arrived since the last call: the latest ROI when it changed and the aim samples,
    /// in time order (the viewer feeds them to its cursor).
    pub fn update(&mut self) -> LiveUpdate {
        let snap = self.live.snapshot();
        let roi = (snap.version != self.version).then(|| {
            self.version = snap.version;
            snap.roi
        });
        let aim = self
            .aim
            .lock()
            .map(|mut g| std::mem::take(&mut *g))
            .unwrap_or_default();
        if let Some(&(t, _)) = aim.last() {
            self.clock = Some((t, Instant::now()));
        }
        let eye = self.head.lock().ok().and_then(|mut g| g.1.take());
        LiveUpdate { roi, aim, eye }
    }

    /// Follows `head` too: its tracked poses' eyes (room frame, through the same decoders and
    /// calibration as the ray gun's) arrive in [`LiveUpdate::eye`].
    pub fn follow_head(&self, head: HeadConfig) {
        if let Ok(mut g) = self.head.lock() {
            *g = (Some(head), None);
        }
    }

    /// The events' clock now (for drawing the cursor); `None` before the first sample.
    #[must_use]
    pub fn now(&self) -> Option<f64> {
        self.clock.map(|(t, at)| t + at.elapsed().as_secs_f64())
    }
}

impl Drop for LiveTracking {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            match t.join() {
                Ok(Err(e)) => eprintln!("raygun view: live tracking stopped: {e}"),
                Err(_) => eprintln!("raygun view: live tracking thread panicked"),
                Ok(Ok(())) => {}
            }
        }
    }
}
