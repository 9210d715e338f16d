"""glTF 2.0's metallic-roughness BSDF as a Mitsuba 3 plugin (`"type": "gltf"`), the same
formulas as raygun's `src/trace/shading.rs`:

    f = (1 - m)(1 - F_d(v.h)) base / pi + F(v.h) D(h) V(i, o)
    F_d = 0.04 s + (s - 0.04 s)(1 - v.h)^5      (dielectric Schlick, KHR_materials_specular s)
    F_m = base + (1 - base)(1 - v.h)^5          (conductor Schlick)
    F   = mix(F_d, F_m, m)
    D   = GGX(alpha), V = height-correlated Smith visibility (G / (4 cos_i cos_o))

sampled like raygun: the specular lobe (GGX normals, D cos theta_h) with the probability
lum(F) / (lum(F) + lum(base)(1 - m)(1 - F_d)) at cos_o, else the cosine-weighted hemisphere;
the pdf is the mixture's. One-sided (wrap it in `twosided`).

This lets Mitsuba's integrator render raygun's materials exactly where Mitsuba has no
equivalent BSDF (glTF's dielectric layer: roughplastic is far off, check_bsdf.py). It is a
Python plugin, so it is meant for the vectorised variants (llvm_ad_rgb, cuda_ad_rgb): in
scalar_rgb every BSDF call goes through the Python interpreter and is far too slow for a
reference. `register()` must be called after `mi.set_variant`.
"""

from __future__ import annotations

import math

_REGISTERED: set[str] = set()


def register() -> None:
    import drjit as dr
    import mitsuba as mi

    variant = mi.variant()
    if variant in _REGISTERED:
        return

    def lum(c):
        return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]

    def pow5(x):
        x2 = x * x
        return x2 * x2 * x

    class GltfBSDF(mi.BSDF):
        def __init__(self, props):
            mi.BSDF.__init__(self, props)
            base = props.get("base_color", None)
            if base is None:
                base = [1.0, 1.0, 1.0]
            if not hasattr(base, "eval"):  # a colour value rather than a texture object
                base = mi.load_dict({"type": "rgb", "value": [float(base[i]) for i in range(3)]})
            self.base = base
            self.metallic = mi.Float(props.get("metallic", 1.0))
            self.alpha = mi.Float(max(props.get("alpha", 1.0), 1e-3))
            self.spec = mi.Float(props.get("specular", 1.0))
            flags = (mi.BSDFFlags.DiffuseReflection | mi.BSDFFlags.GlossyReflection
                     | mi.BSDFFlags.FrontSide)
            self.m_components = [flags]
            self.m_flags = flags

        def _fresnel(self, base, c):
            k = pow5(dr.maximum(1.0 - c, 0.0))
            fd = 0.04 * self.spec + (self.spec - 0.04 * self.spec) * k
            fm = base + (1.0 - base) * k
            return fd, dr.lerp(mi.Color3f(fd), fm, self.metallic)

        def _p_spec(self, base, cos_o):
            fd, f = self._fresnel(base, cos_o)
            ws = lum(f)
            wd = lum(base) * (1.0 - self.metallic) * (1.0 - fd)
            return dr.select(ws + wd > 0.0, ws / (ws + wd), 0.5)

        def _eval_pdf(self, si, wo, active):
            base = mi.Color3f(self.base.eval(si, active))
            wv = si.wi  # towards the viewer (raygun's wo)
            cos_o = mi.Frame3f.cos_theta(wv)
            cos_i = mi.Frame3f.cos_theta(wo)
            ok = active & (cos_o > 0.0) & (cos_i > 0.0)
            h = dr.normalize(wv + wo)
            noh = dr.maximum(h.z, 0.0)
            voh = dr.maximum(dr.dot(wv, h), 1e-7)
            fd, fresnel = self._fresnel(base, voh)
            a2 = self.alpha * self.alpha
            dd = noh * noh * (a2 - 1.0) + 1.0
            d = a2 / (math.pi * dd * dd)
            vis = 0.5 / (cos_i * dr.sqrt(cos_o * cos_o * (1.0 - a2) + a2)
                         + cos_o * dr.sqrt(cos_i * cos_i * (1.0 - a2) + a2))
            spec = fresnel * (d * vis)
            diff = base * ((1.0 - self.metallic) * (1.0 - fd) / math.pi)
            ps = self._p_spec(base, cos_o)
            pdf = ps * d * noh / (4.0 * voh) + (1.0 - ps) * cos_i / math.pi
            value = (diff + spec) * cos_i
            return dr.select(ok, value, 0.0), dr.select(ok, pdf, 0.0)

        def sample(self, ctx, si, sample1, sample2, active=True):
            base = mi.Color3f(self.base.eval(si, active))
            wv = si.wi
            cos_o = mi.Frame3f.cos_theta(wv)
            ps = self._p_spec(base, cos_o)
            a2 = self.alpha * self.alpha
            u, v = sample2.x, sample2.y
            cos_h = dr.sqrt(dr.maximum((1.0 - u) / (1.0 + (a2 - 1.0) * u), 0.0))
            sin_h = dr.sqrt(dr.maximum(1.0 - cos_h * cos_h, 0.0))
            phi = 2.0 * math.pi * v
            h = mi.Vector3f(sin_h * dr.cos(phi), sin_h * dr.sin(phi), cos_h)
            w_spec = 2.0 * dr.dot(wv, h) * h - wv
            w_diff = mi.warp.square_to_cosine_hemisphere(sample2)
            pick_spec = sample1 < ps
            wo = dr.select(pick_spec, w_spec, w_diff)
            value, pdf = self._eval_pdf(si, wo, active & (cos_o > 0.0))
            bs = dr.zeros(mi.BSDFSample3f)
            bs.wo = wo
            bs.pdf = pdf
            bs.eta = 1.0
            bs.sampled_type = mi.UInt32(dr.select(
                pick_spec, mi.UInt32(+mi.BSDFFlags.GlossyReflection),
                mi.UInt32(+mi.BSDFFlags.DiffuseReflection)))
            bs.sampled_component = 0
            ok = active & (pdf > 0.0) & (mi.Frame3f.cos_theta(wo) > 0.0)
            weight = dr.select(ok, value / dr.select(pdf > 0.0, pdf, 1.0), 0.0)
            return bs, weight

        def eval(self, ctx, si, wo, active=True):
            return self._eval_pdf(si, wo, active)[0]

        def pdf(self, ctx, si, wo, active=True):
            return self._eval_pdf(si, wo, active)[1]

        def eval_pdf(self, ctx, si, wo, active=True):
            return self._eval_pdf(si, wo, active)

        def traverse(self, callback):
            pass

        def parameters_changed(self, keys):
            pass

        def to_string(self):
            return "GltfBSDF[]"

    mi.register_bsdf("gltf", lambda props: GltfBSDF(props))
    _REGISTERED.add(variant)
