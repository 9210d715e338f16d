#!/usr/bin/env python3
"""Two (or more) raygun builds side by side on the peer benchmark's scenes: the CPU twin's
ms per megasample, the binaries interleaved per scene and round, medians and ratios to the
first. For measuring one change to the CPU twin on a shared machine, where only ratios taken
in one run mean anything (BENCHMARKS.md, *Methods*).

    python3 tools/peers/ab_raygun.py --rounds 4 before/raygun after/raygun

Scenes, sizes and settings are bench_peers.py's (its Lambert copies, 1280 x 720, 8 spp,
--max-depth 8, 2 threads by default); needs numpy (the GLB rewrite), not Mitsuba.

    python3 tools/peers/ab_raygun.py --side-by-side --rounds 8 before/raygun after/raygun

--side-by-side runs the two builds at the same time, one thread each, each pinned to a core of
its own (the cores swapped every round), and reports each round's ratio: both builds meet the
same moments of a shared machine's noise, which drifts by more than a small change is worth
between one run and the next (BENCHMARKS.md, *Methods*: a build against itself gave x1.006,
rounds 0.95-1.08). Needs two cores and exactly two builds.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

import bench_peers  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("binaries", nargs="+", help="raygun binaries; ratios are to the first")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--spp", type=int, default=8)
    ap.add_argument("--size", default="1280,720")
    ap.add_argument("--max-depth", type=int, default=8)
    ap.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    ap.add_argument("--scenes", help="comma-separated subset of " +
                    ",".join(s[0] for s in bench_peers.SCENES))
    ap.add_argument("--side-by-side", action="store_true",
                    help="two builds at once, one thread and one core each, swapped per round")
    a = ap.parse_args()
    if a.rounds < 1:
        sys.exit("ab_raygun: --rounds must be at least 1")
    for b in a.binaries:
        if not os.access(b, os.X_OK):
            sys.exit(f"ab_raygun: {b}: not an executable")
    wanted = a.scenes.split(",") if a.scenes else [s[0] for s in bench_peers.SCENES]
    unknown = set(wanted) - {s[0] for s in bench_peers.SCENES}
    if unknown:
        sys.exit(f"ab_raygun: unknown scene(s): {', '.join(sorted(unknown))}")
    envs = {name: env for name, _, env in bench_peers.SCENES}
    if a.side_by_side:
        side_by_side(a, wanted, envs)
        return
    times: dict[tuple[str, str], list[float]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        files = bench_peers.lambert_copies(tmp)
        for r in range(a.rounds):
            for name in wanted:
                for b in a.binaries:
                    ms = bench_peers.run_raygun(b, "cpu", files[name], envs[name],
                                                a)["ms_per_megasample"]
                    times.setdefault((name, b), []).append(ms)
                    print(f"  round {r + 1} {name:13s} {b}  {ms:.1f} ms/Msample", flush=True)
    print(f"\nms per megasample, median (min-max) of {a.rounds} rounds; ratio to the first")
    print("| scene | " + " | ".join(a.binaries) + " |")
    print("|---|" + "---|" * len(a.binaries))
    for name in wanted:
        base = statistics.median(times[(name, a.binaries[0])])
        cells = []
        for b in a.binaries:
            t = times[(name, b)]
            m = statistics.median(t)
            cells.append(f"{m:.1f} ({min(t):.0f}-{max(t):.0f}) x{m / base:.3f}")
        print(f"| {name} | " + " | ".join(cells) + " |")


def side_by_side(a, wanted: list[str], envs: dict[str, str]) -> None:
    """The two builds at once per round and scene, one thread each, on two cores swapped
    every round; each round's ratio (second / first), and their median."""
    if len(a.binaries) != 2:
        sys.exit("ab_raygun: --side-by-side compares exactly two builds")
    cores = sorted(os.sched_getaffinity(0))
    if len(cores) < 2:
        sys.exit("ab_raygun: --side-by-side needs two cores; this process may use "
                 f"{len(cores)}")
    pair = cores[:2]
    ratios: dict[str, list[float]] = {}
    with tempfile.TemporaryDirectory() as tmp:
        files = bench_peers.lambert_copies(tmp)
        for r in range(a.rounds):
            for name in wanted:
                order = pair if r % 2 == 0 else pair[::-1]
                procs = []
                for b, core in zip(a.binaries, order):
                    cmd = [b, "bench", "trace", "--backend", "cpu", "--scene", files[name],
                           "--size", a.size, "--spp", str(a.spp), "--max-depth",
                           str(a.max_depth), "--env", envs[name], "--json"]
                    procs.append(subprocess.Popen(
                        cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                        env=dict(os.environ, RAYON_NUM_THREADS="1"),
                        preexec_fn=lambda core=core: os.sched_setaffinity(0, {core})))
                ms = []
                for b, p in zip(a.binaries, procs):
                    out, err = p.communicate()
                    if p.returncode != 0:
                        sys.exit(f"ab_raygun: {b} failed:\n{err[-2000:]}")
                    row = json.loads(out[out.index("{"):])["rows"][0]
                    ms.append(row["ms_per_megasample"])
                ratios.setdefault(name, []).append(ms[1] / ms[0])
                print(f"  round {r + 1} {name:13s} {ms[0]:.1f} / {ms[1]:.1f} ms/Msample "
                      f"(cores {order[0]}, {order[1]}): x{ms[1] / ms[0]:.3f}", flush=True)
    print(f"\n{a.binaries[1]} / {a.binaries[0]}, side by side, one thread each: median of "
          f"{a.rounds} rounds' ratios (min-max)")
    print("| scene | ratio |")
    print("|---|---|")
    for name in wanted:
        t = ratios[name]
        print(f"| {name} | x{statistics.median(t):.3f} ({min(t):.3f}-{max(t):.3f}) |")


if __name__ == "__main__":
    main()
