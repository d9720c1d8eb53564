#!/usr/bin/env python3
"""Constant-speed reference times for the raster programs of the CAM corpus.

For each raster (benches/src/cam.rs: surfaces `gentle_surface`, `curved_surface`,
`wavy_surface`, rows along X every 0.5 mm in Y, F3000) and the mill of
benches/cam-mill.toml, every point of a row is given the highest speed at which the
path could pass it at constant speed with X and Z within their velocity, acceleration and
jerk limits (the exact surface, closed-form derivatives), capped by the feed; the
reference time is the integral of ds / v over the rows, plus the joins at the feed.

It is neither a lower nor an upper bound: it has no ramps at all (from rest, at the row
ends, between the speeds), and a planner that changes its tangential acceleration along
the path can now and then pass a point faster than at constant speed. It says how much of
a raster's time its geometry costs under jerk limits, which the acceleration-limited lower
bound of `cam_table` ignores.

Usage: python3 benches/constant_speed.py [--window MM] [--pieces MM] [--share S]
(standard library only, seconds)
  --window MM also gives each point the slowest speed within MM of it along its row
  (measured in X, the row's direction): what a planner that cannot change its speed within
  that distance could at best do.
  --pieces MM also gives each consecutive stretch of MM along its row (in X) the slowest
  speed within it: pieces that each run at one speed, as Kerf's smoothed pieces of up to
  2 mm have one speed limit (ramps between them free).
  --share S holds the acceleration and jerk to S of their limits (velocity as it is): 0.8075
  is what Kerf's pieces leave the curvature terms (CENTRIPETAL_SHARE 0.85 of the profile's
  0.95).
"""
import argparse
import math

FEED = 50.0
LIMITS = {"x": (200.0, 2000.0, 50000.0), "z": (100.0, 1000.0, 20000.0)}


def waves(terms):
    """z(x, y) and its first three x-derivatives for a sum of a*sin(x/l + y/m)*cos(y/n)."""
    def f(x, y):
        out = [0.0, 0.0, 0.0, 0.0]
        for a, l, m, n in terms:
            ph = x / l + (y / m if m else 0.0)
            c = math.cos(y / n) if n else 1.0
            s, co = math.sin(ph), math.cos(ph)
            out[0] += a * s * c
            out[1] += a / l * co * c
            out[2] += -a / l**2 * s * c
            out[3] += -a / l**3 * co * c
        return out
    return f


SURFACES = {
    # name: (surface, rows, row length mm)
    "raster A": (waves([(1.5, 4.0, 0, 6.0), (0.3, 1.7, 1.7, 0)]), 6, 20.0),
    "raster B": (waves([(1.5, 2.5, 0, 4.0), (0.3, 1.2, 1.2, 0)]), 3, 40.0),
    "raster C": (waves([(0.6, 1.25, 0, 4.0), (0.1, 0.5, 0.5, 0)]), 3, 40.0),
}


def axes_at(v, z1, z2, z3):
    """X and Z velocity, acceleration and jerk at path speed v on z(x) (v constant)."""
    g = math.sqrt(1.0 + z1 * z1)          # ds/dx
    g1 = z1 * z2 / g                      # dg/dx
    g2 = (z2 * z2 + z1 * z3) / g - z1 * z2 * g1 / g**2
    xd = v / g
    xdd = -v * v * g1 / g**3
    xddd = -v**3 * (g2 / g**4 - 3.0 * g1 * g1 / g**5)
    zd = z1 * xd
    zdd = z2 * xd * xd + z1 * xdd
    zddd = z3 * xd**3 + 3.0 * z2 * xd * xdd + z1 * xddd
    return (xd, xdd, xddd), (zd, zdd, zddd)


def within(v, z1, z2, z3, share=1.0):
    (x, z) = axes_at(v, z1, z2, z3)
    scale = (1.0, share, share)
    return all(abs(q) <= k * lim for q, k, lim in zip(x, scale, LIMITS["x"])) and all(
        abs(q) <= k * lim for q, k, lim in zip(z, scale, LIMITS["z"]))


def speed(z1, z2, z3, share=1.0):
    if within(FEED, z1, z2, z3, share):
        return FEED
    lo, hi = 0.0, FEED
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        if within(mid, z1, z2, z3, share):
            lo = mid
        else:
            hi = mid
    return lo


def main():
    ap = argparse.ArgumentParser(description="Constant-speed reference of the CAM rasters.")
    ap.add_argument("--window", type=float, metavar="MM",
                    help="also the slowest speed within MM of each point along its row")
    ap.add_argument("--pieces", type=float, metavar="MM",
                    help="also the slowest speed of each consecutive MM along its row")
    ap.add_argument("--share", type=float, default=1.0, metavar="S",
                    help="acceleration and jerk held to S of their limits (1)")
    args = ap.parse_args()
    window, pieces, share = args.window, args.pieces, args.share
    for name, (surface, rows, length) in SURFACES.items():
        total, windowed, pieced, slowest, n = 0.0, 0.0, 0.0, FEED, 8000
        h = length / n
        for r in range(rows):
            y = 0.5 * r
            ds, vs = [], []
            for i in range(n):
                z, z1, z2, z3 = surface((i + 0.5) * h, y)
                v = speed(z1, z2, z3, share)
                slowest = min(slowest, v)
                ds.append(h * math.sqrt(1.0 + z1 * z1))
                vs.append(v)
                total += ds[-1] / v
            if window is not None:
                k = int(round(window / h))
                for i in range(n):
                    windowed += ds[i] / min(vs[max(0, i - k):i + k + 1])
            if pieces is not None:
                k = max(1, int(round(pieces / h)))
                for i in range(0, n, k):
                    pieced += sum(ds[i:i + k]) / min(vs[i:i + k])
        joins = (rows - 1) * 0.5 / FEED
        line = f"{name}: constant-speed reference {total + joins:.3f} s, slowest {slowest:.1f} mm/s"
        if window is not None:
            line += f"; at the slowest within {window} mm: {windowed + joins:.3f} s"
        if pieces is not None:
            line += f"; in pieces of {pieces} mm: {pieced + joins:.3f} s"
        if share != 1.0:
            line += f" (acceleration and jerk at {share} of their limits)"
        print(line)


if __name__ == "__main__":
    main()
