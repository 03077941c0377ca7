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
//! - **Multiple shooting** ([`shooting`]): a fit whose windows stay above the noise level (a
//!   wrong basin) goes back to its start with the takes cut into segments, each simulated from
//!   its own state and tied to the next by continuity, then finishes by single shooting; then
//!   seeded restarts ([`run`]).
//! - **Start** ([`start`]): the short cost's exact minimum on Savitzky–Golay-smoothed,
//!   gap-filled positions (biased but close), each take's initial state from a quadratic
//!   through its first frames.
//!
//! # What it reports
//!
//! σ̂ from the residuals, a standard error and a 95 % interval per unknown, their correlations,
//! and the directions the data do not determine, by name ([`uncertainty`]). The estimated
//! initial state goes into the identified scene, so replaying it reproduces the observed motion.

pub(crate) mod checks;
mod config;
pub(crate) mod continuity;
pub mod fit;
mod impute;
pub(crate) mod line_profile;
pub mod loss;
pub mod matrix_free;
pub mod observations;
pub mod run;
pub(crate) mod shooting;
pub mod start;
mod summary;
pub mod tangent;
pub mod uncertainty;
mod windows;

use cordis_core::Scene;

pub use config::Config;
pub use line_profile::{Intervals, Widened};
pub use loss::Loss;
pub use observations::Take;
pub use run::{Prepared, Progress, Step};
pub use summary::Estimate;
pub(crate) use summary::{box_interval, interval95};

use crate::error::CostError;
use crate::space::ParameterSpace;
use checks::{check_memory, check_takes};
use fit::Fitter;
use tangent::{Sens, Tangent};

/// The maximum-likelihood estimate of `space`'s unknowns from `takes` (module docs), in one
/// call: [`run`] gives the same fit as steps a run loop can stop between and resume.
pub fn estimate(
    scene: &Scene,
    space: &ParameterSpace,
    takes: &[Take],
    config: &Config,
) -> Result<Estimate, CostError> {
    estimate_until(scene, space, takes, config, &|| false)
        .map(|e| e.expect("a fit that is never halted finishes"))
}

/// [`estimate`], stopped between (or within) the fit's steps once `halt()` turns true
/// (Ctrl-C): `None` then — the windows before the last see part of the motion only, so a
/// stopped fit has no estimate. [`run`] gives the steps themselves, resumable.
pub fn estimate_until(
    scene: &Scene,
    space: &ParameterSpace,
    takes: &[Take],
    config: &Config,
    halt: &dyn Fn() -> bool,
) -> Result<Option<Estimate>, CostError> {
    let prepared = Prepared::new(scene, space, takes.to_vec(), config)?;
    let mut progress = prepared.start(scene, space, config)?;
    loop {
        match prepared.stage(space, &mut progress, halt)? {
            Step::Done => break,
            Step::Stopped => return Ok(None),
            Step::More if halt() => return Ok(None),
            Step::More => {}
        }
    }
    prepared.finish(scene, space, &progress, halt).map(Some)
}

/// Drives `stage(q, w)` (the dense [`fit::lm_stage`] or the matrix-free one) over the growing
/// windows ([`windows`]) to the whole take.
#[cfg(test)]
pub(crate) fn grow_windows(
    fitter: &Fitter<'_>,
    q: &mut Vec<f64>,
    config: &Config,
    stage: &mut dyn FnMut(&mut Vec<f64>, usize) -> fit::StageEnd,
) -> Result<(fit::StageEnd, Vec<usize>), CostError> {
    let (noise, samples) = fitter
        .takes
        .iter()
        .map(start::unit_weight_noise_level)
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

/// The Cramér–Rao bound of the unknowns: standard deviations (physical units) of any unbiased
/// estimate from takes with the given observation pattern (their weights; values unused) and
/// Gaussian noise `sigma` (m) per unit-weight coordinate, the initial states unknown. `truth`
/// holds the true parameters and initial state; `space` names the unknowns. Above
/// [`matrix_free::DENSE_MAX_COLUMNS`] sensitivity columns (the 32 × 32 cloth) the θ block of
/// `H⁻¹` comes from the matrix-free fit's CG solves ([`matrix_free::cramer_rao_sd`]: variances
/// to ~0.1 %, NaN where a solve did not settle).
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
    let large = cols.len > matrix_free::DENSE_MAX_COLUMNS;
    match large {
        true => matrix_free::check_memory(&tangent, takes)?,
        false => check_memory(&tangent, &cols, takes.len())?,
    }
    let base = truth.param_values();
    let fitter = Fitter {
        tangent: &tangent,
        unknowns: &space.unknowns,
        base: &base,
        takes,
        cols,
        continuity: None,
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
    if large {
        return matrix_free::cramer_rao_sd(&fitter, &q, longest, sigma);
    }
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

#[cfg(test)]
mod tests;
