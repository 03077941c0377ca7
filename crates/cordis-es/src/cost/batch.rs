//! Evaluating a whole population in parallel.

use super::objective::Objective;
use crate::error::CostError;
use rayon::prelude::*;

impl Objective {
    /// Global costs of a population: `population` is row-major, one parameter vector of
    /// [`Objective::param_len`] values per individual; `out` gets one cost per individual.
    ///
    /// Parallel over individuals on the current rayon pool, with one scratch per worker split
    /// (no allocation per evaluation). Each individual's cost is computed by one thread in a
    /// fixed order, so the results are bit-identical for any thread count. Errors (nothing
    /// evaluated) when the lengths do not fit.
    pub fn evaluate_batch(&self, population: &[f64], out: &mut [f64]) -> Result<(), CostError> {
        let len = self.param_len();
        let expected = out.len() * len;
        if population.len() != expected {
            return Err(CostError::length(
                format!("population of {} individuals", out.len()),
                expected,
                population.len(),
            ));
        }
        if len == 0 {
            let mut s = self.scratch();
            out.fill(self.total_unchecked(&[], &mut s));
            return Ok(());
        }
        population
            .par_chunks_exact(len)
            .zip(out.par_iter_mut())
            .for_each_init(
                || self.scratch(),
                |s, (p, o)| *o = self.total_unchecked(p, s),
            );
        Ok(())
    }
}
