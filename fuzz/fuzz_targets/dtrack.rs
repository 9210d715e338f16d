//! DTrack datagrams: never panic; whatever parses yields valid events only.
#![no_main]

use libfuzzer_sys::fuzz_target;
use raygun::tracking::dtrack::{DtrackConfig, DtrackDecoder, TimeSource};

fuzz_target!(|data: &[u8]| {
    let mut decoder = DtrackDecoder::new(DtrackConfig::default(), TimeSource::Tracker);
    let mut out = Vec::new();
    // Twice, so the midnight-unwrap state sees a second timestamp.
    for _ in 0..2 {
        if decoder.decode_into(data, 0.0, &mut out).is_ok() {
            assert!(out.iter().all(|e| e.is_valid()));
        }
        out.clear();
    }
});
