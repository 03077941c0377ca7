"""Run a scene exported by ``cordis export --mjcf`` in MuJoCo, with the kinds MJCF lacks.

MuJoCo integrates every particle; this module only adds what MJCF has no element for. Needs
the ``mujoco`` package (``pip install mujoco``); it is imported when :func:`load` is called.

Example::

    import cordis, cordis.mujoco

    scene = cordis.example("horse")
    cordis.export_mjcf(scene, "horse.xml")        # or: cordis export horse.json --mjcf horse.xml
    with cordis.mujoco.load("horse.xml") as sim:  # MjModel + MjData + the callbacks
        motion = sim.run(53)                     # (53, 35, 3), as scene.simulate(53)
        sim.model, sim.data                      # MuJoCo's own objects, for anything else

**What MuJoCo does natively** (the MJCF itself, see docs/cli.md): one body ``p{i}`` per
particle on three slide joints, springs and anchors as spatial tendons, dampers as fixed
tendons, drags as joint damping, zero-length anchors as joint stiffness, gravity, initial
velocities in the keyframe ``cordis_start``; CORDIS' two-step scheme is MuJoCo's
semi-implicit ``integrator="Euler"`` with explicit damping (``eulerdamp="disable"``) and
contacts off.

**What this module adds**, from the model's ``<custom>`` numeric fields (written by cordis,
layout in crates/cordis-core/src/export/mjcf_callback.rs):

- *Forces of the state* ``(x(n), v(n))`` that MJCF cannot express — angle links
  ``E = ½ K (cosθ - c0)²``, conditional links (a spring ``(K (L - l0) + Z s + Z₂ s|s|) u``
  between every pair of their groups closer than ``range``, pairs found anew each step),
  planes (the penalty buffer ``max(0, K d - Z v_n)`` with cordis' regularised Coulomb
  friction) and a spring's quadratic damping ``Z₂ s|s|`` — are added to ``qfrc_passive`` by
  MuJoCo's passive-force callback (``mujoco.set_mjcb_passive``). ``mj_step`` calls it inside
  ``mj_forward``, after the positions and velocities and before the accelerations, so the
  forces enter the same step at the same state as in CORDIS. The callback is process-wide in
  MuJoCo: this module sets one dispatcher (a ctypes function, so that MuJoCo's compiler may
  call it while building other models) that adds forces to the ``data`` of the simulations
  loaded here only, and unsets it when the last one is closed. It refuses to replace a
  passive callback someone else set.
- *Provot's elongation limit* (``max_elongation``) is a projection of the new positions after
  a step, not a force, and MuJoCo has no hook after its integrator: :meth:`Simulation.step`
  runs ``mj_step`` and then the projection (one pass over the limited springs in file order,
  as cordis does), moving ``qpos`` by the correction ``Δ`` and ``qvel`` by ``Δ / dt``:
  CORDIS keeps ``x(n)``, so its next velocity ``(x(n+1) + Δ - x(n)) / dt`` gains ``Δ / dt``
  too. Calling ``mujoco.mj_step`` yourself gives every force but not this projection.

The replay equals ``scene.simulate`` within 1e-9 of the motion's extent for every shipped
passive example (python/tests/test_mujoco.py, which measures it).
"""

from __future__ import annotations

import ctypes
import math
import os
from typing import Any, Dict, List, Optional, Tuple, Union

import numpy as np

__all__ = ["Simulation", "load"]

# Below this length a link has no direction (cordis' MIN_LENGTH).
_MIN_LENGTH = 1e-12
# An angle's arm shorter than this fraction of the other fades its force (cordis' SINGULAR_ARM).
_SINGULAR_ARM = 1e-2
_FORMAT = 1


def _field(model: Any, name: str) -> Optional[np.ndarray]:
    """The data of the numeric custom field ``name``, or None when the model has none."""
    try:
        return np.array(model.numeric(name).data, dtype=np.float64)
    except KeyError:
        return None


def _rows(data: Optional[np.ndarray], width: int, name: str) -> np.ndarray:
    if data is None:
        return np.zeros((0, width))
    if data.size % width:
        raise ValueError(f"custom field {name}: {data.size} numbers, not a multiple of {width}")
    return data.reshape(-1, width)


class _Conditional:
    """One conditional type: a spring between every pair closer than ``range``."""

    def __init__(self, data: np.ndarray, name: str) -> None:
        if data.size < 7:
            raise ValueError(f"custom field {name}: {data.size} numbers, need at least 7")
        self.k, self.l0, self.z, self.z2, self.range = (float(v) for v in data[:5])
        na, nb = int(data[5]), int(data[6])
        if data.size != 7 + na + max(nb, 0):
            raise ValueError(f"custom field {name}: {data.size} numbers for {na} + {nb} members")
        self.a = data[7:7 + na].astype(np.int64)
        self.b = None if nb < 0 else data[7 + na:].astype(np.int64)

    @property
    def members(self) -> Tuple[Tuple[int, ...], Optional[Tuple[int, ...]]]:
        return tuple(self.a.tolist()), None if self.b is None else tuple(self.b.tolist())

    @property
    def valid(self) -> bool:
        """cordis pairs nothing for a range that is not positive and finite."""
        return self.range > 0 and math.isfinite(self.range)


def _within(d2: np.ndarray, r: float) -> np.ndarray:
    """``|d| < r`` as cordis decides it: ``|d|² < r²``, or on ``|d|`` where r² is not a
    normal float (it would under- or overflow)."""
    r2 = r * r
    if r2 >= np.finfo(np.float64).tiny and math.isfinite(r2):
        return d2 < r2
    return np.sqrt(d2) < r


def _conditional_forces(f: np.ndarray, x: np.ndarray, v: np.ndarray,
                        family: List[_Conditional]) -> None:
    """The types of one family (the same groups) share one pair search at their largest
    range; each then keeps its own pairs."""
    valid = [c for c in family if c.valid]
    if not valid:
        return
    first = valid[0]
    i, j, d2 = _near_pairs(x, first.a, first.b, max(c.range for c in valid))
    for c in valid:
        keep = _within(d2, c.range)
        if keep.any():
            _add_spring_forces(f, x, v, (i[keep], j[keep]), (c.k, c.l0, c.z, c.z2))


def _near_pairs(x: np.ndarray, a: np.ndarray, b: Optional[np.ndarray],
                r: float) -> Tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Pairs (i, j) closer than r (see :func:`_within`), i in a and j in b, or both in a
    once, with their squared lengths; found on a grid of cells at least r wide, O(N) plus
    the pairs."""
    empty = (np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(0))
    other = a if b is None else b
    if not (r > 0 and math.isfinite(r)) or a.size == 0 or other.size == 0:
        return empty
    members = np.concatenate([a, other]) if b is not None else a
    pts = x[members]
    if not np.isfinite(pts).all():
        return empty  # cordis finds no pairs while a position is not finite
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    # Cells at least r wide, grown (as cordis' grid) until there are at most 4N + 64 of them.
    max_cells = 4 * len(members) + 64
    cell = max(r, float((hi - lo).max()) / max_cells)
    while True:
        dims = np.floor((hi - lo) / cell) + 1
        if float(np.prod(dims)) <= max_cells:
            break
        cell *= 2
    dims_i = dims.astype(np.int64) + 2  # one empty cell of margin on each side

    def keys(c: np.ndarray) -> np.ndarray:
        return (c[:, 0] * dims_i[1] + c[:, 1]) * dims_i[2] + c[:, 2]

    cell_a = np.minimum(np.floor((x[a] - lo) / cell), dims - 1).astype(np.int64) + 1
    cell_o = np.minimum(np.floor((x[other] - lo) / cell), dims - 1).astype(np.int64) + 1
    key_o = keys(cell_o)
    order = np.argsort(key_o, kind="stable")
    count_of = np.bincount(key_o, minlength=int(np.prod(dims_i)))
    start_of = np.cumsum(count_of) - count_of
    first_i: List[np.ndarray] = []
    first_j: List[np.ndarray] = []
    # Neighbour cells along the axes the grid spans (a flat scene has one layer of cells).
    steps = [(-1, 0, 1) if n > 1 else (0,) for n in dims]
    for off in [(dx, dy, dz) for dx in steps[0] for dy in steps[1] for dz in steps[2]]:
        k = keys(cell_a + np.array(off))
        start, count = start_of[k], count_of[k]
        total = int(count.sum())
        if total == 0:
            continue
        ia = np.repeat(np.arange(a.size), count)
        base = np.repeat(start - np.cumsum(count) + count, count)
        first_i.append(ia)
        first_j.append(order[base + np.arange(total)])
    if not first_i:
        return empty
    ia = np.concatenate(first_i)
    jo = np.concatenate(first_j)
    if b is None:
        keep = ia < jo  # each pair within one group once, no particle with itself
        ia, jo = ia[keep], jo[keep]
    i, j = a[ia], other[jo]
    d = x[j] - x[i]
    d2 = d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2]
    near = _within(d2, r)
    return i[near], j[near], d2[near]


def _add_spring_forces(f: np.ndarray, x: np.ndarray, v: np.ndarray,
                       ends: Tuple[np.ndarray, np.ndarray],
                       params: Tuple[float, float, float, float]) -> None:
    """``F_i = (K (L - l0) + Z s + Z₂ s|s|) u``, ``F_j = -F_i``, ``s = (v_j - v_i)·u``."""
    i, j = ends
    k, l0, z, z2 = params
    d = x[j] - x[i]
    length = np.sqrt(d[:, 0] * d[:, 0] + d[:, 1] * d[:, 1] + d[:, 2] * d[:, 2])
    with np.errstate(divide="ignore"):
        inv = np.where(length >= _MIN_LENGTH, 1.0 / length, 0.0)
    u = d * inv[:, None]
    mag = k * (length - l0)
    if z != 0.0 or z2 != 0.0:
        w = v[j] - v[i]
        s = w[:, 0] * u[:, 0] + w[:, 1] * u[:, 1] + w[:, 2] * u[:, 2]
        mag = mag + z * s
        if z2 != 0.0:
            mag = mag + z2 * (s * np.abs(s))
    _scatter(f, i, j, u * mag[:, None])


def _scatter(f: np.ndarray, i: np.ndarray, j: np.ndarray, fi: np.ndarray) -> None:
    """``f[i] += fi``, ``f[j] -= fi`` with repeated indices summed."""
    n = f.shape[0]
    for c in range(3):
        f[:, c] += np.bincount(i, weights=fi[:, c], minlength=n)
        f[:, c] -= np.bincount(j, weights=fi[:, c], minlength=n)


def _angle_forces(f: np.ndarray, x: np.ndarray, rows: np.ndarray) -> None:
    """Angle links ``E = ½ K (cosθ - c0)²`` at j of (i, j, k), faded near a closed arm."""
    i, j, m = (rows[:, c].astype(np.int64) for c in range(3))
    k, c0 = rows[:, 3], rows[:, 4]
    a = x[i] - x[j]
    b = x[m] - x[j]
    la = np.sqrt(a[:, 0] * a[:, 0] + a[:, 1] * a[:, 1] + a[:, 2] * a[:, 2])
    lb = np.sqrt(b[:, 0] * b[:, 0] + b[:, 1] * b[:, 1] + b[:, 2] * b[:, 2])
    ok = (la >= _MIN_LENGTH) & (lb >= _MIN_LENGTH)
    la, lb = np.where(ok, la, 1.0), np.where(ok, lb, 1.0)
    inv_ab = 1.0 / (la * lb)
    c = (a[:, 0] * b[:, 0] + a[:, 1] * b[:, 1] + a[:, 2] * b[:, 2]) * inv_ab
    g = -k * (c - c0)
    dc_da = b * inv_ab[:, None] - a * (c / (la * la))[:, None]
    dc_db = a * inv_ab[:, None] - b * (c / (lb * lb))[:, None]
    fade = (np.minimum(la / (_SINGULAR_ARM * lb), 1.0) ** 2
            * np.minimum(lb / (_SINGULAR_ARM * la), 1.0) ** 2)
    singular = (la < _SINGULAR_ARM * lb) | (lb < _SINGULAR_ARM * la)
    g = np.where(ok, np.where(singular, g * fade, g), 0.0)
    fi = dc_da * g[:, None]
    fk = dc_db * g[:, None]
    _scatter(f, i, j, fi)
    _scatter(f, m, j, fk)


def _plane_forces(f: np.ndarray, x: np.ndarray, v: np.ndarray, rows: np.ndarray,
                  mass: np.ndarray, dt: float) -> None:
    """Half-space buffers: ``F_n = max(0, K d - Z v_n)`` while ``d = (p - x)·n > 0``, and the
    regularised Coulomb friction ``-(v_t/|v_t|) c a / √(a² + c²)``, ``c = μ F_n``,
    ``a = m |v_t| / dt`` (cordis' forces/plane.rs)."""
    i = rows[:, 0].astype(np.int64)
    k, z, mu = rows[:, 1], rows[:, 2], rows[:, 3]
    point, normal = rows[:, 4:7], rows[:, 7:10]
    xi, vi = x[i], v[i]
    gap = point - xi
    depth = gap[:, 0] * normal[:, 0] + gap[:, 1] * normal[:, 1] + gap[:, 2] * normal[:, 2]
    inside = depth > 0.0
    if not inside.any():
        return
    i, k, z, mu = i[inside], k[inside], z[inside], mu[inside]
    normal, depth, vi = normal[inside], depth[inside], vi[inside]
    vn = vi[:, 0] * normal[:, 0] + vi[:, 1] * normal[:, 1] + vi[:, 2] * normal[:, 2]
    f_n = np.maximum(k * depth - z * vn, 0.0)
    force = normal * f_n[:, None]
    c = mu * f_n
    vt = vi - normal * vn[:, None]
    speed = np.sqrt(vt[:, 0] * vt[:, 0] + vt[:, 1] * vt[:, 1] + vt[:, 2] * vt[:, 2])
    a = mass[i] * speed / dt
    rub = (c > 0.0) & (a > 0.0) & (mu != 0.0)
    if rub.any():
        ratio = c[rub] / a[rub]
        scale = -c[rub] / (speed[rub] * np.sqrt(1.0 + ratio * ratio))
        force[rub] += vt[rub] * scale[:, None]
    np.add.at(f, i, force)


class _Extra:
    """The kinds a cordis model carries in ``<custom>``, read once from the model."""

    def __init__(self, model: Any) -> None:
        fmt = _field(model, "cordis_format")
        if fmt is not None and (fmt.size != 1 or int(fmt[0]) != _FORMAT):
            raise ValueError(f"custom field cordis_format: {fmt.tolist()}; this cordis reads "
                             f"layout {_FORMAT} (export the scene again with this version)")
        self.angles = _rows(_field(model, "cordis_angle"), 5, "cordis_angle")
        self.quadratic = _rows(_field(model, "cordis_spring_quadratic"), 3,
                               "cordis_spring_quadratic")
        self.planes = _rows(_field(model, "cordis_plane"), 10, "cordis_plane")
        families: Dict[Any, List[_Conditional]] = {}
        t = 0
        while (data := _field(model, f"cordis_conditional_{t}")) is not None:
            c = _Conditional(data, f"cordis_conditional_{t}")
            families.setdefault(c.members, []).append(c)
            t += 1
        self.conditionals = list(families.values())
        provot = _rows(_field(model, "cordis_provot"), 4, "cordis_provot")
        # (i, j, limit) with the limit computed as cordis does: (1 + τc) l0.
        self.provot = [(int(i), int(j), (1.0 + tau) * l0 * 1.0) for i, j, tau, l0 in provot]

    @property
    def has_forces(self) -> bool:
        return bool(len(self.angles) or len(self.quadratic) or len(self.planes)
                    or self.conditionals)

    def forces(self, x: np.ndarray, v: np.ndarray, mass: np.ndarray, dt: float) -> np.ndarray:
        f = np.zeros_like(x)
        if len(self.quadratic):
            i, j = (self.quadratic[:, c].astype(np.int64) for c in range(2))
            for z2 in np.unique(self.quadratic[:, 2]):
                sel = self.quadratic[:, 2] == z2
                _add_spring_forces(f, x, v, (i[sel], j[sel]), (0.0, 0.0, 0.0, float(z2)))
        if len(self.angles):
            _angle_forces(f, x, self.angles)
        if len(self.planes):
            _plane_forces(f, x, v, self.planes, mass, dt)
        for family in self.conditionals:
            _conditional_forces(f, x, v, family)
        return f


# The simulations whose forces the dispatcher adds, by the address of their mjModel.
_ACTIVE: Dict[int, "Simulation"] = {}
_CALLBACK = ctypes.CFUNCTYPE(None, ctypes.c_void_p, ctypes.c_void_p)


@_CALLBACK
def _dispatch(model: int, data: int) -> None:
    # Raw pointers, not the bindings' wrappers: MuJoCo's compiler calls the passive callback
    # on models of its own while it builds one, and a Python callable then fails the build
    # ("engine error: Python exception raised"); a ctypes function is called as C.
    sim = _ACTIVE.get(model)
    if sim is not None and data == sim.data._address:
        try:
            sim._add_passive()
        except BaseException as e:  # raised again by Simulation.step, after mj_step
            sim._error = e


class Simulation:
    """A cordis MJCF model in MuJoCo: ``model``, ``data``, and the kinds MJCF lacks.

    Built by :func:`load`. :meth:`step` is ``mj_step`` plus Provot's projection when the
    scene has one; :meth:`run` gives frames as ``Scene.simulate`` does. Close it (or use it
    as a context manager) to remove its forces from MuJoCo's passive callback.
    """

    def __init__(self, model: Any) -> None:
        import mujoco

        self._mujoco = mujoco
        self.model = model
        self.data = mujoco.MjData(model)
        self.particles = 0
        while mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, f"p{self.particles}") >= 0:
            self.particles += 1
        bodies = [model.body(f"p{i}").id for i in range(self.particles)]
        if bodies != list(range(1, self.particles + 1)):
            raise ValueError("not a cordis model: bodies p0, p1, … must come first, in order")
        self._origin = np.array(model.body_pos[bodies], dtype=np.float64)
        self._free = np.array([model.body_jntnum[b] == 3 for b in bodies], dtype=bool)
        free_bodies = [b for b in bodies if model.body_jntnum[b] == 3]
        self._qpos = np.array([model.jnt_qposadr[model.body_jntadr[b]] for b in free_bodies],
                              dtype=np.int64)[:, None] + np.arange(3)
        self._dof = np.array([model.body_dofadr[b] for b in free_bodies],
                             dtype=np.int64)[:, None] + np.arange(3)
        self._mass = np.array(model.body_mass[bodies], dtype=np.float64)
        self._extra = _Extra(model)
        self._installed = False
        self._error: Optional[BaseException] = None
        if self._extra.has_forces:
            self._install()
        self.reset()

    # -- state ----------------------------------------------------------------------------
    def reset(self) -> None:
        """Back to the scene's initial state (the keyframe ``cordis_start``)."""
        if self.model.nkey:
            self._mujoco.mj_resetDataKeyframe(self.model, self.data, 0)
        else:
            self._mujoco.mj_resetData(self.model, self.data)
        self._mujoco.mj_kinematics(self.model, self.data)

    def positions(self) -> np.ndarray:
        """Particle positions ``(particles, 3)``, m: each body's origin plus its joints."""
        x = self._origin.copy()
        x[self._free] += self.data.qpos[self._qpos]
        return x

    def velocities(self) -> np.ndarray:
        """Particle velocities ``(particles, 3)``, m/s (0 for fixed particles)."""
        v = np.zeros_like(self._origin)
        v[self._free] = self.data.qvel[self._dof]
        return v

    def step(self) -> None:
        """One step: ``mj_step`` (the callback adds the forces) then Provot's projection."""
        self._mujoco.mj_step(self.model, self.data)
        if self._error is not None:
            error, self._error = self._error, None
            raise error
        if self._extra.provot:
            self._project()

    def run(self, frames: int) -> np.ndarray:
        """Frames ``x(0)…x(frames-1)`` from the current state, ``(frames, particles, 3)``."""
        out = np.zeros((frames, self.particles, 3))
        for t in range(frames):
            out[t] = self.positions()
            if t < frames - 1:
                self.step()
        return out

    # -- the kinds MJCF lacks -----------------------------------------------------------------
    def _add_passive(self) -> None:
        f = self._extra.forces(self.positions(), self.velocities(), self._mass,
                               float(self.model.opt.timestep))
        self.data.qfrc_passive[self._dof] += f[self._free]

    def _project(self) -> None:
        """Provot's pass on the new positions, in file order, each correction seen by the
        next; ``qpos += Δ``, ``qvel += Δ / dt``."""
        x = self.positions()
        before = x.copy()
        pos = x.tolist()
        free = self._free.tolist()
        for i, j, limit in self._extra.provot:
            xi, xj = pos[i], pos[j]
            d0, d1, d2 = xj[0] - xi[0], xj[1] - xi[1], xj[2] - xi[2]
            length = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
            excess = length - limit
            if not excess > 0.0:
                continue
            inv = 1.0 / length if length >= _MIN_LENGTH else 0.0
            u = (d0 * inv, d1 * inv, d2 * inv)
            if free[i] and free[j]:
                h = 0.5 * excess
                pos[i] = [xi[c] + u[c] * h for c in range(3)]
                pos[j] = [xj[c] - u[c] * h for c in range(3)]
            elif free[i]:
                pos[i] = [xi[c] + u[c] * excess for c in range(3)]
            elif free[j]:
                pos[j] = [xj[c] - u[c] * excess for c in range(3)]
        delta = (np.array(pos) - before)[self._free]
        moved = delta.any(axis=1)
        if moved.any():
            q, dof = self._qpos[moved], self._dof[moved]
            self.data.qpos[q] += delta[moved]
            self.data.qvel[dof] += delta[moved] / self.model.opt.timestep

    def _install(self) -> None:
        _check_callback_free(self._mujoco)
        self._mujoco.set_mjcb_passive(_dispatch)
        _ACTIVE[self.model._address] = self
        self._installed = True

    def close(self) -> None:
        """Removes this model's forces from MuJoCo's passive callback (unset when no model
        is left)."""
        if not self._installed:
            return
        _ACTIVE.pop(self.model._address, None)
        self._installed = False
        if not _ACTIVE and self._mujoco.get_mjcb_passive() is _dispatch:
            self._mujoco.set_mjcb_passive(None)

    def __enter__(self) -> "Simulation":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


def _check_callback_free(mujoco: Any) -> None:
    current = mujoco.get_mjcb_passive()
    if current is not None and current is not _dispatch:
        raise RuntimeError(
            f"MuJoCo's passive-force callback is already set ({current!r}); cordis.mujoco "
            "needs it for the forces MJCF lacks: unset it first (mujoco.set_mjcb_passive(None))")


def load(path: Union[str, "os.PathLike[str]"]) -> Simulation:
    """Loads an MJCF written by cordis and installs what MJCF lacks (see the module)."""
    import mujoco

    # Before compiling: a Python passive callback makes MuJoCo's compiler fail.
    _check_callback_free(mujoco)
    return Simulation(mujoco.MjModel.from_xml_path(os.fspath(path)))
