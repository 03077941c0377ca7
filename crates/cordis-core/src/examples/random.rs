//! Seed-generated random spring networks: test and benchmark scenes of any size, not one of the
//! shipped examples (not in [`super::NAMES`]).

use super::{dist, q, q3, SplitMix64};
use crate::{LinkKind, LinkType, Particle, Scene};

/// Lattice pitch the particles are jittered around, m.
const PITCH: f64 = 0.5;
/// Neighbours closer than this many pitches are linked.
const REACH: f64 = 1.75;

/// A random 3-D network of `masses` particles (at least 3) and `types` spring types (at least
/// 1), the same for the same arguments on every machine.
///
/// Particles sit on a jittered cubic lattice (pitch 0.5 m) with masses 0.5–2 kg and random
/// initial velocities (±0.6 m/s per axis); the first one is fixed, so gravity (−9.81 m/s² along
/// y) swings the network about it. Every pair closer than 1.75 pitches is linked (and every
/// particle gets at least its nearest neighbour), each link by a random type; every type has
/// at least one link. Types: stiffness 40–160 N/m, rest length the mean initial length of its
/// links times 0.9–1.1 (so every type is under tension or compression from frame 0), damping
/// 0.05–0.3 N·s/m on every other type (0 on the others). dt = 0.005 s keeps the stiffest
/// particle well inside the explicit scheme's stability limit for a few hundred frames.
pub fn random_network(seed: u64, masses: usize, types: usize) -> Scene {
    let masses = masses.max(3);
    let types = types.max(1);
    let mut rng = SplitMix64::new(seed ^ 0x5241_4e44_4f4d); // "RANDOM"
    let mut scene = Scene::new(0.005);
    scene.gravity = [0.0, -9.81, 0.0];
    let side = (masses as f64).cbrt().ceil() as usize;
    let jitter = 0.15 * PITCH;
    let mut pos = Vec::with_capacity(masses);
    for n in 0..masses {
        let (a, b, c) = (n % side, (n / side) % side, n / (side * side));
        pos.push(q3([
            a as f64 * PITCH + rng.uniform(-jitter, jitter),
            b as f64 * PITCH + rng.uniform(-jitter, jitter),
            c as f64 * PITCH + rng.uniform(-jitter, jitter),
        ]));
    }
    for (n, &p) in pos.iter().enumerate() {
        let vel = q3([
            rng.uniform(-0.6, 0.6),
            rng.uniform(-0.6, 0.6),
            rng.uniform(-0.6, 0.6),
        ]);
        let particle = Particle::new(q(rng.uniform(0.5, 2.0)), p).with_vel(vel);
        scene.add_particle(if n == 0 { particle.fixed() } else { particle });
    }

    let mut pairs = Vec::new();
    for i in 0..masses {
        for j in i + 1..masses {
            if dist(pos[i], pos[j]) < REACH * PITCH {
                pairs.push([i, j]);
            }
        }
    }
    for i in 0..masses {
        if !pairs.iter().any(|p| p.contains(&i)) {
            let nearest = (0..masses)
                .filter(|&j| j != i)
                .min_by(|&a, &b| dist(pos[i], pos[a]).total_cmp(&dist(pos[i], pos[b])));
            if let Some(j) = nearest {
                pairs.push([i.min(j), i.max(j)]);
            }
        }
    }
    // The first `types` links take one type each (in a random order), the rest random types.
    let mut of: Vec<usize> = (0..pairs.len())
        .map(|_| (rng.next_u64() % types as u64) as usize)
        .collect();
    let n_pairs = pairs.len();
    for (t, ty) in of.iter_mut().enumerate().take(types.min(n_pairs)) {
        let k = t + (rng.next_u64() % (n_pairs - t) as u64) as usize;
        pairs.swap(t, k);
        *ty = t;
    }

    for t in 0..types {
        let lengths: Vec<f64> = pairs
            .iter()
            .zip(&of)
            .filter(|(_, &ty)| ty == t)
            .map(|([i, j], _)| dist(pos[*i], pos[*j]))
            .collect();
        let mean = if lengths.is_empty() {
            PITCH
        } else {
            lengths.iter().sum::<f64>() / lengths.len() as f64
        };
        let damping = if t % 2 == 1 {
            q(rng.uniform(0.05, 0.3))
        } else {
            0.0
        };
        scene.add_type(
            LinkType::new(format!("t{t}"), LinkKind::Spring)
                .with("stiffness", q(rng.uniform(40.0, 160.0)))
                .with("rest_length", q(mean * rng.uniform(0.9, 1.1)))
                .with("damping", damping),
        );
    }
    for (ends, t) in pairs.iter().zip(&of) {
        scene.add_link(&format!("t{t}"), ends);
    }
    scene
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn is_deterministic_valid_and_uses_every_type() {
        for (seed, n, t) in [(1, 10, 3), (7, 30, 8), (3, 3, 1)] {
            let a = random_network(seed, n, t);
            assert_eq!(a, random_network(seed, n, t));
            a.validate().unwrap();
            assert_eq!((a.particles.len(), a.types.len()), (n, t));
            for ty in 0..t {
                assert!(a.links.iter().any(|l| l.type_index == ty), "type {ty}");
            }
            let traj = a.simulate(300).unwrap();
            assert!(traj.as_flat().iter().all(|x| x.abs() < 100.0));
        }
        assert_ne!(random_network(1, 10, 3), random_network(2, 10, 3));
    }
}
