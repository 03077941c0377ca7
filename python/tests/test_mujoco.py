"""The CORDIS scheme equals MuJoCo's semi-implicit Euler for point masses.

CORDIS: x(n+1) = 2 x(n) - x(n-1) + dt² a(n), v(n) = (x(n) - x(n-1)) / dt. Writing
v(n+1) = (x(n+1) - x(n)) / dt gives v(n+1) = v(n) + dt a(n), x(n+1) = x(n) + dt v(n+1):
MuJoCo's `integrator="Euler"` (with implicit damping off). A particle becomes a body with three
slide joints, a spring a spatial tendon with `stiffness`/`springlength`/`damping`, an anchor a
tendon to a site of the world body, a drag the slide joints' `damping`, a fixed particle a site
of the world body. Skipped where mujoco is not installed.
"""

from typing import Any, Dict, List

import numpy as np
import pytest

import cordis
import reference
import scenes

mujoco = pytest.importorskip("mujoco")

FRAMES = 300
RTOL = 1e-9


def _v(x) -> str:
    return " ".join(repr(float(c)) for c in x)


def to_mjcf(d: Dict[str, Any]) -> str:
    """MJCF of a scene made of springs, anchors (with a point) and drags."""
    ps = d["particles"]
    types = d["types"]
    drag = [0.0] * len(ps)
    tendons: List[str] = []
    world_sites: List[str] = []
    for k, link in enumerate(d.get("links", [])):
        t = types[link["type"]]
        kind = t["kind"]
        z = float(t.get("damping", 0.0))
        if kind == "drag":
            drag[link["particles"][0]] += z
            continue
        if kind == "spring":
            a, b = (f"p{i}" for i in link["particles"])
            l0 = float(t["rest_length"])
        elif kind == "anchor":
            point = link.get("point", t.get("point"))
            assert point is not None, "a zero-length tendon has no direction in MuJoCo"
            world_sites.append(f'<site name="anchor{k}" pos="{_v(point)}"/>')
            a, b = f"anchor{k}", f"p{link['particles'][0]}"
            l0 = float(t.get("rest_length", 0.0))
        else:
            raise ValueError(f"no MuJoCo equivalent for {kind} here")
        tendons.append(
            f'<spatial stiffness="{t["stiffness"]!r}" springlength="{l0!r}" damping="{z!r}">'
            f'<site site="{a}"/><site site="{b}"/></spatial>'
        )
    bodies = []
    for i, p in enumerate(ps):
        if p.get("fixed", False):
            world_sites.append(f'<site name="p{i}" pos="{_v(p["pos"])}"/>')
            continue
        joints = "".join(
            f'<joint name="p{i}{axis}" type="slide" axis="{_v(np.eye(3)[c])}" '
            f'damping="{drag[i]!r}"/>'
            for c, axis in enumerate("xyz")
        )
        bodies.append(
            f'<body name="b{i}" pos="{_v(p["pos"])}">'
            f'<inertial pos="0 0 0" mass="{float(p["mass"])!r}" diaginertia="1 1 1"/>'
            f'{joints}<site name="p{i}"/></body>'
        )
    g = d.get("gravity", [0.0, 0.0, 0.0])
    return (
        "<mujoco>"
        f'<option timestep="{float(d["dt"])!r}" gravity="{_v(g)}" integrator="Euler">'
        '<flag contact="disable" eulerdamp="disable"/></option>'
        f'<worldbody>{"".join(world_sites)}{"".join(bodies)}</worldbody>'
        f'<tendon>{"".join(tendons)}</tendon>'
        "</mujoco>"
    )


def simulate_mujoco(d: Dict[str, Any], frames: int) -> np.ndarray:
    model = mujoco.MjModel.from_xml_string(to_mjcf(d))
    data = mujoco.MjData(model)
    ps = d["particles"]
    x0 = np.array([p["pos"] for p in ps], dtype=float)
    adr = {}
    for i, p in enumerate(ps):
        if p.get("fixed", False):
            continue
        j = model.joint(f"p{i}x")
        adr[i] = (int(model.jnt_qposadr[j.id]), int(model.jnt_dofadr[j.id]))
        data.qvel[adr[i][1] : adr[i][1] + 3] = p.get("vel", [0.0, 0.0, 0.0])
    out = np.zeros((frames, len(ps), 3))
    for t in range(frames):
        out[t] = x0
        for i, (q, _) in adr.items():
            out[t, i] += data.qpos[q : q + 3]
        if t < frames - 1:
            mujoco.mj_step(model, data)
    return out


def mujoco_scenes():
    anchored = scenes.anchors()
    anchored["types"]["pin"]["point"] = [0.5, 0.5, 1.5]  # MuJoCo needs a non-zero length
    return {
        "damped_chain": scenes.damped_chain(),
        "pendulum": scenes.pendulum(),
        "anchors": anchored,
        "drags": scenes.drags(),
        "spring_3d": scenes.spring_on_fixed(k=50.0, z=0.2, v0=(0.3, 1.0, -0.4),
                                            gravity=(0.0, -3.0, 0.0)),
    }


@pytest.mark.parametrize("name", sorted(mujoco_scenes()))
def test_cordis_equals_mujoco_semi_implicit_euler(name):
    d = mujoco_scenes()[name]
    want = simulate_mujoco(d, FRAMES)
    got = cordis.Scene.from_dict(d).simulate(FRAMES)
    scale = reference.scale(want)
    assert scale > 0.05
    err = float(np.abs(got - want).max())
    assert err <= RTOL * scale, f"max |cordis - mujoco| = {err:.3e}, scale {scale:.3f} m"


def test_mujoco_comparison_can_fail():
    """A 1e-6 relative change of one stiffness is visible at this tolerance."""
    d = scenes.damped_chain()
    want = simulate_mujoco(d, FRAMES)
    d["types"]["stiff"]["stiffness"] *= 1 + 1e-6
    got = cordis.Scene.from_dict(d).simulate(FRAMES)
    assert np.abs(got - want).max() > RTOL * reference.scale(want)
