//! glTF / GLB bytes: never panics; a scene that loads is sane (finite geometry within
//! MAX_COORDINATE, non-degenerate triangles, unit normals, finite texture coordinates,
//! material and texture indices in range, finite cameras and materials, vertex extras in
//! step with the triangles and in range, punctual lights and orthographic cameras finite), and
//! packs for the tracer without panicking (strips, fans, texture slots, lights).
#![no_main]

use libfuzzer_sys::fuzz_target;
use raygun::scene::{LightKind, MAX_COORDINATE, Scene};

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
    assert!(scene.vertex_extras.is_empty() || scene.vertex_extras.len() == scene.triangles.len());
    for e in &scene.vertex_extras {
        for c in e.color {
            assert!(c.is_finite() && c.min_element() >= 0.0 && c.max_element() <= 1.0);
        }
        assert!(e.uv1.iter().all(|uv| uv.is_finite()));
        assert!(e.tangent.iter().all(|t| t.is_finite()));
    }
    assert!(scene.material_ext.is_empty() || scene.material_ext.len() == scene.materials.len());
    for x in &scene.material_ext {
        for r in [
            x.metallic_roughness_texture,
            x.normal_texture,
            x.emissive_texture,
        ]
        .into_iter()
        .flatten()
        {
            assert!((r.texture as usize) < scene.textures.len() && r.uv.tex_coord <= 1);
        }
        assert!((0.0..=1.0).contains(&x.transmission) && (0.0..=1.0).contains(&x.clearcoat));
        assert!(x.ior >= 1.0 && x.ior.is_finite() && x.specular_color.is_finite());
    }
    for l in &scene.lights {
        assert!(l.position.is_finite() && l.direction.is_normalized());
        assert!(l.intensity.is_finite() && l.intensity.min_element() >= 0.0);
        if let LightKind::Spot { inner, outer } = l.kind {
            assert!(0.0 <= inner && inner < outer && outer <= std::f32::consts::FRAC_PI_2);
        }
    }
    for c in &scene.orthographic_cameras {
        assert!(c.position.is_finite() && c.forward.is_normalized() && c.ymag > 0.0);
    }
    if scene.triangles.len() <= 4096 {
        let packed = raygun::trace::pack::PackedScene::new(&scene);
        assert!(packed.light_count as usize <= scene.triangles.len());
    }
    for c in &scene.cameras {
        assert!(c.position.is_finite() && c.forward.is_normalized() && c.up.is_normalized());
        assert!(c.forward.dot(c.up).abs() < 1e-3);
        assert!(c.yfov > 0.0 && c.yfov < std::f32::consts::PI);
    }
});
