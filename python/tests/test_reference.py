"""cordis against the independent numpy reference of SPEC §2.1–2.2 (tests/reference.py)."""

import copy

import numpy as np
import pytest

import cordis
import reference
import scenes

FRAMES = 300
RTOL = 1e-9  # of the motion's scale


def compare(d, frames=FRAMES, stats=None):
    want = reference.simulate(d, frames, stats)
    got = cordis.Scene.from_dict(d).simulate(frames)
    assert got.shape == want.shape
    scale = reference.scale(want)
    assert scale > 0.05, "the scene should move enough for the comparison to mean something"
    err = float(np.abs(got - want).max())
    assert err <= RTOL * scale, f"max |cordis - reference| = {err:.3e}, scale {scale:.3f} m"
    return want


@pytest.mark.parametrize("name", sorted(scenes.ALL))
def test_matches_reference(name):
    compare(scenes.ALL[name]())


def test_nonlinear_drag_uses_both_regimes():
    d = scenes.nonlinear_drags()
    traj = compare(d)
    speed = np.linalg.norm(np.diff(traj, axis=0), axis=2) / d["dt"]
    v_max = d["types"]["medium"]["v_max"]
    assert (speed < v_max).any() and (speed >= v_max).any()


@pytest.mark.parametrize("make", [scenes.gas, scenes.jet])
def test_conditional_pairs_switch_on_and_off(make):
    d = make()
    traj = compare(d)
    sets = [frozenset(reference.conditional_pairs(d, x)) for x in traj]
    assert max(len(s) for s in sets) > 0
    assert len(set(sets)) > 3, "pairs should come and go during the run"


def test_two_groups_ignore_pairs_within_a_group():
    d = scenes.jet()
    traj = reference.simulate(d, 2)
    groups = [p.get("group") for p in d["particles"]]
    for i, j in reference.conditional_pairs(d, traj[0]) + reference.conditional_pairs(d, traj[1]):
        assert {groups[i], groups[j]} == {"jet", "gas"}


def test_provot_pass_is_exercised():
    stats = {}
    compare(scenes.cloth(), stats=stats)
    assert stats.get("provot", 0) > 10
    # ...and it matters: without the limit the motion is different.
    d = scenes.cloth()
    for t in d["types"].values():
        del t["max_elongation"]
    free = cordis.Scene.from_dict(d).simulate(FRAMES)
    limited = cordis.Scene.from_dict(scenes.cloth()).simulate(FRAMES)
    assert np.abs(free - limited).max() > 1e-3


def test_tolerance_detects_a_tiny_parameter_change():
    """The comparison is tight: a 1e-6 relative change of one stiffness breaks it."""
    d = scenes.damped_chain()
    want = reference.simulate(d, FRAMES)
    bent = copy.deepcopy(d)
    bent["types"]["soft"]["stiffness"] *= 1 + 1e-6
    got = cordis.Scene.from_dict(bent).simulate(FRAMES)
    assert np.abs(got - want).max() > RTOL * reference.scale(want)


def test_reference_angle_forces_are_minus_the_energy_gradient():
    rng = np.random.default_rng(5)
    for _ in range(20):
        x = rng.normal(size=(3, 3))
        k, c0 = 3.0, rng.uniform(-1, 1)
        forces = reference.angle_forces(x[0], x[1], x[2], k, c0)
        h = 1e-6
        for p in range(3):
            for c in range(3):
                xp, xm = x.copy(), x.copy()
                xp[p, c] += h
                xm[p, c] -= h
                grad = (reference.angle_energy(*xp, k, c0) - reference.angle_energy(*xm, k, c0)) / (2 * h)
                assert forces[p][c] == pytest.approx(-grad, abs=1e-7)
        assert np.allclose(sum(forces), 0.0, atol=1e-12)
