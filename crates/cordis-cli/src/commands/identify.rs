use std::io::{IsTerminal, Write};
use std::path::{Path, PathBuf};

use anyhow::Result;
use cordis_core::io::AtomicFile;
use cordis_core::{Observations, Scene};
use cordis_es::cost::{CostKind, LocalCost};
use cordis_es::executor::{HistoryRow, Observer, StopReason};
use cordis_es::identify::StrategyName;
use cordis_es::session::{Generations, IdentifyRequest, Lock, Outcome, Session, Style};
use cordis_es::strategies::cmaes::Restarts;
use cordis_es::strategies::islands::IslandConfig;
use cordis_es::strategies::thesis::Crossover;

use super::Output;

#[derive(clap::Args, Debug)]
// A negative value (`--time-limit -1`, `--seed -1`) is read as the option's value, so that its
// validation names it with the range, rather than clap's "unexpected argument '-1'".
#[command(allow_negative_numbers = true)]
pub struct Args {
    /// Scene whose unknown parameters are written as {"min": …, "max": …}.
    scene: PathBuf,
    /// Observed trajectory (.csv, .tsv, .npy, .tra, .trc, .c3d, .npz; see --columns, --units),
    /// particle i of the file the scene's particle i. Gaps are missing observations: empty
    /// cells, `nan`, absent rows, NaN in .npy, C3D residuals < 0, hidden tracker points;
    /// particles the file lacks are hidden. Repeat for several takes of the same object (one
    /// parameter set, each take its own initial state; output-error only).
    #[arg(long, short = 't', required = true)]
    trajectory: Vec<PathBuf>,
    /// Which scene particle each of the file's markers is, comma-separated (`--markers
    /// 4,0,7`: the file's particle 0 is the scene's particle 4, …), the same for every take.
    /// Particles no marker names are hidden; fixed particles need not be tracked.
    #[arg(long, allow_hyphen_values = true, value_parser = super::particle_indices)]
    markers: Option<super::ParticleIndices>,
    /// Each marker's weight, 1/σ relative to the others, comma-separated: one per marker, or
    /// three per marker (x, y, z). Positive and finite; read by output-error only.
    #[arg(long, value_delimiter = ',', num_args = 1.., allow_negative_numbers = true)]
    weights: Option<Vec<f64>>,
    /// Loss on each position residual (output-error): squared (maximum likelihood under
    /// Gaussian noise) | huber | cauchy (robust against tracking outliers and swapped markers;
    /// auto then picks output-error).
    #[arg(long, default_value = "squared")]
    loss: String,
    /// The 95 % intervals (output-error): wald (from the standard errors, checked along each
    /// unknown's profile direction and widened where the cost there is flatter than its
    /// quadratic model) | profile (the profile likelihood's where it is flatter: every other
    /// variable refitted at each interval edge; several times the fit's time).
    #[arg(long, default_value = "wald")]
    intervals: String,
    /// Strategy: auto | thesis | t2m | least-squares | hybrid | cmaes | self-adaptive |
    /// annealing | parisian | levenberg-marquardt | output-error. thesis = the ES of thesis
    /// §3.2 and Annexe 1 as written; t2m = the same ES with freer operators. auto = output-error
    /// on noisy or gappy data (when every kind has exact sensitivities), else least-squares when
    /// every unknown enters linearly, hybrid when only ranges, v_max or a TGR's stiffness and
    /// tendon do not, levenberg-marquardt when the short cost is smooth in every unknown
    /// (muscles, worlds), else t2m.
    #[arg(long, default_value = "auto")]
    strategy: StrategyName,
    /// Stop after this many generations.
    #[arg(long, short = 'g')]
    generations: Option<u64>,
    /// Population size.
    #[arg(long, short = 'p')]
    population: Option<usize>,
    /// Seed of every random draw: the same seed gives the same result on any thread count.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// Add Gaussian noise of this standard deviation (m) to the observed positions first.
    #[arg(long, default_value_t = 0.0)]
    noise: f64,
    /// Cost: short | horizon:H | long | progressive | harmonic | static (equilibrium poses).
    #[arg(long, default_value = "short")]
    cost: String,
    /// Reject (+inf cost) every candidate whose stability bound exceeds 1 or whose free run
    /// from the observed frames 0 and 1 diverges within this many frames (frame 0 included):
    /// a non-finite or runaway position, or a spread beyond --stable-spread times the observed.
    #[arg(long)]
    stable_horizon: Option<usize>,
    /// With --stable-horizon: the largest spread of the free particles about their centroid,
    /// as a multiple of the largest observed one.
    #[arg(long, default_value_t = cordis_es::stable::DEFAULT_SPREAD)]
    stable_spread: f64,
    /// Stop after this many seconds.
    #[arg(long)]
    time_limit: Option<f64>,
    /// Stop once the best cost is at or below this.
    #[arg(long)]
    target_cost: Option<f64>,
    /// Stop after this many cost evaluations.
    #[arg(long)]
    max_evals: Option<u64>,
    /// An island model of this many populations of the strategy (2 or more), exchanging
    /// their best individuals in a ring.
    #[arg(long)]
    islands: Option<usize>,
    /// With --islands: generations between two migrations.
    #[arg(long, default_value_t = 10)]
    migrate_every: u64,
    /// With --islands: individuals each island sends per migration.
    #[arg(long, default_value_t = 2)]
    migrants: usize,
    /// Thesis file Param.gene (key=value): population, pcross, pmut, reducer, generation, noise
    /// (damping only as 0); pcross, pmut and reducer configure thesis and t2m only (refused
    /// with another strategy).
    #[arg(long)]
    param_gene: Option<PathBuf>,
    /// thesis and t2m: the crossover: mean (Annexe 1: per type, the mean of fathers chosen by
    /// local cost at each end particle), n-parent or mn-parent (§3.2: a type, or each of its
    /// parameters, from one father). Default mean; refused with another strategy.
    #[arg(long)]
    crossover: Option<String>,
    /// thesis and t2m: the local cost that drives their local operators: positions (default:
    /// each particle's prediction error) or distances (thesis eq 3.3 as printed: the error of
    /// the predicted distances to the particles it shares a link with; short cost only). The
    /// global cost is the same. Refused with another strategy.
    #[arg(long)]
    local_cost: Option<String>,
    /// cmaes: how a run that ends restarts: ipop (default: λ doubled) or bipop (Hansen 2009:
    /// large-population IPOP runs interlaced, by budget, with small-population, small-step
    /// ones). Refused with another strategy.
    #[arg(long)]
    restarts: Option<String>,
    /// self-adaptive: (μ+λ) selection, parents competing with their children (default (μ,λ)).
    #[arg(long)]
    plus: bool,
    /// self-adaptive: correlated mutations (Schwefel's rotation angles, one per pair of
    /// coordinates) instead of independent ones.
    #[arg(long)]
    correlated: bool,
    /// thesis and t2m: first generation of Powell's descent on the best individual (default
    /// 400; refused with another strategy).
    #[arg(long)]
    descent_start: Option<u64>,
    /// thesis and t2m: generations between descents (0: never; default 100; refused with
    /// another strategy).
    #[arg(long)]
    descent_every: Option<u64>,
    /// Parameters to keep at their starting value (thesis `.lock`): a `NAME.lock` file, or
    /// comma-separated names such as `types.rib.stiffness,particles[3].mass`.
    #[arg(long)]
    lock: Option<String>,
    /// Write a checkpoint here: every 50 generations but at most once a second, and at the end
    /// however the run stops; the history rows are appended to FILE.history beside it.
    #[arg(long)]
    checkpoint: Option<PathBuf>,
    /// Resume from this checkpoint (same scene, trajectory, strategy and seed).
    #[arg(long)]
    resume: Option<PathBuf>,
    /// Convergence log, one row per generation (.csv or .jsonl).
    #[arg(long)]
    log: Option<PathBuf>,
    /// Where to write the identified scene (JSON), with take 0's estimated initial state
    /// (output-error). With several takes, take k's scene (its own initial state, so that
    /// `cordis simulate` of it replays take k) goes beside it as NAME.take<k>.json.
    #[arg(long, short = 'o')]
    out: Option<PathBuf>,
    /// The true scene, to report the mean parameter error.
    #[arg(long)]
    truth: Option<PathBuf>,
    /// Known total mass (kg) of the free particles, when masses are unknown: masses and link
    /// parameters are otherwise only determined up to a common scale.
    #[arg(long)]
    total_mass: Option<f64>,
    /// Time step of the trajectory when its file does not give one (default: the scene's dt).
    #[arg(long)]
    dt: Option<f64>,
    /// The take's frame 0 is this frame of the scene's motion (a take cropped mid-motion):
    /// every signal's phase is advanced by `K dt / period` before anything else, so TGRs are
    /// driven on the take's clock (the model written by --out keeps that clock). The tendons'
    /// start is the TGR types' `tendon_position` / `tendon_velocity` (known, or boxes to
    /// identify). Default 0.
    #[arg(long, default_value_t = 0)]
    first_frame: usize,
    #[command(flatten)]
    read: super::ReadArgs,
}

pub fn run(a: Args, output: Output) -> Result<()> {
    guard(&a)?;
    let session = Session::new(request(&a)?)?;
    // Known before the run (threads capped): said before the wait, not after it.
    let early = session.warnings().len();
    for w in session.warnings() {
        eprintln!("warning: {w}");
    }
    let ran = session.strategy();
    super::catch_ctrl_c();
    let mut log = match &a.log {
        Some(p) => Some(LogWriter::create(p)?),
        None => None,
    };
    let mut progress = Progress::new(session.stop_rules().generations, output.quiet);
    let mut observers: Vec<&mut dyn Observer> = vec![&mut progress];
    if let Some(l) = log.as_mut() {
        observers.push(l);
    }
    let outcome = session.run(&mut observers, Some(&super::INTERRUPTED))?;
    drop(observers);
    progress.finish();
    // A write that fails here (a full disk) must not lose the result: it is printed first,
    // then the failure names its file (exit 1).
    let mut failed = log.and_then(|l| l.finish().err().map(anyhow::Error::from));
    if let Some(e) = &outcome.result.checkpoint_error {
        failed.get_or_insert(cordis_es::CostError::run("--checkpoint", e.as_str()).into());
    }
    // A run stopped (Ctrl-C) before any finite cost has no model to write.
    let finite = outcome.result.cost.is_finite();
    if let Some(out) = a.out.as_ref().filter(|_| finite) {
        if let Err(e) = super::write_scene(outcome.scene(), Some(out)) {
            failed.get_or_insert(e);
        }
        let paths = take_scene_paths(out, outcome.scenes.len());
        for ((k, scene), path) in outcome.scenes.iter().enumerate().skip(1).zip(paths) {
            match super::write_scene(scene, Some(&path)) {
                Ok(()) if output.human() => eprintln!(
                    "wrote take {k}'s identified scene (its estimated initial state) to {}",
                    path.display()
                ),
                Ok(()) => {}
                Err(e) => {
                    failed.get_or_insert(e);
                }
            }
        }
    }
    if output.human() {
        print_human(ran, &outcome);
    }
    // Warnings print even with --quiet: they say the answer is not to be trusted as it is.
    for w in &outcome.warnings[early..] {
        eprintln!("warning: {w}");
    }
    if let Some(out) = a.out.as_ref().filter(|_| !finite) {
        eprintln!(
            "warning: nothing written to {}: no candidate had a finite cost",
            out.display()
        );
    }
    output.json_line(&summary(ran, &outcome, a.stable_horizon))?;
    if let Some(e) = failed {
        return Err(e);
    }
    if outcome.result.stopped_by == StopReason::Interrupted {
        let kept = match a.out.as_ref().filter(|_| finite) {
            Some(out) => format!("the best result so far was written to {}", out.display()),
            None if finite => "the best result so far is the one reported above".to_string(),
            None => "no candidate had a finite cost yet: nothing to keep".to_string(),
        };
        return Err(super::Interrupted(kept).into());
    }
    // Ctrl-C after the run had ended by its own rule (during the uncertainty, say): the
    // result is whole and labelled as it ended, and the exit is still 130, so that a shell
    // loop over files stops as Ctrl-C asks.
    if super::INTERRUPTED.load(std::sync::atomic::Ordering::Relaxed) {
        let ended = outcome.result.stopped_by.as_str();
        let kept = match a.out.as_ref().filter(|_| finite) {
            Some(out) => format!(
                "the run had already ended ({ended}); its result was written to {}",
                out.display()
            ),
            None => {
                format!("the run had already ended ({ended}); its result is the one reported above")
            }
        };
        return Err(super::Interrupted(kept).into());
    }
    Ok(())
}

/// Refuses a take whose every observed z is 0 for a scene with depth: a table with no z
/// column reads as planar (z = 0), so a misspelt `z` header (`q`) read silently flat, and the
/// fit then diverged with advice about boxes and dt.
fn check_not_flattened(scene: &Scene, obs: &Observations, path: &Path) -> Result<()> {
    let mut z = obs
        .as_flat()
        .iter()
        .skip(2)
        .step_by(3)
        .filter(|v| !v.is_nan());
    let flat = z.clone().next().is_some() && z.all(|v| *v == 0.0);
    match scene.particles.iter().position(|p| p.pos[2] != 0.0) {
        Some(k) if flat => Err(cordis_core::CordisError::trajectory(
            path.display().to_string(),
            format!(
                "every z is 0 (a table without a z column reads as planar), but the scene has \
                 depth (particles[{k}] starts at z = {}): name the z column, --columns z=…",
                scene.particles[k].pos[2]
            ),
        )
        .into()),
        _ => Ok(()),
    }
}

/// Issue 17 hook: outputs off the inputs and each other, writable, before any work.
/// `--checkpoint` may be the `--resume` file (a run that goes on saving where it resumed).
fn guard(a: &Args) -> Result<()> {
    let lock_file = a
        .lock
        .as_deref()
        .filter(|l| l.ends_with(".lock"))
        .map(Path::new);
    let mut inputs = vec![("scene", Some(a.scene.as_path()))];
    inputs.extend(
        a.trajectory
            .iter()
            .map(|t| ("--trajectory", Some(t.as_path()))),
    );
    inputs.extend([
        ("--truth", a.truth.as_deref()),
        ("--param-gene", a.param_gene.as_deref()),
        ("--lock", lock_file),
    ]);
    let (out, log) = (("--out", a.out.as_deref()), ("--log", a.log.as_deref()));
    // Take k's scene beside --out (only output-error writes them; guarded whatever the
    // strategy, before the run knows).
    let take_scenes: Vec<(String, PathBuf)> = match &a.out {
        Some(o) => take_scene_paths(o, a.trajectory.len())
            .into_iter()
            .enumerate()
            .map(|(k, p)| (format!("--out's take {}", k + 1), p))
            .collect(),
        None => Vec::new(),
    };
    // The checkpoint's history rows go to FILE.history beside it: an output too (a --log
    // there was interleaved with them, exit 0).
    let history = a.checkpoint.as_deref().map(checkpoint_history);
    super::guard_outputs(
        &inputs,
        &[
            ("--checkpoint", a.checkpoint.as_deref()),
            ("--checkpoint's history", history.as_deref()),
            out,
            log,
        ]
        .into_iter()
        .chain(
            take_scenes
                .iter()
                .map(|(n, p)| (n.as_str(), Some(p.as_path()))),
        )
        .collect::<Vec<_>>(),
    )?;
    super::guard_outputs(&[("--resume", a.resume.as_deref())], &[out, log])
}

/// Where the identified scenes of takes 1.. of `takes` go beside `out`: `model.json` →
/// `model.take1.json`, …. None when `out` is a device or a pipe (`/dev/null`, `/dev/stdout`):
/// `/dev/null.take1` is no place to write.
fn take_scene_paths(out: &Path, takes: usize) -> Vec<PathBuf> {
    if cordis_core::io::written_in_place(out) {
        return Vec::new();
    }
    let stem = out.file_stem().unwrap_or_default().to_string_lossy();
    (1..takes)
        .map(|k| {
            let name = match out.extension() {
                Some(ext) => format!("{stem}.take{k}.{}", ext.to_string_lossy()),
                None => format!("{stem}.take{k}"),
            };
            out.with_file_name(name)
        })
        .collect()
}

/// `FILE.history`, where the history rows of checkpoint `FILE` are appended.
fn checkpoint_history(checkpoint: &Path) -> PathBuf {
    let mut name = checkpoint.as_os_str().to_owned();
    name.push(".history");
    PathBuf::from(name)
}

/// The command line as a request: nothing is checked here, the session checks it all.
fn request(a: &Args) -> Result<IdentifyRequest> {
    let scene = Scene::from_json_path(&a.scene)?;
    let scene = if a.first_frame > 0 {
        scene
            .from_frame(a.first_frame)
            .map_err(|e| anyhow::anyhow!("--first-frame: {e}"))?
    } else {
        scene
    };
    let mut takes = Vec::with_capacity(a.trajectory.len());
    for path in &a.trajectory {
        let obs = cordis_core::io::read_observations_with(path, &a.read.options()?)?;
        super::check_dt(&scene, a.dt.or(obs.dt), path)?;
        check_not_flattened(&scene, &obs, path)?;
        takes.push(obs);
    }
    let cost: CostKind = a.cost.parse().map_err(|e| anyhow::anyhow!("--cost: {e}"))?;
    let truth = match &a.truth {
        Some(t) => Some(Scene::from_json_path(t)?),
        None => None,
    };
    let mut r = IdentifyRequest::with_takes(scene, takes);
    r.scene_place = a.scene.display().to_string();
    r.take_places = a
        .trajectory
        .iter()
        .map(|t| t.display().to_string())
        .collect();
    r.markers = a.markers.as_ref().map(|m| m.0.clone());
    r.weights = a.weights.clone();
    r.loss = a.loss.parse().map_err(|e| anyhow::anyhow!("--loss: {e}"))?;
    r.intervals = a
        .intervals
        .parse()
        .map_err(|e| anyhow::anyhow!("--intervals: {e}"))?;
    r.strategy = a.strategy;
    r.population = a.population;
    r.param_gene = a.param_gene.clone();
    r.descent_start = a.descent_start;
    r.descent_every = a.descent_every;
    r.crossover = a
        .crossover
        .as_deref()
        .map(Crossover::parse)
        .transpose()
        .map_err(|e| anyhow::anyhow!("--crossover: {e}"))?;
    r.local_cost = a
        .local_cost
        .as_deref()
        .map(LocalCost::parse)
        .transpose()
        .map_err(|e| anyhow::anyhow!("--local-cost: {e}"))?;
    r.restarts = a
        .restarts
        .as_deref()
        .map(Restarts::parse)
        .transpose()
        .map_err(|e| anyhow::anyhow!("--restarts: {e}"))?;
    r.plus = a.plus;
    r.correlated = a.correlated;
    r.islands = a.islands.map(|islands| IslandConfig {
        islands,
        migrate_every: a.migrate_every,
        migrants: a.migrants,
    });
    r.cost = cost;
    r.generations = a
        .generations
        .map_or(Generations::Default, Generations::Limit);
    r.max_evals = a.max_evals;
    r.time_limit = a.time_limit;
    r.target_cost = a.target_cost;
    r.seed = a.seed;
    r.noise = a.noise;
    r.lock = a.lock.as_deref().map(Lock::parse);
    r.total_mass = a.total_mass;
    r.stable_horizon = a.stable_horizon;
    r.stable_spread = a.stable_spread;
    r.truth = truth;
    r.checkpoint = a.checkpoint.clone();
    r.resume = a.resume.clone();
    r.threads = a.threads;
    r.style = Style::Cli;
    Ok(r)
}

fn print_human(ran: &str, outcome: &Outcome) {
    let (result, problem) = (&outcome.result, &outcome.problem);
    eprintln!(
        "{ran}: {} generations, {} evaluations in {:.2} s; cost {:.6e}, rmse {:.6e}{}",
        result.generations,
        result.evals,
        result.seconds,
        result.cost,
        result.rmse,
        result
            .param_error_pct
            .map(|e| format!(", mean parameter error {e:.3e} %"))
            .unwrap_or_default()
    );
    let spread = outcome.report.uncertainty.as_deref();
    let oe = match &outcome.report.solver {
        Some(cordis_es::report::SolverReport::OutputError(r)) => Some(r),
        _ => None,
    };
    // Why `auto` picked the estimator (the JSON line's `solver.chosen_because`).
    if let Some(why) = oe.and_then(|r| r.chosen_because.as_deref()) {
        eprintln!("  chosen by auto: {why}");
    }
    let not_computed = oe.map_or(&[][..], |r| r.stderr_at_least.as_slice());
    for (u, v) in problem
        .space
        .unknowns
        .iter()
        .zip(problem.space.values(&result.genome))
    {
        let truth = problem
            .truth
            .as_ref()
            .map(|t| format!("  (truth {:.6e})", t[u.slot]))
            .unwrap_or_default();
        // A standard error and the 95 % interval, when the strategy estimates them.
        let se = match spread.and_then(|s| s.iter().find(|p| p.name == u.name)) {
            Some(p) if p.std_error.is_finite() => format!(
                " ± {:.2e}  [{:.6e}, {:.6e}]",
                p.std_error, p.interval.0, p.interval.1
            ),
            // Its interval is its box: the data do not narrow it.
            Some(p) => format!(
                " ± not determined  [{:.6e}, {:.6e}] (its box)",
                p.interval.0, p.interval.1
            ),
            None => match not_computed.iter().find(|b| b.name == u.name) {
                Some(b) => match b.rounded_down() {
                    Some(v) => format!(" ± not computed (≥ {v})"),
                    None => " ± not computed".to_string(),
                },
                None => String::new(),
            },
        };
        eprintln!("  {:<40} {:>14.6e}{se}{truth}", u.name, v);
    }
}

/// The one JSON line of a run.
fn summary(ran: &str, outcome: &Outcome, stable_horizon: Option<usize>) -> serde_json::Value {
    let result = &outcome.result;
    let mut summary = serde_json::json!({
        "strategy": ran,
        "cost": super::finite_or_string(result.cost),
        "rmse": super::finite_or_string(result.rmse),
        "evals": result.evals,
        "generations": result.generations,
        "seconds": result.seconds,
        "eval_seconds": result.eval_seconds,
        "stopped_by": result.stopped_by,
    });
    if let Some(e) = result.param_error_pct {
        summary["param_error_pct"] = e.into();
    }
    // The estimate itself, so that `-q --json` without `--out` keeps it (names as the report's).
    let problem = &outcome.problem;
    let params: serde_json::Map<String, serde_json::Value> = problem
        .space
        .unknowns
        .iter()
        .zip(problem.space.values(&result.genome))
        .map(|(u, v)| (u.name.clone(), super::finite_or_string(v)))
        .collect();
    summary["params"] = params.into();
    if let Some(h) = stable_horizon {
        summary["stable_horizon"] = h.into();
    }
    let report = outcome.report.to_json();
    if !report.is_null() {
        summary["solver"] = report;
    }
    summary
}

/// Convergence log, CSV or JSON lines by extension, written whole-line: each row is one
/// write of the full line, unbuffered, so a kill leaves only whole rows; a write that fails
/// (a full disk) is cut back to the last whole row, ends the logging and is reported, naming
/// the file, once the result is out ([`LogWriter::finish`]). The rows stream to a temporary
/// beside the file, renamed over it once the run has a result: a run that fails, crashes or
/// is killed leaves the previous log as it was (it used to be truncated at the start).
struct LogWriter {
    file: AtomicFile,
    jsonl: bool,
    /// Bytes of whole rows written.
    len: u64,
    failed: Option<std::io::Error>,
}

impl LogWriter {
    fn create(path: &std::path::Path) -> Result<Self> {
        let file = AtomicFile::create(path)?;
        let jsonl = path
            .extension()
            .is_some_and(|e| e == "jsonl" || e == "json");
        let mut log = LogWriter {
            file,
            jsonl,
            len: 0,
            failed: None,
        };
        if !jsonl {
            log.write_line(HistoryRow::CSV_HEADER.to_string());
        }
        Ok(log)
    }

    fn write_line(&mut self, mut line: String) {
        if self.failed.is_some() {
            return;
        }
        line.push('\n');
        match self.file.file().write_all(line.as_bytes()) {
            Ok(()) => self.len += line.len() as u64,
            Err(e) => {
                // Best effort: a file that cannot even be cut keeps its torn row.
                let _ = self.file.file().set_len(self.len);
                self.failed = Some(e);
            }
        }
    }

    /// Puts the log in place (the rows written, up to the first failed write), then reports
    /// that write error, naming the file.
    fn finish(self) -> Result<(), cordis_core::CordisError> {
        let path = self.file.path().to_path_buf();
        self.file.commit()?;
        match self.failed {
            Some(e) => Err(cordis_core::CordisError::io(&path, e)),
            None => Ok(()),
        }
    }
}

impl Observer for LogWriter {
    fn observe(&mut self, row: &HistoryRow) -> bool {
        let line = if self.jsonl {
            serde_json::to_string(row).unwrap_or_default()
        } else {
            row.csv()
        };
        self.write_line(line);
        true
    }
}

/// A progress bar with ETA on a terminal; nothing otherwise.
struct Progress {
    bar: Option<indicatif::ProgressBar>,
}

impl Progress {
    fn new(generations: Option<u64>, quiet: bool) -> Self {
        if quiet || !std::io::stderr().is_terminal() {
            return Progress { bar: None };
        }
        // Without a generation budget (a time or evaluation limit) there is no length to
        // fill and no ETA to give: a counter, not a bar reading `gen 123/0 (eta 0s)`.
        let (bar, template) = match generations {
            Some(g) => (
                indicatif::ProgressBar::new(g),
                "{elapsed_precise} [{bar:30}] gen {pos}/{len} (eta {eta}) {msg}",
            ),
            None => (
                indicatif::ProgressBar::no_length(),
                "{elapsed_precise} gen {pos} {msg}",
            ),
        };
        bar.set_style(
            indicatif::ProgressStyle::with_template(template)
                .expect("valid template")
                .progress_chars("=> "),
        );
        Progress { bar: Some(bar) }
    }

    fn finish(&mut self) {
        if let Some(b) = self.bar.take() {
            b.finish_and_clear();
        }
    }
}

impl Observer for Progress {
    fn observe(&mut self, row: &HistoryRow) -> bool {
        if let Some(b) = &self.bar {
            b.set_position(row.generation);
            b.set_message(format!("cost {:.3e}", row.best_cost));
        }
        true
    }
}
