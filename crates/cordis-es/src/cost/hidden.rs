//! Hook for link state that is not a position: tendon lengths driven by signals, controller
//! worlds, a quadripole's `Δ(t-1)` (SPEC §2.5). SPEC §3 says the cost advances such state
//! *along the observed frames*, so that a short-term prediction of frame t starts from the state
//! the real motion had at t-1.
//!
//! [`crate::cost::Objective`] holds one [`HiddenState`] per group of stateful passes (today the
//! core's [`Stateful`] passes of the plan, through [`PlanStateful`]) and calls it in its frame
//! loops:
//!
//! - short cost: the state is reset at frame 0 and advanced by one step per observed frame
//!   0, 1, …, T-2, each step from the observed positions and velocities of that frame; the
//!   prediction of frame t uses the state at t-1.
//! - rollouts (`horizon`, `progressive`, `long`, `harmonic`): a second copy of the state is
//!   driven along the observed frames the same way; a window that starts from the real frames
//!   t0-2, t0-1 starts from a copy of that observed-driven state at t0-1, then advances with
//!   its own predicted positions.
//!
//! The observed velocity of frame 0 is taken as zero (a trajectory has no x(-1)); this only
//! matters for a damped stateful pass (a TGR with `damping` ≠ 0) whose scene does not start at
//! rest. A tendon's start is the TGR type's `tendon_position` / `tendon_velocity` (default at
//! rest), known or identified: what a take cropped mid-motion needs (docs/identification.md).

use cordis_core::forces::stateful::Stateful;
use cordis_core::Vec3;
use std::fmt;

/// A stateful force pass, advanced by the cost's frame loops.
///
/// Contract for implementers: the state is `state_len()` f64 kept in the evaluation's scratch
/// (never in `self`, which is shared between threads). `reset` sets it for frame 0;
/// `add_forces` is called once per step from frame n with the positions and velocities the
/// step starts from, and must advance the state from n to n+1.
pub trait HiddenState: fmt::Debug + Send + Sync {
    /// Number of f64 of per-evaluation state.
    fn state_len(&self) -> usize;
    /// Sets the state at frame 0 from the parameters and the initial positions (m).
    fn reset(&self, p: &[f64], x0: &[Vec3], state: &mut [f64]);
    /// Adds this pass's forces (N) at frame `n`, positions `x` (m) and velocities `v` (m/s) to
    /// `f`, then advances `state` by one step.
    fn add_forces(
        &self,
        p: &[f64],
        n: usize,
        x: &[Vec3],
        v: &[Vec3],
        f: &mut [Vec3],
        state: &mut [f64],
    );
}

/// The plan's stateful passes ([`Stateful`]: TGR tendons…) as a [`HiddenState`]: the same
/// kernels as a simulator step, so a trajectory simulated with the true parameters has a
/// short cost of exactly 0.
#[derive(Clone, Debug)]
pub struct PlanStateful {
    /// The passes, each stepping with its own world's time step.
    pub passes: Stateful,
}

impl HiddenState for PlanStateful {
    fn state_len(&self) -> usize {
        self.passes.state_len()
    }

    fn reset(&self, p: &[f64], x0: &[Vec3], state: &mut [f64]) {
        self.passes.reset(p, x0, state);
    }

    fn add_forces(
        &self,
        p: &[f64],
        n: usize,
        x: &[Vec3],
        v: &[Vec3],
        f: &mut [Vec3],
        state: &mut [f64],
    ) {
        self.passes.accumulate(p, n, x, v, f, state);
    }
}
