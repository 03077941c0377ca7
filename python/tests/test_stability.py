"""Scene.stability(): the per-particle stability bound, as `cordis check` reports it."""

import math

import numpy as np
import pytest

import cordis


def anchored(k_dt2_over_m, mass=2.0, dt=0.01, damping=0.0):
    """One mass 1 m from an anchor at the origin with K dt²/m = k_dt2_over_m."""
    return cordis.Scene.from_dict({
        "format": "cordis-scene/1", "dt": dt,
        "particles": [{"mass": mass, "pos": [1.0, 0.0, 0.0]}],
        "types": {"a": {"kind": "anchor", "stiffness": k_dt2_over_m * mass / dt**2,
                        "damping": damping, "point": [0.0, 0.0, 0.0]}},
        "links": [{"type": "a", "particles": [0]}],
    })


def test_acceptance_ratios_and_verdicts():
    stable = anchored(3.8).stability()
    assert stable["max_stability_ratio"] == pytest.approx(0.95, rel=1e-12)
    assert stable["stable"] is True
    assert stable["worst_particle"] == 0
    assert stable["per_particle"] == [stable["max_stability_ratio"]]
    assert stable["max_stable_dt"] == pytest.approx(0.01 / math.sqrt(0.95), rel=1e-12)
    traj = anchored(3.8).simulate(5000)
    assert np.isfinite(traj).all() and np.abs(traj).max() <= 1 / math.sqrt(0.05) + 1e-9

    unstable = anchored(4.2).stability()
    assert unstable["max_stability_ratio"] == pytest.approx(1.05, rel=1e-12)
    assert unstable["stable"] is False
    with pytest.raises(cordis.DivergedError, match=r"frame \d+, particle 0"):
        anchored(4.2).simulate(5000)


def test_damping_counts_twice_its_dt():
    r = anchored(1.0, damping=50.0).stability()  # Z dt / m = 0.25
    assert r["max_stability_ratio"] == pytest.approx((1.0 + 2 * 0.25) / 4, rel=1e-12)


def test_fixed_particles_have_no_ratio():
    s = cordis.Scene.from_dict({
        "format": "cordis-scene/1", "dt": 0.01,
        "particles": [{"mass": 1.0, "pos": [0, 0, 0], "fixed": True},
                      {"mass": 1.0, "pos": [1, 0, 0]}],
        "types": {"s": {"kind": "spring", "stiffness": 100.0, "rest_length": 1.0}},
        "links": [{"type": "s", "particles": [0, 1]}],
    })
    r = s.stability()
    assert r["per_particle"][0] is None
    assert r["per_particle"][1] == pytest.approx(100.0 * 1e-4 / 4, rel=1e-12)
    assert r["worst_particle"] == 1


def test_an_empty_scene_is_stable_at_any_step():
    r = cordis.Scene.from_dict({"format": "cordis-scene/1", "dt": 0.1, "particles": []}).stability()
    assert r == {"max_stability_ratio": 0.0, "stable": True, "worst_particle": None,
                 "local_max_ratio": 0.0, "max_stable_dt": None, "per_particle": []}
