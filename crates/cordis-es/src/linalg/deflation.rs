//! Deflation of a conjugate-gradient solve by a small recycled subspace (Saad, Yeung, Erhel and
//! Guyomarc'h, "A deflated version of the conjugate gradient algorithm", SIAM J. Sci. Comput.
//! 21, 2000).
//!
//! For `A x = b` (A symmetric positive definite) and a basis `W` (n × k, k ≪ n) of directions
//! CG is known to resolve slowly, with `E = Wᵀ A W`:
//!
//! ```text
//! x₀ = W E⁻¹ Wᵀ b,             r₀ = b − A W E⁻¹ Wᵀ b          (Wᵀ r₀ = 0)
//! z  = M⁻¹ r,                  p  = z + β p − W E⁻¹ (A W)ᵀ z    (p A-orthogonal to W)
//! ```
//!
//! and otherwise the ordinary preconditioned iteration. Every residual stays orthogonal to W,
//! so the solution is exact on span W from the first iteration, and CG spends its iterations
//! on the rest of the spectrum.
//!
//! Why here: near the optimum the matrix-free Gauss–Newton steps line up along the few poorly
//! determined directions (the cloth's structural / bending stiffness valley and the states
//! coupled to it), which CG resolves worst. Deflating each solve by the previous steps costs k
//! operator products per solve and saved 21–44 % of the CG iterations on the cloth at the
//! same estimates (BENCHMARKS "Large scenes"). It does not make the steps themselves converge
//! faster: solved exactly, they still gain only a fixed fraction of the one before.

use super::dot;
use nalgebra::{DMatrix, DVector};

/// A factored deflation subspace for one operator (one linearisation, one λ).
#[derive(Clone, Debug)]
pub struct Deflation {
    n: usize,
    k: usize,
    /// Row-major n × k: the orthonormal basis W and A W.
    basis: Vec<f64>,
    abasis: Vec<f64>,
    /// Cholesky factor of `E = Wᵀ A W`.
    e: nalgebra::Cholesky<f64, nalgebra::Dyn>,
}

/// A vector kept in the basis keeps at least this fraction of its norm after being
/// orthogonalised against the vectors before it (Gram–Schmidt): below, it is (nearly) in
/// their span and would make `E` singular.
const KEEP: f64 = 1e-6;

impl Deflation {
    /// The subspace spanned by `vectors` (orthonormalised; dependent ones dropped), with
    /// `apply(W, k, AW)` multiplying the row-major n × k block W by the operator. `None` when
    /// no vector is left or `E` is not positive definite.
    pub fn new(
        vectors: &[Vec<f64>],
        apply: impl FnOnce(&[f64], usize, &mut [f64]),
    ) -> Option<Self> {
        let n = vectors.first()?.len();
        let mut kept: Vec<Vec<f64>> = Vec::with_capacity(vectors.len());
        for v in vectors {
            let norm0 = dot(v, v).sqrt();
            if !(norm0 > 0.0 && norm0.is_finite()) {
                continue;
            }
            let mut u = v.clone();
            for q in &kept {
                let c = dot(&u, q);
                u.iter_mut().zip(q).for_each(|(a, b)| *a -= c * b);
            }
            let norm = dot(&u, &u).sqrt();
            if norm > KEEP * norm0 {
                u.iter_mut().for_each(|a| *a /= norm);
                kept.push(u);
            }
        }
        let k = kept.len();
        if k == 0 {
            return None;
        }
        let mut basis = vec![0.0; n * k];
        for (c, u) in kept.iter().enumerate() {
            for a in 0..n {
                basis[a * k + c] = u[a];
            }
        }
        let mut abasis = vec![0.0; n * k];
        apply(&basis, k, &mut abasis);
        let mut e = DMatrix::zeros(k, k);
        for a in 0..n {
            for r in 0..k {
                for c in 0..k {
                    e[(r, c)] += basis[a * k + r] * abasis[a * k + c];
                }
            }
        }
        let e = (&e + e.transpose()) * 0.5;
        let e = e.cholesky()?;
        Some(Deflation {
            n,
            k,
            basis,
            abasis,
            e,
        })
    }

    /// The number of directions kept.
    pub fn dim(&self) -> usize {
        self.k
    }

    /// `Bᵀ v` for the row-major block B (k values).
    fn block_t(&self, block: &[f64], v: &[f64]) -> DVector<f64> {
        let mut out = DVector::zeros(self.k);
        for a in 0..self.n {
            for c in 0..self.k {
                out[c] += block[a * self.k + c] * v[a];
            }
        }
        out
    }

    /// `v -= B y` for the row-major block B.
    fn sub_block(&self, block: &[f64], y: &DVector<f64>, v: &mut [f64]) {
        for a in 0..self.n {
            let row = &block[a * self.k..(a + 1) * self.k];
            v[a] -= row.iter().zip(y.iter()).map(|(b, c)| b * c).sum::<f64>();
        }
    }

    /// The start: `x += W E⁻¹ Wᵀ r` and `r -= A W E⁻¹ Wᵀ r` (r enters as the residual of x).
    pub fn start(&self, x: &mut [f64], r: &mut [f64]) {
        let y = self.e.solve(&self.block_t(&self.basis, r));
        let minus_y = -&y;
        self.sub_block(&self.basis, &minus_y, x);
        self.sub_block(&self.abasis, &y, r);
    }

    /// `z -= W E⁻¹ (A W)ᵀ z`: the A-orthogonal projection of a search direction off span W.
    pub fn project(&self, z: &mut [f64]) {
        let y = self.e.solve(&self.block_t(&self.abasis, z));
        self.sub_block(&self.basis, &y, z);
    }

    /// [`Self::start`] for each of the `w` solves whose iterates and residuals are the columns
    /// of the row-major n × w blocks `x` and `r`; `column` is a buffer of n.
    pub fn start_columns(&self, x: &mut [f64], r: &mut [f64], w: usize, column: &mut Vec<f64>) {
        let mut xc = vec![0.0; self.n];
        for c in 0..w {
            gather(x, w, c, &mut xc);
            gather(r, w, c, column);
            self.start(&mut xc, column);
            scatter(&xc, w, c, x);
            scatter(column, w, c, r);
        }
    }

    /// [`Self::project`] for each column of the row-major n × w block `z` in `columns`.
    pub fn project_columns(
        &self,
        z: &mut [f64],
        w: usize,
        columns: &[usize],
        column: &mut Vec<f64>,
    ) {
        for &c in columns {
            gather(z, w, c, column);
            self.project(column);
            scatter(column, w, c, z);
        }
    }
}

/// Column c of the row-major block `m` (w columns) into `out`.
fn gather(m: &[f64], w: usize, c: usize, out: &mut Vec<f64>) {
    out.clear();
    out.extend(m.iter().skip(c).step_by(w));
}

/// `v` into column c of the row-major block `m` (w columns).
fn scatter(v: &[f64], w: usize, c: usize, m: &mut [f64]) {
    for (slot, x) in m.iter_mut().skip(c).step_by(w).zip(v) {
        *slot = *x;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    /// A symmetric positive definite n × n matrix with a few tiny eigenvalues (a "valley").
    fn valley(n: usize) -> DMatrix<f64> {
        let q = DMatrix::from_fn(n, n, |r, c| {
            ((r * 7 + c * 13) % 17) as f64 - 8.0 + 0.1 * r as f64
        })
        .qr()
        .q();
        let d = DVector::from_fn(n, |i, _| if i < 2 { 1e-6 } else { 1.0 + i as f64 });
        &q * DMatrix::from_diagonal(&d) * q.transpose()
    }

    fn apply_of(a: &DMatrix<f64>) -> impl Fn(&[f64], usize, &mut [f64]) + '_ {
        move |w: &[f64], k: usize, out: &mut [f64]| {
            let n = a.nrows();
            let wm = DMatrix::from_fn(n, k, |r, c| w[r * k + c]);
            let aw = a * wm;
            for r in 0..n {
                for c in 0..k {
                    out[r * k + c] = aw[(r, c)];
                }
            }
        }
    }

    #[test]
    fn the_start_solves_exactly_on_the_subspace_and_leaves_a_residual_orthogonal_to_it() {
        let n = 12;
        let a = valley(n);
        let b: Vec<f64> = (0..n).map(|i| (i as f64).sin() + 0.5).collect();
        let w1: Vec<f64> = (0..n).map(|i| (i as f64 * 0.3).cos()).collect();
        let w2: Vec<f64> = (0..n).map(|i| (i % 3) as f64).collect();
        let d = Deflation::new(&[w1.clone(), w2.clone()], apply_of(&a)).unwrap();
        assert_eq!(d.dim(), 2);
        let mut x = vec![0.0; n];
        let mut r = b.clone();
        d.start(&mut x, &mut r);
        // r = b − A x, and Wᵀ r = 0.
        let ax = &a * DVector::from_column_slice(&x);
        for i in 0..n {
            assert_relative_eq!(r[i], b[i] - ax[i], epsilon = 1e-10);
        }
        assert_relative_eq!(dot(&r, &w1), 0.0, epsilon = 1e-9);
        assert_relative_eq!(dot(&r, &w2), 0.0, epsilon = 1e-9);
        // A projected direction is A-orthogonal to W.
        let mut z: Vec<f64> = (0..n).map(|i| 1.0 / (1.0 + i as f64)).collect();
        d.project(&mut z);
        let az = &a * DVector::from_column_slice(&z);
        assert_relative_eq!(dot(az.as_slice(), &w1), 0.0, epsilon = 1e-9);
        assert_relative_eq!(dot(az.as_slice(), &w2), 0.0, epsilon = 1e-9);
    }

    #[test]
    fn column_blocks_are_started_and_projected_as_single_vectors() {
        let (n, w) = (9, 3);
        let a = valley(n);
        let w1: Vec<f64> = (0..n).map(|i| (i as f64 * 0.7).sin()).collect();
        let d = Deflation::new(&[w1], apply_of(&a)).unwrap();
        let col =
            |c: usize| -> Vec<f64> { (0..n).map(|i| ((i * 5 + c * 3) % 7) as f64 - 3.0).collect() };
        let (mut x, mut r, mut z) = (vec![0.0; n * w], vec![0.0; n * w], vec![0.0; n * w]);
        for c in 0..w {
            for i in 0..n {
                r[i * w + c] = col(c)[i];
                z[i * w + c] = col(c + 1)[i];
            }
        }
        let mut buf = Vec::new();
        d.start_columns(&mut x, &mut r, w, &mut buf);
        d.project_columns(&mut z, w, &[0, 2], &mut buf);
        for c in 0..w {
            let (mut xs, mut rs, mut zs) = (vec![0.0; n], col(c), col(c + 1));
            d.start(&mut xs, &mut rs);
            if c != 1 {
                d.project(&mut zs);
            }
            for i in 0..n {
                assert_eq!(x[i * w + c], xs[i]);
                assert_eq!(r[i * w + c], rs[i]);
                assert_eq!(z[i * w + c], zs[i]);
            }
        }
    }

    #[test]
    fn dependent_and_empty_vectors_are_dropped() {
        let a = valley(6);
        let w: Vec<f64> = (0..6).map(|i| i as f64).collect();
        let twice: Vec<f64> = w.iter().map(|v| 2.0 * v).collect();
        let d = Deflation::new(&[w, vec![0.0; 6], twice], apply_of(&a)).unwrap();
        assert_eq!(d.dim(), 1);
        assert!(Deflation::new(&[vec![0.0; 6]], apply_of(&a)).is_none());
        assert!(Deflation::new(&[], apply_of(&a)).is_none());
    }
}
