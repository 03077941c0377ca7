"""Thesis §6.2.1 (benches/neuro_vs_passive_621.sh): best short cost against generations of the
passive and the neuro-mechanical model on data from a passive model, with the thesis ES; one
curve per model and seed. Prints, per seed, the generations at which the order of the two best
costs changes (the crossings) and which model is ahead at the end.

    python3 benches/plot_neuro_passive_621.py OUT_DIR docs/images/neuro_vs_passive_621.png
"""
import csv
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read(path):
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return [int(r["generation"]) for r in rows], [float(r["best_cost"]) for r in rows]


def crossings(neuro, passive):
    """Generations at which the neuro-mechanical best passes below the passive best (+) or
    back above it (-)."""
    out = []
    for g in range(1, min(len(neuro), len(passive))):
        before, now = neuro[g - 1] < passive[g - 1], neuro[g] < passive[g]
        if before != now:
            out.append(f"{'+' if now else '-'}{g}")
    return out


def main(out_dir, png):
    fig, ax = plt.subplots(figsize=(7.5, 4.5))
    curves = {}
    for model, colour in [("passive", "#d62728"), ("neuro", "#1f77b4")]:
        for k, path in enumerate(sorted(Path(out_dir).glob(f"{model}_*.csv"))):
            g, cost = read(path)
            seed = path.stem.split("_")[-1]
            curves[(model, seed)] = cost
            label = ("neuro-mechanical" if model == "neuro" else "passive (standard)") if k == 0 else None
            ax.semilogy(g, [max(c, 1e-32) for c in cost], color=colour, alpha=0.8, label=label)
    ax.set(xlabel="generation (thesis ES, population 1000)", ylabel="best short cost (m²)",
           title="§6.2.1: data from a passive model (muscle, 200 frames)")
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    for (model, seed), cost in sorted(curves.items()):
        if model != "neuro" or ("passive", seed) not in curves:
            continue
        passive = curves[("passive", seed)]
        last = min(len(cost), len(passive)) - 1
        ahead = "neuro-mechanical" if cost[last] < passive[last] else "passive"
        print(f"seed {seed}: generation 0: neuro {cost[0]:.3g}, passive {passive[0]:.3g}; "
              f"crossings {crossings(cost, passive) or 'none'}; at generation {last}: "
              f"neuro {cost[last]:.3g}, passive {passive[last]:.3g} ({ahead} ahead)")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
