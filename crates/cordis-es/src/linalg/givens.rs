//! Givens QR of a stream of rows: the one rotation kernel behind every triangular factor of the
//! crate — the dense factors of the exact solvers ([`Factor`]) and the packed square-root forms
//! of the linear short cost (`cost::sqrt_form`).
//!
//! A row `w` is rotated into the factor's row k (diagonal `r`) by `c = r/ρ`, `s = w_k/ρ`,
//! `ρ = sqrt(r² + w_k²)`: `R_k ← c R_k + s w`, `w ← c w - s R_k`. Orthogonal, so the sum of
//! squares of the rows is kept exactly and nothing is squared (the normal equations would
//! square the condition number).

/// Rotates `row` into one row of a triangular factor: `factor[0]` is the diagonal entry and
/// `factor[1..]` the entries to its right, `row[0]` the row's value in that column and
/// `row[1..]` the rest (rotated in place; `row[0]` is left as it was, the caller moves on).
/// `row[0] == 0` changes nothing.
#[inline(always)]
pub fn rotate_in(factor: &mut [f64], row: &mut [f64]) {
    let w = row[0];
    if w == 0.0 {
        return;
    }
    let r = factor[0];
    // sqrt(a² + b²) is exact enough and 5× cheaper than hypot away from over/underflow.
    let mut rho = (r * r + w * w).sqrt();
    if !(rho > 1e-150 && rho < 1e150) {
        rho = r.hypot(w);
    }
    let (c, s) = (r / rho, w / rho);
    factor[0] = rho;
    for (x, y) in factor[1..].iter_mut().zip(&mut row[1..]) {
        let (xv, yv) = (*x, *y);
        *x = c * xv + s * yv;
        *y = c * yv - s * xv;
    }
}

use nalgebra::DMatrix;

/// Upper-triangular factor of a sum of squared rows, rows rotated in by Givens.
#[derive(Clone, Debug)]
pub struct Factor {
    n: usize,
    a: Vec<f64>,
}

impl Factor {
    /// The factor of no rows (zero), n × n.
    pub fn new(n: usize) -> Self {
        Factor {
            n,
            a: vec![0.0; n * n],
        }
    }

    /// Rotates `row` (length n, destroyed) into the factor.
    pub fn add_row(&mut self, row: &mut [f64]) {
        let n = self.n;
        for k in 0..n {
            rotate_in(&mut self.a[k * n + k..(k + 1) * n], &mut row[k..n]);
        }
    }

    /// The factor R (upper triangular, n × n): `RᵀR` is the sum of the rows' outer products.
    pub fn matrix(&self) -> DMatrix<f64> {
        DMatrix::from_row_slice(self.n, self.n, &self.a)
    }
}
