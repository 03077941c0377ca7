#!/usr/bin/env bash
# Thesis §6.2.1 ("Trajectoire artificielle", figures 6.10-6.13): data from a *passive* model
# (the `muscle` example's muscles as visco-elastic springs, 200 frames), identified by the
# passive model and by the neuro-mechanical one, both with the thesis ES as the text states it
# (`--strategy thesis`), population 1000 and 10,000 generations as in the thesis' figures.
# Every K, l0, Z unknown in boxes 10x wide (seed 9), and the neurons' weights in [-1, 2].
# Writes one convergence log per (model, seed) into OUT_DIR and prints the final costs;
# benches/plot_neuro_passive.py --621 draws docs/images/neuro_vs_passive_621.png from them.
#
#   bash benches/neuro_vs_passive_621.sh [OUT_DIR]
#   EXTRA="--descent-every 0" bash benches/neuro_vs_passive_621.sh OUT_DIR   # the ES alone
set -euo pipefail
cd "$(dirname "$0")/.."
C=${CORDIS:-target/release/cordis}
OUT=${1:-/tmp/cordis-neuro-passive-621}
SEEDS=${SEEDS:-1 2 3}
GENERATIONS=${GENERATIONS:-10000}
mkdir -p "$OUT"
$C example muscle --passive -o "$OUT/passive_truth.json" 2>/dev/null
$C simulate "$OUT/passive_truth.json" -n 200 -o "$OUT/passive.csv" -q >/dev/null
$C example muscle --unknowns --width 10 --seed 9 -o "$OUT/neuro.json" 2>/dev/null
$C example muscle --passive --unknowns --width 10 --seed 9 -o "$OUT/passive.json" 2>/dev/null
# The neuro-mechanical model must be able to be passive: every neuron weight in [-1, 2], which
# holds 0 (no neural force: the passive truth) off-centre. (The example's own boxes are made
# around the active truth's weights and may exclude 0: then the fit has a floor, 4.1e-13 m²
# here, the best the neurons can do while forced to act.)
python3 - "$OUT/neuro.json" <<'PY'
import json, sys
p = sys.argv[1]
d = json.load(open(p))
for t in d["types"].values():
    for key in ("w_len", "w_rate"):
        t[key] = [{"min": -1.0, "max": 2.0} for _ in t[key]]
json.dump(d, open(p, "w"), indent=1)
PY
printf '%-8s %-5s %-12s %s\n' model seed cost rmse
for model in passive neuro; do
  for seed in $SEEDS; do
    line=$($C identify "$OUT/$model.json" -t "$OUT/passive.csv" --strategy thesis -p 1000 \
      --generations "$GENERATIONS" --seed "$seed" --threads 1 -q ${EXTRA:-} --log "$OUT/${model}_$seed.csv")
    echo "$line" | python3 -c "import json,sys; d=json.load(sys.stdin); print('%-8s %-5s %-12.4g %.4g' % ('$model', '$seed', d['cost'], d['rmse']))"
  done
done
