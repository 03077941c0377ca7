"""The local-control muscle (SPEC §2.4) through Python: the shipped example round-trips through
a dict, simulates, and its neurons sustain the motion that passive springs damp out."""

import numpy as np
import pytest

import cordis


def _swing(x, a, b, frames):
    lengths = np.linalg.norm(x[frames, b] - x[frames, a], axis=-1)
    return lengths.max() - lengths.min()


def test_muscle_example_simulates_and_its_neurons_act():
    s = cordis.example("muscle")
    d = s.to_dict()
    assert s.num_particles == 3
    assert [t["kind"] for t in d["types"].values()] == ["muscle", "muscle"]
    assert all(len(t["w_len"]) == len(t["w_rate"]) == 1 for t in d["types"].values())
    assert cordis.Scene.from_dict(d) == s

    x = s.simulate(300)
    assert x.shape == (300, 3, 3) and np.isfinite(x).all()

    for t in d["types"].values():
        t["gain"] = 0.0  # silent neurons: plain damped springs
    p = cordis.Scene.from_dict(d).simulate(300)
    late = slice(200, 300)
    for a, b in [(0, 1), (1, 2)]:
        assert _swing(x, a, b, late) > 20 * _swing(p, a, b, late)


def test_muscle_unknowns_include_the_weights():
    d = cordis.example("muscle", unknowns=True, width=10.0, seed=1).to_dict()
    truth = cordis.example("muscle").to_dict()
    for name, t in d["types"].items():
        for key in ("w_len", "w_rate"):
            for box, w in zip(t[key], truth["types"][name][key]):
                assert isinstance(box, dict) and box["min"] < w < box["max"]


def test_levenberg_marquardt_identifies_the_muscle():
    truth = cordis.example("muscle")
    traj = truth.simulate(300)
    scene = cordis.example("muscle", unknowns=True, seed=0)
    res = cordis.identify(
        scene, traj, strategy="levenberg-marquardt", generations=None, truth=truth
    )
    assert res.strategy == "levenberg-marquardt"
    assert res.stopped_by == "converged"
    assert res.param_error_pct < 0.01
    assert res.evals < 1000
    with pytest.raises(ValueError, match="short cost"):
        cordis.identify(scene, traj, strategy="levenberg-marquardt", cost="horizon:3")
