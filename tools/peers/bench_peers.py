#!/usr/bin/env python3
"""The peer benchmark in one run: raygun's CPU twin against Mitsuba 3 scalar_rgb and
llvm_ad_rgb on the same scenes, interleaved, in ms per megasample.

    python3 tools/peers/bench_peers.py --raygun target/dist/raygun [--spp 8] [--rounds 3]
    python3 tools/peers/bench_peers.py --raygun target/dist/raygun --cuda   # on a GPU machine

Scenes (1280 x 720, raygun --max-depth 8 = Mitsuba max_depth 9, rr_depth 4 in both): the
Cornell box with its ceiling light (light only, env 0), the environment-only Cornell box
(white sky) and the small city (white sky). All three are converted to pure Lambert
(KHR_materials_specular 0; the light doubleSided true, as raygun renders it today), so both
renderers compute the same light transport with the same path-length distribution: glTF's
dielectric and Mitsuba's roughplastic differ, and so would their path lengths. Texture
lookups stay (the city).

Each round runs, per scene, A = raygun (`raygun bench trace --json`: the median of `--spp`
frames of one sample per pixel after 2 warm-up frames), B = Mitsuba scalar_rgb and C =
Mitsuba llvm_ad_rgb (a fresh process: scene built, one untimed warm-up render of `--spp`
samples per pixel - for LLVM that compiles and caches the kernel - then `--timed` renders,
median). ms per megasample = render time / (W x H x spp / 1e6). Every renderer gets
`--threads` threads (RAYON_NUM_THREADS for raygun, drjit's pool for Mitsuba).

llvm_ad_rgb needs an LLVM shared library: on Debian 12 (bookworm) the system's LLVM 14/15
do not work with drjit 1.x; install LLVM 19 (in bookworm's main archive):

    apt-get update && apt-get install -y libllvm19
    export DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM-19.so

(the script sets DRJIT_LIBLLVM_PATH to that file when it exists and the variable is unset).
With `--cuda` it adds Mitsuba cuda_ad_rgb and raygun `--backend gpu`.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
ROOT = os.path.abspath(os.path.join(HERE, "..", ".."))
LLVM19 = "/usr/lib/x86_64-linux-gnu/libLLVM-19.so"

SCENES = [
    # name, source file, raygun --env
    ("cornell-light", "tests/data/scenes/cornell-light.glb", "0,0,0"),
    ("cornell-env", "tests/data/scenes/cornell.glb", "1,1,1"),
    ("city-small", "tests/data/scenes/city-small.glb", "1,1,1"),
]


def lambert_copies(tmp: str) -> dict[str, str]:
    import scenes

    out = {}
    for name, src, _ in SCENES:
        dst = os.path.join(tmp, f"{name}-lambert.glb")
        scenes.rewrite_glb(os.path.join(ROOT, src), dst,
                           lambda d: scenes.make_lambert(d, light_double_sided=True))
        out[name] = dst
    return out


# Mitsuba worker (a subprocess per measurement) ------------------------------------------------


def worker(args) -> None:
    import drjit as dr
    import mitsuba as mi

    import scenes

    mi.set_variant(args.worker)
    dr.set_thread_count(args.threads)
    w, h = (int(v) for v in args.size.split(","))
    sc = scenes.load(args.scene)
    env = scenes.load_environment(args.env)
    d = scenes.mitsuba_dict(sc, w, h, args.spp, args.max_depth, env=env)
    if max(env) == 0:
        del d["environment"]
    t0 = time.perf_counter()
    scene = mi.load_dict(d)
    build = time.perf_counter() - t0

    def render(seed: int) -> float:
        t = time.perf_counter()
        img = mi.render(scene, seed=seed, spp=args.spp)
        dr.eval(img)
        dr.sync_thread()
        return time.perf_counter() - t

    warm = render(1000)
    times = [render(i) for i in range(args.timed)]
    ms = statistics.median(times) * 1e3
    print(json.dumps({"variant": args.worker, "build_s": build, "warmup_s": warm,
                      "ms_per_render": ms, "ms_per_megasample": ms / (w * h * args.spp / 1e6),
                      "version": mi.__version__}))


def run_mitsuba(variant: str, scene: str, env: str, a) -> dict:
    cmd = [sys.executable, os.path.abspath(__file__), "--worker", variant, "--scene", scene,
           "--env", env, "--spp", str(a.spp), "--size", a.size, "--max-depth", str(a.max_depth),
           "--threads", str(a.threads), "--timed", str(a.timed)]
    res = subprocess.run(cmd, capture_output=True, text=True)
    if res.returncode != 0:
        raise RuntimeError(f"Mitsuba {variant} failed:\n{res.stderr[-2000:]}")
    return json.loads(res.stdout.strip().splitlines()[-1])


def run_raygun(binary: str, backend: str, scene: str, env: str, a) -> dict:
    cmd = [binary, "bench", "trace", "--backend", backend, "--scene", scene, "--size", a.size,
           "--spp", str(a.spp), "--max-depth", str(a.max_depth), "--env", env, "--json"]
    envv = dict(os.environ, RAYON_NUM_THREADS=str(a.threads))
    res = subprocess.run(cmd, capture_output=True, text=True, env=envv)
    if res.returncode != 0:
        raise RuntimeError(f"raygun failed:\n{res.stderr[-2000:]}")
    out = res.stdout
    data = json.loads(out[out.index("{"):])
    row = data["rows"][0]
    return {"ms_per_megasample": row["ms_per_megasample"], "device": data.get("device"),
            "rays_per_pixel": row.get("rays_per_pixel")}


def cpu_model() -> str:
    try:
        out = subprocess.run(["lscpu"], capture_output=True, text=True).stdout
        for line in out.splitlines():
            if line.startswith("Model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--raygun", default=os.path.join(ROOT, "target", "release", "raygun"))
    ap.add_argument("--spp", type=int, default=8, help="samples per pixel per measurement")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--timed", type=int, default=1, help="timed Mitsuba renders per round")
    ap.add_argument("--size", default="1280,720")
    ap.add_argument("--max-depth", type=int, default=8, help="raygun convention")
    ap.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--scenes", help="comma-separated subset of " +
                    ",".join(s[0] for s in SCENES))
    ap.add_argument("--no-llvm", action="store_true")
    ap.add_argument("--cuda", action="store_true", help="add cuda_ad_rgb and raygun GPU")
    ap.add_argument("--json", help="also write the measurements here")
    # worker mode
    ap.add_argument("--worker", help=argparse.SUPPRESS)
    ap.add_argument("--scene", help=argparse.SUPPRESS)
    ap.add_argument("--env", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if os.path.exists(LLVM19) and "DRJIT_LIBLLVM_PATH" not in os.environ:
        os.environ["DRJIT_LIBLLVM_PATH"] = LLVM19
    if a.worker:
        worker(a)
        return
    import mitsuba as mi

    renderers = [("raygun cpu", "raygun", "cpu"), ("mitsuba scalar_rgb", "mitsuba", "scalar_rgb")]
    if not a.no_llvm:
        renderers.append(("mitsuba llvm_ad_rgb", "mitsuba", "llvm_ad_rgb"))
    if a.cuda:
        renderers += [("raygun gpu", "raygun", "gpu"), ("mitsuba cuda_ad_rgb", "mitsuba",
                                                         "cuda_ad_rgb")]
    chosen = [s for s in SCENES if not a.scenes or s[0] in a.scenes.split(",")]
    tmp = tempfile.mkdtemp(prefix="bench-peers-")
    files = lambert_copies(tmp)
    print(f"CPU: {cpu_model()}, {os.cpu_count()} logical CPUs; threads per renderer: {a.threads}")
    print(f"Mitsuba {mi.__version__}; raygun {a.raygun}; {a.size}, {a.spp} spp per measurement, "
          f"raygun --max-depth {a.max_depth} = Mitsuba max_depth {a.max_depth + 1}; "
          f"{a.rounds} rounds, interleaved", flush=True)
    results: dict = {}
    for rnd in range(a.rounds):
        for name, _, env in chosen:
            for label, kind, which in renderers:
                if kind == "raygun":
                    r = run_raygun(a.raygun, which, files[name], env, a)
                else:
                    r = run_mitsuba(which, files[name], env, a)
                results.setdefault(name, {}).setdefault(label, []).append(r)
                print(f"  round {rnd + 1} {name:14s} {label:20s} "
                      f"{r['ms_per_megasample']:9.1f} ms/Msample", flush=True)
    print("\nms per megasample (median over rounds; min-max)")
    pairs = [("raygun gpu" if w == "cuda_ad_rgb" else "raygun cpu", l)
             for l, k, w in renderers if k == "mitsuba"]
    head = "| scene | " + " | ".join(l for l, _, _ in renderers) + " | " + " | ".join(
        f"{p.split()[1]} / {l.split()[1]}" for p, l in pairs) + " |"
    print(head)
    print("|" + "---|" * (head.count("|") - 1))
    summary = {}
    for name, _, _ in chosen:
        meds = {}
        cells = []
        for label, _, _ in renderers:
            vals = [r["ms_per_megasample"] for r in results[name][label]]
            meds[label] = statistics.median(vals)
            cells.append(f"{meds[label]:.0f} ({min(vals):.0f}-{max(vals):.0f})")
        ratios = [f"{meds[p] / meds[l]:.2f}" for p, l in pairs]
        print(f"| {name} | " + " | ".join(cells) + " | " + " | ".join(ratios) + " |")
        summary[name] = meds
    # Each round's ratio is taken between measurements minutes apart, so a slow drift of the
    # machine's load cancels in it; the ratio of medians above can pair a quiet raygun round
    # with a busy Mitsuba one.
    print("\nper-round ratios (each round's raygun / Mitsuba): median (min-max)")
    head = "| scene | " + " | ".join(f"{p.split()[1]} / {l.split()[1]}" for p, l in pairs) + " |"
    print(head)
    print("|" + "---|" * (head.count("|") - 1))
    round_ratios = {}
    for name, _, _ in chosen:
        cells = []
        for p, l in pairs:
            rs = [x["ms_per_megasample"] / y["ms_per_megasample"]
                  for x, y in zip(results[name][p], results[name][l])]
            round_ratios.setdefault(name, {})[f"{p} / {l}"] = rs
            cells.append(f"{statistics.median(rs):.2f} ({min(rs):.2f}-{max(rs):.2f})")
        print(f"| {name} | " + " | ".join(cells) + " |")
    print("\nratio < 1: raygun takes less time per sample than that Mitsuba variant.")
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"cpu": cpu_model(), "threads": a.threads, "size": a.size, "spp": a.spp,
                       "max_depth_raygun": a.max_depth, "rounds": a.rounds,
                       "results": results, "median": summary,
                       "round_ratios": round_ratios}, f, indent=1)


if __name__ == "__main__":
    main()
