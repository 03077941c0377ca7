//! A ball dropped on the ground (the `plane` contact, [`crate::forces::plane`]): one particle
//! thrown sideways from 1 m under gravity, bouncing on the plane z = 0 and sliding with
//! friction until it sticks. Its contact parameters (stiffness, damping, friction) are what
//! identification recovers from the motion (`tests/ground_contact.rs`).

use crate::{LinkKind, LinkType, Particle, Scene};

/// The ball is meant to be simulated for 2000 frames (2 s at dt = 1 ms): four bounces, each
/// losing 45 % of the energy of the normal motion (e = 0.744) and some of the sliding speed.
pub const BALL_FRAMES: usize = 2000;
/// Mass of the ball, kg.
pub const BALL_MASS: f64 = 0.5;
/// The ground's stiffness (N/m): `ω₀ = √(K/m) = 200 rad/s`, a contact of about 16 ms
/// (16 steps).
pub const BALL_STIFFNESS: f64 = 2.0e4;
/// The ground's damping (N·s/m): `ζ = Z / (2√(K m)) = 0.1`, a restitution of 0.744.
pub const BALL_DAMPING: f64 = 20.0;
/// The ground's friction coefficient.
pub const BALL_FRICTION: f64 = 0.2;

/// The ball (0.5 kg) at (0, 0, 1) m moving at 4 m/s along x, gravity −9.81 m/s² along z, and a
/// `plane` type `ground` (point at the origin, normal +z) with [`BALL_STIFFNESS`],
/// [`BALL_DAMPING`] and [`BALL_FRICTION`]; dt = 1 ms. Meant for [`BALL_FRAMES`] frames.
pub fn bouncing_ball() -> Scene {
    let mut scene = Scene::new(1e-3);
    scene.gravity = [0.0, 0.0, -9.81];
    scene.add_particle(Particle::new(BALL_MASS, [0.0, 0.0, 1.0]).with_vel([4.0, 0.0, 0.0]));
    scene.add_type(
        LinkType::new("ground", LinkKind::Plane)
            .with("stiffness", BALL_STIFFNESS)
            .with("damping", BALL_DAMPING)
            .with("friction", BALL_FRICTION)
            .with_surface([0.0, 0.0, 0.0], [0.0, 0.0, 1.0]),
    );
    scene.add_link("ground", &[0]);
    scene
}
