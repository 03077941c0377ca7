"""Thesis Tables 4.1 (cloth, with Provot's τc) and 4.2 (fluid, all eight parameters) with the
parameters issue 19 made identifiable: `max_elongation` boxes and `damping_quadratic`.

    python benches/thesis_tables_4.py [--thesis]   # needs numpy; writes target/tables-4/

Table 4.1: the `cloth` example (32×32, τc = 0.1 on the structural springs), 60 frames of its
fall, K and l0 of the 6 types unknown (`cordis example cloth --unknowns`, boxes 25× wide), the
dampings set back to their true values (the thesis identifies l0, K and τ), and τc of both
structural types unknown in [τc/5, 3τc] (a second run: the vertical one only). `auto` (which
takes levenberg-marquardt: the exact solvers refuse an unknown τc); `--thesis` adds the
thesis ES (population 100, 100 generations, Powell's descent from generation 50).

Table 4.2: the `fluid` example with the table's reference values on its gas and jet viscous
types (Z = 2.5 and 4, Z₂ = 1.25 and 2, ranges 1.5 and 2; the elastic K = 2, range 1.1 were
already the table's), simulated 60 frames, frames 40-51 kept (the jet inside the gas), and the
table's eight parameters unknown in boxes 25× wide placed off-centre by a seeded draw. `auto`
(hybrid: ranges swept, the rest exact).
"""

import json
import math
import pathlib
import random
import subprocess
import sys

import numpy as np

ROOT = pathlib.Path(__file__).resolve().parent.parent
OUT = ROOT / "target" / "tables-4"
CORDIS = ROOT / "target" / "release" / "cordis"


def cordis(*args):
    r = subprocess.run([str(CORDIS), *map(str, args)], capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit(f"cordis {' '.join(map(str, args))}: {r.stderr.strip()}")
    return r.stdout


def errors(identified, truth, names):
    a = json.loads(pathlib.Path(identified).read_text())["types"]
    t = json.loads(pathlib.Path(truth).read_text())["types"]
    return [(f"{n}.{k}", a[n][k], t[n][k], abs(a[n][k] - t[n][k]) / t[n][k] * 100) for n, k in names]


def identify(scene, traj, truth, out, *extra):
    line = cordis("identify", scene, "-t", traj, "--truth", truth, "--out", out, "-q", *extra)
    return json.loads(line.strip().splitlines()[-1])


def table_4_1(thesis):
    cloth, unknown = OUT / "cloth.json", OUT / "cloth-unknown.json"
    cordis("example", "cloth", "--out", cloth)
    cordis("example", "cloth", "--unknowns", "--out", unknown)
    traj = OUT / "cloth60.npy"
    cordis("simulate", cloth, "--frames", 60, "--out", traj, "-q")
    truth = json.loads(cloth.read_text())
    u = json.loads(unknown.read_text())
    for name, ty in u["types"].items():
        ty["damping"] = truth["types"][name]["damping"]
        if "max_elongation" in truth["types"][name]:
            tau = truth["types"][name]["max_elongation"]
            ty["max_elongation"] = {"min": tau / 5, "max": 3 * tau}
    both = OUT / "cloth-kl-tau.json"
    both.write_text(json.dumps(u))
    u["types"]["structural_h"]["max_elongation"] = truth["types"]["structural_h"]["max_elongation"]
    vertical = OUT / "cloth-kl-tauv.json"
    vertical.write_text(json.dumps(u))
    names = [(n, k) for n in truth["types"] for k in ("rest_length", "stiffness")]
    runs = [("both τc", both, ()), ("vertical τc", vertical, ())]
    if thesis:
        runs.append(("vertical τc, thesis", vertical, ("--strategy", "thesis", "--generations", 100,
                                                      "--descent-start", 50, "--descent-every", 50)))
    for label, scene, extra in runs:
        out = OUT / f"cloth-identified-{len(extra)}-{scene.stem}.json"
        s = identify(scene, traj, cloth, out, "--threads", 1, *extra)
        taus = [(n, "max_elongation") for n in ("structural_h", "structural_v")]
        rows = errors(out, cloth, names + taus)
        print(f"Table 4.1 ({label}): {s['strategy']}, {s['stopped_by']}, cost {s['cost']:.3e} m², "
              f"{s['evals']} evaluations, {s['seconds']:.2f} s, mean error {s['param_error_pct']:.3e} %")
        for name, v, t, e in rows:
            print(f"  {name:32s} {v:.9e}  truth {t:.6e}  error {e:.2e} %")


def table_4_2():
    fluid = OUT / "fluid.json"
    cordis("example", "fluid", "--out", fluid)
    s = json.loads(fluid.read_text())
    s["types"]["gas_viscous"].update(damping=2.5, damping_quadratic=1.25, range=1.5)
    s["types"]["jet_viscous"].update(damping=4.0, damping_quadratic=2.0, range=2.0)
    truth = OUT / "fluid-table-4-2.json"
    truth.write_text(json.dumps(s))
    full = OUT / "fluid60.npy"
    cordis("simulate", truth, "--frames", 60, "--out", full, "-q")
    traj = OUT / "fluid-40-51.npy"
    np.save(traj, np.load(full)[40:52])
    names = [("gas_viscous", "damping"), ("gas_viscous", "damping_quadratic"), ("gas_viscous", "range"),
             ("jet_viscous", "damping"), ("jet_viscous", "damping_quadratic"), ("jet_viscous", "range"),
             ("gas_elastic", "stiffness"), ("gas_elastic", "range")]
    r, lw = random.Random(1), math.log(25.0)
    for n, k in names:
        v, f = s["types"][n][k], 0.1 + 0.8 * r.random()
        s["types"][n][k] = {"min": v * math.exp(-f * lw), "max": v * math.exp((1 - f) * lw)}
    unknown = OUT / "fluid-table-4-2-unknown.json"
    unknown.write_text(json.dumps(s))
    out = OUT / "fluid-identified.json"
    res = identify(unknown, traj, truth, out)
    print(f"Table 4.2: {res['strategy']}, {res['stopped_by']}, cost {res['cost']:.3e} m², "
          f"{res['seconds']:.2f} s, mean error {res['param_error_pct']:.3e} %")
    for name, v, t, e in errors(out, truth, names):
        print(f"  {name:32s} {v:.9e}  truth {t:.6e}  error {e:.2e} %")
    for note in res["solver"]["notes"]:
        print("  note:", note)


if __name__ == "__main__":
    OUT.mkdir(parents=True, exist_ok=True)
    subprocess.run(["cargo", "build", "--release", "-q", "-p", "cordis-cli"], cwd=ROOT, check=True)
    table_4_1("--thesis" in sys.argv)
    table_4_2()
