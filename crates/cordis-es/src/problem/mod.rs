//! An identification problem: a scene with unknowns, an observed trajectory, a cost — and what
//! the strategies' heuristics need to know about them.
//!
//! Beside [`Problem`]: the unknowns and their genome coordinates ([`space`]), where populations
//! are evaluated ([`evaluator`]) and stability-aware identification ([`stable`]).

mod equilibrium;
pub mod evaluator;
pub mod space;
pub mod stable;

use rayon::prelude::*;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

use cordis_core::forces::angle::cos_angle;
use cordis_core::stability::{plan_max_ratio, StabilityScratch};
use cordis_core::{LinkKind, Scene, Trajectory};

use crate::cost::{CostKind, CostScratch, Objective};
use crate::error::CostError;
use crate::output_error::Take;
use crate::problem::space::{ParameterSpace, Role};
use crate::problem::stable::{Guard, Rejection, StableHorizon};

/// Computes the costs of a population of genomes for a [`Problem`]: where they are computed
/// (a remote pool: the Python bindings' Ray executor; [`crate::problem::evaluator`]).
///
/// An evaluator must return, for every genome, exactly what [`Problem::evaluate`] returns
/// (bit for bit, +inf for a diverged or non-finite cost): a strategy's next generation depends
/// on the costs, so this is what keeps a seed's result independent of where costs are computed.
pub trait Evaluator: Send + Sync {
    /// Global costs of the `costs.len()` genomes of `genomes` (row-major, `problem.dim()`
    /// internal coordinates each) into `costs`; when `local` is given, each genome's
    /// per-particle local costs (row-major, `problem.num_particles` each, m²) into it. The cost
    /// function is `problem.objective` at its current generation (a progressive horizon
    /// depends on it). Does not count evaluations ([`Problem::evaluate_population`] does).
    ///
    /// An `Err` (a lost cluster, a remote exception: [`CostError::Evaluation`]) stops the run
    /// with that error.
    fn evaluate(
        &self,
        problem: &Problem,
        genomes: &[f64],
        costs: &mut [f64],
        local: Option<&mut [f64]>,
    ) -> Result<(), CostError>;
}

/// The `count` genomes of `dim` values each in `genomes`, one slice per individual; without
/// unknowns the slices are empty (each individual still has a cost).
pub(crate) fn genome_rows(genomes: &[f64], dim: usize, count: usize) -> Vec<&[f64]> {
    if dim == 0 {
        vec![&[][..]; count]
    } else {
        genomes.chunks_exact(dim).collect()
    }
}

pub struct Problem {
    pub scene: Scene,
    pub space: ParameterSpace,
    pub objective: Objective,
    /// The true parameter vector, when known (`--truth`): parameter error is then reported.
    pub truth: Option<Vec<f64>>,
    /// Per unknown: the mean observed value a heuristic starts from (rest length: the mean
    /// length of the type's instances over all frames; rest cosine: the mean cosine).
    pub observed: Vec<Option<f64>>,
    /// Per unknown: the particles whose local cost it changes directly (its type's instance
    /// ends, or the particle itself for a mass).
    pub touches: Vec<Vec<u32>>,
    pub num_particles: usize,
    /// Stability-aware identification ([`Problem::with_stable_horizon`]); `None` costs nothing.
    guard: Option<Guard>,
    evals: AtomicU64,
    /// Wall time spent in [`Problem::timed`] sections (population evaluations), ns.
    eval_nanos: AtomicU64,
    /// Where [`Problem::evaluate_population`] computes costs; `None`: this process' rayon
    /// pool ([`Problem::evaluate_here`], what [`crate::problem::evaluator::Local`] does too).
    evaluator: Option<Arc<dyn Evaluator>>,
    /// The first evaluator failure, for the run loop to report.
    eval_error: Mutex<Option<CostError>>,
    /// The observations as recorded (gaps, hidden particles, several takes) for estimators
    /// that read them ([`crate::output_error`]); `None`: the objective's trajectory, complete.
    takes: Option<Vec<Take>>,
}

/// Scratch of one evaluating thread.
pub struct EvalScratch {
    pub params: Vec<f64>,
    pub cost: CostScratch,
    /// Buffers of the stability bound (used only with a stable horizon).
    pub stability: StabilityScratch,
}

impl Problem {
    /// With the static cost, refuses by name the unknowns equilibrium frames cannot determine
    /// (see [`CostKind::Static`]): parameters of velocity-dependent forces (damping,
    /// `damping_quadratic`, drags, friction, `v_max`), masses beside stiffnesses or gains
    /// (only `K/m` is seen), masses without gravity, and every stiffness without gravity.
    pub fn new(scene: &Scene, traj: &Trajectory, kind: CostKind) -> Result<Self, CostError> {
        let objective = Objective::new(scene, traj, kind)?;
        let space = ParameterSpace::from_scene(scene);
        if kind == CostKind::Static {
            equilibrium::check_unknowns(scene, &space)?;
        }
        let mut observed = Vec::with_capacity(space.dim());
        let mut touches = Vec::with_capacity(space.dim());
        for u in &space.unknowns {
            observed.push(match (u.role, u.type_index) {
                (Role::RestLength, Some(t)) => mean_length(scene, traj, t),
                (Role::RestCos, Some(t)) => mean_cos(scene, traj, t),
                _ => None,
            });
            touches.push(match u.type_index {
                Some(t) => type_particles(scene, t),
                None => vec![(u.slot - scene.param_layout().mass_offset) as u32],
            });
        }
        Ok(Problem {
            scene: scene.clone(),
            space,
            objective,
            truth: None,
            observed,
            touches,
            num_particles: scene.num_particles(),
            guard: None,
            evals: AtomicU64::new(0),
            eval_nanos: AtomicU64::new(0),
            evaluator: None,
            eval_error: Mutex::new(None),
            takes: None,
        })
    }

    /// Attaches the observations as recorded (see [`Problem::takes`]); the objective keeps the
    /// trajectory it was built on (gap-filled, for the costs that need every coordinate).
    pub fn with_takes(mut self, takes: Vec<Take>) -> Self {
        self.takes = Some(takes);
        self
    }

    /// The observations as recorded: the takes given to [`Problem::with_takes`], or the
    /// objective's trajectory as one complete take.
    pub fn takes(&self) -> Vec<Take> {
        match &self.takes {
            Some(t) => t.clone(),
            None => vec![self.objective.observed_take()],
        }
    }

    /// Number of takes (recordings) the observations hold.
    pub fn take_count(&self) -> usize {
        self.takes.as_ref().map_or(1, Vec::len)
    }

    /// Whether some observation of a free particle is missing (a gap, a hidden particle) in
    /// the recorded takes.
    pub fn has_missing(&self) -> bool {
        // A fixed particle is where the scene puts it: untracked, it is no missing data.
        let free: Vec<usize> = (0..self.scene.particles.len())
            .filter(|&i| !self.scene.particles[i].fixed)
            .collect();
        self.takes.as_ref().is_some_and(|ts| {
            ts.iter().any(|t| {
                (0..t.frames())
                    .any(|f| free.iter().any(|&i| (0..3).any(|c| t.at(f, i, c).1 == 0.0)))
            })
        })
    }

    /// Whether the recorded takes weigh some coordinates unequally (per-marker weights).
    pub fn has_weights(&self) -> bool {
        self.takes
            .as_ref()
            .is_some_and(|ts| ts.iter().any(Take::weighted))
    }

    /// Computes populations' costs with `evaluator` instead of the local rayon pool.
    pub fn with_evaluator(mut self, evaluator: Arc<dyn Evaluator>) -> Self {
        self.evaluator = Some(evaluator);
        self
    }

    /// Sets the truth from a scene with the same layout (known values).
    pub fn with_truth(mut self, truth: &Scene) -> Result<Self, CostError> {
        let p = truth.param_values();
        if p.len() != self.space.base.len() {
            return Err(CostError::Mismatch {
                place: "truth".into(),
                message: "the truth scene does not have the same types and particles".into(),
            });
        }
        self.truth = Some(p);
        Ok(self)
    }

    /// Sets the known total mass (kg) of the free particles ([`ParameterSpace::total_mass`]).
    pub fn with_total_mass(mut self, total: f64) -> Result<Self, CostError> {
        if !(total > 0.0 && total.is_finite()) {
            return Err(CostError::Mismatch {
                place: "total_mass".into(),
                message: format!("must be a positive number of kg, got {total}"),
            });
        }
        self.space.total_mass = Some(total);
        Ok(self)
    }

    /// Writes `local` as the per-particle local costs ([`crate::cost::LocalCost`]: the
    /// position error, or eq 3.3's neighbour distances); the global cost is unchanged. Errors
    /// (place `local_cost`) when the cost kind is not `short` or a free particle has no linked
    /// neighbour.
    pub fn with_local_cost(mut self, local: crate::cost::LocalCost) -> Result<Self, CostError> {
        self.objective.set_local_cost(local, &self.scene)?;
        Ok(self)
    }

    /// Rejects (`+inf` cost) every candidate whose stability bound exceeds 1 or whose free
    /// run from the observed start diverges within `horizon.frames` frames (see
    /// [`crate::problem::stable`]). The spread limit is fixed here from the observed trajectory.
    pub fn with_stable_horizon(mut self, horizon: StableHorizon) -> Self {
        self.guard = Some(Guard::new(horizon, self.objective.observed_spread()));
        self
    }

    /// Seconds one frame of the free run takes here, measured on the parameters `p` (runs of 16,
    /// 32, … frames until one lasts 2 ms or reaches `frames`; a run that diverges counts the frames
    /// it ran): what [`crate::session`] compares a horizon with before any work.
    pub(crate) fn seconds_per_frame(&self, p: &[f64], frames: usize) -> f64 {
        let mut s = self.objective.scratch();
        let limit = self.guard.map_or(f64::INFINITY, |g| g.limit);
        let mut probe = 16usize.min(frames.max(3));
        loop {
            let start = std::time::Instant::now();
            let ran = self
                .objective
                .free_run_diverges(p, probe, limit, &mut s)
                .unwrap_or(probe);
            let seconds = start.elapsed().as_secs_f64();
            if seconds >= 2e-3 || probe >= frames || ran < probe {
                return seconds / ran.max(1) as f64;
            }
            probe = (2 * probe).min(frames);
        }
    }

    /// The stable horizon set by [`Problem::with_stable_horizon`].
    pub fn stable_horizon(&self) -> Option<StableHorizon> {
        self.guard.map(|g| g.horizon)
    }

    /// Why the stable horizon rejects parameter vector `p` (`None`: accepted, or no horizon).
    pub fn stability_check(&self, p: &[f64], s: &mut EvalScratch) -> Option<Rejection> {
        let g = self.guard.as_ref()?;
        let q = plan_max_ratio(&self.objective.plan, p, &mut s.stability);
        // A NaN bound (absurd values) is a rejection too.
        if q >= 1.0 || q.is_nan() {
            return Some(Rejection::Bound(q));
        }
        self.objective
            .free_run_diverges(p, g.horizon.frames, g.limit, &mut s.cost)
            .map(Rejection::Diverged)
    }

    pub fn dim(&self) -> usize {
        self.space.dim()
    }

    pub fn scratch(&self) -> EvalScratch {
        EvalScratch {
            params: self.space.base.clone(),
            cost: self.objective.scratch(),
            stability: StabilityScratch::default(),
        }
    }

    /// Global cost of a genome (internal coordinates); per-particle local costs into `local`.
    pub fn evaluate(&self, genome: &[f64], s: &mut EvalScratch, local: &mut [f64]) -> f64 {
        self.evals.fetch_add(1, Ordering::Relaxed);
        self.evaluate_uncounted(genome, s, local)
    }

    /// [`Problem::evaluate`] with the position-error local costs whatever the objective's
    /// local cost ([`crate::cost::LocalCost`]): the same global cost, for a caller that reads
    /// no local cost (the thesis ES's descents), without eq 3.3's generic path.
    pub fn evaluate_global(&self, genome: &[f64], s: &mut EvalScratch, local: &mut [f64]) -> f64 {
        self.evals.fetch_add(1, Ordering::Relaxed);
        self.evaluate_with(genome, s, local, true)
    }

    /// [`Problem::evaluate`] without counting the evaluation: for evaluators, whose batches
    /// [`Problem::evaluate_population`] counts.
    pub fn evaluate_uncounted(
        &self,
        genome: &[f64],
        s: &mut EvalScratch,
        local: &mut [f64],
    ) -> f64 {
        self.evaluate_with(genome, s, local, false)
    }

    /// One evaluation, with the objective's local costs or (`positions`) the position error's.
    fn evaluate_with(
        &self,
        genome: &[f64],
        s: &mut EvalScratch,
        local: &mut [f64],
        positions: bool,
    ) -> f64 {
        self.space.fill_params(genome, &mut s.params);
        if self.guard.is_some() && self.rejects_filled(s) {
            // Every free particle's local cost too, so particle-wise operators (the thesis
            // strategy's) never take a gene from a rejected candidate.
            local.fill(0.0);
            for &i in &self.objective.free {
                if let Some(c) = local.get_mut(i) {
                    *c = f64::INFINITY;
                }
            }
            return f64::INFINITY;
        }
        let c = match positions {
            true => self
                .objective
                .evaluate_positions_local(&s.params, &mut s.cost, local),
            false => self.objective.evaluate(&s.params, &mut s.cost, local),
        };
        match c {
            Ok(c) if !c.is_nan() => c,
            _ => f64::INFINITY,
        }
    }

    /// Global costs of a population of genomes (row-major, [`Problem::dim`] values each) into
    /// `costs`, and their per-particle local costs (row-major, `num_particles` each) into
    /// `local` when given, by this problem's [`Evaluator`]. Counts `costs.len()` evaluations
    /// and their time ([`Problem::eval_seconds`]).
    /// Should the evaluator fail, every cost is +inf and the failure is kept for the run loop
    /// ([`Problem::take_eval_error`]), which then stops.
    pub fn evaluate_population(
        &self,
        genomes: &[f64],
        costs: &mut [f64],
        mut local: Option<&mut [f64]>,
    ) {
        self.evals.fetch_add(costs.len() as u64, Ordering::Relaxed);
        // Timed here, not by each strategy: one that forgot (cmaes did) reported 0 s.
        let outcome = self.timed(|| match &self.evaluator {
            Some(evaluator) => evaluator.evaluate(self, genomes, costs, local.as_deref_mut()),
            None => {
                self.evaluate_here(genomes, costs, local.as_deref_mut());
                Ok(())
            }
        });
        match outcome {
            // A remote evaluator's NaN is the same +inf a local one gives.
            Ok(()) => costs
                .iter_mut()
                .filter(|c| c.is_nan())
                .for_each(|c| *c = f64::INFINITY),
            Err(e) => {
                costs.fill(f64::INFINITY);
                if let Some(l) = local {
                    l.fill(0.0);
                }
                let mut slot = self.eval_error.lock().unwrap_or_else(|p| p.into_inner());
                slot.get_or_insert(e);
            }
        }
    }

    /// Global costs (and local costs into `local`) of a population of genomes, as
    /// [`Problem::evaluate_population`] takes them, on the current rayon pool, one scratch per
    /// worker split; not counted. What every [`Evaluator`] must reproduce bit for bit.
    pub fn evaluate_here(&self, genomes: &[f64], costs: &mut [f64], local: Option<&mut [f64]>) {
        let dim = self.dim();
        let n = self.num_particles;
        debug_assert_eq!(genomes.len(), costs.len() * dim, "one genome per cost");
        let rows = genome_rows(genomes, dim, costs.len());
        match local {
            Some(local) if n > 0 => rows
                .par_iter()
                .zip(costs.par_iter_mut())
                .zip(local.par_chunks_mut(n))
                .for_each_init(
                    || self.scratch(),
                    |s, ((g, c), l)| *c = self.evaluate_uncounted(g, s, l),
                ),
            _ => rows.par_iter().zip(costs.par_iter_mut()).for_each_init(
                || (self.scratch(), vec![0.0; n]),
                |(s, l), (g, c)| *c = self.evaluate_uncounted(g, s, l),
            ),
        }
    }

    /// Short-cost residuals of a population of genomes (row-major, [`Problem::dim`] values
    /// each): each genome's [`Objective::residuals`] into its row of `out` (row-major,
    /// [`Objective::residual_len`] each) and its cost into `costs` (`+inf` when it diverged or
    /// the stable horizon rejects it: its row must then not be used). Counts `costs.len()`
    /// evaluations and their time. Computed on this process' rayon pool, whatever evaluator is
    /// plugged in (a residual vector is too large to be worth shipping); the kind must be
    /// `short` or `static` (the least-squares strategies check it before a run).
    pub fn residuals_population(&self, genomes: &[f64], out: &mut [f64], costs: &mut [f64]) {
        self.evals.fetch_add(costs.len() as u64, Ordering::Relaxed);
        let dim = self.dim();
        let len = self.objective.residual_len();
        debug_assert_eq!(out.len(), costs.len() * len, "one residual row per cost");
        if !self.objective.writes_residuals() {
            costs.fill(f64::INFINITY);
            let mut slot = self.eval_error.lock().unwrap_or_else(|p| p.into_inner());
            slot.get_or_insert(CostError::evaluation(format!(
                "cost kind `{}`: residuals are written for the short and static costs only",
                self.objective.kind()
            )));
            return;
        }
        if len == 0 {
            // No free particle: nothing to predict, nothing to miss.
            costs.fill(0.0);
            return;
        }
        let rows = genome_rows(genomes, dim, costs.len());
        self.timed(|| {
            rows.par_iter()
                .zip(out.par_chunks_mut(len))
                .zip(costs.par_iter_mut())
                .for_each_init(
                    || self.scratch(),
                    |s, ((g, r), c)| *c = self.residuals_uncounted(g, s, r),
                )
        });
    }

    /// Whether the stable horizon rejects the parameters already filled into `s.params`.
    fn rejects_filled(&self, s: &mut EvalScratch) -> bool {
        let params = std::mem::take(&mut s.params);
        let rejected = self.stability_check(&params, s).is_some();
        s.params = params;
        rejected
    }

    /// [`Problem::residuals_population`] of one genome, not counted.
    fn residuals_uncounted(&self, genome: &[f64], s: &mut EvalScratch, out: &mut [f64]) -> f64 {
        self.space.fill_params(genome, &mut s.params);
        if self.guard.is_some() && self.rejects_filled(s) {
            return f64::INFINITY;
        }
        match self.objective.residuals(&s.params, &mut s.cost, out) {
            Ok(c) if !c.is_nan() => c,
            _ => f64::INFINITY,
        }
    }

    /// The first evaluator failure since the last call, if any.
    pub fn take_eval_error(&self) -> Option<CostError> {
        self.eval_error
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .take()
    }

    /// Root mean square prediction error (m) of a global cost: sqrt(C / terms).
    pub fn rmse(&self, cost: f64) -> f64 {
        (cost / self.objective.terms().max(1) as f64).sqrt()
    }

    /// Runs `f` (a population's evaluation) and adds its wall time to [`Problem::eval_seconds`]:
    /// the thesis' Annexe 2 split between evaluation and the operators.
    pub fn timed<R>(&self, f: impl FnOnce() -> R) -> R {
        let start = std::time::Instant::now();
        let r = f();
        self.eval_nanos
            .fetch_add(start.elapsed().as_nanos() as u64, Ordering::Relaxed);
        r
    }

    /// Wall time spent evaluating populations so far, s.
    pub fn eval_seconds(&self) -> f64 {
        self.eval_nanos.load(Ordering::Relaxed) as f64 * 1e-9
    }

    /// Number of cost evaluations so far.
    pub fn evals(&self) -> u64 {
        self.evals.load(Ordering::Relaxed)
    }

    pub fn set_evals(&self, n: u64) {
        self.evals.store(n, Ordering::Relaxed);
    }

    /// Mean parameter error (%) of a genome, when the truth is known.
    pub fn error_pct(&self, genome: &[f64]) -> Option<f64> {
        self.truth.as_ref().map(|t| self.space.error_pct(genome, t))
    }
}

fn type_particles(scene: &Scene, t: usize) -> Vec<u32> {
    let ty = &scene.types[t];
    let mut out: Vec<u32> = if ty.kind == LinkKind::Conditional {
        scene
            .particles
            .iter()
            .enumerate()
            .filter(|(_, p)| p.group.as_ref().is_some_and(|g| ty.groups.contains(g)))
            .map(|(i, _)| i as u32)
            .collect()
    } else {
        let links = scene.links.iter().filter(|l| l.type_index == t);
        let couplings = scene.couplings.iter().filter(|c| c.type_index == t);
        links
            .map(|l| &l.particles)
            .chain(couplings.map(|c| &c.particles))
            .flat_map(|ps| ps.iter().map(|&i| i as u32))
            .collect()
    };
    out.sort_unstable();
    out.dedup();
    out
}

fn mean_length(scene: &Scene, traj: &Trajectory, t: usize) -> Option<f64> {
    let mut sum = 0.0;
    let mut n = 0usize;
    for l in scene.links.iter().filter(|l| l.type_index == t) {
        for f in 0..traj.frames() {
            let xi = traj.pos(f, l.particles[0]);
            let xj = match l.particles.get(1) {
                Some(&j) => traj.pos(f, j),
                None => match l.point.or(scene.types[t].point) {
                    Some(p) => p.into(),
                    None => scene.particles[l.particles[0]].pos.into(),
                },
            };
            sum += (xj - xi).norm();
            n += 1;
        }
    }
    // Binary couplings (a TGR's link) too; a controlled TGR's rest length is `l0 + y` with its
    // tendon y near the controller dipole's length, so its l0 starts at the mean difference.
    for c in scene.couplings.iter().filter(|c| c.type_index == t) {
        if let [i, j] = c.particles[..] {
            for f in 0..traj.frames() {
                let anchor = c
                    .controller
                    .map_or(0.0, |[a, b]| (traj.pos(f, b) - traj.pos(f, a)).norm());
                sum += (traj.pos(f, j) - traj.pos(f, i)).norm() - anchor;
                n += 1;
            }
        }
    }
    (n > 0).then(|| sum / n as f64)
}

fn mean_cos(scene: &Scene, traj: &Trajectory, t: usize) -> Option<f64> {
    let mut sum = 0.0;
    let mut n = 0usize;
    for l in scene.links.iter().filter(|l| l.type_index == t) {
        for f in 0..traj.frames() {
            let [i, j, k] = [l.particles[0], l.particles[1], l.particles[2]];
            if let Some(c) = cos_angle(&traj.pos(f, i), &traj.pos(f, j), &traj.pos(f, k)) {
                sum += c;
                n += 1;
            }
        }
    }
    (n > 0).then(|| sum / n as f64)
}
