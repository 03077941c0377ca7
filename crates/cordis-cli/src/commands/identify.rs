use std::fs::File;
use std::io::{BufWriter, IsTerminal, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use anyhow::{bail, Context, Result};
use cordis_core::Scene;
use cordis_es::cost::CostKind;
use cordis_es::executor::{self, HistoryRow, Observer, RunConfig, StopRules};
use cordis_es::identify::{
    add_noise, check_strategy, make_strategy, StrategyName, StrategyOptions,
};
use cordis_es::problem::Problem;

use super::Output;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scene whose unknown parameters are written as {"min": …, "max": …}.
    scene: PathBuf,
    /// Observed trajectory (.csv, .npy or .tra), every particle in scene order.
    #[arg(long, short = 't')]
    trajectory: PathBuf,
    /// Strategy: auto | thesis | least-squares | hybrid | cmaes | self-adaptive | annealing |
    /// parisian | levenberg-marquardt. auto = least-squares when every unknown enters linearly,
    /// hybrid when only ranges, v_max or a TGR's stiffness and tendon do not,
    /// levenberg-marquardt when the short cost is smooth in every unknown (muscles, worlds),
    /// else thesis.
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
    /// Cost: short | horizon:H | long | progressive | harmonic.
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
    /// Thesis file Param.gene (key=value): population, pcross, pmut, reducer, generation, noise.
    #[arg(long)]
    param_gene: Option<PathBuf>,
    /// Thesis strategy: first generation of Powell's descent on the best individual.
    #[arg(long, default_value_t = 400)]
    descent_start: u64,
    /// Thesis strategy: generations between descents (0: never).
    #[arg(long, default_value_t = 100)]
    descent_every: u64,
    /// Parameters to keep at their starting value (thesis `.lock`): a `NAME.lock` file, or
    /// comma-separated names such as `types.rib.stiffness,particles[3].mass`.
    #[arg(long)]
    lock: Option<String>,
    /// Write a checkpoint here (every 50 generations and at the end).
    #[arg(long)]
    checkpoint: Option<PathBuf>,
    /// Resume from this checkpoint (same scene, trajectory, strategy and seed).
    #[arg(long)]
    resume: Option<PathBuf>,
    /// Convergence log, one row per generation (.csv or .jsonl).
    #[arg(long)]
    log: Option<PathBuf>,
    /// Where to write the identified scene (JSON).
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
}

static INTERRUPTED: AtomicBool = AtomicBool::new(false);

pub fn run(a: Args, output: Output) -> Result<()> {
    // Issue 17 hook: outputs off the inputs and each other, writable, before any work.
    // `--checkpoint` may be the `--resume` file (a run that goes on saving where it resumed).
    let lock_file = a
        .lock
        .as_deref()
        .filter(|l| l.ends_with(".lock"))
        .map(Path::new);
    let inputs = [
        ("scene", Some(a.scene.as_path())),
        ("--trajectory", Some(&a.trajectory)),
        ("--truth", a.truth.as_deref()),
        ("--param-gene", a.param_gene.as_deref()),
        ("--lock", lock_file),
    ];
    let (out, log) = (("--out", a.out.as_deref()), ("--log", a.log.as_deref()));
    super::guard_outputs(
        &inputs,
        &[("--checkpoint", a.checkpoint.as_deref()), out, log],
    )?;
    super::guard_outputs(&[("--resume", a.resume.as_deref())], &[out, log])?;
    let scene = Scene::from_json_path(&a.scene)?;
    if !scene.has_unknowns() {
        bail!(
            "{}: no parameter to identify: write unknowns as {{\"min\": …, \"max\": …}}",
            a.scene.display()
        );
    }
    let mut traj = cordis_core::io::read_trajectory(&a.trajectory)?;
    super::check_dt(&scene, a.dt.or(traj.dt), &a.trajectory)?;
    let kind: CostKind = a.cost.parse().map_err(|e| anyhow::anyhow!("--cost: {e}"))?;
    let gene = match &a.param_gene {
        Some(p) => {
            let text = std::fs::read_to_string(p).with_context(|| p.display().to_string())?;
            Some(cordis_core::thesis::parse_gene(
                &p.display().to_string(),
                &text,
            )?)
        }
        None => None,
    };
    let noise = if a.noise > 0.0 {
        a.noise
    } else {
        gene.as_ref().and_then(|g| g.noise).unwrap_or(0.0)
    };
    if noise > 0.0 {
        traj = add_noise(&traj, noise, a.seed);
    }
    let mut problem = Problem::new(&scene, &traj, kind)?;
    if let Some(lock) = &a.lock {
        let (names, from_file) = lock_names(lock)?;
        let known: Vec<&str> = problem
            .space
            .unknowns
            .iter()
            .map(|u| u.name.as_str())
            .collect();
        // A .lock file may lock what the scene already knows; a name given by hand must exist.
        if let Some(bad) = names
            .iter()
            .find(|n| !from_file && !known.contains(&n.as_str()))
        {
            bail!("--lock: `{bad}` is not an unknown of {}", a.scene.display());
        }
        problem.space.lock(&names);
    }
    if let Some(t) = &a.truth {
        problem = problem.with_truth(&Scene::from_json_path(t)?)?;
    }
    if let Some(h) = a.stable_horizon {
        let h = cordis_es::stable::StableHorizon::new(h, a.stable_spread)?;
        problem = problem.with_stable_horizon(h);
    }
    if let Some(m) = a.total_mass {
        problem = problem.with_total_mass(m).context("--total-mass")?;
    }
    let population = a
        .population
        .or(gene.as_ref().and_then(|g| g.population).map(|p| p as usize))
        .unwrap_or(100);
    let generations = a
        .generations
        .or(gene.as_ref().and_then(|g| g.generation))
        .or(
            if a.time_limit.is_none() && a.max_evals.is_none() && a.target_cost.is_none() {
                Some(1000)
            } else {
                None
            },
        );
    let options = StrategyOptions {
        population,
        gene,
        descent_start: a.descent_start,
        descent_every: a.descent_every,
    };
    let (mut strategy, ran) = make_strategy(a.strategy, &problem, &options);
    check_strategy(ran, &problem).map_err(|e| anyhow::anyhow!("{}: {e}", a.scene.display()))?;
    // An exact solver is done after generation 0: the run loop stops it as `converged`.
    let config = RunConfig {
        seed: a.seed,
        stop: StopRules {
            generations,
            max_evals: a.max_evals,
            time_limit: a.time_limit.map(Duration::from_secs_f64),
            target_cost: a.target_cost,
        },
        checkpoint: a.checkpoint.clone(),
        checkpoint_every: 50,
        resume: a.resume.clone(),
    };
    let _ = ctrlc::set_handler(|| INTERRUPTED.store(true, Ordering::Relaxed));
    let mut log = match &a.log {
        Some(p) => Some(LogWriter::create(p)?),
        None => None,
    };
    let mut progress = Progress::new(generations, output.quiet);
    let mut observers: Vec<&mut dyn Observer> = vec![&mut progress];
    if let Some(l) = log.as_mut() {
        observers.push(l);
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(a.threads.unwrap_or(0))
        .build()
        .context("--threads")?;
    let result = pool
        .install(|| {
            executor::run(
                &mut problem,
                strategy.as_mut(),
                &config,
                &mut observers,
                Some(&INTERRUPTED),
            )
        })
        .map_err(|e| anyhow::anyhow!(e))?;
    drop(observers);
    progress.finish();
    if let Some(mut l) = log {
        l.flush()?;
    }
    let identified = problem.space.scene_with(&scene, &result.genome);
    if let Some(out) = &a.out {
        super::write_scene(&identified, Some(out))?;
    }
    if output.human() {
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
            eprintln!("  {:<40} {:>14.6e}{truth}", u.name, v);
        }
    }
    let report = strategy.report();
    // Warnings print even with --quiet: they say the answer is not to be trusted as it is.
    if let Some(e) = report.get("error").and_then(|v| v.as_str()) {
        eprintln!("warning: {e}");
    }
    for (key, what) in [
        (
            "undetermined",
            "not determined by the data (held at the starting value)",
        ),
        (
            "poorly_determined",
            "poorly determined (large condition number)",
        ),
        (
            "clamped",
            "unconstrained solution outside the box (clamped onto it)",
        ),
    ] {
        let names: Vec<&str> = report
            .get(key)
            .and_then(|v| v.as_array())
            .map(|a| a.iter().filter_map(|v| v.as_str()).collect())
            .unwrap_or_default();
        if !names.is_empty() {
            eprintln!("warning: {}: {what}", names.join(", "));
        }
    }
    if let Some(p) = report
        .get("provot")
        .filter(|p| p.get("consistent").and_then(|c| c.as_bool()) == Some(false))
    {
        eprintln!(
            "warning: Provot limit: after {} solves the estimate still marks rows that were kept \
             (the answer may be biased by the limit)",
            p.get("iterations").and_then(|v| v.as_u64()).unwrap_or(0)
        );
    }
    let mut summary = serde_json::json!({
        "strategy": ran,
        "cost": result.cost,
        "rmse": result.rmse,
        "evals": result.evals,
        "generations": result.generations,
        "seconds": result.seconds,
        "eval_seconds": result.eval_seconds,
        "stopped_by": result.stopped_by,
    });
    if let Some(e) = result.param_error_pct {
        summary["param_error_pct"] = e.into();
    }
    if let Some(h) = a.stable_horizon {
        summary["stable_horizon"] = h.into();
        if !result.cost.is_finite() {
            eprintln!(
                "warning: --stable-horizon {h}: every candidate evaluated was rejected as \
                 unstable (widen the budget, or narrow the boxes)"
            );
        }
    }
    if !report.is_null() {
        summary["solver"] = report;
    }
    output.json_line(&summary)?;
    if result.stopped_by == executor::StopReason::Interrupted {
        return Err(super::Interrupted.into());
    }
    Ok(())
}

/// The unknowns named by `--lock`: a thesis `.lock` file (its `x` flags mark l0 — or the rest
/// cosine —, K and Z of a type as known) or a comma-separated list of names.
fn lock_names(lock: &str) -> Result<(Vec<String>, bool)> {
    if lock.ends_with(".lock") {
        let text = std::fs::read_to_string(lock).with_context(|| lock.to_string())?;
        let mut names = Vec::new();
        for t in cordis_core::thesis::parse_lock(lock, &text)? {
            let params: &[&str] = match t.family.kind() {
                cordis_core::LinkKind::Angle => &["rest_cos", "stiffness", "damping"],
                _ => &["rest_length", "stiffness", "damping"],
            };
            for (flag, p) in t.locked.iter().zip(params) {
                if *flag {
                    names.push(format!("types.{}.{p}", t.type_name()));
                }
            }
        }
        Ok((names, true))
    } else {
        let names = lock.split(',').map(|s| s.trim().to_string());
        Ok((names.filter(|s| !s.is_empty()).collect(), false))
    }
}

/// Convergence log, CSV or JSON lines by extension, flushed every row.
struct LogWriter {
    out: BufWriter<File>,
    jsonl: bool,
}

impl LogWriter {
    fn create(path: &std::path::Path) -> Result<Self> {
        let file = File::create(path).with_context(|| format!("{}", path.display()))?;
        let jsonl = path
            .extension()
            .is_some_and(|e| e == "jsonl" || e == "json");
        let mut out = BufWriter::new(file);
        if !jsonl {
            writeln!(out, "{}", HistoryRow::CSV_HEADER)?;
        }
        Ok(LogWriter { out, jsonl })
    }

    fn flush(&mut self) -> Result<()> {
        self.out.flush()?;
        Ok(())
    }
}

impl Observer for LogWriter {
    fn observe(&mut self, row: &HistoryRow) -> bool {
        let line = if self.jsonl {
            serde_json::to_string(row).unwrap_or_default()
        } else {
            row.csv()
        };
        let _ = writeln!(self.out, "{line}");
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
        let bar = indicatif::ProgressBar::new(generations.unwrap_or(0));
        bar.set_style(
            indicatif::ProgressStyle::with_template(
                "{elapsed_precise} [{bar:30}] gen {pos}/{len} (eta {eta}) {msg}",
            )
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
