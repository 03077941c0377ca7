#!/usr/bin/env bash
# Stability-aware identification on the muscle-driven horse (issue 7 part 3, BENCHMARKS.md):
# the passive model (every link a spring, boxes 10x wide) identified from 53 frames of
# `horse-gait` by CMA-ES, with and without --stable-horizon 530 (10x the observed length),
# then run freely for 530 frames from the scene's initial state.
#
#   bash benches/stable_horizon.sh [OUT_DIR] [SEEDS...]
#
# One line per (seed, horizon): the short cost and rmse of the fit, and the free run's largest
# spread over the observed one (benches/spread_ratio.py), or the frame where it diverged.
set -euo pipefail
cd "$(dirname "$0")/.."
C=${CORDIS:-target/release/cordis}
OUT=${1:-/tmp/cordis-stable-horizon}
shift || true
SEEDS=${*:-1 2 3 4 5 6}
EVALS=${EVALS:-20000}
mkdir -p "$OUT"
$C example horse-gait -o "$OUT/truth.json" 2>/dev/null
$C simulate "$OUT/truth.json" -n 53 -o "$OUT/observed.csv" -q >/dev/null
$C simulate "$OUT/truth.json" -n 530 -o "$OUT/truth530.csv" -q >/dev/null
echo "truth: free run 530 frames, spread ratio $(python3 benches/spread_ratio.py "$OUT/observed.csv" "$OUT/truth530.csv")"
$C example horse-gait --passive --unknowns --width 10 -o "$OUT/passive.json" 2>/dev/null
printf '%-5s %-8s %-12s %-12s %s\n' seed horizon cost rmse "free run 530"
for seed in $SEEDS; do
  for h in none 530; do
    opt=()
    [ "$h" != none ] && opt=(--stable-horizon "$h")
    fit="$OUT/fit_${h}_$seed.json"
    line=$($C identify "$OUT/passive.json" -t "$OUT/observed.csv" --strategy cmaes \
      --max-evals "$EVALS" --seed "$seed" --threads 1 -q -o "$fit" "${opt[@]}")
    cost=$(echo "$line" | python3 -c 'import json,sys; d=json.load(sys.stdin); print("%.4g %.4g" % (d["cost"] or float("inf"), d["rmse"] or float("inf")))')
    if $C simulate "$fit" -n 530 -o "$OUT/run_${h}_$seed.csv" -q >"$OUT/sim.log" 2>&1; then
      run="spread x$(python3 benches/spread_ratio.py "$OUT/observed.csv" "$OUT/run_${h}_$seed.csv")"
    else
      run=$(grep -o 'diverged at frame [0-9]*' "$OUT/sim.log" || echo failed)
    fi
    printf '%-5s %-8s %-12s %-12s %s\n' "$seed" "$h" $cost "$run"
  done
done
