//! OSC datagrams (raygun address space and VMC): never panic; failures leave no events.
#![no_main]

use libfuzzer_sys::fuzz_target;
use raygun::tracking::osc::{OscConfig, OscDecoder};

fuzz_target!(|data: &[u8]| {
    let mut decoder = OscDecoder::new(OscConfig::default());
    let mut out = Vec::new();
    match decoder.decode_into(data, 0.0, &mut out) {
        Ok(()) => assert!(out.iter().all(|e| e.is_valid())),
        Err(_) => assert!(out.is_empty()),
    }
});
