"""Plots the convergence logs of benches/rigid_noise.sh: best cost and mean parameter error
against generations, one curve per noise level (thesis Figure 4.1)."""
import csv
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402


def read(path):
    with open(path) as f:
        rows = list(csv.DictReader(f))
    g = [int(r["generation"]) for r in rows]
    cost = [float(r["best_cost"]) for r in rows]
    err = [float(r["param_error_pct"]) for r in rows]
    return g, cost, err


def main(out_dir, png):
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 4.2))
    for rel, colour in [("0", "#1f77b4"), ("1e-4", "#2ca02c"), ("1e-3", "#ff7f0e"), ("1e-2", "#d62728")]:
        path = Path(out_dir) / f"conv_{rel}.csv"
        if not path.exists():
            continue
        g, cost, err = read(path)
        label = "no noise" if rel == "0" else f"σ = {rel} × size"
        ax1.semilogy(g, [max(c, 1e-32) for c in cost], color=colour, label=label)
        ax2.semilogy(g, [max(e, 1e-14) for e in err], color=colour, label=label)
    ax1.set(xlabel="generation", ylabel="best short cost (m²)", title="Cost")
    ax2.set(xlabel="generation", ylabel="mean parameter error (%)", title="Parameter error")
    ax2.axhline(0.01, color="grey", lw=0.8, ls="--")
    ax2.text(5, 0.012, "0.01 % (thesis §4.1)", color="grey", fontsize=8)
    for ax in (ax1, ax2):
        ax.grid(True, which="major", alpha=0.3)
        ax.axvline(400, color="grey", lw=0.6, ls=":")
    ax1.legend(fontsize=8)
    fig.suptitle("rigid (15 masses, 20 unknowns): thesis strategy, population 100, 100 frames")
    fig.tight_layout()
    Path(png).parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(png, dpi=110)
    print(f"wrote {png}")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
