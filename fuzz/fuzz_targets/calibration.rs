//! Calibration JSON: never panics; a calibration that loads maps finite tracker points to
//! finite room points with a proper rotation.
#![no_main]

use libfuzzer_sys::fuzz_target;
use raygun::tracking::calibration::{Calibration, rotation_error};

fuzz_target!(|data: &[u8]| {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(c) = Calibration::from_json(text, std::path::Path::new("fuzz.json")) {
        let t = c.tracker_to_room(1e-3);
        t.validate().expect("a loaded calibration validates");
        assert!(rotation_error(&t) < 1e-2);
        let p = t.map_point(glam::DVec3::new(1234.5, -20.0, 3e3));
        assert!(p.is_finite());
    }
});
