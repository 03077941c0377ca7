//! `least-squares`: the short cost of a linear-in-parameter scene minimised exactly (SPEC §4).
//!
//! The short cost is a sum of squares of residuals affine in θ ([`crate::exact`]), so one
//! weighted linear least-squares solve finds its global minimum: on noiseless data, the
//! generating parameters to rounding. Known masses use the objective's precomputed factor
//! ([`crate::cost::LinearShortCost`]); free masses (under a known total, thesis §3.3) and
//! nonlinear drags at a known v_max use the generic assembly. The solve is rank-revealing (SVD):
//! the report gives the condition number and names what the data cannot determine. On a scene
//! with Provot limits the rows the limit acts on are found by iteration and left out
//! ([`crate::exact::provot_rows`]).
//!
//! As a [`Strategy`]: `init` solves (generation 0); later generations change nothing.

use crate::exact::provot_rows;
use crate::exact::{self, ExactReport, OneShot, Solution};
use crate::problem::Problem;

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
    if provot_rows::applies(&problem.objective) {
        let cols = exact::generic_cols(&problem.scene)?;
        exact::check_scale(problem, &split, &cols)?;
        let base = problem.space.base.clone();
        let (genome, cost) = provot_rows::solve(problem, &cols, base, &split, &mut report)?;
        return Ok(Solution {
            genome,
            cost,
            report,
        });
    }
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

/// The `least-squares` strategy: one exact solve in generation 0.
pub fn strategy() -> OneShot {
    OneShot::new("least-squares", solve)
}
