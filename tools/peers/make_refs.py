#!/usr/bin/env python3
"""Renders the peer reference suite with Mitsuba 3 into tests/data/peers/.

For each scene of SUITE: builds the scene file where it is generated (tests/data/peers/scenes/),
converts it with scenes.py, renders K independent images (seeds 0..K-1) with the scene's
variant (scalar_rgb, the reference variant, for every scene Mitsuba's own BSDFs model; llvm_ad_rgb
for the `*-gltf` scenes, whose BSDF is the Python plugin gltf_bsdf.py - llvm_ad_rgb and
scalar_rgb agree within the MC error on the Lambert scenes, README.md), and writes

* `<name>.exr`: the mean of the K renders, linear RGB float32 (ZIP-compressed scanlines);
* `<name>.json`: everything needed to reproduce and to compare: scene file and its SHA-256,
  camera, size, spp per render and in all, seeds, max_depth in raygun's and Mitsuba's
  convention, environment, integrator, Mitsuba version and variant, the material mapping, the
  raygun command that renders the matching image, the tolerances, and per-region statistics
  (a 4 x 4 grid, the whole image and named regions): mean RGB and luminance over the K
  renders and the standard error of that mean (std over K / sqrt(K)).

    python3 tools/peers/make_refs.py                  # all scenes
    python3 tools/peers/make_refs.py --only glossy    # one
    python3 tools/peers/make_refs.py --quick          # a smoke run (4 renders of 16 spp, /tmp)
    python3 tools/peers/make_refs.py --only cornell-lambert-env --variant llvm_ad_rgb \
        --out /tmp/val        # a cross-check: compare.py the reference against /tmp/val/*.exr

Install: `pip install mitsuba numpy` (3.9.1 used). See README.md beside this file.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import exr  # noqa: E402
import scenes  # noqa: E402

ROOT = os.path.abspath(os.path.join(HERE, "..", ".."))
LLVM19 = "/usr/lib/x86_64-linux-gnu/libLLVM-19.so"
if os.path.exists(LLVM19) and "DRJIT_LIBLLVM_PATH" not in os.environ:
    os.environ["DRJIT_LIBLLVM_PATH"] = LLVM19
OUT = os.path.join(ROOT, "tests", "data", "peers")
SCN = os.path.join(OUT, "scenes")
WIDTH, HEIGHT = 96, 54
GRID = (4, 4)  # columns, rows
SIGMA = 4.0
LUMA = np.array([0.2126, 0.7152, 0.0722])


def _rel(p: str) -> str:
    return os.path.relpath(p, ROOT)


# Generated scene files -----------------------------------------------------------------------


def build_scene_files() -> None:
    os.makedirs(SCN, exist_ok=True)
    src = os.path.join(ROOT, "tests", "data", "scenes")
    scenes.rewrite_glb(os.path.join(src, "cornell-light.glb"),
                       os.path.join(SCN, "cornell-light-lambert.glb"),
                       lambda d: scenes.make_lambert(d, light_double_sided=False))
    scenes.rewrite_glb(os.path.join(src, "cornell-light.glb"),
                       os.path.join(SCN, "cornell-light-lambert-twosided.glb"),
                       lambda d: scenes.make_lambert(d, light_double_sided=True))
    scenes.rewrite_glb(os.path.join(src, "cornell.glb"), os.path.join(SCN, "cornell-lambert.glb"),
                       lambda d: scenes.make_lambert(d))
    scenes.glossy_scene(os.path.join(SCN, "glossy.glb"))
    scenes.envmap_scene(os.path.join(SCN, "envmap.glb"))
    scenes.glass_scene(os.path.join(SCN, "glass.glb"))
    scenes.glass_scene(os.path.join(SCN, "coloured-glass.glb"), coloured=True)
    scenes.lights_scene(os.path.join(SCN, "lights.glb"))
    exr.write_rgb(os.path.join(SCN, "sky.exr"), scenes.sky_map())


LAMBERT_TOL = {"image": 0.02, "region": 0.03}
SUITE = {
    "cornell-light": dict(
        scene="tests/data/scenes/cornell-light.glb", env="0,0,0", spp=512,
        tolerance=None,
        note="raygun's generated Cornell box as is: glTF dielectric materials (metallic 0, "
             "roughness 1, specular 1, i.e. F0 = 0.04 Schlick layer over Lambert), light "
             "doubleSided true (two emitting faces here too), lit by the light alone. Mitsuba "
             "has no equivalent of glTF's dielectric; roughplastic at alpha = 1 keeps only "
             "~35 % of its albedo (check_bsdf.py), so this reference is NOT comparable to "
             "raygun: it documents the gap."),
    "cornell-light-gltf": dict(
        scene="tests/data/scenes/cornell-light.glb", env="0,0,0", spp=512,
        tolerance=LAMBERT_TOL, model="gltf", variant="llvm_ad_rgb",
        note="cornell-light.glb as is (glTF dielectric materials, light doubleSided true), "
             "rendered by Mitsuba's path integrator with raygun's own BSDF formulas "
             "(gltf_bsdf.py, a Python plugin, hence llvm_ad_rgb; validated against "
             "scalar_rgb on the Lambert and metal scenes, README). Comparable: the same "
             "materials, two emitting faces in both."),
    "cornell-light-lambert": dict(
        scene="tests/data/peers/scenes/cornell-light-lambert.glb", env="0,0,0", spp=512,
        tolerance=LAMBERT_TOL,
        note="Pure Lambert (KHR_materials_specular 0) Cornell box, ceiling light radiance "
             "(17, 12, 4) with doubleSided false: one-sided, emitting downwards only; lit by "
             "the light alone (env 0). raygun before its one-sided fix emits from both faces."),
    "cornell-light-lambert-twosided": dict(
        scene="tests/data/peers/scenes/cornell-light-lambert-twosided.glb", env="0,0,0",
        spp=512, tolerance=LAMBERT_TOL,
        note="As cornell-light-lambert with the light doubleSided true: both faces emit "
             "(Mitsuba: two one-sided copies 1e-5 x the scene diagonal apart)."),
    "cornell-lambert-env": dict(
        scene="tests/data/peers/scenes/cornell-lambert.glb", env="1,1,1", spp=512,
        tolerance=LAMBERT_TOL,
        note="Pure Lambert Cornell box without the light, lit by raygun's default "
             "environment (constant white, radiance 1) through its open front."),
    "glossy": dict(
        scene="tests/data/peers/scenes/glossy.glb", env="1,1,1", spp=512,
        tolerance={"image": 0.02, "region": 0.03},
        regions="spheres",
        note="Two metal spheres on a grey Lambert floor under a constant white sky: left a "
             "white metal (F0 = 1: roughconductor eta 0, k 1, Fresnel exact), right copper "
             "(F0 = 0.955, 0.638, 0.538: fitted conductor eta/k), both roughness 0.3 "
             "(alpha 0.09). Model differences: Smith G separable (Mitsuba) vs height-"
             "correlated (glTF), Schlick vs fitted conductor Fresnel (check_bsdf.py: "
             "directional albedo within ~1 % except at grazing angles)."),
    "envmap": dict(
        scene="tests/data/peers/scenes/envmap.glb", env="tests/data/peers/scenes/sky.exr",
        spp=512, tolerance={"image": 0.02, "region": 0.03},
        regions="envmap",
        note="A Lambert sphere (0.8) and a white-metal sphere (roughness 0.2) on a Lambert "
             "floor under a 64 x 32 equirectangular sky (sky.exr: coloured quadrants, +X "
             "red-ish, -Z yellow-ish, -X green-ish, +Z blue-ish, a 2 x 2-texel sun of radiance "
             "60 towards (+X, -Z) at ~35 deg elevation, a brown ground). Mitsuba's envmap gets "
             "the map resampled 8x onto its grid (scenes.py)."),
    "glass": dict(
        scene="tests/data/peers/scenes/glass.glb", env="1,1,1", spp=512,
        tolerance={"image": 0.02, "region": 0.03}, regions="glass",
        note="A smooth glass sphere (Mitsuba dielectric) and a rough one (roughdielectric, GGX "
             "alpha 0.09), ior 1.5, on a red/blue Lambert floor under the white sky. Model "
             "differences: Mitsuba's exact dielectric Fresnel vs glTF's Schlick (taken on the "
             "rarer side; equal at normal incidence and under total internal reflection), "
             "raygun's smooth glass is GGX at alpha 1e-3, no eta^2 radiance scaling (cancels "
             "for light entering and leaving the spheres)."),
    "coloured-glass": dict(
        scene="tests/data/peers/scenes/coloured-glass.glb", env="1,1,1", spp=512,
        tolerance={"image": 0.02, "region": 0.03}, regions="glass",
        note="The glass scene with both spheres filled with absorbing media "
             "(KHR_materials_volume, thicknessFactor 1): amber (attenuationColor 0.9, 0.5, 0.1 "
             "at 0.5 m) in the smooth one, blue-green (0.2, 0.6, 0.8 at 0.7 m) in the rough one. "
             "Mitsuba: the same interfaces with an interior homogeneous medium of sigma_t = "
             "-ln(colour) / distance and albedo 0 (absorption only), rendered by volpath. Model "
             "differences as for glass."),
    "lights": dict(
        scene="tests/data/peers/scenes/lights.glb", env="0,0,0", spp=512,
        tolerance=LAMBERT_TOL,
        note="A Lambert sphere on a Lambert floor lit only by KHR_lights_punctual: a point "
             "light (intensity 2) and a spot light (intensity 6, cones 25 / 25.5 deg; Mitsuba "
             "point and spot with beam_width / cutoff_angle). Exact models but for the spot's "
             "0.5 deg transition (linear in angle in Mitsuba, quadratic in cos in glTF)."),
    "city-small-gltf": dict(
        scene="tests/data/scenes/city-small.glb", env="1,1,1", spp=256, tolerance=LAMBERT_TOL,
        model="gltf", variant="llvm_ad_rgb",
        note="The small city as is (glTF dielectric materials, base colour textures), "
             "camera 'street', white sky, with raygun's BSDF formulas in Mitsuba "
             "(gltf_bsdf.py, llvm_ad_rgb)."),
    "city-small": dict(
        scene="tests/data/scenes/city-small.glb", env="1,1,1", spp=256, tolerance=None,
        note="raygun's small procedural city (3 862 triangles, textures), camera 'street', "
             "white sky. glTF dielectric materials -> roughplastic: NOT comparable to raygun "
             "(see cornell-light); documents Mitsuba's model and the loader/texture path."),
}


# Regions -------------------------------------------------------------------------------------


def regions_for(name: str, spec: dict, w: int, h: int) -> list[dict]:
    xs = np.linspace(0, w, GRID[0] + 1).round().astype(int)
    ys = np.linspace(0, h, GRID[1] + 1).round().astype(int)
    out = [{"name": "image", "x0": 0, "x1": w, "y0": 0, "y1": h}]
    for j in range(GRID[1]):
        for i in range(GRID[0]):
            out.append({"name": f"r{j}c{i}", "x0": int(xs[i]), "x1": int(xs[i + 1]),
                        "y0": int(ys[j]), "y1": int(ys[j + 1])})
    kind = spec.get("regions")
    if kind:
        sc = scenes.load(os.path.join(ROOT, spec["scene"]))
        cam = sc.camera(None)
        if kind == "spheres":
            spheres = [("sphere 0 (white metal)", [-0.45, 0.35, 0.0], 0.35),
                       ("sphere 1 (copper)", [0.45, 0.35, 0.0], 0.35)]
        elif kind == "glass":
            spheres = [("sphere 0 (smooth glass)", [-0.45, 0.35, 0.0], 0.35),
                       ("sphere 1 (rough glass)", [0.45, 0.35, 0.0], 0.35)]
        else:
            spheres = [("sphere 0 (diffuse)", [-0.45, 0.35, 0.0], 0.35),
                       ("sphere 1 (metal)", [0.45, 0.35, 0.0], 0.35)]
        for label, c, r in spheres:
            out.append({"name": label, **_sphere_box(cam, np.array(c), r, w, h)})
        if kind == "envmap":
            out.append({"name": "sky band", "x0": 0, "x1": w, "y0": 0, "y1": max(1, h // 8)})
    return out


def _project(cam, p, w, h):
    f = cam.forward
    r = np.cross(f, cam.up)
    r /= np.linalg.norm(r)
    u = np.cross(r, f)
    d = p - cam.position
    t = np.tan(cam.yfov / 2)
    sx = d.dot(r) / d.dot(f) / (t * w / h)
    sy = d.dot(u) / d.dot(f) / t
    return (sx + 1) * w / 2, (1 - sy) * h / 2


def _sphere_box(cam, c, r, w, h) -> dict:
    """A pixel box well inside the sphere's image (around the centre, half the radius)."""
    x, y = _project(cam, c, w, h)
    x2, _ = _project(cam, c + np.cross(cam.forward, cam.up) / np.linalg.norm(
        np.cross(cam.forward, cam.up)) * r, w, h)
    half = max(1, int(abs(x2 - x) * 0.5))
    return {"x0": int(x - half), "x1": int(x + half), "y0": int(y - half), "y1": int(y + half)}


def region_stats(imgs: np.ndarray, regs: list[dict]) -> list[dict]:
    """imgs: (K, H, W, 3). Mean over K of the region means, and their standard error."""
    k = imgs.shape[0]
    out = []
    for r in regs:
        block = imgs[:, r["y0"]:r["y1"], r["x0"]:r["x1"], :]
        per = block.reshape(k, -1, 3).mean(1)  # (K, 3)
        lum = per @ LUMA
        vals = np.concatenate([per, lum[:, None]], 1)
        mean = vals.mean(0)
        se = vals.std(0, ddof=1) / np.sqrt(k) if k > 1 else np.full(4, np.nan)
        out.append({**r, "mean": [float(v) for v in mean[:3]], "se": [float(v) for v in se[:3]],
                    "luminance": float(mean[3]), "luminance_se": float(se[3])})
    return out


# Rendering -----------------------------------------------------------------------------------


def render_one(name: str, spec: dict, variant: str | None, k: int, spp: int, max_depth: int,
               out_dir: str, w: int, h: int, model: str | None = None) -> dict:
    import mitsuba as mi

    model = model or spec.get("model", "native")
    # The gltf plugin is Python: scalar_rgb would call it per ray (far too slow).
    variant = variant or ("llvm_ad_rgb" if model == "gltf" else spec.get("variant", "scalar_rgb"))
    mi.set_variant(variant)
    path = os.path.join(ROOT, spec["scene"])
    sc = scenes.load(path)
    env_arg = spec["env"]
    env_val = scenes.load_environment(
        os.path.join(ROOT, env_arg) if env_arg.endswith(".exr") else env_arg)
    env_is_zero = not isinstance(env_val, np.ndarray) and max(env_val) == 0
    d = scenes.mitsuba_dict(sc, w, h, spp, max_depth, env=env_val, model=model)
    if env_is_zero:
        del d["environment"]
    scene = mi.load_dict(d)
    t0 = time.time()
    imgs = []
    for seed in range(k):
        img = np.array(mi.render(scene, seed=seed, spp=spp), np.float32)
        imgs.append(img[..., :3])
        print(f"  {name}: render {seed + 1}/{k} ({time.time() - t0:.0f} s)", flush=True)
    imgs = np.stack(imgs)
    mean = imgs.mean(0)
    os.makedirs(out_dir, exist_ok=True)
    exr.write_rgb(os.path.join(out_dir, f"{name}.exr"), mean)
    regs = region_stats(imgs, regions_for(name, spec, w, h))
    with open(path, "rb") as f:
        sha = hashlib.sha256(f.read()).hexdigest()
    integ = dict(d["integrator"])
    env_desc = ("none (black)" if env_is_zero else
                "constant" if not isinstance(env_val, np.ndarray) else
                f"envmap {env_val.shape[1]}x{env_val.shape[0]} resampled x{scenes.ENV_UPSAMPLE}")
    total = k * spp
    meta = {
        "name": name,
        "note": spec["note"],
        "scene": spec["scene"],
        "scene_sha256": sha,
        "camera": sc.camera(None).name,
        "size": [w, h],
        "spp_per_render": spp,
        "renders": k,
        "spp_total": total,
        "seeds": list(range(k)),
        "max_depth": {"raygun": max_depth, "mitsuba": max_depth + 1,
                      "meaning": "raygun --max-depth N = path vertices; Mitsuba max_depth = "
                                 "N + 1 (longest path in segments)"},
        "env": {"raygun": env_arg, "mitsuba": env_desc},
        "integrator": integ,
        "sampler": "independent",
        "rfilter": "box",
        "mitsuba": {"version": mi.__version__, "variant": variant, "bsdf_model": model},
        "materials": [{"name": m.name, "double_sided": m.double_sided,
                       "emissive": bool(np.any(m.emission > 0)),
                       "mitsuba": scenes.material_model(m, model)} for m in sc.materials],
        "raygun_command": (f"raygun render --backend cpu --scene {spec['scene']} --size {w},{h} "
                           f"--spp {total} --max-depth {max_depth} --env {env_arg} "
                           f"--out {name}.exr"),
        "tolerance": None if spec["tolerance"] is None else {
            "sigma": SIGMA, "image_rel": spec["tolerance"]["image"],
            "region_rel": spec["tolerance"]["region"],
            "exempt": [r["name"] for r in regs if "plastic" in r["name"]],
            "rule": "|raygun - ref| <= sigma * sqrt(se_ref^2 + se_raygun^2) + rel * |ref| per "
                    "channel; rel = image_rel for the whole image, region_rel for the others"},
        "comparable": spec["tolerance"] is not None,
        "render_seconds": round(time.time() - t0, 1),
        "generator": "tools/peers/make_refs.py",
        "regions": regs,
    }
    with open(os.path.join(out_dir, f"{name}.json"), "w") as f:
        json.dump(meta, f, indent=1)
        f.write("\n")
    im = regs[0]
    print(f"{name}: mean {np.round(im['mean'], 4)} +- {np.round(im['se'], 5)} "
          f"({time.time() - t0:.0f} s)", flush=True)
    return meta


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--only", nargs="*", help="scene names (default: all)")
    ap.add_argument("--variant", help="override the scene's variant (default scalar_rgb; "
                    "llvm_ad_rgb for the gltf-model scenes)")
    ap.add_argument("--model", choices=["native", "gltf"],
                    help="override the scene's BSDF model (native Mitsuba BSDFs or gltf_bsdf.py)")
    ap.add_argument("--renders", type=int, default=8, help="K independent renders")
    ap.add_argument("--spp", type=int, help="spp per render (default: per scene)")
    ap.add_argument("--max-depth", type=int, default=8, help="raygun convention")
    ap.add_argument("--size", default=f"{WIDTH},{HEIGHT}")
    ap.add_argument("--out", default=OUT)
    ap.add_argument("--quick", action="store_true", help="4 renders of 16 spp into /tmp/peers")
    args = ap.parse_args()
    if args.quick:
        args.renders, args.spp, args.out = 4, 16, "/tmp/peers"
    w, h = (int(v) for v in args.size.split(","))
    build_scene_files()
    for name in args.only or list(SUITE):
        spec = SUITE[name]
        render_one(name, spec, args.variant, args.renders, args.spp or spec["spp"],
                   args.max_depth, args.out, w, h, args.model)


if __name__ == "__main__":
    main()
