//! What a VRPN session needs besides the bytes: the address (`DEVICE@HOST[:PORT]`) and the
//! mapping of sensors, buttons and analog channels onto raygun devices, with the tracker→room
//! calibration.

use std::collections::BTreeMap;
use std::fmt;
use std::str::FromStr;

use serde::{Deserialize, Deserializer, Serialize, Serializer};

use super::wire::{DEFAULT_PORT, MAX_BUTTONS, MAX_CHANNELS, MAX_NAME_LEN};
use crate::tracking::dtrack::TrackerToRoom;
use crate::tracking::event::{DeviceId, DeviceKind, MAX_AXES};

/// How the client reaches the server.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Transport {
    /// VRPN's classic set-up (`DEVICE@HOST`): the client listens on a TCP port and lobs a UDP
    /// datagram at the server, which connects back; poses and analogs then come by UDP,
    /// buttons and descriptions by TCP.
    Udp,
    /// `DEVICE@tcp://HOST`: the client connects, and the server sends everything over TCP.
    Tcp,
}

/// A VRPN device address: `DEVICE@HOST[:PORT]` (classic UDP mode, as VRPN's own clients
/// default to), `DEVICE@tcp://HOST[:PORT]` (TCP only) or `DEVICE@x-vrpn://HOST[:PORT]` (VRPN's
/// name for the classic mode). IPv6 hosts go in brackets.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct VrpnAddress {
    /// The device (sender) name: its messages are the ones decoded.
    pub device: String,
    pub host: String,
    pub port: u16,
    pub transport: Transport,
}

/// Why a string is not a VRPN address.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error(
    "VRPN address {text:?}: {reason} (expected DEVICE@HOST[:PORT] or DEVICE@tcp://HOST[:PORT])"
)]
pub struct VrpnAddressError {
    pub text: String,
    pub reason: &'static str,
}

impl FromStr for VrpnAddress {
    type Err = VrpnAddressError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let err = |reason| VrpnAddressError {
            text: s.chars().take(200).collect(),
            reason,
        };
        let (device, rest) = s
            .split_once('@')
            .ok_or(err("no '@' between device and host"))?;
        if device.is_empty() {
            return Err(err("the device name is empty"));
        }
        if device.len() >= MAX_NAME_LEN || device.chars().any(|c| c.is_control()) {
            return Err(err(
                "the device name is longer than 99 bytes or has control characters",
            ));
        }
        let (transport, hostport) = if let Some(r) = rest.strip_prefix("tcp://") {
            (Transport::Tcp, r)
        } else if let Some(r) = rest.strip_prefix("x-vrpn://") {
            (Transport::Udp, r)
        } else if rest.contains("://") {
            return Err(err("the only schemes are tcp:// and x-vrpn://"));
        } else {
            (Transport::Udp, rest)
        };
        let (host, port) = if let Some(r) = hostport.strip_prefix('[') {
            let (h, after) = r.split_once(']').ok_or(err("an IPv6 host lacks its ']'"))?;
            match after {
                "" => (h, None),
                p => (h, Some(p.strip_prefix(':').ok_or(err("junk after ']'"))?)),
            }
        } else {
            match hostport.rsplit_once(':') {
                Some((h, p)) if !h.contains(':') => (h, Some(p)),
                Some(_) => return Err(err("an IPv6 host must be written in brackets")),
                None => (hostport, None),
            }
        };
        if host.is_empty() || host.chars().any(|c| c.is_whitespace() || c == '/') {
            return Err(err("the host is empty or not a host name"));
        }
        let port = match port {
            None => DEFAULT_PORT,
            Some(p) => p
                .parse::<u16>()
                .ok()
                .filter(|p| *p != 0)
                .ok_or(err("the port is not a number in 1..=65535"))?,
        };
        Ok(Self {
            device: device.to_owned(),
            host: host.to_owned(),
            port,
            transport,
        })
    }
}

impl fmt::Display for VrpnAddress {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let scheme = match self.transport {
            Transport::Tcp => "tcp://",
            Transport::Udp => "",
        };
        if self.host.contains(':') {
            write!(f, "{}@{scheme}[{}]:{}", self.device, self.host, self.port)
        } else {
            write!(f, "{}@{scheme}{}:{}", self.device, self.host, self.port)
        }
    }
}

impl Serialize for VrpnAddress {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> Deserialize<'de> for VrpnAddress {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let text = String::deserialize(d)?;
        text.parse().map_err(serde::de::Error::custom)
    }
}

/// VRPN buttons `first .. first + count` become bits `0 .. count` of `device`'s button mask.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ButtonGroup {
    pub device: DeviceId,
    pub first: u32,
    pub count: u32,
}

/// VRPN analog channels `first .. first + count` become `device`'s axes `0 .. count`, each
/// multiplied by its sign.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct AnalogGroup {
    pub device: DeviceId,
    pub first: u32,
    pub count: u32,
    /// +1 or −1 per axis; empty: all +1. Sticks are mounted and configured differently
    /// between labs, and "push up = bigger FOV" is a user expectation.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub signs: Vec<f64>,
}

impl AnalogGroup {
    /// The sign of axis `i`.
    #[must_use]
    pub fn sign(&self, i: usize) -> f64 {
        self.signs.get(i).copied().unwrap_or(1.0)
    }
}

/// How one VRPN device maps onto raygun devices (JSON; every field may be left out):
///
/// ```json
/// {
///   "tracker_to_room": { "rotation_rows": [[1,0,0],[0,1,0],[0,0,1]],
///                        "translation_m": [0,0,0], "metres_per_unit": 1 },
///   "sensors": { "0": "body:0", "1": "flystick:0" },
///   "buttons": [ { "device": "flystick:0", "first": 0, "count": 8 } ],
///   "analogs": [ { "device": "flystick:0", "first": 0, "count": 2, "signs": [1, 1] } ],
///   "frame_tolerance_s": 0,
///   "silence_s": 0.25
/// }
/// ```
///
/// The defaults are those of `vrpn_Tracker_DTrack` with one body and one FlyStick (VRPN
/// config `vrpn_Tracker_DTrack DTrack 5000 0.0 1 1`): it numbers the bodies first and the
/// FlySticks after them, gives each FlyStick 8 buttons (button i = DTrack button bit i, 0 the
/// trigger) and 2 analogs (joystick x, y), all in one device. With other numbers of bodies the
/// sensors (and, for several FlySticks, the button and analog ranges: 8 and 2 per stick) must
/// be configured.
///
/// VRPN sends positions in the tracker's frame and units; vrpn_Tracker_DTrack sends **metres**
/// (DTrack's millimetres / 1000), so the default transform is the identity in metres. This
/// differs from the DTrack parser's default (millimetres) on purpose.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct VrpnConfig {
    pub tracker_to_room: TrackerToRoom,
    /// VRPN sensor number → raygun device.
    pub sensors: BTreeMap<u32, DeviceId>,
    pub buttons: Vec<ButtonGroup>,
    pub analogs: Vec<AnalogGroup>,
    /// VRPN sends nothing for an untracked target, so "untracked" is inferred: a sensor is
    /// lost when a tracker frame of its sender completes without it, a frame being the
    /// Pos_Quat reports of one time stamp (vrpn_Tracker_DTrack stamps all reports of a DTrack
    /// frame with its `ts`). Servers that stamp each sensor separately need about one frame
    /// period here: a sensor is then lost only when a completed frame is more than this much
    /// newer than its last report.
    pub frame_tolerance_s: f64,
    /// Every sensor is lost when nothing at all has arrived for this long (receive clock): an
    /// idle server and an untracked lone target look the same. 0 turns this off.
    pub silence_s: f64,
}

impl Default for VrpnConfig {
    fn default() -> Self {
        let flystick = DeviceId::new(DeviceKind::Flystick, 0);
        Self {
            tracker_to_room: Self::identity_in_metres(),
            sensors: BTreeMap::from([(0, DeviceId::new(DeviceKind::Body, 0)), (1, flystick)]),
            buttons: vec![ButtonGroup {
                device: flystick,
                first: 0,
                count: 8,
            }],
            analogs: vec![AnalogGroup {
                device: flystick,
                first: 0,
                count: 2,
                signs: Vec::new(),
            }],
            frame_tolerance_s: 0.0,
            silence_s: 0.25,
        }
    }
}

/// Why a VRPN mapping cannot be used; names the field.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("vrpn config field `{field}`: {reason}")]
pub struct VrpnConfigError {
    pub field: String,
    pub reason: String,
}

impl VrpnConfig {
    /// The identity rotation and offset, in metres: VRPN's frame is the tracker's, and
    /// vrpn_Tracker_DTrack already converts DTrack's millimetres to metres.
    #[must_use]
    pub fn identity_in_metres() -> TrackerToRoom {
        TrackerToRoom {
            metres_per_unit: 1.0,
            ..TrackerToRoom::default()
        }
    }

    /// Checks the transform, that every device is used once per role, that button and analog
    /// ranges fit VRPN's limits and raygun's masks and do not overlap, and that the times are
    /// usable.
    pub fn validate(&self) -> Result<(), VrpnConfigError> {
        let bad = |field: String, reason: String| Err(VrpnConfigError { field, reason });
        if let Err(e) = self.tracker_to_room.validate() {
            return bad("tracker_to_room".into(), e.to_string());
        }
        let mut seen = Vec::new();
        for (sensor, device) in &self.sensors {
            let field = format!("sensors.{sensor}");
            if device.kind == DeviceKind::Mouse {
                return bad(
                    field,
                    "a mouse is a canvas pointer, not a tracked pose".into(),
                );
            }
            if seen.contains(device) {
                return bad(
                    field,
                    format!("{device} is already another sensor's device"),
                );
            }
            seen.push(*device);
        }
        check_groups(
            "buttons",
            self.buttons.iter().map(|g| (g.device, g.first, g.count)),
            32,
            MAX_BUTTONS as u32,
            "32 (one button mask)",
        )?;
        check_groups(
            "analogs",
            self.analogs.iter().map(|g| (g.device, g.first, g.count)),
            MAX_AXES as u32,
            MAX_CHANNELS as u32,
            "8 axes",
        )?;
        for (i, g) in self.analogs.iter().enumerate() {
            if !(g.signs.is_empty() || g.signs.len() == g.count as usize) {
                return bad(
                    format!("analogs[{i}].signs"),
                    format!("{} signs for {} axes", g.signs.len(), g.count),
                );
            }
            if let Some(s) = g.signs.iter().find(|s| **s != 1.0 && **s != -1.0) {
                return bad(
                    format!("analogs[{i}].signs"),
                    format!("{s} is not +1 or -1"),
                );
            }
        }
        for (field, v) in [
            ("frame_tolerance_s", self.frame_tolerance_s),
            ("silence_s", self.silence_s),
        ] {
            if !(v.is_finite() && (0.0..=3600.0).contains(&v)) {
                return bad(
                    field.into(),
                    format!("{v} is not a number of seconds in 0..=3600"),
                );
            }
        }
        Ok(())
    }
}

fn check_groups(
    what: &str,
    groups: impl Iterator<Item = (DeviceId, u32, u32)>,
    max_count: u32,
    vrpn_limit: u32,
    max_text: &str,
) -> Result<(), VrpnConfigError> {
    let mut used: Vec<(DeviceId, u32, u32)> = Vec::new();
    for (i, (device, first, count)) in groups.enumerate() {
        let bad = |field: &str, reason: String| {
            Err(VrpnConfigError {
                field: format!("{what}[{i}].{field}"),
                reason,
            })
        };
        if device.kind == DeviceKind::Mouse {
            return bad("device", "a mouse gets its buttons from the window".into());
        }
        if count == 0 || count > max_count {
            return bad("count", format!("{count} is not in 1..={max_text}"));
        }
        if u64::from(first) + u64::from(count) > u64::from(vrpn_limit) {
            return bad(
                "first",
                format!("{first} + {count} goes past VRPN's limit of {vrpn_limit}"),
            );
        }
        if used.iter().any(|(d, _, _)| *d == device) {
            return bad("device", format!("{device} already has a {what} group"));
        }
        if let Some((d, _, _)) = used
            .iter()
            .find(|(_, f, c)| first < f + c && *f < first + count)
        {
            return bad(
                "first",
                format!("VRPN {what} {first}..{} overlap {d}'s", first + count),
            );
        }
        used.push((device, first, count));
    }
    Ok(())
}

/// What a replay header records about a VRPN session: whose messages were recorded and how
/// they map, so that a replay decodes exactly as the live run did.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VrpnHeader {
    /// Where it was recorded from; its device name selects the messages decoded.
    pub source: VrpnAddress,
    #[serde(default)]
    pub config: VrpnConfig,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn addresses_parse_with_defaults_schemes_and_ipv6() {
        let a: VrpnAddress = "DTrack@localhost".parse().unwrap();
        assert_eq!(
            a,
            VrpnAddress {
                device: "DTrack".into(),
                host: "localhost".into(),
                port: 3883,
                transport: Transport::Udp
            }
        );
        let a: VrpnAddress = "Tracker0@tcp://10.0.0.5:3884".parse().unwrap();
        assert_eq!(
            (a.host.as_str(), a.port, a.transport),
            ("10.0.0.5", 3884, Transport::Tcp)
        );
        let a: VrpnAddress = "T@x-vrpn://[::1]:4000".parse().unwrap();
        assert_eq!(
            (a.host.as_str(), a.port, a.transport),
            ("::1", 4000, Transport::Udp)
        );
        assert_eq!(a.to_string(), "T@[::1]:4000");
        for s in ["DTrack@tcp://h:1", "DTrack@h:3883", "x@[::1]:5"] {
            let a: VrpnAddress = s.parse().unwrap();
            assert_eq!(a.to_string().parse::<VrpnAddress>().unwrap(), a);
        }
    }

    #[test]
    fn bad_addresses_say_what_is_wrong() {
        for (s, what) in [
            ("localhost", "'@'"),
            ("@localhost", "device name is empty"),
            ("D@", "host is empty"),
            ("D@h:0", "port"),
            ("D@h:99999", "port"),
            ("D@http://h", "schemes"),
            ("D@::1", "brackets"),
        ] {
            let e = s.parse::<VrpnAddress>().unwrap_err();
            assert!(e.to_string().contains(what), "{s}: {e}");
        }
    }

    #[test]
    fn default_config_is_vrpn_tracker_dtrack_in_metres_and_valid() {
        let c = VrpnConfig::default();
        c.validate().unwrap();
        assert_eq!(c.tracker_to_room.metres_per_unit, 1.0);
        assert_eq!(c.sensors[&1], DeviceId::new(DeviceKind::Flystick, 0));
        assert_eq!(c.sensors[&0], DeviceId::new(DeviceKind::Body, 0));
        let json = serde_json::to_string(&c).unwrap();
        assert_eq!(serde_json::from_str::<VrpnConfig>(&json).unwrap(), c);
        // Every field may be left out.
        assert_eq!(serde_json::from_str::<VrpnConfig>("{}").unwrap(), c);
    }

    #[test]
    fn unknown_fields_are_rejected() {
        assert!(serde_json::from_str::<VrpnConfig>(r#"{"sensor":{}}"#).is_err());
        assert!(
            serde_json::from_str::<VrpnConfig>(
                r#"{"buttons":[{"device":"flystick:0","first":0,"count":8,"x":1}]}"#
            )
            .is_err()
        );
    }

    #[test]
    fn invalid_mappings_name_their_field() {
        let f = DeviceId::new(DeviceKind::Flystick, 0);
        let cases: Vec<(VrpnConfig, &str)> = vec![
            (
                VrpnConfig {
                    buttons: vec![ButtonGroup {
                        device: f,
                        first: 0,
                        count: 33,
                    }],
                    ..VrpnConfig::default()
                },
                "buttons[0].count",
            ),
            (
                VrpnConfig {
                    buttons: vec![
                        ButtonGroup {
                            device: f,
                            first: 0,
                            count: 8,
                        },
                        ButtonGroup {
                            device: DeviceId::new(DeviceKind::Flystick, 1),
                            first: 4,
                            count: 8,
                        },
                    ],
                    ..VrpnConfig::default()
                },
                "buttons[1].first",
            ),
            (
                VrpnConfig {
                    analogs: vec![AnalogGroup {
                        device: f,
                        first: 0,
                        count: 2,
                        signs: vec![1.0, 0.5],
                    }],
                    ..VrpnConfig::default()
                },
                "analogs[0].signs",
            ),
            (
                VrpnConfig {
                    sensors: BTreeMap::from([(0, f), (1, f)]),
                    ..VrpnConfig::default()
                },
                "sensors.1",
            ),
            (
                VrpnConfig {
                    silence_s: f64::NAN,
                    ..VrpnConfig::default()
                },
                "silence_s",
            ),
            (
                VrpnConfig {
                    tracker_to_room: TrackerToRoom {
                        metres_per_unit: 0.0,
                        ..VrpnConfig::identity_in_metres()
                    },
                    ..VrpnConfig::default()
                },
                "tracker_to_room",
            ),
            (
                VrpnConfig {
                    analogs: vec![AnalogGroup {
                        device: f,
                        first: 127,
                        count: 2,
                        signs: vec![],
                    }],
                    ..VrpnConfig::default()
                },
                "analogs[0].first",
            ),
        ];
        for (c, field) in cases {
            let e = c.validate().unwrap_err();
            assert_eq!(e.field, field, "{e}");
            assert!(e.to_string().contains(field));
        }
    }

    #[test]
    fn header_round_trips_with_its_address_as_a_string() {
        let h = VrpnHeader {
            source: "DTrack@tcp://127.0.0.1:3883".parse().unwrap(),
            config: VrpnConfig::default(),
        };
        let json = serde_json::to_string(&h).unwrap();
        assert!(
            json.contains("\"source\":\"DTrack@tcp://127.0.0.1:3883\""),
            "{json}"
        );
        assert_eq!(serde_json::from_str::<VrpnHeader>(&json).unwrap(), h);
    }
}
