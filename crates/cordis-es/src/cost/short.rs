//! The generic short-term cost (Louchet's, thesis §3.2.1): every frame predicted by one
//! simulator step from the two observed frames before it. This is the identification
//! bottleneck: per evaluation it runs every link pass once per frame, so it calls the plan's
//! typed passes directly on the precomputed observed positions and velocities, and replaces
//! the conditional grid by the pairs precomputed from the observation.

use super::kernels::{springs, SpringBuf};
use super::objective::{CostScratch, Objective};
use cordis_core::forces::grid::Grid;
use cordis_core::Vec3;

impl Objective {
    /// `f = F(x(t), v(t))` at observed frame `t`: the plan's passes in `Plan::forces` order,
    /// so the sum is bit-for-bit a simulator step's.
    pub(crate) fn observed_forces(
        &self,
        p: &[f64],
        t: usize,
        f: &mut [Vec3],
        grids: &mut [Grid],
        buf: &mut SpringBuf,
        hidden: &mut [f64],
    ) {
        let plan = &self.plan;
        let (x, v) = (self.obs.frame(t), self.obs.velocity(t));
        f.fill(Vec3::zeros());
        for r in &plan.springs.runs {
            let (k, l0, z) = (p[r.param], p[r.param + 1], p[r.param + 2]);
            let pairs = &plan.springs.pairs[r.start..r.end];
            if z == 0.0 {
                springs::<false>(pairs, [k, l0, 0.0], x, v, f, buf);
            } else {
                springs::<true>(pairs, [k, l0, z], x, v, f, buf);
            }
        }
        plan.dampers.accumulate(p, v, f);
        plan.anchors.accumulate(p, x, v, f);
        plan.drags.accumulate(p, v, f);
        plan.nonlinear_drags.accumulate(p, v, f);
        plan.angles.accumulate(p, x, f);
        for ((c, grid), known) in plan.conditionals.iter().zip(grids).zip(&self.obs.pairs) {
            match known {
                Some(pairs) if c.range(p) == pairs.range => {
                    let (k, l0, z) = (p[c.param], p[c.param + 1], p[c.param + 2]);
                    let pairs = pairs.at(t);
                    if z == 0.0 {
                        springs::<false>(pairs, [k, l0, 0.0], x, v, f, buf);
                    } else {
                        springs::<true>(pairs, [k, l0, z], x, v, f, buf);
                    }
                }
                _ => c.accumulate(p, x, v, f, grid),
            }
        }
        let mut at = 0;
        for h in &self.hidden {
            let len = h.state_len();
            h.add_forces(p, x, v, f, &mut hidden[at..at + len]);
            at += len;
        }
    }

    pub(crate) fn reset_hidden(&self, p: &[f64], state: &mut [f64]) {
        let mut at = 0;
        for h in &self.hidden {
            let len = h.state_len();
            h.reset(p, &mut state[at..at + len]);
            at += len;
        }
    }

    /// Generic short cost: local costs into `per` (zeroed by the caller), returns their sum.
    pub(crate) fn short_generic(&self, p: &[f64], s: &mut CostScratch, per: &mut [f64]) -> f64 {
        let n = self.plan.n;
        let dt2 = self.plan.dt * self.plan.dt;
        let (m, g) = self.masses_gravity(p);
        let provot = !self.plan.provot.links.is_empty();
        self.reset_hidden(p, &mut s.hidden);
        for t in 2..self.obs.frames {
            self.observed_forces(
                p,
                t - 1,
                &mut s.core.f,
                &mut s.core.grids,
                &mut s.springs,
                &mut s.hidden,
            );
            let (x1, x2, x0) = (
                self.obs.frame(t - 1),
                self.obs.frame(t - 2),
                self.obs.frame(t),
            );
            let f = &s.core.f;
            if provot {
                // Provot needs every predicted position (fixed ones exact) before scoring.
                for i in 0..n {
                    s.xhat[i] = if self.plan.free[i] {
                        (x1[i] * 2.0 - x2[i]) + (f[i] / m[i] + g) * dt2
                    } else {
                        x0[i]
                    };
                }
                self.plan.provot.apply(p, &mut s.xhat, &self.plan.free);
                for &i in &self.free {
                    per[i] += squared_error(&s.xhat[i], &x0[i]);
                }
            } else {
                for &i in &self.free {
                    let xh = (x1[i] * 2.0 - x2[i]) + (f[i] / m[i] + g) * dt2;
                    per[i] += squared_error(&xh, &x0[i]);
                }
            }
        }
        s.plain = self.free.iter().map(|&i| per[i]).sum();
        s.plain
    }
}

/// `|a - b|²`, or `+inf` when it is not a finite number (a NaN prediction never escapes).
#[inline(always)]
pub(crate) fn squared_error(a: &Vec3, b: &Vec3) -> f64 {
    let e = (a - b).norm_squared();
    if e < f64::INFINITY {
        e
    } else {
        f64::INFINITY
    }
}
