"""cordis — Cordis-Anima mass-interaction networks: simulate them, identify their parameters.

A scene is a network of point masses (particles) joined by links whose types come from a
catalogue (springs, dampers, anchors, drags, angle and conditional links…). Scenes are read
from the JSON format ``cordis-scene/1``; simulation returns numpy arrays.

Example::

    import cordis

    scene = cordis.Scene.from_dict({
        "dt": 0.01,
        "particles": [
            {"mass": 1.0, "pos": [0, 0, 0], "fixed": True},
            {"mass": 1.0, "pos": [1.5, 0, 0]},
        ],
        "types": {"rib": {"kind": "spring", "stiffness": 20.0, "rest_length": 1.0}},
        "links": [{"type": "rib", "particles": [0, 1]}],
    })
    traj = scene.simulate(frames=200)   # numpy float64, shape (200, 2, 3), in m

Errors are subclasses of :class:`CordisError` (:class:`SceneError`, :class:`FormatError`…) and
name the place of the fault, e.g. ``links[3].particles[1]: particle 40 does not exist``.
"""

from ._cordis import (
    CordisError,
    CordisIOError,
    DivergedError,
    FormatError,
    Scene,
    SceneError,
    TrajectoryError,
    __version__,
)

__all__ = [
    "CordisError",
    "CordisIOError",
    "DivergedError",
    "FormatError",
    "Scene",
    "SceneError",
    "TrajectoryError",
    "__version__",
]
