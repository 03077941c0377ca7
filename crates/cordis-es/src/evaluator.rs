//! Where a population's costs are computed: on this process' rayon pool ([`Local`], the
//! default) or elsewhere (the Python bindings' Ray executor). Strategies never call an
//! evaluator directly: they hand whole populations to [`Problem::evaluate_population`], which
//! counts the evaluations and keeps the first failure for the run loop to report.
//!
//! An evaluator must return, for every genome, exactly what [`Problem::evaluate`] returns
//! (bit for bit, +inf for a diverged or non-finite cost): a strategy's next generation depends
//! on the costs, so this is what keeps a seed's result independent of where costs are computed.

use rayon::prelude::*;

use crate::problem::Problem;

/// Computes the costs of a population of genomes for a [`Problem`].
pub trait Evaluator: Send + Sync {
    /// Global costs of the `costs.len()` genomes of `genomes` (row-major, `problem.dim()`
    /// internal coordinates each) into `costs`; when `local` is given, each genome's
    /// per-particle local costs (row-major, `problem.num_particles` each, m²) into it. The cost
    /// function is `problem.objective` at its current generation (a progressive horizon
    /// depends on it). Does not count evaluations ([`Problem::evaluate_population`] does).
    ///
    /// An `Err` (a lost cluster, a remote exception) stops the run with that message.
    fn evaluate(
        &self,
        problem: &Problem,
        genomes: &[f64],
        costs: &mut [f64],
        local: Option<&mut [f64]>,
    ) -> Result<(), String>;
}

/// The `count` genomes of `dim` values each in `genomes`, one slice per individual; without
/// unknowns the slices are empty (each individual still has a cost).
pub(crate) fn genome_rows(genomes: &[f64], dim: usize, count: usize) -> Vec<&[f64]> {
    if dim == 0 {
        vec![&[][..]; count]
    } else {
        genomes.chunks_exact(dim).collect()
    }
}

/// Evaluation on the current rayon pool, one scratch per worker split: the default.
#[derive(Clone, Copy, Debug, Default)]
pub struct Local;

impl Evaluator for Local {
    fn evaluate(
        &self,
        problem: &Problem,
        genomes: &[f64],
        costs: &mut [f64],
        local: Option<&mut [f64]>,
    ) -> Result<(), String> {
        let dim = problem.dim();
        let n = problem.num_particles;
        debug_assert_eq!(genomes.len(), costs.len() * dim, "one genome per cost");
        let rows = genome_rows(genomes, dim, costs.len());
        match local {
            Some(local) if n > 0 => rows
                .par_iter()
                .zip(costs.par_iter_mut())
                .zip(local.par_chunks_mut(n))
                .for_each_init(
                    || problem.scratch(),
                    |s, ((g, c), l)| *c = problem.evaluate_uncounted(g, s, l),
                ),
            _ => rows.par_iter().zip(costs.par_iter_mut()).for_each_init(
                || (problem.scratch(), vec![0.0; n]),
                |(s, l), (g, c)| *c = problem.evaluate_uncounted(g, s, l),
            ),
        }
        Ok(())
    }
}
