//! One window's Levenberg–Marquardt stage with steps by PCG, and the growing-window driver.

use std::collections::VecDeque;

use nalgebra::{DMatrix, DVector};

use super::super::fit::{Counts, Fitter, LmSettings, StageEnd};
use super::cg::{damped_hv, pcg, CgCounts, CgSettings, CgWork};
use super::operator::{Mf, Work};
use super::preconditioner::Pre;
use super::settings::{
    COLUMNS_EVERY, DEFLATE_STEPS, FINAL_CHI2, PATTERN_MAX, STDERR_DELAY, STEP_CG_ITERATIONS,
    STEP_CG_TOL, STEP_CG_TOL_MAX, WINDOW_CHI2, WINDOW_FTOL, WINDOW_ITERATIONS,
};
use crate::linalg::deflation::Deflation;
use crate::linalg::dot;

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
pub(super) fn pattern_move(
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
pub(super) fn step_deflation(
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

/// Diagonal of the preconditioner's H (exact for θ, the local blocks for states): the
/// Marquardt scaling and gtol's column norms.
pub(super) fn approx_diag(mf: &Mf<'_, '_>, cols: &DMatrix<f64>) -> Vec<f64> {
    let nt = mf.fit.theta();
    let mut d: Vec<f64> = (0..nt).map(|a| cols[(a, a)]).collect();
    for lin in &mf.lins {
        for blk in lin.local.chunks(36) {
            d.extend((0..6).map(|a| blk[7 * a]));
        }
    }
    d
}

/// How one window's stage stops: the Levenberg–Marquardt settings, the CG settings of its
/// steps, and the statistical criterion (`chi2` σ̂², `window_ftol`, and whether an undamped
/// Gauss–Newton solve must confirm it).
#[derive(Clone, Copy, Debug)]
pub(crate) struct StageRule {
    pub window: usize,
    pub set: LmSettings,
    pub cgset: CgSettings,
    pub chi2: f64,
    pub window_ftol: f64,
    pub verify_newton: bool,
}

/// What one window's stage carries from iteration to iteration: the gradient and cost at the
/// iterate, the preconditioner's θ columns and the Marquardt scaling, Nielsen's λ and ν, and
/// the buffers of the step's solve and trials.
pub(super) struct Lm {
    g: Vec<f64>,
    cols: DMatrix<f64>,
    diag: Vec<f64>,
    scale: Vec<f64>,
    cost: f64,
    lambda: f64,
    nu: f64,
    cg: CgWork,
    delta: Vec<f64>,
    hstep: Vec<f64>,
    sens: crate::output_error::tangent::Sens,
    g0norm: Option<f64>,
    accepted: usize,
    /// Observed coordinates in the window less the variables: σ̂² = cost / dof.
    dof: f64,
}

impl Lm {
    /// At a freshly linearised iterate.
    pub(super) fn new(mf: &Mf<'_, '_>, work: &mut Work) -> Self {
        let len = mf.fit.len();
        let mut g = vec![0.0; len];
        mf.gradient(&mut g, work);
        let cols = mf.theta_columns(work);
        let diag = approx_diag(mf, &cols);
        Lm {
            g,
            scale: diag.clone(),
            diag,
            cols,
            cost: mf.cost(),
            lambda: 1e-3,
            nu: 2.0,
            cg: CgWork::default(),
            delta: vec![0.0; len],
            hstep: vec![0.0; len],
            sens: Default::default(),
            g0norm: None,
            accepted: 0,
            dof: mf
                .lins
                .iter()
                .map(|l| l.observed)
                .sum::<usize>()
                .saturating_sub(len)
                .max(1) as f64,
        }
    }

    /// The noise variance the cost implies, σ̂² (the window's observations are fixed).
    fn sigma2(&self) -> f64 {
        self.cost / self.dof
    }

    /// A rejected step: λ grows (Nielsen); true when it has grown past any use.
    fn reject(&mut self) -> bool {
        self.lambda *= self.nu;
        self.nu *= 2.0;
        self.lambda > 1e20
    }

    /// The inexact Newton forcing (Eisenstat–Walker's choice 2 flavour): loose solves far from
    /// the optimum, down to `cgset.tol` as the gradient falls.
    fn forcing(&mut self, cgset: CgSettings) -> CgSettings {
        let gnorm = dot(&self.g, &self.g).sqrt();
        let g0 = *self.g0norm.get_or_insert(gnorm);
        CgSettings {
            tol: (0.5 * (gnorm / g0).sqrt()).clamp(cgset.tol, STEP_CG_TOL_MAX),
            ..cgset
        }
    }

    /// The damped step into `self.delta`; returns whether its CG solve converged.
    ///
    /// A coordinate on its bound whose gradient points in may still be pushed out by the
    /// coupled step (the cloth's bending stiffness, traded against the structural one):
    /// projected, that step raised the cost by 10-10^4 σ̂² and sent λ up, three solves a time
    /// (BENCHMARKS, "Large scenes"). Such a coordinate is held and the step solved again in the
    /// face of the box, once.
    #[allow(clippy::too_many_arguments)]
    fn solve_step(
        &mut self,
        mf: &Mf<'_, '_>,
        q: &[f64],
        held: &mut [bool],
        forcing: CgSettings,
        recent: &VecDeque<Vec<f64>>,
        cgc: &mut CgCounts,
        work: &mut Work,
    ) -> bool {
        let rhs: Vec<f64> = self.g.iter().map(|x| -x).collect();
        let mut ok = false;
        for _ in 0..2 {
            let pre = Pre::new(mf, &self.cols, &self.scale, held, self.lambda);
            let deflation = step_deflation(mf, recent, &self.scale, held, self.lambda, work);
            let (its, conv) = pcg(
                mf,
                &pre,
                &self.scale,
                held,
                self.lambda,
                &rhs,
                &mut self.delta,
                forcing,
                deflation.as_ref(),
                &mut self.cg,
                work,
                &mut |_| false,
            );
            cgc.solves += 1;
            cgc.iterations += its;
            ok = conv;
            let pushed = mf.fit.pushed_out(q, &self.delta, held);
            if pushed.is_empty() {
                break;
            }
            for a in pushed {
                held[a] = true;
            }
        }
        ok
    }

    /// The step, then (if it raises the cost) its halves, into `trial`; returns the trial's
    /// cost and how many times the step was shortened. A rejected Gauss–Newton step is usually
    /// right in direction and too long, and a cost evaluation (one simulation) is far cheaper
    /// than the CG solve at a larger λ.
    ///
    /// A step leaving the box is first tried projected (it usually gains); if that fails, its
    /// halves are tried cut at the box (the fraction f_b that lands the first θ coordinate on
    /// its bound, then f_b/2) rather than projected: a projected step changes direction, and
    /// along the poorly determined pairs (the cloth's structural and bending stiffnesses) the
    /// projected halves raised the cost by 10²–10⁴ σ̂² and sent λ up again and again
    /// (BENCHMARKS, "Large scenes"). On its bound the coordinate is held at the next iterate if
    /// the gradient pushes out.
    fn backtrack(
        &mut self,
        fit: &Fitter<'_>,
        q: &[f64],
        window: usize,
        counts: &mut Counts,
        trial: &mut [f64],
    ) -> (f64, usize) {
        let to_box = fit.fraction_to_bounds(q, &self.delta);
        let cut = to_box < 1.0 && to_box > MIN_CUT;
        let mut c = f64::INFINITY;
        let mut shrunk = 0;
        for t in 0..=BACKTRACK {
            let f = match (t, cut) {
                (0, _) | (_, false) => 0.5f64.powi(t as i32),
                (t, true) => to_box * 0.5f64.powi(t as i32 - 1),
            };
            for a in 0..q.len() {
                trial[a] = q[a] + f * self.delta[a];
            }
            fit.project(trial);
            counts.evaluations += 1;
            c = fit.cost(trial, window, &mut self.sens);
            shrunk = t;
            if c < self.cost {
                break;
            }
        }
        (c, shrunk)
    }

    /// Nielsen's λ rule after a step that lowered the cost to `c` against the model's
    /// `predicted` decrease; a shortened step counts as a rejection for λ.
    fn adapt_lambda(&mut self, c: f64, predicted: f64, shrunk: usize) {
        if shrunk > 0 {
            // The full step failed: damp the next one as a rejection would.
            self.lambda *= self.nu;
            self.nu *= 2.0;
        }
        let rho = if predicted > 0.0 {
            (self.cost - c) / predicted
        } else {
            0.0
        };
        if shrunk == 0 {
            self.lambda *= (1.0 - (2.0 * rho - 1.0).powi(3)).max(1.0 / 3.0);
            self.nu = 2.0;
        }
    }

    /// Moves to the accepted point `q`: the gradient and cost there, the θ columns refreshed
    /// every [`COLUMNS_EVERY`] accepted steps (they only precondition and scale, and cost
    /// nθ-wide passes, ~nθ/3 CG iterations), the scaling widened. False if the model diverged.
    fn relinearise(
        &mut self,
        mf: &mut Mf<'_, '_>,
        q: &[f64],
        window: usize,
        counts: &mut Counts,
        work: &mut Work,
    ) -> bool {
        counts.evaluations += 1;
        if !mf.linearise(q, window, work) {
            return false;
        }
        self.cost = mf.cost();
        mf.gradient(&mut self.g, work);
        self.accepted += 1;
        if self.accepted % COLUMNS_EVERY == 0 {
            self.cols = mf.theta_columns(work);
            self.diag = approx_diag(mf, &self.cols);
        }
        for (s, d) in self.scale.iter_mut().zip(&self.diag) {
            *s = s.max(*d);
        }
        true
    }

    /// Whether the undamped Gauss–Newton step from `q` would lower the cost by at most
    /// `chi2 σ̂²`: a damped or truncated step can gain little far from the optimum (along a
    /// poorly determined parameter λD dominates), so the statistical criterion holds only when
    /// the undamped step would gain as little.
    ///
    /// The model decrease of CG's iterate, `D_j = -gᵀx_j`, rises monotonically to the
    /// Newton decrement `gᵀH⁻¹g` (`D_j = x_jᵀHx_j` since the residual is orthogonal to the
    /// iterate, with or without deflation). So the solve stops as soon as `D_j` exceeds the
    /// criterion (proven: more to gain), when its residual converges (`D_j` is the decrement),
    /// or when `D_j` has settled below it: `D_j + (D_j − D_{j−d}) ≤ chi2 σ̂²` with `d` =
    /// [`STDERR_DELAY`] — what is left of the decrement, `‖x − x_j‖²_H`, estimated by its last
    /// `d` terms as Strakoš and Tichý's delayed estimate does for the standard errors
    /// ([`super::standard_errors::theta_inverse`]), must not carry `D` over the criterion.
    /// Why: on the 32 × 32 cloth (seed 5) every confirmation ran its 300 iterations short of
    /// the residual tolerance with `D` settled at 0–0.8 % of the criterion, eight times in a
    /// row, and the fit ended on its budget after 248 s (BENCHMARKS.md, "Settled decrements").
    pub(super) fn newton_confirms(
        &mut self,
        mf: &Mf<'_, '_>,
        q: &[f64],
        chi2: f64,
        recent: &VecDeque<Vec<f64>>,
        cgc: &mut CgCounts,
        work: &mut Work,
    ) -> bool {
        let fit = mf.fit;
        let limit = chi2 * self.sigma2();
        let held = fit.held(q, &DVector::from_column_slice(&self.g));
        let pre = Pre::new(mf, &self.cols, &self.scale, &held, NEWTON_LAMBDA);
        let rhs: Vec<f64> = self.g.iter().map(|x| -x).collect();
        let deflation = step_deflation(mf, recent, &self.scale, &held, NEWTON_LAMBDA, work);
        let mut decrements: Vec<f64> = Vec::new();
        let mut verdict = None;
        let g = &self.g;
        let (its, ok) = pcg(
            mf,
            &pre,
            &self.scale,
            &held,
            NEWTON_LAMBDA,
            &rhs,
            &mut self.delta,
            NEWTON_CG,
            deflation.as_ref(),
            &mut self.cg,
            work,
            &mut |x| {
                let d = -dot(g, x);
                decrements.push(d);
                let j = decrements.len();
                verdict = if d > limit || d.is_nan() {
                    Some(false)
                } else if j > STDERR_DELAY && 2.0 * d - decrements[j - 1 - STDERR_DELAY] <= limit {
                    Some(true)
                } else {
                    None
                };
                verdict.is_some()
            },
        );
        cgc.solves += 1;
        cgc.iterations += its;
        let decrement = -dot(&self.g, &self.delta);
        if ok {
            return decrement.is_finite() && decrement <= limit;
        }
        if verdict.is_none() {
            cgc.unconverged += 1;
        }
        verdict == Some(true)
    }
}

/// Keeps `step` as the newest of the last [`DEFLATE_STEPS`] accepted steps (reusing the
/// oldest's buffer).
fn remember(recent: &mut VecDeque<Vec<f64>>, step: &[f64]) {
    let mut kept = if recent.len() == DEFLATE_STEPS {
        recent.pop_front().unwrap_or_default()
    } else {
        Vec::new()
    };
    kept.clear();
    kept.extend_from_slice(step);
    recent.push_back(kept);
}

/// The matrix-free counterpart of [`crate::output_error::fit::lm_stage`]: the same Marquardt
/// scaling, Nielsen λ rule, projection and tolerances; steps by PCG, each followed by a pattern
/// move ([`pattern_move`]); the statistical stop of `rule` (module docs). `recent` ends with
/// the window's last accepted steps.
#[allow(clippy::too_many_arguments)]
pub(crate) fn lm_stage(
    mf: &mut Mf<'_, '_>,
    q: &mut [f64],
    rule: StageRule,
    counts: &mut Counts,
    cgc: &mut CgCounts,
    recent: &mut VecDeque<Vec<f64>>,
    work: &mut Work,
    halt: &dyn Fn() -> bool,
) -> StageEnd {
    let (fit, window, set) = (mf.fit, rule.window, rule.set);
    let len = fit.len();
    counts.evaluations += 1;
    if !mf.linearise(q, window, work) {
        return StageEnd::Diverged;
    }
    let mut lm = Lm::new(mf, work);
    let floor = fit.rounding_floor(window);
    let mut trial = vec![0.0; len];
    let mut step = vec![0.0; len];
    recent.clear();
    for _ in 0..set.max_iterations {
        if halt() {
            return StageEnd::Interrupted;
        }
        counts.iterations += 1;
        if lm.cost <= floor {
            return StageEnd::Converged;
        }
        let mut held = fit.held(q, &DVector::from_column_slice(&lm.g));
        let gmax = (0..len)
            .filter(|&a| !held[a] && lm.diag[a] > 0.0)
            .map(|a| lm.g[a].abs() / (lm.diag[a] * lm.cost).sqrt())
            .fold(0.0, f64::max);
        if gmax <= set.gtol {
            return StageEnd::Converged;
        }
        let forcing = lm.forcing(rule.cgset);
        let ok = lm.solve_step(mf, q, &mut held, forcing, recent, cgc, work);
        cgc.unconverged += usize::from(!ok);
        if lm.delta.iter().any(|v| !v.is_finite()) {
            if lm.reject() {
                return StageEnd::Stalled;
            }
            continue;
        }
        let (mut c, shrunk) = lm.backtrack(fit, q, window, counts, &mut trial);
        for a in 0..len {
            step[a] = trial[a] - q[a];
        }
        mf.hv(&step, 1, &mut lm.hstep, work);
        let predicted = -(2.0 * dot(&lm.g, &step) + dot(&step, &lm.hstep));
        if c >= lm.cost || c.is_nan() {
            if lm.reject() {
                return StageEnd::Stalled;
            }
            continue;
        }
        lm.adapt_lambda(c, predicted, shrunk);
        if let Some(before) = recent.back() {
            let d: Vec<f64> = step.iter().zip(before).map(|(a, b)| a + b).collect();
            let sens = &mut lm.sens;
            let (moved, evaluations) = pattern_move(&mut trial, c, &d, |x| {
                fit.project(x);
                fit.cost(x, window, sens)
            });
            counts.evaluations += evaluations;
            c = moved;
            for a in 0..len {
                step[a] = trial[a] - q[a];
            }
        }
        // The stop rules see the whole move, the pattern's gain included; λ above judged the
        // Gauss–Newton step alone (its model's prediction).
        let cost = lm.cost;
        let reduction = cost - c;
        let qnorm = dot(q, q).sqrt();
        let small_step = dot(&step, &step).sqrt() <= set.xtol * (set.xtol + qnorm);
        let small_gain = (reduction <= set.ftol * cost && predicted <= set.ftol * cost)
            || (reduction <= rule.window_ftol * cost && predicted <= rule.window_ftol * cost);
        // The statistical criterion (module docs): a step that lowers the cost by less than
        // `chi2` σ̂² moves the estimate by less than √chi2 standard errors.
        let s2 = lm.sigma2();
        let chi2_gain = reduction <= rule.chi2 * s2 && predicted <= rule.chi2 * s2;
        q.copy_from_slice(&trial);
        remember(recent, &step);
        if !lm.relinearise(mf, q, window, counts, work) {
            return StageEnd::Diverged;
        }
        if small_step || small_gain {
            return StageEnd::Converged;
        }
        if chi2_gain {
            if !rule.verify_newton {
                return StageEnd::Converged;
            }
            if lm.newton_confirms(mf, q, rule.chi2, recent, cgc, work) {
                return StageEnd::Converged;
            }
            // Go on with near-Gauss–Newton steps.
            lm.lambda = lm.lambda.min(1e-6);
            lm.nu = 2.0;
        }
    }
    StageEnd::Budget
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
    let mut recent = VecDeque::new();
    let rule = StageRule {
        window: w,
        set,
        cgset: step_cg,
        chi2,
        window_ftol: wftol,
        verify_newton: last,
    };
    let end = lm_stage(&mut mf, q, rule, counts, cgc, &mut recent, &mut work, halt);
    *steps = recent.into();
    end
}
