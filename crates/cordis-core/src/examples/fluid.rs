//! A 2-D jet entering a gas at rest (§4.3, after Luciani's turbulent flows): conditional
//! visco-elastic links between nearby particles, found anew at every step.

use super::{q, q3, SplitMix64};
use crate::{LinkKind, LinkType, Particle, Scene};

/// The jet is meant to be simulated for 400 frames (8 s at dt = 0.02 s); the thesis shows
/// frames 100 to 400 of its sequence.
pub const FLUID_FRAMES: usize = 400;

/// Lattice pitch (m): the mean spacing of the fluid at rest.
const PITCH: f64 = 1.0;
/// Wall particles are this far apart along the walls, m (close enough that no particle slips
/// between two of them).
const WALL_PITCH: f64 = 0.5;
/// Speed of the jet at frame 0, m/s (about three times the gas's speed of sound).
const JET_SPEED: f64 = 5.0;

/// A box of `cols` × `rows` fluid particles on a triangular lattice (pitch 1 m, z = 0),
/// bounded by fixed `wall` particles half a pitch apart, dt = 0.02 s, no gravity. A block of
/// `jet` particles at the left, mid-height (the first `cols / 4` columns of the middle
/// `rows / 6` rows), starts at 5 m/s into the `gas` at rest; it drives into the gas, spreads
/// into a mushroom head and leaves a wake. Conditional types, one per group pair and effect:
/// `gas_elastic`, `jet_elastic`, `jet_gas_elastic` (K = 2 N/m, rest length = range = 1.1 m:
/// a pressure, since the lattice starts 10 % compressed), `gas_viscous`, `jet_viscous`,
/// `jet_gas_viscous` (K = 0, damping 0.5–1 N·s/m, range 1.5 m, 2 m for the jet), and the
/// repulsive `wall_gas`, `wall_jet` (K = 40 N/m, rest length = range = 1 m). The default
/// `fluid(80, 48)` has 4,338 particles (498 of them walls) and about 23,000 pairs in range at
/// frame 0. Meant for [`FLUID_FRAMES`] frames.
pub fn fluid(cols: usize, rows: usize) -> Scene {
    let mut rng = SplitMix64::new(0x0046_4C55_4944); // "FLUID"
    let mut scene = Scene::new(0.02);
    let row_h = PITCH * 3f64.sqrt() / 2.0;
    let jet_cols = cols.div_ceil(4);
    let jet_rows = rows.div_ceil(6);
    let jet_row0 = (rows - jet_rows.min(rows)) / 2;
    for r in 0..rows {
        for c in 0..cols {
            let shift = if r % 2 == 1 { 0.5 } else { 0.0 };
            // A small jitter breaks the lattice's symmetry so the flow can become irregular.
            let pos = [
                (c as f64 + shift) * PITCH + rng.uniform(-0.02, 0.02),
                r as f64 * row_h + rng.uniform(-0.02, 0.02),
                0.0,
            ];
            let in_jet = c < jet_cols && (jet_row0..jet_row0 + jet_rows).contains(&r);
            let p = Particle::new(1.0, q3(pos));
            scene.add_particle(if in_jet {
                p.with_vel([JET_SPEED, 0.0, 0.0]).in_group("jet")
            } else {
                p.in_group("gas")
            });
        }
    }
    if cols > 0 && rows > 0 {
        // Walls one pitch outside the lattice's box: no wall force at frame 0.
        let (x0, y0) = (-PITCH, -PITCH);
        let x1 = (cols as f64 - 0.5) * PITCH + PITCH;
        let y1 = (rows - 1) as f64 * row_h + PITCH;
        let nx = ((x1 - x0) / WALL_PITCH).ceil() as usize;
        let ny = ((y1 - y0) / WALL_PITCH).ceil() as usize;
        let mut wall = |x: f64, y: f64| {
            scene.add_particle(Particle::new(1.0, q3([x, y, 0.0])).fixed().in_group("wall"));
        };
        for k in 0..nx {
            let x = x0 + (x1 - x0) * k as f64 / nx as f64;
            wall(x, y0);
            wall(x1 + x0 - x, y1);
        }
        for k in 0..ny {
            let y = y0 + (y1 - y0) * k as f64 / ny as f64;
            wall(x1, y);
            wall(x0, y1 + y0 - y);
        }
    }
    // Pressure: repulsive springs whose rest length is their range, 10 % beyond the lattice
    // pitch, so the gas starts compressed and its force vanishes continuously at the range.
    // Viscosity: pure dampers along the pair (K = 0), reaching further (after the thesis'
    // separate elastic and viscous conditional links, Table 4.2).
    let conditional = |name: &str, groups: &[&str], k: f64, l0: f64, z: f64, range: f64| {
        let mut t = LinkType::new(name, LinkKind::Conditional)
            .with("stiffness", k)
            .with("rest_length", q(l0 * PITCH))
            .with("damping", z)
            .with("range", q(range * PITCH));
        t.groups = groups.iter().map(|g| g.to_string()).collect();
        t
    };
    scene.add_type(conditional("gas_elastic", &["gas"], 2.0, 1.1, 0.0, 1.1));
    scene.add_type(conditional("jet_elastic", &["jet"], 2.0, 1.1, 0.0, 1.1));
    scene.add_type(conditional(
        "jet_gas_elastic",
        &["jet", "gas"],
        2.0,
        1.1,
        0.0,
        1.1,
    ));
    scene.add_type(conditional("gas_viscous", &["gas"], 0.0, 0.0, 0.5, 1.5));
    scene.add_type(conditional("jet_viscous", &["jet"], 0.0, 0.0, 1.0, 2.0));
    scene.add_type(conditional(
        "jet_gas_viscous",
        &["jet", "gas"],
        0.0,
        0.0,
        0.5,
        1.5,
    ));
    // Walls repel only, and start one pitch (their range) away from the fluid.
    scene.add_type(conditional(
        "wall_gas",
        &["wall", "gas"],
        40.0,
        1.0,
        1.0,
        1.0,
    ));
    scene.add_type(conditional(
        "wall_jet",
        &["wall", "jet"],
        40.0,
        1.0,
        1.0,
        1.0,
    ));
    // A box too small for a jet (fewer than 4 columns) has no jet particles: a type whose
    // group is empty is an error (it could never act), so it is left out.
    let has = |g: &String| scene.particles.iter().any(|p| p.group.as_ref() == Some(g));
    let kept: Vec<LinkType> = std::mem::take(&mut scene.types)
        .into_iter()
        .filter(|t| t.groups.iter().all(has))
        .collect();
    scene.types = kept;
    scene
}
