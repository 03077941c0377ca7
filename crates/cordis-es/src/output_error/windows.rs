//! The growing windows of the output-error fit, as a state machine a run can stop between
//! (and a checkpoint can hold): the fit runs on the first `W` frames of every take, then `2W`,
//! `4W`, … up to the whole take, each stage from the previous optimum.
//!
//! A window whose fit leaves residuals well above the noise read from the data (rms > 1.5 ×
//! the third-difference level, or beyond rounding on noiseless data) is a wrong basin reached
//! by growing too fast: the fit goes back to the last good window's optimum and grows by a
//! smaller factor (1.5, 1.25, 1.125 of the last clean window); a window that cannot be grown
//! into cleanly even so is a wrong basin no smaller step leaves: the schedule says
//! [`After::Stuck`], and the fit restarts from another start ([`super::run`]); when it has no
//! start left, the window is kept as it ended and the doubling resumes from it
//! ([`Schedule::keep_going`]). A window the last optimum cannot even simulate (it diverges) is
//! a window grown too far, handled alike.

use serde::{Deserialize, Serialize};

use super::fit::{Fitter, StageEnd};
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
    /// Residual rms above which a window counts as a wrong basin, m.
    #[serde(with = "lossless")]
    tolerance: f64,
    /// Whether the stuck window diverged (then no going on from it).
    stuck_diverged: bool,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct Good {
    #[serde(with = "bits")]
    q: Vec<f64>,
    window: usize,
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
    /// The schedule of a fit whose data have noise level `noise` (m, third differences).
    pub fn new(fitter: &Fitter<'_>, first_window: usize, noise: f64) -> Self {
        let longest = fitter.takes.iter().map(|t| t.frames()).max().unwrap_or(0);
        Schedule {
            windows: Vec::new(),
            next: first_window.min(longest),
            good: None,
            growth: 2.0,
            longest,
            tolerance: (1.5 * noise).max(1e-9 * fitter.observed_size()),
            stuck_diverged: false,
        }
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
            return Err(CostError::mismatch(
                "fit",
                format!(
                    "the model diverged from its start within {w} frames: \
                     narrow the boxes or check dt"
                ),
            ));
        }
        if w >= self.longest && !diverged {
            return Ok(After::Done(end));
        }
        let clean = !diverged && fitter.rms(q, w, buf) <= self.tolerance;
        if let (Some(good), false) = (&self.good, clean) {
            if self.growth > 1.1 {
                // Too far in one step: back to the last clean optimum, a smaller step.
                let from = good.window;
                q.clone_from(&good.q);
                self.growth = 1.0 + (self.growth - 1.0) / 2.0;
                self.next =
                    ((from as f64 * self.growth).ceil() as usize).clamp(from + 1, self.longest);
                return Ok(After::Stage);
            }
            self.stuck_diverged = diverged;
            return Ok(After::Stuck);
        }
        self.keep_going(q)
    }

    /// After [`After::Stuck`] with no restart left: keeps the last window as it ended and
    /// resumes the doubling from it (an error when it diverged).
    pub fn keep_going(&mut self, q: &[f64]) -> Result<After, CostError> {
        let w = self.windows.last().copied().unwrap_or(self.next);
        if self.stuck_diverged {
            let from = self.good.as_ref().map_or(0, |g| g.window);
            return Err(CostError::mismatch(
                "fit",
                format!(
                    "the model fitted to {from} frames diverges within {w}: \
                     narrow the boxes or check dt"
                ),
            ));
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
