#!/usr/bin/env python3
"""Independent reference for `vtsim trace info` on the real recordings (docs/traces.md, "Inspect").

Reads the raw TUM and EuRoC files with the Python standard library only and applies the documented
policy: times as exact integer nanoseconds (decimal.Decimal for TUM seconds, int for EuRoC
nanoseconds), relative to the first pose; a pose repeating the previous time is dropped; a step
longer than 10 m at more than 1000 m/s is a cut (none occur here); path length = sum of step
lengths; speeds over steps of at least 2 ms (shorter steps merge with the next).

Usage: python3 tests/data/reference_trace_stats.py [DIR]   (DIR defaults to ../shared/traces-real)
Prints one line per file: frames, duration_s, path_length_m, speed_max_mps (repr, full precision).
"""
import math
import os
import sys
from decimal import Decimal

MIN_STEP_S = 0.002
CUT_SPEED = 1000.0
CUT_DIST = 10.0


def read_tum(path):
    rows = []
    for line in open(path, encoding="utf-8"):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        f = s.split()
        rows.append((int(Decimal(f[0]) * 1000000000), [float(x) for x in f[1:4]]))
    return rows


def read_euroc(path):
    rows = []
    for line in open(path, encoding="utf-8"):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        f = [x.strip() for x in s.split(",")]
        rows.append((int(f[0]), [float(x) for x in f[1:4]]))
    return rows


def stats(rows):
    kept = [rows[0]]
    for r in rows[1:]:
        if r[0] < kept[-1][0]:
            raise ValueError("time goes backwards")
        if r[0] != kept[-1][0]:
            kept.append(r)
    t0 = kept[0][0]
    t = [(ns - t0) / 1e9 for ns, _ in kept]
    p = [pos for _, pos in kept]
    path = 0.0
    speeds = []
    anchor = 0
    for i in range(1, len(p)):
        dt = t[i] - t[i - 1]
        d = [p[i][k] - p[i - 1][k] for k in range(3)]
        dist = math.sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2])
        if dist / dt > CUT_SPEED and dist > CUT_DIST:
            anchor = i
            continue
        path += dist
        if t[i] - t[anchor] >= MIN_STEP_S:
            e = [p[i][k] - p[anchor][k] for k in range(3)]
            speeds.append(math.sqrt(e[0] * e[0] + e[1] * e[1] + e[2] * e[2]) / (t[i] - t[anchor]))
            anchor = i
    return len(p), t[-1] - t[0], path, max(speeds)


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    d = sys.argv[1] if len(sys.argv) > 1 else os.path.join(here, "..", "..", "..", "shared", "traces-real")
    for name, reader in (("tum_fr1_xyz_groundtruth.txt", read_tum),
                         ("tum_fr2_desk_groundtruth.txt", read_tum),
                         ("euroc_V1_02_groundtruth.csv", read_euroc)):
        frames, duration, path, vmax = stats(reader(os.path.join(d, name)))
        print(f"{name}: frames={frames} duration_s={duration!r} path_length_m={path!r} "
              f"speed_max_mps={vmax!r}")


if __name__ == "__main__":
    main()
