//! Identification (SPEC §4): `cordis.identify` and `IdentifyResult`, doing what `cordis
//! identify` does (noise, cost kind, truth, stop rules, checkpoint/resume, a local thread pool)
//! with a Python callback as an extra observer.
//!
//! The run goes on a worker thread, without the GIL; the calling thread waits for it, taking
//! the GIL every 50 ms only to run Python's signal handlers (Ctrl-C), which only the main thread
//! can do. The callback takes the GIL on the worker, once per generation.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc};
use std::time::Duration;

use cordis_es::executor::{
    self, HistoryRow, Observer, RunConfig, RunResult, StopReason, StopRules,
};
use cordis_es::identify::{
    add_noise, check_strategy, make_islands, make_strategy, StrategyName, StrategyOptions,
};
use cordis_es::problem::Problem;
use cordis_es::space::ParameterSpace;
use cordis_es::strategies::islands::IslandConfig;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2};
use pyo3::exceptions::{PyRuntimeError, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::errors::{checkpoint_error, cost_to_py, SceneError};
use crate::evaluator::PyEvaluator;
use crate::scene::Scene;
use crate::trajectory::{check_dt, traj_from_py, traj_to_py};

/// Columns of `IdentifyResult.history`, as in the CLI's CSV log.
const HISTORY_COLUMNS: [&str; 8] = [
    "generation",
    "evals",
    "seconds",
    "best_cost",
    "best_rmse",
    "mean_cost",
    "mean_mutability",
    "param_error_pct",
];

/// How often the waiting thread checks for Ctrl-C.
const SIGNAL_POLL: Duration = Duration::from_millis(50);

/// What `cordis.identify` found.
#[pyclass(frozen, module = "cordis", name = "IdentifyResult")]
pub struct IdentifyResult {
    /// The scene with the identified values written in (every parameter known).
    #[pyo3(get)]
    scene: Py<Scene>,
    /// Identified value of each unknown, by name (`types.NAME.PARAM`, `particles[i].mass`).
    #[pyo3(get)]
    params: Py<PyDict>,
    /// True value of each unknown when `truth` was given, else None.
    #[pyo3(get)]
    truth: Option<Py<PyDict>>,
    /// Global cost of the identified model (m² for every kind but harmonic).
    #[pyo3(get)]
    cost: f64,
    /// sqrt(cost / terms): RMS prediction error of a particle, m.
    #[pyo3(get)]
    rmse: f64,
    /// One row per generation (generation 0 is the initial population), float64, columns
    /// `HISTORY_COLUMNS`; `param_error_pct` is NaN without a truth.
    #[pyo3(get)]
    history: Py<PyArray2<f64>>,
    /// Cost evaluations made (across a resume too).
    #[pyo3(get)]
    evals: u64,
    /// Generations run (across a resume too).
    #[pyo3(get)]
    generations: u64,
    /// Wall-clock seconds (across a resume too).
    #[pyo3(get)]
    seconds: f64,
    /// The strategy that ran (`auto` names its choice).
    #[pyo3(get)]
    strategy: String,
    /// Mean relative error of the identified values against the truth, %, or None.
    #[pyo3(get)]
    param_error_pct: Option<f64>,
    /// Why the run stopped: `generations`, `max_evals`, `time_limit`, `target_cost`,
    /// `callback` or `interrupted`.
    #[pyo3(get)]
    stopped_by: String,
}

#[pymethods]
impl IdentifyResult {
    /// Names of the columns of `history`.
    #[classattr]
    #[allow(non_snake_case)]
    fn HISTORY_COLUMNS() -> Vec<&'static str> {
        HISTORY_COLUMNS.to_vec()
    }

    fn __repr__(&self, py: Python<'_>) -> PyResult<String> {
        let mut s = format!(
            "IdentifyResult(strategy='{}', generations={}, evals={}, seconds={:.3}, \
             stopped_by='{}', cost={:.6e}, rmse={:.6e}",
            self.strategy,
            self.generations,
            self.evals,
            self.seconds,
            self.stopped_by,
            self.cost,
            self.rmse
        );
        if let Some(e) = self.param_error_pct {
            s.push_str(&format!(", param_error_pct={e:.4e}"));
        }
        s.push_str(", params={");
        let truth = self.truth.as_ref().map(|t| t.bind(py));
        for (k, (name, v)) in self.params.bind(py).iter().enumerate() {
            let name: String = name.extract()?;
            let v: f64 = v.extract()?;
            s.push_str(if k == 0 { "\n    " } else { ",\n    " });
            s.push_str(&format!("'{name}': {v:.6e}"));
            if let Some(t) = truth.and_then(|t| t.get_item(&name).ok().flatten()) {
                s.push_str(&format!("  # truth {:.6e}", t.extract::<f64>()?));
            }
        }
        s.push_str("})");
        Ok(s)
    }
}

/// The Python callback as a run-loop observer; also stops the run once it asked to stop or
/// raised (the exception is kept and re-raised by `identify`).
struct CallbackObserver {
    callback: Option<Py<PyAny>>,
    space: ParameterSpace,
    error: Option<PyErr>,
    stop: bool,
}

impl Observer for CallbackObserver {
    fn observe(&mut self, _row: &HistoryRow) -> bool {
        !self.stop
    }

    fn observe_best(&mut self, row: &HistoryRow, best_genome: &[f64]) -> bool {
        if self.stop {
            return false;
        }
        let Some(callback) = &self.callback else {
            return true;
        };
        let outcome = Python::attach(|py| -> PyResult<bool> {
            let params = PyDict::new(py);
            for (u, v) in self
                .space
                .unknowns
                .iter()
                .zip(self.space.values(best_genome))
            {
                params.set_item(&u.name, v)?;
            }
            let ret = callback.call1(py, (row.generation, row.best_cost, params))?;
            let ret = ret.bind(py);
            Ok(ret.is_none() || ret.is_truthy()?)
        });
        match outcome {
            Ok(go_on) => self.stop = !go_on,
            Err(e) => {
                self.error = Some(e);
                self.stop = true;
            }
        }
        !self.stop
    }
}

fn stop_text(s: StopReason) -> &'static str {
    match s {
        StopReason::Generations => "generations",
        StopReason::MaxEvals => "max_evals",
        StopReason::TimeLimit => "time_limit",
        StopReason::TargetCost => "target_cost",
        StopReason::Interrupted => "interrupted",
        StopReason::Observer => "callback",
        StopReason::Converged => "converged",
        other => other.as_str(),
    }
}

/// A non-negative integer argument as `T`, or a `ValueError` naming it (rather than the
/// `OverflowError` of a plain conversion).
fn count<T: TryFrom<i128>>(x: impl Into<i128>, what: &str) -> PyResult<T> {
    let x = x.into();
    T::try_from(x)
        .ok()
        .filter(|_| x >= 0)
        .ok_or_else(|| bad(what, format!("must be a non-negative integer, got {x}")))
}

fn bad(what: &str, message: impl std::fmt::Display) -> PyErr {
    PyValueError::new_err(format!("{what}: {message}"))
}

/// Identifies the unknown parameters of `scene` (written `{"min", "max"}`) from the observed
/// positions `traj` `(T, N, 3)`, m — what `cordis identify` does, with the GIL released.
///
/// - `strategy`: `auto` or `thesis`; `generations` (None: no limit), `population`, `seed` (the
///   same seed gives the same result on any number of threads).
/// - `callback(generation, best_cost, params)` is called after every generation (and once for
///   the initial population), from a worker thread, with the best values so far by name;
///   returning `False` (any false value but None) stops the run, an exception stops it and is
///   raised again here.
/// - `noise` (m): Gaussian noise added to `traj` first (drawn from `seed`); `cost`: the cost
///   kind; `time_limit` (s), `target_cost`, `max_evals`: further stop rules; `threads`
///   (default: all cores); `truth`: the true scene, to report `param_error_pct`;
///   `checkpoint`/`resume`: a checkpoint file written every 50 generations and at the end, and
///   one to continue from; `dt` (s): the trajectory's time step, checked against the scene's.
/// - `executor`: where populations are evaluated: None or `"local"` (this process' threads),
///   `"ray"` (a `cordis.RayExecutor()` on the current or a new local Ray instance: `pip install
///   cordis-anima[ray]`), or an executor object (`cordis.RayExecutor(num_workers=…)`, or any
///   object whose `evaluator(scene_json, traj, cost)` returns a callable `(genomes, generation,
///   local) -> costs | (costs, local)`, with an optional `close()`). The result is the same,
///   bit for bit, on any executor.
/// - `islands` (≥ 2): an island model of that many `thesis` populations of `population` each,
///   seeded from `seed` and the island index, the `migrants` best of each island copied to the
///   next every `migrate_every` generations (a ring); deterministic given the seed and the
///   island count.
///
/// Ctrl-C stops the run cleanly (checkpoint written) and raises `KeyboardInterrupt`, whose
/// `result` attribute holds the `IdentifyResult` so far.
///
/// >>> truth = cordis.example("rigid")
/// >>> res = cordis.identify(cordis.example("rigid", unknowns=True), truth.simulate(100),
/// ...                       generations=300, truth=truth)
/// >>> res.param_error_pct < 1.0
/// True
#[pyfunction]
#[pyo3(signature = (
    scene, traj, strategy = "auto", generations = Some(1000), population = 100, seed = 0,
    callback = None, *, noise = 0.0, cost = "short", time_limit = None, target_cost = None,
    max_evals = None, threads = None, truth = None, checkpoint = None, resume = None, dt = None,
    stable_horizon = None, stable_spread = cordis_es::stable::DEFAULT_SPREAD,
    executor = None, islands = None, migrate_every = 10, migrants = 2
))]
#[pyo3(
    text_signature = "(scene, traj, strategy='auto', generations=1000, population=100, \
    seed=0, callback=None, *, noise=0.0, cost='short', time_limit=None, target_cost=None, \
    max_evals=None, threads=None, truth=None, checkpoint=None, resume=None, dt=None, \
    stable_horizon=None, stable_spread=2.0, \
    executor=None, islands=None, migrate_every=10, migrants=2)"
)]
#[allow(clippy::too_many_arguments)]
pub fn identify(
    py: Python<'_>,
    scene: &Scene,
    traj: &Bound<'_, PyAny>,
    strategy: &str,
    generations: Option<i64>,
    population: i64,
    seed: i128,
    callback: Option<Bound<'_, PyAny>>,
    noise: f64,
    cost: &str,
    time_limit: Option<f64>,
    target_cost: Option<f64>,
    max_evals: Option<i64>,
    threads: Option<i64>,
    truth: Option<PyRef<'_, Scene>>,
    checkpoint: Option<PathBuf>,
    resume: Option<PathBuf>,
    dt: Option<f64>,
    stable_horizon: Option<i64>,
    stable_spread: f64,
    executor: Option<Bound<'_, PyAny>>,
    islands: Option<i64>,
    migrate_every: i64,
    migrants: i64,
) -> PyResult<IdentifyResult> {
    let name: StrategyName = strategy.parse().map_err(|e| bad("strategy", e))?;
    let generations: Option<u64> = generations.map(|g| count(g, "generations")).transpose()?;
    let population: usize = count(population, "population")?;
    let seed: u64 = count(seed, "seed")?;
    let max_evals: Option<u64> = max_evals.map(|m| count(m, "max_evals")).transpose()?;
    let threads: Option<usize> = threads.map(|t| count(t, "threads")).transpose()?;
    let stable = stable_horizon
        .map(|h| {
            let h = count(h, "stable_horizon")?;
            cordis_es::stable::StableHorizon::new(h, stable_spread).map_err(cost_to_py)
        })
        .transpose()?;
    let islands = match islands {
        Some(k) => Some(IslandConfig {
            islands: count(k, "islands")?,
            migrate_every: count(migrate_every, "migrate_every")?,
            migrants: count(migrants, "migrants")?,
        }),
        None => None,
    };
    let executor = executor_object(py, executor)?;
    if population < 2 {
        return Err(bad(
            "population",
            format!("must be 2 or more, got {population}"),
        ));
    }
    if !(noise.is_finite() && noise >= 0.0) {
        return Err(bad(
            "noise",
            format!("must be a standard deviation ≥ 0 m, got {noise}"),
        ));
    }
    let time_limit = match time_limit {
        Some(t) if t.is_finite() && t >= 0.0 => Some(Duration::from_secs_f64(t)),
        Some(t) => return Err(bad("time_limit", format!("must be seconds ≥ 0, got {t}"))),
        None => None,
    };
    if target_cost.is_some_and(f64::is_nan) {
        return Err(bad("target_cost", "must be a number, got nan"));
    }
    if threads == Some(0) {
        return Err(bad("threads", "must be 1 or more (None: all cores)"));
    }
    if let Some(cb) = &callback {
        if !cb.is_callable() {
            return Err(PyTypeError::new_err(format!(
                "callback: expected a callable (generation, best_cost, params), got {}",
                cb.get_type().name()?
            )));
        }
    }
    let kind = cost.parse().map_err(cost_to_py)?;
    let scene = scene.core();
    if !scene.has_unknowns() {
        return Err(SceneError::new_err(
            "scene: no parameter to identify: write unknowns as {\"min\": …, \"max\": …}",
        ));
    }
    let mut traj = traj_from_py(traj, "traj")?;
    if let Some(dt) = dt {
        traj.dt = Some(check_dt(dt, "dt")?);
    }
    let truth = truth.map(|t| t.core().clone());
    let threads = threads.unwrap_or(0);
    let callback = callback.map(Bound::unbind);

    let prepared = py.detach(|| -> Result<_, PyErr> {
        if noise > 0.0 {
            traj = add_noise(&traj, noise, seed);
        }
        let mut problem = Problem::new(&scene, &traj, kind).map_err(cost_to_py)?;
        if let Some(t) = &truth {
            if t.has_unknowns() || t.param_layout() != scene.param_layout() {
                return Err(SceneError::new_err(
                    "truth: must be the scene with every parameter known (same types and \
                     particles)",
                ));
            }
            problem = problem.with_truth(t).map_err(cost_to_py)?;
        }
        if let Some(h) = stable {
            problem = problem.with_stable_horizon(h);
        }
        Ok(problem)
    });
    let mut problem = prepared?;
    let options = StrategyOptions {
        population,
        ..StrategyOptions::default()
    };
    let (mut strategy, ran) = match islands {
        Some(config) => {
            make_islands(name, &problem, &options, config).map_err(|e| bad("islands", e))?
        }
        None => make_strategy(name, &problem, &options),
    };
    if ran == "levenberg-marquardt" {
        // It needs the short cost's residuals: say so before the run, as the CLI does.
        check_strategy(ran, &problem).map_err(|e| bad("strategy", e))?;
    }
    // The executor's workers compile the same problem from the same data (the noisy
    // trajectory, not the caller's): only genomes and costs travel from here on.
    let evaluator = match &executor {
        Some(ex) => {
            let traj = traj_to_py(py, traj.clone())?;
            let ev = ex.call_method1("evaluator", (scene.to_json_string(), traj, cost))?;
            let remote = Arc::new(PyEvaluator::new(ev.clone().unbind()));
            problem = problem.with_evaluator(remote.clone());
            Some((ev, remote))
        }
        None => None,
    };
    let config = RunConfig {
        seed,
        stop: StopRules {
            generations,
            max_evals,
            time_limit,
            target_cost,
        },
        checkpoint,
        checkpoint_every: 50,
        resume,
        fingerprint: None,
    };
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| PyRuntimeError::new_err(format!("threads: {e}")))?;
    let mut observer = CallbackObserver {
        callback,
        space: problem.space.clone(),
        error: None,
        stop: false,
    };
    let interrupt = AtomicBool::new(false);

    let (outcome, signal) = py.detach(|| {
        let (done, finished) = mpsc::channel::<()>();
        let (problem, config, interrupt, pool) = (&mut problem, &config, &interrupt, &pool);
        let observer = &mut observer;
        let strategy = strategy.as_mut();
        std::thread::scope(|s| {
            let worker = s.spawn(move || {
                let mut observers: Vec<&mut dyn Observer> = vec![observer];
                let r = pool.install(|| {
                    executor::run(problem, strategy, config, &mut observers, Some(interrupt))
                });
                let _ = done.send(());
                r
            });
            let mut signal = None;
            loop {
                match finished.recv_timeout(SIGNAL_POLL) {
                    Err(mpsc::RecvTimeoutError::Timeout) if signal.is_none() => {
                        if let Err(e) = Python::attach(|py| py.check_signals()) {
                            signal = Some(e);
                            interrupt.store(true, Ordering::Relaxed);
                        }
                    }
                    Err(mpsc::RecvTimeoutError::Timeout) => {}
                    // Finished, or the worker panicked and dropped its sender.
                    _ => break,
                }
            }
            (worker.join(), signal)
        })
    });
    // The executor's workers are released whatever happened.
    let mut remote_error = None;
    if let Some((ev, remote)) = evaluator {
        remote_error = remote.take_error();
        if ev.hasattr("close")? {
            ev.call_method0("close")?;
        }
    }
    let outcome = outcome
        .map_err(|_| PyRuntimeError::new_err("identify: the run panicked (a bug in cordis)"))?;
    if let Some(e) = observer.error.take() {
        return Err(e);
    }
    // The executor's own exception (a lost cluster, a bad return value), not a string of it.
    if let Some(e) = remote_error {
        return Err(e);
    }
    let run = outcome.map_err(checkpoint_error)?;
    let result = build_result(py, &scene, &problem, run)?;
    if let Some(e) = signal {
        let result = Py::new(py, result)?;
        e.value(py).setattr("result", result)?;
        return Err(e);
    }
    Ok(result)
}

/// The executor object for `executor`: None for the local pool, `"ray"` for a default
/// `cordis.RayExecutor` (a clear error when Ray is not installed), any other object as is.
fn executor_object<'py>(
    py: Python<'py>,
    executor: Option<Bound<'py, PyAny>>,
) -> PyResult<Option<Bound<'py, PyAny>>> {
    let Some(ex) = executor else {
        return Ok(None);
    };
    if let Ok(name) = ex.extract::<String>() {
        return match name.as_str() {
            "local" => Ok(None),
            "ray" => Ok(Some(
                py.import("cordis.ray")?.getattr("RayExecutor")?.call0()?,
            )),
            other => Err(bad(
                "executor",
                format!("unknown executor `{other}` (expected \"local\", \"ray\" or an executor object)"),
            )),
        };
    }
    if !ex.hasattr("evaluator")? {
        return Err(PyTypeError::new_err(format!(
            "executor: expected \"local\", \"ray\" or an object with an evaluator(scene_json, \
             traj, cost) method, got {}",
            ex.get_type().name()?
        )));
    }
    Ok(Some(ex))
}

fn build_result(
    py: Python<'_>,
    scene: &cordis_core::Scene,
    problem: &Problem,
    run: RunResult,
) -> PyResult<IdentifyResult> {
    let space = &problem.space;
    let identified = space.scene_with(scene, &run.genome);
    let params = PyDict::new(py);
    for (u, v) in space.unknowns.iter().zip(space.values(&run.genome)) {
        params.set_item(&u.name, v)?;
    }
    let truth = match &problem.truth {
        Some(t) => {
            let d = PyDict::new(py);
            for u in &space.unknowns {
                d.set_item(&u.name, t[u.slot])?;
            }
            Some(d.unbind())
        }
        None => None,
    };
    let rows: Vec<f64> = run
        .history
        .iter()
        .flat_map(|r| {
            [
                r.generation as f64,
                r.evals as f64,
                r.seconds,
                r.best_cost,
                r.best_rmse,
                r.mean_cost,
                r.mean_mutability,
                r.param_error_pct.unwrap_or(f64::NAN),
            ]
        })
        .collect();
    let history = Array2::from_shape_vec((run.history.len(), HISTORY_COLUMNS.len()), rows)
        .map_err(|e| PyRuntimeError::new_err(format!("history: {e}")))?;
    Ok(IdentifyResult {
        scene: Py::new(py, Scene::from_core(identified))?,
        params: params.unbind(),
        truth,
        cost: run.cost,
        rmse: run.rmse,
        history: history.into_pyarray(py).unbind(),
        evals: run.evals,
        generations: run.generations,
        seconds: run.seconds,
        strategy: run.strategy.to_string(),
        param_error_pct: run.param_error_pct,
        stopped_by: stop_text(run.stopped_by).to_string(),
    })
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<IdentifyResult>()?;
    m.add_function(wrap_pyfunction!(identify, m)?)?;
    Ok(())
}
