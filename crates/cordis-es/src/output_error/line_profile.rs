//! Whether a Wald interval holds along the likelihood, and how far it must reach where it
//! does not.
//!
//! # Why
//!
//! The 95 % interval `z ± 1.96 s` of an unknown (internal coordinate z, standard error s from
//! the Gauss–Newton matrix H at the optimum, [`super::uncertainty`]) is where the *quadratic
//! model* of the cost rises by `χ²₁(0.95) σ̂² = 3.84 σ̂²`. Where the data are thin the cost is
//! far from quadratic at that scale, and the interval is wrong with nothing to say so: three
//! observed frames of 150 gave a `converged` fit 781 % off with intervals excluding the truth,
//! and on the 32 × 32 cloth the curvature along its stiffness valley differs by orders of
//! magnitude between the estimate and the truth (BENCHMARKS.md, "The Cramér–Rao bound of the
//! cloth").
//!
//! # The check
//!
//! Along the linear model's profile direction of unknown a,
//!
//! ```text
//! d_a = Cov(q̂) e_a / √Cov_aa        (Cov = σ̂² H⁻¹, every fit variable: unknowns and states)
//! ```
//!
//! which moves `z_a` by one standard error and every other variable (the initial states
//! included) as the quadratic model's best response, that model predicts `C(q̂ + t d_a) − C(q̂)
//! = t² σ̂²`. The cost is evaluated at the interval's edges `t = ±1.96` (one rollout each); its
//! *rise* is the measured increase over the predicted one. Any point with `z_a` at a value
//! costs at least the profile cost there (the minimum over the other variables), so a rise
//! below 1 proves the profile-likelihood interval (the set where the profile cost stays
//! within 3.84 σ̂²) reaches past the Wald edge on that side.
//!
//! # The widening
//!
//! Where the rise at an edge is below 0.7 ([`WIDEN_BELOW`]) the side is extended to the
//! last point whose cost stays within `3.84 σ̂²` ([`reach`]: secant steps on the signed root,
//! then regula falsi; to [`ROOT_TOL`] of the root, the box capping it): inside the
//! profile-likelihood interval, so never wider than the likelihood ratio allows, and unchanged
//! where the quadratic model holds. The standard errors stay the Gauss–Newton ones; the report
//! names each widened interval with its Wald interval and rises.
//!
//! # Two measures
//!
//! [`Measure::Line`] (the default, `--intervals wald`) reads the cost on the line `q̂ + t d_a`:
//! one rollout a point, an upper bound on the profile, so a widening it finds is due, but it
//! misses most (the states' best response is not linear). [`Measure::Profile`]
//! (`--intervals profile`) refits every other variable at each point: the profile itself, at
//! several times the fit's cost. Squared loss only: a robust loss's intervals are the
//! M-estimate's sandwich ([`super::loss::m_estimate_spread`]), whose cost is not a
//! likelihood. Noiseless fits (σ̂ at the positions' rounding) are not checked: a cost
//! difference there is rounding noise.

use super::fit::{self, Counts, Fitter, LmSettings};
use super::tangent::Sens;

/// A 95 % Wald interval's half-width in standard errors (the reported intervals',
/// [`super::summary::interval95`], so the check measures at their edges): also the signed root
/// `√(ΔC/σ̂²)` an edge is searched at.
pub(crate) const WALD: f64 = 1.96;
/// The cost rise (in σ̂²) at a 95 % interval's edge, `1.96²` (`χ²₁(0.95)` = 3.8415).
pub(crate) const LEVEL: f64 = WALD * WALD;
/// The rise at a Wald edge below which that side is widened: there the Wald edge reaches no
/// further than the cost's 90 % level (`0.7 · 3.84 σ̂² = 2.69 σ̂² = χ²₁(0.90) σ̂²`), so the
/// interval would cover less than the 90 % the issue's coverage bracket starts at. Above it
/// the two intervals differ by less than their own sampling noise (the soft block's rises are
/// 0.98–1.02), and the Wald interval, the standard error's, is kept.
const WIDEN_BELOW: f64 = 0.7;
/// How close to [`WALD`] the signed root at a widened edge must come (0.05: the cost within
/// 0.2 σ̂² of its level).
const ROOT_TOL: f64 = 0.05;
/// Evaluations of the search for one widened edge (each a profile fit on the dense path).
const MAX_EVALUATIONS: usize = 10;

/// Which 95 % intervals the output-error fit reports (`--intervals`, Python `intervals=`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[non_exhaustive]
pub enum Intervals {
    /// Wald intervals from the standard errors, checked along each unknown's profile direction
    /// (one rollout per edge) and widened where the cost there rises slower than its
    /// quadratic model.
    #[default]
    Wald,
    /// Wald intervals widened to the profile likelihood's where it rises slower than its
    /// quadratic model: every other variable refitted at each edge (two
    /// refits or more per unknown, several times the fit's own time on small scenes). The
    /// large scenes' matrix-free path checks along the line only.
    Profile,
}

impl Intervals {
    pub fn as_str(self) -> &'static str {
        match self {
            Intervals::Wald => "wald",
            Intervals::Profile => "profile",
        }
    }
}

impl std::str::FromStr for Intervals {
    type Err = crate::error::CostError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "wald" => Ok(Intervals::Wald),
            "profile" => Ok(Intervals::Profile),
            other => Err(crate::error::CostError::unknown_name(
                other,
                format!(
                    "`{}` is not one of wald, profile",
                    cordis_core::error::printable(other)
                ),
            )),
        }
    }
}

impl std::fmt::Display for Intervals {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.as_str())
    }
}

/// How [`widen`] measures the cost at a point of an unknown's interval.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Measure {
    /// The cost on the linear model's profile direction (one rollout a point): an upper bound
    /// on the profile, so a widening it finds is always due, but it can miss one (the large
    /// scenes' matrix-free path, where a profile fit costs a fit).
    Line,
    /// The profile itself: every other variable refitted with the unknown held (a
    /// Levenberg–Marquardt fit from the line's point, of these settings' face steps).
    Profile { face_steps: bool },
}

/// One unknown's interval where the cost along it rises slower than its quadratic model.
#[derive(Clone, Debug, PartialEq)]
pub struct Widened {
    /// The unknown's index.
    pub unknown: usize,
    /// Its Wald interval (physical units, cut at the box) before widening.
    pub wald: (f64, f64),
    /// The cost rise at the lower and upper Wald edges over the quadratic model's (1 where
    /// the model holds; NaN where that side was not checked: the box cuts it).
    pub rise: [f64; 2],
}

/// What [`widen`] measured of one unknown.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Check {
    /// The rise at the lower and upper Wald edges ([`Widened::rise`]).
    pub rise: [f64; 2],
    /// Where a side was widened, its new edge (internal coordinate).
    pub edge: [Option<f64>; 2],
}

/// What [`widen`] measured: per unknown (`None`: not checked), and the rollouts spent.
pub(crate) struct Profiled {
    pub checks: Vec<Option<Check>>,
    pub rollouts: usize,
    /// The profile refits were stopped (`halt()`): some unknowns were checked along the line.
    pub stopped: bool,
}

/// The estimate the intervals are checked at: the fit's variables `q`, their cost over
/// `window` frames and the noise `sigma2` (σ̂², m²).
pub(crate) struct Optimum<'a> {
    pub q: &'a [f64],
    pub cost: f64,
    pub sigma2: f64,
    pub window: usize,
}

/// Whether σ̂ is at the rounding of the positions, where a cost difference is rounding noise:
/// a rise is read to 1 % only when `σ̂² ≥ 100 · 2 m r σ̂` (`2 Σ|e| r ≈ 2 m σ̂ r` the cost's
/// rounding at per-coordinate rounding `r`, [`Fitter::rounding_floor`]) — noiseless data
/// fitted exactly, where the check would read noise.
fn at_rounding(fitter: &Fitter<'_>, window: usize, sigma2: f64) -> bool {
    let m = fitter.observed_in(window).max(1) as f64;
    let r = (fitter.rounding_floor(window) / m).sqrt();
    sigma2.sqrt() < 200.0 * m * r
}

/// The intervals' check of both paths: with `check` (`None`: a robust loss, its intervals the
/// M-estimate's, unchecked), [`widen`] at `at`, its rollouts counted in `counts` and its
/// widenings applied to `intervals` (physical, one per unknown). Returns the widened ones and
/// which intervals these are (`Estimate::interval_kind`).
#[allow(clippy::too_many_arguments)]
pub(crate) fn check_intervals(
    fitter: &Fitter<'_>,
    at: &Optimum<'_>,
    check: Option<Measure>,
    direction: impl Fn(usize) -> Option<Vec<f64>>,
    halt: &dyn Fn() -> bool,
    intervals: &mut [(f64, f64)],
    counts: &mut Counts,
) -> (Vec<Widened>, String) {
    let Some(measure) = check else {
        return (Vec::new(), "m-estimate".into());
    };
    let profiled = widen(fitter, at, measure, direction, halt);
    counts.evaluations += profiled.rollouts;
    let kind = match (measure, profiled.stopped) {
        (Measure::Profile { .. }, false) => "profile",
        (Measure::Profile { .. }, true) => "profile (stopped: the rest checked along the line)",
        (Measure::Line, _) => "wald",
    };
    (profiled.apply(fitter.unknowns, intervals), kind.into())
}

impl Profiled {
    /// Replaces the widened sides of `intervals` (physical, one per unknown) and names them.
    fn apply(
        &self,
        unknowns: &[crate::space::Unknown],
        intervals: &mut [(f64, f64)],
    ) -> Vec<Widened> {
        let mut widened = Vec::new();
        for (a, check) in self.checks.iter().enumerate() {
            let Some(check) = check else { continue };
            if check.edge.iter().all(Option::is_none) {
                continue;
            }
            let wald = intervals[a];
            let u = &unknowns[a];
            if let Some(z) = check.edge[0] {
                intervals[a].0 = u.from_internal(z).min(wald.0);
            }
            if let Some(z) = check.edge[1] {
                intervals[a].1 = u.from_internal(z).max(wald.1);
            }
            widened.push(Widened {
                unknown: a,
                wald,
                rise: check.rise,
            });
        }
        widened
    }
}

/// The cost along one side of one unknown's interval, `t` standard errors from the estimate.
struct Side<'a, 'f> {
    fitter: &'a Fitter<'f>,
    at: &'a Optimum<'a>,
    /// The profile direction, one standard error long, signed by the side.
    step: Vec<f64>,
    unknown: usize,
    measure: Measure,
    counts: Counts,
    /// The last profile fit's `t` and optimum: the next one starts from it.
    last: Option<(f64, Vec<f64>)>,
    buf: Sens,
    halt: &'a dyn Fn() -> bool,
}

impl Side<'_, '_> {
    /// `(C − C(q̂)) / σ̂²` at `t` (+inf: diverges).
    fn rise(&mut self, t: f64) -> f64 {
        let mut point: Vec<f64> = match &self.last {
            Some((t0, q0)) => q0
                .iter()
                .zip(&self.step)
                .map(|(q, d)| q + (t - t0) * d)
                .collect(),
            None => self
                .at
                .q
                .iter()
                .zip(&self.step)
                .map(|(q, d)| q + t * d)
                .collect(),
        };
        // The held coordinate exactly on the line, whatever the warm start carried.
        point[self.unknown] = self.at.q[self.unknown] + t * self.step[self.unknown];
        self.fitter.project(&mut point);
        let cost = match self.measure {
            Measure::Line => {
                self.counts.evaluations += 1;
                self.fitter.cost(&point, self.at.window, &mut self.buf)
            }
            Measure::Profile { face_steps } => {
                let cost = self.profile(&mut point, face_steps);
                // A diverged refit's point is no start for the next one.
                if cost.is_finite() {
                    self.last = Some((t, point));
                }
                cost
            }
        };
        match cost.is_finite() {
            true => (cost - self.at.cost) / self.at.sigma2,
            false => f64::INFINITY,
        }
    }

    /// Refits every variable but the unknown at `point` (changed in place) and returns the
    /// cost there: the unknown's box is shrunk to its value, so the fit holds it.
    fn profile(&mut self, point: &mut [f64], face_steps: bool) -> f64 {
        let mut unknowns = self.fitter.unknowns.to_vec();
        let held = &mut unknowns[self.unknown];
        let value = held.from_internal(point[self.unknown]);
        (held.min, held.max) = (value, value);
        point[self.unknown] = held.to_internal(value);
        let fitter = Fitter {
            unknowns: &unknowns,
            cols: self.fitter.cols.clone(),
            ..*self.fitter
        };
        // To a tenth of σ̂² of the cost: the rise is read to that.
        let settings = LmSettings {
            max_iterations: 30,
            ftol: 0.1 * self.at.sigma2 / self.at.cost,
            xtol: 1e-12,
            gtol: 0.0,
            face_steps,
        };
        // A refit told to stop keeps its best point so far: its cost still bounds the
        // profile's from above.
        let end = fit::lm_stage(
            &fitter,
            point,
            self.at.window,
            settings,
            &mut self.counts,
            &mut self.buf,
            self.halt,
        );
        match end {
            fit::StageEnd::Diverged => f64::INFINITY,
            _ => {
                self.counts.evaluations += 1;
                fitter.cost(point, self.at.window, &mut self.buf)
            }
        }
    }
}

/// The farthest `t ≤ limit` whose signed root `√rise(t)` stays within [`WALD`], given it is
/// `root` < WALD at `t = WALD`: secant steps on the root (nearly linear in `t` where the
/// profile is a distorted quadratic, Bates and Watts 1988 §6.1), then the Illinois variant of
/// regula falsi once a point past the level brackets it, bisection where that point's cost is
/// not finite (a diverging rollout). Ends within [`ROOT_TOL`] of the level (on either side:
/// a point just past it is as good an edge), at `limit` (the box), or after
/// [`MAX_EVALUATIONS`] with the farthest point known within the level.
fn reach(mut rise: impl FnMut(f64) -> f64, root: f64, limit: f64) -> f64 {
    let mut inside = (WALD, root);
    let mut before = (0.0, 0.0);
    let mut outside: Option<(f64, f64)> = None;
    // Illinois: the retained end's excess is halved each time the same end is kept again.
    let mut kept_outside = false;
    for _ in 0..MAX_EVALUATIONS {
        let t = match outside {
            Some((to, ro)) if ro.is_finite() => {
                inside.0 + (WALD - inside.1) * (to - inside.0) / (ro - inside.1)
            }
            Some((to, _)) => 0.5 * (inside.0 + to),
            None => {
                let slope = (inside.1 - before.1) / (inside.0 - before.0);
                let t = match slope > 0.0 {
                    true => inside.0 + (WALD - inside.1) / slope,
                    false => 2.0 * inside.0,
                };
                t.clamp(1.25 * inside.0, 4.0 * inside.0).min(limit)
            }
        };
        let r = rise(t).max(0.0).sqrt();
        if r <= WALD {
            before = inside;
            inside = (t, r);
            if t >= limit || WALD - r <= ROOT_TOL {
                return t;
            }
            if let (true, Some((to, ro))) = (kept_outside, outside) {
                outside = Some((to, WALD + 0.5 * (ro - WALD)));
            }
            kept_outside = true;
        } else {
            if r - WALD <= ROOT_TOL {
                return t;
            }
            outside = Some((t, r));
            kept_outside = false;
        }
    }
    inside.0
}

/// Checks and widens each unknown's interval at the estimate `at`: `direction(a)` is the
/// full column `Cov(q̂) e_a` of the fit's variables (`None` where the standard error is not
/// finite: undetermined or not computed). Once `halt()` (Ctrl-C, a time limit) the profile
/// refits stop at their best point so far and the unknowns not yet checked are checked along
/// the line ([`Profiled::stopped`]).
fn widen(
    fitter: &Fitter<'_>,
    at: &Optimum<'_>,
    mut measure: Measure,
    direction: impl Fn(usize) -> Option<Vec<f64>>,
    halt: &dyn Fn() -> bool,
) -> Profiled {
    let mut out = Profiled {
        checks: vec![None; fitter.theta()],
        rollouts: 0,
        stopped: false,
    };
    let (q, sigma2) = (at.q, at.sigma2);
    if !(at.cost.is_finite() && sigma2 > 0.0) || at_rounding(fitter, at.window, sigma2) {
        return out;
    }
    for (a, u) in fitter.unknowns.iter().enumerate() {
        if matches!(measure, Measure::Profile { .. }) && halt() {
            measure = Measure::Line;
            out.stopped = true;
        }
        let Some(column) = direction(a) else { continue };
        let variance = column[a];
        if !(variance > 0.0 && variance.is_finite()) {
            continue;
        }
        let se = variance.sqrt();
        let (lo, hi) = u.internal_bounds();
        let mut check = Check {
            rise: [f64::NAN; 2],
            edge: [None; 2],
        };
        for (k, sign) in [-1.0, 1.0].into_iter().enumerate() {
            // The box's edge in standard errors on this side: a Wald edge past it is cut there.
            let limit = match sign > 0.0 {
                true => (hi - q[a]) / se,
                false => (q[a] - lo) / se,
            };
            if limit <= WALD {
                continue;
            }
            let mut side = Side {
                fitter,
                at,
                step: column.iter().map(|c| sign * c / se).collect(),
                unknown: a,
                measure,
                counts: Counts::default(),
                last: None,
                buf: Sens::default(),
                halt,
            };
            let rise = side.rise(WALD);
            check.rise[k] = rise / LEVEL;
            if check.rise[k] < WIDEN_BELOW {
                let t = reach(|t| side.rise(t), rise.max(0.0).sqrt(), limit);
                check.edge[k] = (t > WALD).then_some(q[a] + sign * t * se);
            }
            out.rollouts += side.counts.evaluations;
        }
        out.checks[a] = Some(check);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::identify::add_noise;
    use crate::output_error::{estimate, Config, Estimate, Take};
    use crate::space::ParameterSpace;
    use cordis_core::{Bounds, Param, Scene};

    /// The edge search on known signed roots: a linear root `c t` (a quadratic cost `c² t²`)
    /// ends where `c t` = 1.96 to the tolerance; a root that diverges (+inf) past a point is
    /// bisected to it, not re-evaluated at the same point; a flat root ends at the box, and so
    /// does a falling one (an estimate that is not the optimum).
    #[test]
    fn the_edge_search_finds_the_level_through_divergence_and_the_box() {
        for c in [0.3, 0.5, 0.8] {
            let t = reach(|t: f64| (c * t).powi(2), c * WALD, 1e3);
            assert!((c * t - WALD).abs() <= ROOT_TOL, "c {c}: t {t}");
        }
        // Quadratic up to t = 3, then the rollout diverges: the edge is found just below 3.
        let mut calls = Vec::new();
        let t = reach(
            |t| {
                calls.push(t);
                match t < 3.0 {
                    true => (0.2 * t).powi(2),
                    false => f64::INFINITY,
                }
            },
            0.2 * WALD,
            1e3,
        );
        assert!(t < 3.0 && t > 2.9, "{t} from {calls:?}");
        assert!(
            calls.windows(2).all(|w| w[0] != w[1]),
            "a point evaluated twice in a row: {calls:?}"
        );
        assert_eq!(reach(|_| 0.0, 0.0, 40.0), 40.0);
        assert_eq!(reach(|t| -t, 0.0, 40.0), 40.0);
    }

    /// Guards Ctrl-C during the profile refits: a finish told to stop checks every unknown
    /// along the line instead (the default's intervals, to the bit), and says so.
    #[test]
    fn a_stop_during_the_profile_refits_falls_back_to_the_line() {
        use crate::output_error::{Prepared, Step};
        let (scene, takes) = swing(30, 0.1, 0);
        let space = ParameterSpace::from_scene(&scene);
        let config = Config {
            intervals: Intervals::Profile,
            ..Config::default()
        };
        let prepared = Prepared::new(&scene, &space, takes.clone(), &config).unwrap();
        let mut progress = prepared.start(&scene, &space, &config).unwrap();
        while prepared.stage(&space, &mut progress, &|| false).unwrap() != Step::Done {}
        let stopped = prepared
            .finish(&scene, &space, &progress, &|| true)
            .unwrap();
        let line = fit(&scene, &takes, Intervals::Wald);
        let profile = fit(&scene, &takes, Intervals::Profile);
        assert!(
            stopped.interval_kind.starts_with("profile (stopped"),
            "{}",
            stopped.interval_kind
        );
        assert_eq!(stopped.intervals, line.intervals);
        assert_ne!(
            profile.intervals, line.intervals,
            "the profile widens this take"
        );
    }

    /// One 1 kg particle swinging round an anchor (stiffness 10 N/m, rest length 0.8 m: clear
    /// of the anchor's point), observed for `frames` frames with noise `sigma` (m), and the
    /// scene with its stiffness unknown in [1, 100].
    fn swing(frames: usize, sigma: f64, seed: u64) -> (Scene, Vec<Take>) {
        let mut scene = crate::output_error::tests::anchored_particle();
        scene.types[0].params[1] = Param::Known(0.8);
        scene.particles[0].vel = [0.0, 0.4, 0.1];
        let traj = scene.simulate(frames).unwrap();
        scene.types[0].params[0] = Param::Unknown(Bounds {
            min: 1.0,
            max: 100.0,
            init: None,
        });
        (scene, vec![Take::complete(&add_noise(&traj, sigma, seed))])
    }

    fn fit(scene: &Scene, takes: &[Take], intervals: Intervals) -> Estimate {
        let space = ParameterSpace::from_scene(scene);
        let config = Config {
            intervals,
            ..Config::default()
        };
        estimate(scene, &space, takes, &config).unwrap()
    }

    /// The cost's minimum with the stiffness held at `k` (the initial state refitted), over
    /// the estimate's σ̂²: the profile's rise there.
    fn profile_rise(scene: &Scene, takes: &[Take], e: &Estimate, k: f64) -> f64 {
        let mut held = scene.clone();
        held.types[0].params[0] = Param::Known(k);
        // One unknown is needed: the known rest length in a box of its own value's width.
        held.types[0].params[1] = Param::Unknown(Bounds {
            min: 0.8 - 1e-9,
            max: 0.8 + 1e-9,
            init: None,
        });
        let h = fit(&held, takes, Intervals::Wald);
        (h.cost - e.cost) / (e.sigma * e.sigma)
    }

    /// Where the data determine the unknown well (200 frames, 1 mm), its cost is quadratic at
    /// the interval's scale: both kinds of intervals are the Wald interval, nothing widened.
    #[test]
    fn a_well_determined_unknown_keeps_its_wald_interval() {
        for seed in 0..3 {
            let (scene, takes) = swing(200, 1e-3, seed);
            let wald = fit(&scene, &takes, Intervals::Wald);
            let profile = fit(&scene, &takes, Intervals::Profile);
            assert!(
                wald.widened.is_empty() && profile.widened.is_empty(),
                "seed {seed}"
            );
            assert_eq!(wald.intervals, profile.intervals, "seed {seed}");
            assert_eq!(
                [wald.interval_kind, profile.interval_kind],
                ["wald", "profile"]
            );
        }
    }

    /// Guards the profile widening on thin data (30 frames of a 2 s swing at 10 cm noise),
    /// where the Wald interval of seed 0, [18, 100] N/m, misses the true 10 N/m: the profile
    /// likelihood is far flatter below the estimate than its quadratic model. The widened
    /// edge reaches past the Wald edge and stays inside the profile's 95 % region (its
    /// refitted cost within 3.84 σ̂², to the search's tolerance); every interval holds the
    /// truth.
    #[test]
    fn a_thin_take_widens_to_the_profile_likelihoods_interval() {
        let mut widened = 0;
        for seed in 0..4 {
            let (scene, takes) = swing(30, 0.1, seed);
            let e = fit(&scene, &takes, Intervals::Profile);
            assert!(
                (e.intervals[0].0..=e.intervals[0].1).contains(&10.0),
                "seed {seed}"
            );
            let Some(w) = e.widened.first() else { continue };
            widened += 1;
            // The widened lower edge: within the profile's 95 % region (its refitted cost at
            // most the level, to the search's tolerance), and at the level unless the box
            // cut it.
            let (lo, hi) = e.intervals[0];
            assert!(
                lo < w.wald.0,
                "seed {seed}: {:?} from {:?}",
                e.intervals,
                w.wald
            );
            let rise = profile_rise(&scene, &takes, &e, lo);
            assert!(rise <= LEVEL + 0.5, "seed {seed}: {rise} σ̂² at {lo}");
            if lo > 1.0 {
                assert!(rise >= LEVEL - 0.5, "seed {seed}: {rise} σ̂² at {lo}");
            }
            assert!((lo..=hi).contains(&10.0), "seed {seed}: {:?}", e.intervals);
        }
        // Seeds 1 and 2 end on the box's lower edge 1 N/m: their interval is the box already.
        assert!(widened >= 2, "{widened} of 4 thin takes widened");
        // Seed 0's Wald interval misses the truth; its profile's rise at the truth is inside.
        let (scene, takes) = swing(30, 0.1, 0);
        let wald = fit(&scene, &takes, Intervals::Wald);
        assert!(wald.intervals[0].0 > 10.0, "{:?}", wald.intervals);
        assert!(profile_rise(&scene, &takes, &wald, 10.0) < LEVEL);
    }
}
