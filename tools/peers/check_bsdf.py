#!/usr/bin/env python3
"""Directional albedo of raygun's glTF BSDF against the Mitsuba BSDFs that scenes.py maps it
to, to state the material mapping's model error with numbers.

raygun's BSDF (src/trace/shading.rs) is re-implemented here in numpy and integrated by uniform
hemisphere sampling; Mitsuba's BSDFs are integrated with their own `sample` (llvm_ad_rgb if
available, else scalar_rgb with fewer samples). Prints albedo(theta_o) per material and the
relative difference, and F(cos) for the fitted conductors.

    python3 tools/peers/check_bsdf.py [--samples N]
"""

from __future__ import annotations

import argparse
import math
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import scenes  # noqa: E402


def gltf_eval(base, metallic, alpha, specular, wo, wi):
    """raygun's Bsdf::eval (value only) for n = +Z; wo (3,), wi (N, 3)."""
    cos_o, cos_i = wo[2], wi[:, 2]
    h = wo[None, :] + wi
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    noh = np.maximum(h[:, 2], 0)
    voh = np.maximum(h @ wo, 1e-7)
    k = np.maximum(1 - voh, 0) ** 5
    fd = 0.04 * specular + (specular - 0.04 * specular) * k
    base = np.asarray(base)[None, :]
    fm = base + (1 - base) * k[:, None]
    f = fd[:, None] + (fm - fd[:, None]) * metallic
    a2 = alpha * alpha
    dd = noh * noh * (a2 - 1) + 1
    d = a2 / (math.pi * dd * dd)
    vis = 0.5 / (cos_i * np.sqrt(cos_o**2 * (1 - a2) + a2) + cos_o * np.sqrt(cos_i**2 * (1 - a2) + a2))
    spec = f * (d * vis)[:, None]
    diff = base * ((1 - metallic) * (1 - fd) / math.pi)[:, None]
    return np.where((cos_i > 0)[:, None], diff + spec, 0)


def gltf_albedo(mat: scenes.Material, theta_o: float, n: int, rng) -> np.ndarray:
    """Directional albedo of raygun's BSDF by one-sample MIS: half the directions cosine-
    weighted, half from GGX normals (D cos theta_h), weighted by the mixture density."""
    wo = np.array([math.sin(theta_o), 0, math.cos(theta_o)])
    alpha = max(mat.roughness**2, scenes.MIN_ALPHA)
    a2 = alpha * alpha
    u1, u2, u3 = rng.random(n), rng.random(n), rng.random(n)
    phi = 2 * np.pi * u2
    # cosine hemisphere
    r = np.sqrt(u1)
    wc = np.stack([r * np.cos(phi), r * np.sin(phi), np.sqrt(np.maximum(1 - u1, 0))], 1)
    # GGX normal, reflected
    ch = np.sqrt(np.maximum((1 - u1) / (1 + (a2 - 1) * u1), 0))
    sh = np.sqrt(np.maximum(1 - ch * ch, 0))
    hv = np.stack([sh * np.cos(phi), sh * np.sin(phi), ch], 1)
    wg = 2 * (hv @ wo)[:, None] * hv - wo[None, :]
    wi = np.where((u3 < 0.5)[:, None], wc, wg)
    cos_i = wi[:, 2]
    h = wo[None, :] + wi
    h /= np.maximum(np.linalg.norm(h, axis=1, keepdims=True), 1e-12)
    noh = np.maximum(h[:, 2], 0)
    voh = np.maximum(h @ wo, 1e-7)
    dd = noh * noh * (a2 - 1) + 1
    d = a2 / (math.pi * dd * dd)
    pdf = 0.5 * np.maximum(cos_i, 0) / math.pi + 0.5 * d * noh / (4 * voh)
    ok = (cos_i > 0) & (pdf > 0)
    f = gltf_eval(mat.base_color[:3], mat.metallic, alpha, mat.specular, wo,
                  np.where(ok[:, None], wi, np.array([0, 0, 1.0])))
    w = np.where(ok, np.maximum(cos_i, 0) / np.where(ok, pdf, 1), 0)
    return (f * w[:, None]).mean(0)


def mitsuba_albedo(mi, dr, bsdf, theta_o: float, n: int) -> np.ndarray:
    si = dr.zeros(mi.SurfaceInteraction3f, n)
    si.n = mi.Normal3f(0, 0, 1)
    si.sh_frame = mi.Frame3f(mi.Vector3f(1, 0, 0), mi.Vector3f(0, 1, 0), mi.Vector3f(0, 0, 1))
    si.wi = mi.Vector3f(math.sin(theta_o), 0, math.cos(theta_o))
    sampler = mi.load_dict({"type": "independent"})
    sampler.seed(7, n)
    ctx = mi.BSDFContext()
    _, w = bsdf.sample(ctx, si, sampler.next_1d(), sampler.next_2d())
    return np.array([dr.mean(w[i])[0] if hasattr(dr.mean(w[i]), "__len__") else dr.mean(w[i])
                     for i in range(3)], float)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--samples", type=int, default=2_000_000)
    args = ap.parse_args()
    import drjit as dr
    import mitsuba as mi

    try:
        mi.set_variant("llvm_ad_rgb")
    except Exception:  # noqa: BLE001
        mi.set_variant("scalar_rgb")
        print("(llvm_ad_rgb unavailable: slow scalar fallback)")
    n = args.samples
    rng = np.random.default_rng(1)
    M = scenes.Material
    cases = [
        ("Lambert 0.725 (specular 0)", M("w", np.array([0.725, 0.71, 0.68, 1]), metallic=0, roughness=1, specular=0)),
        ("metal F0=1 rough 0.3", M("m", np.ones(4), metallic=1, roughness=0.3)),
        ("metal F0=1 rough 0.2", M("m", np.ones(4), metallic=1, roughness=0.2)),
        ("metal copper rough 0.3", M("c", np.array([0.955, 0.638, 0.538, 1]), metallic=1, roughness=0.3)),
        ("dielectric 0.725 rough 1", M("d", np.array([0.725, 0.71, 0.68, 1]), metallic=0, roughness=1)),
        ("dielectric red rough 0.3", M("r", np.array([0.7, 0.08, 0.06, 1]), metallic=0, roughness=0.3)),
    ]
    print(f"directional albedo, {n} samples; rel = Mitsuba / raygun - 1 (R, G, B)")
    for name, mat in cases:
        bsdf = mi.load_dict(scenes.bsdf_dict(mat)["bsdf"])
        print(f"\n{name}: Mitsuba {scenes.material_model(mat)}")
        for deg in (0, 30, 60, 75, 85):
            t = math.radians(deg)
            a = gltf_albedo(mat, t, n, rng)
            b = mitsuba_albedo(mi, dr, bsdf, t, n)
            rel = b / np.maximum(a, 1e-9) - 1
            print(f"  theta_o {deg:2d}: raygun {a.round(4)}  Mitsuba {b.round(4)}  rel {rel.round(4)}")
    print("\nfitted conductors (F0 -> eta, k; max |F - Schlick|):")
    c = np.linspace(1e-4, 1, 2001)
    for f0 in (0.04, 0.5, 0.538, 0.638, 0.9, 0.955, 1.0):
        e, k = scenes.conductor_fit(f0)
        d = np.abs(scenes.fresnel_conductor(c, e, k) - scenes.schlick(c, f0)).max()
        print(f"  F0 {f0:5.3f}: eta {e:.4f} k {k:.4f} max|dF| {d:.4f}")


if __name__ == "__main__":
    main()
