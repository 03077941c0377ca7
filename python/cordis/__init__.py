"""cordis — Cordis-Anima mass-interaction networks: simulate them, identify their parameters.

A scene is a network of point masses (particles) joined by links whose types come from a
catalogue (springs, dampers, anchors, drags, angle and conditional links…). Scenes are read
from the JSON format ``cordis-scene/1`` or taken from the shipped examples; simulation,
trajectories and costs are numpy arrays.

Example::

    import cordis

    truth = cordis.example("rigid")                   # or cordis.Scene.from_json("scene.json")
    traj = truth.simulate(frames=100)                 # numpy float64, shape (100, 15, 3), in m
    cordis.write_trajectory("rigid.npy", traj)        # .csv, .npy or .tra

    scene = cordis.example("rigid", unknowns=True)    # stiffnesses and rest lengths unknown
    res = cordis.identify(scene, traj, generations=500, truth=truth)
    print(res.params, res.param_error_pct)

    f = cordis.Objective(truth, traj)                 # the cost, compiled once: f(params) -> float
    f(f.param_vector())                               # 0.0 at the true parameters

    scene.types["brace"]["stiffness"] = 120.0        # edit in place, validated
    scene.types["brace"]["damping"] = cordis.Unknown(0.0, 2.0)   # make a parameter unknown
    scene.particles[0].mass = 2.0
    print(scene)                                      # a summary; scene.to_json() has the edits

Pictures (``pip install cordis-anima[plot]`` for matplotlib): :mod:`cordis.plot` draws
convergence curves, original vs identified frames, local costs and Pareto fronts;
``cordis.animate(scene, traj, "motion.gif")`` writes an animation.

MuJoCo (``pip install mujoco``): ``cordis.export_mjcf(scene, "model.xml")`` then
``cordis.mujoco.load("model.xml")`` runs it in MuJoCo with what MJCF has no element for (angle,
conditional and plane links, Provot's limit) applied while MuJoCo integrates.

Errors are subclasses of :class:`CordisError` (:class:`SceneError`, :class:`TrajectoryError`,
:class:`CostKindError`…) and name the place of the fault, e.g.
``links[3].particles[1]: particle 40 does not exist``. The GIL is released during
``simulate``, ``identify``, batch evaluations and file I/O.

Scaling out (``pip install cordis-anima[ray]``): ``cordis.identify(..., executor="ray")`` or
``executor=cordis.RayExecutor(num_workers=8)`` evaluates populations on Ray actors with the same
result as a local run; :func:`cordis.ray.identify_many` fans one identification per trajectory
out as Ray tasks. Ray is imported only when used.
"""

from ._cordis import (
    EXAMPLES,
    ArgumentError,
    CheckpointError,
    CordisError,
    CordisIOError,
    CostKindError,
    CostReport,
    DiscoverResult,
    DivergedError,
    FormatError,
    IdentifyResult,
    LinkType,
    LinkTypes,
    Objective,
    ParamLengthError,
    Particle,
    ParticleList,
    PopulationEvaluator,
    RefusedError,
    RunError,
    Scene,
    SceneError,
    SceneIndexError,
    SceneKeyError,
    TrajectoryError,
    Unknown,
    __version__,
    cost,
    discover,
    example,
    export_gltf,
    export_mjcf,
    identify,
    random_network,
    read_trajectory,
    scene_from_markers,
    write_trajectory,
)
from . import plot  # matplotlib is imported only when a plot function runs
from .plot import animate

__all__ = [
    "EXAMPLES",
    "export_gltf",
    "export_mjcf",
    "ArgumentError",
    "CheckpointError",
    "CordisError",
    "CordisIOError",
    "CostKindError",
    "CostReport",
    "DiscoverResult",
    "DivergedError",
    "FormatError",
    "IdentifyResult",
    "LinkType",
    "LinkTypes",
    "Objective",
    "ParamLengthError",
    "Particle",
    "ParticleList",
    "PopulationEvaluator",
    "RefusedError",
    "RunError",
    "Scene",
    "SceneError",
    "SceneIndexError",
    "SceneKeyError",
    "TrajectoryError",
    "Unknown",
    "__version__",
    "animate",
    "cost",
    "discover",
    "example",
    "identify",
    "plot",
    "random_network",
    "read_trajectory",
    "scene_from_markers",
    "write_trajectory",
]


# `RayExecutor` is not in `__all__`: `from cordis import *` would import Ray (an optional
# extra) and fail without it. `cordis.RayExecutor` works as before.


def __dir__():
    return sorted(set(globals()) | {"RayExecutor"})


def __getattr__(name: str):
    # Ray is an optional extra and slow to import: `cordis.RayExecutor` imports it on first use
    # (and says how to install it when it is missing).
    if name == "RayExecutor":
        from .ray import RayExecutor

        return RayExecutor
    raise AttributeError(f"module 'cordis' has no attribute {name!r}")
