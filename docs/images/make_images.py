"""Makes the pictures of docs/ with the project itself (cordis.plot); about a minute.

    pip install "./python[plot]" && python docs/images/make_images.py [OUTDIR]

OUTDIR defaults to this file's folder. Every picture is small (< 300 KB).
"""

import os
import pathlib
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import cordis  # noqa: E402
import cordis.plot  # noqa: E402

OUT = pathlib.Path(sys.argv[1]) if len(sys.argv) > 1 else pathlib.Path(__file__).parent
DPI = 100


def save(fig, name):
    path = OUT / name
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    print(f"{path}: {os.path.getsize(path) // 1024} KB")


def without_limit(scene):
    """The scene with Provot's elongation limit taken off every link type."""
    d = scene.to_dict()
    for t in d["types"].values():
        t.pop("max_elongation", None)
    return cordis.Scene.from_dict(d)


def rigid():
    truth = cordis.example("rigid")
    traj = truth.simulate(100)
    scene = cordis.example("rigid", unknowns=True)

    # Figure 4.2 of the thesis: a model stopped early, so that the difference shows.
    early = cordis.identify(scene, traj, strategy="thesis", generations=150, seed=0, truth=truth)
    fig = cordis.plot.trajectories(truth, traj, early.scene.simulate(100),
                                   labels=("original", f"after 150 gen. ({early.param_error_pct:.0f} %)"))
    fig.suptitle("rigid: the observed motion and the motion of a model identified from it")
    save(fig, "rigid_frames.png")

    # Local costs of the first guess (every unknown at the middle of its box).
    f = cordis.Objective(scene, traj)
    fig = cordis.plot.local_costs(scene, traj, f.report(f.param_vector()))
    fig.axes[0].set_title("rigid: local costs $c_i$ of the first guess (box middles)")
    save(fig, "rigid_local_costs.png")

    results = {}
    for sigma in (0.0, 1e-6, 1e-5, 1e-4):
        label = "no noise" if sigma == 0 else f"noise σ = {sigma:g} m"
        results[label] = cordis.identify(scene, traj, strategy="thesis", generations=600,
                                         seed=1, noise=sigma, truth=truth)
    fig = cordis.plot.convergence(results)
    fig.suptitle("rigid: thesis ES, 20 unknowns, observed through noise")
    save(fig, "rigid_noise_convergence.png")

    runs = {"least-squares": cordis.identify(scene, traj, strategy="least-squares",
                                             generations=0, noise=1e-5, truth=truth)}
    for name in ("thesis", "cmaes", "self-adaptive", "annealing"):
        runs[name] = cordis.identify(scene, traj, strategy=name, generations=None,
                                     time_limit=0.6, noise=1e-5, truth=truth)
    fig = cordis.plot.convergence(runs, x="seconds")
    fig.suptitle("rigid, 20 unknowns, noise 1e-5 m: five strategies, 0.6 s each")
    save(fig, "strategies_convergence.png")


def cloth():
    truth = cordis.example("cloth")
    traj = truth.simulate(400)
    free = without_limit(truth).simulate(400)
    fig = cordis.plot.trajectories(truth, traj, free, plane="zy",
                                   labels=("with the limit", "without it"))
    fig.suptitle("cloth, side on: Provot's 10 % elongation limit, and the same cloth without it")
    save(fig, "cloth_frames.png")


def horse():
    truth = cordis.example("horse")
    traj = truth.simulate(53)
    res = cordis.identify(cordis.example("horse", unknowns=True), traj, truth=truth)
    fig = cordis.plot.trajectories(truth, traj, res.scene.simulate(53), frames=[0, 26, 52],
                                   labels=("original", f"{res.strategy}"), follow=True)
    fig.suptitle(f"horse: {len(res.params)} unknowns, {res.strategy} "
                 f"(error {res.param_error_pct:.1e} %)")
    save(fig, "horse_frames.png")


def follower():
    """The visio-motor loop (thesis §6.1.2): the mobile swims to its target 10 body lengths
    away; the controller world (its mental representation, below) changes shape as the
    virtual target comes closer."""
    scene = cordis.example("follower")
    path = cordis.animate(scene, scene.simulate(10000), OUT / "follower.gif", every=125, fps=15)
    print(f"{path}: {os.path.getsize(path) // 1024} KB")


if __name__ == "__main__":
    OUT.mkdir(parents=True, exist_ok=True)
    rigid()
    cloth()
    horse()
    follower()
