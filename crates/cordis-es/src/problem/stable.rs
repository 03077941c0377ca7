//! Stability-aware identification (issue 7, thesis §4.4): the horse model the thesis
//! identified "explodes, the particles moving away from each other" once simulated freely,
//! because a short cost only ever predicts one step from real frames and cannot see an
//! instability that the observed motion does not excite. With a [`StableHorizon`], a candidate
//! is rejected (`+inf` cost, so it ranks last in every strategy) when
//!
//! 1. its stability bound ([`cordis_core::stability`], Gershgorin on the linearised scheme)
//!    exceeds 1 — checked first, O(links); or
//! 2. its free run from the observed frames 0 and 1 diverges within `frames` frames: a
//!    position not finite or beyond the observed motion's guard ([`cordis_core::runaway`]),
//!    or the free particles' spread about their centroid beyond `spread` times the largest
//!    the observed frames show.
//!
//! The spread test is what catches a network that comes apart without blowing up numerically
//! (a particle drifting away at constant speed, a floppy model unfolding): the thesis'
//! "particles moving away from each other". It is blind to rigid motion (translation,
//! rotation), so a horse galloping off is not a divergence. Both checks are deterministic
//! functions of the candidate, so results still depend only on the seed.
//!
//! Cost: one bound (O(links)) plus up to `frames` simulator steps per evaluation, on top of
//! the cost itself; nothing at all when no horizon is set.

use crate::error::CostError;

/// Default `spread`: a network whose particles get twice as far from their centroid as they
/// ever were in the observed motion has lost its shape.
pub const DEFAULT_SPREAD: f64 = 2.0;

/// `--stable-horizon FRAMES` (and `--stable-spread`): how long, from the observed start, a
/// candidate must run freely without diverging.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StableHorizon {
    /// Frames of the free run, frame 0 included (as `simulate --frames`): at least 3.
    pub frames: usize,
    /// Largest allowed spread of the free particles about their centroid, as a multiple of
    /// the largest observed one: finite and ≥ 1.
    pub spread: f64,
}

impl StableHorizon {
    /// Checks the values (the place named in errors is `--stable-horizon`/`--stable-spread`).
    pub fn new(frames: usize, spread: f64) -> Result<Self, CostError> {
        if frames < 3 {
            return Err(CostError::kind(
                "--stable-horizon",
                format!(
                    "the free run needs at least 3 frames (two observed, one run), got {frames}"
                ),
            ));
        }
        if !(spread.is_finite() && spread >= 1.0) {
            return Err(CostError::kind(
                "--stable-spread",
                format!("must be a finite factor ≥ 1 of the observed spread, got {spread}"),
            ));
        }
        Ok(StableHorizon { frames, spread })
    }
}

/// A horizon bound to one problem: the spread limit in metres.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Guard {
    pub horizon: StableHorizon,
    /// `spread ×` the observed spread, m (`+inf` when nothing is free or nothing moves apart
    /// from anything: a single particle has no shape to lose).
    pub limit: f64,
}

impl Guard {
    pub(crate) fn new(horizon: StableHorizon, observed_spread: f64) -> Guard {
        let limit = if observed_spread > 0.0 {
            horizon.spread * observed_spread
        } else {
            f64::INFINITY
        };
        Guard { horizon, limit }
    }
}

/// Why a candidate was rejected (see [`crate::problem::Problem::stability_check`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Rejection {
    /// The stability bound `max q_i` (≥ 1).
    Bound(f64),
    /// The free run diverged at this frame.
    Diverged(usize),
}
