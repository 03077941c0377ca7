#!/usr/bin/env bash
# Thesis §6.2 (issue 6): the neuro-mechanical model against the passive one, same strategy
# (CMA-ES, λ = 16) and budget, several seeds, on
#   - `muscle` (3 particles, 2 muscles; 200 frames; every parameter but the gains unknown,
#     boxes 10x wide; passive: the muscles as springs with the same K, l0, Z boxes), and
#   - `horse-gait` (53 frames; the four leg muscles' types unknown, boxes 10x wide, every
#     other value known; passive: those links as springs, same K, l0, Z boxes).
# Writes one convergence log per (example, model, seed) into OUT_DIR and prints the final
# costs; benches/plot_neuro_passive.py draws docs/images/neuro_vs_passive.png from them.
#
#   bash benches/neuro_vs_passive.sh [OUT_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
C=${CORDIS:-target/release/cordis}
OUT=${1:-/tmp/cordis-neuro-passive}
SEEDS=${SEEDS:-1 2 3}
mkdir -p "$OUT"
MUS=front_left_1-girth,front_right_1-girth,hind_left_1-belly,hind_right_1-belly
$C example muscle -o "$OUT/muscle.json" 2>/dev/null
$C simulate "$OUT/muscle.json" -n 200 -o "$OUT/muscle.csv" -q >/dev/null
$C example muscle --unknowns --width 10 --seed 9 -o "$OUT/muscle_neuro.json" 2>/dev/null
$C example muscle --passive --unknowns --width 10 --seed 9 -o "$OUT/muscle_passive.json" 2>/dev/null
$C example horse-gait -o "$OUT/horse.json" 2>/dev/null
$C simulate "$OUT/horse.json" -n 53 -o "$OUT/horse.csv" -q >/dev/null
$C example horse-gait --unknowns --width 10 --unknown-types $MUS -o "$OUT/horse_neuro.json" 2>/dev/null
$C example horse-gait --passive --unknowns --width 10 --unknown-types $MUS \
  -o "$OUT/horse_passive.json" 2>/dev/null
printf '%-7s %-8s %-5s %-12s %s\n' example model seed cost rmse
for ex in muscle horse; do
  evals=12000
  [ $ex = horse ] && evals=20000
  for model in neuro passive; do
    for seed in $SEEDS; do
      line=$($C identify "$OUT/${ex}_$model.json" -t "$OUT/$ex.csv" --strategy cmaes -p 16 \
        --max-evals $evals --seed "$seed" --threads 1 -q --log "$OUT/${ex}_${model}_$seed.csv")
      echo "$line" | python3 -c "import json,sys; d=json.load(sys.stdin); print('%-7s %-8s %-5s %-12.4g %.4g' % ('$ex', '$model', '$seed', d['cost'], d['rmse']))"
    done
  done
done
