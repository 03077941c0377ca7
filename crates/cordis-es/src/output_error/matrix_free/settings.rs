//! The matrix-free fit's tuning constants, and why each has its value.

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

/// Relative residual of the CG solve of each Levenberg–Marquardt step: an inexact
/// Gauss–Newton step (the λ rule and the cost test still decide), since the step's accuracy
/// beyond this costs CG iterations (each about two simulations) without better steps.
pub const STEP_CG_TOL: f64 = 1e-3;

/// A window stops when a step lowers the cost by less than this many σ̂² (the estimate moves
/// by less than √· standard errors): intermediate windows only have to bring the next into the
/// basin (1 standard error), the last stops at 0.1 standard error. On the cloth the dense
/// criteria (ftol 1e-10) spend most iterations creeping along poorly determined dampings.
pub const WINDOW_CHI2: f64 = 1.0;

/// The last window's criterion: a step gaining less than this many σ̂² moves the estimate by
/// less than 0.1 standard error.
pub const FINAL_CHI2: f64 = 1e-2;

/// Relative residual of the standard-error solves `H x = e_k`: the variances to ~4 digits.
pub const STDERR_CG_TOL: f64 = 1e-6;

/// Or a standard-error solve stops when its variance grew by less than this fraction over the
/// last [`STDERR_DELAY`] iterations ([`super::standard_errors::theta_inverse`]): standard
/// errors to ~0.05 %, correlations to ~3 %.
pub const STDERR_FORM_TOL: f64 = 1e-3;

/// The iterations over which that growth is measured (Strakoš and Tichý's delay).
pub const STDERR_DELAY: usize = 10;

/// The loosest relative residual of a step's CG solve (far from the optimum).
pub const STEP_CG_TOL_MAX: f64 = 0.1;

/// Iteration budget and relative cost tolerance of every window but the last (they only
/// bring the next into the basin).
pub const WINDOW_ITERATIONS: usize = 10;

/// Relative cost gain below which an intermediate window stops.
pub const WINDOW_FTOL: f64 = 1e-4;

/// Iterations of a step's CG solve: beyond, the (truncated, still descending) step is taken.
pub const STEP_CG_ITERATIONS: usize = 80;

/// Accepted steps between refreshes of the preconditioner's θ columns.
pub const COLUMNS_EVERY: usize = 3;

/// Accepted steps of a window kept to deflate the next solves ([`crate::linalg::deflation`]).
pub const DEFLATE_STEPS: usize = 4;

/// The longest pattern move tried, in multiples of the last two steps' sum
/// ([`super::stage::pattern_move`]).
pub const PATTERN_MAX: f64 = 64.0;
