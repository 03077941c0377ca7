//! The thesis' local-control muscle experiment (§6.2, Annexe 2 "Muscle"): 3 particles joined
//! by 2 muscles, each with its own type, so 4 mechanical parameters (K and Z of each) and 4
//! neural weights (each neuron observes the other muscle's elongation and rate).

use crate::{LinkKind, LinkType, Param, Particle, Scene};

/// The muscle example is meant to be simulated for 300 frames (3 s at dt = 0.01 s): long
/// enough for the neurons to grow a small push into a sustained oscillation.
pub const MUSCLE_FRAMES: usize = 300;

/// Per muscle: (name, ends, stiffness N/m, rest length m, damping N·s/m, w_len 1/m,
/// w_rate s/m). Each neuron's rate weight is negative: when the other muscle lengthens, this
/// one pushes its ends apart too, which feeds the in-phase stretch mode (a negative damping of
/// G·|w_rate| = 8–9 N·s/m against Z = 2.5–3 N·s/m) until tanh saturates: a limit cycle.
const MUSCLES: [Muscle; 2] = [
    ("left", [0, 1], 40.0, 1.0, 3.0, 1.2, -8.0),
    ("right", [1, 2], 55.0, 0.8, 2.5, -1.8, -9.0),
];

type Muscle = (&'static str, [usize; 2], f64, f64, f64, f64, f64);

/// Gain G of both neurons, N: the largest force a neuron adds.
pub const MUSCLE_GAIN: f64 = 1.0;

/// Three particles on a line (masses 1.0, 0.8, 1.2 kg), no gravity, the ends pushed slightly
/// apart at 0.1 m/s. Passive springs with these K and Z would damp that out within a second;
/// the neurons instead inject energy and sustain an oscillation of a few cm. dt = 0.01 s,
/// meant for [`MUSCLE_FRAMES`] frames; thresholds θ = 0 and gain [`MUSCLE_GAIN`].
pub fn muscle() -> Scene {
    let mut scene = Scene::new(0.01);
    scene.add_particle(Particle::new(1.0, [0.0, 0.0, 0.0]).with_vel([-0.1, 0.0, 0.0]));
    scene.add_particle(Particle::new(0.8, [1.0, 0.0, 0.0]));
    scene.add_particle(Particle::new(1.2, [1.8, 0.0, 0.0]).with_vel([0.1, 0.0, 0.0]));
    for (name, _, k, l0, z, wl, wr) in MUSCLES {
        scene.add_type(
            LinkType::new(name, LinkKind::Muscle)
                .with("stiffness", k)
                .with("rest_length", l0)
                .with("damping", z)
                .with("gain", MUSCLE_GAIN)
                .with_weights(&[Param::Known(wl)], &[Param::Known(wr)]),
        );
    }
    for (name, ends, ..) in MUSCLES {
        scene.add_link(name, &ends);
    }
    scene
}
