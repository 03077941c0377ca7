//! Seed-generated networks for surveying structure discovery (issue 20), built independently of
//! [`super::random_network`] (which `cordis discover` was first calibrated on): no lattice,
//! every particle's degree drawn in 1–6, pre-stressed rest lengths, planar or 3-D, gravity on or
//! off, fixed particles, dampers and anchors — each case from the seed.

use super::{dist, q, q3, SplitMix64};
use crate::{LinkKind, LinkType, Particle, Scene};

/// Least distance between two particles, m (the mean spacing is ~0.5 m).
const MIN_SPACING: f64 = 0.22;
/// A particle's links go to its nearest neighbours, at most this many away in rank.
pub const VARIED_MAX_RANK: usize = 8;

/// The cases one [`varied_network`] draw covers (for a survey to tabulate by).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct VariedCase {
    pub planar: bool,
    pub gravity: bool,
    pub fixed: usize,
    pub dampers: usize,
    pub anchors: usize,
}

/// What a [`varied_network`] draw may contain; [`VariedKinds::ALL`] is every case.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct VariedKinds {
    /// Damper links (kind `damper`) between particles not linked by a spring.
    pub dampers: bool,
    /// Anchors (kind `anchor`): a spring from a particle to a point on a wall, which carries a
    /// marker (a fixed particle at the point, linked to nothing else).
    pub anchors: bool,
}

impl VariedKinds {
    pub const ALL: VariedKinds = VariedKinds {
        dampers: true,
        anchors: true,
    };
    pub const SPRINGS: VariedKinds = VariedKinds {
        dampers: false,
        anchors: false,
    };
}

/// A network of 8–24 particles drawn from `seed` (the same on every machine):
///
/// - positions uniform in a cube (3-D) or a square in z = 0 (planar, one draw in three, with
///   in-plane gravity and velocities), at least 0.22 m apart, ~0.5 m mean spacing;
/// - each particle wants a degree drawn uniformly in 1–6 and is linked to its nearest
///   neighbours (rank ≤ [`VARIED_MAX_RANK`]) that still have room, then components are joined
///   by their closest pair — so degrees run 1–6 (a join may add one);
/// - 2–6 spring types grouped by length (one type per length band), stiffness 30–250 N/m
///   log-uniform, rest length the band's mean length × 0.85–1.15 (every link pre-stressed),
///   damping 0.02–0.3 N·s/m on about half the types, 0 on the others;
/// - masses 0.3–3 kg log-uniform; gravity −9.81 m/s² along y in two draws of three;
/// - 0–2 fixed particles; with `kinds.dampers`, 0–2 dampers (0.05–0.4 N·s/m); with
///   `kinds.anchors`, an anchor (40–150 N/m to a point 0.2–0.4 m away, marked by a fixed
///   particle appended last) in one draw of four;
/// - thrown and spinning: a common velocity (±1 m/s), an angular velocity (±3 rad/s) about the
///   centroid, and ±0.5 m/s per particle per axis, so every link changes length.
///
/// dt = 0.005 s keeps every particle far inside the explicit scheme's stability limit
/// (ω·dt ≤ 0.6 for the stiffest possible particle).
pub fn varied_network(seed: u64, kinds: VariedKinds) -> (Scene, VariedCase) {
    let mut rng = SplitMix64::new(seed ^ 0x5641_5249_4544); // "VARIED"
    let n = 8 + (rng.next_u64() % 17) as usize;
    let planar = rng.next_u64() % 3 == 0;
    let gravity = rng.next_u64() % 3 != 0;
    let pos = place_particles(&mut rng, n, planar);
    let pairs = draw_links(&mut rng, &pos);
    let mut scene = Scene::new(0.005);
    if gravity {
        scene.gravity = [0.0, -9.81, 0.0];
    }
    let of = add_spring_types(&mut rng, &mut scene, &pos, &pairs);
    let fixed = add_particles(&mut rng, &mut scene, &pos, planar);
    for (k, ends) in pairs.iter().enumerate() {
        scene.add_link(&format!("s{}", of[k]), ends);
    }
    let mut case = VariedCase {
        planar,
        gravity,
        fixed: fixed.iter().filter(|f| **f).count(),
        ..VariedCase::default()
    };
    if kinds.dampers {
        case.dampers = add_dampers(&mut rng, &mut scene, &pos, &fixed);
    }
    if kinds.anchors && rng.next_u64() % 4 == 0 {
        case.anchors = add_anchor(&mut rng, &mut scene, &pos, &fixed, planar);
    }
    (scene, case)
}

/// `n` positions uniform in a cube (3-D) or a square in z = 0 (planar) of side 0.5 n^(1/3)
/// (or 0.5 √n) m, at least [`MIN_SPACING`] apart (the spacing shrunk by 10 % whenever 200
/// draws find no room).
fn place_particles(rng: &mut SplitMix64, n: usize, planar: bool) -> Vec<[f64; 3]> {
    let side = if planar {
        0.5 * (n as f64).sqrt()
    } else {
        0.5 * (n as f64).cbrt()
    };
    let mut pos: Vec<[f64; 3]> = Vec::with_capacity(n);
    let mut spacing = MIN_SPACING;
    while pos.len() < n {
        let mut placed = false;
        for _ in 0..200 {
            let p = q3([
                rng.uniform(0.0, side),
                rng.uniform(0.0, side),
                if planar { 0.0 } else { rng.uniform(0.0, side) },
            ]);
            if pos.iter().all(|o| dist(*o, p) >= spacing) {
                pos.push(p);
                placed = true;
                break;
            }
        }
        if !placed {
            spacing *= 0.9;
        }
    }
    pos
}

/// 2–6 spring types (at most one per link) by length band (the links sorted by length, cut into bands of equal
/// counts): stiffness log-uniform in 30–250 N/m, rest length the band's mean × 0.85–1.15,
/// damping 0.02–0.3 N·s/m on about half. Returns each link's type.
fn add_spring_types(
    rng: &mut SplitMix64,
    scene: &mut Scene,
    pos: &[[f64; 3]],
    pairs: &[[usize; 2]],
) -> Vec<usize> {
    let types = (2 + (rng.next_u64() % 5) as usize).min(pairs.len());
    let mut order: Vec<usize> = (0..pairs.len()).collect();
    let len = |k: usize| dist(pos[pairs[k][0]], pos[pairs[k][1]]);
    order.sort_by(|&a, &b| len(a).total_cmp(&len(b)));
    let mut of = vec![0; pairs.len()];
    for (rank, &k) in order.iter().enumerate() {
        of[k] = rank * types / pairs.len();
    }
    for t in 0..types {
        let lengths: Vec<f64> = (0..pairs.len()).filter(|&k| of[k] == t).map(len).collect();
        let mean = lengths.iter().sum::<f64>() / lengths.len() as f64;
        let damping = if rng.next_u64() % 2 == 0 {
            q(rng.uniform(0.02, 0.3))
        } else {
            0.0
        };
        scene.add_type(
            LinkType::new(format!("s{t}"), LinkKind::Spring)
                .with("stiffness", q(log_uniform(rng, 30.0, 250.0)))
                .with("rest_length", q(mean * rng.uniform(0.85, 1.15)))
                .with("damping", damping),
        );
    }
    of
}

/// The particles at `pos`, thrown (a common velocity, ±1 m/s) and spinning (±3 rad/s about
/// the centroid) with ±0.5 m/s each per axis, masses log-uniform in 0.3–3 kg, 0–2 of them
/// fixed (they are added too, velocity and all, the `fixed` flag set). Returns which are
/// fixed.
fn add_particles(
    rng: &mut SplitMix64,
    scene: &mut Scene,
    pos: &[[f64; 3]],
    planar: bool,
) -> Vec<bool> {
    let n = pos.len();
    let centre = {
        let mut c = [0.0; 3];
        for p in pos {
            for a in 0..3 {
                c[a] += p[a] / n as f64;
            }
        }
        c
    };
    let axes = if planar { 2 } else { 3 };
    let mut common = [0.0; 3];
    for c in common.iter_mut().take(axes) {
        *c = rng.uniform(-1.0, 1.0);
    }
    let mut omega = [0.0; 3];
    if planar {
        omega[2] = rng.uniform(-3.0, 3.0);
    } else {
        for w in &mut omega {
            *w = rng.uniform(-3.0, 3.0);
        }
    }
    let fixed_count = (rng.next_u64() % 3) as usize;
    let mut fixed = vec![false; n];
    for _ in 0..fixed_count {
        fixed[(rng.next_u64() % n as u64) as usize] = true;
    }
    for (i, p) in pos.iter().enumerate() {
        let r = [p[0] - centre[0], p[1] - centre[1], p[2] - centre[2]];
        let spin = [
            omega[1] * r[2] - omega[2] * r[1],
            omega[2] * r[0] - omega[0] * r[2],
            omega[0] * r[1] - omega[1] * r[0],
        ];
        let mut vel = [0.0; 3];
        for a in 0..axes {
            vel[a] = common[a] + spin[a] + rng.uniform(-0.5, 0.5);
        }
        let particle = Particle::new(q(log_uniform(rng, 0.3, 3.0)), p.to_owned()).with_vel(q3(vel));
        scene.add_particle(if fixed[i] { particle.fixed() } else { particle });
    }
    fixed
}

/// 0–2 dampers (one type, 0.05–0.4 N·s/m) between near particles not linked by a spring and
/// not both fixed (a damper beside a spring is one link); returns how many.
fn add_dampers(rng: &mut SplitMix64, scene: &mut Scene, pos: &[[f64; 3]], fixed: &[bool]) -> usize {
    let n = pos.len();
    let dampers = (rng.next_u64() % 3) as usize;
    if dampers == 0 {
        return 0;
    }
    scene.add_type(
        LinkType::new("dashpot", LinkKind::Damper).with("damping", q(rng.uniform(0.05, 0.4))),
    );
    let mut added = 0;
    for _ in 0..dampers {
        let i = (rng.next_u64() % n as u64) as usize;
        let near = nearest(pos, i);
        let free_pair = near.iter().take(VARIED_MAX_RANK).copied().find(|&j| {
            let p = [i.min(j), i.max(j)];
            let linked = scene.links.iter().any(|l| l.particles == p);
            let both_fixed = fixed[i] && fixed[j];
            !linked && !both_fixed
        });
        if let Some(j) = free_pair {
            scene.add_link("dashpot", &[i.min(j), i.max(j)]);
            added += 1;
        }
    }
    added
}

/// An anchor (40–150 N/m) from the first moving particle to a point offset by
/// `reach · (0.8, 0.5, 0.5)` (z 0 when planar), `reach` 0.2–0.4 m — 0.19–0.43 m away — marked
/// by a fixed particle appended last (what a camera sees of the wall); returns 1, or 0 when
/// every particle is fixed.
fn add_anchor(
    rng: &mut SplitMix64,
    scene: &mut Scene,
    pos: &[[f64; 3]],
    fixed: &[bool],
    planar: bool,
) -> usize {
    let Some(i) = (0..pos.len()).find(|&i| !fixed[i]) else {
        return 0;
    };
    let reach = rng.uniform(0.2, 0.4);
    scene.add_type(
        LinkType::new("tether", LinkKind::Anchor)
            .with("stiffness", q(rng.uniform(40.0, 150.0)))
            .with("rest_length", q(reach * rng.uniform(0.85, 1.15)))
            .with("damping", 0.0),
    );
    let a = scene.add_link("tether", &[i]);
    let p = pos[i];
    let dz = if planar { 0.0 } else { 0.5 * reach };
    let point = q3([p[0] + 0.8 * reach, p[1] + 0.5 * reach, p[2] + dz]);
    scene.links[a].point = Some(point);
    scene.add_particle(Particle::new(1.0, point).fixed());
    1
}

fn log_uniform(rng: &mut SplitMix64, lo: f64, hi: f64) -> f64 {
    (rng.uniform(lo.ln(), hi.ln())).exp()
}

/// The other particles by distance from `i` (nearest first; ties by index).
fn nearest(pos: &[[f64; 3]], i: usize) -> Vec<usize> {
    let mut others: Vec<usize> = (0..pos.len()).filter(|&j| j != i).collect();
    others.sort_by(|&a, &b| dist(pos[i], pos[a]).total_cmp(&dist(pos[i], pos[b])));
    others
}

/// Each particle (in a random order) is linked to its nearest neighbours until it reaches the
/// degree it drew (1–6), skipping neighbours already at 6; then components are joined by their
/// closest pair. Pairs `[i, j]` with `i < j`, in the order made.
fn draw_links(rng: &mut SplitMix64, pos: &[[f64; 3]]) -> Vec<[usize; 2]> {
    let n = pos.len();
    let want: Vec<usize> = (0..n).map(|_| 1 + (rng.next_u64() % 6) as usize).collect();
    let mut degree = vec![0usize; n];
    let mut pairs: Vec<[usize; 2]> = Vec::new();
    let mut visit: Vec<usize> = (0..n).collect();
    for k in (1..n).rev() {
        visit.swap(k, (rng.next_u64() % (k as u64 + 1)) as usize);
    }
    for &i in &visit {
        for j in nearest(pos, i).into_iter().take(VARIED_MAX_RANK) {
            if degree[i] >= want[i] {
                break;
            }
            let p = [i.min(j), i.max(j)];
            if degree[j] >= 6 || pairs.contains(&p) {
                continue;
            }
            pairs.push(p);
            degree[i] += 1;
            degree[j] += 1;
        }
    }
    // Join components by their closest pair (within rank) until one remains.
    loop {
        let mut comp: Vec<usize> = (0..n).collect();
        fn root(c: &mut [usize], mut x: usize) -> usize {
            while c[x] != x {
                c[x] = c[c[x]];
                x = c[x];
            }
            x
        }
        for &[a, b] in &pairs {
            let (ra, rb) = (root(&mut comp, a), root(&mut comp, b));
            comp[ra] = rb;
        }
        let mut best: Option<(f64, [usize; 2])> = None;
        for i in 0..n {
            for j in nearest(pos, i).into_iter().take(VARIED_MAX_RANK) {
                if root(&mut comp, i) != root(&mut comp, j) {
                    let d = dist(pos[i], pos[j]);
                    if best.is_none_or(|(bd, _)| d < bd) {
                        best = Some((d, [i.min(j), i.max(j)]));
                    }
                }
            }
        }
        match best {
            Some((_, p)) => {
                pairs.push(p);
                degree[p[0]] += 1;
                degree[p[1]] += 1;
            }
            None => break,
        }
    }
    pairs
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn varied_networks_are_deterministic_valid_stable_and_cover_every_case() {
        let mut seen = [false; 6];
        let mut degrees = [false; 7];
        for seed in 0..40 {
            let (a, case) = varied_network(seed, VariedKinds::ALL);
            assert_eq!(a, varied_network(seed, VariedKinds::ALL).0);
            a.validate().unwrap();
            let traj = a.simulate(300).unwrap();
            assert!(
                traj.as_flat().iter().all(|x| x.abs() < 100.0),
                "seed {seed}"
            );
            seen[0] |= case.planar;
            seen[1] |= !case.planar;
            seen[2] |= case.gravity;
            seen[3] |= case.fixed > 0;
            seen[4] |= case.dampers > 0;
            seen[5] |= case.anchors > 0;
            for i in 0..a.num_particles() {
                let d = a
                    .links
                    .iter()
                    .filter(|l| l.particles.len() == 2 && l.particles.contains(&i))
                    .count();
                degrees[d.min(6)] = true;
            }
        }
        assert_eq!(seen, [true; 6]);
        assert!(degrees[1..].iter().all(|d| *d), "{degrees:?}");
    }
}
