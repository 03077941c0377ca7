//! Provot's cloth (§4.2): a square mesh with six spring types and an elongation limit.

use super::{q, q3};
use crate::{LinkKind, LinkType, OptionalParam, Particle, Scene};

/// The cloth is meant to be simulated for 400 frames (0.8 s at dt = 0.002 s): it falls from
/// horizontal, swings past the vertical and stretches against the Provot limit.
pub const CLOTH_FRAMES: usize = 400;

/// Mesh period, m (a 32 × 32 cloth is about 1 m square).
const PITCH: f64 = 0.03125;
/// Mass of each particle, kg.
const MASS: f64 = 0.001;
/// Provot's critical deformation rate τc on the structural springs.
const TAU_C: f64 = 0.1;

/// An `nx` × `ny` cloth (particles along x and z), horizontal at y = 0, its z = 0 edge pinned
/// (fixed particles) and the rest falling under gravity (dt = 0.002 s). Six spring types in
/// Provot's mesh: structural horizontal (along x) and vertical (along z) neighbours with
/// `max_elongation` τc = 0.1, the two shear diagonals, and bend springs two apart along x and
/// along z; the shear and bend types are damped. The structural springs are soft (the cloth
/// would stretch by half under its own weight), so the Provot limit holds it. Every type has
/// instances when `nx, ny ≥ 3`. Meant for [`CLOTH_FRAMES`] frames.
pub fn cloth(nx: usize, ny: usize) -> Scene {
    let mut scene = Scene::new(0.002);
    scene.gravity = [0.0, -9.81, 0.0];
    let id = |i: usize, j: usize| j * nx + i;
    for j in 0..ny {
        for i in 0..nx {
            let p = Particle::new(MASS, q3([i as f64 * PITCH, 0.0, j as f64 * PITCH]));
            scene.add_particle(if j == 0 { p.fixed() } else { p });
        }
    }
    let diagonal = q(PITCH * std::f64::consts::SQRT_2);
    let types = [
        ("structural_h", 20.0, PITCH, 0.002),
        ("structural_v", 20.0, PITCH, 0.002),
        ("shear_down", 5.0, diagonal, 0.001),
        ("shear_up", 5.0, diagonal, 0.001),
        ("bend_h", 2.0, 2.0 * PITCH, 0.0005),
        ("bend_v", 2.0, 2.0 * PITCH, 0.0005),
    ];
    for (name, k, l0, z) in types {
        let mut t = LinkType::new(name, LinkKind::Spring)
            .with("stiffness", k)
            .with("rest_length", l0)
            .with("damping", z);
        if name.starts_with("structural") {
            t.set_optional(OptionalParam::MaxElongation, Some(TAU_C.into()));
        }
        scene.add_type(t);
    }
    // Links are listed type by type, rows from the pinned edge outward: the Provot pass runs
    // in this order, so each correction propagates away from the fixed edge in one step.
    for j in 0..ny {
        for i in 0..nx.saturating_sub(1) {
            scene.add_link("structural_h", &[id(i, j), id(i + 1, j)]);
        }
    }
    for j in 0..ny.saturating_sub(1) {
        for i in 0..nx {
            scene.add_link("structural_v", &[id(i, j), id(i, j + 1)]);
        }
    }
    for j in 0..ny.saturating_sub(1) {
        for i in 0..nx.saturating_sub(1) {
            scene.add_link("shear_down", &[id(i, j), id(i + 1, j + 1)]);
            scene.add_link("shear_up", &[id(i + 1, j), id(i, j + 1)]);
        }
    }
    for j in 0..ny {
        for i in 0..nx.saturating_sub(2) {
            scene.add_link("bend_h", &[id(i, j), id(i + 2, j)]);
        }
    }
    for j in 0..ny.saturating_sub(2) {
        for i in 0..nx {
            scene.add_link("bend_v", &[id(i, j), id(i, j + 2)]);
        }
    }
    scene
}
