//! The central-control muscle (thesis §5.4, Figures 5.3-5.6): a mobile moved by a TGR whose
//! tendon a controller world drives and which feels the mobile back (proprioception).
//!
//! **Mobile** (main world, dt 0.01 s): the tadpole of §5.1 (see [`super::tadpole`]) — a 1 kg
//! particle at the origin and a 0.3 kg one 1 m along +x, both in Table 6.1's two-regime medium —
//! whose only actuator is the TGR `muscle` between them (K 20 N/m, l0 0.5 m, the tadpole's
//! 10 g tendon with K_t 20 N/m, Z_t 1 N·s/m). The muscle has **no signal**: its tendon is
//! anchored on the controller's dipole (`controller`, see [`crate::forces::controlled_tgr`]),
//! so its rest length `l0 + y` follows `0.5 m + ` the dipole's length.
//!
//! **Controller** (world `mind`, its own clock: dt 0.005 s, one step per frame, so it lives at
//! half the mobile's pace): a fixed virtual foot and a light virtual neck (0.1 kg) 0.5 m
//! away — the dipole the muscle follows — joined by the `nerve`, a TGR of the controller's own
//! (K 100 N/m, Z 2 N·s/m) whose tendon a sawtooth drives (the tadpole's stroke: 3.5 N, rise
//! 0.9, phase 0.75, period 2 s of the controller's time = 4 s of the mobile's). The nerve is
//! the controller's rhythm; the mobile feels it only through the muscle, and the virtual neck
//! feels the muscle's tension back (the tendon's spring pulls it), so the controller's stroke
//! is shaped by the load it moves.
//!
//! **What it shows** (tests/central_muscle.rs): the controller moves the mobile through the TGR
//! alone — it swims 3.6 m in 4000 frames (10 strokes) towards its light end, where the
//! signal-driven tadpole swims 2.9 m; with the controller's neck held still it does not move
//! at all; and the controller feels its load: in a medium ten times thicker its dipole's
//! motion differs by up to 4.7 cm within 800 frames (not at all with the muscle's K = 0).

use super::tadpole::{table_6_1_medium, TADPOLE_BODY_LENGTH};
use crate::signal::{Shape, Signal};
use crate::{LinkKind, LinkType, Particle, Scene};

/// The central-control muscle is meant to be simulated for 4000 frames (40 s, 10 strokes).
pub const CENTRAL_MUSCLE_FRAMES: usize = 4000;

/// Time step of the mobile's (main) world, s.
const DT: f64 = 0.01;

/// Time step of the controller world `mind`, s: its clock runs at half the mobile's.
const MIND_DT: f64 = 0.005;

/// Length of the controller dipole at rest, m: the muscle's rest length is `l0 +` it.
const MIND_LENGTH: f64 = 0.5;

/// The controller world's origin (its fixed virtual foot), beside the mobile so both show on one
/// plot (positions in different worlds never interact).
const MIND_ORIGIN: [f64; 3] = [0.0, -2.0, 0.0];

/// Particle indices of the central-muscle scene.
pub mod central_idx {
    /// The mobile's heavy particle (1 kg).
    pub const HEAVY: usize = 0;
    /// The mobile's light particle (0.3 kg): the mobile swims towards it.
    pub const LIGHT: usize = 1;
    /// The controller's fixed virtual foot.
    pub const MIND_FOOT: usize = 2;
    /// The controller's virtual neck: the dipole (MIND_FOOT, MIND_NECK) drives the muscle.
    pub const MIND_NECK: usize = 3;
}

/// The central-control muscle: the mobile (0, 1), the controller (2, 3), the muscle `muscle`
/// (a controlled TGR) and the controller's `nerve` (a signal-driven TGR in `mind`).
pub fn central_muscle() -> Scene {
    use central_idx::*;
    let mut s = Scene::new(DT);
    s.add_world("mind", MIND_DT);
    s.add_particle(Particle::new(1.0, [0.0; 3]));
    s.add_particle(Particle::new(0.3, [TADPOLE_BODY_LENGTH, 0.0, 0.0]));
    let o = MIND_ORIGIN;
    s.add_particle(Particle::new(1.0, o).fixed().in_world("mind"));
    s.add_particle(Particle::new(0.1, [o[0] + MIND_LENGTH, o[1], o[2]]).in_world("mind"));

    s.add_type(table_6_1_medium("water"));
    s.add_link("water", &[HEAVY]);
    s.add_link("water", &[LIGHT]);
    s.add_type(
        LinkType::new("muscle", LinkKind::Tgr)
            .with("stiffness", 20.0)
            .with("rest_length", TADPOLE_BODY_LENGTH - MIND_LENGTH)
            .with("tendon_mass", 0.01)
            .with("tendon_stiffness", 20.0)
            .with("tendon_damping", 1.0),
    );
    s.add_controlled_tgr("muscle", [HEAVY, LIGHT], [MIND_FOOT, MIND_NECK]);

    s.add_signal(
        Signal::new("rhythm", Shape::Sawtooth, 3.5, 2.0)
            .with_rise(0.9)
            .with_phase(0.75),
    );
    s.add_type(
        LinkType::new("nerve", LinkKind::Tgr)
            .with("stiffness", 100.0)
            .with("rest_length", MIND_LENGTH)
            .with("damping", 2.0)
            .with("tendon_mass", 0.01)
            .with("tendon_stiffness", 20.0)
            .with("tendon_damping", 1.0)
            .with_signal("rhythm"),
    );
    s.add_coupling("nerve", &[MIND_FOOT, MIND_NECK]);
    s
}
