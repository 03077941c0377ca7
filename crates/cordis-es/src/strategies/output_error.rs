//! `output-error`: the maximum-likelihood estimate of [`crate::output_error`] as a strategy.
//!
//! `init` checks the problem's recorded takes ([`Problem::takes`]: gaps and hidden particles
//! included) and computes the start; each generation then fits one growing window
//! ([`crate::output_error::run`]), and the one that reaches the whole take computes the
//! uncertainty and finishes. Ctrl-C or a time limit stops a window within one
//! Levenberg–Marquardt iteration, with the best point so far as the result; a checkpoint holds
//! the fit's progress and a resume reruns the stopped window, so it ends exactly where an
//! uninterrupted run ends. The best genome's cost is the problem's own cost (the short cost
//! unless `--cost` says otherwise), so it compares with every other strategy's; the fit's
//! position cost, σ̂, standard errors, intervals, correlations, undetermined directions and
//! the estimated initial state are in the report.

use serde::{Deserialize, Serialize};

use crate::error::CostError;
use crate::output_error::line_profile::LEVEL;
use crate::output_error::{self, Config, Estimate, Prepared, Progress, Step};
use crate::problem::Problem;
use crate::report::{undetermined_lines, InitialState, ParamUncertainty, Report, SolverReport};
use crate::strategy::{GenerationStats, Strategy};

/// The estimator as a [`Strategy`].
pub struct OutputError {
    config: Config,
    state: State,
    /// What the fit reads, from `init` (or `load_state`) on.
    prepared: Option<Prepared>,
    /// Which particles are free (their initial state is estimated), set by `init`.
    free: Vec<bool>,
    /// Why `auto` chose it, for the report.
    chosen_because: Option<String>,
}

#[derive(Clone, Debug, Default, Serialize, Deserialize)]
struct State {
    genome: Vec<f64>,
    /// +inf for a failed fit or a diverging best point: written as `"inf"` (JSON has no
    /// infinity; a plain f64 became `null`, which no checkpoint could load).
    #[serde(with = "crate::run::float_json::lossless")]
    cost: f64,
    report: OutputErrorReport,
    uncertainty: Option<Vec<ParamUncertainty>>,
    /// Why no estimate could be made.
    error: Option<String>,
    /// Per take: `[x0, v0]` per free particle.
    states: Vec<Vec<f64>>,
    /// The fit while it runs (`None` once finished or failed).
    progress: Option<Progress>,
}

impl OutputError {
    pub fn new(config: Config) -> Self {
        OutputError {
            config,
            state: State::default(),
            prepared: None,
            free: Vec::new(),
            chosen_because: None,
        }
    }

    /// Records why `auto` picked this estimator (said in the report).
    pub fn chosen_because(mut self, why: Option<String>) -> Self {
        self.chosen_because = why;
        self
    }

    /// The fit runs on: its best point so far is the strategy's best, and the report says the
    /// fit has not finished (no uncertainty yet).
    fn show(&mut self, problem: &Problem, progress: Progress) {
        let Some(prepared) = &self.prepared else {
            return;
        };
        let q = progress.best();
        let genome = prepared.genome(&problem.space, q).to_vec();
        let cost = problem_cost(problem, &genome);
        let (iterations, rollouts) = progress.counts();
        let where_ = if progress.stopped() { "in" } else { "before" };
        let (position_cost, observed, variables) = prepared.measure(&problem.space, q);
        let dof = observed.saturating_sub(variables).max(1);
        self.state.report = OutputErrorReport {
            estimator: "output-error".into(),
            start: progress.start_note(),
            windows: progress.windows().to_vec(),
            // The run loop does not tell a strategy it stopped, so every report of an unfinished
            // fit says `stopped` (mid-run checkpoints too): read at the end, that is the truth,
            // where `running` was reported of runs that had ended and a time limit's end was
            // `interrupted`. The run's `stopped_by` says which rule or Ctrl-C stopped it.
            end: "stopped".into(),
            iterations,
            rollouts,
            position_cost,
            sigma: (position_cost / dof as f64).sqrt(),
            noise_level: prepared.noise_level().to_vec(),
            loss: self.config.loss.to_string(),
            observed,
            variables,
            unconverged: Some(format!(
                "output-error: the fit stopped {where_} window {} (windows done: {:?}) before \
                 reaching the whole take: the best point so far, no uncertainty",
                progress.next_window(),
                progress.windows()
            )),
            uncertainty_computed: false,
            ..OutputErrorReport::default()
        };
        self.state.states = prepared.states(&problem.space, q);
        self.state.genome = genome;
        self.state.cost = cost;
        self.state.uncertainty = None;
        self.state.progress = Some(progress);
    }

    /// The fit reached the whole take: `e` is the estimate, `staged` the rollouts of its
    /// stages (already counted on the problem).
    fn finished_with(
        &mut self,
        problem: &Problem,
        e: Estimate,
        staged: usize,
        noise_unread: Vec<usize>,
    ) {
        let cost = problem_cost(problem, &e.genome);
        // The final evaluations (the whole take with sensitivities) beyond the stages'.
        problem.set_evals(problem.evals() + e.evaluations.saturating_sub(staged) as u64);
        let report = OutputErrorReport {
            noise_unread,
            ..OutputErrorReport::new(problem, &e)
        };
        self.state = State {
            report,
            uncertainty: uncertainty(problem, &e),
            genome: e.genome,
            cost,
            error: None,
            states: e.states,
            progress: None,
        };
        self.prepared = None;
    }

    fn fail(&mut self, problem: &Problem, err: String) {
        self.state = State {
            genome: problem.space.genome_of(&problem.space.base),
            cost: f64::INFINITY,
            report: OutputErrorReport::default(),
            uncertainty: None,
            error: Some(err),
            states: Vec::new(),
            progress: None,
        };
        self.prepared = None;
    }
}

/// The problem's own cost at `genome` (what every strategy's best is compared by).
fn problem_cost(problem: &Problem, genome: &[f64]) -> f64 {
    let mut s = problem.scratch();
    let mut local = vec![0.0; problem.num_particles];
    problem.evaluate(genome, &mut s, &mut local)
}

/// Whether `output-error` can run on `problem` (its kinds have exact sensitivities, and the
/// data are a motion: not the static cost's poses at rest).
pub fn supported(problem: &Problem) -> Result<(), String> {
    if problem.objective.kind() == crate::cost::CostKind::Static {
        return Err(
            "cost kind `static`: output-error fits a motion, the static cost's frames \
                    are poses at rest (use levenberg-marquardt or an evolution strategy)"
                .into(),
        );
    }
    output_error::tangent::Tangent::supports(&problem.scene).map_err(|e| e.to_string())
}

pub use crate::report::{OutputErrorReport, StderrBound, WidenedInterval};

impl OutputErrorReport {
    fn new(problem: &Problem, e: &Estimate) -> Self {
        let dim = e.correlation.nrows();
        let names: Vec<&str> = problem
            .space
            .unknowns
            .iter()
            .map(|u| u.name.as_str())
            .collect();
        // Each name once, in the order the directions name them (an unknown on several
        // directions was listed once per direction).
        let mut undetermined: Vec<String> = Vec::new();
        for n in e.undetermined.iter().flatten() {
            if names.contains(&n.as_str()) && !undetermined.contains(n) {
                undetermined.push(n.clone());
            }
        }
        let at_bound = at_bound(problem, e, &undetermined);
        OutputErrorReport {
            estimator: "output-error".into(),
            start: e.start.clone(),
            windows: e.windows.clone(),
            end: e.end.into(),
            iterations: e.iterations,
            rollouts: e.evaluations,
            position_cost: e.cost,
            sigma: e.sigma,
            noise_level: e.noise_level.clone(),
            loss: e.loss.to_string(),
            downweighted: e.downweighted,
            observed: e.observed,
            variables: e.variables,
            correlation: (0..dim)
                .map(|a| (0..dim).map(|b| e.correlation[(a, b)]).collect())
                .collect(),
            undetermined_directions: e.undetermined.clone(),
            undetermined,
            unconverged: (!e.converged).then(|| {
                let window = e.windows.last().copied().unwrap_or(0);
                match e.end {
                    "above_noise" => format!(
                        "output-error: the fit of the whole take ({window} frames) leaves \
                         residuals (σ̂ {:.3e} m) above the data's noise level ({:.3e} m) from \
                         every start: a wrong basin, a model that cannot follow this motion, or \
                         outliers (a swapped marker: try a robust loss, huber)",
                        e.sigma,
                        e.noise_level.iter().cloned().fold(0.0, f64::max)
                    ),
                    end => format!(
                        "output-error: the last window ({window} frames) ended by {end} before \
                         its tolerances held"
                    ),
                }
            }),
            chosen_because: None,
            at_bound,
            noise_unread: Vec::new(),
            uncertainty_computed: !e.stderr.iter().any(|s| s.is_nan()),
            // Every unknown whose standard error was not computed, so a reader finds them all
            // in one place; a solve that never moved bounds it by 0 only.
            stderr_at_least: names
                .iter()
                .zip(&e.stderr)
                .zip(&e.stderr_at_least)
                .filter(|((_, se), _)| se.is_nan())
                .map(|((name, _), lb)| StderrBound {
                    name: name.to_string(),
                    at_least: if *lb > 0.0 { *lb } else { 0.0 },
                })
                .collect(),
            intervals: e.interval_kind.clone(),
            widened_intervals: e
                .widened
                .iter()
                .map(|w| WidenedInterval {
                    name: names[w.unknown].to_string(),
                    wald: w.wald,
                    rise: (w.rise[0], w.rise[1]),
                })
                .collect(),
        }
    }

    /// Whether the fit reached its end (not stopped by the run, nor failed before any end;
    /// `running` and `interrupted` are the older names of `stopped`, in checkpoints): σ̂ and
    /// the standard errors are then the estimate's.
    pub fn finished(&self) -> bool {
        !matches!(
            self.end.as_str(),
            "" | "stopped" | "running" | "interrupted"
        )
    }

    /// What a user must read before trusting the estimate.
    pub fn warnings(&self) -> Vec<String> {
        let mut w: Vec<String> = self.unconverged.iter().cloned().collect();
        if self.finished() && !self.uncertainty_computed {
            let missing: Vec<String> = self
                .stderr_at_least
                .iter()
                .map(|b| match b.rounded_down() {
                    Some(v) => format!("{} ≥ {v}", b.name),
                    None => b.name.clone(),
                })
                .collect();
            w.push(format!(
                "output-error: {} of {} standard errors not computed (the matrix-free solves \
                 for them did not converge; the others are reported): {}",
                missing.len(),
                self.correlation.len(),
                missing.join(", ")
            ));
        }
        if self.finished() && !self.noise_unread.is_empty() {
            let takes: Vec<String> = self.noise_unread.iter().map(|k| k.to_string()).collect();
            w.push(format!(
                "output-error: the noise level of take {} cannot be read (no 4 consecutive \
                 observed frames): the residuals were not judged against it, so a wrong basin \
                 would go unnoticed",
                takes.join(", ")
            ));
        }
        if self.finished() && !self.at_bound.is_empty() {
            w.push(format!(
                "output-error: on an edge of the box: {} (the data pull each further: its \
                 value is the box's edge and its interval is cut there); widen the box, or \
                 check the scene and the data",
                self.at_bound.join(", ")
            ));
        }
        if self.finished() {
            w.extend(self.interval_warnings());
        }
        w.extend(undetermined_lines(&self.undetermined_directions, |n| {
            self.undetermined.iter().any(|u| u.as_str() == n)
        }));
        w
    }
}

/// A cost this many σ̂² below the estimate's at an interval's edge says the estimate is not
/// the optimum: beyond the edge search's own tolerance (its refits stop within a tenth of σ̂²,
/// [`crate::output_error::line_profile`]).
const BELOW_OPTIMUM: f64 = 0.2;

impl OutputErrorReport {
    /// The widened intervals' lines: one for the unknowns whose cost at an interval's edge
    /// fell below the estimate's (the fit had not reached its optimum: the intervals around a
    /// point that is not one mean little), one for those where it rose slower than the
    /// quadratic model.
    fn interval_warnings(&self) -> Vec<String> {
        let lowest = |r: (f64, f64)| {
            [r.0, r.1]
                .into_iter()
                .filter(|x| !x.is_nan())
                .fold(f64::INFINITY, f64::min)
        };
        let (below, flat): (Vec<&WidenedInterval>, Vec<&WidenedInterval>) = self
            .widened_intervals
            .iter()
            .partition(|w| lowest(w.rise) * LEVEL < -BELOW_OPTIMUM);
        // How the cost at an edge was measured.
        let rest = match self.intervals.starts_with("profile") {
            true => "the rest refitted",
            false => "the rest moved along the Gauss–Newton model's line",
        };
        let mut w = Vec::new();
        if !below.is_empty() {
            let named: Vec<String> = below
                .iter()
                .map(|x| format!("{} ({:.1} σ̂²)", x.name, -lowest(x.rise) * LEVEL))
                .collect();
            w.push(format!(
                "output-error: the estimate is not the cost's minimum: with {} held at an \
                 edge of its interval and {rest}, the cost falls below the estimate's by {}; \
                 the intervals are widened about the fit's end point, which is no optimum",
                if below.len() == 1 {
                    "this unknown"
                } else {
                    "each of these"
                },
                named.join(", ")
            ));
        }
        if !flat.is_empty() {
            let named: Vec<String> = flat
                .iter()
                .map(|x| format!("{} (rise {:.2}× the model's)", x.name, lowest(x.rise)))
                .collect();
            w.push(format!(
                "output-error: the cost is far from quadratic at the scale of {} interval{}: \
                 widened past the standard error's (Wald) interval to where the cost ({rest}) \
                 reaches its 95 % level, the data determine {} less than the standard error \
                 says: {}",
                flat.len(),
                if flat.len() == 1 { "" } else { "s" },
                if flat.len() == 1 { "it" } else { "them" },
                named.join(", ")
            ));
        }
        w
    }
}

/// The unknowns on an edge of their box at the estimate ([`crate::space::Unknown::on_box_edge`]);
/// an undetermined unknown is wherever the fit left it (the data pull it nowhere).
fn at_bound(problem: &Problem, e: &Estimate, undetermined: &[String]) -> Vec<String> {
    problem
        .space
        .unknowns
        .iter()
        .zip(&e.genome)
        .filter(|(u, &z)| !undetermined.contains(&u.name) && u.on_box_edge(z))
        .map(|(u, _)| u.name.clone())
        .collect()
}

/// Standard errors and 95 % intervals of the unknowns, by name, in unknown order; an unknown
/// whose standard error was not computed (the matrix-free path's solve for it did not settle)
/// is left out, its lower bound is in the report's `stderr_at_least` (a NaN never leaves a
/// result); `None` when none was computed.
fn uncertainty(problem: &Problem, e: &Estimate) -> Option<Vec<ParamUncertainty>> {
    let list: Vec<ParamUncertainty> = problem
        .space
        .unknowns
        .iter()
        .enumerate()
        .filter(|&(k, _)| !e.stderr[k].is_nan())
        .map(|(k, u)| ParamUncertainty {
            name: u.name.clone(),
            std_error: e.stderr[k],
            interval: e.intervals[k],
            level: 0.95,
        })
        .collect();
    (!list.is_empty()).then_some(list)
}

impl Strategy for OutputError {
    fn name(&self) -> &'static str {
        "output-error"
    }

    fn init(&mut self, problem: &Problem, _seed: u64) {
        self.free = problem.scene.particles.iter().map(|p| !p.fixed).collect();
        let scene = &problem.scene;
        let started = Prepared::new(scene, &problem.space, problem.takes(), &self.config)
            .and_then(|p| Ok((p.start(scene, &problem.space, &self.config)?, p)));
        match started {
            Ok((progress, prepared)) => {
                self.prepared = Some(prepared);
                self.state = State::default();
                self.show(problem, progress);
            }
            Err(err) => self.fail(problem, err.to_string()),
        }
    }

    fn next_generation(&mut self, problem: &Problem, seed: u64, generation: u64) {
        self.next_generation_until(problem, seed, generation, &|| false);
    }

    fn next_generation_until(
        &mut self,
        problem: &Problem,
        _seed: u64,
        _generation: u64,
        halt: &dyn Fn() -> bool,
    ) {
        let (Some(prepared), Some(mut progress)) = (&self.prepared, self.state.progress.take())
        else {
            return;
        };
        let space = &problem.space;
        let rollouts = progress.counts().1;
        // The stages are the run's evaluations (rollouts with their sensitivities, and the
        // Gauss–Newton solves they interleave with): `eval_seconds` is their time.
        let step = problem.timed(|| prepared.stage(space, &mut progress, halt));
        problem.set_evals(problem.evals() + (progress.counts().1 - rollouts) as u64);
        match step {
            Ok(Step::Done) => {
                match problem.timed(|| prepared.finish(&problem.scene, space, &progress, halt)) {
                    Ok(e) => {
                        let unread = prepared.noise_unread();
                        self.finished_with(problem, e, progress.counts().1, unread)
                    }
                    Err(err) => self.fail(problem, err.to_string()),
                }
            }
            Ok(Step::More | Step::Stopped) => self.show(problem, progress),
            Err(err) => self.fail(problem, err.to_string()),
        }
    }

    fn finished(&self) -> bool {
        self.state.progress.is_none()
    }

    fn best(&self) -> (&[f64], f64) {
        (&self.state.genome, self.state.cost)
    }

    fn own_cost(&self) -> Option<(f64, usize)> {
        let r = &self.state.report;
        (self.state.error.is_none() && r.observed > 0).then_some((r.position_cost, r.observed))
    }

    fn stats(&self) -> GenerationStats {
        GenerationStats {
            best_cost: self.state.cost,
            mean_cost: self.state.cost,
            mean_mutability: 0.0,
        }
    }

    fn save_state(&self) -> serde_json::Value {
        serde_json::to_value(&self.state).unwrap_or_default()
    }

    fn load_state(
        &mut self,
        problem: &Problem,
        state: &serde_json::Value,
    ) -> Result<(), CostError> {
        let mut s: State =
            serde_json::from_value(state.clone()).map_err(|e| CostError::state_json(None, e))?;
        if s.genome.len() != problem.dim() {
            return Err(CostError::state(format!(
                "output-error state has {} unknowns, the problem {}",
                s.genome.len(),
                problem.dim()
            )));
        }
        self.free = problem.scene.particles.iter().map(|p| !p.fixed).collect();
        let width = 6 * self.free.iter().filter(|f| **f).count();
        if s.states.iter().any(|t| t.len() != width) {
            return Err(CostError::state(format!(
                "output-error state holds initial states of another length than the {width} \
                 values of this scene's free particles"
            )));
        }
        if let Some(progress) = &mut s.progress {
            let prepared = Prepared::new(
                &problem.scene,
                &problem.space,
                problem.takes(),
                &self.config,
            )?;
            prepared.check(&problem.space, progress)?;
            // A window stopped midway reruns from its start: the same steps as an
            // uninterrupted fit.
            progress.rerun_stopped_stage();
            self.prepared = Some(prepared);
        }
        self.state = s;
        Ok(())
    }

    fn failure(&self) -> Option<String> {
        self.state.error.clone()
    }

    fn initial_states(&self) -> Vec<InitialState> {
        let state = |take: &Vec<f64>| {
            let mut f = 0;
            let particles = self
                .free
                .iter()
                .map(|&free| {
                    free.then(|| {
                        let s = &take[6 * f..6 * f + 6];
                        f += 1;
                        ([s[0], s[1], s[2]], [s[3], s[4], s[5]])
                    })
                })
                .collect();
            InitialState { particles }
        };
        self.state.states.iter().map(state).collect()
    }

    fn report(&self) -> Report {
        if self.state.error.is_some() {
            return Report::default();
        }
        let mut report = self.state.report.clone();
        report.chosen_because.clone_from(&self.chosen_because);
        Report {
            solver: Some(SolverReport::OutputError(report)),
            uncertainty: self.state.uncertainty.clone(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Widened intervals are warned in two kinds: those where the cost at an edge fell below
    /// the estimate's (the fit is not at its optimum) and those where it rose slower than the
    /// quadratic model, each named with its lowest rise; none once nothing was widened.
    #[test]
    fn widened_intervals_are_warned_by_what_the_cost_did_at_their_edges() {
        let widened = |name: &str, rise: (f64, f64)| WidenedInterval {
            name: name.into(),
            wald: (1.0, 2.0),
            rise,
        };
        let mut report = OutputErrorReport {
            end: "converged".into(),
            uncertainty_computed: true,
            widened_intervals: vec![
                widened("types.a.stiffness", (0.25, 3.0)),
                widened("types.b.damping", (f64::NAN, -2.0)),
            ],
            ..OutputErrorReport::default()
        };
        let w = report.warnings();
        assert_eq!(w.len(), 2, "{w:?}");
        assert!(
            w[0].contains("not the cost's minimum") && w[0].contains("types.b.damping (7.7 σ̂²)"),
            "{}",
            w[0]
        );
        assert!(
            w[1].contains("far from quadratic at the scale of 1 interval")
                && w[1].ends_with("types.a.stiffness (rise 0.25× the model's)"),
            "{}",
            w[1]
        );
        report.widened_intervals.clear();
        assert!(report.warnings().is_empty());
    }

    /// A failed fit's state (cost +inf) is saved and loaded again: a checkpoint of it resumes.
    #[test]
    fn a_failed_fits_infinite_cost_survives_its_checkpoint() {
        let state = State {
            cost: f64::INFINITY,
            error: Some("refused".into()),
            ..State::default()
        };
        let json = serde_json::to_value(&state).expect("serialises");
        assert_eq!(json["cost"], "inf");
        let back: State = serde_json::from_value(json).expect("loads");
        assert_eq!(back.cost, f64::INFINITY);
    }

    /// A standard error the matrix-free path did not compute (NaN) leaves the others reported,
    /// by name, and is named in `stderr_at_least` with its bound; none computed gives `None`.
    #[test]
    fn a_standard_error_not_computed_leaves_the_others_reported() {
        use crate::cost::CostKind;
        use crate::identify::with_unknown_boxes;
        let truth = cordis_core::examples::rigid();
        let traj = truth.simulate(40).expect("simulates");
        let problem =
            Problem::new(&with_unknown_boxes(&truth, 2.0, 0), &traj, CostKind::Short).unwrap();
        let take = output_error::Take::complete(&traj);
        let mut e = output_error::estimate(
            &problem.scene,
            &problem.space,
            std::slice::from_ref(&take),
            &Config::default(),
        )
        .expect("fits");
        let n = e.stderr.len();
        assert!(
            n >= 3 && e.stderr.iter().all(|s| s.is_finite()),
            "{:?}",
            e.stderr
        );
        let names: Vec<&str> = problem
            .space
            .unknowns
            .iter()
            .map(|u| u.name.as_str())
            .collect();
        e.stderr[1] = f64::NAN;
        e.stderr_at_least[1] = 0.25;

        let listed = uncertainty(&problem, &e).expect("the others are reported");
        assert_eq!(listed.len(), n - 1);
        assert!(listed
            .iter()
            .all(|p| p.name != names[1] && p.std_error.is_finite()));
        assert_eq!(
            (listed[1].name.as_str(), listed[1].std_error),
            (names[2], e.stderr[2])
        );
        let report = OutputErrorReport::new(&problem, &e);
        assert!(!report.uncertainty_computed);
        assert_eq!(
            report.stderr_at_least,
            vec![StderrBound {
                name: names[1].to_string(),
                at_least: 0.25
            }]
        );

        e.stderr.iter_mut().for_each(|s| *s = f64::NAN);
        assert!(uncertainty(&problem, &e).is_none());
        assert_eq!(
            OutputErrorReport::new(&problem, &e).stderr_at_least.len(),
            n
        );
    }
}
