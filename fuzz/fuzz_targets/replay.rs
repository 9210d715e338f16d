//! Replay files through the whole pipeline (reader, decoders, interaction): never panic, and
//! every ROI change is finite.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use raygun::interaction::{HingedWall, Interaction, InteractionConfig};
use raygun::tracking::dtrack::{DtrackConfig, TimeSource};
use raygun::session::pipeline::Pipeline;
use raygun::tracking::ingest::Ingest;
use raygun::tracking::osc::OscConfig;
use raygun::tracking::replay::{ReplayPayload, ReplayReader};
use raygun::tracking::vrpn::VrpnConfig;

fuzz_target!(|data: &[u8]| {
    // A valid header, so the fuzzer spends its time on the records.
    let mut file = b"{\"raygun_replay\":1}\n".to_vec();
    file.extend_from_slice(data);
    let Ok(mut reader) = ReplayReader::new(&file[..], Path::new("fuzz")) else {
        return;
    };
    reader.problems.quiet = true;
    // VRPN reads (vrpn_tcp_hex, vrpn_udp_hex) go through the VRPN decoder too.
    let mut ingest = Ingest::new(DtrackConfig::default(), OscConfig::default(), TimeSource::Tracker)
        .with_vrpn("DTrack", VrpnConfig::default())
        .unwrap();
    ingest.problems.quiet = true;
    let mut pipeline = Pipeline::new(ingest, Interaction::new(InteractionConfig::default()));
    let wall = HingedWall::hornet();
    while let Some(item) = reader.next_item() {
        let changes = match item.payload {
            ReplayPayload::Datagram(p, bytes) => pipeline.datagram(p, &bytes, item.t, &wall).1.to_vec(),
            ReplayPayload::Event(e) => pipeline.event(e, &wall).to_vec(),
        };
        for c in changes {
            assert!(c.roi.fov_deg.iter().all(|f| f.is_finite()));
            assert!(c.roi.centre.is_none_or(|m| m.canvas_px.is_finite() && m.point.is_finite()));
        }
    }
});
