"""The type stubs (cordis/_cordis.pyi) describe the compiled module exactly (mypy stubtest)."""

import os
import subprocess
import sys

import pytest

pytest.importorskip("mypy")


def test_stubs_match_the_extension(tmp_path):
    # Run outside the source tree so that the installed package is the one inspected.
    env = dict(os.environ, MYPY_CACHE_DIR=str(tmp_path / "cache"))
    out = subprocess.run(
        [sys.executable, "-m", "mypy.stubtest", "cordis._cordis"],
        cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300,
    )
    assert out.returncode == 0, out.stdout + out.stderr
