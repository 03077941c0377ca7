//! The thesis' model files (Annexe 1; SPEC §5.3), read and written.
//!
//! A model `NAME` is `NAME.mas` (masses and link instances), `NAME.cat` (the catalogue of link
//! types; `NAME.sav` is an identified catalogue in the same layout), `NAME.ini` (initial
//! positions and velocities), optionally `NAME.tra` (a trajectory, see [`crate::io::tra`]),
//! `NAME.lock` (which catalogue parameters are known) and `Param.gene` (settings of the
//! thesis' evolution strategy). The layout and every choice made where the thesis is loose
//! are in `docs/file-formats.md`.
//!
//! Links come in five *families*, always in this order: unary position (`anchor`), unary
//! velocity (`drag`), binary position (`spring`), binary velocity (`damper`) and ternary
//! position (`angle`). Catalogue types are named after their family and 0-based index:
//! `up0…`, `uv0…`, `bp0…`, `bv0…`, `tp0…`.

use std::fmt::Write;
use std::path::{Path, PathBuf};

use crate::error::{CordisError, Result};
use crate::io::tokens::{normalize, Cursor, Kind};
use crate::io::{read_text, tra, write_atomic};
use crate::{LinkKind, LinkType, Param, Particle, Scene, Trajectory};

/// A link family of the thesis' files.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Family {
    UnaryPosition,
    UnaryVelocity,
    BinaryPosition,
    BinaryVelocity,
    TernaryPosition,
}

impl Family {
    /// File order.
    pub const ALL: [Family; 5] = [
        Family::UnaryPosition,
        Family::UnaryVelocity,
        Family::BinaryPosition,
        Family::BinaryVelocity,
        Family::TernaryPosition,
    ];

    /// The link kind a type of this family becomes.
    pub fn kind(self) -> LinkKind {
        match self {
            Family::UnaryPosition => LinkKind::Anchor,
            Family::UnaryVelocity => LinkKind::Drag,
            Family::BinaryPosition => LinkKind::Spring,
            Family::BinaryVelocity => LinkKind::Damper,
            Family::TernaryPosition => LinkKind::Angle,
        }
    }

    pub fn of_kind(kind: LinkKind) -> Option<Family> {
        Family::ALL.into_iter().find(|f| f.kind() == kind)
    }

    /// Prefix of the type names: `up`, `uv`, `bp`, `bv`, `tp`.
    pub fn prefix(self) -> &'static str {
        ["up", "uv", "bp", "bv", "tp"][self as usize]
    }

    /// The family's name in the files, e.g. `binaires-position`.
    pub fn french(self) -> &'static str {
        [
            "unaires-position",
            "unaires-vitesse",
            "binaires-position",
            "binaires-vitesse",
            "ternaires-position",
        ][self as usize]
    }

    /// Particles per link.
    pub fn arity(self) -> usize {
        self.kind().arity()
    }

    /// The family a header names (`Nombre de liaisons binaires-position installees`,
    /// `liaisons binaires position`…): by its words, whatever joins them.
    pub fn from_label(label: &str) -> Option<Family> {
        let l = label.to_lowercase();
        let words: Vec<&str> = l
            .split(|c: char| !c.is_alphabetic())
            .map(|w| w.strip_suffix('s').unwrap_or(w))
            .collect();
        let has = |w: &str| words.contains(&w);
        let arity = match (has("unaire"), has("binaire"), has("ternaire")) {
            (true, false, false) => 0,
            (false, true, false) => 1,
            (false, false, true) => 2,
            _ => return None,
        };
        let velocity = match (has("position"), has("vitesse")) {
            (true, false) => false,
            (false, true) => true,
            _ => return None,
        };
        match (arity, velocity) {
            (0, false) => Some(Family::UnaryPosition),
            (0, true) => Some(Family::UnaryVelocity),
            (1, false) => Some(Family::BinaryPosition),
            (1, true) => Some(Family::BinaryVelocity),
            (2, false) => Some(Family::TernaryPosition),
            _ => None,
        }
    }

    fn type_name(self, index: usize) -> String {
        format!("{}{index}", self.prefix())
    }
}

/// One line of `NAME.lock`: which of a catalogue type's parameters are known.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct LockedType {
    pub family: Family,
    /// Index of the type in its family (so the type is `{prefix}{index}`).
    pub index: usize,
    /// `[l0, K, Z]` (rest length or rest cosine, stiffness, damping): true = known, kept.
    pub locked: [bool; 3],
    /// The optional fourth flag, kept as written (its meaning is not documented).
    pub extra: Option<String>,
}

impl LockedType {
    pub fn type_name(&self) -> String {
        self.family.type_name(self.index)
    }
}

/// `Param.gene`: settings of the thesis' evolution strategy; absent keys are `None`.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct GeneParams {
    pub generation: Option<u64>,
    pub population: Option<u64>,
    pub pcross: Option<f64>,
    pub pmut: Option<f64>,
    pub reducer: Option<f64>,
    pub noise: Option<f64>,
    pub damping: Option<f64>,
}

/// A model read from the thesis' files.
#[derive(Clone, Debug, PartialEq)]
pub struct ThesisModel {
    pub scene: Scene,
    /// `NAME.tra` when present, with the `dt` given to [`import`].
    pub trajectory: Option<Trajectory>,
    /// `NAME.lock` (empty when absent).
    pub lock: Vec<LockedType>,
    /// `Param.gene` beside the files, when present.
    pub gene: Option<GeneParams>,
}

/// The content of `NAME.mas`.
#[derive(Clone, Debug, PartialEq)]
pub struct MasFile {
    /// kg, one per particle.
    pub masses: Vec<f64>,
    pub links: Vec<MasLink>,
}

/// One link record of `NAME.mas`.
#[derive(Clone, Debug, PartialEq)]
pub struct MasLink {
    pub family: Family,
    /// Index of the type within the family's section of the catalogue.
    pub type_index: usize,
    pub particles: Vec<usize>,
    /// Line of the record, for errors found later (a type missing from the catalogue).
    pub line: usize,
}

fn mk(place: String, message: String) -> CordisError {
    CordisError::format(place, message)
}

/// The files [`import`] reads for model `base`: `NAME.mas`, `.cat`, `.ini`, `.tra`, `.lock`
/// and the `Param.gene` beside them (the last four when they exist), so that a caller can keep
/// its outputs off them.
pub fn model_files(base: &Path) -> [PathBuf; 6] {
    let [mas, cat, ini, tra, lock] =
        ["mas", "cat", "ini", "tra", "lock"].map(|ext| model_file(base, ext));
    [mas, cat, ini, tra, lock, gene_file(base)]
}

/// The `Param.gene` beside model `base`.
fn gene_file(base: &Path) -> PathBuf {
    base.parent()
        .map_or_else(|| PathBuf::from("Param.gene"), |d| d.join("Param.gene"))
}

/// `base` (without extension, or ending in `.mas`) with extension `ext`.
fn model_file(base: &Path, ext: &str) -> PathBuf {
    let base = match base.extension() {
        Some(e) if e.eq_ignore_ascii_case("mas") => base.with_extension(""),
        _ => base.to_path_buf(),
    };
    let mut s = base.into_os_string();
    s.push(".");
    s.push(ext);
    PathBuf::from(s)
}

/// Reads model `base` (a path without extension, or ending in `.mas`). `dt` (s) is not in the
/// thesis' files. Initial positions and velocities come from `NAME.ini`, or else from the first
/// two frames of `NAME.tra` (`v = (x1 - x0) / dt`). Anchors hold their particle's initial
/// position.
pub fn import(base: &Path, dt: f64) -> Result<ThesisModel> {
    if !(dt.is_finite() && dt > 0.0) {
        return Err(CordisError::scene(
            "dt",
            format!("must be a positive number, got {dt}"),
        ));
    }
    let file = |ext: &str| model_file(base, ext);
    let shown = |p: &Path| p.display().to_string();
    let (mas_path, cat_path) = (file("mas"), file("cat"));
    let mas = parse_mas(&shown(&mas_path), &read_text(&mas_path)?)?;
    let n = mas.masses.len();
    let types = parse_cat(&shown(&cat_path), &read_text(&cat_path)?)?;

    let tra_path = file("tra");
    let trajectory = if tra_path.exists() {
        let t = tra::parse_tra(&shown(&tra_path), &read_text(&tra_path)?)?;
        if t.particles() != n {
            return Err(CordisError::trajectory(
                shown(&tra_path),
                format!(
                    "has {} particles, {} has {n}",
                    t.particles(),
                    shown(&mas_path)
                ),
            ));
        }
        Some(t.with_dt(dt))
    } else {
        None
    };

    let ini_path = file("ini");
    let init = if ini_path.exists() {
        parse_ini(&shown(&ini_path), &read_text(&ini_path)?, n)?
    } else if let Some(t) = &trajectory {
        if t.frames() < 2 {
            return Err(CordisError::trajectory(
                shown(&tra_path),
                format!(
                    "has one frame: initial velocities need two (or give {})",
                    shown(&ini_path)
                ),
            ));
        }
        (0..n)
            .map(|i| {
                let (x0, x1) = (t.pos(0, i), t.pos(1, i));
                let v = (x1 - x0) / dt;
                ([x0.x, x0.y, x0.z], [v.x, v.y, v.z])
            })
            .collect()
    } else {
        return Err(CordisError::format(
            shown(&ini_path),
            format!(
                "no initial state: neither this file nor {} exists",
                shown(&tra_path)
            ),
        ));
    };

    let scene = build_scene(&shown(&mas_path), &mas, types, &init, dt)?;

    let lock_path = file("lock");
    let lock = if lock_path.exists() {
        let name = shown(&lock_path);
        let lines = parse_lock_lines(&name, &read_text(&lock_path)?)?;
        for (l, line) in &lines {
            if scene.type_index(&l.type_name()).is_none() {
                return Err(mk(
                    format!("{name}:{line}"),
                    format!(
                        "type {} of liaisons {} is not in {}",
                        l.index,
                        l.family.french(),
                        shown(&cat_path)
                    ),
                ));
            }
        }
        lines.into_iter().map(|(l, _)| l).collect()
    } else {
        Vec::new()
    };

    let gene_path = gene_file(base);
    let gene = if gene_path.exists() {
        Some(parse_gene(&shown(&gene_path), &read_text(&gene_path)?)?)
    } else {
        None
    };

    Ok(ThesisModel {
        scene,
        trajectory,
        lock,
        gene,
    })
}

/// Assembles a scene; `mas_name` places errors of link records.
fn build_scene(
    mas_name: &str,
    mas: &MasFile,
    types: Vec<LinkType>,
    init: &[([f64; 3], [f64; 3])],
    dt: f64,
) -> Result<Scene> {
    let mut scene = Scene::new(dt);
    for (&m, (pos, vel)) in mas.masses.iter().zip(init) {
        scene.add_particle(Particle::new(m, *pos).with_vel(*vel));
    }
    for t in types {
        scene.add_type(t);
    }
    for l in &mas.links {
        let name = l.family.type_name(l.type_index);
        let Some(type_index) = scene.type_index(&name) else {
            let have = scene
                .types
                .iter()
                .filter(|t| t.kind == l.family.kind())
                .count();
            return Err(mk(
                format!("{mas_name}:{}", l.line),
                format!(
                    "type {} of liaisons {}: the catalogue has {have} such types",
                    l.type_index,
                    l.family.french()
                ),
            ));
        };
        scene.links.push(crate::Link {
            type_index,
            particles: l.particles.clone(),
            point: None,
            observes: None,
        });
    }
    scene.validate()?;
    Ok(scene)
}

/// Consumes a family header and its count. `prev` is the previous family's count, to hint at
/// the likely cause when numbers are found where the header should be.
fn family_header(
    c: &mut Cursor,
    fam: Family,
    shown: &str,
    prev: Option<usize>,
) -> Result<(usize, usize)> {
    let here = c.here();
    let found = c.peek();
    let expected = format!("expected the header `{shown}`");
    match c.label() {
        Some((label, line)) if Family::from_label(&label) == Some(fam) => {
            let count = c.index(|| format!("the count of liaisons {}", fam.french()))?;
            Ok((count, line))
        }
        Some((label, _)) => Err(mk(here, format!("{expected}, found `{label}`"))),
        None => Err(mk(
            here,
            match (found, prev) {
                (Some(t), Some(p)) if t.kind == Kind::Num => format!(
                    "{expected}, found `{}`: more records than the previous count ({p})?",
                    t.text
                ),
                (Some(t), _) => format!("{expected}, found `{}`", t.text),
                (None, _) => format!("{expected}, found the end of the file"),
            },
        )),
    }
}

/// Parses `NAME.mas`: `Nombre de particules:N`, N masses, then for each family its header
/// and `count` records `type a [b [c]]`.
pub fn parse_mas(name: &str, text: &str) -> Result<MasFile> {
    let mut c = Cursor::new(name, text, mk);
    c.expect_label("nombre de particules", "Nombre de particules:N")?;
    let n = c.index(|| "the particle count".into())?;
    if n == 0 {
        return Err(c.error_here("a model needs at least one particle"));
    }
    let mut masses = Vec::with_capacity(n.min(c.remaining()));
    for i in 0..n {
        let line = c.peek().map(|t| t.line);
        let m = c.number(|| format!("the mass of particle {i} (of {n})"))?;
        if m <= 0.0 {
            return Err(c.error(
                line.unwrap_or(0),
                format!("the mass of particle {i} is {m}: it must be positive"),
            ));
        }
        masses.push(m);
    }
    let mut links = Vec::new();
    let mut prev = None;
    for fam in Family::ALL {
        let shown = format!("Nombre de liaisons {} installees:COUNT", fam.french());
        let (count, _) = family_header(&mut c, fam, &shown, prev)?;
        prev = Some(count);
        for r in 0..count {
            let line = c.peek().map_or(0, |t| t.line);
            let what = |k: &str| {
                format!(
                    "the {k} of link {r} (of {count}) of liaisons {}",
                    fam.french()
                )
            };
            let type_index = c.index(|| what("type"))?;
            let mut particles = Vec::with_capacity(fam.arity());
            for k in 0..fam.arity() {
                let p = c.index(|| what(&format!("particle {}", k + 1)))?;
                if p >= n {
                    return Err(c.error(
                        line,
                        format!("particle {p} does not exist (there are {n}, from 0)"),
                    ));
                }
                if particles.contains(&p) {
                    return Err(c.error(line, format!("particle {p} is linked to itself")));
                }
                particles.push(p);
            }
            links.push(MasLink {
                family: fam,
                type_index,
                particles,
                line,
            });
        }
    }
    c.expect_end("the last family (liaisons ternaires-position)")?;
    Ok(MasFile { masses, links })
}

/// Parses `NAME.cat` or `NAME.sav`: for each family its header `…:count`, then `count`
/// records of the same width, each `l0 K Z [ignored mutabilities…]`. Returns the catalogue
/// in family order, named `up0…`, `uv0…`, `bp0…`, `bv0…`, `tp0…`.
pub fn parse_cat(name: &str, text: &str) -> Result<Vec<LinkType>> {
    let mut c = Cursor::new(name, text, mk);
    let mut types = Vec::new();
    for fam in Family::ALL {
        let shown = format!("Nombre de liaisons {}:COUNT", fam.french());
        let (count, hline) = family_header(&mut c, fam, &shown, None)?;
        let mut nums = Vec::new();
        while c.peek().is_some_and(|t| t.kind == Kind::Num) {
            let line = c.peek().map_or(0, |t| t.line);
            let k = nums.len();
            nums.push((
                c.number(|| format!("value {k} of liaisons {}", fam.french()))?,
                line,
            ));
        }
        let width = nums.len().checked_div(count).unwrap_or(0);
        if (count == 0 && !nums.is_empty()) || (count > 0 && (nums.len() % count != 0 || width < 3))
        {
            return Err(c.error(
                hline,
                format!(
                    "{count} types of liaisons {} need {count} records of at least 3 numbers \
                     (l0 K Z [mutabilities…]) each of the same width; found {} numbers",
                    fam.french(),
                    nums.len()
                ),
            ));
        }
        for (r, rec) in nums.chunks_exact(width.max(1)).take(count).enumerate() {
            let (l0, k, z) = (rec[0].0, rec[1].0, rec[2].0);
            let tname = fam.type_name(r);
            let bad = |what: &str, v: f64, want: &str| {
                c.error(
                    rec[0].1,
                    format!(
                        "type {r} ({tname}) of liaisons {}: {what} is {v}, must be {want}",
                        fam.french()
                    ),
                )
            };
            let t = LinkType::new(tname.clone(), fam.kind());
            let t = match fam {
                Family::UnaryPosition | Family::BinaryPosition => {
                    if l0 < 0.0 {
                        return Err(bad("rest length l0", l0, "≥ 0"));
                    }
                    if k < 0.0 {
                        return Err(bad("stiffness K", k, "≥ 0"));
                    }
                    t.with("stiffness", k).with("rest_length", l0)
                }
                Family::TernaryPosition => {
                    if !(-1.0..=1.0).contains(&l0) {
                        return Err(bad("rest cosine", l0, "in [-1, 1]"));
                    }
                    if k < 0.0 {
                        return Err(bad("stiffness K", k, "≥ 0"));
                    }
                    t.with("stiffness", k).with("rest_cos", l0)
                }
                Family::UnaryVelocity | Family::BinaryVelocity => t,
            };
            let t = if fam == Family::TernaryPosition {
                t
            } else {
                if z < 0.0 {
                    return Err(bad("damping Z", z, "≥ 0"));
                }
                t.with("damping", z)
            };
            types.push(t);
        }
    }
    c.expect_end("the last family (liaisons ternaires-position)")?;
    Ok(types)
}

/// Reads a catalogue file, `NAME.cat` or an identified `NAME.sav` (see [`parse_cat`]).
pub fn read_catalogue(path: &Path) -> Result<Vec<LinkType>> {
    parse_cat(&path.display().to_string(), &read_text(path)?)
}

/// Parses `NAME.ini`: `n` records `x y z vx vy vz` (m, m/s), read as tokens.
pub fn parse_ini(name: &str, text: &str, n: usize) -> Result<Vec<([f64; 3], [f64; 3])>> {
    let mut c = Cursor::new(name, text, mk);
    let mut out = Vec::with_capacity(n.min(c.remaining()));
    const FIELDS: [&str; 6] = ["x", "y", "z", "vx", "vy", "vz"];
    for i in 0..n {
        let mut v = [0.0; 6];
        for (k, field) in FIELDS.iter().enumerate() {
            v[k] = c.number(|| format!("{field} of particle {i} (of {n})"))?;
        }
        out.push(([v[0], v[1], v[2]], [v[3], v[4], v[5]]));
    }
    c.expect_end(&format!("the {n} particles (lines `x y z vx vy vz`)"))?;
    Ok(out)
}

/// Parses `NAME.lock`: family header lines (`liaisons binaires position`…), each followed by
/// lines `i f1 f2 f3 [f4]`; a flag `x` (or `X`, `×`) locks l0, K, Z respectively.
pub fn parse_lock(name: &str, text: &str) -> Result<Vec<LockedType>> {
    Ok(parse_lock_lines(name, text)?
        .into_iter()
        .map(|(l, _)| l)
        .collect())
}

fn parse_lock_lines(name: &str, text: &str) -> Result<Vec<(LockedType, usize)>> {
    let mut out: Vec<(LockedType, usize)> = Vec::new();
    let mut family = None;
    let mut seen = Vec::new();
    for (k, line) in text.lines().enumerate() {
        let place = || format!("{name}:{}", k + 1);
        let toks: Vec<&str> = line.split_whitespace().collect();
        let Some(first) = toks.first() else { continue };
        let numeric = first
            .as_bytes()
            .first()
            .is_some_and(|c| c.is_ascii_digit() || matches!(c, b'+' | b'-' | b'.'));
        if !numeric {
            let Some(f) = Family::from_label(&normalize(line)) else {
                return Err(mk(
                    place(),
                    format!(
                        "`{}` is neither a family header (e.g. `liaisons binaires position`) \
                         nor a line `index f1 f2 f3 [f4]`",
                        line.trim()
                    ),
                ));
            };
            if seen.contains(&f) {
                return Err(mk(place(), format!("liaisons {} appear twice", f.french())));
            }
            seen.push(f);
            family = Some(f);
            continue;
        }
        let Some(fam) = family else {
            return Err(mk(place(), "a type line before any family header".into()));
        };
        let index: usize = first.parse().map_err(|_| {
            mk(
                place(),
                format!("type index `{first}` is not a non-negative integer"),
            )
        })?;
        if !(4..=5).contains(&toks.len()) {
            return Err(mk(
                place(),
                format!("{} fields: expected `index f1 f2 f3 [f4]`", toks.len()),
            ));
        }
        if out.iter().any(|(l, _)| l.family == fam && l.index == index) {
            return Err(mk(
                place(),
                format!("type {index} of liaisons {} is listed twice", fam.french()),
            ));
        }
        let flag = |s: &str| matches!(s, "x" | "X" | "×");
        out.push((
            LockedType {
                family: fam,
                index,
                locked: [flag(toks[1]), flag(toks[2]), flag(toks[3])],
                extra: toks.get(4).map(|s| s.to_string()),
            },
            k + 1,
        ));
    }
    Ok(out)
}

/// Parses `Param.gene`: `key=value` lines with keys `generation, population, pcross, pmut,
/// reducer, noise, damping`; blank lines are skipped.
pub fn parse_gene(name: &str, text: &str) -> Result<GeneParams> {
    let mut g = GeneParams::default();
    for (k, line) in text.lines().enumerate() {
        let place = || format!("{name}:{}", k + 1);
        if line.trim().is_empty() {
            continue;
        }
        let Some((key, value)) = line.split_once('=') else {
            return Err(mk(place(), format!("`{}` is not `key=value`", line.trim())));
        };
        let (key, value) = (key.trim(), value.trim());
        let real = || match value.parse::<f64>() {
            Ok(v) if v.is_finite() => Ok(Some(v)),
            _ => Err(mk(
                place(),
                format!("{key}: `{value}` is not a finite number"),
            )),
        };
        let count = || match value.parse::<u64>() {
            Ok(v) => Ok(Some(v)),
            _ => Err(mk(
                place(),
                format!("{key}: `{value}` is not a non-negative integer"),
            )),
        };
        let was_set = match key {
            "generation" => std::mem::replace(&mut g.generation, count()?).is_some(),
            "population" => std::mem::replace(&mut g.population, count()?).is_some(),
            "pcross" => std::mem::replace(&mut g.pcross, real()?).is_some(),
            "pmut" => std::mem::replace(&mut g.pmut, real()?).is_some(),
            "reducer" => std::mem::replace(&mut g.reducer, real()?).is_some(),
            "noise" => std::mem::replace(&mut g.noise, real()?).is_some(),
            "damping" => std::mem::replace(&mut g.damping, real()?).is_some(),
            _ => {
                return Err(mk(
                    place(),
                    format!(
                        "unknown key `{key}`: expected generation, population, pcross, pmut, \
                         reducer, noise or damping"
                    ),
                ))
            }
        };
        if was_set {
            return Err(mk(place(), format!("key `{key}` is given twice")));
        }
    }
    Ok(g)
}

/// Refuses scenes the thesis' files cannot describe, rather than writing a different model.
fn check_writable(scene: &Scene) -> Result<()> {
    let no = |place: String, why: &str| {
        Err(CordisError::scene(
            place,
            format!("{why}: the thesis' files cannot say so"),
        ))
    };
    if scene.gravity != [0.0; 3] {
        return no("gravity".into(), "gravity is not zero");
    }
    for (i, p) in scene.particles.iter().enumerate() {
        if p.fixed {
            return no(format!("particles[{i}].fixed"), "the particle is fixed");
        }
    }
    for t in &scene.types {
        let at = format!("types.{}", t.name);
        if Family::of_kind(t.kind).is_none() {
            return no(
                format!("{at}.kind"),
                &format!("kind {} has no family", t.kind),
            );
        }
        if let Some(which) = t.optional.first() {
            let what = match which {
                crate::OptionalParam::MaxElongation => "the type has a breaking rate",
                crate::OptionalParam::DampingQuadratic => "the type has a quadratic viscosity",
                crate::OptionalParam::TendonPosition | crate::OptionalParam::TendonVelocity => {
                    "the type has a tendon's initial state"
                }
            };
            return no(format!("{at}.{}", which.name()), what);
        }
        if t.point.is_some() {
            return no(format!("{at}.point"), "the anchor has its own point");
        }
    }
    for (li, l) in scene.links.iter().enumerate() {
        if let (Some(point), Some(&p)) = (l.point, l.particles.first()) {
            if scene.particles.get(p).is_none_or(|p| p.pos != point) {
                return no(
                    format!("links[{li}].point"),
                    "the anchor point is not its particle's initial position",
                );
            }
        }
    }
    Ok(())
}

/// Index of each catalogue type within its family (`None` for kinds outside the families).
fn family_indices(scene: &Scene) -> Vec<Option<usize>> {
    let mut counts = [0usize; 5];
    scene
        .types
        .iter()
        .map(|t| {
            Family::of_kind(t.kind).map(|f| {
                counts[f as usize] += 1;
                counts[f as usize] - 1
            })
        })
        .collect()
}

/// `NAME.mas` text of a scene made of the five thesis kinds. Unknown masses are written as
/// their starting value.
pub fn write_mas(scene: &Scene) -> Result<String> {
    check_writable(scene)?;
    let idx = family_indices(scene);
    let mut out = String::new();
    let _ = writeln!(out, "Nombre de particules:{}", scene.particles.len());
    for p in &scene.particles {
        let _ = writeln!(out, "{:?}", p.mass.value());
    }
    for fam in Family::ALL {
        let links: Vec<_> = scene
            .links
            .iter()
            .filter(|l| scene.types[l.type_index].kind == fam.kind())
            .collect();
        let _ = writeln!(
            out,
            "Nombre de liaisons {} installees:{}",
            fam.french(),
            links.len()
        );
        for l in links {
            let _ = write!(out, "{}", idx[l.type_index].unwrap_or(0));
            for p in &l.particles {
                let _ = write!(out, " {p}");
            }
            out.push('\n');
        }
    }
    Ok(out)
}

/// `NAME.cat` (or `NAME.sav`) text: per family, per type `l0 K Z` then six zero mutabilities
/// (the width of the thesis' examples). Velocity types write `0 0 Z`, angles `cos0 K 0`.
/// Unknown parameters are written as their starting value.
pub fn write_cat(scene: &Scene) -> Result<String> {
    check_writable(scene)?;
    let mut out = String::new();
    for fam in Family::ALL {
        let types: Vec<_> = scene
            .types
            .iter()
            .filter(|t| t.kind == fam.kind())
            .collect();
        let _ = writeln!(out, "Nombre de liaisons {}:{}", fam.french(), types.len());
        for t in types {
            let v = |name: &str| t.param(name).map_or(0.0, Param::value);
            let (l0, k, z) = match fam {
                Family::UnaryPosition | Family::BinaryPosition => {
                    (v("rest_length"), v("stiffness"), v("damping"))
                }
                Family::UnaryVelocity | Family::BinaryVelocity => (0.0, 0.0, v("damping")),
                Family::TernaryPosition => (v("rest_cos"), v("stiffness"), 0.0),
            };
            let _ = writeln!(out, "{l0:?} {k:?} {z:?} 0 0 0 0 0 0");
        }
    }
    Ok(out)
}

/// `NAME.ini` text: one line `x y z vx vy vz` per particle.
pub fn write_ini(scene: &Scene) -> Result<String> {
    check_writable(scene)?;
    let mut out = String::new();
    for p in &scene.particles {
        let ([x, y, z], [vx, vy, vz]) = (p.pos, p.vel);
        let _ = writeln!(out, "{x:?} {y:?} {z:?} {vx:?} {vy:?} {vz:?}");
    }
    Ok(out)
}

/// `NAME.lock` text of [`LockedType`]s, grouped by family in file order.
pub fn write_lock(lock: &[LockedType]) -> String {
    let mut out = String::new();
    for fam in Family::ALL {
        let _ = writeln!(out, "liaisons {}", fam.french().replace('-', " "));
        for l in lock.iter().filter(|l| l.family == fam) {
            let f = |b: bool| if b { "x" } else { "0" };
            let _ = write!(
                out,
                "{} {} {} {}",
                l.index,
                f(l.locked[0]),
                f(l.locked[1]),
                f(l.locked[2])
            );
            if let Some(e) = &l.extra {
                let _ = write!(out, " {e}");
            }
            out.push('\n');
        }
    }
    out
}

/// Writes `base.mas`, `base.cat` and `base.ini` (atomically, each), and `base.tra` when a
/// trajectory is given.
pub fn export(base: &Path, scene: &Scene, trajectory: Option<&Trajectory>) -> Result<()> {
    let file = |ext: &str| {
        let mut s = base.as_os_str().to_owned();
        s.push(".");
        s.push(ext);
        PathBuf::from(s)
    };
    let (mas, cat, ini) = (write_mas(scene)?, write_cat(scene)?, write_ini(scene)?);
    write_atomic(&file("mas"), mas.as_bytes())?;
    write_atomic(&file("cat"), cat.as_bytes())?;
    write_atomic(&file("ini"), ini.as_bytes())?;
    if let Some(t) = trajectory {
        write_atomic(&file("tra"), tra::write_tra(t).as_bytes())?;
    }
    Ok(())
}
