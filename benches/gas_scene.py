"""A jittered 2-D gas for the memory benchmarks of BENCHMARKS.md (issue 17): N particles of
1 kg on a square grid of spacing 0.5 m (±5 cm), small random velocities, one conditional
type `near` (stiffness 5 N/m, rest length 0.55 m, range 0.8 m). Writes PREFIX-truth.json and
PREFIX-unknown.json, the latter with stiffness in [1, 20], rest length in [0.3, 0.8] and the
range in [0.5, RMAX] m unknown.

    python3 benches/gas_scene.py 3000 10 g3000
"""
import json
import random
import sys

n, rmax, out = int(sys.argv[1]), float(sys.argv[2]), sys.argv[3]
random.seed(1)
side = int(n ** 0.5) + 1
particles = []
for k in range(n):
    i, j = k % side, k // side
    particles.append({
        "mass": 1.0,
        "pos": [0.5 * i + random.uniform(-0.05, 0.05), 0.5 * j + random.uniform(-0.05, 0.05), 0.0],
        "vel": [random.uniform(-0.1, 0.1), random.uniform(-0.1, 0.1), 0.0],
        "group": "gas",
    })
truth = {"dt": 0.01, "particles": particles,
         "types": {"near": {"kind": "conditional", "stiffness": 5.0, "rest_length": 0.55,
                            "range": 0.8, "groups": ["gas"]}}}
with open(out + "-truth.json", "w") as f:
    json.dump(truth, f)
truth["types"]["near"].update({"stiffness": {"min": 1.0, "max": 20.0},
                               "rest_length": {"min": 0.3, "max": 0.8},
                               "range": {"min": 0.5, "max": rmax}})
with open(out + "-unknown.json", "w") as f:
    json.dump(truth, f)
