//! The thesis' target follower (§6.1.2, Figures 6.3-6.5): a visio-motor loop built only of
//! physical primitives. A mobile swims in a two-regime medium towards a target it "sees" with
//! three eyes; a controller world (the thesis' *mental representation*) receives the eyes'
//! distances to the target through position transmitters and sends forces back to the mobile's
//! muscles through force transmitters.
//!
//! **Mobile** (main world, group `mobile`): a tadpole (see [`super::tadpole`]) whose light
//! front particle is the neck (0.08 kg) and whose heavy rear particle is the foot (1 kg),
//! joined by a TGR (40 N/m) driven by a sawtooth (period 1.2 s: the locomotion level; it swims towards
//! its light end, neck first). The head is three eyes (0.05 kg each) on a circle of radius
//! 0.3 m around the neck, held in shape by soft springs. All five are in the two-regime medium
//! (`nonlinear_drag`, Table 6.1's values). The three steering muscles M1-M3 are force
//! transmitters on the dipoles (foot, eye k).
//!
//! **Controller** (world `mind`, same dt): three fixed virtual eyes laid out like the real
//! ones, a fixed virtual neck at their centre, a virtual target and a *gaze* particle on a
//! stiff 0.25 m leash around the virtual neck. Position transmitters make each (virtual eye,
//! virtual target) distance follow the (eye, target) distance, so the virtual target sits where
//! the target is seen from the head (the representation does not translate, only its shape
//! changes, as in the thesis' Figures 6.6-6.9). The thesis' "follow" spring joins the gaze to
//! the virtual target, so the gaze points at the target whatever its distance. Three *gaze
//! springs* join the gaze to the virtual eyes, at rest when the gaze sits at the virtual neck;
//! their tensions, fed to M1-M3, are lowest (negative: a push) for the eye facing the target.
//!
//! **Why it steers**: on the foot, M1-M3 sum to a force across the body away from the target,
//! of a size independent of the target's distance (the gaze's leash saturates it; the
//! tensions' common part cancels over the symmetric eyes), and its reaction pushes the head
//! towards the target side: the foot swings behind the neck and the strokes carry the body
//! to the target. The transmitted forces are central, so they turn the body only as far as
//! the medium resists the head's counter-rotation: the eyes must be in the medium (without
//! drag on them the head just spins and the body does not turn).
//!
//! **Simplifications** of the thesis' architecture, all kept physical: the body is the
//! tadpole's two particles (no separate hips: the foot plays the body, the neck the
//! stabiliser); the steering muscles M1-M3 act between foot and eyes instead of the
//! head-body muscles M1, M2 plus hip-foot muscles M3, M4; the locomotion rhythm comes from a
//! TGR signal rather than from the controller, which only steers; the controller's spring
//! joins a gaze particle (not the virtual neck) to the virtual target, so that the steering
//! does not grow with the distance.
//!
//! **Speed**: about 0.14 m/s (0.11 body lengths/s): from 10 body lengths it is within 25% of
//! the start distance after 6800-7700 frames, depending on the target's direction. The head's
//! springs are soft (12 N/m): a stiffer head swims slower (100 N/m: 0.11 m/s).

use super::q3;
use super::tadpole::{table_6_1_medium, tadpole_muscle, TADPOLE_BODY_LENGTH};
use crate::signal::{Shape, Signal};
use crate::{LinkKind, LinkType, Particle, Scene, Trajectory, Vec3};

/// The follower is meant to be simulated for 8000 frames (80 s).
pub const FOLLOWER_FRAMES: usize = 8000;

/// Time step of both worlds, s.
const DT: f64 = 0.01;

/// Eye circle radius around the neck, m.
const EYE_RADIUS: f64 = 0.3;

/// Body length, m: foot to the eyes' far side.
pub const FOLLOWER_BODY_LENGTH: f64 = TADPOLE_BODY_LENGTH + EYE_RADIUS;

/// Gaze leash length in the controller, m.
const GAZE_RADIUS: f64 = 0.25;

/// The controller world's origin (its virtual neck), placed beside the scene so that both show
/// on one plot (worlds are separate: positions in different worlds never interact).
const MIND_ORIGIN: [f64; 3] = [0.0, -6.0, 0.0];

/// Particle indices of the follower scene.
pub mod idx {
    /// The mobile's neck (light front end).
    pub const NECK: usize = 0;
    /// The mobile's foot (heavy rear end).
    pub const FOOT: usize = 1;
    /// The first of the three eyes (2, 3, 4).
    pub const EYE0: usize = 2;
    /// The target.
    pub const TARGET: usize = 5;
}

/// A follower facing +x (neck at the origin, foot 1 m behind) and a fixed target at
/// `target` (m, z = 0).
pub fn follower_with_target(target: [f64; 3]) -> Scene {
    build(target, true)
}

/// The default follower: a fixed target 10 body lengths ahead and to the left.
pub fn follower() -> Scene {
    let d = 10.0 * FOLLOWER_BODY_LENGTH;
    let a = 30f64.to_radians();
    follower_with_target([d * a.cos(), d * a.sin(), 0.0])
}

/// A follower whose target (group `target`, 1 kg, linear drag 2 N·s/m) starts at `target` and
/// is moved by a TGR from a fixed pole (the last particle, group `target`) placed
/// `pole_offset` (m) away: the tendon follows a slow sine of `period` s, so the target slides
/// back and forth along the pole's line by about ±`sweep` m.
pub fn follower_moving(target: [f64; 3], pole_offset: [f64; 3], sweep: f64, period: f64) -> Scene {
    let mut s = build(target, false);
    let pole = q3([
        target[0] + pole_offset[0],
        target[1] + pole_offset[1],
        target[2] + pole_offset[2],
    ]);
    let reach = Vec3::from(pole_offset).norm();
    let p = s.add_particle(Particle::new(1.0, pole).fixed().in_group("target"));
    // Tendon: y ≈ S / K_t, the link (20 N/m) being much stiffer than the target's drag.
    let kt = 10.0;
    s.add_signal(Signal::new("sweep", Shape::Sine, sweep * kt, period));
    s.add_type(
        LinkType::new("carrier", LinkKind::Tgr)
            .with("stiffness", 12.0)
            .with("rest_length", reach)
            .with("damping", 2.0)
            .with("tendon_mass", 0.1)
            .with("tendon_stiffness", kt)
            .with("tendon_damping", 2.0)
            .with_signal("sweep"),
    );
    s.add_type(LinkType::new("target_drag", LinkKind::Drag).with("damping", 2.0));
    s.add_link("target_drag", &[idx::TARGET]);
    s.add_coupling("carrier", &[p, idx::TARGET]);
    s
}

/// The mobile (0-4), the target (5), the controller (6-11), their links and couplings.
fn build(target: [f64; 3], fixed_target: bool) -> Scene {
    let (p, e) = PARAMS;
    let mut s = Scene::new(DT);
    s.add_world("mind", DT);
    let eye_angles = [90f64, 210.0, 330.0].map(f64::to_radians);
    let eye = |o: [f64; 3], a: f64| {
        [
            o[0] + EYE_RADIUS * a.cos(),
            o[1] + EYE_RADIUS * a.sin(),
            o[2],
        ]
    };

    // Mobile: neck, foot, three eyes.
    let neck = [0.0; 3];
    s.add_particle(Particle::new(p.neck_mass, neck).in_group("mobile"));
    s.add_particle(Particle::new(1.0, [-TADPOLE_BODY_LENGTH, 0.0, 0.0]).in_group("mobile"));
    for a in eye_angles {
        s.add_particle(Particle::new(0.05, eye(neck, a)).in_group("mobile"));
    }
    let mut t = Particle::new(1.0, target).in_group("target");
    if fixed_target {
        t = t.fixed();
    }
    s.add_particle(t);

    // Controller: virtual neck, virtual eyes, virtual target, gaze.
    let rel = Vec3::from(target) - Vec3::from(neck);
    let dir = rel / rel.norm();
    let o = MIND_ORIGIN;
    let mind = |q: Particle| q.in_world("mind");
    let vneck = s.add_particle(mind(Particle::new(1.0, o).fixed()));
    let veyes: Vec<usize> = eye_angles
        .iter()
        .map(|&a| s.add_particle(mind(Particle::new(1.0, eye(o, a)).fixed())))
        .collect();
    let vtarget = s.add_particle(mind(Particle::new(
        1.0,
        q3([o[0] + rel.x, o[1] + rel.y, o[2] + rel.z]),
    )));
    let gaze = s.add_particle(mind(Particle::new(
        0.2,
        q3([
            o[0] + GAZE_RADIUS * dir.x,
            o[1] + GAZE_RADIUS * dir.y,
            o[2] + GAZE_RADIUS * dir.z,
        ]),
    )));

    // Mobile links.
    s.add_type(table_6_1_medium("water"));
    s.add_link("water", &[idx::NECK]);
    s.add_link("water", &[idx::FOOT]);
    for k in 0..3 {
        s.add_link("water", &[idx::EYE0 + k]);
    }
    s.add_type(
        LinkType::new("skull", LinkKind::Spring)
            .with("stiffness", 12.0)
            .with("rest_length", EYE_RADIUS)
            .with("damping", 1.0),
    );
    let side = EYE_RADIUS * 3f64.sqrt();
    s.add_type(
        LinkType::new("brow", LinkKind::Spring)
            .with("stiffness", 12.0)
            .with("rest_length", side)
            .with("damping", 1.0),
    );
    for k in 0..3 {
        s.add_link("skull", &[idx::NECK, idx::EYE0 + k]);
        s.add_link("brow", &[idx::EYE0 + k, idx::EYE0 + (k + 1) % 3]);
    }
    s.add_signal(
        Signal::new("stroke", Shape::Sawtooth, e.amplitude, e.period)
            .with_rise(0.9)
            .with_phase(0.75),
    );
    s.add_type(tadpole_muscle("body", "stroke").with("stiffness", 40.0));
    s.add_coupling("body", &[idx::NECK, idx::FOOT]);

    // Controller links.
    s.add_type(
        LinkType::new("leash", LinkKind::Spring)
            .with("stiffness", 200.0)
            .with("rest_length", GAZE_RADIUS)
            .with("damping", 2.0),
    );
    s.add_link("leash", &[vneck, gaze]);
    s.add_type(
        LinkType::new("follow", LinkKind::Spring)
            .with("stiffness", p.follow)
            .with("rest_length", 0.0),
    );
    s.add_link("follow", &[gaze, vtarget]);
    s.add_type(LinkType::new("mind_drag", LinkKind::Drag).with("damping", p.mind_drag));
    s.add_link("mind_drag", &[gaze]);
    s.add_link("mind_drag", &[vtarget]);
    s.add_type(
        LinkType::new("gaze_spring", LinkKind::Spring)
            .with("stiffness", 1.0)
            .with("rest_length", EYE_RADIUS),
    );
    let sources: Vec<usize> = veyes
        .iter()
        .map(|&v| s.add_link("gaze_spring", &[v, gaze]))
        .collect();

    // Couplings: the eyes see the target; M1-M3 steer.
    s.add_type(
        LinkType::new("vision", LinkKind::PositionTransmitter)
            .with("stiffness", 500.0)
            .with("damping", 0.5),
    );
    for (k, &v) in veyes.iter().enumerate() {
        s.add_coupling("vision", &[idx::EYE0 + k, idx::TARGET, v, vtarget]);
    }
    s.add_type(LinkType::new("steer", LinkKind::ForceTransmitter).with("gain", p.gain));
    for (k, &source) in sources.iter().enumerate() {
        s.add_force_transmitter("steer", [idx::FOOT, idx::EYE0 + k], source);
    }
    s
}

/// Tuning, chosen by simulation (see tests/follower.rs): neck mass (kg), follow-spring
/// stiffness (N/m), drag on the gaze and the virtual target (N·s/m), steering gain M1-M3.
struct Tuning {
    neck_mass: f64,
    follow: f64,
    mind_drag: f64,
    gain: f64,
}

/// The locomotion rhythm: sawtooth amplitude on the tendon (N) and period (s). Shorter
/// strokes than the tadpole's (4 s) swim faster and keep the heading steadier.
struct Stroke {
    amplitude: f64,
    period: f64,
}

const PARAMS: (Tuning, Stroke) = (
    Tuning {
        neck_mass: 0.08,
        follow: 1.0,
        mind_drag: 5.0,
        gain: 4.0,
    },
    Stroke {
        amplitude: 3.5,
        period: 1.2,
    },
);

/// Distance from the mobile's neck to the target at frame `t`, m.
pub fn follower_distance(traj: &Trajectory, t: usize) -> f64 {
    (traj.pos(t, idx::TARGET) - traj.pos(t, idx::NECK)).norm()
}
