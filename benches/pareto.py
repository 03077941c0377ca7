"""Run time against parameter error for every cordis strategy and for pycma, on every shipped
example, in one run (issue 5).

    pip install ./python numpy cma matplotlib
    cargo build --release -p cordis-cli
    python benches/pareto.py --out pareto.jsonl --plot docs/images/pareto.png [-- BENCH ARGS]

1. Runs ``cordis-bench pareto --data DIR --out FILE BENCH ARGS`` (every strategy, every
   example, several budgets; see ``cordis-bench pareto --help``), which also writes each
   scene's truth, unknowns and trajectory into DIR.
2. Runs pycma (CMA-ES, default population, the peer a Python user would pick) on the same data,
   with the same budgets, seed and time limit, its objective a compiled ``cordis.Objective``
   (``cordis.cost`` compiled once, as the docs tell an optimiser to do). It searches what
   cordis' strategies search: each unknown's box mapped to [0, 1], in log space when the box is
   positive and more than 10x wide, from the centre with sigma0 = 0.3. Its seconds count the
   objective's construction and the search, like the CLI's (not the interpreter's start).
3. Appends pycma's records to FILE (same schema, strategy ``pycma``), prints its points, the
   ``cmaes`` against ``pycma`` times to each scene's target, and draws error against run time,
   one panel per scene (``cordis.plot.pareto``).
"""
import argparse
import json
import math
import os
import subprocess
import sys
import tempfile
import time


def cordis_binary():
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    return os.path.join(root, "target", "release", "cordis-bench")


def slot_box(d, name):
    """The {"min", "max"} box of the slot ``name`` (``types.T.P``, ``types.T.w_len[k]``,
    ``particles[i].mass``) in the scene dict ``d``, or None when the value is known."""
    if name.startswith("types."):
        _, t, p = name.split(".", 2)
        node = d["types"][t]
        if p.endswith("]"):
            p, k = p[:-1].split("[")
            v = node[p][int(k)]
        else:
            v = node.get(p)
    elif name.startswith("particles["):
        i = int(name[len("particles["):name.index("]")])
        v = d["particles"][i].get(name.rsplit(".", 1)[1])
    else:
        v = None
    return v if isinstance(v, dict) and "min" in v else None


def run_pycma(data, scene, budgets, seed, time_limit):
    """pycma on DIR/scene.*; yields one history row per generation."""
    import cma
    import numpy as np

    import cordis

    start = time.perf_counter()
    unknown = cordis.Scene.from_json(os.path.join(data, f"{scene}.unknown.json"))
    truth = cordis.Scene.from_json(os.path.join(data, f"{scene}.truth.json"))
    traj = cordis.read_trajectory(os.path.join(data, f"{scene}.npy"))
    f = cordis.Objective(unknown, traj)
    true = cordis.Objective(truth, traj).param_vector()
    base = f.param_vector()
    d = unknown.to_dict()
    slots, lo, hi, logs = [], [], [], []
    for k, name in enumerate(f.param_names()):
        box = slot_box(d, name)
        if box is None:
            continue
        log = box["min"] > 0 and box["max"] > 10 * box["min"]
        slots.append(k)
        logs.append(log)
        lo.append(math.log(box["min"]) if log else box["min"])
        hi.append(math.log(box["max"]) if log else box["max"])
    slots, lo, hi, logs = np.array(slots), np.array(lo), np.array(hi), np.array(logs)
    t = true[slots]

    def params(x):
        z = lo + np.clip(x, 0.0, 1.0) * (hi - lo)
        p = base.copy()
        p[slots] = np.where(logs, np.exp(z), z)
        return p

    def error_pct(x):
        v = params(x)[slots]
        rel = np.where(t == 0, np.abs(v), np.abs((v - t) / np.where(t == 0, 1, t)))
        return 100.0 * float(np.mean(rel))

    es = cma.CMAEvolutionStrategy(
        [0.5] * len(slots), 0.3,
        {"bounds": [0, 1], "seed": seed + 1, "verbose": -9, "tolfun": 0, "tolx": 0,
         "tolfunhist": 0, "tolflatfitness": 10**9, "maxfevals": max(budgets)})
    evals, generation = 0, 0
    history = [dict(generation=0, evals=0, seconds=time.perf_counter() - start,
                    cost=float(f(params(es.mean))), param_error_pct=error_pct(es.mean))]
    stopped_by = "max_evals"
    while evals < max(budgets):
        if time.perf_counter() - start > time_limit:
            stopped_by = "time_limit"
            break
        if es.stop():
            stopped_by = "converged"
            break
        xs = es.ask()
        es.tell(xs, [float(f(params(x))) for x in xs])
        evals += len(xs)
        generation += 1
        history.append(dict(generation=generation, evals=evals,
                            seconds=time.perf_counter() - start,
                            cost=float(es.result.fbest), param_error_pct=error_pct(es.result.xbest)))
    return history, stopped_by


def finite(x):
    return x if x is not None and math.isfinite(x) else None


def pycma_records(scene_rec, history, stopped_by, budgets):
    scene = scene_rec["scene"]
    out, used = [], None
    for b in budgets:
        i = next((i for i, r in enumerate(history) if r["evals"] >= b), None)
        if i is None:
            break
        used = i
        out.append(dict(history[i], budget=b, stopped_by=None))
    if used != len(history) - 1:
        out.append(dict(history[-1], budget=None, stopped_by=stopped_by))
    recs = [{"bench": "pareto", "record": "point", "scene": scene, "strategy": "pycma",
             "budget": r["budget"], "evals": r["evals"], "generations": r["generation"],
             "seconds": r["seconds"], "cost": finite(r["cost"]),
             "param_error_pct": finite(r["param_error_pct"]), "stopped_by": r["stopped_by"]}
            for r in out]
    target = scene_rec["target_pct"]
    hit = next((r for r in history if r["param_error_pct"] <= target), None)
    recs.append({"bench": "pareto", "record": "reach", "scene": scene, "strategy": "pycma",
                 "target_pct": target, "seconds": hit and hit["seconds"],
                 "evals": hit and hit["evals"], "run_seconds": history[-1]["seconds"],
                 "run_evals": history[-1]["evals"]})
    return recs


def plot(records, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    import cordis.plot

    scenes = [r for r in records if r["record"] == "scene"]
    # One marker and colour per strategy across the panels.
    order = list(dict.fromkeys(r["strategy"] for r in records if r["record"] == "point"))
    cols = min(3, len(scenes))
    rows = -(-len(scenes) // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(5.2 * cols, 4.2 * rows), squeeze=False,
                             layout="constrained")
    for ax, s in zip(axes.flat, scenes):
        pts = [r for r in records if r["record"] == "point" and r["scene"] == s["scene"]
               and r["param_error_pct"] is not None and r["seconds"] > 0]
        if not pts:
            ax.set_visible(False)
            continue
        cordis.plot.pareto(pts, ax=ax, strategies=order)
        ax.axhline(s["target_pct"], color="black", lw=0.8, ls="--")
        ax.set_title(f"{s['scene']} ({s['unknowns']} unknowns; dashed: thesis' error "
                     f"{s['target_pct']:g} %)", fontsize="medium")
        ax.legend(fontsize="x-small", title=None, loc="best")
    for ax in list(axes.flat)[len(scenes):]:
        ax.set_visible(False)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cordis-bench", dest="cordis", default=cordis_binary(),
                    help="the cordis-bench binary (cargo build --release -p cordis-bench)")
    ap.add_argument("--out", default="pareto.jsonl", help="JSON-lines output")
    ap.add_argument("--plot", help="error against run time, one panel per scene (.png/.svg)")
    ap.add_argument("--no-pycma", action="store_true", help="only the CLI bench")
    ap.add_argument("--reuse", nargs=2, metavar=("FILE", "DIR"),
                    help="skip the CLI bench: add pycma to the records FILE of an earlier "
                         "`cordis-bench pareto --out FILE --data DIR`")
    ap.add_argument("bench_args", nargs="*", help="arguments of `cordis-bench pareto` (after --)")
    a = ap.parse_args()
    with tempfile.TemporaryDirectory(prefix="cordis-pareto-") as tmp:
        if a.reuse:
            source, data = a.reuse
        else:
            source, data = a.out, tmp
            cmd = [a.cordis, "pareto", "--out", a.out, "--data", data, *a.bench_args]
            print("$", " ".join(cmd), flush=True)
            subprocess.run(cmd, check=True)
        with open(source) as fh:
            records = [json.loads(line) for line in fh if line.strip()]
        records = [r for r in records if r.get("strategy") != "pycma"]
        if not a.no_pycma:
            print("\npycma (default population, cordis.Objective as the cost):")
            print(f"{'scene':<7} {'budget':>10} {'evals':>10} {'seconds':>9} {'cost':>11} "
                  f"{'error %':>12}  stop")
            for s in [r for r in records if r["record"] == "scene"]:
                history, stopped_by = run_pycma(data, s["scene"], s["budgets"], s["seed"],
                                                s.get("time_limit", 60.0))
                recs = pycma_records(s, history, stopped_by, s["budgets"])
                for r in recs:
                    if r["record"] == "point":
                        print(f"{r['scene']:<7} {str(r['budget'] or '-'):>10} {r['evals']:>10} "
                              f"{r['seconds']:>9.3f} {r['cost'] if r['cost'] is not None else math.inf:>11.3e} "
                              f"{r['param_error_pct']:>12.3e}  {r['stopped_by'] or ''}")
                records.extend(recs)
            with open(a.out, "w") as fh:
                for r in records:
                    fh.write(json.dumps(r) + "\n")
            reach = {(r["scene"], r["strategy"]): r for r in records if r["record"] == "reach"}
            print("\ncmaes against pycma, time to the thesis' error:")
            print(f"{'scene':<7} {'target %':>9} {'cmaes (s)':>10} {'pycma (s)':>11} {'ratio':>8}")
            for s in [r for r in records if r["record"] == "scene"]:
                c, p = reach.get((s["scene"], "cmaes")), reach.get((s["scene"], "pycma"))
                if not c or not p:
                    continue
                cs = c["seconds"]
                ps, lb = (p["seconds"], "") if p["seconds"] is not None else (p["run_seconds"], ">")
                ratio = f"{lb}{ps / cs:.0f}x" if cs else "-"
                print(f"{s['scene']:<7} {s['target_pct']:>9g} "
                      f"{'-' if cs is None else f'{cs:.3f}':>10} {lb}{ps:>10.3f} {ratio:>8}")
        if a.plot:
            plot(records, a.plot)
            print(f"wrote {a.plot}")
    print(f"wrote {a.out}")


if __name__ == "__main__":
    sys.exit(main())
