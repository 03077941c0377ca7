#!/usr/bin/env bash
# Builds the wheel of the Python package `cordis` (distribution cordis-anima) with
# `maturin build --release`, installs it into a fresh venv and runs its tests (mypy is for the
# stub check). MuJoCo is installed for the tests that compare with it.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
python="${PYTHON:-python3}"
venv="$(mktemp -d "${TMPDIR:-/tmp}/cordis-venv.XXXXXX")"
trap 'rm -rf "$venv"' EXIT

"$python" -m venv "$venv"
# The wheel a release would ship, built once (`maturin build --release`, the extension's only
# release build in CI) and installed like a user would: this checks that it installs into a
# fresh venv and imports, not only that the source tree builds. maturin is pinned as
# python/pyproject.toml's build-system pins it.
"$venv/bin/python" -m pip install --quiet "maturin>=1.7,<2"
wheels="$venv/wheels"
(cd python && "$venv/bin/maturin" build --release --out "$wheels" --quiet)
wheel=("$wheels"/cordis_anima-*.whl)
# With the ray extra, for the Ray executor's tests (python/tests/test_ray.py, about a minute
# with Ray's start-up); if Ray has no wheel for this Python, without it (those tests then skip).
if ! "$venv/bin/python" -m pip install --quiet "${wheel[0]}[ray]" pytest mypy hypothesis; then
    echo "python-test: the ray extra could not be installed; test_ray.py will be skipped" >&2
    "$venv/bin/python" -m pip install --quiet "${wheel[0]}" pytest mypy hypothesis
fi
(cd "$venv" && "$venv/bin/python" -c 'import cordis; print("python-test: installed cordis", cordis.__version__, "from", cordis.__file__)')
# The plot extra, for cordis.plot's tests and the examples/ scripts (a wheel: a few seconds),
# and imageio-ffmpeg (the video extra: an ffmpeg binary in a wheel) so that the .mp4 test of
# cordis.animate runs rather than skips without a system ffmpeg.
"$venv/bin/python" -m pip install --quiet matplotlib imageio-ffmpeg
# MuJoCo, for the MJCF export's replay test (test_mujoco.py) and the prediction score on MuJoCo's
# own cable (test_mujoco_prediction.py, benches/mujoco_prediction.py: 4.x flexcomp rods and the
# `discrete` integrator). Required: a test of an installable tool never skips in CI.
"$venv/bin/python" -m pip install --quiet "mujoco>=4,<5"
# An independent glTF reader for the export tests (test_export.py): pure Python.
"$venv/bin/python" -m pip install --quiet pygltflib
# A third-party C3D writer (pure Python) for the marker-reading tests (test_markers.py).
"$venv/bin/python" -m pip install --quiet c3d
# Run from the repository root so that `import cordis` finds the installed package (the source
# folder python/cordis/ has no compiled extension).
"$venv/bin/python" -m pytest python/tests -q
