//! The scene: particles, the link catalogue and link instances (thesis `.mas` + `.cat` + `.ini`).

use crate::error::{CordisError, Result};
use crate::signal::{Shape, Signal};
use crate::{Coupling, Link, LinkKind, LinkType, OptionalParam, Param, Particle, World};

/// A Cordis-Anima network and its time step. Build one in code with [`Scene::new`] and the
/// `add_*` methods, or read one with [`Scene::from_json_str`]; run [`Scene::validate`] before
/// simulating (the JSON reader does).
#[derive(Clone, Debug, PartialEq)]
pub struct Scene {
    /// Time step in s.
    pub dt: f64,
    /// Acceleration of every free particle, m/s².
    pub gravity: [f64; 3],
    pub particles: Vec<Particle>,
    /// The catalogue, in file order.
    pub types: Vec<LinkType>,
    pub links: Vec<Link>,
    /// Command signals, by name (known inputs: never identified).
    pub signals: Vec<Signal>,
    /// Instances of the coupling kinds ([`LinkKind::is_coupling`]), in file order.
    pub couplings: Vec<Coupling>,
    /// Extra worlds with their own time step ([`crate::world`]); the main world is implicit.
    pub worlds: Vec<World>,
}

impl Scene {
    pub fn new(dt: f64) -> Self {
        Scene {
            dt,
            gravity: [0.0; 3],
            particles: Vec::new(),
            types: Vec::new(),
            links: Vec::new(),
            signals: Vec::new(),
            couplings: Vec::new(),
            worlds: Vec::new(),
        }
    }

    pub fn add_particle(&mut self, p: Particle) -> usize {
        self.particles.push(p);
        self.particles.len() - 1
    }

    /// Adds a type to the catalogue, replacing one of the same name.
    pub fn add_type(&mut self, t: LinkType) -> usize {
        if let Some(i) = self.type_index(&t.name) {
            self.types[i] = t;
            i
        } else {
            self.types.push(t);
            self.types.len() - 1
        }
    }

    /// Adds a link of the named type. Panics on an unknown type name (code-built scenes only).
    pub fn add_link(&mut self, type_name: &str, particles: &[usize]) -> usize {
        let type_index = self
            .type_index(type_name)
            .unwrap_or_else(|| panic!("no link type named {type_name}"));
        self.links.push(Link {
            type_index,
            particles: particles.to_vec(),
            point: None,
            observes: None,
        });
        self.links.len() - 1
    }

    /// Adds a signal, replacing one of the same name.
    pub fn add_signal(&mut self, s: Signal) -> usize {
        if let Some(i) = self.signal_index(&s.name) {
            self.signals[i] = s;
            i
        } else {
            self.signals.push(s);
            self.signals.len() - 1
        }
    }

    pub fn signal_index(&self, name: &str) -> Option<usize> {
        self.signals.iter().position(|s| s.name == name)
    }

    /// Adds a coupling of the named type. Panics on an unknown type name (code-built scenes
    /// only).
    pub fn add_coupling(&mut self, type_name: &str, particles: &[usize]) -> usize {
        let type_index = self
            .type_index(type_name)
            .unwrap_or_else(|| panic!("no link type named {type_name}"));
        self.couplings.push(Coupling {
            type_index,
            particles: particles.to_vec(),
            source: None,
            controller: None,
        });
        self.couplings.len() - 1
    }

    /// Adds a `tgr` coupling of the named type between `particles` (M1, M2) whose tendon is
    /// anchored on the controller dipole `controller` (two particles of another world): the
    /// central-control muscle ([`crate::forces::controlled_tgr`]). Panics on an unknown type
    /// name (code-built scenes only).
    pub fn add_controlled_tgr(
        &mut self,
        type_name: &str,
        particles: [usize; 2],
        controller: [usize; 2],
    ) -> usize {
        let c = self.add_coupling(type_name, &particles);
        self.couplings[c].controller = Some(controller);
        c
    }

    /// Adds a `force_transmitter` coupling of the named type on dipole `particles`, fed by the
    /// tension of spring link `source`. Panics on an unknown type name (code-built scenes only).
    pub fn add_force_transmitter(
        &mut self,
        type_name: &str,
        particles: [usize; 2],
        source: usize,
    ) -> usize {
        let c = self.add_coupling(type_name, &particles);
        self.couplings[c].source = Some(source);
        c
    }

    pub fn type_index(&self, name: &str) -> Option<usize> {
        self.types.iter().position(|t| t.name == name)
    }

    pub fn num_particles(&self) -> usize {
        self.particles.len()
    }

    /// True when some parameter or mass is still to be identified.
    pub fn has_unknowns(&self) -> bool {
        self.particles.iter().any(|p| p.mass.is_unknown())
            || self
                .types
                .iter()
                .any(|t| t.params.iter().any(Param::is_unknown))
    }

    /// Checks every semantic rule of SPEC §5.1 and names the place of the first violation.
    pub fn validate(&self) -> Result<()> {
        self.validate_globals()?;
        self.validate_worlds()?;
        for i in 0..self.particles.len() {
            self.validate_particle(i)?;
        }
        self.validate_signals()?;
        for ti in 0..self.types.len() {
            self.validate_type(ti)?;
        }
        self.validate_links()?;
        self.validate_couplings()
    }

    /// The rules on `dt` and `gravity` alone (part of [`Scene::validate`]), for editors that
    /// change one of them and need not re-check the whole scene.
    pub fn validate_globals(&self) -> Result<()> {
        if !(self.dt.is_finite() && self.dt > 0.0) {
            return Err(CordisError::scene(
                "dt",
                format!("must be a positive number, got {}", self.dt),
            ));
        }
        check_finite3("gravity", &self.gravity)
    }

    /// The rules on particle `i` alone: mass positive (or a valid box), finite position and
    /// velocity. Part of [`Scene::validate`]; `i` must exist.
    pub fn validate_particle(&self, i: usize) -> Result<()> {
        let p = &self.particles[i];
        let at = format!("particles[{i}]");
        check_param(&format!("{at}.mass"), &p.mass, Sign::Positive)?;
        check_finite3(&format!("{at}.pos"), &p.pos)?;
        check_finite3(&format!("{at}.vel"), &p.vel)?;
        self.check_particle_world(i)
    }

    /// The rules on catalogue entry `ti` alone (name, parameter count and signs, kind-specific
    /// keys); the links that use it are checked by [`Scene::validate`]. `ti` must exist.
    pub fn validate_type(&self, ti: usize) -> Result<()> {
        let t = &self.types[ti];
        let at = format!("types.{}", t.name);
        self.check_type_name(ti)?;
        check_param_count(t, &at)?;
        check_param_signs(t, &at)?;
        check_optional_params(t, &at)?;
        check_neural_weights(t, &at)?;
        if t.observes.is_some() && t.kind != LinkKind::Muscle {
            return Err(CordisError::scene(
                format!("{at}.observes"),
                "only muscle types have it",
            ));
        }
        self.check_tgr_signal(ti, &at)?;
        if let Some(point) = &t.point {
            if !matches!(t.kind, LinkKind::Anchor | LinkKind::Plane) {
                return Err(CordisError::scene(
                    format!("{at}.point"),
                    "only anchors and planes have it",
                ));
            }
            check_finite3(&format!("{at}.point"), point)?;
        }
        check_surface(&at, t)?;
        if t.kind == LinkKind::Conditional {
            if !(1..=2).contains(&t.groups.len()) {
                return Err(CordisError::scene(
                    format!("{at}.groups"),
                    format!("names one or two groups, got {}", t.groups.len()),
                ));
            }
            self.check_groups_have_particles(ti)?;
            self.check_groups_world(ti)?;
        } else if !t.groups.is_empty() {
            return Err(CordisError::scene(
                format!("{at}.groups"),
                "only conditional types have it",
            ));
        }
        Ok(())
    }

    /// Type `ti` has a name, and no type before it has the same.
    fn check_type_name(&self, ti: usize) -> Result<()> {
        let t = &self.types[ti];
        if t.name.is_empty() {
            return Err(CordisError::scene(
                format!("types[{ti}]"),
                "a type needs a non-empty name",
            ));
        }
        if self.types[..ti].iter().any(|o| o.name == t.name) {
            return Err(CordisError::scene(
                format!("types.{}", t.name),
                "the name is used twice",
            ));
        }
        Ok(())
    }

    /// A `tgr` type names an existing signal, unless every coupling of it has a controller;
    /// no other kind names one.
    fn check_tgr_signal(&self, ti: usize, at: &str) -> Result<()> {
        let t = &self.types[ti];
        match (&t.signal, t.kind == LinkKind::Tgr) {
            (Some(name), true) => {
                if self.signal_index(name).is_none() {
                    return Err(CordisError::scene(
                        format!("{at}.signal"),
                        format!("no signal named `{name}` in `signals`"),
                    ));
                }
            }
            (None, true) => {
                // A controller may drive the tendon instead: every coupling of the type needs one.
                let undriven = self
                    .couplings
                    .iter()
                    .position(|c| c.type_index == ti && c.controller.is_none());
                if let Some(k) = undriven {
                    return Err(CordisError::scene(
                        at,
                        format!(
                            "a `tgr` type needs `signal` (the name of its command signal) \
                             unless every coupling of it has a `controller` (couplings[{k}] \
                             has none)"
                        ),
                    ));
                }
            }
            (Some(_), false) => {
                return Err(CordisError::scene(
                    format!("{at}.signal"),
                    "only tgr types have it",
                ))
            }
            (None, false) => {}
        }
        Ok(())
    }

    /// Every group a conditional type names has a particle: a type whose group is empty
    /// never links a pair, and is nearly always a misspelt name (`gaz`), which used to leave
    /// the scene silently without that force. An error rather than a warning: a scene file
    /// has no other channel, and removing an unused type loses nothing.
    fn check_groups_have_particles(&self, ti: usize) -> Result<()> {
        let t = &self.types[ti];
        for g in &t.groups {
            if self.particles.iter().any(|p| p.group.as_ref() == Some(g)) {
                continue;
            }
            let present: std::collections::BTreeSet<&str> = self
                .particles
                .iter()
                .filter_map(|p| p.group.as_deref())
                .collect();
            let present = if present.is_empty() {
                "no particle has a group".to_string()
            } else {
                let names: Vec<&str> = present.iter().take(10).copied().collect();
                let more = if present.len() > 10 { ", …" } else { "" };
                format!("the groups are {}{more}", names.join(", "))
            };
            return Err(CordisError::scene(
                format!("types.{}.groups", t.name),
                crate::error::printable(&format!(
                    "no particle is in group `{g}` ({present}): the type would never link a pair"
                )),
            ));
        }
        Ok(())
    }

    /// The rules on the link instances (types exist, arity, particle indices, muscles'
    /// observed links).
    fn validate_links(&self) -> Result<()> {
        for (li, l) in self.links.iter().enumerate() {
            let at = format!("links[{li}]");
            let Some(t) = self.types.get(l.type_index) else {
                return Err(CordisError::scene(
                    format!("{at}.type"),
                    format!("type index {} does not exist", l.type_index),
                ));
            };
            if t.kind == LinkKind::Conditional {
                return Err(CordisError::scene(
                    format!("{at}.type"),
                    format!(
                        "`{}` is conditional: its pairs are found from its groups, not listed",
                        t.name
                    ),
                ));
            }
            if t.kind.is_coupling() {
                return Err(CordisError::scene(
                    format!("{at}.type"),
                    format!(
                        "`{}` is a `{}` type, a coupling kind: list it in `couplings`",
                        t.name, t.kind
                    ),
                ));
            }
            self.check_particles(&at, t.kind, &l.particles)?;
            self.check_link_world(&at, &l.particles)?;
            if let Some(point) = &l.point {
                if t.kind != LinkKind::Anchor {
                    return Err(CordisError::scene(
                        format!("{at}.point"),
                        "only anchor links have it",
                    ));
                }
                check_finite3(&format!("{at}.point"), point)?;
            }
            if t.kind == LinkKind::Muscle {
                self.check_observes(li, &at)?;
            } else if l.observes.is_some() {
                return Err(CordisError::scene(
                    format!("{at}.observes"),
                    "only muscle links have it",
                ));
            }
        }
        Ok(())
    }

    /// The rules on the couplings (types exist and are coupling kinds, arity, particles).
    fn validate_couplings(&self) -> Result<()> {
        for (ci, c) in self.couplings.iter().enumerate() {
            let at = format!("couplings[{ci}]");
            let Some(t) = self.types.get(c.type_index) else {
                return Err(CordisError::scene(
                    format!("{at}.type"),
                    format!("type index {} does not exist", c.type_index),
                ));
            };
            if !t.kind.is_coupling() {
                return Err(CordisError::scene(
                    format!("{at}.type"),
                    format!(
                        "`{}` is a `{}` type, not a coupling kind: list it in `links`",
                        t.name, t.kind
                    ),
                ));
            }
            self.check_particles(&at, t.kind, &c.particles)?;
            self.check_source(&at, t.kind, c.source)?;
            self.check_controller(&at, t.kind, c)?;
            self.check_coupling_worlds(&at, t.kind, c)?;
        }
        Ok(())
    }

    /// A force transmitter names an existing spring link as `source`; other couplings do not.
    fn check_source(&self, at: &str, kind: LinkKind, source: Option<usize>) -> Result<()> {
        let place = format!("{at}.source");
        match (kind == LinkKind::ForceTransmitter, source) {
            (false, Some(_)) => Err(CordisError::scene(
                place,
                "only force_transmitter couplings have it",
            )),
            (true, None) => Err(CordisError::scene(
                at,
                "a force_transmitter needs `source`: the index in `links` of a spring",
            )),
            (true, Some(li)) => match self.links.get(li).map(|l| &self.types[l.type_index]) {
                // The transmitter reads `K (L - l0) + Z s`: a quadratic viscosity would be
                // left out of the tension it sends.
                Some(t)
                    if t.kind == LinkKind::Spring
                        && t.optional_param(OptionalParam::DampingQuadratic)
                            .is_some_and(|z| !z.is_known_zero()) =>
                {
                    Err(CordisError::scene(
                        place,
                        format!(
                            "link {li}'s type `{}` has a damping_quadratic: a force transmitter \
                             sends K (L - l0) + Z s only",
                            t.name
                        ),
                    ))
                }
                Some(t) if t.kind == LinkKind::Spring => Ok(()),
                Some(t) => Err(CordisError::scene(
                    place,
                    format!(
                        "link {li} is a `{}`: a force transmitter reads a spring's tension",
                        t.kind
                    ),
                )),
                None => Err(CordisError::scene(
                    place,
                    format!("link {li} does not exist ({} links)", self.links.len()),
                )),
            },
            (false, None) => Ok(()),
        }
    }

    /// A TGR coupling's `controller`: two existing, distinct particles (their worlds are
    /// checked by [`Scene::check_coupling_worlds`]); other couplings have none.
    fn check_controller(&self, at: &str, kind: LinkKind, c: &Coupling) -> Result<()> {
        let Some(dipole) = c.controller else {
            return Ok(());
        };
        let place = format!("{at}.controller");
        if kind != LinkKind::Tgr {
            return Err(CordisError::scene(place, "only tgr couplings have it"));
        }
        for (k, &q) in dipole.iter().enumerate() {
            if q >= self.particles.len() {
                return Err(CordisError::scene(
                    format!("{place}[{k}]"),
                    format!("particle {q} does not exist"),
                ));
            }
        }
        if dipole[0] == dipole[1] {
            return Err(CordisError::scene(
                format!("{place}[1]"),
                format!(
                    "particle {} twice: a controller is a dipole [c, d] whose length anchors \
                     the tendon",
                    dipole[1]
                ),
            ));
        }
        Ok(())
    }

    /// A link's or coupling's particles: as many as the kind joins, existing, distinct.
    fn check_particles(&self, at: &str, kind: LinkKind, particles: &[usize]) -> Result<()> {
        if particles.len() != kind.arity() {
            return Err(CordisError::scene(
                format!("{at}.particles"),
                format!(
                    "`{}` links join {} particle(s), got {}",
                    kind,
                    kind.arity(),
                    particles.len()
                ),
            ));
        }
        for (k, &p) in particles.iter().enumerate() {
            if p >= self.particles.len() {
                return Err(CordisError::scene(
                    format!("{at}.particles[{k}]"),
                    format!("particle {p} does not exist"),
                ));
            }
            if particles[..k].contains(&p) {
                return Err(CordisError::scene(
                    format!("{at}.particles[{k}]"),
                    format!("particle {p} is linked to itself"),
                ));
            }
        }
        Ok(())
    }

    /// Every signal: a unique non-empty name, finite numbers, a positive period, and a rise in
    /// (0, 1) for sawtooths.
    fn validate_signals(&self) -> Result<()> {
        for (k, s) in self.signals.iter().enumerate() {
            let at = format!("signals.{}", s.name);
            if s.name.is_empty() {
                return Err(CordisError::scene(
                    format!("signals[{k}]"),
                    "a signal needs a non-empty name",
                ));
            }
            if self.signals[..k].iter().any(|o| o.name == s.name) {
                return Err(CordisError::scene(at, "the name is used twice"));
            }
            check_value(&format!("{at}.amplitude"), s.amplitude, Sign::Any)?;
            check_value(&format!("{at}.period"), s.period, Sign::Positive)?;
            check_value(&format!("{at}.phase"), s.phase, Sign::Any)?;
            check_value(&format!("{at}.offset"), s.offset, Sign::Any)?;
            if s.shape == Shape::Sawtooth && !(s.rise > 0.0 && s.rise < 1.0) {
                return Err(CordisError::scene(
                    format!("{at}.rise"),
                    format!(
                        "must be in (0, 1) (the fraction of the period spent rising), got {}",
                        s.rise
                    ),
                ));
            }
        }
        Ok(())
    }

    /// The links muscle link `li` observes, in weight order (SPEC §2.4): its own `observes`,
    /// else its type's, else every other muscle link in file order.
    pub fn observed_links(&self, li: usize) -> Vec<usize> {
        let l = &self.links[li];
        let listed = l.observes.as_ref().or(self
            .types
            .get(l.type_index)
            .and_then(|t| t.observes.as_ref()));
        match listed {
            Some(list) => list.clone(),
            None => (0..self.links.len())
                .filter(|&k| k != li && self.is_muscle_link(k))
                .collect(),
        }
    }

    fn is_muscle_link(&self, k: usize) -> bool {
        self.links
            .get(k)
            .and_then(|l| self.types.get(l.type_index))
            .is_some_and(|t| t.kind == LinkKind::Muscle)
    }

    /// A muscle link observes as many links as its type has weights, each an other muscle link.
    fn check_observes(&self, li: usize, at: &str) -> Result<()> {
        let l = &self.links[li];
        let t = &self.types[l.type_index];
        let place = if l.observes.is_some() {
            format!("{at}.observes")
        } else if t.observes.is_some() {
            format!("types.{}.observes", t.name)
        } else {
            at.to_string()
        };
        let seen = self.observed_links(li);
        if seen.len() != t.num_weights() {
            return Err(CordisError::scene(
                place,
                format!(
                    "observes {} muscle link(s) but type `{}` has {} weight(s) per input \
                     (w_len, w_rate)",
                    seen.len(),
                    t.name,
                    t.num_weights()
                ),
            ));
        }
        for (k, &o) in seen.iter().enumerate() {
            if o == li {
                return Err(CordisError::scene(
                    format!("{place}[{k}]"),
                    "a muscle does not observe itself (thesis §5.5)",
                ));
            }
            if !self.is_muscle_link(o) {
                return Err(CordisError::scene(
                    format!("{place}[{k}]"),
                    format!("link {o} is not a muscle link"),
                ));
            }
        }
        Ok(())
    }
}

#[derive(Clone, Copy)]
enum Sign {
    Positive,
    NonNegative,
    UnitInterval,
    Any,
}

fn check_value(place: &str, v: f64, sign: Sign) -> Result<()> {
    let ok = v.is_finite()
        && match sign {
            Sign::Positive => v > 0.0,
            Sign::NonNegative => v >= 0.0,
            Sign::UnitInterval => (-1.0..=1.0).contains(&v),
            Sign::Any => true,
        };
    if ok {
        return Ok(());
    }
    let want = match sign {
        Sign::Positive => "a positive number",
        Sign::NonNegative => "a non-negative number",
        Sign::UnitInterval => "a number in [-1, 1]",
        Sign::Any => "a finite number",
    };
    Err(CordisError::scene(
        place,
        format!("must be {want}, got {v}"),
    ))
}

fn check_param(place: &str, p: &Param, sign: Sign) -> Result<()> {
    match p {
        Param::Known(v) => check_value(place, *v, sign),
        Param::Unknown(b) => {
            check_value(&format!("{place}.min"), b.min, sign)?;
            check_value(&format!("{place}.max"), b.max, sign)?;
            if b.min > b.max {
                return Err(CordisError::scene(
                    place,
                    format!("min {} is above max {}", b.min, b.max),
                ));
            }
            if let Some(init) = b.init {
                if !(init >= b.min && init <= b.max) {
                    return Err(CordisError::scene(
                        format!("{place}.init"),
                        format!("{init} is outside [{}, {}]", b.min, b.max),
                    ));
                }
            }
            Ok(())
        }
    }
}

/// The number of parameters a type of its kind has (its kind's, its optional ones, and for a
/// muscle as many `w_len` as `w_rate` weights).
fn check_param_count(t: &LinkType, at: &str) -> Result<()> {
    let specs = t.kind.param_specs();
    let extra = t.params.len().wrapping_sub(specs.len());
    if t.kind == LinkKind::Muscle && t.params.len() >= specs.len() && extra % 2 != 0 {
        return Err(CordisError::scene(
            format!("{at}.w_rate"),
            format!(
                "w_len has {} weight(s), w_rate {}: they must match",
                extra.div_ceil(2),
                extra / 2
            ),
        ));
    }
    let expected = specs.len() + t.optional.len();
    if t.params.len() != expected && !(t.kind == LinkKind::Muscle && t.params.len() > specs.len()) {
        return Err(CordisError::scene(
            at,
            format!(
                "`{}` types have {} parameters, got {}",
                t.kind,
                expected,
                t.params.len()
            ),
        ));
    }
    Ok(())
}

/// Each of the kind's parameters' sign: a rest cosine in [-1, 1], a range or tendon mass
/// positive, a threshold any, the rest non-negative.
fn check_param_signs(t: &LinkType, at: &str) -> Result<()> {
    for ((name, _), p) in t.kind.param_specs().iter().zip(&t.params) {
        let sign = match *name {
            "rest_cos" => Sign::UnitInterval,
            "range" | "tendon_mass" => Sign::Positive,
            "threshold" => Sign::Any,
            _ => Sign::NonNegative,
        };
        check_param(&format!("{at}.{name}"), p, sign)?;
    }
    Ok(())
}

/// A muscle's neural weights: finite, of either sign (excitation or inhibition).
fn check_neural_weights(t: &LinkType, at: &str) -> Result<()> {
    if t.kind == LinkKind::Muscle {
        let specs = t.kind.param_specs().len();
        for (k, p) in t.params.iter().enumerate().skip(specs) {
            check_param(&format!("{at}.{}", t.param_name(k)), p, Sign::Any)?;
        }
    }
    Ok(())
}

/// Each optional parameter allowed for the kind, given once, of its sign (`max_elongation`
/// positive, a quadratic damping non-negative, a tendon's start any).
fn check_optional_params(t: &LinkType, at: &str) -> Result<()> {
    let specs = t.kind.param_specs();
    for (k, &which) in t.optional.iter().enumerate() {
        let place = format!("{at}.{}", which.name());
        if !which.kinds().contains(&t.kind) {
            let who = match which {
                OptionalParam::MaxElongation => "only springs have it",
                OptionalParam::DampingQuadratic => "only springs and conditional links have it",
                OptionalParam::TendonPosition | OptionalParam::TendonVelocity => {
                    "only TGRs have a tendon"
                }
            };
            return Err(CordisError::scene(place, who));
        }
        if t.optional[..k].contains(&which) {
            return Err(CordisError::scene(place, "given twice"));
        }
        let sign = match which {
            OptionalParam::MaxElongation => Sign::Positive,
            OptionalParam::DampingQuadratic => Sign::NonNegative,
            OptionalParam::TendonPosition | OptionalParam::TendonVelocity => Sign::Any,
        };
        check_param(&place, &t.params[specs.len() + k], sign)?;
    }
    Ok(())
}

/// A plane type's `point` and `normal`: both present, the normal finite and not zero (it is
/// normalised, so a zero vector has no direction); other kinds have no `normal`.
fn check_surface(at: &str, t: &LinkType) -> Result<()> {
    if t.kind != LinkKind::Plane {
        if t.normal.is_some() {
            return Err(CordisError::scene(
                format!("{at}.normal"),
                "only planes have it",
            ));
        }
        return Ok(());
    }
    for (key, v) in [("point", &t.point), ("normal", &t.normal)] {
        if v.is_none() {
            return Err(CordisError::scene(
                at,
                format!("a `plane` type needs `{key}` [x, y, z]"),
            ));
        }
    }
    let normal = t.normal.expect("checked above");
    check_finite3(&format!("{at}.normal"), &normal)?;
    if crate::forces::plane::unit_normal(normal).is_none() {
        return Err(CordisError::scene(
            format!("{at}.normal"),
            format!(
                "must not be the zero vector (it is the plane's outward direction, normalised), \
                 got [{}, {}, {}]",
                normal[0], normal[1], normal[2]
            ),
        ));
    }
    Ok(())
}

fn check_finite3(place: &str, v: &[f64; 3]) -> Result<()> {
    for (k, x) in v.iter().enumerate() {
        if !x.is_finite() {
            return Err(CordisError::scene(
                format!("{place}[{k}]"),
                format!("must be a finite number, got {x}"),
            ));
        }
    }
    Ok(())
}
