#!/usr/bin/env python3
"""Two (or more) raygun builds side by side on the peer benchmark's scenes: the CPU twin's
ms per megasample, the binaries interleaved per scene and round, medians and ratios to the
first. For measuring one change to the CPU twin on a shared machine, where only ratios taken
in one run mean anything (BENCHMARKS.md).

    python3 tools/peers/ab_raygun.py --rounds 4 before/raygun after/raygun

Scenes, sizes and settings are bench_peers.py's (its Lambert copies, 1280 x 720, 8 spp,
--max-depth 8, 2 threads by default); needs numpy (the GLB rewrite), not Mitsuba.
"""

from __future__ import annotations

import argparse
import os
import statistics
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
    a = ap.parse_args()
    for b in a.binaries:
        if not os.access(b, os.X_OK):
            sys.exit(f"ab_raygun: {b}: not an executable")
    wanted = a.scenes.split(",") if a.scenes else [s[0] for s in bench_peers.SCENES]
    unknown = set(wanted) - {s[0] for s in bench_peers.SCENES}
    if unknown:
        sys.exit(f"ab_raygun: unknown scene(s): {', '.join(sorted(unknown))}")
    envs = {name: env for name, _, env in bench_peers.SCENES}
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


if __name__ == "__main__":
    main()
