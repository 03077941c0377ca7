"""`cordis export --mjcf` replays in MuJoCo as cordis simulates (issue 18, SPEC §7.3).

CORDIS: x(n+1) = 2 x(n) - x(n-1) + dt² a(n), v(n) = (x(n) - x(n-1)) / dt. Writing
v(n+1) = (x(n+1) - x(n)) / dt gives v(n+1) = v(n) + dt a(n), x(n+1) = x(n) + dt v(n+1):
MuJoCo's `integrator="Euler"` with implicit damping off. The model is the CLI's own export
(crates/cordis-core/src/export/mjcf.rs): body p{i} per particle on three slide joints, spatial
tendons for springs and anchors, fixed tendons for dampers, joint damping for drags, joint
stiffness for zero-length anchors, a keyframe for the initial velocities. MuJoCo is read back
only through its own API (body positions `xpos`), so this checks the file, not a copy of it.
Needs mujoco (scripts/python-test.sh installs it: CI never skips this).
"""

import copy
import os
import shutil
import subprocess
import sys
from typing import Any, Dict

import numpy as np
import pytest

import cordis
import reference
import scenes

mujoco = pytest.importorskip("mujoco")

FRAMES = 300
RTOL = 1e-9
PASSIVE = ("rigid", "cloth", "fluid", "horse")
EXPRESSIBLE = {"spring", "damper", "anchor", "drag"}


def cordis_exe() -> str:
    exe = shutil.which("cordis", path=os.path.dirname(sys.executable))
    assert exe is not None, "the cordis console script is not installed beside python"
    return exe


def export(tmp_path, d: Dict[str, Any], name="scene"):
    """Writes the scene, runs `cordis export --mjcf`, returns (process, xml path)."""
    scene_path = tmp_path / f"{name}.json"
    scene_path.write_text(cordis.Scene.from_dict(d).to_json())
    xml = tmp_path / f"{name}.xml"
    out = subprocess.run([cordis_exe(), "export", str(scene_path), "--mjcf", str(xml)],
                         capture_output=True, text=True, timeout=120)
    return out, xml


def simulate_mujoco(xml, particles: int, frames: int) -> np.ndarray:
    model = mujoco.MjModel.from_xml_path(str(xml))
    data = mujoco.MjData(model)
    if model.nkey:
        mujoco.mj_resetDataKeyframe(model, data, 0)
    mujoco.mj_kinematics(model, data)
    bodies = [model.body(f"p{i}").id for i in range(particles)]
    assert bodies == list(range(1, particles + 1)), "one body per particle, in particle order"
    out = np.zeros((frames, particles, 3))
    for t in range(frames):
        out[t] = data.xpos[bodies]
        if t < frames - 1:
            mujoco.mj_step(model, data)
            mujoco.mj_kinematics(model, data)
    return out


def without(d: Dict[str, Any], kinds=(), provot=False) -> Dict[str, Any]:
    """The scene without the link types of `kinds` (and without Provot's max_elongation)."""
    d = copy.deepcopy(d)
    gone = {n for n, t in d["types"].items() if t["kind"] in kinds}
    d["types"] = {n: t for n, t in d["types"].items() if n not in gone}
    d["links"] = [link for link in d.get("links", []) if link["type"] not in gone]
    if provot:
        for t in d["types"].values():
            t.pop("max_elongation", None)
    return d


def mujoco_scenes() -> Dict[str, Any]:
    anchored = scenes.anchors()
    anchored["types"]["pin"]["point"] = [0.5, 0.5, 1.5]  # a tendon away from its point
    return {
        "damped_chain": scenes.damped_chain(),
        "pendulum": scenes.pendulum(),
        "anchors": anchored,
        # The default anchor point is the start itself: a zero-length anchor, in the joints.
        "anchors_at_start": without(scenes.anchors(), kinds=()),
        "dampers": scenes.dampers(),
        "fixed_mix": scenes.fixed_mix(),
        "drags": scenes.drags(),
        "spring_3d": scenes.spring_on_fixed(k=50.0, z=0.2, v0=(0.3, 1.0, -0.4),
                                            gravity=(0.0, -3.0, 0.0)),
        # Shipped passive examples: rigid whole; of the others, what MuJoCo can express (each
        # is refused whole below, by the kinds it lacks).
        "example_rigid": cordis.example("rigid").to_dict(),
        "example_cloth_without_provot": without(cordis.example("cloth").to_dict(), provot=True),
        "example_horse_without_angles": without(cordis.example("horse").to_dict(), ("angle",)),
    }


@pytest.mark.parametrize("name", sorted(mujoco_scenes()))
def test_mjcf_export_replays_in_mujoco_as_cordis_simulates(tmp_path, name):
    d = mujoco_scenes()[name]
    out, xml = export(tmp_path, d)
    assert out.returncode == 0, out.stderr
    n = len(d["particles"])
    want = simulate_mujoco(xml, n, FRAMES)
    got = cordis.Scene.from_dict(d).simulate(FRAMES)
    scale = reference.scale(got)
    assert scale > 0.05
    assert float(np.abs(got - got[0]).max()) > 0.01 * scale, "the scene moves"
    err = float(np.abs(got - want).max())
    assert err <= RTOL * scale, f"max |cordis - mujoco| = {err:.3e}, scale {scale:.3f} m"


def test_zero_length_anchor_is_written_as_joint_stiffness(tmp_path):
    out, xml = export(tmp_path, scenes.anchors())
    assert out.returncode == 0, out.stderr
    text = xml.read_text()
    assert 'stiffness="8.0" springref="0.0"' in text  # "pin": 8 N/m at the start, no tendon
    assert text.count("<spatial ") == 2  # the two "hook" anchors


@pytest.mark.parametrize("name", cordis.EXAMPLES)
def test_every_example_exports_or_is_refused_by_the_kinds_it_has(tmp_path, name):
    d = cordis.example(name).to_dict()
    out, xml = export(tmp_path, d, name)
    kinds = {t["kind"] for t in d["types"].values()}
    provot = any("max_elongation" in t for t in d["types"].values())
    lacking = sorted(kinds - EXPRESSIBLE)
    if name == "rigid":
        assert out.returncode == 0 and xml.is_file(), out.stderr
        return
    assert name not in PASSIVE or lacking or provot, f"{name} should export"
    assert out.returncode == 2, out.stderr
    assert not xml.exists(), "a refused export writes nothing"
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1, out.stderr
    line = lines[0]
    assert line.startswith(f"error: {tmp_path / name}.json: types."), line
    assert "MuJoCo (MJCF) cannot express" in line, line
    for kind in lacking:
        assert kind in line, f"{kind} not named: {line}"
    if provot:
        assert "max_elongation" in line, line


def test_mujoco_comparison_can_fail(tmp_path):
    """A 1e-6 relative change of one stiffness is visible at this tolerance."""
    d = scenes.damped_chain()
    out, xml = export(tmp_path, d)
    assert out.returncode == 0, out.stderr
    want = simulate_mujoco(xml, len(d["particles"]), FRAMES)
    d["types"]["stiff"]["stiffness"] *= 1 + 1e-6
    got = cordis.Scene.from_dict(d).simulate(FRAMES)
    assert np.abs(got - want).max() > RTOL * reference.scale(want)
