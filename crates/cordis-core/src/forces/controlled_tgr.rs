//! The central-control muscle (thesis §5.4, SPEC §7.2): a [`tgr`](super::tgr) whose tendon is
//! driven by a controller world instead of (or besides) a signal, and whose reaction the
//! controller feels.
//!
//! The thesis' TGR is operated by a hand on its tendon; §5.4.2 replaces the hand by a
//! *physical* controller living in another world with its own time. Here the controller is a
//! dipole `(c, d)` of that world, of length `a = |x_d - x_c|`, and the tendon's spring — anchored
//! at 0 in a signal-driven TGR — is anchored on `a`: a position transmitter from the controller
//! into the tendon that does not cut the reaction (a quadripole between the dipole and the
//! tendon's 1-D position, thesis eq 5.1 with ratio 1):
//!
//! ```text
//! f(n)   = K (L(n) - (l0 + y(n))) + Z s(n)                 the muscle's tension, N (as a TGR)
//! h(n)   = K_t (y(n) - a(n)) + Z_t ((y(n) - a(n)) - (y(n-1) - a(n-1))) / dt
//! y(n+1) = 2y(n) - y(n-1) + dt²/m_t (S(n dt) + f(n) - h(n))   the tendon (S = 0 without signal)
//! F_d   += h u_cd,   F_c -= h u_cd                          the reaction on the controller
//! ```
//!
//! with `dt` the muscle's world's time step, `u_cd` the unit vector c→d, and the tendon starting
//! at its anchor, at rest: `y(0) = y(-1) = a(0)`, `a(-1) = a(0)`. So the muscle's rest length
//! `l0 + y` follows `l0 + a` (within `(S + f)/K_t` at equilibrium): the controller's dipole is
//! the muscle's length, offset by l0, and the controller is pulled by the tendon with the
//! force h, which at equilibrium is the muscle's tension f — the proprioception of §5.4.1
//! reaching the controller. With `Z = Z_t = 0` and no signal the coupling conserves the summed
//! energy of both worlds (`½K(L - l0 - y)² + ½K_t(y - a)² + ½ m_t ẏ²` stored between them; the
//! test `an_undamped_central_muscle_conserves_both_worlds_energy`).
//!
//! The controller's particles lie in one world other than the muscle's (validated: thesis
//! §5.4.2, "controller and controlled must belong to different mechanical universes"); the
//! reaction moves them with their own world's `dt`.
//!
//! State per instance (in the caller's state vector, like [`super::tgr`]'s): `y(n)`, `y(n-1)`,
//! `a(n-1)`: three f64.

use super::tgr::link_force;
use super::{unit_and_length, Run};
use crate::signal::Signal;
use crate::Vec3;

/// f64 of state per instance: `y(n)`, `y(n-1)`, `a(n-1)`.
pub const STATE_PER_CONTROLLED_TGR: usize = 3;

/// Controlled TGR instances in runs of one type and world. A run's parameters are the TGR's:
/// `p[run.param..]` = K (N/m), l0 (m), Z (N·s/m), m_t (kg), K_t (N/m), Z_t (N·s/m).
#[derive(Clone, Debug, Default)]
pub struct ControlledTgrPass {
    pub runs: Vec<Run>,
    /// Each run's type's signal (index into the plan's signals), if it has one.
    pub signals: Vec<Option<usize>>,
    /// Time step of each run's (the muscle's) world, s.
    pub dts: Vec<f64>,
    /// Slots of each run's type's `tendon_position` and `tendon_velocity` (see
    /// [`super::tgr::initial_tendon`]): the tendon's start about its anchor.
    pub initial: Vec<[Option<usize>; 2]>,
    /// `[M1, M2]` of each instance.
    pub pairs: Vec<[u32; 2]>,
    /// The controller dipole `[c, d]` of each instance.
    pub controllers: Vec<[u32; 2]>,
}

impl ControlledTgrPass {
    pub fn len(&self) -> usize {
        self.pairs.len()
    }

    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }

    pub fn state_len(&self) -> usize {
        STATE_PER_CONTROLLED_TGR * self.pairs.len()
    }

    /// Each tendon at its anchor and at rest, `y(0) = y(-1) = a(-1) = a(0)` the controller
    /// dipole's length at positions `x0` (m), unless its type gives `tendon_position` y₀ and
    /// `tendon_velocity` v₀: then `y(0) = a(0) + y₀`, `y(-1) = y(0) - v₀ dt`.
    pub fn reset(&self, p: &[f64], x0: &[Vec3], state: &mut [f64]) {
        for ((r, slots), &dt) in self.runs.iter().zip(&self.initial).zip(&self.dts) {
            for m in r.start..r.end {
                let s = &mut state[STATE_PER_CONTROLLED_TGR * m..][..STATE_PER_CONTROLLED_TGR];
                let a = anchor(self.controllers[m], x0).1;
                let (y, y_prev) = super::tgr::initial_tendon(p, *slots, dt, a);
                s.copy_from_slice(&[y, y_prev, a]);
            }
        }
    }

    /// Adds every muscle's link force and every controller's reaction at positions `x`,
    /// velocities `v` to `f`, and advances each tendon from step n to n+1 (signals read at
    /// `t = n dt` of the muscle's world).
    #[allow(clippy::too_many_arguments)]
    pub fn accumulate(
        &self,
        p: &[f64],
        signals: &[Signal],
        n: usize,
        x: &[Vec3],
        v: &[Vec3],
        f: &mut [Vec3],
        state: &mut [f64],
    ) {
        for ((r, sg), &dt) in self.runs.iter().zip(&self.signals).zip(&self.dts) {
            let dt2 = dt * dt;
            let q = &p[r.param..r.param + 6];
            let (mt, kt, zt) = (q[3], q[4], q[5]);
            let command = sg.map_or(0.0, |s| signals[s].value(n as f64 * dt));
            for m in r.start..r.end {
                let s = &mut state[STATE_PER_CONTROLLED_TGR * m..][..STATE_PER_CONTROLLED_TGR];
                let (y, y_prev, a_prev) = (s[0], s[1], s[2]);
                let tension = link_force(q, self.pairs[m], y, x, v, f);
                let (u, a) = anchor(self.controllers[m], x);
                let stretch = y - a;
                let hold = kt * stretch + zt * (stretch - (y_prev - a_prev)) / dt;
                let [c, d] = self.controllers[m].map(|i| i as usize);
                let fd = u * hold;
                f[d] += fd;
                f[c] -= fd;
                let force = command + tension - hold;
                s[0] = (2.0 * y - y_prev) + dt2 / mt * force;
                s[1] = y;
                s[2] = a;
            }
        }
    }
}

/// The controller dipole's unit vector c→d and length `a` (m) at positions `x`.
#[inline(always)]
fn anchor([c, d]: [u32; 2], x: &[Vec3]) -> (Vec3, f64) {
    unit_and_length(&(x[d as usize] - x[c as usize]))
}
