"""Identification on a Ray cluster (``pip install 'cordis-anima[ray]'``).

Two ways to scale out, both on an existing Ray instance (``ray.init(address=...)``) or on a
local one started on first use:

- :class:`RayExecutor`: ``cordis.identify(..., executor=cordis.RayExecutor(num_workers=8))``
  (or ``executor="ray"``) evaluates each generation's population on Ray actors. Each actor
  compiles the scene and the trajectory once, when it starts (a
  :class:`cordis.PopulationEvaluator`); afterwards only genomes (one row of internal
  coordinates per individual) go out and costs come back. The run itself — the strategy, its
  random draws, stop rules, callbacks, checkpoints — stays in the calling process, so the
  result is bit-identical to a local run with the same seed. An actor that dies is restarted
  (its problem compiled again) and its batch re-run (``max_restarts``).
- :func:`identify_many`: one independent identification per trajectory (one model per recorded
  take), each a Ray task; progress is reported as takes finish, finished takes are written to
  ``out_dir`` (and skipped when the call is repeated), and a task whose worker dies is re-run
  (``max_retries``).

Islands (``cordis.identify(..., islands=K)``) run with either executor: every island's
population is one batch of the executor.
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path
from typing import Any, Callable, Dict, Iterable, Mapping, Optional, Union

import numpy as np

try:
    import ray
except ImportError as e:  # pragma: no cover - exercised without ray installed
    raise ImportError(
        "cordis.ray needs Ray, an optional extra: pip install 'cordis-anima[ray]' "
        "(or pip install ray)"
    ) from e

import cordis

__all__ = ["RayExecutor", "RayEvaluator", "identify_many"]


def _ensure_ray(address: Optional[str], init_kwargs: Mapping[str, Any]) -> None:
    """Connects to Ray once: to `address` (a cluster), else to a local instance started here."""
    if not ray.is_initialized():
        ray.init(address=address, **dict(init_kwargs))


class _Worker:
    """A Ray actor holding one compiled problem; restarted by Ray if its process dies."""

    def __init__(self, spec: tuple) -> None:
        scene_json, traj, cost, threads = spec
        self._ev = cordis.PopulationEvaluator(
            cordis.Scene.from_json(scene_json), traj, cost, threads=threads
        )

    def evaluate(self, genomes: np.ndarray, generation: int, local: bool) -> Any:
        # The actor's own evaluation time travels back too: the driver can tell the round
        # trip's overhead from the work (RayEvaluator.last_timing).
        start = time.perf_counter()
        out = self._ev.evaluate(genomes, generation, local)
        return out, time.perf_counter() - start

    def pid(self) -> int:
        return os.getpid()


_RemoteWorker = ray.remote(_Worker)


class RayEvaluator:
    """The evaluator of one run: `num_workers` actors; each population is split into as many
    contiguous row blocks, one per actor, evaluated in parallel (one round trip per
    generation). Made by :meth:`RayExecutor.evaluator`; :meth:`close` kills the actors."""

    def __init__(
        self,
        scene_json: str,
        traj: np.ndarray,
        cost: str,
        num_workers: int,
        threads_per_worker: int,
        max_restarts: int,
    ) -> None:
        # Sent to the object store once; every actor (and every restart) reads it from there.
        spec = ray.put((scene_json, np.ascontiguousarray(traj), cost, threads_per_worker))
        # Held until close(): a restarted actor reads its constructor argument again.
        self._spec = spec
        self.num_workers = num_workers
        # (wall seconds of the last generation's round trip, seconds the slowest actor spent
        # evaluating): their difference is Ray's overhead for that generation.
        self.last_timing = (0.0, 0.0)
        self._actors = [
            _RemoteWorker.options(
                num_cpus=threads_per_worker,
                max_restarts=max_restarts,
                max_task_retries=max_restarts,
            ).remote(spec)
            for _ in range(num_workers)
        ]

    def __call__(self, genomes: np.ndarray, generation: int, local: bool) -> Any:
        blocks = [b for b in np.array_split(genomes, len(self._actors)) if len(b)]
        start = time.perf_counter()
        refs = [a.evaluate.remote(b, generation, local) for a, b in zip(self._actors, blocks)]
        timed = ray.get(refs)
        outs = [o for o, _ in timed]
        self.last_timing = (time.perf_counter() - start, max(t for _, t in timed))
        if not local:
            return np.concatenate(outs)
        return np.concatenate([o[0] for o in outs]), np.concatenate([o[1] for o in outs])

    def pids(self) -> list:
        """The process ids of the actors (for monitoring, or to test fault tolerance)."""
        return ray.get([a.pid.remote() for a in self._actors])

    def close(self) -> None:
        for a in self._actors:
            ray.kill(a, no_restart=True)
        self._actors = []
        self._spec = None


class RayExecutor:
    """Evaluates `cordis.identify`'s populations on Ray actors.

    - `num_workers`: actors (default: the cluster's CPUs divided by `threads_per_worker`);
    - `threads_per_worker`: threads of each actor's evaluator (and the CPUs it reserves);
    - `address`: the Ray cluster to join when Ray is not initialised yet (None: start a local
      instance; ``"auto"``: the cluster this machine belongs to); `init_kwargs`: more
      ``ray.init`` arguments;
    - `max_restarts`: how many times a dead actor is restarted and its batch re-run.

    The executor can serve several runs one after the other; `last` is the evaluator of the
    current (or last) run.
    """

    def __init__(
        self,
        num_workers: Optional[int] = None,
        *,
        threads_per_worker: int = 1,
        address: Optional[str] = None,
        max_restarts: int = 3,
        init_kwargs: Optional[Mapping[str, Any]] = None,
    ) -> None:
        if num_workers is not None and num_workers < 1:
            raise ValueError(f"num_workers: must be 1 or more, got {num_workers}")
        if threads_per_worker < 1:
            raise ValueError(f"threads_per_worker: must be 1 or more, got {threads_per_worker}")
        self.num_workers = num_workers
        self.threads_per_worker = threads_per_worker
        self.address = address
        self.max_restarts = max_restarts
        self.init_kwargs = dict(init_kwargs or {})
        self.last: Optional[RayEvaluator] = None

    def evaluator(self, scene_json: str, traj: np.ndarray, cost: str) -> RayEvaluator:
        """Starts the actors of one run (called by `cordis.identify`)."""
        _ensure_ray(self.address, self.init_kwargs)
        cpus = int(ray.cluster_resources().get("CPU", 1))
        n = self.num_workers
        if n is None:
            n = max(1, cpus // self.threads_per_worker)
        elif n * self.threads_per_worker > cpus:
            # Ray would wait forever for CPUs that do not exist: say so instead of hanging.
            raise ValueError(
                f"num_workers: {n} workers of {self.threads_per_worker} thread(s) need "
                f"{n * self.threads_per_worker} CPUs, the Ray cluster has {cpus}"
            )
        self.last = RayEvaluator(
            scene_json, traj, cost, n, self.threads_per_worker, self.max_restarts
        )
        return self.last

    def __repr__(self) -> str:
        return (
            f"RayExecutor(num_workers={self.num_workers}, "
            f"threads_per_worker={self.threads_per_worker}, address={self.address!r})"
        )


def _summary(name: str, res: "cordis.IdentifyResult") -> Dict[str, Any]:
    """An `IdentifyResult` as plain JSON values (what `identify_many` returns and writes)."""

    def num(x: Optional[float]) -> Any:
        return None if x is None or not np.isfinite(x) else float(x)

    return {
        "name": name,
        "params": {k: float(v) for k, v in res.params.items()},
        "cost": num(res.cost),
        "rmse": num(res.rmse),
        "param_error_pct": num(res.param_error_pct),
        "evals": int(res.evals),
        "generations": int(res.generations),
        "seconds": float(res.seconds),
        "strategy": res.strategy,
        "stopped_by": res.stopped_by,
        "scene": res.scene.to_json(),
        "history_columns": list(cordis.IdentifyResult.HISTORY_COLUMNS),
        "history": [[num(v) for v in row] for row in res.history.tolist()],
    }


@ray.remote
def _identify_take(name: str, scene_json: str, traj: np.ndarray, kwargs: dict) -> Dict[str, Any]:
    res = cordis.identify(cordis.Scene.from_json(scene_json), traj, **kwargs)
    return _summary(name, res)


def _write_atomic(path: Path, text: str) -> None:
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    tmp.write_text(text)
    os.replace(tmp, path)


def identify_many(
    scene: "cordis.Scene",
    trajectories: Union[Mapping[str, Any], Iterable[Any]],
    *,
    out_dir: Optional[Union[str, os.PathLike]] = None,
    progress: Optional[Callable[[int, int, str, Dict[str, Any]], Any]] = None,
    max_retries: int = 3,
    threads: int = 1,
    address: Optional[str] = None,
    init_kwargs: Optional[Mapping[str, Any]] = None,
    **identify_kwargs: Any,
) -> Dict[str, Dict[str, Any]]:
    """Identifies `scene`'s unknowns once per trajectory, each take a Ray task.

    - `trajectories`: ``{name: (T, N, 3) array}``, or a sequence (named ``"0"``, ``"1"``…);
    - `identify_kwargs`: passed to :func:`cordis.identify` for every take (``strategy``,
      ``generations``, ``seed``, ``truth``…); each task uses `threads` threads (and reserves as
      many CPUs);
    - `out_dir`: each finished take is written there as ``NAME.json`` the moment it finishes
      (atomically); takes already there are loaded, not re-run — a crashed or interrupted
      batch resumes where it stopped;
    - `progress(done, total, name, result)`: called in this process as each take finishes;
    - `max_retries`: how often a take whose worker died is re-run (Ray's task retries).

    Returns ``{name: result}``, each result a dict of plain values: ``params`` by name,
    ``cost``, ``rmse``, ``param_error_pct``, ``evals``, ``generations``, ``seconds``,
    ``strategy``, ``stopped_by``, ``scene`` (identified, JSON text) and ``history`` (rows of
    ``history_columns``). A take that keeps failing raises its error after the others are kept.
    """
    if isinstance(trajectories, Mapping):
        takes = {str(k): v for k, v in trajectories.items()}
    else:
        takes = {str(k): v for k, v in enumerate(trajectories)}
    if identify_kwargs.get("executor") is not None:
        raise ValueError("identify_many: each take runs on its own worker; pass no executor")
    identify_kwargs.setdefault("threads", threads)
    out = Path(out_dir) if out_dir is not None else None
    results: Dict[str, Dict[str, Any]] = {}
    if out is not None:
        out.mkdir(parents=True, exist_ok=True)
        for name in takes:
            f = out / f"{name}.json"
            if f.exists():
                results[name] = json.loads(f.read_text())
    total = len(takes)
    done = len(results)
    _ensure_ray(address, init_kwargs or {})
    cpus = int(ray.cluster_resources().get("CPU", 1))
    if threads > cpus:
        raise ValueError(f"threads: a take on {threads} threads needs {threads} CPUs, "
                         f"the Ray cluster has {cpus}")
    scene_json = scene.to_json()
    scene_ref = ray.put(scene_json)
    pending = {
        _identify_take.options(max_retries=max_retries, num_cpus=threads).remote(
            name, scene_ref, ray.put(np.ascontiguousarray(traj, dtype=np.float64)),
            identify_kwargs,
        ): name
        for name, traj in takes.items()
        if name not in results
    }
    failure: Optional[BaseException] = None
    while pending:
        ready, _ = ray.wait(list(pending), num_returns=1)
        name = pending.pop(ready[0])
        try:
            res = ray.get(ready[0])
        except Exception as e:  # a take that kept failing; the others go on
            failure = failure or e
            continue
        results[name] = res
        done += 1
        if out is not None:
            _write_atomic(out / f"{name}.json", json.dumps(res))
        if progress is not None:
            progress(done, total, name, res)
    if failure is not None:
        raise failure
    return {name: results[name] for name in takes}
