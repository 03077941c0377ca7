//! Dense linear algebra of the solvers, one method per file: the Givens factor of a stream of
//! rows ([`givens`]), the column-equilibrated SVD least squares ([`equilibrated`]), Brent's
//! bounded line search ([`line_search`]), Powell's conjugate-direction descent built on it
//! ([`powell`]) and the deflation of a conjugate-gradient solve by a recycled subspace
//! ([`deflation`]).

/// `aᵀ b` of two slices (the first `min(len)` entries), summed in order.
pub fn dot(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| x * y).sum()
}

pub mod deflation;
pub mod equilibrated;
pub mod givens;
pub mod line_search;
pub mod powell;
