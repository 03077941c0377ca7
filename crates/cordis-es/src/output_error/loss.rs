//! Robust losses against tracking outliers and swapped markers, by iteratively reweighted
//! least squares (IRLS).
//!
//! With a robust loss ρ the fit minimises `Σ ρ(r/s)` over the weighted residuals
//! `r = w (x − y)`, where `s` is the residuals' robust scale `1.4826 · median |r|` (σ for
//! Gaussian noise). Each window's Levenberg–Marquardt stage runs on the weights
//! `w √ω(r/s)` with `ω(u) = ρ'(u)/u` read at the previous stage's residuals, and the window is
//! fitted again until no multiplier moves by more than 0.01 (at most
//! [`MAX_REWEIGHTS`] times): the fixed point is the robust estimate (Huber's M-estimator, or
//! Cauchy's redescending one). The tuning constants are the usual 95 %-efficiency ones
//! (Huber 1.345, Cauchy 2.385): with Gaussian noise only, the estimate loses about 5 % of its
//! efficiency; an outlier's pull is bounded (Huber) or vanishes (Cauchy).

use std::str::FromStr;

use crate::error::CostError;

use serde::{Deserialize, Serialize};

/// Reweighting rounds of the last window (the whole take) at most.
pub const MAX_REWEIGHTS: usize = 12;
/// Reweighting rounds of an intermediate window at most: they only steer the growth.
pub const WINDOW_REWEIGHTS: usize = 2;

/// The loss on each residual.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Loss {
    /// Least squares: the maximum-likelihood estimate under Gaussian noise.
    #[default]
    Squared,
    /// Quadratic within 1.345 s, linear beyond.
    Huber,
    /// `log(1 + (u/2.385)²)`: a far outlier has no pull.
    Cauchy,
}

/// The tuning constants, in units of the robust scale (95 % efficiency on Gaussian noise).
const HUBER: f64 = 1.345;
const CAUCHY: f64 = 2.385;

impl Loss {
    /// IRLS weight `ω(u) = ρ'(u)/u` of a residual `u` in units of the robust scale.
    pub fn weight(self, u: f64) -> f64 {
        match self {
            Loss::Squared => 1.0,
            Loss::Huber if u.abs() <= HUBER => 1.0,
            Loss::Huber => HUBER / u.abs(),
            Loss::Cauchy => 1.0 / (1.0 + (u / CAUCHY).powi(2)),
        }
    }

    /// `ψ'(u)`, the derivative of the influence `ψ(u) = ρ'(u) = ω(u) u`: 1 within Huber's
    /// corner and 0 beyond; `(1 - (u/c)²) / (1 + (u/c)²)²` for Cauchy's.
    pub fn slope(self, u: f64) -> f64 {
        match self {
            Loss::Squared => 1.0,
            Loss::Huber if u.abs() <= HUBER => 1.0,
            Loss::Huber => 0.0,
            Loss::Cauchy => {
                let a = (u / CAUCHY).powi(2);
                (1.0 - a) / ((1.0 + a) * (1.0 + a))
            }
        }
    }

    pub fn as_str(self) -> &'static str {
        match self {
            Loss::Squared => "squared",
            Loss::Huber => "huber",
            Loss::Cauchy => "cauchy",
        }
    }
}

impl FromStr for Loss {
    type Err = CostError;

    fn from_str(s: &str) -> Result<Self, CostError> {
        match s {
            "squared" => Ok(Loss::Squared),
            "huber" => Ok(Loss::Huber),
            "cauchy" => Ok(Loss::Cauchy),
            other => Err(CostError::unknown_name(
                other,
                format!(
                    "`{}` is not one of squared, huber, cauchy",
                    cordis_core::error::printable(other)
                ),
            )),
        }
    }
}

impl std::fmt::Display for Loss {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// The robust scale of residuals: `1.4826 · median |r|` over the finite ones (0 when none).
pub fn robust_scale(residuals: impl Iterator<Item = f64>) -> f64 {
    let mut a: Vec<f64> = residuals.filter(|r| r.is_finite()).map(f64::abs).collect();
    if a.is_empty() {
        return 0.0;
    }
    let mid = a.len() / 2;
    let (_, m, _) = a.select_nth_unstable_by(mid, f64::total_cmp);
    1.4826 * *m
}

/// The variance of an M-estimate on residuals `r` against its IRLS normal equations' own:
/// the factor that turns `σ̂²_ω H_ω⁻¹` (what the fit's last normal equations give, with
/// `σ̂²_ω = Σ ω r² / dof` and `H_ω = Jᵀ Ω J`) into Huber's covariance of the M-estimate (Huber,
/// *Robust Statistics*, 1981, §7.6, his first form:
/// `K² s² [Σ ψ² / (n − p)] / [Σ ψ' / n]² (JᵀJ)⁻¹`, `K = 1 + (p/n) var ψ' / (mean ψ')²`, with
/// `JᵀJ ≈ H_ω / mean ω`, `mean_weight` the mean of the multipliers `ω` the normal equations
/// were built on), and the noise level the residuals give, the robust scale `s` (consistent
/// for σ on Gaussian noise, where `σ̂_ω` reads 0.83–0.90 σ). `variables` is the fit's count
/// (p). Residuals exactly 0 (a planar take's z, a fixed marker without noise) carry no noise
/// and are left out: a third of them would pull `s` to 0.47 σ. `None` when the residuals
/// give no scale.
pub fn m_estimate_spread(
    loss: Loss,
    residuals: &[f64],
    mean_weight: f64,
    variables: usize,
    sigma2_weighted: f64,
) -> Option<(f64, f64)> {
    let r: Vec<f64> = residuals
        .iter()
        .copied()
        .filter(|r| r.is_finite() && *r != 0.0)
        .collect();
    let s = robust_scale(r.iter().copied());
    if !(s > 0.0 && s.is_finite() && sigma2_weighted > 0.0) {
        return None;
    }
    let n = r.len() as f64;
    let p = variables as f64;
    let (mut psi2, mut slope, mut slope2) = (0.0, 0.0, 0.0);
    for u in r.iter().map(|r| r / s) {
        let w = loss.weight(u);
        psi2 += (w * u) * (w * u);
        let d = loss.slope(u);
        slope += d;
        slope2 += d * d;
    }
    let mean_slope = slope / n;
    if mean_slope.is_nan() || mean_slope <= 0.0 {
        return None;
    }
    let var_slope = (slope2 / n - mean_slope * mean_slope).max(0.0);
    let k = 1.0 + p / n * var_slope / (mean_slope * mean_slope);
    let dof = (n - p).max(1.0);
    let variance = k * k * s * s * (psi2 / dof) / (mean_slope * mean_slope) * mean_weight;
    Some((variance / sigma2_weighted, s))
}

#[cfg(test)]
mod tests {
    use approx::assert_relative_eq;

    use super::*;

    /// Gaussian quantiles `Φ⁻¹(k / (m + 1))` by bisection on `erf`-free Φ (a series), enough
    /// for expectations over N(0, 1) to 1e-3.
    fn gaussian_sample(m: usize) -> Vec<f64> {
        let phi = |x: f64| {
            // Φ through the complementary error function's continued-fraction-free series
            // (Abramowitz–Stegun 26.2.17, |error| < 7.5e-8).
            let t = 1.0 / (1.0 + 0.2316419 * x.abs());
            let d = (-x * x / 2.0).exp() / (2.0 * std::f64::consts::PI).sqrt();
            let tail = d
                * t
                * (0.319381530
                    + t * (-0.356563782
                        + t * (1.781477937 + t * (-1.821255978 + t * 1.330274429))));
            if x >= 0.0 {
                1.0 - tail
            } else {
                tail
            }
        };
        (1..=m)
            .map(|k| {
                let p = k as f64 / (m + 1) as f64;
                let (mut lo, mut hi) = (-10.0, 10.0);
                for _ in 0..80 {
                    let mid = 0.5 * (lo + hi);
                    if phi(mid) < p {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                0.5 * (lo + hi)
            })
            .collect()
    }

    /// On Gaussian residuals the robust scale is σ, and the variance factor is the loss's
    /// efficiency loss against what the IRLS normal equations say: `E ψ² / (E ψ')²` = 1/0.95
    /// (the tuning constants' 95 % efficiency) over `E ψ u / E ω`, the weighted σ̂²'s and
    /// H_ω's shares — so the M-estimate's standard errors are 1/√0.95 those of least squares,
    /// not the 0.9 the IRLS equations alone gave (a tester's finding: 8–11 % too small).
    #[test]
    fn on_gaussian_noise_an_m_estimates_variance_is_least_squares_over_its_efficiency() {
        let sigma = 2.0;
        let r: Vec<f64> = gaussian_sample(20_000).iter().map(|u| sigma * u).collect();
        let n = r.len() as f64;
        for loss in [Loss::Huber, Loss::Cauchy] {
            let weighted: f64 = r
                .iter()
                .map(|&r| loss.weight(r / sigma) * r * r)
                .sum::<f64>()
                / n;
            let omega: f64 = r.iter().map(|&r| loss.weight(r / sigma)).sum::<f64>() / n;
            let (factor, s) = m_estimate_spread(loss, &r, omega, 0, weighted).unwrap();
            assert_relative_eq!(s, sigma, max_relative = 2e-3);
            // The M-estimate's variance σ² · factor · σ̂²_ω / mean ω against least squares' σ².
            let relative = factor * weighted / omega / (sigma * sigma);
            assert_relative_eq!(relative, 1.0 / 0.95, max_relative = 5e-3);
            // What the IRLS equations alone said: 0.86 (Huber), 0.80 (Cauchy) of least squares'.
            let irls = weighted / omega / (sigma * sigma);
            assert!((0.75..0.9).contains(&irls), "{loss}: {irls}");
            // Exact zeros (a planar take's z) change neither the scale nor the factor.
            let planar: Vec<f64> = r.iter().flat_map(|&x| [x, 0.0]).collect();
            let (with_zeros, s0) = m_estimate_spread(loss, &planar, omega, 0, weighted).unwrap();
            assert_relative_eq!(s0, s, max_relative = 1e-12);
            assert_relative_eq!(with_zeros, factor, max_relative = 1e-12);
            // Huber's K: p fitted variables of n widen it by (1 + (p/n) var ψ' / (mean ψ')²)².
            let (small, _) = m_estimate_spread(loss, &r, omega, 2_000, weighted).unwrap();
            assert!(small > factor, "{loss}: {small} against {factor}");
        }
        let (factor, _) = m_estimate_spread(Loss::Squared, &r, 1.0, 0, sigma * sigma).unwrap();
        assert_relative_eq!(factor, 1.0, max_relative = 5e-3);
    }

    #[test]
    fn weights_are_one_inside_and_fall_outside() {
        assert_eq!(Loss::Squared.weight(50.0), 1.0);
        assert_eq!(Loss::Huber.weight(1.0), 1.0);
        assert_relative_eq!(Loss::Huber.weight(13.45), 0.1);
        assert_relative_eq!(Loss::Cauchy.weight(2.385), 0.5);
        assert!(Loss::Cauchy.weight(100.0) < 1e-3);
    }

    #[test]
    fn the_scale_of_gaussian_residuals_is_their_sigma() {
        // Quantiles of N(0, 2²): the median |r| is 0.6745 σ.
        let r = (1..2000).map(|k| {
            let p = k as f64 / 2000.0;
            // A crude inverse normal through the logistic approximation is enough here.
            2.0 * (p / (1.0 - p)).ln() / 1.702
        });
        assert_relative_eq!(robust_scale(r), 2.0, max_relative = 0.05);
        assert_eq!(robust_scale([f64::NAN].into_iter()), 0.0);
        assert_eq!("huber".parse::<Loss>().ok(), Some(Loss::Huber));
        assert!("l1"
            .parse::<Loss>()
            .unwrap_err()
            .to_string()
            .contains("squared, huber, cauchy"));
    }
}
