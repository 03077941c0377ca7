"""Largest spread of a free run against the observed one (benches/stable_horizon.sh).

    python3 benches/spread_ratio.py OBSERVED.csv RUN.csv

The spread of a frame is the largest distance of a particle from the particles' centroid (m),
blind to rigid motion; prints `max spread(RUN) / max spread(OBSERVED)` (1.0: the run keeps the
observed size; ≫ 1: the network came apart or exploded). Standard library only.
"""
import csv
import math
import sys


def spreads(path):
    frames = {}
    with open(path) as f:
        for row in csv.DictReader(f):
            frames.setdefault(int(row["frame"]), []).append(
                (float(row["x"]), float(row["y"]), float(row["z"]))
            )
    out = []
    for t in sorted(frames):
        pts = frames[t]
        c = [sum(p[k] for p in pts) / len(pts) for k in range(3)]
        out.append(max(math.dist(p, c) for p in pts))
    return out


def main(observed, run):
    ref = max(spreads(observed))
    s = spreads(run)
    print(f"{max(s) / ref:.3g}")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
