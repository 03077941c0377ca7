//! Which cost an [`crate::cost::Objective`] computes (SPEC §3, thesis §3.2.1).

use crate::error::CostError;
use cordis_core::{Plan, Scene};
use std::fmt;
use std::str::FromStr;

/// Default ε of the harmonic cost, m² (a squared error of 1 µm): it keeps `1/(e + ε)` finite
/// where a prediction is exact.
pub const DEFAULT_HARMONIC_EPS: f64 = 1e-12;

/// Default number of generations over which the progressive horizon grows to its full length.
pub const DEFAULT_GENERATIONS_TO_FULL: usize = 1000;

/// The cost kinds of SPEC §3. Parsed from and displayed as the strings `short`, `horizon:H`,
/// `long`, `progressive[:G[:START]]`, `harmonic[:EPS]`, `static`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub enum CostKind {
    /// Louchet's short-term cost (the default): every frame predicted by one step from the two
    /// real frames before it.
    #[default]
    Short,
    /// From every real start `(x(t-1), x(t-2))`, roll out `H ≥ 1` steps and sum the error of
    /// every predicted frame against the real one. `Horizon(1)` is `Short`.
    Horizon(usize),
    /// One rollout from frames 0 and 1 over the whole trajectory.
    Long,
    /// `Horizon(h)` with `h` growing linearly with the generation counter
    /// ([`crate::cost::Objective::set_generation`]), from `start` (default 1) at generation 0
    /// to the full length `T - 2` at generation `generations_to_full` (default 1000), then
    /// staying there. This is the thesis' second remedy (§3.2.1: "compute the cost over a few
    /// time steps at first, then progressively increase their number"), read as windows from
    /// every real start so that the whole trajectory is used from the first generation; at
    /// `h = 1` it is the short cost (and uses its precomputed linear form), at full length a
    /// window costs O(T) steps, so a generation costs O(T²) steps.
    Progressive {
        start: usize,
        generations_to_full: usize,
    },
    /// Thesis eq 3.2 on the long rollout: `C = 1 / Σ_t Σ_i 1 / (e_i(t) + ε)`, ε in m²
    /// (default [`DEFAULT_HARMONIC_EPS`]).
    ///
    /// The printed equation is garbled; its text says it favours the smallest errors,
    /// "apparentée à une moyenne harmonique", and offers it as the first remedy to the
    /// long-term cost, so it is applied to the rollout from frames 0 and 1. ε (absent from the
    /// thesis, present in the SPEC) keeps an exact prediction from making the cost 0. The local
    /// cost is the same form over one particle, `c_i = 1 / Σ_t 1/(e_i(t) + ε)`, so that
    /// `C = 1 / Σ_i 1/c_i` (not `Σ_i c_i`). Like the thesis says, one good frame can hide many
    /// bad ones: it is here for comparison, not as a default.
    Harmonic { eps: f64 },
    /// Equilibrium frames (thesis §4.2: the cloth identified from "une seule image
    /// correspondant à l'état de l'équilibre"): every frame is a pose at rest, and its
    /// residual is the net force on each free particle at zero velocity — links at the pose,
    /// plus gravity — as the displacement `dt² (F/m + g)` one simulator step makes from rest
    /// at the pose (m), then Provot's pass when the scene has one. So the static cost of a
    /// pose is the short cost of that pose held for three frames; it is 0 exactly at a fixed
    /// point of the simulator. Frames are independent poses (no velocity is read from
    /// consecutive frames; one frame is enough). It determines the parameters of forces at
    /// rest only up to the scale `K/m` (with gravity, `K/(m g)`): see
    /// [`crate::problem::Problem::new`] for the unknowns it refuses.
    Static,
}

const SYNTAX: &str =
    "expected short, horizon:H, long, progressive[:G[:START]], harmonic[:EPS] or static";

impl FromStr for CostKind {
    type Err = CostError;

    fn from_str(s: &str) -> Result<Self, CostError> {
        let place = format!("cost kind `{s}`");
        let mut parts = s.trim().split(':');
        let name = parts.next().unwrap_or_default();
        let args: Vec<&str> = parts.collect();
        let count = |n: &str, what: &str| -> Result<usize, CostError> {
            match n.trim().parse::<usize>() {
                Ok(v) if v >= 1 => Ok(v),
                _ => Err(CostError::kind(
                    &place,
                    format!("{what} must be a whole number ≥ 1, got `{n}`"),
                )),
            }
        };
        let too_many = |max: usize| {
            CostError::kind(
                &place,
                format!("`{name}` takes at most {max} `:` argument(s); {SYNTAX}"),
            )
        };
        match name.trim() {
            "short" if args.is_empty() => Ok(CostKind::Short),
            "long" if args.is_empty() => Ok(CostKind::Long),
            "static" if args.is_empty() => Ok(CostKind::Static),
            "short" | "long" | "static" => Err(too_many(0)),
            "horizon" => match args.as_slice() {
                [h] => Ok(CostKind::Horizon(count(h, "the horizon H")?)),
                [] => Err(CostError::kind(
                    &place,
                    "give the horizon, e.g. `horizon:5`",
                )),
                _ => Err(too_many(1)),
            },
            "progressive" => {
                let (g, start) = match args.as_slice() {
                    [] => (DEFAULT_GENERATIONS_TO_FULL, 1),
                    [g] => (count(g, "the generation count G")?, 1),
                    [g, st] => (
                        count(g, "the generation count G")?,
                        count(st, "the start horizon")?,
                    ),
                    _ => return Err(too_many(2)),
                };
                Ok(CostKind::Progressive {
                    start,
                    generations_to_full: g,
                })
            }
            "harmonic" => match args.as_slice() {
                [] => Ok(CostKind::Harmonic {
                    eps: DEFAULT_HARMONIC_EPS,
                }),
                [e] => match e.trim().parse::<f64>() {
                    Ok(eps) if eps.is_finite() && eps > 0.0 => Ok(CostKind::Harmonic { eps }),
                    _ => Err(CostError::kind(
                        &place,
                        format!("ε must be a positive number (m²), got `{e}`"),
                    )),
                },
                _ => Err(too_many(1)),
            },
            _ => Err(CostError::kind(&place, format!("unknown cost; {SYNTAX}"))),
        }
    }
}

impl fmt::Display for CostKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            CostKind::Short => f.write_str("short"),
            CostKind::Horizon(h) => write!(f, "horizon:{h}"),
            CostKind::Long => f.write_str("long"),
            CostKind::Progressive {
                start: 1,
                generations_to_full,
            } => write!(f, "progressive:{generations_to_full}"),
            CostKind::Progressive {
                start,
                generations_to_full,
            } => write!(f, "progressive:{generations_to_full}:{start}"),
            CostKind::Harmonic { eps } => write!(f, "harmonic:{eps}"),
            CostKind::Static => f.write_str("static"),
        }
    }
}

impl CostKind {
    /// For the windowed kinds (`short`, `horizon`, `progressive`): the number of steps each
    /// window predicts at generation `generation` on a trajectory of `frames` frames, clamped
    /// to `1..=frames - 2` (the whole trajectory). `None` for `long` and `harmonic`, which are
    /// one rollout from frames 0 and 1, and for `static`, which predicts no motion.
    pub fn window(&self, frames: usize, generation: usize) -> Option<usize> {
        let full = frames.saturating_sub(2).max(1);
        let h = match *self {
            CostKind::Short => 1,
            CostKind::Horizon(h) => h,
            CostKind::Progressive {
                start,
                generations_to_full,
            } => {
                let start = start.clamp(1, full);
                let g = generation.min(generations_to_full);
                // u128: exact, and no overflow for any counts.
                let grown = (full - start) as u128 * g as u128 / generations_to_full.max(1) as u128;
                start + grown as usize
            }
            CostKind::Long | CostKind::Harmonic { .. } | CostKind::Static => return None,
        };
        Some(h.clamp(1, full))
    }
}

impl CostKind {
    /// The fewest frames a trajectory needs for this kind: 3 for the kinds that predict
    /// motion (a step reads the two frames before it), 1 for the static kind's poses.
    pub fn min_frames(self) -> usize {
        match self {
            CostKind::Static => 1,
            _ => 3,
        }
    }

    /// Whether this kind can read `scene` (compiled as `plan`): `Err` naming what it cannot.
    /// The static kind refuses couplings by the type's name: they carry a state between steps
    /// (a TGR's tendon follows a signal in time, a quadripole remembers Δ(n-1)) that a pose
    /// at rest does not show.
    pub(crate) fn check_scene(self, scene: &Scene, plan: &Plan) -> Result<(), CostError> {
        if self != CostKind::Static {
            return Ok(());
        }
        if let Some(ty) = scene.types.iter().find(|t| t.kind.is_coupling()) {
            return Err(CostError::refused(
                format!("types.{} ({})", ty.name, ty.kind),
                "the static cost cannot read a coupling's state from an equilibrium pose \
                 (use a dynamic cost: short, horizon:H, long)",
            ));
        }
        if !plan.stateful.is_empty() {
            return Err(CostError::refused(
                "cost kind `static`",
                "the scene has stateful passes, whose state a pose does not show",
            ));
        }
        Ok(())
    }
}
