//! Live DTrack / OSC input for the viewer: the UDP receive loop on its own thread, feeding the
//! tracking pipeline; the window reads the latest ROI and the device's aim each frame.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;

use glam::DVec2;

use super::core::ViewerState;
use crate::display::DisplayModel;
use crate::interaction::RaySurface;
use crate::tracking::event::{DeviceId, Tracking};
use crate::tracking::ingest::{Pipeline, Protocol};
use crate::tracking::udp::{ListenerConfig, Live, UdpSource, run_live};

/// A running listener; stops and joins its thread when dropped.
pub struct LiveTracking {
    live: Arc<Live>,
    aim: Arc<Mutex<Option<DVec2>>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<std::io::Result<()>>>,
    version: u64,
    pub port: u16,
}

impl LiveTracking {
    /// Listens on loopback `port` for `protocol`, following `device`.
    pub fn start(
        port: u16,
        protocol: Protocol,
        device: DeviceId,
        model: DisplayModel,
    ) -> anyhow::Result<Self> {
        let mut source = UdpSource::bind(ListenerConfig::loopback(port))?;
        let port = source.local_addr()?.port();
        let live = Arc::new(Live::default());
        let aim = Arc::new(Mutex::new(None));
        let stop = Arc::new(AtomicBool::new(false));
        let mut pipeline = Pipeline::quiet_live(device);
        let (pointing, _, _) = pipeline.interaction.config().axes();
        let (l, a, s) = (Arc::clone(&live), Arc::clone(&aim), Arc::clone(&stop));
        let thread = std::thread::Builder::new()
            .name("raygun live tracking".into())
            .spawn(move || {
                run_live(
                    &mut source,
                    protocol,
                    &mut pipeline,
                    &model,
                    &s,
                    &l,
                    |events, _| {
                        for e in events.iter().filter(|e| e.device == device) {
                            let new = match e.pose {
                                Some(Tracking::Tracked(p)) => model
                                    .hit(p.position, p.orientation * pointing)
                                    .map(|h| h.canvas_px),
                                Some(Tracking::Lost) => None,
                                None => continue,
                            };
                            if let Ok(mut g) = a.lock() {
                                *g = new;
                            }
                        }
                    },
                )
            })?;
        Ok(Self {
            live,
            aim,
            stop,
            thread: Some(thread),
            version: 0,
            port,
        })
    }

    /// Copies the latest ROI (when it changed) and aim into `state`.
    pub fn update(&mut self, state: &mut ViewerState) {
        let snap = self.live.snapshot();
        if snap.version != self.version {
            self.version = snap.version;
            state.tracked = snap.roi;
        }
        state.aim = self.aim.lock().map(|g| *g).unwrap_or(None);
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
