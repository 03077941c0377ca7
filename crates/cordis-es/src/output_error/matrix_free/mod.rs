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
//! iterate by the nonlinear rollout ([`operator::Lin`]): forward and adjoint then read the same
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
//! preconditioner's), Nielsen λ rule and projection as [`crate::output_error::fit::lm_stage`], with what a
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
//! - **pattern moves** ([`stage::pattern_move`]): after an accepted step, one more move along the
//!   sum of the last two, doubled while the cost falls: consecutive steps zig-zag across a
//!   long curved valley (the cloth's structural/bending one), their sum points along it;
//! - **statistical stopping**: a window stops when a step lowers the cost by less than
//!   `χ² σ̂²` (the estimate moves by less than √χ² standard errors): [`FINAL_CHI2`] = 0.01 on
//!   the last window, [`WINDOW_CHI2`] = 1 (or [`WINDOW_FTOL`], or [`WINDOW_ITERATIONS`]) on the
//!   others, whose only job is to bring the next into the basin. On the last window the
//!   criterion is confirmed by the undamped Gauss–Newton decrement `gᵀH⁻¹g ≤ χ² σ̂²` (one CG
//!   solve at λ ≈ 0, stopped once its monotone model decrease exceeds the criterion or has
//!   settled below it): a damped or truncated step gains little along a poorly determined
//!   parameter however far the optimum is. The dense criteria
//!   (ftol 1e-10) spend most iterations creeping along parameters held at their bounds;
//! - the preconditioner's θ columns refreshed every [`COLUMNS_EVERY`] accepted steps.
//!
//! # What it reports
//!
//! Standard errors for θ: the θ block of `H⁻¹` by nθ PCG solves `H x_k = e_k` (run together,
//! as wide as the solves still running, deflated by the last window's last accepted steps),
//! scaled by `σ̂²`, each stopped when its variance has settled
//! ([`standard_errors::theta_inverse`]). A solve that does not converge leaves its unknown's
//! standard error NaN (not computed), never a guessed number. The undetermined directions are
//! those of the θ block `H_θθ` ([`standard_errors::theta_undetermined`]: each is one of the
//! full system; a parameter only the initial states compensate is not found without an
//! eigendecomposition of a 6,000-wide H or the profiled information, and the note says so).

// Index loops mirror the row-major `(3i + c)·w + col` layout the passes address.
#![allow(clippy::needless_range_loop)]

mod cg;
mod operator;
mod passes;
mod preconditioner;
mod settings;
mod stage;
mod standard_errors;
#[cfg(test)]
mod tests;

pub(crate) use cg::CgCounts;
pub(crate) use operator::{Mf, Work};
pub use settings::{
    COLUMNS_EVERY, DEFLATE_STEPS, DENSE_MAX_COLUMNS, FINAL_CHI2, PATTERN_MAX, SPLIT_MIN_SPRINGS,
    STDERR_CG_TOL, STDERR_DELAY, STDERR_FORM_TOL, STEP_CG_ITERATIONS, STEP_CG_TOL, STEP_CG_TOL_MAX,
    WINDOW_CHI2, WINDOW_FTOL, WINDOW_ITERATIONS,
};
pub(crate) use stage::stage;
pub(crate) use standard_errors::{cramer_rao_sd, finish};

use super::tangent::spring::LINK;
use super::tangent::{angle, plane, provot};

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
