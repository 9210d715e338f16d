//! Frames → normalised tracking events: the time source, day wrap-around, per-device state.

use super::*;

/// Where event times come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum TimeSource {
    /// The frame's `ts`/`ts2` when it has one (the tracker's measurement time, free of network
    /// jitter), else the receive time.
    #[default]
    Tracker,
    /// Always the receive time.
    Receive,
}

/// A stateful decoder: parses datagrams and turns them into events with continuous times
/// (the `ts` midnight wrap is undone).
#[derive(Clone, Debug)]
pub struct DtrackDecoder {
    config: DtrackConfig,
    time_source: TimeSource,
    last_ts: Option<f64>,
    day_offset: f64,
}

impl DtrackDecoder {
    #[must_use]
    pub fn new(config: DtrackConfig, time_source: TimeSource) -> Self {
        Self {
            config,
            time_source,
            last_ts: None,
            day_offset: 0.0,
        }
    }

    #[must_use]
    pub fn config(&self) -> &DtrackConfig {
        &self.config
    }

    /// Replaces the configuration (a calibration given after construction).
    pub fn set_config(&mut self, config: DtrackConfig) {
        self.config = config;
    }

    /// The continuous time of a `ts` value: a jump back by more than half a day is a wrap
    /// past midnight (DTrack frames are milliseconds apart, never hours).
    fn unwrap_ts(&mut self, ts: f64) -> f64 {
        let t = ts + self.day_offset;
        let t = match self.last_ts {
            Some(last) if t < last - SECONDS_PER_DAY / 2.0 => {
                self.day_offset += SECONDS_PER_DAY;
                ts + self.day_offset
            }
            _ => t,
        };
        self.last_ts = Some(t);
        t
    }

    /// Parses one datagram received at `receive_t` and appends its events to `out`.
    pub fn decode_into(
        &mut self,
        data: &[u8],
        receive_t: f64,
        out: &mut Vec<TrackingEvent>,
    ) -> Result<DtrackFrame, DtrackError> {
        let frame = parse_datagram(data, &self.config)?;
        let t = match (self.time_source, frame.timestamp) {
            (TimeSource::Tracker, Some(Timestamp::SinceMidnight(ts))) => self.unwrap_ts(ts),
            (TimeSource::Tracker, Some(Timestamp::Unix { sec, usec })) => {
                sec as f64 + f64::from(usec) * 1e-6
            }
            _ => receive_t,
        };
        let tracking = |pose: Option<Pose>| Some(pose.map_or(Tracking::Lost, Tracking::Tracked));
        for b in &frame.bodies {
            out.push(TrackingEvent {
                pose: tracking(b.pose),
                ..TrackingEvent::empty(t, DeviceId::new(DeviceKind::Body, b.id))
            });
        }
        for s in &frame.flysticks {
            out.push(TrackingEvent {
                pose: tracking(s.pose),
                buttons: Some(s.buttons),
                axes: Some(s.axes.clone()),
                ..TrackingEvent::empty(t, DeviceId::new(DeviceKind::Flystick, s.id))
            });
        }
        Ok(frame)
    }
}
