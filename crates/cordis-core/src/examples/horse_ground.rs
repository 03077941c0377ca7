//! The horse of §4.4 with gravity and the ground under its feet (issue 19): the thesis ran it
//! weightless "with no ground"; here every marker has a `plane` contact with the ground
//! y = [`GROUND_HEIGHT`] and falls under gravity while it gallops forward.

use super::horse::horse;
use crate::Scene;
use crate::{LinkKind, LinkType};

/// 530 frames at dt = 2 ms: the 1.06 s of the thesis' sequence.
pub const HORSE_GROUND_FRAMES: usize = 530;
/// Height of the ground (m): 1 cm under the lowest hoof.
pub const GROUND_HEIGHT: f64 = -0.06;
/// The ground's stiffness (N/m): about 1 cm of sinking under a quarter of the horse's 435 kg.
pub const GROUND_STIFFNESS: f64 = 2.0e5;
/// The ground's damping (N·s/m): ζ ≈ 0.4 on a 2 kg hoof pushed alone.
pub const GROUND_DAMPING: f64 = 500.0;
/// The ground's friction coefficient (turf).
pub const GROUND_FRICTION: f64 = 0.6;

/// [`horse`] with gravity (−9.81 m/s² along y), a `plane` type `ground` (point
/// (0, [`GROUND_HEIGHT`], 0), normal +y, [`GROUND_STIFFNESS`], [`GROUND_DAMPING`],
/// [`GROUND_FRICTION`]) on every marker, and a step ten times smaller than the recording's
/// (dt = 2 ms): a ground stiff enough to carry the horse on its 2 kg hooves is, at 20 ms,
/// far beyond the scheme's stability (`K dt² / 4m` = 10), here 0.1. A passive horse has nothing
/// to hold it up: over [`HORSE_GROUND_FRAMES`] frames it comes down (the midback from 1.58 to
/// 1.25 m above the ground), its belly landing at 4.2 m/s and sinking 5.4 cm, below the
/// `v √(m/K)` = 6.0 cm of a lone 40 kg mass (`tests/ground_contact.rs`).
pub fn horse_ground() -> Scene {
    let mut scene = horse();
    scene.dt = 0.002;
    scene.gravity = [0.0, -9.81, 0.0];
    scene.add_type(
        LinkType::new("ground", LinkKind::Plane)
            .with("stiffness", GROUND_STIFFNESS)
            .with("damping", GROUND_DAMPING)
            .with("friction", GROUND_FRICTION)
            .with_surface([0.0, GROUND_HEIGHT, 0.0], [0.0, 1.0, 0.0]),
    );
    for i in 0..scene.particles.len() {
        scene.add_link("ground", &[i]);
    }
    scene
}
