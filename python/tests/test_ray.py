"""Identification on a local Ray instance (2 worker processes): the same result as a local run
for a seed, a killed actor or task worker loses nothing, islands and batch runs. Skipped when
Ray is not installed (``pip install cordis-anima[ray]``); one ``ray.init`` for the module."""

import json
import os
import signal

import numpy as np
import pytest

import cordis

ray = pytest.importorskip("ray")
cordis_ray = pytest.importorskip("cordis.ray")

# Everything but the wall-clock seconds (column 2) of IdentifyResult.history.
DETERMINISTIC = [0, 1, 3, 4, 5, 6, 7]


@pytest.fixture(scope="module")
def local_ray():
    # Ray start-up costs seconds: one instance for the whole module, shut down after it.
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False,
             configure_logging=False)
    yield
    ray.shutdown()


@pytest.fixture(scope="module")
def rigid():
    truth = cordis.example("rigid")
    return truth, truth.simulate(40), cordis.example("rigid", unknowns=True)


# `t2m` (the T2M variant of the thesis ES): each generation replaces most of the population, so
# 12 generations of 20 make progress to compare; the text's `thesis` draws ~15 % crossovers and
# 1 % mutations per generation and, at this size, may not improve on its first generation.
RUN = dict(strategy="t2m", generations=12, population=20, seed=5)


def same(a, b):
    np.testing.assert_array_equal(a.history[:, DETERMINISTIC], b.history[:, DETERMINISTIC])
    assert a.params == b.params and a.cost == b.cost and a.evals == b.evals


def test_ray_run_equals_the_local_run(local_ray, rigid):
    truth, traj, scene = rigid
    local = cordis.identify(scene, traj, truth=truth, **RUN)
    ex = cordis.RayExecutor(num_workers=2)
    remote = cordis.identify(scene, traj, truth=truth, executor=ex, **RUN)
    same(local, remote)
    assert remote.cost < remote.history[0, 3], "no progress"
    assert ex.last is not None and ex.last.num_workers == 2


def test_executor_ray_string_and_a_noisy_progressive_cost(local_ray, rigid):
    # The workers must see the noisy trajectory and the growing horizon the driver sees.
    truth, traj, scene = rigid
    kw = dict(RUN, noise=1e-4, cost="progressive:4:2")
    same(cordis.identify(scene, traj, **kw), cordis.identify(scene, traj, executor="ray", **kw))


def test_a_killed_worker_does_not_lose_the_run(local_ray, rigid):
    truth, traj, scene = rigid
    ex = cordis.RayExecutor(num_workers=2)
    killed = []

    def kill_one(generation, best_cost, params):
        if generation == 4 and not killed:
            pid = ex.last.pids()[0]
            os.kill(pid, signal.SIGKILL)
            killed.append(pid)

    remote = cordis.identify(scene, traj, executor=ex, callback=kill_one, **RUN)
    assert killed, "the callback never ran"
    same(cordis.identify(scene, traj, **RUN), remote)


def test_islands_on_ray_equal_islands_locally(local_ray, rigid):
    truth, traj, scene = rigid
    kw = dict(RUN, islands=2, migrate_every=3, migrants=1)
    local = cordis.identify(scene, traj, **kw)
    same(local, cordis.identify(scene, traj, executor=cordis.RayExecutor(num_workers=2), **kw))
    assert local.strategy == "islands"
    # Two islands of 20 evaluate 40 individuals at generation 0.
    assert local.history[0, 1] == 40


def test_identify_many_keeps_results_and_reruns_a_killed_task(local_ray, rigid, tmp_path):
    truth, traj, scene = rigid
    takes = {"a": traj, "b": truth.simulate(30)}
    marker = tmp_path / "killed"

    def die_once(generation, best_cost, params):
        # The first attempt at a take kills its own worker process mid-run; Ray re-runs it.
        if generation == 3 and not marker.exists():
            marker.write_text("x")
            os.kill(os.getpid(), signal.SIGKILL)

    seen = []
    out = tmp_path / "out"
    res = cordis_ray.identify_many(
        scene, takes, out_dir=out, progress=lambda d, t, n, r: seen.append((d, t, n)),
        callback=die_once, **RUN)
    assert marker.exists(), "no worker was killed"
    assert [(d, t) for d, t, _ in seen] == [(1, 2), (2, 2)]
    assert sorted(n for _, _, n in seen) == ["a", "b"]
    for name, t in takes.items():
        local = cordis.identify(scene, t, **RUN)
        assert res[name]["params"] == local.params
        assert res[name]["cost"] == local.cost
        assert json.loads((out / f"{name}.json").read_text()) == res[name]
    # Finished takes are kept: a second call loads them instead of running anything.
    seen.clear()
    again = cordis_ray.identify_many(scene, takes, out_dir=out, progress=seen.append, **RUN)
    assert again == res and seen == []


def test_more_workers_than_cpus_is_an_error_not_a_hang(local_ray, rigid):
    truth, traj, scene = rigid
    with pytest.raises(ValueError, match="need 3 CPUs, the Ray cluster has 2"):
        cordis.identify(scene, traj, executor=cordis.RayExecutor(num_workers=3), **RUN)


def test_bad_executor_arguments(rigid):
    truth, traj, scene = rigid
    with pytest.raises(ValueError, match="unknown executor `dask`"):
        cordis.identify(scene, traj, executor="dask", **RUN)
    with pytest.raises(TypeError, match="evaluator"):
        cordis.identify(scene, traj, executor=object(), **RUN)
    with pytest.raises(ValueError, match="num_workers"):
        cordis.RayExecutor(num_workers=0)
