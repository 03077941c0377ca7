"""Overhead of evaluating populations on Ray actors vs locally, per generation (BENCHMARKS.md).

    pip install "./python[ray]"
    python benches/ray_overhead.py [--population 40] [--repeats 7] [--frames 100]

For each scene (the rigid example, random spring networks of growing size, the 32x32 cloth)
it captures one realistic population (the genomes of a thesis run's first generation), then
times, interleaved and repeated (medians):

- ``local1``: the population on one local thread (gives the cost of one evaluation);
- ``local2``: on a local pool of 2 threads (what `cordis.identify` does on this machine);
- ``ray1`` / ``ray2``: through a RayExecutor's evaluator with 1 / 2 actors (1 thread each),
  local costs included as the thesis strategy asks, i.e. one generation's round trip.

The overhead of a generation (``over1``/``over2``) is the round trip minus the slowest actor's
own evaluation time (``RayEvaluator.last_timing``); the per-actor part of it is ``over2 -
over1``. It prints one table row per scene and a
projection for N nodes of C cores: ``T(N) = M t_eval / (N C) + o0 + o1 N C``.
"""

import argparse
import statistics
import time

import numpy as np
import ray

import cordis
import cordis.ray as cray


def capture_population(scene, traj, population):
    """The genomes of generation 1 of a thesis run (realistic points inside the boxes)."""
    seen = []

    class Capture:
        def evaluator(self, scene_json, traj, cost):
            ev = cordis.PopulationEvaluator(cordis.Scene.from_json(scene_json), traj, cost)

            def evaluate(genomes, generation, local):
                seen.append(np.array(genomes))
                return ev.evaluate(genomes, generation, local)

            return evaluate

    cordis.identify(scene, traj, strategy="thesis", generations=1, population=population,
                    seed=0, executor=Capture())
    return seen[0]


def scenes(frames):
    rigid = cordis.example("rigid")
    yield "rigid (15 particles, 31 links)", rigid, cordis.example("rigid", unknowns=True)
    for masses in (100, 400, 1000):
        truth = cordis.random_network(1, masses, 4)
        d = truth.to_dict()
        # Rest lengths unknown too: the cost is then evaluated by simulation steps (the
        # generic path, cost ∝ links × frames), not by the precomputed quadratic form that
        # linear unknowns alone allow (µs whatever the size).
        for t in d["types"].values():
            for key in ("stiffness", "rest_length"):
                if t.get(key, 0) > 0:
                    t[key] = {"min": t[key] / 2, "max": t[key] * 2}
        scene = cordis.Scene.from_dict(d)
        yield f"random network ({truth.num_particles} particles, {truth.num_links} links)", \
            truth, scene
    cloth = cordis.example("cloth")
    yield "cloth 32x32 (1024 particles, 5826 links)", cloth, cordis.example("cloth", unknowns=True)


def timed(f, repeats):
    out = []
    for _ in range(repeats):
        t = time.perf_counter()
        f()
        out.append(time.perf_counter() - t)
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--population", type=int, default=40)
    ap.add_argument("--repeats", type=int, default=7)
    ap.add_argument("--frames", type=int, default=100)
    args = ap.parse_args()
    # 3 logical CPUs: the 1-actor and the 2-actor evaluators live side by side (idle actors
    # cost nothing); the machine has 2 cores, which is what the timings see.
    ray.init(num_cpus=3, include_dashboard=False, log_to_driver=False)
    rows = []
    for name, truth, scene in scenes(args.frames):
        traj = truth.simulate(args.frames)
        g = capture_population(scene, traj, args.population)
        m = len(g)
        l1 = cordis.PopulationEvaluator(scene, traj, "short", threads=1)
        l2 = cordis.PopulationEvaluator(scene, traj, "short", threads=2)
        r1 = cray.RayExecutor(num_workers=1).evaluator(scene.to_json(), traj, "short")
        r2 = cray.RayExecutor(num_workers=2).evaluator(scene.to_json(), traj, "short")
        for f in (lambda: r1(g, 0, True), lambda: r2(g, 0, True)):
            f()  # actors compile the problem on their first call's wait
        t = {k: [] for k in ("local1", "local2", "ray1", "ray2", "over1", "over2")}
        for _ in range(args.repeats):  # interleaved: a load change hits every column alike
            t["local1"] += timed(lambda: l1.evaluate(g, 0, True), 1)
            t["local2"] += timed(lambda: l2.evaluate(g, 0, True), 1)
            for k, r in (("1", r1), ("2", r2)):
                t["ray" + k] += timed(lambda: r(g, 0, True), 1)
                # The round trip minus the slowest actor's own evaluation: Ray's overhead,
                # whatever the load did to the evaluation itself (Ray's workers run niced).
                wall, work = r.last_timing
                t["over" + k].append(wall - work)
        r1.close()
        r2.close()
        med = {k: statistics.median(v) for k, v in t.items()}
        rows.append((name, m, med))
        print(f"{name}: M={m} "
              + " ".join(f"{k}={v * 1e3:.2f}ms" for k, v in med.items())
              + f" t_eval={med['local1'] / m * 1e3:.3f}ms"
              + f" ray2/local2={med['ray2'] / med['local2']:.2f}"
              + f" ray2/local1={med['ray2'] / med['local1']:.2f}", flush=True)
    # Projection: o0 (fixed) and o1 (per actor) from the 1- and 2-actor overheads of the
    # largest scene, the evaluation cost from one local thread.
    name, m, med = rows[-1]
    t_eval = med["local1"] / m
    o1 = max(med["over2"] - med["over1"], 0.0)
    o0 = max(med["over1"] - o1, 0.0)
    print(f"\nprojection for {name}: t_eval={t_eval * 1e3:.3f} ms, o0={o0 * 1e3:.2f} ms, "
          f"o1={o1 * 1e3:.2f} ms per actor")
    for pop in (100, 1000, 2000):
        cells = []
        for nodes in (1, 2, 4, 8, 16, 32):
            workers = 2 * nodes
            t = pop * t_eval / workers + o0 + o1 * workers
            cells.append(f"N={nodes}: {t * 1e3:.1f} ms (x{pop * t_eval / t:.1f})")
        print(f"population {pop}: " + ", ".join(cells))
    ray.shutdown()


if __name__ == "__main__":
    main()
