//! Standard errors from the θ block of `H⁻¹` (deflated PCG solves), the Cramér–Rao bound of
//! large scenes, and the estimate's summary.

use nalgebra::DMatrix;

use super::super::fit::{Counts, Fitter, StageEnd};
use super::cg::CgCounts;
use super::operator::{Mf, Work};
use super::preconditioner::Pre;
use super::settings::{DENSE_MAX_COLUMNS, STDERR_CG_TOL, STDERR_DELAY, STDERR_FORM_TOL};
use super::stage::approx_diag;
use crate::linalg::deflation::Deflation;
use crate::output_error::line_profile;
use crate::output_error::uncertainty;

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
/// linearisation `mf` holds (`cols`: its θ columns, [`Mf::theta_columns`]), run together
/// (every product as wide as the solves still running: the passes read the stored
/// linearisation once for all of them). Columns whose solve did not converge are NaN, and so
/// are the `skip`ped ones (unknowns [`theta_undetermined`] found: `H x = e_k` has no solution
/// there, and the solve would only run out its iterations).
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
/// Also returned, per column whose solve did not converge (NaN elsewhere): its last variance
/// `e_kᵀx_j`, a lower bound on `e_kᵀH⁻¹e_k` (PCG from zero raises it monotonically), so a
/// standard error not computed can still be reported as at least that large; and each
/// converged solve's whole column `H⁻¹e_k` (every fit variable: the profile direction of
/// [`crate::output_error::line_profile`]).
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
    cols: &DMatrix<f64>,
    skip: &[bool],
    stop: StderrStop,
    recycled: &[Vec<f64>],
    cgc: &mut CgCounts,
    work: &mut Work,
) -> (DMatrix<f64>, Vec<f64>, Vec<Option<Vec<f64>>>) {
    let nt = mf.fit.theta();
    let mut out = DMatrix::from_element(nt, nt, f64::NAN);
    let mut at_least = vec![f64::NAN; nt];
    let mut columns = vec![None; nt];
    if nt == 0 {
        return (out, at_least, columns);
    }
    let scale = approx_diag(mf, cols);
    let held = vec![false; mf.fit.len()];
    // A tiny damping in the preconditioner only (the operator is H itself): hidden particles'
    // empty local blocks stay invertible.
    let pre = Pre::new(mf, cols, &scale, &held, 1e-12);
    let deflation = match recycled.is_empty() {
        true => None,
        false => Deflation::new(recycled, |v, k, out| mf.hv(v, k, out, work)),
    };
    debug_assert_eq!(skip.len(), nt, "one skip flag per unknown");
    let mut solves = BlockSolves::start(mf.fit.len(), skip, &pre, deflation.as_ref());
    let mut its = 0;
    while its < stop.max_iterations && solves.any_running() {
        its += 1;
        let running = solves.running();
        solves.multiply(mf, &running, work);
        solves.advance(&running, stop);
        solves.next_directions(&running, &pre, deflation.as_ref());
    }
    cgc.solves += skip.iter().filter(|s| !**s).count();
    cgc.iterations += its;
    for c in (0..nt).filter(|&c| !skip[c]) {
        if solves.done[c] {
            for a in 0..nt {
                out[(a, c)] = solves.x[a * nt + c];
            }
            columns[c] = Some((0..solves.len).map(|a| solves.x[a * nt + c]).collect());
        } else {
            cgc.unconverged += 1;
            // The current iterate's variance: the last one before a failure, or the
            // deflated start's when a column fails at once.
            at_least[c] = solves.x[c * nt + c];
        }
    }
    (out, at_least, columns)
}

/// The solves `H x_k = e_k` of [`theta_inverse`] as one block of PCG iterations: row-major
/// `len × w` buffers whose column k is the k-th solve, each column with its own step lengths
/// and stop.
struct BlockSolves {
    len: usize,
    w: usize,
    x: Vec<f64>,
    r: Vec<f64>,
    z: Vec<f64>,
    p: Vec<f64>,
    ap: Vec<f64>,
    /// The running columns' directions and products, packed (len × running).
    packed: Vec<f64>,
    packed_ap: Vec<f64>,
    /// One column's residual and preconditioned residual, and the deflation's buffer.
    rc: Vec<f64>,
    zc: Vec<f64>,
    column: Vec<f64>,
    /// The columns a deflated iteration projects.
    still: Vec<usize>,
    rz: Vec<f64>,
    done: Vec<bool>,
    failed: Vec<bool>,
    /// Each column's variance x_k after every iteration (its settling test).
    variance: Vec<Vec<f64>>,
}

impl BlockSolves {
    /// The first directions: residuals `e_k` (deflated), preconditioned; the `skip`ped columns
    /// count as done from the start.
    fn start(len: usize, skip: &[bool], pre: &Pre, deflation: Option<&Deflation>) -> Self {
        let w = skip.len();
        let mut s = BlockSolves {
            len,
            w,
            x: vec![0.0; len * w],
            r: vec![0.0; len * w],
            z: vec![0.0; len * w],
            p: vec![0.0; len * w],
            ap: vec![0.0; len * w],
            packed: vec![0.0; len * w],
            packed_ap: vec![0.0; len * w],
            rc: vec![0.0; len],
            zc: vec![0.0; len],
            column: Vec::with_capacity(len),
            still: (0..w).collect(),
            rz: Vec::new(),
            done: skip.to_vec(),
            failed: vec![false; w],
            variance: vec![Vec::new(); w],
        };
        for k in 0..w {
            s.r[k * w + k] = 1.0;
        }
        if let Some(d) = deflation {
            d.start_columns(&mut s.x, &mut s.r, w, &mut s.column);
        }
        s.precondition(pre);
        if let Some(d) = deflation {
            d.project_columns(&mut s.z, w, &s.still, &mut s.column);
        }
        s.p.copy_from_slice(&s.z);
        s.rz = (0..w).map(|c| column_dot(&s.r, &s.z, w, c)).collect();
        s
    }

    fn any_running(&self) -> bool {
        self.done.iter().zip(&self.failed).any(|(d, f)| !d && !f)
    }

    fn running(&self) -> Vec<usize> {
        (0..self.w)
            .filter(|&c| !self.done[c] && !self.failed[c])
            .collect()
    }

    /// `z = M⁻¹ r`, column by column.
    fn precondition(&mut self, pre: &Pre) {
        let (len, w) = (self.len, self.w);
        for c in 0..w {
            for a in 0..len {
                self.rc[a] = self.r[a * w + c];
            }
            pre.apply(&self.rc, &mut self.zc);
            for a in 0..len {
                self.z[a * w + c] = self.zc[a];
            }
        }
    }

    /// `ap = H p` on the running columns, in one product as wide as they are.
    fn multiply(&mut self, mf: &Mf<'_, '_>, running: &[usize], work: &mut Work) {
        let (len, w, nr) = (self.len, self.w, running.len());
        for a in 0..len {
            for (slot, &c) in running.iter().enumerate() {
                self.packed[a * nr + slot] = self.p[a * w + c];
            }
        }
        mf.hv(
            &self.packed[..len * nr],
            nr,
            &mut self.packed_ap[..len * nr],
            work,
        );
        for a in 0..len {
            for (slot, &c) in running.iter().enumerate() {
                self.ap[a * w + c] = self.packed_ap[a * nr + slot];
            }
        }
    }

    /// The step along each running column's direction, then its stop: the residual below
    /// `stop.residual` (`‖e_k‖` = 1: already relative), or the variance settled.
    fn advance(&mut self, running: &[usize], stop: StderrStop) {
        let (len, w) = (self.len, self.w);
        for &c in running {
            let pap = column_dot(&self.p, &self.ap, w, c);
            if pap.is_nan() || pap <= 0.0 {
                self.failed[c] = true;
                continue;
            }
            let alpha = self.rz[c] / pap;
            for a in 0..len {
                self.x[a * w + c] += alpha * self.p[a * w + c];
                self.r[a * w + c] -= alpha * self.ap[a * w + c];
            }
            let history = &mut self.variance[c];
            history.push(self.x[c * w + c]);
            let settled = stop.form > 0.0
                && history.len() > STDERR_DELAY
                && history[history.len() - 1] - history[history.len() - 1 - STDERR_DELAY]
                    <= stop.form * history[history.len() - 1];
            if settled || column_dot(&self.r, &self.r, w, c).sqrt() <= stop.residual {
                self.done[c] = true;
            }
        }
    }

    /// The next directions of the columns still running: `p = z + β p` from the new
    /// preconditioned (and deflated) residuals.
    fn next_directions(&mut self, running: &[usize], pre: &Pre, deflation: Option<&Deflation>) {
        let (len, w) = (self.len, self.w);
        self.precondition(pre);
        if let Some(d) = deflation {
            self.still.clear();
            self.still.extend(
                running
                    .iter()
                    .filter(|&&c| !self.done[c] && !self.failed[c]),
            );
            d.project_columns(&mut self.z, w, &self.still, &mut self.column);
        }
        for &c in running {
            if self.done[c] || self.failed[c] {
                continue;
            }
            let rz_new = column_dot(&self.r, &self.z, w, c);
            let beta = rz_new / self.rz[c];
            self.rz[c] = rz_new;
            for a in 0..len {
                self.p[a * w + c] = self.z[a * w + c] + beta * self.p[a * w + c];
            }
        }
    }
}

/// `uᵀv` of column c of two row-major `· × w` blocks.
fn column_dot(u: &[f64], v: &[f64], w: usize, c: usize) -> f64 {
    (0..u.len() / w).map(|a| u[a * w + c] * v[a * w + c]).sum()
}

/// Which of the `nt` unknowns the directions `undetermined` carry.
fn carried(nt: usize, undetermined: &[Vec<usize>]) -> Vec<bool> {
    let mut skip = vec![false; nt];
    for &a in undetermined.iter().flatten() {
        skip[a] = true;
    }
    skip
}

/// The directions of θ the data do not determine even with every initial state known: the
/// eigen-test of the dense path ([`uncertainty::covariance`]: eigenvalues of the equilibrated
/// matrix below [`uncertainty::RANK_TOL`] of the largest, named by the unknowns carrying ≥ 0.3
/// of the unit vector) on the θ block `H_θθ` of the θ columns `cols` (exact; indices into θ).
///
/// Such a direction is one of the whole fit: `vᵀH_θθv = ‖W J_θ v‖² = 0` makes `J_θ v = 0` on
/// every observed coordinate, so `H (v, 0) = 0`. The converse does not hold: a parameter the
/// initial states alone can compensate is undetermined with `H_θθ` regular; finding it takes
/// the profiled information `H_θθ − H_θs H_ss⁻¹ H_sθ`, nθ solves with the states' block that
/// converge slowly on large scenes (BENCHMARKS.md, "The bound is exact"), which the fit does not
/// run. The estimate's note says so. The eigenvalues are compared with the θ block's largest,
/// not the whole H's, which is at least as large: a direction within a factor of that
/// difference of the threshold may be named by the dense path and not here.
pub(crate) fn theta_undetermined(cols: &DMatrix<f64>) -> Vec<Vec<usize>> {
    let nt = cols.ncols();
    if nt == 0 {
        return Vec::new();
    }
    let block = cols.rows(0, nt);
    let sym = (block + block.transpose()) * 0.5;
    uncertainty::covariance(&sym, 1.0).1
}

/// Marks the unknowns of `undetermined` as not determined in a physical covariance: an
/// infinite variance and zero covariances (their CG solves were skipped). Their standard
/// errors (∞), intervals and correlations (0) are then the dense path's; its covariance
/// matrix keeps the pseudo-inverse's finite covariances instead.
pub(crate) fn mark_undetermined(covariance: &mut DMatrix<f64>, undetermined: &[Vec<usize>]) {
    let n = covariance.nrows();
    for &a in undetermined.iter().flatten() {
        for b in 0..n {
            covariance[(a, b)] = 0.0;
            covariance[(b, a)] = 0.0;
        }
        covariance[(a, a)] = f64::INFINITY;
    }
}

/// The Cramér–Rao standard deviations (physical units) of the unknowns at `q` (the truth) for
/// Gaussian noise `sigma` (m) per unit-weight coordinate over `window` frames: `σ² [H⁻¹]_θθ`
/// by [`theta_inverse`] (its default stop: variances to ~0.1 %; NaN where a solve did not
/// settle, ∞ for an unknown [`theta_undetermined`] names), the matrix-free counterpart of the
/// dense bound of [`crate::output_error::cramer_rao_takes`].
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
    let cols = mf.theta_columns(&mut work);
    let undetermined = theta_undetermined(&cols);
    let skip = carried(fitter.theta(), &undetermined);
    let (inv, _, _) = theta_inverse(
        &mf,
        &cols,
        &skip,
        STDERR_STOP,
        &[],
        &mut CgCounts::default(),
        &mut work,
    );
    let mut cov = theta_covariance(&inv, sigma * sigma, &fitter.chain(q));
    mark_undetermined(&mut cov, &undetermined);
    Ok((0..fitter.theta()).map(|a| cov[(a, a)].sqrt()).collect())
}

/// `σ² [H⁻¹]_θθ` in physical units from the θ block `inv` of [`theta_inverse`] (internal
/// coordinates, symmetrised; `chain` the internal-to-physical derivatives).
pub(super) fn theta_covariance(inv: &DMatrix<f64>, sigma2: f64, chain: &[f64]) -> DMatrix<f64> {
    let cov_q = DMatrix::from_fn(inv.nrows(), inv.ncols(), |a, b| {
        let v = 0.5 * (inv[(a, b)] + inv[(b, a)]);
        sigma2 * v
    });
    crate::output_error::uncertainty::physical(&cov_q, chain)
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
    check: Option<line_profile::Measure>,
    halt: &dyn Fn() -> bool,
) -> Result<crate::output_error::Estimate, crate::error::CostError> {
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
    let observed: usize = fitter
        .takes
        .iter()
        .map(crate::output_error::Take::observed)
        .sum();
    let variables = fitter.len();
    let dof = observed.saturating_sub(variables).max(1);
    let sigma2 = cost / dof as f64;
    let dim = fitter.theta();
    let cols = mf.theta_columns(&mut work);
    let undetermined = theta_undetermined(&cols);
    let skip = carried(dim, &undetermined);
    let (inv, at_least, columns) = theta_inverse(
        &mf,
        &cols,
        &skip,
        STDERR_STOP,
        last_steps,
        &mut cgc,
        &mut work,
    );
    let chain = fitter.chain(&q);
    let stderr_at_least = at_least
        .iter()
        .zip(&chain)
        .map(|(v, c)| c.abs() * (sigma2 * v).sqrt())
        .collect();
    let mut covariance = theta_covariance(&inv, sigma2, &chain);
    mark_undetermined(&mut covariance, &undetermined);
    let correlation = crate::output_error::uncertainty::correlation(&covariance);
    let params = fitter.params(&q);
    let (stderr, mut intervals) =
        crate::output_error::summary::spread(fitter, &params, &covariance);
    let at = line_profile::Optimum {
        q: &q,
        cost,
        sigma2,
        window: longest,
    };
    let column = |a: usize| Some(columns[a].as_ref()?.iter().map(|v| sigma2 * v).collect());
    let (widened, interval_kind) = line_profile::check_intervals(
        fitter,
        &at,
        check,
        column,
        halt,
        &mut intervals,
        &mut counts,
    );
    let states = crate::output_error::summary::take_states(fitter, &q);
    // Solves that did not settle, the undetermined unknowns' apart (those are reported as such).
    let missing = (0..dim).filter(|&a| covariance[(a, a)].is_nan()).count();
    let note = format!(
        "{start}; matrix-free Gauss–Newton ({variables} variables > {DENSE_MAX_COLUMNS} dense \
         columns): {} CG solves, {} iterations, {} short of tolerance; standard errors from \
         {dim} CG solves of H{}; undetermined directions from the parameters' own block of H \
         (trade-offs with the initial states alone not tested)",
        cgc.solves,
        cgc.iterations,
        cgc.unconverged,
        if missing > 0 {
            format!(" ({missing} did not converge: those are NaN, not computed)")
        } else {
            String::new()
        }
    );
    Ok(crate::output_error::Estimate {
        genome: q[..dim].to_vec(),
        params,
        states,
        cost,
        sigma: sigma2.sqrt(),
        noise_level,
        observed,
        variables,
        stderr,
        stderr_at_least,
        intervals,
        widened,
        interval_kind,
        covariance,
        correlation,
        undetermined: undetermined
            .iter()
            .map(|d| d.iter().map(|&a| fitter.unknowns[a].name.clone()).collect())
            .collect(),
        converged: end == StageEnd::Converged,
        above_noise: false,
        end: crate::output_error::summary::end_text(end),
        iterations: counts.iterations,
        evaluations: counts.evaluations,
        windows,
        start: note,
        loss: crate::output_error::Loss::Squared,
        downweighted: 0,
    })
}
