#!/usr/bin/env python3
"""Random raster finishing passes: how Kerf's time compares with the feed time and with the
constant-speed reference of benches/constant_speed.py, and, given two builds, which one is
quicker on each (a "nothing slower" check beyond the bundled corpus).

Each case is a surface z = a1 sin(x/l1) cos(y/n1) + a2 sin((x + y)/l2) with its parameters
drawn from a fixed-seed generator (a1 0.1-2 mm, l1 1-8 mm, n1 3-10 mm, a2 0-0.4 mm, l2
0.4-3 mm: from gentle to steep, from one wave to a fine ripple), written as the corpus's
rasters are (3 rows of 30 mm, a G1 point every 0.05 mm, Z with 3, 4 or 6 decimals, F3000,
G64 P0.01) and run with `kerf sim` on benches/cam-mill.toml. The reference has no ramps
(see constant_speed.py): it says what the geometry costs under the jerk limits, not a bound.

Usage: python3 benches/surface_sweep.py KERF [OTHER_KERF] [--seed S] [--cases N] [--decimals D]
  e.g. python3 benches/surface_sweep.py /tmp/old/release/kerf target/release/kerf
Standard library only; about a second per case and build.
"""
import argparse
import math
import os
import random
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import constant_speed as cs  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
CONFIG = os.path.join(HERE, "cam-mill.toml")
ROWS, ROW_MM, STEP_MM, GAP_MM = 3, 30.0, 0.05, 0.5


def case(rnd):
    """Surface parameters and decimals of the next case."""
    a1, l1, n1 = rnd.uniform(0.1, 2.0), rnd.uniform(1.0, 8.0), rnd.uniform(3.0, 10.0)
    a2, l2 = rnd.uniform(0.0, 0.4), rnd.uniform(0.4, 3.0)
    dec = rnd.choice([3, 4, 4, 6])
    return (a1, l1, n1, a2, l2), dec


def program(surface, dec):
    def num(v):
        s = f"{v:.{dec}f}"
        return s[1:] if s.startswith("-") and float(s) == 0.0 else s

    lines = ["G21 G90 G17 G94 G64 P0.01 F3000"]
    points = int(round(ROW_MM / STEP_MM))
    first = True
    for r in range(ROWS):
        y = GAP_MM * r
        forward = r % 2 == 0
        for i in range(1, points + 1):
            x = (i if forward else points - i) * STEP_MM
            lines.append(("G1 " if first else "") + f"X{num(x)} Y{num(y)} Z{num(surface(x, y)[0])}")
            first = False
        if r + 1 < ROWS:
            x = (points if forward else 0) * STEP_MM
            lines.append(f"X{num(x)} Y{num(y + GAP_MM)} Z{num(surface(x, y + GAP_MM)[0])}")
    lines.append("M2")
    return "\n".join(lines) + "\n"


def references(surface):
    """Feed time and constant-speed reference time, s."""
    n = 4000
    h = ROW_MM / n
    feed_t = ref_t = 0.0
    for r in range(ROWS):
        y = GAP_MM * r
        for i in range(n):
            _, z1, z2, z3 = surface((i + 0.5) * h, y)
            ds = h * math.sqrt(1.0 + z1 * z1)
            feed_t += ds / cs.FEED
            ref_t += ds / cs.speed(z1, z2, z3)
    joins = (ROWS - 1) * GAP_MM / cs.FEED
    return feed_t + joins, ref_t + joins


def duration(kerf, path, out):
    res = subprocess.run([kerf, "sim", "--config", CONFIG, "--out", out, path],
                         capture_output=True, text=True)
    for line in (res.stdout + res.stderr).splitlines():
        if line.startswith("duration"):
            return float(line.split()[1]), "fallback" in line
    sys.exit(f"{kerf} failed on {path}:\n{res.stderr}")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("kerf", nargs="+")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--cases", type=int, default=30)
    ap.add_argument("--decimals", type=int, default=None,
                    help="write every case with this many decimals (2: rounding up to half "
                    "the 0.01 mm band) instead of drawing 3, 4 or 6")
    args = ap.parse_args()
    rnd = random.Random(args.seed)
    slower = faster = 0
    with tempfile.TemporaryDirectory() as tmp:
        path, out = os.path.join(tmp, "case.ngc"), os.path.join(tmp, "out.csv")
        print("case | a1 l1 n1 a2 l2 | dec | feed s | reference s | " +
              " | ".join(f"build {i + 1} s (/feed, /ref)" for i in range(len(args.kerf))))
        for k in range(args.cases):
            (a1, l1, n1, a2, l2), dec = case(rnd)
            if args.decimals is not None:
                dec = args.decimals
            surface = cs.waves([(a1, l1, 0, n1), (a2, l2, l2, 0)])
            with open(path, "w") as f:
                f.write(program(surface, dec))
            feed_t, ref_t = references(surface)
            times = []
            for kerf in args.kerf:
                t, fallback = duration(kerf, path, out)
                times.append(t)
                if fallback:
                    print(f"case {k}: {kerf} fell back to the closed-form profile")
            cols = " | ".join(f"{t:.3f} ({t / feed_t:.2f}, {t / ref_t:.2f})" for t in times)
            mark = ""
            if len(times) == 2 and times[1] > times[0] + 1e-9:
                slower += 1
                mark = " SLOWER"
            elif len(times) == 2 and times[1] < times[0] - 1e-9:
                faster += 1
            print(f"{k} | {a1:.2f} {l1:.2f} {n1:.2f} {a2:.2f} {l2:.2f} | {dec} | "
                  f"{feed_t:.3f} | {ref_t:.3f} | {cols}{mark}")
    if len(args.kerf) == 2:
        print(f"second build: {slower} slower, {faster} faster, "
              f"{args.cases - slower - faster} the same")


if __name__ == "__main__":
    main()
