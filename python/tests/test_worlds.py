"""Scenes with several worlds and couplings between them load and simulate from Python
(they come through JSON, so nothing Python-specific is needed)."""

import numpy as np
import pytest

import cordis


def two_worlds(ctrl_dt=0.004):
    return {
        "format": "cordis-scene/1",
        "dt": 0.01,
        "gravity": [0, -9.81, 0],
        "worlds": {"ctrl": {"dt": ctrl_dt}},
        "particles": [
            {"mass": 1.0, "pos": [0, 0, 0], "fixed": True},
            {"mass": 1.0, "pos": [1.3, 0, 0]},
            {"mass": 1.0, "pos": [0, 5, 0], "fixed": True, "world": "ctrl"},
            {"mass": 0.5, "pos": [0, 5.9, 0], "world": "ctrl"},
        ],
        "types": {
            "body": {"kind": "spring", "stiffness": 20.0, "rest_length": 1.0},
            "mind": {"kind": "spring", "stiffness": 10.0, "rest_length": 1.0},
            "q": {"kind": "quadripole", "stiffness": 15.0},
        },
        "links": [
            {"type": "body", "particles": [0, 1]},
            {"type": "mind", "particles": [2, 3]},
        ],
        "couplings": [{"type": "q", "particles": [0, 1, 2, 3]}],
    }


def test_worlds_round_trip_and_simulate():
    scene = cordis.Scene.from_dict(two_worlds())
    again = cordis.Scene.from_json(scene.to_json())
    assert again.to_dict() == scene.to_dict()
    assert scene.to_dict()["worlds"] == {"ctrl": {"dt": 0.004}}
    traj = scene.simulate(400)
    assert traj.shape == (400, 4, 3)
    assert np.all(np.isfinite(traj))
    # Gravity acts on the main world only: the ctrl particle stays on its line (x = 0, z = 0)
    # while the main one falls.
    assert np.all(traj[:, 3, 0] == 0.0)
    assert traj[:, 1, 1].min() < -0.5


def test_the_ctrl_world_dt_changes_the_motion():
    a = cordis.Scene.from_dict(two_worlds(0.004)).simulate(200)
    b = cordis.Scene.from_dict(two_worlds(0.002)).simulate(200)
    assert not np.array_equal(a[:, 3], b[:, 3])


def test_a_link_across_worlds_is_an_error_naming_it():
    d = two_worlds()
    d["links"][1]["particles"] = [1, 3]
    with pytest.raises(cordis.CordisError, match=r"links\[1\]\.particles\[1\]"):
        cordis.Scene.from_dict(d)
