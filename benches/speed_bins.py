#!/usr/bin/env python3
"""Where a CAM program's time goes: Kerf's setpoints against the jerk-limited bound, in bins
of path length.

    cargo run --release -p kerf-benches --bin cam_table -- --write DIR
    cargo run --release -p kerf-benches --bin cam_table -- --bound-speeds "raster B 4 dec" > bound.csv
    kerf sim --config benches/cam-mill.toml --out kerf.csv "DIR/raster_B_4_dec.ngc"
    python3 benches/speed_bins.py bound.csv kerf.csv [--bin MM] [--ramp SHARE] [--quiet]

`bound.csv` is the bound's path speed along the path (`s_mm,speed_mm_s`); `kerf.csv` is
`kerf sim`'s output (`t,x,y,z,...`: the setpoints at the period). Kerf's arc length is
the sum of the distances between its setpoints, the bound's that of the exact path; both
follow the same programmed path within the tolerance, so their lengths agree to about a
twentieth of a millimetre on the corpus' rasters (128.43 and 128.38 mm on raster C).

For each bin: the time Kerf spends in it (its periods there times the period) and the
bound's (the integral of ds / v), and the mean speeds. The bound's integral is a little
under its own time, which `cam_table` reports (2.985 against 3.026 s on raster B, 3.739
against 3.872 s on raster C): the cone program lets an interval's time exceed its length
over its mean speed. The summary splits the bins into
ramps (where the bound's speed falls below SHARE of its top speed anywhere in the bin: the
stops and the corners) and the rest, so that the time lost at the ramps and along the
rows can be told apart. Standard library only.
"""
import argparse
import bisect
import csv
import math


def bound_speeds(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    data = [(float(r[0]), float(r[1])) for r in rows[1:] if r]
    return [s for s, _ in data], [v for _, v in data]


def kerf_setpoints(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    t = [float(r[0]) for r in rows[1:] if r]
    p = [(float(r[1]), float(r[2]), float(r[3])) for r in rows[1:] if r]
    s = [0.0]
    for i in range(1, len(p)):
        s.append(s[-1] + math.dist(p[i], p[i - 1]))
    period = (t[-1] - t[0]) / (len(t) - 1) if len(t) > 1 else 0.0
    return s, period


def bound_time(bs, bv, a, b):
    """The bound's time over [a, b): ds over the mean speed of each sample interval."""
    total = 0.0
    k = max(bisect.bisect_right(bs, a) - 1, 0)
    while k + 1 < len(bs) and bs[k] < b:
        lo, hi = max(bs[k], a), min(bs[k + 1], b)
        v = 0.5 * (bv[k] + bv[k + 1])
        if hi > lo and v > 0.0:
            total += (hi - lo) / v
        k += 1
    return total


def bound_min(bs, bv, a, b):
    i = max(bisect.bisect_right(bs, a) - 1, 0)
    j = min(bisect.bisect_left(bs, b) + 1, len(bs))
    return min(bv[i:j]) if j > i else 0.0


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("bound", help="cam_table --bound-speeds output (s_mm,speed_mm_s)")
    ap.add_argument("kerf", help="kerf sim --out CSV (t,x,y,z,...)")
    ap.add_argument("--bin", type=float, default=2.0, help="bin length, mm (2)")
    ap.add_argument(
        "--ramp",
        type=float,
        default=0.6,
        help="a bin is a ramp where the bound's speed is below this share of its top (0.6)",
    )
    ap.add_argument("--quiet", action="store_true", help="the summary only")
    args = ap.parse_args()
    bs, bv = bound_speeds(args.bound)
    ks, period = kerf_setpoints(args.kerf)
    top = max(bv)
    length = min(bs[-1], ks[-1])
    totals = {"ramp": [0.0, 0.0, 0], "rest": [0.0, 0.0, 0]}
    if not args.quiet:
        print("| from mm | Kerf s | bound s | Kerf mm/s | bound mm/s | kind |")
        print("|---:|---:|---:|---:|---:|---|")
    n = int(math.ceil(length / args.bin))
    for i in range(n):
        a, b = i * args.bin, min((i + 1) * args.bin, length)
        if i == n - 1:
            b = max(bs[-1], ks[-1]) + 1.0  # the rest of both paths
        tk = (bisect.bisect_left(ks, b) - bisect.bisect_left(ks, a)) * period
        tb = bound_time(bs, bv, a, b)
        kind = "ramp" if bound_min(bs, bv, a, b) < args.ramp * top else "rest"
        totals[kind][0] += tk
        totals[kind][1] += tb
        totals[kind][2] += 1
        if not args.quiet:
            w = min(b, length) - a
            vk = w / tk if tk > 0 else 0.0
            vb = w / tb if tb > 0 else 0.0
            print(f"| {a:.1f} | {tk:.3f} | {tb:.3f} | {vk:.1f} | {vb:.1f} | {kind} |")
    print()
    print(f"path {length:.2f} mm, bins of {args.bin} mm, period {period * 1e3:.3f} ms, "
          f"bound's top speed {top:.1f} mm/s")
    print("| bins | count | Kerf s | bound s | Kerf - bound s |")
    print("|---|---:|---:|---:|---:|")
    for kind in ("ramp", "rest"):
        tk, tb, c = totals[kind]
        print(f"| {kind} | {c} | {tk:.3f} | {tb:.3f} | {tk - tb:.3f} |")
    tk = sum(v[0] for v in totals.values())
    tb = sum(v[1] for v in totals.values())
    print(f"| all | {n} | {tk:.3f} | {tb:.3f} | {tk - tb:.3f} |")


if __name__ == "__main__":
    main()
