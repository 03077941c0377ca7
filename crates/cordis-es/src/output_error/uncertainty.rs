//! Standard errors, intervals, correlations and the directions the data do not determine, from
//! the Gauss–Newton information matrix at the optimum.
//!
//! With residuals `e = x_sim - x_obs` weighted by `w` (1/σ relative), the information matrix of
//! the fit's variables q is `H = Σ w² J_rᵀ J_r` and, when the noise is Gaussian of scale σ,
//! `Cov(q̂) ≈ σ² H⁻¹` (the Cramér–Rao bound at the truth, the asymptotic covariance of the
//! maximum-likelihood estimate). σ² is estimated as `σ̂² = C / (m - P)` (m observed
//! coordinates, P variables). The initial states are nuisance variables: a parameter's variance
//! is its diagonal entry of the *full* inverse, so their uncertainty is accounted for.
//!
//! H is inverted in its equilibrated form `Ĥ = D⁻¹ H D⁻¹` (`D = diag(H)^½`) by a symmetric
//! eigendecomposition; eigenvalues below `1e-10 λ_max` are directions the data do not determine.
//! Each is reported by the names of the variables that carry it (components ≥ 0.3 of the unit
//! eigenvector), and those variables get an infinite standard error instead of the
//! pseudo-inverse's finite, meaningless one. So does a variable no single direction names but
//! whose unit vector lies that much in their span (`Σ_k v_k[a]² ≥ 0.3²` over the undetermined
//! eigenvectors: not estimable, its variance the pseudo-inverse's arbitrary part): on the soft
//! block observed every 20th frame, 8 of 9 unknowns undetermined over 11 directions, the ninth
//! was reported `± 1.8e-14`, an interval one value wide. It is named on the direction that
//! carries most of it.

use nalgebra::{DMatrix, SymmetricEigen};

/// Relative eigenvalue below which a direction is not determined.
pub const RANK_TOL: f64 = 1e-10;
/// Component of an undetermined eigenvector above which a variable is named.
const NAMED: f64 = 0.3;

/// Covariance of the fit's variables `σ² H⁺` and the undetermined directions (indices of the
/// variables each carries).
pub(crate) fn covariance(h: &DMatrix<f64>, sigma2: f64) -> (DMatrix<f64>, Vec<Vec<usize>>) {
    let n = h.nrows();
    let d: Vec<f64> = (0..n)
        .map(|a| {
            let v = h[(a, a)];
            if v > 0.0 {
                1.0 / v.sqrt()
            } else {
                0.0
            }
        })
        .collect();
    let mut hs = h.clone();
    for a in 0..n {
        for b in 0..n {
            hs[(a, b)] *= d[a] * d[b];
        }
    }
    let eig = SymmetricEigen::new(hs);
    let lmax = eig.eigenvalues.iter().cloned().fold(0.0, f64::max);
    let mut inv = DMatrix::zeros(n, n);
    let mut undetermined = Vec::new();
    for (k, &l) in eig.eigenvalues.iter().enumerate() {
        let v = eig.eigenvectors.column(k);
        if l.partial_cmp(&(RANK_TOL * lmax)) != Some(std::cmp::Ordering::Greater) {
            let mut carried: Vec<usize> = (0..n).filter(|&a| v[a].abs() >= NAMED).collect();
            if carried.is_empty() {
                carried = vec![v.iamax()];
            }
            undetermined.push(carried);
            continue;
        }
        inv += (v * v.transpose()) / l;
    }
    let mut cov = inv;
    for a in 0..n {
        for b in 0..n {
            cov[(a, b)] *= sigma2 * d[a] * d[b];
        }
        if d[a] == 0.0 {
            cov[(a, a)] = f64::INFINITY;
        }
    }
    name_spanned(&eig, lmax, &mut undetermined);
    for dir in &undetermined {
        for &a in dir {
            cov[(a, a)] = f64::INFINITY;
        }
    }
    (cov, undetermined)
}

/// Adds to `undetermined` (one list of variables per undetermined eigenvector of `eig`, in
/// eigenvalue order) every variable whose share of the undetermined span reaches `NAMED²`,
/// on the direction where its component is largest.
fn name_spanned(
    eig: &SymmetricEigen<f64, nalgebra::Dyn>,
    lmax: f64,
    undetermined: &mut [Vec<usize>],
) {
    let null: Vec<usize> = (0..eig.eigenvalues.len())
        .filter(|&k| {
            eig.eigenvalues[k].partial_cmp(&(RANK_TOL * lmax)) != Some(std::cmp::Ordering::Greater)
        })
        .collect();
    debug_assert_eq!(null.len(), undetermined.len());
    for a in 0..eig.eigenvectors.nrows() {
        if undetermined.iter().any(|d| d.contains(&a)) {
            continue;
        }
        let share: f64 = null.iter().map(|&k| eig.eigenvectors[(a, k)].powi(2)).sum();
        if share < NAMED * NAMED {
            continue;
        }
        let main = (0..null.len())
            .max_by(|&i, &j| {
                let c = |k: usize| eig.eigenvectors[(a, null[k])].abs();
                c(i).total_cmp(&c(j))
            })
            .expect("a share needs a direction");
        undetermined[main].push(a);
    }
}

/// The parameter block (first `dim` variables) of a covariance in internal coordinates,
/// turned into physical units: `Cov(p) = C Cov(z) C` with `C = diag(dp/dz)`.
pub(crate) fn physical(cov: &DMatrix<f64>, chain: &[f64]) -> DMatrix<f64> {
    let dim = chain.len();
    DMatrix::from_fn(dim, dim, |a, b| {
        let c = cov[(a, b)];
        if a == b && c.is_infinite() {
            c
        } else {
            chain[a] * chain[b] * c
        }
    })
}

/// Correlations from a covariance: 0 where a variance is infinite or 0 (an undetermined
/// unknown), NaN where one is NaN (not computed: its row says nothing, not "uncorrelated").
pub(crate) fn correlation(cov: &DMatrix<f64>) -> DMatrix<f64> {
    let n = cov.nrows();
    DMatrix::from_fn(n, n, |a, b| {
        let s = (cov[(a, a)] * cov[(b, b)]).sqrt();
        if cov[(a, a)].is_nan() || cov[(b, b)].is_nan() {
            f64::NAN
        } else if a == b {
            1.0
        } else if s.is_finite() && s > 0.0 {
            cov[(a, b)] / s
        } else {
            0.0
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Guards the span rule: a variable no undetermined eigenvector names (each carries 0.25
    /// of it, below 0.3) but whose share of their span is 0.125 ≥ 0.09 is not estimable and
    /// is named; one outside the span is not.
    #[test]
    fn a_variable_spread_over_undetermined_directions_is_named() {
        let (a, x) = (0.25f64, 0.0625 / (1.0f64 - 0.0625).sqrt());
        let n1 = [a, (1.0 - a * a).sqrt(), 0.0, 0.0];
        let n2 = [a, -x, (1.0 - a * a - x * x).sqrt(), 0.0];
        // Completes the orthonormal basis: the fourth axis, and the rest of the first three.
        let n4 = [0.0, 0.0, 0.0, 1.0];
        let mut n3 = [1.0, 0.0, 0.0, 0.0];
        for n in [&n1, &n2] {
            let dot: f64 = n3.iter().zip(n).map(|(p, q)| p * q).sum();
            for (p, q) in n3.iter_mut().zip(n) {
                *p -= dot * q;
            }
        }
        let norm = n3.iter().map(|p| p * p).sum::<f64>().sqrt();
        n3.iter_mut().for_each(|p| *p /= norm);
        let eig = SymmetricEigen {
            eigenvectors: DMatrix::from_fn(4, 4, |r, c| [n1, n2, n3, n4][c][r]),
            eigenvalues: nalgebra::DVector::from_vec(vec![1e-13, 1e-12, 1.0, 1.0]),
        };
        let mut undetermined = vec![vec![1], vec![2]];
        name_spanned(&eig, 1.0, &mut undetermined);
        assert!(
            undetermined.iter().any(|d| d.contains(&0)),
            "{undetermined:?}"
        );
        assert!(
            undetermined.iter().all(|d| !d.contains(&3)),
            "{undetermined:?}"
        );
        assert_eq!(undetermined.iter().map(Vec::len).sum::<usize>(), 3);
    }

    /// A standard error not computed (NaN variance) must not read as "uncorrelated": its row
    /// and column are NaN, an undetermined unknown's (∞) are 0, the others exact.
    #[test]
    fn a_variance_not_computed_gives_nan_correlations_not_zero() {
        let mut cov = DMatrix::from_row_slice(
            4,
            4,
            &[
                4.0,
                1.0,
                0.0,
                0.5, //
                1.0,
                9.0,
                0.0,
                0.3, //
                0.0,
                0.0,
                f64::NAN,
                0.0, //
                0.5,
                0.3,
                0.0,
                f64::INFINITY,
            ],
        );
        cov[(3, 3)] = f64::INFINITY;
        let r = correlation(&cov);
        approx::assert_relative_eq!(r[(0, 1)], 1.0 / 6.0, max_relative = 1e-15);
        assert_eq!(r[(0, 0)], 1.0);
        assert_eq!(r[(3, 3)], 1.0);
        assert_eq!(r[(0, 3)], 0.0);
        for k in 0..4 {
            assert!(
                r[(2, k)].is_nan() && r[(k, 2)].is_nan(),
                "row/column 2 at {k}"
            );
        }
    }
}
