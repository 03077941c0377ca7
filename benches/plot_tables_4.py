"""Figure of thesis Tables 4.1 (cloth with τc) and 4.2 (fluid, eight parameters): cordis' error
per identified parameter against the thesis' own errors, from the files
`benches/thesis_tables_4.py` writes.

    python benches/thesis_tables_4.py            # writes target/tables-4/
    python benches/plot_tables_4.py [target/tables-4] [docs/images/thesis_tables_4.png]

Errors are |identified - reference| / reference in %, on a log axis (an error of 0 at the printed
digits is drawn at the axis' floor). The thesis' errors are its tables' printed values: Table 4.1
gives five parameters (l0 of three types 0.24, 0.09, 0.27 %, one stiffness 2.1 %, τc 0.58 %), drawn
as the largest of its group over every parameter of that group; Table 4.2 gives all eight.
"""

import json
import pathlib
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent))
from thesis_tables_4 import errors  # noqa: E402  (the error the tables print)

ROOT = pathlib.Path(__file__).resolve().parent.parent
FLOOR = 1e-13

# Thesis Table 4.1 (§4.2): the worst printed error of each group of parameters.
THESIS_4_1 = {"rest_length": 0.27, "stiffness": 2.1, "max_elongation": 0.58}
# Thesis Table 4.2 (§4.3): the eight printed errors.
THESIS_4_2 = {
    ("gas_viscous", "damping"): 0.04,
    ("gas_viscous", "damping_quadratic"): 0.16,
    ("gas_viscous", "range"): 0.0,
    ("jet_viscous", "damping"): 0.96,
    ("jet_viscous", "damping_quadratic"): 2.6,
    ("jet_viscous", "range"): 0.0,
    ("gas_elastic", "stiffness"): 0.0,
    ("gas_elastic", "range"): 0.0,
}


def rows(identified, truth, names, thesis):
    """(label, cordis' error, the thesis' error) per parameter, errors floored for the log axis."""
    found = errors(identified, truth, names)
    return [(name.replace(".", "\n", 1).replace("max_elongation", "τc"), max(err, FLOOR),
             max(t, FLOOR))
            for (name, _, _, err), t in zip(found, thesis)]


def table_4_1(out):
    truth = json.loads((out / "cloth.json").read_text())["types"]
    names = [(n, k) for k in ("rest_length", "stiffness") for n in truth]
    names.append(("structural_v", "max_elongation"))
    thesis = [THESIS_4_1[k] for _, k in names]
    return rows(out / "cloth-identified-0-cloth-kl-tauv.json", out / "cloth.json", names, thesis)


def table_4_2(out):
    return rows(out / "fluid-identified.json", out / "fluid-table-4-2.json", list(THESIS_4_2),
                list(THESIS_4_2.values()))


def panel(ax, rows, title):
    xs = range(len(rows))
    ax.bar(xs, [r[1] for r in rows], color="#3465a4", label="cordis (auto)")
    ax.scatter(xs, [r[2] for r in rows], color="#cc0000", marker="_", s=400, linewidths=3,
               label="thesis (printed error; 0.0 % at the floor)", zorder=3)
    ax.set_yscale("log")
    ax.set_ylim(FLOOR / 2, 1e5)  # headroom: the legend above the thesis marks
    ax.set_xticks(list(xs))
    ax.set_xticklabels([r[0] for r in rows], rotation=60, ha="right", fontsize=7)
    ax.set_ylabel("parameter error (%)")
    ax.set_title(title, fontsize=10)
    ax.grid(axis="y", alpha=0.3)
    ax.legend(fontsize=7, loc="upper left")


def main():
    out = pathlib.Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT / "target" / "tables-4"
    png = pathlib.Path(sys.argv[2]) if len(sys.argv) > 2 else ROOT / "docs" / "images" / "thesis_tables_4.png"
    fig, (a, b) = plt.subplots(1, 2, figsize=(13, 5), gridspec_kw={"width_ratios": [13, 8]})
    panel(a, table_4_1(out), "Table 4.1: cloth 32×32, 60 frames, l0, K, τc (vertical) unknown")
    panel(b, table_4_2(out), "Table 4.2: fluid, frames 40–51, the eight parameters unknown")
    fig.tight_layout()
    png.parent.mkdir(parents=True, exist_ok=True)
    tmp = png.with_suffix(".tmp.png")
    fig.savefig(tmp, dpi=110)
    tmp.replace(png)
    print(f"wrote {png}")


if __name__ == "__main__":
    main()
