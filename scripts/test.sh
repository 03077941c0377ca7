#!/usr/bin/env bash
# Every test of cordis: formatting, lints, Rust tests (release: they simulate), then the Python
# package built into a fresh venv and its pytest suite. CI (`.ci/run`) calls this script.
set -euo pipefail
cd "$(dirname "$0")/.."

echo "== cargo fmt --check"
cargo fmt --all -- --check
echo "== cargo clippy (all targets, warnings are errors)"
cargo clippy --workspace --all-targets -- -D warnings
echo "== cargo test --release"
cargo test --release
echo "== python package + pytest"
bash scripts/python-test.sh
echo "== HTML viewer in headless Chromium (skipped without chromium)"
bash tests/viewer/screenshot.sh
