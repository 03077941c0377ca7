//! What `output-error` reports ([`crate::strategies::output_error`], which fills it in).

use serde::{Deserialize, Serialize};

use crate::run::float_json::lossless;

/// What `output-error` reports beside the estimate (see [`crate::output_error::Estimate`]).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct OutputErrorReport {
    pub estimator: String,
    /// Where the fit started.
    pub start: String,
    /// The growing windows, frames.
    pub windows: Vec<usize>,
    /// How the last window ended: converged, budget or stalled; `running` or `interrupted`
    /// when the run stopped before the fit reached the whole take.
    pub end: String,
    pub iterations: usize,
    /// Rollouts (with or without sensitivities).
    pub rollouts: usize,
    /// Weighted sum of squared position residuals at the estimate, m².
    /// (At the best point so far while the fit runs or once it was stopped; "inf" when that
    /// point diverges over the whole take.)
    #[serde(with = "lossless")]
    pub position_cost: f64,
    /// σ̂, m (unit-weight noise from the residuals).
    #[serde(with = "lossless")]
    pub sigma: f64,
    /// Noise level of each take from its third differences before the fit, m.
    pub noise_level: Vec<f64>,
    /// The loss on each residual (`squared`, `huber`, `cauchy`) and, with a robust one, the
    /// observed coordinates it weighs at less than half (outliers).
    #[serde(default)]
    pub loss: String,
    #[serde(default)]
    pub downweighted: usize,
    /// Observed coordinates and fit variables (unknowns + 6 per free particle and take).
    pub observed: usize,
    pub variables: usize,
    /// Correlations of the unknowns (row-major, unknown order).
    pub correlation: Vec<Vec<f64>>,
    /// Directions the data do not determine, each by the variables it moves.
    pub undetermined_directions: Vec<Vec<String>>,
    /// Unknowns on an undetermined direction.
    pub undetermined: Vec<String>,
    /// Why the fit stopped short of its criterion, when it did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub unconverged: Option<String>,
    /// Why `auto` chose this estimator, when it did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub chosen_because: Option<String>,
    /// Whether every standard error could be computed.
    pub uncertainty_computed: bool,
}
