//! The thesis' frog (§5.1, Figure 5.2): two tadpoles side by side, the simplest vehicle that
//! can change its direction by itself. Each side is a tadpole (a heavy and a light particle
//! joined by a TGR, in the two-regime medium of [`super::tadpole`]); springs join the two heavy
//! and the two light particles, and angle links at the four corners keep the frame
//! rectangular. Driven alike, both sides swim alike and the frog goes straight (towards its
//! light end, +x); when one side's signal runs faster, that side strokes more often, travels
//! further, and the frog turns towards the other side, like a tracked vehicle.

use super::tadpole::{table_6_1_medium, tadpole_muscle, TADPOLE_BODY_LENGTH};
use crate::signal::{Shape, Signal};
use crate::{LinkKind, LinkType, Particle, Scene, Trajectory, Vec3};

/// The frog is meant to be simulated for 4000 frames (40 s).
pub const FROG_FRAMES: usize = 4000;

/// Distance between the two tadpoles, m.
const WIDTH: f64 = 0.8;

/// The frog with both sides driven by the tadpole's stroke (period 4 s): it goes straight.
pub fn frog() -> Scene {
    frog_with(4.0, 4.0)
}

/// The frog with its left (+y) and right (-y) TGRs driven by sawtooths of the given periods
/// (s; the tadpole's amplitude 3.5 N, rise 0.9, phase 0.75). Particles: 0 left heavy (1 kg),
/// 1 left light (0.3 kg), 2 right heavy, 3 right light; the heavy ones on x = 0, the light ones
/// on x = 1 m, at y = ±0.4 m. dt = 0.01 s.
pub fn frog_with(left_period: f64, right_period: f64) -> Scene {
    let mut s = Scene::new(0.01);
    let half = 0.5 * WIDTH;
    for y in [half, -half] {
        s.add_particle(Particle::new(1.0, [0.0, y, 0.0]));
        s.add_particle(Particle::new(0.3, [TADPOLE_BODY_LENGTH, y, 0.0]));
    }
    for (name, period) in [("left", left_period), ("right", right_period)] {
        s.add_signal(
            Signal::new(name, Shape::Sawtooth, 3.5, period)
                .with_rise(0.9)
                .with_phase(0.75),
        );
        s.add_type(tadpole_muscle(&format!("{name}_muscle"), name));
    }
    s.add_type(table_6_1_medium("water"));
    s.add_type(
        LinkType::new("rib", LinkKind::Spring)
            .with("stiffness", 20.0)
            .with("rest_length", WIDTH),
    );
    s.add_type(
        LinkType::new("corner", LinkKind::Angle)
            .with("stiffness", 2.0)
            .with("rest_cos", 0.0),
    );
    for i in 0..4 {
        s.add_link("water", &[i]);
    }
    s.add_link("rib", &[0, 2]);
    s.add_link("rib", &[1, 3]);
    // Corners: (neighbour, corner, neighbour) around the rectangle 0-1-3-2.
    for tri in [[2, 0, 1], [0, 1, 3], [1, 3, 2], [3, 2, 0]] {
        s.add_link("corner", &tri);
    }
    s.add_coupling("left_muscle", &[0, 1]);
    s.add_coupling("right_muscle", &[2, 3]);
    s
}

/// The frog's heading at frame `t`, radians from +x (counter-clockwise positive): the
/// direction from the heavy particles' midpoint to the light ones'.
pub fn frog_heading(traj: &Trajectory, t: usize) -> f64 {
    let mid = |a: usize, b: usize| -> Vec3 { 0.5 * (traj.pos(t, a) + traj.pos(t, b)) };
    let d = mid(1, 3) - mid(0, 2);
    d.y.atan2(d.x)
}
