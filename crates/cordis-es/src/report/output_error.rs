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
    /// How the last window ended: converged, budget or stalled; `stopped` when the run (a stop
    /// rule or Ctrl-C: its `stopped_by`) stopped before the fit reached the whole take.
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
    /// Noise level of each take from its third differences before the fit, m, of a weight-1
    /// coordinate (σ's unit).
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
    /// Correlations of the unknowns (row-major, unknown order): 0 beside an undetermined
    /// unknown, NaN (JSON `"NaN"`) in the row and column of one whose standard error was not
    /// computed.
    #[serde(with = "lossless::matrix")]
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
    /// Unknowns that ended on an edge of their box (a damping's floor 0 apart: that is an
    /// answer, not the box): the data pull them further, so their value is the box's and their
    /// interval is cut at it.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub at_bound: Vec<String>,
    /// Takes whose noise level could not be read (no 4 consecutive observed frames): the
    /// fit's residuals were not judged against it, so a wrong basin would go unnoticed.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub noise_unread: Vec<usize>,
    /// Whether every standard error could be computed.
    pub uncertainty_computed: bool,
    /// The unknowns whose standard error was not computed (the matrix-free solve did not
    /// settle), each with a lower bound on it in the unknown's unit (0 when the solve never
    /// moved); empty when every one was. They are absent from `Report::uncertainty`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub stderr_at_least: Vec<StderrBound>,
    /// Which intervals `uncertainty` holds: `wald` (checked along each unknown's profile
    /// direction), `profile` (the profile likelihood's where it is flatter than the quadratic
    /// model) or `m-estimate` (a robust loss's).
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub intervals: String,
    /// The intervals widened past their Wald interval because the cost along them rises
    /// slower than the Gauss–Newton model's (the likelihood is not quadratic at the scale of
    /// the interval: [`crate::output_error::line_profile`]).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub widened_intervals: Vec<WidenedInterval>,
}

/// An interval reported wider than its Wald interval: the cost along the unknown's profile
/// direction stays within the 95 % level past the Wald edge.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct WidenedInterval {
    pub name: String,
    /// `value ± 1.96 std_error` (on `ln value` for a log-searched unknown), cut at the box.
    #[serde(with = "lossless::pair")]
    pub wald: (f64, f64),
    /// The cost's rise at the Wald interval's lower and upper edges over the rise its
    /// quadratic model predicts (1 where the model holds; NaN where the box cuts that side).
    #[serde(with = "lossless::pair")]
    pub rise: (f64, f64),
}

/// A lower bound on a standard error that was not computed: the unsettled CG solve's variance
/// rises monotonically towards the true one, so its last value bounds it from below.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct StderrBound {
    pub name: String,
    #[serde(with = "lossless")]
    pub at_least: f64,
}

impl StderrBound {
    /// The bound to three significant digits, rounded down so the printed value stays a lower
    /// bound (`1.53e-3`); `None` when it is 0 (a solve that never moved bounds nothing).
    pub fn rounded_down(&self) -> Option<String> {
        let v = self.at_least;
        if !(v > 0.0 && v.is_finite()) {
            return None;
        }
        let exponent = v.log10().floor();
        let mantissa = (v / 10f64.powf(exponent) * 100.0).floor() / 100.0;
        Some(format!("{mantissa:.2}e{exponent}"))
    }
}

/// The warning lines for the directions the data do not determine (each a list of the names
/// of the variables it moves): a direction that moves an unknown (`moves_unknown`) has a line
/// of its own; the ones that move initial states only (a particle that no observation
/// follows) are counted in one line, each coordinate once, not one line per coordinate
/// (a degenerate null space's directions share coordinates: 108 lines on the soft block).
pub(crate) fn undetermined_lines(
    directions: &[Vec<String>],
    moves_unknown: impl Fn(&str) -> bool,
) -> Vec<String> {
    // A degenerate point (a fit stopped far from its optimum, a wrong graph) has as many
    // directions as unknowns: past this many, one line names the unknowns the rest move.
    const DIRECTION_LINES: usize = 8;
    let (with_unknowns, states_only): (Vec<&Vec<String>>, Vec<&Vec<String>>) = directions
        .iter()
        .partition(|d| d.iter().any(|n| moves_unknown(n)));
    // Directions naming the same variables (distinct vectors, the same names above the
    // naming threshold) share a line: a swapped marker's fit printed one line twice.
    let mut groups: Vec<(&Vec<String>, usize)> = Vec::new();
    for d in with_unknowns {
        match groups.iter_mut().find(|(names, _)| *names == d) {
            Some((_, count)) => *count += 1,
            None => groups.push((d, 1)),
        }
    }
    let mut w: Vec<String> = groups
        .iter()
        .take(DIRECTION_LINES)
        .map(|(d, count)| match count {
            1 => format!("not determined by the data together: {}", d.join(", ")),
            n => format!(
                "not determined by the data together ({n} directions): {}",
                d.join(", ")
            ),
        })
        .collect();
    let rest = groups.get(DIRECTION_LINES..).unwrap_or_default();
    if !rest.is_empty() {
        let names = || rest.iter().flat_map(|(d, _)| d.iter());
        let moved = distinct(names().filter(|n| moves_unknown(n)));
        let states = distinct(names().filter(|n| !moves_unknown(n))).len();
        let more: usize = rest.iter().map(|(_, count)| count).sum();
        w.push(format!(
            "not determined by the data: {} more direction{} like these, moving {} unknown{} \
             ({}){}",
            more,
            if more == 1 { "" } else { "s" },
            moved.len(),
            if moved.len() == 1 { "" } else { "s" },
            first_of(&moved, 6),
            match states {
                0 => String::new(),
                1 => " and 1 initial-state coordinate".to_string(),
                n => format!(" and {n} initial-state coordinates"),
            }
        ));
    }
    let states = distinct(states_only.into_iter().flatten());
    if !states.is_empty() {
        w.push(format!(
            "not determined by the data: {} initial-state coordinate{} ({}); the \
             parameters' estimates do not depend on them",
            states.len(),
            if states.len() == 1 { "" } else { "s" },
            first_of(&states, 4)
        ));
    }
    w
}

/// Each name once, in the order first met.
fn distinct<'a>(names: impl Iterator<Item = &'a String>) -> Vec<&'a String> {
    let mut out: Vec<&String> = Vec::new();
    for n in names {
        if !out.contains(&n) {
            out.push(n);
        }
    }
    out
}

/// The first `shown` names, then "and K more".
fn first_of(names: &[&String], shown: usize) -> String {
    let list: Vec<&str> = names.iter().take(shown).map(|s| s.as_str()).collect();
    match names.len().saturating_sub(shown) {
        0 => list.join(", "),
        n => format!("{} and {n} more", list.join(", ")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A direction moving an unknown gets a line of its own; directions moving initial
    /// states only share one line that counts each coordinate once (discover --identify
    /// printed one line per direction: 117 on the soft block).
    #[test]
    fn state_only_undetermined_directions_share_one_line() {
        let d = |names: &[&str]| names.iter().map(|n| n.to_string()).collect::<Vec<_>>();
        let directions = [
            d(&["types.a.stiffness", "take 0: particles[1].x0.x"]),
            d(&["take 0: particles[2].v0.y"]),
            d(&["take 0: particles[2].v0.y", "take 0: particles[3].x0.z"]),
        ];
        let lines = undetermined_lines(&directions, |n| n.starts_with("types."));
        assert_eq!(lines.len(), 2, "{lines:?}");
        assert_eq!(
            lines[0],
            "not determined by the data together: types.a.stiffness, take 0: particles[1].x0.x"
        );
        assert!(
            lines[1].starts_with(
                "not determined by the data: 2 initial-state coordinates (take 0: \
                 particles[2].v0.y, take 0: particles[3].x0.z)"
            ),
            "{}",
            lines[1]
        );
        // A degenerate point: 8 lines, then one naming what the other 4 directions move.
        let many: Vec<Vec<String>> = (0..12)
            .map(|k| {
                d(&[
                    &format!("types.t{k}.stiffness"),
                    "take 0: particles[1].x0.x",
                ])
            })
            .collect();
        let lines = undetermined_lines(&many, |n| n.starts_with("types."));
        assert_eq!(lines.len(), 9, "{lines:?}");
        assert_eq!(
            lines[8],
            "not determined by the data: 4 more directions like these, moving 4 unknowns \
             (types.t8.stiffness, types.t9.stiffness, types.t10.stiffness, types.t11.stiffness) \
             and 1 initial-state coordinate"
        );
    }

    /// Two directions naming the same variables share one line that counts them (a swapped
    /// marker's fit printed `not determined by the data together: types.horiz.rest_length`
    /// twice).
    #[test]
    fn directions_naming_the_same_variables_share_a_line() {
        let d = |names: &[&str]| names.iter().map(|n| n.to_string()).collect::<Vec<_>>();
        let directions = [
            d(&["types.h.rest_length"]),
            d(&["types.v.damping"]),
            d(&["types.h.rest_length"]),
        ];
        let lines = undetermined_lines(&directions, |n| n.starts_with("types."));
        assert_eq!(
            lines,
            [
                "not determined by the data together (2 directions): types.h.rest_length",
                "not determined by the data together: types.v.damping",
            ]
        );
    }

    /// Correlations not computed survive the JSON line and a checkpoint as NaN (`"NaN"`),
    /// the others exactly.
    #[test]
    fn nan_correlations_round_trip_through_json() {
        let report = OutputErrorReport {
            correlation: vec![
                vec![1.0, f64::NAN, 0.25],
                vec![f64::NAN; 3],
                vec![0.25, f64::NAN, 1.0],
            ],
            ..OutputErrorReport::default()
        };
        let text = serde_json::to_string(&report).expect("serialises");
        assert!(
            text.contains(
                r#""correlation":[[1.0,"NaN",0.25],["NaN","NaN","NaN"],[0.25,"NaN",1.0]]"#
            ),
            "{text}"
        );
        let back: OutputErrorReport = serde_json::from_str(&text).expect("reads back");
        assert_eq!(back.correlation[0][2], 0.25);
        assert!(back.correlation[0][1].is_nan() && back.correlation[1].iter().all(|x| x.is_nan()));
    }

    /// A fit whose standard errors were not all computed warns so, naming each with its lower
    /// bound (none where the solve never moved), and counts them against the unknowns.
    #[test]
    fn standard_errors_not_computed_are_warned_with_their_lower_bounds() {
        let report = OutputErrorReport {
            end: "converged".into(),
            uncertainty_computed: false,
            correlation: vec![vec![f64::NAN; 3]; 3],
            stderr_at_least: vec![
                StderrBound {
                    name: "types.a.damping".into(),
                    at_least: 1.537e-3,
                },
                StderrBound {
                    name: "types.a.stiffness".into(),
                    at_least: 0.0,
                },
            ],
            ..OutputErrorReport::default()
        };
        let w = report.warnings();
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(
            w[0].contains("2 of 3 standard errors not computed")
                && w[0].ends_with(": types.a.damping ≥ 1.53e-3, types.a.stiffness"),
            "{}",
            w[0]
        );
        let text = serde_json::to_string(&report).expect("serialises");
        assert!(
            text.contains(r#""stderr_at_least":[{"name":"types.a.damping","at_least":0.001537},"#),
            "{text}"
        );
    }
}
