#!/usr/bin/env python3
"""Compares raygun renders with a peer reference (tests/data/peers/<name>.json).

    python3 tools/peers/compare.py tests/data/peers/cornell-lambert-env.json render.exr [more.exr …]
    python3 tools/peers/compare.py tests/data/peers/cornell-lambert-env.json \
        --raygun target/dist/raygun [--backend cpu|gpu] [--spp N] [--renders K]

With `--raygun` the script renders the reference's scene itself (its `raygun_command`, seeds
1..K, spp split evenly); otherwise it reads the EXRs given. Several renders (different seeds)
give raygun's own standard error per region; from one render it is assumed to be the
reference's, scaled by sqrt(reference spp / raygun spp) (`--spp` says raygun's spp; default:
the reference's total).

For each region (whole image, 4 x 4 grid, named regions) it prints the reference and raygun
luminance, the relative difference, the combined standard error and the bound, and per RGB
channel checks

    |raygun - ref| <= sigma * sqrt(se_ref^2 + se_raygun^2) + rel * |ref|

with sigma and rel (image_rel for the whole image, region_rel for the others) from the
reference's `tolerance` (override with --sigma / --image-rel / --region-rel). Regions listed
in tolerance.exempt are shown but not held to it. Exit status 0 when every held region
passes, 1 when one fails, 2 when the reference is marked not comparable and no tolerance was
given. Needs numpy only (the EXR reader is exr.py beside this file).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import exr  # noqa: E402

ROOT = os.path.abspath(os.path.join(HERE, "..", ".."))
LUMA = np.array([0.2126, 0.7152, 0.0722])


def render_raygun(ref: dict, binary: str, backend: str, spp: int, k: int, max_depth: int | None,
                  out_dir: str) -> list[str]:
    w, h = ref["size"]
    paths = []
    for seed in range(1, k + 1):
        out = os.path.join(out_dir, f"{ref['name']}-{seed}.exr")
        cmd = [binary, "render", "--backend", backend, "--quiet", "--scene",
               os.path.join(ROOT, ref["scene"]), "--size", f"{w},{h}", "--spp",
               str(max(1, spp // k)), "--max-depth",
               str(max_depth if max_depth is not None else ref["max_depth"]["raygun"]),
               "--seed", str(seed), "--out", out]
        env = ref["env"]["raygun"]
        if env:
            cmd += ["--env", os.path.join(ROOT, env) if env.endswith((".exr", ".hdr")) else env]
        print(" ".join(cmd), file=sys.stderr, flush=True)
        res = subprocess.run(cmd, capture_output=True, text=True)
        if res.returncode != 0:
            sys.exit(f"raygun failed:\n{res.stderr}")
        for line in (res.stdout + res.stderr).splitlines():
            if "ms per megasample" in line:
                print("  " + line.strip(), file=sys.stderr)
        paths.append(out)
    return paths


def compare(ref: dict, imgs: np.ndarray, raygun_spp: int, sigma: float, image_rel: float,
            region_rel: float, exempt: set[str]) -> tuple[bool, list[dict]]:
    """imgs: (K, H, W, 3) raygun renders. Returns (all held regions pass, rows)."""
    k = imgs.shape[0]
    rows, ok = [], True
    for r in ref["regions"]:
        block = imgs[:, r["y0"]:r["y1"], r["x0"]:r["x1"], :].reshape(k, -1, 3).mean(1)
        mean = block.mean(0)
        ref_mean = np.array(r["mean"])
        ref_se = np.array(r["se"])
        if k > 1:
            se = block.std(0, ddof=1) / np.sqrt(k)
            lum_se = (block @ LUMA).std(ddof=1) / np.sqrt(k)
        else:
            scale = np.sqrt(ref["spp_total"] / raygun_spp)
            se = ref_se * scale
            lum_se = r["luminance_se"] * scale
        comb = np.sqrt(ref_se**2 + se**2)
        rel = image_rel if r["name"] == "image" else region_rel
        bound = sigma * comb + rel * np.abs(ref_mean)
        diff = mean - ref_mean
        passed = bool(np.all(np.abs(diff) <= bound))
        held = r["name"] not in exempt
        if held and not passed:
            ok = False
        lum, ref_lum = float(mean @ LUMA), r["luminance"]
        rows.append({
            "name": r["name"], "ref": ref_lum, "raygun": lum,
            "rel": lum / ref_lum - 1 if ref_lum > 0 else float("nan"),
            "rel_rgb": [float(v) for v in (diff / np.where(ref_mean > 0, ref_mean, np.nan))],
            "mc_rel": float(np.sqrt(r["luminance_se"] ** 2 + lum_se**2) / ref_lum)
            if ref_lum > 0 else float("nan"),
            "worst": float(np.max(np.abs(diff) / bound)), "pass": passed, "held": held,
        })
    return ok, rows


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("reference", help="tests/data/peers/<name>.json")
    ap.add_argument("exr", nargs="*", help="raygun renders (linear EXR), one per seed")
    ap.add_argument("--raygun", help="raygun binary: render the reference's scene first")
    ap.add_argument("--backend", default="cpu")
    ap.add_argument("--spp", type=int, help="raygun's total spp (default: the reference's)")
    ap.add_argument("--renders", type=int, default=4, help="with --raygun: seeds 1..K")
    ap.add_argument("--max-depth", type=int, help="with --raygun: override (raygun convention)")
    ap.add_argument("--sigma", type=float)
    ap.add_argument("--image-rel", type=float)
    ap.add_argument("--region-rel", type=float)
    ap.add_argument("--json", action="store_true", help="print the rows as JSON")
    args = ap.parse_args()
    with open(args.reference) as f:
        ref = json.load(f)
    spp = args.spp or ref["spp_total"]
    if args.raygun:
        tmp = tempfile.mkdtemp(prefix="peers-")
        paths = render_raygun(ref, args.raygun, args.backend, spp, args.renders,
                              args.max_depth, tmp)
    else:
        paths = args.exr
    if not paths:
        sys.exit("give raygun EXRs or --raygun BINARY")
    imgs = np.stack([exr.read_rgb(p) for p in paths])
    if imgs.shape[1:3] != (ref["size"][1], ref["size"][0]):
        sys.exit(f"size {imgs.shape[2]}x{imgs.shape[1]} != reference {ref['size']}")
    tol = ref.get("tolerance") or {}
    if not tol and args.image_rel is None:
        print(f"{ref['name']}: the reference is marked not comparable "
              f"(comparable: false); numbers only:")
    sigma = args.sigma if args.sigma is not None else tol.get("sigma", 4.0)
    image_rel = args.image_rel if args.image_rel is not None else tol.get("image_rel", 0.0)
    region_rel = args.region_rel if args.region_rel is not None else tol.get("region_rel", 0.0)
    exempt = set(tol.get("exempt", []))
    ok, rows = compare(ref, imgs, spp, sigma, image_rel, region_rel, exempt)
    if args.json:
        print(json.dumps({"reference": ref["name"], "pass": ok, "rows": rows}, indent=1))
    else:
        print(f"{ref['name']}: {len(paths)} raygun render(s), {spp} spp vs Mitsuba "
              f"{ref['mitsuba']['version']} {ref['mitsuba']['variant']} {ref['spp_total']} spp; "
              f"bound = {sigma:g} sigma + {image_rel:.1%} (image) / {region_rel:.1%} (regions)")
        print(f"{'region':24s} {'ref Y':>9s} {'raygun Y':>9s} {'rel Y':>8s} {'MC 1σ':>7s} "
              f"{'rel R':>7s} {'rel G':>7s} {'rel B':>7s} {'|d|/bound':>9s}")
        for r in rows:
            mark = "ok" if r["pass"] else ("FAIL" if r["held"] else "(exempt)")
            rr = " ".join(f"{v:+7.2%}" for v in r["rel_rgb"])
            print(f"{r['name']:24s} {r['ref']:9.5f} {r['raygun']:9.5f} {r['rel']:+8.2%} "
                  f"{r['mc_rel']:7.2%} {rr} {r['worst']:9.2f}  {mark}")
        print("PASS" if ok else "FAIL")
    if not tol and args.image_rel is None:
        sys.exit(2)
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
