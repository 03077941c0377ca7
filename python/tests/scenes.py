"""Small scene dicts, one per passive link kind, shared by the tests.

Each is stable at its `dt` (ratio of dt to the shortest period well below the CORDIS bound) and
moves visibly over a few hundred frames, so that a comparison at 1e-9 of the motion's scale
can fail.
"""

from __future__ import annotations

from typing import Any, Dict

import numpy as np


def particle(pos, mass=1.0, vel=None, fixed=False, group=None) -> Dict[str, Any]:
    p: Dict[str, Any] = {"mass": float(mass), "pos": [float(c) for c in pos]}
    if vel is not None:
        p["vel"] = [float(c) for c in vel]
    if fixed:
        p["fixed"] = True
    if group is not None:
        p["group"] = group
    return p


def spring_on_fixed(k=20.0, l0=1.0, z=0.0, m=2.0, x0=(1.5, 0.0, 0.0), v0=(0.0, 0.0, 0.0),
                    dt=0.01, gravity=(0.0, 0.0, 0.0)) -> Dict[str, Any]:
    """One free mass on a spring to a fixed particle at the origin."""
    return {
        "format": "cordis-scene/1",
        "dt": dt,
        "gravity": list(gravity),
        "particles": [particle([0, 0, 0], fixed=True), particle(x0, mass=m, vel=v0)],
        "types": {"rib": {"kind": "spring", "stiffness": k, "rest_length": l0, "damping": z}},
        "links": [{"type": "rib", "particles": [0, 1]}],
    }


def damped_chain() -> Dict[str, Any]:
    """A 3-D chain of damped springs hanging from a fixed particle, with gravity."""
    ps = [particle([0, 0, 0], fixed=True)]
    ps += [particle([0.9 * i, 0.2 * i, -0.1 * i], mass=0.5 + 0.1 * i, vel=[0, 0.3 * i, 0])
           for i in range(1, 6)]
    return {
        "dt": 0.005,
        "gravity": [0.0, 0.0, -9.81],
        "particles": ps,
        "types": {
            "soft": {"kind": "spring", "stiffness": 40.0, "rest_length": 0.8, "damping": 0.4},
            "stiff": {"kind": "spring", "stiffness": 90.0, "rest_length": 0.9, "damping": 0.1},
        },
        "links": [{"type": "soft" if i % 2 else "stiff", "particles": [i, i + 1]}
                  for i in range(5)],
    }


def dampers() -> Dict[str, Any]:
    """Three particles with different velocities, coupled by dampers and one spring."""
    return {
        "dt": 0.01,
        "particles": [
            particle([0, 0, 0], vel=[1.0, 0.0, 0.2]),
            particle([1, 0, 0], mass=2.0, vel=[-0.5, 0.7, 0.0]),
            particle([0, 1, 0], mass=0.7, vel=[0.0, -0.3, 0.9]),
        ],
        "types": {
            "visc": {"kind": "damper", "damping": 0.8},
            "visc2": {"kind": "damper", "damping": 0.3},
            "tie": {"kind": "spring", "stiffness": 5.0, "rest_length": 1.0},
        },
        "links": [
            {"type": "visc", "particles": [0, 1]},
            {"type": "visc2", "particles": [1, 2]},
            {"type": "tie", "particles": [0, 2]},
        ],
    }


def anchors() -> Dict[str, Any]:
    """Anchors: the type's point, a link's own point, and the default (initial position)."""
    return {
        "dt": 0.01,
        "gravity": [0.0, -2.0, 0.0],
        "particles": [
            particle([1, 0, 0], vel=[0, 1, 0]),
            particle([0, 2, 0], mass=1.5, vel=[0.5, 0, 0.5]),
            particle([0, 0, 1], mass=0.8, vel=[1, 1, 0]),
        ],
        "types": {
            "hook": {"kind": "anchor", "stiffness": 12.0, "rest_length": 0.5, "damping": 0.2,
                     "point": [0, 0, 0]},
            "pin": {"kind": "anchor", "stiffness": 8.0},
        },
        "links": [
            {"type": "hook", "particles": [0]},
            {"type": "hook", "particles": [1], "point": [0.3, 1.0, -0.2]},
            {"type": "pin", "particles": [2]},
        ],
    }


def drags() -> Dict[str, Any]:
    """Projectiles in a viscous medium under gravity."""
    return {
        "dt": 0.01,
        "gravity": [0.0, 0.0, -9.81],
        "particles": [particle([0, 0, 0], vel=[3, 0, 5]),
                      particle([0, 1, 0], mass=0.3, vel=[-1, 2, 8])],
        "types": {"air": {"kind": "drag", "damping": 0.15}},
        "links": [{"type": "air", "particles": [0]}, {"type": "air", "particles": [1]}],
    }


def nonlinear_drags() -> Dict[str, Any]:
    """Falling masses whose speed crosses v_max, so both regimes act."""
    return {
        "dt": 0.01,
        "gravity": [0.0, 0.0, -9.81],
        "particles": [particle([0, 0, 0], vel=[0.5, 0, 0]),
                      particle([1, 0, 0], mass=0.5, vel=[0, 0, 4.0])],
        "types": {"medium": {"kind": "nonlinear_drag", "z1": 0.05, "z2": 1.5, "v_max": 3.0}},
        "links": [{"type": "medium", "particles": [0]}, {"type": "medium", "particles": [1]}],
    }


def angles() -> Dict[str, Any]:
    """A bent 4-particle chain with springs along it and angle links at its two joints."""
    return {
        "dt": 0.005,
        "particles": [
            particle([0, 0, 0]),
            particle([1, 0, 0], mass=1.2),
            particle([1.6, 0.8, 0.1], mass=0.8, vel=[0, 0, 0.5]),
            particle([1.5, 1.8, -0.3], vel=[0.3, 0, 0]),
        ],
        "types": {
            "bone": {"kind": "spring", "stiffness": 60.0, "rest_length": 1.0, "damping": 0.05},
            "joint": {"kind": "angle", "stiffness": 4.0, "rest_cos": -0.5},
            "joint2": {"kind": "angle", "stiffness": 2.5, "rest_cos": 0.2},
        },
        "links": [
            {"type": "bone", "particles": [0, 1]},
            {"type": "bone", "particles": [1, 2]},
            {"type": "bone", "particles": [2, 3]},
            {"type": "joint", "particles": [0, 1, 2]},
            {"type": "joint2", "particles": [1, 2, 3]},
        ],
    }


def _cloud(rng, n, center, spread, group, speed):
    return [particle(center + rng.uniform(-spread, spread, 3), mass=rng.uniform(0.5, 1.5),
                     vel=rng.normal(0, speed, 3), group=group) for _ in range(n)]


def gas(seed=1) -> Dict[str, Any]:
    """A cloud of 14 particles whose pairs attract and repel within range (one group)."""
    rng = np.random.default_rng(seed)
    return {
        "dt": 0.005,
        "particles": _cloud(rng, 14, np.zeros(3), 0.8, "gas", 0.4),
        "types": {"fluid": {"kind": "conditional", "stiffness": 30.0, "rest_length": 0.35,
                            "damping": 0.05, "range": 0.6, "groups": ["gas"]}},
        "links": [],
    }


def jet(seed=2) -> Dict[str, Any]:
    """A jet of 5 particles shot through a gas of 10: only jet–gas pairs interact."""
    rng = np.random.default_rng(seed)
    ps = _cloud(rng, 10, np.zeros(3), 0.7, "gas", 0.05)
    ps += [particle([-1.5 - 0.3 * i, rng.uniform(-0.2, 0.2), rng.uniform(-0.2, 0.2)],
                    mass=0.6, vel=[3.0, 0, 0], group="jet") for i in range(5)]
    return {
        "dt": 0.005,
        "particles": ps,
        "types": {
            "hit": {"kind": "conditional", "stiffness": 40.0, "rest_length": 0.4,
                    "range": 0.4, "groups": ["jet", "gas"]},
            "air": {"kind": "drag", "damping": 0.02},
        },
        "links": [{"type": "air", "particles": [i]} for i in range(15)],
    }


def pendulum() -> Dict[str, Any]:
    """A double pendulum under gravity (stiff springs), swinging out of plane."""
    return {
        "dt": 0.002,
        "gravity": [0.0, 0.0, -9.81],
        "particles": [particle([0, 0, 0], fixed=True), particle([1, 0, 0], vel=[0, 0.5, 0]),
                      particle([2, 0, 0.2], mass=0.5)],
        "types": {"rod": {"kind": "spring", "stiffness": 2000.0, "rest_length": 1.0}},
        "links": [{"type": "rod", "particles": [0, 1]}, {"type": "rod", "particles": [1, 2]}],
    }


def fixed_mix() -> Dict[str, Any]:
    """Fixed particles at both ends of a chain, one with a damper to a free particle."""
    return {
        "dt": 0.01,
        "gravity": [0.0, 0.0, -1.0],
        "particles": [particle([0, 0, 0], fixed=True), particle([1, 0.1, 0], vel=[0, 0, 1]),
                      particle([2, -0.1, 0], mass=0.5), particle([3, 0, 0], fixed=True)],
        "types": {"s": {"kind": "spring", "stiffness": 15.0, "rest_length": 0.9},
                  "d": {"kind": "damper", "damping": 0.3}},
        "links": [{"type": "s", "particles": [0, 1]}, {"type": "s", "particles": [1, 2]},
                  {"type": "s", "particles": [2, 3]}, {"type": "d", "particles": [3, 2]}],
    }


def cloth(tau=0.05) -> Dict[str, Any]:
    """A 4×3 hanging sheet of soft springs, top corners fixed, with Provot's limit."""
    w, h = 4, 3
    ps = []
    for r in range(h):
        for c in range(w):
            fixed = r == 0 and c in (0, w - 1)
            ps.append(particle([0.5 * c, 0.0, -0.5 * r], mass=0.2, fixed=fixed,
                               vel=[0, 0.3 * c, 0]))
    links = []
    for r in range(h):
        for c in range(w):
            i = r * w + c
            if c + 1 < w:
                links.append({"type": "weft", "particles": [i, i + 1]})
            if r + 1 < h:
                links.append({"type": "warp", "particles": [i, i + w]})
    return {
        "dt": 0.01,
        "gravity": [0.0, 0.0, -9.81],
        "particles": ps,
        "types": {
            "weft": {"kind": "spring", "stiffness": 8.0, "rest_length": 0.5, "damping": 0.02,
                     "max_elongation": tau},
            "warp": {"kind": "spring", "stiffness": 6.0, "rest_length": 0.5,
                     "max_elongation": tau},
        },
        "links": links,
    }


ALL = {
    "damped_chain": damped_chain,
    "dampers": dampers,
    "anchors": anchors,
    "drags": drags,
    "nonlinear_drags": nonlinear_drags,
    "angles": angles,
    "gas": gas,
    "jet": jet,
    "pendulum": pendulum,
    "fixed_mix": fixed_mix,
    "cloth": cloth,
}
