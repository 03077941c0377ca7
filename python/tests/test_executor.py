"""The executor protocol without Ray: a pure-Python executor built on PopulationEvaluator gives
the local result bit for bit; its exceptions reach the caller; islands are deterministic; and
`executor="ray"` without Ray says how to install it."""

import sys

import numpy as np
import pytest

import cordis

DETERMINISTIC = [0, 1, 3, 4, 5, 6, 7]  # every history column but the seconds
RUN = dict(strategy="thesis", generations=10, population=16, seed=9)


@pytest.fixture(scope="module")
def rigid():
    truth = cordis.example("rigid")
    return truth, truth.simulate(40), cordis.example("rigid", unknowns=True)


class Reversed:
    """Evaluates each population one genome at a time, last first, on its own compiled copy
    of the problem built from the JSON text (as a remote worker does)."""

    def __init__(self):
        self.calls = []

    def evaluator(self, scene_json, traj, cost):
        ev = cordis.PopulationEvaluator(cordis.Scene.from_json(scene_json), traj, cost)

        def evaluate(genomes, generation, local):
            self.calls.append((genomes.shape, generation, local))
            rows = [ev.evaluate(g[None, :], generation, local) for g in genomes[::-1]]
            if not local:
                return np.concatenate(rows[::-1])
            return (np.concatenate([r[0] for r in rows[::-1]]),
                    np.concatenate([r[1] for r in rows[::-1]]))

        return evaluate


def same(a, b):
    np.testing.assert_array_equal(a.history[:, DETERMINISTIC], b.history[:, DETERMINISTIC])
    assert a.params == b.params and a.cost == b.cost


@pytest.mark.parametrize("strategy", ["thesis", "t2m", "cmaes"])
def test_a_python_executor_gives_the_local_result(rigid, strategy):
    truth, traj, scene = rigid
    ex = Reversed()
    kw = dict(RUN, strategy=strategy, noise=1e-4)
    same(cordis.identify(scene, traj, **kw), cordis.identify(scene, traj, executor=ex, **kw))
    gens = [g for _, g, _ in ex.calls]
    if strategy == "thesis":
        # The text's ES may draw no child in a generation of 16 (then no batch).
        assert gens[0] == 0 and gens == sorted(set(gens)) and gens[-1] <= RUN["generations"]
    else:
        assert len(ex.calls) == RUN["generations"] + 1, "one batch per generation"
        assert gens == list(range(RUN["generations"] + 1))
    # Only the thesis ES asks for local costs (its crossover uses them).
    assert all(local == (strategy in ("thesis", "t2m")) for _, _, local in ex.calls)


def test_population_evaluator_matches_objective(rigid):
    truth, traj, scene = rigid
    ev = cordis.PopulationEvaluator(scene, traj)
    g = np.random.default_rng(0).uniform(0.3, 0.7, size=(5, ev.dim))
    costs, local = ev.evaluate(g, local=True)
    assert costs.shape == (5,) and local.shape == (5, ev.num_particles)
    np.testing.assert_allclose(local.sum(axis=1), costs, rtol=1e-12)
    np.testing.assert_array_equal(ev.evaluate(g), costs)
    with pytest.raises(ValueError, match=rf"expected shape \(M, {ev.dim}\)"):
        ev.evaluate(np.zeros((2, ev.dim + 1)))


def test_executor_exceptions_reach_the_caller(rigid):
    truth, traj, scene = rigid

    class Broken:
        def evaluator(self, scene_json, traj, cost):
            calls = []

            def evaluate(genomes, generation, local):
                calls.append(generation)
                if generation == 3:
                    raise ConnectionError("cluster lost")
                return Reversed().evaluator(scene_json, traj, cost)(genomes, generation, local)

            return evaluate

    with pytest.raises(ConnectionError, match="cluster lost"):
        cordis.identify(scene, traj, executor=Broken(), **RUN)

    class WrongShape:
        def evaluator(self, scene_json, traj, cost):
            return lambda genomes, generation, local: np.zeros(len(genomes) + 1)

    with pytest.raises(ValueError, match="costs: expected shape"):
        cordis.identify(scene, traj, executor=WrongShape(), **dict(RUN, strategy="cmaes"))


def test_islands_are_deterministic_and_count_their_populations(rigid):
    truth, traj, scene = rigid
    kw = dict(RUN, islands=3, migrate_every=2, migrants=1)
    a = cordis.identify(scene, traj, threads=1, **kw)
    same(a, cordis.identify(scene, traj, threads=2, **kw))
    assert a.strategy == "islands" and a.history[0, 1] == 3 * RUN["population"]
    b = cordis.identify(scene, traj, **dict(kw, islands=2))
    assert not np.array_equal(a.history[:, 3], b.history[:, 3])
    with pytest.raises(ValueError, match="cmaes"):
        cordis.identify(scene, traj, **dict(kw, strategy="cmaes"))
    with pytest.raises(ValueError, match="islands"):
        cordis.identify(scene, traj, **dict(kw, islands=1))


def test_executor_ray_without_ray_says_how_to_install_it(rigid, monkeypatch):
    # Ray made unimportable (CI installs it, so the test hides it rather than skipping).
    monkeypatch.setitem(sys.modules, "ray", None)
    monkeypatch.delitem(sys.modules, "cordis.ray", raising=False)
    truth, traj, scene = rigid
    with pytest.raises(ImportError, match=r"cordis-anima\[ray\]"):
        cordis.identify(scene, traj, executor="ray", **RUN)
    with pytest.raises(ImportError, match=r"cordis-anima\[ray\]"):
        cordis.RayExecutor()
