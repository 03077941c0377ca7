//! What the exact solvers share ([`crate::strategies::least_squares`], [`crate::strategies::hybrid`]): the short cost of
//! a scene whose forces are linear in θ written as a least-squares system, reduced to the
//! unknowns, and solved by SVD with rank, box and total-mass handling.
//!
//! **θ** (the columns, [`Col`]): per type `(K, K·l0, Z)` for springs, anchors and conditional
//! links (at a given range), `(Z)` for dampers and drags, `(z1, z2)` for a nonlinear drag (at a
//! given v_max), `(K, K·c0)` for angles; gravity is known (a constant); and `Z₂` of a spring
//! or conditional type with a `damping_quadratic` (its force `Z₂ s |s|` is linear in Z₂ at
//! the observed rates). Every prediction residual is affine in θ.
//!
//! **Provot's τc** (`max_elongation`) is refused when it is unknown, by name: the solvers
//! leave out the rows the limit acts on ([`self::provot_rows`]), and those rows are the only
//! ones that depend on τc, so the system carries no information on it. Profiling it as a
//! range is not sound either: the rows left out grow as τc falls, and a cost over fewer rows
//! is smaller, so the profile would fall to the smallest τc whatever the data. A known τc is
//! used as before.
//!
//! **The system** ([`System`]): blocks of rows `[Φ | a]` whose sum of squares `Σ |Φθ + m a|²`
//! is the cost. Either one block from [`LinearShortCost::factor`] (known masses, position space:
//! exactly the short cost, `m = 1`), or one block per free particle from [`assemble`]
//! (force space: the rows are the particle's `dt² F_i(θ) + m_i (dt² g - dt² a_i)`, `a_i` its
//! observed acceleration, compressed to a triangular factor). A force-space block is turned
//! into the short cost's rows by dividing Φ by the particle's mass (position weighting), or
//! used as is with the mass unknown (force weighting, [`Weighting`]).
//!
//! **The reduction** to the unknowns ξ: a known parameter is a constant; a type with unknown K
//! and unknown l0 contributes ξ = (K, K·l0) and `l0 = (K·l0)/K` afterwards; with one of them
//! known the other is the unknown itself (`θ_{K·l0} = l0 · ξ_K` or `K · ξ_{l0}`). So θ = Aξ + c
//! and the cost is `|D ξ + d|²` with `D`, `d` from the blocks.
//!
//! **Free masses** (force weighting): each particle's mass is eliminated from its own rows by
//! a QR whose first column is the mass: the first row `ρ_i m_i + s_iᵀξ + c_i` is the only one
//! that involves `m_i`, the others go to the global system. Under a known total `Σ m_i = M` the
//! first rows' residuals `e_i` are no longer free: the least `Σ e_i²` with `Σ e_i/ρ_i = γ(ξ)`
//! (γ affine in ξ) is `γ²/Σ ρ_i⁻²`, one more row of the global system. Without a total the
//! first rows are fitted exactly (the scale then comes from a known parameter or mass).
//!
//! **Solving**: SVD of the column-equilibrated `D` (each column scaled to unit norm, so that
//! the condition number compares unknowns of different units fairly). A singular value below
//! [`RANK_TOL`] × the largest means the data cannot determine a combination of unknowns: the
//! unknowns loading on its singular vector are reported **undetermined** and the one loading
//! most is held at its starting value, then the system is solved again. An unknown that comes
//! out of its box is clamped onto the box and held there, the worst one first, and the system
//! solved again (an active-set heuristic: each clamp is optimal for the others, not a full
//! bounded least-squares search). Both are reported.
//!
//! This folder is the linear-solver library under `least-squares` and `hybrid` (design
//! assembly, reduction and solve, Provot rows, TGR columns, the cached design, range sweeps,
//! the 1-D profile search); the strategies themselves live in [`crate::strategies`].

pub(crate) mod design;
pub(crate) mod profile;
pub mod provot_rows;
pub mod range_sweep;
pub(crate) mod row_mask;
pub(crate) mod tgr_cols;

use std::collections::HashMap;

use cordis_core::{LinkKind, OptionalParam, Param, Scene, Vec3};
use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use self::row_mask::RowMask;
use crate::cost::{CostKind, CostScratch, LinearShortCost, Objective, ThetaEntry};
use crate::error::CostError;
use crate::linalg::equilibrated::{lsq, Lsq};
pub(crate) use crate::linalg::givens::Factor;
use crate::problem::space::Role;
use crate::problem::Problem;
pub use crate::report::ExactReport;
use crate::run::float_json::{bits, lossless};
use crate::run::strategy::{GenerationStats, Strategy};

pub use crate::linalg::equilibrated::RANK_TOL;

/// Above this condition number an identified value is reported as poorly determined (data
/// noise of relative size ε moves it by up to ~ε × condition).
pub const POOR_CONDITION: f64 = 1e8;

/// One entry of θ.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Col {
    /// K of type t (N/m; angles N·m).
    K(usize),
    /// K·l0 (N) or K·c0 (N·m) of type t.
    KRest(usize),
    /// Z of type t (N·s/m), or z1 of a nonlinear drag.
    Z(usize),
    /// z2 of a nonlinear drag (N·s/m).
    Z2(usize),
    /// Gravity along an axis (m/s²), always known.
    G(usize),
    /// Rest length l0 of TGR type t (m), at the TGR's K and tendon in `p`: its force is affine
    /// in (l0, Z) through the tendon (see [`self::tgr_cols`]).
    Rest(usize),
    /// Z₂ of type t (N·s²/m²): a spring's or conditional type's `damping_quadratic`.
    Quadratic(usize),
    /// θ = 1: the forces at every linear parameter 0 with the nonlinear ones in `p` (a TGR's
    /// `K (L - y)` at l0 = Z = 0 and the signal's push through the tendon), N.
    Known,
}

/// Rows `[Φ | a]` (`cols + 1` columns) of one particle (`Some(i)`: a force-space block whose
/// `a` column is multiplied by the particle's mass) or of the whole cost (`None`: position space,
/// `a` multiplied by 1).
#[derive(Clone, Debug)]
pub(crate) struct Block {
    pub particle: Option<usize>,
    pub rows: DMatrix<f64>,
}

#[derive(Clone, Debug)]
pub(crate) struct System {
    pub cols: Vec<Col>,
    pub blocks: Vec<Block>,
    /// Some rows of the short cost are left out (Provot's, [`self::provot_rows`]): the
    /// system's minimum is then not the cost.
    pub partial: bool,
}

/// How force-space blocks enter the cost.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Weighting {
    /// Divided by the (known) mass: exactly the short cost.
    Position,
    /// As they are, masses unknown allowed: the short cost with particle i's terms weighted
    /// by m_i² (the only weighting in which the residual is linear in the masses).
    Force,
}

/// The θ columns of a scene for [`assemble`], or why its short cost is not linear in θ.
pub(crate) fn generic_cols(scene: &Scene) -> Result<Vec<Col>, String> {
    if let Some(i) = (0..scene.particles.len()).find(|&i| scene.world_of(i) != 0) {
        return Err(format!(
            "particles[{i}].world: the exact solvers assume one time step and gravity on every \
             particle, not several worlds"
        ));
    }
    let mut cols = Vec::new();
    for (t, ty) in scene.types.iter().enumerate() {
        if ty.max_elongation().is_some_and(Param::is_unknown) {
            return Err(format!(
                "types.{}.max_elongation: the exact solvers leave out the rows Provot's limit \
                 acts on, the only rows that depend on τc, so they cannot identify it: use \
                 levenberg-marquardt or an evolution strategy",
                ty.name
            ));
        }
        match ty.kind {
            LinkKind::Spring | LinkKind::Anchor | LinkKind::Conditional => {
                cols.extend([Col::K(t), Col::KRest(t), Col::Z(t)]);
                if ty.optional_param(OptionalParam::DampingQuadratic).is_some() {
                    cols.push(Col::Quadratic(t));
                }
            }
            LinkKind::Damper | LinkKind::Drag => cols.push(Col::Z(t)),
            LinkKind::NonlinearDrag => cols.extend([Col::Z(t), Col::Z2(t)]),
            LinkKind::Angle => cols.extend([Col::K(t), Col::KRest(t)]),
            LinkKind::Muscle => {
                return Err(format!(
                    "types.{}: a muscle's neuron (tanh) makes the short cost nonlinear",
                    ty.name
                ))
            }
            LinkKind::Tgr => cols.extend(self::tgr_cols::cols(t)),
            LinkKind::Plane => {
                return Err(format!(
                    "types.{}: a plane's contact force `max(0, K d - Z v_n)` is clamped at 0 and \
                     its friction is proportional to it, so the short cost is not linear in \
                     (stiffness, damping, friction): use levenberg-marquardt or an evolution \
                     strategy",
                    ty.name
                ))
            }
            #[allow(unreachable_patterns)]
            other => {
                return Err(format!(
                    "types.{}: kind `{}` is not supported by the exact solvers",
                    ty.name,
                    other.name()
                ))
            }
        }
    }
    if scene.types.iter().any(|ty| ty.kind == LinkKind::Tgr) {
        cols.push(Col::Known);
    }
    Ok(cols)
}

/// Why the exact solvers cannot run on a problem (`Ok` when they can).
pub(crate) fn supported(problem: &Problem) -> Result<(), String> {
    let kind = problem.objective.kind();
    if problem.objective.window() != Some(1) || matches!(kind, CostKind::Harmonic { .. }) {
        return Err(format!(
            "the exact solvers minimise the short cost, not `{kind}`"
        ));
    }
    generic_cols(&problem.scene).map(|_| ())
}

/// The system of a [`LinearShortCost`]: its global factor as one position-space block.
pub(crate) fn from_linear(lin: &LinearShortCost) -> System {
    let (r, q, rho) = lin.factor();
    let d = lin.dim();
    let mut rows = DMatrix::zeros(d + 1, d + 1);
    for k in 0..d {
        for l in k..d {
            rows[(k, l)] = r[k * d + l];
        }
        rows[(k, d)] = q[k];
    }
    rows[(d, d)] = rho;
    let cols = lin
        .entries()
        .iter()
        .map(|e| match *e {
            ThetaEntry::Stiffness { type_index } => Col::K(type_index),
            ThetaEntry::StiffnessRestLength { type_index }
            | ThetaEntry::StiffnessRestCos { type_index } => Col::KRest(type_index),
            ThetaEntry::Damping { type_index } => Col::Z(type_index),
            ThetaEntry::Gravity { axis } => Col::G(axis),
        })
        .collect();
    System {
        cols,
        blocks: vec![Block {
            particle: None,
            rows,
        }],
        partial: false,
    }
}

/// Parameter slot of a column's linear parameter: K, the rest parameter, Z (z1) or z2.
pub(crate) fn slots(scene: &Scene, t: usize) -> (usize, usize, usize) {
    let o = scene.param_layout().type_offsets[t];
    match scene.types[t].kind {
        LinkKind::Damper | LinkKind::Drag | LinkKind::NonlinearDrag => (o, o + 1, o),
        _ => (o, o + 1, o + 2),
    }
}

/// Slot of type t's Z₂ (`damping_quadratic`); t must have one.
pub(crate) fn quadratic_slot(scene: &Scene, t: usize) -> usize {
    let k = scene.types[t]
        .optional_index(OptionalParam::DampingQuadratic)
        .expect("a Quadratic column's type has damping_quadratic");
    scene.param_layout().type_offsets[t] + k
}

/// The slots of the θ-linear parameters of every type (K, l0, Z, c0, z1, z2, Z₂): not
/// ranges and not v_max.
fn linear_slots(scene: &Scene) -> Vec<usize> {
    let layout = scene.param_layout();
    let mut out = Vec::new();
    for (t, ty) in scene.types.iter().enumerate() {
        let o = layout.type_offsets[t];
        let n = match ty.kind {
            LinkKind::Damper | LinkKind::Drag => 1,
            LinkKind::Angle | LinkKind::NonlinearDrag => 2,
            _ => 3,
        };
        if ty.kind == LinkKind::Tgr {
            // K stays: a TGR's force is linear in (l0, Z) only at a given K.
            out.extend(o + 1..o + 3);
            continue;
        }
        out.extend(o..o + n);
        if let Some(k) = ty.optional_index(OptionalParam::DampingQuadratic) {
            out.push(o + k);
        }
    }
    out
}

/// Builds the force-space blocks of the short cost at the nonlinear values in `p` (ranges,
/// v_max; the linear parameters in `p` are ignored). Each θ column's forces come from the
/// scene's own force passes run on a probe parameter vector (the column's parameter 1, every
/// other linear one 0; `K·l0` as the difference of `K = 1, l0 = 1` and `K = 1, l0 = 0`), so
/// the design is the cost's own arithmetic. Cost: (columns + 1) force passes per frame.
/// Provot's pass is not applied: on a scene with a limit use [`assemble_masked`].
pub(crate) fn assemble(obj: &Objective, scene: &Scene, cols: &[Col], p: &[f64]) -> System {
    assemble_masked(obj, scene, cols, p, None)
}

/// [`assemble`] without the rows (frame, particle) that `dropped` marks.
pub(crate) fn assemble_masked(
    obj: &Objective,
    scene: &Scene,
    cols: &[Col],
    p: &[f64],
    dropped: Option<&RowMask>,
) -> System {
    let nc = cols.len();
    let free = &obj.free;
    let mut factors: Vec<Factor> = free.iter().map(|_| Factor::new(nc + 1)).collect();
    let none = vec![false; nc];
    design_rows(obj, scene, cols, p, &none, dropped, |_, l, row| {
        factors[l].add_row(row)
    });
    System {
        cols: cols.to_vec(),
        blocks: free
            .iter()
            .zip(factors)
            .map(|(&i, f)| Block {
                particle: Some(i),
                rows: f.matrix(),
            })
            .collect(),
        partial: dropped.is_some(),
    }
}

/// The force-space rows of [`assemble_masked`], uncompressed: `visit(frame, l, row)` for every
/// frame the short cost computes forces at (`frame` = 0 for observed frame 1 …), free particle
/// `l` (index into `obj.free`) and axis, in that order (frame-major, then particle, then axis),
/// except the rows `dropped` marks; `row` holds `nc + 1` values and may be destroyed. Columns
/// flagged in `zero_cols` are known to vanish at `p` (a conditional type with range 0): their
/// force passes are skipped.
pub(crate) fn design_rows(
    obj: &Objective,
    scene: &Scene,
    cols: &[Col],
    p: &[f64],
    zero_cols: &[bool],
    dropped: Option<&RowMask>,
    mut visit: impl FnMut(usize, usize, &mut [f64]),
) {
    let plan = obj.plan();
    let nc = cols.len();
    let mut forces = ColumnForces::new(obj, scene, cols, p, zero_cols);
    let dt2 = plan.dt * plan.dt;
    let layout = &plan.layout;
    let g = if plan.has_gravity {
        let o = layout.gravity_offset;
        Vec3::new(p[o], p[o + 1], p[o + 2])
    } else {
        Vec3::zeros()
    };
    let mut row = vec![0.0; nc + 1];
    for t in 2..obj.obs.frames {
        forces.advance(t);
        let (x1, x2, x0) = (obj.obs.frame(t - 1), obj.obs.frame(t - 2), obj.obs.frame(t));
        for (l, &i) in obj.free.iter().enumerate() {
            if dropped.is_some_and(|d| d.get(t, i)) {
                continue;
            }
            let b = (x1[i] * 2.0 - x2[i]) - x0[i];
            for r in 0..3 {
                forces.columns(i, r, dt2, &mut row[..nc]);
                row[nc] = dt2 * g[r] + b[r];
                visit(t - 2, l, &mut row);
            }
        }
    }
}

/// The forces per unit of each column's unknown along the observed frames, for
/// [`design_rows`]: the scene's own force passes run at a probe per column (its unknown at 1,
/// every linear one at 0) and at the zero probe, each probe driving its own hidden state.
struct ColumnForces<'a> {
    obj: &'a Objective,
    cols: &'a [Col],
    zero_cols: &'a [bool],
    /// `p` with every linear slot at 0.
    zero: Vec<f64>,
    /// Per column: its probe, and the column whose probe's force is its base (K·l0's probe, K
    /// at 1 too, carries K's force), `None`: the zero probe's.
    probes: Vec<(Vec<f64>, Option<usize>)>,
    s: CostScratch,
    /// Hidden state (TGR tendons) of the zero probe (0) and of every probe (k + 1), each
    /// driven along the observed frames by its own parameters, as the short cost drives it.
    states: Vec<f64>,
    /// The zero probe's forces and each column probe's, at the frame last advanced to.
    f0: Vec<Vec3>,
    raw: Vec<Vec<Vec3>>,
}

impl<'a> ColumnForces<'a> {
    fn new(
        obj: &'a Objective,
        scene: &Scene,
        cols: &'a [Col],
        p: &[f64],
        zero_cols: &'a [bool],
    ) -> Self {
        let n = obj.plan().n;
        let nc = cols.len();
        let mut zero = p.to_vec();
        for s in linear_slots(scene) {
            zero[s] = 0.0;
        }
        let probes = column_probes(scene, cols, &zero);
        let mut s = obj.scratch();
        let h = s.hidden.len();
        let mut states = vec![0.0; h * (nc + 1)];
        if h > 0 {
            let all = std::iter::once(&zero).chain(probes.iter().map(|(q, _)| q));
            for (q, st) in all.zip(states.chunks_mut(h)) {
                obj.reset_hidden(q, st);
                obj.advance_hidden_observed(q, 0, st, &mut s.discard);
            }
        }
        ColumnForces {
            obj,
            cols,
            zero_cols,
            zero,
            probes,
            s,
            states,
            f0: vec![Vec3::zeros(); n],
            raw: vec![vec![Vec3::zeros(); n]; nc],
        }
    }

    /// The forces at observed frame `t - 1`, each probe's hidden state advanced past it.
    fn advance(&mut self, t: usize) {
        let (obj, s) = (self.obj, &mut self.s);
        let geo = obj.geometry();
        let h = s.hidden.len();
        s.hidden.copy_from_slice(&self.states[..h]);
        obj.observed_forces(&self.zero, t - 1, s, geo);
        self.states[..h].copy_from_slice(&s.hidden);
        self.f0.copy_from_slice(&s.core.f);
        for (k, (q, _)) in self.probes.iter().enumerate() {
            if self.cols[k] == Col::Known || self.zero_cols[k] {
                continue;
            }
            let st = &mut self.states[h * (k + 1)..h * (k + 2)];
            s.hidden.copy_from_slice(st);
            obj.observed_forces(q, t - 1, s, geo);
            st.copy_from_slice(&s.hidden);
            self.raw[k].copy_from_slice(&s.core.f);
        }
    }

    /// The columns of particle `i`'s row on axis `r` at the frame last advanced to, dt² × the
    /// force per unit of each unknown (the known forces' for [`Col::Known`]).
    fn columns(&self, i: usize, r: usize, dt2: f64, row: &mut [f64]) {
        for (k, (_, reference)) in self.probes.iter().enumerate() {
            if self.cols[k] == Col::Known {
                row[k] = dt2 * self.f0[i][r];
                continue;
            }
            if self.zero_cols[k] {
                row[k] = 0.0;
                continue;
            }
            let base = match reference {
                Some(j) => self.raw[*j][i][r],
                None => self.f0[i][r],
            };
            row[k] = dt2 * (self.raw[k][i][r] - base);
        }
    }
}

/// Per column, the parameters that isolate its force: `zero` (every linear slot at 0) with the
/// column's unknown at 1; and for K·l0, whose probe has K at 1 too, the K column whose force
/// is subtracted.
fn column_probes(scene: &Scene, cols: &[Col], zero: &[f64]) -> Vec<(Vec<f64>, Option<usize>)> {
    let mut probes: Vec<(Vec<f64>, Option<usize>)> = Vec::with_capacity(cols.len());
    for (k, c) in cols.iter().enumerate() {
        let mut q = zero.to_vec();
        let reference = match *c {
            Col::K(t) => {
                q[slots(scene, t).0] = 1.0;
                None
            }
            Col::KRest(t) => {
                let (ks, rs, _) = slots(scene, t);
                q[ks] = 1.0;
                q[rs] = 1.0;
                cols[..k].iter().position(|&c| c == Col::K(t))
            }
            Col::Z(t) => {
                q[slots(scene, t).2] = 1.0;
                None
            }
            Col::Z2(t) => {
                q[slots(scene, t).1] = 1.0;
                None
            }
            Col::G(_) => None, // never a generic column: gravity is in the `a` column
            Col::Rest(t) => {
                q[slots(scene, t).1] = 1.0;
                None
            }
            Col::Quadratic(t) => {
                q[quadratic_slot(scene, t)] = 1.0;
                None
            }
            Col::Known => None, // the zero probe itself (not run again below)
        };
        probes.push((q, reference));
    }
    probes
}

/// One unknown of the reduced problem: `p[slot] = ξ`, or `ξ / ξ[per]` (a rest length or cosine
/// recovered from K·l0 and K).
#[derive(Clone, Copy, Debug)]
struct Xi {
    slot: usize,
    per: Option<usize>,
}

/// θ = Aξ + c: per column, at most one term (ξ index, coefficient), and a constant.
pub(crate) struct Reduction {
    xi: Vec<Xi>,
    pub terms: Vec<Option<(usize, f64)>>,
    consts: Vec<f64>,
}

impl Reduction {
    /// Number of reduced unknowns ξ.
    pub fn len(&self) -> usize {
        self.xi.len()
    }
}

/// The value of θ column `c` at the full parameter vector `p`.
pub(crate) fn theta_of(scene: &Scene, c: Col, p: &[f64]) -> f64 {
    match c {
        Col::K(t) | Col::Z(t) | Col::Z2(t) => {
            let (ks, rs, zs) = slots(scene, t);
            p[match c {
                Col::K(_) => ks,
                Col::Z(_) => zs,
                _ => rs,
            }]
        }
        Col::KRest(t) => {
            let (ks, rs, _) = slots(scene, t);
            p[ks] * p[rs]
        }
        Col::G(axis) => p[scene.param_layout().gravity_offset + axis],
        Col::Rest(t) => p[slots(scene, t).1],
        Col::Quadratic(t) => p[quadratic_slot(scene, t)],
        Col::Known => 1.0,
    }
}

pub(crate) fn reduce(scene: &Scene, cols: &[Col], p: &[f64], free: &[bool]) -> Reduction {
    let mut xi: Vec<Xi> = Vec::new();
    let mut index: HashMap<usize, usize> = HashMap::new();
    let mut get = |slot: usize, per: Option<usize>, xi: &mut Vec<Xi>| -> usize {
        *index.entry(slot).or_insert_with(|| {
            xi.push(Xi { slot, per });
            xi.len() - 1
        })
    };
    let gravity = scene.param_layout().gravity_offset;
    let mut terms = Vec::with_capacity(cols.len());
    let mut consts = Vec::with_capacity(cols.len());
    for c in cols {
        let (term, constant) = match *c {
            Col::K(t) | Col::Z(t) | Col::Z2(t) => {
                let (ks, rs, zs) = slots(scene, t);
                let s = match *c {
                    Col::K(_) => ks,
                    Col::Z(_) => zs,
                    _ => rs,
                };
                if free[s] {
                    (Some((get(s, None, &mut xi), 1.0)), 0.0)
                } else {
                    (None, p[s])
                }
            }
            Col::KRest(t) => {
                let (k, r, _) = slots(scene, t);
                match (free[k], free[r]) {
                    (true, true) => {
                        let kx = get(k, None, &mut xi);
                        (Some((get(r, Some(kx), &mut xi), 1.0)), 0.0)
                    }
                    (true, false) => (Some((get(k, None, &mut xi), p[r])), 0.0),
                    (false, true) => (Some((get(r, None, &mut xi), p[k])), 0.0),
                    (false, false) => (None, p[k] * p[r]),
                }
            }
            Col::G(axis) => (None, p[gravity + axis]),
            Col::Rest(_) | Col::Quadratic(_) => {
                let s = match *c {
                    Col::Rest(t) => slots(scene, t).1,
                    Col::Quadratic(t) => quadratic_slot(scene, t),
                    _ => unreachable!(),
                };
                if free[s] {
                    (Some((get(s, None, &mut xi), 1.0)), 0.0)
                } else {
                    (None, p[s])
                }
            }
            Col::Known => (None, 1.0),
        };
        terms.push(term);
        consts.push(constant);
    }
    Reduction { xi, terms, consts }
}

/// The first QR row of a particle whose mass is free: `ρ m + sᵀξ + c`.
struct MassRow {
    particle: usize,
    rho: f64,
    s: DVector<f64>,
    c: f64,
}

/// `|Dξ + d|² + ρ²` (D square upper-triangular: the rows are compressed by Givens as they
/// come) and the free masses' first rows.
struct XiSystem {
    d: DMatrix<f64>,
    rhs: DVector<f64>,
    rho2: f64,
    masses: Vec<MassRow>,
}

/// The reduced system; `mass(i)` is `Some(m)` for a known (or held) mass, `None` for a free one.
fn xi_system(
    sys: &System,
    red: &Reduction,
    weighting: Weighting,
    mass: &dyn Fn(usize) -> Option<f64>,
    total: Option<f64>,
) -> XiSystem {
    let p = red.xi.len();
    let nc = sys.cols.len();
    let mut global = Factor::new(p + 1);
    let mut masses = Vec::new();
    let mut y = vec![0.0; p + 2];
    let mut out = vec![0.0; p + 1];
    for b in &sys.blocks {
        let rows = &b.rows;
        let free_mass = b.particle.filter(|&i| mass(i).is_none());
        let mut local = free_mass.map(|_| Factor::new(p + 2));
        for r in 0..rows.nrows() {
            // y = [a | Yξ | yc] for a free mass, else [Y | const].
            y.fill(0.0);
            let off = usize::from(local.is_some());
            let mut yc = 0.0;
            for k in 0..nc {
                let v = rows[(r, k)];
                if v == 0.0 {
                    continue;
                }
                if let Some((j, coef)) = red.terms[k] {
                    y[off + j] += v * coef;
                }
                yc += v * red.consts[k];
            }
            let a = rows[(r, nc)];
            if let Some(f) = &mut local {
                y[0] = a;
                y[p + 1] = yc;
                f.add_row(&mut y);
                continue;
            }
            let (scale, constant) = match (b.particle, weighting) {
                (None, _) => (1.0, yc + a),
                (Some(i), Weighting::Position) => {
                    let m = mass(i).unwrap_or(1.0);
                    (1.0 / m, yc / m + a)
                }
                (Some(i), Weighting::Force) => (1.0, yc + mass(i).unwrap_or(1.0) * a),
            };
            for (o, v) in out.iter_mut().zip(&y[..p]) {
                *o = v * scale;
            }
            out[p] = constant;
            global.add_row(&mut out);
        }
        if let (Some(f), Some(i)) = (local, free_mass) {
            let m = f.matrix();
            masses.push(MassRow {
                particle: i,
                rho: m[(0, 0)],
                s: DVector::from_iterator(p, (1..=p).map(|l| m[(0, l)])),
                c: m[(0, p + 1)],
            });
            for r in 1..p + 2 {
                for (o, l) in out.iter_mut().zip(1..p + 2) {
                    *o = m[(r, l)];
                }
                global.add_row(&mut out);
            }
        }
    }
    if let Some(total) = total.filter(|_| !masses.is_empty()) {
        let w2: f64 = masses.iter().map(|m| (1.0 / m.rho).powi(2)).sum();
        let sw = w2.sqrt();
        out.fill(0.0);
        let mut c = total;
        for m in &masses {
            for (r, s) in out.iter_mut().zip(m.s.iter()) {
                *r += s / m.rho;
            }
            c += m.c / m.rho;
        }
        out[p] = c;
        for v in &mut out {
            *v /= sw;
        }
        global.add_row(&mut out);
    }
    let m = global.matrix();
    XiSystem {
        d: m.view((0, 0), (p, p)).into_owned(),
        rhs: m.view((0, p), (p, 1)).column(0).into_owned(),
        rho2: m[(p, p)].powi(2),
        masses,
    }
}

/// What to solve: the problem's unknowns `linear` (indices into `space.unknowns`: type
/// parameters entering θ and masses) with everything else at its value in `p`.
pub(crate) struct Spec<'a> {
    pub problem: &'a Problem,
    pub system: &'a System,
    /// Full parameter vector: known values, nonlinear values, starting values of the unknowns.
    pub p: Vec<f64>,
    pub linear: Vec<usize>,
    pub weighting: Weighting,
}

#[derive(Clone, Debug, Default)]
pub(crate) struct Outcome {
    /// The full parameter vector with the solution in place.
    pub params: Vec<f64>,
    /// The cost in the system's weighting (position weighting: the short cost), m².
    pub residual: f64,
    /// Of the column-equilibrated design of the last solve.
    pub condition: f64,
    pub undetermined: Vec<String>,
    pub poorly: Vec<String>,
    pub clamped: Vec<String>,
}

/// Solves a [`Spec`]: see the module docs (undetermined unknowns held, out-of-box ones clamped,
/// re-solving after each). `Err` when the numbers are not finite.
pub(crate) fn solve(spec: &Spec) -> Result<Outcome, String> {
    let mut set = ActiveSet::new(spec);
    for _ in 0..=spec.linear.len() + 1 {
        let (red, xs, total) = set.system();
        if set.hold_unobserved_mass(&xs) {
            continue;
        }
        let sol = lsq(&xs.d, &xs.rhs).ok_or("the least-squares system is not finite")?;
        if set.hold_null_space(&sol, &red) {
            continue;
        }
        set.note_conditioning(&sol, &red);
        let residual = set.take_values(&red, &xs, &sol, total);
        if set.clamp_worst() {
            continue;
        }
        let mut out = set.out;
        out.residual = residual;
        out.params = set.p;
        return Ok(out);
    }
    Err("the least-squares solve did not settle (every unknown held)".into())
}

/// The active set of [`solve`]: the parameters so far, the linear unknowns held — at their
/// start when the data do not determine them, at their box's edge when it stopped them — and
/// what the outcome will say of them.
struct ActiveSet<'s> {
    spec: &'s Spec<'s>,
    layout: cordis_core::ParamLayout,
    /// The unknown of each linear unknown's parameter slot.
    by_slot: HashMap<usize, usize>,
    held: Vec<bool>,
    p: Vec<f64>,
    out: Outcome,
}

impl<'s> ActiveSet<'s> {
    fn new(spec: &'s Spec<'s>) -> Self {
        let space = &spec.problem.space;
        let by_slot: HashMap<usize, usize> = spec
            .linear
            .iter()
            .map(|&k| (space.unknowns[k].slot, k))
            .collect();
        ActiveSet {
            spec,
            layout: spec.problem.scene.param_layout(),
            by_slot,
            held: vec![false; space.unknowns.len()],
            p: spec.p.clone(),
            out: Outcome::default(),
        }
    }

    /// The reduced least-squares system over the unknowns not held, and the moving mass the
    /// free masses share when the total is known.
    fn system(&self) -> (Reduction, XiSystem, Option<f64>) {
        let spec = self.spec;
        let space = &spec.problem.space;
        let scene = &spec.problem.scene;
        let layout = &self.layout;
        let p = &self.p;
        let mut free = vec![false; p.len()];
        let mut free_mass = vec![false; scene.num_particles()];
        for &k in &spec.linear {
            let u = &space.unknowns[k];
            if self.held[k] {
                continue;
            }
            if u.role == Role::Mass {
                free_mass[u.slot - layout.mass_offset] = true;
            } else {
                free[u.slot] = true;
            }
        }
        let red = reduce(scene, &spec.system.cols, p, &free);
        let mass = |i: usize| (!free_mass[i]).then(|| p[layout.mass_offset + i]);
        let total = space.total_mass.map(|m| {
            m - spec
                .problem
                .objective
                .free
                .iter()
                .filter(|&&i| !free_mass[i])
                .map(|&i| p[layout.mass_offset + i])
                .sum::<f64>()
        });
        let xs = xi_system(spec.system, &red, spec.weighting, &mass, total);
        (red, xs, total)
    }

    /// Holds linear unknown `k` at its start.
    fn hold(&mut self, k: usize) {
        let slot = self.spec.problem.space.unknowns[k].slot;
        self.held[k] = true;
        self.p[slot] = self.spec.p[slot];
    }

    /// Holds a mass with no acceleration information at all (rows independent of it).
    fn hold_unobserved_mass(&mut self, xs: &XiSystem) -> bool {
        let rho_max = xs.masses.iter().map(|m| m.rho.abs()).fold(0.0, f64::max);
        let Some(m) = xs
            .masses
            .iter()
            .find(|m| m.rho.abs() <= RANK_TOL * rho_max || m.rho.is_nan())
        else {
            return false;
        };
        let k = self.by_slot[&(self.layout.mass_offset + m.particle)];
        self.hold(k);
        push_unique(
            &mut self.out.undetermined,
            &self.spec.problem.space.unknowns[k].name,
        );
        true
    }

    /// The unknown of the reduced system's column j.
    fn name_of(&self, red: &Reduction, j: usize) -> &'s str {
        &self.spec.problem.space.unknowns[self.by_slot[&red.xi[j].slot]].name
    }

    /// Names the unknowns of every null direction and holds each one's largest.
    fn hold_null_space(&mut self, sol: &Lsq, red: &Reduction) -> bool {
        if sol.null.is_empty() {
            return false;
        }
        for v in &sol.null {
            let big = v.amax();
            for j in 0..v.len() {
                if v[j].abs() >= 0.2 * big {
                    let name = self.name_of(red, j);
                    push_unique(&mut self.out.undetermined, name);
                }
            }
            let k = self.by_slot[&red.xi[v.iamax()].slot];
            if !self.held[k] {
                self.hold(k);
            }
        }
        true
    }

    /// The design's condition, and the unknowns of its weakest direction when it is poor.
    fn note_conditioning(&mut self, sol: &Lsq, red: &Reduction) {
        self.out.condition = sol.condition;
        self.out.poorly.clear();
        if sol.condition > POOR_CONDITION {
            if let Some(v) = &sol.weakest {
                let big = v.amax();
                for j in 0..v.len() {
                    if v[j].abs() >= 0.2 * big {
                        let name = self.name_of(red, j);
                        push_unique(&mut self.out.poorly, name);
                    }
                }
            }
        }
    }

    /// Puts the solution in the parameters (direct values first, then rest lengths and
    /// cosines as (K·l0)/K, then the free masses) and returns its residual.
    fn take_values(
        &mut self,
        red: &Reduction,
        xs: &XiSystem,
        sol: &Lsq,
        total: Option<f64>,
    ) -> f64 {
        let p = &mut self.p;
        for (j, x) in red.xi.iter().enumerate() {
            if x.per.is_none() {
                p[x.slot] = sol.xi[j];
            }
        }
        for (j, x) in red.xi.iter().enumerate() {
            if let Some(kx) = x.per {
                p[x.slot] = sol.xi[j] / sol.xi[kx];
            }
        }
        // With free masses, the total's row already holds the first rows' Σe².
        let residual = (&xs.d * &sol.xi + &xs.rhs).norm_squared() + xs.rho2;
        if !xs.masses.is_empty() {
            let w2: f64 = xs.masses.iter().map(|m| m.rho.powi(-2)).sum();
            let gamma = total.map(|t| {
                t + xs
                    .masses
                    .iter()
                    .map(|m| (m.s.dot(&sol.xi) + m.c) / m.rho)
                    .sum::<f64>()
            });
            for m in &xs.masses {
                let e = gamma.map_or(0.0, |g| g / m.rho / w2);
                p[self.layout.mass_offset + m.particle] = (e - m.s.dot(&sol.xi) - m.c) / m.rho;
            }
        }
        residual
    }

    /// Clamps the unknown furthest outside its box (in internal coordinates per box width)
    /// to it and holds it there.
    fn clamp_worst(&mut self) -> bool {
        let space = &self.spec.problem.space;
        let mut worst: Option<(usize, f64)> = None;
        for &k in &self.spec.linear {
            if self.held[k] {
                continue;
            }
            let u = &space.unknowns[k];
            let v = self.p[u.slot];
            let (lo, hi) = u.internal_bounds();
            let excess = if v.is_nan() || (u.log && v <= 0.0) {
                f64::INFINITY
            } else {
                let z = u.to_internal(v);
                ((lo - z).max(z - hi)) / (hi - lo).max(f64::MIN_POSITIVE)
            };
            if excess > 1e-9 && worst.is_none_or(|(_, w)| excess > w) {
                worst = Some((k, excess));
            }
        }
        let Some((k, _)) = worst else {
            return false;
        };
        let u = &space.unknowns[k];
        let v = self.p[u.slot];
        self.p[u.slot] = if v.is_nan() || (u.log && v <= 0.0) {
            u.min
        } else {
            u.from_internal(u.to_internal(v))
        };
        self.held[k] = true;
        push_unique(&mut self.out.clamped, &u.name);
        true
    }
}

fn push_unique(v: &mut Vec<String>, s: &str) {
    if !v.iter().any(|x| x == s) {
        v.push(s.to_string());
    }
}

/// The answer of an exact solver.
#[derive(Clone, Debug)]
pub struct Solution {
    /// Internal coordinates ([`crate::problem::space`]).
    pub genome: Vec<f64>,
    /// The problem's own cost of the genome.
    pub cost: f64,
    pub report: ExactReport,
}

/// The problem's unknowns split into those the linear solve determines (type parameters that
/// enter θ, masses of free particles) and the nonlinear ones (ranges, v_max); masses of fixed
/// particles enter no cost and are neither.
pub(crate) struct Split {
    pub linear: Vec<usize>,
    pub nonlinear: Vec<usize>,
    pub fixed_masses: Vec<usize>,
    pub free_masses: bool,
}

pub(crate) fn split(problem: &Problem) -> Split {
    let layout = problem.scene.param_layout();
    let mut s = Split {
        linear: Vec::new(),
        nonlinear: Vec::new(),
        fixed_masses: Vec::new(),
        free_masses: false,
    };
    for (k, u) in problem.space.unknowns.iter().enumerate() {
        match u.role {
            Role::Range | Role::Speed => s.nonlinear.push(k),
            _ if self::tgr_cols::is_nonlinear(&problem.scene, u) => s.nonlinear.push(k),
            Role::Mass => {
                if problem.scene.particles[u.slot - layout.mass_offset].fixed {
                    s.fixed_masses.push(k);
                } else {
                    s.free_masses = true;
                    s.linear.push(k);
                }
            }
            _ => s.linear.push(k),
        }
    }
    s
}

/// With free masses, something must fix the scale of masses and forces together: a total
/// mass, a known mass of a free particle, or a known nonzero force parameter.
pub(crate) fn check_scale(problem: &Problem, split: &Split, cols: &[Col]) -> Result<(), String> {
    if !split.free_masses || problem.space.total_mass.is_some() {
        return Ok(());
    }
    let layout = problem.scene.param_layout();
    let masses: Vec<usize> = split
        .linear
        .iter()
        .map(|&k| problem.space.unknowns[k].slot)
        .collect();
    let known_mass = problem
        .objective
        .free
        .iter()
        .any(|&i| !masses.contains(&(layout.mass_offset + i)));
    let mut free = vec![false; problem.space.base.len()];
    for &s in &masses {
        free[s] = true;
    }
    let red = reduce(&problem.scene, cols, &problem.space.base, &free);
    let known_force = cols
        .iter()
        .zip(&red.consts)
        .any(|(c, &v)| !matches!(c, Col::G(_)) && v != 0.0);
    if known_mass || known_force {
        return Ok(());
    }
    Err(
        "masses and link parameters are only determined up to a common scale \
         (thesis §3.3): give the total mass of the free particles (--total-mass)"
            .into(),
    )
}

/// The problem's cost of a full parameter vector (one counted evaluation).
pub(crate) fn real_cost(problem: &Problem, params: &[f64]) -> (Vec<f64>, f64) {
    let genome = problem.space.genome_of(params);
    let mut s = problem.scratch();
    let mut local = vec![0.0; problem.num_particles];
    let cost = problem.evaluate(&genome, &mut s, &mut local);
    (genome, cost)
}

/// Solves the linear unknowns of `split` at the nonlinear values in `p`. With free masses:
/// force weighting first (masses and θ together), then θ again in position weighting at those
/// masses (the short cost's own weighting); the better by the problem's cost is kept.
pub(crate) fn solve_linear(
    problem: &Problem,
    system: &System,
    p: Vec<f64>,
    split: &Split,
    report: &mut ExactReport,
) -> Result<(Vec<f64>, f64), String> {
    let weighting = if split.free_masses {
        Weighting::Force
    } else {
        Weighting::Position
    };
    let spec = Spec {
        problem,
        system,
        p,
        linear: split.linear.clone(),
        weighting,
    };
    let mut best = solve(&spec)?;
    let (mut genome, mut cost) = real_cost(problem, &best.params);
    if split.free_masses {
        let theta_only: Vec<usize> = split
            .linear
            .iter()
            .copied()
            .filter(|&k| problem.space.unknowns[k].role != Role::Mass)
            .collect();
        let refined = solve(&Spec {
            problem,
            system,
            p: best.params.clone(),
            linear: theta_only,
            weighting: Weighting::Position,
        })?;
        let (g2, c2) = real_cost(problem, &refined.params);
        report.notes.push(format!(
            "free masses: masses and links solved together in force weighting (each particle's \
             terms weighted by m²; cost {cost:.6e}), then the links again at those masses in the \
             short cost's weighting (cost {c2:.6e}); kept the {}",
            if c2 < cost { "second" } else { "first" }
        ));
        if c2 < cost {
            // What was undetermined or clamped among the masses stays reported.
            best = Outcome {
                undetermined: best.undetermined,
                clamped: best.clamped,
                ..refined
            };
            genome = g2;
            cost = c2;
        }
    } else if cost.is_finite() && !system.partial {
        // Below an rmse of 1e-10 m both are rounding of an exact fit.
        let floor = 1e-20 * problem.objective.terms() as f64;
        let scale = cost.abs().max(best.residual.abs());
        if (cost - best.residual).abs() > 1e-6 * scale && scale > floor {
            report.notes.push(format!(
                "the solver's residual {:.6e} differs from the cost {cost:.6e}",
                best.residual
            ));
        }
    }
    report.condition = best.condition;
    report.undetermined = best.undetermined;
    report.poorly_determined = best.poorly;
    report.clamped = best.clamped;
    for &k in &split.fixed_masses {
        let name = &problem.space.unknowns[k].name;
        push_unique(&mut report.undetermined, name);
    }
    Ok((genome, cost))
}

#[derive(Clone, Debug, Default, Serialize, Deserialize)]
struct OneShotState {
    #[serde(with = "bits")]
    genome: Vec<f64>,
    #[serde(with = "lossless")]
    cost: f64,
    report: ExactReport,
}

/// A strategy that solves once, in generation 0, and is then finished: `least-squares` and
/// `hybrid` are this with their own solve.
pub struct OneShot {
    name: &'static str,
    solve: fn(&Problem) -> Result<Solution, String>,
    state: OneShotState,
    /// A solve already made on the same problem (`auto` solves to judge the noise) and the
    /// evaluations it counted, used by `init` instead of solving again.
    solved: Option<(Solution, u64)>,
}

impl OneShot {
    pub fn new(name: &'static str, solve: fn(&Problem) -> Result<Solution, String>) -> Self {
        OneShot {
            name,
            solve,
            state: OneShotState::default(),
            solved: None,
        }
    }

    /// The strategy with `solution`, the result of `solve` on the problem it will run on, made
    /// with `evals` cost evaluations (counted again by `init`, as if it had solved there).
    pub fn with_solution(mut self, solution: Solution, evals: u64) -> Self {
        self.solved = Some((solution, evals));
        self
    }

    /// Condition number, undetermined and clamped unknowns, notes, error.
    pub fn report(&self) -> &ExactReport {
        &self.state.report
    }
}

/// The starting point, scored: the answer of a failed solve.
fn fallback(problem: &Problem, error: String) -> (Vec<f64>, f64, ExactReport) {
    let genome = problem.space.genome_of(&problem.space.base);
    let mut s = problem.scratch();
    let mut local = vec![0.0; problem.num_particles];
    let cost = problem.evaluate(&genome, &mut s, &mut local);
    let report = ExactReport {
        condition: f64::INFINITY,
        error: Some(error),
        ..ExactReport::default()
    };
    (genome, cost, report)
}

impl Strategy for OneShot {
    fn name(&self) -> &'static str {
        self.name
    }

    fn init(&mut self, problem: &Problem, _seed: u64) {
        let solution = match self.solved.take() {
            Some((s, evals)) => {
                problem.set_evals(problem.evals() + evals);
                Ok(s)
            }
            None => (self.solve)(problem),
        };
        self.state = match solution {
            Ok(s) => OneShotState {
                genome: s.genome,
                cost: s.cost,
                report: s.report,
            },
            Err(e) => {
                let (genome, cost, report) = fallback(problem, e);
                OneShotState {
                    genome,
                    cost,
                    report,
                }
            }
        };
    }

    fn next_generation(&mut self, _problem: &Problem, _seed: u64, _generation: u64) {}

    fn finished(&self) -> bool {
        true
    }

    fn failure(&self) -> Option<String> {
        self.state.report.error.clone()
    }

    fn best(&self) -> (&[f64], f64) {
        (&self.state.genome, self.state.cost)
    }

    fn stats(&self) -> GenerationStats {
        GenerationStats {
            best_cost: self.state.cost,
            mean_cost: self.state.cost,
            mean_mutability: 0.0,
        }
    }

    fn save_state(&self) -> serde_json::Value {
        serde_json::to_value(&self.state).unwrap_or_default()
    }

    fn load_state(
        &mut self,
        problem: &Problem,
        state: &serde_json::Value,
    ) -> Result<(), CostError> {
        let s: OneShotState =
            serde_json::from_value(state.clone()).map_err(|e| CostError::state_json(None, e))?;
        if s.genome.len() != problem.dim() {
            return Err(CostError::state(format!(
                "state has {} unknowns, the problem {}",
                s.genome.len(),
                problem.dim()
            )));
        }
        self.state = s;
        Ok(())
    }

    fn report(&self) -> crate::report::Report {
        crate::report::Report::exact(self.state.report.clone())
    }
}
