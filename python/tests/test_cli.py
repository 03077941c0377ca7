"""The `cordis` console script installed with the package is the Rust CLI."""

import json
import os
import shutil
import subprocess
import sys

import pytest

import cordis
from cordis import _cordis


def cordis_exe():
    exe = shutil.which("cordis", path=os.path.dirname(sys.executable))
    assert exe is not None, "the cordis console script is not installed beside python"
    return exe


def run(args, **kw):
    return subprocess.run(args, capture_output=True, text=True, timeout=120, **kw)


def test_console_script_writes_an_example():
    out = run([cordis_exe(), "example", "rigid"])
    assert out.returncode == 0, out.stderr
    assert cordis.Scene.from_json(out.stdout) == cordis.example("rigid")


def test_python_dash_m_cordis():
    out = run([sys.executable, "-m", "cordis", "--version"])
    assert out.returncode == 0
    assert out.stdout.strip() == f"cordis {cordis.__version__}"


def test_errors_are_one_line_with_the_cli_exit_codes(tmp_path):
    out = run([cordis_exe(), "simulate", str(tmp_path / "missing.json"), "--frames", "3"])
    assert out.returncode == 1
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and "missing.json" in lines[0]
    assert run([cordis_exe(), "no-such-command"]).returncode == 2


def test_cli_main_in_process(tmp_path):
    path = tmp_path / "cloth.json"
    assert _cordis._cli_main(["cordis", "example", "cloth", "--out", str(path)]) == 0
    assert cordis.Scene.from_json(path) == cordis.example("cloth")
    assert _cordis._cli_main(["cordis", "example", "nope"]) == 2


def test_cli_identify_equals_python_identify(tmp_path):
    """Same scene, trajectory, seed and options: the CLI's summary line and Python's result
    agree exactly (both run cordis_es::executor::run)."""
    truth = cordis.example("rigid")
    traj = truth.simulate(100)
    scene = cordis.example("rigid", unknowns=True)
    (tmp_path / "truth.json").write_text(truth.to_json())
    (tmp_path / "scene.json").write_text(scene.to_json())
    cordis.write_trajectory(tmp_path / "traj.npy", traj)
    out = run([cordis_exe(), "identify", "scene.json", "--trajectory", "traj.npy",
               "--truth", "truth.json", "--generations", "60", "--seed", "4",
               "--noise", "1e-5", "--out", "out.json", "-q"], cwd=tmp_path)
    assert out.returncode == 0, out.stderr
    summary = json.loads(out.stdout.strip().splitlines()[-1])
    res = cordis.identify(scene, traj, generations=60, seed=4, noise=1e-5, truth=truth)
    assert summary["cost"] == res.cost and summary["evals"] == res.evals
    assert summary["param_error_pct"] == res.param_error_pct
    assert summary["stopped_by"] == res.stopped_by == "converged"  # auto: output-error (noisy)
    assert cordis.Scene.from_json(tmp_path / "out.json") == res.scene


def test_json_output_parses_line_by_line(tmp_path):
    """`--json`: stdout is JSON objects only, one per line, for every command; a scene that
    would go to stdout is embedded in the summary."""
    def objects(args):
        out = run([cordis_exe(), *args, "--json", "-q"], cwd=tmp_path)
        assert out.returncode == 0, out.stderr
        assert out.stderr == ""
        return [json.loads(line) for line in out.stdout.splitlines()]

    [ex] = objects(["example", "rigid"])
    assert cordis.Scene.from_dict(ex["scene"]) == cordis.example("rigid")
    assert (ex["particles"], ex["frames"]) == (15, 100)
    [ex] = objects(["example", "rigid", "--out", "rigid.json"])
    assert ex["out"] == "rigid.json" and "scene" not in ex
    [sim] = objects(["simulate", "rigid.json", "--frames", "40", "--out", "rigid.npy"])
    assert sim["frames"] == 40 and sim["out"] == "rigid.npy"
    [c] = objects(["cost", "rigid.json", "--trajectory", "rigid.npy"])
    report = cordis.cost(cordis.example("rigid"), cordis.read_trajectory(tmp_path / "rigid.npy"))
    assert c["total"] == report.total and c["per_particle"] == report.per_particle.tolist()
    [chk] = objects(["check", "rigid.json"])
    assert chk["max_stability_ratio"] == cordis.example("rigid").stability()["max_stability_ratio"]


@pytest.mark.parametrize("args, code", [
    (["simulate", "missing.json", "--frames", "3"], 1),
    (["example", "nope"], 2),
])
def test_json_errors_carry_the_exit_code(tmp_path, args, code):
    out = run([cordis_exe(), *args, "--json"], cwd=tmp_path)
    assert out.returncode == code
    [err] = [json.loads(line) for line in out.stdout.splitlines()]
    assert err["exit_code"] == code and err["error"] in out.stderr
