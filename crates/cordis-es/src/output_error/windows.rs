//! The growing windows of the output-error fit, as a state machine a run can stop between
//! (and a checkpoint can hold): the fit runs on the first `W` frames of every take, then `2W`,
//! `4W`, … up to the whole take, each stage from the previous optimum.
//!
//! A window is *clean* when its fit leaves residuals no larger than the noise read from the
//! data allows: rms ≤ σₙ · (1 + 3 √(4/n + 1/(2 n_w))), σₙ the third-difference level read from
//! `n` differences (its relative spread ≈ 2/√n, [`super::start::noise_level_and_samples`]) and
//! `n_w` the window's observed coordinates (the relative spread of a residual rms at the right
//! parameters is √(1/(2 n_w)); fitting `p` variables only lowers it, by √(1 − p/n_w)). Beyond
//! rounding on noiseless data. Three spreads above: a wrong basin. With a robust loss the
//! residuals are measured by their robust scale (`1.4826 · median |r|`, relative variance
//! `1.36/n_w`) instead: the outliers the loss downweights would keep the rms above the noise. Measured: the 1.5 σₙ this
//! replaced let fits stuck at 1.3 σₙ (a quarter of the particles hidden, σ = 1e-2 of the size:
//! 19 of 20 fits at σ̂ ≈ 2 σ, parameters 1.97× the Cramér–Rao bound off) through as clean.
//!
//! The whole take's window is clean only when its residuals are also *white*: their lag-1
//! autocorrelation `ρ₁ = Σ rₜ rₜ₊₁ / Σ rₜ²` (over every observed coordinate's consecutive
//! observed frames, `m` pairs) at most `3/√m`, three of its standard deviations for white
//! residuals. A wrong basin leaves a smooth misfit in the residuals (the wrong model's motion
//! against the observed one, sampled far above its frequencies: lag-1 correlation ≈ 1), so a
//! misfit of `δ² σ²` raises `ρ₁` by `≈ δ²/(1 + δ²)`, whereas the rms test cannot tell a misfit
//! smaller than the noise level's own uncertainty (`3 · 2/√n`, ≈ 8 % at 200 frames of 20
//! particles). At the maximum-likelihood optimum the fitted variables make `ρ₁` slightly
//! negative (the residual is the noise less its projection on the smooth sensitivities): the
//! test is conservative. Measured with a quarter of the particles hidden at σ = 1e-2 (draws
//! 0–13, 17, 21, 45 of `bench noise`): the fits that converged at the noise level end at
//! ρ₁ = −0.030 … +0.003; four that ended on their budget at σ̂ = 1.02–1.06 σ — inside the rms
//! bound — at ρ₁ = 0.059–0.119 (> 3/√m = 0.027–0.039); with the test all four converge in the
//! truth's basin. Shorter windows are not tested: there the test stepped back from windows a
//! wrong basin had reached, every restart got stuck at a short window, and the fit went on
//! from one of them to σ̂ = 1.4 σ (draw 9) where the rms test alone reached 1.04 σ. Noiseless
//! residuals at rounding are not tested.
//!
//! A window that is not clean, the last one included, is a wrong basin reached by growing too
//! fast: the fit goes back to the last clean window's optimum and grows by a smaller factor
//! (1.5, 1.25, 1.125 of the last clean window); a window that cannot be grown into cleanly
//! even so is a wrong basin no smaller step leaves: the schedule says [`After::Stuck`], and
//! the fit restarts from another start ([`super::run`]); when it has no start left, the window
//! is kept as it ended and the doubling resumes from it ([`Schedule::keep_going`]) without
//! stepping back again ([`Schedule::settle`]). In the dense fits a whole take that ends on
//! its budget with clean residuals is stuck too ([`Schedule::restart_on_budget`]): a crawl a
//! wrong basin's valley makes as often as the truth's (a quarter hidden at σ = 1e-2, 50 draws:
//! 1 of the 2 such ends converges after the restarts, 49 → 19 %). The first
//! window has nothing to go back to and is kept as it ends. A window the last optimum cannot
//! even simulate (it diverges) is a window grown too far, handled alike.

use serde::{Deserialize, Serialize};

use super::fit::{Fitter, StageEnd};
use super::loss;
use super::tangent::Sens;
use crate::error::CostError;
use crate::strategy::{bits, lossless};

/// Where the growing windows stand: the window the next stage fits and what a back-off
/// returns to. Serialised exactly (IEEE bits), so a resumed fit takes the same steps.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub(crate) struct Schedule {
    /// The windows fitted so far, frames.
    pub windows: Vec<usize>,
    /// The window the next stage fits, frames.
    pub next: usize,
    /// The last clean window's optimum and its length.
    good: Option<Good>,
    #[serde(with = "lossless")]
    growth: f64,
    longest: usize,
    /// The data's noise level (third differences), m, and the differences it was read from.
    #[serde(with = "lossless")]
    noise: f64,
    noise_samples: usize,
    /// Residual rms of noiseless data at rounding, m.
    #[serde(with = "lossless")]
    rounding: f64,
    /// How the last stage ended.
    last: Option<Last>,
    /// Whether the fit's loss is robust: windows are then measured by the residuals' robust
    /// scale (`1.4826 · median |r|`), which the outliers it downweights do not inflate.
    robust: bool,
    /// Whether the stuck window diverged (then no going on from it).
    stuck_diverged: bool,
    /// No start reaches the noise ([`Schedule::settle`]): windows above it no longer step
    /// back, the doubling goes on.
    #[serde(default)]
    settled: bool,
    /// Whether a whole-take stage that ends on its iteration budget counts as stuck
    /// ([`Schedule::restart_on_budget`]).
    #[serde(default)]
    budget_is_stuck: bool,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct Good {
    #[serde(with = "bits")]
    q: Vec<f64>,
    window: usize,
}

/// How a stage ended: the solver's end, the residual rms (m; +inf when it diverged) and the
/// window's clean bound (m), the residuals' lag-1 autocorrelation and its bound (module doc;
/// 0 and 0 in checkpoints from before the whiteness test).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
struct Last {
    end: StageEnd,
    #[serde(with = "lossless")]
    rms: f64,
    #[serde(with = "lossless")]
    tolerance: f64,
    #[serde(with = "lossless", default)]
    lag: f64,
    #[serde(with = "lossless", default)]
    lag_bound: f64,
}

impl Last {
    /// Residuals at the noise level and white; never a diverged window's (its rms is
    /// infinite, which an unknown noise level's infinite tolerance would let through).
    fn clean(&self) -> bool {
        self.rms.is_finite() && self.rms <= self.tolerance && self.lag <= self.lag_bound
    }
}

/// What comes after a stage.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum After {
    /// Fit [`Schedule::next`] next.
    Stage,
    /// The whole take is fitted; the last stage ended so.
    Done(StageEnd),
    /// The last window left residuals above the noise even after the smallest step back: a
    /// wrong basin. Restart, or [`Schedule::keep_going`].
    Stuck,
}

impl Schedule {
    /// The schedule of a fit whose data have noise level `noise` (m, third differences) read
    /// from `noise_samples` differences.
    pub fn new(
        fitter: &Fitter<'_>,
        first_window: usize,
        noise: f64,
        noise_samples: usize,
        robust: bool,
    ) -> Self {
        let longest = fitter.takes.iter().map(|t| t.frames()).max().unwrap_or(0);
        Schedule {
            windows: Vec::new(),
            next: first_window.min(longest),
            good: None,
            growth: 2.0,
            longest,
            noise,
            noise_samples,
            rounding: 1e-9 * fitter.observed_size(),
            last: None,
            robust,
            stuck_diverged: false,
            settled: false,
            budget_is_stuck: false,
        }
    }

    /// A whole-take stage that ends on its budget counts as stuck: the fit restarts (module
    /// doc) and keeps the attempt that fits the whole take best. For the dense fits only,
    /// whose budget is a wrong basin's crawl; the matrix-free ones end on it in the right basin.
    pub fn restart_on_budget(mut self) -> Self {
        self.budget_is_stuck = true;
        self
    }

    /// Residual rms above which a fit of `window` frames is a wrong basin, m (module doc).
    fn tolerance(&self, fitter: &Fitter<'_>, window: usize) -> f64 {
        // No third difference to read the noise from (a take of 3 frames, or gaps in every
        // run of 4): nothing to judge a basin against. Treating the unknown level as 0 called
        // every fit "above the data's noise level (0.000e0 m)" and sent it to the restarts.
        if self.noise_samples == 0 {
            return f64::INFINITY;
        }
        let n = self.noise_samples as f64;
        let n_w = fitter.observed_in(window).max(1) as f64;
        // The relative variance of a residual rms is 1/(2 n_w); of the median-based scale
        // 1.167²/n_w.
        let measure = if self.robust { 1.36 } else { 0.5 };
        let spread = (4.0 / n + measure / n_w).sqrt();
        (self.noise * (1.0 + 3.0 * spread)).max(self.rounding)
    }

    /// The residuals' lag-1 autocorrelation over `window` frames and its bound `3/√m` (module
    /// doc); `(0, 0)` where it is not tested: a window short of the whole take, a diverged one
    /// (its rms already fails), residuals at rounding (noiseless data fitted exactly).
    fn whiteness(
        &self,
        fitter: &Fitter<'_>,
        q: &[f64],
        window: usize,
        rms: f64,
        buf: &mut Sens,
    ) -> (f64, f64) {
        if window < self.longest || !rms.is_finite() || rms <= self.rounding {
            return (0.0, 0.0);
        }
        match fitter.lag_correlation(q, window, buf, self.robust) {
            Some((lag, pairs)) if pairs > 0 => (lag, 3.0 / (pairs as f64).sqrt()),
            _ => (0.0, 0.0),
        }
    }

    /// The residuals' rms over `window` frames (their robust scale for a robust loss), m.
    pub(super) fn residual_scale(
        &self,
        fitter: &Fitter<'_>,
        q: &[f64],
        window: usize,
        buf: &mut Sens,
    ) -> f64 {
        if !self.robust {
            return fitter.rms(q, window, buf);
        }
        fitter.residuals(q, window, buf).map_or(f64::INFINITY, |r| {
            loss::robust_scale(r.iter().flatten().copied())
        })
    }

    /// The last stage's residual rms, m (+inf when it diverged).
    pub fn last_rms(&self) -> f64 {
        self.last.map_or(f64::INFINITY, |l| l.rms)
    }

    /// Whether the last stage left residuals above its window's clean bound, or not white.
    pub fn above_noise(&self) -> bool {
        self.last.is_some_and(|l| !l.clean())
    }

    /// The longest take, frames.
    pub fn longest(&self) -> usize {
        self.longest
    }

    /// Records that the stage on [`Schedule::next`] ended with `end` at `q` and decides the
    /// next window; `q` goes back to the last clean optimum when the window was grown too far.
    pub fn after(
        &mut self,
        fitter: &Fitter<'_>,
        q: &mut Vec<f64>,
        end: StageEnd,
        buf: &mut Sens,
    ) -> Result<After, CostError> {
        let w = self.next;
        self.windows.push(w);
        self.stuck_diverged = false;
        let diverged = end == StageEnd::Diverged;
        if diverged && self.good.is_none() {
            // Diverged from this attempt's start: stuck, so another start (multiple shooting,
            // a seeded restart) gets its turn; an error only when every one did
            // ([`Self::keep_going`]).
            self.last = Some(Last {
                end,
                rms: f64::INFINITY,
                tolerance: self.tolerance(fitter, w),
                lag: 0.0,
                lag_bound: 0.0,
            });
            self.stuck_diverged = true;
            return Ok(After::Stuck);
        }
        let rms = match diverged {
            true => f64::INFINITY,
            false => self.residual_scale(fitter, q, w, buf),
        };
        let tolerance = self.tolerance(fitter, w);
        let (lag, lag_bound) = self.whiteness(fitter, q, w, rms, buf);
        let last = Last {
            end,
            rms,
            tolerance,
            lag,
            lag_bound,
        };
        self.last = Some(last);
        if self.crawled() {
            return Ok(After::Stuck);
        }
        let Some(from) = self.good.as_ref().map(|g| g.window) else {
            // The first window: nothing to go back to.
            return self.keep_going(q);
        };
        if last.clean() || (self.settled && !diverged) {
            return self.keep_going(q);
        }
        if self.growth > 1.1 {
            // Too far in one step: back to the last clean optimum, a smaller step.
            if let Some(good) = &self.good {
                q.clone_from(&good.q);
            }
            self.growth = 1.0 + (self.growth - 1.0) / 2.0;
            self.next = ((from as f64 * self.growth).ceil() as usize).clamp(from + 1, self.longest);
            return Ok(After::Stage);
        }
        self.stuck_diverged = diverged;
        Ok(After::Stuck)
    }

    /// Whether the whole take's stage ended on its budget with clean residuals while
    /// [`Schedule::restart_on_budget`] holds and starts are left: a crawl along a valley,
    /// stuck (a window above the noise steps back first, as any other).
    fn crawled(&self) -> bool {
        let at_whole = self.windows.last().is_some_and(|&w| w >= self.longest);
        self.budget_is_stuck
            && !self.settled
            && at_whole
            && self
                .last
                .is_some_and(|l| l.end == StageEnd::Budget && l.clean())
    }

    /// The window this schedule got stuck at, frames.
    pub fn stuck_window(&self) -> usize {
        self.windows.last().copied().unwrap_or(self.next)
    }

    /// No start reaches the noise level: from here on a window above it is kept and the
    /// doubling goes on (stepping back again at every doubling would only repeat the search).
    pub fn settle(&mut self) {
        self.settled = true;
    }

    /// Whether [`Schedule::settle`] was called.
    pub fn settled(&self) -> bool {
        self.settled
    }

    /// After [`After::Stuck`] with no restart left: keeps the last window as it ended and
    /// resumes the doubling from it (an error when it diverged).
    pub fn keep_going(&mut self, q: &[f64]) -> Result<After, CostError> {
        let w = self.windows.last().copied().unwrap_or(self.next);
        if self.stuck_diverged {
            return Err(CostError::mismatch(
                "fit",
                match &self.good {
                    Some(g) => format!(
                        "the model fitted to {} frames diverges within {w}: narrow the boxes \
                         or check dt",
                        g.window
                    ),
                    None => format!(
                        "the model diverged within {w} frames from every start (the first, \
                         multiple shooting, the seeded restarts): narrow the boxes, check dt, \
                         or against outliers (a swapped marker) try a robust loss"
                    ),
                },
            ));
        }
        if w >= self.longest {
            // The solver's criterion held on residuals above the noise: not converged.
            let end = match self.last {
                Some(l) if !l.clean() && l.end == StageEnd::Converged => StageEnd::AboveNoise,
                Some(l) => l.end,
                None => StageEnd::Budget,
            };
            return Ok(After::Done(end));
        }
        // Clean, the first window, or no smaller step left: go on from here.
        self.good = Some(Good {
            q: q.to_vec(),
            window: w,
        });
        self.growth = 2.0;
        self.next = (2 * w).min(self.longest);
        Ok(After::Stage)
    }
}

#[cfg(test)]
mod tests {
    use super::super::observations::Take;
    use super::super::tangent::Tangent;
    use super::super::tests::{anchored_particle, fitter_of};
    use super::*;
    use crate::space::ParameterSpace;
    use cordis_core::{Bounds, Param};

    const FRAMES: usize = 1000;
    const SIGMA: f64 = 1e-2;

    /// A diverged window (rms +inf) is never clean, even where the noise level could not be
    /// read and every finite rms passes (the tolerance is then infinite): it was taken as a
    /// clean optimum and the back-off never ran.
    #[test]
    fn a_diverged_window_is_never_clean_even_with_an_unknown_noise_level() {
        let last = |rms: f64| Last {
            end: StageEnd::Diverged,
            rms,
            tolerance: f64::INFINITY,
            lag: 0.0,
            lag_bound: 0.0,
        };
        assert!(!last(f64::INFINITY).clean());
        assert!(!last(f64::NAN).clean());
        assert!(last(1.0).clean());
    }

    /// An anchored particle thrown sideways (it circles the anchor instead of swinging through
    /// it), 1000 noisy frames, its stiffness (10) unknown.
    struct Thrown {
        tangent: Tangent,
        space: ParameterSpace,
        base: Vec<f64>,
        takes: Vec<Take>,
    }

    impl Thrown {
        fn new() -> Self {
            let mut scene = anchored_particle();
            scene.particles[0].vel = [0.0, 1.0, 0.0];
            let traj = crate::identify::add_noise(&scene.simulate(FRAMES).unwrap(), SIGMA, 7);
            scene.types[0].params[0] = Param::Unknown(Bounds {
                min: 1.0,
                max: 100.0,
                init: None,
            });
            Thrown {
                tangent: Tangent::new(&scene).unwrap(),
                space: ParameterSpace::from_scene(&scene),
                base: scene.param_values(),
                takes: vec![Take::complete(&traj)],
            }
        }

        fn fitter(&self) -> Fitter<'_> {
            fitter_of(&self.tangent, &self.space, &self.base, &self.takes)
        }

        /// The whole take's stage ending with `end` at `stiffness` (the true initial state).
        fn end_at(&self, stiffness: f64, end: StageEnd, schedule: &mut Schedule) -> After {
            let mut q = vec![self.space.unknowns[0].to_internal(stiffness)];
            q.extend_from_slice(&[1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
            schedule
                .after(&self.fitter(), &mut q, end, &mut Sens::default())
                .unwrap()
        }

        /// A schedule whose first window is the whole take, the noise level the truth's.
        fn schedule(&self) -> Schedule {
            Schedule::new(&self.fitter(), FRAMES, SIGMA, 3 * (FRAMES - 3), false)
        }
    }

    /// Guards the whiteness test: a whole-take fit whose residual rms is inside the noise
    /// bound (a level read from as many differences as the take has) but whose residuals carry
    /// a smooth misfit (the stiffness 0.2 % off: the oscillation drifts out of phase) is not
    /// clean, so not called converged; the true parameters on the same data are.
    #[test]
    fn a_smooth_misfit_inside_the_rms_bound_is_not_clean() {
        let thrown = Thrown::new();
        let fitter = thrown.fitter();
        let mut truth = thrown.schedule();
        let after = thrown.end_at(10.0, StageEnd::Converged, &mut truth);
        assert_eq!(after, After::Done(StageEnd::Converged));
        assert!(!truth.above_noise());
        let mut off = thrown.schedule();
        let after = thrown.end_at(10.02, StageEnd::Converged, &mut off);
        let tolerance = off.tolerance(&fitter, FRAMES);
        assert!(
            off.last_rms() > truth.last_rms() && off.last_rms() < tolerance,
            "the misfit is inside the rms bound: {} < {tolerance} (truth {})",
            off.last_rms(),
            truth.last_rms()
        );
        let last = off.last.unwrap();
        assert!(
            last.lag > last.lag_bound,
            "{} vs {}",
            last.lag,
            last.lag_bound
        );
        assert_eq!(after, After::Done(StageEnd::AboveNoise));
        assert!(off.above_noise());
    }

    /// A first window that diverges is stuck, not an error: the fit's other starts (multiple
    /// shooting, seeded restarts) get their turn (a swapped marker or weights 2 on every
    /// marker once ended the whole fit here). Going on from it, every start having diverged,
    /// is the error, which says so.
    #[test]
    fn a_first_window_that_diverges_is_stuck_and_an_error_only_from_every_start() {
        let thrown = Thrown::new();
        let mut schedule = thrown.schedule();
        let after = thrown.end_at(10.0, StageEnd::Diverged, &mut schedule);
        assert_eq!(after, After::Stuck);
        assert!(schedule.above_noise() && schedule.last_rms() == f64::INFINITY);
        let e = schedule.keep_going(&[]).unwrap_err().to_string();
        assert!(e.contains("from every start"), "{e}");
    }

    /// Guards the budget rule of the dense fits: a whole-take stage that ends on its budget
    /// with clean residuals is stuck (the fit restarts) when the schedule restarts on the
    /// budget and no start is left to settle it; otherwise, or once settled, it is done, on
    /// its budget. A budget end above the noise is handled as any window above it.
    #[test]
    fn a_whole_take_budget_end_restarts_only_where_asked_and_not_once_settled() {
        let thrown = Thrown::new();
        let after = thrown.end_at(10.0, StageEnd::Budget, &mut thrown.schedule());
        assert_eq!(after, After::Done(StageEnd::Budget));
        let mut restarting = thrown.schedule().restart_on_budget();
        let after = thrown.end_at(10.0, StageEnd::Budget, &mut restarting);
        assert_eq!(after, After::Stuck);
        assert!(
            !restarting.above_noise(),
            "stuck for its budget, not its residuals"
        );
        restarting.settle();
        assert_eq!(
            restarting.keep_going(&[]).unwrap(),
            After::Done(StageEnd::Budget)
        );
        let after = thrown.end_at(10.0, StageEnd::Budget, &mut restarting);
        assert_eq!(
            after,
            After::Done(StageEnd::Budget),
            "settled: no start left"
        );
        let after = thrown.end_at(
            10.0,
            StageEnd::Converged,
            &mut thrown.schedule().restart_on_budget(),
        );
        assert_eq!(after, After::Done(StageEnd::Converged));
        // Above the noise (a smooth misfit) with nothing to step back to: kept as it ended.
        let mut off = thrown.schedule().restart_on_budget();
        let after = thrown.end_at(10.02, StageEnd::Budget, &mut off);
        assert_eq!(after, After::Done(StageEnd::Budget));
        assert!(off.above_noise());
    }
}
