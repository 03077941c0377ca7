//! The shipped example scenes (SPEC §6): the thesis' reference experiments rebuilt as code.
//!
//! Each builder returns a validated, deterministic [`Scene`] (no RNG: the few pseudo-random
//! numbers come from a seeded SplitMix64); [`by_name`] gives the default size of each, as
//! used by the CLI and the benchmarks, and [`default_frames`] how many frames it is meant to
//! be simulated for. Generated coordinates are rounded to 1e-9 so that a scene written to JSON
//! and read back is bit-for-bit the same scene.

mod bouncing_ball;
mod central_muscle;
mod cloth;
mod fluid;
mod follower;
mod frog;
mod horse;
mod horse_gait;
mod horse_ground;
mod muscle;
mod random;
mod rigid;
mod tadpole;
mod varied;

pub use bouncing_ball::{
    bouncing_ball, BALL_DAMPING, BALL_FRAMES, BALL_FRICTION, BALL_MASS, BALL_STIFFNESS,
};
pub use central_muscle::{central_idx, central_muscle, CENTRAL_MUSCLE_FRAMES};
pub use cloth::{cloth, CLOTH_FRAMES};
pub use fluid::{fluid, FLUID_FRAMES};
pub use follower::{
    follower, follower_distance, follower_moving, follower_with_target, FOLLOWER_BODY_LENGTH,
    FOLLOWER_FRAMES,
};
pub use frog::{frog, frog_heading, frog_with, FROG_FRAMES};
pub use horse::{horse, HORSE_FRAMES};
pub use horse_gait::{horse_gait, GAIT_GAIN, GAIT_RATE_WEIGHT};
pub use horse_ground::{
    horse_ground, GROUND_DAMPING, GROUND_FRICTION, GROUND_HEIGHT, GROUND_STIFFNESS,
    HORSE_GROUND_FRAMES,
};
pub use muscle::{muscle, MUSCLE_FRAMES, MUSCLE_GAIN};
pub use random::{random_network, tracked_network, tracked_network_with_angles};
pub use rigid::{rigid, RIGID_FRAMES};
pub use tadpole::{
    tadpole, tadpole_vmax_bracket, tadpole_with, TADPOLE_BODY_LENGTH, TADPOLE_FRAMES,
};
pub use varied::{varied_network, VariedCase, VariedKinds, VARIED_MAX_RANK};

use crate::{LinkKind, LinkType, Scene};

/// Names accepted by [`by_name`], in the order the thesis presents them.
pub const NAMES: &[&str] = &[
    "rigid",
    "cloth",
    "fluid",
    "horse",
    "muscle",
    "horse-gait",
    "tadpole",
    "frog",
    "follower",
    "central-muscle",
    "bouncing-ball",
    "horse-ground",
];

/// The example of that name at its default size, or `None` for a name not in [`NAMES`].
pub fn by_name(name: &str) -> Option<Scene> {
    match name {
        "rigid" => Some(rigid()),
        "cloth" => Some(cloth(32, 32)),
        "fluid" => Some(fluid(80, 48)),
        "horse" => Some(horse()),
        "muscle" => Some(muscle()),
        "horse-gait" => Some(horse_gait()),
        "tadpole" => Some(tadpole()),
        "frog" => Some(frog()),
        "follower" => Some(follower()),
        "central-muscle" => Some(central_muscle()),
        "bouncing-ball" => Some(bouncing_ball()),
        "horse-ground" => Some(horse_ground()),
        _ => None,
    }
}

/// Number of frames the named example is meant to be simulated for (frame 0 included);
/// 0 for a name not in [`NAMES`].
pub fn default_frames(name: &str) -> usize {
    match name {
        "rigid" => RIGID_FRAMES,
        "cloth" => CLOTH_FRAMES,
        "fluid" => FLUID_FRAMES,
        "horse" | "horse-gait" => HORSE_FRAMES,
        "muscle" => MUSCLE_FRAMES,
        "tadpole" => TADPOLE_FRAMES,
        "frog" => FROG_FRAMES,
        "follower" => FOLLOWER_FRAMES,
        "central-muscle" => CENTRAL_MUSCLE_FRAMES,
        "bouncing-ball" => BALL_FRAMES,
        "horse-ground" => HORSE_GROUND_FRAMES,
        _ => 0,
    }
}

/// The passive counterpart of a scene (thesis §6.2): every muscle type becomes a spring with
/// the muscle's stiffness, rest length and damping (known or unknown as they were), and the
/// neurons are dropped (gain, threshold, weights, `observes`). Every other type, the links and
/// the particles are unchanged, so the result fits the same trajectories with the same
/// topology, without energy injection.
pub fn passive(scene: &Scene) -> Scene {
    let mut out = scene.clone();
    for t in out.types.iter_mut().filter(|t| t.kind == LinkKind::Muscle) {
        let mut spring = LinkType::new(t.name.clone(), LinkKind::Spring);
        for name in ["stiffness", "rest_length", "damping"] {
            if let Some(p) = t.param(name) {
                spring = spring.with(name, *p);
            }
        }
        *t = spring;
    }
    for l in &mut out.links {
        l.observes = None;
    }
    out
}

/// SplitMix64 (Steele, Lea & Flood 2014): a tiny seeded generator, so that the examples' jitter
/// is the same on every machine and every run.
#[derive(Clone, Debug)]
pub(crate) struct SplitMix64(u64);

impl SplitMix64 {
    pub(crate) fn new(seed: u64) -> Self {
        SplitMix64(seed)
    }

    pub(crate) fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [lo, hi).
    pub(crate) fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        let unit = (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64;
        lo + (hi - lo) * unit
    }
}

/// `x` rounded to 1e-9. A value with at most nine decimals prints and parses back exactly, so
/// rounding generated coordinates makes the JSON round trip exact whatever the float parser.
pub(crate) fn q(x: f64) -> f64 {
    (x * 1e9).round() / 1e9
}

/// [`q`] on each coordinate.
pub(crate) fn q3(v: [f64; 3]) -> [f64; 3] {
    v.map(q)
}

/// Distance between two points, m.
pub(crate) fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
}
