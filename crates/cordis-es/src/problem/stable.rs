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

/// The warning for an identified model beyond the stability bound
/// ([`cordis_core::stability`]: `max q_i ≥ 1`), `None` below it. The bound is sufficient, not
/// necessary: such a model can replay its data from the state it was fitted from and still
/// blow up from another start (the output-error fit of the soft block's discovered graph,
/// ratio 2.5, replayed from the observed first frames: 3e13 m RMS). Every shipped example's
/// truth is below it (0.02–0.90), so a model of tracked motion beyond it is suspect.
pub fn beyond_bound_warning(scene: &cordis_core::Scene) -> Option<String> {
    let r = cordis_core::stability::stability(scene).ok()?;
    if r.stable {
        return None;
    }
    let at = r
        .worst_particle
        .map_or(String::new(), |i| format!(" at particle {i}"));
    Some(format!(
        "the identified model is beyond the stability bound (ratio {:.3}{at}, `cordis check`): \
         it may blow up when simulated from a start other than the one it was fitted from; \
         suspect its values on a box's edge, or the scene's links",
        r.max_ratio
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Guards the warning against an identified scene beyond the bound (the rigid object with
    /// masses 100× lighter: every ratio 100× larger): it names the ratio and the particle;
    /// the rigid object itself (ratio 0.41) says nothing.
    #[test]
    fn an_identified_model_beyond_the_stability_bound_is_named() {
        let mut scene = cordis_core::examples::rigid();
        assert_eq!(beyond_bound_warning(&scene), None);
        for p in &mut scene.particles {
            p.mass = cordis_core::Param::Known(p.mass.value() / 100.0);
        }
        let w = beyond_bound_warning(&scene).expect("a warning");
        assert!(w.contains("beyond the stability bound (ratio "), "{w}");
        assert!(w.contains("at particle "), "{w}");
    }
}
