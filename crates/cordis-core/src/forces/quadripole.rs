//! `quadripole` and `position_transmitter` (thesis §5.4.2-5.4.3, eq 5.1-5.2, SPEC §2.5): a
//! coupling between two dipoles, usually in two worlds. Dipole 1 = (a, b), dipole 2 = (c, d):
//!
//! ```text
//! Δ(n) = |x_b - x_a| - r |x_d - x_c|                             m
//! F(n) = -K Δ(n) - Z (Δ(n) - Δ(n-1))                             N (Z in N/m: per step)
//! F_b += F u1,  F_a -= F u1;   F_d -= r F u2,  F_c += r F u2      (u = unit vectors a→b, c→d)
//! ```
//!
//! with `Δ(-1) = Δ(0)`. With Z = 0 the forces are `-∇(½ K Δ²)`: the coupling stores energy
//! and gives it back, so two undamped worlds joined by it conserve their summed energy. The
//! damping is written on Δ's change per step (the thesis' discrete form), so it needs no dt
//! and means the same whatever the worlds' time steps. `Δ(n-1)` is state carried from step to
//! step (one f64 per instance, in the caller's state vector).
//!
//! A `position_transmitter` computes the same F but applies only dipole 2's forces: dipole 1
//! is read, not pushed, so dipole 2's length follows `|x_b - x_a| / r` (a sensor, thesis
//! §5.4.3).

use super::{unit_and_length, Run};
use crate::Vec3;

/// Instances in runs of one type; a run's parameters are `p[run.param..]` = stiffness K (N/m),
/// damping Z (N/m, on Δ's change per step), ratio r (dimensionless).
#[derive(Clone, Debug, Default)]
pub struct QuadripolePass {
    pub runs: Vec<Run>,
    /// `[a, b, c, d]` of each instance.
    pub quads: Vec<[u32; 4]>,
}

impl QuadripolePass {
    pub fn len(&self) -> usize {
        self.quads.len()
    }

    pub fn is_empty(&self) -> bool {
        self.quads.is_empty()
    }

    /// One f64 per instance: Δ(n-1).
    pub fn state_len(&self) -> usize {
        self.quads.len()
    }

    /// Δ(-1) = Δ(0) at positions `x0` (m).
    pub fn reset(&self, p: &[f64], x0: &[Vec3], state: &mut [f64]) {
        for r in &self.runs {
            let ratio = p[r.param + 2];
            let quads = &self.quads[r.start..r.end];
            for (prev, q) in state[r.start..r.end].iter_mut().zip(quads) {
                *prev = delta(q, ratio, x0).0;
            }
        }
    }

    /// Adds the forces at positions `x` to `f` (both dipoles when `BOTH`, dipole 2 only for a
    /// position transmitter) and advances each `Δ(n-1)` in `state` to Δ(n).
    pub fn accumulate<const BOTH: bool>(
        &self,
        p: &[f64],
        x: &[Vec3],
        f: &mut [Vec3],
        state: &mut [f64],
    ) {
        for r in &self.runs {
            let (k, z, ratio) = (p[r.param], p[r.param + 1], p[r.param + 2]);
            let quads = &self.quads[r.start..r.end];
            for (prev, q) in state[r.start..r.end].iter_mut().zip(quads) {
                let (d, u1, u2) = delta(q, ratio, x);
                let force = -k * d - z * (d - *prev);
                *prev = d;
                if BOTH {
                    let f1 = u1 * force;
                    f[q[1] as usize] += f1;
                    f[q[0] as usize] -= f1;
                }
                let f2 = u2 * (ratio * force);
                f[q[3] as usize] -= f2;
                f[q[2] as usize] += f2;
            }
        }
    }
}

/// Δ = L1 - r L2 (m) and the dipoles' unit vectors a→b, c→d.
#[inline(always)]
fn delta(q: &[u32; 4], ratio: f64, x: &[Vec3]) -> (f64, Vec3, Vec3) {
    let [a, b, c, d] = q.map(|i| i as usize);
    let (u1, l1) = unit_and_length(&(x[b] - x[a]));
    let (u2, l2) = unit_and_length(&(x[d] - x[c]));
    (l1 - ratio * l2, u1, u2)
}
