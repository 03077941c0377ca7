"""cordis' CMA-ES against pycma driving a vectorised numpy short cost, on the `rigid` example
(20 unknowns: K and l0 of 10 spring types, boxes 25× wide, 100 frames): wall time of the whole
process (interpreter start, imports, data, search) until the mean parameter error falls below
0.01 %, each side in its own subprocess, 3 seeds.

    pip install ./python numpy cma && python benches/pycma_compare.py

Both sides search the same coordinates: each unknown's box mapped to [0, 1] in log space (the
boxes are positive and 25× wide), start at the box centre with σ0 = 0.3, default population.
"""
import json
import math
import os
import statistics
import subprocess
import sys
import time

TARGET_PCT = 0.01
MAX_EVALS = 400_000


def problem():
    import cordis

    truth = cordis.example("rigid")
    traj = truth.simulate(100)
    unknown = cordis.example("rigid", unknowns=True)
    return truth, traj, unknown


def run_pycma(seed):
    import cma
    import numpy as np

    sys.path.insert(0, os.path.dirname(__file__))
    from numpy_cost import NumpyShortCost

    truth, traj, unknown = problem()
    d = json.loads(unknown.to_json())
    t = json.loads(truth.to_json())
    names = list(d["types"])
    boxes, true = [], []
    for n in names:
        for p in ("stiffness", "rest_length"):
            b = d["types"][n][p]
            boxes.append((math.log(b["min"]), math.log(b["max"])))
            true.append(t["types"][n][p])
    lo, hi = np.array([b[0] for b in boxes]), np.array([b[1] for b in boxes])
    true = np.array(true)
    cost = NumpyShortCost(d, traj)
    z = np.zeros(len(names))

    def values(x):
        return np.exp(lo + np.clip(x, 0, 1) * (hi - lo))

    def f(x):
        v = values(x)
        return cost(v[0::2], v[1::2], z)

    es = cma.CMAEvolutionStrategy([0.5] * len(boxes), 0.3,
                                  {"bounds": [0, 1], "seed": seed + 1, "verbose": -9,
                                   "tolfun": 0, "tolx": 0, "tolfunhist": 0, "maxfevals": MAX_EVALS})
    evals = 0
    while not es.stop():
        xs = es.ask()
        es.tell(xs, [f(x) for x in xs])
        evals += len(xs)
        err = 100 * np.mean(np.abs(values(es.result.xbest) - true) / true)
        if err < TARGET_PCT:
            break
    return {"evals": evals, "error_pct": float(err)}


def run_cordis(seed):
    import cordis

    truth, traj, unknown = problem()
    t = json.loads(truth.to_json())
    true = {f"types.{n}.{p}": t["types"][n][p] for n in t["types"] for p in ("stiffness", "rest_length")}
    err = [math.inf]

    def callback(generation, best_cost, params):
        err[0] = 100 * statistics.fmean(abs(params[k] - v) / v for k, v in true.items())
        return err[0] >= TARGET_PCT

    r = cordis.identify(unknown, traj, strategy="cmaes", generations=None, max_evals=MAX_EVALS,
                        seed=seed, callback=callback)
    return {"evals": r.evals, "error_pct": err[0]}


def main():
    if len(sys.argv) == 3:
        side, seed = sys.argv[1], int(sys.argv[2])
        out = run_pycma(seed) if side == "pycma" else run_cordis(seed)
        print(json.dumps(out))
        return
    rows = {"cordis": [], "pycma": []}
    for seed in range(3):
        for side in ("cordis", "pycma"):
            start = time.perf_counter()
            p = subprocess.run([sys.executable, __file__, side, str(seed)], capture_output=True,
                               text=True, check=True)
            wall = time.perf_counter() - start
            r = json.loads(p.stdout.strip().splitlines()[-1])
            r.update(side=side, seed=seed, wall_s=wall)
            rows[side].append(r)
            print(json.dumps({"bench": "pycma_compare", **r}))
    c = statistics.median(r["wall_s"] for r in rows["cordis"])
    p = statistics.median(r["wall_s"] for r in rows["pycma"])
    print(f"median wall to {TARGET_PCT} %: cordis cmaes {c:.2f} s, pycma + numpy {p:.2f} s: {p / c:.0f}x")


if __name__ == "__main__":
    main()
