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

impl Loss {
    /// IRLS weight `ω(u) = ρ'(u)/u` of a residual `u` in units of the robust scale.
    pub fn weight(self, u: f64) -> f64 {
        const HUBER: f64 = 1.345;
        const CAUCHY: f64 = 2.385;
        match self {
            Loss::Squared => 1.0,
            Loss::Huber if u.abs() <= HUBER => 1.0,
            Loss::Huber => HUBER / u.abs(),
            Loss::Cauchy => 1.0 / (1.0 + (u / CAUCHY).powi(2)),
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

#[cfg(test)]
mod tests {
    use approx::assert_relative_eq;

    use super::*;

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
