//! 1-D minimisation of a profile cost over a box, for `hybrid`'s continuous nonlinear unknowns
//! (a TGR's K, its tendon's parameters): the cost is the inner least-squares minimum at each
//! value, smooth but not quadratic, and cheap enough (tens of µs) that a derivative-free
//! search of a few dozen points is the fastest robust choice.
//!
//! A coarse grid of [`GRID`] points over the whole box (scored as one batch, in parallel)
//! finds the basin; Brent's method (parabolic steps safeguarded by golden sections) then
//! polishes the best point inside the bracket of its two neighbours. Deterministic: the same
//! box and cost give the same answer whatever the thread count. On noiseless data the profile
//! is exactly 0 at the truth and grows quadratically away from it, so the tolerance can be far
//! below the usual √ε: the minimum is located to ~1e-11 of the coordinate.

use crate::linalg::line_search::brent;

/// Points of the coarse grid (box ends included).
pub(crate) const GRID: usize = 16;
/// Brent's relative tolerance on the internal coordinate (ln v for a log-scaled unknown).
pub(crate) const TOL: f64 = 1e-11;
/// Most Brent steps.
const MAX_STEPS: usize = 200;

/// The least `f` over `[lo, hi]` (internal coordinates): `(x, f(x))`. `f` scores a batch of
/// points. `tol` is relative to the box width plus |x|; [`TOL`] for the final answer, larger
/// for a cheap early cycle of a coordinate descent.
pub(crate) fn minimize(
    lo: f64,
    hi: f64,
    tol: f64,
    mut f: impl FnMut(&[f64]) -> Vec<f64>,
) -> (f64, f64) {
    if hi.is_nan() || lo.is_nan() || hi <= lo {
        let v = f(&[lo])[0];
        return (lo, v);
    }
    let xs: Vec<f64> = (0..GRID)
        .map(|k| lo + (hi - lo) * k as f64 / (GRID - 1) as f64)
        .collect();
    let fs = f(&xs);
    let mut b = 0;
    for (k, &v) in fs.iter().enumerate() {
        if v < fs[b] {
            b = k;
        }
    }
    let (a, c) = (xs[b.saturating_sub(1)], xs[(b + 1).min(GRID - 1)]);
    if !fs[b].is_finite() {
        return (xs[b], fs[b]);
    }
    brent(
        |x| Some(f(&[x])[0]),
        a,
        xs[b],
        fs[b],
        c,
        tol * (hi - lo),
        tol,
        MAX_STEPS,
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    #[test]
    fn finds_a_zero_residual_minimum_to_the_tolerance() {
        // A profile like a noiseless fit's: 0 at the truth, quadratic near it, flat-ish far.
        let truth = 20f64.ln();
        let f = |x: f64| -3.0 * (-(x - truth).powi(2)).exp_m1();
        let (x, v) = minimize(0.0, 5.0, TOL, |xs| xs.iter().map(|&x| f(x)).collect());
        assert_relative_eq!(x, truth, max_relative = 1e-9);
        assert!(v < 1e-18, "{v}");
    }

    #[test]
    fn a_diverging_side_costs_inf_and_is_avoided() {
        let f = |x: f64| {
            if x > 2.0 {
                f64::INFINITY
            } else {
                (x - 1.9).powi(2)
            }
        };
        let (x, _) = minimize(0.0, 4.0, TOL, |xs| xs.iter().map(|&x| f(x)).collect());
        assert_relative_eq!(x, 1.9, max_relative = 1e-9);
    }

    #[test]
    fn a_minimum_on_the_box_edge_is_found() {
        let (x, _) = minimize(1.0, 2.0, TOL, |xs| xs.iter().map(|&x| x * x).collect());
        assert!((x - 1.0).abs() < 1e-9, "{x}");
    }
}
