//! The one interface every identification strategy implements (argmin-style): the run loop in
//! [`crate::run::executor`] drives it, counts evaluations, logs, checkpoints and stops it.

use crate::error::CostError;
use crate::problem::Problem;

/// Summary of the current generation, for logs and progress.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GenerationStats {
    pub best_cost: f64,
    /// Mean cost of the population (finite members only).
    pub mean_cost: f64,
    /// Mean mutability (step size in internal coordinates) of the population.
    pub mean_mutability: f64,
}

pub trait Strategy: Send {
    /// The name used by `--strategy`.
    fn name(&self) -> &'static str;

    /// Creates and evaluates the initial population (generation 0).
    fn init(&mut self, problem: &Problem, seed: u64);

    /// Produces and evaluates generation `generation` (1, 2, …). All randomness must come from
    /// [`crate::run::rng::stream`]`(seed, generation, …)` so that a run depends on its seed only.
    fn next_generation(&mut self, problem: &Problem, seed: u64, generation: u64);

    /// [`Strategy::next_generation`] for strategies whose one generation can take long (a
    /// window of the output-error fit): `halt()` turns true when the run must stop (Ctrl-C,
    /// the time limit), and the strategy then ends the generation early, its best so far kept
    /// and its state still resumable. The run loop calls this one; the default ignores `halt`.
    fn next_generation_until(
        &mut self,
        problem: &Problem,
        seed: u64,
        generation: u64,
        halt: &dyn Fn() -> bool,
    ) {
        let _ = halt;
        self.next_generation(problem, seed, generation);
    }

    /// True when the strategy has nothing left to do (an exact solver after its solve): the
    /// run loop then stops, as [`crate::run::executor::StopReason::Converged`] only when
    /// [`Strategy::report`] says its criterion was met and every unknown determined.
    fn finished(&self) -> bool {
        false
    }

    /// Why the strategy could not produce an estimate at all (an exact solve that failed, a
    /// fit that diverged): the run is then an error, never its starting point handed back as a
    /// result. Read after [`Strategy::init`] and after every generation.
    fn failure(&self) -> Option<String> {
        None
    }

    /// The estimated initial state of the free particles (positions, m, and velocities, m/s)
    /// of every take, in take order, for strategies that estimate it along with the
    /// parameters (an output-error estimator); the session writes each into a copy of the
    /// identified scene (take 0's is the identified scene's). Empty (the default) keeps the
    /// scene's.
    fn initial_states(&self) -> Vec<crate::report::InitialState> {
        Vec::new()
    }

    /// The cost function changed (a progressive horizon grew): re-evaluate every stored cost.
    /// Strategies that keep costs across generations must override this.
    fn reevaluate(&mut self, problem: &Problem) {
        let _ = problem;
    }

    /// The best genome (internal coordinates) found so far and its global cost.
    fn best(&self) -> (&[f64], f64);

    fn stats(&self) -> GenerationStats;

    /// The whole state, for a checkpoint.
    fn save_state(&self) -> serde_json::Value;

    /// Restores a state written by [`Strategy::save_state`].
    fn load_state(&mut self, problem: &Problem, state: &serde_json::Value)
        -> Result<(), CostError>;

    /// Whether [`Strategy::emigrants`] and [`Strategy::immigrate`] work: the strategy can run
    /// as an island of [`crate::strategies::islands::Islands`].
    fn migrates(&self) -> bool {
        false
    }

    /// Copies of the `count` best individuals (fewer if the population is smaller), best
    /// first, in the strategy's own format: what [`Strategy::immigrate`] of another island
    /// running the same strategy on the same problem reads.
    fn emigrants(&self, count: usize) -> Vec<serde_json::Value> {
        let _ = count;
        Vec::new()
    }

    /// Replaces the worst individuals by `migrants` (from [`Strategy::emigrants`]), costs
    /// included: no evaluation, so the run stays deterministic and cheap.
    fn immigrate(
        &mut self,
        problem: &Problem,
        migrants: &[serde_json::Value],
    ) -> Result<(), CostError> {
        let _ = (problem, migrants);
        Err(CostError::state(format!(
            "strategy `{}` cannot run on islands",
            self.name()
        )))
    }

    /// When the strategy minimises a cost of its own instead of the problem's (output-error:
    /// the replay's weighted squared position residuals over the whole takes, m²), that cost
    /// at [`Strategy::best`] and its number of terms: the run summary's `cost` and `rmse` are
    /// then these, what the estimate was chosen by. `None`: the problem's cost.
    fn own_cost(&self) -> Option<(f64, usize)> {
        None
    }

    /// What the strategy wants the run summary to say beside the numbers (an exact solver's
    /// condition number and warnings, a local solver's restarts); empty for nothing.
    fn report(&self) -> crate::report::Report {
        crate::report::Report::default()
    }
}

// The exact-float JSON forms live in `crate::run::float_json`; these paths stay valid.
pub use crate::run::float_json::{bits, lossless};
