//! Structure discovery (issue 10): from positions alone, propose a spring network — which
//! particle pairs are linked, each link's stiffness, rest length and damping, the masses (under
//! a known total, or given), gravity, and a catalogue of types grouping equal links.
//!
//! Stages (one module each): [`candidates`] (fixed particles; pairs closer than a radius, grid),
//! [`select`] (per particle, the equation of motion as a least-squares system over all its
//! candidate pairs; group-sparse backward selection with a BIC threshold on each pair's Wald
//! statistic), masses (ratios of one link's estimates at its two ends, solved on the link graph
//! in log space, scaled to the total), per-link parameters, [`cluster`] (types), then a
//! catalogue-level refit with the exact least-squares solver
//! ([`crate::strategies::least_squares`]) on the short cost. See `docs/discover.md`.

pub mod candidates;
pub mod cluster;
pub mod identify;
pub mod link_test;
pub mod select;
pub mod smooth;

use cordis_core::{Bounds, LinkKind, LinkType, Param, Particle, Scene, Trajectory, Vec3};
use nalgebra::{Matrix3, Vector3};
use serde::Serialize;

use crate::cost::CostKind;
use crate::error::CostError;
use crate::problem::Problem;
use crate::strategies::{exact::ExactReport, least_squares};
use cluster::Estimate;

/// Above this many types the catalogue refit is skipped (its design is dense in 3 × types per
/// particle: memory ~ particles × (3 × types)²): the per-link
/// estimates are kept and a note says so.
pub const MAX_REFIT_TYPES: usize = 32;

/// Noisy positions are told from a smooth noiseless motion by their differences: white noise's
/// estimates from orders 3 and 6 agree, a motion's own fall as `(ω dt)³` from one to the
/// other. The data are taken as noisy when the 6th-order estimate is at least this share of
/// the 3rd's (white noise: 1 within 2 %, for ~10⁴ differences; the varied generator's
/// noiseless motions: below 0.01).
pub const NOISY_ORDER_RATIO: f64 = 0.5;

/// The link kinds discovery looks for (`--kinds`, `kinds=`): `spring` between two moving
/// particles, `anchor` (a spring-like link to a fixed particle: the particle marks the
/// anchor's point), `damper` (isotropic, `F_i = Z (v_j − v_i)`, between any two particles not
/// both fixed).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Kinds {
    pub spring: bool,
    pub damper: bool,
    pub anchor: bool,
}

impl Kinds {
    pub const ALL: Kinds = Kinds {
        spring: true,
        damper: true,
        anchor: true,
    };
    /// The names [`Kinds::parse`] reads.
    pub const NAMES: [&'static str; 3] = ["spring", "damper", "anchor"];

    /// Reads a list of kind names (each once or more; at least one): `kinds: unknown link kind
    /// `x` …` on anything else.
    pub fn parse<S: AsRef<str>>(names: &[S]) -> Result<Kinds, CostError> {
        let mut k = Kinds {
            spring: false,
            damper: false,
            anchor: false,
        };
        for name in names {
            match name.as_ref().trim() {
                "spring" => k.spring = true,
                "damper" => k.damper = true,
                "anchor" => k.anchor = true,
                other => {
                    return Err(CostError::invalid(
                        "kinds",
                        format!(
                            "unknown link kind `{other}` (discover looks for {})",
                            Kinds::NAMES.join(", ")
                        ),
                    ))
                }
            }
        }
        if !(k.spring || k.damper || k.anchor) {
            return Err(CostError::invalid(
                "kinds",
                format!("give at least one of {}", Kinds::NAMES.join(", ")),
            ));
        }
        Ok(k)
    }

    /// The candidate groups of a pair: a spring-like group (spring, or anchor when an end is
    /// fixed) and a damper group, as the kinds allow (`damper`: false for a pair whose damper
    /// another pair stands for, see [`discover`]).
    fn groups(&self, anchored: bool, damper: bool) -> impl Iterator<Item = select::GroupKind> {
        let spring = if anchored { self.anchor } else { self.spring };
        [
            spring.then_some(select::GroupKind::Spring),
            (self.damper && damper).then_some(select::GroupKind::Damper),
        ]
        .into_iter()
        .flatten()
    }
}

/// What [`discover`] is told besides the trajectory.
#[derive(Clone, Debug)]
pub struct DiscoverOptions {
    /// Total mass of the free (moving) particles, kg. One of this and `masses` is required.
    pub total_mass: Option<f64>,
    /// Every particle's mass, kg (fixed particles' values are kept as given).
    pub masses: Option<Vec<f64>>,
    /// Candidate pairs are those closer than this in the first frame, m (default
    /// [`candidates::RADIUS_PER_NEAREST`] × the median nearest-neighbour distance).
    pub max_range: Option<f64>,
    /// Standard deviation of the position noise, m (0: noiseless). Sets the tolerance under
    /// which a particle counts as fixed. `None`: estimated from the data
    /// ([`estimate_noise_level`]).
    pub noise_level: Option<f64>,
    /// Multiplies the selection threshold (1: BIC).
    pub threshold_scale: f64,
    /// Relative tolerance under which two links' parameters are taken as equal (one type).
    pub type_tolerance: f64,
    /// Gravity, m/s², when known; estimated otherwise.
    pub gravity: Option<[f64; 3]>,
    /// The link kinds looked for (`None`: all of [`Kinds::NAMES`]).
    pub kinds: Option<Kinds>,
    /// How errors spell an option: `--total-mass` (the CLI) or `total_mass` (Python).
    pub style: crate::session::Style,
}

impl Default for DiscoverOptions {
    fn default() -> Self {
        DiscoverOptions {
            total_mass: None,
            masses: None,
            max_range: None,
            noise_level: None,
            threshold_scale: 1.0,
            type_tolerance: 1e-3,
            gravity: None,
            kinds: None,
            style: crate::session::Style::default(),
        }
    }
}

/// How sure the discovery is of one link.
#[derive(Clone, Debug, Serialize)]
pub struct LinkScore {
    pub particles: [usize; 2],
    /// `spring`, `anchor` (a spring-like link to a fixed particle) or `damper`.
    pub kind: &'static str,
    /// Its type in the proposed catalogue.
    #[serde(rename = "type")]
    pub type_name: String,
    /// This link's own estimates before the catalogue refit: K (N/m), l0 (m), Z (N·s/m); a
    /// damper's K and l0 are 0.
    pub stiffness: f64,
    pub rest_length: f64,
    pub damping: f64,
    /// Standard errors of the three (same units).
    pub stiffness_se: f64,
    pub rest_length_se: f64,
    pub damping_se: f64,
    /// Wald statistic of the link (cost increase when removed over the noise floor, summed
    /// over its free ends); kept when above `threshold`.
    pub score: f64,
    pub threshold: f64,
}

/// A candidate that was not kept, with how close it came.
#[derive(Clone, Debug, Serialize)]
pub struct NearMiss {
    pub particles: [usize; 2],
    pub kind: &'static str,
    pub score: f64,
    pub threshold: f64,
}

/// Something the data cannot decide, by name: the particles or links it concerns.
#[derive(Clone, Debug, Serialize)]
pub struct Undetermined {
    /// What is not determined: `masses`, `links`, `gravity`.
    pub what: String,
    pub particles: Vec<usize>,
    pub links: Vec<[usize; 2]>,
    pub why: String,
}

impl Undetermined {
    /// One line for a terminal.
    pub fn line(&self) -> String {
        let mut names = Vec::new();
        if !self.particles.is_empty() {
            names.push(format!("particles {:?}", self.particles));
        }
        if !self.links.is_empty() {
            names.push(format!("links {:?}", self.links));
        }
        format!(
            "{} of {}: not determined ({})",
            self.what,
            names.join(", "),
            self.why
        )
    }
}

/// The answer of [`discover`].
#[derive(Clone, Debug)]
pub struct Discovery {
    /// The proposed scene: every value known, initial state from the first frames.
    pub scene: Scene,
    /// Per link of `scene.links` (same order).
    pub links: Vec<LinkScore>,
    /// The candidates closest to being kept (highest score over threshold first), up to 20.
    pub near_misses: Vec<NearMiss>,
    /// Candidate radius used, m.
    pub radius: f64,
    pub candidates: usize,
    /// The candidate pairs a spring-like link (spring, or anchor to a fixed particle) was
    /// looked for on, ascending: what [`link_test`] tests again by output error.
    pub candidate_pairs: Vec<[usize; 2]>,
    /// Rounds of the backward selection.
    pub rounds: usize,
    /// Short cost of the proposed scene on the trajectory, m², and its rmse, m.
    pub cost: f64,
    pub rmse: f64,
    /// The exact solver's report of the catalogue refit.
    pub solver: ExactReport,
    /// What the data cannot decide (empty when everything is determined).
    pub undetermined: Vec<Undetermined>,
    /// What a user should know about the data (noisy positions, an estimated noise level).
    pub data_warnings: Vec<String>,
    /// The position noise used, m (given, or estimated when `estimated_noise`).
    pub noise_level: f64,
    pub estimated_noise: bool,
    pub notes: Vec<String>,
}

impl Discovery {
    /// One line per thing a user should know, for a terminal (the CLI's `warning:` lines,
    /// Python's `warnings.warn`): the data's, what is not determined, the refit's.
    pub fn warnings(&self) -> Vec<String> {
        let mut w = self.data_warnings.clone();
        w.extend(self.undetermined.iter().map(Undetermined::line));
        w.extend(self.solver.warnings());
        w
    }
}

/// The position of a particle that does not move, from a trajectory whose every frame observes
/// it with independent noise of one σ: the mean over the frames, the maximum-likelihood
/// estimate (error σ/√frames, against σ for any single frame). The smoothing
/// ([`smooth::smooth`]) puts fixed particles there too, but only when it runs (noise > 0 and
/// at least 12 frames): the scene reads this whatever the path
/// ([`cordis_core::from_markers::rest_position`]: a noiseless particle keeps its position to
/// the bit).
pub fn fixed_position(traj: &Trajectory, i: usize) -> Vec3 {
    let points: Vec<[f64; 3]> = (0..traj.frames()).map(|t| traj.pos(t, i).into()).collect();
    cordis_core::from_markers::rest_position(&points).map_or_else(|| traj.pos(0, i), Vec3::from)
}

fn bad(place: &str, msg: impl Into<String>) -> CostError {
    CostError::mismatch(place, msg)
}

/// Discovers a spring network from a trajectory sampled every `dt` seconds (module docs).
pub fn discover(traj: &Trajectory, dt: f64, opt: &DiscoverOptions) -> Result<Discovery, CostError> {
    check_options(traj, dt, opt)?;
    let mut notes = Vec::new();
    let mut data_warnings: Vec<String> = Vec::new();
    let noise = noise_level(traj, opt, &mut notes, &mut data_warnings);

    // Stage 1: fixed particles and candidates.
    let data = Positions::read(traj, dt, noise, &mut notes)?;
    let cand = Candidates::find(&data, opt)?;

    // Stages 2–3: local systems and selection.
    let locals = select::build(
        data.used(),
        dt,
        &data.free,
        &cand.pairs,
        &cand.group_kinds,
        data.accel.as_ref(),
    );
    let mut sel = select_links(&data, &cand, &locals, opt, &mut notes)?;
    let kept: Vec<usize> = (0..cand.pairs.len()).filter(|&p| sel.active[p]).collect();
    if kept.is_empty() {
        return Err(bad(
            "trajectory",
            "no candidate pair explains the motion (no link found)",
        ));
    }
    let at = kept_places(&locals, &sel, cand.pairs.len());

    // Stage 4: masses.
    let mut undetermined = cand.damper_ends_undetermined(&kept, &data.fixed);
    let (masses, mass_groups) = discovered_masses(
        &locals,
        &sel,
        &kept,
        &cand.pairs,
        &at,
        &data.free,
        opt,
        &mut notes,
    )?;
    let estimates = link_estimates(&kept, &cand.group_kinds, &at, &locals, &sel, &masses);
    let g = mean_gravity(&locals, &sel, &masses, opt.gravity);
    // The local factors and fits are done with: freed before the refit, whose own memory
    // would otherwise come on top (6,000 particles: 0.93 GB peak with them, 0.62 GB without).
    drop(locals);
    drop(at);
    sel.fits = Vec::new();

    // Stage 5: types, springs (and anchors) and dampers apart.
    let types = Types::cluster(&kept, &cand.group_kinds, &estimates, opt.type_tolerance);

    // Stage 6: the scene, refitted at catalogue level by the exact solver.
    let scene = proposed_scene(&data, &masses, g, &types, &kept, &cand.pairs, opt)?;
    let refit = refit(&scene, data.used(), dt, opt, types.count(), &mut notes)?;
    undetermined.extend(undetermined_mass_groups(
        &mass_groups,
        &scene,
        &refit.solver,
        &data.free,
    ));

    let (links, near) = scored_links(&cand, &data.fixed, &sel, &kept, &estimates, &types.type_of);
    notes.push(format!(
        "{} candidate pairs within {:.6} m ({} candidate links), {} links kept after {} \
         rounds, {} types",
        cand.within,
        cand.radius,
        cand.pairs.len(),
        kept.len(),
        sel.rounds,
        types.count()
    ));
    Ok(Discovery {
        scene: refit.scene,
        links,
        near_misses: near,
        radius: cand.radius,
        candidates: cand.within,
        candidate_pairs: cand.spring_pairs(),
        rounds: sel.rounds,
        cost: refit.cost,
        rmse: refit.rmse,
        solver: refit.solver,
        undetermined,
        data_warnings,
        noise_level: noise,
        estimated_noise: opt.noise_level.is_none(),
        notes,
    })
}

/// The position noise, m: given, or estimated from the data (a warning when it finds some, a
/// note when it finds none).
fn noise_level(
    traj: &Trajectory,
    opt: &DiscoverOptions,
    notes: &mut Vec<String>,
    data_warnings: &mut Vec<String>,
) -> f64 {
    match opt.noise_level {
        Some(s) => s,
        None => {
            let (s, line) = estimate_noise_level(traj);
            if s > 0.0 {
                data_warnings.push(line);
            } else {
                notes.push(line);
            }
            s
        }
    }
}

/// Where each of `pairs` candidate pairs that `sel` kept sits in the locals: (local index,
/// position in it), one per free end.
fn kept_places(
    locals: &[select::Local],
    sel: &select::Selection,
    pairs: usize,
) -> Vec<Vec<(usize, usize)>> {
    let mut at: Vec<Vec<(usize, usize)>> = vec![Vec::new(); pairs];
    for (l, loc) in locals.iter().enumerate() {
        for (q, &p) in loc.pairs.iter().enumerate() {
            if sel.active[p] {
                at[p].push((l, q));
            }
        }
    }
    at
}

/// The masses: given, or from the kept links' estimates at their two ends
/// ([`masses_from_ratios`]) scaled to the given total; with the groups of moving particles
/// that no link between two moving particles joins when there are several (noted: their
/// ratios come from the catalogue refit alone).
#[allow(clippy::too_many_arguments)]
fn discovered_masses(
    locals: &[select::Local],
    sel: &select::Selection,
    kept: &[usize],
    pairs: &[[usize; 2]],
    at: &[Vec<(usize, usize)>],
    free: &[bool],
    opt: &DiscoverOptions,
    notes: &mut Vec<String>,
) -> Result<(Vec<f64>, Vec<Vec<usize>>), CostError> {
    if let Some(ms) = &opt.masses {
        return Ok((ms.clone(), Vec::new()));
    }
    let (m, groups) = masses_from_ratios(
        locals,
        &sel.fits,
        kept,
        pairs,
        at,
        free,
        opt.total_mass.unwrap_or(1.0),
    )?;
    if groups.len() < 2 {
        return Ok((m, Vec::new()));
    }
    notes.push(format!(
        "the links split the moving particles into {} groups without a link between two \
         moving particles: their mass ratios come only from the catalogue refit (shared types)",
        groups.len()
    ));
    Ok((m, groups))
}

/// The report's links (each kept link with its estimates, score and threshold) and its
/// near misses (the 20 candidates closest to being kept, highest score over threshold first).
fn scored_links(
    cand: &Candidates,
    fixed: &[bool],
    sel: &select::Selection,
    kept: &[usize],
    estimates: &[Estimate],
    type_of: &[String],
) -> (Vec<LinkScore>, Vec<NearMiss>) {
    let links = kept
        .iter()
        .enumerate()
        .map(|(e, &p)| {
            let est = &estimates[e];
            LinkScore {
                particles: cand.pairs[p],
                kind: cand.kind_name(p, fixed),
                type_name: type_of[e].clone(),
                stiffness: est.value[0],
                rest_length: est.value[1],
                damping: est.value[2],
                stiffness_se: est.se[0],
                rest_length_se: est.se[1],
                damping_se: est.se[2],
                score: sel.score[p],
                threshold: sel.threshold[p],
            }
        })
        .collect();
    let mut near: Vec<NearMiss> = (0..cand.pairs.len())
        .filter(|&p| !sel.active[p])
        .map(|p| NearMiss {
            particles: cand.pairs[p],
            kind: cand.kind_name(p, fixed),
            score: sel.score[p],
            threshold: sel.threshold[p],
        })
        .collect();
    near.sort_by(|a, b| (b.score / b.threshold).total_cmp(&(a.score / a.threshold)));
    near.truncate(20);
    (links, near)
}

/// The masses discovery scales by, kg: beyond, forces and their squares in the least squares
/// left the finite numbers (a total mass of 1e300 kg came back as "gravity[0]: must be a
/// finite number, got NaN").
const MASS_RANGE: (f64, f64) = (1e-30, 1e30);

/// Refuses a step, a take or an option discovery cannot use, naming it.
fn check_options(traj: &Trajectory, dt: f64, opt: &DiscoverOptions) -> Result<(), CostError> {
    let (frames, n) = (traj.frames(), traj.particles());
    let name = |option: &str| opt.style.opt(option);
    if !(dt > 0.0 && dt.is_finite()) {
        return Err(bad(
            &name("dt"),
            format!("must be a positive number of seconds, got {dt}"),
        ));
    }
    // Accelerations divide by dt²: a dt whose square underflows (5e-324 s) made every one
    // infinite and the selection loop never ended.
    if !(dt * dt).is_normal() {
        // 1e300 s was called "too small" (its square overflows, it does not underflow).
        let why = match (dt * dt).is_infinite() {
            true => "too large: dt² overflows",
            false => "too small: dt² underflows",
        };
        return Err(bad(
            &name("dt"),
            format!("{dt:e} s is {why} to {:e}", dt * dt),
        ));
    }
    if frames < 8 {
        return Err(bad(
            &name("trajectory"),
            format!("has {frames} frames, discovery needs at least 8"),
        ));
    }
    if n < 2 {
        return Err(bad(&name("trajectory"), "needs at least 2 particles"));
    }
    check_mass_options(opt, n)?;
    if let Some(s) = opt.noise_level {
        if !(s >= 0.0 && s.is_finite()) {
            return Err(bad(
                &name("noise_level"),
                "must be a non-negative number of m",
            ));
        }
        // A level far above the motion is a wrong unit: 1e300 m was answered "no particle
        // moves", blaming the data (as identify's noise, bounded by the same rule).
        let positions = traj.as_flat().chunks_exact(3).map(|p| [p[0], p[1], p[2]]);
        let size = cordis_core::from_markers::extent_of(positions);
        if let Some(why) = cordis_core::arg::noise_out_of_scale(s, size, "the motion") {
            return Err(bad(&name("noise_level"), why));
        }
    }
    // NaN or inf here used to pass silently (NaN keeps every link or none).
    use cordis_core::arg::{number, Low};
    number(
        &name("threshold_scale"),
        opt.threshold_scale,
        Low::Above(0.0),
        f64::MAX,
        "a multiple of the selection threshold",
    )?;
    number(
        &name("type_tolerance"),
        opt.type_tolerance,
        Low::AtLeast(0.0),
        f64::MAX,
        "relative",
    )?;
    if let Some(g) = opt.gravity {
        if let Some(c) = g.iter().position(|v| !v.is_finite()) {
            return Err(bad(
                &format!("{}[{c}]", name("gravity")),
                "must be a finite number of m/s²",
            ));
        }
    }
    if let Some(r) = opt.max_range {
        if !(r > 0.0 && r.is_finite()) {
            return Err(bad(
                &name("max_range"),
                format!("must be a positive number of m, got {r}"),
            ));
        }
    }
    Ok(())
}

/// The masses' scale: the total of the moving particles or every mass, positive and within
/// [`MASS_RANGE`].
fn check_mass_options(opt: &DiscoverOptions, n: usize) -> Result<(), CostError> {
    let (low, high) = MASS_RANGE;
    let outside = |m: f64| !(m >= low && m <= high);
    let name = |option: &str| opt.style.opt(option);
    match (&opt.total_mass, &opt.masses) {
        (Some(m), _) if !(*m > 0.0 && m.is_finite()) => Err(bad(
            &name("total_mass"),
            format!("must be a positive number of kg, got {m}"),
        )),
        (Some(m), _) if outside(*m) => Err(bad(
            &name("total_mass"),
            format!("{m:e} kg is outside [{low:e}, {high:e}] kg"),
        )),
        (_, Some(ms)) if ms.len() != n => Err(bad(
            &name("masses"),
            format!("has {} values, the trajectory {n} particles", ms.len()),
        )),
        (_, Some(ms)) => match ms.iter().position(|m| outside(*m)) {
            Some(k) => Err(bad(
                &format!("{}[{k}]", name("masses")),
                format!(
                    "must be a positive number of kg in [{low:e}, {high:e}], got {:e}",
                    ms[k]
                ),
            )),
            None => Ok(()),
        },
        (None, None) => Err(bad(
            &name("masses"),
            "masses and stiffnesses are only determined up to a common scale: give the total \
             mass of the moving particles or every mass",
        )),
        _ => Ok(()),
    }
}

/// The positions discovery reads: the raw take, which particles are fixed, and (on noisy data)
/// the smoothed positions with the accelerations' kernel.
struct Positions<'a> {
    raw: &'a Trajectory,
    dt: f64,
    noise: f64,
    fixed: Vec<bool>,
    free: Vec<bool>,
    /// The smoothing's half-width (frames dropped at each end) and the smoothed take.
    smoothing: Option<(usize, Trajectory)>,
    accel: Option<smooth::Accelerations>,
}

impl<'a> Positions<'a> {
    /// Fixed particles (those that move less than 3σ), then the positions smoothed when noisy.
    fn read(
        raw: &'a Trajectory,
        dt: f64,
        noise: f64,
        notes: &mut Vec<String>,
    ) -> Result<Self, CostError> {
        let scale = raw.scale().max(f64::MIN_POSITIVE);
        let fixed = candidates::fixed_particles(raw, (3.0 * noise).max(1e-12 * scale));
        let free: Vec<bool> = fixed.iter().map(|f| !f).collect();
        if !free.iter().any(|&f| f) {
            return Err(bad("trajectory", "no particle moves: nothing to discover"));
        }
        let mut accel = None;
        let smoothing = match smooth::smooth(raw, &fixed, noise).filter(|_| noise > 0.0) {
            Some((s, h)) => {
                accel = smooth::Accelerations::new(raw, h, dt);
                notes.push(format!(
                    "noisy positions: cubic Savitzky-Golay filter over {} frames ({h} frames \
                     dropped at each end; the scene's initial state at the first frame by its \
                     end-point fit{})",
                    2 * h + 1,
                    if accel.is_some() {
                        "; accelerations from the raw positions by a kernel uncorrelated with it"
                    } else {
                        ""
                    }
                ));
                Some((h, s))
            }
            None => None,
        };
        Ok(Positions {
            raw,
            dt,
            noise,
            fixed,
            free,
            smoothing,
            accel,
        })
    }

    /// The positions the equations of motion are written on: smoothed when noisy, else raw.
    fn used(&self) -> &Trajectory {
        self.smoothing.as_ref().map_or(self.raw, |(_, s)| s)
    }

    /// Frames with an equation of motion.
    fn row_frames(&self) -> usize {
        self.accel
            .as_ref()
            .map_or(self.used().frames() - 2, |a| a.last - a.first)
    }

    /// The scene's initial position and velocity of particle `i`: a fixed particle at its
    /// maximum-likelihood position under noise, the mean over every raw frame (frame 0 alone is
    /// off by the full noise σ, biasing every link anchored on it); a moving one at the take's
    /// first frame: smoothed by the end-point form of the smoothing when it ran (the smoothed
    /// trajectory starts h frames in), else raw, its velocity from x(-1).
    fn initial_state(&self, i: usize) -> (Vec3, Vec3) {
        let (raw, traj) = (self.raw, self.used());
        let smoothed_start = self
            .smoothing
            .as_ref()
            .and_then(|(h, _)| smooth::start_positions(raw, i, *h));
        let (pos, xm1) = match smoothed_start {
            _ if self.fixed[i] => (fixed_position(raw, i), raw.pos(0, i)),
            Some(start) => start,
            // x(-1) by quadratic extrapolation of frames 0–2.
            None => (
                traj.pos(0, i),
                traj.pos(0, i) * 3.0 - traj.pos(1, i) * 3.0 + traj.pos(2, i),
            ),
        };
        (pos, (pos - xm1) / self.dt)
    }
}

/// The candidate groups: per candidate pair, one per kind looked for (a pair may carry a
/// spring and a damper).
struct Candidates {
    radius: f64,
    /// How many candidate pairs lie within the radius.
    within: usize,
    /// Per group: its pair and kind.
    pairs: Vec<[usize; 2]>,
    group_kinds: Vec<select::GroupKind>,
    /// Per moving particle: how many fixed particles it could be damped to.
    fixed_choices: Vec<usize>,
}

impl Candidates {
    /// The pairs of the spring groups (spring, or anchor to a fixed particle), in group order:
    /// the [`Discovery::candidate_pairs`] that [`link_test`] tests again.
    fn spring_pairs(&self) -> Vec<[usize; 2]> {
        (0..self.pairs.len())
            .filter(|&p| self.group_kinds[p] == select::GroupKind::Spring)
            .map(|p| self.pairs[p])
            .collect()
    }

    /// Pairs within the radius (given, or from the first frame's spacing), refused when a
    /// particle would have more unknowns than equations or the local systems would not fit in
    /// memory.
    fn find(data: &Positions<'_>, opt: &DiscoverOptions) -> Result<Self, CostError> {
        let traj = data.used();
        let n = traj.particles();
        let (fixed, free) = (&data.fixed, &data.free);
        let x0: Vec<Vec3> = (0..n).map(|i| traj.pos(0, i)).collect();
        let radius = match opt.max_range {
            Some(r) => r,
            None => candidates::default_radius(&x0)
                .ok_or_else(|| bad("trajectory", "the particles of the first frame coincide"))?,
        };
        let place = if opt.max_range.is_some() {
            "max_range"
        } else {
            "trajectory"
        };
        let row_frames = data.row_frames();
        let kinds = opt.kinds.unwrap_or(Kinds::ALL);
        // Before storing any pair: each counted at the most columns a pair can take.
        let widest = kinds
            .groups(false, true)
            .map(|g| g.width())
            .sum::<usize>()
            .max(kinds.groups(true, true).map(|g| g.width()).sum::<usize>());
        let degrees = candidates::degrees_within(&x0, fixed, radius);
        let widest_cols: Vec<usize> = degrees.iter().map(|d| d * widest).collect();
        let noisy = data.accel.is_some();
        check_candidates(
            row_frames,
            noisy,
            (&degrees, &widest_cols),
            free,
            radius,
            place,
        )?;
        let within = candidates::candidate_pairs(&x0, fixed, radius, opt.max_range.is_none());
        // A damper to a fixed particle pulls `−Z v_i` whichever fixed particle it ends on: one
        // candidate per moving particle stands for them all (the nearest fixed one; several
        // would make the fit rank-deficient), and when the particle had a choice its end is
        // named as not determined.
        let mut to_fixed: Vec<Option<(f64, usize)>> = vec![None; n];
        let mut fixed_choices = vec![0usize; n];
        for (k, ([i, j], d)) in within.iter().enumerate() {
            for (a, b) in [(*i, *j), (*j, *i)] {
                if free[a] && fixed[b] {
                    fixed_choices[a] += 1;
                    if to_fixed[a].is_none_or(|(bd, _)| *d < bd) {
                        to_fixed[a] = Some((*d, k));
                    }
                }
            }
        }
        let mut pairs: Vec<[usize; 2]> = Vec::new();
        let mut group_kinds: Vec<select::GroupKind> = Vec::new();
        let (mut degree, mut cols) = (vec![0; n], vec![0; n]);
        for (k, ([i, j], _)) in within.iter().enumerate() {
            degree[*i] += 1;
            degree[*j] += 1;
            let anchored = fixed[*i] || fixed[*j];
            let moving = if fixed[*i] { *j } else { *i };
            let damper = !anchored || to_fixed[moving].is_some_and(|(_, b)| b == k);
            for g in kinds.groups(anchored, damper) {
                pairs.push([*i, *j]);
                group_kinds.push(g);
                cols[*i] += g.width();
                cols[*j] += g.width();
            }
        }
        check_candidates(row_frames, noisy, (&degree, &cols), free, radius, place)?;
        if pairs.is_empty() {
            return Err(bad(
                "max_range",
                format!("no pair of particles is closer than {radius} m"),
            ));
        }
        Ok(Candidates {
            radius,
            within: within.len(),
            pairs,
            group_kinds,
            fixed_choices,
        })
    }

    /// The kind of group `p`, as the report names it.
    fn kind_name(&self, p: usize, fixed: &[bool]) -> &'static str {
        match self.group_kinds[p] {
            select::GroupKind::Damper => "damper",
            select::GroupKind::Spring if self.pairs[p].iter().any(|&i| fixed[i]) => "anchor",
            select::GroupKind::Spring => "spring",
        }
    }

    /// The kept dampers to a fixed particle whose moving end had a choice of fixed ones.
    fn damper_ends_undetermined(&self, kept: &[usize], fixed: &[bool]) -> Vec<Undetermined> {
        let mut out = Vec::new();
        for &p in kept {
            let [i, j] = self.pairs[p];
            let moving = if fixed[i] { j } else { i };
            if self.group_kinds[p] == select::GroupKind::Damper
                && (fixed[i] || fixed[j])
                && self.fixed_choices[moving] > 1
            {
                out.push(Undetermined {
                    what: "links".into(),
                    particles: vec![moving],
                    links: vec![self.pairs[p]],
                    why: format!(
                        "a damper from a moving particle to a fixed one pulls -Z v whichever \
                         fixed particle it ends on: the end is one of the {} fixed candidates",
                        self.fixed_choices[moving]
                    ),
                });
            }
        }
        out
    }
}

/// The backward selection over the candidate groups, with gravity given, shared by every
/// particle (from a first selection without it), or per particle when not determined apart
/// from the links (noted).
fn select_links(
    data: &Positions<'_>,
    cand: &Candidates,
    locals: &[select::Local],
    opt: &DiscoverOptions,
    notes: &mut Vec<String>,
) -> Result<select::Selection, CostError> {
    let (dt, noise) = (data.dt, data.noise);
    // The least residual variance per row: rounding, or the position noise carried into the
    // accelerations (σ² Σg²/dt⁴): a pair is then tested against the noise the data are
    // known to carry, not against a residual it may have fitted.
    let noise_floor = data
        .accel
        .as_ref()
        .map_or(0.0, |a| noise * noise * a.gain / dt.powi(4));
    let floor = select::rounding_floor(data.used(), dt).max(noise_floor);
    let threshold = opt.threshold_scale;
    let noise_model = data.accel.as_ref().map(|a| select::Noise {
        variance: noise * noise,
        dt,
        accel_autocorrelation: a.accel_autocorrelation.clone(),
        smooth_autocorrelation: a.smooth_autocorrelation.clone(),
    });
    let num_pairs = cand.pairs.len();
    let gravity = match opt.gravity {
        Some(g) => Some(Vector3::from(g)),
        None => {
            let first = select::select(
                locals,
                num_pairs,
                threshold,
                floor,
                None,
                noise_model.as_ref(),
            );
            let g = select::shared_gravity(locals, &first.fits, &first.active);
            if g.is_none() {
                notes.push(
                    "gravity is not determined apart from the links (every particle's links \
                     can stand in for some direction of it): estimated per particle, where it \
                     trades off with the pull of fixed particles (give --gravity)"
                        .into(),
                );
            }
            g
        }
    };
    Ok(select::select(
        locals,
        num_pairs,
        threshold,
        floor,
        gravity,
        noise_model.as_ref(),
    ))
}

/// Per kept link, θ from its ends' local estimates (each `β = θ/m` scaled by its particle's
/// mass): their inverse-variance mean, with its standard error (a spring's rest length from
/// `K l0` and `K`).
fn link_estimates(
    kept: &[usize],
    group_kinds: &[select::GroupKind],
    at: &[Vec<(usize, usize)>],
    locals: &[select::Local],
    sel: &select::Selection,
    masses: &[f64],
) -> Vec<Estimate> {
    let mut estimates = Vec::with_capacity(kept.len());
    for &p in kept {
        let width = group_kinds[p].width();
        let (mut sw, mut swx) = (Vector3::zeros(), Vector3::zeros());
        for &(l, q) in &at[p] {
            let m = masses[locals[l].particle];
            let f = &sel.fits[l];
            let b = f.beta[q] * m;
            for c in 0..width {
                let var = (f.cov[q][(c, c)] * m * m)
                    .max((1e-13 * b[c]).powi(2))
                    .max(1e-300);
                sw[c] += 1.0 / var;
                swx[c] += b[c] / var;
            }
        }
        let th = swx.component_div(&sw);
        let var = sw.map(|w| 1.0 / w);
        if group_kinds[p] == select::GroupKind::Damper {
            estimates.push(Estimate {
                value: [0.0, 0.0, th[0]],
                se: [0.0, 0.0, var[0].sqrt()],
            });
            continue;
        }
        let k = th[0];
        let l0 = th[1] / k;
        estimates.push(Estimate {
            value: [k, l0, th[2]],
            se: [
                var[0].sqrt(),
                ((var[1] + l0 * l0 * var[0]).sqrt() / k.abs()).min(f64::MAX),
                var[2].sqrt(),
            ],
        });
    }
    estimates
}

/// Gravity: the given one, or the particles' estimates weighted by `m²/σ²` (0 when smaller
/// than its own noise).
fn mean_gravity(
    locals: &[select::Local],
    sel: &select::Selection,
    masses: &[f64],
    given: Option<[f64; 3]>,
) -> Vector3<f64> {
    let mut g = Vector3::zeros();
    let mut wsum = 0.0;
    for (l, f) in sel.fits.iter().enumerate() {
        let w = masses[locals[l].particle].powi(2) / f.sigma2.max(f64::MIN_POSITIVE);
        g += f.gravity * w;
        wsum += w;
    }
    g /= wsum;
    // Gravity smaller than its own noise is taken as none.
    let g_scale = sel
        .fits
        .iter()
        .map(|f| f.gravity.norm())
        .fold(0.0, f64::max);
    if g.norm() <= 1e-9 * g_scale.max(1e-300) {
        g = Vector3::zeros();
    }
    // Given gravity is the scene's as given (the weighted mean of equal values drifted by an
    // ulp: -9.810000000000002).
    if let Some(given) = given {
        g = Vector3::from(given);
    }
    g
}

/// The kept links' types: springs (and anchors) and dampers clustered apart.
struct Types {
    springs: cluster::Clusters,
    dampers: cluster::Clusters,
    /// Per kept link, its type's name (`t…` or `d…`).
    type_of: Vec<String>,
    /// The springs' mean |Z|: a damping below its noise and a millionth of it is 0.
    z_floor: f64,
}

impl Types {
    fn cluster(
        kept: &[usize],
        group_kinds: &[select::GroupKind],
        estimates: &[Estimate],
        tolerance: f64,
    ) -> Self {
        let is_damper = |e: usize| group_kinds[kept[e]] == select::GroupKind::Damper;
        let springs: Vec<usize> = (0..kept.len()).filter(|&e| !is_damper(e)).collect();
        let dampers: Vec<usize> = (0..kept.len()).filter(|&e| is_damper(e)).collect();
        let pick = |of: &[usize]| of.iter().map(|&e| estimates[e]).collect::<Vec<_>>();
        let cl = cluster::cluster(&pick(&springs), tolerance);
        let cl_damper = cluster::cluster(&pick(&dampers), tolerance);
        let mut type_of = vec![String::new(); kept.len()];
        for (s, &e) in springs.iter().enumerate() {
            type_of[e] = format!("t{}", cl.of[s]);
        }
        for (s, &e) in dampers.iter().enumerate() {
            type_of[e] = format!("d{}", cl_damper.of[s]);
        }
        let z_floor = springs
            .iter()
            .map(|&e| estimates[e].value[2].abs())
            .sum::<f64>()
            / springs.len().max(1) as f64;
        Types {
            springs: cl,
            dampers: cl_damper,
            type_of,
            z_floor,
        }
    }

    fn count(&self) -> usize {
        self.springs.centres.len() + self.dampers.centres.len()
    }
}

/// The proposed scene: every particle at its initial state (masses unknown within a decade
/// unless given), one link type per cluster (boxes a decade either side of its centre), the
/// kept links.
fn proposed_scene(
    data: &Positions<'_>,
    masses: &[f64],
    g: Vector3<f64>,
    types: &Types,
    kept: &[usize],
    pairs: &[[usize; 2]],
    opt: &DiscoverOptions,
) -> Result<Scene, CostError> {
    let mut scene = Scene::new(data.dt);
    scene.gravity = [g.x, g.y, g.z];
    for (i, &m) in masses.iter().enumerate() {
        let (pos, vel) = data.initial_state(i);
        let fixed = data.fixed[i];
        let mass = if fixed || opt.masses.is_some() {
            Param::Known(m)
        } else {
            Param::Unknown(Bounds {
                min: m / 10.0,
                max: m * 10.0,
                init: Some(m),
            })
        };
        let mut particle = Particle::new(m, [pos.x, pos.y, pos.z]);
        particle.mass = mass;
        if fixed {
            particle = particle.fixed();
        } else {
            particle = particle.with_vel([vel.x, vel.y, vel.z]);
        }
        scene.add_particle(particle);
    }
    // Boxes a decade either side; a non-positive estimate (noise) gets the box of the
    // catalogue's typical value, which the exact solver may still clamp onto.
    let typical = |c: usize| {
        let v: Vec<f64> = types
            .springs
            .centres
            .iter()
            .map(|e| e.value[c])
            .filter(|v| *v > 0.0)
            .collect();
        if v.is_empty() {
            1.0
        } else {
            v.iter().sum::<f64>() / v.len() as f64
        }
    };
    let (k_typ, l_typ, z_typ) = (typical(0), typical(1), typical(2));
    let width = |v: f64, reference: f64| -> Param {
        let v = if v > 0.0 && v.is_finite() {
            v
        } else {
            reference
        };
        Param::Unknown(Bounds {
            min: v / 10.0,
            max: v * 10.0,
            init: Some(v),
        })
    };
    for (t, c) in types.springs.centres.iter().enumerate() {
        let [k, l0, z] = c.value;
        let z_zero = z.abs() <= cluster::SIGMAS * c.se[2] + 1e-6 * types.z_floor;
        scene.add_type(
            LinkType::new(format!("t{t}"), LinkKind::Spring)
                .with("stiffness", width(k, k_typ))
                .with("rest_length", width(l0, l_typ))
                .with(
                    "damping",
                    if z_zero || z <= 0.0 {
                        Param::Known(0.0)
                    } else {
                        width(z, z_typ)
                    },
                ),
        );
    }
    for (t, c) in types.dampers.centres.iter().enumerate() {
        scene.add_type(
            LinkType::new(format!("d{t}"), LinkKind::Damper)
                .with("damping", width(c.value[2], z_typ)),
        );
    }
    for (e, &p) in kept.iter().enumerate() {
        scene.add_link(&types.type_of[e], &pairs[p]);
    }
    scene.validate()?;
    Ok(scene)
}

/// The catalogue refit's answer.
struct Refit {
    scene: Scene,
    cost: f64,
    rmse: f64,
    solver: ExactReport,
}

/// The proposed scene refitted at catalogue level by the exact solver on the short cost (the
/// masses scaled to the given total); when it cannot run, the per-link estimates are kept
/// (noted).
fn refit(
    scene: &Scene,
    traj: &Trajectory,
    dt: f64,
    opt: &DiscoverOptions,
    types: usize,
    notes: &mut Vec<String>,
) -> Result<Refit, CostError> {
    let traj_dt = traj.clone().with_dt(dt);
    let mut problem = Problem::new(scene, &traj_dt, CostKind::Short)?;
    if opt.masses.is_none() {
        problem = problem.with_total_mass(opt.total_mass.unwrap_or(1.0))?;
    }
    let refit = if types <= MAX_REFIT_TYPES {
        least_squares::solve(&problem)
    } else {
        Err(format!(
            "{types} types: above {MAX_REFIT_TYPES}, the links are unlikely to be springs of a \
             few types (other link kinds?)"
        ))
    };
    let (final_scene, cost, solver) = match refit {
        Ok(sol) => (
            problem.space.scene_with(scene, &sol.genome),
            sol.cost,
            sol.report,
        ),
        Err(e) => {
            notes.push(format!(
                "catalogue refit failed ({e}); kept the per-link estimates"
            ));
            let mut s = scene.clone();
            let p = s.param_values();
            s.set_param_values(&p);
            let genome = problem.space.genome_of(&p);
            let mut sc = problem.scratch();
            let mut local = vec![0.0; scene.num_particles()];
            let c = problem.evaluate(&genome, &mut sc, &mut local);
            (
                problem.space.scene_with(scene, &genome),
                c,
                ExactReport::default(),
            )
        }
    };
    Ok(Refit {
        scene: final_scene,
        cost,
        rmse: problem.rmse(cost),
        solver,
    })
}

/// The mass groups (particles joined by links between moving particles; the largest first
/// or not, any order) whose scale the catalogue refit could not measure: a group whose links'
/// types include one the refit reports undetermined (a type no other group shares, so only
/// `K/m` is seen). Such a group's masses are named, and so is every other moving particle's,
/// since the given total is shared with them (issue 20: a particle hanging from a fixed one
/// by a link of its own type took 3.3 × its mass, and the total's remainder moved every
/// other mass by 3 %).
fn undetermined_mass_groups(
    groups: &[Vec<usize>],
    scene: &Scene,
    solver: &ExactReport,
    free: &[bool],
) -> Vec<Undetermined> {
    if groups.len() < 2 {
        return Vec::new();
    }
    let unmeasured = |group: &Vec<usize>| {
        scene
            .links
            .iter()
            .filter(|l| l.particles.iter().any(|i| group.contains(i)))
            .any(|l| {
                let prefix = format!("types.{}.", scene.types[l.type_index].name);
                solver.undetermined.iter().any(|u| u.starts_with(&prefix))
            })
            || solver.error.is_some()
    };
    let bad: Vec<&Vec<usize>> = groups.iter().filter(|g| unmeasured(g)).collect();
    if bad.is_empty() {
        return Vec::new();
    }
    let named: Vec<usize> = bad.iter().flat_map(|g| g.iter().copied()).collect();
    let mut out: Vec<Undetermined> = bad
        .iter()
        .map(|g| Undetermined {
            what: "masses".into(),
            particles: (*g).clone(),
            links: Vec::new(),
            why: "joined to the other moving particles only through fixed particles, by \
                  links of types no other group shares: only stiffness / mass is measured"
                .into(),
        })
        .collect();
    let rest: Vec<usize> = (0..free.len())
        .filter(|&i| free[i] && !named.contains(&i))
        .collect();
    if !rest.is_empty() {
        out.push(Undetermined {
            what: "masses".into(),
            particles: rest,
            links: Vec::new(),
            why: format!(
                "their ratios are measured, but the given total is shared with particles \
                 {named:?}, whose masses are not"
            ),
        });
    }
    out
}

/// The position noise (m) read from the data, and a line saying so: the 6th-difference
/// estimate ([`crate::output_error::start::difference_noise_level`]) when it agrees with the
/// 3rd's (ratio ≥ [`NOISY_ORDER_RATIO`], white noise) and stands above the positions' rounding
/// (10⁴ ε max|x|); 0 otherwise (a smooth motion: the differences are its own).
pub fn estimate_noise_level(traj: &Trajectory) -> (f64, String) {
    use crate::output_error::{observations::Take, start::difference_noise_level};
    let take = Take::complete(traj);
    let (s3, _) = difference_noise_level(&take, 3);
    let (s6, samples) = difference_noise_level(&take, 6);
    let xmax = traj.as_flat().iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let rounding = 1e4 * f64::EPSILON * xmax;
    let size = traj.scale().max(f64::MIN_POSITIVE);
    if s6 >= NOISY_ORDER_RATIO * s3 && s6 > rounding {
        (
            s6,
            format!(
                "the positions look noisy: noise level {s6:.3e} m ({:.1e} of the motion's \
                 size) estimated from {samples} 6th differences (3rd: {s3:.3e} m); smoothed \
                 before differentiating (give --noise-level when it is known)",
                s6 / size
            ),
        )
    } else {
        (
            0.0,
            format!(
                "positions taken as noiseless: their differences are the motion's own (noise \
                 read from 6th differences {s6:.3e} m, from 3rd {s3:.3e} m)"
            ),
        )
    }
}

/// Refuses, before any pair is stored, candidate sets the selection cannot use or hold (issue
/// 17: `--max-range 10` on 6,000 particles of a gas aborted at 3.6 GB). A free particle's
/// equation has `3 + 3·pairs` unknowns and `3·(frames − 2)` rows: with no more rows than
/// unknowns its fit is exact whatever the data, every pair scores as significant and the
/// answer is noise (300 such particles kept all 44,719 candidates, of 44,706 types). Then the
/// factors' memory, which grows as pairs² per particle, against the memory available.
fn check_candidates(
    row_frames: usize,
    noisy: bool,
    (degree, cols): (&[usize], &[usize]),
    free: &[bool],
    radius: f64,
    place: &str,
) -> Result<(), CostError> {
    let rows = 3 * row_frames;
    let worst = (0..degree.len())
        .filter(|&i| free[i])
        .max_by_key(|&i| (cols[i], std::cmp::Reverse(i)));
    if let Some(i) = worst {
        let unknowns = select::columns(cols[i]) - 1;
        if unknowns >= rows {
            return Err(bad(
                place,
                format!(
                    "particle {i} has {} candidate pairs within {radius} m: {unknowns} unknowns in \
                     its equation of motion from {rows} equations ({} frames); give at least {} \
                     frames or a smaller max range",
                    degree[i],
                    row_frames + 2,
                    unknowns / 3 + 3,
                ),
            ));
        }
    }
    let bytes = select::memory_bytes(
        cols,
        free,
        rayon::current_num_threads(),
        3 * row_frames,
        noisy,
    );
    cordis_core::arg::fits_in_memory(
        place,
        bytes,
        &format!(
            "the local systems of {} candidate pairs within {radius} m",
            degree.iter().sum::<usize>() / 2
        ),
    )?;
    Ok(())
}

/// Masses from the ratio of each link's estimates at its two free ends
/// (`β_i = θ/m_i`, `β_j = θ/m_j`, so `m_j/m_i = β_i/β_j`): weighted least squares of
/// `log m_j - log m_i = log ρ` on the link graph (conjugate gradients, Jacobi-preconditioned:
/// linear in the links per iteration), then scaled to the total. Fixed particles get mass 1.
fn masses_from_ratios(
    locals: &[select::Local],
    fits: &[select::Fit],
    kept: &[usize],
    pairs: &[[usize; 2]],
    at: &[Vec<(usize, usize)>],
    free: &[bool],
    total: f64,
) -> Result<(Vec<f64>, Vec<Vec<usize>>), CostError> {
    let n = free.len();
    let edges = ratio_edges(locals, fits, kept, pairs, at);
    // Connected components of the free particles.
    let mut parent: Vec<usize> = (0..n).collect();
    for &(i, j, _, _) in &edges {
        let (a, b) = (find_root(&mut parent, i), find_root(&mut parent, j));
        parent[a] = b;
    }
    let x = log_masses(n, &edges);
    // Each group of particles joined by links is centred on its own (log) mean: between
    // groups the ratios are unknown here (the catalogue refit, whose types are shared, can
    // still find them).
    let mut sum: std::collections::HashMap<usize, (f64, f64)> = Default::default();
    for i in (0..n).filter(|&i| free[i]) {
        let e = sum.entry(find_root(&mut parent, i)).or_default();
        e.0 += x[i];
        e.1 += 1.0;
    }
    let mut m: Vec<f64> = (0..n)
        .map(|i| {
            if free[i] {
                let (s, c) = sum[&find_root(&mut parent, i)];
                (x[i] - s / c).exp()
            } else {
                1.0
            }
        })
        .collect();
    let s: f64 = (0..n).filter(|&i| free[i]).map(|i| m[i]).sum();
    for i in (0..n).filter(|&i| free[i]) {
        m[i] *= total / s;
    }
    if m.iter().any(|v| !v.is_finite()) {
        return Err(bad("masses", "the mass ratios are not finite"));
    }
    let mut by_root: std::collections::BTreeMap<usize, Vec<usize>> = Default::default();
    for i in (0..n).filter(|&i| free[i]) {
        by_root
            .entry(find_root(&mut parent, i))
            .or_default()
            .push(i);
    }
    let mut groups: Vec<Vec<usize>> = by_root.into_values().collect();
    groups.sort();
    Ok((m, groups))
}

/// One edge `(i, j, log ρ, weight)` per kept link both of whose ends were fitted and whose
/// ratio is positive and finite: ρ = m_j/m_i
/// from the two ends' coefficients of the link, weighted by the inverse of its log's variance
/// (weights floored at 1e-8 of the largest).
fn ratio_edges(
    locals: &[select::Local],
    fits: &[select::Fit],
    kept: &[usize],
    pairs: &[[usize; 2]],
    at: &[Vec<(usize, usize)>],
) -> Vec<(usize, usize, f64, f64)> {
    let mut edges = Vec::new();
    for &p in kept {
        if at[p].len() != 2 {
            continue;
        }
        let (li, qi) = at[p][0];
        let (lj, qj) = at[p][1];
        let (bi, bj) = (fits[li].beta[qi], fits[lj].beta[qj]);
        let (ci, cj) = (fits[li].cov[qi], fits[lj].cov[qj]);
        // Weighted by the inverse of the summed variances (diagonal), floored at rounding.
        let mut w = Matrix3::zeros();
        for c in 0..3 {
            let floor = (1e-13 * bi[c].abs().max(bj[c].abs())).powi(2).max(1e-300);
            w[(c, c)] = 1.0 / (ci[(c, c)] + cj[(c, c)]).max(floor);
        }
        let den = (bj.transpose() * w * bj)[0];
        let rho = (bj.transpose() * w * bi)[0] / den;
        if !(rho > 0.0 && rho.is_finite()) {
            continue;
        }
        let var_log = 1.0 / (den * rho * rho);
        let (i, j) = (locals[li].particle, locals[lj].particle);
        debug_assert!(pairs[p].contains(&i) && pairs[p].contains(&j));
        edges.push((i, j, rho.ln(), 1.0 / var_log.max(1e-300)));
    }
    // Weights spanning more than 1e8 only slow the solve: on consistent data any weights give
    // the same answer, on noisy data the weakest edges barely matter.
    let wmax = edges.iter().map(|e| e.3).fold(0.0, f64::max);
    for e in &mut edges {
        e.3 = e.3.max(1e-8 * wmax);
    }
    edges
}

/// The root of `x`'s component (union–find with path halving).
fn find_root(parent: &mut [usize], mut x: usize) -> usize {
    while parent[x] != x {
        parent[x] = parent[parent[x]];
        x = parent[x];
    }
    x
}

/// The log masses `x` of the `n` particles that best fit the edges' log ratios,
/// `x_j − x_i ≈ r` weighted: the graph Laplacian `L x = Bᵀ W r`, by Jacobi-preconditioned CG
/// (each component's level is arbitrary: the caller centres it).
fn log_masses(n: usize, edges: &[(usize, usize, f64, f64)]) -> Vec<f64> {
    let mut diag = vec![0.0; n];
    let mut rhs = vec![0.0; n];
    for &(i, j, r, w) in edges {
        diag[i] += w;
        diag[j] += w;
        rhs[j] += w * r;
        rhs[i] -= w * r;
    }
    let apply = |x: &[f64], out: &mut [f64]| {
        out.iter_mut().for_each(|v| *v = 0.0);
        for &(i, j, _, w) in edges {
            let d = w * (x[j] - x[i]);
            out[j] += d;
            out[i] -= d;
        }
    };
    let pre = |r: &[f64], out: &mut [f64]| {
        for k in 0..n {
            out[k] = if diag[k] > 0.0 { r[k] / diag[k] } else { 0.0 };
        }
    };
    let mut x = vec![0.0; n];
    let mut r = rhs.clone();
    let mut z = vec![0.0; n];
    pre(&r, &mut z);
    let mut d = z.clone();
    let mut rz: f64 = r.iter().zip(&z).map(|(a, b)| a * b).sum();
    let r0 = rhs.iter().map(|v| v * v).sum::<f64>().sqrt();
    let mut q = vec![0.0; n];
    for _ in 0..(20 * n + 100) {
        let rn = r.iter().map(|v| v * v).sum::<f64>().sqrt();
        if rn <= 1e-15 * r0 || rn == 0.0 {
            break;
        }
        apply(&d, &mut q);
        let dq: f64 = d.iter().zip(&q).map(|(a, b)| a * b).sum();
        if dq.is_nan() || dq <= 0.0 {
            break;
        }
        let alpha = rz / dq;
        for k in 0..n {
            x[k] += alpha * d[k];
            r[k] -= alpha * q[k];
        }
        pre(&r, &mut z);
        let rz2: f64 = r.iter().zip(&z).map(|(a, b)| a * b).sum();
        let beta = rz2 / rz;
        rz = rz2;
        for k in 0..n {
            d[k] = z[k] + beta * d[k];
        }
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fixed particle seen with noise σ over F frames: its position is the frames' mean,
    /// within 4 σ/√F of the truth per axis, and closer than frame 0 (which a scene used to
    /// take).
    #[test]
    fn a_fixed_particle_sits_at_the_mean_of_its_noisy_frames() {
        let (frames, sigma) = (200, 1e-3);
        let truth = Vec3::new(0.1, -0.2, 0.05);
        let mut draw = crate::rng::stream(7, 0, 0);
        let mut data = Vec::with_capacity(frames * 2 * 3);
        for t in 0..frames {
            // Particle 0 fixed, particle 1 moving (ignored).
            for c in 0..3 {
                data.push(truth[c] + sigma * crate::rng::normal(&mut draw));
            }
            data.extend_from_slice(&[t as f64 * 0.01, 0.0, 0.0]);
        }
        let traj = Trajectory::from_flat(frames, 2, data).expect("finite");
        let x = fixed_position(&traj, 0);
        let bound = 4.0 * sigma / (frames as f64).sqrt();
        for c in 0..3 {
            assert!(
                (x[c] - truth[c]).abs() <= bound,
                "axis {c}: {} vs {}",
                x[c],
                truth[c]
            );
        }
        let (err, err0) = ((x - truth).norm(), (traj.pos(0, 0) - truth).norm());
        assert!(err < err0, "mean off by {err}, frame 0 by {err0}");
        assert!(err0 > 3.0 * err, "mean off by {err}, frame 0 by {err0}");
    }
}
