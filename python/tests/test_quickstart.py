"""examples/quickstart.py runs and prints the table of true vs identified values."""

import pathlib
import subprocess
import sys

import pytest

QUICKSTART = pathlib.Path(__file__).resolve().parents[2] / "examples" / "quickstart.py"


@pytest.mark.skipif(not QUICKSTART.exists(), reason="not run from a repository checkout")
def test_quickstart_runs(tmp_path):
    out = subprocess.run([sys.executable, str(QUICKSTART)], cwd=tmp_path, capture_output=True,
                         text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    lines = out.stdout.splitlines()
    assert lines[0].split() == ["parameter", "true", "identified", "error", "%"]
    rows = [l.split() for l in lines[1:] if l.startswith("types.")]
    assert len(rows) == 20
    for name, true, found, err in rows:
        assert abs(float(found) - float(true)) <= 0.01 * abs(float(true)), name
    summary = lines[-1]
    assert summary.startswith("thesis: 500 generations") and "mean parameter error" in summary
    assert float(summary.split("mean parameter error ")[1].split()[0]) < 1.0
