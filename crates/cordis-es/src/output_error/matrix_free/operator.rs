//! The matrix-free operator: the stored linearisation of every take at one iterate and the
//! Gauss–Newton products over it.

use cordis_core::plan::Scratch;
use cordis_core::Vec3;
use nalgebra::DMatrix;

use super::super::fit::Fitter;
use super::super::tangent::spring::{self, LINK};
use super::super::tangent::{angle, conditional, plane, provot, spring_link, NONE};
use super::settings::SPLIT_MIN_SPRINGS;

/// The linearisation of one take's rollout at the current iterate, over its window.
#[derive(Clone, Debug, Default)]
pub(crate) struct Lin {
    pub(super) frames: usize,
    /// `[(n · springs + l) · LINK ..]`, steps n < frames - 1.
    pub(super) springs: Vec<f64>,
    pub(super) anchors: Vec<f64>,
    /// `[(n · dampers + l) · 3 ..]`: `v_j - v_i` (∂f_i/∂Z).
    pub(super) dampers: Vec<f64>,
    /// `[(n · angles + l) · ANGLE ..]` ([`angle::store`]).
    pub(super) angles: Vec<f64>,
    /// `[(n · planes + l) · PLANE ..]` ([`plane::store`]).
    pub(super) planes: Vec<f64>,
    /// The conditional passes' active pairs at every step, with their records.
    pub(super) cond: conditional::Pairs,
    /// Provot's corrections at every step ([`provot::Corrections`]).
    pub(super) proj: provot::Corrections,
    /// `[n · 3N + r]`: v(n) (drags' ∂f/∂Z) and F(n) (the mass column).
    pub(super) vel: Vec<f64>,
    pub(super) force: Vec<f64>,
    /// `[t · 3N + r]`: `w²` (0 where missing) and `w² (x - y)`.
    pub(super) wsq: Vec<f64>,
    pub(super) res: Vec<f64>,
    /// Per free particle, the local-model 6×6 block (row-major).
    pub(super) local: Vec<f64>,
    pub cost: f64,
    /// Observed coordinates in the window.
    pub observed: usize,
}

/// Caller-owned buffers of the passes (no allocation once sized).
#[derive(Clone, Debug, Default)]
pub(crate) struct Work {
    pub(super) x: Vec<Vec3>,
    pub(super) x_prev: Vec<Vec3>,
    pub(super) scratch: Option<Scratch>,
    pub(super) cur: Vec<f64>,
    pub(super) prev: Vec<f64>,
    pub(super) vel: Vec<f64>,
    pub(super) df: Vec<f64>,
    pub(super) phi: Vec<f64>,
    pub(super) dth: Vec<f64>,
    /// Local direction (θ, the take's state) × width, and the local gradient.
    pub(super) dir: Vec<f64>,
    pub(super) grad: Vec<f64>,
    /// Forward output, frames × 3N × width.
    pub(super) out: Vec<f64>,
    /// Local model: K_ii and C_ii per particle (9 each).
    pub(super) kii: Vec<f64>,
    pub(super) cii: Vec<f64>,
    /// One grid per conditional pass.
    pub(super) grids: Vec<cordis_core::forces::grid::Grid>,
    /// The second half's sums when a step's springs are split over two threads
    /// ([`SPLIT_MIN_SPRINGS`]): its force (forward), Aᵀφ and Bᵀφ and θ gradient (adjoint).
    pub(super) half: Half,
}

/// Buffers of the second half of a split step.
#[derive(Clone, Debug, Default)]
pub(super) struct Half {
    pub(super) df: Vec<f64>,
    pub(super) na: Vec<f64>,
    pub(super) psi: Vec<f64>,
    pub(super) grad: Vec<f64>,
}

/// The matrix-free operator at one iterate: the fitter, its parameters and every take's
/// linearisation.
pub(crate) struct Mf<'a, 'b> {
    pub fit: &'a Fitter<'b>,
    pub(super) p: Vec<f64>,
    pub(super) chain: Vec<f64>,
    pub lins: Vec<Lin>,
    /// Per particle `dt²/m` (s²/kg), 0 on fixed particles: the step's `h`.
    pub(super) h: Vec<f64>,
    /// The free particles whose mass is unknown, with the mass's column.
    pub(super) unknown_masses: Vec<(usize, usize)>,
    /// Steps split their springs over two threads from this many ([`SPLIT_MIN_SPRINGS`]).
    pub(super) split_min_springs: usize,
}

impl<'a, 'b> Mf<'a, 'b> {
    pub fn new(fit: &'a Fitter<'b>) -> Self {
        let plan = &fit.tangent.plan;
        let (mo, of_slot) = (plan.layout.mass_offset, &fit.cols.of_slot);
        let unknown_masses = (0..plan.n)
            .filter(|&i| plan.free[i] && of_slot[mo + i] != NONE)
            .map(|i| (i, of_slot[mo + i]))
            .collect();
        Mf {
            fit,
            p: Vec::new(),
            chain: Vec::new(),
            lins: vec![Lin::default(); fit.takes.len()],
            h: Vec::new(),
            unknown_masses,
            split_min_springs: SPLIT_MIN_SPRINGS,
        }
    }

    pub(super) fn local_len(&self) -> usize {
        self.fit.theta() + self.fit.state_len()
    }

    pub fn cost(&self) -> f64 {
        self.lins.iter().map(|l| l.cost).sum()
    }

    /// Rolls every take out from `q` over `window` frames, storing the linearisation; returns
    /// false when a rollout diverges or the cost is not finite.
    pub fn linearise(&mut self, q: &[f64], window: usize, work: &mut Work) -> bool {
        self.p = self.fit.params(q);
        self.chain = self.fit.chain(q);
        let plan = &self.fit.tangent.plan;
        let mo = plan.layout.mass_offset;
        self.h = (0..plan.n)
            .map(|i| match plan.free[i] {
                true => plan.dt * plan.dt / self.p[mo + i],
                false => 0.0,
            })
            .collect();
        let (nt, ns) = (self.fit.theta(), self.fit.state_len());
        for k in 0..self.fit.takes.len() {
            let state = &q[nt + k * ns..][..ns];
            let mut lin = std::mem::take(&mut self.lins[k]);
            let ok = self.linearise_take(k, state, window, &mut lin, work);
            self.lins[k] = lin;
            if !ok {
                return false;
            }
        }
        self.cost().is_finite()
    }

    pub(super) fn linearise_take(
        &self,
        k: usize,
        state: &[f64],
        window: usize,
        lin: &mut Lin,
        work: &mut Work,
    ) -> bool {
        let tangent = self.fit.tangent;
        let plan = &tangent.plan;
        let take = &self.fit.takes[k];
        let (n, dt, p) = (plan.n, plan.dt, &self.p);
        let rows = 3 * n;
        let frames = window.min(take.frames());
        let steps = frames - 1;
        let (nsp, nan, nd) = (
            plan.springs.pairs.len(),
            plan.anchors.particles.len(),
            plan.dampers.pairs.len(),
        );
        lin.frames = frames;
        lin.springs.resize(steps * nsp * LINK, 0.0);
        lin.anchors.resize(steps * nan * LINK, 0.0);
        lin.dampers.resize(steps * nd * 3, 0.0);
        let nag = plan.angles.triples.len();
        lin.angles.resize(steps * nag * angle::ANGLE, 0.0);
        let npl = plan.planes.len();
        lin.planes.resize(steps * npl * plane::PLANE, 0.0);
        lin.vel.resize(steps * rows, 0.0);
        lin.force.resize(steps * rows, 0.0);
        lin.wsq.resize(frames * rows, 0.0);
        lin.res.resize(frames * rows, 0.0);
        lin.cond.reset(plan.conditionals.len());
        lin.proj.reset();
        let projected = !plan.provot.links.is_empty();
        lin.cost = 0.0;
        lin.observed = 0;
        let Work {
            x,
            x_prev,
            scratch,
            grids,
            ..
        } = work;
        grids.resize_with(plan.conditionals.len(), Default::default);
        x.clear();
        x.extend_from_slice(&plan.x0);
        x_prev.clear();
        x_prev.extend_from_slice(&plan.x0);
        for (f, &i) in tangent.free.iter().enumerate() {
            let s = &state[6 * f..6 * f + 6];
            x[i] = Vec3::new(s[0], s[1], s[2]);
            x_prev[i] = Vec3::new(s[0] - s[3] * dt, s[1] - s[4] * dt, s[2] - s[5] * dt);
        }
        let mut sc = scratch.take().unwrap_or_else(|| plan.scratch());
        plan.reset_state(p, &mut sc);
        sc.frame = 0;
        sc.runaway = tangent.runaway;
        let mut ok = true;
        for t in 0..frames {
            for (i, xi) in x.iter().enumerate() {
                for c in 0..3 {
                    let (y, w) = take.at(t, i, c);
                    let r = t * rows + 3 * i + c;
                    if w > 0.0 {
                        let e = xi[c] - y;
                        lin.cost += w * w * e * e;
                        lin.observed += 1;
                        lin.wsq[r] = w * w;
                        lin.res[r] = w * w * e;
                    } else {
                        lin.wsq[r] = 0.0;
                        lin.res[r] = 0.0;
                    }
                }
            }
            if t + 1 == frames {
                break;
            }
            let bad = if projected {
                // The step's projection run here, its corrections recorded.
                let bad = plan.step_unprojected(p, x, x_prev, &mut sc);
                let proj = &mut lin.proj;
                plan.provot
                    .apply_recorded(p, x, &plan.free, |c| proj.push(c));
                proj.end_step();
                bad
            } else {
                plan.step(p, x, x_prev, &mut sc)
            };
            if bad.is_some() {
                ok = false;
                break;
            }
            // After the step: x_prev = x(t), sc.v = v(t), sc.f = F(t): the point the tangent
            // step from t to t+1 is linearised at (as in `Tangent::tangent_step`).
            let (xn, v) = (&*x_prev, &sc.v);
            for (ri, r) in plan.springs.runs.iter().enumerate() {
                let (kk, l0, z) = (p[r.param], p[r.param + 1], p[r.param + 2]);
                let z2 = spring::quadratic(&plan.springs, ri).map_or(0.0, |q| p[q]);
                for (l, &[i, j]) in plan.springs.pairs[r.start..r.end].iter().enumerate() {
                    let (i, j) = (i as usize, j as usize);
                    let lk = spring_link(&xn[j], &xn[i], &v[j], &v[i], kk, l0, z, z2);
                    let d = &mut lin.springs[(t * nsp + r.start + l) * LINK..][..LINK];
                    lk.store(d);
                }
            }
            for r in &plan.anchors.runs {
                let (kk, l0, z) = (p[r.param], p[r.param + 1], p[r.param + 2]);
                let items = plan.anchors.particles[r.start..r.end]
                    .iter()
                    .zip(&plan.anchors.points[r.start..r.end]);
                for (l, (&i, point)) in items.enumerate() {
                    let i = i as usize;
                    let lk = spring_link(point, &xn[i], &Vec3::zeros(), &v[i], kk, l0, z, 0.0);
                    let d = &mut lin.anchors[(t * nan + r.start + l) * LINK..][..LINK];
                    lk.store(d);
                }
            }
            for (l, &[i, j]) in plan.dampers.pairs.iter().enumerate() {
                let rel = v[j as usize] - v[i as usize];
                lin.dampers[(t * nd + l) * 3..][..3].copy_from_slice(rel.as_slice());
            }
            if nag > 0 {
                let out = &mut lin.angles[t * nag * angle::ANGLE..][..nag * angle::ANGLE];
                angle::store(&plan.angles, p, xn, out);
            }
            if npl > 0 {
                let out = &mut lin.planes[t * npl * plane::PLANE..][..npl * plane::PLANE];
                plane::store(&plan.planes, p, (xn, v), out);
            }
            if !plan.conditionals.is_empty() {
                lin.cond.push_step(&plan.conditionals, p, (xn, v), grids);
            }
            for i in 0..n {
                for c in 0..3 {
                    lin.vel[t * rows + 3 * i + c] = v[i][c];
                    lin.force[t * rows + 3 * i + c] = sc.f[i][c];
                }
            }
        }
        *scratch = Some(sc);
        if ok {
            self.local_blocks(lin, work);
        }
        ok && lin.cost.is_finite()
    }

    /// `out = H v` over every take (global variables × w), `H = Σ w² JᵀJ`.
    pub fn hv(&self, v: &[f64], w: usize, out: &mut [f64], work: &mut Work) {
        let (nt, ns) = (self.fit.theta(), self.fit.state_len());
        out.iter_mut().for_each(|x| *x = 0.0);
        for k in 0..self.lins.len() {
            self.gather(v, k, w, work);
            self.forward(k, w, work);
            let mut cot = std::mem::take(&mut work.out);
            let rows = 3 * self.fit.tangent.plan.n;
            for (chunk, wsq) in cot.chunks_mut(w).zip(&self.lins[k].wsq) {
                chunk.iter_mut().for_each(|x| *x *= wsq);
            }
            debug_assert_eq!(cot.len(), self.lins[k].frames * rows * w);
            self.adjoint(k, w, &cot, work);
            work.out = cot;
            self.scatter(k, w, &work.grad, out, nt, ns);
        }
    }

    /// Half the gradient, `g = Σ w² e J` (global variables).
    pub fn gradient(&self, out: &mut [f64], work: &mut Work) {
        let (nt, ns) = (self.fit.theta(), self.fit.state_len());
        out.iter_mut().for_each(|x| *x = 0.0);
        for k in 0..self.lins.len() {
            self.adjoint(k, 1, &self.lins[k].res, work);
            self.scatter(k, 1, &work.grad, out, nt, ns);
        }
    }

    pub(super) fn gather(&self, v: &[f64], k: usize, w: usize, work: &mut Work) {
        let (nt, ns) = (self.fit.theta(), self.fit.state_len());
        work.dir.clear();
        work.dir.extend_from_slice(&v[..nt * w]);
        work.dir
            .extend_from_slice(&v[(nt + k * ns) * w..(nt + (k + 1) * ns) * w]);
    }

    pub(super) fn scatter(
        &self,
        k: usize,
        w: usize,
        grad: &[f64],
        out: &mut [f64],
        nt: usize,
        ns: usize,
    ) {
        for (o, g) in out[..nt * w].iter_mut().zip(&grad[..nt * w]) {
            *o += g;
        }
        for (o, g) in out[(nt + k * ns) * w..(nt + (k + 1) * ns) * w]
            .iter_mut()
            .zip(&grad[nt * w..])
        {
            *o += g;
        }
    }

    /// The parts of the preconditioner that do not depend on λ: the θ columns of H (exact)
    /// and the local blocks (already in the linearisation).
    pub fn theta_columns(&self, work: &mut Work) -> DMatrix<f64> {
        let (nt, ns, len) = (self.fit.theta(), self.fit.state_len(), self.fit.len());
        let mut cols = DMatrix::zeros(len, nt);
        if nt == 0 {
            return cols;
        }
        let local = self.local_len();
        let rows = 3 * self.fit.tangent.plan.n;
        for k in 0..self.lins.len() {
            work.dir.clear();
            work.dir.resize(local * nt, 0.0);
            for a in 0..nt {
                work.dir[a * nt + a] = 1.0;
            }
            self.forward(k, nt, work);
            let mut cot = std::mem::take(&mut work.out);
            for (chunk, wsq) in cot.chunks_mut(nt).zip(&self.lins[k].wsq) {
                chunk.iter_mut().for_each(|x| *x *= wsq);
            }
            debug_assert_eq!(cot.len(), self.lins[k].frames * rows * nt);
            self.adjoint(k, nt, &cot, work);
            work.out = cot;
            for a in 0..local {
                let g = if a < nt { a } else { nt + k * ns + (a - nt) };
                for c in 0..nt {
                    cols[(g, c)] += work.grad[a * nt + c];
                }
            }
        }
        cols
    }
}
