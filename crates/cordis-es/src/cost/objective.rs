//! The objective of identification: a compiled scene, an observed trajectory and a cost kind,
//! evaluated on parameter vectors (SPEC §3).

use super::geometry::Geometry;
use super::hidden::{HiddenState, PlanStateful};
use super::kernels::{SpringBuf, GEOMETRY_BUDGET_BYTES};
use super::kind::CostKind;
use super::linear::LinearShortCost;
use super::observed::Observed;
use crate::error::CostError;
use cordis_core::plan::Scratch;
use cordis_core::{Plan, Runaway, Scene, Trajectory, Vec3};
use std::sync::OnceLock;

/// A cost function ready to evaluate: built once per (scene, trajectory, kind), then evaluated
/// on any number of parameter vectors laid out as [`cordis_core::ParamLayout`] (every type's
/// parameters, then one mass per particle, then gravity).
///
/// Conventions (SPEC §3, thesis §3.2.1):
/// - Only free particles are scored. Fixed particles are *exact*: wherever a prediction needs
///   their position at a frame, it takes the observed one.
/// - The short cost predicts frame t (t = 2 … T-1) by one simulator step from the observed
///   frames t-1 and t-2 (velocity `v = (x(t-1) - x(t-2)) / dt`, every link pass, gravity, then
///   Provot's pass on the predicted positions). On a trajectory simulated with the same
///   parameters it is exactly 0.
/// - `e_i(t) = |x̂_i(t) - x_i(t)|²` (m²); the global cost is `C = Σ_i c_i` with the
///   position-error local cost `c_i = Σ_t e_i(t)` (eq 3.1 split by particle, what §3.2.1's
///   sentence describes; eq 3.3 as printed, the error of the distances to the neighbours, is
///   [`super::LocalCost::Distances`], which changes the local costs written and not `C`). The
///   harmonic kind differs: see [`CostKind::Harmonic`] and [`Objective::evaluate`].
/// - `terms` counts (predicted frame, free particle) pairs — particles, not coordinates — so
///   `rmse = sqrt(C / terms)` is the root-mean-square prediction error of a particle, in m.
/// - Never NaN: a prediction that is not finite (or, in a rollout, a coordinate beyond
///   [`cordis_core::runaway::CAP`] = 1e100 m: see `rollout.rs` for why not the relative
///   guard) makes that particle's local cost and the
///   global cost `+inf`.
/// - Speed: a one-step window on a linear-in-parameter scene is evaluated from its
///   precomputed quadratic form ([`LinearShortCost`]: O(θ²) for the total, equal to the
///   generic path to rounding); otherwise the geometry of springs and known-range conditional
///   pairs at every frame is precomputed on first use ([`Objective::set_geometry_budget`]),
///   with bit-identical results.
#[derive(Debug)]
pub struct Objective {
    pub(crate) plan: Plan,
    pub(crate) kind: CostKind,
    pub(crate) obs: Observed,
    /// Indices of the free particles, ascending.
    pub(crate) free: Vec<usize>,
    /// The precomputed quadratic form of the short cost, when the scene is linear in its
    /// parameters and the kind's window is 1 step.
    pub(crate) linear: Option<LinearShortCost>,
    pub(crate) use_linear: bool,
    /// Geometry of the listed pairs at the observed frames, built by the first generic short
    /// evaluation (a linear scene or a rollout kind may never need it).
    pub(crate) geometry: OnceLock<Geometry>,
    pub(crate) geometry_budget: usize,
    /// The caller's generation counter (progressive horizon).
    pub(crate) generation: usize,
    /// The linked pairs with a free end when the local costs are eq 3.3's distances
    /// ([`super::LocalCost`]); `None`: the position error.
    pub(crate) neighbour_pairs: Option<Vec<[u32; 2]>>,
    /// Stateful passes advanced along the observed frames (see [`HiddenState`]).
    pub(crate) hidden: Vec<Box<dyn HiddenState>>,
    /// The divergence guard of the observed motion ([`cordis_core::runaway`]), for the stable
    /// horizon's free run.
    pub(crate) runaway: Runaway,
    /// The scene's gravity, m/s² (fixed: not a parameter one identifies).
    pub(crate) gravity: Vec3,
}

/// Per-evaluation buffers, one per thread ([`Objective::scratch`]); an evaluation allocates
/// nothing once it has one.
#[derive(Clone, Debug)]
pub struct CostScratch {
    pub(crate) core: Scratch,
    /// Predicted positions of a step, m.
    pub(crate) xhat: Vec<Vec3>,
    /// Rollout state x(n), x(n-1), m (eq 3.3's path: the predicted positions of a frame).
    pub(crate) x: Vec<Vec3>,
    pub(crate) x_prev: Vec<Vec3>,
    /// Local costs of an evaluation whose caller wants only the total.
    pub(crate) per: Vec<f64>,
    /// Harmonic sums `Σ_t 1/(e_i(t) + ε)` per particle; eq 3.3's path keeps each particle's
    /// position error here.
    pub(crate) inv: Vec<f64>,
    /// θ of the linear path.
    pub(crate) theta: Vec<f64>,
    /// State of the hidden passes (the short cost's, or a rollout window's).
    pub(crate) hidden: Vec<f64>,
    /// Rollouts: the hidden state driven along the observed frames, copied into `hidden` at
    /// the start of each window.
    pub(crate) hidden_obs: Vec<f64>,
    /// Forces of hidden passes advanced along observed frames, not used (N).
    pub(crate) discard: Vec<Vec3>,
    /// Arrays of the spring kernel (boxed: 3 KiB that need not move with the scratch).
    pub(crate) springs: Box<SpringBuf>,
    /// `Σ e` over every term of the last evaluation (the harmonic kind's total is not it).
    pub(crate) plain: f64,
}

/// Everything [`Objective::report`] says about one parameter vector.
#[derive(Clone, Debug, PartialEq)]
pub struct CostReport {
    /// The global cost C (m² for every kind but harmonic).
    pub total: f64,
    /// `sqrt(Σ e / terms)`: RMS prediction error of a particle, m (for the harmonic kind, of
    /// its long rollout). `+inf` when the candidate diverged; 0 when there are no terms.
    pub rmse: f64,
    /// Local cost `c_i` of every particle (0 for fixed particles).
    pub per_particle: Vec<f64>,
    /// Number of (predicted frame, free particle) pairs (static: (frame, free particle)).
    pub terms: usize,
}

impl Objective {
    /// Compiles `scene`, checks that `traj` fits it (same particle count, at least 3 frames, the
    /// same `dt` when the trajectory states one) and precomputes what does not depend on the
    /// parameters: velocities, conditional pairs at a known range, and for a short cost on a
    /// linear-in-parameter scene its quadratic form ([`LinearShortCost`]).
    ///
    /// The static kind needs 1 frame, refuses couplings by name (their state between steps has
    /// no rest value here) and reads every frame with zero velocity.
    pub fn new(scene: &Scene, traj: &Trajectory, kind: CostKind) -> Result<Objective, CostError> {
        let plan = Plan::compile(scene)?;
        let is_static = kind == CostKind::Static;
        kind.check_scene(scene, &plan)?;
        let mut obs = Observed::new(scene, &plan, traj, kind.min_frames())?;
        if is_static {
            // Frames are independent poses at rest: no velocity between them.
            obs.vs.fill(Vec3::zeros());
        }
        let free = (0..plan.n).filter(|&i| plan.free[i]).collect();
        let runaway = plan.runaway_of((0..obs.frames).map(|t| obs.frame(t)));
        let mut hidden: Vec<Box<dyn HiddenState>> = Vec::new();
        if !plan.stateful.is_empty() {
            hidden.push(Box::new(PlanStateful {
                passes: plan.stateful.clone(),
            }));
        }
        let linear = if kind.window(obs.frames, 0) == Some(1) {
            LinearShortCost::build(scene, &plan, &obs)
        } else {
            None
        };
        let geometry = OnceLock::new();
        if is_static {
            let _ = geometry.set(Geometry::none(obs.pairs.len()));
        }
        Ok(Objective {
            kind,
            obs,
            free,
            linear,
            use_linear: true,
            geometry,
            geometry_budget: GEOMETRY_BUDGET_BYTES,
            generation: 0,
            neighbour_pairs: None,
            hidden,
            runaway,
            gravity: Vec3::from(scene.gravity),
            plan,
        })
    }

    /// Buffers for [`Objective::evaluate`]; make one per thread.
    pub fn scratch(&self) -> CostScratch {
        let n = self.plan.n;
        CostScratch {
            core: self.plan.scratch(),
            xhat: vec![Vec3::zeros(); n],
            x: vec![Vec3::zeros(); n],
            x_prev: vec![Vec3::zeros(); n],
            per: vec![0.0; n],
            inv: vec![0.0; n],
            theta: vec![0.0; self.linear.as_ref().map_or(0, |l| l.dim())],
            hidden: vec![0.0; self.hidden_len()],
            hidden_obs: vec![0.0; self.hidden_len()],
            discard: if self.hidden.is_empty() {
                Vec::new()
            } else {
                vec![Vec3::zeros(); n]
            },
            springs: Box::default(),
            plain: 0.0,
        }
    }

    /// The observed trajectory as one complete take (every coordinate, weight 1).
    pub fn observed_take(&self) -> crate::output_error::Take {
        let flat: Vec<f64> = self
            .obs
            .xs
            .iter()
            .flat_map(|x| [x[0], x[1], x[2]])
            .collect();
        let traj = cordis_core::Trajectory::from_flat(self.obs.frames, self.obs.n, flat)
            .unwrap_or_else(|_| cordis_core::Trajectory::zeros(self.obs.frames, self.obs.n));
        crate::output_error::Take::complete(&traj)
    }

    pub fn plan(&self) -> &Plan {
        &self.plan
    }

    /// f64 of hidden state of all the stateful passes.
    fn hidden_len(&self) -> usize {
        self.hidden.iter().map(|h| h.state_len()).sum()
    }

    pub fn kind(&self) -> CostKind {
        self.kind
    }

    /// Length of the parameter vectors this objective takes.
    pub fn param_len(&self) -> usize {
        self.plan.layout.len
    }

    /// Number of observed frames T.
    pub fn frames(&self) -> usize {
        self.obs.frames
    }

    /// Number of particles N (local-cost vectors have this length).
    pub fn particles(&self) -> usize {
        self.plan.n
    }

    /// Sets the caller's generation counter, which drives the progressive horizon (other kinds
    /// ignore it). An evolution strategy calls it once per generation, before evaluating.
    pub fn set_generation(&mut self, generation: usize) {
        self.generation = generation;
    }

    pub fn generation(&self) -> usize {
        self.generation
    }

    /// Steps per window at the current generation (`None` for `long` and `harmonic`).
    pub fn window(&self) -> Option<usize> {
        self.kind.window(self.obs.frames, self.generation)
    }

    /// Number of (predicted frame, free particle) pairs at the current generation.
    pub fn terms(&self) -> usize {
        let t = self.obs.frames;
        let steps: usize = match self.window() {
            // Windows start at t0 = 2 … T-1 and stop at the last frame.
            Some(h) => (2..t).map(|t0| h.min(t - t0)).sum(),
            // Every frame is a pose at rest.
            None if self.kind == CostKind::Static => t,
            None => t - 2,
        };
        steps * self.free.len()
    }

    /// Link evaluations of one generic evaluation (link instances × predicted steps; active
    /// conditional pairs not counted): the unit of the throughput figures.
    pub fn link_evaluations(&self) -> usize {
        self.plan.num_links() * self.terms() / self.free.len().max(1)
    }

    /// The precomputed short cost, when the scene allows it.
    pub fn linear(&self) -> Option<&LinearShortCost> {
        self.linear.as_ref()
    }

    /// Enables (the default) or disables the precomputed linear path; disabled, every
    /// evaluation runs the generic simulator-step path (for checks and benchmarks).
    pub fn set_linear(&mut self, enabled: bool) {
        self.use_linear = enabled;
    }

    /// The linear path that applies to `p`: it exists, is enabled, the window is one step, and
    /// `p` agrees with the scene on what the form was built with (masses, ranges).
    pub(crate) fn linear_for(&self, p: &[f64]) -> Option<&LinearShortCost> {
        self.linear
            .as_ref()
            .filter(|l| self.use_linear && self.window() == Some(1) && l.applies_to(p))
    }

    /// Caps the memory (bytes, default [`GEOMETRY_BUDGET_BYTES`]) of the generic short cost's
    /// precomputed geometry: unit vector, length and elongation rate of every listed spring
    /// and known-range conditional pair at every frame, 40 bytes each, which spares every
    /// evaluation its square roots and divisions (about 2× faster on a cloth). Passes that do
    /// not fit compute their geometry at each evaluation; results are identical either way.
    pub fn set_geometry_budget(&mut self, bytes: usize) {
        self.geometry_budget = bytes;
        if self.kind != CostKind::Static {
            self.geometry = OnceLock::new();
        }
    }

    /// The precomputed geometry, built on first call (thread-safe; later calls are free).
    pub(crate) fn geometry(&self) -> &Geometry {
        self.geometry.get_or_init(|| {
            Geometry::build(&self.obs, &self.plan.springs.pairs, self.geometry_budget)
        })
    }

    /// Whether an evaluation of `p` takes the precomputed linear path.
    pub fn uses_linear(&self, p: &[f64]) -> bool {
        self.linear_for(p).is_some()
    }

    pub(crate) fn check_params(&self, p: &[f64]) -> Result<(), CostError> {
        if p.len() != self.plan.layout.len {
            return Err(CostError::length(
                "parameter vector",
                self.plan.layout.len,
                p.len(),
            ));
        }
        Ok(())
    }

    /// Evaluates the cost of `p`: returns the global cost C and writes every particle's local
    /// cost `c_i` into `per_particle` (length N; 0 for fixed particles).
    ///
    /// For every kind but harmonic, `C = Σ_i c_i` with `c_i = Σ_t e_i(t)` over the kind's
    /// predicted frames (windows overlap for `horizon`: a frame counts once per window that
    /// predicts it). Harmonic (thesis eq 3.2, read as a harmonic-mean-like sum over the long
    /// rollout): `c_i = 1 / Σ_t 1/(e_i(t) + ε)` and `C = 1 / Σ_i 1/c_i = 1 / Σ_{t,i} 1/(e_i(t) + ε)`.
    ///
    /// Errors when `p` or `per_particle` has the wrong length; never panics, never NaN.
    pub fn evaluate(
        &self,
        p: &[f64],
        scratch: &mut CostScratch,
        per_particle: &mut [f64],
    ) -> Result<f64, CostError> {
        self.check_params(p)?;
        if per_particle.len() != self.plan.n {
            return Err(CostError::length(
                "local cost buffer",
                self.plan.n,
                per_particle.len(),
            ));
        }
        Ok(self.evaluate_unchecked(p, scratch, per_particle))
    }

    /// [`Objective::evaluate`] with the position-error local costs whatever
    /// [`Objective::local_cost`] says: the same global cost, for a caller that needs no other
    /// (a descent), without eq 3.3's generic path.
    pub fn evaluate_positions_local(
        &self,
        p: &[f64],
        scratch: &mut CostScratch,
        per_particle: &mut [f64],
    ) -> Result<f64, CostError> {
        self.check_params(p)?;
        if per_particle.len() != self.plan.n {
            return Err(CostError::length(
                "local cost buffer",
                self.plan.n,
                per_particle.len(),
            ));
        }
        per_particle.fill(0.0);
        Ok(self.evaluate_positions(p, scratch, per_particle))
    }

    /// The global cost only (the linear path then costs O(θ²), independent of N and T).
    pub fn total(&self, p: &[f64], scratch: &mut CostScratch) -> Result<f64, CostError> {
        self.check_params(p)?;
        Ok(self.total_unchecked(p, scratch))
    }

    pub(crate) fn total_unchecked(&self, p: &[f64], s: &mut CostScratch) -> f64 {
        if let Some(lin) = self.linear_for(p) {
            lin.theta_into(p, &mut s.theta);
            let c = lin.total_unchecked(&s.theta);
            s.plain = c;
            return c;
        }
        // The global cost does not depend on the local cost chosen: the position-error path.
        let mut per = std::mem::take(&mut s.per);
        per.fill(0.0);
        let c = self.evaluate_positions(p, s, &mut per);
        s.per = per;
        c
    }

    fn evaluate_unchecked(&self, p: &[f64], s: &mut CostScratch, per: &mut [f64]) -> f64 {
        per.fill(0.0);
        match &self.neighbour_pairs {
            // Eq 3.3 needs every prediction: the generic path.
            Some(pairs) => match self.short_distances(p, pairs, s, per) {
                c if c.is_nan() => f64::INFINITY,
                c => c,
            },
            None => self.evaluate_positions(p, s, per),
        }
    }

    /// The global cost, and the position-error local costs into `per` (zeroed by the caller).
    fn evaluate_positions(&self, p: &[f64], s: &mut CostScratch, per: &mut [f64]) -> f64 {
        if let Some(lin) = self.linear_for(p) {
            lin.theta_into(p, &mut s.theta);
            let c = lin.local_unchecked(&s.theta, per);
            s.plain = c;
            return c;
        }
        let c = match self.kind {
            CostKind::Harmonic { eps } => self.harmonic(p, eps, s, per),
            CostKind::Static => self.static_cost(p, s, per),
            _ => match self.window() {
                Some(1) => self.short_generic(p, s, per),
                Some(h) => self.windows(p, h, 2..self.obs.frames, s, per),
                None => self.windows(p, self.obs.frames - 2, 2..3, s, per),
            },
        };
        if c.is_nan() {
            f64::INFINITY
        } else {
            c
        }
    }

    /// Cost, RMSE, local costs and term count of `p`.
    pub fn report(&self, p: &[f64]) -> Result<CostReport, CostError> {
        let mut s = self.scratch();
        let mut per_particle = vec![0.0; self.plan.n];
        let total = self.evaluate(p, &mut s, &mut per_particle)?;
        let terms = self.terms();
        let plain = if total.is_finite() {
            s.plain
        } else {
            f64::INFINITY
        };
        let rmse = if terms == 0 {
            0.0
        } else {
            (plain / terms as f64).sqrt()
        };
        Ok(CostReport {
            total,
            rmse,
            per_particle,
            terms,
        })
    }

    /// Masses (kg) and gravity (m/s², zero when the scene has none) of `p`.
    pub(crate) fn masses_gravity<'a>(&self, p: &'a [f64]) -> (&'a [f64], Vec3) {
        let l = &self.plan.layout;
        let m = &p[l.mass_offset..l.mass_offset + self.plan.n];
        let g = if self.plan.has_gravity {
            let o = l.gravity_offset;
            Vec3::new(p[o], p[o + 1], p[o + 2])
        } else {
            Vec3::zeros()
        };
        (m, g)
    }
}
