//! The thesis' tadpole (§5.1, §6.1.1 and Table 6.1): the simplest vehicle that moves by its own
//! means. Two particles of different masses (the thesis: they must have different speeds at the
//! same moment, hence different masses) joined by a TGR, each in a two-regime medium
//! (`nonlinear_drag`), the tendon driven by an asymmetric sawtooth.
//!
//! Why it swims: over one period of a periodic gait the medium's impulses sum to zero, so with
//! a particle's displacement `D` per period split into its slow part (drag z1) and fast part
//! (z2), `2 z1 D + (z2 - z1)(d0_fast + d1_fast) = 0`: the body travels against the net
//! displacement its particles make while above `v_max`. The sawtooth's fast fall jerks the
//! light particle towards the heavy one above `v_max` (it grips the medium) and its slow rise
//! pushes it back below `v_max` (it slips): the tadpole swims towards its light end, about
//! 0.3 body lengths per stroke. A symmetric triangle of the same amplitude keeps both speeds
//! under `v_max` nearly all the time, so the medium acts linearly and the body only
//! oscillates in place.
//!
//! Table 6.1's values are kept: `v_max` 0.5 m/s, z1 0.1 N·s/m, z2 1 N·s/m, rest length 1 m,
//! stiffness 20 N/m. The rest (masses, dt, tendon, signal) is chosen so that the first 100
//! frames — the thesis identified from 100 images — already hold a fast stroke whose light
//! particle's speed hovers around `v_max` (the drag's jump makes it chatter there), so the
//! data pin `v_max` down: see [`tadpole_vmax_bracket`].

use crate::signal::{Shape, Signal};
use crate::{LinkKind, LinkType, Particle, Scene, Trajectory};

/// The tadpole is meant to be simulated for 4000 frames (40 s, 10 strokes).
pub const TADPOLE_FRAMES: usize = 4000;

/// Body length, m: the TGR's rest length.
pub const TADPOLE_BODY_LENGTH: f64 = 1.0;

/// The sawtooth's amplitude (N on the tendon), period (s), rise fraction and phase.
const STROKE: (f64, f64, f64, f64) = (3.5, 4.0, 0.9, 0.75);

/// The tadpole driven by its asymmetric sawtooth (see [`tadpole_with`]).
pub fn tadpole() -> Scene {
    tadpole_with(Shape::Sawtooth)
}

/// The tadpole with its command signal of the given shape (same amplitude, period and phase;
/// `Shape::Triangle` is the symmetric control, `Shape::Sine` another one). dt = 0.01 s.
///
/// Particle 0 (1 kg) at the origin, particle 1 (0.3 kg) 1 m along +x, both at rest; a
/// `nonlinear_drag` type `water` (Table 6.1: z1 0.1, z2 1, v_max 0.5) on each; a `tgr` type
/// `muscle` (K 20 N/m, l0 1 m, undamped) whose tendon (10 g, K_t 20 N/m, Z_t 1 N·s/m: a
/// position command of about ±0.17 m, following the signal within a few hundredths of a
/// second) is driven by the signal `stroke`: 3.5 N, period 4 s, rise 0.9, phase 0.75 (the
/// first fast fall starts at 0.6 s).
pub fn tadpole_with(shape: Shape) -> Scene {
    let (amplitude, period, rise, phase) = STROKE;
    let mut s = Scene::new(0.01);
    s.add_particle(Particle::new(1.0, [0.0; 3]));
    s.add_particle(Particle::new(0.3, [TADPOLE_BODY_LENGTH, 0.0, 0.0]));
    let mut signal = Signal::new("stroke", shape, amplitude, period).with_phase(phase);
    if shape == Shape::Sawtooth {
        signal = signal.with_rise(rise);
    }
    s.add_signal(signal);
    s.add_type(table_6_1_medium("water"));
    s.add_type(tadpole_muscle("muscle", "stroke"));
    s.add_link("water", &[0]);
    s.add_link("water", &[1]);
    s.add_coupling("muscle", &[0, 1]);
    s
}

/// What a trajectory can say about a two-regime drag's `v_max`: the largest observed speed
/// below `v_max` and the smallest at or above it (m/s, backward differences as the cost uses
/// them, frames 1…T-2: the ones whose drag a short-term prediction sees). Every `v_max` in
/// `(below, above]` explains the data equally well, so no method can do better than this
/// bracket. `None` on a side with no speed.
pub fn tadpole_vmax_bracket(traj: &Trajectory, v_max: f64) -> (Option<f64>, Option<f64>) {
    let dt = traj.dt.unwrap_or(0.01);
    let (mut below, mut above): (Option<f64>, Option<f64>) = (None, None);
    for t in 1..traj.frames().saturating_sub(1) {
        for i in 0..traj.particles() {
            let v = (traj.pos(t, i) - traj.pos(t - 1, i)).norm() / dt;
            if v < v_max {
                below = Some(below.map_or(v, |b| b.max(v)));
            } else {
                above = Some(above.map_or(v, |a| a.min(v)));
            }
        }
    }
    (below, above)
}

/// The thesis' Table 6.1 medium (`z1` 0.1, `z2` 1, `v_max` 0.5), shared by the mobiles.
pub(crate) fn table_6_1_medium(name: &str) -> LinkType {
    LinkType::new(name, LinkKind::NonlinearDrag)
        .with("z1", 0.1)
        .with("z2", 1.0)
        .with("v_max", 0.5)
}

/// The tadpole's TGR (Table 6.1's stiffness 20 and rest length, a 10 g tendon) driven by
/// `signal`, shared by the mobiles.
pub(crate) fn tadpole_muscle(name: &str, signal: &str) -> LinkType {
    LinkType::new(name, LinkKind::Tgr)
        .with("stiffness", 20.0)
        .with("rest_length", TADPOLE_BODY_LENGTH)
        .with("tendon_mass", 0.01)
        .with("tendon_stiffness", 20.0)
        .with("tendon_damping", 1.0)
        .with_signal(signal)
}
