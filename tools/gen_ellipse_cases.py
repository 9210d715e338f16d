#!/usr/bin/env python3
"""Generate tests/data/ellipse_hard_cases.csv: hard cases for the closest point on an ellipse.

Usage: python3 tools/gen_ellipse_cases.py > tests/data/ellipse_hard_cases.csv

Deterministic (fixed seed, no clock). Needs mpmath (tested with 1.3.0).

Each case is an ellipse (x/a)^2 + (y/b)^2 = 1 and a query point (x, y), all four exact doubles
(printed with 17 significant digits, which round-trips). The reference is computed in mpmath at
80 significant digits from those exact doubles, independently of the Rust solver's method:

* every stationary point of the squared distance on the ellipse is found: the Lagrange
  condition P - C = t * grad((X/a)^2 + (Y/b)^2)/2 gives C = (a^2 x/(t + a^2), b^2 y/(t + b^2)),
  where t is a real root of F(t) = (a x/(t + a^2))^2 + (b y/(t + b^2))^2 - 1 (the quartic). F is
  monotone on the two outer intervals and convex between the poles, so every real root is
  bracketed (the convex part through its closed-form minimum) and bisected to 70 digits, in
  unknowns measured from the nearest pole so that no root is lost to cancellation;
* the degenerate stationary points where t sits at a pole (y = 0 or x = 0: the point is on an
  axis and the closest point leaves it) and the four vertices are added;
* the reference is the candidate with the smallest distance (the global minimiser) among those
  on the query point's side of each axis it is off (a mirror image is farther by 4|Y y|, which
  80 digits cannot see for y = 1e-300); it is non-unique when another such candidate, at a
  different point, has the same distance to 1e-40. A sampled check (4096 points on the
  ellipse, in floats) asserts that nothing is closer.

Columns:
  a, b, x, y     the case (exact doubles)
  d_ref          distance from (x, y) to the curve, 21 significant digits
  cx_ref, cy_ref the closest point (one of them when not unique)
  unique         1 if the closest point is unique, 0 if not (then only the distance is checked)
  kappa          condition number of the closest point with respect to the query point,
                 rho/|rho +- d| (rho the radius of curvature at the closest point, minus sign for
                 inside points): how much a perturbation of the input moves the answer; "inf"
                 when not unique
  category       what the case covers (for test messages)
"""

import math
import random
import sys

from mpmath import mp, mpf

mp.dps = 80
REL_STOP = mpf(10) ** -72


def bisect_decreasing(g, lo, hi):
    """Root of a decreasing g on (lo, hi) with g(lo) > 0 > g(hi), lo > 0: geometric bisection
    while the bracket spans more than a factor 2, then arithmetic bisection to 72 digits."""
    for _ in range(5000):
        if hi - lo <= lo * REL_STOP:
            break
        mid = mp.sqrt(lo * hi) if hi > 2 * lo else (lo + hi) / 2
        if mid <= lo or mid >= hi:
            break
        if g(mid) > 0:
            lo = mid
        else:
            hi = mid
    return (lo + hi) / 2


def candidates_oriented(a, b, x, y):
    """Candidate closest points for A = a^2 >= B = b^2 > 0 (mpf inputs, any signs)."""
    A, B = a * a, b * b
    c = A - B
    al, be = a * abs(x), b * abs(y)
    out = [(a, mpf(0)), (-a, mpf(0)), (mpf(0), b), (mpf(0), -b)]
    # Right interval, t > -B: v = t + B.
    if be > 0:
        g = lambda v: (al / (v + c)) ** 2 + (be / v) ** 2 - 1
        hi = mp.sqrt(al * al + be * be) * 2 + 1
        lo = be / 2
        while g(lo) <= 0:
            lo /= 2
        v = bisect_decreasing(g, lo, hi)
        out.append((A * x / (v + c), B * y / v))
    elif al > c:
        v = al - c
        out.append((A * x / (v + c), mpf(0)))
    # Left interval, t < -A: v = -(t + A); t + B = -(v + c).
    if al > 0:
        g = lambda v: (al / v) ** 2 + (be / (v + c)) ** 2 - 1
        hi = mp.sqrt(al * al + be * be) * 2 + 1
        lo = al / 2
        while g(lo) <= 0:
            lo /= 2
        v = bisect_decreasing(g, lo, hi)
        out.append((-A * x / v, -B * y / (v + c)))
    elif be > c:
        v = be - c
        out.append((mpf(0), -B * y / (v + c)))
    # Middle interval, -A < t < -B: v = t + A in (0, c), u = c - v = -(t + B).
    if c > 0 and al > 0 and be > 0:
        k = (be / al) ** (mpf(2) / 3)
        vmin, umin = c / (1 + k), c * k / (1 + k)
        gv = lambda v: (al / v) ** 2 + (be / (c - v)) ** 2 - 1
        if (al / vmin) ** 2 + (be / umin) ** 2 - 1 < 0:
            v = bisect_decreasing(gv, _pos_lo(gv, vmin), vmin)
            out.append((A * x / v, -B * y / (c - v)))
            gu = lambda u: (al / (c - u)) ** 2 + (be / u) ** 2 - 1
            u = bisect_decreasing(gu, _pos_lo(gu, umin), umin)
            out.append((A * x / (c - u), -B * y / u))
    # Degenerate stationary points with t at a pole.
    if y == 0 and c > 0:
        X = A * x / c
        if abs(X) <= a:
            Y = b * mp.sqrt(1 - (X / a) ** 2)
            out += [(X, Y), (X, -Y)]
    if x == 0 and c > 0:
        Y = -B * y / c
        if abs(Y) <= b:
            X = a * mp.sqrt(1 - (Y / b) ** 2)
            out += [(X, Y), (-X, Y)]
    return out


def _pos_lo(g, start):
    lo = start / 2
    while g(lo) <= 0:
        lo /= 2
    return lo


def reference(a_f, b_f, x_f, y_f):
    """(d, cx, cy, unique, kappa) in mpf for exact double inputs."""
    a, b, x, y = (mpf(v) for v in (a_f, b_f, x_f, y_f))
    if a == 0 or b == 0:
        # Segment (or point): clamp along the segment; unique.
        if a == 0 and b == 0:
            return mp.hypot(x, y), mpf(0), mpf(0), True, mpf(0)
        if b == 0:
            cx, cy = min(max(x, -a), a), mpf(0)
        else:
            cx, cy = mpf(0), min(max(y, -b), b)
        return mp.hypot(x - cx, y - cy), cx, cy, True, mpf(1)
    if a == b and x == 0 and y == 0:
        # Circle centre: every point is closest.
        return a, mpf(0), b, False, mp.inf
    if b > a:
        cands = [(X, Y) for (Y, X) in candidates_oriented(b, a, y, x)]
    else:
        cands = candidates_oriented(a, b, x, y)
    # Every candidate must lie on the ellipse (the bisection converged).
    for (X, Y) in cands:
        assert abs((X / a) ** 2 + (Y / b) ** 2 - 1) < mpf(10) ** -60, (a_f, b_f, x_f, y_f, X, Y)
    # The closest point to a point off an axis lies on the point's side of it (its mirror image
    # is farther by 4|Y y|): keep only such candidates. Without this, a point 1e-300 off the
    # major axis would "tie" with its mirror image to 80 digits and lose its one right answer.
    def same_side(X, Y):
        return (x == 0 or X == 0 or (X > 0) == (x > 0)) and (y == 0 or Y == 0 or (Y > 0) == (y > 0))
    cands = [c for c in cands if same_side(*c)]
    dists = [mp.hypot(x - X, y - Y) for (X, Y) in cands]
    k = min(range(len(cands)), key=lambda i: dists[i])
    d = dists[k]
    cx, cy = cands[k]
    scale = max(a, b, mp.hypot(x, y))
    tie = mpf(10) ** -40 * scale
    unique = not any(
        abs(dists[i] - d) <= tie and mp.hypot(cands[i][0] - cx, cands[i][1] - cy) > tie
        for i in range(len(cands))
    )
    if not unique:
        return d, cx, cy, False, mp.inf
    # Radius of curvature at (cx, cy) and whether the point is inside.
    rho = (a * a * (cy / b) ** 2 + b * b * (cx / a) ** 2) ** mpf(1.5) / (a * b)
    inside = (x / a) ** 2 + (y / b) ** 2 < 1
    kappa = rho / abs(rho - d) if inside else rho / (rho + d)
    return d, cx, cy, True, kappa


def sampled_check(a, b, x, y, d):
    """No sampled ellipse point is closer than the reference (global minimum). In floats, scaled
    so that nothing overflows; the slack covers float rounding."""
    s = max(a, b, abs(x), abs(y))
    a, b, x, y = a / s, b / s, x / s, y / s
    n = 4096
    best = min(math.hypot(x - a * math.cos(2 * math.pi * i / n), y - b * math.sin(2 * math.pi * i / n))
               for i in range(n))
    assert best >= float(d / s) * (1 - 1e-9) - 1e-14, (a, b, x, y, d, best)


def point_on(a, b, th, off):
    """Double point at signed normal offset `off` from the ellipse point at angle th."""
    a, b = mpf(a), mpf(b)
    X, Y = a * mp.cos(th), b * mp.sin(th)
    nx, ny = X / (a * a), Y / (b * b)
    n = mp.hypot(nx, ny)
    return float(X + off * nx / n), float(Y + off * ny / n)


def main():
    rng = random.Random(20261122)
    cases = []

    def add(a, b, x, y, cat, signs=True):
        if signs:
            x = x if rng.random() < 0.5 else -x
            y = y if rng.random() < 0.5 else -y
        cases.append((float(a), float(b), float(x), float(y), cat))

    ratios = [1.0, 1.0 + 2.0**-52, 1.0001, 1.4, 2.0, 7.0, 10.0, 100.0, 900.0, 1e4, 1e6, 1e8]
    for ratio in ratios:
        for major in (1.0, 1873.25):
            for flip in (False, True):
                a, b = major, major / ratio
                ev = (a * a - b * b) / a  # evolute's reach along the major axis
                pts = []
                pts.append((0.0, 0.0, "centre"))
                for k in (0.1, 0.5, 0.9, 0.999999):
                    pts.append((k * a, 0.0, "major-axis-inside"))
                for k in (1.5, 1e3):
                    pts.append((k * a, 0.0, "major-axis-outside"))
                for k in (0.5, 0.999):
                    pts.append((0.0, k * b, "minor-axis-inside"))
                for k in (2.0, 1e3):
                    pts.append((0.0, k * b, "minor-axis-outside"))
                pts.append((0.0, b + 1e-12 * a, "minor-axis-hair-outside"))
                pts.append((a * (1 + 1e-12), 0.0, "major-axis-hair-outside"))
                if ev > 0:
                    for k in (0.3, 0.99):
                        pts.append((k * ev, 1e-10 * b, "near-axis-inside-evolute"))
                        pts.append((k * ev, 0.0, "major-axis-inside-evolute"))
                for _ in range(4):
                    r, th = rng.random() ** 0.5, rng.uniform(0, math.pi / 2)
                    pts.append((r * a * math.cos(th), r * b * math.sin(th), "inside"))
                for _ in range(3):
                    r, th = 1 + 9 * rng.random(), rng.uniform(0, math.pi / 2)
                    pts.append((r * a * math.cos(th), r * a * math.sin(th), "outside"))
                for off in (1e-12, -1e-12, 1e-6):
                    th = mpf(rng.uniform(0, math.pi / 2))
                    x, y = point_on(a, b, th, off * a)
                    pts.append((x, y, "hair-outside" if off > 0 and off < 1e-9 else
                                "hair-inside" if off < 0 else "near-boundary"))
                # Near the vertex of an eccentric ellipse, where curvature is largest.
                th = mpf(1e-3) / ratio
                x, y = point_on(a, b, th, 1e-12 * a)
                pts.append((x, y, "hair-outside-near-vertex"))
                for k in (1e3, 1e8):
                    th = rng.uniform(0, math.pi / 2)
                    pts.append((k * a * math.cos(th), k * a * math.sin(th), "far"))
                for (x, y, cat) in pts:
                    if flip:
                        add(b, a, y, x, cat + "/b-major")
                    else:
                        add(a, b, x, y, cat)

    # Extreme magnitudes: scale whole cases (huge, tiny, subnormal).
    for s in (1e150, 1e-150, 1e300, 2.0**-1060, 1e-310 / 7):
        for ratio in (1.0, 3.0, 1e4, 1e8):
            a, b = 1.0, 1.0 / ratio
            for _ in range(5):
                th = rng.uniform(0, math.pi / 2)
                r = rng.choice([0.0, 0.3, 0.999, 1.0 + 1e-9, 2.0, 1e3])
                x, y = r * a * math.cos(th), r * a * math.sin(th)
                add(a * s, b * s, x * s, y * s, "scaled-%g" % s)
            if b * s > 0:
                add(a * s, b * s, 0.5 * a * s, 0.0, "scaled-axis-%g" % s)
    # Mixed magnitudes: tiny ellipse, huge point (x/a overflows) and the reverse.
    for (a, b, x, y) in [
        (1e-300, 5e-301, 1e300, 3e299),
        (1e-300, 1e-308, 1e300, 1e300),
        (3e-310, 1e-310, 1e300, 2e300),
        (1e-300, 1e-300, 0.0, 1.5e308),
        (1e300, 3e299, 1e-300, 2e-300),
        (1e300, 1e292, 1e-300, 0.0),
        (1e300, 1e292, 1e-300, 1e-310),
        (1e308, 1e300, 1.7e308, 1e308),
        (5e-324, 5e-324, 1e-323, 0.0),
        (1.0, 5e-324, 0.5, 1.0),
        (1.0, 1e-300, 0.5, 1e-310),
        (1.0, 1e-300, 2.0, 1.0),
    ]:
        add(a, b, x, y, "mixed-magnitude")
    # Circles at several radii.
    for rad in (1.0, 0.37, 2160.0):
        for _ in range(8):
            r, th = rng.choice([0.0, 1e-12, 0.5, 1.0 - 1e-12, 1.0 + 1e-12, 3.0, 1e8]), rng.uniform(0, 2 * math.pi)
            add(rad, rad, r * rad * math.cos(th), r * rad * math.sin(th), "circle", signs=False)
        add(rad, rad, 0.0, 0.0, "circle-centre", signs=False)
    # Segments (b = 0 or a = 0) and the point ellipse.
    for (a, b) in ((1.0, 0.0), (0.0, 2.5), (1e8, 0.0), (0.0, 0.0)):
        for (x, y) in ((0.0, 0.0), (0.3, 0.0), (0.3, 1e-9), (5.0, 0.0), (5.0, 2.0),
                       (1e-12, 0.5), (0.0, 3.0), (1.0, 1.0), (2e8, 1.0)):
            add(a, b, x, y, "segment" if a or b else "point")
    # Random cases, all quadrants, mixed ratios and positions.
    for _ in range(300):
        a = 10 ** rng.uniform(-3, 4)
        b = a / 10 ** rng.uniform(-8, 8)
        r = 10 ** rng.uniform(-6, 4) * max(a, b)
        th = rng.uniform(0, 2 * math.pi)
        add(a, b, r * math.cos(th), r * math.sin(th), "random", signs=False)

    # Inside, near either axis, with the off-axis coordinate tiny or subnormal (from 1e-300 down
    # to the smallest subnormal, not exactly zero). Near the major axis inside the evolute's span
    # the secular root is of the order of that coordinate, so it carries few bits when it is
    # subnormal; the solver must still return a point on the ellipse.
    # Its own seed, so the cases above stay as they were.
    rng_tiny = random.Random(20261201)
    tiny = (1e-300, 2.0**-1022, 1e-310, 1e-315, 1e-320, 2.77e-322, 5e-324)
    for ratio in (1.0001, 1.4, 2.0, 7.0, 100.0, 1e4, 1e6, 1e8):
        for major in (1.0, 1873.25):
            for flip in (False, True):
                a, b = major, major / ratio
                ev = (a * a - b * b) / a
                xs = [(0.3 * ev, "tiny-off-axis-inside-evolute"),
                      (0.9 * ev, "tiny-off-axis-inside-evolute"),
                      (rng_tiny.uniform(0.0, ev), "tiny-off-axis-inside-evolute"),
                      ((ev + a) / 2, "tiny-off-axis-inside-beyond-evolute")]
                for t in tiny:
                    pts = [(x, t, cat) for (x, cat) in xs]
                    pts.append((t, 0.5 * b, "tiny-off-axis-near-minor-axis"))
                    for (x, y, cat) in pts:
                        if flip:
                            add(b, a, y, x, cat + "/b-major")
                        else:
                            add(a, b, x, y, cat)
    # The case this class was found by.
    add(0.8264120060636826, 0.02754706686878942, 0.5053656884960821, -2.77e-322,
        "tiny-off-axis-inside-evolute", signs=False)

    out = sys.stdout
    out.write(__doc__.replace("\n", "\n# ").join(["# ", "\n"]).replace("# \n", "#\n"))
    out.write("a,b,x,y,d_ref,cx_ref,cy_ref,unique,kappa,category\n")
    g17 = lambda v: "%.17g" % v
    r21 = lambda v: mp.nstr(v, 21, strip_zeros=False) if mp.isfinite(v) else "inf"
    for i, (a, b, x, y, cat) in enumerate(cases):
        d, cx, cy, unique, kappa = reference(a, b, x, y)
        if max(a, b, abs(x), abs(y)) > 0:
            sampled_check(a, b, x, y, d)
        out.write(",".join([g17(a), g17(b), g17(x), g17(y), r21(d), r21(cx), r21(cy),
                            "1" if unique else "0", r21(kappa) if unique else "inf", cat]) + "\n")
    print("%d cases" % len(cases), file=sys.stderr)


if __name__ == "__main__":
    main()
