//! KTX2 bytes (KHR_texture_basisu textures): never panics or crashes (the Basis Universal
//! transcoder is C++ and is handed only ranges checked against the file), and an image that
//! decodes has exactly width × height texels within the size bound.
#![no_main]

use libfuzzer_sys::fuzz_target;
use raygun::scene::ktx2::{MAX_TEXELS, decode};

fuzz_target!(|data: &[u8]| {
    if let Ok((w, h, texels)) = decode(data) {
        assert!(w > 0 && h > 0 && u64::from(w) * u64::from(h) <= MAX_TEXELS);
        assert_eq!(texels.len(), w as usize * h as usize);
    }
});
