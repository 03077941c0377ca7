//! Exact sensitivities of a simulated trajectory: the tangent recursion of the CORDIS step.
//!
//! The step (SPEC §2.1) is `v(n) = (x(n) - x(n-1))/dt`, `x(n+1) = 2x(n) - x(n-1) + dt² (F/m + g)`
//! with `F = F(x(n), v(n); θ)`. Differentiating it with respect to any quantity q (a link
//! parameter, a mass, a free particle's initial position or velocity) gives, with
//! `S(n) = ∂x(n)/∂q` and `V(n) = (S(n) - S(n-1))/dt`,
//!
//! ```text
//! S(n+1) = 2 S(n) - S(n-1) + dt²/m (∂F/∂x S(n) + ∂F/∂v V(n) + ∂F/∂q) - dt² F/m² ∂m/∂q
//! ```
//!
//! from `S(0) = ∂x(0)/∂q`, `S(-1) = ∂(x(0) - v(0) dt)/∂q`. The recursion is exact (no finite
//! difference): it is the derivative of the same floating-point scheme up to rounding. The
//! positions themselves come from the core's compiled [`Plan::step`], so the trajectory this
//! module differentiates is bit for bit the one `cordis simulate` writes.
//!
//! `∂F/∂x` is never formed: each link adds its 3×3 blocks times the sensitivity rows of its
//! ends (sparsity: a particle's force depends on its neighbours only). One file per kind gives
//! its force's derivatives: [`spring`] (springs and anchors, with the quadratic viscosity Z₂),
//! [`angle`], [`plane`] (ground contact), [`conditional`] (the active pairs as springs, an
//! unknown range refused); a damper `f_i = Z w` and a drag `f_i = -Z v_i` are written out
//! here. Each kind's file also holds its matrix-free passes (forward, adjoint, local blocks).
//!
//! Provot's elongation limit is not a force but the projection that ends the step: S(n+1)
//! above is that of the prediction x̃(n+1), then pushed through the pass's active corrections
//! in order ([`provot`]: `δc = M δd - u δλ`, `M = (1 - λ/L) I + (λ/L) u uᵀ`). The rollout
//! runs the projection itself when it carries columns
//! ([`cordis_core::plan::Plan::step_unprojected`], then the core's own pass, recorded), so the
//! positions are the core's bit for bit; a scene without the limit steps as before.
//!
//! Kinds without a tangent (muscles, couplings, nonlinear drags, several worlds) are refused
//! by name before any work ([`Tangent::supports`]).
//!
//! Cost per step: about 30 P multiply-adds per link and 6 P per particle for P sensitivity
//! columns, no allocation (the matrices are caller-owned scratch, row-major `3N × P`, so each
//! coordinate's row of P columns is contiguous and every update is an axpy the compiler
//! vectorises).

use cordis_core::plan::{Plan, Scratch};
use cordis_core::{LinkKind, Runaway, Scene, Vec3};

use super::observations::Take;
use crate::error::CostError;

pub(crate) mod angle;
pub(crate) mod conditional;
mod no_column;
pub(crate) mod plane;
pub(crate) mod provot;
pub(crate) mod spring;

pub(crate) use no_column::NONE;
pub(crate) use spring::spring_link;

/// A scene compiled for rollouts with sensitivities.
#[derive(Clone, Debug)]
pub(crate) struct Tangent {
    pub plan: Plan,
    /// Free particles in scene order.
    pub free: Vec<usize>,
    /// The divergence guard of every rollout ([`cordis_core::runaway`]): the scene's start,
    /// merged with the takes' motion by [`Tangent::guard_by`]. A rollout beyond it diverged.
    pub runaway: Runaway,
}

/// What a rollout calls at every frame n: `(n, x(n), S(n))`.
pub(crate) type Visit<'a> = dyn FnMut(usize, &[Vec3], Option<&[f64]>) + 'a;

/// Where each sensitivity column comes from.
#[derive(Clone, Debug)]
pub(crate) struct Columns {
    /// `of_slot[k]`: the column of parameter slot k, or [`NONE`].
    pub of_slot: Vec<usize>,
    /// Number of parameter columns; columns `theta + 6 f + c` (c < 3) are free particle f's
    /// initial position, `theta + 6 f + 3 + c` its initial velocity.
    pub theta: usize,
    /// Total number of columns.
    pub len: usize,
}

/// Caller-owned buffers of one rollout.
#[derive(Clone, Debug, Default)]
pub(crate) struct Sens {
    x: Vec<Vec3>,
    x_prev: Vec<Vec3>,
    scratch: Option<Scratch>,
    /// ∂x(n)/∂q and ∂x(n-1)/∂q, row-major 3N × P.
    pub s: Vec<f64>,
    s_prev: Vec<f64>,
    vel: Vec<f64>,
    df: Vec<f64>,
    diff: Vec<f64>,
    /// One grid per conditional pass (its active pairs at each step).
    grids: Vec<cordis_core::forces::grid::Grid>,
    /// The Provot corrections of the current step.
    proj: provot::Corrections,
}

impl Tangent {
    /// Compiles `scene`; refuses the kinds this module has no tangent for, by name.
    pub fn new(scene: &Scene) -> Result<Self, CostError> {
        Self::supports(scene)?;
        let plan = Plan::compile(scene)?;
        let free: Vec<usize> = (0..plan.n).filter(|&i| plan.free[i]).collect();
        let runaway = plan.runaway;
        Ok(Tangent {
            plan,
            free,
            runaway,
        })
    }

    /// Bounds the rollouts by the observed motion of `takes` too (a model that goes 10⁶ times
    /// beyond the size and speeds of what was observed has run away: its cost is `+inf`, not
    /// a finite number of 10⁴⁴ m that a fit could hand back as an estimate).
    pub fn guard_by(&mut self, takes: &[Take]) {
        for take in takes {
            let seen = self
                .plan
                .runaway_of((0..take.frames()).map(|t| take.positions(t)));
            self.runaway = self.runaway.merge(seen);
        }
    }

    /// Whether every kind `scene` uses has a tangent here (an error naming the first that has
    /// none), without compiling the scene.
    pub fn supports(scene: &Scene) -> Result<(), CostError> {
        for (t, ty) in scene.types.iter().enumerate() {
            let used = scene.links.iter().any(|l| l.type_index == t)
                || scene.couplings.iter().any(|c| c.type_index == t)
                || ty.kind == LinkKind::Conditional;
            let supported = matches!(
                ty.kind,
                LinkKind::Spring
                    | LinkKind::Damper
                    | LinkKind::Anchor
                    | LinkKind::Drag
                    | LinkKind::Angle
                    | LinkKind::Plane
                    | LinkKind::Conditional
            );
            if used && !supported {
                return Err(CostError::mismatch(
                    format!("types.{}", ty.name),
                    format!(
                        "kind `{}` has no exact sensitivities yet: the output-error estimator \
                         takes springs (with Z₂ and Provot's limit), dampers, anchors, drags, \
                         angles, planes and conditional links",
                        ty.kind.name()
                    ),
                ));
            }
            if ty.kind == LinkKind::Conditional && ty.param("range").is_some_and(|r| r.is_unknown())
            {
                return Err(CostError::mismatch(
                    format!("types.{}.range", ty.name),
                    "an unknown range moves the output-error cost only in steps (pairs appear \
                     and vanish as it crosses their lengths; its sensitivity is 0): give it, \
                     or bracket it with `hybrid` on the short cost",
                ));
            }
        }
        if scene.has_worlds() {
            return Err(CostError::mismatch(
                "worlds",
                "several worlds have no exact sensitivities yet (output-error)",
            ));
        }
        Ok(())
    }

    /// Columns for the parameter slots `slots` (in order), then the free particles' states.
    pub fn columns(&self, slots: &[usize]) -> Columns {
        let mut of_slot = vec![NONE; self.plan.layout.len];
        for (c, &k) in slots.iter().enumerate() {
            of_slot[k] = c;
        }
        Columns {
            of_slot,
            theta: slots.len(),
            len: slots.len() + 6 * self.free.len(),
        }
    }

    /// Rolls out `frames` frames (frame 0 included) from the initial state `state`
    /// (`[x0, v0]` per free particle, 6 values each; fixed particles stay at the scene's
    /// positions), calling `visit(n, x(n), S(n))` at every frame. With `cols`, S(n) is the
    /// `3N × cols.len` sensitivity matrix; without, `visit` gets `None` and no tangent is
    /// computed. Returns the first frame whose step diverged, as an error.
    pub fn rollout(
        &self,
        p: &[f64],
        state: &[f64],
        frames: usize,
        cols: Option<&Columns>,
        buf: &mut Sens,
        visit: &mut Visit<'_>,
    ) -> Result<(), usize> {
        let plan = &self.plan;
        let n = plan.n;
        let dt = plan.dt;
        buf.x.clear();
        buf.x.extend_from_slice(&plan.x0);
        buf.x_prev.clear();
        buf.x_prev.extend_from_slice(&plan.x0);
        for (f, &i) in self.free.iter().enumerate() {
            let q = &state[6 * f..6 * f + 6];
            buf.x[i] = Vec3::new(q[0], q[1], q[2]);
            buf.x_prev[i] = Vec3::new(q[0] - q[3] * dt, q[1] - q[4] * dt, q[2] - q[5] * dt);
        }
        let mut scratch = buf.scratch.take().unwrap_or_else(|| plan.scratch());
        plan.reset_state(p, &mut scratch);
        scratch.frame = 0;
        scratch.runaway = self.runaway;
        let width = cols.map_or(0, |c| c.len);
        if let Some(c) = cols {
            self.init_sensitivities(c, buf);
        }
        let mut out = Ok(());
        for t in 0..frames {
            visit(t, &buf.x, cols.map(|_| &buf.s[..]));
            if t + 1 == frames {
                break;
            }
            let projected = cols.is_some() && !plan.provot.links.is_empty();
            let bad = if projected {
                // The step's projection run here, its corrections recorded for the tangent.
                let bad = plan.step_unprojected(p, &mut buf.x, &mut buf.x_prev, &mut scratch);
                buf.proj.reset();
                let (x, proj) = (&mut buf.x, &mut buf.proj);
                plan.provot
                    .apply_recorded(p, x, &plan.free, |c| proj.push(c));
                buf.proj.end_step();
                bad
            } else {
                plan.step(p, &mut buf.x, &mut buf.x_prev, &mut scratch)
            };
            if bad.is_some() {
                out = Err(t + 1);
                break;
            }
            if let Some(c) = cols {
                // After the step: x_prev = x(n), scratch.v = v(n), scratch.f = F(n).
                self.tangent_step(p, c, width, n, &scratch, buf);
                if projected {
                    let step = buf.proj.step(0);
                    provot::dense(
                        &plan.provot,
                        &plan.free,
                        step,
                        p,
                        &c.of_slot,
                        width,
                        &mut buf.s,
                    );
                }
            }
        }
        buf.scratch = Some(scratch);
        out
    }

    fn init_sensitivities(&self, c: &Columns, buf: &mut Sens) {
        let rows = 3 * self.plan.n;
        for m in [&mut buf.s, &mut buf.s_prev, &mut buf.vel, &mut buf.df] {
            m.clear();
            m.resize(rows * c.len, 0.0);
        }
        buf.diff.clear();
        buf.diff.resize(6 * c.len, 0.0);
        let dt = self.plan.dt;
        for (f, &i) in self.free.iter().enumerate() {
            for k in 0..3 {
                let row = (3 * i + k) * c.len;
                buf.s[row + c.theta + 6 * f + k] = 1.0;
                buf.s_prev[row + c.theta + 6 * f + k] = 1.0;
                buf.s_prev[row + c.theta + 6 * f + 3 + k] = -dt;
            }
        }
    }

    /// One step of the tangent recursion (module docs), S(n) → S(n+1).
    fn tangent_step(
        &self,
        p: &[f64],
        c: &Columns,
        w: usize,
        n: usize,
        scratch: &Scratch,
        buf: &mut Sens,
    ) {
        let plan = &self.plan;
        let dt = plan.dt;
        let inv_dt = 1.0 / dt;
        let Sens {
            x_prev: xn,
            s,
            s_prev,
            vel,
            df,
            diff,
            grids,
            ..
        } = buf;
        for ((v, a), b) in vel.iter_mut().zip(s.iter()).zip(s_prev.iter()) {
            *v = (a - b) * inv_dt;
        }
        df.iter_mut().for_each(|x| *x = 0.0);
        let v = &scratch.v;
        let cx = Ctx { s, vel, w };
        for (ri, r) in plan.springs.runs.iter().enumerate() {
            let (k, l0, z) = (p[r.param], p[r.param + 1], p[r.param + 2]);
            let z2 = spring::quadratic(&plan.springs, ri).map_or(0.0, |q| p[q]);
            let slots = spring::slots(&plan.springs, ri, r.param, &c.of_slot);
            for &[i, j] in &plan.springs.pairs[r.start..r.end] {
                let (i, j) = (i as usize, j as usize);
                let lk = spring_link(&xn[j], &xn[i], &v[j], &v[i], k, l0, z, z2);
                cx.diff_rows(Some(j), i, diff);
                lk.add(df, diff, w, i, Some(j), slots);
            }
        }
        for r in &plan.anchors.runs {
            let (k, l0, z) = (p[r.param], p[r.param + 1], p[r.param + 2]);
            let slots = [
                c.of_slot[r.param],
                c.of_slot[r.param + 1],
                c.of_slot[r.param + 2],
                NONE,
            ];
            let items = plan.anchors.particles[r.start..r.end]
                .iter()
                .zip(&plan.anchors.points[r.start..r.end]);
            for (&i, point) in items {
                let i = i as usize;
                let lk = spring_link(point, &xn[i], &Vec3::zeros(), &v[i], k, l0, z, 0.0);
                cx.diff_rows(None, i, diff);
                lk.add(df, diff, w, i, None, slots);
            }
        }
        for r in &plan.dampers.runs {
            let z = p[r.param];
            let col = c.of_slot[r.param];
            for &[i, j] in &plan.dampers.pairs[r.start..r.end] {
                let (i, j) = (i as usize, j as usize);
                let rel = v[j] - v[i];
                for k in 0..3 {
                    let (ri, rj) = ((3 * i + k) * w, (3 * j + k) * w);
                    for q in 0..w {
                        let g = z * (vel[rj + q] - vel[ri + q]);
                        df[ri + q] += g;
                        df[rj + q] -= g;
                    }
                    if col != NONE {
                        df[ri + col] += rel[k];
                        df[rj + col] -= rel[k];
                    }
                }
            }
        }
        for r in &plan.drags.runs {
            let z = p[r.param];
            let col = c.of_slot[r.param];
            for &i in &plan.drags.particles[r.start..r.end] {
                let i = i as usize;
                for (k, vk) in v[i].iter().enumerate() {
                    let ri = (3 * i + k) * w;
                    for q in 0..w {
                        df[ri + q] -= z * vel[ri + q];
                    }
                    if col != NONE {
                        df[ri + col] -= vk;
                    }
                }
            }
        }
        if !plan.angles.runs.is_empty() {
            angle::dense(&plan.angles, p, &c.of_slot, xn, s, w, df, diff);
        }
        if !plan.planes.is_empty() {
            plane::dense(&plan.planes, p, &c.of_slot, (xn, v), (s, vel), w, df);
        }
        grids.resize_with(plan.conditionals.len(), Default::default);
        for (pass, grid) in plan.conditionals.iter().zip(grids.iter_mut()) {
            let slots = conditional::slots(pass, &c.of_slot);
            conditional::each_pair(pass, p, (xn, v), grid, |i, j, lk| {
                cx.diff_rows(Some(j), i, diff);
                lk.add(df, diff, w, i, Some(j), slots);
            });
        }
        let mo = plan.layout.mass_offset;
        let dt2 = dt * dt;
        // An unknown gravity component g_k: `∂(dt² g)/∂g_k = dt² e_k` on every free particle
        // (one world: gravity acts on all of them).
        let go = plan.layout.gravity_offset;
        let gcol = [0, 1, 2].map(|k| c.of_slot[go + k]);
        for i in 0..n {
            let base = 3 * i * w;
            if !plan.free[i] {
                s_prev[base..base + 3 * w].iter_mut().for_each(|x| *x = 0.0);
                continue;
            }
            let m = p[mo + i];
            let h = dt2 / m;
            let mcol = c.of_slot[mo + i];
            for k in 0..3 {
                let row = base + k * w;
                let (sn, sp, d) = (
                    &s[row..row + w],
                    &mut s_prev[row..row + w],
                    &df[row..row + w],
                );
                for q in 0..w {
                    sp[q] = 2.0 * sn[q] - sp[q] + h * d[q];
                }
                if mcol != NONE {
                    sp[mcol] -= h * scratch.f[i][k] / m;
                }
                if gcol[k] != NONE {
                    sp[gcol[k]] += dt2;
                }
            }
        }
        std::mem::swap(s, s_prev);
    }
}

/// Read access to the sensitivity rows of one step.
struct Ctx<'a> {
    s: &'a [f64],
    vel: &'a [f64],
    w: usize,
}

impl Ctx<'_> {
    /// `diff[0..3] = S_j - S_i` and `diff[3..6] = V_j - V_i` (row blocks of width w); a fixed
    /// point (`j = None`) has S = V = 0.
    fn diff_rows(&self, j: Option<usize>, i: usize, diff: &mut [f64]) {
        let w = self.w;
        for k in 0..3 {
            let ri = (3 * i + k) * w;
            let (dd, rest) = diff[k * w..].split_at_mut(w);
            let dv = &mut rest[(2 * w)..(3 * w)];
            match j {
                Some(j) => {
                    let rj = (3 * j + k) * w;
                    for q in 0..w {
                        dd[q] = self.s[rj + q] - self.s[ri + q];
                        dv[q] = self.vel[rj + q] - self.vel[ri + q];
                    }
                }
                None => {
                    for q in 0..w {
                        dd[q] = -self.s[ri + q];
                        dv[q] = -self.vel[ri + q];
                    }
                }
            }
        }
    }
}
