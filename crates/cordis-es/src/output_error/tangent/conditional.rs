//! Conditional links (`cordis_core::forces::conditional`): a spring between every pair of the
//! type's groups closer than its range, differentiable between switches.
//!
//! At step n the pairs are those the core's own test finds active at `x(n)` (the same grid,
//! the same comparison, so the same set), and each active pair is a spring with the type's
//! K, l0, Z and quadratic viscosity Z₂: its derivatives are [`super::spring`]'s. The set is
//! constant under small changes of the state and of K, l0, Z, Z₂ as long as no pair's length
//! crosses the range at some step, so the recursion is exact between switches. A switch is a
//! step of the force (`K (range - l0) + Z s + Z₂ s|s|` appears or vanishes), so under noise the
//! cost has steps where a pair's crossing moves across a frame, as a plane's landing does.
//!
//! **The range itself** moves the cost only in steps (∂x/∂range = 0 wherever it is defined):
//! Gauss–Newton has no slope along it. [`super::Tangent::supports`] therefore refuses an
//! unknown range by name; the `hybrid` strategy brackets it on the short cost, and the
//! output-error fit then takes it as known. (An interval search of the range around the
//! output-error fit, as `exact/range_sweep.rs` does around the exact solvers, would cost one
//! whole fit per trial range; not done.)
//!
//! The matrix-free linearisation stores, per step and pass, the active pairs and one
//! [`super::spring::LINK`] record each: the set changes from step to step, so its storage is a
//! list with offsets.

use cordis_core::forces::conditional::ConditionalPass;
use cordis_core::forces::grid::Grid;
use cordis_core::Vec3;

use super::no_column::NONE;
use super::spring::{self, spring_link, LINK};

/// Calls `visit(i, j, link)` for every pair of `c` active at `x` (force on i, minus on j).
pub(super) fn each_pair(
    c: &ConditionalPass,
    p: &[f64],
    (x, v): (&[Vec3], &[Vec3]),
    grid: &mut Grid,
    mut visit: impl FnMut(usize, usize, spring::SpringLink),
) {
    let (k, l0, z) = (p[c.param], p[c.param + 1], p[c.param + 2]);
    let z2 = c.quadratic.map_or(0.0, |q| p[q]);
    c.for_each_active_pair(p, x, grid, |i, j, _| {
        visit(i, j, spring_link(&x[j], &x[i], &v[j], &v[i], k, l0, z, z2));
    });
}

/// The columns of pass `c`'s (K, l0, Z, Z₂).
pub(super) fn slots(c: &ConditionalPass, of_slot: &[usize]) -> [usize; 4] {
    [
        of_slot[c.param],
        of_slot[c.param + 1],
        of_slot[c.param + 2],
        c.quadratic.map_or(NONE, |q| of_slot[q]),
    ]
}

/// The active pairs of every step of a rollout, with their [`LINK`] records: pass `k`'s pairs
/// at step t are `pairs[start[t·passes + k]..start[t·passes + k + 1]]`.
#[derive(Clone, Debug, Default)]
pub(crate) struct Pairs {
    passes: usize,
    pairs: Vec<[u32; 2]>,
    records: Vec<f64>,
    start: Vec<usize>,
}

impl Pairs {
    /// Empties the store for a rollout of `passes` conditional passes.
    pub fn reset(&mut self, passes: usize) {
        self.passes = passes;
        self.pairs.clear();
        self.records.clear();
        self.start.clear();
        self.start.push(0);
    }

    /// Appends one step: every pass's active pairs at `(x, v)`.
    pub fn push_step(
        &mut self,
        passes: &[ConditionalPass],
        p: &[f64],
        xv: (&[Vec3], &[Vec3]),
        grids: &mut [Grid],
    ) {
        for (c, grid) in passes.iter().zip(grids) {
            each_pair(c, p, xv, grid, |i, j, lk| {
                self.pairs.push([i as u32, j as u32]);
                let at = self.records.len();
                self.records.resize(at + LINK, 0.0);
                lk.store(&mut self.records[at..]);
            });
            self.start.push(self.pairs.len());
        }
    }

    /// Pass `k`'s pairs and records at step t.
    fn step(&self, t: usize, k: usize) -> (&[[u32; 2]], &[f64]) {
        let (a, b) = (
            self.start[t * self.passes + k],
            self.start[t * self.passes + k + 1],
        );
        (&self.pairs[a..b], &self.records[a * LINK..b * LINK])
    }
}

/// Matrix-free forward at step t: every active pair as a spring ([`spring::forward`]).
#[allow(clippy::too_many_arguments)]
pub(crate) fn forward(
    passes: &[ConditionalPass],
    store: &Pairs,
    t: usize,
    p: &[f64],
    of_slot: &[usize],
    w: usize,
    cs: (&[f64], &[f64]),
    df: &mut [f64],
    dth: &[f64],
) {
    for (k, c) in passes.iter().enumerate() {
        let slots = slots(c, of_slot);
        let (pairs, recs) = store.step(t, k);
        for (&[i, j], d) in pairs.iter().zip(recs.chunks_exact(LINK)) {
            let ends = (i as usize, Some(j as usize));
            spring::forward(d, p[c.param], &slots, ends, w, cs, df, dth);
        }
    }
}

/// Matrix-free adjoint at step t ([`spring::adjoint`] per active pair).
#[allow(clippy::too_many_arguments)]
pub(crate) fn adjoint(
    passes: &[ConditionalPass],
    store: &Pairs,
    t: usize,
    p: &[f64],
    of_slot: &[usize],
    w: usize,
    phi: &[f64],
    (na, psi): (&mut [f64], &mut [f64]),
    grad: &mut [f64],
) {
    for (k, c) in passes.iter().enumerate() {
        let slots = slots(c, of_slot);
        let (pairs, recs) = store.step(t, k);
        for (&[i, j], d) in pairs.iter().zip(recs.chunks_exact(LINK)) {
            let ends = (i as usize, Some(j as usize));
            spring::adjoint(
                d,
                p[c.param],
                &slots,
                ends,
                w,
                phi,
                (&mut *na, &mut *psi),
                grad,
            );
        }
    }
}

/// The preconditioner's local model at step t: each active pair's `-A` and `-Z' u uᵀ` on both
/// ends' 3×3 blocks.
pub(crate) fn local(store: &Pairs, t: usize, kii: &mut [f64], cii: &mut [f64]) {
    for k in 0..store.passes {
        let (pairs, recs) = store.step(t, k);
        for (&[i, j], d) in pairs.iter().zip(recs.chunks_exact(LINK)) {
            let u = spring::unit(d);
            let z = d[spring::ZEFF];
            let a = spring::a_matrix(d);
            for e in [i as usize, j as usize] {
                for r in 0..3 {
                    for q in 0..3 {
                        kii[9 * e + 3 * r + q] -= a[3 * r + q];
                        cii[9 * e + 3 * r + q] -= z * u[r] * u[q];
                    }
                }
            }
        }
    }
}
