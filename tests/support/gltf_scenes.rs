//! glTF-feature scenes built in code (tests/scene/gltf_features.rs, tests/twins/trace.rs).

#![allow(dead_code)]

use glam::{Vec2, Vec3, Vec4};
use raygun::scene::{
    AlphaMode, Camera, Environment, LightKind, Material, MaterialExt, OrthographicCamera,
    PunctualLight, Sampler, Scene, Texture, TextureRef, Triangle, UvMap, UvTransform, VertexExtras,
    Wrap,
};

pub fn material(
    base: Vec3,
    metallic: f32,
    roughness: f32,
    specular: f32,
    emission: Vec3,
) -> Material {
    Material {
        name: "m".into(),
        base_color: base.extend(1.0),
        base_color_texture: None,
        metallic,
        roughness,
        specular,
        emission,
        double_sided: true,
    }
}

pub fn flat(p: [Vec3; 3], uv: [Vec2; 3], material: u32) -> Triangle {
    let n = (p[1] - p[0]).cross(p[2] - p[0]).normalize();
    Triangle {
        p,
        n: [n; 3],
        uv,
        material,
    }
}

/// An axis-aligned rectangle in the plane z = `z` from (x0, y0) to (x1, y1), facing +Z, with
/// glTF texture coordinates (u along +x, v = 0 at the top edge).
pub fn rect(x0: f32, y0: f32, x1: f32, y1: f32, z: f32, material: u32) -> Vec<Triangle> {
    let (a, b, c, d) = (
        Vec3::new(x0, y0, z),
        Vec3::new(x1, y0, z),
        Vec3::new(x1, y1, z),
        Vec3::new(x0, y1, z),
    );
    let (ua, ub, uc, ud) = (
        Vec2::new(0.0, 1.0),
        Vec2::new(1.0, 1.0),
        Vec2::new(1.0, 0.0),
        Vec2::new(0.0, 0.0),
    );
    vec![
        flat([a, b, c], [ua, ub, uc], material),
        flat([a, c, d], [ua, uc, ud], material),
    ]
}

pub fn texture(name: &str, width: u32, height: u32, texels: Vec<[u8; 4]>, srgb: bool) -> Texture {
    Texture {
        name: name.into(),
        width,
        height,
        texels,
        sampler: Sampler {
            wrap_s: Wrap::ClampToEdge,
            wrap_t: Wrap::ClampToEdge,
            nearest: true,
        },
        srgb,
    }
}

pub fn tex_ref(texture: u32) -> Option<TextureRef> {
    Some(TextureRef {
        texture,
        uv: UvMap::default(),
    })
}

pub fn ortho(position: Vec3, ymag: f32) -> OrthographicCamera {
    OrthographicCamera {
        name: "ortho".into(),
        position,
        forward: Vec3::NEG_Z,
        up: Vec3::Y,
        ymag,
    }
}

/// One scene with every one of these features: textures with transforms, wrap modes and both
/// filters, TEXCOORD_1, vertex colours, a normal map, a metallic-roughness map, an emissive
/// texture, MASK (a diffusely transmitting leaf) and BLEND, rough and smooth glass (the rough one brushed and absorbing behind
/// it, the smooth one dispersive), a brushed metal with a clear coat over a sheen, specular colour, the
/// extensions' textures (transmission, specular, specular colour, coat, coat roughness, coat
/// normal, sheen colour, sheen roughness, anisotropy), point, spot and directional lights and an
/// environment.
pub fn everything() -> Scene {
    let mut tris = Vec::new();
    tris.extend(rect(-2.0, -2.0, 2.0, 2.0, -1.0, 0)); // back wall: textured, vertex colours
    tris.extend(rect(-1.8, -1.8, -0.6, -0.6, -0.5, 1)); // normal + MR map, clear coat
    tris.extend(rect(-0.4, -1.8, 0.8, -0.6, -0.5, 2)); // emissive texture, uv1
    tris.extend(rect(-1.5, 0.2, -0.3, 1.4, -0.3, 3)); // MASK
    tris.extend(rect(0.3, 0.2, 1.5, 1.4, -0.3, 4)); // BLEND
    tris.extend(rect(-1.0, -1.0, 0.0, 0.0, 0.2, 5)); // rough glass
    tris.extend(rect(0.1, -0.3, 1.1, 0.7, 0.3, 6)); // smooth glass, specular colour
    let n = tris.len();
    let mut extras = vec![VertexExtras::default(); n];
    for (i, e) in extras.iter_mut().enumerate() {
        let t = &tris[i];
        e.color =
            t.p.map(|p| Vec4::new(0.5 + 0.25 * p.x, 0.5 + 0.25 * p.y, 0.8, 1.0));
        e.uv1 = t.uv.map(|uv| Vec2::new(uv.y, uv.x) * 2.0);
        e.tangent = [Vec4::new(1.0, 0.0, 0.0, 1.0); 3];
    }
    let checker: Vec<[u8; 4]> = (0..64)
        .map(|i| {
            let (x, y) = (i % 8, i / 8);
            if (x + y) % 2 == 0 {
                [230, 200, 40, 255]
            } else {
                [30, 90, 200, 120]
            }
        })
        .collect();
    let bumps: Vec<[u8; 4]> = (0..16)
        .map(|i| [128 + 60 * (i % 2) as u8, 128, 220, 255])
        .collect();
    let mr: Vec<[u8; 4]> = (0..4)
        .map(|i| [255, 60 * i as u8, 255 - 50 * i as u8, 255])
        .collect();
    let glow: Vec<[u8; 4]> = (0..4)
        .map(|i| {
            if i % 3 == 0 {
                [255, 180, 90, 255]
            } else {
                [0, 0, 0, 255]
            }
        })
        .collect();
    let tex = |name, w, h, texels, wrap, nearest, srgb| Texture {
        name,
        width: w,
        height: h,
        texels,
        sampler: Sampler {
            wrap_s: wrap,
            wrap_t: Wrap::MirroredRepeat,
            nearest,
        },
        srgb,
    };
    let textures = vec![
        tex(
            "checker".to_string(),
            8,
            8,
            checker.clone(),
            Wrap::Repeat,
            false,
            true,
        ),
        tex("bumps".to_string(), 4, 4, bumps, Wrap::Repeat, false, false),
        tex("mr".to_string(), 2, 2, mr, Wrap::ClampToEdge, true, false),
        tex(
            "glow".to_string(),
            2,
            2,
            glow,
            Wrap::MirroredRepeat,
            true,
            true,
        ),
        tex(
            "cutout".to_string(),
            8,
            8,
            checker,
            Wrap::ClampToEdge,
            true,
            true,
        ),
    ];
    let transformed = |texture, tex_coord| {
        Some(TextureRef {
            texture,
            uv: UvMap {
                tex_coord,
                transform: UvTransform {
                    offset: Vec2::new(0.1, -0.2),
                    rotation: 0.4,
                    scale: Vec2::new(1.5, 0.75),
                },
            },
        })
    };
    let m = |base: Vec3, metallic, roughness| material(base, metallic, roughness, 1.0, Vec3::ZERO);
    let materials = vec![
        Material {
            base_color_texture: Some(0),
            ..m(Vec3::splat(0.9), 0.0, 0.7)
        },
        m(Vec3::new(0.8, 0.3, 0.2), 0.5, 0.6),
        Material {
            emission: Vec3::splat(4.0),
            ..m(Vec3::splat(0.2), 0.0, 0.5)
        },
        Material {
            base_color_texture: Some(4),
            ..m(Vec3::splat(0.8), 0.0, 0.4)
        },
        Material {
            base_color: Vec4::new(0.2, 0.8, 0.3, 0.4),
            ..m(Vec3::ONE, 0.0, 0.4)
        },
        m(Vec3::new(0.9, 0.95, 1.0), 0.0, 0.25),
        m(Vec3::ONE, 0.0, 0.0),
    ];
    let material_ext = vec![
        MaterialExt {
            base_color_uv: transformed(0, 1).unwrap().uv,
            ..Default::default()
        },
        MaterialExt {
            normal_texture: transformed(1, 0),
            normal_scale: 0.8,
            metallic_roughness_texture: tex_ref(2),
            clearcoat: 0.8,
            clearcoat_roughness: 0.1,
            // The coat's strength from the bumps' red, its roughness from the MR map's green.
            clearcoat_texture: transformed(1, 1),
            clearcoat_roughness_texture: tex_ref(2),
            // Its own normal map: the bumps again, on the other set, at another scale.
            clearcoat_normal_texture: transformed(1, 1),
            clearcoat_normal_scale: 0.6,
            // A sheen beneath the coat: its colour × the glow's RGB (sRGB), its roughness × the
            // checker's alpha.
            sheen_color: Vec3::new(0.9, 0.6, 0.3),
            sheen_roughness: 0.5,
            sheen_color_texture: tex_ref(3),
            sheen_roughness_texture: transformed(0, 1),
            // Brushed: the direction rotated by 0.6 rad and by the bumps' RG, its strength × B.
            anisotropy_strength: 0.7,
            anisotropy_rotation: 0.6,
            anisotropy_texture: transformed(1, 0),
            ..Default::default()
        },
        MaterialExt {
            emissive_texture: transformed(3, 1),
            ..Default::default()
        },
        MaterialExt {
            alpha: AlphaMode::Mask(0.5),
            // A cut-out leaf (KHR_materials_diffuse_transmission): its strength × the bumps'
            // alpha, its colour × the glow's RGB (sRGB).
            diffuse_transmission: 0.6,
            diffuse_transmission_color: Vec3::new(0.9, 0.5, 0.2),
            diffuse_transmission_texture: transformed(1, 1),
            diffuse_transmission_color_texture: tex_ref(3),
            ..Default::default()
        },
        MaterialExt {
            alpha: AlphaMode::Blend,
            ..Default::default()
        },
        MaterialExt {
            transmission: 1.0,
            ior: 1.45,
            // A medium behind it (KHR_materials_volume): rays that meet it from behind are
            // attenuated by the length they travelled. Brushed (anisotropic refraction).
            absorption: Vec3::new(0.8, 0.3, 1.5),
            anisotropy_strength: 0.5,
            ..Default::default()
        },
        MaterialExt {
            transmission: 0.9,
            ior: 1.6,
            specular_color: Vec3::new(1.0, 0.7, 0.4),
            // Transmission × the bumps' red, specular × the checker's alpha, the specular
            // colour × the glow's RGB (sRGB).
            transmission_texture: transformed(1, 0),
            specular_texture: transformed(0, 0),
            specular_color_texture: tex_ref(3),
            // Dispersive (KHR_materials_dispersion): a path through it follows one channel.
            dispersion: 0.8,
            ..Default::default()
        },
    ];
    let light = |kind, position: Vec3, direction: Vec3, intensity: Vec3| PunctualLight {
        name: "l".into(),
        kind,
        position,
        direction: direction.normalize(),
        intensity,
    };
    Scene {
        triangles: tris,
        materials,
        material_ext,
        vertex_extras: extras,
        textures,
        lights: vec![
            light(
                LightKind::Point,
                Vec3::new(1.5, 1.5, 1.5),
                Vec3::NEG_Z,
                Vec3::splat(3.0),
            ),
            light(
                LightKind::Spot {
                    inner: 0.2,
                    outer: 0.5,
                },
                Vec3::new(-1.0, 0.5, 2.0),
                Vec3::new(0.3, -0.3, -1.0),
                Vec3::new(8.0, 6.0, 4.0),
            ),
            light(
                LightKind::Directional,
                Vec3::ZERO,
                Vec3::new(-0.3, -0.4, -1.0),
                Vec3::splat(0.7),
            ),
        ],
        cameras: vec![Camera {
            name: "front".into(),
            position: Vec3::new(0.0, 0.0, 4.0),
            forward: Vec3::NEG_Z,
            up: Vec3::Y,
            yfov: 50f32.to_radians(),
        }],
        environment: Environment::Constant(Vec3::new(0.2, 0.25, 0.3)),
        ..Default::default()
    }
}
