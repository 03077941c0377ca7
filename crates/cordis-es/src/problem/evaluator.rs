//! Where a population's costs are computed: on this process' rayon pool ([`Local`], the
//! default) or elsewhere (the Python bindings' Ray executor). Strategies never call an
//! evaluator directly: they hand whole populations to [`Problem::evaluate_population`], which
//! counts the evaluations and keeps the first failure for the run loop to report.
//!
//! The [`Evaluator`] trait is defined beside [`Problem`] (a problem holds one, and an evaluator
//! reads the problem): an evaluator must return, for every genome, exactly what
//! [`Problem::evaluate`] returns (bit for bit, +inf for a diverged or non-finite cost), since a
//! strategy's next generation depends on the costs; this keeps a seed's result independent of
//! where costs are computed.

pub use crate::problem::Evaluator;
use crate::problem::Problem;

/// Evaluation on the current rayon pool, one scratch per worker split: the default
/// ([`Problem::evaluate_here`]).
#[derive(Clone, Copy, Debug, Default)]
pub struct Local;

impl Evaluator for Local {
    fn evaluate(
        &self,
        problem: &Problem,
        genomes: &[f64],
        costs: &mut [f64],
        local: Option<&mut [f64]>,
    ) -> Result<(), crate::error::CostError> {
        problem.evaluate_here(genomes, costs, local);
        Ok(())
    }
}
