//! The output-error fit: Levenberg–Marquardt on exact sensitivities, over the unknown
//! parameters and every take's initial state, on windows that grow to the whole take.

use nalgebra::{DMatrix, DVector};

use super::continuity::{Continuity, Layout, SegmentEnd};
use super::observations::Take;
use super::tangent::{Columns, Sens, Tangent};
use crate::space::Unknown;

/// The fit's variables: `q = [z_θ, state of take 0, state of take 1, …]` where `z_θ` are the
/// unknowns' internal coordinates ([`crate::space`]: log for wide positive boxes) and a take's
/// state is `[x0, v0]` (m, m/s) per free particle.
pub(crate) struct Fitter<'a> {
    pub tangent: &'a Tangent,
    pub unknowns: &'a [Unknown],
    pub base: &'a [f64],
    pub takes: &'a [Take],
    pub cols: Columns,
    /// Multiple shooting ([`super::shooting`]): the takes are segments and each one's end is
    /// tied to the next one's state. `None`: every take is a rollout of its own.
    pub continuity: Option<&'a Continuity>,
}

/// What one evaluation with sensitivities returns: `cost = Σ w² e²`, the Gauss–Newton matrix
/// `H = Σ w² J_rᵀ J_r` and `g = Σ w² e J_r` (half the gradient) over the observed coordinates.
pub(crate) struct Normal {
    pub cost: f64,
    pub h: DMatrix<f64>,
    pub g: DVector<f64>,
}

impl Fitter<'_> {
    pub fn theta(&self) -> usize {
        self.unknowns.len()
    }

    pub fn state_len(&self) -> usize {
        6 * self.tangent.free.len()
    }

    pub fn len(&self) -> usize {
        self.theta() + self.takes.len() * self.state_len()
    }

    /// The scene's parameter vector at `q`.
    pub fn params(&self, q: &[f64]) -> Vec<f64> {
        let mut p = self.base.to_vec();
        for (u, &z) in self.unknowns.iter().zip(q) {
            p[u.slot] = u.from_internal(z);
        }
        p
    }

    /// `dp/dz` of each unknown at `q`.
    pub(crate) fn chain(&self, q: &[f64]) -> Vec<f64> {
        self.unknowns
            .iter()
            .zip(q)
            .map(|(u, &z)| if u.log { u.from_internal(z) } else { 1.0 })
            .collect()
    }

    /// Cost over the first `window` frames of each take; +inf when a rollout diverges.
    pub fn cost(&self, q: &[f64], window: usize, buf: &mut Sens) -> f64 {
        let p = self.params(q);
        let mut total = 0.0;
        let mut end = SegmentEnd::default();
        for (k, take) in self.takes.iter().enumerate() {
            let state = &q[self.theta() + k * self.state_len()..][..self.state_len()];
            let frames = window.min(take.frames());
            let tied = self.continuity.and_then(|c| c.tied(k, window, take));
            let mut visit = |t: usize, x: &[cordis_core::Vec3], _: Option<&[f64]>| {
                if tied.is_some() {
                    end.record(t, frames, x, None);
                }
                for (i, xi) in x.iter().enumerate() {
                    for c in 0..3 {
                        let (obs, w) = take.at(t, i, c);
                        if w > 0.0 {
                            let e = xi[c] - obs;
                            total += w * w * e * e;
                        }
                    }
                }
            };
            if self
                .tangent
                .rollout(&p, state, frames, None, buf, &mut visit)
                .is_err()
            {
                return f64::INFINITY;
            }
            if let (Some(c), Some(j)) = (self.continuity, tied) {
                let next = &q[self.theta() + j * self.state_len()..][..self.state_len()];
                total += c.cost(&self.tangent.free, next, &end);
            }
        }
        if total.is_finite() {
            total
        } else {
            f64::INFINITY
        }
    }

    /// The weighted residuals `w (x − y)` of each take over its first `window` frames (the
    /// take's layout, NaN where a coordinate is missing or beyond the window); `None` when a
    /// rollout diverges. For the robust loss's reweighting only: no NaN leaves the fit.
    pub fn residuals(&self, q: &[f64], window: usize, buf: &mut Sens) -> Option<Vec<Vec<f64>>> {
        let p = self.params(q);
        let mut out = Vec::with_capacity(self.takes.len());
        for (k, take) in self.takes.iter().enumerate() {
            let state = &q[self.theta() + k * self.state_len()..][..self.state_len()];
            let n = take.particles();
            let mut r = vec![f64::NAN; take.frames() * n * 3];
            let mut visit = |t: usize, x: &[cordis_core::Vec3], _: Option<&[f64]>| {
                for (i, xi) in x.iter().enumerate() {
                    for c in 0..3 {
                        let (obs, w) = take.at(t, i, c);
                        if w > 0.0 {
                            r[(t * n + i) * 3 + c] = w * (xi[c] - obs);
                        }
                    }
                }
            };
            let frames = window.min(take.frames());
            self.tangent
                .rollout(&p, state, frames, None, buf, &mut visit)
                .ok()?;
            out.push(r);
        }
        Some(out)
    }

    /// The weighted residuals' lag-1 autocorrelation over the first `window` frames,
    /// `Σ rₜ rₜ₊₁ / Σ rₜ²` over every observed coordinate's pairs of consecutive observed
    /// frames, and the number of pairs ([`super::windows`]: the whiteness test); `None` when a
    /// rollout diverges or every residual is 0. `inliers_only` (a robust loss): pairs with a
    /// residual beyond [`INLIER_SCALES`] robust scales left out — a tracking outlier (a swapped
    /// marker: tens of frames off together) is the loss's to discount, not a misfit.
    pub fn lag_correlation(
        &self,
        q: &[f64],
        window: usize,
        buf: &mut Sens,
        inliers_only: bool,
    ) -> Option<(f64, usize)> {
        let res = self.residuals(q, window, buf)?;
        let bound = match inliers_only {
            true => INLIER_SCALES * super::loss::robust_scale(res.iter().flatten().copied()),
            false => f64::INFINITY,
        };
        let (mut num, mut den, mut pairs) = (0.0, 0.0, 0usize);
        for (take, r) in self.takes.iter().zip(&res) {
            let n = take.particles();
            let frames = window.min(take.frames());
            for i in 0..n {
                for c in 0..3 {
                    for t in 0..frames.saturating_sub(1) {
                        let (a, b) = (r[(t * n + i) * 3 + c], r[((t + 1) * n + i) * 3 + c]);
                        if a.abs() <= bound && b.abs() <= bound {
                            num += a * b;
                            den += a * a;
                            pairs += 1;
                        }
                    }
                }
            }
        }
        (den > 0.0).then_some((num / den, pairs))
    }

    /// Cost, Gauss–Newton matrix and gradient over the first `window` frames of each take, in
    /// the fit's variables (internal coordinates for θ); `None` when a rollout diverges.
    pub fn normal(&self, q: &[f64], window: usize, buf: &mut Sens) -> Option<Normal> {
        let p = self.params(q);
        let chain = self.chain(q);
        let (nt, ns, width) = (self.theta(), self.state_len(), self.cols.len);
        let len = self.len();
        let mut h = DMatrix::zeros(len, len);
        let mut g = DVector::zeros(len);
        let mut cost = 0.0;
        let n = self.tangent.plan.n;
        // The weighted rows of several frames, row-major (row r at `[r · width ..]`), and
        // their weighted residuals: `H += GᵀG` and `g += Gᵀ(w e)` once per block, by one
        // matrix product (matrixmultiply through nalgebra's gemm) instead of one small
        // product per frame — measured 70 % of a 26-mass fit's time in the per-frame form.
        let block_frames = (BLOCK_BYTES / (8 * 3 * n * width).max(1)).clamp(1, 64);
        let capacity = block_frames * 3 * n;
        let mut rows = vec![0.0; capacity * width];
        let mut we = vec![0.0; capacity];
        let mut local_h = DMatrix::<f64>::zeros(width, width);
        let mut local_g = DVector::<f64>::zeros(width);
        let mut end = SegmentEnd::default();
        for (k, take) in self.takes.iter().enumerate() {
            local_h.fill(0.0);
            local_g.fill(0.0);
            let state = &q[nt + k * ns..][..ns];
            let frames = window.min(take.frames());
            let tied = self.continuity.and_then(|c| c.tied(k, window, take));
            let mut m = 0;
            let mut visit = |t: usize, x: &[cordis_core::Vec3], s: Option<&[f64]>| {
                let s = s.expect("rollout with columns");
                if tied.is_some() {
                    end.record(t, frames, x, Some(s));
                }
                for (i, xi) in x.iter().enumerate() {
                    for c in 0..3 {
                        let (obs, w) = take.at(t, i, c);
                        if w <= 0.0 {
                            continue;
                        }
                        let e = xi[c] - obs;
                        cost += w * w * e * e;
                        // θ columns in internal coordinates (times dp/dz), state columns as
                        // they are: two loops, no branch per column.
                        let src = &s[(3 * i + c) * width..][..width];
                        let (theta, state) = src.split_at(nt);
                        let row = &mut rows[m * width..(m + 1) * width];
                        let (rt, rs) = row.split_at_mut(nt);
                        for ((r, d), dz) in rt.iter_mut().zip(theta).zip(&chain) {
                            *r = w * (d * dz);
                        }
                        for (r, d) in rs.iter_mut().zip(state) {
                            *r = w * d;
                        }
                        we[m] = w * e;
                        m += 1;
                    }
                }
                if m + 3 * n > capacity || t + 1 == frames {
                    accumulate(&rows, &we, m, width, &mut local_h, &mut local_g);
                    m = 0;
                }
            };
            self.tangent
                .rollout(&p, state, frames, Some(&self.cols), buf, &mut visit)
                .ok()?;
            // Scatter the take's local columns (θ, then its own state) into the global system.
            let global = |a: usize| if a < nt { a } else { nt + k * ns + (a - nt) };
            for a in 0..width {
                g[global(a)] += local_g[a];
                for b in 0..width {
                    h[(global(a), global(b))] += local_h[(a, b)];
                }
            }
            if let (Some(c), Some(j)) = (self.continuity, tied) {
                let at = Layout {
                    free: &self.tangent.free,
                    theta: nt,
                    state: ns,
                    width,
                };
                cost += c.accumulate(&at, (k, j), (q, &mut end), &chain, &mut h, &mut g);
            }
        }
        cost.is_finite().then_some(Normal { cost, h, g })
    }

    /// The cost at which residuals are at the rounding of the positions themselves
    /// (`(8 ε max|y|)²` per observed coordinate): noiseless data fitted exactly, where no step
    /// can lower the cost any further.
    pub(crate) fn rounding_floor(&self, window: usize) -> f64 {
        let (mut count, mut size) = (0usize, 0.0f64);
        for take in self.takes {
            for t in 0..window.min(take.frames()) {
                for i in 0..take.particles() {
                    for c in 0..3 {
                        let (y, w) = take.at(t, i, c);
                        if w > 0.0 {
                            count += 1;
                            size = size.max((w * y).abs());
                        }
                    }
                }
            }
        }
        let r = 8.0 * f64::EPSILON * size;
        count as f64 * r * r
    }

    /// Root mean square of the weighted residuals over `window` frames, m.
    pub fn rms(&self, q: &[f64], window: usize, buf: &mut Sens) -> f64 {
        (self.cost(q, window, buf) / self.observed_in(window).max(1) as f64).sqrt()
    }

    /// The observed coordinates in the first `window` frames of every take.
    pub fn observed_in(&self, window: usize) -> usize {
        self.takes
            .iter()
            .map(|t| {
                let frames = window.min(t.frames());
                (0..frames)
                    .map(|f| {
                        (0..t.particles())
                            .map(|i| (0..3).filter(|&c| t.at(f, i, c).1 > 0.0).count())
                            .sum::<usize>()
                    })
                    .sum::<usize>()
            })
            .sum()
    }

    /// Largest weighted observed coordinate, m: the scale of rounding.
    pub fn observed_size(&self) -> f64 {
        let mut size = 0.0f64;
        for take in self.takes {
            for t in 0..take.frames() {
                for i in 0..take.particles() {
                    for c in 0..3 {
                        let (y, w) = take.at(t, i, c);
                        if w > 0.0 {
                            size = size.max((w * y).abs());
                        }
                    }
                }
            }
        }
        size
    }

    /// Projects `q` into the boxes (θ only; states are free).
    pub fn project(&self, q: &mut [f64]) {
        for (u, z) in self.unknowns.iter().zip(q.iter_mut()) {
            *z = u.clamp_internal(*z);
        }
    }

    /// The largest fraction f ≤ 1 of the step `delta` from `q` that keeps every θ coordinate
    /// in its box (1 when the whole step does).
    pub(crate) fn fraction_to_bounds(&self, q: &[f64], delta: &[f64]) -> f64 {
        let mut f: f64 = 1.0;
        for (k, u) in self.unknowns.iter().enumerate() {
            let (lo, hi) = u.internal_bounds();
            let room = if delta[k] > 0.0 {
                hi - q[k]
            } else if delta[k] < 0.0 {
                lo - q[k]
            } else {
                continue;
            };
            f = f.min((room / delta[k]).max(0.0));
        }
        f
    }

    /// The θ coordinates, not already held, that sit on a bound with the step `delta`
    /// pointing out of the box.
    pub(crate) fn pushed_out(&self, q: &[f64], delta: &[f64], held: &[bool]) -> Vec<usize> {
        let mut out = Vec::new();
        for (k, u) in self.unknowns.iter().enumerate() {
            let (lo, hi) = u.internal_bounds();
            let eps = 1e-12 * (hi - lo).abs().max(1e-300);
            let at_lo = q[k] <= lo + eps && delta[k] < 0.0;
            let at_hi = q[k] >= hi - eps && delta[k] > 0.0;
            if !held[k] && (at_lo || at_hi) {
                out.push(k);
            }
        }
        out
    }

    /// Which θ coordinates sit on a bound with the descent direction (-g) pointing out.
    pub(crate) fn held(&self, q: &[f64], g: &DVector<f64>) -> Vec<bool> {
        let mut held = vec![false; self.len()];
        for (k, u) in self.unknowns.iter().enumerate() {
            let (lo, hi) = u.internal_bounds();
            let eps = 1e-12 * (hi - lo).abs().max(1e-300);
            held[k] = (q[k] <= lo + eps && g[k] > 0.0) || (q[k] >= hi - eps && g[k] < 0.0);
        }
        held
    }
}

/// Weighted residuals beyond this many robust scales are outliers to the whiteness test of a
/// robust fit ([`Fitter::lag_correlation`]). The fit weighs a residual `r` by its loss's
/// `√ω(r/s)`, so an outlier's weighted residual is not large: Cauchy's tends to 2.385 s, and
/// exceeds 2 s from |r| = 3.7 s; Huber's `√(1.345 s |r|)` exceeds 2 s from |r| = 3 s. The
/// Gaussian residuals left out (4.6 %) are symmetric about 0 and leave white residuals white.
/// Measured on the soft block with two markers swapped for 40 frames (Cauchy, converged): the
/// lag-1 correlation of the inliers is 0.001; at 3 scales the swapped frames' 2.4 s weighted
/// residuals stay in and make it 0.070.
const INLIER_SCALES: f64 = 2.0;

/// Bytes of one block of weighted sensitivity rows in [`Fitter::normal`] (a few MB: the
/// product runs at matrix-multiply speed and the block stays in the last-level cache).
const BLOCK_BYTES: usize = 4 << 20;

/// `h += GᵀG`, `g += Gᵀ r` for the first `m` rows `G` of the row-major `rows` (`width`
/// columns) and their entries `r` of `we`.
fn accumulate(
    rows: &[f64],
    we: &[f64],
    m: usize,
    width: usize,
    h: &mut DMatrix<f64>,
    g: &mut DVector<f64>,
) {
    if m == 0 {
        return;
    }
    use nalgebra::{DVectorView, Dyn, MatrixView};
    let data = &rows[..m * width];
    // G (m × width, rows contiguous) and Gᵀ (width × m) as strided views of one buffer.
    let rows_view = MatrixView::<f64, Dyn, Dyn, Dyn, Dyn>::from_slice_with_strides_generic(
        data,
        Dyn(m),
        Dyn(width),
        Dyn(width),
        Dyn(1),
    );
    let cols_view = MatrixView::<f64, Dyn, Dyn, Dyn, Dyn>::from_slice_with_strides_generic(
        data,
        Dyn(width),
        Dyn(m),
        Dyn(1),
        Dyn(width),
    );
    h.gemm(1.0, &cols_view, &rows_view, 1.0);
    g.gemv(1.0, &cols_view, &DVectorView::from_slice(&we[..m], m), 1.0);
}

/// Levenberg–Marquardt settings of one stage.
#[derive(Clone, Copy, Debug)]
pub(crate) struct LmSettings {
    pub max_iterations: usize,
    pub ftol: f64,
    pub xtol: f64,
    pub gtol: f64,
    /// Dense path: a θ coordinate on its bound that the step pushes out is held and the step
    /// solved again on the box's face ([`step_in_the_box`]) instead of projected. Off where
    /// the cost kinks (contacts, conditional links, Provot's limit): measured on the Provot
    /// patch (`tests/output_error_kinds.rs`, seed 0) the face steps crawl along a kink to the
    /// window's budget (278 iterations, the same cost) where the projected ones converge in
    /// 226. The matrix-free path always re-solves.
    pub face_steps: bool,
}

/// How one LM stage ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub(crate) enum StageEnd {
    /// ftol, xtol or gtol held (or the cost is 0).
    Converged,
    /// The iteration budget ran out.
    Budget,
    /// λ grew past 1e20: no descent direction left from here.
    Stalled,
    /// The start of the stage diverged.
    Diverged,
    /// The run was told to stop (Ctrl-C, a time limit) before the stage ended: `q` holds the
    /// best point so far.
    Interrupted,
    /// The whole take's stage met its criterion with residuals above the data's noise level
    /// ([`super::windows`]), every restart too: a wrong basin, or a model that cannot follow
    /// the motion. Not converged.
    AboveNoise,
}

/// Counters of a fit.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub(crate) struct Counts {
    pub iterations: usize,
    pub evaluations: usize,
}

/// Minimises the cost over `window` frames from `q` (changed in place; only accepted steps
/// move it, so it is always the best point so far). `halt()` is asked before every iteration.
pub(crate) fn lm_stage(
    fit: &Fitter<'_>,
    q: &mut [f64],
    window: usize,
    set: LmSettings,
    counts: &mut Counts,
    buf: &mut Sens,
    halt: &dyn Fn() -> bool,
) -> StageEnd {
    let len = fit.len();
    counts.evaluations += 1;
    let Some(mut ne) = fit.normal(q, window, buf) else {
        return StageEnd::Diverged;
    };
    let mut scale: Vec<f64> = (0..len).map(|a| ne.h[(a, a)]).collect();
    let mut lambda = 1e-3;
    let mut nu = 2.0;
    let floor = fit.rounding_floor(window);
    for _ in 0..set.max_iterations {
        if halt() {
            return StageEnd::Interrupted;
        }
        counts.iterations += 1;
        if ne.cost <= floor {
            return StageEnd::Converged;
        }
        let mut held = fit.held(q, &ne.g);
        // gtol: every free column's cosine with the residual.
        let gmax = (0..len)
            .filter(|&a| !held[a] && ne.h[(a, a)] > 0.0)
            .map(|a| ne.g[a].abs() / (ne.h[(a, a)] * ne.cost).sqrt())
            .fold(0.0, f64::max);
        if gmax <= set.gtol {
            return StageEnd::Converged;
        }
        let solved = match set.face_steps {
            true => step_in_the_box(fit, q, &ne, &scale, &mut held, lambda),
            false => damped_step(&ne, &scale, &held, lambda),
        };
        let Some(delta) = solved else {
            lambda *= nu;
            nu *= 2.0;
            if lambda > 1e20 {
                return StageEnd::Stalled;
            }
            continue;
        };
        let mut trial: Vec<f64> = q.iter().zip(delta.iter()).map(|(a, b)| a + b).collect();
        fit.project(&mut trial);
        let step: DVector<f64> =
            DVector::from_iterator(len, trial.iter().zip(q.iter()).map(|(a, b)| a - b));
        let predicted = -(2.0 * ne.g.dot(&step) + step.dot(&(&ne.h * &step)));
        counts.evaluations += 1;
        let c = fit.cost(&trial, window, buf);
        if c < ne.cost {
            let reduction = ne.cost - c;
            let rho = if predicted > 0.0 {
                reduction / predicted
            } else {
                0.0
            };
            lambda *= (1.0 - (2.0 * rho - 1.0).powi(3)).max(1.0 / 3.0);
            nu = 2.0;
            let qnorm = q.iter().map(|x| x * x).sum::<f64>().sqrt();
            let small_step = step.norm() <= set.xtol * (set.xtol + qnorm);
            let small_gain = reduction <= set.ftol * ne.cost && predicted <= set.ftol * ne.cost;
            q.copy_from_slice(&trial);
            counts.evaluations += 1;
            let Some(next) = fit.normal(q, window, buf) else {
                return StageEnd::Diverged;
            };
            ne = next;
            for (s, a) in scale.iter_mut().zip(0..len) {
                *s = s.max(ne.h[(a, a)]);
            }
            if small_step || small_gain {
                return StageEnd::Converged;
            }
        } else {
            // MINPACK's ftol test holds for a rejected step too: neither the actual change nor
            // the model's gain exceeds ftol of the cost. At rounding (noiseless data fitted
            // exactly, a rollout's own rounding a few times `rounding_floor`) every step is
            // rejected and λ would otherwise climb to `Stalled`.
            if (c - ne.cost).abs() <= set.ftol * ne.cost && predicted <= set.ftol * ne.cost {
                return StageEnd::Converged;
            }
            lambda *= nu;
            nu *= 2.0;
            if lambda > 1e20 {
                return StageEnd::Stalled;
            }
        }
    }
    StageEnd::Budget
}

/// The damped step from `q`, with every θ coordinate on a bound that the step pushes out of
/// the box held (added to `held`) and the step solved again on the box's face, as the
/// matrix-free path does: projecting the coupled step instead changes its direction, and the
/// coordinates still free never get the step that is best with the others held. `None` when a
/// solve fails.
fn step_in_the_box(
    fit: &Fitter<'_>,
    q: &[f64],
    ne: &Normal,
    scale: &[f64],
    held: &mut [bool],
    lambda: f64,
) -> Option<DVector<f64>> {
    loop {
        let delta = damped_step(ne, scale, held, lambda)?;
        let pushed = fit.pushed_out(q, delta.as_slice(), held);
        if pushed.is_empty() {
            return Some(delta);
        }
        // Each pass holds at least one more coordinate: at most θ passes.
        for a in pushed {
            held[a] = true;
        }
    }
}

/// `(H + λ D) δ = -g` on the coordinates not held (held ones get δ = 0), by Cholesky.
fn damped_step(ne: &Normal, scale: &[f64], held: &[bool], lambda: f64) -> Option<DVector<f64>> {
    let free: Vec<usize> = (0..held.len()).filter(|&a| !held[a]).collect();
    let m = free.len();
    let mut a = DMatrix::zeros(m, m);
    let mut b = DVector::zeros(m);
    for (r, &i) in free.iter().enumerate() {
        b[r] = -ne.g[i];
        for (c, &j) in free.iter().enumerate() {
            a[(r, c)] = ne.h[(i, j)];
        }
        let d = if scale[i] > 0.0 { scale[i] } else { 1.0 };
        a[(r, r)] += lambda * d;
    }
    let x = a.cholesky()?.solve(&b);
    let mut out = DVector::zeros(held.len());
    for (r, &i) in free.iter().enumerate() {
        out[i] = x[r];
    }
    x.iter().all(|v| v.is_finite()).then_some(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::space::ParameterSpace;
    use cordis_core::{Bounds, Param};

    /// A step that pushes a θ coordinate on its bound out of the box is solved again with that
    /// coordinate held: the others get the reduced system's solution, not the coupled step's
    /// (guards `step_in_the_box` against falling back to a projection of the coupled step).
    #[test]
    fn a_step_pushing_a_bound_coordinate_out_is_solved_again_on_the_face() {
        let mut scene = super::super::tests::anchored_particle();
        let unknown = |min: f64, max: f64| {
            Param::Unknown(Bounds {
                min,
                max,
                init: None,
            })
        };
        scene.types[0].params[0] = unknown(1.0, 100.0);
        scene.types[0].params[1] = unknown(0.1, 2.0);
        let traj = scene.simulate(5).unwrap();
        let takes = vec![Take::complete(&traj)];
        let tangent = Tangent::new(&scene).unwrap();
        let space = ParameterSpace::from_scene(&scene);
        let base = scene.param_values();
        let fit = super::super::tests::fitter_of(&tangent, &space, &base, &takes);
        let len = fit.len();
        assert_eq!((fit.theta(), len), (2, 8));
        // θ0 on its lower bound, its gradient pointing into the box; a quadratic model coupling
        // θ0 and θ1 whose unconstrained step still moves θ0 further down (δ ≈ (-0.67, 1.6)).
        let mut q = vec![0.0; len];
        q[0] = space.unknowns[0].internal_bounds().0;
        q[1] =
            0.5 * (space.unknowns[1].internal_bounds().0 + space.unknowns[1].internal_bounds().1);
        let mut h = DMatrix::<f64>::identity(len, len);
        h[(0, 0)] = 2.0;
        h[(0, 1)] = 0.9;
        h[(1, 0)] = 0.9;
        let mut g = DVector::zeros(len);
        g[0] = -0.1;
        g[1] = -1.0;
        let ne = Normal { cost: 1.0, h, g };
        let scale = vec![1.0; len];
        let mut held = fit.held(&q, &ne.g);
        assert!(!held[0], "the gradient alone does not hold θ0");
        let lambda = 1e-3;
        let coupled = damped_step(&ne, &scale, &held, lambda).unwrap();
        assert!(coupled[0] < 0.0, "the coupled step pushes θ0 out");
        let delta = step_in_the_box(&fit, &q, &ne, &scale, &mut held, lambda).unwrap();
        assert!(held[0] && delta[0] == 0.0);
        // On the face: (1 + λ) δ1 = -g1.
        let face = 1.0 / (1.0 + lambda);
        assert!((delta[1] - face).abs() < 1e-12, "{} vs {face}", delta[1]);
        assert!(
            (coupled[1] - face).abs() > 0.1,
            "the coupled step differs: {}",
            coupled[1]
        );
    }
}
