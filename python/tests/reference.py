"""An independent, deliberately naive numpy implementation of SPEC §2.1–2.2.

It reads the scene *dict* itself (not through cordis), loops over links one by one, finds
conditional pairs by brute force over all pairs, and applies Provot's pass link by link. It
shares no code with the Rust core: agreement between the two is evidence that both follow
the SPEC, not that they share a bug.

Only known parameters (plain numbers) are supported.
"""

from __future__ import annotations

import math
from typing import Any, Dict, List, Optional, Tuple

import numpy as np

MIN_LENGTH = 1e-12  # below this a link has no direction: u = 0 (SPEC §2.2)

# Per kind: parameter names and defaults (None: required), SPEC §2.2 table.
PARAMS = {
    "spring": {"stiffness": None, "rest_length": None, "damping": 0.0},
    "damper": {"damping": None},
    "anchor": {"stiffness": None, "rest_length": 0.0, "damping": 0.0},
    "drag": {"damping": None},
    "nonlinear_drag": {"z1": None, "z2": None, "v_max": None},
    "angle": {"stiffness": None, "rest_cos": None},
    "conditional": {"stiffness": None, "rest_length": None, "damping": 0.0, "range": None},
}


def _vec(v: Any) -> np.ndarray:
    return np.array([float(c) for c in v], dtype=np.float64)


def _params(t: Dict[str, Any]) -> Dict[str, float]:
    out = {}
    for name, default in PARAMS[t["kind"]].items():
        value = t.get(name, default)
        if value is None:
            raise ValueError(f"a {t['kind']} needs {name}")
        out[name] = float(value)
    return out


def unit_and_length(d: np.ndarray):
    length = math.sqrt(float(d @ d))
    if length < MIN_LENGTH:
        return np.zeros(3), length
    return d / length, length


def spring_force_on_i(xi, xj, vi, vj, k, l0, z) -> np.ndarray:
    """F_i = (K (L - l0) + Z s) u with u = (x_j - x_i)/L, s = (v_j - v_i)·u."""
    u, length = unit_and_length(xj - xi)
    s = float((vj - vi) @ u)
    return (k * (length - l0) + z * s) * u


def angle_forces(xi, xj, xk, k, c0):
    """-∇ of E = ½K(cosθ - c0)², θ the angle at j between a = x_i - x_j and b = x_k - x_j.

    With c = a·b/(|a||b|): ∂c/∂a = b/(|a||b|) - (a·b) a/(|a|³|b|), symmetric for b, and
    ∂E/∂x_j = -(∂E/∂a + ∂E/∂b). Returns (F_i, F_j, F_k).
    """
    a = xi - xj
    b = xk - xj
    la = math.sqrt(float(a @ a))
    lb = math.sqrt(float(b @ b))
    if la < MIN_LENGTH or lb < MIN_LENGTH:
        z = np.zeros(3)
        return z, z, z
    ab = float(a @ b)
    c = ab / (la * lb)
    dc_da = b / (la * lb) - ab * a / (la**3 * lb)
    dc_db = a / (la * lb) - ab * b / (lb**3 * la)
    de_dc = k * (c - c0)
    fi = -de_dc * dc_da
    fk = -de_dc * dc_db
    return fi, -(fi + fk), fk


def angle_energy(xi, xj, xk, k, c0) -> float:
    a = xi - xj
    b = xk - xj
    c = float(a @ b) / (math.sqrt(float(a @ a)) * math.sqrt(float(b @ b)))
    return 0.5 * k * (c - c0) ** 2


class Reference:
    """The scene dict, unpacked once."""

    def __init__(self, scene: Dict[str, Any]):
        self.dt = float(scene["dt"])
        self.g = _vec(scene.get("gravity", [0.0, 0.0, 0.0]))
        ps = scene["particles"]
        self.n = len(ps)
        self.m = np.array([float(p["mass"]) for p in ps])
        self.x0 = np.array([_vec(p["pos"]) for p in ps]).reshape(self.n, 3)
        self.v0 = np.array([_vec(p.get("vel", [0, 0, 0])) for p in ps]).reshape(self.n, 3)
        self.fixed = np.array([bool(p.get("fixed", False)) for p in ps])
        self.group = [p.get("group") for p in ps]
        self.types = {name: dict(t) for name, t in scene.get("types", {}).items()}
        self.links = [dict(l) for l in scene.get("links", [])]

    def forces(self, x: np.ndarray, v: np.ndarray) -> np.ndarray:
        f = np.zeros((self.n, 3))
        for link in self.links:
            t = self.types[link["type"]]
            p = _params(t)
            kind = t["kind"]
            idx = link["particles"]
            if kind == "spring":
                i, j = idx
                fi = spring_force_on_i(
                    x[i], x[j], v[i], v[j], p["stiffness"], p["rest_length"], p["damping"]
                )
                f[i] += fi
                f[j] -= fi
            elif kind == "damper":
                i, j = idx
                fi = p["damping"] * (v[j] - v[i])
                f[i] += fi
                f[j] -= fi
            elif kind == "anchor":
                (i,) = idx
                # The link's own point, else the type's, else where the particle started.
                point = link.get("point", t.get("point"))
                point = self.x0[i] if point is None else _vec(point)
                f[i] += spring_force_on_i(
                    x[i], point, v[i], np.zeros(3), p["stiffness"], p["rest_length"], p["damping"]
                )
            elif kind == "drag":
                (i,) = idx
                f[i] -= p["damping"] * v[i]
            elif kind == "nonlinear_drag":
                (i,) = idx
                speed = math.sqrt(float(v[i] @ v[i]))
                z = p["z1"] if speed < p["v_max"] else p["z2"]
                f[i] -= z * v[i]
            elif kind == "angle":
                i, j, k = idx
                fi, fj, fk = angle_forces(x[i], x[j], x[k], p["stiffness"], p["rest_cos"])
                f[i] += fi
                f[j] += fj
                f[k] += fk
            else:
                raise ValueError(f"unsupported listed link kind {kind}")
        for t in self.types.values():
            if t["kind"] == "conditional":
                self._conditional(t, x, v, f)
        return f

    def pairs_of(self, t: Dict[str, Any]) -> List[Tuple[int, int]]:
        """Every candidate pair of a conditional type: within its group, or across two."""
        groups = t["groups"]
        a = [i for i in range(self.n) if self.group[i] == groups[0]]
        if len(groups) == 1 or groups[1] == groups[0]:
            return [(a[s], a[r]) for s in range(len(a)) for r in range(s + 1, len(a))]
        b = [i for i in range(self.n) if self.group[i] == groups[1]]
        return [(i, j) for i in a for j in b]

    def _conditional(self, t, x, v, f) -> None:
        p = _params(t)
        for i, j in self.pairs_of(t):
            d = x[j] - x[i]
            if math.sqrt(float(d @ d)) < p["range"]:
                fi = spring_force_on_i(
                    x[i], x[j], v[i], v[j], p["stiffness"], p["rest_length"], p["damping"]
                )
                f[i] += fi
                f[j] -= fi

    def provot(self, x: np.ndarray, stats: Optional[Dict[str, int]]) -> None:
        """One pass over limited springs in listed order, each correction seen by the next."""
        for link in self.links:
            t = self.types[link["type"]]
            tau = t.get("max_elongation")
            if t["kind"] != "spring" or tau is None:
                continue
            i, j = link["particles"]
            limit = (1.0 + float(tau)) * float(t["rest_length"])
            u, length = unit_and_length(x[j] - x[i])
            excess = length - limit
            if excess <= 0.0:
                continue
            if stats is not None:
                stats["provot"] = stats.get("provot", 0) + 1
            if not self.fixed[i] and not self.fixed[j]:
                x[i] += 0.5 * excess * u
                x[j] -= 0.5 * excess * u
            elif not self.fixed[i]:
                x[i] += excess * u
            elif not self.fixed[j]:
                x[j] -= excess * u

    def simulate(self, frames: int, stats: Optional[Dict[str, int]] = None) -> np.ndarray:
        dt = self.dt
        out = np.zeros((frames, self.n, 3))
        x = self.x0.copy()
        # x(-1) = x(0) - v0 dt; a fixed particle never moves, so its velocity is 0 throughout.
        x_prev = np.where(self.fixed[:, None], self.x0, self.x0 - self.v0 * dt)
        for t in range(frames):
            out[t] = x
            if t == frames - 1:
                break
            v = (x - x_prev) / dt
            f = self.forces(x, v)
            x_next = x.copy()
            for i in range(self.n):
                if not self.fixed[i]:
                    x_next[i] = 2.0 * x[i] - x_prev[i] + dt * dt * (f[i] / self.m[i] + self.g)
            self.provot(x_next, stats)
            x_prev, x = x, x_next
        return out


def simulate(scene: Dict[str, Any], frames: int, stats: Optional[Dict[str, int]] = None):
    """Positions (frames, N, 3) of a scene dict, per SPEC §2.1–2.2."""
    return Reference(scene).simulate(frames, stats)


def scale(traj: np.ndarray) -> float:
    """The motion's scale: the largest extent of the trajectory's bounding box, m."""
    flat = traj.reshape(-1, 3)
    return float((flat.max(axis=0) - flat.min(axis=0)).max())


def conditional_pairs(scene: Dict[str, Any], x: np.ndarray) -> List[Tuple[int, int]]:
    """The conditional pairs active at positions x (to check that a test exercises switching)."""
    ref = Reference(scene)
    out = []
    for t in ref.types.values():
        if t["kind"] != "conditional":
            continue
        for i, j in ref.pairs_of(t):
            d = x[j] - x[i]
            if math.sqrt(float(d @ d)) < float(t["range"]):
                out.append((i, j))
    return out
