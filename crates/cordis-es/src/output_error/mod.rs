//! `output-error`: the maximum-likelihood estimate of a network's parameters from tracked
//! motion — noisy, with gaps, partly observed, without velocities.
//!
//! # The estimator
//!
//! The short cost (SPEC §3) compares observed accelerations with the model's: it differentiates
//! the positions twice, so position noise σ becomes acceleration noise `√6 σ/dt²` *inside the
//! regressors*, which biases every estimate (errors-in-variables: on a soft block at 1 mm it is
//! 491 % off). The output-error estimate instead simulates the model and compares *positions*:
//!
//! ```text
//! min over θ, s_1…s_K   C = Σ_k Σ_t Σ_(i,c) observed  w_ic² (x_ic(t; θ, s_k) - y_ic(t))²
//! ```
//!
//! where `x(t; θ, s_k)` is the CORDIS simulation of take k from its initial state `s_k` (every
//! free particle's position x0 and velocity v0, unknown as in any real recording), `y` the
//! observations and `w` the weights (1/σ relative; 0 for a missing coordinate, a hidden
//! marker or an untracked particle). With Gaussian noise this is the maximum-likelihood
//! estimate; noise is never differentiated.
//!
//! # How it is minimised
//!
//! - **Exact sensitivities** `∂x(t)/∂(θ, s)` by the tangent recursion of the scheme
//!   ([`tangent`]), not finite differences: one rollout gives the cost, the Gauss–Newton matrix
//!   and the gradient.
//! - **Levenberg–Marquardt** ([`fit`]): Marquardt scaling, Nielsen's λ rule, projection on the
//!   boxes (θ in the internal coordinates of [`crate::space`]: log for wide positive boxes),
//!   scipy's `ftol`/`xtol`/`gtol`.
//! - **Growing windows**: one long rollout from a poor start has local minima (a wrong
//!   frequency puts the simulated motion out of phase). The fit runs on the first `W` frames of
//!   every take, then `2W`, `4W`, … up to the whole take, each stage from the previous optimum.
//!   On a short window the cost is nearly quadratic around any start that gets the first
//!   oscillation right.
//! - **Start** ([`start`]): the short cost's exact minimum on Savitzky–Golay-smoothed,
//!   gap-filled positions (biased but close), each take's initial state from a quadratic
//!   through its first frames.
//!
//! # What it reports
//!
//! σ̂ from the residuals, a standard error and a 95 % interval per unknown, their correlations,
//! and the directions the data do not determine, by name ([`uncertainty`]). The estimated
//! initial state goes into the identified scene, so replaying it reproduces the observed motion.

pub mod fit;
pub mod loss;
pub mod matrix_free;
pub mod observations;
pub mod run;
pub mod start;
pub mod tangent;
pub mod uncertainty;
mod windows;

use std::collections::VecDeque;

use cordis_core::Scene;
use nalgebra::DMatrix;

pub use loss::Loss;
pub use observations::Take;
pub use run::{Prepared, Progress, Step};

use crate::error::CostError;
use crate::space::ParameterSpace;
use fit::{Counts, Fitter, StageEnd};
use tangent::{Sens, Tangent};

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
        }
    }
}

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
    /// Estimated noise of a unit-weight coordinate, m: `√(C / (m - P))`.
    pub sigma: f64,
    /// Noise level read from the data before the fit (third differences), m, per take.
    pub noise_level: Vec<f64>,
    /// Observed coordinates m and fit variables P.
    pub observed: usize,
    pub variables: usize,
    /// Standard error per unknown in its physical unit (inf: not determined; NaN: not
    /// computed, when the matrix-free path's solve for it did not converge — the strategy
    /// then reports no uncertainty rather than a NaN).
    pub stderr: Vec<f64>,
    /// 95 % interval per unknown (`value ± 1.96 stderr`).
    pub intervals: Vec<(f64, f64)>,
    /// Covariance of the unknowns (physical units), row-major dim × dim.
    pub covariance: DMatrix<f64>,
    pub correlation: DMatrix<f64>,
    /// Directions the data do not determine, each by the names of the variables it moves.
    pub undetermined: Vec<Vec<String>>,
    /// The last window's Levenberg–Marquardt met its own criterion (ftol, xtol or gtol).
    pub converged: bool,
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

/// The maximum-likelihood estimate of `space`'s unknowns from `takes` (module docs), in one
/// call: [`run`] gives the same fit as steps a run loop can stop between and resume.
pub fn estimate(
    scene: &Scene,
    space: &ParameterSpace,
    takes: &[Take],
    config: &Config,
) -> Result<Estimate, CostError> {
    let prepared = Prepared::new(scene, space, takes.to_vec(), config)?;
    let mut progress = prepared.start(scene, space, config)?;
    while prepared.stage(space, &mut progress, &|| false)? != Step::Done {}
    prepared.finish(scene, space, &progress)
}

/// Drives `stage(q, w)` (the dense [`fit::lm_stage`] or the matrix-free one) over the growing
/// windows ([`windows`]) to the whole take.
#[cfg(test)]
pub(crate) fn grow_windows(
    fitter: &Fitter<'_>,
    q: &mut Vec<f64>,
    config: &Config,
    stage: &mut dyn FnMut(&mut Vec<f64>, usize) -> StageEnd,
) -> Result<(StageEnd, Vec<usize>), CostError> {
    let (noise, samples) = fitter
        .takes
        .iter()
        .map(start::noise_level_and_samples)
        .fold((0.0, 0), |a, b| if b.0 > a.0 { b } else { a });
    let robust = config.loss != Loss::Squared;
    let mut schedule = windows::Schedule::new(fitter, config.first_window, noise, samples, robust);
    loop {
        let end = stage(q, schedule.next);
        let mut after = schedule.after(fitter, q, end, &mut Sens::default())?;
        if after == windows::After::Stuck {
            after = schedule.keep_going(q)?;
        }
        if let windows::After::Done(end) = after {
            return Ok((end, schedule.windows));
        }
    }
}

#[allow(clippy::too_many_arguments)]
pub(crate) fn summarise(
    fitter: &Fitter<'_>,
    scene: &Scene,
    q: Vec<f64>,
    ne: fit::Normal,
    noise_level: Vec<f64>,
    counts: Counts,
    end: StageEnd,
    windows: Vec<usize>,
    start: String,
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
    let (stderr, intervals) = spread(fitter, &params, &covariance);
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
        stderr,
        intervals,
        covariance,
        correlation,
        undetermined,
        converged: end == StageEnd::Converged,
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

/// Standard errors (the covariance's diagonal) and 95 % intervals `θ̂ ± 1.96 se`.
pub(crate) fn spread(
    fitter: &Fitter<'_>,
    params: &[f64],
    covariance: &DMatrix<f64>,
) -> (Vec<f64>, Vec<(f64, f64)>) {
    let stderr: Vec<f64> = (0..fitter.theta())
        .map(|a| covariance[(a, a)].sqrt())
        .collect();
    let intervals = stderr
        .iter()
        .zip(fitter.unknowns)
        .map(|(se, u)| (params[u.slot] - 1.96 * se, params[u.slot] + 1.96 * se))
        .collect();
    (stderr, intervals)
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

/// The Cramér–Rao bound of the unknowns: standard deviations (physical units) of any unbiased
/// estimate from takes with the given observation pattern (their weights; values unused) and
/// Gaussian noise `sigma` (m) per unit-weight coordinate, the initial states unknown. `truth`
/// holds the true parameters and initial state; `space` names the unknowns.
pub fn cramer_rao(
    truth: &Scene,
    space: &ParameterSpace,
    takes: &[Take],
    sigma: f64,
) -> Result<Vec<f64>, CostError> {
    let truths = vec![truth; takes.len()];
    cramer_rao_takes(&truths, space, takes, sigma)
}

/// [`cramer_rao`] for takes that start from different initial states: `truths[k]` holds the
/// parameters (the same in every scene) and take k's true initial state.
pub fn cramer_rao_takes(
    truths: &[&Scene],
    space: &ParameterSpace,
    takes: &[Take],
    sigma: f64,
) -> Result<Vec<f64>, CostError> {
    if truths.len() != takes.len() {
        return Err(CostError::length("truths", takes.len(), truths.len()));
    }
    let truth = truths[0];
    let mut tangent = Tangent::new(truth)?;
    check_takes(truth, &tangent, takes)?;
    tangent.guard_by(takes);
    let slots: Vec<usize> = space.unknowns.iter().map(|u| u.slot).collect();
    let cols = tangent.columns(&slots);
    check_memory(&tangent, &cols, takes.len())?;
    let base = truth.param_values();
    let fitter = Fitter {
        tangent: &tangent,
        unknowns: &space.unknowns,
        base: &base,
        takes,
        cols,
    };
    let mut q: Vec<f64> = space
        .unknowns
        .iter()
        .map(|u| u.to_internal(base[u.slot]))
        .collect();
    for t in truths {
        for &i in &tangent.free {
            q.extend_from_slice(&t.particles[i].pos);
            q.extend_from_slice(&t.particles[i].vel);
        }
    }
    let longest = takes.iter().map(Take::frames).max().unwrap_or(0);
    let ne = fitter
        .normal(&q, longest, &mut Sens::default())
        .ok_or_else(|| CostError::mismatch("truth", "the true model diverges"))?;
    let (cov, _) = uncertainty::covariance(&ne.h, sigma * sigma);
    let cov = uncertainty::physical(&cov, &fitter.chain(&q));
    Ok((0..space.dim()).map(|a| cov[(a, a)].sqrt()).collect())
}

/// The expected mean absolute relative error (%) of estimates with standard deviations `sd`
/// about `values`: `100 · mean_k √(2/π) sd_k / |value_k|` (the mean of |N(0, sd²)| is
/// `sd √(2/π)`). This is the Cramér–Rao bound on the "mean parameter error" cordis reports.
pub fn expected_error_pct(sd: &[f64], values: &[f64]) -> f64 {
    let k = (2.0 / std::f64::consts::PI).sqrt();
    let sum: f64 = sd
        .iter()
        .zip(values)
        .map(|(s, v)| k * s / v.abs().max(f64::MIN_POSITIVE))
        .sum();
    100.0 * sum / sd.len().max(1) as f64
}

/// The scene with the estimate's parameters and take `take`'s estimated initial state written
/// in, so that simulating it replays that take.
pub fn identified_scene(scene: &Scene, estimate: &Estimate, take: usize) -> Scene {
    let mut out = scene.clone();
    out.set_param_values(&estimate.params);
    let free: Vec<usize> = (0..scene.num_particles())
        .filter(|&i| !scene.particles[i].fixed)
        .collect();
    for (f, &i) in free.iter().enumerate() {
        let s = &estimate.states[take][6 * f..6 * f + 6];
        out.particles[i].pos = [s[0], s[1], s[2]];
        out.particles[i].vel = [s[3], s[4], s[5]];
    }
    out
}

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
    Ok(())
}

/// Every take fits the scene, has 3 frames, and every free particle it does not observe is
/// tied by links to one it observes (or to a fixed one): otherwise nothing can estimate that
/// particle's initial state.
pub(crate) fn check_takes(
    scene: &Scene,
    tangent: &Tangent,
    takes: &[Take],
) -> Result<(), CostError> {
    if takes.is_empty() {
        return Err(CostError::mismatch("trajectory", "no take given"));
    }
    let n = scene.num_particles();
    let mut adj = vec![Vec::new(); n];
    for l in &scene.links {
        if let [a, b] = l.particles[..] {
            adj[a].push(b);
            adj[b].push(a);
        }
    }
    for (k, take) in takes.iter().enumerate() {
        if take.particles() != n {
            return Err(CostError::mismatch(
                format!("take {k}"),
                format!("has {} particles, the scene {n}", take.particles()),
            ));
        }
        if take.frames() < 3 {
            return Err(CostError::mismatch(
                format!("take {k}"),
                format!("has {} frames, at least 3 are needed", take.frames()),
            ));
        }
        let mut seen: Vec<bool> = (0..n).map(|i| take.tracks(i)).collect();
        let mut queue: VecDeque<usize> = (0..n).filter(|&i| seen[i]).collect();
        while let Some(i) = queue.pop_front() {
            for &j in &adj[i] {
                if !seen[j] {
                    seen[j] = true;
                    queue.push_back(j);
                }
            }
        }
        if let Some(&i) = tangent.free.iter().find(|&&i| !seen[i]) {
            return Err(CostError::mismatch(
                format!("take {k}, particle {i}"),
                "has no visible frame and no link to an observed particle: \
                 its initial state cannot be estimated",
            ));
        }
    }
    Ok(())
}

/// Refuses fits whose sensitivity matrices and normal equations would not fit in memory.
pub(crate) fn check_memory(
    tangent: &Tangent,
    cols: &tangent::Columns,
    takes: usize,
) -> Result<(), CostError> {
    const LIMIT: f64 = 8.0 * (1u64 << 30) as f64;
    let rows = 3.0 * tangent.plan.n as f64;
    let width = cols.len as f64;
    let total = cols.theta as f64 + takes as f64 * (cols.len - cols.theta) as f64;
    let bytes = 8.0 * (6.0 * rows * width + 2.0 * width * width + total * total);
    if bytes > LIMIT {
        return Err(CostError::mismatch(
            "output-error",
            format!(
                "needs about {:.1} GB for {} sensitivity columns over {} coordinates \
                 (limit {:.0} GB)",
                bytes / 1e9,
                cols.len,
                rows,
                LIMIT / 1e9
            ),
        ));
    }
    Ok(())
}

#[cfg(test)]
mod tests;
