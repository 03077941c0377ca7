//! One identification session, for the CLI, Python and the benches alike.
//!
//! An [`IdentifyRequest`] says everything a run needs: the scene, the observed takes, the
//! strategy and its options, the stop rules, noise, locks, a total mass, a stable horizon,
//! checkpoint/resume and threads. [`Session::new`] validates every option once (finite, in
//! range, its unit in the message), prepares the data and the [`Problem`], picks the strategy
//! and refuses what cannot run *before any work*: an exact solver on a cost it cannot solve,
//! unknown masses whose scale nothing fixes. [`Session::run`] runs it and returns an
//! [`Outcome`]: the run's numbers, the strategy's typed [`Report`], the identified scene and
//! the warnings a user must read.
//!
//! The front ends only translate their arguments into a request, so an option means the
//! same thing everywhere and a check cannot be forgotten by one of them; messages name the
//! option as the front end spells it ([`Style`]: `--total-mass` or `total_mass`).

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Duration;

use cordis_core::thesis::GeneParams;
use cordis_core::{Observations, Scene, Trajectory};

use crate::cost::{CostKind, LocalCost};
use crate::evaluator::Evaluator;
use crate::executor::{self, Fingerprint, Observer, RunConfig, RunResult, StopReason, StopRules};
use crate::identify::{self, make_islands, make_strategy, StrategyName, StrategyOptions};
use crate::output_error::checks::{linked, unestimable_state};
use crate::output_error::Take;
use crate::problem::Problem;
use crate::report::Report;
use crate::stable::StableHorizon;
use crate::strategies::cmaes::Restarts;
use crate::strategies::exact;
use crate::strategies::islands::IslandConfig;
use crate::strategies::thesis::Crossover;
use crate::strategy::Strategy;
use crate::CostError;

/// Generations between two checkpoints.
pub const CHECKPOINT_EVERY: u64 = 50;
/// Generations run when no stop rule is given at all.
pub const DEFAULT_GENERATIONS: u64 = 1000;
/// Population when neither the request nor a `Param.gene` file gives one.
pub const DEFAULT_POPULATION: usize = 100;
/// Longest accepted time limit, s (a year): `Duration` overflows far beyond, and a longer
/// limit is no limit.
pub const MAX_TIME_LIMIT: f64 = 365.0 * 24.0 * 3600.0;

/// How the front end spells its options, for messages that name them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Style {
    /// `--total-mass`.
    #[default]
    Cli,
    /// `total_mass`.
    Python,
}

impl Style {
    /// The option `name` (snake_case) as this front end spells it.
    pub fn opt(self, name: &str) -> String {
        match self {
            Style::Cli => format!("--{}", name.replace('_', "-")),
            Style::Python => name.to_string(),
        }
    }
}

/// The generation budget.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Generations {
    /// A `Param.gene` file's `generation`, else [`DEFAULT_GENERATIONS`] when no other stop rule
    /// is given, else none.
    #[default]
    Default,
    /// At most this many generations after generation 0.
    Limit(u64),
    /// No generation limit.
    Unlimited,
}

/// Everything an identification run needs.
#[derive(Clone, Debug)]
pub struct IdentifyRequest {
    /// The scene, unknowns written `{"min", "max"}`.
    pub scene: Scene,
    /// Where the scene came from (a file name, `scene`), to place messages.
    pub scene_place: String,
    /// The observed takes, particle `i` of each the scene's particle `i`; NaN is a missing
    /// coordinate and particles beyond a take's are hidden (only `output-error` reads gaps
    /// and several takes; the other strategies refuse them by name).
    pub takes: Vec<Observations>,
    /// Where each take came from (a file name), to place messages about it; a take with no
    /// entry is named as the front end spells the option (`--trajectory`, `trajectory[1]`).
    pub take_places: Vec<String>,
    /// Which scene particle each tracked marker (a take's particle index) is, the same for
    /// every take (`None`: marker `i` is particle `i`). Particles no marker names are hidden;
    /// fixed ones need not be tracked at all.
    pub markers: Option<Vec<usize>>,
    /// The output-error fit's loss on each residual: squared, or robust (`huber`, `cauchy`)
    /// against tracking outliers and swapped markers.
    pub loss: crate::output_error::Loss,
    /// The output-error fit's 95 % intervals: Wald (checked along a line) or the profile
    /// likelihood's.
    pub intervals: crate::output_error::Intervals,
    /// Each marker's weight, 1/σ relative to the others (one per marker, or three per marker:
    /// x, y, z), read by `output-error` only (`None`: all 1).
    pub weights: Option<Vec<f64>>,
    /// `--strategy`.
    pub strategy: StrategyName,
    /// Population (λ, chains, …); `None`: the `Param.gene` file's, else [`DEFAULT_POPULATION`].
    pub population: Option<usize>,
    /// A thesis `Param.gene` file (population, pcross, pmut, reducer, generation, noise;
    /// `damping` only as 0).
    pub param_gene: Option<PathBuf>,
    /// `thesis` and `t2m`: first generation of Powell's descent, and generations between two
    /// (`None`: 400 and 100; given with another strategy, refused by name).
    pub descent_start: Option<u64>,
    pub descent_every: Option<u64>,
    /// `thesis` and `t2m`: the crossover (Annexe 1's mean, or §3.2's n- or m·n-parent;
    /// `None`: the mean; given with another strategy, refused by name).
    pub crossover: Option<Crossover>,
    /// `thesis` and `t2m`: the local costs that drive their local operators, the position
    /// error or eq 3.3's neighbour distances (`None`: positions; given with another strategy,
    /// refused by name).
    pub local_cost: Option<LocalCost>,
    /// `cmaes`: IPOP or BIPOP restarts (`None`: IPOP; given with another strategy, refused by
    /// name).
    pub restarts: Option<Restarts>,
    /// `self-adaptive`: (μ+λ) selection (parents compete with their children) instead of (μ,λ).
    pub plus: bool,
    /// `self-adaptive`: correlated mutations (one rotation angle per pair of coordinates).
    pub correlated: bool,
    /// An island model of the strategy, when given.
    pub islands: Option<IslandConfig>,
    /// Cost kind.
    pub cost: CostKind,
    pub generations: Generations,
    pub max_evals: Option<u64>,
    /// Seconds.
    pub time_limit: Option<f64>,
    /// Stop once the best cost is at or below this (the cost's unit, m² for most kinds).
    pub target_cost: Option<f64>,
    /// Seed of every random draw.
    pub seed: u64,
    /// Standard deviation of the Gaussian noise added to the observed positions, m (0: none;
    /// then the `Param.gene` file's, if any).
    pub noise: f64,
    /// Unknowns to keep at their starting value: a thesis `NAME.lock` file, or names.
    pub lock: Option<Lock>,
    /// Known total mass of the free particles, kg.
    pub total_mass: Option<f64>,
    /// Frames of the free run a candidate must survive, and the spread factor.
    pub stable_horizon: Option<usize>,
    pub stable_spread: f64,
    /// The true scene, to report the parameter error.
    pub truth: Option<Scene>,
    pub checkpoint: Option<PathBuf>,
    pub resume: Option<PathBuf>,
    /// Worker threads (`None`: all cores); more than the machine has are capped, with a warning.
    pub threads: Option<usize>,
    pub style: Style,
}

/// What `lock` names.
#[derive(Clone, Debug, PartialEq)]
pub enum Lock {
    /// A thesis `.lock` file: its `x` flags mark l0 (or the rest cosine), K and Z of a type.
    File(PathBuf),
    /// Unknown names (`types.rib.stiffness`, `particles[3].mass`); each must exist.
    Names(Vec<String>),
}

impl IdentifyRequest {
    /// A request with the defaults of `cordis identify` for `scene` and one complete take.
    pub fn new(scene: Scene, take: Trajectory) -> Self {
        Self::with_takes(scene, vec![Observations::from_trajectory(&take)])
    }

    /// A request with the defaults of `cordis identify` for `scene` and takes as recorded
    /// (gaps are NaN; see [`IdentifyRequest::takes`]).
    pub fn with_takes(scene: Scene, takes: Vec<Observations>) -> Self {
        IdentifyRequest {
            scene,
            scene_place: "scene".into(),
            takes,
            take_places: Vec::new(),
            markers: None,
            weights: None,
            loss: crate::output_error::Loss::Squared,
            intervals: crate::output_error::Intervals::Wald,
            strategy: StrategyName::Auto,
            population: None,
            param_gene: None,
            descent_start: None,
            descent_every: None,
            crossover: None,
            local_cost: None,
            restarts: None,
            plus: false,
            correlated: false,
            islands: None,
            cost: CostKind::Short,
            generations: Generations::Default,
            max_evals: None,
            time_limit: None,
            target_cost: None,
            seed: 0,
            noise: 0.0,
            lock: None,
            total_mass: None,
            stable_horizon: None,
            stable_spread: crate::stable::DEFAULT_SPREAD,
            truth: None,
            checkpoint: None,
            resume: None,
            threads: None,
            style: Style::Cli,
        }
    }

    fn opt(&self, name: &str) -> String {
        self.style.opt(name)
    }

    /// Take `k` as messages name it: its file, else the option (indexed when there are
    /// several takes).
    fn take_place(&self, k: usize) -> String {
        match self.take_places.get(k) {
            Some(place) => place.clone(),
            None if self.takes.len() == 1 => self.opt("trajectory"),
            None => format!("{}[{k}]", self.opt("trajectory")),
        }
    }
}

/// A prepared run: the problem built, the strategy chosen and checked.
pub struct Session {
    problem: Problem,
    strategy: Box<dyn Strategy>,
    ran: &'static str,
    scene: Scene,
    data: Trajectory,
    config: RunConfig,
    threads: usize,
    warnings: Vec<String>,
}

/// What a run found.
pub struct Outcome {
    /// The run's numbers: best genome, cost, evaluations, history, why it stopped.
    pub result: RunResult,
    /// The strategy's own report.
    pub report: Report,
    /// One identified scene per take (never empty), each with the identified values written
    /// in and that take's estimated initial state, so that simulating `scenes[k]` replays take
    /// k; a single scene, with the initial state as given, when the strategy estimates none.
    pub scenes: Vec<Scene>,
    /// The problem it ran on (unknowns, truth).
    pub problem: Problem,
    /// What the user must read before trusting the answer: the report's warnings and the
    /// session's own (threads capped, every candidate rejected as unstable).
    pub warnings: Vec<String>,
}

impl Outcome {
    /// The identified scene: every identified value written in, and take 0's estimated initial
    /// state when the strategy estimated one.
    pub fn scene(&self) -> &Scene {
        &self.scenes[0]
    }
}

impl Session {
    /// Validates `req`, prepares its data and problem, picks and checks the strategy.
    pub fn new(req: IdentifyRequest) -> Result<Session, CostError> {
        validate(&req)?;
        let mut warnings = Vec::new();
        let threads = cap_threads(&req, &mut warnings);
        let gene = read_gene(&req)?;
        let noise = match req.noise {
            n if n > 0.0 => n,
            _ => gene.as_ref().and_then(|g| g.noise).unwrap_or(0.0),
        };
        if noise != req.noise {
            // The gene file's level (`validate` checked the request's own).
            check_noise(&req, noise)?;
        }
        let (data, takes) = prepare_takes(&req, noise)?;
        warnings.extend(fixed_far_from_the_scene(&req, &takes, noise));
        let mut problem = build_problem(&req, &data)?;
        let recorded = takes.len() > 1
            || req.weights.is_some()
            || takes
                .iter()
                .any(|t| t.observed() < t.frames() * t.particles() * 3);
        if recorded {
            problem = problem.with_takes(takes);
        }
        let defaults = StrategyOptions::default();
        let options = StrategyOptions {
            population: req
                .population
                .or(gene.as_ref().and_then(|g| g.population).map(|p| p as usize))
                .unwrap_or(DEFAULT_POPULATION),
            descent_start: req.descent_start.unwrap_or(defaults.descent_start),
            descent_every: req.descent_every.unwrap_or(defaults.descent_every),
            crossover: req.crossover.unwrap_or(defaults.crossover),
            gene: gene.clone(),
            loss: req.loss,
            intervals: req.intervals,
            plus: req.plus,
            correlated: req.correlated,
            restarts: req.restarts.unwrap_or_default(),
        };
        check_self_adaptive_options(&req)?;
        check_islands(&req, options.population)?;
        check_memory(&req, &problem, &options)?;
        check_horizon_time(&req, &problem)?;
        let (strategy, ran) = match req.islands {
            // The option's place as the front end spells it (`--islands`, `islands`).
            Some(c) => make_islands(req.strategy, &problem, &options, c).map_err(|e| match e {
                CostError::Refused { message, .. } => {
                    CostError::refused(req.opt("islands"), message)
                }
                CostError::Invalid { place, message } => {
                    CostError::invalid(req.opt(&place), message)
                }
                other => other,
            })?,
            None => make_strategy(req.strategy, &problem, &options),
        };
        check_thesis_options(&req, ran, gene.as_ref())?;
        check_cmaes_options(&req, ran)?;
        check(&req, ran, &problem)?;
        // Only a checkpoint reads it; hashing the data costs a pass over it.
        let fingerprint = (req.checkpoint.is_some() || req.resume.is_some())
            .then(|| fingerprint(&req, &data, noise, &options));
        let config = RunConfig {
            seed: req.seed,
            stop: stop_rules(&req, gene.as_ref()),
            checkpoint: req.checkpoint.clone(),
            checkpoint_every: CHECKPOINT_EVERY,
            resume: req.resume.clone(),
            fingerprint,
        };
        Ok(Session {
            problem,
            strategy,
            ran,
            scene: req.scene,
            data,
            config,
            threads,
            warnings,
        })
    }

    /// The strategy that will run (`auto` resolved; each island's for an island model).
    pub fn strategy(&self) -> &'static str {
        self.ran
    }

    /// The take as the strategies see it (noise added): what a remote evaluator must compile.
    pub fn data(&self) -> &Trajectory {
        &self.data
    }

    /// The problem (unknowns, truth).
    pub fn problem(&self) -> &Problem {
        &self.problem
    }

    /// The stop rules in force (the default generation budget resolved).
    pub fn stop_rules(&self) -> &StopRules {
        &self.config.stop
    }

    /// Warnings known before the run (threads capped).
    pub fn warnings(&self) -> &[String] {
        &self.warnings
    }

    /// Evaluates populations with `evaluator` (a remote executor) instead of this process.
    pub fn with_evaluator(mut self, evaluator: Arc<dyn Evaluator>) -> Self {
        self.problem = self.problem.with_evaluator(evaluator);
        self
    }

    /// Runs to a stop rule, an observer's stop or `interrupt`, on a pool of the session's
    /// threads.
    pub fn run(
        mut self,
        observers: &mut [&mut dyn Observer],
        interrupt: Option<&AtomicBool>,
    ) -> Result<Outcome, CostError> {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(self.threads)
            .build()
            .map_err(|e| CostError::run("threads", e.to_string()))?;
        let (problem, strategy, config) = (&mut self.problem, self.strategy.as_mut(), &self.config);
        let result =
            pool.install(|| executor::run_typed(problem, strategy, config, observers, interrupt))?;
        let report = self.strategy.report();
        let identified = self.problem.space.scene_with(&self.scene, &result.genome);
        let mut scenes: Vec<Scene> = self
            .strategy
            .initial_states()
            .iter()
            .map(|state| {
                let mut scene = identified.clone();
                state.apply(&mut scene);
                scene
            })
            .collect();
        if scenes.is_empty() {
            scenes.push(identified);
        }
        let mut warnings = self.warnings;
        warnings.extend(report.warnings());
        if result.cost.is_finite() {
            warnings.extend(crate::stable::beyond_bound_warning(&scenes[0]));
        } else {
            let why = match self.problem.stable_horizon() {
                Some(h) => format!(
                    "stable horizon {}: every candidate evaluated was rejected as unstable \
                     (widen the budget, or narrow the boxes)",
                    h.frames
                ),
                None => "every candidate evaluated diverged (cost inf: its motion left the \
                         observed one's size and speeds a millionfold, or was not finite); \
                         widen the budget, or narrow the boxes"
                    .to_string(),
            };
            // No finite cost is no estimate: an error, not the best diverging candidate as a
            // model. Ctrl-C keeps its own ending (the best so far, the checkpoint resumes).
            if result.stopped_by != StopReason::Interrupted {
                return Err(CostError::run(
                    self.strategy.name(),
                    format!(
                        "no estimate ({} reached): {why}",
                        result.stopped_by.as_str()
                    ),
                ));
            }
            warnings.push(why);
        }
        Ok(Outcome {
            result,
            report,
            scenes,
            problem: self.problem,
            warnings,
        })
    }
}

/// Every marker names a particle of the scene, no particle twice; every weight is a positive
/// finite number (their counts are each take's, checked with it: [`check_take`]).
fn validate_markers(req: &IdentifyRequest) -> Result<(), CostError> {
    let n = req.scene.num_particles();
    let at = |name: &str, k: usize| format!("{}[{k}]", req.opt(name));
    if let Some(markers) = &req.markers {
        let mut owner = vec![None; n];
        for (m, &p) in markers.iter().enumerate() {
            if p >= n {
                return Err(CostError::invalid(
                    at("markers", m),
                    format!("particle {p} does not exist (the scene has {n}, from 0)"),
                ));
            }
            if let Some(first) = owner[p] {
                return Err(CostError::invalid(
                    at("markers", m),
                    format!("particle {p} is already tracked by marker {first}"),
                ));
            }
            owner[p] = Some(m);
        }
    }
    if let Some((k, why)) = req
        .weights
        .as_deref()
        .and_then(cordis_core::arg::bad_weight)
    {
        return Err(CostError::invalid(at("weights", k), why));
    }
    Ok(())
}

/// Take `k` against the request before it is read: as many markers as `markers` names and
/// `weights` weighs (the counts are the file's, so the refusal names both the option and the
/// file), and enough frames for the cost. Every take is bad input alike, whatever its
/// position: a short second take used to reach the estimator and fail as a run (exit 1).
fn check_take(req: &IdentifyRequest, k: usize, obs: &Observations) -> Result<(), CostError> {
    let place = req.take_place(k);
    let (count, n) = (obs.particles(), req.scene.num_particles());
    match &req.markers {
        Some(m) if m.len() != count => {
            return Err(CostError::invalid(
                req.opt("markers"),
                format!(
                    "names {} particles for the {count} markers of {place}",
                    m.len()
                ),
            ))
        }
        // No mapping helps: markers name distinct particles.
        None if count > n => {
            return Err(cordis_core::CordisError::trajectory(
                place,
                format!("has {count} particles but the scene has {n}"),
            )
            .into())
        }
        _ => {}
    }
    if let Some(w) = req
        .weights
        .as_ref()
        .filter(|w| w.len() != count && w.len() != 3 * count)
    {
        return Err(CostError::invalid(
            req.opt("weights"),
            format!(
                "holds {} values for the {count} markers of {place}: give one per marker or \
                 three (x, y, z)",
                w.len()
            ),
        ));
    }
    let min = req.cost.min_frames();
    if obs.frames() < min {
        return Err(cordis_core::CordisError::trajectory(
            place,
            match obs.frames() {
                1 => format!("has 1 frame, at least {min} are needed"),
                f => format!("has {f} frames, at least {min} are needed"),
            },
        )
        .into());
    }
    Ok(())
}

/// Every numeric option in range, once, for every front end.
fn validate(req: &IdentifyRequest) -> Result<(), CostError> {
    let bad = |name: &str, m: String| Err(CostError::invalid(req.opt(name), m));
    if !req.scene.has_unknowns() {
        return Err(cordis_core::CordisError::scene(
            &req.scene_place,
            "no parameter to identify: write unknowns as {\"min\": …, \"max\": …}",
        )
        .into());
    }
    if let Some(p) = req.population.filter(|&p| p < 2) {
        return bad("population", format!("must be 2 or more, got {p}"));
    }
    // A budget of 0 generations (or evaluations, or seconds) is generation 0 alone: the
    // exact solvers' whole solve (`generations=0` is what docs/python.md tells their users),
    // the evolution strategies' first population; an output-error fit it stops reports
    // `end: stopped`, not `running`.
    if let Some(t) = req.time_limit {
        if !(t.is_finite() && (0.0..=MAX_TIME_LIMIT).contains(&t)) {
            return bad(
                "time_limit",
                format!("must be seconds in [0, {MAX_TIME_LIMIT:.0}] (a year), got {t:?}"),
            );
        }
    }
    if let Some(c) = req.target_cost.filter(|c| !c.is_finite()) {
        return bad("target_cost", format!("must be a finite number, got {c:?}"));
    }
    if req.threads == Some(0) {
        return bad("threads", "must be 1 or more (default: all cores)".into());
    }
    validate_markers(req)?;
    if let Some(m) = req.total_mass {
        if !(m.is_finite() && m > 0.0) {
            return bad(
                "total_mass",
                format!("must be a positive number of kg, got {m:?}"),
            );
        }
    }
    check_noise(req, req.noise)
}

fn check_noise(req: &IdentifyRequest, noise: f64) -> Result<(), CostError> {
    if !(noise.is_finite() && noise >= 0.0) {
        return Err(CostError::invalid(
            req.opt("noise"),
            format!("must be a standard deviation ≥ 0 m, got {noise:?}"),
        ));
    }
    if noise == 0.0 {
        return Ok(());
    }
    // The scene's particles and every observed position (NaN, missing, is left out).
    let observed = req
        .takes
        .iter()
        .flat_map(|t| t.as_flat().chunks_exact(3).map(|p| [p[0], p[1], p[2]]));
    let at = req.scene.particles.iter().map(|p| p.pos).chain(observed);
    let size = cordis_core::from_markers::extent_of(at);
    match cordis_core::arg::noise_out_of_scale(noise, size, "the scene and its motion") {
        Some(why) => Err(CostError::invalid(req.opt("noise"), why)),
        None => Ok(()),
    }
}

/// A fixed particle observed on average farther from where the scene holds it than this
/// fraction of the scene's size (and than [`FIXED_FAR_NOISE`] times the noise added by
/// `noise`) is a sign of a wrong map or unit, not of tracking noise.
const FIXED_FAR: f64 = 0.05;

/// The mean distance of a point with Gaussian noise σ per coordinate is 1.6 σ: five σ is far.
const FIXED_FAR_NOISE: f64 = 5.0;

/// Takes whose observed fixed particles sit far from the scene's positions for them (module
/// constant [`FIXED_FAR`]): one warning per take naming the farthest. A file in mm for a scene
/// in m, a forgotten `--markers`, a shifted origin: each ran to a fit that diverged or stayed
/// far above the noise, with advice about boxes and dt and no word about the data.
fn fixed_far_from_the_scene(req: &IdentifyRequest, takes: &[Take], noise: f64) -> Vec<String> {
    takes
        .iter()
        .enumerate()
        .filter_map(|(k, take)| {
            fixed_far_warning(
                &req.scene,
                take,
                noise,
                &req.take_place(k),
                &req.opt("markers"),
            )
        })
        .collect()
}

/// The warning of [`fixed_far_from_the_scene`] for one take placed `place`, `markers` the
/// option that maps markers to particles as the front end spells it: also what `cordis
/// report` says of a file read without the `--markers` its fit had (its page showed a fit
/// RMS of 0.235 m for one of 1 mm, silently).
pub fn fixed_far_warning(
    scene: &Scene,
    take: &Take,
    noise: f64,
    place: &str,
    markers: &str,
) -> Option<String> {
    let at: Vec<[f64; 3]> = scene.particles.iter().map(|p| p.pos).collect();
    let size = cordis_core::from_markers::extent(&at);
    if size.is_nan() || size <= 0.0 {
        return None;
    }
    let far_enough = (FIXED_FAR * size).max(FIXED_FAR_NOISE * noise);
    let mut far: Vec<(usize, f64)> = Vec::new();
    for (i, p) in scene.particles.iter().enumerate().filter(|(_, p)| p.fixed) {
        let (mut sum, mut count) = (0.0, 0usize);
        for t in 0..take.frames() {
            let seen = [0, 1, 2].map(|c| take.at(t, i, c));
            if seen.iter().all(|&(_, w)| w > 0.0) {
                let d2: f64 = (0..3).map(|c| (seen[c].0 - p.pos[c]).powi(2)).sum();
                sum += d2.sqrt();
                count += 1;
            }
        }
        if count > 0 && sum / count as f64 > far_enough {
            far.push((i, sum / count as f64));
        }
    }
    let &(i, d) = far.iter().max_by(|a, b| a.1.total_cmp(&b.1))?;
    Some(format!(
        "{place}: {} fixed particle{} observed far from where the scene holds {} (particle \
         {i}: {d:.3e} m on average, {:.0} % of the scene's size): check {markers}, the data's \
         units and the scene",
        far.len(),
        if far.len() == 1 { " is" } else { "s are" },
        if far.len() == 1 { "it" } else { "them" },
        100.0 * d / size,
    ))
}

/// `threads`, at most the machine's parallelism: more only adds switching (and a hundred
/// thousand threads take the machine down); the result is the same on any count.
fn cap_threads(req: &IdentifyRequest, warnings: &mut Vec<String>) -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    match req.threads {
        Some(t) if t > cores => {
            warnings.push(format!(
                "{} {t}: capped to the machine's {cores} (the result does not depend on it)",
                req.opt("threads")
            ));
            cores
        }
        Some(t) => t,
        None => 0,
    }
}

fn read_gene(req: &IdentifyRequest) -> Result<Option<GeneParams>, CostError> {
    let Some(p) = &req.param_gene else {
        return Ok(None);
    };
    let text = cordis_core::io::read_text(p)?;
    let name = p.display().to_string();
    let gene = cordis_core::thesis::parse_gene(&name, &text)?;
    check_gene_damping(&name, &text, &gene)?;
    Ok(Some(gene))
}

/// `damping` is the one `Param.gene` key no strategy reads: Annexe 1 lists `damping=0` without
/// saying what it sets (an added damping, or no damping genes: its genome has none). Both
/// readings leave a scene as it is at 0, so 0 is accepted; any other value is refused by name
/// rather than silently ignored.
fn check_gene_damping(name: &str, text: &str, gene: &GeneParams) -> Result<(), CostError> {
    match gene.damping {
        Some(d) if d != 0.0 => {
            let line = text
                .lines()
                .position(|l| {
                    l.split_once('=')
                        .is_some_and(|(k, _)| k.trim() == "damping")
                })
                .map_or(0, |k| k + 1);
            Err(CostError::invalid(
                format!("{name}:{line}"),
                format!(
                    "damping={d}: not supported (the thesis does not say what Param.gene's \
                     `damping` sets; only damping=0 is accepted): give the dampings in the \
                     scene, known or as {{\"min\", \"max\"}}"
                ),
            ))
        }
        _ => Ok(()),
    }
}

/// The problem of `data`: cost, locks, truth, stable horizon, total mass.
fn build_problem(req: &IdentifyRequest, data: &Trajectory) -> Result<Problem, CostError> {
    let mut problem = Problem::new(&req.scene, data, req.cost)?;
    if let Some(lock) = &req.lock {
        let names = lock_names(req, &problem, lock)?;
        problem.space.lock(&names);
    }
    if let Some(t) = &req.truth {
        if t.has_unknowns() || t.param_layout() != req.scene.param_layout() {
            return Err(cordis_core::CordisError::scene(
                req.opt("truth"),
                "must be the scene with every parameter known (same types and particles)",
            )
            .into());
        }
        problem = problem.with_truth(t)?;
    }
    if let Some(h) = req.stable_horizon {
        problem = problem.with_stable_horizon(StableHorizon::new(h, req.stable_spread)?);
    }
    if let Some(m) = req.total_mass {
        problem = problem.with_total_mass(m)?;
    }
    if let Some(local) = req.local_cost {
        problem = problem.with_local_cost(local).map_err(|e| match e {
            CostError::Invalid { message, .. } => {
                CostError::invalid(req.opt("local_cost"), message)
            }
            other => other,
        })?;
    }
    Ok(problem)
}

/// The unknowns a lock names. A `.lock` file may lock what the scene already knows; a name
/// given by hand must be an unknown.
fn lock_names(
    req: &IdentifyRequest,
    problem: &Problem,
    lock: &Lock,
) -> Result<Vec<String>, CostError> {
    match lock {
        Lock::File(path) => {
            let place = path.display().to_string();
            let text = cordis_core::io::read_text(path)?;
            let mut names = Vec::new();
            for t in cordis_core::thesis::parse_lock(&place, &text)? {
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
            Ok(names)
        }
        Lock::Names(names) => {
            let unknowns = &problem.space.unknowns;
            if let Some(bad) = names
                .iter()
                .find(|n| !unknowns.iter().any(|u| &u.name == *n))
            {
                return Err(CostError::invalid(
                    req.opt("lock"),
                    format!("`{bad}` is not an unknown of {}", req.scene_place),
                ));
            }
            Ok(names.clone())
        }
    }
}

/// The stop rules, the default generation budget resolved.
fn stop_rules(req: &IdentifyRequest, gene: Option<&GeneParams>) -> StopRules {
    let other = req.time_limit.is_some() || req.max_evals.is_some() || req.target_cost.is_some();
    let generations = match req.generations {
        Generations::Limit(g) => Some(g),
        Generations::Unlimited => None,
        Generations::Default => gene
            .and_then(|g| g.generation)
            .or((!other).then_some(DEFAULT_GENERATIONS)),
    };
    StopRules {
        generations,
        max_evals: req.max_evals,
        time_limit: req.time_limit.map(Duration::from_secs_f64),
        target_cost: req.target_cost,
    }
}

/// Refuses, before any work, what the chosen strategy cannot run, and unknown masses whose
/// scale nothing fixes (masses and forces then trade off: every answer is a box centre).
fn check(req: &IdentifyRequest, ran: &str, problem: &Problem) -> Result<(), CostError> {
    let place = format!("{} ({ran})", req.scene_place);
    // Options only output-error reads, set to something else than their default.
    let output_error_only = [
        ("loss", req.loss.to_string(), req.loss != Default::default()),
        (
            "intervals",
            req.intervals.to_string(),
            req.intervals != Default::default(),
        ),
    ];
    if let Some((option, value, _)) = output_error_only
        .iter()
        .find(|(_, _, set)| *set && ran != "output-error")
    {
        return Err(CostError::invalid(
            req.opt(option),
            format!(
                "`{value}` is read by output-error only, not `{ran}` (use --strategy output-error or auto)"
            )
            .replace("--strategy", &req.opt("strategy")),
        ));
    }
    // Only the exact solvers put Σm = M into their solve; every other strategy would run as if
    // the total were not given (issue 19 item 7): refused by name rather than ignored.
    let honours_total = matches!(ran, "least-squares" | "hybrid");
    if req.total_mass.is_some() && !honours_total {
        return Err(CostError::invalid(
            req.opt("total_mass"),
            format!(
                "is honoured by least-squares and hybrid only (they constrain the free masses' \
                 sum in their solve); `{ran}` would ignore it: leave it out and make one mass \
                 known instead (a value in the scene, not a box: that fixes the scale for every \
                 strategy), or use {} least-squares or hybrid{}",
                req.opt("strategy"),
                match ran {
                    "output-error" => " (exact, but on noisy data they differentiate the noise)",
                    _ => "",
                }
            ),
        ));
    }
    if req.total_mass.is_none() {
        let split = exact::split(problem);
        if split.free_masses {
            if let Ok(cols) = exact::generic_cols(&problem.scene) {
                if exact::check_scale(problem, &split, &cols).is_err() {
                    return Err(CostError::refused(
                        &place,
                        format!(
                            "masses and forces are unknown together and only their ratios show \
                             in the motion: make a mass or a force known (a value in the scene, \
                             not a box), or pass {} (kg){}",
                            req.opt("total_mass"),
                            if req.strategy == StrategyName::Auto {
                                // auto picks output-error on noisy data, which refuses the
                                // total: the advice must not lead there.
                                format!(
                                    " with {} least-squares or hybrid (the strategies that \
                                     honour it; on noisy data they differentiate the noise, and \
                                     the output-error estimate auto would pick needs a known \
                                     mass or force)",
                                    req.opt("strategy")
                                )
                            } else if honours_total {
                                String::new()
                            } else {
                                format!(
                                    " with {} least-squares or hybrid (the strategies that \
                                     honour it)",
                                    req.opt("strategy")
                                )
                            }
                        ),
                    ));
                }
            }
        }
    }
    identify::check_strategy(ran, problem).map_err(|e| CostError::refused(place, e))
}

/// `plus` and `correlated` configure `self-adaptive` only: asked of another strategy, they are
/// refused by name rather than ignored.
fn check_self_adaptive_options(req: &IdentifyRequest) -> Result<(), CostError> {
    let asked = [("plus", req.plus), ("correlated", req.correlated)];
    match asked.iter().find(|(_, on)| *on) {
        Some((name, _)) if req.strategy != StrategyName::SelfAdaptive => Err(CostError::invalid(
            req.opt(name),
            format!(
                "configures the self-adaptive strategy only, not {}",
                req.strategy.name()
            ),
        )),
        _ => Ok(()),
    }
}

/// The thesis ES's own options, given with a strategy that would ignore them (issue 19):
/// refused by name, in one line. `ran` is what runs (`auto` resolved; each island's
/// strategy), so `auto` accepts them when it picks `t2m`. A `Param.gene` file is read by every
/// strategy for its `population`, `generation` and `noise`; its `pcross`, `pmut` and `reducer`
/// only by `thesis` and `t2m`.
fn check_thesis_options(
    req: &IdentifyRequest,
    ran: &str,
    gene: Option<&GeneParams>,
) -> Result<(), CostError> {
    if matches!(ran, "thesis" | "t2m") {
        return Ok(());
    }
    let which = match req.strategy {
        StrategyName::Auto => format!("{ran} (what auto picked here)"),
        _ => ran.to_string(),
    };
    let asked = [
        ("crossover", req.crossover.is_some()),
        ("descent_start", req.descent_start.is_some()),
        ("descent_every", req.descent_every.is_some()),
        ("local_cost", req.local_cost.is_some()),
    ];
    if let Some((name, _)) = asked.iter().find(|(_, given)| *given) {
        return Err(CostError::invalid(
            req.opt(name),
            format!("configures the thesis ES only (thesis, t2m), not {which}"),
        ));
    }
    let Some(g) = gene else { return Ok(()) };
    let keys: Vec<&str> = [
        ("pcross", g.pcross.is_some()),
        ("pmut", g.pmut.is_some()),
        ("reducer", g.reducer.is_some()),
    ]
    .iter()
    .filter_map(|&(k, set)| set.then_some(k))
    .collect();
    if keys.is_empty() {
        return Ok(());
    }
    let file = req
        .param_gene
        .as_ref()
        .map_or(String::new(), |p| format!(" {}", p.display()));
    Err(CostError::invalid(
        format!("{}{file}", req.opt("param_gene")),
        format!(
            "{} configure the thesis ES only (thesis, t2m), not {which} (which reads the \
             file's population, generation and noise): remove them or use {} thesis or t2m",
            keys.join(", "),
            req.opt("strategy")
        ),
    ))
}

/// `restarts` configures `cmaes` only (`ran`: what runs, `auto` resolved): asked of another
/// strategy, refused by name rather than ignored.
fn check_cmaes_options(req: &IdentifyRequest, ran: &str) -> Result<(), CostError> {
    if req.restarts.is_none() || ran == "cmaes" {
        return Ok(());
    }
    let which = match req.strategy {
        StrategyName::Auto => format!("{ran} (what auto picked here)"),
        _ => ran.to_string(),
    };
    Err(CostError::invalid(
        req.opt("restarts"),
        format!("configures the cmaes strategy only, not {which}"),
    ))
}

/// An island model's layout, each value under its own option's name: 2 or more islands,
/// migrations at least a generation apart, and no more migrants than an island holds
/// (`migrants` above the population used to be accepted and silently cut).
fn check_islands(req: &IdentifyRequest, population: usize) -> Result<(), CostError> {
    let Some(c) = req.islands else {
        return Ok(());
    };
    let bad = |name: &str, m: String| Err(CostError::invalid(req.opt(name), m));
    if c.islands < 2 {
        return bad(
            "islands",
            format!("must be 2 or more islands, got {}", c.islands),
        );
    }
    if c.migrate_every == 0 {
        return bad(
            "migrate_every",
            "must be 1 or more generations, got 0".into(),
        );
    }
    if c.migrants > population {
        return bad(
            "migrants",
            format!(
                "{} is more than an island's population of {population} (each island sends \
                 copies of its best to the next): give at most {population}",
                c.migrants
            ),
        );
    }
    Ok(())
}

/// Refuses a population whose individuals would not fit in memory (rather than aborting on
/// the allocation), with the estimate.
fn check_memory(
    req: &IdentifyRequest,
    problem: &Problem,
    options: &StrategyOptions,
) -> Result<(), CostError> {
    // Per individual: genes, step sizes and a few copies of them, local costs per particle;
    // parents and offspring both live during a generation.
    let per = 8.0 * (4.0 * problem.dim() as f64 + problem.num_particles as f64 + 8.0) * 2.0;
    let copies = req.islands.map_or(1, |c| c.islands.max(1)) as f64;
    let bytes = per * options.population as f64 * copies;
    let limit = available_memory();
    if bytes > limit {
        // Name the option that made it large: the islands multiply the population.
        let (name, what) = match req.islands {
            Some(c) if c.islands > 1 => (
                "islands",
                format!(
                    "{} islands of {} individuals",
                    c.islands, options.population
                ),
            ),
            _ => ("population", format!("{} individuals", options.population)),
        };
        return Err(CostError::invalid(
            req.opt(name),
            format!(
                "{what} need about {:.1} GiB, more than the {:.1} GiB available",
                bytes / GIB,
                limit / GIB
            ),
        ));
    }
    Ok(())
}

const GIB: f64 = 1024.0 * 1024.0 * 1024.0;

/// The longest one evaluation's free run may take without a time limit, s: a day.
pub const MAX_FREE_RUN_SECONDS: f64 = 24.0 * 3600.0;

/// Refuses a stable horizon whose free run, one per evaluation, cannot end within the time
/// limit (or within [`MAX_FREE_RUN_SECONDS`] without one): the run would spend its whole
/// budget inside its first evaluation and stop long past the limit (`time_limit` is checked
/// between generations). The time of a frame is measured here on the start parameters
/// (about 2 ms of probing), so a refusal says what this machine does.
fn check_horizon_time(req: &IdentifyRequest, problem: &Problem) -> Result<(), CostError> {
    let Some(frames) = req.stable_horizon else {
        return Ok(());
    };
    let per_frame = problem.seconds_per_frame(&problem.space.base, frames);
    let needed = per_frame * frames as f64;
    let (limit, what) = match req.time_limit {
        Some(t) => (t, format!("{} {t} s", req.opt("time_limit"))),
        None => (
            MAX_FREE_RUN_SECONDS,
            "a day (no time limit given)".to_string(),
        ),
    };
    if needed > limit {
        return Err(CostError::invalid(
            req.opt("stable_horizon"),
            format!(
                "{frames} frames: one candidate's free run takes about {needed:.2e} s here \
                 ({per_frame:.3e} s per frame, measured), beyond {what}; lower it"
            ),
        ));
    }
    Ok(())
}

/// Memory the run may use, bytes: `MemAvailable` on Linux, else 16 GiB.
fn available_memory() -> f64 {
    std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|t| {
            t.lines()
                .find_map(|l| l.strip_prefix("MemAvailable:"))
                .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<f64>().ok())
        })
        .map_or(16.0 * GIB, |kib| kib * 1024.0)
}

/// Take `k` is not an earlier take again, bit for bit, whole or cropped (the same file or
/// array given twice, or one the start of the other): its noise would count twice, and every
/// standard error shrink by √2 with nothing to show it (a tester's finding). Also with the
/// request's `noise` added: the copies then get different draws, but whatever noise the data
/// had already would still count twice.
fn check_not_repeated(req: &IdentifyRequest, k: usize) -> Result<(), CostError> {
    let obs = &req.takes[k];
    let repeats = |other: &Observations| {
        let frames = other.frames().min(obs.frames());
        let len = frames * obs.particles() * 3;
        other.particles() == obs.particles()
            && other.as_flat()[..len]
                .iter()
                .zip(&obs.as_flat()[..len])
                .all(|(a, b)| a.to_bits() == b.to_bits())
    };
    let Some(j) = req.takes[..k].iter().position(repeats) else {
        return Ok(());
    };
    let how = match req.takes[j].frames().cmp(&obs.frames()) {
        std::cmp::Ordering::Equal => "the same motion as",
        std::cmp::Ordering::Greater => "the start of",
        std::cmp::Ordering::Less => "a longer copy of",
    };
    Err(cordis_core::CordisError::trajectory(
        req.take_place(k),
        format!(
            "is {how} {} (take {j}), bit for bit: a take given twice counts its noise twice \
             and shrinks every standard error by √2",
            req.take_place(j)
        ),
    )
    .into())
}

/// The takes with the request's noise added (seeded as `try_add_noise`, take k from `seed +
/// k`), as the estimators read them, and the complete trajectory the costs are built on: the
/// first take itself when it is complete (bit for bit what one complete take always gave),
/// else its gaps filled by interpolation and hidden particles at the scene's positions.
fn prepare_takes(req: &IdentifyRequest, noise: f64) -> Result<(Trajectory, Vec<Take>), CostError> {
    if req.takes.is_empty() {
        return Err(CostError::invalid(req.opt("trajectory"), "no take given"));
    }
    let n = req.scene.num_particles();
    let free: Vec<usize> = (0..n).filter(|&i| !req.scene.particles[i].fixed).collect();
    let adjacency = linked(&req.scene);
    let mut takes = Vec::with_capacity(req.takes.len());
    let mut first = None;
    for (k, obs) in req.takes.iter().enumerate() {
        check_take(req, k, obs)?;
        check_not_repeated(req, k)?;
        let place = req.take_place(k);
        let noisy = match noise > 0.0 {
            true => identify::try_add_noise_observations(obs, noise, req.seed + k as u64)
                .ok_or_else(|| {
                    CostError::invalid(
                        req.opt("noise"),
                        format!("{noise:?} m makes the observed positions overflow"),
                    )
                })?,
            false => obs.clone(),
        };
        let mapped = req.markers.is_some() || req.weights.is_some();
        let take = match mapped {
            false => Take::from_observations(&noisy, n),
            true => Take::from_markers(
                noisy.frames(),
                noisy.as_flat(),
                n,
                req.markers.as_deref(),
                req.weights.as_deref(),
                None,
            ),
        };
        // What is left to refuse is the data's own (every coordinate missing, a value not
        // finite): the take's file is the place, the take's own place (a frame, a marker)
        // follows it.
        let take = take.map_err(|e| {
            let (at, message) = match e {
                CostError::Mismatch { place: at, message } if at == "trajectory" => {
                    (place.clone(), message)
                }
                CostError::Mismatch { place: at, message } => (format!("{place}, {at}"), message),
                e => (place.clone(), e.to_string()),
            };
            CostError::Core(cordis_core::CordisError::trajectory(at, message))
        })?;
        // Bad input named by the file, before any run (the estimator's own check names the
        // take's index and, reached in a run, was a run's failure: exit 1).
        if let Some((particle, why)) = unestimable_state(&req.scene, &adjacency, &free, &take) {
            let at = match particle {
                Some(i) => format!("{place}, particle {i}"),
                None => place,
            };
            return Err(cordis_core::CordisError::trajectory(at, why).into());
        }
        if k == 0 {
            first = Some(noisy);
        }
        takes.push(take);
    }
    let first = first.expect("at least one take");
    let dt = first.dt;
    let in_scene_order = req.markers.is_none() && first.particles() == n;
    let data = match in_scene_order && first.missing() == 0 {
        true => first.into_trajectory()?,
        false => {
            let at: Vec<cordis_core::Vec3> = req
                .scene
                .particles
                .iter()
                .map(|p| cordis_core::Vec3::from(p.pos))
                .collect();
            let mut t = takes[0].filled(&at);
            t.dt = dt;
            t
        }
    };
    Ok((data, takes))
}

/// What a checkpoint must match to be resumed by this request, by component.
fn fingerprint(
    req: &IdentifyRequest,
    data: &Trajectory,
    noise: f64,
    options: &StrategyOptions,
) -> Fingerprint {
    let mut f = Fingerprint::new();
    f.insert(
        "scene".into(),
        digest(req.scene.to_json_string().as_bytes()),
    );
    let bits: Vec<u8> = data
        .as_flat()
        .iter()
        .flat_map(|x| x.to_bits().to_le_bytes())
        .collect();
    f.insert("trajectory".into(), digest(&bits));
    if req.takes.len() > 1 || req.takes.iter().any(|t| t.missing() > 0) {
        let bits: Vec<u8> = req
            .takes
            .iter()
            .flat_map(|t| t.as_flat().iter().flat_map(|x| x.to_bits().to_le_bytes()))
            .collect();
        f.insert("takes".into(), digest(&bits));
    }
    if req.markers.is_some() || req.weights.is_some() {
        let weights: Option<Vec<u64>> = req
            .weights
            .as_ref()
            .map(|w| w.iter().map(|x| x.to_bits()).collect());
        f.insert("markers".into(), format!("{:?} {:?}", req.markers, weights));
    }
    f.insert("cost".into(), req.cost.to_string());
    if req.loss != crate::output_error::Loss::Squared {
        f.insert("loss".into(), req.loss.to_string());
    }
    // Written only when not the default, so older checkpoints still match.
    if req.intervals != crate::output_error::Intervals::Wald {
        f.insert("intervals".into(), req.intervals.to_string());
    }
    f.insert("noise".into(), format!("{noise:e}"));
    f.insert("population".into(), options.population.to_string());
    // The crossover is written only when not the default, so older checkpoints still match.
    let mut crossover = match options.crossover {
        Crossover::Mean => String::new(),
        c => format!(" {}", c.name()),
    };
    // Likewise self-adaptive's selection and mutation options.
    if options.plus {
        crossover.push_str(" plus");
    }
    if options.correlated {
        crossover.push_str(" correlated");
    }
    if req.local_cost == Some(LocalCost::Distances) {
        crossover.push_str(" local-cost distances");
    }
    if options.restarts == Restarts::Bipop {
        crossover.push_str(" bipop");
    }
    f.insert(
        "strategy options".into(),
        format!(
            "{:?} {} {} {:?}{crossover}",
            options.gene, options.descent_start, options.descent_every, req.islands
        ),
    );
    f.insert("lock".into(), format!("{:?}", req.lock));
    f.insert("total mass".into(), format!("{:?}", req.total_mass));
    f.insert(
        "stable horizon".into(),
        format!("{:?} {:e}", req.stable_horizon, req.stable_spread),
    );
    f
}

/// FNV-1a, 64 bits, in hex: stable across builds and platforms (std's hasher is not promised
/// to be), which a checkpoint read by another build needs.
fn digest(bytes: &[u8]) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for &b in bytes {
        h ^= u64::from(b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    format!("{h:016x}")
}

impl Lock {
    /// `--lock`'s syntax: a path ending in `.lock`, else comma-separated names.
    pub fn parse(text: &str) -> Lock {
        if text.ends_with(".lock") {
            Lock::File(text.into())
        } else {
            let names = text.split(',').map(|s| s.trim().to_string());
            Lock::Names(names.filter(|s| !s.is_empty()).collect())
        }
    }
}
