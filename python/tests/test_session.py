"""`cordis.identify` and `cordis identify` are one session: the same checks, refusals,
warnings and outcome for the same request."""

import json
import os
import shutil
import subprocess
import sys
import time
import warnings

import pytest

import cordis

STRATEGIES = ["auto", "thesis", "t2m", "least-squares", "hybrid", "cmaes", "self-adaptive",
              "annealing", "parisian", "levenberg-marquardt", "output-error"]


@pytest.fixture(scope="module")
def rigid():
    truth = cordis.example("rigid")
    return truth, truth.simulate(60), cordis.example("rigid", unknowns=True)


def with_unknown_masses(scene):
    d = json.loads(scene.to_json())
    for p in d["particles"]:
        if not p.get("fixed"):
            p["mass"] = {"min": 0.3, "max": 3.0}
    return cordis.Scene.from_dict(d)


def test_unknown_masses_without_a_total_say_to_pass_total_mass(rigid):
    truth, traj, scene = rigid
    masses = with_unknown_masses(scene)
    for strategy in ["auto", "least-squares", "thesis"]:
        with pytest.raises(ValueError, match="pass total_mass"):
            cordis.identify(masses, traj, strategy=strategy, generations=2)
    # With the total, the exact solver determines masses and links together.
    total = sum(p.mass for p in truth.particles if not p.fixed)
    r = cordis.identify(masses, traj, total_mass=total, truth=truth)
    assert r.strategy == "least-squares" and r.param_error_pct < 1e-6


def test_a_total_mass_is_refused_by_the_strategies_that_would_ignore_it(rigid):
    truth, traj, scene = rigid
    masses = with_unknown_masses(scene)
    total = sum(p.mass for p in truth.particles if not p.fixed)
    for strategy in ["thesis", "cmaes", "levenberg-marquardt"]:
        with pytest.raises(ValueError, match=f"total_mass: is honoured by least-squares and "
                                             f"hybrid only .* `{strategy}` would ignore it"):
            cordis.identify(masses, traj, strategy=strategy, total_mass=total, generations=2)


def test_an_exact_solver_on_a_muscle_is_refused_before_any_work():
    truth = cordis.example("muscle")
    traj = truth.simulate(100)
    scene = cordis.example("muscle", unknowns=True)
    calls = []
    for strategy in ["least-squares", "hybrid"]:
        start = time.perf_counter()
        with pytest.raises(ValueError, match="muscle"):
            cordis.identify(scene, traj, strategy=strategy,
                            callback=lambda *a: calls.append(a))
        assert time.perf_counter() - start < 5.0
    assert calls == [], "a refused run evaluated something"
    with pytest.raises(ValueError, match="short cost"):
        cordis.identify(cordis.example("rigid", unknowns=True), cordis.example("rigid").simulate(50),
                        strategy="least-squares", cost="long")


def test_session_errors_are_cordis_error_classes_with_place_and_message(rigid, tmp_path):
    """Each way a session fails has its own CordisError subclass, still catchable as the
    built-in class it used to be, with `place` and `message` attributes."""
    truth, traj, scene = rigid
    # An option out of its range: ArgumentError (a ValueError).
    with pytest.raises(cordis.ArgumentError) as e:
        cordis.identify(scene, traj, strategy="thesis", time_limit=1e308)
    assert isinstance(e.value, ValueError) and isinstance(e.value, cordis.CordisError)
    assert "time_limit" in e.value.place and e.value.message in str(e.value)
    with pytest.raises(cordis.ArgumentError, match="unknown strategy `nope`") as e:
        cordis.identify(scene, traj, strategy="nope")
    assert e.value.place == "strategy"
    # A strategy that cannot run on the problem: RefusedError (a ValueError), before any work.
    muscle = cordis.example("muscle")
    with pytest.raises(cordis.RefusedError) as e:
        cordis.identify(cordis.example("muscle", unknowns=True), muscle.simulate(50),
                        strategy="least-squares")
    assert isinstance(e.value, ValueError) and isinstance(e.value, cordis.CordisError)
    assert "tanh" in e.value.message and e.value.place
    # A solve that cannot succeed (the motion at 1e300 m overflows the normal equations):
    # RunError (a RuntimeError), no result.
    with pytest.raises(cordis.RunError) as e:
        cordis.identify(scene, traj * 1e300, strategy="least-squares")
    assert isinstance(e.value, RuntimeError) and isinstance(e.value, cordis.CordisError)
    assert "least-squares" in str(e.value) and e.value.message
    # A checkpoint of another request: CheckpointError naming what differs.
    cp = tmp_path / "cp.json"
    cordis.identify(scene, traj, strategy="thesis", population=10, generations=3, checkpoint=cp)
    with pytest.raises(cordis.CheckpointError) as e:
        cordis.identify(scene, traj, strategy="thesis", population=10, generations=5,
                        noise=1e-4, resume=cp)
    assert "noise" in e.value.message and e.value.place
    # A checkpoint that cannot be written (/dev/full: ENOSPC): RunError, the result kept.
    full = tmp_path / "full.json"
    full.symlink_to("/dev/full")
    with pytest.raises(cordis.RunError) as e:
        cordis.identify(scene, traj, strategy="thesis", population=10, generations=3,
                        checkpoint=full)
    assert e.value.place == "checkpoint" and e.value.result.generations == 3


def test_threads_beyond_the_machine_are_capped_with_a_warning(rigid):
    _, traj, scene = rigid
    with pytest.warns(UserWarning, match="threads 100000: capped"):
        r = cordis.identify(scene, traj, threads=100000)
    assert any("capped" in w for w in r.warnings)


def test_out_of_range_options_are_value_errors_naming_them(rigid):
    _, traj, scene = rigid
    for key, value in [("time_limit", 1e308), ("noise", 1e308), ("noise", float("inf")),
                       ("total_mass", -1.0), ("population", 10**11)]:
        with pytest.raises(ValueError, match=key):
            cordis.identify(scene, traj, strategy="thesis", **{key: value})


def test_the_report_and_lock_reach_python(rigid, tmp_path):
    truth, traj, scene = rigid
    r = cordis.identify(scene, traj, truth=truth)
    assert r.report["condition"] >= 1.0 and r.report["undetermined"] == []
    assert r.warnings == []
    name = next(iter(r.params))
    locked = cordis.identify(scene, traj, lock=[name])
    assert name not in locked.params
    with pytest.raises(ValueError, match="not an unknown"):
        cordis.identify(scene, traj, lock=["types.nope.stiffness"])
    gene = tmp_path / "Param.gene"
    gene.write_text("population=12\ngeneration=3\n")
    g = cordis.identify(scene, traj, strategy="thesis", generations=3, param_gene=gene,
                        descent_start=2, descent_every=1)
    assert g.history[0, 1] == 12 and g.generations == 3
    # Param.gene's `damping`: the thesis' 0 is accepted, another value refused by name.
    gene.write_text("population=12\ndamping=0\n")
    g = cordis.identify(scene, traj, strategy="thesis", generations=2, param_gene=gene,
                        crossover="n-parent")
    assert g.generations == 2
    gene.write_text("population=12\ndamping=0.5\n")
    with pytest.raises(ValueError, match=r"Param.gene:2: damping=0.5: not supported"):
        cordis.identify(scene, traj, strategy="thesis", generations=2, param_gene=gene)
    with pytest.raises(ValueError, match="crossover: unknown crossover `uniform`"):
        cordis.identify(scene, traj, strategy="thesis", generations=2, crossover="uniform")


def test_import_star_works_without_ray(tmp_path):
    code = ("import sys; sys.modules['ray'] = None\n"
            "from cordis import *\n"
            "assert 'identify' in dir() and 'RayExecutor' not in dir()\n"
            "import cordis; assert 'RayExecutor' in dir(cordis)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=tmp_path, timeout=120)
    assert out.returncode == 0, out.stderr


def test_help_lists_every_strategy():
    for name in STRATEGIES:
        assert f"`{name}`" in cordis.identify.__doc__, name


def cordis_exe():
    exe = shutil.which("cordis", path=os.path.dirname(sys.executable))
    assert exe is not None, "the cordis console script is not installed beside python"
    return exe


@pytest.mark.parametrize("strategy", STRATEGIES + ["islands"])
def test_the_cli_and_python_give_the_same_outcome(rigid, tmp_path, strategy):
    """Same request through both front ends: the same numbers, stop reason, report and
    identified scene, for every strategy (a few generations on the rigid example)."""
    truth, traj, scene = rigid
    (tmp_path / "truth.json").write_text(truth.to_json())
    (tmp_path / "scene.json").write_text(scene.to_json())
    cordis.write_trajectory(tmp_path / "traj.npy", traj)
    kw = dict(strategy=strategy, generations=4, population=8, seed=3, noise=1e-6)
    args = ["--strategy", strategy, "--generations", "4", "--population", "8", "--seed", "3",
            "--noise", "1e-6"]
    if strategy == "islands":
        kw.update(strategy="thesis", islands=2, migrate_every=2, migrants=1)
        args[1] = "thesis"
        args += ["--islands", "2", "--migrate-every", "2", "--migrants", "1"]
    out = subprocess.run([cordis_exe(), "identify", "scene.json", "-t", "traj.npy", "--truth",
                          "truth.json", "--out", "out.json", "-q", *args],
                         capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert out.returncode == 0, out.stderr
    summary = json.loads(out.stdout.strip().splitlines()[-1])
    with warnings.catch_warnings(record=True):
        res = cordis.identify(scene, traj, truth=truth, **kw)
    for key in ["cost", "rmse", "evals", "generations", "param_error_pct", "stopped_by"]:
        assert summary[key] == getattr(res, key), key
    if strategy != "islands":  # the CLI names what each island runs, Python "islands"
        assert summary["strategy"] == res.strategy
    assert json.loads(json.dumps(summary.get("solver"))) == json.loads(json.dumps(res.report))
    assert cordis.Scene.from_json(tmp_path / "out.json") == res.scene


def falling_chain(unknown):
    """Five beads between fixed ends 1 m apart, falling under gravity (as the CLI test's)."""
    particles = [{"mass": 1.0, "pos": [0, 0, 0], "fixed": True}]
    particles += [{"mass": 0.1, "pos": [k / 6.0, 0, 0]} for k in range(1, 6)]
    particles.append({"mass": 1.0, "pos": [1.0, 0, 0], "fixed": True})
    links = [{"type": "link", "particles": [i, i + 1]} for i in range(6)]
    links += [{"type": "air", "particles": [i]} for i in range(1, 6)]
    return cordis.Scene.from_dict({
        "dt": 0.01, "gravity": [0, 0, -9.81], "particles": particles, "links": links,
        "types": {"link": dict(kind="spring", **unknown), "air": {"kind": "drag", "damping": 0.3}},
    })


def test_self_adaptive_plus_and_correlated_are_read_and_refused_elsewhere():
    traj = falling_chain(dict(stiffness=50, rest_length=0.15, damping=0.5)).simulate(60)
    scene = falling_chain(dict(stiffness={"min": 5, "max": 500},
                               rest_length={"min": 0.05, "max": 0.5}, damping=0.5))
    kw = dict(strategy="self-adaptive", generations=15, population=14, seed=3)
    costs = {}
    for opts in [(), ("plus",), ("correlated",), ("plus", "correlated")]:
        res = cordis.identify(scene, traj, **kw, **{o: True for o in opts})
        assert res.strategy == "self-adaptive" and res.cost == res.cost
        costs[opts] = res.cost
    # Each option changes the search: it is read, not ignored.
    assert len(set(costs.values())) == 4, costs
    for key in ("plus", "correlated"):
        with pytest.raises(ValueError, match=f"{key}.*self-adaptive"):
            cordis.identify(scene, traj, strategy="cmaes", generations=2, **{key: True})


def test_cmaes_bipop_restarts_are_read_and_refused_elsewhere():
    traj = falling_chain(dict(stiffness=50, rest_length=0.15, damping=0.5)).simulate(60)
    scene = falling_chain(dict(stiffness={"min": 5, "max": 500},
                               rest_length={"min": 0.05, "max": 0.5}, damping=0.5))
    kw = dict(strategy="cmaes", generations=300, population=6, seed=3)
    ipop = cordis.identify(scene, traj, **kw)
    bipop = cordis.identify(scene, traj, **kw, restarts="bipop")
    # After the first run ends BIPOP runs a small population where IPOP doubles it.
    assert ipop.evals != bipop.evals
    assert cordis.identify(scene, traj, **kw, restarts="ipop").evals == ipop.evals
    again = cordis.identify(scene, traj, **kw, restarts="bipop")
    assert (again.evals, again.cost) == (bipop.evals, bipop.cost)
    with pytest.raises(ValueError, match="restarts: configures the cmaes strategy only, not t2m"):
        cordis.identify(scene, traj, strategy="t2m", generations=2, restarts="bipop")
    with pytest.raises(ValueError, match="restarts: unknown restarts `nbipop`"):
        cordis.identify(scene, traj, **kw, restarts="nbipop")


def test_thesis_options_are_read_by_the_thesis_es_and_refused_elsewhere(tmp_path):
    traj = falling_chain(dict(stiffness=50, rest_length=0.15, damping=0.5)).simulate(60)
    scene = falling_chain(dict(stiffness={"min": 5, "max": 500},
                               rest_length={"min": 0.05, "max": 0.5}, damping=0.5))
    es = tmp_path / "es.gene"
    es.write_text("pcross=30\npmut=2\n")
    kw = dict(strategy="t2m", generations=15, population=14, seed=3)
    plain = cordis.identify(scene, traj, **kw).cost
    # Read: each changes the t2m search.
    for opts in [dict(crossover="n-parent"), dict(descent_start=5, descent_every=5),
                 dict(param_gene=es), dict(local_cost="distances")]:
        assert cordis.identify(scene, traj, **kw, **opts).cost != plain, opts
    assert cordis.identify(scene, traj, **kw, crossover="mean").cost == plain
    assert cordis.identify(scene, traj, **kw, local_cost="positions").cost == plain
    # Eq 3.3 is the short cost's, and computed in this process only.
    with pytest.raises(ValueError, match=r"local_cost: distances \(eq 3.3\).*not the `long`"):
        cordis.identify(scene, traj, **kw, cost="long", local_cost="distances")
    with pytest.raises(ValueError, match="local_cost: 'distances' is computed in this process"):
        cordis.identify(scene, traj, **kw, local_cost="distances", executor="ray")
    with pytest.raises(ValueError, match="local_cost: unknown local cost `eq3.3`"):
        cordis.identify(scene, traj, **kw, local_cost="eq3.3")
    # Ignored elsewhere: refused by name (`auto` picks least-squares on this linear chain).
    for strategy, opts, says in [
            ("cmaes", dict(crossover="mean"), "crossover: .*, not cmaes"),
            ("self-adaptive", dict(descent_start=5), "descent_start: .*, not self-adaptive"),
            ("hybrid", dict(descent_every=0), "descent_every: .*, not hybrid"),
            ("auto", dict(crossover="n-parent"), r"crossover: .*least-squares \(what auto picked"),
            ("annealing", dict(param_gene=es), "param_gene .*es.gene: pcross, pmut configure"),
            ("parisian", dict(local_cost="distances"), "local_cost: .*, not parisian")]:
        with pytest.raises(ValueError, match=says) as e:
            cordis.identify(scene, traj, strategy=strategy, generations=2, **opts)
        assert "the thesis ES only (thesis, t2m)" in str(e.value)
