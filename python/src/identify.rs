//! Identification (SPEC §4): `cordis.identify` and `IdentifyResult`, doing what `cordis
//! identify` does (noise, cost kind, truth, stop rules, checkpoint/resume, a local thread pool)
//! with a Python callback as an extra observer.
//!
//! The run goes on a worker thread, without the GIL; the calling thread waits for it, taking
//! the GIL every 50 ms only to run Python's signal handlers (Ctrl-C), which only the main thread
//! can do. The callback takes the GIL on the worker, once per generation.

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use cordis_es::cost::LocalCost;
use cordis_es::executor::{HistoryRow, Observer, StopReason};
use cordis_es::report::{Report, SolverReport};
use cordis_es::session::{Generations, IdentifyRequest, Lock, Outcome, Session, Style};
use cordis_es::space::ParameterSpace;
use cordis_es::strategies::cmaes::Restarts;
use cordis_es::strategies::islands::IslandConfig;
use cordis_es::strategies::thesis::Crossover;
use cordis_es::CostError;
use numpy::ndarray::Array2;
use numpy::{IntoPyArray, PyArray2, PyUntypedArrayMethods};
use pyo3::exceptions::{PyRuntimeError, PyTypeError, PyUserWarning};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::errors::{argument_error, cost_to_py, run_error};
use crate::evaluator::PyEvaluator;
use crate::scene::Scene;
use crate::trajectory::{check_dt, observations_from_py, traj_to_py};

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

/// What `cordis.identify` found.
#[pyclass(frozen, module = "cordis", name = "IdentifyResult")]
pub struct IdentifyResult {
    /// The scene with the identified values written in (every parameter known), with take
    /// 0's estimated initial state when the strategy estimates one.
    #[pyo3(get)]
    scene: Py<Scene>,
    /// One identified scene per take, each with that take's estimated initial state
    /// (`scenes[k].simulate(T)` replays take k; `scenes[0]` is `scene`); `[scene]` when the
    /// strategy estimates no initial state.
    #[pyo3(get)]
    scenes: Vec<Py<Scene>>,
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
    /// Why the run stopped: `converged` (the solver's own criterion met), `strategy_budget`
    /// (its restarts or cycles spent short of it), `not_determined` (unknowns the data leave
    /// free, see `report`), or a stop rule: `generations`, `max_evals`, `time_limit`,
    /// `target_cost`, `callback`, `interrupted`.
    #[pyo3(get)]
    stopped_by: String,
    /// The solver's own report (an exact solver's condition number, undetermined and clamped
    /// unknowns and notes; levenberg-marquardt's restarts), as the CLI prints it under
    /// `"solver"`; None for the evolution strategies.
    #[pyo3(get)]
    report: Option<Py<PyAny>>,
    /// What the CLI prints as `warning:` lines (also raised with `warnings.warn`).
    #[pyo3(get)]
    warnings: Vec<String>,
    /// Standard error of each unknown in its own unit (inf: not determined by the data), by
    /// name, for strategies that estimate it (`output-error`); None otherwise.
    #[pyo3(get)]
    stderr: Option<Py<PyDict>>,
    /// 95 % interval `(low, high)` of each unknown, by name (an undetermined unknown's box:
    /// the data do not narrow it); None when not estimated.
    #[pyo3(get)]
    intervals: Option<Py<PyDict>>,
    /// Covariance of the unknowns (unknown order, `list(params)`), float64 `(n, n)`; an
    /// undetermined unknown has inf on the diagonal and 0 beside it; None when not estimated.
    #[pyo3(get)]
    covariance: Option<Py<PyArray2<f64>>>,
    /// Noise of the observed positions estimated from the residuals, m (with `weights`, a
    /// weight-1 coordinate's); None when not estimated (nor for a fit the run stopped:
    /// `report["sigma"]`, the CLI's `solver.sigma`, is then the residuals' level).
    #[pyo3(get)]
    sigma: Option<f64>,
    /// The run as `cordis identify --json` prints it, for [`IdentifyResult::write_report`].
    summary: serde_json::Value,
    /// Best cost per generation, for the report's convergence chart.
    convergence: Vec<cordis_cli::report::ConvergencePoint>,
    /// The run's marker map and weights, [`IdentifyResult::write_report`]'s defaults.
    markers: Option<Vec<usize>>,
    weights: Option<Vec<f64>>,
}

#[pymethods]
impl IdentifyResult {
    /// Names of the columns of `history`.
    #[classattr]
    #[allow(non_snake_case)]
    fn HISTORY_COLUMNS() -> Vec<&'static str> {
        HISTORY_COLUMNS.to_vec()
    }

    /// Writes the identification report (`cordis report`): one self-contained HTML page on
    /// the identified scene and the observed motion `trajectory` (`(T, N, 3)`, NaN or
    /// `visible` False where missing), with this run's intervals and convergence. `markers`
    /// and `weights` as given to `identify` (default: this run's own): marker m is the
    /// scene's particle `markers[m]`; the weights add the weighted position RMS to the fit.
    /// Fixed particles observed far from where the scene holds them (data mapped otherwise
    /// than the run's markers, or in other units) are warned of (`UserWarning`), as
    /// `cordis report` does.
    #[pyo3(signature = (path, trajectory, visible = None, title = None, markers = None, weights = None))]
    #[allow(clippy::too_many_arguments)]
    fn write_report(
        &self,
        py: Python<'_>,
        path: std::path::PathBuf,
        trajectory: &Bound<'_, PyAny>,
        visible: Option<&Bound<'_, PyAny>>,
        title: Option<String>,
        markers: Option<Bound<'_, PyAny>>,
        weights: Option<Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        let markers = particle_indices(markers, "markers")?;
        let weights = weights_from_py(weights)?;
        let observed =
            crate::trajectory::observations_from_py(trajectory, visible, "trajectory", "visible")?;
        let scene = self.scene.get().core();
        let title = title.unwrap_or_else(|| format!("identified by {}", self.strategy));
        // The run's map unless told otherwise: a marker file read in scene order put the
        // markers on the wrong particles (an RMS error of 0.12 m for a 1 mm fit).
        let markers = markers.or_else(|| self.markers.clone());
        let weights = weights.or_else(|| self.weights.clone());
        let far = py
            .detach(|| {
                let (observed, weights) = match markers.is_some() || weights.is_some() {
                    true => cordis_cli::report::in_scene_order(
                        &observed,
                        scene.num_particles(),
                        markers.as_deref(),
                        weights.as_deref(),
                        ["markers", "weights", "trajectory"],
                    )?,
                    false => (observed, None),
                };
                let page = cordis_cli::report::report_html(&cordis_cli::report::ReportInput {
                    scene: &scene,
                    observed: &observed,
                    convergence: Some(&self.convergence),
                    summary: Some(&self.summary),
                    weights: weights.as_deref(),
                    title: &title,
                })?;
                cordis_core::io::write_atomic(&path, page.as_bytes())?;
                Ok(cordis_cli::report::fixed_far_warning(
                    &scene,
                    &observed,
                    "trajectory",
                    "markers=",
                ))
            })
            .map_err(crate::errors::to_py)?;
        warn_all(py, &far.into_iter().collect::<Vec<_>>())
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
    argument_error(what, &message.to_string())
}

/// `cordis.identify`'s arguments, as received (checked by the session, not here).
struct PyArgs<'py> {
    strategy: &'py str,
    generations: Option<i64>,
    population: Option<i64>,
    seed: i128,
    noise: f64,
    cost: &'py str,
    time_limit: Option<f64>,
    target_cost: Option<f64>,
    max_evals: Option<i64>,
    threads: Option<i64>,
    checkpoint: Option<PathBuf>,
    resume: Option<PathBuf>,
    dt: Option<f64>,
    stable_horizon: Option<i64>,
    stable_spread: f64,
    islands: Option<i64>,
    migrate_every: i64,
    migrants: i64,
    total_mass: Option<f64>,
    lock: Option<Bound<'py, PyAny>>,
    param_gene: Option<PathBuf>,
    descent_start: Option<i64>,
    descent_every: Option<i64>,
    crossover: Option<&'py str>,
    local_cost: Option<&'py str>,
    restarts: Option<&'py str>,
    plus: bool,
    correlated: bool,
    visible: Option<Bound<'py, PyAny>>,
    markers: Option<Vec<usize>>,
    weights: Option<Vec<f64>>,
    loss: &'py str,
    intervals: &'py str,
}

/// The arguments as a session request: integer conversions and Python's types here, every
/// range check in the session (the same as the CLI's).
fn request(
    scene: &cordis_core::Scene,
    traj: &Bound<'_, PyAny>,
    truth: Option<PyRef<'_, Scene>>,
    a: PyArgs<'_>,
) -> PyResult<IdentifyRequest> {
    let mut takes = takes_from_py(traj, a.visible.as_ref())?;
    if let Some(dt) = a.dt {
        let dt = check_dt(dt, "dt")?;
        for t in &mut takes {
            t.dt = Some(dt);
        }
    }
    let mut r = IdentifyRequest::with_takes(scene.clone(), takes);
    r.style = Style::Python;
    r.markers = a.markers;
    r.weights = a.weights;
    r.loss = a.loss.parse().map_err(|e| bad("loss", e))?;
    r.intervals = a.intervals.parse().map_err(|e| bad("intervals", e))?;
    r.strategy = a.strategy.parse().map_err(|e| bad("strategy", e))?;
    r.generations = match a.generations {
        Some(g) => Generations::Limit(count(g, "generations")?),
        None => Generations::Unlimited,
    };
    r.population = a.population.map(|p| count(p, "population")).transpose()?;
    r.seed = count(a.seed, "seed")?;
    r.noise = a.noise;
    r.cost = a.cost.parse().map_err(cost_to_py)?;
    r.time_limit = a.time_limit;
    r.target_cost = a.target_cost;
    r.max_evals = a.max_evals.map(|m| count(m, "max_evals")).transpose()?;
    r.threads = a.threads.map(|t| count(t, "threads")).transpose()?;
    r.checkpoint = a.checkpoint;
    r.resume = a.resume;
    r.stable_horizon = a
        .stable_horizon
        .map(|h| count(h, "stable_horizon"))
        .transpose()?;
    r.stable_spread = a.stable_spread;
    r.islands = match a.islands {
        Some(k) => Some(IslandConfig {
            islands: count(k, "islands")?,
            migrate_every: count(a.migrate_every, "migrate_every")?,
            migrants: count(a.migrants, "migrants")?,
        }),
        None => None,
    };
    r.total_mass = a.total_mass;
    r.lock = a.lock.map(|l| lock_arg(&l)).transpose()?;
    r.param_gene = a.param_gene;
    r.descent_start = a
        .descent_start
        .map(|d| count(d, "descent_start"))
        .transpose()?;
    r.descent_every = a
        .descent_every
        .map(|d| count(d, "descent_every"))
        .transpose()?;
    r.crossover = a
        .crossover
        .map(Crossover::parse)
        .transpose()
        .map_err(|e| bad("crossover", e))?;
    r.local_cost = a
        .local_cost
        .map(LocalCost::parse)
        .transpose()
        .map_err(|e| bad("local_cost", e))?;
    r.restarts = a
        .restarts
        .map(Restarts::parse)
        .transpose()
        .map_err(|e| bad("restarts", e))?;
    r.plus = a.plus;
    r.correlated = a.correlated;
    r.truth = truth.map(|t| (*t.core()).clone());
    Ok(r)
}

/// `traj`: one array `(T, N, 3)` (NaN: missing) or a list of them (several takes of the same
/// object); `visible`: a boolean `(T, N)` array, or a list of them, one per take.
fn takes_from_py(
    traj: &Bound<'_, PyAny>,
    visible: Option<&Bound<'_, PyAny>>,
) -> PyResult<Vec<cordis_core::Observations>> {
    let several = traj.is_instance_of::<pyo3::types::PyList>()
        || traj.is_instance_of::<pyo3::types::PyTuple>();
    let items: Vec<Bound<'_, PyAny>> = match several {
        true => traj.try_iter()?.collect::<PyResult<_>>()?,
        false => Vec::new(),
    };
    // A nested list of one take's frames (`A.tolist()`) is one take, not a list of takes: its
    // first item is a frame `(N, 3)`, a take's would be `(T, N, 3)` (it was refused as
    // "traj[0]: expected … got shape (12, 3)").
    let frames = items.first().is_some_and(|first| {
        crate::trajectory::as_f64_array(first, "traj[0]").is_ok_and(|a| a.ndim() == 2)
    });
    if !several || frames {
        return Ok(vec![observations_from_py(
            traj, visible, "traj", "visible",
        )?]);
    }
    let masks: Option<Vec<Bound<'_, PyAny>>> = match visible.filter(|v| !v.is_none()) {
        Some(v) => Some(
            v.try_iter()
                .and_then(|m| m.collect::<PyResult<_>>())
                .map_err(|_| {
                    PyTypeError::new_err(format!(
                        "visible: expected a list of {} masks (boolean (T, N) arrays, or None \
                         for a take whose particles are all visible), got {}",
                        items.len(),
                        crate::scene_edit::type_name(v)
                    ))
                })?,
        ),
        None => None,
    };
    if let Some(m) = &masks {
        if m.len() != items.len() {
            return Err(bad(
                "visible",
                format!("{} masks for {} takes", m.len(), items.len()),
            ));
        }
    }
    items
        .iter()
        .enumerate()
        .map(|(k, t)| {
            let v = masks.as_ref().map(|m| &m[k]);
            observations_from_py(t, v, &format!("traj[{k}]"), &format!("visible[{k}]"))
        })
        .collect()
}

/// `lock`: a `NAME.lock` path or comma-separated names as in the CLI, or a list of names.
fn lock_arg(l: &Bound<'_, PyAny>) -> PyResult<Lock> {
    if let Ok(text) = l.extract::<String>() {
        return Ok(Lock::parse(&text));
    }
    if let Ok(p) = l.extract::<PathBuf>() {
        return Ok(Lock::File(p));
    }
    l.extract::<Vec<String>>().map(Lock::Names).map_err(|_| {
        PyTypeError::new_err(format!(
            "lock: expected a .lock path, comma-separated names or a list of names, got {}",
            l.get_type()
                .name()
                .map(|n| n.to_string())
                .unwrap_or_default()
        ))
    })
}

/// Identifies the unknown parameters of `scene` (written `{"min", "max"}`) from the observed
/// positions `traj` `(T, N, 3)`, m — what `cordis identify` does, with the GIL released, under
/// the same option names (`time_limit` is `--time-limit`).
///
/// - `strategy`: `auto`, `thesis`, `t2m`, `least-squares`, `hybrid`, `cmaes`, `self-adaptive`,
///   `annealing`, `parisian`, `levenberg-marquardt` or `output-error` (see
///   docs/identification.md; `auto` picks one from the scene and the data); `generations`
///   (None: no limit),
///   `population` (None: the `param_gene` file's, else 100), `seed` (the same seed gives the
///   same result on any number of threads).
/// - `callback(generation, best_cost, params)` is called after every generation (and once for
///   the initial population), from a worker thread, with the best values so far by name;
///   returning `False` (any false value but None) stops the run, an exception stops it and is
///   raised again here.
/// - `noise` (m): Gaussian noise added to `traj` first (drawn from `seed`); `cost`: the cost
///   kind; `time_limit` (s), `target_cost`, `max_evals`: further stop rules; `threads`
///   (default: all cores; more than the machine has are capped, with a warning); `truth`: the
///   true scene, to report `param_error_pct`; `checkpoint`/`resume`: a checkpoint file written
///   every 50 generations but at most once a second, and at the end however the run stops (its
///   history rows appended to `checkpoint + ".history"`), and one to continue from (refused
///   when made for another scene, data, cost, noise or options); `dt` (s): the trajectory's
///   time step.
/// - `total_mass` (kg): the free particles' total, needed when their masses are unknown;
///   `lock`: unknowns kept at their start (a `NAME.lock` file or names); `param_gene`: a thesis
///   `Param.gene` file (`damping` only as 0; its `pcross`, `pmut`, `reducer` read by `thesis`
///   and `t2m` only); `descent_start`, `descent_every`: the thesis ES's Powell descent (None:
///   400 and 100); `crossover`: its crossover, `"mean"` (Annexe 1, None's), `"n-parent"` or
///   `"mn-parent"` (§3.2); `local_cost`: the local cost driving its local operators,
///   `"positions"` (None's) or `"distances"` (eq 3.3 as printed: the error of the predicted
///   distances to linked particles; short cost, no executor) — these refused with another
///   strategy; `restarts`: `cmaes`'s, `"ipop"` (None's) or `"bipop"` (Hansen 2009); `plus`,
///   `correlated`: `self-adaptive`'s (μ+λ) selection and correlated mutations (refused with
///   another strategy).
/// - `executor`: where populations are evaluated: None or `"local"`, `"ray"` (a
///   `cordis.RayExecutor()`: `pip install cordis-anima[ray]`), or an executor object whose
///   `evaluator(scene_json, traj, cost)` returns a callable `(genomes, generation, local) ->
///   costs | (costs, local)`, with an optional `close()`. The result is the same, bit for bit.
/// - Tracked motion: `traj` may hold NaN (a missing coordinate), have fewer particles than
///   the scene (the rest are hidden and simulated), or be a list of arrays (several takes of
///   the same object: one parameter set, each take its own initial state); `visible`
///   (boolean `(T, N)`, or a list of one per take, None for a take whose particles are all
///   visible) hides a particle where it is False; `markers[j]` is the scene particle that the
///   data's particle j tracks (the rest hidden; fixed particles need not be tracked);
///   `weights`: each marker's weight, 1/σ relative (`(M,)` one per marker, or `(M, 3)` one
///   per marker and coordinate x, y, z; read by `output-error` only); `loss`: `"squared"`, or `"huber"` /
///   `"cauchy"`, robust against tracking outliers and swapped markers (output-error);
///   `intervals`: `"wald"` (from the standard errors, checked along each unknown's profile
///   direction and widened where the cost is flatter there than its quadratic model) or
///   `"profile"` (the profile likelihood's where it is flatter: every other variable refitted
///   at each edge, several times the fit's time; output-error). Only
///   `output-error` reads gaps and takes; `auto` picks it for them and for noisy data, and its
///   result has `stderr`, `intervals`, `covariance` and `sigma` (None for other strategies);
///   its `scene` carries the estimated initial state, so `res.scene.simulate(T)` replays
///   the take.
/// - `islands` (≥ 2): an island model of that many populations of `population` each, the
///   `migrants` best of each copied to the next every `migrate_every` generations (a ring).
///
/// A strategy that cannot run on the problem is refused before any work (`RefusedError`, a
/// `ValueError`), one that finds no estimate raises `RunError` (a `RuntimeError`), an option
/// out of its range `ArgumentError` (a `ValueError`), a checkpoint that cannot resume
/// `CheckpointError`, all under `CordisError`; what the CLI prints as `warning:` is raised
/// with `warnings.warn` and kept in `IdentifyResult.warnings`. Ctrl-C stops the run cleanly
/// (checkpoint written) and raises `KeyboardInterrupt`, whose `result` attribute holds the
/// `IdentifyResult` so far; a checkpoint that cannot be written (a full disk) raises
/// `RunError` naming the file once the run is over, its `result` attribute holding the
/// whole `IdentifyResult`.
///
/// >>> truth = cordis.example("rigid")
/// >>> res = cordis.identify(cordis.example("rigid", unknowns=True), truth.simulate(100),
/// ...                       generations=300, truth=truth)
/// >>> res.param_error_pct < 1.0
/// True
#[pyfunction]
#[pyo3(signature = (
    scene, traj, strategy = "auto", generations = Some(1000), population = None, seed = 0,
    callback = None, *, noise = 0.0, cost = "short", time_limit = None, target_cost = None,
    max_evals = None, threads = None, truth = None, checkpoint = None, resume = None, dt = None,
    stable_horizon = None, stable_spread = cordis_es::stable::DEFAULT_SPREAD,
    executor = None, islands = None, migrate_every = 10, migrants = 2, total_mass = None,
    lock = None, param_gene = None, descent_start = None, descent_every = None,
    crossover = None, local_cost = None, restarts = None, plus = false, correlated = false, visible = None, markers = None, weights = None, loss = "squared",
    intervals = "wald"
))]
#[pyo3(
    text_signature = "(scene, traj, strategy='auto', generations=1000, population=None, \
    seed=0, callback=None, *, noise=0.0, cost='short', time_limit=None, target_cost=None, \
    max_evals=None, threads=None, truth=None, checkpoint=None, resume=None, dt=None, \
    stable_horizon=None, stable_spread=2.0, \
    executor=None, islands=None, migrate_every=10, migrants=2, total_mass=None, lock=None, \
    param_gene=None, descent_start=None, descent_every=None, crossover=None, local_cost=None, restarts=None, plus=False, \
    correlated=False, visible=None, markers=None, weights=None, loss='squared', intervals='wald')"
)]
#[allow(clippy::too_many_arguments)]
pub fn identify(
    py: Python<'_>,
    scene: &Scene,
    traj: &Bound<'_, PyAny>,
    strategy: &str,
    generations: Option<i64>,
    population: Option<i64>,
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
    total_mass: Option<f64>,
    lock: Option<Bound<'_, PyAny>>,
    param_gene: Option<PathBuf>,
    descent_start: Option<i64>,
    descent_every: Option<i64>,
    crossover: Option<&str>,
    local_cost: Option<&str>,
    restarts: Option<&str>,
    plus: bool,
    correlated: bool,
    visible: Option<Bound<'_, PyAny>>,
    markers: Option<Bound<'_, PyAny>>,
    weights: Option<Bound<'_, PyAny>>,
    loss: &str,
    intervals: &str,
) -> PyResult<IdentifyResult> {
    let markers = particle_indices(markers, "markers")?;
    let weights = weights_from_py(weights)?;
    let args = PyArgs {
        strategy,
        generations,
        population,
        seed,
        noise,
        cost,
        time_limit,
        target_cost,
        max_evals,
        threads,
        checkpoint,
        resume,
        dt,
        stable_horizon,
        stable_spread,
        islands,
        migrate_every,
        migrants,
        total_mass,
        lock,
        param_gene,
        descent_start,
        descent_every,
        crossover,
        local_cost,
        restarts,
        plus,
        correlated,
        visible,
        markers,
        weights,
        loss,
        intervals,
    };
    let req = request(&scene.core(), traj, truth, args)?;
    let remote_asked = executor
        .as_ref()
        .is_some_and(|e| e.extract::<String>().map_or(true, |n| n != "local"));
    if remote_asked && req.local_cost == Some(LocalCost::Distances) {
        // An executor's workers compile the scene, data and cost kind only: they would send
        // back the position-error local costs.
        return Err(bad(
            "local_cost",
            "'distances' is computed in this process only: leave executor out (or None)",
        ));
    }
    let executor = executor_object(py, executor)?;
    if let Some(cb) = &callback {
        if !cb.is_callable() {
            return Err(PyTypeError::new_err(format!(
                "callback: expected a callable (generation, best_cost, params), got {}",
                cb.get_type().name()?
            )));
        }
    }
    let remote = executor.map(|ex| (ex, scene.core().to_json_string(), cost));
    run_session(py, req, remote, callback)
}

/// Runs the request: warnings raised as they come, the executor (with the scene's JSON and the
/// cost kind its workers compile) closed whatever happens, the callback's or the executor's
/// own exception raised as it was, a Ctrl-C or an unwritable checkpoint raised with the whole
/// result on it.
fn run_session(
    py: Python<'_>,
    req: IdentifyRequest,
    executor: Option<(Bound<'_, PyAny>, String, &str)>,
    callback: Option<Bound<'_, PyAny>>,
) -> PyResult<IdentifyResult> {
    let (markers, weights) = (req.markers.clone(), req.weights.clone());
    let mut session = py.detach(|| Session::new(req)).map_err(cost_to_py)?;
    warn_all(py, session.warnings())?;
    let early = session.warnings().len();
    let evaluator = match &executor {
        Some((ex, scene_json, cost)) => {
            let (s, ev) = attach(py, session, ex, scene_json, cost)?;
            session = s;
            Some(ev)
        }
        None => None,
    };
    let observer = CallbackObserver {
        callback: callback.map(Bound::unbind),
        space: session.problem().space.clone(),
        error: None,
        stop: false,
    };
    let (outcome, signal, mut observer) = run_waiting(py, session, observer);
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
    let outcome = outcome.map_err(cost_to_py)?;
    warn_all(py, &outcome.warnings[early..])?;
    let checkpoint_error = outcome.result.checkpoint_error.clone();
    let mut result = build_result(py, outcome)?;
    (result.markers, result.weights) = (markers, weights);
    // A checkpoint that could not be written (a full disk) fails the call, as the CLI exits 1,
    // but loses nothing: the whole result rides on the exception.
    let signal = signal.or_else(|| checkpoint_error.map(|e| run_error("checkpoint", &e)));
    if let Some(e) = signal {
        let result = Py::new(py, result)?;
        e.value(py).setattr("result", result)?;
        return Err(e);
    }
    Ok(result)
}

/// A remote evaluator: the executor's object (closed after the run) and its adapter.
type Remote<'py> = (Bound<'py, PyAny>, Arc<PyEvaluator>);

/// The session evaluating on `executor`'s workers, with the evaluator (to close). They
/// compile the same problem from the same data (the noisy trajectory, not the caller's): only
/// genomes and costs travel from here on.
fn attach<'py>(
    py: Python<'py>,
    session: Session,
    executor: &Bound<'py, PyAny>,
    scene_json: &str,
    cost: &str,
) -> PyResult<(Session, Remote<'py>)> {
    let data = traj_to_py(py, session.data().clone())?;
    let ev = executor.call_method1("evaluator", (scene_json, data, cost))?;
    let remote = Arc::new(PyEvaluator::new(ev.clone().unbind()));
    Ok((session.with_evaluator(remote.clone()), (ev, remote)))
}

/// `warnings.warn` for each line the CLI prints as `warning:`.
pub(crate) fn warn_all(py: Python<'_>, lines: &[String]) -> PyResult<()> {
    let warnings = py.import("warnings")?;
    for w in lines {
        warnings.call_method1("warn", (w.as_str(), py.get_type::<PyUserWarning>(), 2))?;
    }
    Ok(())
}

/// A sequence of particle indices, each a non-negative integer: an item that is not an
/// integer (`10.5`, NaN, a string) is a `TypeError` naming its index (the whole sequence's
/// conversion named none), a negative one an `ArgumentError`.
fn particle_indices(value: Option<Bound<'_, PyAny>>, name: &str) -> PyResult<Option<Vec<usize>>> {
    let Some(v) = value.filter(|v| !v.is_none()) else {
        return Ok(None);
    };
    let not_a_sequence = || {
        PyTypeError::new_err(format!(
            "{name}: expected a sequence of particle indices, got {}",
            crate::scene_edit::type_name(&v)
        ))
    };
    if v.is_instance_of::<pyo3::types::PyString>() {
        return Err(not_a_sequence());
    }
    let items = v.try_iter().map_err(|_| not_a_sequence())?;
    items
        .enumerate()
        .map(|(k, item)| {
            let item = item?;
            let index = item.extract::<i64>().map_err(|_| {
                PyTypeError::new_err(format!(
                    "{name}[{k}]: expected a particle index (an integer), got {} {}",
                    crate::scene_edit::type_name(&item),
                    item.repr().map(|r| r.to_string()).unwrap_or_default()
                ))
            })?;
            count(index, &format!("{name}[{k}]"))
        })
        .collect::<PyResult<Vec<usize>>>()
        .map(Some)
}

/// `weights` as the session takes them, flat: `(M,)` one per marker, `(M, 3)` one per marker
/// and coordinate (x, y, z), read row by row; any other shape names the two it takes (a
/// per-coordinate `(M, 3)` array used to be refused by the flat-sequence conversion).
fn weights_from_py(weights: Option<Bound<'_, PyAny>>) -> PyResult<Option<Vec<f64>>> {
    let Some(w) = weights.filter(|w| !w.is_none()) else {
        return Ok(None);
    };
    let a = crate::trajectory::as_f64_array(&w, "weights")?;
    match a.shape() {
        [_] | [_, 3] => crate::trajectory::c_order_values(&a).map(Some),
        [] => Err(PyTypeError::new_err(format!(
            "weights: expected a sequence of numbers, shape (M,) or (M, 3), got {}",
            crate::scene_edit::type_name(&w)
        ))),
        shape => Err(crate::errors::argument_error(
            "weights",
            &format!(
                "expected shape (M,) (one weight per marker) or (M, 3) (one per marker and \
                 coordinate x, y, z), got shape {}",
                crate::trajectory::shape_text(shape)
            ),
        )),
    }
}

type RunOutcome = std::thread::Result<Result<Outcome, CostError>>;

/// Runs the session on a worker thread without the GIL while this thread, the one Python
/// delivers signals to, checks for Ctrl-C every [`SIGNAL_POLL`] and raises the interrupt flag.
fn run_waiting(
    py: Python<'_>,
    session: Session,
    mut observer: CallbackObserver,
) -> (RunOutcome, Option<PyErr>, CallbackObserver) {
    let interrupt = AtomicBool::new(false);
    let (outcome, signal) = crate::signals::with_signals(py, &interrupt, || {
        let mut observers: Vec<&mut dyn Observer> = vec![&mut observer];
        session.run(&mut observers, Some(&interrupt))
    });
    (outcome, signal, observer)
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

fn build_result(py: Python<'_>, outcome: Outcome) -> PyResult<IdentifyResult> {
    let Outcome {
        result: run,
        report,
        scenes,
        problem,
        warnings,
    } = outcome;
    let space = &problem.space;
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
    let spread = uncertainty_to_py(py, &report)?;
    let summary = serde_json::json!({
        "strategy": run.strategy.to_string(),
        "cost": run.cost,
        "rmse": run.rmse,
        "evals": run.evals,
        "generations": run.generations,
        "seconds": run.seconds,
        "stopped_by": stop_text(run.stopped_by),
        "solver": report.to_json(),
    });
    let convergence = run
        .history
        .iter()
        .map(|r| cordis_cli::report::ConvergencePoint {
            generation: r.generation as f64,
            best_cost: r.best_cost,
        })
        .collect();
    let report = match report.to_json() {
        serde_json::Value::Null => None,
        v => Some(crate::json::to_py(py, &v)?.unbind()),
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
    // `scenes[0]` is `scene`, the same object (take 0's state is the identified scene's).
    let scenes: Vec<Py<Scene>> = scenes
        .into_iter()
        .map(|s| Py::new(py, Scene::from_core(s)))
        .collect::<PyResult<_>>()?;
    let scene = scenes[0].clone_ref(py);
    Ok(IdentifyResult {
        scene,
        scenes,
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
        report,
        warnings,
        stderr: spread.stderr,
        intervals: spread.intervals,
        covariance: spread.covariance,
        sigma: spread.sigma,
        summary,
        convergence,
        markers: None,
        weights: None,
    })
}

/// The uncertainty fields of a result.
#[derive(Default)]
struct Spread {
    stderr: Option<Py<PyDict>>,
    intervals: Option<Py<PyDict>>,
    covariance: Option<Py<PyArray2<f64>>>,
    sigma: Option<f64>,
}

/// Standard errors, intervals, the covariance (from the correlations and standard errors)
/// and σ̂ of a report that has them.
fn uncertainty_to_py(py: Python<'_>, report: &Report) -> PyResult<Spread> {
    let mut spread = Spread::default();
    let oe = match &report.solver {
        Some(SolverReport::OutputError(r)) => Some(r),
        _ => None,
    };
    // σ̂ of a finished fit (not of an interrupted one's best point, nor of a failed one).
    spread.sigma = oe.filter(|r| r.finished()).map(|r| r.sigma);
    let Some(u) = &report.uncertainty else {
        return Ok(spread);
    };
    let (stderr, intervals) = (PyDict::new(py), PyDict::new(py));
    for p in u {
        stderr.set_item(&p.name, p.std_error)?;
        intervals.set_item(&p.name, (p.interval.0, p.interval.1))?;
    }
    spread.stderr = Some(stderr.unbind());
    spread.intervals = Some(intervals.unbind());
    // A matrix over every unknown in order: none when some standard error was not computed
    // (those are absent from `u`).
    if let Some(r) = oe.filter(|r| r.correlation.len() == u.len()) {
        let n = u.len();
        let cov = Array2::from_shape_fn((n, n), |(a, b)| {
            let (sa, sb) = (u[a].std_error, u[b].std_error);
            match a == b {
                true => sa * sa,
                false if sa.is_finite() && sb.is_finite() => r.correlation[a][b] * sa * sb,
                // An undetermined unknown: its variance is inf, its covariances undefined
                // (0 here: no NaN leaves a result).
                false => 0.0,
            }
        });
        spread.covariance = Some(cov.into_pyarray(py).unbind());
    }
    Ok(spread)
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<IdentifyResult>()?;
    m.add_function(wrap_pyfunction!(identify, m)?)?;
    Ok(())
}
