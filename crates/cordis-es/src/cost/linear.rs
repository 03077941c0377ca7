//! The precomputed short cost of linear-in-parameter scenes (SPEC §3, last paragraph).
//!
//! For springs, dampers, anchors, drags, angles, conditional links at a known range and
//! gravity, with known masses and no Provot limit or nonlinear drag, the force is linear in
//!
//! ```text
//! θ = per type, in catalogue order:
//!       spring, anchor, conditional: (K, K·l0, Z)      N/m, N, N·s/m
//!       damper, drag:                (Z)               N·s/m
//!       angle:                       (K, K·c0)         N·m, N·m
//!       (nonlinear_drag types without links contribute nothing; a muscle type makes the
//!       cost nonlinear through its neuron's tanh, so muscle scenes take the generic path)
//!     then, when the scene has gravity: (g_x, g_y, g_z)  m/s²
//! ```
//!
//! (entries listed by [`LinearShortCost::entries`]; a spring's Z is there even when its
//! damping is known to be 0). Every residual of the short cost is then affine in θ:
//! `r_i(t) = x̂_i(t) - x_i(t) = Σ_k θ_k φ_ik(t) + b_i(t)`, with `φ` and `b` computed from the
//! observed frames only. Summing the squares once per trajectory gives
//! `C(θ) = θᵀGθ + 2hᵀθ + c`, and each evaluation costs O(dim θ²) whatever the number of frames
//! and links.
//!
//! The sums are kept in square-root form ([`super::sqrt_form`]): a Gram form evaluated near
//! its minimum cancels catastrophically, the factor does not. Measured on an exact 5×4 cloth
//! trajectory at the generating parameters (true cost 0): Gram form 1.5e-17 m² (c = 3.7e-4,
//! so rounding of c), factor 3e-31 m²; away from the optimum or on noisy data both agree with
//! the generic path to ~1e-13 relative. An evolution strategy near convergence ranks candidates
//! by costs of that size, so the Gram form would rank them by rounding noise. One factor per free particle over the θ
//! entries that touch it gives the local costs (memory O(N · p_local²)), one global factor gives
//! the total; [`LinearShortCost::gram`] returns G, h, c for solvers that want them.

use super::observed::Observed;
use super::sqrt_form;
use crate::error::CostError;
use cordis_core::forces::unit_and_length;
use cordis_core::forces::MIN_LENGTH;
use cordis_core::{LinkKind, OptionalParam, Param, Plan, Scene, Trajectory, Vec3};

/// What one entry of θ is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ThetaEntry {
    /// K of a type (N/m; angles N·m).
    Stiffness { type_index: usize },
    /// K · l0 of a spring, anchor or conditional type (N).
    StiffnessRestLength { type_index: usize },
    /// K · c0 of an angle type (N·m).
    StiffnessRestCos { type_index: usize },
    /// Z of a type (N·s/m).
    Damping { type_index: usize },
    /// Gravity component along axis 0, 1 or 2 (m/s²).
    Gravity { axis: usize },
}

/// The short cost as quadratic forms in θ. Holds no per-frame data.
#[derive(Clone, Debug)]
pub struct LinearShortCost {
    entries: Vec<ThetaEntry>,
    /// `θ_k = p[a]`, or `p[a] · p[b]` when `b` is given.
    sources: Vec<(usize, Option<usize>)>,
    /// Values of `p` the forms were built with (free particles' masses, conditional ranges).
    pins: Vec<(usize, f64)>,
    param_len: usize,
    /// Number of particles N.
    n: usize,
    /// Local form l belongs to particle `particles[l]` and covers the θ entries
    /// `cols[cols_start[l]..cols_start[l + 1]]` (ascending).
    particles: Vec<usize>,
    cols_start: Vec<usize>,
    cols: Vec<usize>,
    /// Packed factors of the local forms, one after the other.
    forms_start: Vec<usize>,
    forms: Vec<f64>,
    /// Packed factor of the global form.
    global: Vec<f64>,
}

impl LinearShortCost {
    /// Builds the forms for `scene` observed as `traj`: `Ok(None)` when the scene is not linear
    /// in its parameters or has no form here (a Provot limit, a quadratic viscosity, a nonlinear drag link, an unknown mass of a free
    /// particle, a conditional type with an unknown range).
    pub fn new(scene: &Scene, traj: &Trajectory) -> Result<Option<Self>, CostError> {
        let plan = Plan::compile(scene)?;
        let obs = Observed::new(scene, &plan, traj, 3)?;
        Ok(Self::build(scene, &plan, &obs))
    }

    pub(crate) fn build(scene: &Scene, plan: &Plan, obs: &Observed) -> Option<Self> {
        if !short_form_applies(scene, plan) {
            return None;
        }
        let pins = pins(scene, plan, obs)?;
        let theta = Theta::of(scene, plan)?;
        let locals = Locals::new(plan, &theta);
        let forms = locals.factors(scene, plan, obs, &theta)?;
        let global = locals.global_factor(&forms, theta.entries.len());
        Some(LinearShortCost {
            entries: theta.entries,
            sources: theta.sources,
            pins,
            param_len: plan.layout.len,
            n: plan.n,
            particles: locals.particles,
            cols_start: locals.cols_start,
            cols: locals.cols,
            forms_start: locals.forms_start,
            forms,
            global,
        })
    }

    /// Number of θ entries.
    pub fn dim(&self) -> usize {
        self.entries.len()
    }

    /// What each θ entry is, in θ order (see the module docs).
    pub fn entries(&self) -> &[ThetaEntry] {
        &self.entries
    }

    /// True when `p` has the layout's length and the values the forms were built with for the
    /// free particles' masses and the conditional ranges (otherwise the forms do not apply).
    pub fn applies_to(&self, p: &[f64]) -> bool {
        p.len() == self.param_len && self.pins.iter().all(|&(k, v)| p[k] == v)
    }

    /// θ of a parameter vector into `theta` (lengths unchecked: crate-internal).
    pub(crate) fn theta_into(&self, p: &[f64], theta: &mut [f64]) {
        for (th, &(a, b)) in theta.iter_mut().zip(&self.sources) {
            *th = match b {
                Some(b) => p[a] * p[b],
                None => p[a],
            };
        }
    }

    /// θ of a parameter vector laid out as the scene's [`cordis_core::ParamLayout`].
    pub fn theta(&self, p: &[f64]) -> Result<Vec<f64>, CostError> {
        if p.len() != self.param_len {
            return Err(CostError::length(
                "parameter vector",
                self.param_len,
                p.len(),
            ));
        }
        let mut th = vec![0.0; self.dim()];
        self.theta_into(p, &mut th);
        Ok(th)
    }

    fn check_theta(&self, theta: &[f64]) -> Result<(), CostError> {
        if theta.len() != self.dim() {
            return Err(CostError::length("θ", self.dim(), theta.len()));
        }
        Ok(())
    }

    /// Global short cost at θ (m²), O(dim²); `+inf` instead of NaN or overflow.
    pub fn total(&self, theta: &[f64]) -> Result<f64, CostError> {
        self.check_theta(theta)?;
        Ok(self.total_unchecked(theta))
    }

    pub(crate) fn total_unchecked(&self, theta: &[f64]) -> f64 {
        finite_or_inf(sqrt_form::value(&self.global, self.dim(), |k| theta[k]))
    }

    /// Local costs at θ into `per_particle` (length N; fixed particles untouched), returns
    /// their sum (m²). O(Σ_i p_i²), p_i the number of θ entries that touch particle i.
    pub fn local(&self, theta: &[f64], per_particle: &mut [f64]) -> Result<f64, CostError> {
        self.check_theta(theta)?;
        if per_particle.len() != self.n {
            return Err(CostError::length(
                "local cost buffer",
                self.n,
                per_particle.len(),
            ));
        }
        Ok(self.local_unchecked(theta, per_particle))
    }

    pub(crate) fn local_unchecked(&self, theta: &[f64], per_particle: &mut [f64]) -> f64 {
        let mut total = 0.0;
        for (l, &i) in self.particles.iter().enumerate() {
            let c = &self.cols[self.cols_start[l]..self.cols_start[l + 1]];
            let form = &self.forms[self.forms_start[l]..self.forms_start[l + 1]];
            let v = finite_or_inf(sqrt_form::value(form, c.len(), |k| theta[c[k]]));
            per_particle[i] = v;
            total += v;
        }
        total
    }

    /// The Gram form: `G` (dim × dim, row-major), `h`, `c` with `C(θ) = θᵀGθ + 2hᵀθ + c`.
    pub fn gram(&self) -> (Vec<f64>, Vec<f64>, f64) {
        sqrt_form::gram(&self.global, self.dim())
    }

    /// The global factor: `R` (dim × dim upper-triangular, row-major), `q`, `ρ` with
    /// `C(θ) = |Rθ + q|² + ρ²` (a least-squares solution solves `Rθ = -q`).
    pub fn factor(&self) -> (Vec<f64>, Vec<f64>, f64) {
        let d = self.dim();
        let mut r = vec![0.0; d * d];
        let mut q = vec![0.0; d];
        let mut at = 0;
        for k in 0..d {
            for l in k..d {
                r[k * d + l] = self.global[at + l - k];
            }
            q[k] = self.global[at + d - k];
            at += d + 1 - k;
        }
        (r, q, self.global[at])
    }

    /// Number of numbers stored (f64 and indices): depends on the scene, never on the frame
    /// count.
    pub fn stored_values(&self) -> usize {
        self.sources.len() * 2
            + self.pins.len() * 2
            + self.particles.len()
            + self.cols_start.len()
            + self.cols.len()
            + self.forms_start.len()
            + self.forms.len()
            + self.global.len()
    }
}

fn finite_or_inf(v: f64) -> f64 {
    if v < f64::INFINITY {
        v
    } else {
        f64::INFINITY
    }
}

fn same_type(a: &ThetaEntry, b: &ThetaEntry) -> bool {
    let t = |e: &ThetaEntry| match *e {
        ThetaEntry::Stiffness { type_index }
        | ThetaEntry::StiffnessRestLength { type_index }
        | ThetaEntry::StiffnessRestCos { type_index }
        | ThetaEntry::Damping { type_index } => Some(type_index),
        ThetaEntry::Gravity { .. } => None,
    };
    t(a) == t(b)
}

/// Whether the scene's kinds and plan allow the precomputed form (unknown masses, muscles
/// and TGRs are refused later, by [`pins`] and [`Theta::of`]). Several worlds (per-particle
/// dt and gravity on the main world only) take the generic path (such scenes couple worlds
/// through nonlinear couplings anyway); a quadratic viscosity's θ (Z₂) has no entry here: the
/// generic design takes it.
fn short_form_applies(scene: &Scene, plan: &Plan) -> bool {
    let quadratic = scene
        .types
        .iter()
        .any(|t| t.optional_param(OptionalParam::DampingQuadratic).is_some());
    !quadratic
        && plan.provot.links.is_empty()
        && plan.nonlinear_drags.particles.is_empty()
        && plan.worlds.is_none()
}

/// The parameter values the forms are built with: every free particle's mass (`None` when one
/// is unknown) and every conditional type's range (`None` when its pairs were not listed).
fn pins(scene: &Scene, plan: &Plan, obs: &Observed) -> Option<Vec<(usize, f64)>> {
    let mut pins = Vec::new();
    for i in (0..plan.n).filter(|&i| plan.free[i]) {
        match scene.particles[i].mass {
            Param::Known(m) => pins.push((plan.layout.mass_offset + i, m)),
            Param::Unknown(_) => return None,
        }
    }
    for (c, pairs) in plan.conditionals.iter().zip(&obs.pairs) {
        pins.push((c.param + 3, pairs.as_ref()?.range));
    }
    Some(pins)
}

/// The θ layout (module docs).
struct Theta {
    entries: Vec<ThetaEntry>,
    sources: Vec<(usize, Option<usize>)>,
    /// Where each type's θ starts, indexed by the type's parameter offset.
    at: Vec<usize>,
    /// The first of the three gravity entries, when the scene has gravity.
    gravity: Option<usize>,
}

impl Theta {
    /// `None` when a type has no entries here: muscles and TGRs (their force is not linear
    /// in their parameters) and any kind not listed.
    fn of(scene: &Scene, plan: &Plan) -> Option<Theta> {
        let layout = &plan.layout;
        let mut entries = Vec::new();
        let mut sources = Vec::new();
        let mut at = vec![usize::MAX; layout.len];
        for (t, ty) in scene.types.iter().enumerate() {
            let o = layout.type_offsets[t];
            let ti = t;
            let these: &[(ThetaEntry, (usize, Option<usize>))] = match ty.kind {
                LinkKind::Spring | LinkKind::Anchor | LinkKind::Conditional => &[
                    (ThetaEntry::Stiffness { type_index: ti }, (o, None)),
                    (
                        ThetaEntry::StiffnessRestLength { type_index: ti },
                        (o, Some(o + 1)),
                    ),
                    (ThetaEntry::Damping { type_index: ti }, (o + 2, None)),
                ],
                LinkKind::Damper | LinkKind::Drag => {
                    &[(ThetaEntry::Damping { type_index: ti }, (o, None))]
                }
                LinkKind::Angle => &[
                    (ThetaEntry::Stiffness { type_index: ti }, (o, None)),
                    (
                        ThetaEntry::StiffnessRestCos { type_index: ti },
                        (o, Some(o + 1)),
                    ),
                ],
                LinkKind::NonlinearDrag => &[], // no links (checked above): no effect
                // A neuron's tanh makes the muscle force nonlinear in its weights.
                LinkKind::Muscle => return None,
                // A tendon's hidden state depends on the parameters through its feedback.
                LinkKind::Tgr => return None,
                _ => return None,
            };
            at[o] = entries.len();
            for &(e, src) in these {
                entries.push(e);
                sources.push(src);
            }
        }
        let gravity = plan.has_gravity.then(|| {
            let at = entries.len();
            for axis in 0..3 {
                entries.push(ThetaEntry::Gravity { axis });
                sources.push((layout.gravity_offset + axis, None));
            }
            at
        });
        Some(Theta {
            entries,
            sources,
            at,
            gravity,
        })
    }

    /// The number of θ entries of the type whose first entry is `t0`.
    fn width(&self, t0: usize) -> usize {
        let dim = self.entries.len();
        (t0 + 1..=dim)
            .find(|&k| k == dim || !same_type(&self.entries[t0], &self.entries[k]))
            .unwrap_or(dim)
            - t0
    }
}

/// The local forms' layout: one per free particle, over the θ entries that touch it.
struct Locals {
    /// Local form l belongs to particle `particles[l]` and covers the θ entries
    /// `cols[cols_start[l]..cols_start[l + 1]]` (ascending).
    particles: Vec<usize>,
    cols_start: Vec<usize>,
    cols: Vec<usize>,
    /// Each particle's form (`usize::MAX` for fixed particles).
    form_of: Vec<usize>,
    /// Where each form's packed factor starts, and its frame rows in [`Acc::phi`].
    forms_start: Vec<usize>,
    row_start: Vec<usize>,
}

impl Locals {
    fn new(plan: &Plan, theta: &Theta) -> Locals {
        let mut touch: Vec<Vec<usize>> = vec![Vec::new(); plan.n];
        let mut mark = |i: usize, param: usize| {
            let t0 = theta.at[param];
            touch[i].extend(t0..t0 + theta.width(t0));
        };
        for_each_item(plan, |param, ps| ps.iter().for_each(|&i| mark(i, param)));
        for c in &plan.conditionals {
            for &i in c.a.iter().chain(c.b.iter().flatten()) {
                mark(i as usize, c.param);
            }
        }
        let mut particles = Vec::new();
        let mut cols_start = vec![0];
        let mut cols = Vec::new();
        let mut form_of = vec![usize::MAX; plan.n];
        for i in (0..plan.n).filter(|&i| plan.free[i]) {
            let mut c = std::mem::take(&mut touch[i]);
            if let Some(g) = theta.gravity {
                c.extend(g..g + 3);
            }
            c.sort_unstable();
            c.dedup();
            form_of[i] = particles.len();
            particles.push(i);
            cols.extend(c);
            cols_start.push(cols.len());
        }
        let nl = particles.len();
        let local_dim = |l: usize| cols_start[l + 1] - cols_start[l];
        let mut forms_start = vec![0];
        let mut row_start = vec![0];
        for l in 0..nl {
            forms_start.push(forms_start[l] + sqrt_form::packed_len(local_dim(l)));
            row_start.push(row_start[l] + 3 * (local_dim(l) + 1));
        }
        Locals {
            particles,
            cols_start,
            cols,
            form_of,
            forms_start,
            row_start,
        }
    }

    fn local_dim(&self, l: usize) -> usize {
        self.cols_start[l + 1] - self.cols_start[l]
    }

    /// Every frame's rows `[φ | b]` rotated into the local factors (packed, one after the
    /// other). `None` when a conditional type's pairs were not listed.
    fn factors(
        &self,
        scene: &Scene,
        plan: &Plan,
        obs: &Observed,
        theta: &Theta,
    ) -> Option<Vec<f64>> {
        let nl = self.particles.len();
        let mut forms = vec![0.0; self.forms_start[nl]];
        let dt2 = plan.dt * plan.dt;
        let coef: Vec<f64> = (0..plan.n)
            .map(|i| match scene.particles[i].mass {
                Param::Known(m) if plan.free[i] => dt2 / m,
                _ => 0.0,
            })
            .collect();
        let mut acc = Acc {
            locals: self,
            coef: &coef,
            phi: vec![0.0; self.row_start[nl]],
        };
        for t in 2..obs.frames {
            acc.phi.fill(0.0);
            acc.links(plan, obs, t - 1, &theta.at)?;
            let (x1, x2, x0) = (obs.frame(t - 1), obs.frame(t - 2), obs.frame(t));
            for (l, &i) in self.particles.iter().enumerate() {
                let p_l = self.local_dim(l);
                let stride = p_l + 1;
                let base = self.row_start[l];
                let b = (x1[i] * 2.0 - x2[i]) - x0[i];
                let gc = theta.gravity.map(|g| acc.col(l, g));
                for r in 0..3 {
                    let row = &mut acc.phi[base + r * stride..base + (r + 1) * stride];
                    row[p_l] = b[r];
                    if let Some(gc) = gc {
                        row[gc + r] += dt2;
                    }
                    let form = &mut forms[self.forms_start[l]..self.forms_start[l + 1]];
                    sqrt_form::add_row(form, p_l, row);
                }
            }
        }
        Some(forms)
    }

    /// The global factor: the local factors' rows, spread over the whole θ (`dim` entries).
    fn global_factor(&self, forms: &[f64], dim: usize) -> Vec<f64> {
        let mut global = vec![0.0; sqrt_form::packed_len(dim)];
        let mut row = vec![0.0; dim + 1];
        for l in 0..self.particles.len() {
            let p_l = self.local_dim(l);
            let c = &self.cols[self.cols_start[l]..self.cols_start[l + 1]];
            let form = &forms[self.forms_start[l]..self.forms_start[l + 1]];
            let mut at = 0;
            for k in 0..=p_l {
                row.fill(0.0);
                for kk in k..p_l {
                    row[c[kk]] = form[at + kk - k];
                }
                row[dim] = form[at + p_l - k];
                at += p_l + 1 - k;
                sqrt_form::add_row(&mut global, dim, &mut row);
            }
        }
        global
    }
}

/// Calls `visit(type param offset, particles)` for every listed link instance of the plan.
fn for_each_item(plan: &Plan, mut visit: impl FnMut(usize, &[usize])) {
    for r in &plan.springs.runs {
        for &[i, j] in &plan.springs.pairs[r.start..r.end] {
            visit(r.param, &[i as usize, j as usize]);
        }
    }
    for r in &plan.dampers.runs {
        for &[i, j] in &plan.dampers.pairs[r.start..r.end] {
            visit(r.param, &[i as usize, j as usize]);
        }
    }
    for r in &plan.anchors.runs {
        for &i in &plan.anchors.particles[r.start..r.end] {
            visit(r.param, &[i as usize]);
        }
    }
    for r in &plan.drags.runs {
        for &i in &plan.drags.particles[r.start..r.end] {
            visit(r.param, &[i as usize]);
        }
    }
    for r in &plan.angles.runs {
        for &[i, j, k] in &plan.angles.triples[r.start..r.end] {
            visit(r.param, &[i as usize, j as usize, k as usize]);
        }
    }
}

/// One frame's rows `[φ | b]` of every free particle, 3 rows (x, y, z) each.
struct Acc<'a> {
    locals: &'a Locals,
    /// dt²/m_i (0 for fixed particles).
    coef: &'a [f64],
    phi: Vec<f64>,
}

impl Acc<'_> {
    /// Local column of θ entry `theta` in form l.
    fn col(&self, l: usize, theta: usize) -> usize {
        let c = &self.locals.cols[self.locals.cols_start[l]..self.locals.cols_start[l + 1]];
        c.binary_search(&theta).unwrap_or(0)
    }

    /// Every link's force per unit of its θ entries at frame `f` (`theta_at`: where each
    /// type's θ starts). `None` when a conditional type's pairs were not listed.
    fn links(&mut self, plan: &Plan, obs: &Observed, f: usize, theta_at: &[usize]) -> Option<()> {
        let (x, v) = (obs.frame(f), obs.velocity(f));
        let th = |param: usize| theta_at[param];
        for r in &plan.springs.runs {
            for &[i, j] in &plan.springs.pairs[r.start..r.end] {
                self.spring(th(r.param), i as usize, j as usize, x, v);
            }
        }
        for r in &plan.dampers.runs {
            for &[i, j] in &plan.dampers.pairs[r.start..r.end] {
                let (i, j) = (i as usize, j as usize);
                let w = v[j] - v[i];
                self.add(i, th(r.param), 0, w);
                self.add(j, th(r.param), 0, -w);
            }
        }
        let a = &plan.anchors;
        for r in &a.runs {
            for (&i, point) in a.particles[r.start..r.end]
                .iter()
                .zip(&a.points[r.start..r.end])
            {
                let i = i as usize;
                let (u, len) = unit_and_length(&(point - x[i]));
                let s = (-v[i]).dot(&u);
                let t0 = th(r.param);
                self.add(i, t0, 0, u * len);
                self.add(i, t0, 1, -u);
                self.add(i, t0, 2, u * s);
            }
        }
        for r in &plan.drags.runs {
            for &i in &plan.drags.particles[r.start..r.end] {
                self.add(i as usize, th(r.param), 0, -v[i as usize]);
            }
        }
        for r in &plan.angles.runs {
            for &[i, j, k] in &plan.angles.triples[r.start..r.end] {
                self.angle(th(r.param), [i as usize, j as usize, k as usize], x);
            }
        }
        for (c, pairs) in plan.conditionals.iter().zip(&obs.pairs) {
            let pairs = pairs.as_ref()?;
            for &[i, j] in pairs.at(f) {
                self.spring(th(c.param), i as usize, j as usize, x, v);
            }
        }
        Some(())
    }

    /// Adds force direction `w` (force per unit of θ entry `t0 + k`) on particle i.
    fn add(&mut self, i: usize, t0: usize, k: usize, w: Vec3) {
        let l = self.locals.form_of[i];
        if l == usize::MAX {
            return;
        }
        let c = self.col(l, t0) + k;
        let stride = self.locals.local_dim(l) + 1;
        let base = self.locals.row_start[l];
        let coef = self.coef[i];
        for r in 0..3 {
            self.phi[base + r * stride + c] += coef * w[r];
        }
    }

    /// `F_i = K (L u) - K l0 u + Z s u`, `F_j = -F_i`.
    fn spring(&mut self, t0: usize, i: usize, j: usize, x: &[Vec3], v: &[Vec3]) {
        let (u, len) = unit_and_length(&(x[j] - x[i]));
        let s = (v[j] - v[i]).dot(&u);
        for (k, w) in [u * len, -u, u * s].into_iter().enumerate() {
            self.add(i, t0, k, w);
            self.add(j, t0, k, -w);
        }
    }

    /// `F_i = -K (c - c0) ∂c/∂a = K (-c ∂c/∂a) + K c0 (∂c/∂a)`; likewise k; j gets minus both.
    fn angle(&mut self, t0: usize, [i, j, k]: [usize; 3], x: &[Vec3]) {
        let a = x[i] - x[j];
        let b = x[k] - x[j];
        let (la, lb) = (a.norm(), b.norm());
        if la <= MIN_LENGTH || lb <= MIN_LENGTH {
            return;
        }
        let inv_ab = 1.0 / (la * lb);
        let c = a.dot(&b) * inv_ab;
        let dc_da = b * inv_ab - a * (c / (la * la));
        let dc_db = a * inv_ab - b * (c / (lb * lb));
        self.add(i, t0, 0, dc_da * -c);
        self.add(i, t0, 1, dc_da);
        self.add(k, t0, 0, dc_db * -c);
        self.add(k, t0, 1, dc_db);
        self.add(j, t0, 0, (dc_da + dc_db) * c);
        self.add(j, t0, 1, -(dc_da + dc_db));
    }
}
