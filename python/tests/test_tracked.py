"""Tracked motion through cordis.identify: NaN masks, `visible`, hidden particles, several
takes, the uncertainty on the result, and the CLI's estimate on the same data."""
import importlib.util
import json
import math
import os
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import cordis

SOFT = Path(__file__).resolve().parents[2] / "examples" / "data" / "soft-block"


def load():
    guess = cordis.Scene.from_json(SOFT / "guess.json")
    truth = cordis.Scene.from_json(SOFT / "truth.json")
    rows = np.loadtxt(SOFT / "markers.csv", delimiter=",", skiprows=1)
    frames, n = int(rows[:, 0].max()) + 1, int(rows[:, 1].max()) + 1
    traj = np.zeros((frames, n, 3))
    traj[rows[:, 0].astype(int), rows[:, 1].astype(int)] = rows[:, 2:]
    return guess, truth, traj


def error_pct(res, truth):
    t = truth.to_dict()["types"]
    errs = []
    for name, v in res.params.items():
        _, ty, p = name.split(".")
        errs.append(abs(v - t[ty][p]) / abs(t[ty][p]))
    return 100 * sum(errs) / len(errs)


def gaps(traj, seed=3):
    rng = np.random.default_rng(seed)
    out = traj.copy()
    out[rng.random(out.shape) < 0.1] = np.nan
    return out


def test_nan_is_a_missing_coordinate_and_the_result_has_its_uncertainty():
    guess, truth, traj = load()
    with _no_warning():
        res = cordis.identify(guess, gaps(traj), truth=truth)
    assert res.strategy == "output-error"
    assert res.stopped_by == "converged"
    assert res.param_error_pct < 5.0
    names = list(res.params)
    assert set(res.stderr) == set(names) == set(res.intervals)
    for n in names:
        lo, hi = res.intervals[n]
        assert lo < res.params[n] < hi
        assert res.stderr[n] > 0 and math.isfinite(res.stderr[n])
    cov = res.covariance
    assert cov.shape == (len(names), len(names))
    assert np.allclose(cov, cov.T) and np.all(np.diag(cov) > 0)
    assert np.allclose(np.sqrt(np.diag(cov)), [res.stderr[n] for n in names])
    # 1 mm of noise on the markers: σ̂ from the residuals.
    assert 0.9e-3 < res.sigma < 1.1e-3
    # The identified scene replays the take from its estimated initial state.
    replay = res.scene.simulate(traj.shape[0])
    assert np.sqrt(np.nanmean((replay - traj) ** 2)) < 1.2e-3


class _no_warning:
    def __enter__(self):
        import warnings
        self._w = warnings.catch_warnings()
        self._w.__enter__()
        warnings.simplefilter("error")

    def __exit__(self, *exc):
        return self._w.__exit__(*exc)


def test_visible_hides_like_nan():
    guess, _, traj = load()
    visible = np.ones(traj.shape[:2], dtype=bool)
    visible[50:80, 13] = False
    nan = traj.copy()
    nan[50:80, 13] = np.nan
    a = cordis.identify(guess, traj, visible=visible)
    b = cordis.identify(guess, nan)
    assert a.params == b.params and a.intervals == b.intervals
    # A nested list of the frames is the same take (it was read as a list of takes).
    c = cordis.identify(guess, nan.tolist())
    assert c.params == b.params
    # ArgumentErrors (CordisError and ValueError both), as every option out of its domain.
    with pytest.raises(cordis.ArgumentError, match="visible: shape"):
        cordis.identify(guess, traj, visible=visible[:10])
    with pytest.raises(cordis.ArgumentError, match=r"^traj: expected an array of shape \(T, N, 3\)"):
        cordis.identify(guess, traj[:, :, :2])


def test_a_take_without_a_mask_is_given_none_among_the_masks():
    # `visible=[None, mask]` raised a bare TypeError: None is "every particle visible", as
    # visible=None is for one take.
    guess, _, traj = load()
    second = traj[:120].copy()
    mask = np.ones(second.shape[:2], dtype=bool)
    mask[40:70, 13] = False
    a = cordis.identify(guess, [traj, second], visible=[None, mask])
    b = cordis.identify(guess, [traj, second], visible=[np.ones(traj.shape[:2], bool), mask])
    assert a.params == b.params and a.intervals == b.intervals
    with pytest.raises(TypeError, match=r"^visible\[1\]: expected a boolean array of shape "
                       r"\(120, 27\) or None \(all visible\), got str"):
        cordis.identify(guess, [traj, second], visible=[None, "all"])
    with pytest.raises(TypeError, match=r"^visible: expected a list of 2 masks"):
        cordis.identify(guess, [traj, second], visible=3)


def test_a_fit_the_run_stopped_has_no_sigma_its_report_the_residual_level():
    # res.sigma was None where the CLI's JSON gave solver.sigma: the two are the same number,
    # res.report["sigma"] (the CLI's solver), the residuals' level at the best point so far;
    # res.sigma is the estimate of the noise, None until the fit reached the whole take.
    guess, _, traj = load()
    with pytest.warns(UserWarning, match="before reaching the whole take"):
        res = cordis.identify(guess, traj, generations=1)
    assert res.stopped_by == "generations" and res.report["end"] == "stopped"
    assert res.sigma is None and res.stderr is None and res.intervals is None
    assert math.isfinite(res.report["sigma"]) and res.report["sigma"] > 0


def test_a_hidden_particle_is_simulated_not_compared():
    guess, truth, traj = load()
    hidden = traj.copy()
    hidden[:, 26] = np.nan  # a corner never tracked
    res = cordis.identify(guess, hidden, truth=truth)
    assert res.strategy == "output-error"
    assert res.param_error_pct < 5.0
    assert "missing" in res.report["chosen_because"]


def test_other_strategies_refuse_gaps_by_name():
    guess, _, traj = load()
    with pytest.raises(ValueError, match="missing observations: `thesis` needs every coordinate"):
        cordis.identify(guess, gaps(traj), strategy="thesis")


def test_several_takes_share_one_parameter_set():
    guess, truth, traj = load()
    other = cordis.Scene.from_json(SOFT / "truth.json")
    for p in other.particles:
        if not p.fixed:
            p.vel = [-0.2, 0.0, 0.1]
    second = other.simulate(120)
    res = cordis.identify(guess, [traj, second], truth=truth)
    assert res.strategy == "output-error"
    assert res.report["variables"] == 9 + 2 * 6 * 18
    assert res.param_error_pct < 5.0
    # One scene per take, each with its own estimated initial state: the second replays the
    # noiseless second take, which the first scene (take 0's state) does not.
    assert len(res.scenes) == 2
    assert res.scenes[0] is res.scene
    replay = res.scenes[1].simulate(120)
    assert np.sqrt(np.mean((replay - second) ** 2)) < 2e-3
    assert np.sqrt(np.mean((res.scenes[0].simulate(120) - second) ** 2)) > 1e-2


def test_the_cli_gives_the_same_estimate_and_intervals(tmp_path):
    guess, truth, traj = load()
    data = gaps(traj, seed=5)
    np.save(tmp_path / "gaps.npy", data)
    exe = shutil.which("cordis", path=os.path.dirname(sys.executable))
    out = subprocess.run(
        [exe, "identify", str(SOFT / "guess.json"), "-t", str(tmp_path / "gaps.npy"), "-q"],
        capture_output=True, text=True, timeout=120,
    )
    assert out.returncode == 0, out.stderr
    line = json.loads(out.stdout.strip().splitlines()[-1])
    res = cordis.identify(guess, data)
    assert line["strategy"] == res.strategy == "output-error"
    assert line["cost"] == res.cost
    cli = {u["name"]: (u["std_error"], tuple(u["interval"])) for u in line["solver"]["uncertainty"]}
    assert cli == {n: (res.stderr[n], res.intervals[n]) for n in res.params}


def test_markers_map_data_in_its_own_order_and_weights_match_the_cli(tmp_path):
    guess, truth, traj = load()
    order = list(range(26, 8, -1))  # the free particles, reversed; the clamped ones untracked
    data = traj[:, order]
    res = cordis.identify(guess, data, markers=order, truth=truth)
    assert res.strategy == "output-error" and res.stopped_by == "converged"
    assert res.param_error_pct < 5.0
    assert res.report["observed"] == 18 * 200 * 3
    weights = [0.5] * 2 + [1.0] * 16
    w = cordis.identify(guess, data, markers=order, weights=weights, truth=truth)
    assert w.cost != res.cost and w.param_error_pct < 5.0
    np.save(tmp_path / "m.npy", data)
    exe = shutil.which("cordis", path=os.path.dirname(sys.executable))
    out = subprocess.run(
        [exe, "identify", str(SOFT / "guess.json"), "-t", str(tmp_path / "m.npy"), "-q",
         "--markers", ",".join(map(str, order)), "--weights", ",".join(map(str, weights))],
        capture_output=True, text=True, timeout=120,
    )
    assert out.returncode == 0, out.stderr
    line = json.loads(out.stdout.strip().splitlines()[-1])
    assert line["cost"] == w.cost
    cli = {u["name"]: (u["std_error"], tuple(u["interval"])) for u in line["solver"]["uncertainty"]}
    assert cli == {n: (w.stderr[n], w.intervals[n]) for n in w.params}


def test_weights_per_coordinate_are_an_m_by_3_array():
    # A (M, 3) array (per marker, x y z) was refused: only the flat 3M sequence was read.
    guess, _, traj = load()
    w = np.ones((27, 3))
    w[13] = [0.5, 1.0, 2.0]
    a = cordis.identify(guess, traj, weights=w)
    b = cordis.identify(guess, traj, weights=list(w.ravel()))
    assert a.cost == b.cost and a.params == b.params and a.sigma == b.sigma
    with pytest.raises(cordis.ArgumentError, match=r"^weights: expected shape \(M,\) \(one weight per "
                       r"marker\) or \(M, 3\) .*, got shape \(27, 2\)"):
        cordis.identify(guess, traj, weights=np.ones((27, 2)))


@pytest.mark.parametrize("kw, says", [
    ({"markers": [0, 0]}, r"markers\[1\]: particle 0 is already tracked by marker 0"),
    ({"markers": [0, 99]}, r"markers\[1\]: particle 99 does not exist"),
    ({"markers": [0, -1]}, r"markers\[1\]: must be a non-negative integer"),
    ({"weights": [1.0] * 26 + [float("nan")]}, r"weights\[26\]: must be a positive finite"),
    ({"weights": [1.0, 0.0]}, r"weights\[1\]: must be a positive finite"),
    ({"weights": [1.0, 2.0]}, r"weights: holds 2 values for the 27 markers of trajectory"),
    ({"weights": [2.0] * 27, "strategy": "least-squares"}, r"per-marker weights"),
])
def test_bad_markers_and_weights_are_refused_by_name(kw, says):
    guess, _, traj = load()
    with pytest.raises(ValueError, match=says):
        cordis.identify(guess, traj, **kw)


@pytest.mark.parametrize("kw, says", [
    ({"markers": "1,2"}, r"^markers: expected a sequence of particle indices, got str"),
    ({"markers": [0, 10.5]}, r"^markers\[1\]: expected a particle index \(an integer\), got float 10.5"),
    ({"markers": [float("nan")]}, r"^markers\[0\]: expected a particle index \(an integer\), got float nan"),
    ({"weights": "heavy"}, r"^weights: expected an array of numbers"),
    ({"weights": 1.0}, r"^weights: expected a sequence of numbers, shape \(M,\) or \(M, 3\), got float"),
])
def test_markers_and_weights_of_the_wrong_type_name_the_argument(kw, says):
    guess, _, traj = load()
    with pytest.raises(TypeError, match=says):
        cordis.identify(guess, traj, **kw)


def test_a_robust_loss_downweights_a_marker_swap_and_the_cli_agrees(tmp_path):
    guess, truth, traj = load()
    swapped = traj.copy()
    swapped[60:100, [13, 14]] = traj[60:100, [14, 13]]
    res = cordis.identify(guess, swapped, loss="huber", truth=truth)
    assert res.strategy == "output-error" and res.stopped_by == "converged"
    assert "robust loss (huber)" in res.report["chosen_because"]
    assert res.report["loss"] == "huber" and res.report["downweighted"] >= 200
    assert res.param_error_pct < 5.0
    np.save(tmp_path / "s.npy", swapped)
    exe = shutil.which("cordis", path=os.path.dirname(sys.executable))
    out = subprocess.run(
        [exe, "identify", str(SOFT / "guess.json"), "-t", str(tmp_path / "s.npy"), "-q",
         "--loss", "huber"],
        capture_output=True, text=True, timeout=300,
    )
    assert out.returncode == 0, out.stderr
    assert json.loads(out.stdout.strip().splitlines()[-1])["cost"] == res.cost
    with pytest.raises(ValueError, match="loss: `l1` is not one of squared, huber, cauchy"):
        cordis.identify(guess, traj, loss="l1")


THIN_BENCH = Path(__file__).resolve().parents[2] / "benches" / "thin_coverage.py"


def swing(stiffness):
    """The thin-data bench's scene (benches/thin_coverage.py): one 1 kg particle swinging round
    an anchor (rest length 0.8 m, clear of its point)."""
    spec = importlib.util.spec_from_file_location("thin_coverage", THIN_BENCH)
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    return bench.swing(stiffness)


def test_profile_intervals_reach_as_far_as_the_likelihood_on_thin_data(tmp_path):
    # 30 frames of a 2 s swing at 10 cm noise: the cost is far flatter below the estimate than
    # its quadratic model, and seed 4's Wald interval [16, 100] N/m misses the true 10 N/m.
    truth, guess = swing(10.0), swing({"min": 1.0, "max": 100.0})
    traj = truth.simulate(frames=30)
    name = "types.a.stiffness"
    for seed in range(8):
        noisy = traj + np.random.default_rng(seed).normal(0.0, 0.1, traj.shape)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            wald = cordis.identify(guess, noisy, strategy="output-error")
            prof = cordis.identify(guess, noisy, strategy="output-error", intervals="profile")
        assert (wald.report["intervals"], prof.report["intervals"]) == ("wald", "profile")
        assert prof.params == wald.params and prof.stderr == wald.stderr
        (lo, hi), (wlo, whi) = prof.intervals[name], wald.intervals[name]
        assert lo <= wlo and hi >= whi and lo <= 10.0 <= hi, (seed, prof.intervals)
        if seed == 4:
            assert wlo > 10.0, wald.intervals
            [w] = prof.report["widened_intervals"]
            assert w["name"] == name and w["rise"][0] < 0.7 and lo < wlo
            np.save(tmp_path / "swing.npy", noisy)
            (tmp_path / "guess.json").write_text(guess.to_json())
            exe = shutil.which("cordis", path=os.path.dirname(sys.executable))
            out = subprocess.run(
                [exe, "identify", str(tmp_path / "guess.json"), "-t", str(tmp_path / "swing.npy"),
                 "--strategy", "output-error", "--intervals", "profile", "-q"],
                capture_output=True, text=True, timeout=120,
            )
            assert out.returncode == 0, out.stderr
            line = json.loads(out.stdout.strip().splitlines()[-1])
            [u] = line["solver"]["uncertainty"]
            assert tuple(u["interval"]) == prof.intervals[name]
    with pytest.raises(cordis.ArgumentError, match="^intervals: `likelihood` is not one of wald, profile"):
        cordis.identify(guess, traj, intervals="likelihood")
    with pytest.raises(cordis.ArgumentError, match="read by output-error only"):
        cordis.identify(guess, traj, strategy="cmaes", intervals="profile", generations=1)


def test_the_thin_coverage_bench_runs_and_profile_covers_at_least_as_often():
    # benches/thin_coverage.py (BENCHMARKS.md, "Coverage on thin data"), on a few draws.
    out = subprocess.run([sys.executable, str(THIN_BENCH), "--draws", "20", "--frames", "30"],
                         capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    [line] = [json.loads(x) for x in out.stdout.splitlines()]
    assert line["frames"] == 30 and line["draws"] == 20
    cov = line["coverage"]
    assert cov["profile"] >= cov["wald"] and cov["profile"] >= 0.9, cov
    assert line["widened"] > 0
