"""`IdentifyResult.write_report`: the identification report page from Python (issue 18,
Deliver 4), the same page as `cordis report` (its browser test is tests/viewer/screenshot.sh)."""

import warnings

import numpy as np
import pytest

import cordis


@pytest.fixture(scope="module")
def fitted():
    truth = cordis.example("rigid")
    rng = np.random.default_rng(3)
    observed = truth.simulate(100) + rng.normal(0.0, 1e-3, (100, 15, 3))
    res = cordis.identify(cordis.example("rigid", unknowns=True), observed,
                          strategy="output-error")
    return res, observed


def test_the_report_has_every_section_and_this_runs_intervals(tmp_path, fitted):
    res, observed = fitted
    res.write_report(tmp_path / "report.html", observed, title="rigid <noisy>")
    page = (tmp_path / "report.html").read_text()
    assert page.startswith("<!DOCTYPE html>")
    assert "<title>rigid &lt;noisy&gt;</title>" in page
    for section in ("data", "parameters", "markers", "residuals", "convergence", "replay"):
        assert f'<section id="{section}">' in page, section
    assert "identify: strategy</th><td>output-error" in page
    finite = [n for n, s in res.stderr.items() if np.isfinite(s)]
    assert finite, "output-error gives standard errors"
    assert page.count("(95 %)") == len(finite)
    assert page.count("<svg ") == 15 + 3  # a panel per marker, two residual charts, convergence
    assert "http://" not in page and "https://" not in page


def test_gaps_give_the_model_alone_in_the_replay_and_bad_input_raises(tmp_path, fitted):
    res, observed = fitted
    gappy = observed.copy()
    gappy[10:20, 3] = np.nan
    res.write_report(tmp_path / "gaps.html", gappy)
    page = (tmp_path / "gaps.html").read_text()
    assert "30 of 4500 coordinates" in page
    assert "the model alone (the observation has gaps" in page
    with pytest.raises(cordis.TrajectoryError, match="has 16 particles, the scene has 15"):
        res.write_report(tmp_path / "bad.html", np.zeros((5, 16, 3)))
    assert not (tmp_path / "bad.html").exists()
    with pytest.raises(ValueError, match=r"shape \(T, N, 3\)"):
        res.write_report(tmp_path / "bad.html", np.zeros((5, 15)))


def test_markers_and_weights_map_the_report_as_identify_does(tmp_path, fitted):
    # Three markers, given in the order 7, 2, 11: the page is about those particles only.
    res, observed = fitted
    three = observed[:, [7, 2, 11]]
    res.write_report(tmp_path / "m.html", three, markers=[7, 2, 11], weights=[1.0, 2.0, 0.5])
    page = (tmp_path / "m.html").read_text()
    assert "12 never observed" in page
    assert "weighted position RMS error</th><td>" in page
    with pytest.raises(ValueError, match=r"^markers\[1\]: particle 7 is already tracked"):
        res.write_report(tmp_path / "bad.html", three, markers=[7, 7, 11])
    with pytest.raises(ValueError, match=r"^weights\[0\]: must be a positive finite"):
        res.write_report(tmp_path / "bad.html", three, markers=[7, 2, 11], weights=[0, 1, 1])
    assert not (tmp_path / "bad.html").exists()


def test_the_report_takes_the_runs_own_markers_by_default(tmp_path):
    # A run fitted on markers given in another order than the scene's: the page maps them as
    # the run did without being told again (it used to read them in scene order, putting
    # each marker on the wrong particle: an RMS error of 0.12 m for a 1 mm fit).
    truth = cordis.example("rigid")
    rng = np.random.default_rng(4)
    order = [7, 2, 11, 0, 5, 14, 9, 3]
    observed = truth.simulate(60)[:, order] + rng.normal(0.0, 1e-4, (60, len(order), 3))
    res = cordis.identify(cordis.example("rigid", unknowns=True), observed,
                          strategy="output-error", markers=order)
    res.write_report(tmp_path / "own.html", observed)
    res.write_report(tmp_path / "told.html", observed, markers=order)
    assert (tmp_path / "own.html").read_text() == (tmp_path / "told.html").read_text()
    assert "7 never observed" in (tmp_path / "own.html").read_text()


def test_fixed_particles_observed_far_from_the_scene_are_warned(tmp_path):
    # The soft block's markers reversed: the clamped top layer's places hold the bottom
    # layer's motion, 20 cm away. The page would show a fit far worse than it was, silently
    # (`cordis report` warned; Python did not).
    from test_tracked import load
    guess, _, traj = load()
    res = cordis.identify(guess, traj)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res.write_report(tmp_path / "right.html", traj)
    with pytest.warns(UserWarning, match=r"^trajectory: 9 fixed particles are observed far from "
                      r"where the scene holds them .* check markers="):
        res.write_report(tmp_path / "reversed.html", traj[:, ::-1])
    assert (tmp_path / "reversed.html").exists()
