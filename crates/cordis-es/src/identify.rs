//! Choosing and configuring a strategy by name, and the data preparation `identify` shares
//! between the CLI and Python.

use cordis_core::thesis::GeneParams;
use cordis_core::Trajectory;

use crate::error::CostError;
use crate::output_error;
use crate::problem::space::Role;
use crate::problem::Problem;
use crate::run::rng;
use crate::run::strategy::Strategy;
use crate::strategies::annealing::{Annealing, AnnealingConfig};
use crate::strategies::cmaes::{Cmaes, CmaesConfig, Restarts};
use crate::strategies::exact;
use crate::strategies::islands::{IslandConfig, Islands};
use crate::strategies::levenberg_marquardt::{self, LevenbergMarquardt, LmConfig};
use crate::strategies::output_error::OutputError;
use crate::strategies::parisian::{Parisian, ParisianConfig};
use crate::strategies::self_adaptive::{SelfAdaptive, SelfAdaptiveConfig};
use crate::strategies::thesis::{Crossover, Thesis, ThesisConfig};
use crate::strategies::{self, hybrid, least_squares};

pub use crate::strategies::registry::StrategyName;

/// What a strategy may be configured with, from the CLI or Python.
#[derive(Clone, Debug, PartialEq)]
pub struct StrategyOptions {
    pub population: usize,
    /// Thesis `Param.gene` values.
    pub gene: Option<GeneParams>,
    /// Thesis strategy: Powell's descent from this generation, every `descent_every`.
    pub descent_start: u64,
    pub descent_every: u64,
    /// `thesis` and `t2m`: the crossover (Annexe 1's mean, or §3.2's n- or m·n-parent).
    pub crossover: Crossover,
    /// The output-error fit's loss on each residual.
    pub loss: output_error::Loss,
    /// The output-error fit's intervals (Wald, or the profile likelihood's).
    pub intervals: output_error::Intervals,
    /// `self-adaptive`: (μ+λ) selection instead of (μ,λ).
    pub plus: bool,
    /// `self-adaptive`: correlated mutations (rotation angles, Schwefel).
    pub correlated: bool,
    /// `cmaes`: IPOP or BIPOP restarts.
    pub restarts: Restarts,
}

impl Default for StrategyOptions {
    fn default() -> Self {
        let t = ThesisConfig::default();
        StrategyOptions {
            population: t.population,
            gene: None,
            descent_start: t.descent_start,
            descent_every: t.descent_every,
            crossover: t.crossover,
            loss: output_error::Loss::Squared,
            intervals: output_error::Intervals::Wald,
            plus: false,
            correlated: false,
            restarts: Restarts::Ipop,
        }
    }
}

/// Builds the named strategy; returns it with the name of what will actually run.
pub fn make_strategy(
    name: StrategyName,
    problem: &Problem,
    options: &StrategyOptions,
) -> (Box<dyn Strategy>, &'static str) {
    let robust = options.loss != output_error::Loss::Squared;
    let (auto_reason, solved) = match name {
        StrategyName::Auto if robust && strategies::output_error::supported(problem).is_ok() => (
            Some(format!("a robust loss ({}) is asked for", options.loss)),
            None,
        ),
        StrategyName::Auto
            if options.intervals != output_error::Intervals::Wald
                && strategies::output_error::supported(problem).is_ok() =>
        {
            (
                Some(format!("{} intervals are asked for", options.intervals)),
                None,
            )
        }
        StrategyName::Auto => auto_probe(problem),
        _ => (None, None),
    };
    let name = match name {
        StrategyName::Auto if auto_reason.is_some() => StrategyName::OutputError,
        StrategyName::Auto => match exact::supported(problem) {
            Ok(()) if exact::split(problem).nonlinear.is_empty() => StrategyName::LeastSquares,
            Ok(()) => StrategyName::Hybrid,
            Err(_) if smooth_short_cost(problem) => StrategyName::LevenbergMarquardt,
            Err(_) => StrategyName::T2m,
        },
        other => other,
    };
    match name {
        StrategyName::LeastSquares => {
            let strategy = match solved {
                Some((s, evals)) => least_squares::strategy().with_solution(s, evals),
                None => least_squares::strategy(),
            };
            (Box::new(strategy), name.name())
        }
        StrategyName::Hybrid => (Box::new(hybrid::strategy()), name.name()),
        StrategyName::Thesis | StrategyName::T2m | StrategyName::Auto => {
            let (base, name) = match name {
                StrategyName::T2m => (ThesisConfig::t2m(), StrategyName::T2m),
                _ => (ThesisConfig::thesis(), StrategyName::Thesis),
            };
            let mut c = ThesisConfig {
                population: options.population,
                descent_start: options.descent_start,
                descent_every: options.descent_every,
                crossover: options.crossover,
                ..base
            };
            if let Some(g) = &options.gene {
                c.pcross = g.pcross.unwrap_or(c.pcross);
                c.pmut = g.pmut.unwrap_or(c.pmut);
                c.reducer = g.reducer.unwrap_or(c.reducer);
            }
            (Box::new(Thesis::new(c)), name.name())
        }
        // `population` is λ (the initial λ for cmaes, the number of chains for annealing, the
        // total over the sub-populations for parisian).
        StrategyName::Cmaes => {
            let c = CmaesConfig {
                population: Some(options.population),
                restarts: options.restarts,
                ..CmaesConfig::default()
            };
            (Box::new(Cmaes::new(c)), name.name())
        }
        StrategyName::SelfAdaptive => {
            let c = SelfAdaptiveConfig {
                plus: options.plus,
                correlated: options.correlated,
                ..SelfAdaptiveConfig::with_lambda(options.population)
            };
            (Box::new(SelfAdaptive::new(c)), name.name())
        }
        StrategyName::Annealing => {
            let c = AnnealingConfig {
                chains: options.population,
                ..AnnealingConfig::default()
            };
            (Box::new(Annealing::new(c)), name.name())
        }
        StrategyName::Parisian => {
            let c = ParisianConfig {
                population: options.population,
                ..ParisianConfig::default()
            };
            (Box::new(Parisian::new(c)), name.name())
        }
        // No population: one point, its Jacobian's columns evaluated in parallel.
        StrategyName::LevenbergMarquardt => (
            Box::new(LevenbergMarquardt::new(LmConfig::default())),
            name.name(),
        ),
        StrategyName::OutputError => {
            let config = output_error::Config {
                loss: options.loss,
                intervals: options.intervals,
                ..output_error::Config::default()
            };
            let oe = OutputError::new(config).chosen_because(auto_reason);
            (Box::new(oe), name.name())
        }
    }
}

/// Relative short-cost residual above which data count as noisy: `√(C_min / A)` with `C_min`
/// the short cost's exact minimum and `A` what a model with no force would miss
/// ([`crate::cost::Objective::acceleration_cost`]). A network's own motion leaves 0 to
/// rounding (a CSV written by `cordis simulate` keeps every digit: ~1e-12); any measured
/// noise leaves far more, and there the short cost's errors-in-variables bias is what the
/// output-error fit removes.
pub const NOISY: f64 = 1e-6;

/// Why `auto` picks `output-error`, or `None` when it does not: observations are missing, or
/// the scene is linear in its unknowns and the short cost's exact minimum leaves a residual
/// above [`NOISY`] of the motion (the data are not what a network of this structure makes:
/// noise), and every kind has exact sensitivities. The short cost differentiates noise twice;
/// the output-error fit does not.
pub fn output_error_reason(problem: &Problem) -> Option<String> {
    auto_probe(problem).0
}

/// [`output_error_reason`], and the short cost's exact solution when it was computed to judge
/// the noise (the `least-squares` that `auto` then runs takes it instead of solving again).
fn auto_probe(problem: &Problem) -> (Option<String>, Option<(exact::Solution, u64)>) {
    if strategies::output_error::supported(problem).is_err() || problem.space.dim() == 0 {
        return (None, None);
    }
    if problem.has_missing() {
        return (
            Some("observations are missing (gaps or hidden particles)".into()),
            None,
        );
    }
    if problem.take_count() > 1 {
        let why = format!("{} takes share one parameter set", problem.take_count());
        return (Some(why), None);
    }
    if problem.has_weights() {
        return (Some("per-marker weights are given".into()), None);
    }
    if !matches!(problem.objective.kind(), crate::cost::CostKind::Short) {
        return (None, None);
    }
    let before = problem.evals();
    let Ok(solution) = least_squares::solve(problem) else {
        return (None, None);
    };
    let evals = problem.evals() - before;
    let motion = problem.objective.acceleration_cost();
    let residual = (solution.cost / motion.max(f64::MIN_POSITIVE)).sqrt();
    match residual > NOISY {
        true => (
            Some(format!(
                "the data look noisy: the short cost's exact minimum leaves {residual:.1e} of \
                 the motion's acceleration (noise, not a network's motion)"
            )),
            None,
        ),
        false => (None, Some((solution, evals))),
    }
}

/// Whether `levenberg-marquardt` suits a problem the exact solvers refuse: the short cost, and
/// no unknown that moves it in steps (a conditional range, a nonlinear drag's `v_max`: the
/// cost reads them only through comparisons with observed values, so a finite difference sees
/// a zero or a jump). Muscles' neurons, worlds and couplings are smooth in their parameters.
fn smooth_short_cost(problem: &Problem) -> bool {
    levenberg_marquardt::supported(problem).is_ok()
        && problem
            .space
            .unknowns
            .iter()
            .all(|u| !matches!(u.role, Role::Range | Role::Speed))
}

/// `config.islands` copies of the named strategy run as an island model
/// ([`Islands`]), each with `options.population` individuals; errors when that strategy
/// cannot exchange individuals. `auto` means the `t2m` ES here: islands are populations
/// exchanging individuals, and what `auto` picks otherwise (an exact solver, one
/// levenberg-marquardt point) has none. Returns the strategy with the name of what each
/// island runs.
pub fn make_islands(
    name: StrategyName,
    problem: &Problem,
    options: &StrategyOptions,
    config: IslandConfig,
) -> Result<(Box<dyn Strategy>, &'static str), CostError> {
    let name = match name {
        StrategyName::Auto => StrategyName::T2m,
        other => other,
    };
    let mut ran = "islands";
    let islands = (0..config.islands)
        .map(|_| {
            let (s, r) = make_strategy(name, problem, options);
            ran = r;
            s
        })
        .collect();
    Ok((Box::new(Islands::new(config, islands)?), ran))
}

/// Whether the strategy that will run (as named by [`make_strategy`]) can run on `problem`:
/// the exact solvers say why not (a nonlinear cost kind, free masses without a total…),
/// `levenberg-marquardt` that it needs the short cost,
/// before a run starts.
pub fn check_strategy(ran: &str, problem: &Problem) -> Result<(), String> {
    if ran == "output-error" {
        return strategies::output_error::supported(problem);
    }
    if problem.has_missing() {
        return Err(format!(
            "the trajectory has missing observations: `{ran}` needs every coordinate \
             (use --strategy output-error or auto)"
        ));
    }
    if problem.has_weights() {
        return Err(format!(
            "per-marker weights: `{ran}` weighs every coordinate alike (output-error reads \
             them; use --strategy output-error or auto)"
        ));
    }
    if problem.take_count() > 1 {
        return Err(format!(
            "{} takes: `{ran}` reads one (output-error fits several takes with one parameter \
             set; use --strategy output-error or auto)",
            problem.take_count()
        ));
    }
    if ran == "levenberg-marquardt" {
        return levenberg_marquardt::supported(problem);
    }
    if ran != "least-squares" && ran != "hybrid" {
        return Ok(());
    }
    exact::supported(problem)?;
    let split = exact::split(problem);
    if ran == "least-squares" {
        if let Some(&k) = split.nonlinear.first() {
            return Err(format!(
                "{}: enters the short cost nonlinearly (use --strategy hybrid)",
                problem.space.unknowns[k].name
            ));
        }
    }
    let cols = exact::generic_cols(&problem.scene)?;
    exact::check_scale(problem, &split, &cols)
}

/// The trajectory with Gaussian noise of standard deviation `sigma` (m) added to every
/// coordinate (thesis §4.1), drawn from the run's seed.
pub fn add_noise(traj: &Trajectory, sigma: f64, seed: u64) -> Trajectory {
    try_add_noise(traj, sigma, seed).expect("finite data plus finite noise")
}

/// [`add_noise`], `None` when the noise makes a coordinate overflow (σ near f64's range).
pub fn try_add_noise(traj: &Trajectory, sigma: f64, seed: u64) -> Option<Trajectory> {
    let mut r = rng::stream(seed, u64::MAX, 0);
    let data: Vec<f64> = traj
        .as_flat()
        .iter()
        .map(|x| x + sigma * rng::normal(&mut r))
        .collect();
    let mut out = Trajectory::from_flat(traj.frames(), traj.particles(), data).ok()?;
    out.dt = traj.dt;
    Some(out)
}

/// [`try_add_noise`] for observations with gaps: the same draws in the same order (one per
/// coordinate, a missing one included, so a complete take gets exactly `try_add_noise`'s
/// values); a missing coordinate stays missing. `None` when a value overflows.
pub fn try_add_noise_observations(
    obs: &cordis_core::Observations,
    sigma: f64,
    seed: u64,
) -> Option<cordis_core::Observations> {
    let mut r = rng::stream(seed, u64::MAX, 0);
    let data: Vec<f64> = obs
        .as_flat()
        .iter()
        .map(|x| x + sigma * rng::normal(&mut r))
        .collect();
    if data.iter().any(|v| v.is_infinite()) {
        return None;
    }
    let mut out = cordis_core::Observations::from_flat(obs.frames(), obs.particles(), data).ok()?;
    out.dt = obs.dt;
    Some(out)
}

/// A copy of `scene` whose positive link-type parameters are unknown, each in a box `width`
/// times wide (max/min = width) that holds the scene's value at a pseudo-random place drawn
/// from `seed` (not at the centre: a strategy must not find the truth by starting in the
/// middle). Zero-valued parameters (an absent damping) stay known. A muscle's weights (and a
/// non-zero threshold) get additive boxes `4|v| + 2` wide, since they may be negative or 0;
/// its gain stays known, and so do a TGR's tendon parameters. The input is the truth.
pub fn with_unknown_boxes(scene: &cordis_core::Scene, width: f64, seed: u64) -> cordis_core::Scene {
    use cordis_core::{Bounds, Param};
    let mut out = scene.clone();
    let mut r = rng::stream(seed, u64::MAX - 1, 0);
    let lw = width.max(1.0).ln();
    for t in &mut out.types {
        let names: Vec<String> = (0..t.params.len()).map(|k| t.param_name(k)).collect();
        for (p, name) in t.params.iter_mut().zip(&names) {
            let Param::Known(v) = *p else { continue };
            // A neuron's weights and threshold have either sign and may be 0 (an absent
            // connection, thesis §6.2): an additive box 2(2|v| + 1) wide holds v off-centre. Its
            // gain stays known: it sets the scale of the weights, which would otherwise trade
            // off against it.
            let neural = name.starts_with("w_") || (name == "threshold" && v != 0.0);
            if neural {
                let u = 0.1 + 0.8 * rng::uniform(&mut r);
                let half = 2.0 * v.abs() + 1.0;
                *p = Param::Unknown(Bounds {
                    min: v - 2.0 * half * u,
                    max: v + 2.0 * half * (1.0 - u),
                    init: None,
                });
                continue;
            }
            // A TGR's tendon is the experimenter's transducer, not the body: it stays known
            // (thesis Table 6.1 identifies the link and the medium). The optional parameters
            // (Provot's τc, a quadratic viscosity) stay known too, and draw nothing, so a scene
            // gets the boxes it got before they existed: give them a box in the file.
            if v <= 0.0
                || cordis_core::OptionalParam::from_name(name).is_some()
                || name == "rest_cos"
                || name == "gain"
                || name == "threshold"
                || name.starts_with("tendon_")
            {
                continue;
            }
            let u = 0.1 + 0.8 * rng::uniform(&mut r);
            let min = v * (-u * lw).exp();
            let max = v * ((1.0 - u) * lw).exp();
            *p = Param::Unknown(Bounds {
                min,
                max,
                init: None,
            });
        }
    }
    out
}
