//! Matrix-free Gauss–Newton for large scenes: the same estimate as [`super::fit`], without ever
//! forming the sensitivity matrices or the normal equations.
//!
//! # Why
//!
//! The dense path carries `S(n) = ∂x(n)/∂q`, a `3N × P` matrix, through every step and
//! accumulates `H = Σ w² JᵀJ` (`3N P²` multiply-adds per frame). On the 32 × 32 cloth
//! (N = 1024, P = 18 + 6·992 = 5,970) that is ~1.1·10¹¹ per frame for H alone and ~10⁹ per
//! frame for the tangent: hours per Levenberg–Marquardt iteration. Here every product with J
//! costs about one simulation.
//!
//! # The step
//!
//! Each Levenberg–Marquardt step solves `(JᵀW²J + λD) δ = -JᵀW²e` by preconditioned conjugate
//! gradients (PCG), which only needs products `H v = Jᵀ (W² (J v))`:
//!
//! - **`J v`** (forward, [`Mf::forward`]): the tangent recursion of [`super::tangent`] for a single
//!   direction v instead of P columns,
//!
//!   ```text
//!   s(n+1) = 2 s(n) - s(n-1) + h (K(n) s(n) + C(n) ṡ(n) + G(n) v_θ),   ṡ(n) = (s(n) - s(n-1))/dt
//!   ```
//!
//!   with `h = dt²/m` per particle (0 rows for fixed particles), `K = ∂F/∂x`, `C = ∂F/∂v`
//!   assembled from the per-link 3×3 blocks `A = ∂f/∂d`, `B = ∂f/∂w = Z u uᵀ` of
//!   [`super::tangent`] (`K_ii = K_jj = -A`, `K_ij = K_ji = A` for a link i–j), `G = ∂F/∂θ`
//!   (with the mass column `-F/m`), and `s(0) = v_x0`, `s(-1) = v_x0 - dt v_v0`. An angle adds
//!   its 6×6 block `∂(f_i, f_k)/∂(a, b)` instead ([`super::tangent::angle`], which holds its
//!   forward, adjoint and local-block passes).
//! - **`Jᵀ u`** (reverse, [`Mf::adjoint`]): the transpose of that linear recursion, run
//!   backwards over the stored linearisation. With `z(n) = (s(n), s(n-1))` the forward map is
//!   `z(n+1) = Φ(n) z(n) + …`; the adjoint `λ(n) = (a(n), b(n))` obeys
//!   `λ(n) = Φ(n)ᵀ λ(n+1) + (u(n), 0)`, i.e. with `P` the free-row mask,
//!
//!   ```text
//!   φ = h ⊙ P a(n+1)                                   (adjoint of the force increment)
//!   ψ = C(n)ᵀ φ                                        (adjoint of the velocity ṡ(n))
//!   a(n) = u(n) + 2 P a(n+1) + K(n)ᵀ φ + ψ/dt + b(n+1)
//!   b(n) = -P a(n+1) - ψ/dt
//!   ∂/∂θ += G(n)ᵀ φ
//!   ```
//!
//!   from `a(T-1) = u(T-1)`, `b(T-1) = 0`; then `∂/∂x0 = a(0) + b(0)`, `∂/∂v0 = -dt b(0)`.
//!   `Kᵀ` uses `Aᵀ` per link: A is *not* symmetric when the spring is damped (its last term
//!   `(Z/l) u ((I - u uᵀ) w)ᵀ`), so the transpose is applied explicitly.
//!
//! The linearisation (A by its factors `α u uᵀ + β I + u qᵀ`, l - l0, w·u and Z' per link —
//! [`super::tangent::spring::LINK`] — v and F per particle, every step) is stored once per
//! iterate by the nonlinear rollout ([`Lin`]): forward and adjoint then read the same
//! numbers, and `⟨J v, u⟩ = ⟨v, Jᵀ u⟩` holds to rounding (tested).
//!
//! # Threads
//!
//! A CG iteration is one forward and one adjoint pass with a single direction: there is no
//! population to spread over threads. From [`SPLIT_MIN_SPRINGS`] springs each step splits its
//! springs in two halves, the second on the pool's other thread, summed into separate buffers
//! and added in a fixed order, so the fit does not depend on the thread count.
//!
//! # The preconditioner
//!
//! `M = [[H_θθ, H_θs], [H_sθ, D_s]]`: the θ rows and columns of H exactly (one forward pass
//! with the `nθ` unit directions and one adjoint pass, both `nθ` wide), and for the initial
//! states a 6×6 block per free particle from a *local model* (the particle alone, its
//! neighbours held: `s(n+1) = 2s - s(n-1) + h (K_ii s + C_ii ṡ)`, `D_i = Σ w² sᵀ s` over its
//! own observed coordinates). `M⁻¹` is applied through the Schur complement
//! `H_θθ - H_θs D_s⁻¹ H_sθ` (18 × 18 on the cloth); if that is not positive definite the
//! θ–state coupling is dropped (block-Jacobi). The exact θ rows matter: the parameters couple
//! to every initial state, and a diagonal preconditioner leaves that coupling to CG.
//!
//! # The iteration
//!
//! The same windows, start, Marquardt scaling (the running maximum of the diagonal, here the
//! preconditioner's), Nielsen λ rule and projection as [`super::fit::lm_stage`], with what a
//! step costing ~50–300 simulations calls for:
//!
//! - **inexact steps**: the CG solve stops at a relative residual `0.5 √(‖g‖/‖g₀‖)` clamped
//!   to [[`STEP_CG_TOL`], [`STEP_CG_TOL_MAX`]], or after [`STEP_CG_ITERATIONS`] (a truncated
//!   CG iterate still descends the model);
//! - **recycled directions**: each solve is deflated ([`crate::linalg::deflation`]) by the
//!   window's last [`DEFLATE_STEPS`] accepted steps: exact on their span from the start, CG
//!   spends its iterations on the rest. Near the optimum the steps line up along the few
//!   poorly determined directions (the cloth's structural/bending valley) that CG resolves
//!   worst; one product as wide as the subspace per solve, 21–44 % fewer CG iterations on the
//!   cloth (BENCHMARKS, "Large scenes");
//! - **halving before re-solving**: a step that raises the cost is tried at ½ and ¼ (one
//!   simulation each) before a new solve at a larger λ;
//! - **pattern moves** ([`pattern_move`]): after an accepted step, one more move along the
//!   sum of the last two, doubled while the cost falls: consecutive steps zig-zag across a
//!   long curved valley (the cloth's structural/bending one), their sum points along it;
//! - **statistical stopping**: a window stops when a step lowers the cost by less than
//!   `χ² σ̂²` (the estimate moves by less than √χ² standard errors): [`FINAL_CHI2`] = 0.01 on
//!   the last window, [`WINDOW_CHI2`] = 1 (or [`WINDOW_FTOL`], or [`WINDOW_ITERATIONS`]) on the
//!   others, whose only job is to bring the next into the basin. On the last window the
//!   criterion is confirmed by the undamped Gauss–Newton decrement `gᵀH⁻¹g ≤ χ² σ̂²` (one CG
//!   solve at λ ≈ 0): a damped or truncated step gains little along a poorly determined
//!   parameter however far the optimum is. The dense criteria
//!   (ftol 1e-10) spend most iterations creeping along parameters held at their bounds;
//! - the preconditioner's θ columns refreshed every [`COLUMNS_EVERY`] accepted steps.
//!
//! # What it reports
//!
//! Standard errors for θ: the θ block of `H⁻¹` by nθ PCG solves `H x_k = e_k` (run together,
//! as wide as the solves still running, deflated by the last window's last accepted steps),
//! scaled by `σ̂²`, each stopped when its variance has settled ([`theta_inverse`]). A solve that does not converge leaves its unknown's standard
//! error NaN (not computed), never a guessed number. The undetermined directions of the full system
//! are not computed on this path (no eigendecomposition of a 6,000-wide H).

// Index loops mirror the row-major `(3i + c)·w + col` layout the passes address.
#![allow(clippy::needless_range_loop)]

use cordis_core::plan::Scratch;
use cordis_core::Vec3;
use nalgebra::{DMatrix, DVector, Matrix6};
use std::ops::Range;

use super::fit::{Counts, Fitter, LmSettings, StageEnd};
use super::tangent::spring::{self, LINK};
use super::tangent::{angle, conditional, plane, provot, spring_link, NONE};
use crate::linalg::deflation::Deflation;
use crate::linalg::dot;

/// The dense path is used up to this many local columns (θ plus one take's initial state).
/// Measured on the cloth without its Provot limit, 100 frames, σ = 1e-3 of its size, on the
/// shared 2-core machine: the dense path on 8 × 8 (P = 354) takes 96 s wall (0.18 s per
/// evaluation of the normal equations, `3N·P²` per frame), the matrix-free one on 12 × 12
/// (P = 810) 11 s for the fit plus 12 s for the standard errors. Below the threshold the dense
/// path stays: it is exact, it reports the undetermined directions, and on the 12–30-mass
/// networks it is well under a second.
pub const DENSE_MAX_COLUMNS: usize = 500;

/// From this many springs each step of a pass splits its springs in two halves summed into
/// separate buffers, the second half on another rayon thread, and adds the buffers (the first
/// half's plus the second's, in that order whatever the thread count: the sums, hence the
/// fit, do not depend on it). Below it a step (~15 µs on the 12 × 12 cloth's 818 springs) is
/// too short to pay a fork–join. The 32 × 32 cloth has 5,826 (BENCHMARKS, "Large scenes").
pub const SPLIT_MIN_SPRINGS: usize = 2048;

/// Refuses matrix-free fits whose stored linearisations would not fit in memory: per take and
/// frame, 14 floats per spring or anchor, 3 per damper, 4 per coordinate, plus the θ-wide
/// forward output of the preconditioner (3N·nθ per frame).
pub(crate) fn check_memory(
    tangent: &super::tangent::Tangent,
    takes: &[super::Take],
) -> Result<(), crate::error::CostError> {
    const LIMIT: f64 = 8.0 * (1u64 << 30) as f64;
    let plan = &tangent.plan;
    let links = (plan.springs.pairs.len() + plan.anchors.particles.len()) as f64;
    let per_frame = LINK as f64 * links
        + angle::ANGLE as f64 * plan.angles.triples.len() as f64
        + plane::PLANE as f64 * plan.planes.len() as f64
        + 3.0 * plan.dampers.pairs.len() as f64
        + (provot::REC + 1) as f64 * plan.provot.links.len() as f64
        + 4.0 * 3.0 * plan.n as f64;
    let frames: f64 = takes.iter().map(|t| t.frames() as f64).sum();
    let longest = takes.iter().map(|t| t.frames()).max().unwrap_or(0) as f64;
    let theta = plan.layout.len as f64;
    let bytes = 8.0 * (per_frame * frames + 3.0 * plan.n as f64 * longest * theta.min(64.0));
    if bytes > LIMIT {
        return Err(crate::error::CostError::mismatch(
            "output-error",
            format!(
                "the matrix-free fit needs about {:.1} GB to store {frames} frames' \
                 linearisation (limit {:.0} GB)",
                bytes / 1e9,
                LIMIT / 1e9
            ),
        ));
    }
    Ok(())
}

/// Relative residual of the CG solve of each Levenberg–Marquardt step: an inexact
/// Gauss–Newton step (the λ rule and the cost test still decide), since the step's accuracy
/// beyond this costs CG iterations (each about two simulations) without better steps.
pub const STEP_CG_TOL: f64 = 1e-3;
/// A window stops when a step lowers the cost by less than this many σ̂² (the estimate moves
/// by less than √· standard errors): intermediate windows only have to bring the next into the
/// basin (1 standard error), the last stops at 0.1 standard error. On the cloth the dense
/// criteria (ftol 1e-10) spend most iterations creeping along poorly determined dampings.
pub const WINDOW_CHI2: f64 = 1.0;
pub const FINAL_CHI2: f64 = 1e-2;

/// Relative residual of the standard-error solves `H x = e_k`: the variances to ~4 digits.
pub const STDERR_CG_TOL: f64 = 1e-6;
/// Or a standard-error solve stops when its variance grew by less than this fraction over the
/// last [`STDERR_DELAY`] iterations ([`theta_inverse`]): standard errors to ~0.05 %,
/// correlations to ~3 %.
pub const STDERR_FORM_TOL: f64 = 1e-3;
pub const STDERR_DELAY: usize = 10;
/// The loosest relative residual of a step's CG solve (far from the optimum).
pub const STEP_CG_TOL_MAX: f64 = 0.1;
/// The damping (relative to the Marquardt scale) of the undamped Gauss–Newton solve that
/// checks the last window's statistical criterion, and that solve's CG settings: the
/// decrement `gᵀH⁻¹g` to ~1 %, with the standard errors' iteration budget.
const NEWTON_LAMBDA: f64 = 1e-9;
const NEWTON_CG: CgSettings = CgSettings {
    tol: 1e-2,
    max_iterations: 300,
};
/// Halvings of a rejected step tried before a new solve at a larger λ.
const BACKTRACK: usize = 2;
/// A step cut at the box below this fraction is not worth a simulation: the halves are
/// projected as the full step was.
const MIN_CUT: f64 = 1e-3;
/// Iteration budget and relative cost tolerance of every window but the last (they only
/// bring the next into the basin).
pub const WINDOW_ITERATIONS: usize = 10;
pub const WINDOW_FTOL: f64 = 1e-4;
/// Iterations of a step's CG solve: beyond, the (truncated, still descending) step is taken.
pub const STEP_CG_ITERATIONS: usize = 80;
/// Accepted steps between refreshes of the preconditioner's θ columns.
pub const COLUMNS_EVERY: usize = 3;
/// Accepted steps of a window kept to deflate the next solves ([`crate::linalg::deflation`]).
pub const DEFLATE_STEPS: usize = 4;
/// The longest pattern move tried, in multiples of the last two steps' sum ([`pattern_move`]).
pub const PATTERN_MAX: f64 = 64.0;

/// Settings of the inner conjugate-gradient solves.
#[derive(Clone, Copy, Debug)]
pub(crate) struct CgSettings {
    /// Relative residual `‖r‖/‖b‖` at which a solve stops.
    pub tol: f64,
    pub max_iterations: usize,
}

impl Default for CgSettings {
    fn default() -> Self {
        CgSettings {
            tol: 1e-6,
            max_iterations: 300,
        }
    }
}

/// The linearisation of one take's rollout at the current iterate, over its window.
#[derive(Clone, Debug, Default)]
pub(crate) struct Lin {
    frames: usize,
    /// `[(n · springs + l) · LINK ..]`, steps n < frames - 1.
    springs: Vec<f64>,
    anchors: Vec<f64>,
    /// `[(n · dampers + l) · 3 ..]`: `v_j - v_i` (∂f_i/∂Z).
    dampers: Vec<f64>,
    /// `[(n · angles + l) · ANGLE ..]` ([`angle::store`]).
    angles: Vec<f64>,
    /// `[(n · planes + l) · PLANE ..]` ([`plane::store`]).
    planes: Vec<f64>,
    /// The conditional passes' active pairs at every step, with their records.
    cond: conditional::Pairs,
    /// Provot's corrections at every step ([`provot::Corrections`]).
    proj: provot::Corrections,
    /// `[n · 3N + r]`: v(n) (drags' ∂f/∂Z) and F(n) (the mass column).
    vel: Vec<f64>,
    force: Vec<f64>,
    /// `[t · 3N + r]`: `w²` (0 where missing) and `w² (x - y)`.
    wsq: Vec<f64>,
    res: Vec<f64>,
    /// Per free particle, the local-model 6×6 block (row-major).
    local: Vec<f64>,
    pub cost: f64,
    /// Observed coordinates in the window.
    pub observed: usize,
}

/// Caller-owned buffers of the passes (no allocation once sized).
#[derive(Clone, Debug, Default)]
pub(crate) struct Work {
    x: Vec<Vec3>,
    x_prev: Vec<Vec3>,
    scratch: Option<Scratch>,
    cur: Vec<f64>,
    prev: Vec<f64>,
    vel: Vec<f64>,
    df: Vec<f64>,
    phi: Vec<f64>,
    dth: Vec<f64>,
    /// Local direction (θ, the take's state) × width, and the local gradient.
    dir: Vec<f64>,
    grad: Vec<f64>,
    /// Forward output, frames × 3N × width.
    out: Vec<f64>,
    /// Local model: K_ii and C_ii per particle (9 each).
    kii: Vec<f64>,
    cii: Vec<f64>,
    /// One grid per conditional pass.
    grids: Vec<cordis_core::forces::grid::Grid>,
    /// The second half's sums when a step's springs are split over two threads
    /// ([`SPLIT_MIN_SPRINGS`]): its force (forward), Aᵀφ and Bᵀφ and θ gradient (adjoint).
    half: Half,
}

/// Buffers of the second half of a split step.
#[derive(Clone, Debug, Default)]
struct Half {
    df: Vec<f64>,
    na: Vec<f64>,
    psi: Vec<f64>,
    grad: Vec<f64>,
}

/// The matrix-free operator at one iterate: the fitter, its parameters and every take's
/// linearisation.
pub(crate) struct Mf<'a, 'b> {
    pub fit: &'a Fitter<'b>,
    p: Vec<f64>,
    chain: Vec<f64>,
    pub lins: Vec<Lin>,
    /// Per particle `dt²/m` (s²/kg), 0 on fixed particles: the step's `h`.
    h: Vec<f64>,
    /// The free particles whose mass is unknown, with the mass's column.
    unknown_masses: Vec<(usize, usize)>,
    /// Steps split their springs over two threads from this many ([`SPLIT_MIN_SPRINGS`]).
    split_min_springs: usize,
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

    fn local_len(&self) -> usize {
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

    fn linearise_take(
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

    /// The local-model 6×6 block of every free particle (module docs): its own sensitivity
    /// to its own initial state with its neighbours held, accumulated over its observations.
    fn local_blocks(&self, lin: &mut Lin, work: &mut Work) {
        let plan = &self.fit.tangent.plan;
        let free = &self.fit.tangent.free;
        let (n, dt, p) = (plan.n, plan.dt, &self.p);
        let rows = 3 * n;
        let (nsp, nan) = (plan.springs.pairs.len(), plan.anchors.particles.len());
        let mo = plan.layout.mass_offset;
        lin.local.clear();
        lin.local.resize(36 * free.len(), 0.0);
        // Particle → its free index (the Provot corrections address particles).
        let mut block_of = vec![None; if plan.provot.links.is_empty() { 0 } else { n }];
        if !block_of.is_empty() {
            for (f, &i) in free.iter().enumerate() {
                block_of[i] = Some(f);
            }
        }
        // Per free particle: S (3×6) and S(n-1), row-major, packed.
        let Work {
            cur,
            prev,
            df,
            kii,
            cii,
            ..
        } = work;
        cur.clear();
        cur.resize(18 * free.len(), 0.0);
        prev.clear();
        prev.resize(18 * free.len(), 0.0);
        df.clear();
        df.resize(18, 0.0);
        for f in 0..free.len() {
            for k in 0..3 {
                cur[18 * f + 6 * k + k] = 1.0;
                prev[18 * f + 6 * k + k] = 1.0;
                prev[18 * f + 6 * k + 3 + k] = -dt;
            }
        }
        for t in 0..lin.frames {
            for (f, &i) in free.iter().enumerate() {
                let s = &cur[18 * f..18 * f + 18];
                let blk = &mut lin.local[36 * f..36 * f + 36];
                for c in 0..3 {
                    let w2 = lin.wsq[t * rows + 3 * i + c];
                    if w2 > 0.0 {
                        let row = &s[6 * c..6 * c + 6];
                        for a in 0..6 {
                            for b in 0..6 {
                                blk[6 * a + b] += w2 * row[a] * row[b];
                            }
                        }
                    }
                }
            }
            if t + 1 == lin.frames {
                break;
            }
            kii.clear();
            kii.resize(9 * n, 0.0);
            cii.clear();
            cii.resize(9 * n, 0.0);
            let sub = |m: &mut Vec<f64>, i: usize, a: &[f64]| {
                for (x, y) in m[9 * i..9 * i + 9].iter_mut().zip(a) {
                    *x -= y;
                }
            };
            let mut bz = [0.0; 9];
            for r in &plan.springs.runs {
                for (l, &[i, j]) in plan.springs.pairs[r.start..r.end].iter().enumerate() {
                    let d = &lin.springs[(t * nsp + r.start + l) * LINK..][..LINK];
                    rank_one(&mut bz, d[spring::ZEFF], spring::unit(d));
                    let a = spring::a_matrix(d);
                    for e in [i as usize, j as usize] {
                        sub(kii, e, &a);
                        sub(cii, e, &bz);
                    }
                }
            }
            for r in &plan.anchors.runs {
                for (l, &i) in plan.anchors.particles[r.start..r.end].iter().enumerate() {
                    let d = &lin.anchors[(t * nan + r.start + l) * LINK..][..LINK];
                    rank_one(&mut bz, d[spring::ZEFF], spring::unit(d));
                    sub(kii, i as usize, &spring::a_matrix(d));
                    sub(cii, i as usize, &bz);
                }
            }
            for r in &plan.dampers.runs {
                let z = p[r.param];
                let id = [z, 0.0, 0.0, 0.0, z, 0.0, 0.0, 0.0, z];
                for &[i, j] in &plan.dampers.pairs[r.start..r.end] {
                    sub(cii, i as usize, &id);
                    sub(cii, j as usize, &id);
                }
            }
            for r in &plan.drags.runs {
                let z = p[r.param];
                let id = [z, 0.0, 0.0, 0.0, z, 0.0, 0.0, 0.0, z];
                for &i in &plan.drags.particles[r.start..r.end] {
                    sub(cii, i as usize, &id);
                }
            }
            let nag = plan.angles.triples.len();
            if nag > 0 {
                let recs = &lin.angles[t * nag * angle::ANGLE..][..nag * angle::ANGLE];
                angle::local(&plan.angles, recs, kii);
            }
            let npl = plan.planes.len();
            if npl > 0 {
                let recs = &lin.planes[t * npl * plane::PLANE..][..npl * plane::PLANE];
                plane::local(&plan.planes, recs, kii, cii);
            }
            if !plan.conditionals.is_empty() {
                conditional::local(&lin.cond, t, kii, cii);
            }
            for (f, &i) in free.iter().enumerate() {
                let h = dt * dt / p[mo + i];
                let (s, sp) = (&cur[18 * f..18 * f + 18], &prev[18 * f..18 * f + 18]);
                let (km, cm) = (&kii[9 * i..9 * i + 9], &cii[9 * i..9 * i + 9]);
                for r in 0..3 {
                    for q in 0..6 {
                        let mut g = 0.0;
                        for c in 0..3 {
                            let sv = s[6 * c + q];
                            g += km[3 * r + c] * sv + cm[3 * r + c] * (sv - sp[6 * c + q]) / dt;
                        }
                        df[6 * r + q] = 2.0 * s[6 * r + q] - sp[6 * r + q] + h * g;
                    }
                }
                prev[18 * f..18 * f + 18].copy_from_slice(&cur[18 * f..18 * f + 18]);
                cur[18 * f..18 * f + 18].copy_from_slice(df);
            }
            if !plan.provot.links.is_empty() {
                let block = |i: usize| block_of[i].map(|f| 18 * f);
                provot::local(&plan.provot, &plan.free, &lin.proj, t, block, cur);
            }
        }
    }

    /// `J v` for one take, `w` directions at once: `dir` holds the take's local variables
    /// (θ in internal coordinates, then the take's state) × `w`, row-major; the raw position
    /// sensitivities s(t) (frames × 3N × w) go to `work.out`.
    pub fn forward(&self, k: usize, w: usize, work: &mut Work) {
        let plan = &self.fit.tangent.plan;
        let lin = &self.lins[k];
        let (n, dt, nt) = (plan.n, plan.dt, self.fit.theta());
        let rows = 3 * n;
        let Work {
            cur,
            prev,
            vel,
            df,
            dth,
            dir,
            out,
            half,
            ..
        } = work;
        for b in [&mut *cur, &mut *prev, &mut *vel, &mut *df] {
            b.clear();
            b.resize(rows * w, 0.0);
        }
        out.clear();
        out.resize(lin.frames * rows * w, 0.0);
        dth.clear();
        dth.extend((0..nt * w).map(|a| dir[a] * self.chain[a / w]));
        for (f, &i) in self.fit.tangent.free.iter().enumerate() {
            for c in 0..3 {
                for col in 0..w {
                    let x0 = dir[(nt + 6 * f + c) * w + col];
                    let v0 = dir[(nt + 6 * f + 3 + c) * w + col];
                    cur[(3 * i + c) * w + col] = x0;
                    prev[(3 * i + c) * w + col] = x0 - dt * v0;
                }
            }
        }
        for t in 0..lin.frames {
            out[t * rows * w..(t + 1) * rows * w].copy_from_slice(cur);
            if t + 1 == lin.frames {
                break;
            }
            self.forward_step(lin, t, w, cur, prev, vel, (df, &mut half.df), dth);
            std::mem::swap(cur, prev);
            let pass = &plan.provot;
            if !pass.links.is_empty() {
                let of_slot = &self.fit.cols.of_slot;
                provot::forward(
                    pass, &plan.free, &lin.proj, t, &self.p, of_slot, w, cur, dth,
                );
            }
        }
    }

    /// Calls `f(K, columns of (K, l0, Z, Z₂), ends, record)` for the springs in `springs`
    /// (indices into the pass) and, if `anchors`, every anchor (`j = None`) at step t: the
    /// walk the forward and adjoint passes share, inlined into each.
    #[inline(always)]
    fn each_link(
        &self,
        lin: &Lin,
        t: usize,
        (springs, anchors): (Range<usize>, bool),
        mut f: impl FnMut(f64, &[usize; 4], (usize, Option<usize>), &[f64]),
    ) {
        let plan = &self.fit.tangent.plan;
        let (of_slot, p) = (&self.fit.cols.of_slot, &self.p);
        let (nsp, nan) = (plan.springs.pairs.len(), plan.anchors.particles.len());
        for (ri, r) in plan.springs.runs.iter().enumerate() {
            let (a, b) = (r.start.max(springs.start), r.end.min(springs.end));
            if a >= b {
                continue;
            }
            let slots = spring::slots(&plan.springs, ri, r.param, of_slot);
            let recs = &lin.springs[(t * nsp + a) * LINK..(t * nsp + b) * LINK];
            for (&[i, j], d) in plan.springs.pairs[a..b].iter().zip(recs.chunks_exact(LINK)) {
                f(p[r.param], &slots, (i as usize, Some(j as usize)), d);
            }
        }
        if !anchors {
            return;
        }
        for r in &plan.anchors.runs {
            let slots = [r.param, r.param + 1, r.param + 2].map(|q| of_slot[q]);
            let slots = [slots[0], slots[1], slots[2], NONE];
            let recs = &lin.anchors[(t * nan + r.start) * LINK..(t * nan + r.end) * LINK];
            for (&i, d) in plan.anchors.particles[r.start..r.end]
                .iter()
                .zip(recs.chunks_exact(LINK))
            {
                f(p[r.param], &slots, (i as usize, None), d);
            }
        }
    }

    /// The springs' and anchors' share of one forward step into `df`: split over two threads
    /// from [`SPLIT_MIN_SPRINGS`] springs (the second half summed in `df2`, then added).
    #[allow(clippy::too_many_arguments)]
    fn forward_links_step(
        &self,
        lin: &Lin,
        t: usize,
        w: usize,
        sv: (&[f64], &[f64]),
        df: &mut [f64],
        df2: &mut Vec<f64>,
        dth: &[f64],
    ) {
        let nsp = self.fit.tangent.plan.springs.pairs.len();
        // One direction (every CG iteration) gets its own instance of the link loops, the
        // width a constant (BENCHMARKS, "Large scenes"). The kernels are forced inline: left
        // to itself the compiler called each link's as a function, reloading the environment
        // (perf, 32 x 32 cloth: a single-thread product 21 → 17 ms; BENCHMARKS, "Lean passes").
        let run = |springs: (Range<usize>, bool), df: &mut [f64]| {
            if w == 1 {
                self.each_link(
                    lin,
                    t,
                    springs,
                    #[inline(always)]
                    |k, slots, ends, d| spring::forward(d, k, slots, ends, 1, sv, df, dth),
                );
            } else {
                self.each_link(
                    lin,
                    t,
                    springs,
                    #[inline(always)]
                    |k, slots, ends, d| spring::forward(d, k, slots, ends, w, sv, df, dth),
                );
            }
        };
        if nsp < self.split_min_springs {
            run((0..nsp, true), df);
            return;
        }
        let half = nsp / 2;
        df2.clear();
        df2.resize(df.len(), 0.0);
        if rayon::current_thread_index().is_some() {
            rayon::join(
                || run((0..half, true), &mut *df),
                || run((half..nsp, false), &mut df2[..]),
            );
        } else {
            // Outside a pool a join would hand every step to the global pool and block on
            // it (measured: 78 s of system time on the 32 x 32 fit); the same two sums, in turn.
            run((0..half, true), &mut *df);
            run((half..nsp, false), &mut df2[..]);
        }
        for (a, b) in df.iter_mut().zip(df2.iter()) {
            *a += b;
        }
    }

    /// The springs' and anchors' share of one adjoint step: split as
    /// [`Self::forward_links_step`], the second half's `na`, `psi` and θ gradient in `half`.
    #[allow(clippy::too_many_arguments)]
    fn adjoint_links_step(
        &self,
        lin: &Lin,
        t: usize,
        w: usize,
        phi: &[f64],
        (na, psi): (&mut [f64], &mut [f64]),
        grad: &mut [f64],
        half: &mut Half,
    ) {
        let nsp = self.fit.tangent.plan.springs.pairs.len();
        let run =
            |springs: (Range<usize>, bool), (na, psi): (&mut [f64], &mut [f64]), g: &mut [f64]| {
                if w == 1 {
                    self.each_link(
                        lin,
                        t,
                        springs,
                        #[inline(always)]
                        |k, slots, ends, d| {
                            spring::adjoint(d, k, slots, ends, 1, phi, (&mut *na, &mut *psi), g)
                        },
                    );
                } else {
                    self.each_link(
                        lin,
                        t,
                        springs,
                        #[inline(always)]
                        |k, slots, ends, d| {
                            spring::adjoint(d, k, slots, ends, w, phi, (&mut *na, &mut *psi), g)
                        },
                    );
                }
            };
        if nsp < self.split_min_springs {
            run((0..nsp, true), (na, psi), grad);
            return;
        }
        let mid = nsp / 2;
        // Spring parameters are θ columns: the second half's gradient is nθ × w wide.
        let nt = self.fit.theta() * w;
        let Half {
            na: na2,
            psi: psi2,
            grad: grad2,
            ..
        } = half;
        for (b, len) in [
            (&mut *na2, na.len()),
            (&mut *psi2, psi.len()),
            (&mut *grad2, nt),
        ] {
            b.clear();
            b.resize(len, 0.0);
        }
        let second = (&mut na2[..], &mut psi2[..]);
        if rayon::current_thread_index().is_some() {
            rayon::join(
                || run((0..mid, true), (&mut *na, &mut *psi), &mut *grad),
                || run((mid..nsp, false), second, &mut grad2[..]),
            );
        } else {
            run((0..mid, true), (&mut *na, &mut *psi), &mut *grad);
            run((mid..nsp, false), second, &mut grad2[..]);
        }
        for (a, b) in na.iter_mut().zip(na2.iter()) {
            *a += b;
        }
        for (a, b) in psi.iter_mut().zip(psi2.iter()) {
            *a += b;
        }
        for (a, b) in grad[..nt].iter_mut().zip(grad2.iter()) {
            *a += b;
        }
    }

    /// One step of the directional tangent recursion: writes s(t+1) into `prev`.
    #[allow(clippy::too_many_arguments)]
    fn forward_step(
        &self,
        lin: &Lin,
        t: usize,
        w: usize,
        cur: &[f64],
        prev: &mut [f64],
        vel: &mut [f64],
        (df, df2): (&mut [f64], &mut Vec<f64>),
        dth: &[f64],
    ) {
        let plan = &self.fit.tangent.plan;
        let of_slot = &self.fit.cols.of_slot;
        let (n, dt, p) = (plan.n, plan.dt, &self.p);
        let rows = 3 * n;
        let inv_dt = 1.0 / dt;
        for ((v, a), b) in vel.iter_mut().zip(cur).zip(prev.iter()) {
            *v = (a - b) * inv_dt;
        }
        df.iter_mut().for_each(|x| *x = 0.0);
        let nd = plan.dampers.pairs.len();
        self.forward_links_step(lin, t, w, (cur, vel), df, df2, dth);
        for r in &plan.dampers.runs {
            let z = p[r.param];
            let s = of_slot[r.param];
            for (l, &[i, j]) in plan.dampers.pairs[r.start..r.end].iter().enumerate() {
                let (i, j) = (i as usize, j as usize);
                let rel = &lin.dampers[(t * nd + r.start + l) * 3..][..3];
                for col in 0..w {
                    let dz = if s != NONE { dth[s * w + col] } else { 0.0 };
                    for c in 0..3 {
                        let (ri, rj) = ((3 * i + c) * w + col, (3 * j + c) * w + col);
                        let g = z * (vel[rj] - vel[ri]) + rel[c] * dz;
                        df[ri] += g;
                        df[rj] -= g;
                    }
                }
            }
        }
        for r in &plan.drags.runs {
            let z = p[r.param];
            let s = of_slot[r.param];
            for &i in &plan.drags.particles[r.start..r.end] {
                let i = i as usize;
                for col in 0..w {
                    let dz = if s != NONE { dth[s * w + col] } else { 0.0 };
                    for c in 0..3 {
                        let ri = (3 * i + c) * w + col;
                        df[ri] -= z * vel[ri] + lin.vel[t * rows + 3 * i + c] * dz;
                    }
                }
            }
        }
        let nag = plan.angles.triples.len();
        if nag > 0 {
            let recs = &lin.angles[t * nag * angle::ANGLE..][..nag * angle::ANGLE];
            angle::forward(&plan.angles, recs, p, of_slot, w, cur, df, dth);
        }
        let npl = plan.planes.len();
        if npl > 0 {
            let recs = &lin.planes[t * npl * plane::PLANE..][..npl * plane::PLANE];
            plane::forward(&plan.planes, recs, of_slot, w, (cur, vel), df, dth);
        }
        if !plan.conditionals.is_empty() {
            let cs = (cur, &*vel);
            conditional::forward(&plan.conditionals, &lin.cond, t, p, of_slot, w, cs, df, dth);
        }
        // Slices zipped per particle, not indexed: the indexed loop, generic in w, spent more
        // time on bounds and overlap checks than on the update (perf, 32 x 32 cloth).
        let particles = prev
            .chunks_exact_mut(3 * w)
            .zip(cur.chunks_exact(3 * w))
            .zip(df.chunks_exact(3 * w));
        for (((next, cur), df), &h) in particles.zip(&self.h) {
            // h = 0 on fixed particles, whose rows are 0.
            for ((x, &c), &f) in next.iter_mut().zip(cur).zip(df) {
                *x = 2.0 * c - *x + h * f;
            }
        }
        for &(i, ms) in &self.unknown_masses {
            let h = self.h[i];
            let m = p[plan.layout.mass_offset + i];
            for c in 0..3 {
                let fm = h * lin.force[t * rows + 3 * i + c] / m;
                let row = &mut prev[(3 * i + c) * w..(3 * i + c + 1) * w];
                for (x, &d) in row.iter_mut().zip(&dth[ms * w..(ms + 1) * w]) {
                    *x -= fm * d;
                }
            }
        }
    }

    /// `Jᵀ u` for one take, `w` cotangents at once: `cot` holds u(t) (frames × 3N × w, raw
    /// positions); the local gradient (θ in internal coordinates, then the take's state) × w
    /// goes to `work.grad`. The adjoint recursion of the module docs.
    pub fn adjoint(&self, k: usize, w: usize, cot: &[f64], work: &mut Work) {
        let plan = &self.fit.tangent.plan;
        let of_slot = &self.fit.cols.of_slot;
        let lin = &self.lins[k];
        let (n, dt, p, nt) = (plan.n, plan.dt, &self.p, self.fit.theta());
        let rows = 3 * n;
        let frames = lin.frames;
        let Work {
            cur: a,
            prev: b,
            vel: psi,
            df: na,
            phi,
            grad,
            half,
            ..
        } = work;
        for buf in [&mut *b, &mut *psi, &mut *na, &mut *phi] {
            buf.clear();
            buf.resize(rows * w, 0.0);
        }
        grad.clear();
        grad.resize(self.local_len() * w, 0.0);
        a.clear();
        a.extend_from_slice(&cot[(frames - 1) * rows * w..frames * rows * w]);
        let nd = plan.dampers.pairs.len();
        let mo = plan.layout.mass_offset;
        let inv_dt = 1.0 / dt;
        for t in (0..frames.saturating_sub(1)).rev() {
            if !plan.provot.links.is_empty() {
                // a(t+1) is the cotangent of the projected x(t+1): through the corrections.
                provot::adjoint(
                    &plan.provot,
                    &plan.free,
                    &lin.proj,
                    t,
                    p,
                    of_slot,
                    w,
                    a,
                    grad,
                );
            }
            // φ = h ⊙ P a(t+1); a(t) starts as u(t) + 2 P a(t+1) + b(t+1), b(t) as -P a(t+1).
            let u = &cot[t * rows * w..(t + 1) * rows * w];
            let particles = phi
                .chunks_exact_mut(3 * w)
                .zip(na.chunks_exact_mut(3 * w))
                .zip(b.chunks_exact_mut(3 * w))
                .zip(a.chunks_exact(3 * w).zip(u.chunks_exact(3 * w)));
            for ((((phi, na), b), (a, u)), (&h, &free)) in
                particles.zip(self.h.iter().zip(&plan.free))
            {
                let rows = phi.iter_mut().zip(na.iter_mut()).zip(b.iter_mut());
                let rows = rows.zip(a.iter().zip(u));
                if free {
                    for (((phi, na), b), (&a, &u)) in rows {
                        *phi = h * a;
                        *na = u + 2.0 * a + *b;
                        *b = -a;
                    }
                } else {
                    // The free-row mask P is 0 on a fixed particle.
                    for (((phi, na), b), (_, &u)) in rows {
                        *phi = 0.0;
                        *na = u + *b;
                        *b = 0.0;
                    }
                }
            }
            psi.iter_mut().for_each(|x| *x = 0.0);
            self.adjoint_links_step(lin, t, w, phi, (na, psi), grad, half);
            for r in &plan.dampers.runs {
                let z = p[r.param];
                let s = of_slot[r.param];
                for (l, &[i, j]) in plan.dampers.pairs[r.start..r.end].iter().enumerate() {
                    let (i, j) = (i as usize, j as usize);
                    let rel = &lin.dampers[(t * nd + r.start + l) * 3..][..3];
                    for col in 0..w {
                        for c in 0..3 {
                            let (ri, rj) = ((3 * i + c) * w + col, (3 * j + c) * w + col);
                            let del = phi[rj] - phi[ri];
                            psi[ri] += z * del;
                            psi[rj] -= z * del;
                            if s != NONE {
                                grad[s * w + col] -= rel[c] * del;
                            }
                        }
                    }
                }
            }
            for r in &plan.drags.runs {
                let z = p[r.param];
                let s = of_slot[r.param];
                for &i in &plan.drags.particles[r.start..r.end] {
                    let i = i as usize;
                    for col in 0..w {
                        for c in 0..3 {
                            let ri = (3 * i + c) * w + col;
                            psi[ri] -= z * phi[ri];
                            if s != NONE {
                                grad[s * w + col] -= lin.vel[t * rows + 3 * i + c] * phi[ri];
                            }
                        }
                    }
                }
            }
            let nag = plan.angles.triples.len();
            if nag > 0 {
                let recs = &lin.angles[t * nag * angle::ANGLE..][..nag * angle::ANGLE];
                angle::adjoint(&plan.angles, recs, p, of_slot, w, phi, na, grad);
            }
            let npl = plan.planes.len();
            if npl > 0 {
                let recs = &lin.planes[t * npl * plane::PLANE..][..npl * plane::PLANE];
                plane::adjoint(&plan.planes, recs, of_slot, w, phi, (na, psi), grad);
            }
            if !plan.conditionals.is_empty() {
                let cond = &plan.conditionals;
                conditional::adjoint(cond, &lin.cond, t, p, of_slot, w, phi, (na, psi), grad);
            }
            for &(i, ms) in &self.unknown_masses {
                let m = p[mo + i];
                for c in 0..3 {
                    let fm = lin.force[t * rows + 3 * i + c] / m;
                    for col in 0..w {
                        grad[ms * w + col] -= fm * phi[(3 * i + c) * w + col];
                    }
                }
            }
            for ((x, y), s) in na.iter_mut().zip(b.iter_mut()).zip(psi.iter()) {
                *x += s * inv_dt;
                *y -= s * inv_dt;
            }
            std::mem::swap(a, na);
        }
        for (g, c) in grad[..nt * w].iter_mut().zip(0..) {
            *g *= self.chain[c / w];
        }
        for (f, &i) in self.fit.tangent.free.iter().enumerate() {
            for c in 0..3 {
                for col in 0..w {
                    let q = (3 * i + c) * w + col;
                    grad[(nt + 6 * f + c) * w + col] = a[q] + b[q];
                    grad[(nt + 6 * f + 3 + c) * w + col] = -dt * b[q];
                }
            }
        }
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

    fn gather(&self, v: &[f64], k: usize, w: usize, work: &mut Work) {
        let (nt, ns) = (self.fit.theta(), self.fit.state_len());
        work.dir.clear();
        work.dir.extend_from_slice(&v[..nt * w]);
        work.dir
            .extend_from_slice(&v[(nt + k * ns) * w..(nt + (k + 1) * ns) * w]);
    }

    fn scatter(&self, k: usize, w: usize, grad: &[f64], out: &mut [f64], nt: usize, ns: usize) {
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

/// `z u uᵀ`, row-major.
fn rank_one(out: &mut [f64; 9], z: f64, u: &[f64]) {
    for r in 0..3 {
        for c in 0..3 {
            out[3 * r + c] = z * u[r] * u[c];
        }
    }
}

/// The preconditioner `M⁻¹` at one λ (module docs).
pub(crate) struct Pre {
    nt: usize,
    /// Inverse of each damped local block, 36 per free particle per take, in state order.
    dinv: Vec<f64>,
    /// `Y = D⁻¹ H_sθ` (state rows × nθ), and the Cholesky factor of the θ system.
    y: DMatrix<f64>,
    hst: DMatrix<f64>,
    schur: Option<nalgebra::Cholesky<f64, nalgebra::Dyn>>,
    held: Vec<bool>,
}

impl Pre {
    /// Builds `M + λ diag(scale)` restricted to the coordinates not held, and factors it.
    pub fn new(
        mf: &Mf<'_, '_>,
        cols: &DMatrix<f64>,
        scale: &[f64],
        held: &[bool],
        lambda: f64,
    ) -> Pre {
        let nt = mf.fit.theta();
        let len = mf.fit.len();
        let nss = len - nt;
        let mut dinv = vec![0.0; 36 * (nss / 6)];
        let mut b = 0;
        for lin in &mf.lins {
            for blk in lin.local.chunks(36) {
                let mut m = Matrix6::from_row_slice(blk);
                for a in 0..6 {
                    let s = scale[nt + 6 * b + a];
                    m[(a, a)] += lambda * if s > 0.0 { s } else { 1.0 };
                    // A particle its own observations do not see (hidden): keep D invertible.
                    if m[(a, a)] <= 0.0 {
                        m[(a, a)] = 1.0;
                    }
                }
                let inv = m
                    .cholesky()
                    .map(|c| c.inverse())
                    .unwrap_or_else(|| Matrix6::from_diagonal(&m.diagonal().map(|d| 1.0 / d)));
                for r in 0..6 {
                    for c in 0..6 {
                        dinv[36 * b + 6 * r + c] = inv[(r, c)];
                    }
                }
                b += 1;
            }
        }
        let mut hst = cols.rows(nt, nss).into_owned();
        let mut att = cols.rows(0, nt).into_owned();
        for a in 0..nt {
            att[(a, a)] += lambda * if scale[a] > 0.0 { scale[a] } else { 1.0 };
        }
        for a in 0..nt {
            if held[a] {
                for c in 0..nt {
                    att[(a, c)] = 0.0;
                    att[(c, a)] = 0.0;
                }
                att[(a, a)] = 1.0;
                hst.column_mut(a).fill(0.0);
            }
        }
        let att = (&att + att.transpose()) * 0.5;
        let mut y = DMatrix::zeros(nss, nt);
        for p in 0..nss / 6 {
            for c in 0..nt {
                for r in 0..6 {
                    let mut s = 0.0;
                    for q in 0..6 {
                        s += dinv[36 * p + 6 * r + q] * hst[(6 * p + q, c)];
                    }
                    y[(6 * p + r, c)] = s;
                }
            }
        }
        let s = &att - hst.transpose() * &y;
        let s = (&s + s.transpose()) * 0.5;
        let schur = s.cholesky().or_else(|| {
            // The local blocks underestimate the states' information: drop the coupling.
            y.fill(0.0);
            hst.fill(0.0);
            att.clone().cholesky()
        });
        Pre {
            nt,
            dinv,
            y,
            hst,
            schur,
            held: held.to_vec(),
        }
    }

    /// `z = M⁻¹ r` (one vector).
    pub fn apply(&self, r: &[f64], z: &mut [f64]) {
        let nt = self.nt;
        let (rt, rs) = r.split_at(nt);
        let (zt, zs) = z.split_at_mut(nt);
        for (p, (o, x)) in zs.chunks_mut(6).zip(rs.chunks(6)).enumerate() {
            let m = &self.dinv[36 * p..36 * p + 36];
            for a in 0..6 {
                o[a] = (0..6).map(|b| m[6 * a + b] * x[b]).sum();
            }
        }
        if nt == 0 {
            return;
        }
        let mut rhs =
            DVector::from_iterator(nt, (0..nt).map(|a| if self.held[a] { 0.0 } else { rt[a] }));
        let zs_v = DVector::from_column_slice(zs);
        rhs -= self.hst.transpose() * &zs_v;
        let th = match &self.schur {
            Some(c) => c.solve(&rhs),
            None => rhs,
        };
        let corr = &self.y * &th;
        for (o, c) in zs.iter_mut().zip(corr.iter()) {
            *o -= c;
        }
        for a in 0..nt {
            zt[a] = if self.held[a] { 0.0 } else { th[a] };
        }
    }
}

/// Buffers of the conjugate-gradient solves (one vector each).
#[derive(Clone, Debug, Default)]
pub(crate) struct CgWork {
    r: Vec<f64>,
    z: Vec<f64>,
    p: Vec<f64>,
    ap: Vec<f64>,
}

/// Solves `(H + λ diag(scale)) x = rhs` on the coordinates not held (held ones stay 0) by
/// PCG; returns the iterations and whether the relative residual reached `set.tol`.
#[allow(clippy::too_many_arguments)]
pub(crate) fn pcg(
    mf: &Mf<'_, '_>,
    pre: &Pre,
    scale: &[f64],
    held: &[bool],
    lambda: f64,
    rhs: &[f64],
    x: &mut [f64],
    set: CgSettings,
    deflation: Option<&Deflation>,
    cg: &mut CgWork,
    work: &mut Work,
) -> (usize, bool) {
    let len = rhs.len();
    let CgWork { r, z, p, ap } = cg;
    for v in [&mut *r, &mut *z, &mut *p, &mut *ap] {
        v.clear();
        v.resize(len, 0.0);
    }
    x.iter_mut().for_each(|v| *v = 0.0);
    for a in 0..len {
        r[a] = if held[a] { 0.0 } else { rhs[a] };
    }
    let bnorm = dot(r, r).sqrt();
    if bnorm == 0.0 {
        return (0, true);
    }
    if let Some(d) = deflation {
        d.start(x, r);
        if dot(r, r).sqrt() <= set.tol * bnorm {
            return (0, true);
        }
    }
    pre.apply(r, z);
    if let Some(d) = deflation {
        d.project(z);
    }
    p.copy_from_slice(z);
    let mut rz = dot(r, z);
    for it in 1..=set.max_iterations {
        damped_hv(mf, p, 1, scale, held, lambda, ap, work);
        let pap = dot(p, ap);
        if pap.is_nan() || pap <= 0.0 {
            return (it, false);
        }
        let alpha = rz / pap;
        for a in 0..len {
            x[a] += alpha * p[a];
            r[a] -= alpha * ap[a];
        }
        if dot(r, r).sqrt() <= set.tol * bnorm {
            return (it, true);
        }
        pre.apply(r, z);
        let rz_new = dot(r, z);
        let beta = rz_new / rz;
        rz = rz_new;
        if let Some(d) = deflation {
            d.project(z);
        }
        for a in 0..len {
            p[a] = z[a] + beta * p[a];
        }
    }
    (set.max_iterations, false)
}

/// Hooke and Jeeves' pattern move after an accepted step: from the new iterate `at` (cost
/// `cost`), moves along `d` (the sum of the last two accepted steps) by `α d`, α = 1, 2, 4, …
/// up to [`PATTERN_MAX`] while the cost keeps falling, and leaves `at` on the best point;
/// returns its cost and the number of costs evaluated. `cost_of` projects a candidate into the
/// box in place and returns its cost (NaN or +inf: no gain).
///
/// Why: along the cloth's structural/bending valley the Gauss–Newton steps zig-zag across the
/// valley's floor (each gains about what its model predicts, λ ≈ 0, yet consecutive steps
/// alternate sides), so the estimate creeps along it by 0.5–2 % of a stiffness per step: the
/// 20 × 20 cloth ended on its 100-iteration budget 94 σ̂² above the optimum it reaches with
/// these moves (BENCHMARKS.md, "Pattern moves"). Two consecutive zig-zag steps sum to the
/// valley's direction. A trial costs one simulation against the step's CG solve of 10–80
/// iterations (2 passes each), and only a lower cost is kept: the fit stays monotone.
fn pattern_move(
    at: &mut [f64],
    cost: f64,
    d: &[f64],
    mut cost_of: impl FnMut(&mut [f64]) -> f64,
) -> (f64, usize) {
    let from = at.to_vec();
    let mut cand = vec![0.0; at.len()];
    let (mut best, mut evaluations) = (cost, 0);
    let mut alpha = 1.0;
    while alpha <= PATTERN_MAX {
        for ((c, f), d) in cand.iter_mut().zip(&from).zip(d) {
            *c = f + alpha * d;
        }
        evaluations += 1;
        let c = cost_of(&mut cand);
        if c.is_nan() || c >= best {
            break;
        }
        best = c;
        at.copy_from_slice(&cand);
        alpha *= 2.0;
    }
    (best, evaluations)
}

/// The deflation subspace of a step's solve: the window's last accepted steps ([`DEFLATE_STEPS`]),
/// zero on the held coordinates, under the solve's own operator `H + λ diag(scale)` (one
/// product as wide as the subspace).
fn step_deflation(
    mf: &Mf<'_, '_>,
    recent: &std::collections::VecDeque<Vec<f64>>,
    scale: &[f64],
    held: &[bool],
    lambda: f64,
    work: &mut Work,
) -> Option<Deflation> {
    let vectors: Vec<Vec<f64>> = recent
        .iter()
        .map(|v| {
            v.iter()
                .zip(held)
                .map(|(x, &h)| if h { 0.0 } else { *x })
                .collect()
        })
        .collect();
    Deflation::new(&vectors, |v, k, out| {
        damped_hv(mf, v, k, scale, held, lambda, out, work)
    })
}

/// `out = (H + λ diag(scale)) v` on `w` row-major columns, 0 on the held coordinates: the
/// operator of a step's solve (a zero scale counts as 1).
#[allow(clippy::too_many_arguments)]
fn damped_hv(
    mf: &Mf<'_, '_>,
    v: &[f64],
    w: usize,
    scale: &[f64],
    held: &[bool],
    lambda: f64,
    out: &mut [f64],
    work: &mut Work,
) {
    mf.hv(v, w, out, work);
    for (a, (row, vs)) in out.chunks_mut(w).zip(v.chunks(w)).enumerate() {
        let s = if scale[a] > 0.0 { scale[a] } else { 1.0 };
        for (o, x) in row.iter_mut().zip(vs) {
            *o = if held[a] { 0.0 } else { *o + lambda * s * x };
        }
    }
}

/// Diagonal of the preconditioner's H (exact for θ, the local blocks for states): the
/// Marquardt scaling and gtol's column norms.
fn approx_diag(mf: &Mf<'_, '_>, cols: &DMatrix<f64>) -> Vec<f64> {
    let nt = mf.fit.theta();
    let mut d: Vec<f64> = (0..nt).map(|a| cols[(a, a)]).collect();
    for lin in &mf.lins {
        for blk in lin.local.chunks(36) {
            d.extend((0..6).map(|a| blk[7 * a]));
        }
    }
    d
}

/// Statistics of the matrix-free fit, for the estimate's note.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub(crate) struct CgCounts {
    pub solves: usize,
    pub iterations: usize,
    pub unconverged: usize,
}

/// The matrix-free counterpart of [`super::fit::lm_stage`]: the same Marquardt scaling,
/// Nielsen λ rule, projection and tolerances; steps by PCG.
#[allow(clippy::too_many_arguments)]
pub(crate) fn lm_stage(
    mf: &mut Mf<'_, '_>,
    q: &mut [f64],
    window: usize,
    set: LmSettings,
    cgset: CgSettings,
    chi2: f64,
    window_ftol: f64,
    verify_newton: bool,
    counts: &mut Counts,
    cgc: &mut CgCounts,
    recent: &mut std::collections::VecDeque<Vec<f64>>,
    work: &mut Work,
    halt: &dyn Fn() -> bool,
) -> StageEnd {
    let fit = mf.fit;
    let len = fit.len();
    counts.evaluations += 1;
    if !mf.linearise(q, window, work) {
        return StageEnd::Diverged;
    }
    let mut g = vec![0.0; len];
    mf.gradient(&mut g, work);
    let mut cols = mf.theta_columns(work);
    let mut diag = approx_diag(mf, &cols);
    let mut scale = diag.clone();
    let mut cost = mf.cost();
    let mut lambda = 1e-3;
    let mut nu = 2.0;
    let floor = fit.rounding_floor(window);
    let mut cg = CgWork::default();
    let mut delta = vec![0.0; len];
    let mut hstep = vec![0.0; len];
    let mut sens = super::tangent::Sens::default();
    let mut g0norm: Option<f64> = None;
    let mut accepted = 0usize;
    recent.clear();
    for _ in 0..set.max_iterations {
        if halt() {
            return StageEnd::Interrupted;
        }
        counts.iterations += 1;
        if cost <= floor {
            return StageEnd::Converged;
        }
        let gv = DVector::from_column_slice(&g);
        let mut held = fit.held(q, &gv);
        let gmax = (0..len)
            .filter(|&a| !held[a] && diag[a] > 0.0)
            .map(|a| g[a].abs() / (diag[a] * cost).sqrt())
            .fold(0.0, f64::max);
        if gmax <= set.gtol {
            return StageEnd::Converged;
        }
        let rhs: Vec<f64> = g.iter().map(|x| -x).collect();
        // Inexact Newton (Eisenstat–Walker's choice 2 flavour): loose solves far from the
        // optimum, down to `cgset.tol` as the gradient falls.
        let gnorm = dot(&g, &g).sqrt();
        let g0 = *g0norm.get_or_insert(gnorm);
        let forcing = CgSettings {
            tol: (0.5 * (gnorm / g0).sqrt()).clamp(cgset.tol, STEP_CG_TOL_MAX),
            ..cgset
        };
        // A coordinate on its bound whose gradient points in may still be pushed out by the
        // coupled step (the cloth's bending stiffness, traded against the structural one):
        // projected, that step raised the cost by 10-10^4 σ̂² and sent λ up, three solves a
        // time (BENCHMARKS, "Large scenes"). Such a coordinate is held and the step solved
        // again in the face of the box, once.
        let mut ok = false;
        for _ in 0..2 {
            let pre = Pre::new(mf, &cols, &scale, &held, lambda);
            let deflation = step_deflation(mf, recent, &scale, &held, lambda, work);
            let (its, conv) = pcg(
                mf,
                &pre,
                &scale,
                &held,
                lambda,
                &rhs,
                &mut delta,
                forcing,
                deflation.as_ref(),
                &mut cg,
                work,
            );
            cgc.solves += 1;
            cgc.iterations += its;
            ok = conv;
            let pushed = fit.pushed_out(q, &delta, &held);
            if pushed.is_empty() {
                break;
            }
            for a in pushed {
                held[a] = true;
            }
        }
        cgc.unconverged += usize::from(!ok);
        if delta.iter().any(|v| !v.is_finite()) {
            lambda *= nu;
            nu *= 2.0;
            if lambda > 1e20 {
                return StageEnd::Stalled;
            }
            continue;
        }
        // The step, then (if it raises the cost) its halves: a rejected Gauss–Newton step is
        // usually right in direction and too long, and a cost evaluation (one simulation)
        // is far cheaper than the CG solve at a larger λ.
        let mut trial = vec![0.0; len];
        let mut step = vec![0.0; len];
        let mut c = f64::INFINITY;
        let mut shrunk = 0;
        // A step leaving the box is first tried projected (it usually gains); if that fails,
        // its halves are tried cut at the box (the fraction f_b that lands the first θ
        // coordinate on its bound, then f_b/2) rather than projected: a projected step
        // changes direction, and along the poorly determined pairs (the cloth's structural
        // and bending stiffnesses) the projected halves raised the cost by 10²–10⁴ σ̂² and
        // sent λ up again and again (BENCHMARKS, "Large scenes"). On its bound the coordinate
        // is held at the next iterate if the gradient pushes out.
        let to_box = fit.fraction_to_bounds(q, &delta);
        let cut = to_box < 1.0 && to_box > MIN_CUT;
        for t in 0..=BACKTRACK {
            let f = match (t, cut) {
                (0, _) | (_, false) => 0.5f64.powi(t as i32),
                (t, true) => to_box * 0.5f64.powi(t as i32 - 1),
            };
            for a in 0..len {
                trial[a] = q[a] + f * delta[a];
            }
            fit.project(&mut trial);
            counts.evaluations += 1;
            c = fit.cost(&trial, window, &mut sens);
            shrunk = t;
            if c < cost {
                break;
            }
        }
        for a in 0..len {
            step[a] = trial[a] - q[a];
        }
        mf.hv(&step, 1, &mut hstep, work);
        let predicted = -(2.0 * dot(&g, &step) + dot(&step, &hstep));
        if c < cost {
            if shrunk > 0 {
                // The full step failed: damp the next one as a rejection would.
                lambda *= nu;
                nu *= 2.0;
            }
            let rho = if predicted > 0.0 {
                (cost - c) / predicted
            } else {
                0.0
            };
            if shrunk == 0 {
                lambda *= (1.0 - (2.0 * rho - 1.0).powi(3)).max(1.0 / 3.0);
                nu = 2.0;
            }
            if let Some(before) = recent.back() {
                let d: Vec<f64> = step.iter().zip(before).map(|(a, b)| a + b).collect();
                let (moved, evaluations) = pattern_move(&mut trial, c, &d, |x| {
                    fit.project(x);
                    fit.cost(x, window, &mut sens)
                });
                counts.evaluations += evaluations;
                c = moved;
                for a in 0..len {
                    step[a] = trial[a] - q[a];
                }
            }
            // The stop rules below see the whole move, the pattern's gain included; λ above
            // judged the Gauss–Newton step alone (its model's prediction).
            let reduction = cost - c;
            let qnorm = dot(q, q).sqrt();
            let small_step = dot(&step, &step).sqrt() <= set.xtol * (set.xtol + qnorm);
            let small_gain = reduction <= set.ftol * cost && predicted <= set.ftol * cost;
            // The statistical criterion (module docs): a step that lowers the cost by less
            // than `chi2` σ̂² moves the estimate by less than √chi2 standard errors.
            let observed: usize = mf.lins.iter().map(|l| l.observed).sum();
            let s2 = cost / observed.saturating_sub(len).max(1) as f64;
            let chi2_gain = reduction <= chi2 * s2 && predicted <= chi2 * s2;
            let small_gain =
                small_gain || (reduction <= window_ftol * cost && predicted <= window_ftol * cost);
            q.copy_from_slice(&trial);
            let mut kept = if recent.len() == DEFLATE_STEPS {
                recent.pop_front().unwrap_or_default()
            } else {
                Vec::new()
            };
            kept.clone_from(&step);
            recent.push_back(kept);
            counts.evaluations += 1;
            if !mf.linearise(q, window, work) {
                return StageEnd::Diverged;
            }
            cost = mf.cost();
            mf.gradient(&mut g, work);
            // The θ columns only precondition (and scale): refreshed every few accepted steps,
            // they cost nθ-wide passes, ~nθ/3 CG iterations.
            accepted += 1;
            if accepted % COLUMNS_EVERY == 0 {
                cols = mf.theta_columns(work);
                diag = approx_diag(mf, &cols);
            }
            for (s, d) in scale.iter_mut().zip(&diag) {
                *s = s.max(*d);
            }
            if small_step || small_gain {
                return StageEnd::Converged;
            }
            if chi2_gain {
                // A damped or truncated step can gain little far from the optimum (along a
                // poorly determined parameter λD dominates): the statistical criterion holds
                // only when the undamped Gauss–Newton step would gain as little.
                if !verify_newton {
                    return StageEnd::Converged;
                }
                let s2 = cost / observed.saturating_sub(len).max(1) as f64;
                let held = fit.held(q, &DVector::from_column_slice(&g));
                let pre = Pre::new(mf, &cols, &scale, &held, NEWTON_LAMBDA);
                let rhs: Vec<f64> = g.iter().map(|x| -x).collect();
                let deflation = step_deflation(mf, recent, &scale, &held, NEWTON_LAMBDA, work);
                let (its, ok) = pcg(
                    mf,
                    &pre,
                    &scale,
                    &held,
                    NEWTON_LAMBDA,
                    &rhs,
                    &mut delta,
                    NEWTON_CG,
                    deflation.as_ref(),
                    &mut cg,
                    work,
                );
                cgc.solves += 1;
                cgc.iterations += its;
                // CG's model decrease -gᵀx grows monotonically to gᵀH⁻¹g: an unconverged
                // solve that already exceeds the criterion proves there is more to gain.
                let decrement = -dot(&g, &delta);
                if ok && decrement.is_finite() && decrement <= chi2 * s2 {
                    return StageEnd::Converged;
                }
                cgc.unconverged += usize::from(!ok);
                // Go on with near-Gauss–Newton steps.
                lambda = lambda.min(1e-6);
                nu = 2.0;
            }
        } else {
            lambda *= nu;
            nu *= 2.0;
            if lambda > 1e20 {
                return StageEnd::Stalled;
            }
        }
    }
    StageEnd::Budget
}

/// How a standard-error solve `H x = e_k` is judged converged ([`theta_inverse`]).
#[derive(Clone, Copy, Debug)]
pub(crate) struct StderrStop {
    /// Relative residual `‖H x − e_k‖` (`‖e_k‖` = 1) at which the solve is exact enough.
    pub residual: f64,
    /// Or: the variance `x_k = e_kᵀx` grew by at most this fraction of itself over the last
    /// [`STDERR_DELAY`] iterations (0: off).
    pub form: f64,
    pub max_iterations: usize,
}

/// The default: the residual of [`STDERR_CG_TOL`], or the variance settled to
/// [`STDERR_FORM_TOL`], within 300 iterations.
pub(crate) const STDERR_STOP: StderrStop = StderrStop {
    residual: STDERR_CG_TOL,
    form: STDERR_FORM_TOL,
    max_iterations: 300,
};

/// The θ block of `H⁻¹` (internal coordinates) by nθ PCG solves `H x_k = e_k`, at the
/// linearisation `mf` holds, run together (every product as wide as the solves still running:
/// the passes read the stored linearisation once for all of them). Columns whose solve did not
/// converge are NaN.
///
/// A column is converged when its residual is below `stop.residual`, or when its variance
/// has settled: PCG from zero raises `e_kᵀx_j` monotonically to `e_kᵀH⁻¹e_k`, and what is left,
/// `‖x − x_j‖²_H = Σ_{i≥j} α_i r_iᵀz_i`, is estimated by the last [`STDERR_DELAY`] terms
/// (Strakoš and Tichý's delayed estimate, a lower bound); the solve stops when they add less
/// than `stop.form` of the variance. The covariances follow: `|e_lᵀ(x − x_j)| ≤ √(var_l ‖x −
/// x_j‖²_H)`, so a correlation is off by about `√stop.form`. Why: on the 32 × 32 cloth the
/// residual criterion (1e-6) was never met in 300 iterations (`‖r‖` 0.02–0.3) while every
/// variance had settled to 4 digits: the fit reported no standard error at all, for 49 s
/// (BENCHMARKS.md, "Pattern moves").
///
/// The solves are deflated ([`crate::linalg::deflation`]) by `recycled`, the last window's
/// last accepted steps: they line up with the poorly determined directions (the cloth's
/// structural/bending valley), which carry most of each variance and which CG resolves last.
/// Deflated CG keeps its residuals orthogonal to the steps and its iterates Galerkin on the
/// steps and the Krylov space, so `e_kᵀx_j` still rises monotonically to the variance and the
/// stopping rule holds. Measured on the 32 × 32 cloth: 253 → 178 iterations, 28 → 17 s, the
/// same standard errors to 3 digits (BENCHMARKS.md, "Lean passes").
pub(crate) fn theta_inverse(
    mf: &Mf<'_, '_>,
    stop: StderrStop,
    recycled: &[Vec<f64>],
    cgc: &mut CgCounts,
    work: &mut Work,
) -> DMatrix<f64> {
    let nt = mf.fit.theta();
    let len = mf.fit.len();
    let mut out = DMatrix::from_element(nt, nt, f64::NAN);
    if nt == 0 {
        return out;
    }
    let cols = mf.theta_columns(work);
    let scale = approx_diag(mf, &cols);
    let held = vec![false; len];
    // A tiny damping in the preconditioner only (the operator is H itself): hidden particles'
    // empty local blocks stay invertible.
    let pre = Pre::new(mf, &cols, &scale, &held, 1e-12);
    let w = nt;
    // Row-major len × w: column k solves H x = e_k.
    let mut x = vec![0.0; len * w];
    let mut r = vec![0.0; len * w];
    let mut z = vec![0.0; len * w];
    let mut p = vec![0.0; len * w];
    let mut ap = vec![0.0; len * w];
    // The running columns' directions and products, packed (len × running).
    let (mut packed, mut packed_ap) = (vec![0.0; len * w], vec![0.0; len * w]);
    let (mut rc, mut zc) = (vec![0.0; len], vec![0.0; len]);
    for k in 0..nt {
        r[k * w + k] = 1.0;
    }
    let precondition = |r: &[f64], z: &mut [f64], rc: &mut [f64], zc: &mut [f64]| {
        for c in 0..w {
            for a in 0..len {
                rc[a] = r[a * w + c];
            }
            pre.apply(rc, zc);
            for a in 0..len {
                z[a * w + c] = zc[a];
            }
        }
    };
    let coldot = |u: &[f64], v: &[f64], c: usize| -> f64 {
        (0..len).map(|a| u[a * w + c] * v[a * w + c]).sum()
    };
    let deflation = match recycled.is_empty() {
        true => None,
        false => Deflation::new(recycled, |v, k, out| mf.hv(v, k, out, work)),
    };
    let mut column = Vec::with_capacity(len);
    if let Some(d) = &deflation {
        d.start_columns(&mut x, &mut r, w, &mut column);
    }
    // The columns a deflated iteration projects (all of them at the start).
    let mut still: Vec<usize> = (0..w).collect();
    precondition(&r, &mut z, &mut rc, &mut zc);
    if let Some(d) = &deflation {
        d.project_columns(&mut z, w, &still, &mut column);
    }
    p.copy_from_slice(&z);
    let mut rz: Vec<f64> = (0..w).map(|c| coldot(&r, &z, c)).collect();
    let mut done = vec![false; w];
    let mut failed = vec![false; w];
    // Each column's variance x_k after every iteration (its settling test).
    let mut variance: Vec<Vec<f64>> = vec![Vec::new(); w];
    let mut its = 0;
    while its < stop.max_iterations && done.iter().zip(&failed).any(|(d, f)| !d && !f) {
        its += 1;
        let running: Vec<usize> = (0..w).filter(|&c| !done[c] && !failed[c]).collect();
        let nr = running.len();
        for a in 0..len {
            for (slot, &c) in running.iter().enumerate() {
                packed[a * nr + slot] = p[a * w + c];
            }
        }
        mf.hv(&packed[..len * nr], nr, &mut packed_ap[..len * nr], work);
        for a in 0..len {
            for (slot, &c) in running.iter().enumerate() {
                ap[a * w + c] = packed_ap[a * nr + slot];
            }
        }
        for &c in &running {
            let pap = coldot(&p, &ap, c);
            if pap.is_nan() || pap <= 0.0 {
                failed[c] = true;
                continue;
            }
            let alpha = rz[c] / pap;
            for a in 0..len {
                x[a * w + c] += alpha * p[a * w + c];
                r[a * w + c] -= alpha * ap[a * w + c];
            }
            let history = &mut variance[c];
            history.push(x[c * w + c]);
            let settled = stop.form > 0.0
                && history.len() > STDERR_DELAY
                && history[history.len() - 1] - history[history.len() - 1 - STDERR_DELAY]
                    <= stop.form * history[history.len() - 1];
            // ‖e_k‖ = 1: the residual is already relative.
            if settled || coldot(&r, &r, c).sqrt() <= stop.residual {
                done[c] = true;
            }
        }
        precondition(&r, &mut z, &mut rc, &mut zc);
        if let Some(d) = &deflation {
            still.clear();
            still.extend(running.iter().filter(|&&c| !done[c] && !failed[c]));
            d.project_columns(&mut z, w, &still, &mut column);
        }
        for &c in &running {
            if done[c] || failed[c] {
                continue;
            }
            let rz_new = coldot(&r, &z, c);
            let beta = rz_new / rz[c];
            rz[c] = rz_new;
            for a in 0..len {
                p[a * w + c] = z[a * w + c] + beta * p[a * w + c];
            }
        }
    }
    cgc.solves += nt;
    cgc.iterations += its;
    for c in 0..w {
        if done[c] {
            for a in 0..nt {
                out[(a, c)] = x[a * w + c];
            }
        } else {
            cgc.unconverged += 1;
        }
    }
    out
}

/// The Cramér–Rao standard deviations (physical units) of the unknowns at `q` (the truth) for
/// Gaussian noise `sigma` (m) per unit-weight coordinate over `window` frames: `σ² [H⁻¹]_θθ`
/// by [`theta_inverse`] (its default stop: variances to ~0.1 %; NaN where a solve did not
/// settle), the matrix-free counterpart of the dense bound of [`super::cramer_rao_takes`].
pub(crate) fn cramer_rao_sd(
    fitter: &Fitter<'_>,
    q: &[f64],
    window: usize,
    sigma: f64,
) -> Result<Vec<f64>, crate::error::CostError> {
    let mut mf = Mf::new(fitter);
    let mut work = Work::default();
    if !mf.linearise(q, window, &mut work) {
        return Err(crate::error::CostError::mismatch(
            "truth",
            "the true model diverges",
        ));
    }
    let inv = theta_inverse(&mf, STDERR_STOP, &[], &mut CgCounts::default(), &mut work);
    let cov = theta_covariance(&inv, sigma * sigma, &fitter.chain(q));
    Ok((0..fitter.theta()).map(|a| cov[(a, a)].sqrt()).collect())
}

/// `σ² [H⁻¹]_θθ` in physical units from the θ block `inv` of [`theta_inverse`] (internal
/// coordinates, symmetrised; `chain` the internal-to-physical derivatives).
fn theta_covariance(inv: &DMatrix<f64>, sigma2: f64, chain: &[f64]) -> DMatrix<f64> {
    let cov_q = DMatrix::from_fn(inv.nrows(), inv.ncols(), |a, b| {
        let v = 0.5 * (inv[(a, b)] + inv[(b, a)]);
        sigma2 * v
    });
    super::uncertainty::physical(&cov_q, chain)
}

/// One window's stage of the matrix-free fit: the last window (the whole take) to the final
/// tolerances, earlier ones looser and shorter ([`WINDOW_CHI2`], [`WINDOW_ITERATIONS`]).
#[allow(clippy::too_many_arguments)]
pub(crate) fn stage(
    fitter: &Fitter<'_>,
    q: &mut [f64],
    w: usize,
    longest: usize,
    set: LmSettings,
    counts: &mut Counts,
    cgc: &mut CgCounts,
    steps: &mut Vec<Vec<f64>>,
    halt: &dyn Fn() -> bool,
) -> StageEnd {
    let step_cg = CgSettings {
        tol: STEP_CG_TOL,
        max_iterations: STEP_CG_ITERATIONS,
    };
    let mut mf = Mf::new(fitter);
    let mut work = Work::default();
    let last = w >= longest;
    let (chi2, wftol) = if last {
        (FINAL_CHI2, 0.0)
    } else {
        (WINDOW_CHI2, WINDOW_FTOL)
    };
    let set = if last {
        set
    } else {
        LmSettings {
            max_iterations: set.max_iterations.min(WINDOW_ITERATIONS),
            ..set
        }
    };
    let mut recent = std::collections::VecDeque::new();
    let end = lm_stage(
        &mut mf,
        q,
        w,
        set,
        step_cg,
        chi2,
        wftol,
        last,
        counts,
        cgc,
        &mut recent,
        &mut work,
        halt,
    );
    *steps = recent.into();
    end
}

/// The estimate at the end of the matrix-free fit, its standard errors by CG solves of H.
#[allow(clippy::too_many_arguments)]
pub(crate) fn finish(
    fitter: &Fitter<'_>,
    q: Vec<f64>,
    mut counts: Counts,
    mut cgc: CgCounts,
    end: StageEnd,
    windows: Vec<usize>,
    noise_level: Vec<f64>,
    start: String,
    last_steps: &[Vec<f64>],
) -> Result<super::Estimate, crate::error::CostError> {
    let mut mf = Mf::new(fitter);
    let mut work = Work::default();
    let longest = windows.iter().copied().max().unwrap_or(0);
    counts.evaluations += 1;
    if !mf.linearise(&q, longest, &mut work) {
        return Err(crate::error::CostError::mismatch(
            "output-error",
            "the model diverged at its estimate",
        ));
    }
    let cost = mf.cost();
    let observed: usize = fitter.takes.iter().map(super::Take::observed).sum();
    let variables = fitter.len();
    let dof = observed.saturating_sub(variables).max(1);
    let sigma2 = cost / dof as f64;
    let dim = fitter.theta();
    let solves_before = cgc.unconverged;
    let inv = theta_inverse(&mf, STDERR_STOP, last_steps, &mut cgc, &mut work);
    let covariance = theta_covariance(&inv, sigma2, &fitter.chain(&q));
    let correlation = super::uncertainty::correlation(&covariance);
    let params = fitter.params(&q);
    let (stderr, intervals) = super::summary::spread(fitter, &params, &covariance);
    let states = super::summary::take_states(fitter, &q);
    let missing = cgc.unconverged - solves_before;
    let note = format!(
        "{start}; matrix-free Gauss–Newton ({variables} variables > {DENSE_MAX_COLUMNS} dense \
         columns): {} CG solves, {} iterations, {} short of tolerance; standard errors from \
         {dim} CG solves of H{}; undetermined directions not computed",
        cgc.solves,
        cgc.iterations,
        cgc.unconverged,
        if missing > 0 {
            format!(" ({missing} did not converge: those are NaN, not computed)")
        } else {
            String::new()
        }
    );
    Ok(super::Estimate {
        genome: q[..dim].to_vec(),
        params,
        states,
        cost,
        sigma: sigma2.sqrt(),
        noise_level,
        observed,
        variables,
        stderr,
        intervals,
        covariance,
        correlation,
        undetermined: Vec::new(),
        converged: end == StageEnd::Converged,
        above_noise: false,
        end: super::summary::end_text(end),
        iterations: counts.iterations,
        evaluations: counts.evaluations,
        windows,
        start: note,
        loss: super::Loss::Squared,
        downweighted: 0,
    })
}

#[cfg(test)]
mod tests {
    //! The matrix-free products against the dense sensitivities of [`super::super::tangent`].

    use approx::assert_relative_eq;
    use cordis_core::{Bounds, Param, Scene, Vec3};

    use super::super::fit::{self, Counts, Fitter, LmSettings};
    use super::super::observations::Take;
    use super::super::tangent::{Sens, Tangent};
    use super::*;
    use crate::identify::{add_noise, with_unknown_boxes};
    use crate::space::ParameterSpace;

    /// Damped springs (A not symmetric) with a quadratic viscosity, a damper, an anchor, a drag,
    /// angles, an unknown mass, a fixed particle: every term of the recursion.
    fn truth() -> Scene {
        let mut s = super::super::tests::every_term_scene(7);
        s.particles[5].fixed = true;
        s
    }

    struct Setup {
        tangent: Tangent,
        space: ParameterSpace,
        base: Vec<f64>,
        takes: Vec<Take>,
        q: Vec<f64>,
    }

    fn setup(noise: f64) -> Setup {
        let truth = truth();
        let mut guess = with_unknown_boxes(&truth, 25.0, 3);
        guess.particles[2].mass = Param::Unknown(Bounds {
            min: 0.1,
            max: 10.0,
            init: None,
        });
        // The quadratic viscosity and the angles' rest cosine unknown too: every θ column.
        let quadratic = Param::Unknown(Bounds {
            min: 0.01,
            max: 5.0,
            init: None,
        });
        guess.types[0].set_optional(
            cordis_core::OptionalParam::DampingQuadratic,
            Some(quadratic),
        );
        // A conditional range is refused unknown (a step in the cost).
        let touch = guess.types.iter_mut().find(|t| t.name == "touch").unwrap();
        touch.params[3] = Param::Known(touch.params[3].value());
        let bend = guess.types.iter_mut().find(|t| t.name == "bend").unwrap();
        let c0 = bend.params[1].value();
        bend.params[1] = Param::Unknown(Bounds {
            min: c0 - 0.5,
            max: c0 + 0.5,
            init: None,
        });
        setup_of(&truth, &guess, 60, noise)
    }

    /// The Provot patch ([`super::super::tests::provot_scene`]): K, l0, Z of every type, τc of
    /// one structural type and one mass unknown.
    fn provot_setup(noise: f64) -> Setup {
        let truth = super::super::tests::provot_scene();
        let mut guess = with_unknown_boxes(&truth, 25.0, 3);
        guess.particles[6].mass = Param::Unknown(Bounds {
            min: 1e-4,
            max: 1e-2,
            init: None,
        });
        let tau = Param::Unknown(Bounds {
            min: 0.02,
            max: 0.5,
            init: None,
        });
        guess.types[0].set_optional(cordis_core::OptionalParam::MaxElongation, Some(tau));
        setup_of(&truth, &guess, 60, noise)
    }

    /// Two takes of `truth`'s `frames` frames (the second with gaps) for the unknowns of
    /// `guess`, at an iterate slightly off the truth.
    fn setup_of(truth: &Scene, guess: &Scene, frames: usize, noise: f64) -> Setup {
        let tangent = Tangent::new(guess).unwrap();
        let space = ParameterSpace::from_scene(guess);
        let traj = truth.simulate(frames).unwrap();
        let noisy = add_noise(&traj, noise * traj.scale(), 1);
        // Two takes, the second with gaps: the θ block sums over takes.
        let t0 = Take::complete(&noisy);
        let t1 = Take::complete(&noisy.clone()).masked(|t, i, c| (t * 7 + i * 3 + c) % 5 != 0);
        let base = truth.param_values();
        let mut q: Vec<f64> = space
            .unknowns
            .iter()
            .map(|u| u.to_internal(base[u.slot]) + 0.01)
            .collect();
        for k in 0..2 {
            for &i in &tangent.free {
                let p = truth.particles[i].pos;
                let v = truth.particles[i].vel;
                q.extend([p[0], p[1] + 0.001 * k as f64, p[2], v[0], v[1], v[2] + 0.01]);
            }
        }
        Setup {
            tangent,
            space,
            base,
            takes: vec![t0, t1],
            q,
        }
    }

    fn fitter(s: &Setup) -> Fitter<'_> {
        let slots: Vec<usize> = s.space.unknowns.iter().map(|u| u.slot).collect();
        Fitter {
            tangent: &s.tangent,
            unknowns: &s.space.unknowns,
            base: &s.base,
            takes: &s.takes,
            cols: s.tangent.columns(&slots),
            continuity: None,
        }
    }

    /// Deterministic pseudo-random numbers in [-1, 1].
    fn noise(k: usize, salt: u64) -> f64 {
        let mut h = (k as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ salt;
        h ^= h >> 31;
        h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
        h ^= h >> 29;
        (h >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }

    /// The dense sensitivities S(t) of take k, frames × 3N × P.
    fn dense(fit: &Fitter<'_>, q: &[f64], k: usize, frames: usize) -> Vec<f64> {
        let p = fit.params(q);
        let (nt, ns) = (fit.theta(), fit.state_len());
        let mut out = Vec::new();
        let mut visit = |_: usize, _: &[Vec3], s: Option<&[f64]>| out.extend_from_slice(s.unwrap());
        fit.tangent
            .rollout(
                &p,
                &q[nt + k * ns..][..ns],
                frames,
                Some(&fit.cols),
                &mut Sens::default(),
                &mut visit,
            )
            .unwrap();
        out
    }

    #[test]
    fn directional_rollout_is_the_dense_sensitivities_times_v() {
        forward_matches_dense(&setup(0.0));
    }

    #[test]
    fn directional_rollout_through_provot_is_the_dense_sensitivities_times_v() {
        forward_matches_dense(&provot_setup(0.0));
    }

    fn forward_matches_dense(s: &Setup) {
        let fit = fitter(s);
        let mut mf = Mf::new(&fit);
        let mut work = Work::default();
        let frames = 60;
        assert!(mf.linearise(&s.q, frames, &mut work));
        let (nt, width) = (fit.theta(), fit.cols.len);
        let chain = fit.chain(&s.q);
        let rows = 3 * s.tangent.plan.n;
        for k in 0..2 {
            let v: Vec<f64> = (0..width).map(|a| noise(a, 11 + k as u64)).collect();
            work.dir = v.clone();
            mf.forward(k, 1, &mut work);
            let sens = dense(&fit, &s.q, k, frames);
            let mut worst: f64 = 0.0;
            let mut size: f64 = 0.0;
            for r in 0..frames * rows {
                let row = &sens[r * width..(r + 1) * width];
                let exact: f64 = (0..width)
                    .map(|a| row[a] * v[a] * if a < nt { chain[a] } else { 1.0 })
                    .sum();
                worst = worst.max((exact - work.out[r]).abs());
                size = size.max(exact.abs());
            }
            assert!(worst <= 1e-12 * size, "take {k}: {worst:e} of {size:e}");
        }
    }

    #[test]
    fn adjoint_is_the_transpose_of_the_directional_rollout() {
        adjoint_matches_forward(&setup(1e-3));
    }

    #[test]
    fn adjoint_through_provot_is_the_transpose_of_the_directional_rollout() {
        adjoint_matches_forward(&provot_setup(1e-3));
    }

    fn adjoint_matches_forward(s: &Setup) {
        let fit = fitter(s);
        let mut mf = Mf::new(&fit);
        let mut work = Work::default();
        let frames = 60;
        assert!(mf.linearise(&s.q, frames, &mut work));
        let (nt, width) = (fit.theta(), fit.cols.len);
        let chain = fit.chain(&s.q);
        let rows = 3 * s.tangent.plan.n;
        for k in 0..2 {
            let v: Vec<f64> = (0..width).map(|a| noise(a, 21 + k as u64)).collect();
            let u: Vec<f64> = (0..frames * rows)
                .map(|a| noise(a, 31 + k as u64))
                .collect();
            work.dir = v.clone();
            mf.forward(k, 1, &mut work);
            let jv_u = dot(&work.out, &u);
            mf.adjoint(k, 1, &u, &mut work);
            let v_jtu = dot(&v, &work.grad);
            // The forward applies A as β d + u (α u·d + q·d), the adjoint Aᵀ as
            // β δ + (α u + q)(u·δ): the same operator rounded differently over 60 frames
            // (measured 1.05e-12 relative here); a wrong transpose shows at 1e-3 and above.
            assert!(
                (jv_u - v_jtu).abs() <= 1e-11 * jv_u.abs().max(v_jtu.abs()),
                "take {k}: <Jv,u> = {jv_u:e}, <v,J'u> = {v_jtu:e}"
            );
            // And against the dense transpose, column by column.
            let sens = dense(&fit, &s.q, k, frames);
            for a in 0..width {
                let exact: f64 = (0..frames * rows)
                    .map(|r| sens[r * width + a] * u[r])
                    .sum::<f64>()
                    * if a < nt { chain[a] } else { 1.0 };
                let got = work.grad[a];
                assert!(
                    (exact - got).abs() <= 1e-11 * exact.abs().max(1.0),
                    "take {k}, column {a}: dense {exact:e}, adjoint {got:e}"
                );
            }
        }
    }

    /// The box bookkeeping of a step: a coordinate on its bound that the step pushes out is
    /// named (unless already held), one the step moves inward is not; the fraction to the box
    /// lands the first coordinate to leave exactly on its bound.
    #[test]
    fn a_step_pushing_a_coordinate_out_of_its_box_is_caught() {
        let s = setup(1e-3);
        let fit = fitter(&s);
        let (lo, hi) = s.space.unknowns[0].internal_bounds();
        let mut q = s.q.clone();
        q[0] = lo;
        let mut delta = vec![0.0; q.len()];
        delta[0] = -1.0;
        let mut held = vec![false; q.len()];
        assert_eq!(fit.pushed_out(&q, &delta, &held), vec![0]);
        held[0] = true;
        assert!(fit.pushed_out(&q, &delta, &held).is_empty());
        delta[0] = 1.0;
        assert!(fit
            .pushed_out(&q, &vec![0.0; q.len()], &[false].repeat(q.len()))
            .is_empty());
        q[0] = lo + 0.25 * (hi - lo);
        delta[0] = hi - lo;
        assert!((fit.fraction_to_bounds(&q, &delta) - 0.75).abs() < 1e-12);
        delta[0] = -(hi - lo);
        assert!((fit.fraction_to_bounds(&q, &delta) - 0.25).abs() < 1e-12);
        delta[0] = 0.1 * (hi - lo);
        assert_eq!(fit.fraction_to_bounds(&q, &delta), 1.0);
    }

    /// A step split over two threads sums as the unsplit one to rounding, and bit for bit the
    /// same whatever the thread count (guards determinism and the halves' bookkeeping: a
    /// half skipped or added twice, anchors in both halves).
    #[test]
    fn split_steps_match_the_unsplit_ones_and_not_the_thread_count() {
        let s = setup(1e-3);
        let fit = fitter(&s);
        let frames = 40;
        let rows = 3 * s.tangent.plan.n;
        let width = fit.cols.len;
        let v: Vec<f64> = (0..width).map(|a| noise(a, 7)).collect();
        let u: Vec<f64> = (0..frames * rows).map(|a| noise(a, 8)).collect();
        let run = |split_min: usize, threads: usize| {
            let mut mf = Mf::new(&fit);
            mf.split_min_springs = split_min;
            let mut work = Work::default();
            assert!(mf.linearise(&s.q, frames, &mut work));
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                work.dir = v.clone();
                mf.forward(1, 1, &mut work);
                let jv = work.out.clone();
                mf.adjoint(1, 1, &u, &mut work);
                (jv, work.grad.clone())
            })
        };
        let (jv, jtu) = run(usize::MAX, 1);
        let (jv1, jtu1) = run(1, 1);
        let (jv2, jtu2) = run(1, 2);
        assert!(
            jv1 == jv2 && jtu1 == jtu2,
            "the thread count changed a split pass"
        );
        let close = |a: &[f64], b: &[f64]| {
            let scale = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
            a.iter().zip(b).all(|(x, y)| (x - y).abs() <= 1e-12 * scale)
        };
        assert!(
            close(&jv, &jv1),
            "split forward differs from the unsplit one"
        );
        assert!(
            close(&jtu, &jtu1),
            "split adjoint differs from the unsplit one"
        );
    }

    #[test]
    fn gauss_newton_products_match_the_dense_normal_equations() {
        products_match_dense(&setup(1e-3));
    }

    #[test]
    fn gauss_newton_products_through_provot_match_the_dense_normal_equations() {
        products_match_dense(&provot_setup(1e-3));
    }

    fn products_match_dense(s: &Setup) {
        let fit = fitter(s);
        let frames = 40;
        let ne = fit.normal(&s.q, frames, &mut Sens::default()).unwrap();
        let mut mf = Mf::new(&fit);
        let mut work = Work::default();
        assert!(mf.linearise(&s.q, frames, &mut work));
        assert!((mf.cost() - ne.cost).abs() <= 1e-12 * ne.cost);
        let len = fit.len();
        let mut g = vec![0.0; len];
        mf.gradient(&mut g, &mut work);
        let v: Vec<f64> = (0..len).map(|a| noise(a, 41)).collect();
        let mut hv = vec![0.0; len];
        mf.hv(&v, 1, &mut hv, &mut work);
        let exact = &ne.h * DVector::from_column_slice(&v);
        let hs = exact.amax();
        let gs = ne.g.amax();
        for a in 0..len {
            assert!((exact[a] - hv[a]).abs() <= 1e-10 * hs, "Hv[{a}]");
            assert!((ne.g[a] - g[a]).abs() <= 1e-10 * gs, "g[{a}]");
        }
        // The θ columns the preconditioner uses are H's own.
        let cols = mf.theta_columns(&mut work);
        for a in 0..len {
            for c in 0..fit.theta() {
                let e = ne.h[(a, c)];
                assert!(
                    (e - cols[(a, c)]).abs() <= 1e-10 * hs.max(e.abs()),
                    "H[{a},{c}]"
                );
            }
        }
    }

    #[test]
    fn a_solve_deflated_by_earlier_steps_reaches_the_same_step_in_fewer_iterations() {
        let s = setup(1e-3);
        let fit = fitter(&s);
        let frames = 40;
        let mut mf = Mf::new(&fit);
        let mut work = Work::default();
        assert!(mf.linearise(&s.q, frames, &mut work));
        let len = fit.len();
        let mut g = vec![0.0; len];
        mf.gradient(&mut g, &mut work);
        let rhs: Vec<f64> = g.iter().map(|x| -x).collect();
        let cols = mf.theta_columns(&mut work);
        let scale = approx_diag(&mf, &cols);
        let held = vec![false; len];
        let lambda = 1e-6;
        let pre = Pre::new(&mf, &cols, &scale, &held, lambda);
        let set = CgSettings {
            tol: 1e-10,
            max_iterations: 2000,
        };
        let mut cg = CgWork::default();
        let mut plain = vec![0.0; len];
        let (its_plain, ok) = pcg(
            &mf, &pre, &scale, &held, lambda, &rhs, &mut plain, set, None, &mut cg, &mut work,
        );
        assert!(ok);
        // Earlier "steps": the solution seen through two perturbed copies, as the last steps
        // of a window approximate the next one.
        let recent: std::collections::VecDeque<Vec<f64>> = [3, 5]
            .iter()
            .map(|&salt| {
                (0..len)
                    .map(|a| plain[a] * (1.0 + 0.3 * noise(a, salt)))
                    .collect()
            })
            .collect();
        let d = step_deflation(&mf, &recent, &scale, &held, lambda, &mut work).unwrap();
        assert_eq!(d.dim(), 2);
        let mut deflated = vec![0.0; len];
        let (its_deflated, ok) = pcg(
            &mf,
            &pre,
            &scale,
            &held,
            lambda,
            &rhs,
            &mut deflated,
            set,
            Some(&d),
            &mut cg,
            &mut work,
        );
        assert!(ok);
        let scale_x = plain.iter().fold(0.0f64, |m, v| m.max(v.abs()));
        for a in 0..len {
            assert!((plain[a] - deflated[a]).abs() <= 1e-6 * scale_x, "x[{a}]");
        }
        assert!(
            its_deflated < its_plain,
            "deflated {its_deflated} against plain {its_plain} iterations"
        );
    }

    /// Guards the matrix-free Cramér–Rao bound (large scenes) against the dense one.
    #[test]
    fn the_matrix_free_bound_is_the_dense_one() {
        let s = setup(0.0);
        let fit = fitter(&s);
        let frames = 60;
        let sigma = 1e-3;
        let sd = cramer_rao_sd(&fit, &s.q, frames, sigma).unwrap();
        let ne = fit.normal(&s.q, frames, &mut Sens::default()).unwrap();
        let (cov, _) = super::super::uncertainty::covariance(&ne.h, sigma * sigma);
        let cov = super::super::uncertainty::physical(&cov, &fit.chain(&s.q));
        assert_eq!(sd.len(), fit.theta());
        for (a, sd) in sd.iter().enumerate() {
            // Variances settled to 0.1 %: standard deviations within 0.5 %.
            let dense = cov[(a, a)].sqrt();
            assert!(
                (sd / dense - 1.0).abs() <= 5e-3,
                "θ {a}: {sd} against {dense}"
            );
        }
    }

    /// Guards the pattern move's rule: doubling along the direction while the cost falls,
    /// keeping the best point, and leaving the iterate alone when the first trial does not gain.
    #[test]
    fn a_pattern_move_doubles_along_the_valley_while_the_cost_falls() {
        // A long valley along x with its floor's minimum at x = 10.
        let valley = |x: &mut [f64]| (x[0] - 10.0).powi(2) / 100.0 + x[1] * x[1];
        let mut at = vec![0.0, 0.0];
        let c0 = valley(&mut at.clone());
        let (c, evaluations) = pattern_move(&mut at, c0, &[1.0, 0.0], valley);
        // α = 1, 2, 4, 8 gain; 16 (x = 16, cost 0.36 > 0.04) does not.
        assert_eq!(at, vec![8.0, 0.0]);
        assert_eq!(evaluations, 5);
        assert_relative_eq!(c, 0.04, max_relative = 1e-12);
        let (c, evaluations) = pattern_move(&mut at, c, &[0.0, 1.0], valley);
        assert_eq!((at.clone(), evaluations), (vec![8.0, 0.0], 1));
        assert_relative_eq!(c, 0.04, max_relative = 1e-12);
        // A diverging model (+inf, NaN) is no gain either.
        let (_, evaluations) = pattern_move(&mut at, c, &[1.0, 0.0], |_| f64::NAN);
        assert_eq!((at, evaluations), (vec![8.0, 0.0], 1));
    }

    #[test]
    fn matrix_free_fit_reaches_the_dense_fits_estimate() {
        let s = setup(1e-3);
        let fit = fitter(&s);
        let set = LmSettings {
            max_iterations: 100,
            ftol: 1e-10,
            xtol: 1e-10,
            gtol: 1e-10,
            face_steps: true,
        };
        let config = super::super::Config::default();
        let mut qd = s.q.clone();
        let mut counts = Counts::default();
        let mut buf = Sens::default();
        let never = || false;
        super::super::grow_windows(&fit, &mut qd, &config, &mut |q, w| {
            fit::lm_stage(&fit, q, w, set, &mut counts, &mut buf, &never)
        })
        .unwrap();
        let mut qm = s.q.clone();
        let (mut mcounts, mut cgc) = (Counts::default(), CgCounts::default());
        let mut steps = Vec::new();
        let longest = fit.takes.iter().map(Take::frames).max().unwrap();
        let (end, windows) = super::super::grow_windows(&fit, &mut qm, &config, &mut |q, w| {
            super::stage(
                &fit,
                q,
                w,
                longest,
                set,
                &mut mcounts,
                &mut cgc,
                &mut steps,
                &never,
            )
        })
        .unwrap();
        let e = super::finish(
            &fit,
            qm,
            mcounts,
            cgc,
            end,
            windows,
            fit.takes
                .iter()
                .map(super::super::start::noise_level)
                .collect(),
            "test".into(),
            &steps,
        )
        .unwrap();
        let nt = fit.theta();
        let moved = (0..nt).map(|a| (qd[a] - s.q[a]).abs()).fold(0.0, f64::max);
        assert!(moved > 1e-3, "the dense fit did not move from its start");
        // The matrix-free fit stops when a step would move the estimate by less than 0.1
        // standard error (FINAL_CHI2): the same optimum within a fraction of its uncertainty.
        let pd = fit.params(&qd);
        for (a, u) in fit.unknowns.iter().enumerate() {
            let (m, d) = (e.params[u.slot], pd[u.slot]);
            assert!(
                (m - d).abs() <= 0.3 * e.stderr[a],
                "θ {a}: matrix-free {m}, dense {d}, standard error {}",
                e.stderr[a]
            );
        }
        // Standard errors against the dense inverse.
        let ne = fit.normal(&qd, 60, &mut Sens::default()).unwrap();
        let dof = (e.observed - e.variables) as f64;
        let (cov, _) = super::super::uncertainty::covariance(&ne.h, ne.cost / dof);
        let cov = super::super::uncertainty::physical(&cov, &fit.chain(&qd));
        for a in 0..nt {
            let sd = cov[(a, a)].sqrt();
            // At its own (slightly different) estimate.
            assert!(
                (e.stderr[a] - sd).abs() <= 1e-2 * sd,
                "stderr {a}: matrix-free {} dense {sd}",
                e.stderr[a]
            );
        }
        // At the same point, the CG solves are the dense inverse's θ block.
        let (hinv, _) = super::super::uncertainty::covariance(&ne.h, 1.0);
        let mut mf = Mf::new(&fit);
        let mut work = Work::default();
        assert!(mf.linearise(&qd, 60, &mut work));
        let exact = StderrStop {
            form: 0.0,
            ..STDERR_STOP
        };
        // Without and with the fit's last steps deflating the solves (exact on any subspace).
        assert!(!steps.is_empty(), "the last stage kept no step");
        for recycled in [&[][..], &steps[..]] {
            let inv = theta_inverse(&mf, exact, recycled, &mut CgCounts::default(), &mut work);
            for a in 0..nt {
                for b in 0..nt {
                    let scale = (hinv[(a, a)] * hinv[(b, b)]).sqrt();
                    assert!(
                        (inv[(a, b)] - hinv[(a, b)]).abs() <= 1e-6 * scale,
                        "H⁻¹[{a},{b}]: CG {} dense {} ({} steps)",
                        inv[(a, b)],
                        hinv[(a, b)],
                        recycled.len()
                    );
                }
            }
            // The default stop (the variances settled): variances within 1 % (standard errors
            // within 0.5 %), covariances within 0.1 of their scale (correlations within 0.1).
            let inv = theta_inverse(
                &mf,
                STDERR_STOP,
                recycled,
                &mut CgCounts::default(),
                &mut work,
            );
            for a in 0..nt {
                assert!((inv[(a, a)] / hinv[(a, a)] - 1.0).abs() <= 1e-2);
                for b in 0..nt {
                    let scale = (hinv[(a, a)] * hinv[(b, b)]).sqrt();
                    assert!((inv[(a, b)] - hinv[(a, b)]).abs() <= 0.1 * scale);
                }
            }
        }
    }
}
