//! The thesis' quasi-rigid object (§4.1): 15 masses, 10 spring types (20 identifiable
//! parameters: K and l0 of each, no damping), 31 links, thrown and spinning under gravity.

use super::{dist, q, q3, SplitMix64};
use crate::{LinkKind, LinkType, Particle, Scene};

/// The rigid object is meant to be simulated for 100 frames (1 s at dt = 0.01 s), the length
/// of the thesis' identification runs.
pub const RIGID_FRAMES: usize = 100;

const COLS: usize = 5;
const ROWS: usize = 3;
/// Lattice pitch along x and y before jitter, m.
const PITCH: [f64; 2] = [0.3, 0.25];
/// Launch velocity of the centre of mass (m/s) and spin about z (rad/s).
const THROW: [f64; 3] = [3.0, 4.0, 0.0];
const SPIN: f64 = 1.5;

/// The ten types: (name, stiffness N/m, rest length as a fraction of the mean initial length of
/// the type's links). Rest lengths 0.5–1 % off the initial shape pre-stress the object, so that
/// every type vibrates from frame 0 and the identification sees each one.
const TYPES: [(&str, f64, f64); 10] = [
    ("h_bottom", 1050.0, 1.006),
    ("h_middle", 1275.0, 0.994),
    ("h_top", 950.0, 1.007),
    ("v_end", 1150.0, 0.992),
    ("v_inner", 825.0, 1.009),
    ("v_center", 1375.0, 0.991),
    ("diag_low_left", 750.0, 1.005),
    ("diag_low_right", 900.0, 0.995),
    ("diag_high", 1100.0, 1.006),
    ("brace", 625.0, 0.994),
];

/// A planar (z = 0) 5 × 3 truss, triangulated and braced corner to corner, launched upward
/// and spinning under gravity (dt = 0.01 s). Stiff springs (625–1375 N/m on 0.5–1.5 kg) keep
/// the shape within a few % while every type vibrates; damping is 0 so the 20 parameters are
/// K and l0 of the ten types. Meant for [`RIGID_FRAMES`] frames.
pub fn rigid() -> Scene {
    let mut rng = SplitMix64::new(0x0052_4947_4944); // "RIGID"
    let mut scene = Scene::new(0.01);
    scene.gravity = [0.0, -9.81, 0.0];

    let node = |c: usize, r: usize| r * COLS + c;
    let mut pos = Vec::with_capacity(COLS * ROWS);
    let mut mass = Vec::with_capacity(COLS * ROWS);
    for r in 0..ROWS {
        for c in 0..COLS {
            pos.push([
                c as f64 * PITCH[0] + rng.uniform(-0.0015, 0.0015),
                r as f64 * PITCH[1] + rng.uniform(-0.0015, 0.0015),
                0.0,
            ]);
            mass.push(q(rng.uniform(0.5, 1.5)));
        }
    }
    let total: f64 = mass.iter().sum();
    let centre = (0..2).map(|k| pos.iter().zip(&mass).map(|(p, m)| p[k] * m).sum::<f64>() / total);
    let centre: Vec<f64> = centre.collect();
    for (p, &m) in pos.iter().zip(&mass) {
        let (rx, ry) = (p[0] - centre[0], p[1] - centre[1]);
        // Rigid motion: v = v_c + ω ẑ × r.
        let vel = [THROW[0] - SPIN * ry, THROW[1] + SPIN * rx, 0.0];
        scene.add_particle(Particle::new(m, q3(*p)).with_vel(q3(vel)));
    }

    let mut links: Vec<(usize, [usize; 2])> = Vec::new();
    for r in 0..ROWS {
        for c in 0..COLS - 1 {
            links.push((r, [node(c, r), node(c + 1, r)]));
        }
    }
    for c in 0..COLS {
        let t = match c {
            0 | 4 => 3,
            2 => 5,
            _ => 4,
        };
        for r in 0..ROWS - 1 {
            links.push((t, [node(c, r), node(c, r + 1)]));
        }
    }
    for r in 0..ROWS - 1 {
        for c in 0..COLS - 1 {
            let t = match (r, c) {
                (0, 0 | 1) => 6,
                (0, _) => 7,
                _ => 8,
            };
            // Alternate the diagonal's direction so the truss has no preferred shear.
            let ends = if (r + c) % 2 == 0 {
                [node(c, r), node(c + 1, r + 1)]
            } else {
                [node(c + 1, r), node(c, r + 1)]
            };
            links.push((t, ends));
        }
    }
    links.push((9, [node(0, 0), node(COLS - 1, ROWS - 1)]));

    for (t, (name, k, stretch)) in TYPES.iter().enumerate() {
        let lengths: Vec<f64> = links
            .iter()
            .filter(|(lt, _)| *lt == t)
            .map(|(_, [i, j])| dist(scene.particles[*i].pos, scene.particles[*j].pos))
            .collect();
        let mean = lengths.iter().sum::<f64>() / lengths.len() as f64;
        scene.add_type(
            LinkType::new(*name, LinkKind::Spring)
                .with("stiffness", *k)
                .with("rest_length", q(mean * stretch)),
        );
    }
    for (t, ends) in &links {
        scene.add_link(TYPES[*t].0, ends);
    }
    scene
}
