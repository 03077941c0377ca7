//! The least-squares solve of the exact solvers: `min |Dξ + d|²` by SVD of `D` with every
//! column scaled to unit norm (equilibrated), so that the condition number compares unknowns
//! of different units fairly and a rank decision does not depend on the units chosen.

use nalgebra::{DMatrix, DVector};

/// Singular values below this fraction of the largest (column-scaled design) are taken as
/// zero. Measured on noiseless data, a never-stretched type gives ~1e-15 and the shipped
/// examples' smallest legitimate ones are above 1e-9.
pub const RANK_TOL: f64 = 1e-11;

/// SVD solution of `min |Dξ + d|²` on equilibrated columns.
pub struct Lsq {
    /// The solution (original, unscaled units).
    pub xi: DVector<f64>,
    /// Condition number of the equilibrated D (`inf` with a null space).
    pub condition: f64,
    /// Right singular vectors (scaled space) of the zero singular values.
    pub null: Vec<DVector<f64>>,
    /// Right singular vector of the smallest nonzero singular value.
    pub weakest: Option<DVector<f64>>,
}

/// `None` when `d` or `rhs` is not finite (or the SVD fails).
pub fn lsq(d: &DMatrix<f64>, rhs: &DVector<f64>) -> Option<Lsq> {
    let p = d.ncols();
    if p == 0 {
        return Some(Lsq {
            xi: DVector::zeros(0),
            condition: 1.0,
            null: Vec::new(),
            weakest: None,
        });
    }
    let scale: Vec<f64> = (0..p)
        .map(|j| {
            let n = d.column(j).norm();
            if n > 0.0 {
                n
            } else {
                1.0
            }
        })
        .collect();
    let mut ds = d.clone();
    for (j, &sc) in scale.iter().enumerate() {
        ds.column_mut(j).unscale_mut(sc);
    }
    if !ds.iter().all(|v| v.is_finite()) || !rhs.iter().all(|v| v.is_finite()) {
        return None;
    }
    let svd = ds.svd(true, true);
    let (u, vt) = (svd.u.as_ref()?, svd.v_t.as_ref()?);
    let sv = &svd.singular_values;
    let smax = sv.iter().cloned().fold(0.0, f64::max);
    let mut xi = DVector::zeros(p);
    let mut null = Vec::new();
    let mut smin = f64::INFINITY;
    let mut weakest = None;
    for k in 0..sv.len() {
        let v = vt.row(k).transpose();
        if sv[k] <= RANK_TOL * smax || smax == 0.0 {
            null.push(v);
            continue;
        }
        let coef = u.column(k).dot(rhs) / sv[k];
        xi -= &v * coef;
        if sv[k] < smin {
            smin = sv[k];
            weakest = Some(v);
        }
    }
    for j in 0..p {
        xi[j] /= scale[j];
    }
    let condition = if null.is_empty() {
        smax / smin
    } else {
        f64::INFINITY
    };
    Some(Lsq {
        xi,
        condition,
        null,
        weakest,
    })
}
