//! A scene compiled for simulation: only the passes the scene uses, instances grouped by type,
//! parameters read from a flat vector (see [`crate::ParamLayout`]). Compile once, then step
//! with any parameter vector of the same layout: identification reuses one plan for every
//! candidate.

use crate::error::Result;
use crate::forces::conditional::Part;
use crate::forces::{
    anchor::AnchorPass, angle::AnglePass, conditional::ConditionalPass,
    controlled_tgr::ControlledTgrPass, damper::DamperPass, drag::DragPass,
    force_transmitter::ForceTransmitterPass, grid::Grid, muscle::MuscleBuf, muscle::MusclePass,
    nonlinear_drag::NonlinearDragPass, plane::PlanePass, plane::Surface, provot::ProvotLink,
    provot::ProvotPass, quadripole::QuadripolePass, runs_by_type, runs_by_type_and_world,
    spring::SpringPass, stateful::Stateful, tgr::TgrPass,
};
use crate::runaway::Runaway;
use crate::world::{Clock, OneClock, WorldClock, WorldSteps};
use crate::{LinkKind, OptionalParam, ParamLayout, Scene, Vec3};

#[derive(Clone, Debug)]
pub struct Plan {
    /// Number of particles.
    pub n: usize,
    /// Time step of the main world, s (the trajectory's frame interval).
    pub dt: f64,
    /// Per-particle time steps when some particle is outside the main world; `None` (every
    /// particle steps with `dt`) keeps the one-world loops.
    pub worlds: Option<WorldSteps>,
    pub layout: ParamLayout,
    /// `free[i]` is false for fixed particles.
    pub free: Vec<bool>,
    /// Initial positions x(0) and x(-1) = x(0) - v0 dt (fixed particles: x(-1) = x(0)).
    pub x0: Vec<Vec3>,
    pub x_minus1: Vec<Vec3>,
    pub springs: SpringPass,
    pub dampers: DamperPass,
    pub anchors: AnchorPass,
    pub drags: DragPass,
    pub nonlinear_drags: NonlinearDragPass,
    pub angles: AnglePass,
    /// Contacts with half-spaces ([`crate::forces::plane`]).
    pub planes: PlanePass,
    pub muscles: MusclePass,
    pub conditionals: Vec<ConditionalPass>,
    /// Passes with state carried between steps (TGR tendons…): see [`Stateful`]. Not part of
    /// [`Plan::forces`]; [`Plan::step`] runs them after it.
    pub stateful: Stateful,
    pub provot: ProvotPass,
    /// Some pass reads velocities (a damper, a drag, or a damping or a plane's friction that is
    /// not known to be 0).
    /// When false, [`Plan::velocities`] skips its work, so a parameter vector must keep every
    /// damping that the scene knew to be 0 at 0 (identification only varies unknowns).
    pub needs_velocity: bool,
    /// The scene was compiled with a non-zero gravity (informative: the integrator always
    /// reads gravity from the parameter vector).
    pub has_gravity: bool,
    /// Large scenes split their force passes in two fixed halves, summed in a fixed order
    /// (see [`Split`]); small ones take the sequential path.
    pub split: Option<Split>,
    /// The divergence guard of the scene's own start (`x(0)`, its velocities): what
    /// [`Plan::scratch`] gives a simulation; a caller starting elsewhere (observed motion)
    /// sets [`Scratch::runaway`] to its own.
    pub runaway: Runaway,
}

/// The two halves of a large scene's force work. Half 0 holds the first half of the springs,
/// every other listed pass and the first half of each conditional pass's cells; half 1 the
/// rest. Each half writes its own force buffer and `f = f0 + f1`: the arithmetic is the same
/// whether rayon runs the halves on one thread or two, so a simulation's result does not depend
/// on the thread count.
#[derive(Clone, Debug)]
pub struct Split {
    pub springs: [SpringPass; 2],
}

/// Scenes with at least this many link evaluations per step (listed links, or conditional
/// members) split their work: below it a rayon join costs more than it saves.
pub const SPLIT_MIN_WORK: usize = 2048;

/// Per-simulation scratch that a step writes: velocities, forces, grids.
#[derive(Clone, Debug, Default)]
pub struct Scratch {
    pub v: Vec<Vec3>,
    pub f: Vec<Vec3>,
    pub grids: Vec<Grid>,
    /// Forces of the second half of a split step.
    pub f2: Vec<Vec3>,
    /// Per conditional pass: its grid is ready (split steps build grids before the halves).
    pub ready: Vec<bool>,
    /// Every muscle's elongation, rate and direction, read by the neurons.
    pub muscles: MuscleBuf,
    /// State of the stateful passes ([`Stateful`]) at frame `frame`: per simulation, like the
    /// positions, so it lives here and not in the shared plan. Set by [`Plan::reset_state`].
    pub state: Vec<f64>,
    /// Index n of the frame the next [`Plan::step`] starts from (signals read `t = n dt`).
    pub frame: usize,
    /// The divergence guard [`Plan::step`] applies at frame `frame` (the plan's own unless the
    /// caller set one for another start).
    pub runaway: Runaway,
}

impl Plan {
    /// Compiles a validated scene.
    pub fn compile(scene: &Scene) -> Result<Plan> {
        scene.validate()?;
        let layout = scene.param_layout();
        let off = &layout.type_offsets;
        let worlds = WorldSteps::of(scene);
        let mut items = Items::default();
        items.add_links(scene, off, worlds.as_ref());
        items.add_couplings(scene, off);
        let (runs, pairs) = runs_by_type(&items.springs, off);
        let springs = SpringPass {
            quadratic: runs
                .iter()
                .map(|r| type_of_run(off, r).and_then(|t| quadratic_slot(scene, off, t)))
                .collect(),
            runs,
            pairs,
        };
        let (runs, pairs) = runs_by_type(&items.dampers, off);
        let dampers = DamperPass { runs, pairs };
        let (runs, anchored) = runs_by_type(&items.anchors, off);
        let anchors = AnchorPass {
            runs,
            particles: anchored.iter().map(|a| a.0).collect(),
            points: anchored.iter().map(|a| a.1).collect(),
        };
        let (runs, particles) = runs_by_type(&items.drags, off);
        let drags = DragPass { runs, particles };
        let (runs, particles) = runs_by_type(&items.nonlinear_drags, off);
        let nonlinear_drags = NonlinearDragPass { runs, particles };
        let (runs, triples) = runs_by_type(&items.angles, off);
        let angles = AnglePass { runs, triples };
        let planes = plane_pass(scene, &items.planes, off, layout.mass_offset);
        let muscles = muscle_pass(scene, &items.muscles, off);
        let stateful = items.stateful(scene, off);
        let (conditionals, conditionals_read_velocity) = conditional_passes(scene, off);
        let needs_velocity = items.needs_velocity || conditionals_read_velocity;
        let (free, x0, x_minus1) = start_positions(scene, worlds.as_ref());
        let runaway = start_runaway(scene, &x0, worlds.as_ref());
        Ok(Plan {
            n: scene.particles.len(),
            dt: scene.dt,
            worlds,
            layout,
            free,
            x0,
            x_minus1,
            springs,
            dampers,
            anchors,
            drags,
            nonlinear_drags,
            angles,
            planes,
            muscles,
            conditionals,
            stateful,
            provot: items.provot,
            needs_velocity,
            has_gravity: scene.gravity != [0.0; 3],
            runaway,
            split: None,
        }
        .with_split())
    }

    /// Sets up the two-way split when the scene is large enough to gain from it.
    fn with_split(mut self) -> Self {
        let work = self.num_links()
            + self
                .conditionals
                .iter()
                .map(|c| c.a.len() + c.b.as_ref().map_or(0, Vec::len))
                .sum::<usize>();
        if work < SPLIT_MIN_WORK {
            return self;
        }
        let half = self.springs.pairs.len() / 2;
        let mut parts = [SpringPass::default(), SpringPass::default()];
        for (r, &quadratic) in self.springs.runs.iter().zip(&self.springs.quadratic) {
            for (k, range) in [(0, r.start..r.end.min(half)), (1, r.start.max(half)..r.end)] {
                if range.start < range.end {
                    let part = &mut parts[k];
                    let start = part.pairs.len();
                    part.pairs.extend_from_slice(&self.springs.pairs[range]);
                    part.quadratic.push(quadratic);
                    part.runs.push(crate::forces::Run {
                        param: r.param,
                        start,
                        end: part.pairs.len(),
                    });
                }
            }
        }
        self.split = Some(Split { springs: parts });
        self
    }

    /// Scratch sized for this plan.
    pub fn scratch(&self) -> Scratch {
        Scratch {
            v: vec![Vec3::zeros(); self.n],
            f: vec![Vec3::zeros(); self.n],
            grids: vec![Grid::default(); self.conditionals.len()],
            f2: if self.split.is_some() {
                vec![Vec3::zeros(); self.n]
            } else {
                Vec::new()
            },
            ready: vec![false; self.conditionals.len()],
            muscles: MuscleBuf::new(self.muscles.len()),
            state: vec![0.0; self.stateful.state_len()],
            frame: 0,
            runaway: self.runaway,
        }
    }

    /// Puts the stateful passes' state of `s` at frame 0 for parameters `p` (a new scratch
    /// starts at frame 0 with zero state, which is frame 0's for tendons but not for every
    /// stateful kind: call this before stepping with parameters).
    pub fn reset_state(&self, p: &[f64], s: &mut Scratch) {
        s.frame = 0;
        s.state.resize(self.stateful.state_len(), 0.0);
        self.stateful.reset(p, &self.x0, &mut s.state);
    }

    /// The divergence guard of a start given as observed frames of this plan's particles
    /// (NaN where a marker is missing), each world's steps counted as in the plan's own.
    pub fn runaway_of<F: AsRef<[Vec3]>>(
        &self,
        frames: impl IntoIterator<Item = F> + Clone,
    ) -> Runaway {
        runaway_of(self.dt, self.worlds.as_ref(), frames)
    }

    /// Number of link instances (conditional pairs not counted: they change every step).
    pub fn num_links(&self) -> usize {
        self.springs.pairs.len()
            + self.dampers.pairs.len()
            + self.anchors.particles.len()
            + self.drags.particles.len()
            + self.nonlinear_drags.particles.len()
            + self.angles.triples.len()
            + self.planes.len()
            + self.muscles.len()
            + self.stateful.len()
    }

    /// Time step of particle `i`'s world, s.
    pub fn dt_of(&self, i: usize) -> f64 {
        self.worlds.as_ref().map_or(self.dt, |w| w.dt[i])
    }

    /// Velocities `v(n) = (x(n) - x(n-1)) / dt` into `scratch.v` (each particle's world dt),
    /// when some pass reads them.
    pub fn velocities(&self, x: &[Vec3], x_prev: &[Vec3], v: &mut [Vec3]) {
        if !self.needs_velocity {
            return;
        }
        match &self.worlds {
            None => {
                let dt = self.dt;
                for ((v, x), xp) in v.iter_mut().zip(x).zip(x_prev) {
                    *v = (x - xp) / dt;
                }
            }
            Some(w) => w.velocities(x, x_prev, v),
        }
    }

    /// `f = F(x, v)`: the sum of every stateless pass's link forces (the stateful ones need
    /// their state: [`Plan::step`] adds them). `grids` and `muscles` are scratch
    /// ([`Scratch::grids`], [`Scratch::muscles`]).
    pub fn forces(
        &self,
        p: &[f64],
        x: &[Vec3],
        v: &[Vec3],
        f: &mut [Vec3],
        grids: &mut [Grid],
        muscles: &mut MuscleBuf,
    ) {
        f.fill(Vec3::zeros());
        self.springs.accumulate(p, x, v, f);
        self.dampers.accumulate(p, v, f);
        self.anchors.accumulate(p, x, v, f);
        self.drags.accumulate(p, v, f);
        self.nonlinear_drags.accumulate(p, v, f);
        self.angles.accumulate(p, x, f);
        self.planes.accumulate(p, x, v, f);
        self.muscles.accumulate(p, x, v, f, muscles);
        for (c, grid) in self.conditionals.iter().zip(grids) {
            c.accumulate(p, x, v, f, grid);
        }
    }

    /// `F(x, v)` in two halves (see [`Split`]), on two threads when rayon has them.
    fn forces_split(&self, split: &Split, p: &[f64], x: &[Vec3], s: &mut Scratch) {
        for ((c, grid), ready) in self.conditionals.iter().zip(&mut s.grids).zip(&mut s.ready) {
            *ready = c.prepare(p, x, grid);
        }
        let (grids, ready, v, mb) = (&s.grids, &s.ready, &s.v, &mut s.muscles);
        let conditional_half = |f: &mut [Vec3], index: usize| {
            let part = Part { index, count: 2 };
            for ((c, grid), &ok) in self.conditionals.iter().zip(grids).zip(ready) {
                if ok {
                    c.accumulate_part(p, x, v, f, grid, part);
                }
            }
        };
        let (f, f2) = (&mut s.f, &mut s.f2);
        rayon::join(
            || {
                f.fill(Vec3::zeros());
                split.springs[0].accumulate(p, x, v, f);
                self.dampers.accumulate(p, v, f);
                self.anchors.accumulate(p, x, v, f);
                self.drags.accumulate(p, v, f);
                self.nonlinear_drags.accumulate(p, v, f);
                self.angles.accumulate(p, x, f);
                self.planes.accumulate(p, x, v, f);
                self.muscles.accumulate(p, x, v, f, mb);
                conditional_half(f, 0);
            },
            || {
                f2.fill(Vec3::zeros());
                split.springs[1].accumulate(p, x, v, f2);
                conditional_half(f2, 1);
            },
        );
        for (a, b) in f.iter_mut().zip(f2.iter()) {
            *a += b;
        }
    }

    /// One step of the CORDIS scheme (SPEC §2.1): on entry `x` = x(n), `x_prev` = x(n-1),
    /// `s.state` the stateful passes' state at n = `s.frame`; on exit `x` = x(n+1), `x_prev` =
    /// x(n), the state and `s.frame` at n+1. Returns the first particle whose new position is not
    /// finite, if any (the step is still completed).
    pub fn step(
        &self,
        p: &[f64],
        x: &mut Vec<Vec3>,
        x_prev: &mut Vec<Vec3>,
        s: &mut Scratch,
    ) -> Option<usize> {
        let bad = self.step_unprojected(p, x, x_prev, s);
        self.provot.apply(p, x, &self.free);
        bad
    }

    /// [`Plan::step`] without its last phase, Provot's projection ([`ProvotPass`]): the
    /// output-error tangent runs that phase itself, recording its corrections
    /// ([`ProvotPass::apply_recorded`]); `step` is this followed by `self.provot.apply`.
    #[inline(always)]
    pub fn step_unprojected(
        &self,
        p: &[f64],
        x: &mut Vec<Vec3>,
        x_prev: &mut Vec<Vec3>,
        s: &mut Scratch,
    ) -> Option<usize> {
        self.velocities(x, x_prev, &mut s.v);
        match &self.split {
            None => self.forces(p, x, &s.v, &mut s.f, &mut s.grids, &mut s.muscles),
            Some(split) => self.forces_split(split, p, x, s),
        }
        if !self.stateful.is_empty() {
            self.stateful
                .accumulate(p, s.frame, x, &s.v, &mut s.f, &mut s.state);
        }
        s.frame += 1;
        let bad = self.integrate(p, x, x_prev, &s.f, (&s.runaway, s.frame));
        std::mem::swap(x, x_prev);
        bad
    }

    /// Writes x(n+1) into `x_prev` (so a swap completes the step): `2x - x_prev + dt² (F/m + g)`
    /// for free particles (each with its world's dt; gravity on the main world only), `x` for
    /// fixed ones. Returns the first particle beyond the guard `runaway` at frame `steps`.
    fn integrate(
        &self,
        p: &[f64],
        x: &[Vec3],
        x_prev: &mut [Vec3],
        f: &[Vec3],
        (runaway, steps): (&Runaway, usize),
    ) -> Option<usize> {
        // Gravity is read from `p` even when the scene had none: the plan must follow any
        // parameter vector of its layout, and adding a zero vector costs what skipping did.
        let o = self.layout.gravity_offset;
        let g = Vec3::new(p[o], p[o + 1], p[o + 2]);
        let guard = (runaway, runaway.limit(steps, g.norm()));
        match &self.worlds {
            None => self.integrate_with(OneClock::new(self.dt, g), p, x, x_prev, f, guard),
            Some(steps) => self.integrate_worlds(WorldClock { steps, g }, p, x, x_prev, f, guard),
        }
    }

    /// The several-worlds integrator, kept out of line (like [`WorldSteps::velocities`]) so
    /// that the one-world step compiles as before worlds existed: inlined, the two loops cost
    /// the one-world path a register spill, one more load per particle (callgrind).
    #[inline(never)]
    fn integrate_worlds(
        &self,
        clock: WorldClock<'_>,
        p: &[f64],
        x: &[Vec3],
        x_prev: &mut [Vec3],
        f: &[Vec3],
        guard: (&Runaway, f64),
    ) -> Option<usize> {
        self.integrate_with(clock, p, x, x_prev, f, guard)
    }

    #[inline(always)]
    fn integrate_with<C: Clock>(
        &self,
        clock: C,
        p: &[f64],
        x: &[Vec3],
        x_prev: &mut [Vec3],
        f: &[Vec3],
        (runaway, limit): (&Runaway, f64),
    ) -> Option<usize> {
        let m = &p[self.layout.mass_offset..self.layout.mass_offset + self.n];
        let mut finite = true;
        for i in 0..self.n {
            let next = if self.free[i] {
                (x[i] * 2.0 - x_prev[i]) + clock.kick(i, f[i] / m[i])
            } else {
                x[i]
            };
            finite &= runaway.within(&next, limit);
            x_prev[i] = next;
        }
        if finite {
            None
        } else {
            (0..self.n).find(|&i| !runaway.within(&x_prev[i], limit))
        }
    }
}

/// A type's damping (linear or quadratic) may be non-zero: its pass reads velocities.
fn damping_matters(scene: &Scene, t: usize) -> bool {
    let ty = &scene.types[t];
    ty.param("damping").is_some_and(|z| !z.is_known_zero())
        || ty
            .optional_param(OptionalParam::DampingQuadratic)
            .is_some_and(|z| !z.is_known_zero())
}

/// The parameter slot of a type's quadratic damping, if it has one.
fn quadratic_slot(scene: &Scene, off: &[usize], t: usize) -> Option<usize> {
    scene.types[t]
        .optional_index(OptionalParam::DampingQuadratic)
        .map(|k| off[t] + k)
}

/// A tendon's type and world.
type TypeWorld = (usize, usize);

/// A controlled tendon's ends and its controller's particles.
type Controlled = ([u32; 2], [u32; 2]);

/// A force transmitter's source: its link's ends and its type's parameter offset.
type SourceLink = ([u32; 2], usize);

/// The scene's links and couplings grouped by kind, each with its type (and world, for the
/// tendons), before they are grouped into runs; whether some pass reads velocities.
#[derive(Default)]
struct Items {
    springs: Vec<(usize, [u32; 2])>,
    dampers: Vec<(usize, [u32; 2])>,
    anchors: Vec<(usize, (u32, Vec3))>,
    drags: Vec<(usize, u32)>,
    nonlinear_drags: Vec<(usize, u32)>,
    angles: Vec<(usize, [u32; 3])>,
    /// A plane's particle and that particle's world dt.
    planes: Vec<(usize, (u32, f64))>,
    /// A muscle's ends and its link index.
    muscles: Vec<(usize, ([u32; 2], usize))>,
    tgrs: Vec<(TypeWorld, [u32; 2])>,
    controlled: Vec<(TypeWorld, Controlled)>,
    quadripoles: Vec<(usize, [u32; 4])>,
    position_transmitters: Vec<(usize, [u32; 4])>,
    force_transmitters: Vec<(usize, ([u32; 2], SourceLink))>,
    provot: ProvotPass,
    needs_velocity: bool,
}

impl Items {
    /// Every link, by kind (a spring with a `max_elongation` also gets its Provot limit).
    fn add_links(&mut self, scene: &Scene, off: &[usize], worlds: Option<&WorldSteps>) {
        let dt_of = |i: usize| worlds.map_or(scene.dt, |w| w.dt[i]);
        for (li, l) in scene.links.iter().enumerate() {
            let t = l.type_index;
            let ty = &scene.types[t];
            let ps: Vec<u32> = l.particles.iter().map(|&i| i as u32).collect();
            match ty.kind {
                LinkKind::Spring => {
                    self.springs.push((t, [ps[0], ps[1]]));
                    self.needs_velocity |= damping_matters(scene, t);
                    if let Some(k) = ty.optional_index(OptionalParam::MaxElongation) {
                        self.provot.links.push(ProvotLink {
                            i: ps[0],
                            j: ps[1],
                            param: off[t],
                            tau: off[t] + k,
                        });
                    }
                }
                LinkKind::Damper => {
                    self.dampers.push((t, [ps[0], ps[1]]));
                    self.needs_velocity = true;
                }
                LinkKind::Anchor => {
                    let point = l
                        .point
                        .or(ty.point)
                        .unwrap_or(scene.particles[l.particles[0]].pos);
                    self.anchors.push((t, (ps[0], Vec3::from(point))));
                    self.needs_velocity |= damping_matters(scene, t);
                }
                LinkKind::Drag => {
                    self.drags.push((t, ps[0]));
                    self.needs_velocity = true;
                }
                LinkKind::NonlinearDrag => {
                    self.nonlinear_drags.push((t, ps[0]));
                    self.needs_velocity = true;
                }
                LinkKind::Angle => self.angles.push((t, [ps[0], ps[1], ps[2]])),
                LinkKind::Plane => {
                    self.planes.push((t, (ps[0], dt_of(l.particles[0]))));
                    let friction_matters = ty.param("friction").is_some_and(|m| !m.is_known_zero());
                    self.needs_velocity |= damping_matters(scene, t) || friction_matters;
                }
                LinkKind::Muscle => {
                    self.muscles.push((t, ([ps[0], ps[1]], li)));
                    // Rates feed the damping and the neurons' rate weights.
                    self.needs_velocity |=
                        damping_matters(scene, t) || ty.w_rate().iter().any(|w| !w.is_known_zero());
                }
                LinkKind::Conditional => unreachable!("validated: conditional types have no links"),
                LinkKind::Tgr
                | LinkKind::Quadripole
                | LinkKind::PositionTransmitter
                | LinkKind::ForceTransmitter => unreachable!("validated: couplings are not links"),
            }
        }
    }

    /// Every coupling, by kind.
    fn add_couplings(&mut self, scene: &Scene, off: &[usize]) {
        for c in &scene.couplings {
            let t = c.type_index;
            let ps: Vec<u32> = c.particles.iter().map(|&i| i as u32).collect();
            match scene.types[t].kind {
                LinkKind::Tgr => {
                    let key = (t, scene.world_of(c.particles[0]));
                    match c.controller {
                        None => self.tgrs.push((key, [ps[0], ps[1]])),
                        Some(cd) => self
                            .controlled
                            .push((key, ([ps[0], ps[1]], cd.map(|i| i as u32)))),
                    }
                    self.needs_velocity |= damping_matters(scene, t);
                }
                LinkKind::Quadripole => self.quadripoles.push((t, [ps[0], ps[1], ps[2], ps[3]])),
                LinkKind::PositionTransmitter => self
                    .position_transmitters
                    .push((t, [ps[0], ps[1], ps[2], ps[3]])),
                LinkKind::ForceTransmitter => {
                    let src = &scene.links[c.source.expect("validated: a source")];
                    let ends = [src.particles[0] as u32, src.particles[1] as u32];
                    self.force_transmitters
                        .push((t, ([ps[0], ps[1]], (ends, off[src.type_index]))));
                    // The source's tension reads its rate when its damping may be non-zero.
                    self.needs_velocity |= damping_matters(scene, src.type_index);
                }
                k => unreachable!("validated: `{k}` is not a coupling kind"),
            }
        }
    }

    /// The passes with state carried between steps: tendons (driven by a signal or by a
    /// controller), quadripoles and transmitters.
    fn stateful(&self, scene: &Scene, off: &[usize]) -> Stateful {
        let type_of = |r: &crate::forces::Run| type_of_run(off, r).expect("a run's type");
        let signal_of = |r: &crate::forces::Run| {
            let name = scene.types[type_of(r)].signal.as_deref()?;
            Some(
                scene
                    .signal_index(name)
                    .expect("validated: the signal exists"),
            )
        };
        // A run's tendon start: the slots of its type's `tendon_position` and `tendon_velocity`
        // (absent: 0, at rest at the anchor).
        let initial_of = |r: &crate::forces::Run| {
            let t = type_of(r);
            let slot = |w| scene.types[t].optional_index(w).map(|k| off[t] + k);
            [
                slot(OptionalParam::TendonPosition),
                slot(OptionalParam::TendonVelocity),
            ]
        };
        let (runs, tgr_worlds, pairs) = runs_by_type_and_world(&self.tgrs, off);
        let (c_runs, c_worlds, c_items) = runs_by_type_and_world(&self.controlled, off);
        let (q_runs, quads) = runs_by_type(&self.quadripoles, off);
        let (p_runs, p_quads) = runs_by_type(&self.position_transmitters, off);
        let (f_runs, f_items) = runs_by_type(&self.force_transmitters, off);
        Stateful {
            signals: scene.signals.clone(),
            tgrs: TgrPass {
                signals: runs
                    .iter()
                    .map(|r| signal_of(r).expect("validated: an undriven tgr has a signal"))
                    .collect(),
                dts: tgr_worlds.iter().map(|&w| scene.world_dt(w)).collect(),
                initial: runs.iter().map(initial_of).collect(),
                runs,
                pairs,
            },
            controlled_tgrs: ControlledTgrPass {
                signals: c_runs.iter().map(signal_of).collect(),
                dts: c_worlds.iter().map(|&w| scene.world_dt(w)).collect(),
                initial: c_runs.iter().map(initial_of).collect(),
                pairs: c_items.iter().map(|i| i.0).collect(),
                controllers: c_items.iter().map(|i| i.1).collect(),
                runs: c_runs,
            },
            quadripoles: QuadripolePass {
                runs: q_runs,
                quads,
            },
            position_transmitters: QuadripolePass {
                runs: p_runs,
                quads: p_quads,
            },
            force_transmitters: ForceTransmitterPass {
                runs: f_runs,
                pairs: f_items.iter().map(|i| i.0).collect(),
                sources: f_items.iter().map(|i| i.1).collect(),
            },
        }
    }
}

/// The type of a run (the type whose parameters start at the run's offset).
fn type_of_run(off: &[usize], r: &crate::forces::Run) -> Option<usize> {
    off.iter().position(|&o| o == r.param)
}

/// One pass per conditional type, over the members of its group (or its two groups); and
/// whether one of them reads velocities (a damping that may be non-zero).
fn conditional_passes(scene: &Scene, off: &[usize]) -> (Vec<ConditionalPass>, bool) {
    let members = |g: &str| -> Vec<u32> {
        (0..scene.particles.len() as u32)
            .filter(|&i| scene.particles[i as usize].group.as_deref() == Some(g))
            .collect()
    };
    let mut conditionals = Vec::new();
    let mut needs_velocity = false;
    for (t, ty) in scene.types.iter().enumerate() {
        if ty.kind != LinkKind::Conditional {
            continue;
        }
        needs_velocity |= damping_matters(scene, t);
        let a = members(&ty.groups[0]);
        let b = match ty.groups.get(1) {
            Some(g) if *g != ty.groups[0] => Some(members(g)),
            _ => None,
        };
        conditionals.push(ConditionalPass {
            param: off[t],
            quadratic: quadratic_slot(scene, off, t),
            a,
            b,
        });
    }
    (conditionals, needs_velocity)
}

/// Which particles move, `x(0)`, and `x(-1) = x(0) − v0 dt` (each particle's own world dt: v0
/// is a velocity in its world's time; a fixed particle's `x(-1)` is its `x(0)`).
fn start_positions(
    scene: &Scene,
    worlds: Option<&WorldSteps>,
) -> (Vec<bool>, Vec<Vec3>, Vec<Vec3>) {
    let free: Vec<bool> = scene.particles.iter().map(|p| !p.fixed).collect();
    let x0: Vec<Vec3> = scene.particles.iter().map(|p| Vec3::from(p.pos)).collect();
    let x_minus1 = scene
        .particles
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let x = Vec3::from(p.pos);
            if p.fixed {
                x
            } else {
                let dt = worlds.map_or(scene.dt, |w| w.dt[i]);
                x - Vec3::from(p.vel) * dt
            }
        })
        .collect();
    (free, x0, x_minus1)
}

/// The plane pass: instances grouped by type, each run with its type's surface (the normal
/// made a unit vector; validated non-zero).
fn plane_pass(
    scene: &Scene,
    items: &[(usize, (u32, f64))],
    off: &[usize],
    mass_offset: usize,
) -> PlanePass {
    let (runs, members) = runs_by_type(items, off);
    let surfaces = runs
        .iter()
        .map(|r| {
            let ty = &scene.types[type_of_run(off, r).expect("a run's type")];
            Surface {
                point: Vec3::from(ty.point.expect("validated: a plane has a point")),
                normal: crate::forces::plane::unit_normal(ty.normal.expect("validated: a normal"))
                    .expect("validated: the normal is not zero"),
            }
        })
        .collect();
    PlanePass {
        runs,
        surfaces,
        particles: members.iter().map(|m| m.0).collect(),
        dt: members.iter().map(|m| m.1).collect(),
        mass_offset,
    }
}

/// The muscle pass: instances grouped by type, each one's observed links (link indices) turned
/// into positions in the pass.
fn muscle_pass(scene: &Scene, items: &[(usize, ([u32; 2], usize))], off: &[usize]) -> MusclePass {
    let (runs, members) = runs_by_type(items, off);
    let mut at_link = vec![u32::MAX; scene.links.len()];
    for (m, &(_, li)) in members.iter().enumerate() {
        at_link[li] = m as u32;
    }
    let mut observed = Vec::new();
    let mut start = vec![0u32];
    for &(_, li) in &members {
        observed.extend(scene.observed_links(li).into_iter().map(|k| at_link[k]));
        start.push(observed.len() as u32);
    }
    let weights = runs
        .iter()
        .map(|r| scene.types[scene.links[members[r.start].1].type_index].num_weights())
        .collect();
    MusclePass {
        runs,
        weights,
        pairs: members.iter().map(|m| m.0).collect(),
        observed,
        start,
    }
}

/// The guard of the scene's start (see [`crate::runaway`]): the bounding box of `x(0)`, the
/// fastest initial velocity.
fn start_runaway(scene: &Scene, x0: &[Vec3], worlds: Option<&WorldSteps>) -> Runaway {
    let fastest = scene
        .particles
        .iter()
        .map(|p| Vec3::from(p.vel).norm())
        .fold(0.0, f64::max);
    Runaway {
        speed: fastest,
        ..runaway_of(scene.dt, worlds, [x0])
    }
}

/// [`Runaway::of_motion`] with the worlds' steps: the launch speed at the smallest, time at the
/// largest (a particle of a finer world has moved for less time), speeds measured at the
/// smallest (so never underestimated).
fn runaway_of<F: AsRef<[Vec3]>>(
    dt: f64,
    worlds: Option<&WorldSteps>,
    frames: impl IntoIterator<Item = F> + Clone,
) -> Runaway {
    let (min_dt, max_dt) = worlds.map_or((dt, dt), |w| {
        let fold = |f: fn(f64, f64) -> f64, init| w.dts.iter().copied().fold(init, f);
        (fold(f64::min, f64::INFINITY), fold(f64::max, 0.0))
    });
    Runaway {
        dt: max_dt,
        ..Runaway::of_motion(frames, min_dt)
    }
}
