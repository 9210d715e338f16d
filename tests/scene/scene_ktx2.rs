//! KTX2 textures (glTF's KHR_texture_basisu) against files written by Binomial's own encoder
//! (`tests/data/ktx2/README.md` says how): ETC1S (BasisLZ) with and without alpha and mipmaps,
//! UASTC raw and Zstandard-compressed, sizes that are not multiples of the 4×4 blocks; then
//! glTF files that use them, with and without a PNG fallback, and files that are broken.

use std::path::PathBuf;

use raygun::scene::{Scene, ktx2};

fn data(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/ktx2")
        .join(name)
}

fn read(name: &str) -> Vec<u8> {
    std::fs::read(data(name)).unwrap()
}

fn png(name: &str) -> image::RgbaImage {
    image::open(data(name)).unwrap().to_rgba8()
}

/// The largest per-channel difference of the decoded texels from `reference`.
fn max_error(decoded: &ktx2::Rgba8, reference: &image::RgbaImage, alpha: bool) -> u8 {
    let (w, h, texels) = decoded;
    assert_eq!((*w, *h), reference.dimensions());
    texels
        .iter()
        .zip(reference.pixels())
        .flat_map(|(a, b)| (0..if alpha { 4 } else { 3 }).map(move |c| a[c].abs_diff(b.0[c])))
        .max()
        .unwrap()
}

/// The mean absolute difference of the decoded RGB from `reference`.
fn mean_error(decoded: &ktx2::Rgba8, reference: &image::RgbaImage) -> f64 {
    let sum: u64 = decoded
        .2
        .iter()
        .zip(reference.pixels())
        .flat_map(|(a, b)| (0..3).map(move |c| u64::from(a[c].abs_diff(b.0[c]))))
        .sum();
    sum as f64 / (3 * decoded.2.len()) as f64
}

/// ETC1S transcoded to RGBA is the ETC1 decoding of its blocks: bit for bit what basisu's own
/// `-unpack` writes, and near the source image.
#[test]
fn etc1s_decodes_as_basis_universal_unpacks_it() {
    let decoded = ktx2::decode(&read("gradient-etc1s.ktx2")).unwrap();
    let unpacked = png("gradient-etc1s.basisu-unpack.png");
    assert_eq!(max_error(&decoded, &unpacked, false), 0);
    assert!(decoded.2.iter().all(|p| p[3] == 255), "no alpha: opaque");
    // ETC1S is lossy: a 4×4 block has one base colour and four intensities, and this gradient
    // climbs 48 levels across a block in x and 76 in y, so at basisu's default quality it is
    // off by up to 39 levels, 11.1 on average.
    let source = png("gradient.png");
    let e = max_error(&decoded, &source, false);
    assert!((1..=48).contains(&e), "ETC1S error {e}");
    let mean = mean_error(&decoded, &source);
    assert!(mean < 14.0, "ETC1S mean error {mean}");
    // The same image with its mipmaps: level 0 is the image (the level count changes where
    // the codebooks are in the global data).
    let mips = ktx2::decode(&read("gradient-etc1s-mips.ktx2")).unwrap();
    assert!(max_error(&mips, &source, false) <= 48);
    assert!(mean_error(&mips, &source) < 12.0);
}

/// UASTC is near-lossless: raw and Zstandard-compressed levels both decode to the source
/// within a few levels, including the partial blocks at the right and bottom edges (21×13).
#[test]
fn uastc_raw_and_zstandard_decode_to_the_source() {
    let raw = ktx2::decode(&read("gradient-uastc.ktx2")).unwrap();
    let e = max_error(&raw, &png("gradient.png"), false);
    assert!(e <= 6, "UASTC error {e}");
    let zstd = ktx2::decode(&read("quadrants-uastc-zstd.ktx2")).unwrap();
    let e = max_error(&zstd, &png("quadrants.png"), true);
    assert!(e <= 6, "UASTC+Zstandard error {e}");
}

/// Alpha survives both codecs: the quadrant at half alpha is half transparent, the others
/// opaque (ETC1S keeps alpha in a second slice).
#[test]
fn alpha_survives_etc1s_and_uastc() {
    for file in ["quadrants-etc1s.ktx2", "quadrants-uastc-zstd.ktx2"] {
        let (w, h, texels) = ktx2::decode(&read(file)).unwrap();
        assert_eq!((w, h), (32, 32));
        let at = |x: usize, y: usize| texels[y * 32 + x];
        for (x, y, want) in [
            (8, 8, [255, 0, 0, 255]),
            (24, 8, [0, 255, 0, 255]),
            (8, 24, [0, 0, 255, 255]),
            (24, 24, [255, 255, 255, 128]),
        ] {
            let got = at(x, y);
            let e = (0..4).map(|c| got[c].abs_diff(want[c])).max().unwrap();
            assert!(e <= 8, "{file} ({x}, {y}): {got:?}, want {want:?}");
        }
    }
}

/// Broken and unsupported KTX2 files are errors that say what is wrong, never a crash.
#[test]
fn broken_ktx2_files_are_clear_errors() {
    let good = read("quadrants-etc1s.ktx2");
    assert!(
        ktx2::decode(&good[..40])
            .unwrap_err()
            .to_string()
            .starts_with("not a valid KTX2 file")
    );
    assert!(
        ktx2::decode(b"\xabKTX 20\xbb\r\n\x1a\n")
            .unwrap_err()
            .to_string()
            .starts_with("not a valid KTX2 file")
    );
    // The two descriptors the container crate would panic on (found by fuzzing).
    let dfd = u32::from_le_bytes(good[48..52].try_into().unwrap()) as usize;
    let mut b = good.clone();
    b[dfd + 4 + 12] = 255;
    assert!(
        ktx2::decode(&b)
            .unwrap_err()
            .to_string()
            .contains("texel block dimension of 256")
    );
    let mut b = good.clone();
    b[52..56].copy_from_slice(&2u32.to_le_bytes());
    assert!(
        ktx2::decode(&b)
            .unwrap_err()
            .to_string()
            .contains("fewer than its length field")
    );
    // Every truncation and every single flipped byte: an error or an image, never a panic.
    for n in (0..good.len()).step_by(7) {
        let _ = ktx2::decode(&good[..n]);
    }
    for i in 0..good.len() {
        let mut b = good.clone();
        b[i] ^= 0x5a;
        if let Ok((w, h, t)) = ktx2::decode(&b) {
            assert_eq!(t.len(), w as usize * h as usize);
        }
    }
    // An ETC1S codebook whose variable-length code runs past 32 bits (found by fuzzing): the
    // transcoder's development `assert` aborted the process; built as its release is
    // (.cargo/config.toml), it takes its error path and the texture is refused.
    let e = ktx2::decode(&read("fuzz-decode-vlc-overrun.ktx2")).unwrap_err();
    assert!(!e.to_string().is_empty());
    let zstd = read("quadrants-uastc-zstd.ktx2");
    for i in (zstd.len() - 60)..zstd.len() {
        let mut b = zstd.clone();
        b[i] ^= 0xff;
        if let Ok((w, h, t)) = ktx2::decode(&b) {
            assert_eq!(t.len(), w as usize * h as usize);
        }
    }
}

/// A glTF quad whose base colour is `uri` through KHR_texture_basisu (required, no fallback),
/// or with `fallback` as the texture's plain source.
fn basisu_gltf(dir: &std::path::Path, uri: &str, fallback: Option<&str>) -> PathBuf {
    let positions: [f32; 12] = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 0.0];
    let uvs: [f32; 8] = [0.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0];
    let indices: [u16; 6] = [0, 1, 2, 0, 2, 3];
    let mut bin = Vec::new();
    bin.extend(positions.iter().flat_map(|f| f.to_le_bytes()));
    bin.extend(uvs.iter().flat_map(|f| f.to_le_bytes()));
    bin.extend(indices.iter().flat_map(|i| i.to_le_bytes()));
    let buffer = format!(
        "data:application/octet-stream;base64,{}",
        base64::encode(&bin)
    );
    let mut images = vec![serde_json::json!({ "uri": uri, "mimeType": "image/ktx2" })];
    let mut texture =
        serde_json::json!({ "extensions": { "KHR_texture_basisu": { "source": 0 } } });
    let mut required = vec!["KHR_texture_basisu"];
    if let Some(png) = fallback {
        images.push(serde_json::json!({ "uri": png }));
        texture["source"] = 1.into();
        required.clear();
    }
    let doc = serde_json::json!({
        "asset": { "version": "2.0" },
        "extensionsUsed": ["KHR_texture_basisu"],
        "extensionsRequired": required,
        "buffers": [{ "uri": buffer, "byteLength": bin.len() }],
        "bufferViews": [
            { "buffer": 0, "byteOffset": 0, "byteLength": 48 },
            { "buffer": 0, "byteOffset": 48, "byteLength": 32 },
            { "buffer": 0, "byteOffset": 80, "byteLength": 12 }
        ],
        "accessors": [
            { "bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
              "min": [0, 0, 0], "max": [1, 1, 0] },
            { "bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC2" },
            { "bufferView": 2, "componentType": 5123, "count": 6, "type": "SCALAR" }
        ],
        "images": images,
        "textures": [texture],
        "materials": [{ "pbrMetallicRoughness": { "baseColorTexture": { "index": 0 } } }],
        "meshes": [{ "primitives": [{ "attributes": { "POSITION": 0, "TEXCOORD_0": 1 },
                                     "indices": 2, "material": 0 }] }],
        "nodes": [{ "mesh": 0 }],
        "scenes": [{ "nodes": [0] }]
    });
    let path = dir.join("quad.gltf");
    std::fs::write(&path, serde_json::to_vec_pretty(&doc).unwrap()).unwrap();
    path
}

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("raygun-ktx2-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// A glTF that requires KHR_texture_basisu loads, its texture the decoded KTX2 (and is used
/// by the material); with a PNG fallback the KTX2 is still preferred.
#[test]
fn gltf_with_khr_texture_basisu_loads_the_ktx2() {
    let dir = temp_dir("load");
    for file in ["quadrants-etc1s.ktx2", "quadrants-uastc-zstd.ktx2"] {
        std::fs::copy(data(file), dir.join(file)).unwrap();
        let want = ktx2::decode(&read(file)).unwrap();
        for fallback in [None, Some("gradient.png")] {
            if let Some(png) = fallback {
                std::fs::copy(data(png), dir.join(png)).unwrap();
            }
            let scene = Scene::load(basisu_gltf(&dir, file, fallback)).unwrap();
            assert_eq!(scene.textures.len(), 1, "{file} {fallback:?}");
            let t = &scene.textures[0];
            assert_eq!((t.width, t.height), (32, 32));
            assert_eq!(t.texels, want.2, "{file} {fallback:?}");
            assert!(scene.materials[0].base_color_texture.is_some());
            assert!(
                !scene.unsupported.iter().any(|u| u.contains("basisu")),
                "{:?}",
                scene.unsupported
            );
        }
    }
    std::fs::remove_dir_all(&dir).unwrap();
}

/// A broken KTX2 with a fallback: the fallback is used and the KTX2's fault is reported;
/// without one, the material keeps its factor and the fault is reported.
#[test]
fn a_broken_ktx2_falls_back_or_is_reported() {
    let dir = temp_dir("broken");
    let mut broken = read("quadrants-etc1s.ktx2");
    broken.truncate(100);
    std::fs::write(dir.join("broken.ktx2"), &broken).unwrap();
    std::fs::copy(data("gradient.png"), dir.join("gradient.png")).unwrap();
    let scene = Scene::load(basisu_gltf(&dir, "broken.ktx2", Some("gradient.png"))).unwrap();
    assert_eq!(
        (scene.textures[0].width, scene.textures[0].height),
        (21, 13)
    );
    let warned = |s: &Scene| {
        s.warnings
            .iter()
            .any(|w| w.contains("KTX2 image (not a valid KTX2 file"))
    };
    assert!(warned(&scene), "{:?}", scene.warnings);
    let scene = Scene::load(basisu_gltf(&dir, "broken.ktx2", None)).unwrap();
    assert!(scene.textures.is_empty());
    assert!(scene.materials[0].base_color_texture.is_none());
    assert!(warned(&scene), "{:?}", scene.warnings);
    std::fs::remove_dir_all(&dir).unwrap();
}
