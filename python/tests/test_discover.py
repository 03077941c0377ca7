"""cordis.discover: a generated network's links, masses and types from its motion alone."""

import os
import signal
import threading
import time
from pathlib import Path

import pytest

import cordis

SOFT = Path(__file__).resolve().parents[2] / "examples" / "data" / "soft-block"


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


def test_discover_takes_gravity_as_given():
    truth = cordis.random_network(2, 14, 4)
    traj = truth.simulate(300)
    d = truth.to_dict()
    total = sum(p["mass"] for p in d["particles"] if not p.get("fixed", False))
    g = tuple(d["gravity"])
    res = cordis.discover(traj, truth.dt, total_mass=total, gravity=g)
    assert tuple(res.scene.to_dict()["gravity"]) == g
    assert _pairs(res.scene) == _pairs(truth)
    assert res.undetermined == []
    # Noiseless data: the noise level was estimated, as none.
    assert res.noise_estimated and res.noise_level == 0.0
    with pytest.raises(cordis.CordisError, match=r"gravity\[1\]"):
        cordis.discover(traj, truth.dt, total_mass=total, gravity=(0.0, float("nan"), 0.0))


def test_discover_estimates_the_noise_and_warns_when_the_data_look_noisy():
    np = pytest.importorskip("numpy")
    truth = cordis.random_network(2, 14, 4)
    traj = np.asarray(truth.simulate(300))
    d = truth.to_dict()
    total = sum(p["mass"] for p in d["particles"] if not p.get("fixed", False))
    size = float(np.max(traj.max(axis=(0, 1)) - traj.min(axis=(0, 1))))
    sigma = 1e-4 * size
    noisy = traj + np.random.default_rng(7).normal(0.0, sigma, traj.shape)
    with pytest.warns(UserWarning, match="look noisy"):
        res = cordis.discover(noisy, truth.dt, total_mass=total)
    assert res.noise_estimated
    assert res.noise_level == pytest.approx(sigma, rel=0.1)
    given = cordis.discover(noisy, truth.dt, total_mass=total, noise_level=sigma)
    assert not given.noise_estimated and given.noise_level == sigma


def test_discover_reports_each_links_kind_and_takes_the_kinds_to_look_for():
    # random_network: particle 0 fixed, so links to it are anchors.
    truth = cordis.random_network(2, 14, 4)
    traj = truth.simulate(300)
    d = truth.to_dict()
    total = sum(p["mass"] for p in d["particles"] if not p.get("fixed", False))
    res = cordis.discover(traj, truth.dt, total_mass=total)
    kinds = {l["kind"] for l in res.links}
    assert kinds <= {"spring", "anchor", "damper"} and "spring" in kinds
    only = cordis.discover(traj, truth.dt, total_mass=total, kinds=["spring", "anchor"])
    assert all(l["kind"] != "damper" for l in only.links)
    assert _pairs(only.scene) == _pairs(truth)
    with pytest.raises(ValueError, match="dumper"):
        cordis.discover(traj, truth.dt, total_mass=total, kinds=["spring", "dumper"])


def test_discover_identify_returns_what_the_cli_writes(tmp_path):
    """`identify=True` (issue 20): the discovered network identified by output-error, the
    same scene the CLI's `--identify` writes, the estimator's status and intervals; closer to
    the truth than the discovered values (seed 6 at noise 1e-4)."""
    np = pytest.importorskip("numpy")
    truth = cordis.random_network(6, 10, 3)
    clean = np.asarray(truth.simulate(300))
    rng = np.random.default_rng(6)
    traj = clean + rng.normal(0.0, 1e-4 * np.ptp(clean), clean.shape)
    d = truth.to_dict()
    total = sum(p["mass"] for p in d["particles"] if not p.get("fixed", False))
    with pytest.warns(UserWarning, match="noisy"):
        res = cordis.discover(traj, truth.dt, total_mass=total, identify=True)
    ident = res.identification
    assert ident["end"] == "converged" and ident["converged"] is True
    assert ident["gravity_fitted"] is True
    assert ident["warnings"] == []  # the CLI's summary carries the same list
    for p in ident["params"]:
        # A damping found absent (0) has its interval cut at that floor: no negative damping.
        assert p["low"] < p["value"] < p["high"] or p["low"] == p["value"] == 0.0 < p["high"]
        # Floats as identify's stderr, never JSON's "inf" strings.
        assert all(isinstance(p[k], float) for k in ("stderr", "low", "high"))
    masses = [p["mass"] for p in d["particles"] if not p.get("fixed", False)]
    found = [p["mass"] for p in res.scene.to_dict()["particles"] if not p.get("fixed", False)]
    fitted = [p["mass"] for p in res.identified.to_dict()["particles"] if not p.get("fixed", False)]
    err = lambda got: np.mean(np.abs(np.subtract(got, masses)) / masses)
    assert err(fitted) * 10 < err(found)
    assert sum(fitted) == pytest.approx(total, rel=1e-12)

    path, out = tmp_path / "net.npy", tmp_path / "id.json"
    cordis.write_trajectory(path, traj)
    argv = ["cordis", "discover", "-t", str(path), "--dt", repr(truth.dt), "--total-mass",
            repr(total), "--identify", str(out), "--out", str(tmp_path / "found.json"), "-q"]
    from cordis import _cordis

    assert _cordis._cli_main(argv) == 0
    assert cordis.Scene.from_json(out).to_dict() == res.identified.to_dict()
    with pytest.warns(UserWarning, match="noisy"):
        plain = cordis.discover(traj, truth.dt, total_mass=total)
    assert plain.identified is None and plain.identification is None


def test_discover_link_test_returns_what_the_cli_writes(tmp_path):
    """`link_test=True` (issue 20): every candidate pair tested again by output error; the
    summary lists each pair's verdict (a probability, a score and the cut it is held to), the
    scene holds the kept pairs, and the CLI's `--link-test` writes the same scene."""
    np = pytest.importorskip("numpy")
    truth = cordis.random_network(3, 6, 2)
    clean = np.asarray(truth.simulate(300))
    rng = np.random.default_rng(3)
    traj = clean + rng.normal(0.0, 1e-3 * np.ptp(clean), clean.shape)
    d = truth.to_dict()
    total = sum(p["mass"] for p in d["particles"] if not p.get("fixed", False))
    with pytest.warns(UserWarning, match="noisy"):
        res = cordis.discover(traj, truth.dt, total_mass=total, link_test=True)
    lt = res.link_test
    assert lt["converged"] == (lt["end"] == "converged")
    assert lt["kept"] == sum(p["kept"] for p in lt["pairs"])
    for p in lt["pairs"]:
        assert 0.0 <= p["p_value"] <= 1.0
        assert p["kept"] == (lt["applied"] and p["score"] > p["threshold"])
    kept = {tuple(p["particles"]) for p in lt["pairs"] if p["kept"]}
    springs = {tuple(l["particles"]) for l in res.links if l["kind"] != "damper"}
    # Not applied (its fit above the noise): the selection's graph stands.
    assert springs == kept if lt["applied"] else lt["kept"] == 0

    path, out = tmp_path / "net.npy", tmp_path / "found.json"
    cordis.write_trajectory(path, traj)
    argv = ["cordis", "discover", "-t", str(path), "--dt", repr(truth.dt), "--total-mass",
            repr(total), "--link-test", "--out", str(out), "-q"]
    from cordis import _cordis

    assert _cordis._cli_main(argv) == 0
    assert cordis.Scene.from_json(out).to_dict() == res.scene.to_dict()
    with pytest.warns(UserWarning, match="noisy"):
        assert cordis.discover(traj, truth.dt, total_mass=total).link_test is None


def test_ctrl_c_during_discover_identify_raises_with_the_discovery():
    # The soft block's discovered network (16 types) takes minutes to identify: only the
    # interrupt ends it early. The discovery is kept on the exception, without identification.
    markers = cordis.read_trajectory(str(SOFT / "markers.csv"))
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    timer = threading.Timer(1.0, lambda: os.kill(os.getpid(), signal.SIGINT))
    start = time.monotonic()
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt) as e:
            cordis.discover(markers, 0.01, total_mass=0.36, identify=True)
    finally:
        timer.cancel()
        signal.signal(signal.SIGINT, previous)
    assert time.monotonic() - start < 90
    res = e.value.result
    assert res.identified is None and res.identification is None
    assert res.scene.num_particles == 27 and len(res.links) > 0


def test_ctrl_c_during_discovery_alone_still_hands_back_what_was_found():
    # Discovery does not stop in the middle (seconds): Ctrl-C during it is raised once it is
    # done, with the discovery on the exception rather than thrown away.
    markers = cordis.read_trajectory(str(SOFT / "markers.csv"))
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    timer = threading.Timer(0.2, lambda: os.kill(os.getpid(), signal.SIGINT))
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt) as e:
            cordis.discover(markers, 0.01, total_mass=0.36)
    finally:
        timer.cancel()
        signal.signal(signal.SIGINT, previous)
    res = e.value.result
    assert res.identified is None and res.scene.num_particles == 27
