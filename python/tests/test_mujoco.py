"""`cordis export --mjcf` replays in MuJoCo as cordis simulates (issue 18, SPEC §7.3).

CORDIS: x(n+1) = 2 x(n) - x(n-1) + dt² a(n), v(n) = (x(n) - x(n-1)) / dt. Writing
v(n+1) = (x(n+1) - x(n)) / dt gives v(n+1) = v(n) + dt a(n), x(n+1) = x(n) + dt v(n+1):
MuJoCo's `integrator="Euler"` with implicit damping off. The model is the CLI's own export
(crates/cordis-core/src/export/mjcf.rs): body p{i} per particle on three slide joints, spatial
tendons for springs and anchors, fixed tendons for dampers, joint damping for drags, joint
stiffness for zero-length anchors, a keyframe for the initial velocities. MuJoCo is read back
only through its own API (body positions `xpos`, `qpos`), so this checks the file, not a copy
of it. What MJCF has no element for (angle, conditional and plane links, damping_quadratic,
Provot's max_elongation) is `<custom>` data that `cordis.mujoco` applies: forces through
MuJoCo's passive callback, Provot's projection between `mj_step` calls; MuJoCo still
integrates every step. Needs mujoco (scripts/python-test.sh installs it: CI never skips this).
"""

import copy
import json
import os
import shutil
import subprocess
import sys
from typing import Any, Dict, Tuple

import numpy as np
import pytest

import cordis
import reference
import scenes

mujoco = pytest.importorskip("mujoco")
import cordis.mujoco  # noqa: E402  (after the skip: it needs mujoco)

FRAMES = 300
RTOL = 1e-9
# The shipped examples without energy injection (no muscle, TGR, transmitter nor signal):
# every one exports and replays (test_the_passive_examples_are_those_without_active_kinds).
PASSIVE = ("rigid", "cloth", "fluid", "horse", "bouncing-ball", "horse-ground")
ACTIVE = {"muscle", "tgr", "quadripole", "position_transmitter", "force_transmitter"}
NATIVE = {"spring", "damper", "anchor", "drag"}
# Examples whose own motion a one-ulp change of the start moves by more than RTOL / 10 of its
# extent before their default length ends: measured in
# test_every_passive_example_replays_in_mujoco_within_1e9 (horse-ground: a horse falling on a
# frictional ground, from frame ~330 of 530).
SENSITIVE = {"horse-ground"}


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


def replay(xml, frames: int) -> np.ndarray:
    """MuJoCo's motion with what MJCF lacks applied by cordis.mujoco."""
    with cordis.mujoco.load(xml) as sim:
        return sim.run(frames)


def mujoco_scenes() -> Dict[str, Any]:
    anchored = scenes.anchors()
    anchored["types"]["pin"]["point"] = [0.5, 0.5, 1.5]  # a tendon away from its point
    quadratic = scenes.damped_chain()
    for t in quadratic["types"].values():
        if t["kind"] == "spring":
            t["damping_quadratic"] = 0.4
    sticky = scenes.jet()
    sticky["types"]["hit"]["damping_quadratic"] = 0.3
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
        # What MJCF lacks, through cordis.mujoco: angles, conditional pairs (one group, two
        # groups, with Z₂), a spring's Z₂, Provot's projection with fixed ends.
        "angles": scenes.angles(),
        "gas": scenes.gas(),
        "jet_quadratic": sticky,
        "chain_quadratic": quadratic,
        "small_cloth": scenes.cloth(tau=0.05),
        # The examples' native parts alone (MuJoCo without any callback).
        "example_cloth_without_provot": without(cordis.example("cloth").to_dict(), provot=True),
        "example_horse_without_angles": without(cordis.example("horse").to_dict(), ("angle",)),
    }


@pytest.mark.parametrize("name", sorted(mujoco_scenes()))
def test_mjcf_export_replays_in_mujoco_as_cordis_simulates(tmp_path, name):
    d = mujoco_scenes()[name]
    out, xml = export(tmp_path, d)
    assert out.returncode == 0, out.stderr
    n = len(d["particles"])
    want = replay(xml, FRAMES)
    got = cordis.Scene.from_dict(d).simulate(FRAMES)
    scale = reference.scale(got)
    assert scale > 0.05
    assert float(np.abs(got - got[0]).max()) > 0.01 * scale, "the scene moves"
    err = float(np.abs(got - want).max())
    assert err <= RTOL * scale, f"max |cordis - mujoco| = {err:.3e}, scale {scale:.3f} m"
    if "<custom>" not in xml.read_text():
        # MuJoCo alone, read through its own body positions, is the same motion.
        plain = simulate_mujoco(xml, n, FRAMES)
        assert float(np.abs(got - plain).max()) <= RTOL * scale


def test_small_scenes_exercise_what_they_stand_for():
    """The callback scenes above switch pairs and hit Provot's limit (else they test little)."""
    for name in ("gas", "jet_quadratic"):
        d = mujoco_scenes()[name]
        traj = cordis.Scene.from_dict(d).simulate(FRAMES)
        counts = {len(reference.conditional_pairs(d, traj[t])) for t in range(0, FRAMES, 10)}
        assert len(counts) > 2 and max(counts) > 0, (name, counts)
    d = scenes.cloth(tau=0.05)
    traj = cordis.Scene.from_dict(d).simulate(FRAMES)
    free = without(d, provot=True)
    assert np.abs(cordis.Scene.from_dict(free).simulate(FRAMES) - traj).max() > 1e-3


def example_files(tmp_path, name: str) -> Tuple[Any, int, Any]:
    """`cordis example NAME` then `cordis export --mjcf`: (scene path, default frames, xml)."""
    scene_path = tmp_path / f"{name}.json"
    made = subprocess.run([cordis_exe(), "example", name, "--out", str(scene_path), "--json",
                           "-q"], capture_output=True, text=True, timeout=120)
    assert made.returncode == 0, made.stderr
    frames = json.loads(made.stdout)["frames"]
    xml = tmp_path / f"{name}.xml"
    out = subprocess.run([cordis_exe(), "export", str(scene_path), "--mjcf", str(xml)],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    return scene_path, frames, xml


def rounding_sensitivity(scene: cordis.Scene, frames: int, draws: int = 3) -> np.ndarray:
    """Per frame, how far cordis' own motion moves when every start coordinate moves by one
    ulp (largest over `draws` random directions): how well the start determines the motion."""
    got = scene.simulate(frames)
    rng = np.random.default_rng(7)
    worst = np.zeros(frames)
    for _ in range(draws):
        d = scene.to_dict()
        for p in d["particles"]:
            p["pos"] = [float(np.nextafter(c, np.inf if rng.random() < 0.5 else -np.inf))
                        for c in p["pos"]]
        moved = cordis.Scene.from_dict(d).simulate(frames)
        worst = np.maximum(worst, np.abs(moved - got).max(axis=(1, 2)))
    return worst


@pytest.mark.parametrize("name", PASSIVE)
def test_every_passive_example_replays_in_mujoco_within_1e9(tmp_path, name):
    """Each passive example over its default length, MuJoCo integrating: within 1e-9 of the
    motion's extent while the motion is determined to 1e-10 by its start (cordis moved by one
    ulp stays that close); where it is not (SENSITIVE), no closer than rounding allows: within
    10x of how far one ulp at the start moves cordis itself."""
    scene_path, frames, xml = example_files(tmp_path, name)
    scene = cordis.Scene.from_json(scene_path)
    want = replay(xml, frames)
    got = scene.simulate(frames)
    scale = reference.scale(got)
    err = np.abs(got - want).max(axis=(1, 2))
    sensitivity = rounding_sensitivity(scene, frames)
    undetermined = np.flatnonzero(sensitivity > 0.1 * RTOL * scale)
    window = int(undetermined[0]) if undetermined.size else frames
    assert (window < frames) == (name in SENSITIVE), (
        f"{name}: one ulp at the start moves the motion by > 1e-10 of its extent from frame "
        f"{window} of {frames}")
    assert window >= frames // 2, (name, window)
    worst = float(err[:window].max())
    assert worst <= RTOL * scale, (
        f"{name}: max |cordis - mujoco| over frames 0..{window} = {worst / scale:.2e} of the "
        f"extent {scale:.3f} m")
    # Beyond the window: as close as one ulp at the start keeps cordis to itself (×10).
    envelope = np.maximum.accumulate(sensitivity)[window:]
    late = err[window:]
    assert (late <= 10 * envelope).all(), (
        f"{name}: beyond the rounding envelope at frame {window + int(np.argmax(late > 10 * envelope))}")


@pytest.mark.parametrize("name", ["cloth", "fluid", "horse", "bouncing-ball"])
def test_without_cordis_mujoco_the_kinds_mjcf_lacks_are_missing(tmp_path, name):
    """Plain MuJoCo on the same file misses the angles, pairs, contact or Provot's limit: the
    comparison above depends on cordis.mujoco, and would see it wrong."""
    scene_path, frames, xml = example_files(tmp_path, name)
    if name == "fluid":
        frames = 50  # the jet has moved 5 m into the gas: no force, no pressure without it
    got = cordis.Scene.from_json(scene_path).simulate(frames)
    plain = simulate_mujoco(xml, len(got[0]), frames)
    assert np.abs(got - plain).max() > 1e-3 * reference.scale(got)


def test_the_passive_examples_are_those_without_active_kinds():
    passive = tuple(n for n in cordis.EXAMPLES
                    if not {t["kind"] for t in cordis.example(n).to_dict()["types"].values()}
                    & ACTIVE and not cordis.example(n).to_dict().get("signals"))
    assert passive == PASSIVE


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
    if name in PASSIVE:
        assert out.returncode == 0 and xml.is_file(), out.stderr
        lacking = sorted(kinds - NATIVE)
        if lacking or any("max_elongation" in t for t in d["types"].values()):
            assert "note: " in out.stderr and "cordis.mujoco.load" in out.stderr, out.stderr
            assert "<custom>" in xml.read_text()
        return
    assert out.returncode == 2, out.stderr
    assert not xml.exists(), "a refused export writes nothing"
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1, out.stderr
    line = lines[0]
    assert line.startswith(f"error: {tmp_path / name}.json: "), line
    assert "MuJoCo (MJCF) cannot express" in line, line
    for kind in sorted(kinds & ACTIVE):
        assert kind in line, f"{kind} not named: {line}"


def test_mujoco_comparison_can_fail(tmp_path):
    """A 1e-6 relative change of one stiffness is visible at this tolerance."""
    d = scenes.damped_chain()
    out, xml = export(tmp_path, d)
    assert out.returncode == 0, out.stderr
    want = simulate_mujoco(xml, len(d["particles"]), FRAMES)
    d["types"]["stiff"]["stiffness"] *= 1 + 1e-6
    got = cordis.Scene.from_dict(d).simulate(FRAMES)
    assert np.abs(got - want).max() > RTOL * reference.scale(want)


def test_an_angles_stiffness_change_is_visible_through_the_callback(tmp_path):
    """The callback's data are the scene's: a 1e-6 change of an angle's stiffness shows."""
    d = scenes.angles()
    out, xml = export(tmp_path, d)
    assert out.returncode == 0, out.stderr
    want = replay(xml, FRAMES)
    d["types"]["joint"]["stiffness"] *= 1 + 1e-6
    got = cordis.Scene.from_dict(d).simulate(FRAMES)
    assert np.abs(got - want).max() > RTOL * reference.scale(want)


def test_models_share_the_passive_callback_and_closing_unsets_it(tmp_path):
    """Two cordis models stepped in turn each get their own forces, another model compiles
    and steps meanwhile untouched, and the callback is unset once both are closed."""
    paths = {}
    for name, d in (("angles", scenes.angles()), ("gas", scenes.gas())):
        out, paths[name] = export(tmp_path, d, name)
        assert out.returncode == 0, out.stderr
    alone = {name: replay(xml, 50) for name, xml in paths.items()}
    assert mujoco.get_mjcb_passive() is None
    a, b = cordis.mujoco.load(paths["angles"]), cordis.mujoco.load(paths["gas"])
    frames = {"angles": [a.positions()], "gas": [b.positions()]}
    # Compiling a model while the dispatcher is set works (MuJoCo's compiler calls it).
    other = mujoco.MjModel.from_xml_path(str(paths["angles"]))
    other_data = mujoco.MjData(other)
    mujoco.mj_resetDataKeyframe(other, other_data, 0)
    for _ in range(49):
        a.step()
        b.step()
        mujoco.mj_step(other, other_data)
        frames["angles"].append(a.positions())
        frames["gas"].append(b.positions())
    a.close()
    assert mujoco.get_mjcb_passive() is not None, "b still needs it"
    b.close()
    assert mujoco.get_mjcb_passive() is None
    for name in alone:
        np.testing.assert_array_equal(np.array(frames[name]), alone[name])
    # The other model's data got no angle forces: it is the plain MuJoCo motion.
    plain = simulate_mujoco(paths["angles"], 4, 50)
    np.testing.assert_array_equal(other_data.xpos[1:5], plain[-2])


def test_a_passive_callback_set_by_someone_else_is_not_replaced(tmp_path):
    out, xml = export(tmp_path, scenes.angles())
    assert out.returncode == 0, out.stderr

    def theirs(model, data):
        pass

    mujoco.set_mjcb_passive(theirs)
    try:
        with pytest.raises(RuntimeError, match="passive-force callback is already set"):
            cordis.mujoco.load(xml)
        assert mujoco.get_mjcb_passive() is theirs
    finally:
        mujoco.set_mjcb_passive(None)
    with cordis.mujoco.load(xml) as sim:  # and with it unset, it loads
        assert sim.particles == 4


def test_near_pairs_are_the_brute_force_pairs():
    """cordis.mujoco's pair grid against every pair, in 3-D and flat, one group and two."""
    rng = np.random.default_rng(3)
    for flat in (False, True):
        x = rng.uniform(-2.0, 2.0, (300, 3))
        if flat:
            x[:, 2] = 0.5
        a, b = np.arange(0, 200), np.arange(200, 300)
        for r in (0.05, 0.3, 1.0, 10.0):
            i, j, _ = cordis.mujoco._near_pairs(x, a, None, r)
            got = {(min(p, q), max(p, q)) for p, q in zip(i.tolist(), j.tolist())}
            d = np.linalg.norm(x[a][:, None] - x[a][None], axis=2)
            want = {(int(p), int(q)) for p, q in zip(*np.nonzero(d < r)) if p < q}
            assert got == want and len(i) == len(want), (flat, r)
            i, j, _ = cordis.mujoco._near_pairs(x, a, b, r)
            got = set(zip(i.tolist(), j.tolist()))
            d = np.linalg.norm(x[a][:, None] - x[b][None], axis=2)
            want = {(int(a[p]), int(b[q])) for p, q in zip(*np.nonzero(d < r))}
            assert got == want and len(i) == len(want), (flat, r)


def test_a_model_of_another_layout_is_refused_by_its_field(tmp_path):
    out, xml = export(tmp_path, scenes.angles())
    assert out.returncode == 0, out.stderr
    text = xml.read_text().replace('name="cordis_format" size="1" data="1.0"',
                                   'name="cordis_format" size="1" data="2.0"')
    xml.write_text(text)
    with pytest.raises(ValueError, match="custom field cordis_format: \\[2.0\\]"):
        cordis.mujoco.load(xml)
