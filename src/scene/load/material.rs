//! glTF materials → [`Material`] and [`MaterialExt`]: the core factors, the extensions raygun
//! shades (clear coat, sheen, diffuse transmission, anisotropy, transmission, IOR, volume,
//! dispersion, specular, emissive strength) and their texture references.

use glam::{Vec2, Vec3, Vec4};

use super::super::report::{Report, SceneError, label};
use super::super::{AlphaMode, Material, MaterialExt, TextureRef, UvMap, UvTransform};
use super::{Converted, Loader, MAX_ABSORPTION};

impl Loader<'_> {
    /// Number `key` of an extension given as JSON (`default` where absent); anything else is
    /// an error naming the material and the key.
    fn json_number(
        &self,
        element: &str,
        ext: &serde_json::Value,
        key: &str,
        default: f64,
    ) -> Result<f64, SceneError> {
        match ext.get(key) {
            None => Ok(default),
            Some(v) => v.as_f64().ok_or_else(|| {
                self.element_error(element.to_string(), format!("{key} {v} is not a number"))
            }),
        }
    }

    /// Three numbers `key` of an extension given as JSON (`default` where absent); anything
    /// else is an error naming the element.
    fn json_rgb(
        &self,
        element: &str,
        ext: &serde_json::Value,
        key: &str,
        default: [f64; 3],
    ) -> Result<[f64; 3], SceneError> {
        let Some(v) = ext.get(key) else {
            return Ok(default);
        };
        let numbers: Option<Vec<f64>> = v
            .as_array()
            .filter(|a| a.len() == 3)
            .and_then(|a| a.iter().map(serde_json::Value::as_f64).collect());
        numbers.map(|c| [c[0], c[1], c[2]]).ok_or_else(|| {
            self.element_error(
                element.to_string(),
                format!("{key} {v} is not three numbers"),
            )
        })
    }

    /// KHR_materials_volume's absorption coefficient (`MaterialExt::absorption`): the medium
    /// behind a surface of thickness > 0 absorbs −ln(attenuationColor) / attenuationDistance per
    /// unit length; a thin-walled one (thicknessFactor 0, the default) bounds no medium. The
    /// thickness itself is for renderers that cannot trace the mesh: a path tracer measures the
    /// distance a ray travels inside, so thicknessTexture is noted and not used.
    fn absorption(
        &mut self,
        element: &str,
        v: &gltf::material::Volume<'_>,
    ) -> Result<Vec3, SceneError> {
        let problem = |what: String| {
            self.element_error(element.to_string(), format!("KHR_materials_volume: {what}"))
        };
        let thickness = v.thickness_factor();
        if !(thickness.is_finite() && thickness >= 0.0) {
            return Err(problem(format!(
                "thicknessFactor {thickness} is not a finite number ≥ 0"
            )));
        }
        let distance = v.attenuation_distance();
        if !(distance > 0.0) {
            return Err(problem(format!(
                "attenuationDistance {distance} is not a number > 0"
            )));
        }
        // (JSON numbers beyond f32's range are refused by the parser, so these are finite.)
        let given = v.attenuation_color();
        let color = given.map(|c| c.clamp(0.0, 1.0));
        if color != given {
            self.report.warn(format!(
                "{element}: KHR_materials_volume attenuationColor {given:?} clamped to [0, 1]"
            ));
        }
        if v.thickness_texture().is_some() {
            self.report.note(format!(
                "thicknessTexture ({element}) not used: the path tracer measures the distance \
                 light travels inside the mesh"
            ));
        }
        let absorbs = distance < f32::INFINITY && color.iter().any(|&c| c < 1.0);
        if thickness == 0.0 {
            if absorbs {
                self.report.note(format!(
                    "{element}: KHR_materials_volume with thicknessFactor 0 is thin-walled: \
                     its attenuation does not apply"
                ));
            }
            return Ok(Vec3::ZERO);
        }
        // σ = −ln(c)/d per channel; a black channel absorbs everything within any length
        // (capped to stay finite for the shaders: exp(−σt) is 0 for every t a hit can have).
        Ok(Vec3::from(color.map(|c| {
            if c >= 1.0 || distance == f32::INFINITY {
                0.0
            } else {
                (-c.ln() / distance).min(MAX_ABSORPTION)
            }
        })))
    }

    /// The scene material for a glTF material (None: glTF's default material), converted once.
    pub(super) fn material(&mut self, m: gltf::Material) -> Result<Converted, SceneError> {
        let key = m.index();
        if let Some(&c) = self.materials.get(&key) {
            return Ok(c);
        }
        let (converted, ext) = match key {
            Some(_) => self.convert_material(&m)?,
            None => (Material::default(), MaterialExt::default()),
        };
        let c = Converted {
            index: self.scene.materials.len() as u32,
            // Tangents for the base's normal map, else for the coat's, else for the anisotropy
            // texture's (on its set), else TEXCOORD_0's for an anisotropy without one.
            normal_uv: ext
                .normal_texture
                .or(ext.clearcoat_normal_texture)
                .or(ext.anisotropy_texture)
                .map(|t| t.uv.tex_coord)
                .or((ext.anisotropy_strength > 0.0).then_some(0)),
        };
        self.scene.materials.push(converted);
        self.material_ext.push(ext);
        self.materials.insert(key, c);
        Ok(c)
    }

    /// A texture reference: its scene texture (None where it cannot be used, reported) and UVs.
    fn texture_ref(
        &mut self,
        element: &str,
        what: &str,
        tex: &gltf::Texture,
        uv: UvMap,
        srgb: bool,
    ) -> Result<Option<TextureRef>, SceneError> {
        if uv.tex_coord > 1 {
            self.report.unsupported(format!(
                "texCoord {} ({element} {what}; only TEXCOORD_0 and TEXCOORD_1 are read, the factor is used)",
                uv.tex_coord
            ));
            return Ok(None);
        }
        let texture = self.res.texture(
            self.doc,
            tex,
            srgb,
            &mut self.scene.textures,
            &mut self.report,
        )?;
        Ok(texture.map(|texture| TextureRef { texture, uv }))
    }

    /// [`Self::texture_ref`] for a glTF texture info, where there is one.
    fn info_ref(
        &mut self,
        element: &str,
        what: &str,
        info: Option<gltf::texture::Info>,
        srgb: bool,
    ) -> Result<Option<TextureRef>, SceneError> {
        match info {
            Some(info) => self.texture_ref(element, what, &info.texture(), info_uv(&info), srgb),
            None => Ok(None),
        }
    }

    /// A texture reference an extension gives as JSON (`{"index", "texCoord", "extensions":
    /// {"KHR_texture_transform"}}`: the gltf crate has no typed form for it), read as data
    /// (colour data in sRGB where `srgb`). None where `info` is absent or the texture cannot be
    /// used (reported); an index that names no texture is an error naming the material and the
    /// key.
    fn json_texture_ref(
        &mut self,
        element: &str,
        what: &str,
        info: Option<&serde_json::Value>,
        srgb: bool,
    ) -> Result<Option<TextureRef>, SceneError> {
        let Some(info) = info else {
            return Ok(None);
        };
        let count = self.doc.textures().len();
        let index = info.get("index").and_then(serde_json::Value::as_u64);
        let Some(tex) = index.and_then(|i| self.doc.textures().nth(usize::try_from(i).ok()?))
        else {
            let index = info
                .get("index")
                .map_or("missing".into(), ToString::to_string);
            return Err(self.element_error(
                element.to_string(),
                format!("{what}: index {index} names no texture (the file has {count})"),
            ));
        };
        let tex_coord = match info.get("texCoord") {
            None => 0,
            Some(v) => match v.as_u64() {
                Some(c) => c.min(u64::from(u32::MAX)) as u32,
                None => {
                    return Err(self.element_error(
                        element.to_string(),
                        format!("{what}: texCoord {v} is not a number ≥ 0"),
                    ));
                }
            },
        };
        let uv = texture_transform(
            info.get("extensions")
                .and_then(|e| e.get("KHR_texture_transform")),
            tex_coord,
        );
        self.texture_ref(element, what, &tex, uv, srgb)
    }

    /// A glTF material's scene material and extended features: the core factors, then each
    /// extension and texture in turn (the order in which textures are added to the scene and
    /// problems reported).
    fn convert_material(
        &mut self,
        m: &gltf::Material,
    ) -> Result<(Material, MaterialExt), SceneError> {
        let index = m.index().unwrap_or(0);
        let element = label("material", m.name(), index);
        let name = m
            .name()
            .map_or_else(|| format!("material {index}"), str::to_string);
        let pbr = m.pbr_metallic_roughness();
        let file = self.file;
        let factor =
            |report: &mut Report, what: &str, v: f32| unit_factor(file, &element, report, what, v);
        let r = &mut self.report;
        let bc = pbr.base_color_factor();
        let base_color = Vec4::new(
            factor(r, "baseColorFactor", bc[0])?,
            factor(r, "baseColorFactor", bc[1])?,
            factor(r, "baseColorFactor", bc[2])?,
            factor(r, "baseColorFactor", bc[3])?,
        );
        let metallic = factor(r, "metallicFactor", pbr.metallic_factor())?;
        let roughness = factor(r, "roughnessFactor", pbr.roughness_factor())?;
        let ef = m.emissive_factor();
        let emissive = Vec3::new(
            factor(r, "emissiveFactor", ef[0])?,
            factor(r, "emissiveFactor", ef[1])?,
            factor(r, "emissiveFactor", ef[2])?,
        );
        let mut ext = MaterialExt::default();
        self.clearcoat(m, &element, &mut ext)?;
        self.sheen(m, &element, &mut ext)?;
        self.diffuse_transmission(m, &element, &mut ext)?;
        self.anisotropy(m, &element, &mut ext)?;
        self.transmission(m, &element, &mut ext)?;
        let strength = m.emissive_strength().unwrap_or(1.0);
        if !(strength >= 0.0 && strength.is_finite()) {
            return Err(self.element_error(
                element,
                format!("emissiveStrength {strength} is not a finite number ≥ 0"),
            ));
        }
        ext.alpha = match m.alpha_mode() {
            gltf::material::AlphaMode::Opaque => AlphaMode::Opaque,
            gltf::material::AlphaMode::Blend => AlphaMode::Blend,
            gltf::material::AlphaMode::Mask => {
                let cutoff = m.alpha_cutoff().unwrap_or(0.5);
                if !cutoff.is_finite() || cutoff < 0.0 {
                    return Err(self.element_error(
                        element,
                        format!("alphaCutoff {cutoff} is not a finite number ≥ 0"),
                    ));
                }
                AlphaMode::Mask(cutoff)
            }
        };
        let base_color_texture = self.core_textures(m, &element, &mut ext)?;
        let specular = self.specular(m, &element, &mut ext)?;
        let emission = if m.emissive_texture().is_some() && ext.emissive_texture.is_none() {
            Vec3::ZERO
        } else {
            emissive * strength
        };
        Ok((
            Material {
                name,
                base_color,
                base_color_texture,
                metallic,
                roughness,
                specular,
                emission,
                double_sided: m.double_sided(),
            },
            ext,
        ))
    }

    /// KHR_materials_clearcoat, given as JSON (the gltf crate has no typed form for it).
    fn clearcoat(
        &mut self,
        m: &gltf::Material,
        element: &str,
        ext: &mut MaterialExt,
    ) -> Result<(), SceneError> {
        let Some(c) = m.extension_value("KHR_materials_clearcoat") else {
            return Ok(());
        };
        let file = self.file;
        let factor =
            |report: &mut Report, what: &str, v: f32| unit_factor(file, element, report, what, v);
        let r = &mut self.report;
        let get = |key: &str| c.get(key).and_then(serde_json::Value::as_f64);
        ext.clearcoat = factor(
            r,
            "clearcoatFactor",
            get("clearcoatFactor").unwrap_or(0.0) as f32,
        )?;
        ext.clearcoat_roughness = factor(
            r,
            "clearcoatRoughnessFactor",
            get("clearcoatRoughnessFactor").unwrap_or(0.0) as f32,
        )?;
        ext.clearcoat_texture = self.json_texture_ref(
            element,
            "clearcoatTexture",
            c.get("clearcoatTexture"),
            false,
        )?;
        ext.clearcoat_roughness_texture = self.json_texture_ref(
            element,
            "clearcoatRoughnessTexture",
            c.get("clearcoatRoughnessTexture"),
            false,
        )?;
        let normal = c.get("clearcoatNormalTexture");
        ext.clearcoat_normal_texture =
            self.json_texture_ref(element, "clearcoatNormalTexture", normal, false)?;
        let scale = normal.and_then(|n| n.get("scale"));
        ext.clearcoat_normal_scale = match scale {
            None => 1.0,
            Some(v) => match v.as_f64().map(|s| s as f32).filter(|s| s.is_finite()) {
                Some(s) => s,
                None => {
                    return Err(self.element_error(
                        element.to_owned(),
                        format!("clearcoatNormalTexture: scale {v} is not a finite number"),
                    ));
                }
            },
        };
        Ok(())
    }

    /// KHR_materials_sheen (JSON to the gltf crate, as the clear coat is).
    fn sheen(
        &mut self,
        m: &gltf::Material,
        element: &str,
        ext: &mut MaterialExt,
    ) -> Result<(), SceneError> {
        let Some(sh) = m.extension_value("KHR_materials_sheen") else {
            return Ok(());
        };
        let file = self.file;
        let factor =
            |report: &mut Report, what: &str, v: f32| unit_factor(file, element, report, what, v);
        let colour = self.json_rgb(element, sh, "sheenColorFactor", [0.0; 3])?;
        let roughness = self.json_number(element, sh, "sheenRoughnessFactor", 0.0)?;
        let r = &mut self.report;
        ext.sheen_color = Vec3::new(
            factor(r, "sheenColorFactor", colour[0] as f32)?,
            factor(r, "sheenColorFactor", colour[1] as f32)?,
            factor(r, "sheenColorFactor", colour[2] as f32)?,
        );
        ext.sheen_roughness = factor(r, "sheenRoughnessFactor", roughness as f32)?;
        ext.sheen_color_texture = self.json_texture_ref(
            element,
            "sheenColorTexture",
            sh.get("sheenColorTexture"),
            true,
        )?;
        ext.sheen_roughness_texture = self.json_texture_ref(
            element,
            "sheenRoughnessTexture",
            sh.get("sheenRoughnessTexture"),
            false,
        )?;
        Ok(())
    }

    /// KHR_materials_diffuse_transmission (JSON to the gltf crate, as the clear coat is).
    fn diffuse_transmission(
        &mut self,
        m: &gltf::Material,
        element: &str,
        ext: &mut MaterialExt,
    ) -> Result<(), SceneError> {
        let Some(dt) = m.extension_value("KHR_materials_diffuse_transmission") else {
            return Ok(());
        };
        let file = self.file;
        let factor =
            |report: &mut Report, what: &str, v: f32| unit_factor(file, element, report, what, v);
        let strength = self.json_number(element, dt, "diffuseTransmissionFactor", 0.0)?;
        let colour = self.json_rgb(element, dt, "diffuseTransmissionColorFactor", [1.0; 3])?;
        let r = &mut self.report;
        ext.diffuse_transmission = factor(r, "diffuseTransmissionFactor", strength as f32)?;
        ext.diffuse_transmission_color = Vec3::new(
            factor(r, "diffuseTransmissionColorFactor", colour[0] as f32)?,
            factor(r, "diffuseTransmissionColorFactor", colour[1] as f32)?,
            factor(r, "diffuseTransmissionColorFactor", colour[2] as f32)?,
        );
        ext.diffuse_transmission_texture = self.json_texture_ref(
            element,
            "diffuseTransmissionTexture",
            dt.get("diffuseTransmissionTexture"),
            false,
        )?;
        ext.diffuse_transmission_color_texture = self.json_texture_ref(
            element,
            "diffuseTransmissionColorTexture",
            dt.get("diffuseTransmissionColorTexture"),
            true,
        )?;
        Ok(())
    }

    /// KHR_materials_anisotropy (JSON to the gltf crate, as the clear coat is).
    fn anisotropy(
        &mut self,
        m: &gltf::Material,
        element: &str,
        ext: &mut MaterialExt,
    ) -> Result<(), SceneError> {
        let Some(an) = m.extension_value("KHR_materials_anisotropy") else {
            return Ok(());
        };
        let strength = self.json_number(element, an, "anisotropyStrength", 0.0)?;
        let rotation = self.json_number(element, an, "anisotropyRotation", 0.0)? as f32;
        if !rotation.is_finite() {
            return Err(self.element_error(
                element.to_owned(),
                format!("anisotropyRotation {rotation} is not finite"),
            ));
        }
        ext.anisotropy_strength = unit_factor(
            self.file,
            element,
            &mut self.report,
            "anisotropyStrength",
            strength as f32,
        )?;
        ext.anisotropy_rotation = rotation;
        ext.anisotropy_texture = self.json_texture_ref(
            element,
            "anisotropyTexture",
            an.get("anisotropyTexture"),
            false,
        )?;
        Ok(())
    }

    /// What light passing through the surface meets: KHR_materials_transmission, _ior,
    /// _volume and _dispersion.
    fn transmission(
        &mut self,
        m: &gltf::Material,
        element: &str,
        ext: &mut MaterialExt,
    ) -> Result<(), SceneError> {
        if let Some(t) = m.transmission() {
            ext.transmission = unit_factor(
                self.file,
                element,
                &mut self.report,
                "transmissionFactor",
                t.transmission_factor(),
            )?;
            ext.transmission_texture = self.info_ref(
                element,
                "transmissionTexture",
                t.transmission_texture(),
                false,
            )?;
        }
        if let Some(ior) = m.ior() {
            // glTF: ior ≥ 1, or 0 for "reflects like a metal" (F0 = 1); raygun needs a
            // refracting interface, so 0 and values under 1 are clamped and said.
            ext.ior = if ior.is_finite() && ior >= 1.0 {
                ior.min(10.0)
            } else {
                self.report
                    .warn(format!("{element}: ior {ior} replaced by 1.5"));
                1.5
            };
        }
        if let Some(v) = m.volume() {
            ext.absorption = self.absorption(element, &v)?;
        }
        if let Some(dp) = m.extension_value("KHR_materials_dispersion") {
            // (JSON to the gltf crate, as the clear coat is.) raygun refracts every
            // transmitting surface, with or without KHR_materials_volume, so the dispersion
            // applies wherever light is transmitted.
            let d = self.json_number(element, dp, "dispersion", 0.0)? as f32;
            if !(d.is_finite() && d >= 0.0) {
                // (The file's own number: beyond f32's range it would read "inf".)
                let given = &dp["dispersion"];
                return Err(self.element_error(
                    element.to_owned(),
                    format!(
                        "KHR_materials_dispersion: dispersion {given} is not a finite number ≥ 0"
                    ),
                ));
            }
            if d > 0.0 && ext.transmission == 0.0 {
                self.report.note(format!(
                    "{element}: KHR_materials_dispersion without transmission changes nothing \
                     (only refracted light is dispersed)"
                ));
            } else {
                ext.dispersion = d;
            }
        }
        Ok(())
    }

    /// The core textures but the specular ones: normal, occlusion (not used, said), emissive,
    /// metallic-roughness and base colour (returned; its UVs go to `ext`).
    fn core_textures(
        &mut self,
        m: &gltf::Material,
        element: &str,
        ext: &mut MaterialExt,
    ) -> Result<Option<u32>, SceneError> {
        let pbr = m.pbr_metallic_roughness();
        if let Some(t) = m.normal_texture() {
            // The gltf crate has no typed transform for normal textures: read its JSON.
            let uv = texture_transform(t.extension_value("KHR_texture_transform"), t.tex_coord());
            ext.normal_texture =
                self.texture_ref(element, "normalTexture", &t.texture(), uv, false)?;
            let s = t.scale();
            ext.normal_scale = if s.is_finite() { s } else { 1.0 };
        }
        if m.occlusion_texture().is_some() {
            self.report.note(format!(
                "occlusionTexture ({element}) not used: the path tracer computes occlusion"
            ));
        }
        if let Some(t) = m.emissive_texture() {
            ext.emissive_texture =
                self.texture_ref(element, "emissiveTexture", &t.texture(), info_uv(&t), true)?;
            if ext.emissive_texture.is_none() {
                // The factor alone would turn the whole mesh into a lamp; what the texture
                // leaves dark is the usual case (exporters write factor 1 beside the texture).
                self.report.warn(format!(
                    "{element}: its emissive texture cannot be used; the material does not emit"
                ));
            }
        }
        ext.metallic_roughness_texture = self.info_ref(
            element,
            "metallicRoughnessTexture",
            pbr.metallic_roughness_texture(),
            false,
        )?;
        Ok(match pbr.base_color_texture() {
            Some(info) => {
                let r = self.texture_ref(
                    element,
                    "baseColorTexture",
                    &info.texture(),
                    info_uv(&info),
                    true,
                )?;
                if let Some(r) = r {
                    ext.base_color_uv = r.uv;
                }
                r.map(|r| r.texture)
            }
            None => None,
        })
    }

    /// KHR_materials_specular: the factor (returned) scales the dielectric Fresnel term, the
    /// colour tints its F0 (the tracer's BSDF); its textures multiply them (A and RGB).
    fn specular(
        &mut self,
        m: &gltf::Material,
        element: &str,
        ext: &mut MaterialExt,
    ) -> Result<f32, SceneError> {
        let mut specular = 1.0;
        if let Some(sp) = m.specular() {
            let f = sp.specular_factor();
            specular = if f.is_finite() {
                f.clamp(0.0, 1.0)
            } else {
                1.0
            };
            let c = Vec3::from_array(sp.specular_color_factor());
            ext.specular_color = if c.is_finite() {
                c.clamp(Vec3::ZERO, Vec3::splat(10.0))
            } else {
                Vec3::ONE
            };
            ext.specular_texture =
                self.info_ref(element, "specularTexture", sp.specular_texture(), false)?;
            ext.specular_color_texture = self.info_ref(
                element,
                "specularColorTexture",
                sp.specular_color_texture(),
                true,
            )?;
        }
        Ok(specular)
    }
}

/// A texture info's texture coordinates: its texCoord, or KHR_texture_transform's override,
/// and the transform (non-finite values are the identity's).
fn info_uv(info: &gltf::texture::Info) -> UvMap {
    let Some(t) = info.texture_transform() else {
        return UvMap {
            tex_coord: info.tex_coord(),
            transform: UvTransform::default(),
        };
    };
    let finite2 = |v: [f32; 2], d: Vec2| {
        let v = Vec2::from_array(v);
        if v.is_finite() { v } else { d }
    };
    UvMap {
        tex_coord: t.tex_coord().unwrap_or(info.tex_coord()),
        transform: UvTransform {
            offset: finite2(t.offset(), Vec2::ZERO),
            rotation: if t.rotation().is_finite() {
                t.rotation()
            } else {
                0.0
            },
            scale: finite2(t.scale(), Vec2::ONE),
        },
    }
}

/// KHR_texture_transform of a texture reference (its JSON), and the texCoord it overrides.
fn texture_transform(ext: Option<&serde_json::Value>, tex_coord: u32) -> UvMap {
    let Some(t) = ext else {
        return UvMap {
            tex_coord,
            transform: UvTransform::default(),
        };
    };
    let pair = |key: &str, default: Vec2| {
        t.get(key)
            .and_then(|v| v.as_array())
            .and_then(|a| {
                Some(Vec2::new(
                    a.first()?.as_f64()? as f32,
                    a.get(1)?.as_f64()? as f32,
                ))
            })
            .filter(|v| v.is_finite())
            .unwrap_or(default)
    };
    let rotation = t
        .get("rotation")
        .and_then(serde_json::Value::as_f64)
        .map(|r| r as f32)
        .filter(|r| r.is_finite())
        .unwrap_or(0.0);
    UvMap {
        tex_coord: t
            .get("texCoord")
            .and_then(serde_json::Value::as_u64)
            .map_or(tex_coord, |c| c.min(u64::from(u32::MAX)) as u32),
        transform: UvTransform {
            offset: pair("offset", Vec2::ZERO),
            rotation,
            scale: pair("scale", Vec2::ONE),
        },
    }
}

/// A factor of `element` that glTF bounds to [0, 1]: clamped (and the clamp reported) where
/// outside, an error naming it where not finite.
fn unit_factor(
    file: &str,
    element: &str,
    report: &mut Report,
    what: &str,
    v: f32,
) -> Result<f32, SceneError> {
    if !v.is_finite() {
        return Err(SceneError::Element {
            file: file.into(),
            element: element.to_owned(),
            problem: format!("{what} {v} is not finite"),
        });
    }
    let c = v.clamp(0.0, 1.0);
    if c != v {
        report.warn(format!("{element}: {what} {v} clamped to [0, 1]"));
    }
    Ok(c)
}
