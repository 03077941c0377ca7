//! Options of the output-error fit and their validation.

use crate::error::CostError;

use super::line_profile::Intervals;
use super::loss::Loss;

/// Options of the output-error fit.
#[derive(Clone, Debug, PartialEq)]
pub struct Config {
    /// Frames of the first window (each later window doubles it).
    pub first_window: usize,
    /// Levenberg–Marquardt iterations per window.
    pub max_iterations: usize,
    /// scipy's tolerances, for every window.
    pub ftol: f64,
    pub xtol: f64,
    pub gtol: f64,
    /// Starting genome (internal coordinates); `None`: the short-cost start ([`start`]).
    pub start: Option<Vec<f64>>,
    /// Starting initial state per take (`[x0, v0]` per free particle); `None`: from the data.
    pub start_states: Option<Vec<Vec<f64>>>,
    /// The loss on each residual ([`loss`]: squared, or robust against outliers).
    pub loss: Loss,
    /// Which intervals are reported ([`Intervals`]: Wald checked along a line, or the
    /// profile likelihood's where it differs).
    pub intervals: Intervals,
    /// Standard deviation of the position noise per unit-weight coordinate, m, when known:
    /// the windows' clean bound ([`super::windows`]) and the start's smoothing use it instead
    /// of the level read from each take's third differences. `None`: read from the data.
    pub noise_level: Option<f64>,
    /// Fit variables (θ and initial states) above which the fit is matrix-free
    /// ([`super::matrix_free`]): below, the dense Levenberg–Marquardt with exact standard
    /// errors. Default [`super::matrix_free::DENSE_MAX_COLUMNS`]; raised where standard
    /// errors are the point of the fit (the output-error link test of
    /// [`crate::discover::link_test`]: its matrix-free standard-error solves did not converge).
    pub dense_max_columns: usize,
}

impl Default for Config {
    fn default() -> Self {
        Config {
            first_window: 16,
            max_iterations: 100,
            ftol: 1e-10,
            xtol: 1e-10,
            gtol: 1e-10,
            start: None,
            start_states: None,
            loss: Loss::Squared,
            intervals: Intervals::Wald,
            noise_level: None,
            dense_max_columns: super::matrix_free::DENSE_MAX_COLUMNS,
        }
    }
}

/// Every option is in its range: a window of at least 3 frames, at least one iteration, finite
/// tolerances ≥ 0, a given noise level finite and ≥ 0.
pub(crate) fn check_config(c: &Config) -> Result<(), CostError> {
    if c.first_window < 3 {
        return Err(CostError::mismatch(
            "first_window",
            format!("must be at least 3 frames, got {}", c.first_window),
        ));
    }
    if c.max_iterations == 0 {
        return Err(CostError::mismatch("max_iterations", "must be at least 1"));
    }
    for (name, v) in [("ftol", c.ftol), ("xtol", c.xtol), ("gtol", c.gtol)] {
        if !(v.is_finite() && v >= 0.0) {
            return Err(CostError::mismatch(
                name,
                format!("must be a finite number ≥ 0, got {v}"),
            ));
        }
    }
    if let Some(s) = c.noise_level {
        if !(s.is_finite() && s >= 0.0) {
            return Err(CostError::mismatch(
                "noise_level",
                format!("must be a finite number of m ≥ 0, got {s}"),
            ));
        }
    }
    Ok(())
}
