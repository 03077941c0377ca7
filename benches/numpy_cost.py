"""cordis' short cost from Python against a vectorised numpy implementation of the same cost
(SPEC §3), on a 20×20 spring cloth (structural, shear, bend; damping; gravity; one pinned
edge), 100 frames. Prints one JSON line per measurement and the ratios.

    python benches/numpy_cost.py          # needs `pip install ./python numpy`

The numpy version is written for speed: every frame at once, forces scattered with
np.bincount. Both sides are checked to agree to 1e-9 (relative) before timing.
"""
import json
import statistics
import time

import numpy as np

import cordis

NX = NY = 20
H = 0.05
DT = 2e-3
FRAMES = 100


def cloth_dict():
    particles = []
    for j in range(NY):
        for i in range(NX):
            particles.append(
                {"mass": 0.01 + 0.0005 * ((i * 7 + j * 3) % 5), "pos": [i * H, 0.0, -j * H * 0.2 + 0.001 * i],
                 "fixed": j == 0}
            )
    d = H * 2 ** 0.5
    types = {
        "st": {"kind": "spring", "stiffness": 20.0, "rest_length": H, "damping": 2e-3},
        "sh": {"kind": "spring", "stiffness": 5.0, "rest_length": d, "damping": 1e-3},
        "be": {"kind": "spring", "stiffness": 2.0, "rest_length": 2 * H, "damping": 5e-4},
    }
    idx = lambda i, j: j * NX + i  # noqa: E731
    links = []
    for j in range(NY):
        for i in range(NX):
            if i + 1 < NX:
                links.append({"type": "st", "particles": [idx(i, j), idx(i + 1, j)]})
            if j + 1 < NY:
                links.append({"type": "st", "particles": [idx(i, j), idx(i, j + 1)]})
            if i + 1 < NX and j + 1 < NY:
                links.append({"type": "sh", "particles": [idx(i, j), idx(i + 1, j + 1)]})
                links.append({"type": "sh", "particles": [idx(i + 1, j), idx(i, j + 1)]})
            if i + 2 < NX:
                links.append({"type": "be", "particles": [idx(i, j), idx(i + 2, j)]})
            if j + 2 < NY:
                links.append({"type": "be", "particles": [idx(i, j), idx(i, j + 2)]})
    return {"format": "cordis-scene/1", "dt": DT, "gravity": [0, 0, -9.81], "particles": particles,
            "types": types, "links": links}


class NumpyShortCost:
    """The short cost C = Σ_t Σ_free |x̂(t) - x(t)|², every frame at once."""

    def __init__(self, d, traj):
        self.X = np.asarray(traj, dtype=np.float64)
        self.T, self.N, _ = self.X.shape
        names = list(d["types"])
        self.i = np.array([l["particles"][0] for l in d["links"]])
        self.j = np.array([l["particles"][1] for l in d["links"]])
        self.type_of = np.array([names.index(l["type"]) for l in d["links"]])
        self.m = np.array([p["mass"] for p in d["particles"]])
        self.free = ~np.array([p.get("fixed", False) for p in d["particles"]])
        self.g = np.array(d["gravity"], dtype=np.float64)
        self.dt = d["dt"]
        x1, x0 = self.X[1:-1], self.X[:-2]
        self.x1, self.x0, self.target = x1, x0, self.X[2:]
        self.v = (x1 - x0) / self.dt
        t = np.arange(self.T - 2)[:, None]
        self.flat_i = (t * self.N + self.i[None, :]).ravel()
        self.flat_j = (t * self.N + self.j[None, :]).ravel()

    def __call__(self, k, l0, z):
        k, l0, z = k[self.type_of], l0[self.type_of], z[self.type_of]
        dvec = self.x1[:, self.j] - self.x1[:, self.i]
        length = np.linalg.norm(dvec, axis=2)
        u = dvec / np.where(length < 1e-12, np.inf, length)[..., None]
        s = np.einsum("tlc,tlc->tl", self.v[:, self.j] - self.v[:, self.i], u)
        f = (k * (length - l0) + z * s)[..., None] * u
        size = (self.T - 2) * self.N
        F = np.empty((size, 3))
        for c in range(3):
            fc = f[..., c].ravel()
            F[:, c] = np.bincount(self.flat_i, fc, size) - np.bincount(self.flat_j, fc, size)
        F = F.reshape(self.T - 2, self.N, 3)
        xhat = 2 * self.x1 - self.x0 + self.dt**2 * (F / self.m[None, :, None] + self.g)
        e = np.sum((xhat - self.target) ** 2, axis=2)
        return float(np.sum(e[:, self.free]))


def median_time(f, min_seconds=0.3, repeats=5):
    samples = []
    for _ in range(repeats):
        n, start = 0, time.perf_counter()
        while time.perf_counter() - start < min_seconds or n == 0:
            f()
            n += 1
        samples.append((time.perf_counter() - start) / n)
    return statistics.median(samples)


def main():
    d = cloth_dict()
    truth = cordis.Scene.from_dict(d)
    traj = truth.simulate(FRAMES)
    # Evaluate away from the truth (the cost at the truth is ~0 for both).
    k, l0, z = np.array([18.0, 5.5, 2.2]), np.array([H * 1.01, H * 2**0.5, 2 * H]), np.array([2e-3, 1e-3, 5e-4])
    for name, kk, ll, zz in zip(["st", "sh", "be"], k, l0, z):
        d["types"][name].update(stiffness=kk, rest_length=ll, damping=zz)
    scene = cordis.Scene.from_dict(d)
    ref = NumpyShortCost(d, traj)
    generic = cordis.Objective(scene, traj, precompute=False)
    precomputed = cordis.Objective(scene, traj)
    p = generic.param_vector()
    c_np, c_gen, c_pre = ref(k, l0, z), generic(p), precomputed(p)
    assert abs(c_np - c_gen) <= 1e-9 * abs(c_np), (c_np, c_gen)
    assert abs(c_np - c_pre) <= 1e-9 * abs(c_np), (c_np, c_pre)
    t_np = median_time(lambda: ref(k, l0, z))
    t_cost = median_time(lambda: cordis.cost(scene, traj))
    t_gen = median_time(lambda: generic(p))
    t_pre = median_time(lambda: precomputed(p))
    links = len(d["links"])
    for name, t in [("numpy", t_np), ("cordis.cost", t_cost), ("Objective generic", t_gen),
                    ("Objective precomputed", t_pre)]:
        print(json.dumps({"bench": "numpy_cost", "impl": name, "cloth": f"{NX}x{NY}", "links": links,
                          "frames": FRAMES, "seconds_per_eval": t,
                          "link_evals_per_s": links * (FRAMES - 2) / t, "speedup_vs_numpy": t_np / t}))
    print(f"numpy {t_np*1e3:.3f} ms | cordis.cost {t_cost*1e3:.3f} ms ({t_np/t_cost:.0f}x) | "
          f"Objective generic {t_gen*1e3:.3f} ms ({t_np/t_gen:.0f}x) | precomputed {t_pre*1e6:.1f} µs "
          f"({t_np/t_pre:.0f}x)")


if __name__ == "__main__":
    main()
