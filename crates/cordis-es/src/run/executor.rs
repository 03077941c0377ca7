//! The run loop every strategy shares: stopping rules, observers (log, progress), checkpoints.

use std::path::PathBuf;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use serde::{Deserialize, Serialize};

use crate::problem::Problem;
use crate::run::float_json::lossless;
use crate::run::strategy::Strategy;
use crate::CostError;

/// When to stop; the first rule met ends the run. `None` everywhere runs until stopped.
#[derive(Clone, Debug, Default)]
pub struct StopRules {
    pub generations: Option<u64>,
    pub max_evals: Option<u64>,
    pub time_limit: Option<Duration>,
    pub target_cost: Option<f64>,
}

#[derive(Clone, Debug, Default)]
pub struct RunConfig {
    pub seed: u64,
    pub stop: StopRules,
    /// Write the state here every `checkpoint_every` generations (at most once a second) and at
    /// the end, atomically; its history rows go to `PATH.history` beside it, appended.
    pub checkpoint: Option<PathBuf>,
    pub checkpoint_every: u64,
    /// Continue from this checkpoint.
    pub resume: Option<PathBuf>,
    /// Written into checkpoints and compared on resume (`None`: neither).
    pub fingerprint: Option<Fingerprint>,
}

/// One line of the convergence log.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HistoryRow {
    pub generation: u64,
    pub evals: u64,
    #[serde(with = "lossless")]
    pub seconds: f64,
    #[serde(with = "lossless")]
    pub best_cost: f64,
    #[serde(with = "lossless")]
    pub best_rmse: f64,
    #[serde(with = "lossless")]
    pub mean_cost: f64,
    #[serde(with = "lossless")]
    pub mean_mutability: f64,
    #[serde(with = "lossless::option", default)]
    pub param_error_pct: Option<f64>,
}

impl HistoryRow {
    pub const CSV_HEADER: &'static str =
        "generation,evals,seconds,best_cost,best_rmse,mean_cost,mean_mutability,param_error_pct";

    pub fn csv(&self) -> String {
        format!(
            "{},{},{:.6},{:e},{:e},{:e},{:e},{}",
            self.generation,
            self.evals,
            self.seconds,
            self.best_cost,
            self.best_rmse,
            self.mean_cost,
            self.mean_mutability,
            self.param_error_pct
                .map(|e| format!("{e:e}"))
                .unwrap_or_default()
        )
    }
}

/// Sees every generation; returns false to stop the run (a Python callback, Ctrl-C…).
pub trait Observer: Send {
    fn observe(&mut self, row: &HistoryRow) -> bool;

    /// [`Observer::observe`] with the best genome so far (internal coordinates, see
    /// [`crate::problem::space`]), for observers that report the parameters themselves (the Python
    /// callback). The run loop calls this one; by default it forwards to `observe`.
    fn observe_best(&mut self, row: &HistoryRow, best_genome: &[f64]) -> bool {
        let _ = best_genome;
        self.observe(row)
    }
}

/// Why a run stopped. The budgets (`generations`, `max_evals`, `time_limit`) and the target
/// are the run loop's rules; the last three are the strategy's own word, read from its
/// [`crate::report::Report`] once it says it is [finished](Strategy::finished).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum StopReason {
    /// The generation budget was spent.
    Generations,
    /// The evaluation budget was spent.
    MaxEvals,
    /// The time budget was spent.
    TimeLimit,
    /// The best cost reached the target.
    TargetCost,
    /// Ctrl-C (or the caller's interrupt flag).
    Interrupted,
    /// An observer asked to stop (the Python callback).
    Observer,
    /// The strategy finished and its own criterion was met (an exact solve that determined
    /// every unknown, levenberg-marquardt at a small cost).
    Converged,
    /// The strategy finished on its own budget short of its criterion (levenberg-marquardt's
    /// restarts, hybrid's cycle cap): the report's warnings say which.
    StrategyBudget,
    /// The strategy finished but the data do not determine some unknowns (named in the
    /// report; held at their starting value).
    NotDetermined,
}

impl StopReason {
    /// The name used in JSON and Python (`converged`, `max_evals`, `callback`…).
    pub fn as_str(self) -> &'static str {
        match self {
            StopReason::Generations => "generations",
            StopReason::MaxEvals => "max_evals",
            StopReason::TimeLimit => "time_limit",
            StopReason::TargetCost => "target_cost",
            StopReason::Interrupted => "interrupted",
            StopReason::Observer => "observer",
            StopReason::Converged => "converged",
            StopReason::StrategyBudget => "strategy_budget",
            StopReason::NotDetermined => "not_determined",
        }
    }

    /// How a finished strategy ended, from its report.
    fn of_finished(report: &crate::report::Report) -> Self {
        if report.unconverged().is_some() {
            StopReason::StrategyBudget
        } else if !report.undetermined().is_empty() {
            StopReason::NotDetermined
        } else {
            StopReason::Converged
        }
    }
}

/// What a checkpoint records of the request it was made for, by component (`scene`, `data`,
/// `cost`, `noise`, options…) → a digest of it, so that a resume names what differs.
pub type Fingerprint = std::collections::BTreeMap<String, String>;

#[derive(Clone, Debug)]
pub struct RunResult {
    pub strategy: &'static str,
    /// Best genome, internal coordinates.
    pub genome: Vec<f64>,
    /// The best model's full parameter vector.
    pub params: Vec<f64>,
    pub cost: f64,
    pub rmse: f64,
    pub evals: u64,
    pub generations: u64,
    pub seconds: f64,
    /// Of `seconds`, the time spent evaluating costs (this session only, when resumed).
    pub eval_seconds: f64,
    pub history: Vec<HistoryRow>,
    pub stopped_by: StopReason,
    pub param_error_pct: Option<f64>,
    /// The first checkpoint write that failed (a full disk: the file and the system's
    /// reason), at which generation. The run went on without checkpoints, so this result is
    /// whole, but the checkpoint file holds an earlier generation or nothing: front ends give
    /// the result first, then report this as a failed write (CLI exit 1).
    pub checkpoint_error: Option<String>,
}

#[derive(Serialize, Deserialize)]
struct Checkpoint {
    format: String,
    strategy: String,
    seed: u64,
    dim: usize,
    generation: u64,
    evals: u64,
    #[serde(with = "lossless")]
    seconds: f64,
    /// The history inline: checkpoints written before issue 17 (still read). Now empty, the
    /// rows being in the history file beside the checkpoint ([`HistoryFile`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    history: Vec<HistoryRow>,
    /// How many rows of the history file belong to this checkpoint (rows after them are of a
    /// later checkpoint that was not written).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    history_rows: Option<usize>,
    state: serde_json::Value,
    /// Absent in checkpoints written before fingerprints (accepted as they are).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    fingerprint: Option<Fingerprint>,
}

const CHECKPOINT_FORMAT: &str = "cordis-checkpoint/1";

/// Periodic checkpoints are at least this far apart: each one is synced to disk (two fsyncs,
/// ~10 ms here), which every 50 generations of a fast run cost 15× the run itself. A resume
/// is exact from any checkpoint; a kill loses at most this much more work.
const CHECKPOINT_INTERVAL: Duration = Duration::from_secs(1);

/// Runs `strategy` on `problem` until a stop rule, an observer or `interrupt` says stop (the
/// same as [`run_typed`], kept for its callers).
pub fn run(
    problem: &mut Problem,
    strategy: &mut dyn Strategy,
    config: &RunConfig,
    observers: &mut [&mut dyn Observer],
    interrupt: Option<&AtomicBool>,
) -> Result<RunResult, CostError> {
    run_typed(problem, strategy, config, observers, interrupt)
}

/// Where a run starts: generation, evaluations and seconds before it, history so far.
struct Start {
    generation: u64,
    seconds_before: f64,
    history: Vec<HistoryRow>,
}

/// [`run`] with a typed error: [`CostError::Resume`] for a checkpoint that cannot resume this
/// run, [`CostError::Run`] for a run that failed (no estimate, a failed evaluation, a
/// checkpoint not written).
pub fn run_typed(
    problem: &mut Problem,
    strategy: &mut dyn Strategy,
    config: &RunConfig,
    observers: &mut [&mut dyn Observer],
    interrupt: Option<&AtomicBool>,
) -> Result<RunResult, CostError> {
    let start = Instant::now();
    // A failure left over from an earlier run on this problem is not this run's.
    problem.take_eval_error();
    let Start {
        mut generation,
        seconds_before,
        mut history,
    } = match &config.resume {
        Some(path) => resume(path, problem, strategy, config)?,
        None => init(problem, strategy, config, observers, &start)?,
    };
    let elapsed = |start: &Instant| seconds_before + start.elapsed().as_secs_f64();
    let stop = &config.stop;
    let mut history_file = HistoryFile::default();
    let mut last_checkpoint: Option<Instant> = None;
    let mut checkpoint_error: Option<String> = None;
    let stopped_by = loop {
        if let Some(reason) = stop_reason(
            stop,
            problem,
            &*strategy,
            generation,
            &|| elapsed(&start),
            interrupt,
        ) {
            break reason;
        }
        generation += 1;
        // A progressive horizon grows with the generations: stored costs are then stale.
        let window = problem.objective.window();
        problem.objective.set_generation(generation as usize);
        if problem.objective.window() != window {
            strategy.reevaluate(problem);
        }
        let halt = || {
            interrupt.is_some_and(|f| f.load(Ordering::Relaxed))
                || stop
                    .time_limit
                    .is_some_and(|t| elapsed(&start) >= t.as_secs_f64())
        };
        strategy.next_generation_until(problem, config.seed, generation, &halt);
        if let Some(e) = strategy.failure() {
            return Err(CostError::run(strategy.name(), e));
        }
        // A failed evaluation left +inf costs in the strategy's state: stop before that state
        // reaches a checkpoint, which keeps the last good generation.
        if let Some(e) = problem.take_eval_error() {
            return Err(CostError::run_from(format!("generation {generation}"), e));
        }
        let row = make_row(problem, &*strategy, generation, elapsed(&start));
        let mut go_on = true;
        for o in observers.iter_mut() {
            go_on &= o.observe_best(&row, strategy.best().0);
        }
        history.push(row);
        let due = config.checkpoint_every > 0
            && generation % config.checkpoint_every == 0
            && last_checkpoint.is_none_or(|t| t.elapsed() >= CHECKPOINT_INTERVAL);
        if due && config.checkpoint.is_some() && checkpoint_error.is_none() {
            last_checkpoint = Some(Instant::now());
            checkpoint_error = write_checkpoint(
                config,
                problem,
                &*strategy,
                generation,
                elapsed(&start),
                &history,
                &mut history_file,
            )
            .err()
            .map(|e| failed_checkpoint(e, generation));
        }
        if !go_on {
            break StopReason::Observer;
        }
    };
    let seconds = elapsed(&start);
    if checkpoint_error.is_none() {
        checkpoint_error = write_checkpoint(
            config,
            problem,
            &*strategy,
            generation,
            seconds,
            &history,
            &mut history_file,
        )
        .err()
        .map(|e| failed_checkpoint(e, generation));
    }
    Ok(result_at_best(
        problem,
        &*strategy,
        generation,
        seconds,
        history,
        stopped_by,
        checkpoint_error,
    ))
}

/// The stop rule met before generation `generation + 1`, checked in this order: generations,
/// evaluations, time (`elapsed`, s, read only when there is a limit), target cost, the
/// strategy finished, interrupt.
fn stop_reason(
    stop: &StopRules,
    problem: &Problem,
    strategy: &dyn Strategy,
    generation: u64,
    elapsed: &dyn Fn() -> f64,
    interrupt: Option<&AtomicBool>,
) -> Option<StopReason> {
    let (_, best) = strategy.best();
    if stop.generations.is_some_and(|g| generation >= g) {
        return Some(StopReason::Generations);
    }
    if stop.max_evals.is_some_and(|m| problem.evals() >= m) {
        return Some(StopReason::MaxEvals);
    }
    if stop
        .time_limit
        .is_some_and(|t| elapsed() >= t.as_secs_f64())
    {
        return Some(StopReason::TimeLimit);
    }
    if stop.target_cost.is_some_and(|t| best <= t) {
        return Some(StopReason::TargetCost);
    }
    // A strategy that has met its own criterion is done whatever came after: Ctrl-C pressed
    // once the fit had converged (its uncertainty computed) was reported as an interrupted
    // run, exit 130 (a new user's finding).
    if strategy.finished() {
        return Some(StopReason::of_finished(&strategy.report()));
    }
    if interrupt.is_some_and(|f| f.load(Ordering::Relaxed)) {
        return Some(StopReason::Interrupted);
    }
    None
}

/// The run's result at the strategy's best: genome, parameters, cost (the strategy's own when
/// it minimises one) and RMSE, the problem's counts, and what the loop recorded.
fn result_at_best(
    problem: &Problem,
    strategy: &dyn Strategy,
    generations: u64,
    seconds: f64,
    history: Vec<HistoryRow>,
    stopped_by: StopReason,
    checkpoint_error: Option<String>,
) -> RunResult {
    let (genome, cost) = strategy.best();
    let mut params = problem.space.base.clone();
    problem.space.fill_params(genome, &mut params);
    let (cost, rmse) = match strategy.own_cost() {
        Some((own, terms)) => (own, (own / terms.max(1) as f64).sqrt()),
        None => (cost, problem.rmse(cost)),
    };
    RunResult {
        strategy: strategy.name(),
        genome: genome.to_vec(),
        params,
        cost,
        rmse,
        evals: problem.evals(),
        generations,
        seconds,
        eval_seconds: problem.eval_seconds(),
        param_error_pct: problem.error_pct(genome),
        history,
        stopped_by,
        checkpoint_error,
    }
}

/// A failed checkpoint write as [`RunResult::checkpoint_error`] says it: the file and the
/// reason, and from which generation on the run had no checkpoint.
fn failed_checkpoint(e: CostError, generation: u64) -> String {
    let reason = match e {
        CostError::Run { message, .. } => message,
        other => other.to_string(),
    };
    format!("{reason} (generation {generation}: no checkpoint written from there on)")
}

/// Generation 0: the strategy's initial population, evaluated and observed.
fn init(
    problem: &mut Problem,
    strategy: &mut dyn Strategy,
    config: &RunConfig,
    observers: &mut [&mut dyn Observer],
    start: &Instant,
) -> Result<Start, CostError> {
    problem.set_evals(0);
    problem.objective.set_generation(0);
    strategy.init(problem, config.seed);
    if let Some(e) = problem.take_eval_error() {
        return Err(CostError::run_from("generation 0", e));
    }
    // A strategy that found no estimate is an error, not its start point as a result.
    if let Some(e) = strategy.failure() {
        return Err(CostError::run(strategy.name(), e));
    }
    let row = make_row(problem, &*strategy, 0, start.elapsed().as_secs_f64());
    for o in observers.iter_mut() {
        o.observe_best(&row, strategy.best().0);
    }
    Ok(Start {
        generation: 0,
        seconds_before: 0.0,
        history: vec![row],
    })
}

/// Reads the checkpoint at `path` into `strategy` and `problem`, after checking that it was
/// made for this run: format, strategy, dimension, seed, then the request's fingerprint.
fn resume(
    path: &std::path::Path,
    problem: &mut Problem,
    strategy: &mut dyn Strategy,
    config: &RunConfig,
) -> Result<Start, CostError> {
    let place = path.display().to_string();
    let bad = |m: String| CostError::resume(&place, m);
    // A checkpoint that cannot be read is an I/O error (CLI exit 1, as for every input); one
    // that reads but cannot resume this run is a resume error (exit 2).
    let text = cordis_core::io::read_text(path)?;
    let cp: Checkpoint =
        serde_json::from_str(&text).map_err(|e| bad(format!("not a checkpoint: {e}")))?;
    if cp.format != CHECKPOINT_FORMAT || cp.strategy != strategy.name() || cp.dim != problem.dim() {
        return Err(bad(format!(
            "checkpoint of strategy `{}` with {} unknowns cannot resume `{}` with {}",
            cp.strategy,
            cp.dim,
            strategy.name(),
            problem.dim()
        )));
    }
    if cp.seed != config.seed {
        return Err(bad(format!(
            "checkpoint was made with seed {}, not {}",
            cp.seed, config.seed
        )));
    }
    if let (Some(was), Some(now)) = (&cp.fingerprint, &config.fingerprint) {
        let differs: Vec<&str> = now
            .iter()
            .filter(|(k, v)| was.get(*k) != Some(*v))
            .map(|(k, _)| k.as_str())
            .chain(
                was.keys()
                    .filter(|k| !now.contains_key(*k))
                    .map(|k| k.as_str()),
            )
            .collect();
        if !differs.is_empty() {
            // One fingerprint entry holds the marker map and the weights together.
            let named: Vec<&str> = differs
                .iter()
                .map(|&k| {
                    if k == "markers" {
                        "markers or weights"
                    } else {
                        k
                    }
                })
                .collect();
            return Err(bad(format!(
                "checkpoint was made for another request: it differs from this run in its {}",
                named.join(", ")
            )));
        }
    }
    let history = match cp.history_rows {
        Some(rows) => HistoryFile::read(path, rows)?,
        None => cp.history,
    };
    strategy
        .load_state(problem, &cp.state)
        .map_err(|e| CostError::resume_from(&place, e))?;
    problem.set_evals(cp.evals);
    problem.objective.set_generation(cp.generation as usize);
    Ok(Start {
        generation: cp.generation,
        seconds_before: cp.seconds,
        history,
    })
}

fn make_row(problem: &Problem, s: &dyn Strategy, generation: u64, seconds: f64) -> HistoryRow {
    let st = s.stats();
    let (genome, _) = s.best();
    // A strategy with a cost of its own (output-error's position residuals) logs that, the
    // cost the summary reports, not the problem's it is never steered by.
    let (best_cost, best_rmse, mean_cost) = match s.own_cost() {
        Some((own, terms)) => (own, (own / terms.max(1) as f64).sqrt(), own),
        None => (st.best_cost, problem.rmse(st.best_cost), st.mean_cost),
    };
    HistoryRow {
        generation,
        evals: problem.evals(),
        seconds,
        best_cost,
        best_rmse,
        mean_cost,
        mean_mutability: st.mean_mutability,
        param_error_pct: problem.error_pct(genome),
    }
}

/// Writes `config.checkpoint` (when set), atomically.
fn write_checkpoint(
    config: &RunConfig,
    problem: &Problem,
    s: &dyn Strategy,
    generation: u64,
    seconds: f64,
    history: &[HistoryRow],
    history_file: &mut HistoryFile,
) -> Result<(), CostError> {
    let Some(path) = &config.checkpoint else {
        return Ok(());
    };
    // The rows first: a checkpoint never counts rows its history file does not hold.
    history_file.write(path, history)?;
    let cp = Checkpoint {
        format: CHECKPOINT_FORMAT.into(),
        strategy: s.name().into(),
        seed: config.seed,
        dim: problem.dim(),
        generation,
        evals: problem.evals(),
        seconds,
        history: Vec::new(),
        history_rows: Some(history.len()),
        state: s.save_state(),
        fingerprint: config.fingerprint.clone(),
    };
    let place = path.display().to_string();
    let text = serde_json::to_string(&cp).map_err(|e| CostError::run(&place, e.to_string()))?;
    // The core's error names the path already.
    cordis_core::io::write_atomic(path, text.as_bytes())
        .map_err(|e| CostError::run("checkpoint", e.to_string()))
}

/// A checkpoint's history, kept beside it in `PATH.history` (one JSON row per line) and
/// appended to, so that a checkpoint's cost does not grow with the generations: rewriting the
/// whole history into the checkpoint every 50 generations made 100,000 generations write
/// ~22 GB. The checkpoint says how many rows are its own ([`Checkpoint::history_rows`]); a
/// row appended for a checkpoint that a kill then prevented, even half a row, is ignored.
#[derive(Default)]
struct HistoryFile {
    /// Rows of the history that this run has put in the file (`None`: none yet).
    written: Option<usize>,
}

impl HistoryFile {
    /// `PATH.history` beside checkpoint `PATH`.
    fn path(checkpoint: &std::path::Path) -> PathBuf {
        let mut name = checkpoint.as_os_str().to_owned();
        name.push(".history");
        PathBuf::from(name)
    }

    /// Puts `history` in the file: whole and atomically the first time in a run (the file may
    /// be another run's, or the one a resumed checkpoint reads, whose rows are a prefix of
    /// `history`: either way it stays readable), then only the new rows, appended and synced.
    fn write(
        &mut self,
        checkpoint: &std::path::Path,
        history: &[HistoryRow],
    ) -> Result<(), CostError> {
        use std::io::Write;
        let path = Self::path(checkpoint);
        let fail = |e: String| CostError::run("checkpoint", format!("{}: {e}", path.display()));
        let from = self.written.unwrap_or(0).min(history.len());
        let mut text = String::new();
        for row in &history[from..] {
            text.push_str(&serde_json::to_string(row).map_err(|e| fail(e.to_string()))?);
            text.push('\n');
        }
        match self.written {
            None => cordis_core::io::write_atomic(&path, text.as_bytes())
                .map_err(|e| CostError::run("checkpoint", e.to_string()))?,
            Some(_) => std::fs::OpenOptions::new()
                .append(true)
                .open(&path)
                .and_then(|mut f| {
                    f.write_all(text.as_bytes())?;
                    f.sync_data()
                })
                .map_err(|e| fail(e.to_string()))?,
        }
        self.written = Some(history.len());
        Ok(())
    }

    /// The first `rows` rows of checkpoint `PATH`'s history file.
    fn read(checkpoint: &std::path::Path, rows: usize) -> Result<Vec<HistoryRow>, CostError> {
        let path = Self::path(checkpoint);
        let place = path.display().to_string();
        let text = cordis_core::io::read_text(&path)?;
        let history = text
            .lines()
            .take(rows)
            .enumerate()
            .map(|(k, line)| {
                serde_json::from_str(line).map_err(|e| {
                    CostError::resume(
                        format!("{place}:{}", k + 1),
                        format!("not a history row: {e}"),
                    )
                })
            })
            .collect::<Result<Vec<HistoryRow>, _>>()?;
        if history.len() < rows {
            return Err(CostError::resume(
                &place,
                format!(
                    "has {} history rows, the checkpoint needs {rows}",
                    history.len()
                ),
            ));
        }
        Ok(history)
    }
}
