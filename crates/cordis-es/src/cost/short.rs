//! The generic short-term cost (Louchet's, thesis §3.2.1): every frame predicted by one
//! simulator step from the two observed frames before it. This is the identification
//! bottleneck: per evaluation it runs every link pass once per frame, so it calls the plan's
//! typed passes directly on the precomputed observed positions and velocities, and replaces
//! the conditional grid by the pairs precomputed from the observation.

use super::geometry::Geometry;
use super::kernels::{springs, PairGeometry, SpringBuf};
use super::kind::CostKind;
use super::objective::{CostScratch, Objective};
use crate::error::CostError;
use cordis_core::forces::spring::spring_force_quadratic;
use cordis_core::world::{Clock, OneClock, WorldClock};
use cordis_core::Vec3;
use std::ops::Range;

impl Objective {
    /// `s.core.f = F(x(t), v(t))` at observed frame `t`: the plan's passes in `Plan::forces`
    /// order, so the sum is bit-for-bit a simulator step's.
    pub(crate) fn observed_forces(&self, p: &[f64], t: usize, s: &mut CostScratch, geo: &Geometry) {
        let plan = &self.plan;
        let (x, v) = (self.obs.frame(t), self.obs.velocity(t));
        let f = &mut s.core.f;
        let buf = &mut s.springs;
        f.fill(Vec3::zeros());
        for (ri, r) in plan.springs.runs.iter().enumerate() {
            let z2 = plan.springs.quadratic.get(ri).copied().flatten();
            let kz = [
                p[r.param],
                p[r.param + 1],
                p[r.param + 2],
                z2.map_or(0.0, |s| p[s]),
            ];
            let pairs = &plan.springs.pairs;
            let g = geo.springs.as_ref();
            listed_springs(g, (t, x, v), pairs, r.start..r.end, kz, f, buf);
        }
        plan.dampers.accumulate(p, v, f);
        plan.anchors.accumulate(p, x, v, f);
        plan.drags.accumulate(p, v, f);
        plan.nonlinear_drags.accumulate(p, v, f);
        plan.angles.accumulate(p, x, f);
        plan.planes.accumulate(p, x, v, f);
        plan.muscles.accumulate(p, x, v, f, &mut s.core.muscles);
        let passes = plan.conditionals.iter().zip(&mut s.core.grids);
        for (((c, grid), known), g) in passes.zip(&self.obs.pairs).zip(&geo.conditionals) {
            match known {
                Some(known) if c.range(p) == known.range => {
                    let z2 = c.quadratic.map_or(0.0, |s| p[s]);
                    let kz = [p[c.param], p[c.param + 1], p[c.param + 2], z2];
                    let pairs = known.at(t);
                    listed_springs(g.as_ref(), (t, x, v), pairs, 0..pairs.len(), kz, f, buf);
                }
                _ => c.accumulate(p, x, v, f, grid),
            }
        }
        self.hidden_forces(p, t, x, v, f, &mut s.hidden);
    }

    /// Every hidden pass's forces at frame `n` into `f`, advancing `state` to n+1.
    pub(crate) fn hidden_forces(
        &self,
        p: &[f64],
        n: usize,
        x: &[Vec3],
        v: &[Vec3],
        f: &mut [Vec3],
        state: &mut [f64],
    ) {
        let mut at = 0;
        for h in &self.hidden {
            let len = h.state_len();
            h.add_forces(p, n, x, v, f, &mut state[at..at + len]);
            at += len;
        }
    }

    /// Advances `state` by the step from observed frame `n` (its forces are discarded).
    pub(crate) fn advance_hidden_observed(
        &self,
        p: &[f64],
        n: usize,
        state: &mut [f64],
        discard: &mut [Vec3],
    ) {
        let (x, v) = (self.obs.frame(n), self.obs.velocity(n));
        self.hidden_forces(p, n, x, v, discard, state);
    }

    /// The hidden state of frame 0.
    pub(crate) fn reset_hidden(&self, p: &[f64], state: &mut [f64]) {
        let x0 = self.obs.frame(0);
        let mut at = 0;
        for h in &self.hidden {
            let len = h.state_len();
            h.reset(p, x0, &mut state[at..at + len]);
            at += len;
        }
    }

    /// Generic short cost: local costs into `per` (zeroed by the caller), returns their sum.
    pub(crate) fn short_generic(&self, p: &[f64], s: &mut CostScratch, per: &mut [f64]) -> f64 {
        let (_, g) = self.masses_gravity(p);
        match &self.plan.worlds {
            None => self.short_with(&OneClock::new(self.plan.dt, g), p, s, per),
            Some(steps) => self.short_with(&WorldClock { steps, g }, p, s, per),
        }
    }

    /// The short cost with each particle's world dt and gravity from `clock`.
    #[inline(always)]
    fn short_with<C: Clock>(
        &self,
        clock: &C,
        p: &[f64],
        s: &mut CostScratch,
        per: &mut [f64],
    ) -> f64 {
        self.short_terms(clock, p, s, |_, i, xh, x0| per[i] += squared_error(xh, x0));
        s.plain = self.free.iter().map(|&i| per[i]).sum();
        s.plain
    }

    /// Every term of the short cost, in order (predicted frame t = 2 … T-1, then free particle
    /// ascending): `term(t, i, x̂_i(t), x_i(t))`. The one loop behind the cost, its residuals
    /// and eq 3.3's local costs, so all see the same predictions bit for bit.
    #[inline(always)]
    pub(crate) fn short_terms<C: Clock>(
        &self,
        clock: &C,
        p: &[f64],
        s: &mut CostScratch,
        mut term: impl FnMut(usize, usize, &Vec3, &Vec3),
    ) {
        let n = self.plan.n;
        let (m, _) = self.masses_gravity(p);
        let provot = !self.plan.provot.links.is_empty();
        let geo = self.geometry();
        if !self.hidden.is_empty() {
            // Frame 1's state: one step along observed frame 0 (frame t's prediction below
            // advances it from t-1 to t).
            self.reset_hidden(p, &mut s.hidden);
            self.advance_hidden_observed(p, 0, &mut s.hidden, &mut s.discard);
        }
        for t in 2..self.obs.frames {
            self.observed_forces(p, t - 1, s, geo);
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
                        (x1[i] * 2.0 - x2[i]) + clock.kick(i, f[i] / m[i])
                    } else {
                        x0[i]
                    };
                }
                self.plan.provot.apply(p, &mut s.xhat, &self.plan.free);
                for &i in &self.free {
                    term(t, i, &s.xhat[i], &x0[i]);
                }
            } else {
                for &i in &self.free {
                    let xh = (x1[i] * 2.0 - x2[i]) + clock.kick(i, f[i] / m[i]);
                    term(t, i, &xh, &x0[i]);
                }
            }
        }
    }

    /// Number of residual components of the short cost: 3 per (predicted frame, free
    /// particle), the length [`Objective::residuals`] writes (static cost: 3 per (frame, free
    /// particle)).
    pub fn residual_len(&self) -> usize {
        let frames = match self.kind {
            CostKind::Static => self.obs.frames,
            _ => self.obs.frames.saturating_sub(2),
        };
        3 * frames * self.free.len()
    }

    /// The short cost as a residual vector, for least-squares solvers: writes the components
    /// `x̂_i(t) - x_i(t)` (m; x, y, z of every free particle ascending, frame t = 2 … T-1) into
    /// `out` (length [`Objective::residual_len`], owned by the caller: nothing is allocated)
    /// and returns the short cost of `p`, bit for bit what the generic path of
    /// [`Objective::evaluate`] returns (`Σ out² ` equals it to rounding: the cost sums each
    /// particle's terms first). When a prediction is not finite the cost is `+inf` and `out`
    /// must not be used.
    ///
    /// The static cost's residuals are written the same way: `x̂_i - x_i(t)` of the step
    /// from rest at every frame t = 0 … T-1 ([`CostKind::Static`]).
    ///
    /// Errors unless the kind is `short` or `static` (the residuals of other kinds are not
    /// written), or when `p` or `out` has the wrong length.
    pub fn residuals(
        &self,
        p: &[f64],
        s: &mut CostScratch,
        out: &mut [f64],
    ) -> Result<f64, CostError> {
        if !self.writes_residuals() {
            return Err(CostError::kind(
                format!("cost kind `{}`", self.kind),
                "residuals are written for the short and static costs only",
            ));
        }
        self.check_params(p)?;
        let len = self.residual_len();
        if out.len() != len {
            return Err(CostError::length("residual buffer", len, out.len()));
        }
        Ok(self.residuals_unchecked(p, s, out))
    }

    pub(crate) fn residuals_unchecked(
        &self,
        p: &[f64],
        s: &mut CostScratch,
        out: &mut [f64],
    ) -> f64 {
        let mut per = std::mem::take(&mut s.per);
        per.fill(0.0);
        let (_, g) = self.masses_gravity(p);
        let mut k = 0;
        let mut write = |i: usize, xh: &Vec3, x0: &Vec3| {
            let e = xh - x0;
            out[k] = e.x;
            out[k + 1] = e.y;
            out[k + 2] = e.z;
            k += 3;
            per[i] += squared_error(xh, x0);
        };
        let rest = self.kind == CostKind::Static;
        match (&self.plan.worlds, rest) {
            (None, false) => {
                let mut write = |_, i, xh: &Vec3, x0: &Vec3| write(i, xh, x0);
                self.short_terms(&OneClock::new(self.plan.dt, g), p, s, &mut write)
            }
            (None, true) => self.static_terms(&OneClock::new(self.plan.dt, g), p, s, &mut write),
            (Some(steps), false) => {
                let mut write = |_, i, xh: &Vec3, x0: &Vec3| write(i, xh, x0);
                self.short_terms(&WorldClock { steps, g }, p, s, &mut write)
            }
            (Some(steps), true) => self.static_terms(&WorldClock { steps, g }, p, s, &mut write),
        }
        let c: f64 = self.free.iter().map(|&i| per[i]).sum();
        s.per = per;
        s.plain = c;
        if c.is_nan() {
            f64::INFINITY
        } else {
            c
        }
    }

    /// Whether [`Objective::residuals`] writes this kind's residuals (`short`, `static`).
    pub fn writes_residuals(&self) -> bool {
        matches!(self.kind, CostKind::Short | CostKind::Static)
    }

    /// The short cost of a model with no force and no gravity, `Σ |x(t) - 2x(t-1) + x(t-2)|²`
    /// over the free particles (m²): the scale of what the forces must explain, against which
    /// a least-squares solver judges whether a minimum it found is a fit. For the static cost,
    /// what gravity alone would move the poses in one step, `Σ_t Σ_i |dt_i² g|²` (0 without
    /// gravity).
    pub fn acceleration_cost(&self) -> f64 {
        if self.kind == CostKind::Static {
            return self.static_scale();
        }
        let mut c = 0.0;
        for t in 2..self.obs.frames {
            let (x0, x1, x2) = (
                self.obs.frame(t),
                self.obs.frame(t - 1),
                self.obs.frame(t - 2),
            );
            for &i in &self.free {
                c += (x0[i] - x1[i] * 2.0 + x2[i]).norm_squared();
            }
        }
        c
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

/// Spring forces of `pairs[range]` at observed frame `t` (positions x, velocities v), from
/// the precomputed geometry when there is one; `kz` = [K, l0, Z, Z₂]. One branch per call
/// (a run of one type), none per link.
fn listed_springs(
    geo: Option<&PairGeometry>,
    (t, x, v): (usize, &[Vec3], &[Vec3]),
    pairs: &[[u32; 2]],
    range: Range<usize>,
    [k, l0, z, z2]: [f64; 4],
    f: &mut [Vec3],
    buf: &mut SpringBuf,
) {
    if z2 != 0.0 {
        match geo {
            Some(g) => g.springs_quadratic(t, range, pairs, [k, l0, z, z2], f),
            None => {
                for &[i, j] in &pairs[range] {
                    let (i, j) = (i as usize, j as usize);
                    let fi = spring_force_quadratic((&x[i], &x[j]), (&v[i], &v[j]), [k, l0, z, z2]);
                    f[i] += fi;
                    f[j] -= fi;
                }
            }
        }
        return;
    }
    let kz = [k, l0, z];
    // Z = 0 skips the velocity terms, as the core's kernel does (same bits).
    let damped = kz[2] != 0.0;
    match (geo, damped) {
        (Some(g), false) => g.springs::<false>(t, range, pairs, [kz[0], kz[1], 0.0], f),
        (Some(g), true) => g.springs::<true>(t, range, pairs, kz, f),
        (None, false) => springs::<false>(&pairs[range], [kz[0], kz[1], 0.0], x, v, f, buf),
        (None, true) => springs::<true>(&pairs[range], kz, x, v, f, buf),
    }
}
