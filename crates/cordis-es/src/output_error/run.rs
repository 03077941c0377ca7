//! One output-error fit as steps a run loop can stop between: [`Prepared`] holds what the fit
//! reads (the sensitivity recursion, the takes) and is rebuilt from the problem on resume;
//! [`Progress`] holds where the fit stands and is what a checkpoint saves.
//!
//! One step is one window's Levenberg–Marquardt stage ([`super::windows`]). A stage told to
//! stop (`halt()`, asked before every iteration: Ctrl-C, a time limit) keeps its best point so
//! far in [`Progress::best`] while `Progress` itself stays at the stage's start: resuming
//! from a checkpoint reruns that stage from the same point and so takes exactly the steps an
//! uninterrupted fit takes.

use cordis_core::Scene;
use serde::{Deserialize, Serialize};

use super::checks::{check_memory, check_takes};
use super::config::{check_config, Config};
use super::fit::{self, Counts, Fitter, LmSettings, StageEnd};
use super::line_profile::Measure;
use super::loss::{self, Loss};
use super::matrix_free::{self, CgCounts};
use super::observations::Take;
use super::shooting;
use super::start;
use super::summary::{self, Estimate};
use super::tangent::{Columns, Sens, Tangent};
use super::windows::{After, Schedule};
use crate::error::CostError;
use crate::space::{ParameterSpace, Role};
use crate::strategy::bits;

/// Restarts from other starts after a fit got stuck in a wrong basin (a window whose
/// residuals stay above the noise level after the smallest step back). Measured on generated
/// networks with a quarter of the particles hidden at σ = 1e-3: 2 of 20 fits get stuck from
/// the heuristic start, and 2 of 5 random restarts reach the noise level.
const MAX_RESTARTS: usize = 6;

/// Segments of multiple shooting, in first windows: each as long as the second window of the
/// growing schedule.
const SEGMENT_WINDOWS: usize = 2;

/// Relative residual difference under which two stuck attempts count as one optimum (see
/// [`Prepared::unstick`]): a wrong basin from another random start lands elsewhere.
const SAME_OPTIMUM: f64 = 0.01;

/// What a fit reads and never changes.
pub struct Prepared {
    scene: Scene,
    tangent: Tangent,
    takes: Vec<Take>,
    cols: Columns,
    /// Above [`Config::dense_max_columns`] the dense normal equations cost more than the
    /// whole matrix-free fit.
    large: bool,
    /// Noise level of each take read from its third differences, m, of a weight-1 coordinate.
    noise_level: Vec<f64>,
    /// How many third differences each take's noise level was read from.
    noise_samples: Vec<usize>,
    set: LmSettings,
    first_window: usize,
    loss: Loss,
    intervals: super::Intervals,
}

/// Where a fit stands between two stages.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Progress {
    /// The fit's variables at the start of the next stage: the unknowns' internal
    /// coordinates, then `[x0, v0]` per free particle and take.
    #[serde(with = "bits")]
    q: Vec<f64>,
    schedule: Schedule,
    counts: Counts,
    cg: CgCounts,
    /// Where the fit started (short-cost solve or heuristic, and why).
    start: String,
    /// The best point of a stage stopped before it ended.
    partial: Option<Partial>,
    /// How the last window's stage ended, once the whole take is fitted.
    last_end: Option<StageEnd>,
    /// Restarts so far, each from [`start::restart_genome`].
    restarts: usize,
    /// The initial states the fit started from (restarts start from them too).
    #[serde(with = "bits")]
    states0: Vec<f64>,
    /// The genome the fit started from: the first restart shoots from it
    /// ([`Prepared::shoot`]). Empty in checkpoints from before multiple shooting.
    #[serde(with = "bits", default)]
    genome0: Vec<f64>,
    /// Whether multiple shooting from the start was tried (at the first stuck window, before
    /// the seeded restarts), whether the seeded restart now running has shot (each shoots
    /// once, from its own seeded point, at its first stuck window), and whether the attempt
    /// now running is a shooting's single-shooting finish.
    #[serde(default)]
    shot: bool,
    #[serde(default)]
    attempt_shot: bool,
    #[serde(default)]
    shooting: bool,
    /// The first stuck attempt's initial states: the first seeded restart redraws about them.
    #[serde(with = "bits", default)]
    first_stuck: Vec<f64>,
    /// Of the attempts stuck so far, the one with the smallest residuals: what the fit goes on
    /// from when no restart is left.
    best_stuck: Option<Box<Stuck>>,
    /// The robust loss's weight multipliers per take (the take's layout; empty: all 1).
    #[serde(with = "nested_bits")]
    robust: Vec<Vec<f64>>,
    /// Reweighting rounds of the current window.
    reweights: usize,
    /// The last accepted steps of the last stage of a matrix-free fit: they deflate its
    /// standard-error solves ([`matrix_free::standard_errors::theta_inverse`]). Empty on the
    /// dense path and in checkpoints from before.
    #[serde(with = "nested_bits", default)]
    last_steps: Vec<Vec<f64>>,
}

/// Exact f64 vectors of vectors in JSON (IEEE bits).
mod nested_bits {
    use serde::{Deserialize, Deserializer, Serialize, Serializer};

    pub fn serialize<S: Serializer>(v: &[Vec<f64>], s: S) -> Result<S::Ok, S::Error> {
        v.iter()
            .map(|r| r.iter().map(|x| x.to_bits()).collect::<Vec<u64>>())
            .collect::<Vec<_>>()
            .serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<Vec<f64>>, D::Error> {
        Ok(Vec::<Vec<u64>>::deserialize(d)?
            .into_iter()
            .map(|r| r.into_iter().map(f64::from_bits).collect())
            .collect())
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct Stuck {
    #[serde(with = "bits")]
    q: Vec<f64>,
    schedule: Schedule,
}

impl Stuck {
    /// The stuck attempt whose estimate fits the whole takes better, by `whole` (their
    /// residual scale over every frame; `self` on a tie or when neither is a number). Not by
    /// the residual rms of the window each got stuck at: an attempt stuck at 16 frames fits
    /// those frames closer than one stuck at 200 fits its 200, and the fit goes on from the
    /// winner over the whole takes.
    fn better(self: Box<Self>, other: Box<Stuck>, whole: impl Fn(&[f64]) -> f64) -> Box<Stuck> {
        match whole(&other.q) < whole(&self.q) {
            true => other,
            false => self,
        }
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
struct Partial {
    #[serde(with = "bits")]
    q: Vec<f64>,
    counts: Counts,
}

/// What one [`Prepared::stage`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Step {
    /// A window is fitted; more follow.
    More,
    /// Told to stop within the stage: [`Progress::best`] is the best point so far.
    Stopped,
    /// The whole take is fitted ([`Prepared::finish`] gives the estimate).
    Done,
}

impl Prepared {
    /// Checks the takes, the options and the memory the fit needs.
    pub fn new(
        scene: &Scene,
        space: &ParameterSpace,
        takes: Vec<Take>,
        config: &Config,
    ) -> Result<Self, CostError> {
        let mut tangent = Tangent::new(scene)?;
        check_takes(scene, &tangent, &takes)?;
        tangent.guard_by(&takes);
        check_config(config)?;
        let slots: Vec<usize> = space.unknowns.iter().map(|u| u.slot).collect();
        let cols = tangent.columns(&slots);
        let large = cols.len > config.dense_max_columns;
        if let Some(u) = space.unknowns.iter().find(|u| u.role == Role::Gravity) {
            if large {
                return Err(CostError::mismatch(
                    &u.name,
                    format!(
                        "an unknown gravity has sensitivities on the dense path only ({} fit \
                         variables > {}): give it",
                        cols.len, config.dense_max_columns
                    ),
                ));
            }
        }
        if large {
            matrix_free::check_memory(&tangent, &takes)?;
        } else {
            check_memory(&tangent, &cols, takes.len())?;
        }
        // A given level is exact: no spread from the differences it would be read from.
        let (noise_level, noise_samples) = match config.noise_level {
            Some(s) => (vec![s; takes.len()], vec![usize::MAX; takes.len()]),
            None => takes.iter().map(start::unit_weight_noise_level).unzip(),
        };
        // Kinks in the cost: contacts, pairs appearing and vanishing, Provot's projection.
        let kinked = !tangent.plan.planes.is_empty()
            || !tangent.plan.conditionals.is_empty()
            || !tangent.plan.provot.links.is_empty();
        Ok(Prepared {
            scene: scene.clone(),
            tangent,
            takes,
            cols,
            large,
            noise_level,
            noise_samples,
            set: LmSettings {
                max_iterations: config.max_iterations,
                ftol: config.ftol,
                xtol: config.xtol,
                gtol: config.gtol,
                face_steps: !kinked,
            },
            first_window: config.first_window,
            loss: config.loss,
            intervals: config.intervals,
        })
    }

    fn fitter<'a>(&'a self, space: &'a ParameterSpace) -> Fitter<'a> {
        self.fitter_on(space, &self.takes)
    }

    fn fitter_on<'a>(&'a self, space: &'a ParameterSpace, takes: &'a [Take]) -> Fitter<'a> {
        Fitter {
            tangent: &self.tangent,
            unknowns: &space.unknowns,
            base: &space.base,
            takes,
            cols: self.cols.clone(),
            continuity: None,
        }
    }

    /// The takes the fit weighs now: the observed ones, times the robust loss's multipliers.
    fn weighed(&self, progress: &Progress) -> Vec<Take> {
        match progress.robust.is_empty() {
            true => self.takes.clone(),
            false => self
                .takes
                .iter()
                .zip(&progress.robust)
                .map(|(t, m)| t.reweighted(m))
                .collect(),
        }
    }

    /// IRLS ([`super::loss`]): the multipliers `√ω(r/s)` at `q` over the first `window`
    /// frames (the others kept), and whether one moved by more than 0.01 from `p`'s (then the
    /// window is fitted again); `None` when the residuals give no scale.
    fn multipliers(
        &self,
        space: &ParameterSpace,
        q: &[f64],
        window: usize,
        p: &Progress,
    ) -> Option<(Vec<Vec<f64>>, bool)> {
        let res = self
            .fitter(space)
            .residuals(q, window, &mut Sens::default())?;
        let scale = loss::robust_scale(res.iter().flatten().copied());
        if scale.is_nan() || scale <= 0.0 {
            return None;
        }
        let mut robust = match p.robust.is_empty() {
            true => self
                .takes
                .iter()
                .map(|t| vec![1.0; t.frames() * t.particles() * 3])
                .collect(),
            false => p.robust.clone(),
        };
        let mut moved = false;
        for (mult, r) in robust.iter_mut().zip(&res) {
            for (m, &r) in mult.iter_mut().zip(r) {
                if r.is_finite() {
                    let next = self.loss.weight(r / scale).sqrt();
                    moved |= (next - *m).abs() > 0.01;
                    *m = next;
                }
            }
        }
        Some((robust, moved))
    }

    /// The schedule of a fit from its first window, on the noisiest take's noise level.
    /// The window schedule of attempt `attempt` (0: the first start, k: restart k). Restarts
    /// alternate the first window (×1, ×2, ×4 of the configured one) as well as the start: a
    /// wrong basin is often reached by short windows' parameters wandering where the data do
    /// not hold them yet, and a longer first window avoids that on some draws and falls into
    /// others (measured with a quarter of the particles hidden at σ = 1e-2, 10 draws: a first
    /// window of 64 frames converged on 7, 16 frames on 5, not the same ones; BENCHMARKS.md).
    fn schedule(&self, fitter: &Fitter<'_>, attempt: usize) -> Schedule {
        self.schedule_from(fitter, self.first_window.saturating_mul(1 << (attempt % 3)))
    }

    /// The schedule of a fit whose first window is `first` frames (at most the longest take).
    fn schedule_from(&self, fitter: &Fitter<'_>, first: usize) -> Schedule {
        // The noisiest take whose level could be read (a take too short to read one has
        // 0 samples and level 0: it would switch the basin check off by its order alone).
        let key = |k: usize| (self.noise_samples[k] > 0, self.noise_level[k]);
        let noisiest = (0..self.noise_level.len()).max_by(|&a, &b| {
            let ((ra, la), (rb, lb)) = (key(a), key(b));
            ra.cmp(&rb).then(la.total_cmp(&lb))
        });
        let (noise, samples) =
            noisiest.map_or((0.0, 0), |k| (self.noise_level[k], self.noise_samples[k]));
        let schedule = Schedule::new(fitter, first, noise, samples, self.loss != Loss::Squared);
        match self.large {
            true => schedule,
            false => schedule.restart_on_budget(),
        }
    }

    /// The takes whose noise level could not be read (no third difference of observed
    /// frames); none when the level was given.
    pub fn noise_unread(&self) -> Vec<usize> {
        (0..self.noise_samples.len())
            .filter(|&k| self.noise_samples[k] == 0)
            .collect()
    }

    /// The fit's start: `config.start` (and `config.start_states`) or the short-cost start
    /// ([`start`]) and each take's initial state from its first frames.
    pub fn start(
        &self,
        scene: &Scene,
        space: &ParameterSpace,
        config: &Config,
    ) -> Result<Progress, CostError> {
        let genomes = match &config.start {
            Some(g) if g.len() == space.dim() => vec![(g.clone(), "given start".to_string())],
            Some(g) => return Err(CostError::length("start", space.dim(), g.len())),
            // Each take's starts compete (one take may track what another hides). The
            // smoother reads positions: their own level from the data (the weights are the
            // user's claim, the differences what the tracker did), or a given weight-1 level
            // over the take's typical weight.
            None => {
                let mut genomes = Vec::new();
                for (k, take) in self.takes.iter().enumerate() {
                    let position_noise = match config.noise_level {
                        Some(unit) if take.weighted() => unit / take.rms_weight(),
                        Some(unit) => unit,
                        None => start::noise_level(take),
                    };
                    let starts = start::start_genomes(scene, space, take, position_noise);
                    genomes.extend(starts.into_iter().map(|(g, note)| match self.takes.len() {
                        1 => (g, note),
                        _ => (g, format!("{note}, take {k}")),
                    }));
                }
                genomes
            }
        };
        let fitter = self.fitter(space);
        let mut states = Vec::new();
        for (k, take) in self.takes.iter().enumerate() {
            match config.start_states.as_ref().and_then(|s| s.get(k)) {
                Some(s) if s.len() == fitter.state_len() => states.extend_from_slice(s),
                Some(s) => {
                    return Err(CostError::length(
                        format!("start_states[{k}]"),
                        fitter.state_len(),
                        s.len(),
                    ))
                }
                None => states.extend(start::initial_state(scene, &self.tangent.free, take)),
            }
        }
        let (q, start_note) = self.cheapest_start(&fitter, genomes, &states);
        Ok(Progress {
            states0: q[space.dim()..].to_vec(),
            genome0: q[..space.dim()].to_vec(),
            shot: false,
            attempt_shot: false,
            shooting: false,
            first_stuck: Vec::new(),
            restarts: 0,
            best_stuck: None,
            robust: Vec::new(),
            reweights: 0,
            last_steps: Vec::new(),
            q,
            schedule: self.schedule(&fitter, 0),
            counts: Counts::default(),
            cg: CgCounts::default(),
            start: start_note,
            partial: None,
            last_end: None,
        })
    }

    /// Of several starting genomes (each followed by `states`, projected into the boxes), the
    /// one whose first window costs least, its note saying what it was chosen over; the first
    /// when every one diverges there (a fit and its restarts then take it from there).
    fn cheapest_start(
        &self,
        fitter: &Fitter<'_>,
        genomes: Vec<(Vec<f64>, String)>,
        states: &[f64],
    ) -> (Vec<f64>, String) {
        let mut starts: Vec<(Vec<f64>, String)> = genomes
            .into_iter()
            .map(|(mut q, note)| {
                q.extend_from_slice(states);
                fitter.project(&mut q);
                (q, note)
            })
            .collect();
        if starts.len() == 1 {
            return starts.pop().expect("one start");
        }
        // One rollout per take and start; the first of equal costs (every one diverging) wins.
        let longest = self.takes.iter().map(Take::frames).max().unwrap_or(0);
        let frames = self.first_window.min(longest);
        let buf = &mut Sens::default();
        let costs: Vec<f64> = starts
            .iter()
            .map(|(q, _)| fitter.cost(q, frames, buf))
            .collect();
        let best = (0..starts.len())
            .min_by(|&a, &b| costs[a].total_cmp(&costs[b]))
            .expect("start_genomes gives one start or more");
        let others: Vec<String> = (0..starts.len())
            .filter(|&k| k != best)
            .map(|k| format!("“{}” (cost {:.3e})", starts[k].1, costs[k]))
            .collect();
        let (q, note) = starts.swap_remove(best);
        let note = format!(
            "{note}; its first {frames} frames cost {:.3e}, chosen over {}",
            costs[best],
            others.join(" and ")
        );
        (q, note)
    }

    /// Fits the next window (or reruns a stopped one) from where `progress` stands.
    pub fn stage(
        &self,
        space: &ParameterSpace,
        progress: &mut Progress,
        halt: &dyn Fn() -> bool,
    ) -> Result<Step, CostError> {
        // What a stop inside the shooting attempt goes back to: the stage is rerun on resume.
        let at_start = progress.clone();
        let takes = self.weighed(progress);
        let fitter = self.fitter_on(space, &takes);
        let w = progress.schedule.next;
        let mut q = progress.q.clone();
        let mut counts = progress.counts;
        let mut cg = progress.cg;
        let mut steps = Vec::new();
        let end = if self.large {
            let longest = progress.schedule.longest();
            matrix_free::stage(
                &fitter,
                &mut q,
                w,
                longest,
                self.set,
                &mut counts,
                &mut cg,
                &mut steps,
                halt,
            )
        } else {
            let buf = &mut Sens::default();
            fit::lm_stage(&fitter, &mut q, w, self.set, &mut counts, buf, halt)
        };
        if end == StageEnd::Interrupted {
            progress.partial = Some(Partial { q, counts });
            return Ok(Step::Stopped);
        }
        progress.partial = None;
        progress.counts = counts;
        progress.cg = cg;
        progress.last_steps = steps;
        // Intermediate windows only steer the growth: a few rounds; the last one to the fixed
        // point.
        let rounds = match w >= progress.schedule.longest() {
            true => loss::MAX_REWEIGHTS,
            false => loss::WINDOW_REWEIGHTS,
        };
        let mut end = end;
        if self.loss != Loss::Squared && end != StageEnd::Diverged {
            if let Some((robust, moved)) = self.multipliers(space, &q, w, progress) {
                if progress.reweights < rounds {
                    progress.robust = robust;
                    if moved {
                        // The same window again on the new weights.
                        progress.reweights += 1;
                        progress.q = q;
                        return Ok(Step::More);
                    }
                } else if moved && w >= progress.schedule.longest() && end == StageEnd::Converged {
                    // The weights had not settled when the rounds ran out: the robust fit's
                    // own criterion did not hold.
                    end = StageEnd::Budget;
                }
            }
        }
        progress.reweights = 0;
        let mut after = progress
            .schedule
            .after(&fitter, &mut q, end, &mut Sens::default())?;
        // The shooting attempt fits the whole take at once: above the noise there, it is stuck
        // as a window that cannot be grown into is.
        let shot_above =
            progress.shooting && matches!(after, After::Done(_)) && progress.schedule.above_noise();
        if after == After::Stuck || shot_above {
            let stuck = q.clone();
            match self.unstick(space, progress, &mut q, halt)? {
                Some(next) => after = next,
                None => {
                    let counts = progress.counts;
                    *progress = at_start;
                    progress.partial = Some(Partial { q: stuck, counts });
                    return Ok(Step::Stopped);
                }
            }
        }
        progress.q = q;
        Ok(match after {
            After::Stage | After::Stuck => Step::More,
            After::Done(end) => {
                progress.last_end = Some(end);
                Step::Done
            }
        })
    }

    /// A stuck fit (a wrong basin) restarts from [`start::restart_genome`] and, for what the
    /// takes do not see, [`start::restart_states`] while restarts are left and the restarts
    /// do not repeat one optimum; then it goes on from the stuck attempt with the smallest
    /// residuals, settled (no more stepping back). Each attempt, the first start and every
    /// seeded restart, first shoots once from the θ it started from ([`Prepared::shoot`]) at
    /// its first stuck window: growing windows and multiple shooting fail on different draws
    /// from one θ (BENCHMARKS.md, "Shooting from every restart"). `None` when told to stop
    /// within a shooting.
    fn unstick(
        &self,
        space: &ParameterSpace,
        progress: &mut Progress,
        q: &mut Vec<f64>,
        halt: &dyn Fn() -> bool,
    ) -> Result<Option<After>, CostError> {
        let fitter = self.fitter(space);
        let this = Box::new(Stuck {
            q: q.clone(),
            schedule: progress.schedule.clone(),
        });
        // Two attempts stuck at the same window with the same residuals are the same optimum:
        // a model that cannot follow the motion there, not a basin another start leaves.
        let repeated = progress.best_stuck.as_ref().is_some_and(|b| {
            let (a, c) = (b.schedule.last_rms(), this.schedule.last_rms());
            b.schedule.stuck_window() == this.schedule.stuck_window()
                && (a - c).abs() <= SAME_OPTIMUM * a.min(c)
        });
        let best = match progress.best_stuck.take() {
            Some(best) => best.better(this, |q| {
                let mut buf = super::tangent::Sens::default();
                progress
                    .schedule
                    .residual_scale(&fitter, q, usize::MAX, &mut buf)
            }),
            None => this,
        };
        if let Some(from) = self.shooting_start(space, progress) {
            match progress.restarts {
                0 => {
                    progress.shot = true;
                    progress.first_stuck = q[space.dim()..].to_vec();
                }
                _ => progress.attempt_shot = true,
            }
            let mut counts = progress.counts;
            let shot = self.shoot(space, &from, &mut counts, halt);
            progress.counts = counts;
            if let shooting::Shot::Interrupted = shot {
                return Ok(None);
            }
            if let shooting::Shot::Done(shot) = shot {
                progress.best_stuck = Some(best);
                progress.shooting = true;
                *q = shot;
                fitter.project(q);
                // Shooting fitted the whole take: single shooting goes on there, not from a
                // short window whose parameters the data do not hold yet.
                progress.schedule = self.schedule_from(&fitter, usize::MAX);
                return Ok(Some(After::Stage));
            }
        }
        progress.shooting = false;
        if progress.restarts < MAX_RESTARTS && !repeated {
            progress.best_stuck = Some(best);
            // The seeded restarts go as they would have without the shooting attempt: the
            // first redraws about the first attempt's states.
            let stuck_states = match progress.restarts == 0 && !progress.first_stuck.is_empty() {
                true => progress.first_stuck.clone(),
                false => q[space.dim()..].to_vec(),
            };
            progress.restarts += 1;
            progress.attempt_shot = false;
            *q = start::restart_genome(&self.scene, space, &self.takes[0], progress.restarts);
            let len = fitter.state_len();
            for (k, take) in self.takes.iter().enumerate() {
                let span = k * len..(k + 1) * len;
                q.extend(start::restart_states(
                    &self.scene,
                    &self.tangent.free,
                    take,
                    &progress.states0[span.clone()],
                    &stuck_states[span],
                    (progress.restarts, k),
                ));
            }
            fitter.project(q);
            progress.schedule = self.schedule(&fitter, progress.restarts);
            return Ok(Some(After::Stage));
        }
        *q = best.q;
        progress.schedule = best.schedule;
        progress.schedule.settle();
        progress.schedule.keep_going(q).map(Some)
    }

    /// The θ the attempt now stuck shoots from, when it has not shot yet: the start's for the
    /// first attempt, restart k's seeded point ([`start::restart_genome`]) for restart k. None
    /// on the matrix-free path (its budget ends are the cloth's crawl, not a wrong basin).
    fn shooting_start(&self, space: &ParameterSpace, progress: &Progress) -> Option<Vec<f64>> {
        match progress.restarts {
            _ if self.large => None,
            0 if !progress.shot && !progress.genome0.is_empty() => Some(progress.genome0.clone()),
            0 => None,
            r if !progress.attempt_shot => {
                Some(start::restart_genome(&self.scene, space, &self.takes[0], r))
            }
            _ => None,
        }
    }

    /// Multiple shooting ([`shooting`]) from `genome`: the takes cut into segments of twice
    /// the first window, each started from its own first frames, tied by the penalty stages;
    /// θ and each take's first segment's state for single shooting to go on from, or how it
    /// ended without them (a stage diverged, or `halt()` stopped it).
    fn shoot(
        &self,
        space: &ParameterSpace,
        genome: &[f64],
        counts: &mut Counts,
        halt: &dyn Fn() -> bool,
    ) -> shooting::Shot {
        let initial = |take: &Take| start::initial_state(&self.scene, &self.tangent.free, take);
        shooting::shoot(
            &self.fitter(space),
            genome,
            SEGMENT_WINDOWS * self.first_window,
            &initial,
            (self.set, counts),
            halt,
        )
    }

    /// Hands `f` the number of fit variables and the matrix-free Gauss–Newton product
    /// `(v, width, out) ↦ out = H v` (row-major, variables × width) at `progress`'s variables
    /// over the whole take: the operator every CG iteration of a large fit applies, for the
    /// criterion benchmark (`benches/matrix_free.rs`). `None` when the rollout diverges there.
    #[doc(hidden)]
    pub fn with_gauss_newton_product<R>(
        &self,
        space: &ParameterSpace,
        progress: &Progress,
        f: impl FnOnce(usize, &mut (dyn FnMut(&[f64], usize, &mut [f64]) + Send)) -> R,
    ) -> Option<R> {
        let takes = self.weighed(progress);
        let fitter = self.fitter_on(space, &takes);
        let mut mf = matrix_free::Mf::new(&fitter);
        let mut work = matrix_free::Work::default();
        if !mf.linearise(&progress.q, progress.schedule.longest(), &mut work) {
            return None;
        }
        Some(f(fitter.len(), &mut |v, w, out| {
            mf.hv(v, w, out, &mut work)
        }))
    }

    /// The estimate at the end of a fit whose last [`Prepared::stage`] was [`Step::Done`]:
    /// σ̂, standard errors, intervals, correlations and undetermined directions. `halt()`
    /// (Ctrl-C, a time limit) cuts the intervals' profile refits short
    /// (docs/identification.md, "Intervals on thin data").
    pub fn finish(
        &self,
        scene: &Scene,
        space: &ParameterSpace,
        progress: &Progress,
        halt: &dyn Fn() -> bool,
    ) -> Result<Estimate, CostError> {
        let mut e = self.finish_fit(scene, space, progress, halt)?;
        e.loss = self.loss;
        if self.large && self.loss == Loss::Squared && self.intervals == super::Intervals::Profile {
            e.interval_kind = "wald (profile asked: a refit costs a fit on the matrix-free path, \
                               so its intervals are checked along the line only)"
                .into();
        }
        e.downweighted = self
            .observed_weights(progress)
            .filter(|&omega| omega < 0.5)
            .count();
        if self.loss != Loss::Squared {
            self.m_estimate_spread(space, progress, &mut e);
        }
        Ok(e)
    }

    /// The IRLS weights `ω` (the squared multipliers) of the observed coordinates of every
    /// take, at `progress`.
    fn observed_weights<'a>(&'a self, progress: &'a Progress) -> impl Iterator<Item = f64> + 'a {
        progress
            .robust
            .iter()
            .zip(&self.takes)
            .flat_map(|(m, take)| {
                m.iter()
                    .enumerate()
                    .filter(move |&(k, _)| take.weight_at(k) > 0.0)
                    .map(|(_, m)| m * m)
            })
    }

    /// A robust fit's standard errors, intervals and σ̂ as the M-estimate's
    /// ([`loss::m_estimate_spread`]), not as its last IRLS normal equations': those read the
    /// reweighted residuals, whose σ̂ understates the noise (0.83–0.90 σ on Gaussian noise,
    /// standard errors 8–11 % small and 95 % intervals covering 91–92 %, measured by a new
    /// user over 360 intervals).
    fn m_estimate_spread(&self, space: &ParameterSpace, progress: &Progress, e: &mut Estimate) {
        let window = progress.schedule.longest();
        let Some(res) = self
            .fitter(space)
            .residuals(&progress.q, window, &mut Sens::default())
        else {
            return;
        };
        let r: Vec<f64> = res
            .into_iter()
            .flatten()
            .filter(|r| r.is_finite())
            .collect();
        // The weights the last normal equations were built on (H_ω's ω).
        let (sum, count) = self
            .observed_weights(progress)
            .fold((0.0, 0usize), |(s, c), omega| (s + omega, c + 1));
        let mean_weight = match count {
            0 => 1.0,
            _ => sum / count as f64,
        };
        let spread =
            loss::m_estimate_spread(self.loss, &r, mean_weight, e.variables, e.sigma * e.sigma);
        let Some((factor, scale)) = spread else {
            return;
        };
        let root = factor.sqrt();
        e.covariance *= factor;
        for se in e.stderr.iter_mut().chain(e.stderr_at_least.iter_mut()) {
            *se *= root;
        }
        e.intervals = summary::intervals(space.unknowns.as_slice(), &e.params, &e.stderr);
        e.sigma = scale;
    }

    fn finish_fit(
        &self,
        scene: &Scene,
        space: &ParameterSpace,
        progress: &Progress,
        halt: &dyn Fn() -> bool,
    ) -> Result<Estimate, CostError> {
        let end = progress.last_end.ok_or_else(|| {
            CostError::mismatch("output-error", "the fit has not reached the whole take")
        })?;
        let takes = self.weighed(progress);
        let fitter = self.fitter_on(space, &takes);
        let p = progress;
        let windows = p.schedule.windows.clone();
        let mut e = self.summarise(&fitter, scene, p, end, windows, halt)?;
        e.above_noise = p.schedule.above_noise();
        Ok(e)
    }

    fn summarise(
        &self,
        fitter: &Fitter<'_>,
        scene: &Scene,
        p: &Progress,
        end: StageEnd,
        windows: Vec<usize>,
        halt: &dyn Fn() -> bool,
    ) -> Result<Estimate, CostError> {
        debug_assert_eq!(windows.last(), Some(&p.schedule.longest()));
        if self.large {
            return matrix_free::finish(
                fitter,
                p.q.clone(),
                p.counts,
                p.cg,
                end,
                windows,
                self.noise_level.clone(),
                p.start_note(),
                &p.last_steps,
                self.interval_check(),
                halt,
            );
        }
        let mut counts = p.counts;
        counts.evaluations += 1;
        let ne = fitter
            .normal(&p.q, p.schedule.longest(), &mut Sens::default())
            .ok_or_else(|| CostError::mismatch("fit", "the model diverged at its estimate"))?;
        Ok(summary::summarise(
            fitter,
            scene,
            p.q.clone(),
            ne,
            self.noise_level.clone(),
            counts,
            end,
            windows,
            p.start_note(),
            self.interval_check(),
            halt,
        ))
    }

    /// How the intervals are checked ([`super::line_profile`]): not with a robust loss (its
    /// intervals are the M-estimate's sandwich, its cost not a likelihood); along the line
    /// only on the matrix-free path (a profile refit there costs a fit).
    fn interval_check(&self) -> Option<Measure> {
        if self.large {
            return (self.loss == Loss::Squared).then_some(Measure::Line);
        }
        match (self.loss, self.intervals) {
            (Loss::Squared, super::Intervals::Profile) => Some(Measure::Profile {
                face_steps: self.set.face_steps,
            }),
            (Loss::Squared, _) => Some(Measure::Line),
            _ => None,
        }
    }

    /// Whether `progress` (read from a checkpoint) belongs to this fit.
    pub fn check(&self, space: &ParameterSpace, progress: &Progress) -> Result<(), CostError> {
        let len = self.fitter(space).len();
        let longest = self.takes.iter().map(Take::frames).max().unwrap_or(0);
        let partial = progress.partial.as_ref().map_or(len, |p| p.q.len());
        if progress.q.len() != len || partial != len {
            return Err(CostError::state(format!(
                "output-error state holds {} fit variables, this problem has {len}",
                progress.q.len()
            )));
        }
        let robust_fits = progress.robust.is_empty()
            || (progress.robust.len() == self.takes.len()
                && progress
                    .robust
                    .iter()
                    .zip(&self.takes)
                    .all(|(m, t)| m.len() == t.frames() * t.particles() * 3));
        if !robust_fits {
            return Err(CostError::state(
                "output-error state holds robust weights of another shape",
            ));
        }
        if progress.schedule.longest() != longest || progress.schedule.next > longest {
            return Err(CostError::state(format!(
                "output-error state was made on takes of {} frames, these have {longest}",
                progress.schedule.longest()
            )));
        }
        Ok(())
    }

    /// The fit's variables of the unknowns (the genome, internal coordinates) in `q`.
    pub fn genome<'q>(&self, space: &ParameterSpace, q: &'q [f64]) -> &'q [f64] {
        &q[..space.dim()]
    }

    /// At `q`: the weighted squared position residuals over the whole takes (m², +inf when
    /// the model diverges), the observed coordinates and the fit variables.
    pub fn measure(&self, space: &ParameterSpace, q: &[f64]) -> (f64, usize, usize) {
        let fitter = self.fitter(space);
        let longest = self.takes.iter().map(Take::frames).max().unwrap_or(0);
        let observed = self.takes.iter().map(Take::observed).sum();
        let cost = fitter.cost(q, longest, &mut Sens::default());
        (cost, observed, fitter.len())
    }

    /// Each take's noise level read from its third differences, m.
    pub fn noise_level(&self) -> &[f64] {
        &self.noise_level
    }

    /// Each take's `[x0, v0]` per free particle at `q`.
    pub fn states(&self, space: &ParameterSpace, q: &[f64]) -> Vec<Vec<f64>> {
        summary::take_states(&self.fitter(space), q)
    }
}

impl Progress {
    /// The best point so far: a stopped stage's, else the last finished stage's.
    pub fn best(&self) -> &[f64] {
        self.partial.as_ref().map_or(&self.q, |p| &p.q)
    }

    /// Forgets a stopped stage's partial result, so the next [`Prepared::stage`] reruns it
    /// from its start (what a resumed run does: the same steps as an uninterrupted one).
    pub fn rerun_stopped_stage(&mut self) {
        self.partial = None;
    }

    /// Whether the last stage was stopped before it ended.
    pub fn stopped(&self) -> bool {
        self.partial.is_some()
    }

    /// The windows fitted so far, frames, and the one being fitted.
    pub fn windows(&self) -> &[usize] {
        &self.schedule.windows
    }

    pub fn next_window(&self) -> usize {
        self.schedule.next
    }

    /// Levenberg–Marquardt iterations and rollouts so far (a stopped stage's included).
    pub fn counts(&self) -> (usize, usize) {
        let c = self.partial.as_ref().map_or(self.counts, |p| p.counts);
        (c.iterations, c.evaluations)
    }

    /// Where the fit started, and its restarts.
    pub fn start_note(&self) -> String {
        let shot = match (self.shot, self.restarts) {
            (false, _) => "",
            (true, 0) if !self.schedule.settled() => {
                "; restarted by multiple shooting from the start"
            }
            (true, _) => "; multiple shooting from the start stuck too",
        };
        // Seeded restarts shoot when the start did (the dense path).
        let (last_shot, each_shot) = match self.shot {
            true if self.shooting => (", the last by multiple shooting from its seeded point", ""),
            true => (
                "",
                ", each also by multiple shooting from its seeded point,",
            ),
            false => ("", ""),
        };
        match (self.restarts, self.schedule.settled()) {
            (0, false) => format!("{}{shot}", self.start),
            (r, false) => format!(
                "{}{shot}; restarted {r} time(s) from seeded points in the boxes (a window stuck \
                 above the noise level, or the whole take's on its budget){last_shot}",
                self.start
            ),
            (r, true) => format!(
                "{}{shot}; {r} restart(s){each_shot} stuck above the noise level or on their \
                 budget as the first start did: went on from the attempt with the smallest \
                 residuals",
                self.start
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use cordis_core::{Bounds, Param};

    /// Guards the restarts' shooting: the first start shoots once from its start θ, each
    /// seeded restart once from its own seeded point, the matrix-free path never.
    #[test]
    fn every_attempt_shoots_once_from_the_theta_it_started_from() {
        let mut scene = super::super::tests::anchored_particle();
        let traj = scene.simulate(60).unwrap();
        scene.types[0].params[0] = Param::Unknown(Bounds {
            min: 1.0,
            max: 100.0,
            init: None,
        });
        let space = ParameterSpace::from_scene(&scene);
        let takes = vec![Take::complete(&traj)];
        let config = Config::default();
        let prepared = Prepared::new(&scene, &space, takes.clone(), &config).unwrap();
        let mut progress = prepared.start(&scene, &space, &config).unwrap();
        let from = |p: &Progress| prepared.shooting_start(&space, p);
        assert_eq!(from(&progress), Some(progress.genome0.clone()));
        progress.shot = true;
        assert_eq!(from(&progress), None, "the start shoots once");
        let mut seeded = Vec::new();
        for r in 1..=2 {
            progress.restarts = r;
            progress.attempt_shot = false;
            seeded.push(start::restart_genome(&scene, &space, &takes[0], r));
            assert_eq!(from(&progress).as_ref(), seeded.last(), "restart {r}");
            progress.attempt_shot = true;
            assert_eq!(from(&progress), None, "restart {r} shoots once");
        }
        assert_ne!(seeded[0], seeded[1], "each restart from its own point");
        let config = Config {
            dense_max_columns: 0,
            ..config
        };
        let large = Prepared::new(&scene, &space, takes, &config).unwrap();
        progress.attempt_shot = false;
        assert_eq!(large.shooting_start(&space, &progress), None);
        progress.restarts = 0;
        progress.shot = false;
        assert_eq!(large.shooting_start(&space, &progress), None);
    }

    /// Guards `Stuck::better`: when every restart is stuck, the attempt the fit goes on from is
    /// the one fitting the whole take better, not the one with the smaller rms over the
    /// (shorter) window it got stuck at.
    #[test]
    fn the_stuck_attempt_kept_is_the_one_fitting_the_whole_take_not_its_own_window() {
        let mut scene = super::super::tests::anchored_particle();
        let traj = scene.simulate(120).unwrap();
        scene.types[0].params[0] = Param::Unknown(Bounds {
            min: 1.0,
            max: 100.0,
            init: None,
        });
        let takes = vec![Take::complete(&traj)];
        let tangent = Tangent::new(&scene).unwrap();
        let space = ParameterSpace::from_scene(&scene);
        let base = scene.param_values();
        let fitter = super::super::tests::fitter_of(&tangent, &space, &base, &takes);
        let at = |k: f64, dx: f64| {
            let mut q = vec![space.unknowns[0].to_internal(k)];
            q.extend_from_slice(&[1.0 + dx, 0.0, 0.0, 0.0, 0.0, 0.0]);
            q
        };
        // A: a stiffness 30 % off, close over its first 8 frames, out of phase later.
        // B: the true stiffness from a start 1 mm off: the same small error over every frame.
        let attempt = |mut q: Vec<f64>, window: usize| {
            let mut schedule = Schedule::new(&fitter, window, 1e-6, usize::MAX, false);
            let mut buf = Sens::default();
            schedule
                .after(&fitter, &mut q, StageEnd::Budget, &mut buf)
                .unwrap();
            Box::new(Stuck { q, schedule })
        };
        let a = attempt(at(13.0, 0.0), 8);
        let b = attempt(at(10.0, 1e-3), 120);
        assert!(
            a.schedule.last_rms() < b.schedule.last_rms(),
            "A looks better on its window"
        );
        let whole = |q: &[f64]| {
            a.schedule
                .residual_scale(&fitter, q, usize::MAX, &mut Sens::default())
        };
        let (wa, wb) = (whole(&a.q), whole(&b.q));
        assert!(wb < wa, "B fits the whole take better: {wb} vs {wa}");
        let kept = a.clone().better(b.clone(), whole);
        assert_eq!(kept.q, b.q);
        let kept = b.clone().better(a.clone(), whole);
        assert_eq!(kept.q, b.q);
    }
}
