"""Identify the rigid example from motion observed through more and more noise.

    python examples/identify_rigid_noise.py        # writes ./out/rigid_noise_convergence.png

The rigid object of the thesis (§4.1: 15 particles, 10 spring types) is simulated for 100
frames; its 20 stiffnesses and rest lengths, hidden in boxes 25 times wide, are then
identified by the thesis' evolution strategy from positions carrying Gaussian noise of a few
standard deviations. The parameter error follows the noise down: the cost cannot tell apart
models closer to each other than the noise. The output directory is ``$CORDIS_OUT`` or
``./out``. About three seconds.
"""

import os
import pathlib

import cordis
import cordis.plot


def main() -> None:
    out = pathlib.Path(os.environ.get("CORDIS_OUT", "out"))
    out.mkdir(parents=True, exist_ok=True)
    truth = cordis.example("rigid")
    traj = truth.simulate(frames=100)  # m; the object is about 1.2 m wide
    scene = cordis.example("rigid", unknowns=True)

    results = {}
    for sigma in (0.0, 1e-6, 1e-5, 1e-4):
        res = cordis.identify(scene, traj, strategy="thesis", generations=600, seed=1,
                              noise=sigma, truth=truth)
        label = "no noise" if sigma == 0 else f"noise σ = {sigma:g} m"
        results[label] = res
        print(f"{label:<22} cost {res.cost:.3e} m²  parameter error "
              f"{res.param_error_pct:.3e} %  ({res.seconds:.2f} s)")

    fig = cordis.plot.convergence(results)
    fig.suptitle("rigid: thesis ES, 20 unknowns, observed through noise")
    path = out / "rigid_noise_convergence.png"
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
