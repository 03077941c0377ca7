//! `output-error`: the maximum-likelihood estimate of [`crate::output_error`] as a strategy.
//!
//! `init` runs the whole fit (growing windows of Levenberg–Marquardt on exact sensitivities)
//! on the problem's recorded takes ([`Problem::takes`]: gaps and hidden particles included);
//! later generations change nothing. The best genome's cost is the problem's own cost (the
//! short cost unless `--cost` says otherwise), so it compares with every other strategy's; the
//! fit's position cost, σ̂, standard errors, intervals, correlations, undetermined directions
//! and the estimated initial state are in the report.

use serde::{Deserialize, Serialize};

use crate::output_error::{self, Config, Estimate};
use crate::problem::Problem;
use crate::strategy::{GenerationStats, Strategy};

/// The estimator as a [`Strategy`].
pub struct OutputError {
    config: Config,
    state: State,
}

#[derive(Clone, Debug, Default, Serialize, Deserialize)]
struct State {
    genome: Vec<f64>,
    cost: f64,
    report: serde_json::Value,
    /// Why no estimate could be made.
    error: Option<String>,
    /// Per take: `[x0, v0]` per free particle.
    states: Vec<Vec<f64>>,
    converged: bool,
}

impl OutputError {
    pub fn new(config: Config) -> Self {
        OutputError {
            config,
            state: State::default(),
        }
    }

    /// Why the fit could not produce an estimate, if it could not.
    pub fn error(&self) -> Option<&str> {
        self.state.error.as_deref()
    }

    /// Whether the last window met the solver's own criterion.
    pub fn converged(&self) -> bool {
        self.state.converged
    }

    /// The estimated initial states, per take (`[x0, v0]` per free particle, m and m/s).
    pub fn states(&self) -> &[Vec<f64>] {
        &self.state.states
    }
}

/// Whether `output-error` can run on `problem` (its kinds have exact sensitivities).
pub fn supported(problem: &Problem) -> Result<(), String> {
    output_error::tangent::Tangent::new(&problem.scene)
        .map(|_| ())
        .map_err(|e| e.to_string())
}

/// The fit's summary for the run report (JSON).
pub fn report_json(problem: &Problem, e: &Estimate) -> serde_json::Value {
    let params: Vec<serde_json::Value> = problem
        .space
        .unknowns
        .iter()
        .enumerate()
        .map(|(k, u)| {
            let se = e.stderr[k];
            serde_json::json!({
                "name": u.name,
                "value": e.params[u.slot],
                "stderr": if se.is_finite() { serde_json::json!(se) } else { serde_json::json!("inf") },
                "interval95": if se.is_finite() {
                    serde_json::json!([e.intervals[k].0, e.intervals[k].1])
                } else {
                    serde_json::Value::Null
                },
            })
        })
        .collect();
    let dim = e.correlation.nrows();
    let correlation: Vec<Vec<f64>> = (0..dim)
        .map(|a| (0..dim).map(|b| e.correlation[(a, b)]).collect())
        .collect();
    serde_json::json!({
        "estimator": "output-error",
        "start": e.start,
        "windows": e.windows,
        "end": e.end,
        "iterations": e.iterations,
        "rollouts": e.evaluations,
        "position_cost": e.cost,
        "sigma": e.sigma,
        "noise_level": e.noise_level,
        "observed": e.observed,
        "variables": e.variables,
        "parameters": params,
        "correlation": correlation,
        "undetermined_directions": e.undetermined,
    })
}

impl Strategy for OutputError {
    fn name(&self) -> &'static str {
        "output-error"
    }

    fn init(&mut self, problem: &Problem, _seed: u64) {
        let takes = problem.takes();
        let fit = output_error::estimate(&problem.scene, &problem.space, &takes, &self.config);
        self.state = match fit {
            Ok(e) => {
                let mut s = problem.scratch();
                let mut local = vec![0.0; problem.num_particles];
                let cost = problem.evaluate(&e.genome, &mut s, &mut local);
                problem.set_evals(problem.evals() + e.evaluations as u64);
                State {
                    report: report_json(problem, &e),
                    genome: e.genome,
                    cost,
                    error: None,
                    converged: e.converged,
                    states: e.states,
                }
            }
            Err(err) => State {
                genome: problem.space.genome_of(&problem.space.base),
                cost: f64::INFINITY,
                report: serde_json::json!({ "estimator": "output-error", "error": err.to_string() }),
                error: Some(err.to_string()),
                states: Vec::new(),
                converged: false,
            },
        };
    }

    fn next_generation(&mut self, _problem: &Problem, _seed: u64, _generation: u64) {}

    fn finished(&self) -> bool {
        true
    }

    fn best(&self) -> (&[f64], f64) {
        (&self.state.genome, self.state.cost)
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

    fn load_state(&mut self, problem: &Problem, state: &serde_json::Value) -> Result<(), String> {
        let s: State = serde_json::from_value(state.clone()).map_err(|e| e.to_string())?;
        if s.genome.len() != problem.dim() {
            return Err(format!(
                "output-error state has {} unknowns, the problem {}",
                s.genome.len(),
                problem.dim()
            ));
        }
        self.state = s;
        Ok(())
    }

    fn report(&self) -> serde_json::Value {
        self.state.report.clone()
    }
}
