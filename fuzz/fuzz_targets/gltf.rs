//! glTF / GLB bytes: never panics; a scene that loads is sane (finite geometry within
//! MAX_COORDINATE, non-degenerate triangles, unit normals, finite texture coordinates,
//! material and texture indices in range, finite cameras and materials).
#![no_main]

use libfuzzer_sys::fuzz_target;
use raygun::scene::{MAX_COORDINATE, Scene};

fuzz_target!(|data: &[u8]| {
    let Ok(scene) = Scene::from_glb_bytes(data, "fuzz.glb") else {
        return;
    };
    for t in &scene.triangles {
        for p in t.p {
            assert!(p.is_finite() && p.abs().max_element() <= MAX_COORDINATE);
        }
        let area2 = (t.p[1] - t.p[0]).cross(t.p[2] - t.p[0]).length_squared();
        assert!(area2 >= f32::MIN_POSITIVE && area2.is_finite());
        for n in t.n {
            assert!(n.is_finite() && (n.length() - 1.0).abs() < 1e-3);
        }
        assert!(t.uv.iter().all(|uv| uv.is_finite()));
        assert!((t.material as usize) < scene.materials.len());
    }
    for m in &scene.materials {
        assert!(m.base_color.is_finite() && m.emission.is_finite());
        assert!(m.emission.min_element() >= 0.0);
        assert!((0.0..=1.0).contains(&m.metallic) && (0.0..=1.0).contains(&m.roughness));
        if let Some(i) = m.base_color_texture {
            let t = &scene.textures[i as usize];
            assert_eq!(t.texels.len(), (t.width * t.height) as usize);
        }
    }
    for c in &scene.cameras {
        assert!(c.position.is_finite() && c.forward.is_normalized() && c.up.is_normalized());
        assert!(c.forward.dot(c.up).abs() < 1e-3);
        assert!(c.yfov > 0.0 && c.yfov < std::f32::consts::PI);
    }
});
