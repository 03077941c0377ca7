//! The JSON scene format `cordis-scene/1` (SPEC §5.1), read and written.
//!
//! The reader walks a `serde_json::Value` by hand rather than deriving `Deserialize`, so that
//! every error names its place as a path (`links[12].particles[1]`) and says what was expected.

use std::path::Path;

use serde_json::{Map, Value};

use crate::error::{CordisError, Result};
use crate::signal::{Shape, Signal, DEFAULT_RISE};
use crate::{
    Bounds, Coupling, Link, LinkKind, LinkType, OptionalParam, Param, Particle, Scene, World,
};

pub const FORMAT: &str = "cordis-scene/1";

impl Scene {
    /// Reads and validates a scene from JSON text.
    pub fn from_json_str(text: &str) -> Result<Scene> {
        Self::from_json_text(text, "scene")
    }

    /// Reads and validates a scene file; error places start with the file name.
    pub fn from_json_path(path: impl AsRef<Path>) -> Result<Scene> {
        let path = path.as_ref();
        let bytes = crate::io::read_input(path)?;
        let text = String::from_utf8(bytes).map_err(|e| {
            CordisError::format(
                path.display().to_string(),
                format!(
                    "not UTF-8 text (byte {} is not valid): expected a JSON scene",
                    e.utf8_error().valid_up_to()
                ),
            )
        })?;
        Self::from_json_text(&text, &path.display().to_string())
    }

    fn from_json_text(text: &str, origin: &str) -> Result<Scene> {
        if text.trim().is_empty() {
            return Err(CordisError::format(
                origin,
                "empty file: expected a JSON scene",
            ));
        }
        let value: Value = parse_unique_keys(text).map_err(|e| {
            // The place already says line and column: drop serde_json's own copy of them.
            let full = e.to_string();
            let suffix = format!(" at line {} column {}", e.line(), e.column());
            let what = full.strip_suffix(&suffix).unwrap_or(&full);
            // `1e999` (the nearest a JSON file gets to an infinity) fails here, not in
            // validation: say why.
            let hint = if what.starts_with("number out of range") {
                " (numbers must be finite: |x| < 1.8e308)"
            } else {
                ""
            };
            CordisError::format(
                format!("{origin}:{}:{}", e.line(), e.column()),
                format!("invalid JSON: {what}{hint}"),
            )
        })?;
        Self::from_json_value(&value)
    }

    /// Reads and validates a scene from a parsed JSON value.
    pub fn from_json_value(value: &Value) -> Result<Scene> {
        let scene = read_scene(value)?;
        scene.validate()?;
        Ok(scene)
    }

    /// The scene as JSON; unknown parameters are written back as `{"min", "max"[, "init"]}`.
    pub fn to_json_value(&self) -> Value {
        let mut root = Map::new();
        root.insert("format".into(), FORMAT.into());
        root.insert("dt".into(), self.dt.into());
        if self.gravity != [0.0; 3] {
            root.insert("gravity".into(), vec3(&self.gravity));
        }
        if !self.worlds.is_empty() {
            let mut worlds = Map::new();
            for w in &self.worlds {
                let mut o = Map::new();
                o.insert("dt".into(), w.dt.into());
                worlds.insert(w.name.clone(), Value::Object(o));
            }
            root.insert("worlds".into(), Value::Object(worlds));
        }
        let particles = self.particles.iter().map(particle_json).collect();
        root.insert("particles".into(), Value::Array(particles));
        if !self.signals.is_empty() {
            let signals = self
                .signals
                .iter()
                .map(|sg| (sg.name.clone(), signal_json(sg)))
                .collect();
            root.insert("signals".into(), Value::Object(signals));
        }
        let types = self
            .types
            .iter()
            .map(|t| (t.name.clone(), type_json(t)))
            .collect();
        root.insert("types".into(), Value::Object(types));
        let links = self.links.iter().map(|l| self.link_json(l)).collect();
        root.insert("links".into(), Value::Array(links));
        if !self.couplings.is_empty() {
            let couplings = self
                .couplings
                .iter()
                .map(|c| self.coupling_json(c))
                .collect();
            root.insert("couplings".into(), Value::Array(couplings));
        }
        Value::Object(root)
    }

    /// A link: its type's name, particles, anchor point and observed links when given.
    fn link_json(&self, l: &Link) -> Value {
        let mut o = Map::new();
        o.insert("type".into(), self.types[l.type_index].name.clone().into());
        o.insert("particles".into(), l.particles.clone().into());
        if let Some(point) = &l.point {
            o.insert("point".into(), vec3(point));
        }
        if let Some(obs) = &l.observes {
            o.insert("observes".into(), obs.clone().into());
        }
        Value::Object(o)
    }

    /// A coupling: its type's name, particles, source link and controller when given.
    fn coupling_json(&self, c: &Coupling) -> Value {
        let mut o = Map::new();
        o.insert("type".into(), self.types[c.type_index].name.clone().into());
        o.insert("particles".into(), c.particles.clone().into());
        if let Some(src) = c.source {
            o.insert("source".into(), src.into());
        }
        if let Some(ctrl) = c.controller {
            o.insert("controller".into(), ctrl.to_vec().into());
        }
        Value::Object(o)
    }

    /// Pretty-printed JSON text of [`Scene::to_json_value`].
    pub fn to_json_string(&self) -> String {
        let mut s = serde_json::to_string_pretty(&self.to_json_value())
            .expect("a JSON value always serialises");
        s.push('\n');
        s
    }
}

/// Parses JSON text as [`serde_json::from_str`] does, but refuses an object that repeats a key
/// (serde_json keeps the last one silently: `"stiffness": 1, "stiffness": 100` read as 100).
/// The error names the key; serde_json adds its line and column.
fn parse_unique_keys(text: &str) -> serde_json::Result<Value> {
    use serde::de::DeserializeSeed;
    let mut de = serde_json::Deserializer::from_str(text);
    let value = UniqueKeys.deserialize(&mut de)?;
    de.end()?;
    Ok(value)
}

/// A [`Value`] read with every object's keys distinct (see [`parse_unique_keys`]).
struct UniqueKeys;

impl<'de> serde::de::DeserializeSeed<'de> for UniqueKeys {
    type Value = Value;
    fn deserialize<D: serde::Deserializer<'de>>(
        self,
        d: D,
    ) -> std::result::Result<Value, D::Error> {
        d.deserialize_any(self)
    }
}

impl<'de> serde::de::Visitor<'de> for UniqueKeys {
    type Value = Value;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("a JSON value")
    }
    fn visit_bool<E>(self, v: bool) -> std::result::Result<Value, E> {
        Ok(Value::Bool(v))
    }
    fn visit_i64<E>(self, v: i64) -> std::result::Result<Value, E> {
        Ok(Value::from(v))
    }
    fn visit_u64<E>(self, v: u64) -> std::result::Result<Value, E> {
        Ok(Value::from(v))
    }
    fn visit_f64<E>(self, v: f64) -> std::result::Result<Value, E> {
        Ok(serde_json::Number::from_f64(v).map_or(Value::Null, Value::Number))
    }
    fn visit_str<E>(self, v: &str) -> std::result::Result<Value, E> {
        Ok(Value::String(v.to_owned()))
    }
    fn visit_string<E>(self, v: String) -> std::result::Result<Value, E> {
        Ok(Value::String(v))
    }
    fn visit_unit<E>(self) -> std::result::Result<Value, E> {
        Ok(Value::Null)
    }
    fn visit_seq<A: serde::de::SeqAccess<'de>>(
        self,
        mut seq: A,
    ) -> std::result::Result<Value, A::Error> {
        let mut out = Vec::new();
        while let Some(v) = seq.next_element_seed(UniqueKeys)? {
            out.push(v);
        }
        Ok(Value::Array(out))
    }
    fn visit_map<A: serde::de::MapAccess<'de>>(
        self,
        mut map: A,
    ) -> std::result::Result<Value, A::Error> {
        let mut out = Map::new();
        while let Some(key) = map.next_key::<String>()? {
            if out.contains_key(&key) {
                return Err(serde::de::Error::custom(format!(
                    "duplicate key `{}` (a key appears once per object)",
                    crate::error::printable(&key)
                )));
            }
            let v = map.next_value_seed(UniqueKeys)?;
            out.insert(key, v);
        }
        Ok(Value::Object(out))
    }
}

fn vec3(v: &[f64; 3]) -> Value {
    Value::Array(v.iter().map(|&x| x.into()).collect())
}

fn param_json(p: &Param) -> Value {
    match p {
        Param::Known(v) => (*v).into(),
        Param::Unknown(b) => {
            let mut o = Map::new();
            o.insert("min".into(), b.min.into());
            o.insert("max".into(), b.max.into());
            if let Some(init) = b.init {
                o.insert("init".into(), init.into());
            }
            Value::Object(o)
        }
    }
}

/// A particle: mass, position, and what differs from the defaults (velocity, fixed, group,
/// world).
fn particle_json(p: &Particle) -> Value {
    let mut o = Map::new();
    o.insert("mass".into(), param_json(&p.mass));
    o.insert("pos".into(), vec3(&p.pos));
    if p.vel != [0.0; 3] {
        o.insert("vel".into(), vec3(&p.vel));
    }
    if p.fixed {
        o.insert("fixed".into(), true.into());
    }
    if let Some(g) = &p.group {
        o.insert("group".into(), g.clone().into());
    }
    if let Some(w) = &p.world {
        o.insert("world".into(), w.clone().into());
    }
    Value::Object(o)
}

/// A signal: shape, amplitude, period, and the phase, rise and offset where they matter.
fn signal_json(sg: &Signal) -> Value {
    let mut o = Map::new();
    o.insert("shape".into(), sg.shape.name().into());
    o.insert("amplitude".into(), sg.amplitude.into());
    o.insert("period".into(), sg.period.into());
    if sg.phase != 0.0 {
        o.insert("phase".into(), sg.phase.into());
    }
    if sg.shape == Shape::Sawtooth {
        o.insert("rise".into(), sg.rise.into());
    }
    if sg.offset != 0.0 {
        o.insert("offset".into(), sg.offset.into());
    }
    Value::Object(o)
}

/// A link type: its kind, its kind's parameters and its optional ones by name, and the keys
/// its kind has (point, normal, groups, a muscle's weights, observed links, signal).
fn type_json(t: &LinkType) -> Value {
    let mut o = Map::new();
    o.insert("kind".into(), t.kind.name().into());
    for ((name, _), p) in t.kind.param_specs().iter().zip(&t.params) {
        o.insert((*name).into(), param_json(p));
    }
    for (k, which) in t.optional.iter().enumerate() {
        let p = &t.params[t.kind.param_specs().len() + k];
        o.insert(which.name().into(), param_json(p));
    }
    if let Some(point) = &t.point {
        o.insert("point".into(), vec3(point));
    }
    if let Some(normal) = &t.normal {
        o.insert("normal".into(), vec3(normal));
    }
    if !t.groups.is_empty() {
        o.insert("groups".into(), t.groups.clone().into());
    }
    if t.kind == LinkKind::Muscle {
        let ws = |w: &[Param]| Value::Array(w.iter().map(param_json).collect());
        o.insert("w_len".into(), ws(t.w_len()));
        o.insert("w_rate".into(), ws(t.w_rate()));
    }
    if let Some(obs) = &t.observes {
        o.insert("observes".into(), obs.clone().into());
    }
    if let Some(sg) = &t.signal {
        o.insert("signal".into(), sg.clone().into());
    }
    Value::Object(o)
}

fn err(place: &str, message: impl Into<String>) -> CordisError {
    CordisError::scene(place, message)
}

fn kind_of(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "a boolean",
        Value::Number(_) => "a number",
        Value::String(_) => "a string",
        Value::Array(_) => "an array",
        Value::Object(_) => "an object",
    }
}

fn as_object<'a>(v: &'a Value, place: &str, allowed: &[&str]) -> Result<&'a Map<String, Value>> {
    let Value::Object(o) = v else {
        return Err(err(
            place,
            format!("expected an object, got {}", kind_of(v)),
        ));
    };
    if let Some(k) = o.keys().find(|k| !allowed.contains(&k.as_str())) {
        return Err(err(
            &join(place, k),
            format!(
                "unknown key `{k}` (expected one of: {})",
                allowed.join(", ")
            ),
        ));
    }
    Ok(o)
}

fn join(place: &str, key: &str) -> String {
    if place.is_empty() {
        key.to_string()
    } else {
        format!("{place}.{key}")
    }
}

fn number(v: &Value, place: &str) -> Result<f64> {
    v.as_f64()
        .ok_or_else(|| err(place, format!("expected a number, got {}", kind_of(v))))
}

fn index(v: &Value, place: &str) -> Result<usize> {
    match v.as_u64() {
        Some(i) => usize::try_from(i).map_err(|_| err(place, "index too large")),
        None => Err(err(
            place,
            format!("expected a particle index (a non-negative integer), got {v}"),
        )),
    }
}

fn vector3(v: &Value, place: &str) -> Result<[f64; 3]> {
    let Value::Array(a) = v else {
        return Err(err(
            place,
            format!("expected [x, y, z], got {}", kind_of(v)),
        ));
    };
    if a.len() != 3 {
        return Err(err(
            place,
            format!("expected 3 numbers [x, y, z], got {}", a.len()),
        ));
    }
    let mut out = [0.0; 3];
    for (k, x) in a.iter().enumerate() {
        out[k] = number(x, &format!("{place}[{k}]"))?;
    }
    Ok(out)
}

fn param(v: &Value, place: &str) -> Result<Param> {
    if let Value::Object(_) = v {
        let o = as_object(v, place, &["min", "max", "init"])?;
        let get = |k: &str| -> Result<Option<f64>> {
            o.get(k).map(|x| number(x, &join(place, k))).transpose()
        };
        let min = get("min")?.ok_or_else(|| err(place, "an unknown parameter needs `min`"))?;
        let max = get("max")?.ok_or_else(|| err(place, "an unknown parameter needs `max`"))?;
        Ok(Param::Unknown(Bounds {
            min,
            max,
            init: get("init")?,
        }))
    } else {
        Ok(Param::Known(number(v, place)?))
    }
}

fn string(v: &Value, place: &str) -> Result<String> {
    v.as_str()
        .map(str::to_string)
        .ok_or_else(|| err(place, format!("expected a string, got {}", kind_of(v))))
}

fn read_scene(v: &Value) -> Result<Scene> {
    let root = scene_root(v)?;
    let dt = number(
        root.get("dt")
            .ok_or_else(|| err("dt", "missing: the time step in s is required"))?,
        "dt",
    )?;
    let mut scene = Scene::new(dt);
    if let Some(g) = root.get("gravity") {
        scene.gravity = vector3(g, "gravity")?;
    }
    if let Some(worlds) = root.get("worlds") {
        for (name, wv) in named(worlds, "worlds")? {
            scene.worlds.push(read_world(name, wv)?);
        }
    }
    let particles = match root.get("particles") {
        Some(a) => array(a, "particles")?,
        None => return Err(err("particles", "missing: a scene needs particles")),
    };
    for (i, pv) in particles.iter().enumerate() {
        scene.particles.push(read_particle(i, pv)?);
    }
    if let Some(signals) = root.get("signals") {
        for (name, sv) in named(signals, "signals")? {
            scene.signals.push(read_signal(name, sv)?);
        }
    }
    let mut weights_given = Vec::new();
    if let Some(types) = root.get("types") {
        for (name, tv) in named(types, "types")? {
            let (t, has_weights) = read_type(name, tv)?;
            scene.types.push(t);
            weights_given.push(has_weights);
        }
    }
    if let Some(links) = root.get("links") {
        for (i, lv) in array(links, "links")?.iter().enumerate() {
            let link = read_link(&scene, i, lv)?;
            scene.links.push(link);
        }
    }
    if let Some(couplings) = root.get("couplings") {
        for (i, cv) in array(couplings, "couplings")?.iter().enumerate() {
            let coupling = read_coupling(&scene, i, cv)?;
            scene.couplings.push(coupling);
        }
    }
    zero_unweighted_muscles(&mut scene, weights_given);
    Ok(scene)
}

/// The scene's top-level object (only its known keys), with `format`, when given, this
/// reader's.
fn scene_root(v: &Value) -> Result<&Map<String, Value>> {
    let root = as_object(
        v,
        "",
        &[
            "format",
            "dt",
            "gravity",
            "worlds",
            "particles",
            "signals",
            "types",
            "links",
            "couplings",
        ],
    )
    .map_err(|e| match e {
        CordisError::Scene { place, message } if place.is_empty() => {
            err("scene", format!("{message}: a scene is a JSON object"))
        }
        e => e,
    })?;
    if let Some(f) = root.get("format") {
        let f = string(f, "format")?;
        if f != FORMAT {
            return Err(err("format", format!("expected \"{FORMAT}\", got \"{f}\"")));
        }
    }
    Ok(root)
}

/// A top-level object of named entries (`worlds`, `signals`, `types`).
fn named<'a>(v: &'a Value, key: &str) -> Result<&'a Map<String, Value>> {
    match v {
        Value::Object(o) => Ok(o),
        other => Err(err(
            key,
            format!("expected an object of named {key}, got {}", kind_of(other)),
        )),
    }
}

/// A top-level array (`particles`, `links`, `couplings`).
fn array<'a>(v: &'a Value, key: &str) -> Result<&'a Vec<Value>> {
    match v {
        Value::Array(a) => Ok(a),
        other => Err(err(
            key,
            format!("expected an array, got {}", kind_of(other)),
        )),
    }
}

/// `worlds.<name>`: a world's time step (s).
fn read_world(name: &str, wv: &Value) -> Result<World> {
    let at = format!("worlds.{name}");
    let o = as_object(wv, &at, &["dt"])?;
    let dt = number(
        o.get("dt")
            .ok_or_else(|| err(&at, "missing `dt`: the world's time step in s"))?,
        &join(&at, "dt"),
    )?;
    Ok(World {
        name: name.to_string(),
        dt,
    })
}

/// `particles[i]`: mass (kg, a parameter), position and velocity (m, m/s), and whether it is
/// fixed, its group and its world.
fn read_particle(i: usize, pv: &Value) -> Result<Particle> {
    let at = format!("particles[{i}]");
    let o = as_object(pv, &at, &["mass", "pos", "vel", "fixed", "group", "world"])?;
    let mass = param(
        o.get("mass").ok_or_else(|| err(&at, "missing `mass`"))?,
        &join(&at, "mass"),
    )?;
    let pos = vector3(
        o.get("pos").ok_or_else(|| err(&at, "missing `pos`"))?,
        &join(&at, "pos"),
    )?;
    let mut p = Particle::new(1.0, pos);
    p.mass = mass;
    if let Some(vel) = o.get("vel") {
        p.vel = vector3(vel, &join(&at, "vel"))?;
    }
    if let Some(f) = o.get("fixed") {
        p.fixed = f.as_bool().ok_or_else(|| {
            err(
                &join(&at, "fixed"),
                format!("expected true or false, got {f}"),
            )
        })?;
    }
    if let Some(g) = o.get("group") {
        p.group = Some(string(g, &join(&at, "group"))?);
    }
    if let Some(w) = o.get("world") {
        // `"main"` is the default: store it as `None` so a scene round-trips.
        p = p.in_world(string(w, &join(&at, "world"))?);
    }
    Ok(p)
}

/// `links[i]`: its type (among `scene`'s), particles, anchor point and observed links.
fn read_link(scene: &Scene, i: usize, lv: &Value) -> Result<Link> {
    let at = format!("links[{i}]");
    let o = as_object(lv, &at, &["type", "particles", "point", "observes"])?;
    let type_index = type_ref(scene, o, &at)?;
    let particles = particle_list(o, &at)?;
    let point = o
        .get("point")
        .map(|p| vector3(p, &join(&at, "point")))
        .transpose()?;
    let observes = o
        .get("observes")
        .map(|v| indices(v, &join(&at, "observes")))
        .transpose()?;
    Ok(Link {
        type_index,
        particles,
        point,
        observes,
    })
}

/// `couplings[i]`: its type (among `scene`'s), particles, source link and controller.
fn read_coupling(scene: &Scene, i: usize, cv: &Value) -> Result<Coupling> {
    let at = format!("couplings[{i}]");
    let o = as_object(cv, &at, &["type", "particles", "source", "controller"])?;
    let type_index = type_ref(scene, o, &at)?;
    let particles = particle_list(o, &at)?;
    let source = o
        .get("source")
        .map(|v| link_index(v, &join(&at, "source")))
        .transpose()?;
    let controller = o
        .get("controller")
        .map(|v| dipole(v, &join(&at, "controller")))
        .transpose()?;
    Ok(Coupling {
        type_index,
        particles,
        source,
        controller,
    })
}

/// A muscle type without weights (`weights_given[t]` false) gets zero weights, as many as its
/// first instance observes (a plain spring until identification gives them values).
fn zero_unweighted_muscles(scene: &mut Scene, weights_given: Vec<bool>) {
    for (t, given) in weights_given.into_iter().enumerate() {
        if given || scene.types[t].kind != LinkKind::Muscle {
            continue;
        }
        let m = (0..scene.links.len())
            .find(|&li| scene.links[li].type_index == t)
            .map_or(0, |li| scene.observed_links(li).len());
        let zeros = vec![Param::Known(0.0); m];
        scene.types[t] = scene.types[t].clone().with_weights(&zeros, &zeros);
    }
}

/// A link index (a non-negative integer).
fn link_index(v: &Value, place: &str) -> Result<usize> {
    match v.as_u64().and_then(|i| usize::try_from(i).ok()) {
        Some(i) => Ok(i),
        None => Err(err(
            place,
            format!("expected a link index (a non-negative integer), got {v}"),
        )),
    }
}

/// Two particle indices `[c, d]` (a TGR's controller dipole).
fn dipole(v: &Value, place: &str) -> Result<[usize; 2]> {
    match v {
        Value::Array(a) if a.len() == 2 => Ok([
            index(&a[0], &format!("{place}[0]"))?,
            index(&a[1], &format!("{place}[1]"))?,
        ]),
        Value::Array(a) => Err(err(
            place,
            format!("expected two particle indices [c, d], got {}", a.len()),
        )),
        other => Err(err(
            place,
            format!(
                "expected two particle indices [c, d], got {}",
                kind_of(other)
            ),
        )),
    }
}

/// The catalogue index of the `type` a link or coupling names.
fn type_ref(scene: &Scene, o: &Map<String, Value>, at: &str) -> Result<usize> {
    let tname = string(
        o.get("type").ok_or_else(|| err(at, "missing `type`"))?,
        &join(at, "type"),
    )?;
    scene.type_index(&tname).ok_or_else(|| {
        err(
            &join(at, "type"),
            format!("no type named `{tname}` in `types`"),
        )
    })
}

/// The `particles` array of a link or coupling.
fn particle_list(o: &Map<String, Value>, at: &str) -> Result<Vec<usize>> {
    let pl = join(at, "particles");
    match o.get("particles") {
        Some(Value::Array(a)) => a
            .iter()
            .enumerate()
            .map(|(k, x)| index(x, &format!("{pl}[{k}]")))
            .collect(),
        Some(other) => Err(err(
            &pl,
            format!(
                "expected an array of particle indices, got {}",
                kind_of(other)
            ),
        )),
        None => Err(err(at, "missing `particles`")),
    }
}

/// A named signal: `{"shape", "amplitude", "period"[, "phase", "rise", "offset"]}`.
fn read_signal(name: &str, v: &Value) -> Result<Signal> {
    let at = format!("signals.{name}");
    let Value::Object(o) = v else {
        return Err(err(&at, format!("expected an object, got {}", kind_of(v))));
    };
    let sname = string(
        o.get("shape").ok_or_else(|| err(&at, "missing `shape`"))?,
        &join(&at, "shape"),
    )?;
    let shape = Shape::from_name(&sname).ok_or_else(|| {
        let all: Vec<_> = Shape::ALL.iter().map(|s| s.name()).collect();
        err(
            &join(&at, "shape"),
            format!(
                "unknown shape `{sname}` (expected one of: {})",
                all.join(", ")
            ),
        )
    })?;
    let mut allowed = vec!["shape", "amplitude", "period", "phase", "offset"];
    if shape == Shape::Sawtooth {
        // Only the sawtooth has a free rise fraction (the triangle's is ½).
        allowed.push("rise");
    }
    as_object(v, &at, &allowed)?;
    let get = |k: &str| o.get(k).map(|x| number(x, &join(&at, k))).transpose();
    let need = |k: &str| get(k)?.ok_or_else(|| err(&at, format!("a signal needs `{k}`")));
    let mut s = Signal::new(name, shape, need("amplitude")?, need("period")?);
    s.phase = get("phase")?.unwrap_or(0.0);
    s.offset = get("offset")?.unwrap_or(0.0);
    if shape == Shape::Sawtooth {
        s.rise = get("rise")?.unwrap_or(DEFAULT_RISE);
    }
    Ok(s)
}

/// An array of link indices.
fn indices(v: &Value, place: &str) -> Result<Vec<usize>> {
    match v {
        Value::Array(a) => a
            .iter()
            .enumerate()
            .map(|(k, x)| index(x, &format!("{place}[{k}]")))
            .collect(),
        other => Err(err(
            place,
            format!("expected an array of link indices, got {}", kind_of(other)),
        )),
    }
}

/// An array of parameters (numbers or `{"min", "max"[, "init"]}` unknowns).
fn params(v: &Value, place: &str) -> Result<Vec<Param>> {
    match v {
        Value::Array(a) => a
            .iter()
            .enumerate()
            .map(|(k, x)| param(x, &format!("{place}[{k}]")))
            .collect(),
        other => Err(err(
            place,
            format!("expected an array of weights, got {}", kind_of(other)),
        )),
    }
}

/// A type, and whether it listed muscle weights.
fn read_type(name: &str, v: &Value) -> Result<(LinkType, bool)> {
    let at = format!("types.{name}");
    let Value::Object(o) = v else {
        return Err(err(&at, format!("expected an object, got {}", kind_of(v))));
    };
    let kname = string(
        o.get("kind").ok_or_else(|| err(&at, "missing `kind`"))?,
        &join(&at, "kind"),
    )?;
    let kind = LinkKind::from_name(&kname).ok_or_else(|| {
        let all: Vec<_> = LinkKind::ALL.iter().map(|k| k.name()).collect();
        err(
            &join(&at, "kind"),
            format!(
                "unknown kind `{kname}` (expected one of: {})",
                all.join(", ")
            ),
        )
    })?;
    let mut allowed: Vec<&str> = vec!["kind"];
    allowed.extend(kind.param_names());
    allowed.extend(kind.extra_keys());
    as_object(v, &at, &allowed)?;
    let mut t = LinkType::new(name, kind);
    for (k, (pname, default)) in kind.param_specs().iter().enumerate() {
        t.params[k] = match (o.get(*pname), default) {
            (Some(pv), _) => param(pv, &join(&at, pname))?,
            (None, Some(d)) => Param::Known(*d),
            (None, None) => {
                return Err(err(&at, format!("`{kind}` types need `{pname}`")));
            }
        };
    }
    for which in OptionalParam::ALL {
        if let Some(pv) = o.get(which.name()) {
            let value = param(pv, &join(&at, which.name()))?;
            t.set_optional(which, Some(value));
        }
    }
    if let Some(p) = o.get("point") {
        t.point = Some(vector3(p, &join(&at, "point"))?);
    }
    if let Some(n) = o.get("normal") {
        t.normal = Some(vector3(n, &join(&at, "normal"))?);
    }
    if kind == LinkKind::Conditional {
        let gp = join(&at, "groups");
        t.groups = match o.get("groups") {
            Some(Value::Array(a)) => a
                .iter()
                .enumerate()
                .map(|(k, g)| string(g, &format!("{gp}[{k}]")))
                .collect::<Result<Vec<_>>>()?,
            Some(other) => {
                return Err(err(
                    &gp,
                    format!("expected an array of group names, got {}", kind_of(other)),
                ))
            }
            None => return Err(err(&at, "a conditional needs `groups`")),
        };
    }
    if let Some(sg) = o.get("signal") {
        t.signal = Some(string(sg, &join(&at, "signal"))?);
    }
    let mut has_weights = false;
    if kind == LinkKind::Muscle {
        let (wl, wr) = (o.get("w_len"), o.get("w_rate"));
        if let (Some(wl), Some(wr)) = (wl, wr) {
            let wl = params(wl, &join(&at, "w_len"))?;
            let wr = params(wr, &join(&at, "w_rate"))?;
            if wl.len() != wr.len() {
                return Err(err(
                    &join(&at, "w_rate"),
                    format!(
                        "has {} weight(s) but w_len has {}: one of each per observed link",
                        wr.len(),
                        wl.len()
                    ),
                ));
            }
            t = t.with_weights(&wl, &wr);
            has_weights = true;
        } else if wl.is_some() || wr.is_some() {
            return Err(err(
                &at,
                "a muscle lists both `w_len` and `w_rate`, or neither",
            ));
        }
        if let Some(obs) = o.get("observes") {
            t.observes = Some(indices(obs, &join(&at, "observes"))?);
        }
    }
    Ok((t, has_weights))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Provot's τc as an unknown box and a quadratic viscosity (known on one type, a box on
    /// another) read, write and read back to the same scene, in the parameter vector after
    /// the kind's own parameters.
    #[test]
    fn optional_parameters_round_trip_as_numbers_and_boxes() {
        let text = r#"{"dt": 0.01,
          "particles": [{"mass": 1.0, "pos": [0, 0, 0], "fixed": true, "group": "g"},
                        {"mass": 1.0, "pos": [1.1, 0, 0], "group": "g"}],
          "types": {"rib": {"kind": "spring", "stiffness": 10, "rest_length": 1.0,
                            "max_elongation": {"min": 0.05, "max": 0.5, "init": 0.2},
                            "damping_quadratic": 0.3},
                    "mist": {"kind": "conditional", "stiffness": 0, "rest_length": 0,
                             "damping": 0.1, "range": 2, "groups": ["g"],
                             "damping_quadratic": {"min": 0, "max": 4}}},
          "links": [{"type": "rib", "particles": [0, 1]}]}"#;
        let scene = Scene::from_json_str(text).unwrap();
        let rib = &scene.types[0];
        assert_eq!(
            rib.optional,
            [
                OptionalParam::MaxElongation,
                OptionalParam::DampingQuadratic
            ]
        );
        assert_eq!(rib.param_name(3), "max_elongation");
        assert_eq!(rib.param_name(4), "damping_quadratic");
        assert!(rib.max_elongation().unwrap().is_unknown());
        assert_eq!(rib.max_elongation().unwrap().value(), 0.2);
        assert_eq!(scene.param_layout().type_offsets, [0, 5]);
        let again = Scene::from_json_str(&scene.to_json_string()).unwrap();
        assert_eq!(again, scene);
        let written = scene.to_json_value();
        assert_eq!(
            written["types"]["mist"]["damping_quadratic"],
            serde_json::json!({"min": 0.0, "max": 4.0})
        );
    }
}
