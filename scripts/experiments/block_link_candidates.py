"""Per-link output-error candidates for the soft block (issue 20 experiment, BENCHMARKS
"Structure discovery on the varied generator", "Output-error per link on the soft block").

Writes a scene with one spring type per candidate pair (stiffness unknown in [0, 60] N/m, rest
length in ±30 % of the layout distance, damping in [0, 0.1] N·s/m): every pair with a moving end
closer than 0.175 m (the block's edges, face and body diagonals: its 138 true links), and with
`two` also the 21 pairs 0.2 m apart (two pitches along a line: not links). Then

    cordis identify cand-two.json -t ../shared/data/soft-block/markers.csv --threads 1 -o id.json

fits every candidate's stiffness from the markers; a link is a candidate whose stiffness the
motion holds away from 0.

Usage: python3 scripts/experiments/block_link_candidates.py GUESS.json [none|two] OUT.json
"""

import itertools
import json
import math
import sys


def main() -> None:
    guess_path, extra, out_path = sys.argv[1], sys.argv[2], sys.argv[3]
    scene = json.load(open(guess_path))
    particles = scene["particles"]
    candidates = []
    for i, j in itertools.combinations(range(len(particles)), 2):
        if particles[i].get("fixed") and particles[j].get("fixed"):
            continue
        d = math.dist(particles[i]["pos"], particles[j]["pos"])
        if d < 0.175 or (extra == "two" and abs(d - 0.2) < 1e-6):
            candidates.append((i, j, d))
    types, links = {}, []
    for k, (i, j, d) in enumerate(candidates):
        name = f"L{k}_{i}_{j}"
        types[name] = {
            "kind": "spring",
            "stiffness": {"min": 0, "max": 60},
            "rest_length": {"min": round(0.7 * d, 4), "max": round(1.3 * d, 4)},
            "damping": {"min": 0, "max": 0.1},
        }
        links.append({"type": name, "particles": [i, j]})
    scene["types"], scene["links"] = types, links
    json.dump(scene, open(out_path, "w"), indent=1)
    print(f"{len(candidates)} candidates -> {out_path}")


if __name__ == "__main__":
    main()
