"""95 % interval coverage and the noise level read from the residuals, per loss (squared,
huber, cauchy), on clean Gaussian tracking noise: a robust loss should cost a little
efficiency (its intervals about 1/sqrt(0.95) wider) and keep its intervals' level.

    pip install ./python numpy
    python benches/robust_coverage.py [--draws 40]

The scene: a 3 x 4 hanging grid (the top row fixed; 50 g, 10 cm pitch; horizontal, vertical
and shear spring types, 9 unknowns in boxes [1, 1000] N/m, [0.05, 0.3] m, [0, 1] N s/m),
150 frames, 1 mm noise, marker 7 hidden for frames 40-59. One line per loss.
"""

import argparse
import json
import warnings

import numpy as np

import cordis


def scenes():
    nx, ny = 3, 4
    idx = lambda i, j: j * nx + i  # noqa: E731
    particles, links = [], []
    for j in range(ny):
        for i in range(nx):
            p = {"mass": 0.05, "pos": [0.1 * i, -0.1 * j, 0.0]}
            if j == 0:
                p["fixed"] = True
            else:
                p["vel"] = [0.3, 0.0, 0.2 * j]
            particles.append(p)
            if i + 1 < nx:
                links.append({"type": "horiz", "particles": [idx(i, j), idx(i + 1, j)]})
            if j + 1 < ny:
                links.append({"type": "vert", "particles": [idx(i, j), idx(i, j + 1)]})
            if i + 1 < nx and j + 1 < ny:
                links.append({"type": "shear", "particles": [idx(i, j), idx(i + 1, j + 1)]})
                links.append({"type": "shear", "particles": [idx(i + 1, j), idx(i, j + 1)]})
    types = {
        "horiz": {"kind": "spring", "stiffness": 30.0, "rest_length": 0.1, "damping": 0.05},
        "vert": {"kind": "spring", "stiffness": 50.0, "rest_length": 0.1, "damping": 0.08},
        "shear": {"kind": "spring", "stiffness": 10.0, "rest_length": 0.1414, "damping": 0.02},
    }
    truth = {"format": "cordis-scene/1", "dt": 0.01, "gravity": [0, -9.81, 0],
             "particles": particles, "types": types, "links": links}
    guess = json.loads(json.dumps(truth))
    for t in guess["types"].values():
        t["stiffness"] = {"min": 1, "max": 1000}
        t["rest_length"] = {"min": 0.05, "max": 0.3}
        t["damping"] = {"min": 0, "max": 1}
    for p in guess["particles"]:
        p.pop("vel", None)
    return cordis.Scene.from_dict(truth), cordis.Scene.from_dict(guess), types


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--draws", type=int, default=40)
    args = ap.parse_args()
    warnings.simplefilter("ignore")
    truth, guess, types = scenes()
    x = truth.simulate(150)
    want = {f"types.{t}.{k}": types[t][k] for t in types for k in ("stiffness", "rest_length", "damping")}
    for loss in ("squared", "huber", "cauchy"):
        inside, total, sigmas, ends = 0, 0, [], {}
        for seed in range(args.draws):
            rng = np.random.default_rng(100 + seed)
            obs = x + rng.normal(0, 1e-3, x.shape)
            obs[40:60, 7] = np.nan
            res = cordis.identify(guess, obs, loss=loss)
            ends[res.stopped_by] = ends.get(res.stopped_by, 0) + 1
            if res.intervals is None:
                continue
            sigmas.append(res.sigma)
            for name, value in want.items():
                lo, hi = res.intervals[name]
                inside += lo <= value <= hi
                total += 1
        print(json.dumps({"loss": loss, "ends": ends, "sigma_median_mm": 1e3 * float(np.median(sigmas)),
                          "coverage": inside / total, "intervals": total}))


if __name__ == "__main__":
    main()
