#!/usr/bin/env bash
# Thesis §4.1 on the `rigid` example: identify its 20 parameters (boxes 25× wide) from 100
# frames with Gaussian noise σ = 0, 1e-4, 1e-3, 1e-2 of the object's size (1.2 m), population
# 100, 1000 generations, strategy `thesis`. Writes the convergence logs to $OUT (default
# target/rigid-noise), a table on stdout, and the figure docs/images/rigid_convergence.png
# when matplotlib is importable by $PYTHON (default python3).
set -euo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-target/rigid-noise}
PYTHON=${PYTHON:-python3}
mkdir -p "$OUT"
cargo build --release -q -p cordis-cli
C=target/release/cordis
$C example rigid --out "$OUT/rigid.json" 2>/dev/null
$C simulate "$OUT/rigid.json" --frames 100 --out "$OUT/rigid.csv" -q >/dev/null
$C example rigid --unknowns --out "$OUT/rigid-unknown.json" 2>/dev/null
SIZE=1.2
echo "| noise σ / size | σ (m) | final cost | rmse (m) | mean parameter error (%) | seconds |"
echo "|---|---|---|---|---|---|"
for rel in 0 1e-4 1e-3 1e-2; do
  sigma=$(python3 -c "print($rel*$SIZE)")
  line=$($C identify "$OUT/rigid-unknown.json" --trajectory "$OUT/rigid.csv" --truth "$OUT/rigid.json" \
      --strategy thesis --population 100 --generations 1000 --seed 1 --noise "$sigma" \
      --log "$OUT/conv_$rel.csv" --out "$OUT/identified_$rel.json" -q)
  python3 - "$rel" "$sigma" "$line" <<'PY'
import json, sys
rel, sigma, s = sys.argv[1], float(sys.argv[2]), json.loads(sys.argv[3])
print(f"| {rel} | {sigma:.2e} | {s['cost']:.3e} | {s['rmse']:.3e} | {s['param_error_pct']:.3e} | {s['seconds']:.2f} |")
PY
done
if $PYTHON -c "import matplotlib" 2>/dev/null; then
  $PYTHON benches/plot_convergence.py "$OUT" docs/images/rigid_convergence.png
fi
