//! The stateful passes (SPEC §2.5): force passes whose output depends on state carried from
//! step to step besides the positions — TGR tendons driven by signals or by a controller world,
//! quadripole memories.
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
//! its forces and advances the state to frame n+1. A pass steps with its own world's time
//! step, and signals read that world's time `t_n = n dt_w` (every world takes one step per
//! frame).
//!
//! To add a stateful kind: a pass in its own file with `state_len`, `reset` and an
//! `accumulate` that advances its slice; a field here; one line in each method below.

use super::controlled_tgr::ControlledTgrPass;
use super::force_transmitter::ForceTransmitterPass;
use super::quadripole::QuadripolePass;
use super::tgr::TgrPass;
use crate::signal::Signal;
use crate::Vec3;

#[derive(Clone, Debug, Default)]
pub struct Stateful {
    /// The scene's signals, in scene order (passes refer to them by index).
    pub signals: Vec<Signal>,
    pub tgrs: TgrPass,
    /// Quadripoles: one f64 of state each, Δ(n-1).
    pub quadripoles: QuadripolePass,
    /// Position transmitters: quadripoles that push dipole 2 only; Δ(n-1) too.
    pub position_transmitters: QuadripolePass,
    /// Force transmitters (stateless, kept with the couplings they belong to).
    pub force_transmitters: ForceTransmitterPass,
    /// TGRs whose tendon a controller world drives: `y(n)`, `y(n-1)`, `a(n-1)` each.
    pub controlled_tgrs: ControlledTgrPass,
}

impl Stateful {
    /// True when the scene has no stateful pass: steps then skip this machinery entirely.
    pub fn is_empty(&self) -> bool {
        self.tgrs.is_empty()
            && self.quadripoles.is_empty()
            && self.position_transmitters.is_empty()
            && self.force_transmitters.is_empty()
            && self.controlled_tgrs.is_empty()
    }

    /// Number of instances (for link counts).
    pub fn len(&self) -> usize {
        self.tgrs.len()
            + self.quadripoles.len()
            + self.position_transmitters.len()
            + self.force_transmitters.len()
            + self.controlled_tgrs.len()
    }

    /// Number of f64 of state.
    pub fn state_len(&self) -> usize {
        self.tgrs.state_len()
            + self.quadripoles.state_len()
            + self.position_transmitters.state_len()
            + self.controlled_tgrs.state_len()
    }

    /// `state` split into each pass's slice: TGRs, quadripoles, position transmitters,
    /// controlled TGRs.
    fn slices<'s>(&self, state: &'s mut [f64]) -> [&'s mut [f64]; 4] {
        let (tgr, rest) = state.split_at_mut(self.tgrs.state_len());
        let (quad, rest) = rest.split_at_mut(self.quadripoles.state_len());
        let (pos, controlled) = rest.split_at_mut(self.position_transmitters.state_len());
        [tgr, quad, pos, controlled]
    }

    /// Sets `state` (length [`Stateful::state_len`]) to frame 0's from the parameters `p` and
    /// the initial positions `x0` (m).
    pub fn reset(&self, p: &[f64], x0: &[Vec3], state: &mut [f64]) {
        let [tgr, quad, pos, controlled] = self.slices(state);
        self.tgrs.reset(p, tgr);
        self.quadripoles.reset(p, x0, quad);
        self.position_transmitters.reset(p, x0, pos);
        self.controlled_tgrs.reset(p, x0, controlled);
    }

    /// Adds the stateful passes' forces at frame `n` (positions `x`, velocities `v`) to `f`
    /// and advances `state` from frame n to n+1.
    pub fn accumulate(
        &self,
        p: &[f64],
        n: usize,
        x: &[Vec3],
        v: &[Vec3],
        f: &mut [Vec3],
        state: &mut [f64],
    ) {
        let [tgr, quad, pos, controlled] = self.slices(state);
        self.tgrs.accumulate(p, &self.signals, n, x, v, f, tgr);
        self.quadripoles.accumulate::<true>(p, x, f, quad);
        self.position_transmitters.accumulate::<false>(p, x, f, pos);
        self.force_transmitters.accumulate(p, x, v, f);
        if !self.controlled_tgrs.is_empty() {
            let signals = &self.signals;
            self.controlled_tgrs
                .accumulate(p, signals, n, x, v, f, controlled);
        }
    }
}
