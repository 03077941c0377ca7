//! Provot's elongation limit ([`cordis_core::forces::provot`]): the projection that ends every
//! step, differentiated piece by piece.
//!
//! After the integration gives the predicted positions x̃(n+1), the core runs one pass over the
//! limited springs in file order, each correction seen by the next. At its turn a link i–j
//! with `d = x_j - x_i`, `L = |d|`, `u = d/L` and limit `λ = (1 + τc) l0` is *active* when
//! `L > λ`; its free ends then move by the correction `c = (L - λ) u = d - λ u`:
//! `x_i += α c`, `x_j -= β c` with `(α, β) = (½, ½)` when both ends are free, `(1, 0)` or
//! `(0, 1)` when one is fixed. An inactive link changes nothing. With the active set fixed
//! (it is, under small changes, unless some link's length crosses its limit at some step), each
//! correction is a smooth map and its derivative is
//!
//! ```text
//! δc = M δd - u δλ,   M = ∂c/∂d = (1 - r) I + r u uᵀ,   r = λ / L,
//! δd = δx_j - δx_i,   δλ = (1 + τc) δl0 + l0 δτc
//! δx_i += α δc,       δx_j -= β δc
//! ```
//!
//! (`∂u/∂d = (I - u uᵀ)/L`). The sensitivities S(n+1) of the tangent recursion are those of
//! x̃(n+1) pushed through the active corrections in the pass's order, each at the positions
//! the pass saw (recorded by [`cordis_core::forces::provot::ProvotPass::apply_recorded`], the
//! core's own pass, so the active set is the core's). x(n) is left alone, so the next step's
//! velocity `(x(n+1) - x(n))/dt` carries the correction, as in the core. τc is an ordinary
//! column (its derivative `-α l0 u`, `β l0 u` on the ends of each active link of its type).
//!
//! The adjoint applies each correction's transpose in reverse order to the cotangent of
//! x(n+1) before the step's own adjoint: with `c̄ = α a_i - β a_j`,
//! `a_i -= M c̄`, `a_j += M c̄` (M is symmetric), and `∂/∂λ += -uᵀ c̄`.
//!
//! A switch (a link reaching or leaving its limit) is a kink, not a step: the correction
//! vanishes there, so the trajectory stays continuous in every unknown and only its slope jumps.
//! The matrix-free linearisation stores each step's corrections (link and [`REC`] floats
//! `u, r`) in a list with offsets: the active set changes from step to step.

use cordis_core::forces::provot::{Correction, ProvotPass};

use super::no_column::NONE;

/// Floats stored per correction: `u` (3) and `r = λ/L`.
pub(crate) const REC: usize = 4;

/// The corrections of every step of a rollout: step t's are `links[start[t]..start[t + 1]]`
/// with `records[REC · start[t]..]`.
#[derive(Clone, Debug, Default)]
pub(crate) struct Corrections {
    links: Vec<u32>,
    records: Vec<f64>,
    start: Vec<usize>,
}

impl Corrections {
    /// Empties the store (no step).
    pub fn reset(&mut self) {
        self.links.clear();
        self.records.clear();
        self.start.clear();
        self.start.push(0);
    }

    /// Appends one correction to the current step.
    pub fn push(&mut self, c: Correction) {
        self.links.push(c.link as u32);
        self.records
            .extend_from_slice(&[c.u[0], c.u[1], c.u[2], c.limit / c.len]);
    }

    /// Closes the current step.
    pub fn end_step(&mut self) {
        self.start.push(self.links.len());
    }

    /// Step t's links and records.
    pub fn step(&self, t: usize) -> (&[u32], &[f64]) {
        let (a, b) = (self.start[t], self.start[t + 1]);
        (&self.links[a..b], &self.records[a * REC..b * REC])
    }
}

/// How much of a correction each end takes: `(α, β)` (module docs).
#[inline]
fn shares(free: &[bool], i: usize, j: usize) -> (f64, f64) {
    match (free[i], free[j]) {
        (true, true) => (0.5, 0.5),
        (true, false) => (1.0, 0.0),
        (false, true) => (0.0, 1.0),
        (false, false) => (0.0, 0.0),
    }
}

/// The columns of link l's rest length and τc, and the factors `(1 + τc, l0)` of `δλ`.
#[inline]
fn limit_columns(pass: &ProvotPass, l: usize, p: &[f64], of_slot: &[usize]) -> [(usize, f64); 2] {
    let link = &pass.links[l];
    [
        (of_slot[link.param + 1], 1.0 + p[link.tau]),
        (of_slot[link.tau], p[link.param + 1]),
    ]
}

/// Pushes the row-major `3N × w` sensitivities `s` through step t's corrections `(links,
/// records)`, in order. `dl(cols, col)` is `δλ` in column col of a link whose
/// [`limit_columns`] are `cols`.
#[allow(clippy::too_many_arguments)]
fn push_through(
    pass: &ProvotPass,
    free: &[bool],
    (links, records): (&[u32], &[f64]),
    p: &[f64],
    of_slot: &[usize],
    w: usize,
    s: &mut [f64],
    dl: impl Fn(&[(usize, f64); 2], usize) -> f64,
) {
    for (&l, rec) in links.iter().zip(records.chunks_exact(REC)) {
        let l = l as usize;
        let (i, j) = pass.ends(l);
        let (alpha, beta) = shares(free, i, j);
        let (u, r) = ([rec[0], rec[1], rec[2]], rec[3]);
        let cols = limit_columns(pass, l, p, of_slot);
        for col in 0..w {
            let mut dd = [0.0; 3];
            for k in 0..3 {
                dd[k] = s[(3 * j + k) * w + col] - s[(3 * i + k) * w + col];
            }
            let ud = u[0] * dd[0] + u[1] * dd[1] + u[2] * dd[2];
            let dlim = dl(&cols, col);
            for k in 0..3 {
                let dc = (1.0 - r) * dd[k] + (r * ud - dlim) * u[k];
                s[(3 * i + k) * w + col] += alpha * dc;
                s[(3 * j + k) * w + col] -= beta * dc;
            }
        }
    }
}

/// Dense tangent: the full sensitivity matrix S(n+1) (columns `of_slot`'s, width w) through
/// the corrections of one step.
pub(super) fn dense(
    pass: &ProvotPass,
    free: &[bool],
    step: (&[u32], &[f64]),
    p: &[f64],
    of_slot: &[usize],
    w: usize,
    s: &mut [f64],
) {
    push_through(pass, free, step, p, of_slot, w, s, |cols, col| {
        cols.iter().filter(|(c, _)| *c == col).map(|(_, f)| f).sum()
    });
}

/// Matrix-free forward: `w` directions s(t+1) through step t's corrections; `dth` holds the θ
/// directions (physical units) × w.
#[allow(clippy::too_many_arguments)]
pub(crate) fn forward(
    pass: &ProvotPass,
    free: &[bool],
    store: &Corrections,
    t: usize,
    p: &[f64],
    of_slot: &[usize],
    w: usize,
    s: &mut [f64],
    dth: &[f64],
) {
    push_through(pass, free, store.step(t), p, of_slot, w, s, |cols, col| {
        cols.iter()
            .filter(|(c, _)| *c != NONE)
            .map(|&(c, f)| f * dth[c * w + col])
            .sum()
    });
}

/// Matrix-free adjoint: the cotangent `a` of x(t+1) (× w) becomes that of the prediction
/// x̃(t+1), the corrections' transposes in reverse order; their θ parts go to `grad`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn adjoint(
    pass: &ProvotPass,
    free: &[bool],
    store: &Corrections,
    t: usize,
    p: &[f64],
    of_slot: &[usize],
    w: usize,
    a: &mut [f64],
    grad: &mut [f64],
) {
    let (links, records) = store.step(t);
    for (&l, rec) in links.iter().zip(records.chunks_exact(REC)).rev() {
        let l = l as usize;
        let (i, j) = pass.ends(l);
        let (alpha, beta) = shares(free, i, j);
        let (u, r) = ([rec[0], rec[1], rec[2]], rec[3]);
        let cols = limit_columns(pass, l, p, of_slot);
        for col in 0..w {
            let mut cb = [0.0; 3];
            for k in 0..3 {
                cb[k] = alpha * a[(3 * i + k) * w + col] - beta * a[(3 * j + k) * w + col];
            }
            let uc = u[0] * cb[0] + u[1] * cb[1] + u[2] * cb[2];
            for k in 0..3 {
                let m = (1.0 - r) * cb[k] + r * uc * u[k];
                a[(3 * i + k) * w + col] -= m;
                a[(3 * j + k) * w + col] += m;
            }
            for &(c, f) in &cols {
                if c != NONE {
                    grad[c * w + col] -= f * uc;
                }
            }
        }
    }
}

/// The preconditioner's local model (each particle alone, its neighbours held): an active
/// link multiplies its free ends' 3×6 blocks by `I - α M` (resp. `I - β M`). `local[i]` is
/// particle i's block in `cur` (18 floats), or `None` for a fixed particle.
pub(crate) fn local(
    pass: &ProvotPass,
    free: &[bool],
    store: &Corrections,
    t: usize,
    block: impl Fn(usize) -> Option<usize>,
    cur: &mut [f64],
) {
    let (links, records) = store.step(t);
    for (&l, rec) in links.iter().zip(records.chunks_exact(REC)) {
        let (i, j) = pass.ends(l as usize);
        let (alpha, beta) = shares(free, i, j);
        let (u, r) = ([rec[0], rec[1], rec[2]], rec[3]);
        for (e, share) in [(i, alpha), (j, beta)] {
            let Some(b) = block(e).filter(|_| share > 0.0) else {
                continue;
            };
            let s = &mut cur[b..b + 18];
            for q in 0..6 {
                let col = [s[q], s[6 + q], s[12 + q]];
                let uc = u[0] * col[0] + u[1] * col[1] + u[2] * col[2];
                for k in 0..3 {
                    s[6 * k + q] -= share * ((1.0 - r) * col[k] + r * uc * u[k]);
                }
            }
        }
    }
}
