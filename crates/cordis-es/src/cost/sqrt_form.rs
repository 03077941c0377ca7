//! Least-squares quadratic forms kept in square-root (QR) form.
//!
//! A sum of squared affine residuals `C(θ) = Σ_rows (φ_row · θ + b_row)²` is the Gram form
//! `θᵀGθ + 2hᵀθ + c`, but evaluating it that way cancels catastrophically near the minimum:
//! `c` and `θᵀGθ` are both of the size of the residuals' *signal* while `C` is of the size of
//! their *misfit*, so relative rounding of 1e-16 on `c` becomes an absolute error that can
//! dwarf `C` (measured: see the crate's tests and the report). Rotating every row
//! `[φ_row | b_row]` into an upper-triangular factor `A = [[R, q], [0, ρ]]` with Givens
//! rotations keeps `C(θ) = |R θ + q|² + ρ²` a sum of squares of small numbers: no
//! cancellation, never negative, same O(dim²) cost per evaluation.
//!
//! Storage: `A` is packed row by row, row k holding columns k..=dim (the last column is q, and
//! ρ sits alone in the last row).

use crate::linalg::givens::rotate_in;

/// Packed length of the augmented factor for `dim` unknowns.
pub(crate) fn packed_len(dim: usize) -> usize {
    let d = dim + 1;
    d * (d + 1) / 2
}

/// Offset of row k in the packed factor with `d = dim + 1` columns.
#[inline(always)]
fn row_offset(k: usize, d: usize) -> usize {
    k * d - k * k.saturating_sub(1) / 2
}

/// Rotates `row` (`dim + 1` values: φ then b; destroyed) into the packed factor `a`.
pub(crate) fn add_row(a: &mut [f64], dim: usize, row: &mut [f64]) {
    let d = dim + 1;
    debug_assert_eq!(row.len(), d);
    for k in 0..d {
        let o = row_offset(k, d);
        rotate_in(&mut a[o..o + d - k], &mut row[k..d]);
    }
}

/// `|R θ + q|² + ρ²`, reading θ_l as `theta(l)` (so that a local form can gather its entries
/// from a global vector). Never negative; NaN parameters give NaN (the caller maps it to +inf).
#[inline]
pub(crate) fn value(a: &[f64], dim: usize, theta: impl Fn(usize) -> f64) -> f64 {
    let d = dim + 1;
    let mut sum = 0.0;
    for k in 0..dim {
        let o = row_offset(k, d);
        let row = &a[o..o + d - k];
        let mut s = row[d - k - 1];
        for (l, r) in row[..d - k - 1].iter().enumerate() {
            s += r * theta(k + l);
        }
        sum += s * s;
    }
    let rho = a[row_offset(dim, d)];
    sum + rho * rho
}

/// The Gram form of a packed factor: `G = RᵀR` (dim × dim, row-major), `h = Rᵀq`,
/// `c = |q|² + ρ²`, so that `C(θ) = θᵀGθ + 2hᵀθ + c`.
pub(crate) fn gram(a: &[f64], dim: usize) -> (Vec<f64>, Vec<f64>, f64) {
    let d = dim + 1;
    let at = |k: usize, l: usize| -> f64 {
        if l < k {
            0.0
        } else {
            a[row_offset(k, d) + l - k]
        }
    };
    // AᵀA = [[RᵀR, Rᵀq], [qᵀR, |q|² + ρ²]]: one product gives all three pieces.
    let mut full = vec![0.0; d * d];
    for i in 0..d {
        for j in i..d {
            let s: f64 = (0..=i.min(j)).map(|k| at(k, i) * at(k, j)).sum();
            full[i * d + j] = s;
            full[j * d + i] = s;
        }
    }
    let g = (0..dim)
        .flat_map(|i| (0..dim).map(move |j| (i, j)))
        .map(|(i, j)| full[i * d + j])
        .collect();
    let h = (0..dim).map(|i| full[i * d + dim]).collect();
    (g, h, full[d * d - 1])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn factor_reproduces_the_sum_of_squares() {
        let dim = 3;
        let rows: Vec<[f64; 4]> = (0..20)
            .map(|r| {
                let r = r as f64;
                [
                    r.sin(),
                    (1.3 * r).cos(),
                    0.1 * r - 1.0,
                    (0.7 * r).sin() + 0.2,
                ]
            })
            .collect();
        let mut a = vec![0.0; packed_len(dim)];
        for r in &rows {
            add_row(&mut a, dim, &mut r.clone());
        }
        let theta = [0.3, -1.2, 2.0];
        let direct: f64 = rows
            .iter()
            .map(|r| {
                let e = r[0] * theta[0] + r[1] * theta[1] + r[2] * theta[2] + r[3];
                e * e
            })
            .sum();
        let v = value(&a, dim, |l| theta[l]);
        approx::assert_relative_eq!(v, direct, max_relative = 1e-13);
        let (g, h, c) = gram(&a, dim);
        let mut q = c;
        for i in 0..dim {
            q += 2.0 * h[i] * theta[i];
            for j in 0..dim {
                q += theta[i] * g[i * dim + j] * theta[j];
            }
        }
        approx::assert_relative_eq!(q, direct, max_relative = 1e-12);
    }
}
