//! The stateful passes (SPEC §2.5): force passes whose output depends on state carried from
//! step to step besides the positions — TGR tendons driven by signals, and later quadripole
//! memories and the like.
//!
//! # Where the state lives
//!
//! A [`crate::Plan`] is immutable and shared between threads (identification evaluates one
//! plan on many parameter vectors at once), so the passes here hold only indices and
//! constants. Their state is one flat `Vec<f64>` owned by whoever runs the plan: the
//! simulator keeps it in [`crate::plan::Scratch::state`] next to the step counter
//! `Scratch::frame`; the cost (cordis-es) keeps its own copy and advances it along the
//! observed frames. Each pass owns a fixed slice of that vector (its `state_len`), in the
//! order of the fields below.
//!
//! # Protocol
//!
//! [`Stateful::reset`] sets the state of frame 0; [`Stateful::accumulate`] is called once per
//! step n, after the stateless passes, with the positions and velocities of frame n: it adds
//! its forces and advances the state to frame n+1. Signals read the main world's time
//! `t_n = n dt`.
//!
//! To add a stateful kind: a pass in its own file with `state_len`, `reset` and an
//! `accumulate` that advances its slice; a field here; one line in each method below.

use super::tgr::TgrPass;
use crate::signal::Signal;
use crate::Vec3;

#[derive(Clone, Debug, Default)]
pub struct Stateful {
    /// The scene's signals, in scene order (passes refer to them by index).
    pub signals: Vec<Signal>,
    pub tgrs: TgrPass,
}

impl Stateful {
    /// True when the scene has no stateful pass: steps then skip this machinery entirely.
    pub fn is_empty(&self) -> bool {
        self.tgrs.is_empty()
    }

    /// Number of instances (for link counts).
    pub fn len(&self) -> usize {
        self.tgrs.len()
    }

    /// Number of f64 of state.
    pub fn state_len(&self) -> usize {
        self.tgrs.state_len()
    }

    /// Sets `state` (length [`Stateful::state_len`]) to frame 0's from the parameters `p` and
    /// the initial positions `x0` (m).
    pub fn reset(&self, _p: &[f64], _x0: &[Vec3], state: &mut [f64]) {
        let nt = self.tgrs.state_len();
        self.tgrs.reset(&mut state[..nt]);
    }

    /// Adds the stateful passes' forces at frame `n` (positions `x`, velocities `v`) to `f`
    /// and advances `state` from frame n to n+1; `dt` in s.
    #[allow(clippy::too_many_arguments)]
    pub fn accumulate(
        &self,
        p: &[f64],
        n: usize,
        dt: f64,
        x: &[Vec3],
        v: &[Vec3],
        f: &mut [Vec3],
        state: &mut [f64],
    ) {
        let t = n as f64 * dt;
        let nt = self.tgrs.state_len();
        self.tgrs
            .accumulate(p, &self.signals, t, dt, x, v, f, &mut state[..nt]);
    }
}
