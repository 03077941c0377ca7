//! Hook for link state that is not a position: tendon lengths driven by signals, controller
//! worlds, a quadripole's `Δ(t-1)` (SPEC §2.5). SPEC §3 says the cost advances such state
//! *along the observed frames*, so that a short-term prediction of frame t starts from the state
//! the real motion had at t-1.
//!
//! No pass has hidden state yet (muscles and worlds come in a later issue):
//! [`crate::cost::Objective`] holds an empty list of them and calls the hook in its frame loops,
//! so that adding one needs no change to the loops' structure.

use cordis_core::Vec3;
use std::fmt;

/// A stateful force pass, advanced by the cost's frame loops.
///
/// Contract for implementers: the state is `state_len()` f64 kept in the evaluation's scratch
/// (never in `self`, which is shared between threads). `reset` sets it for frame 0;
/// `add_forces` is called once per predicted step, after the link passes, with the positions
/// and velocities the step starts from, and must advance the state by one step. For the short
/// cost those are the observed frames in order, so the state follows the real motion; a
/// rollout that starts at a real frame must start from a copy of that observed state.
pub trait HiddenState: fmt::Debug + Send + Sync {
    /// Number of f64 of per-evaluation state.
    fn state_len(&self) -> usize;
    /// Sets the state at frame 0 from the parameters.
    fn reset(&self, p: &[f64], state: &mut [f64]);
    /// Adds this pass's forces (N) at positions `x` (m) and velocities `v` (m/s) to `f`, then
    /// advances `state` by one step.
    fn add_forces(&self, p: &[f64], x: &[Vec3], v: &[Vec3], f: &mut [Vec3], state: &mut [f64]);
}
