//! Worlds (SPEC §2.5, thesis §5.4.2): sets of particles with their own time step.
//!
//! "Deux mondes physiques sont séparés ssi ils ont des variables temporelles différentes": a
//! particle of world w advances by that world's `dt_w`, both in its velocity
//! `v(n) = (x(n) - x(n-1)) / dt_w` and in its update `x(n+1) = 2x(n) - x(n-1) + dt_w² F/m`.
//! Every world takes one step of its own `dt` per main frame (lockstep), so a trajectory holds
//! one frame per main step whatever the worlds. Gravity acts on the main world only: the other
//! worlds are the thesis' "mental representations" (controllers), which have no weight.
//!
//! Plain links stay inside one world (a link that crossed two time scales would have no
//! single `dt` to be integrated with); only couplings cross worlds.
//!
//! A scene whose particles are all in the main world compiles to a plan without [`WorldSteps`]
//! and steps exactly as before worlds existed (same code, same bits).

use crate::error::{CordisError, Result};
use crate::{Coupling, LinkKind, Scene, Vec3};

/// Name of the scene's own world, whose `dt` is the scene `dt`.
pub const MAIN_WORLD: &str = "main";

/// An extra world, declared in the scene's top-level `"worlds"` object.
#[derive(Clone, Debug, PartialEq)]
pub struct World {
    pub name: String,
    /// Time step of this world, s: one step of it per main frame.
    pub dt: f64,
}

impl Scene {
    /// The scene as its frame `k` sees the clock: every signal's phase advanced by
    /// `k dt_w / period`, `dt_w` the time step of the world whose TGRs read it (a TGR reads
    /// its signal at `n dt_w`), so that a take cropped to start at frame `k` of this scene's
    /// motion is driven by the same commands at the same frames. Signals no TGR reads are
    /// advanced by the main `dt`. Fails, naming the signal, when TGRs in worlds of different
    /// time steps read one signal (no single phase fits both). The tendons' state at frame `k`
    /// is another matter: `tendon_position` / `tendon_velocity` (known or identified).
    pub fn from_frame(&self, k: usize) -> Result<Scene> {
        let mut out = self.clone();
        for sg in out.signals.iter_mut() {
            let mut dt = None;
            for c in &self.couplings {
                let ty = &self.types[c.type_index];
                if ty.kind != LinkKind::Tgr || ty.signal.as_deref() != Some(sg.name.as_str()) {
                    continue;
                }
                let w = self.particle_dt(c.particles[0]);
                match dt {
                    Some(d) if d != w => {
                        return Err(CordisError::scene(
                            format!("signals.{}", sg.name),
                            format!(
                                "`{}` drives TGRs in worlds of time steps {d} s and {w} s: \
                                 frame {k} is not one time for both",
                                sg.name
                            ),
                        ));
                    }
                    _ => dt = Some(w),
                }
            }
            let c = sg.phase + k as f64 * dt.unwrap_or(self.dt) / sg.period;
            sg.phase = c - c.floor();
        }
        Ok(out)
    }

    /// Declares a world of time step `dt` (s), replacing one of the same name; returns its
    /// world index (main = 0).
    pub fn add_world(&mut self, name: impl Into<String>, dt: f64) -> usize {
        let name = name.into();
        if let Some(k) = self.worlds.iter().position(|w| w.name == name) {
            self.worlds[k].dt = dt;
            k + 1
        } else {
            self.worlds.push(World { name, dt });
            self.worlds.len()
        }
    }

    /// Index of the world called `name`: 0 for the main world (`None` or `"main"`), k for
    /// `worlds[k - 1]`; `None` when no world has that name.
    pub fn world_index(&self, name: Option<&str>) -> Option<usize> {
        match name {
            None | Some(MAIN_WORLD) => Some(0),
            Some(n) => self.worlds.iter().position(|w| w.name == n).map(|k| k + 1),
        }
    }

    /// World index of particle `i` (0 = main). A particle of an undeclared world (rejected by
    /// [`Scene::validate`]) counts as main.
    pub fn world_of(&self, i: usize) -> usize {
        self.world_index(self.particles[i].world.as_deref())
            .unwrap_or(0)
    }

    /// Name of world `w` (0 = main).
    pub fn world_name(&self, w: usize) -> &str {
        if w == 0 {
            MAIN_WORLD
        } else {
            &self.worlds[w - 1].name
        }
    }

    /// Time step of world `w` (0 = main: the scene `dt`), s.
    pub fn world_dt(&self, w: usize) -> f64 {
        if w == 0 {
            self.dt
        } else {
            self.worlds[w - 1].dt
        }
    }

    /// Time step of particle `i`'s world, s.
    pub fn particle_dt(&self, i: usize) -> f64 {
        self.world_dt(self.world_of(i))
    }

    /// True when some particle lives outside the main world (the plan then steps each particle
    /// with its world's `dt`).
    pub fn has_worlds(&self) -> bool {
        (0..self.particles.len()).any(|i| self.world_of(i) != 0)
    }

    /// The world declarations: distinct names other than `main`, a positive `dt` (particles'
    /// worlds are checked with each particle).
    pub(crate) fn validate_worlds(&self) -> Result<()> {
        for (k, w) in self.worlds.iter().enumerate() {
            let at = format!("worlds.{}", w.name);
            if w.name.is_empty() {
                return Err(CordisError::scene(
                    format!("worlds[{k}]"),
                    "a world needs a non-empty name",
                ));
            }
            if w.name == MAIN_WORLD {
                return Err(CordisError::scene(
                    at,
                    "`main` is the scene's own world: its time step is the scene `dt`",
                ));
            }
            if self.worlds[..k].iter().any(|o| o.name == w.name) {
                return Err(CordisError::scene(at, "the name is used twice"));
            }
            if !(w.dt.is_finite() && w.dt > 0.0) {
                return Err(CordisError::scene(
                    format!("{at}.dt"),
                    format!("must be a positive number, got {}", w.dt),
                ));
            }
        }
        Ok(())
    }

    /// Particle `i`'s world is declared (part of [`Scene::validate_particle`]).
    pub(crate) fn check_particle_world(&self, i: usize) -> Result<()> {
        match &self.particles[i].world {
            Some(name) if self.world_index(Some(name)).is_none() => Err(CordisError::scene(
                format!("particles[{i}].world"),
                format!("no world named `{name}` in `worlds`"),
            )),
            _ => Ok(()),
        }
    }

    /// A plain link (`links[li]`, particle indices already checked) joins particles of one world.
    pub(crate) fn check_link_world(&self, at: &str, particles: &[usize]) -> Result<()> {
        let Some(&first) = particles.first() else {
            return Ok(());
        };
        let w0 = self.world_of(first);
        for (k, &p) in particles.iter().enumerate().skip(1) {
            let w = self.world_of(p);
            if w != w0 {
                return Err(CordisError::scene(
                    format!("{at}.particles[{k}]"),
                    format!(
                        "particle {p} is in world `{}` but particle {first} in `{}`: a link \
                         stays inside one world (join worlds with a coupling)",
                        self.world_name(w),
                        self.world_name(w0)
                    ),
                ));
            }
        }
        Ok(())
    }

    /// A coupling against the worlds (part of [`Scene::validate`], particle indices already
    /// checked): each dipole it reads or pushes lies in one world (a TGR's link, a quadripole's
    /// or transmitter's dipoles: a length between two time scales has no single `dt`), and a
    /// TGR's controller lies in one world other than the muscle's (thesis §5.4.2: controller and
    /// controlled are separate worlds, each with its own time).
    pub(crate) fn check_coupling_worlds(
        &self,
        at: &str,
        kind: LinkKind,
        c: &Coupling,
    ) -> Result<()> {
        let why = match kind {
            LinkKind::Tgr => {
                "a TGR's link stays inside one world (its tendon steps with that \
                              world's dt; a controller in another world drives it through \
                              `controller`)"
            }
            _ => {
                "a coupling's dipole stays inside one world (it is a length, and a length \
                  between two time scales has no single dt)"
            }
        };
        for (k, dipole) in c.particles.chunks(2).enumerate() {
            if let [a, b] = *dipole {
                let (wa, wb) = (self.world_of(a), self.world_of(b));
                if wa != wb {
                    return Err(CordisError::scene(
                        format!("{at}.particles[{}]", 2 * k + 1),
                        format!(
                            "particle {b} is in world `{}` but particle {a} in `{}`: {why}",
                            self.world_name(wb),
                            self.world_name(wa)
                        ),
                    ));
                }
            }
        }
        let Some([cc, cd]) = c.controller else {
            return Ok(());
        };
        let muscle = self.world_of(c.particles[0]);
        for (k, q) in [cc, cd].into_iter().enumerate() {
            if self.world_of(q) == muscle {
                return Err(CordisError::scene(
                    format!("{at}.controller[{k}]"),
                    format!(
                        "particle {q} is in the muscle's own world `{}`: a controller lives in \
                         another world (thesis §5.4.2: controller and controlled keep separate \
                         times)",
                        self.world_name(muscle)
                    ),
                ));
            }
        }
        let (wc, wd) = (self.world_of(cc), self.world_of(cd));
        if wc != wd {
            return Err(CordisError::scene(
                format!("{at}.controller[1]"),
                format!(
                    "particle {cd} is in world `{}` but particle {cc} in `{}`: a controller \
                     dipole stays inside one world",
                    self.world_name(wd),
                    self.world_name(wc)
                ),
            ));
        }
        Ok(())
    }

    /// A conditional type's groups lie in one world (its pairs are links).
    pub(crate) fn check_groups_world(&self, ti: usize) -> Result<()> {
        let t = &self.types[ti];
        if t.kind != LinkKind::Conditional {
            return Ok(());
        }
        let mut first: Option<(usize, usize)> = None;
        for (i, p) in self.particles.iter().enumerate() {
            if !p.group.as_ref().is_some_and(|g| t.groups.contains(g)) {
                continue;
            }
            let w = self.world_of(i);
            match first {
                None => first = Some((i, w)),
                Some((j, w0)) if w != w0 => {
                    return Err(CordisError::scene(
                        format!("types.{}.groups", t.name),
                        format!(
                            "particle {i} is in world `{}` but particle {j} in `{}`: a \
                             conditional link stays inside one world",
                            self.world_name(w),
                            self.world_name(w0)
                        ),
                    ));
                }
                Some(_) => {}
            }
        }
        Ok(())
    }
}

/// The per-particle time data of a plan whose particles are not all in the main world.
#[derive(Clone, Debug)]
pub struct WorldSteps {
    /// World index of every particle (0 = main).
    pub world: Vec<u32>,
    /// Time step of every world, s (index 0 = main).
    pub dts: Vec<f64>,
    /// Time step of every particle, s.
    pub dt: Vec<f64>,
    /// `dt²` of every particle, s².
    pub dt2: Vec<f64>,
}

impl WorldSteps {
    /// The worlds of `scene`, or `None` when every particle is in the main world.
    pub fn of(scene: &Scene) -> Option<WorldSteps> {
        if !scene.has_worlds() {
            return None;
        }
        let n = scene.particles.len();
        let world: Vec<u32> = (0..n).map(|i| scene.world_of(i) as u32).collect();
        let dts: Vec<f64> = (0..=scene.worlds.len())
            .map(|w| scene.world_dt(w))
            .collect();
        let dt: Vec<f64> = world.iter().map(|&w| dts[w as usize]).collect();
        let dt2 = dt.iter().map(|d| d * d).collect();
        Some(WorldSteps {
            world,
            dts,
            dt,
            dt2,
        })
    }
}

impl WorldSteps {
    /// `v = (x - x_prev) / dt` with each particle's world dt (m/s).
    #[inline(never)]
    pub fn velocities(&self, x: &[Vec3], x_prev: &[Vec3], v: &mut [Vec3]) {
        for (((v, x), xp), dt) in v.iter_mut().zip(x).zip(x_prev).zip(&self.dt) {
            *v = (x - xp) / *dt;
        }
    }
}

/// How a step turns a particle's acceleration into motion: its `dt` and gravity. One world
/// ([`OneClock`]) or several ([`WorldClock`]); loops generic over it compile to the same code
/// as a loop written with a constant `dt` for the one-world case.
pub trait Clock {
    /// Time step of particle `i`, s.
    fn dt(&self, i: usize) -> f64;
    /// `dt² (a + g)` (m) for particle `i`'s acceleration `a` (m/s²), with the gravity `g` its
    /// world feels, evaluated as `(a + g) * dt²`.
    fn kick(&self, i: usize, a: Vec3) -> Vec3;
}

/// Every particle in the main world: one `dt`, gravity everywhere.
#[derive(Clone, Copy, Debug)]
pub struct OneClock {
    pub dt: f64,
    pub dt2: f64,
    /// Gravity, m/s².
    pub g: Vec3,
}

impl OneClock {
    pub fn new(dt: f64, g: Vec3) -> Self {
        OneClock {
            dt,
            dt2: dt * dt,
            g,
        }
    }
}

impl Clock for OneClock {
    #[inline(always)]
    fn dt(&self, _: usize) -> f64 {
        self.dt
    }
    #[inline(always)]
    fn kick(&self, _: usize, a: Vec3) -> Vec3 {
        (a + self.g) * self.dt2
    }
}

/// Several worlds: each particle's own `dt`, gravity on the main world only.
#[derive(Clone, Copy, Debug)]
pub struct WorldClock<'a> {
    pub steps: &'a WorldSteps,
    /// Gravity of the main world, m/s².
    pub g: Vec3,
}

impl Clock for WorldClock<'_> {
    #[inline(always)]
    fn dt(&self, i: usize) -> f64 {
        self.steps.dt[i]
    }
    #[inline(always)]
    fn kick(&self, i: usize, a: Vec3) -> Vec3 {
        let a = if self.steps.world[i] == 0 {
            a + self.g
        } else {
            a
        };
        a * self.steps.dt2[i]
    }
}
