//! `levenberg-marquardt`: the short cost minimised as a nonlinear least-squares problem, what
//! `scipy.optimize.least_squares(method="lm")` does, for scenes the exact solvers refuse
//! (muscles' `tanh`, Provot's limit, ranges).
//!
//! The short cost is `C(z) = |r(z)|²` with `r` the residual vector of
//! [`crate::cost::Objective::residuals`] (3 per predicted frame and free particle); the static
//! cost ([`crate::cost::CostKind::Static`], equilibrium frames) is minimised the same way. Each
//! iteration works in the search space's internal coordinates `z` ([`crate::problem::space`]: log for
//! wide positive boxes, so a relative change of a stiffness is one step):
//!
//! - **Jacobian** by forward differences, column j from `r(z + h_j e_j)` with
//!   `h_j = √ε · max(|z_j|, w_j)` (`w_j` the internal box width, ε the f64 epsilon), stepping
//!   backwards when `z_j + h_j` would leave the box. The n columns are one population,
//!   evaluated in parallel; a column whose evaluation diverged is 0 for that iteration.
//! - **Step**: the damped normal equations `(JᵀJ + λ D) δ = -Jᵀr` (Cholesky), with Marquardt's
//!   scaling `D = diag(JᵀJ)` (each entry the largest seen since the start, as MINPACK does).
//! - **Bounds by projection**: a coordinate on a bound whose gradient points out of the box is
//!   held for the iteration (removed from the system); the step of the others is clamped into
//!   the box. An optimum on a bound is then reached and stays there.
//! - **Accept/reject**: a trial point is accepted when its cost is finite and lower; a diverged
//!   candidate (+inf) is a rejected step. λ follows Nielsen's rule: on acceptance
//!   `λ ← λ · max(1/3, 1 - (2ρ - 1)³)` with ρ the ratio of actual to predicted reduction, on
//!   rejection `λ ← λ ν, ν ← 2ν`. A rejection keeps the Jacobian: the next iteration costs
//!   one evaluation.
//! - **Convergence**, with scipy's tolerances (default 1e-8 each): `ftol` when an accepted
//!   step reduced the cost by less than `ftol · C` and predicted no more; `xtol` when the step
//!   `|Δz| ≤ xtol (xtol + |z|)`; `gtol` when every free column's cosine with the residual
//!   `|J_jᵀ r| / (|J_j| |r|)` is at most `gtol`; also when the cost is 0, after
//!   `max_iterations`, or when λ has grown beyond 1e20 (no descent left).
//!
//! The run starts where every strategy of this crate starts (`common::start_genome`): rest
//! lengths and cosines at their observed means, an unknown's `init` when it has one, otherwise
//! the centre of its internal box. Measured on `cordis-bench pareto` (noiseless), that start
//! against the plain box centre: muscle 45 against 67 evaluations to 0.01 %, cloth 27 against
//! 308 to 0.656 %. A convergence at a cost above
//! `small · A`, where `A` is [`crate::cost::Objective::acceleration_cost`] (what a model with no
//! force would miss), is taken for a local minimum: the next generation restarts from a point
//! drawn uniformly in the internal box from [`crate::run::rng::stream`]`(seed, generation, 0)`, up
//! to `restarts` times; the best point ever accepted is kept. [`Strategy::finished`] is true
//! after a convergence at a small cost or when restarts are exhausted. On noisy data no
//! minimum is "small" (the noise's own cost is a floor): every restart is then spent, which is
//! bounded by `restarts`.
//!
//! One generation is one iteration: the Jacobian when the previous step was accepted (n
//! evaluations), then one trial (1 evaluation); a restart is a generation of one evaluation.
//! Every residual vector counts as one evaluation. Residuals are computed on the local rayon
//! pool; the result depends on the seed only (every evaluation is a pure function of its
//! point, every sum runs in a fixed order). A checkpoint holds the point, λ, ν, the scaling
//! and the restart count, not the residuals nor the Jacobian: a resumed run recomputes them
//! at the same point (the same bits, n + 1 more evaluations counted).

use serde::{Deserialize, Serialize};

use super::common::{load_checked, start_genome, NO_STATS};
use crate::error::CostError;
use crate::linalg::dot;
use crate::problem::Problem;
use crate::run::float_json::{bits, lossless};
use crate::run::rng;
use crate::run::strategy::{GenerationStats, Strategy};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LmConfig {
    /// Relative cost reduction below which an accepted step ends a start (scipy's `ftol`).
    pub ftol: f64,
    /// Relative step length below which a start ends (scipy's `xtol`).
    pub xtol: f64,
    /// Largest cosine between the residual and a Jacobian column at a minimum (`gtol`).
    pub gtol: f64,
    /// Random restarts after a convergence at a cost that is not small.
    pub restarts: u32,
    /// A converged cost is small when at most `small` times the acceleration cost.
    pub small: f64,
    /// Iterations of one start before it is taken as converged.
    pub max_iterations: u64,
    /// λ at every start (relative to the scaling D).
    pub lambda0: f64,
}

impl Default for LmConfig {
    fn default() -> Self {
        LmConfig {
            ftol: 1e-8,
            xtol: 1e-8,
            gtol: 1e-8,
            restarts: 20,
            small: 1e-10,
            max_iterations: 500,
            lambda0: 1e-3,
        }
    }
}

/// What the iteration needs of a problem: residual vectors of a batch of points. A seam so
/// that the algorithm is tested on plain functions (Rosenbrock) as well as on problems.
pub(crate) trait ResidualFn: Sync {
    /// Residual components per point.
    fn len(&self) -> usize;
    /// Residuals of each point (row-major, dim each) into its row of `out`, its cost `Σ r²`
    /// into `costs` (+inf when not finite: that row is not read).
    fn eval(&self, points: &[f64], out: &mut [f64], costs: &mut [f64]);
}

struct ProblemFn<'a>(&'a Problem);

impl ResidualFn for ProblemFn<'_> {
    fn len(&self) -> usize {
        self.0.objective.residual_len()
    }

    fn eval(&self, points: &[f64], out: &mut [f64], costs: &mut [f64]) {
        self.0.residuals_population(points, out, costs);
    }
}

/// Where the next generation starts.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
enum Phase {
    /// Draw a new start point.
    Restart,
    /// The point moved: compute the Jacobian, then try a step.
    Jacobian,
    /// The Jacobian is current (the last trial was rejected): try a step.
    Trial,
    Finished,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
struct State {
    #[serde(with = "bits")]
    z: Vec<f64>,
    #[serde(with = "lossless")]
    cost: f64,
    #[serde(with = "lossless")]
    lambda: f64,
    #[serde(with = "lossless")]
    nu: f64,
    /// Marquardt's scaling: the largest `(JᵀJ)_jj` of this start.
    #[serde(with = "bits")]
    diag: Vec<f64>,
    /// Length of the last step, internal units.
    #[serde(with = "lossless")]
    step: f64,
    iterations: u64,
    restarts: u32,
    #[serde(with = "bits")]
    best_z: Vec<f64>,
    #[serde(with = "lossless")]
    best_cost: f64,
    /// Absolute cost under which a convergence ends the run, m².
    #[serde(with = "lossless")]
    small_cost: f64,
    phase: Phase,
}

/// Buffers of the iteration, allocated once per run (none per generation).
#[derive(Clone, Debug, Default)]
struct Work {
    /// Internal boxes (lo, hi).
    bounds: Vec<(f64, f64)>,
    /// Residuals at `z`, and whether they are current (not after a resume).
    r: Vec<f64>,
    r_valid: bool,
    r_trial: Vec<f64>,
    /// Jacobian, column-major: column j (∂r/∂z_j) is `jac[j*m..(j+1)*m]`.
    jac: Vec<f64>,
    /// Perturbed points of the Jacobian (n × n) and their costs.
    points: Vec<f64>,
    costs: Vec<f64>,
    /// JᵀJ (n × n), Jᵀr, the Cholesky factor of the free block, the step, the trial point.
    a: Vec<f64>,
    g: Vec<f64>,
    chol: Vec<f64>,
    delta: Vec<f64>,
    trial: Vec<f64>,
    /// Coordinates free in this iteration.
    free: Vec<usize>,
}

impl Work {
    fn new(bounds: Vec<(f64, f64)>, m: usize) -> Self {
        let n = bounds.len();
        Work {
            bounds,
            r: vec![0.0; m],
            r_valid: false,
            r_trial: vec![0.0; m],
            jac: vec![0.0; n * m],
            points: vec![0.0; n * n],
            costs: vec![0.0; n.max(1)],
            a: vec![0.0; n * n],
            g: vec![0.0; n],
            chol: vec![0.0; n * n],
            delta: vec![0.0; n],
            trial: vec![0.0; n],
            free: Vec::with_capacity(n),
        }
    }
}

/// The algorithm on any [`ResidualFn`] with internal boxes.
#[derive(Clone, Debug)]
pub(crate) struct Lm {
    config: LmConfig,
    state: Option<State>,
    work: Work,
}

impl Lm {
    pub(crate) fn new(config: LmConfig) -> Self {
        Lm {
            config,
            state: None,
            work: Work::default(),
        }
    }

    /// Starts at `z0` (clamped into `bounds`); `small_cost` is the absolute cost at which a
    /// convergence ends the run. One evaluation.
    pub(crate) fn start(
        &mut self,
        f: &dyn ResidualFn,
        bounds: Vec<(f64, f64)>,
        z0: &[f64],
        small_cost: f64,
    ) {
        let n = bounds.len();
        self.work = Work::new(bounds, f.len());
        let z: Vec<f64> = z0
            .iter()
            .zip(&self.work.bounds)
            .map(|(&z, &(lo, hi))| z.clamp(lo, hi))
            .collect();
        self.state = Some(State {
            z: z.clone(),
            cost: f64::INFINITY,
            lambda: self.config.lambda0,
            nu: 2.0,
            diag: vec![0.0; n],
            step: 0.0,
            iterations: 0,
            restarts: 0,
            best_z: z,
            best_cost: f64::INFINITY,
            small_cost,
            phase: Phase::Jacobian,
        });
        self.evaluate_point(f);
    }

    /// Residuals and cost at the current point (one evaluation); a diverged start point
    /// restarts (or ends the run).
    fn evaluate_point(&mut self, f: &dyn ResidualFn) {
        let (st, w) = (self.state.as_mut().expect("started"), &mut self.work);
        f.eval(&st.z, &mut w.r, &mut w.costs[..1]);
        st.cost = w.costs[0];
        w.r_valid = st.cost.is_finite();
        if st.cost < st.best_cost {
            st.best_cost = st.cost;
            st.best_z.copy_from_slice(&st.z);
        }
        if !w.r_valid {
            self.converged();
        }
    }

    /// One iteration (one generation).
    pub(crate) fn iterate(&mut self, f: &dyn ResidualFn, seed: u64, generation: u64) {
        let Some(st) = self.state.as_mut() else {
            return;
        };
        match st.phase {
            Phase::Finished => {}
            Phase::Restart => {
                let mut r = rng::stream(seed, generation, 0);
                for (z, &(lo, hi)) in st.z.iter_mut().zip(&self.work.bounds) {
                    *z = lo + (hi - lo) * rng::uniform(&mut r);
                }
                st.lambda = self.config.lambda0;
                st.nu = 2.0;
                st.diag.fill(0.0);
                st.iterations = 0;
                st.phase = Phase::Jacobian;
                self.evaluate_point(f);
            }
            Phase::Jacobian => {
                if !self.work.r_valid {
                    self.evaluate_point(f);
                    if self
                        .state
                        .as_ref()
                        .is_some_and(|s| s.phase != Phase::Jacobian)
                    {
                        return;
                    }
                }
                self.jacobian(f);
                if self.state.as_ref().is_some_and(|s| s.phase == Phase::Trial) {
                    self.trial(f);
                }
            }
            Phase::Trial => self.trial(f),
        }
    }

    /// The Jacobian at `z` by forward differences (n evaluations, in parallel), then JᵀJ, Jᵀr,
    /// the scaling and the gtol test.
    fn jacobian(&mut self, f: &dyn ResidualFn) {
        let st = self.state.as_mut().expect("started");
        let w = &mut self.work;
        let n = st.z.len();
        let m = w.r.len();
        let sqrt_eps = f64::EPSILON.sqrt();
        for j in 0..n {
            let (lo, hi) = w.bounds[j];
            let row = &mut w.points[j * n..(j + 1) * n];
            row.copy_from_slice(&st.z);
            let mut h = sqrt_eps * st.z[j].abs().max(hi - lo);
            if st.z[j] + h > hi {
                h = -h;
            }
            row[j] = st.z[j] + h;
            // The step actually taken (z + h rounded), as the difference quotient needs.
            w.delta[j] = row[j] - st.z[j];
        }
        f.eval(&w.points, &mut w.jac, &mut w.costs[..n]);
        for j in 0..n {
            let col = &mut w.jac[j * m..(j + 1) * m];
            let h = w.delta[j];
            if w.costs[j].is_finite() && h != 0.0 {
                for (c, &r) in col.iter_mut().zip(&w.r) {
                    *c = (*c - r) / h;
                }
            } else {
                col.fill(0.0);
            }
        }
        for j in 0..n {
            let cj = &w.jac[j * m..(j + 1) * m];
            w.g[j] = dot(cj, &w.r);
            for k in 0..=j {
                let v = dot(cj, &w.jac[k * m..(k + 1) * m]);
                w.a[j * n + k] = v;
                w.a[k * n + j] = v;
            }
            st.diag[j] = st.diag[j].max(w.a[j * n + j]);
        }
        st.phase = Phase::Trial;
        // gtol: the residual is (nearly) orthogonal to every column that can move.
        let rn = st.cost.sqrt();
        let cosine = (0..n)
            .filter(|&j| w.a[j * n + j] > 0.0 && movable(&w.bounds[j], st.z[j], w.g[j]))
            .map(|j| w.g[j].abs() / (w.a[j * n + j].sqrt() * rn))
            .fold(0.0, f64::max);
        if st.cost == 0.0 || cosine <= self.config.gtol {
            self.converged();
        }
    }

    /// Solves the damped system for a step, evaluates it (one evaluation), accepts or rejects.
    fn trial(&mut self, f: &dyn ResidualFn) {
        let cfg = &self.config;
        let st = self.state.as_mut().expect("started");
        let w = &mut self.work;
        let n = st.z.len();
        w.free.clear();
        for j in 0..n {
            if st.diag[j] > 0.0 && movable(&w.bounds[j], st.z[j], w.g[j]) {
                w.free.push(j);
            }
        }
        if w.free.is_empty() {
            self.converged();
            return;
        }
        // Damped normal equations on the free block; a failed factorisation raises λ.
        loop {
            if st.lambda > 1e20 || !st.lambda.is_finite() {
                self.converged();
                return;
            }
            if cholesky_free(&w.a, &st.diag, st.lambda, &w.free, n, &mut w.chol) {
                break;
            }
            st.lambda *= st.nu;
            st.nu *= 2.0;
        }
        solve_free(&w.chol, &w.free, &w.g, &mut w.delta);
        let mut step2 = 0.0;
        let mut z2 = 0.0;
        for j in 0..n {
            let (lo, hi) = w.bounds[j];
            w.trial[j] = (st.z[j] + w.delta[j]).clamp(lo, hi);
            // The step actually taken, after clamping (what the prediction uses).
            w.delta[j] = w.trial[j] - st.z[j];
            step2 += w.delta[j] * w.delta[j];
            z2 += st.z[j] * st.z[j];
        }
        let step = step2.sqrt();
        st.step = step;
        st.iterations += 1;
        if step <= cfg.xtol * (cfg.xtol + z2.sqrt()) {
            self.converged();
            return;
        }
        // Predicted reduction of the linear model: -(2 gᵀs + sᵀ A s).
        let mut pred = 0.0;
        for j in 0..n {
            let mut as_j = 0.0;
            for k in 0..n {
                as_j += w.a[j * n + k] * w.delta[k];
            }
            pred -= w.delta[j] * (2.0 * w.g[j] + as_j);
        }
        f.eval(&w.trial, &mut w.r_trial, &mut w.costs[..1]);
        let c = w.costs[0];
        if c.is_finite() && c < st.cost {
            let actual = st.cost - c;
            let rho = if pred > 0.0 { actual / pred } else { 1.0 };
            let ftol = actual <= cfg.ftol * st.cost && pred <= cfg.ftol * st.cost;
            std::mem::swap(&mut w.r, &mut w.r_trial);
            st.z.copy_from_slice(&w.trial);
            st.cost = c;
            if c < st.best_cost {
                st.best_cost = c;
                st.best_z.copy_from_slice(&st.z);
            }
            st.lambda *= (1.0 - (2.0 * rho - 1.0).powi(3)).max(1.0 / 3.0);
            st.nu = 2.0;
            st.phase = Phase::Jacobian;
            if c == 0.0 || ftol {
                self.converged();
                return;
            }
        } else {
            st.lambda *= st.nu;
            st.nu *= 2.0;
        }
        if st.iterations >= cfg.max_iterations {
            self.converged();
        }
    }

    /// The current start has converged: finish if its cost is small or no restart is left.
    fn converged(&mut self) {
        let st = self.state.as_mut().expect("started");
        if st.cost <= st.small_cost || st.restarts >= self.config.restarts {
            st.phase = Phase::Finished;
        } else {
            st.restarts += 1;
            st.phase = Phase::Restart;
        }
    }

    pub(crate) fn finished(&self) -> bool {
        self.state
            .as_ref()
            .is_some_and(|s| s.phase == Phase::Finished)
    }

    pub(crate) fn best(&self) -> (&[f64], f64) {
        match &self.state {
            Some(s) => (&s.best_z, s.best_cost),
            None => (&[], f64::INFINITY),
        }
    }

    /// Number of restarts spent so far.
    pub(crate) fn restarts(&self) -> u32 {
        self.state.as_ref().map_or(0, |s| s.restarts)
    }
}

/// Whether coordinate j may move: not held on a bound by a gradient `g = Jᵀr` pointing out.
fn movable(&(lo, hi): &(f64, f64), z: f64, g: f64) -> bool {
    hi > lo && !(z <= lo && g > 0.0) && !(z >= hi && g < 0.0)
}

/// Cholesky factor (lower, row-major k × k, k = free.len()) of `A_ff + λ D_ff`; false when the
/// matrix is not numerically positive definite.
fn cholesky_free(
    a: &[f64],
    diag: &[f64],
    lambda: f64,
    free: &[usize],
    n: usize,
    l: &mut [f64],
) -> bool {
    let k = free.len();
    for (p, &i) in free.iter().enumerate() {
        for (q, &j) in free.iter().enumerate().take(p + 1) {
            let mut s = a[i * n + j];
            if p == q {
                s += lambda * diag[i];
            }
            for r in 0..q {
                s -= l[p * k + r] * l[q * k + r];
            }
            if p == q {
                if s.is_nan() || s <= 0.0 || s.is_infinite() {
                    return false;
                }
                l[p * k + p] = s.sqrt();
            } else {
                l[p * k + q] = s / l[q * k + q];
            }
        }
    }
    true
}

/// δ_f = -(L Lᵀ)⁻¹ g_f, δ = 0 off the free set.
fn solve_free(l: &[f64], free: &[usize], g: &[f64], delta: &mut [f64]) {
    let k = free.len();
    delta.fill(0.0);
    // Forward: L y = -g_f, y stored in delta[free[p]].
    for p in 0..k {
        let mut s = -g[free[p]];
        for q in 0..p {
            s -= l[p * k + q] * delta[free[q]];
        }
        delta[free[p]] = s / l[p * k + p];
    }
    // Backward: Lᵀ x = y.
    for p in (0..k).rev() {
        let mut s = delta[free[p]];
        for q in p + 1..k {
            s -= l[q * k + p] * delta[free[q]];
        }
        delta[free[p]] = s / l[p * k + p];
    }
}

/// The `levenberg-marquardt` strategy: [`Lm`] on a problem's short-cost residuals.
pub struct LevenbergMarquardt {
    lm: Lm,
}

impl LevenbergMarquardt {
    pub fn new(config: LmConfig) -> Self {
        LevenbergMarquardt {
            lm: Lm::new(config),
        }
    }

    /// Random restarts spent so far.
    pub fn restarts(&self) -> u32 {
        self.lm.restarts()
    }
}

/// Internal boxes (lo, hi) of every unknown.
fn internal_bounds(problem: &Problem) -> Vec<(f64, f64)> {
    problem
        .space
        .unknowns
        .iter()
        .map(|u| u.internal_bounds())
        .collect()
}

/// Why `levenberg-marquardt` cannot run on `problem` (it needs the short or static cost's
/// residuals).
pub fn supported(problem: &Problem) -> Result<(), String> {
    match problem.objective.writes_residuals() {
        true => Ok(()),
        false => Err(format!(
            "cost kind `{}`: levenberg-marquardt minimises the short cost or the static cost only \
             (use --cost short)",
            problem.objective.kind()
        )),
    }
}

impl Strategy for LevenbergMarquardt {
    fn name(&self) -> &'static str {
        "levenberg-marquardt"
    }

    fn init(&mut self, problem: &Problem, _seed: u64) {
        let bounds = internal_bounds(problem);
        let small = self.lm.config.small * problem.objective.acceleration_cost();
        self.lm
            .start(&ProblemFn(problem), bounds, &start_genome(problem), small);
    }

    fn next_generation(&mut self, problem: &Problem, seed: u64, generation: u64) {
        self.lm.iterate(&ProblemFn(problem), seed, generation);
    }

    fn finished(&self) -> bool {
        self.lm.finished()
    }

    fn reevaluate(&mut self, problem: &Problem) {
        // Not reached with the short cost (no progressive horizon); kept correct anyway.
        if let Some(st) = self.lm.state.as_mut() {
            let f = ProblemFn(problem);
            let mut c = [0.0];
            f.eval(&st.best_z, &mut self.lm.work.r_trial, &mut c);
            st.best_cost = c[0];
            st.phase = match st.phase {
                Phase::Trial => Phase::Jacobian,
                p => p,
            };
            self.lm.work.r_valid = false;
        }
    }

    fn best(&self) -> (&[f64], f64) {
        self.lm.best()
    }

    fn stats(&self) -> GenerationStats {
        match &self.lm.state {
            Some(s) => GenerationStats {
                best_cost: s.best_cost,
                mean_cost: s.cost,
                mean_mutability: s.step,
            },
            None => NO_STATS,
        }
    }

    fn save_state(&self) -> serde_json::Value {
        serde_json::to_value(&self.lm.state).unwrap_or(serde_json::Value::Null)
    }

    fn load_state(
        &mut self,
        problem: &Problem,
        state: &serde_json::Value,
    ) -> Result<(), CostError> {
        let dim = problem.dim();
        let mut st: Option<State> = load_checked("levenberg-marquardt", state, |s: &State| {
            s.z.len() == dim && s.best_z.len() == dim && s.diag.len() == dim
        })?;
        if let Some(s) = st.as_mut() {
            // Residuals and Jacobian are not in the checkpoint: recompute them at z.
            if s.phase == Phase::Trial {
                s.phase = Phase::Jacobian;
            }
        }
        self.lm.work = Work::new(internal_bounds(problem), problem.objective.residual_len());
        self.lm.state = st;
        Ok(())
    }

    fn report(&self) -> crate::report::Report {
        let Some(s) = &self.lm.state else {
            return crate::report::Report::default();
        };
        // Its criterion is a small cost (a fit to rounding); a finish above it means every
        // start ended in a local minimum, or the model does not fit the data (noise).
        let unconverged = (s.phase == Phase::Finished && s.best_cost > s.small_cost).then(|| {
            format!(
                "levenberg-marquardt: {} restarts ended at cost {:.3e}, above the {:.3e} of a \
                 fit to rounding: a local minimum, or data the model does not fit (noise)",
                s.restarts, s.best_cost, s.small_cost
            )
        });
        crate::report::Report {
            solver: Some(crate::report::SolverReport::LevenbergMarquardt(
                crate::report::LmReport {
                    restarts: s.restarts,
                    lambda: s.lambda,
                    unconverged,
                },
            )),
            uncertainty: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Residuals of a plain function of the point, evaluated one point at a time.
    struct Plain<F: Fn(&[f64], &mut [f64]) + Sync> {
        dim: usize,
        len: usize,
        f: F,
        evals: std::sync::atomic::AtomicU64,
    }

    impl<F: Fn(&[f64], &mut [f64]) + Sync> ResidualFn for Plain<F> {
        fn len(&self) -> usize {
            self.len
        }

        fn eval(&self, points: &[f64], out: &mut [f64], costs: &mut [f64]) {
            for ((p, r), c) in points
                .chunks_exact(self.dim)
                .zip(out.chunks_exact_mut(self.len))
                .zip(costs.iter_mut())
            {
                self.evals
                    .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                (self.f)(p, r);
                let s: f64 = r.iter().map(|x| x * x).sum();
                *c = if s.is_finite() { s } else { f64::INFINITY };
            }
        }
    }

    fn run(lm: &mut Lm, f: &dyn ResidualFn, generations: u64) -> u64 {
        let mut g = 0;
        while !lm.finished() && g < generations {
            g += 1;
            lm.iterate(f, 7, g);
        }
        g
    }

    #[test]
    fn rosenbrock_as_least_squares_reaches_its_minimum() {
        // r = (10 (y - x²), 1 - x): C = Rosenbrock, minimum 0 at (1, 1), from (-1.2, 1).
        let f = Plain {
            dim: 2,
            len: 2,
            f: |p: &[f64], r: &mut [f64]| {
                r[0] = 10.0 * (p[1] - p[0] * p[0]);
                r[1] = 1.0 - p[0];
            },
            evals: Default::default(),
        };
        let mut lm = Lm::new(LmConfig::default());
        // xtol = 1e-8 stops the start within about 1e-8 of (1, 1): a cost near 1e-18.
        lm.start(&f, vec![(-5.0, 5.0); 2], &[-1.2, 1.0], 1e-12);
        let g = run(&mut lm, &f, 200);
        let (z, c) = lm.best();
        assert!(lm.finished(), "not converged after {g} iterations");
        assert!(g < 40, "{g} iterations");
        assert!(c < 1e-16, "cost {c:e}");
        approx::assert_abs_diff_eq!(z[0], 1.0, epsilon = 1e-8);
        approx::assert_abs_diff_eq!(z[1], 1.0, epsilon = 1e-8);
        assert_eq!(lm.restarts(), 0, "converged from its start");
    }

    #[test]
    fn an_optimum_on_the_bound_is_reached_and_kept() {
        // r = (x - 3, 2 (y + 1)) in the box [0, 2] × [0, 1]: the optimum is (2, 0), both on
        // bounds; the cost there is 1 + 4 = 5 and no restart can do better.
        let f = Plain {
            dim: 2,
            len: 2,
            f: |p: &[f64], r: &mut [f64]| {
                r[0] = p[0] - 3.0;
                r[1] = 2.0 * (p[1] + 1.0);
            },
            evals: Default::default(),
        };
        let config = LmConfig {
            restarts: 2,
            ..LmConfig::default()
        };
        let mut lm = Lm::new(config);
        lm.start(&f, vec![(0.0, 2.0), (0.0, 1.0)], &[1.0, 0.5], 0.0);
        run(&mut lm, &f, 500);
        assert!(lm.finished());
        let (z, c) = lm.best();
        assert_eq!(z, &[2.0, 0.0], "on the bounds exactly (projection)");
        approx::assert_relative_eq!(c, 5.0, max_relative = 1e-14);
        assert_eq!(lm.restarts(), 2, "a cost of 5 is not small: restarts spent");
    }

    static DIVERGED: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

    #[test]
    fn a_diverging_trial_is_a_rejected_step() {
        // r = x³ - 0.729 (root 0.9), NaN beyond 0.95 (a model that diverges): from 0.1 the
        // Gauss-Newton step (+24) lands in the divergence; the state must stay finite, the
        // step be rejected and shortened, and the root be reached.
        let f = Plain {
            dim: 1,
            len: 1,
            f: |p: &[f64], r: &mut [f64]| {
                r[0] = if p[0] > 0.95 {
                    DIVERGED.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    f64::NAN
                } else {
                    p[0].powi(3) - 0.729
                };
            },
            evals: Default::default(),
        };
        let config = LmConfig {
            lambda0: 1e-12,
            ..LmConfig::default()
        };
        let mut lm = Lm::new(config);
        lm.start(&f, vec![(-10.0, 100.0)], &[0.1], 1e-12);
        run(&mut lm, &f, 200);
        let (z, c) = lm.best();
        assert!(lm.finished() && lm.restarts() == 0);
        assert!(c.is_finite() && c < 1e-14, "cost {c:e}");
        approx::assert_abs_diff_eq!(z[0], 0.9, epsilon = 1e-8);
        let diverged = DIVERGED.load(std::sync::atomic::Ordering::Relaxed);
        assert!(diverged > 0, "no trial diverged: the test tests nothing");
        let st = lm.state.as_ref().unwrap();
        assert!(st.z.iter().all(|z| z.is_finite()) && st.lambda.is_finite());
    }
}
