"""Convergence of the neuro-mechanical and passive models (benches/neuro_vs_passive.sh): best
short cost against generations, one panel per example, one curve per model and seed.

    python3 benches/plot_neuro_passive.py OUT_DIR docs/images/neuro_vs_passive.png
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


def main(out_dir, png):
    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    titles = {
        "muscle": "muscle (3 particles, 2 muscles, 200 frames)",
        "horse": "horse-gait (4 leg muscles unknown, 53 frames)",
    }
    for ax, ex in zip(axes, ["muscle", "horse"]):
        for model, colour in [("neuro", "#1f77b4"), ("passive", "#d62728")]:
            paths = sorted(Path(out_dir).glob(f"{ex}_{model}_*.csv"))
            for k, path in enumerate(paths):
                g, cost = read(path)
                label = ("neuro-mechanical" if model == "neuro" else "passive") if k == 0 else None
                ax.semilogy(g, [max(c, 1e-32) for c in cost], color=colour, alpha=0.8, label=label)
        ax.set(xlabel="generation (CMA-ES, λ = 16)", ylabel="best short cost (m²)", title=titles[ex])
        ax.grid(True, which="major", alpha=0.3)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(png, dpi=110)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
