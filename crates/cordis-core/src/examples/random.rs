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

/// The generated networks of `cordis bench noise` (and the tracked-motion tests):
/// [`random_network`]`(7000 + seed, masses, types)` with every spring type damped (0.02–0.3
/// N·s/m from the seed), a damper between particles 1 and `masses - 1`, air drag on particles 2
/// and `masses - 2`, and an anchor (25 N/m, 0.2 m, 0.05 N·s/m) from particle `masses / 2` to a
/// point beside it: every kind the output-error estimator differentiates. `masses` ≥ 4.
pub fn tracked_network(seed: u64, masses: usize, types: usize) -> Scene {
    let mut truth = random_network(7_000 + seed, masses, types);
    for (k, t) in truth.types.iter_mut().enumerate() {
        let u = ((seed * 11 + k as u64 * 17) % 31) as f64 / 31.0;
        t.params[2] = crate::Param::Known(0.02 + 0.28 * u);
    }
    truth.add_type(LinkType::new("dashpot", LinkKind::Damper).with("damping", 0.12));
    truth.add_type(LinkType::new("air", LinkKind::Drag).with("damping", 0.05));
    truth.add_type(
        LinkType::new("tether", LinkKind::Anchor)
            .with("stiffness", 25.0)
            .with("rest_length", 0.2)
            .with("damping", 0.05),
    );
    truth.add_link("dashpot", &[1, masses - 1]);
    truth.add_link("air", &[2]);
    truth.add_link("air", &[masses - 2]);
    let a = truth.add_link("tether", &[masses / 2]);
    let x = truth.particles[masses / 2].pos;
    truth.links[a].point = Some([x[0] + 0.3, x[1] + 0.1, x[2] - 0.1]);
    truth
}

/// The networks of `cordis bench noise` (issue 16): [`tracked_network`]`(seed, masses, types)`
/// plus angle links — two angle types (stiffness 5–30 N·m, rest cosine the mean of its
/// triples' initial cosines shifted by ±0.1, so they are loaded from frame 0) on up to
/// `masses / 3` triples `(i, j, k)` of linked particles (j linked to both) whose initial angle
/// is neither near straight nor near square (`0.3 ≤ |cos θ| ≤ 0.9`: at a straight angle the
/// force `∝ sin θ` vanishes, and a rest cosine near 0 makes its relative error meaningless).
/// Triples are taken in a seed-drawn order, at most one per middle particle.
pub fn tracked_network_with_angles(seed: u64, masses: usize, types: usize) -> Scene {
    let mut scene = tracked_network(seed, masses, types);
    let mut rng = SplitMix64::new(seed ^ 0x414e_474c_4553); // "ANGLES"
    let n = scene.particles.len();
    let mut adj = vec![Vec::new(); n];
    for l in &scene.links {
        if let [a, b] = l.particles[..] {
            if scene.types[l.type_index].kind == LinkKind::Spring {
                adj[a].push(b);
                adj[b].push(a);
            }
        }
    }
    let pos: Vec<[f64; 3]> = scene.particles.iter().map(|p| p.pos).collect();
    let cosine = |i: usize, j: usize, k: usize| {
        let a: Vec<f64> = (0..3).map(|c| pos[i][c] - pos[j][c]).collect();
        let b: Vec<f64> = (0..3).map(|c| pos[k][c] - pos[j][c]).collect();
        let dot: f64 = (0..3).map(|c| a[c] * b[c]).sum();
        dot / (dist(pos[i], pos[j]) * dist(pos[k], pos[j]))
    };
    let mut order: Vec<usize> = (0..n).collect();
    for t in (1..n).rev() {
        order.swap(t, (rng.next_u64() % (t as u64 + 1)) as usize);
    }
    let mut triples = Vec::new();
    for &j in &order {
        if triples.len() >= masses / 3 {
            break;
        }
        let pick = adj[j].iter().enumerate().find_map(|(x, &i)| {
            adj[j][x + 1..]
                .iter()
                .find(|&&k| (0.3..=0.9).contains(&cosine(i, j, k).abs()))
                .map(|&k| [i, j, k])
        });
        triples.extend(pick);
    }
    for t in 0..2 {
        let mine: Vec<&[usize; 3]> = triples.iter().skip(t).step_by(2).collect();
        if mine.is_empty() {
            continue;
        }
        let mean = mine.iter().map(|&&[i, j, k]| cosine(i, j, k)).sum::<f64>() / mine.len() as f64;
        let shift = rng.uniform(-0.1, 0.1);
        let name = format!("bend{t}");
        scene.add_type(
            LinkType::new(&name, LinkKind::Angle)
                .with("stiffness", q(rng.uniform(5.0, 30.0)))
                .with("rest_cos", q((mean + shift).clamp(-0.95, 0.95))),
        );
        for &&[i, j, k] in &mine {
            scene.add_link(&name, &[i, j, k]);
        }
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

    #[test]
    fn the_noise_benchs_networks_carry_loaded_angles_and_stay_bounded() {
        for (seed, n) in [(0, 12), (1, 20), (2, 30), (3, 17)] {
            let s = tracked_network_with_angles(seed, n, 7);
            s.validate().unwrap();
            let angles: Vec<_> = s
                .links
                .iter()
                .filter(|l| s.types[l.type_index].kind == LinkKind::Angle)
                .collect();
            assert!(
                !angles.is_empty() && angles.len() <= n / 3,
                "seed {seed}: {}",
                angles.len()
            );
            let traj = s.simulate(200).unwrap();
            assert!(
                traj.as_flat().iter().all(|x| x.abs() < 100.0),
                "seed {seed}"
            );
        }
    }
}
