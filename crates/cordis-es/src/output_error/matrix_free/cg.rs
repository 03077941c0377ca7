//! Preconditioned conjugate gradients on the damped Gauss–Newton system.

use super::operator::{Mf, Work};
use super::preconditioner::Pre;
use crate::linalg::deflation::Deflation;
use crate::linalg::dot;

/// Settings of the inner conjugate-gradient solves.
#[derive(Clone, Copy, Debug)]
pub(crate) struct CgSettings {
    /// Relative residual `‖r‖/‖b‖` at which a solve stops.
    pub tol: f64,
    pub max_iterations: usize,
}

impl Default for CgSettings {
    fn default() -> Self {
        CgSettings {
            tol: 1e-6,
            max_iterations: 300,
        }
    }
}

/// Buffers of the conjugate-gradient solves (one vector each).
#[derive(Clone, Debug, Default)]
pub(crate) struct CgWork {
    pub(super) r: Vec<f64>,
    pub(super) z: Vec<f64>,
    pub(super) p: Vec<f64>,
    pub(super) ap: Vec<f64>,
}

/// Solves `(H + λ diag(scale)) x = rhs` on the coordinates not held (held ones stay 0) by
/// PCG; returns the iterations and whether the relative residual reached `set.tol`. `watch`
/// sees every iterate and stops the solve by returning true (the residual then counts as not
/// reached).
#[allow(clippy::too_many_arguments)]
pub(crate) fn pcg(
    mf: &Mf<'_, '_>,
    pre: &Pre,
    scale: &[f64],
    held: &[bool],
    lambda: f64,
    rhs: &[f64],
    x: &mut [f64],
    set: CgSettings,
    deflation: Option<&Deflation>,
    cg: &mut CgWork,
    work: &mut Work,
    watch: &mut dyn FnMut(&[f64]) -> bool,
) -> (usize, bool) {
    let len = rhs.len();
    let CgWork { r, z, p, ap } = cg;
    for v in [&mut *r, &mut *z, &mut *p, &mut *ap] {
        v.clear();
        v.resize(len, 0.0);
    }
    x.iter_mut().for_each(|v| *v = 0.0);
    for a in 0..len {
        r[a] = if held[a] { 0.0 } else { rhs[a] };
    }
    let bnorm = dot(r, r).sqrt();
    if bnorm == 0.0 {
        return (0, true);
    }
    if let Some(d) = deflation {
        d.start(x, r);
        if dot(r, r).sqrt() <= set.tol * bnorm {
            return (0, true);
        }
    }
    pre.apply(r, z);
    if let Some(d) = deflation {
        d.project(z);
    }
    p.copy_from_slice(z);
    let mut rz = dot(r, z);
    for it in 1..=set.max_iterations {
        damped_hv(mf, p, 1, scale, held, lambda, ap, work);
        let pap = dot(p, ap);
        if pap.is_nan() || pap <= 0.0 {
            return (it, false);
        }
        let alpha = rz / pap;
        for a in 0..len {
            x[a] += alpha * p[a];
            r[a] -= alpha * ap[a];
        }
        if dot(r, r).sqrt() <= set.tol * bnorm {
            return (it, true);
        }
        if watch(x) {
            return (it, false);
        }
        pre.apply(r, z);
        let rz_new = dot(r, z);
        let beta = rz_new / rz;
        rz = rz_new;
        if let Some(d) = deflation {
            d.project(z);
        }
        for a in 0..len {
            p[a] = z[a] + beta * p[a];
        }
    }
    (set.max_iterations, false)
}

/// `out = (H + λ diag(scale)) v` on `w` row-major columns, 0 on the held coordinates: the
/// operator of a step's solve (a zero scale counts as 1).
#[allow(clippy::too_many_arguments)]
pub(super) fn damped_hv(
    mf: &Mf<'_, '_>,
    v: &[f64],
    w: usize,
    scale: &[f64],
    held: &[bool],
    lambda: f64,
    out: &mut [f64],
    work: &mut Work,
) {
    mf.hv(v, w, out, work);
    for (a, (row, vs)) in out.chunks_mut(w).zip(v.chunks(w)).enumerate() {
        let s = if scale[a] > 0.0 { scale[a] } else { 1.0 };
        for (o, x) in row.iter_mut().zip(vs) {
            *o = if held[a] { 0.0 } else { *o + lambda * s * x };
        }
    }
}

/// Statistics of the matrix-free fit, for the estimate's note.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub(crate) struct CgCounts {
    pub solves: usize,
    pub iterations: usize,
    pub unconverged: usize,
}
