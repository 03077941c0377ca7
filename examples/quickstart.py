"""Quickstart: simulate a shipped example, then identify its parameters back from the motion.

Run from anywhere once the package is installed (``pip install ./python``)::

    python examples/quickstart.py

It takes about a second: the rigid example (15 particles, 10 spring types) is simulated for
100 frames, then its 20 stiffnesses and rest lengths, hidden in boxes 25 times wide, are
identified by the thesis' evolution strategy from the positions alone.
"""

import cordis


def main() -> None:
    truth = cordis.example("rigid")
    traj = truth.simulate(frames=100)  # float64 (100, 15, 3), m

    scene = cordis.example("rigid", unknowns=True)  # same scene, parameters as {"min", "max"}
    # The thesis ES explicitly: `auto` would solve this scene exactly by least squares (try it).
    res = cordis.identify(scene, traj, strategy="thesis", generations=500, seed=0, truth=truth)

    print(f"{'parameter':<34} {'true':>12} {'identified':>12} {'error %':>10}")
    for name, value in res.params.items():
        true = res.truth[name]
        print(f"{name:<34} {true:>12.6g} {value:>12.6g} {100 * abs(value - true) / abs(true):>10.2e}")
    print(
        f"\n{res.strategy}: {res.generations} generations, {res.evals} cost evaluations in "
        f"{res.seconds:.2f} s; rmse {res.rmse:.3e} m; mean parameter error "
        f"{res.param_error_pct:.3e} %"
    )


if __name__ == "__main__":
    main()
