//! What a strategy says beside its numbers: a typed report per solver, with the warnings a
//! user must read before trusting the answer.
//!
//! The CLI prints [`Report::warnings`] as `warning:` lines and the report itself (as JSON,
//! [`Report::to_json`]) under `"solver"`; Python raises them through `warnings.warn` and keeps
//! the report on `IdentifyResult.report`. One list of warnings for both, so they cannot drift.
//!
//! A report also decides how a finished run is labelled ([`crate::run::executor::StopReason`]):
//! `converged` only when the solver's own criterion was met ([`Report::unconverged`] is
//! `None`) and every unknown was determined ([`Report::undetermined`] is empty).

use serde::{Deserialize, Serialize};

use crate::run::float_json::lossless;

mod exact;
mod output_error;

pub use exact::{ExactReport, ProvotRows};
pub(crate) use output_error::undetermined_lines;
pub use output_error::{OutputErrorReport, StderrBound, WidenedInterval};

/// What `levenberg-marquardt` reports.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LmReport {
    /// Restarts spent from random points after the first start.
    pub restarts: u32,
    /// Marquardt's damping at the end (dimensionless, relative to the scaled JᵀJ).
    #[serde(with = "lossless")]
    pub lambda: f64,
    /// Why the run ended short of the solver's criterion (a small cost), when it did.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub unconverged: Option<String>,
}

/// The uncertainty of one identified parameter, in the parameter's own unit (N/m, m, kg…).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ParamUncertainty {
    /// The unknown's name (`types.NAME.PARAM`, `particles[i].mass`).
    pub name: String,
    /// Standard error of the estimate.
    #[serde(with = "lossless")]
    pub std_error: f64,
    /// A confidence interval (lower, upper) around the estimate; an undetermined parameter's
    /// is its search box (the data do not narrow it). Written as `std_error` is, an infinite
    /// end as a string, never `null`.
    #[serde(with = "lossless::pair")]
    pub interval: (f64, f64),
    /// Confidence level of `interval` (0.95 for a 95 % interval).
    pub level: f64,
}

/// A solver's own report. `untagged`: its JSON is the solver's fields as they always were.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(untagged)]
#[non_exhaustive]
// One report per run, built once at its end and never in a loop: the output-error variant's
// size costs nothing, and boxing it would change every match on it.
#[allow(clippy::large_enum_variant)]
pub enum SolverReport {
    /// `least-squares`, `hybrid`: condition number, undetermined and clamped unknowns, notes.
    Exact(ExactReport),
    /// `levenberg-marquardt`: restarts and damping.
    LevenbergMarquardt(LmReport),
    /// `output-error`: σ̂, windows, correlations, undetermined directions.
    OutputError(OutputErrorReport),
}

/// Everything a strategy reports beside the best point and its cost.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Report {
    /// The solver's own report; `None` for the evolution strategies, which have nothing to
    /// add to the history.
    pub solver: Option<SolverReport>,
    /// Per-parameter standard errors and intervals, by name, for strategies that estimate
    /// them (in unknown order; an unknown whose standard error was not computed is left out,
    /// output-error names it in `stderr_at_least`); `None` otherwise or when none was.
    pub uncertainty: Option<Vec<ParamUncertainty>>,
}

impl Report {
    /// A report of an exact solver.
    pub fn exact(r: ExactReport) -> Self {
        Report {
            solver: Some(SolverReport::Exact(r)),
            uncertainty: None,
        }
    }

    /// The exact solver's report, if this is one.
    pub fn as_exact(&self) -> Option<&ExactReport> {
        match &self.solver {
            Some(SolverReport::Exact(r)) => Some(r),
            _ => None,
        }
    }

    /// Why the solver stopped short of its own criterion (restarts or cycles spent), if it did.
    pub fn unconverged(&self) -> Option<&str> {
        match &self.solver {
            Some(SolverReport::Exact(r)) => r.unconverged.as_deref(),
            Some(SolverReport::LevenbergMarquardt(r)) => r.unconverged.as_deref(),
            Some(SolverReport::OutputError(r)) => r.unconverged.as_deref(),
            None => None,
        }
    }

    /// Unknowns the data do not determine (an exact solver holds them at their starting
    /// value; output-error names those on an undetermined direction).
    pub fn undetermined(&self) -> &[String] {
        match &self.solver {
            Some(SolverReport::Exact(r)) => &r.undetermined,
            Some(SolverReport::OutputError(r)) => &r.undetermined,
            _ => &[],
        }
    }

    /// One line per thing a user should know before trusting the answer.
    pub fn warnings(&self) -> Vec<String> {
        match &self.solver {
            Some(SolverReport::Exact(r)) => r.warnings(),
            Some(SolverReport::LevenbergMarquardt(r)) => r.unconverged.iter().cloned().collect(),
            Some(SolverReport::OutputError(r)) => r.warnings(),
            None => Vec::new(),
        }
    }

    /// The JSON the CLI prints under `"solver"` (and `"uncertainty"`); `null` for nothing.
    pub fn to_json(&self) -> serde_json::Value {
        let mut v = match &self.solver {
            Some(s) => serde_json::to_value(s).unwrap_or_default(),
            None => serde_json::Value::Null,
        };
        if let Some(u) = &self.uncertainty {
            if !v.is_object() {
                v = serde_json::json!({});
            }
            v["uncertainty"] = serde_json::to_value(u).unwrap_or_default();
        }
        v
    }
}

/// An estimated initial state: one entry per particle, in scene order; `None` keeps that
/// particle's initial state as the scene gives it (fixed particles, particles not estimated).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct InitialState {
    /// Per particle: (position x(0), m; velocity v(0), m/s).
    pub particles: Vec<Option<([f64; 3], [f64; 3])>>,
}

impl InitialState {
    /// Writes the estimated states into `scene` (the particles it names; the rest unchanged).
    pub fn apply(&self, scene: &mut cordis_core::Scene) {
        for (p, s) in scene.particles.iter_mut().zip(&self.particles) {
            if let Some((pos, vel)) = s {
                p.pos = *pos;
                p.vel = *vel;
            }
        }
    }
}
