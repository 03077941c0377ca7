//! `least-squares`: the short cost of a linear-in-parameter scene minimised exactly (SPEC §4).
//!
//! The short cost is a sum of squares of residuals affine in θ ([`super::exact`]), so one
//! weighted linear least-squares solve finds its global minimum: on noiseless data, the
//! generating parameters to rounding. Known masses use the objective's precomputed factor
//! ([`crate::cost::LinearShortCost`]); free masses (under a known total, thesis §3.3) and
//! nonlinear drags at a known v_max use the generic assembly. The solve is rank-revealing (SVD):
//! the report gives the condition number and names what the data cannot determine.
//!
//! As a [`Strategy`]: `init` solves (generation 0); later generations change nothing.

use serde::{Deserialize, Serialize};

use super::exact::{self, ExactReport, Solution};
use crate::problem::Problem;
use crate::strategy::{bits, lossless, GenerationStats, Strategy};

/// Solves `problem` exactly; `Err` when it is not linear in its unknowns (a range or v_max
/// unknown: use [`super::hybrid`]), not a short cost, or not determined up to scale.
pub fn solve(problem: &Problem) -> Result<Solution, String> {
    exact::supported(problem)?;
    let split = exact::split(problem);
    if let Some(&k) = split.nonlinear.first() {
        return Err(format!(
            "{}: enters the short cost nonlinearly (use the hybrid strategy)",
            problem.space.unknowns[k].name
        ));
    }
    let mut report = ExactReport::default();
    let system = match problem.objective.linear().filter(|_| !split.free_masses) {
        Some(lin) => exact::from_linear(lin),
        None => {
            report
                .notes
                .push("design assembled from the force passes (no precomputed form)".into());
            let cols = exact::generic_cols(&problem.scene)?;
            exact::check_scale(problem, &split, &cols)?;
            exact::assemble(
                &problem.objective,
                &problem.scene,
                &cols,
                &problem.space.base,
            )
        }
    };
    let (genome, cost) = exact::solve_linear(
        problem,
        &system,
        problem.space.base.clone(),
        &split,
        &mut report,
    )?;
    Ok(Solution {
        genome,
        cost,
        report,
    })
}

#[derive(Clone, Debug, Default, Serialize, Deserialize)]
struct State {
    #[serde(with = "bits")]
    genome: Vec<f64>,
    #[serde(with = "lossless")]
    cost: f64,
    report: ExactReport,
}

/// The `least-squares` strategy.
#[derive(Default)]
pub struct LeastSquares {
    state: State,
}

impl LeastSquares {
    pub fn new() -> Self {
        Self::default()
    }

    /// Condition number, undetermined and clamped unknowns, notes, error.
    pub fn report(&self) -> &ExactReport {
        &self.state.report
    }
}

/// The starting point, scored: the answer of a failed solve.
pub(crate) fn fallback(problem: &Problem, error: String) -> (Vec<f64>, f64, ExactReport) {
    let genome = problem.space.genome_of(&problem.space.base);
    let mut s = problem.scratch();
    let mut local = vec![0.0; problem.num_particles];
    let cost = problem.evaluate(&genome, &mut s, &mut local);
    let report = ExactReport {
        condition: f64::INFINITY,
        error: Some(error),
        ..ExactReport::default()
    };
    (genome, cost, report)
}

impl Strategy for LeastSquares {
    fn name(&self) -> &'static str {
        "least-squares"
    }

    fn init(&mut self, problem: &Problem, _seed: u64) {
        self.state = match solve(problem) {
            Ok(s) => State {
                genome: s.genome,
                cost: s.cost,
                report: s.report,
            },
            Err(e) => {
                let (genome, cost, report) = fallback(problem, e);
                State {
                    genome,
                    cost,
                    report,
                }
            }
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
                "state has {} unknowns, the problem {}",
                s.genome.len(),
                problem.dim()
            ));
        }
        self.state = s;
        Ok(())
    }

    fn report(&self) -> serde_json::Value {
        serde_json::to_value(&self.state.report).unwrap_or_default()
    }
}
