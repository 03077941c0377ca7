//! `tgr`: the force-feedback gesture transducer (thesis §5.4.1, SPEC §2.5), the central-control
//! muscle. A sensori-motor link between M1 (i) and M2 (j) whose rest length `l0 + y` follows a
//! tendon, a 1-D mass at position y (m) driven by a command signal S (N):
//!
//! ```text
//! f(n)   = K (L(n) - (l0 + y(n))) + Z s(n)                          link tension, N
//! F_i   += f u,  F_j -= f u                                          as a spring
//! y(n+1) = 2y(n) - y(n-1) + dt²/m_t (S(t_n) + f(n) - K_t y(n) - Z_t (y(n) - y(n-1))/dt)
//! ```
//!
//! with `t_n = n dt` and `y(0) = y(-1) = 0`, `dt` the time step of the TGR's world (M1 and M2
//! lie in one world: validated), so a TGR in a controller world steps its tendon and reads its
//! signal on that world's own clock. The tendon feels the tension f: a stretched link
//! pulls its rest length longer, so the command "feels" the environment (proprioception).
//! With `K_t > 0` the tendon settles where `S + f = K_t y`, so a slow signal sets the rest
//! length `l0 + S/K_t` of a link at rest (a position command); with `K_t = 0` it is a force
//! command, `f ≈ -S`.
//!
//! The tendon's `(y(n), y(n-1))` is state carried from step to step: it lives in the caller's
//! state vector ([`crate::plan::Scratch::state`]), two f64 per instance, never in the plan.

use super::{unit_and_length, Run};
use crate::signal::Signal;
use crate::Vec3;

/// TGR instances in runs of one type. A run's parameters are `p[run.param..]` = stiffness K
/// (N/m), rest length l0 (m), damping Z (N·s/m), tendon mass m_t (kg), tendon stiffness K_t
/// (N/m), tendon damping Z_t (N·s/m).
#[derive(Clone, Debug, Default)]
pub struct TgrPass {
    pub runs: Vec<Run>,
    /// Index into the plan's signals of each run's type's signal.
    pub signals: Vec<usize>,
    /// Time step of each run's world, s (runs are grouped by type and world).
    pub dts: Vec<f64>,
    /// Slots in `p` of each run's type's `tendon_position` (m) and `tendon_velocity` (m/s),
    /// when it has them (see [`initial_tendon`]).
    pub initial: Vec<[Option<usize>; 2]>,
    pub pairs: Vec<[u32; 2]>,
}

/// f64 of state per TGR instance: `y(n)`, `y(n-1)`.
pub const STATE_PER_TGR: usize = 2;

impl TgrPass {
    pub fn len(&self) -> usize {
        self.pairs.len()
    }

    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }

    pub fn state_len(&self) -> usize {
        STATE_PER_TGR * self.pairs.len()
    }

    /// Tendons at frame 0: `y(0) = y₀`, `y(-1) = y₀ - v₀ dt` from each type's
    /// `tendon_position` and `tendon_velocity`, at rest at 0 without them.
    pub fn reset(&self, p: &[f64], state: &mut [f64]) {
        state.fill(0.0);
        for ((r, slots), &dt) in self.runs.iter().zip(&self.initial).zip(&self.dts) {
            let (y, y_prev) = initial_tendon(p, *slots, dt, 0.0);
            for m in r.start..r.end {
                state[2 * m] = y;
                state[2 * m + 1] = y_prev;
            }
        }
    }

    /// Adds every TGR's link force at positions `x`, velocities `v` to `f`, and advances each
    /// tendon from step n to n+1 (each run's signal read at `t = n dt` of its world).
    /// `state` = `[y, y_prev]` per instance, in pass order.
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
        for ((r, &sg), &dt) in self.runs.iter().zip(&self.signals).zip(&self.dts) {
            let dt2 = dt * dt;
            let q = &p[r.param..r.param + 6];
            let (mt, kt, zt) = (q[3], q[4], q[5]);
            // One signal per type and world: evaluated once per run.
            let command = signals[sg].value(n as f64 * dt);
            for m in r.start..r.end {
                let (y, y_prev) = (state[2 * m], state[2 * m + 1]);
                let tension = link_force(q, self.pairs[m], y, x, v, f);
                let force = command + tension - kt * y - zt * (y - y_prev) / dt;
                state[2 * m + 1] = y;
                state[2 * m] = (2.0 * y - y_prev) + dt2 / mt * force;
            }
        }
    }
}

/// A tendon's `(y(0), y(-1))` (m) about its anchor `a` (m): `a + y₀` and `a + y₀ - v₀ dt`
/// from the slots of `tendon_position` y₀ and `tendon_velocity` v₀ (absent: 0), so a type
/// without them starts at rest on its anchor, bit for bit as before they existed.
#[inline]
pub(crate) fn initial_tendon(
    p: &[f64],
    [y0, v0]: [Option<usize>; 2],
    dt: f64,
    a: f64,
) -> (f64, f64) {
    let y = y0.map_or(a, |k| a + p[k]);
    let y_prev = v0.map_or(y, |k| y - p[k] * dt);
    (y, y_prev)
}

/// Adds the force of a TGR's link between `[i, j]` whose rest length is `l0 + y` (m) to `f`
/// and returns its tension `f = K (L - (l0 + y)) + Z s` (N); `q` = the type's parameters
/// `[K, l0, Z, …]`.
#[inline(always)]
pub(crate) fn link_force(
    q: &[f64],
    [i, j]: [u32; 2],
    y: f64,
    x: &[Vec3],
    v: &[Vec3],
    f: &mut [Vec3],
) -> f64 {
    let (k, l0, z) = (q[0], q[1], q[2]);
    let (i, j) = (i as usize, j as usize);
    let (u, l) = unit_and_length(&(x[j] - x[i]));
    let mut tension = k * (l - (l0 + y));
    if z != 0.0 {
        tension += z * (v[j] - v[i]).dot(&u);
    }
    let fi = u * tension;
    f[i] += fi;
    f[j] -= fi;
    tension
}
