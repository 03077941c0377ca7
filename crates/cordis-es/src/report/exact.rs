//! What the exact solvers (`least-squares`, `hybrid`, [`crate::exact`]) report.

use serde::{Deserialize, Serialize};

use crate::run::float_json::lossless;

/// What an exact solve says beside its answer (the `solver` field of a run summary).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ExactReport {
    /// Condition number of the column-equilibrated design of the final solve (1: orthogonal
    /// unknowns; `inf` when nothing was solved).
    #[serde(with = "lossless")]
    pub condition: f64,
    /// Unknowns the data cannot determine (held at their starting value).
    pub undetermined: Vec<String>,
    /// Unknowns on the weakest direction when the condition number exceeds [`crate::exact::POOR_CONDITION`].
    pub poorly_determined: Vec<String>,
    /// Unknowns whose unconstrained solution left the box (clamped onto it).
    pub clamped: Vec<String>,
    /// How the answer was reached (weightings, intervals of the nonlinear parameters…).
    pub notes: Vec<String>,
    /// Why the solve failed; the answer is then the starting point.
    pub error: Option<String>,
    /// Rows left out on a scene with Provot limits ([`crate::exact::provot_rows`]); absent otherwise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub provot: Option<ProvotRows>,
    /// Why the search stopped short of its own criterion (`hybrid`'s coordinate descent at its
    /// cycle cap while still moving); absent when it met it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub unconverged: Option<String>,
}

impl ExactReport {
    /// One line per thing a user should know, for a terminal.
    pub fn warnings(&self) -> Vec<String> {
        let mut w = Vec::new();
        if let Some(e) = &self.error {
            w.push(e.clone());
        }
        if !self.undetermined.is_empty() {
            w.push(format!(
                "{}: not determined by the data (held at the starting value)",
                self.undetermined.join(", ")
            ));
        }
        if !self.poorly_determined.is_empty() {
            w.push(format!(
                "{}: poorly determined (condition number {:.1e})",
                self.poorly_determined.join(", "),
                self.condition
            ));
        }
        if !self.clamped.is_empty() {
            w.push(format!(
                "{}: the unconstrained solution is outside the box (clamped onto it)",
                self.clamped.join(", ")
            ));
        }
        if let Some(u) = &self.unconverged {
            w.push(u.clone());
        }
        if let Some(p) = self.provot.as_ref().filter(|p| !p.consistent) {
            w.push(format!(
                "Provot limit: after {} solves the estimate still marks rows that were kept \
                 (the answer may be biased by the limit)",
                p.iterations
            ));
        }
        w
    }
}

/// What the Provot iteration did (the `provot` field of an exact solver's report).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct ProvotRows {
    /// Rows (particle, frame) of the short cost left out: the limit may have acted on them.
    pub dropped: usize,
    /// Rows of the short cost (free particles × predicted frames).
    pub rows: usize,
    /// Solve–mark rounds.
    pub iterations: usize,
    /// Whether the rows the final estimate marks are all dropped (false only when the
    /// iteration ran out of rounds).
    pub consistent: bool,
    /// Root mean square residual of the kept rows, per coordinate, m.
    #[serde(with = "lossless")]
    pub kept_rmse: f64,
}
