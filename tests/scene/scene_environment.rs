//! The `--env` argument: a constant radiance or an equirectangular .hdr / .exr in linear RGB;
//! bad values are errors naming the argument, the file or the pixel.

use crate::support;
use support::tmp_file;

use glam::Vec3;
use raygun::scene::{Environment, EnvironmentError};

/// 3×2 texels, all exactly representable in RGBE (a power-of-two scale of an 8-bit mantissa
/// shared by the channels), so the .hdr round trip is exact: (x + 1, y + 1, 0.5) / 4.
fn texel(x: usize, y: usize) -> Vec3 {
    Vec3::new((x + 1) as f32, (y + 1) as f32, 0.5) / 4.0
}

fn expected_texels() -> Vec<Vec3> {
    (0..2)
        .flat_map(|y| (0..3).map(move |x| texel(x, y)))
        .collect()
}

#[test]
fn constant_radiance_parses() {
    assert_eq!(
        Environment::parse("1, 0.5,0").unwrap(),
        Environment::Constant(Vec3::new(1.0, 0.5, 0.0))
    );
    assert_eq!(
        Environment::parse("0,0,0").unwrap(),
        Environment::Constant(Vec3::ZERO)
    );
    for bad in [
        "1,2", "1,2,3,4", "-1,0,0", "nan,0,0", "inf,1,1", "sky.png", "white",
    ] {
        let e = Environment::parse(bad).unwrap_err();
        assert!(
            matches!(e, EnvironmentError::Argument { .. }) && e.to_string().contains(bad),
            "{bad}: {e}"
        );
    }
}

#[test]
fn radiance_hdr_loads_in_linear_rgb_with_row_zero_on_top() {
    let path = tmp_file("sky.hdr");
    let pixels: Vec<image::Rgb<f32>> = expected_texels()
        .iter()
        .map(|t| image::Rgb(t.to_array()))
        .collect();
    let file = std::fs::File::create(&path).unwrap();
    image::codecs::hdr::HdrEncoder::new(file)
        .encode(&pixels, 3, 2)
        .unwrap();
    let Environment::Map(map) = Environment::parse(path.to_str().unwrap()).unwrap() else {
        panic!("a map");
    };
    assert_eq!((map.width, map.height), (3, 2));
    assert_eq!(map.texels, expected_texels());
    assert_eq!(map.name, path.display().to_string());
}

#[test]
fn openexr_loads_exactly_and_bad_texels_name_the_pixel() {
    let path = tmp_file("sky.exr");
    exr::prelude::write_rgb_file(&path, 3, 2, |x, y| {
        let t = texel(x, y);
        (t.x, t.y, t.z)
    })
    .unwrap();
    let Environment::Map(map) = Environment::parse(path.to_str().unwrap()).unwrap() else {
        panic!("a map");
    };
    assert_eq!(map.texels, expected_texels());

    for (value, what) in [(-1.0f32, "-1"), (f32::NAN, "NaN"), (f32::INFINITY, "inf")] {
        let bad = tmp_file("bad.exr");
        exr::prelude::write_rgb_file(&bad, 3, 2, |x, y| {
            if (x, y) == (2, 1) {
                (0.5f32, value, 0.5f32)
            } else {
                (0.5, 0.5, 0.5)
            }
        })
        .unwrap();
        let e = Environment::parse(bad.to_str().unwrap()).unwrap_err();
        let msg = e.to_string();
        assert!(
            matches!(e, EnvironmentError::Texel { x: 2, y: 1, .. }),
            "{msg}"
        );
        assert!(
            msg.contains("bad.exr: pixel (2, 1)") && msg.contains(what),
            "{msg}"
        );
    }
}

#[test]
fn unreadable_environment_files_name_the_file() {
    let e = Environment::parse("/no/such/sky.hdr")
        .unwrap_err()
        .to_string();
    assert!(e.starts_with("/no/such/sky.hdr: cannot read"), "{e}");
    let junk = tmp_file("junk.exr");
    std::fs::write(&junk, b"not an exr").unwrap();
    let e = Environment::parse(junk.to_str().unwrap())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("junk.exr: cannot read the environment image"),
        "{e}"
    );
    let junk = tmp_file("junk.hdr");
    std::fs::write(&junk, b"#?RADIANCE\nnonsense").unwrap();
    let e = Environment::parse(junk.to_str().unwrap())
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("junk.hdr: cannot read the environment image"),
        "{e}"
    );
}
