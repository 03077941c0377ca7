"""Prediction on motion no cordis model generated: MuJoCo's own cable and cloth (issue 16).

Real objects are not mass-spring networks. MuJoCo 4's deformables are: a 1-D flexcomp (a
discrete elastic rod, bending and torsion, inextensible edges held by soft equality
constraints) for the cable, a 2-D flexcomp (Saint Venant-Kirchhoff membrane and a discrete
hinge bending model) for the cloth, both stepped by MuJoCo's implicit integrator for flex
elasticity (``integrator="discrete"``; 4.0 refuses ``implicit`` for flexes). The cable is
clamped at one end (``<pin id="0 1"/>``), the cloth hangs from two corners of one edge; both
start straight/flat and horizontal with a seed-drawn sideways swing, and fall.

Each motion's vertex positions, one frame every ``frame_steps`` MuJoCo steps, become the
observed take. The cordis scene a user would write for it: a particle at each tracked point
(the object's weighed mass spread evenly), the pinned points fixed, springs between
neighbours along the cable (``stretch``) and the second neighbours (``bend``), and on the
cloth's grid the edges (``structural``), the diagonals (``shear``) and every second point
along the rows and columns (``bend``); every type's stiffness, rest length and damping unknown
in a wide box. cordis fits on the first 70 % of the frames and replays the whole take from
the estimated state, and the last 30 % is scored (PhysTwin's split): RMS distance between the
replayed and MuJoCo's positions of the free points.

Estimators: ``output-error`` (the maximum-likelihood fit, which estimates the initial state
too) and ``least-squares`` (the short cost's exact minimum). The short cost estimates no
state, so its parameters are replayed from the output-error machinery's state fit with those
parameters locked: the difference between the rows is the parameters only. Baselines that
use no model: every point held at its last fitted frame, and constant velocity (a line
through each point's last 10 fitted frames, extrapolated).

    pip install ./python mujoco && python benches/mujoco_prediction.py
    python benches/mujoco_prediction.py --motions cable --seeds 0 --noise 0   # one case

Prints one JSON line per (motion, seed, noise, method) and a table of medians.
"""

import argparse
import dataclasses
import json
import statistics
import sys
import time
import warnings
from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np

import cordis

FIT_FRACTION = 0.7
GRAVITY = (0.0, 0.0, -9.81)
BASELINE_LINE_FRAMES = 10


@dataclasses.dataclass
class Motion:
    """A recorded MuJoCo motion: what a tracker would give, plus what a user knows."""

    name: str
    positions: np.ndarray  # (T, N, 3) m, MuJoCo's vertex positions
    dt: float  # s between frames
    fixed: List[int]  # pinned points
    total_mass: float  # kg, the whole object
    links: Dict[str, List[Tuple[int, int]]]  # cordis link type -> neighbour pairs
    size: float  # m, the object's largest extent


def _step_record(model, data, frames: int, frame_steps: int) -> np.ndarray:
    import mujoco

    out = np.empty((frames, model.nflexvert, 3))
    for f in range(frames):
        out[f] = data.flexvert_xpos
        for _ in range(frame_steps):
            mujoco.mj_step(model, data)
    return out


def _swing(model, data, rng: np.random.Generator, name: str, speed: float, extent) -> None:
    """A seed-drawn initial velocity of every vertex body: a sideways and vertical flick
    growing with the distance from the pinned end (``extent`` maps a vertex to [0, 1])."""
    import mujoco

    direction = rng.normal(size=3)
    direction /= np.linalg.norm(direction)
    twist = rng.normal(size=3) * 0.3
    for b in range(model.nbody):
        body = model.body(b).name
        if not body.startswith(name + "_") or "twist" in body:
            continue
        vertex = int(body[len(name) + 1 :])
        dof = model.body_dofadr[b]
        if model.body_dofnum[b] != 3:
            continue
        s = extent(vertex)
        data.qvel[dof : dof + 3] = speed * s * (direction + twist * s)
    mujoco.mj_forward(model, data)


def mujoco_cable(
    seed: int = 0,
    points: int = 17,
    length: float = 0.4,
    frames: int = 300,
    frame_steps: int = 2,
    timestep: float = 1e-3,
) -> Motion:
    """A cable clamped at one end (points 0 and 1), starting horizontal, swung and falling."""
    import mujoco

    spacing = length / (points - 1)
    mass = 0.1
    xml = f"""
<mujoco>
  <option timestep="{timestep!r}" integrator="discrete" solver="Newton" gravity="{GRAVITY[0]} {GRAVITY[1]} {GRAVITY[2]}">
    <flag contact="disable"/>
  </option>
  <worldbody>
    <flexcomp name="cable" type="grid" dim="1" count="{points} 1 1" spacing="{spacing!r} {spacing!r} {spacing!r}"
              mass="{mass!r}" radius="0.004" pos="{length / 2!r} 0 1">
      <edge equality="true" solref="0.004 1"/>
      <elasticity young="3e6" shear="1e6" damping="0.005"/>
      <pin id="0 1"/>
    </flexcomp>
  </worldbody>
</mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    rng = np.random.default_rng(seed)
    _swing(model, data, rng, "cable", rng.uniform(0.5, 1.5), lambda v: v / (points - 1))
    pos = _step_record(model, data, frames, frame_steps)
    links = {
        "stretch": [(i, i + 1) for i in range(points - 1)],
        "bend": [(i, i + 2) for i in range(points - 2)],
    }
    return Motion("cable", pos, timestep * frame_steps, [0, 1], mass, links, length)


def mujoco_cloth(
    seed: int = 0,
    side: int = 5,
    spacing: float = 0.04,
    frames: int = 300,
    frame_steps: int = 2,
    timestep: float = 1e-3,
) -> Motion:
    """A square cloth hanging from the two corners of one edge, starting flat and horizontal."""
    import mujoco

    mass = 0.1
    xml = f"""
<mujoco>
  <option timestep="{timestep!r}" integrator="discrete" solver="Newton" gravity="{GRAVITY[0]} {GRAVITY[1]} {GRAVITY[2]}">
    <flag contact="disable"/>
  </option>
  <worldbody>
    <flexcomp name="cloth" type="grid" dim="2" count="{side} {side} 1" spacing="{spacing!r} {spacing!r} {spacing!r}"
              mass="{mass!r}" radius="0.002" pos="0 0 1">
      <elasticity young="5e5" poisson="0.2" thickness="1e-3" damping="1e-3" elastic2d="both"/>
      <pin id="0 {side - 1}"/>
    </flexcomp>
  </worldbody>
</mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    mujoco.mj_forward(model, data)
    rng = np.random.default_rng(seed)
    _swing(model, data, rng, "cloth", rng.uniform(0.3, 1.0), lambda v: (v // side) / (side - 1))
    pos = _step_record(model, data, frames, frame_steps)

    def at(i: int, j: int) -> int:
        return i * side + j

    structural, shear, bend = [], [], []
    for i in range(side):
        for j in range(side):
            if j + 1 < side:
                structural.append((at(i, j), at(i, j + 1)))
            if i + 1 < side:
                structural.append((at(i, j), at(i + 1, j)))
            if i + 1 < side and j + 1 < side:
                shear.append((at(i, j), at(i + 1, j + 1)))
                shear.append((at(i, j + 1), at(i + 1, j)))
            if j + 2 < side:
                bend.append((at(i, j), at(i, j + 2)))
            if i + 2 < side:
                bend.append((at(i, j), at(i + 2, j)))
    # The grid's vertex order must be the one the pairs assume: check it on the first frame.
    d = np.linalg.norm(pos[0][[a for a, _ in structural]] - pos[0][[b for _, b in structural]], axis=1)
    assert np.allclose(d, spacing, rtol=1e-6), "flexcomp grid order is not row-major"
    links = {"structural": structural, "shear": shear, "bend": bend}
    return Motion("cloth", pos, timestep * frame_steps, [0, side - 1], mass, links, spacing * (side - 1))


MOTIONS = {"cable": mujoco_cable, "cloth": mujoco_cloth}


def _degree(motion: Motion, n: int) -> int:
    """The most links any one point has."""
    deg = np.zeros(n, dtype=int)
    for pairs in motion.links.values():
        for i, j in pairs:
            deg[i] += 1
            deg[j] += 1
    return int(deg.max())


def boxes(motion: Motion, n: int, rule: str) -> Tuple[Tuple[float, float], Tuple[float, float]]:
    """(stiffness, damping) boxes of every type. ``wide``: 1e-3..1e4 N/m and 0..1 N·s/m, what a
    user guesses. ``stable``: the CORDIS step's bound (dt² ΣK + 2 dt ΣZ) / 4m < 1 per point,
    neighbours' motion counted (a factor 2, as ``Scene.stability`` reports it), with a 10 %
    margin, split evenly among the point's links, three quarters of it for stiffness and a
    quarter for damping: a scene anywhere in these boxes passes ``cordis check``."""
    if rule == "wide":
        return (1e-3, 1e4), (0.0, 1.0)
    if rule != "stable":
        raise ValueError(f"--boxes: `wide` or `stable`, got {rule!r}")
    m = motion.total_mass / n
    per_link = 0.9 * 2.0 * m / _degree(motion, n)
    k_top = 0.75 * per_link / motion.dt**2
    z_top = 0.25 * per_link / (2.0 * motion.dt)
    return (1e-3, k_top), (0.0, z_top)


def observed_state(observed: np.ndarray, dt: float, frames: int = 9) -> Tuple[np.ndarray, np.ndarray]:
    """Initial state from a least-squares quadratic through each point's first ``frames``
    observed frames: x(0), and the CORDIS velocity v(0) = (x(0) - x(-1)) / dt."""
    k = min(frames, observed.shape[0])
    t = np.arange(k) * dt
    c2, c1, c0 = np.polyfit(t, observed[:k].reshape(k, -1), 2)
    shape = observed.shape[1:]
    return c0.reshape(shape), (c1 - c2 * dt).reshape(shape)


def cordis_scene(motion: Motion, observed: np.ndarray, rule: str = "stable") -> cordis.Scene:
    """The scene a user would write for ``motion`` from the observed take (fit frames only):
    particles at the observed initial state (``observed_state``), the pinned points fixed at
    their observed mean, every type's stiffness, rest length and damping unknown (``boxes``;
    rest lengths 0.5..1.5 × the type's mean observed length at frame 0)."""
    n = observed.shape[1]
    x0, v0 = observed_state(observed, motion.dt)
    for i in motion.fixed:
        x0[i] = observed[:, i].mean(axis=0)
    mass = motion.total_mass / n
    particles = []
    for i in range(n):
        p: Dict[str, Any] = {"mass": mass, "pos": x0[i].tolist()}
        if i in motion.fixed:
            p["fixed"] = True
        else:
            p["vel"] = v0[i].tolist()
        particles.append(p)
    (k_lo, k_hi), (z_lo, z_hi) = boxes(motion, n, rule)
    types, links = {}, []
    for name, pairs in motion.links.items():
        a = np.array([p[0] for p in pairs])
        b = np.array([p[1] for p in pairs])
        spread = np.linalg.norm(x0[a] - x0[b], axis=1).mean()
        types[name] = {
            "kind": "spring",
            "stiffness": {"min": k_lo, "max": k_hi},
            "rest_length": {"min": 0.5 * spread, "max": 1.5 * spread},
            "damping": {"min": z_lo, "max": z_hi},
        }
        links += [{"type": name, "particles": [int(i), int(j)]} for i, j in pairs]
    d = {
        "format": "cordis-scene/1",
        "dt": motion.dt,
        "gravity": list(GRAVITY),
        "particles": particles,
        "types": types,
        "links": links,
    }
    return cordis.Scene.from_dict(d)


def _rms(pred: np.ndarray, truth: np.ndarray, free: np.ndarray) -> float:
    """RMS distance (m) between predicted and true positions of the free points."""
    if not np.all(np.isfinite(pred)):
        return float("inf")
    diff = pred[:, free] - truth[:, free]
    return float(np.sqrt(np.mean(np.sum(diff * diff, axis=-1))))


def baselines(observed_fit: np.ndarray, horizon: int, dt: float) -> Dict[str, np.ndarray]:
    """Predictions of the last ``horizon`` frames without a model."""
    last = observed_fit[-1]
    held = np.broadcast_to(last, (horizon,) + last.shape).copy()
    k = min(BASELINE_LINE_FRAMES, observed_fit.shape[0])
    t = np.arange(k) * dt
    window = observed_fit[-k:].reshape(k, -1)
    slope, intercept = np.polyfit(t, window, 1)
    future = t[-1] + dt * np.arange(1, horizon + 1)
    line = (intercept[None, :] + future[:, None] * slope[None, :]).reshape((horizon,) + last.shape)
    return {"held": held, "constant-velocity": line}


def run_case(
    motion: Motion,
    noise: float,
    seed: int,
    methods: Sequence[str] = ("output-error:stable", "least-squares:stable"),
) -> List[Dict[str, Any]]:
    """Fits each method (``STRATEGY:BOXES``) on the first 70 % of ``motion`` (with Gaussian
    noise of ``noise`` × its size, drawn from ``seed``) and scores the replay of the last 30 %
    against MuJoCo's positions, beside the baselines."""
    truth = motion.positions
    frames, n, _ = truth.shape
    fit = int(round(FIT_FRACTION * frames))
    rng = np.random.default_rng(10_000 + seed)
    sigma = noise * motion.size
    observed = truth + rng.normal(scale=sigma, size=truth.shape) if sigma > 0 else truth.copy()
    observed_fit = observed[:fit]
    free = np.array([i for i in range(n) if i not in motion.fixed])
    common = {"motion": motion.name, "seed": seed, "noise": noise, "sigma_m": sigma,
              "points": n, "frames": frames, "fit_frames": fit, "dt": motion.dt,
              "size_m": motion.size}
    rows: List[Dict[str, Any]] = []
    for name, pred in baselines(observed_fit, frames - fit, motion.dt).items():
        rows.append({**common, "method": name, "predict_rms_m": _rms(pred, truth[fit:], free)})
    for method in methods:
        strategy, _, rule = method.partition(":")
        scene = cordis_scene(motion, observed_fit, rule or "stable")
        row: Dict[str, Any] = {**common, "method": method}
        t0 = time.perf_counter()
        try:
            with warnings.catch_warnings(record=True) as caught:
                warnings.simplefilter("always")
                res = cordis.identify(scene, observed_fit, strategy=strategy)
            row["seconds"] = time.perf_counter() - t0
            report = res.report or {}
            row.update(stopped_by=res.stopped_by, short_rmse_m=res.rmse, params=res.params,
                       warnings=len(caught), sigma_hat_m=res.sigma,
                       windows=len(report.get("windows", [])), end=report.get("end"),
                       stability=res.scene.stability()["max_stability_ratio"])
        except (cordis.CordisError, RuntimeError, ValueError) as e:
            row.update(seconds=time.perf_counter() - t0, error=f"{type(e).__name__}: {e}",
                       predict_rms_m=float("inf"))
            rows.append(row)
            continue
        try:
            replay = res.scene.simulate(frames)
            row["fit_rms_m"] = _rms(replay[:fit], truth[:fit], free)
            row["predict_rms_m"] = _rms(replay[fit:], truth[fit:], free)
        except cordis.DivergedError as e:
            row.update(error=f"replay diverged at frame {e.frame}", predict_rms_m=float("inf"))
        rows.append(row)
    return rows


def table(rows: List[Dict[str, Any]]) -> str:
    """Medians (and ranges) over seeds of the prediction RMS, in mm and in % of the object's
    size; ``converged`` counts the fits whose solver met its own criterion, ``diverged`` the
    identified scenes whose replay left the finite numbers or ran away (> 100 × the size)."""
    keys = sorted({(r["motion"], r["noise"], r["method"]) for r in rows},
                  key=lambda k: (k[0], k[1], _method_key(str(k[2]))))
    out = ["| motion | σ/size | method | seeds | predict RMS, mm: median [min, max] | % of size "
           "| fit-window RMS, mm | s/fit | converged | diverged |",
           "|---|---|---|---|---|---|---|---|---|---|"]
    for motion, noise, method in keys:
        sel = [r for r in rows if (r["motion"], r["noise"], r["method"]) == (motion, noise, method)]
        size = float(sel[0]["size_m"])
        pred = [float(r["predict_rms_m"]) for r in sel]
        med = statistics.median(pred)
        fitr = [float(r["fit_rms_m"]) for r in sel if "fit_rms_m" in r]
        secs = [float(r["seconds"]) for r in sel if "seconds" in r]
        fitted = "stopped_by" in sel[0] or "error" in sel[0]
        conv = sum(1 for r in sel if r.get("stopped_by") == "converged")
        div = sum(1 for p in pred if not p < 100 * size)

        def mm(v: float) -> str:
            return f"{1e3 * v:.3g}" if v < 100 * size else "runaway"

        out.append(
            f"| {motion} | {noise:g} | {method} | {len(sel)} | {mm(med)} [{mm(min(pred))}, "
            f"{mm(max(pred))}] | " + (f"{100 * med / size:.3g}" if med < 100 * size else "–")
            + " | " + (mm(statistics.median(fitr)) if fitr else "–") + " | "
            + (f"{statistics.median(secs):.3g}" if secs else "–") + " | "
            + (f"{conv}/{len(sel)} | {div}/{len(sel)}" if fitted else "– | –") + " |"
        )
    return "\n".join(out)


def _method_key(method: str) -> Tuple[int, str]:
    order = ["held", "constant-velocity", "least-squares", "output-error"]
    return (order.index(method.partition(":")[0]), method)


def main(argv: Optional[Sequence[str]] = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--motions", default="cable,cloth")
    ap.add_argument("--seeds", default="0,1,2")
    ap.add_argument("--noise", default="0,1e-3", help="σ as a fraction of the object's size")
    ap.add_argument("--frames", type=int, default=300)
    ap.add_argument("--table", nargs="+", metavar="JSONL",
                    help="only print the table of these files' JSON lines (earlier runs)")
    ap.add_argument("--methods", default="output-error:stable,least-squares:stable",
                    help="STRATEGY:BOXES, BOXES `stable` or `wide` (see boxes())")
    args = ap.parse_args(argv)
    rows: List[Dict[str, Any]] = []
    if args.table:
        for path in args.table:
            with open(path) as f:
                rows += [json.loads(line) for line in f if line.startswith("{")]
        print(table(rows))
        return 0
    for name in args.motions.split(","):
        for seed in (int(s) for s in args.seeds.split(",")):
            motion = MOTIONS[name](seed=seed, frames=args.frames)
            for noise in (float(s) for s in args.noise.split(",")):
                for row in run_case(motion, noise, seed, args.methods.split(",")):
                    print(json.dumps(row), flush=True)
                    rows.append(row)
    print(table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
