//! What an output-error fit reports: the [`Estimate`] and how it is assembled from the fit's
//! last normal equations (σ̂ from the residuals, the covariance, intervals, undetermined
//! directions by name).

use cordis_core::Scene;
use nalgebra::DMatrix;

use super::fit::{self, Counts, Fitter, StageEnd};
use super::line_profile::{self, Widened};
use super::loss::Loss;
use super::observations::Take;
use super::uncertainty;

/// The result of [`estimate`].
#[derive(Clone, Debug)]
pub struct Estimate {
    /// Internal coordinates of the unknowns ([`crate::space`]).
    pub genome: Vec<f64>,
    /// The scene's whole parameter vector at the estimate.
    pub params: Vec<f64>,
    /// Per take: `[x0, v0]` per free particle (m, m/s), free particles in scene order.
    pub states: Vec<Vec<f64>>,
    /// Weighted sum of squared position residuals, m².
    pub cost: f64,
    /// Estimated noise of a unit-weight coordinate, m: `√(C / (m - P))`; with a robust loss the
    /// residuals' robust scale ([`super::loss::m_estimate_spread`]).
    pub sigma: f64,
    /// Noise level read from the data before the fit (third differences), m, per take, of a
    /// weight-1 coordinate (σ's unit).
    pub noise_level: Vec<f64>,
    /// Observed coordinates m and fit variables P.
    pub observed: usize,
    pub variables: usize,
    /// Standard error per unknown in its physical unit (inf: not determined; NaN: not
    /// computed, when the matrix-free path's solve for it did not converge — the strategy
    /// then leaves that unknown out of its uncertainty rather than report a NaN).
    pub stderr: Vec<f64>,
    /// Where a standard error is NaN (not computed), a lower bound on it in the same unit
    /// (from the unsettled CG solve's last variance, `σ̂ |dθ/dz| √v`; possibly far below
    /// the true one); NaN elsewhere.
    pub stderr_at_least: Vec<f64>,
    /// 95 % interval per unknown ([`interval95`]: `value ± 1.96 stderr`, on `ln value` for
    /// the log-searched ones, cut at the box; an undetermined unknown's box `(min, max)`:
    /// [`box_interval`]), widened where the cost along it rises slower than its quadratic
    /// model ([`line_profile`]).
    pub intervals: Vec<(f64, f64)>,
    /// The intervals [`line_profile`] widened, with their Wald intervals and cost rises.
    pub widened: Vec<Widened>,
    /// Which intervals these are: `wald` (checked along each unknown's profile direction),
    /// `profile` (widened to the profile likelihood's where it is flatter than its quadratic
    /// model) or `m-estimate` (a robust loss's Wald intervals of the M-estimate's spread).
    pub interval_kind: String,
    /// Covariance of the unknowns (physical units), row-major dim × dim.
    pub covariance: DMatrix<f64>,
    pub correlation: DMatrix<f64>,
    /// Directions the data do not determine, each by the names of the variables it moves.
    pub undetermined: Vec<Vec<String>>,
    /// The last window's Levenberg–Marquardt met its own criterion (ftol, xtol or gtol).
    pub converged: bool,
    /// The residuals over the whole takes stayed above the noise level's clean bound (a model
    /// or basin that cannot follow the motion), whatever `end` says (a `budget` end can be).
    pub above_noise: bool,
    /// How the last window ended: `converged`, `budget` or `stalled`.
    pub end: &'static str,
    pub iterations: usize,
    pub evaluations: usize,
    /// The windows, frames.
    pub windows: Vec<usize>,
    /// Where the fit started (short-cost solve or heuristic, and why).
    pub start: String,
    /// The loss, and with a robust one the observed coordinates it weighs at less than half
    /// (ω < 0.5: outliers).
    pub loss: Loss,
    pub downweighted: usize,
}

/// The [`Estimate`] at `q` from the fit's normal equations `ne` there over `window` frames;
/// `check`: how the intervals are checked along the cost ([`line_profile`]; squared loss).
#[allow(clippy::too_many_arguments)]
pub(crate) fn summarise(
    fitter: &Fitter<'_>,
    scene: &Scene,
    q: Vec<f64>,
    ne: fit::Normal,
    noise_level: Vec<f64>,
    mut counts: Counts,
    end: StageEnd,
    windows: Vec<usize>,
    start: String,
    check: Option<line_profile::Measure>,
    halt: &dyn Fn() -> bool,
) -> Estimate {
    let observed: usize = fitter.takes.iter().map(Take::observed).sum();
    let variables = fitter.len();
    let dof = observed.saturating_sub(variables).max(1);
    let sigma2 = ne.cost / dof as f64;
    let (cov_q, dirs) = uncertainty::covariance(&ne.h, sigma2);
    let chain = fitter.chain(&q);
    let covariance = uncertainty::physical(&cov_q, &chain);
    let correlation = uncertainty::correlation(&covariance);
    let params = fitter.params(&q);
    let dim = fitter.theta();
    let (stderr, mut intervals) = spread(fitter, &params, &covariance);
    let at = line_profile::Optimum {
        q: &q,
        cost: ne.cost,
        sigma2,
        window: windows.iter().copied().max().unwrap_or(0),
    };
    let column = |a: usize| Some(cov_q.column(a).iter().copied().collect());
    let (widened, interval_kind) = line_profile::check_intervals(
        fitter,
        &at,
        check,
        column,
        halt,
        &mut intervals,
        &mut counts,
    );
    let names = variable_names(fitter, scene);
    let undetermined = dirs
        .iter()
        .map(|d| d.iter().map(|&a| names[a].clone()).collect())
        .collect();
    let states = take_states(fitter, &q);
    Estimate {
        genome: q[..dim].to_vec(),
        params,
        states,
        cost: ne.cost,
        sigma: sigma2.sqrt(),
        noise_level,
        observed,
        variables,
        stderr_at_least: vec![f64::NAN; stderr.len()],
        stderr,
        intervals,
        widened,
        interval_kind,
        covariance,
        correlation,
        undetermined,
        converged: end == StageEnd::Converged,
        above_noise: false,
        end: end_text(end),
        iterations: counts.iterations,
        evaluations: counts.evaluations,
        windows,
        start,
        loss: Loss::Squared,
        downweighted: 0,
    }
}

/// How the last window ended, as reported.
pub(crate) fn end_text(end: StageEnd) -> &'static str {
    match end {
        StageEnd::Converged => "converged",
        StageEnd::Budget => "budget",
        StageEnd::Stalled | StageEnd::Diverged => "stalled",
        StageEnd::Interrupted => "interrupted",
        StageEnd::AboveNoise => "above_noise",
    }
}

/// Standard errors (the covariance's diagonal) and 95 % intervals ([`interval95`]; an
/// undetermined unknown's is its box, [`box_interval`]).
pub(crate) fn spread(
    fitter: &Fitter<'_>,
    params: &[f64],
    covariance: &DMatrix<f64>,
) -> (Vec<f64>, Vec<(f64, f64)>) {
    let stderr: Vec<f64> = (0..fitter.theta())
        .map(|a| covariance[(a, a)].sqrt())
        .collect();
    let intervals = intervals(fitter.unknowns, params, &stderr);
    (stderr, intervals)
}

/// Each unknown's 95 % interval from its standard error, within its box ([`box_interval`]).
pub(crate) fn intervals(
    unknowns: &[crate::space::Unknown],
    params: &[f64],
    stderr: &[f64],
) -> Vec<(f64, f64)> {
    stderr
        .iter()
        .zip(unknowns)
        .map(|(&se, u)| box_interval(interval95(params[u.slot], se, u.log), se, (u.min, u.max)))
        .collect()
}

/// The interval of an unknown with standard error `se` searched in `bounds`: `wald` cut at
/// the box, or the box itself when `se` is infinite (undetermined); NaN (not computed) stays
/// NaN. The estimate is searched in the box, so no value outside it is a candidate: a Wald
/// interval reaching past it (a damping's `[-9e-4, …]`, a stiffness pinned at the box's max
/// 10 reported as `[9.91, 10.09]`) named values the fit could never return. An undetermined
/// unknown's `(0, inf)` or `(-inf, inf)` also wrote infinity into JSON as `null`.
pub(crate) fn box_interval(wald: (f64, f64), se: f64, bounds: (f64, f64)) -> (f64, f64) {
    if se == f64::INFINITY {
        return bounds;
    }
    if wald.0.is_nan() || wald.1.is_nan() {
        return wald;
    }
    (wald.0.max(bounds.0), wald.1.min(bounds.1))
}

/// The 95 % Wald interval of a value `v` with standard error `se`: on `ln v` for a parameter
/// searched in log coordinates (`log`: positive, with a wide box), `v e^(±1.96 se/v)` (the
/// delta method's `se(ln v) = se/v`), else `v ± 1.96 se`.
///
/// Why on `ln v`: a positive parameter the data determine poorly (a damping with `se/v` ≈ 0.75
/// at σ = 1e-2) has a skewed estimate, and the symmetric interval reaches below zero, where
/// no truth is, while too short above: with every coordinate or 20 % missing at σ = 1e-2
/// (50 draws each) the symmetric intervals held 98.3 % of the true dampings, these 94.4 %
/// (stiffness and rest lengths, `se/v` ≈ 1 %, unchanged); BENCHMARKS.md, "Intervals on ln θ".
/// The fit's own coordinates are these, so the interval is the Gauss–Newton model's where it
/// was built. Always positive, never past zero.
pub(crate) fn interval95(v: f64, se: f64, log: bool) -> (f64, f64) {
    use line_profile::WALD as Z95;
    match log && v > 0.0 {
        true => {
            let factor = (Z95 * se / v).exp();
            (v / factor, v * factor)
        }
        false => (v - Z95 * se, v + Z95 * se),
    }
}

/// Each take's `[x0, v0]` block of the fit's variables.
pub(crate) fn take_states(fitter: &Fitter<'_>, q: &[f64]) -> Vec<Vec<f64>> {
    let (dim, ns) = (fitter.theta(), fitter.state_len());
    (0..fitter.takes.len())
        .map(|k| q[dim + k * ns..dim + (k + 1) * ns].to_vec())
        .collect()
}

/// Names of the fit's variables: the unknowns', then `take K: particles[i].x0.x` etc.
fn variable_names(fitter: &Fitter<'_>, _scene: &Scene) -> Vec<String> {
    let mut names: Vec<String> = fitter.unknowns.iter().map(|u| u.name.clone()).collect();
    for k in 0..fitter.takes.len() {
        for &i in &fitter.tangent.free {
            for what in ["x0", "v0"] {
                for c in ["x", "y", "z"] {
                    names.push(format!("take {k}: particles[{i}].{what}.{c}"));
                }
            }
        }
    }
    names
}

#[cfg(test)]
mod tests {
    use super::{box_interval, interval95};
    use approx::assert_relative_eq;

    /// Guards the log intervals: positive, the value their geometric centre, the Wald interval
    /// on `ln v`, and the symmetric one where se ≪ v (the two agree to first order).
    #[test]
    fn a_log_searched_interval_is_symmetric_in_ln_v_and_never_reaches_zero() {
        let (v, se) = (0.2, 0.15);
        let (lo, hi) = interval95(v, se, true);
        assert!(lo > 0.0 && lo < v && v < hi);
        assert_relative_eq!(lo * hi, v * v, max_relative = 1e-12);
        assert_relative_eq!((hi / lo).ln(), 2.0 * 1.96 * se / v, max_relative = 1e-12);
        let (slo, shi) = interval95(v, se, false);
        assert!(slo < 0.0, "the symmetric one reaches below zero: {slo}");
        assert_relative_eq!(shi - slo, 2.0 * 1.96 * se, max_relative = 1e-12);
        let (lo, hi) = interval95(100.0, 1e-3, true);
        assert_relative_eq!(lo, 100.0 - 1.96e-3, max_relative = 1e-9);
        assert_relative_eq!(hi, 100.0 + 1.96e-3, max_relative = 1e-9);
    }

    /// A value at or below zero (a damping on its floor 0) or a standard error not computed
    /// keeps the symmetric interval, or NaN: no log of a non-positive number, no invented bound.
    #[test]
    fn a_non_positive_value_or_unknown_error_gives_no_log_interval() {
        let (lo, hi) = interval95(0.0, 0.1, true);
        assert_relative_eq!(lo, -0.196, max_relative = 1e-12);
        assert_relative_eq!(hi, 0.196, max_relative = 1e-12);
        let (lo, hi) = interval95(1.0, f64::NAN, true);
        assert!(lo.is_nan() && hi.is_nan());
        let (lo, hi) = interval95(1.0, f64::INFINITY, true);
        assert_eq!((lo, hi), (0.0, f64::INFINITY));
    }

    #[test]
    fn an_interval_is_cut_at_the_box_the_box_when_undetermined_nan_when_not_computed() {
        let damping = interval95(2e-4, 5e-4, false);
        assert!(damping.0 < 0.0);
        assert_eq!(box_interval(damping, 5e-4, (0.0, 1.0)), (0.0, damping.1));
        assert_eq!(box_interval((9.9, 10.1), 0.05, (1.0, 10.0)), (9.9, 10.0));
        assert_eq!(box_interval((2.0, 3.0), 0.2, (1.0, 10.0)), (2.0, 3.0));
        assert_eq!(
            box_interval((0.0, f64::INFINITY), f64::INFINITY, (1.0, 10.0)),
            (1.0, 10.0)
        );
        let (lo, hi) = box_interval((f64::NAN, f64::NAN), f64::NAN, (1.0, 10.0));
        assert!(lo.is_nan() && hi.is_nan());
    }
}
