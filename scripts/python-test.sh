#!/usr/bin/env bash
# Builds the Python package `cordis` (distribution cordis-anima) into a fresh venv and runs its
# tests (mypy is for the stub check). MuJoCo is installed for the scheme-equivalence test when
# pip can get it; that test skips itself otherwise.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
python="${PYTHON:-python3}"
venv="$(mktemp -d "${TMPDIR:-/tmp}/cordis-venv.XXXXXX")"
trap 'rm -rf "$venv"' EXIT

"$python" -m venv "$venv"
# With the ray extra, for the Ray executor's tests (python/tests/test_ray.py, ~1 min with Ray's
# start-up); if Ray has no wheel for this Python, without it (those tests then skip).
if ! "$venv/bin/python" -m pip install --quiet "./python[ray]" pytest mypy; then
    echo "python-test: the ray extra could not be installed; test_ray.py will be skipped" >&2
    "$venv/bin/python" -m pip install --quiet ./python pytest mypy
fi
# The plot extra, for cordis.plot's tests and the examples/ scripts (a wheel: a few seconds).
"$venv/bin/python" -m pip install --quiet matplotlib
if ! "$venv/bin/python" -m pip install --quiet mujoco; then
    echo "python-test: mujoco could not be installed; its comparison test will be skipped" >&2
fi
# Run from the repository root so that `import cordis` finds the installed package (the source
# folder python/cordis/ has no compiled extension).
"$venv/bin/python" -m pytest python/tests -q
