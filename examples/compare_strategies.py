"""Compare a few identification strategies on the rigid example, with small budgets.

    python examples/compare_strategies.py   # writes ./out/strategies_convergence.png,
                                            #        ./out/strategies.jsonl, ./out/pareto.png

Each strategy identifies the 20 unknowns of the rigid example (boxes 25 times wide) from the
same slightly noisy motion (σ = 10 µm): the exact least-squares solver in one step, the
evolution strategies within 0.6 s each. The convergence plot shows the best cost against the
run time; the Pareto plot puts run time against parameter error (where each run stood after
0.05, 0.15 and 0.3 s and at its end), from the JSON-lines file written alongside (one point a
line: strategy, scene, seconds, param_error_pct). The output directory is ``$CORDIS_OUT`` or ``./out``. About five seconds.
"""

import json
import os
import pathlib

import numpy as np

import cordis
import cordis.plot

STRATEGIES = ("least-squares", "thesis", "cmaes", "self-adaptive", "annealing")


def main() -> None:
    out = pathlib.Path(os.environ.get("CORDIS_OUT", "out"))
    out.mkdir(parents=True, exist_ok=True)
    truth = cordis.example("rigid")
    traj = truth.simulate(frames=100)
    scene = cordis.example("rigid", unknowns=True)

    results = {}
    records = []
    for name in STRATEGIES:
        # The exact solver needs no generations (0: solve once); the others get 0.6 s each.
        budget = {"generations": 0} if name == "least-squares" else \
            {"generations": None, "time_limit": 0.6}
        res = cordis.identify(scene, traj, strategy=name, seed=0, noise=1e-5, truth=truth,
                              **budget)
        results[name] = res
        # One Pareto point per budget, read off the history: where the run stood at that time.
        h = res.history  # columns: res.HISTORY_COLUMNS
        sec, err = h[:, 2], h[:, 7]
        for budget in sorted({0.05, 0.15, 0.3, res.seconds}):
            row = int(np.searchsorted(sec, budget, side="right")) - 1
            if row >= 0 and budget <= res.seconds:
                records.append({"strategy": name, "scene": "rigid", "seconds": float(sec[row]),
                                "param_error_pct": float(err[row])})
        print(f"{name:<14} {res.generations:>6} generations {res.evals:>8} evals "
              f"{res.seconds:6.2f} s  cost {res.cost:.3e}  error {res.param_error_pct:.3e} %")

    fig = cordis.plot.convergence(results, x="seconds")
    fig.suptitle("rigid, 20 unknowns, noise 1e-5 m: best cost against time")
    fig.savefig(out / "strategies_convergence.png", dpi=110)

    jsonl = out / "strategies.jsonl"
    jsonl.write_text("".join(json.dumps(r) + "\n" for r in records))
    cordis.plot.pareto(jsonl).savefig(out / "pareto.png", dpi=110)
    print(f"wrote {out / 'strategies_convergence.png'}, {jsonl}, {out / 'pareto.png'}")


if __name__ == "__main__":
    main()
