//! `raygun ellipse-distance` input: never panics, one output line per query line, and every
//! accepted query gives a finite, non-negative distance.
#![no_main]

use libfuzzer_sys::fuzz_target;
use raygun::cli::ellipse_distance::run;

fuzz_target!(|data: &[u8]| {
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let stats = run(data, &mut out, &mut err).expect("in-memory streams cannot fail");
    let text = String::from_utf8(out).expect("output is UTF-8");
    assert_eq!(text.lines().count(), stats.queries);
    for line in text.lines().filter(|l| !l.starts_with("nan")) {
        let d: f64 = line.split(',').next().unwrap().parse().unwrap();
        assert!(d >= 0.0 && !d.is_nan(), "{line}");
    }
});
