//! The free run of a candidate from the observed start, for stability-aware identification
//! ([`crate::problem::stable`]): no observed frame is used after the first two.

use super::kind::CostKind;
use super::objective::{CostScratch, Objective};
use cordis_core::Vec3;

impl Objective {
    /// Largest distance (m) of a free particle from the free particles' centroid over the
    /// observed frames: the size the network's shape is known to reach. 0 without free
    /// particles.
    pub(crate) fn observed_spread(&self) -> f64 {
        (0..self.obs.frames)
            .map(|t| spread(self.obs.frame(t), &self.free))
            .fold(0.0, f64::max)
    }

    /// Runs the rollout step of the costs (the simulator's step, fixed particles held where
    /// frame 1 has them, hidden state — TGR tendons… — driven along frame 0 then carried) from
    /// the observed frames 0 and 1 (static cost: at rest at frame 0) up to frame
    /// `frames - 1`, as `simulate --frames` would;
    /// returns the first frame at which a free particle's position is not finite or beyond
    /// the observed motion's divergence guard ([`cordis_core::runaway`], growing with the
    /// time run), or the free particles' spread exceeds `limit` (m).
    pub(crate) fn free_run_diverges(
        &self,
        p: &[f64],
        frames: usize,
        limit: f64,
        s: &mut CostScratch,
    ) -> Option<usize> {
        let mg = self.masses_gravity(p);
        // Static frames are poses, not a motion: the run starts at rest at the first one.
        let start = usize::from(self.kind != CostKind::Static);
        s.x_prev.copy_from_slice(self.obs.frame(0));
        s.x.copy_from_slice(self.obs.frame(start));
        if !self.hidden.is_empty() {
            self.reset_hidden(p, &mut s.hidden);
            self.advance_hidden_observed(p, 0, &mut s.hidden, &mut s.discard);
        }
        let hold = self.obs.frame(start);
        for t in 2..frames {
            self.rollout_step(p, t - 1, mg, hold, s);
            let bound = self.runaway.limit(t - 1, mg.1.norm());
            let runaway = self
                .free
                .iter()
                .any(|&i| !self.runaway.within(&s.x[i], bound));
            if runaway {
                return Some(t);
            }
            // A NaN spread (it cannot be: positions are finite here) counts as diverged.
            let d = spread(&s.x, &self.free);
            if d > limit || d.is_nan() {
                return Some(t);
            }
        }
        None
    }
}

/// Largest distance (m) of the particles `ids` of `x` from their centroid.
fn spread(x: &[Vec3], ids: &[usize]) -> f64 {
    if ids.is_empty() {
        return 0.0;
    }
    let c = ids.iter().fold(Vec3::zeros(), |c, &i| c + x[i]) / ids.len() as f64;
    ids.iter()
        .map(|&i| (x[i] - c).norm_squared())
        .fold(0.0, f64::max)
        .sqrt()
}
