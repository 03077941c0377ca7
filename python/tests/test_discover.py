"""cordis.discover: a generated network's links, masses and types from its motion alone."""

import pytest

import cordis


def _pairs(scene):
    d = scene.to_dict()
    return {tuple(sorted(l["particles"])) for l in d["links"]}


def test_discover_finds_the_generating_network():
    truth = cordis.random_network(2, 14, 4)
    traj = truth.simulate(300)
    d = truth.to_dict()
    total = sum(p["mass"] for p in d["particles"] if not p.get("fixed", False))
    res = cordis.discover(traj, truth.dt, total_mass=total)
    assert isinstance(res, cordis.DiscoverResult)
    assert _pairs(res.scene) == _pairs(truth)
    assert res.scene.num_types == 4
    assert len(res.links) == res.scene.num_links
    assert all(l["score"] >= l["threshold"] for l in res.links)
    found = res.scene.to_dict()["particles"]
    for p, q in zip(d["particles"], found):
        if not p.get("fixed", False):
            assert q["mass"] == pytest.approx(p["mass"], rel=1e-3)
    assert "links" in repr(res)


def test_discover_needs_a_mass_scale():
    traj = cordis.random_network(1, 10, 3).simulate(50)
    with pytest.raises(cordis.CordisError, match="masses"):
        cordis.discover(traj, 0.005)
    with pytest.raises(ValueError, match="dt"):
        cordis.discover(traj, -1.0, total_mass=5.0)
