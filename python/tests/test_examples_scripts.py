"""Every script in the repository's examples/ runs to completion and writes what it promises."""

import os
import pathlib
import subprocess
import sys

import pytest

EXAMPLES = pathlib.Path(__file__).resolve().parents[2] / "examples"
SCRIPTS = sorted(EXAMPLES.glob("*.py")) if EXAMPLES.is_dir() else []
try:
    import matplotlib  # noqa: F401
    HAS_MATPLOTLIB = True
except ImportError:
    HAS_MATPLOTLIB = False

# What each script must leave in its output directory (scripts not listed: just run).
OUTPUTS = {
    "identify_rigid_noise.py": ["rigid_noise_convergence.png"],
    "cloth_motion.py": ["cloth.json", "cloth.npy", "cloth.gif", "cloth.html"],
    "compare_strategies.py": ["strategies_convergence.png", "strategies.jsonl", "pareto.png"],
}


@pytest.mark.skipif(not SCRIPTS, reason="not run from a repository checkout")
@pytest.mark.parametrize("script", SCRIPTS, ids=lambda p: p.name)
def test_example_script_runs(script, tmp_path):
    source = script.read_text()
    if not HAS_MATPLOTLIB and ("cordis.plot" in source or "cordis.animate" in source):
        pytest.skip("matplotlib is not installed")
    out = tmp_path / "results"
    env = dict(os.environ, CORDIS_OUT=str(out), MPLBACKEND="Agg")
    run = subprocess.run([sys.executable, str(script)], cwd=tmp_path, env=env,
                         capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stdout + run.stderr
    for name in OUTPUTS.get(script.name, []):
        assert (out / name).stat().st_size > 0, f"{script.name} did not write {name}"


def test_every_example_script_is_known():
    """A new script gets its expected outputs listed here (quickstart only prints)."""
    assert {p.name for p in SCRIPTS} - {"quickstart.py"} <= set(OUTPUTS)
