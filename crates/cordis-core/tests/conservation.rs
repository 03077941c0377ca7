//! Conservation laws of the CORDIS scheme (SPEC §2.1) on random networks.
//!
//! - Momentum: with internal links only (no anchor, drag, gravity or fixed particle), every
//!   link gives its ends opposite forces, so `Σ m (x(n+1) - 2x(n) + x(n-1)) = dt² Σ F = 0` and
//!   `Σ m v(n)` is constant to rounding.
//! - Energy: the scheme is position Verlet, which is symplectic: with conservative links only
//!   (undamped springs, angles) the energy oscillates boundedly around a conserved "shadow"
//!   energy, it does not drift. A force that is not exactly `-∇E` would make it drift.
//!
//! Run in release: `cargo test --release -p cordis-core --test conservation`.

use cordis_core::{LinkKind, LinkType, Particle, Scene, Simulator, Vec3};

struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next()
    }
    fn v3(&mut self, h: f64) -> [f64; 3] {
        [self.range(-h, h), self.range(-h, h), self.range(-h, h)]
    }
    fn below(&mut self, n: usize) -> usize {
        ((self.next() * n as f64) as usize).min(n - 1)
    }
}

fn dist(a: [f64; 3], b: [f64; 3]) -> f64 {
    (Vec3::from(a) - Vec3::from(b)).norm()
}

/// A random connected network of `n` particles: a spanning chain plus extra damped springs,
/// angles on consecutive chain triples, dampers, and a conditional type over the even
/// particles. Rest lengths differ from the initial lengths so the network is excited.
fn network(seed: u64, n: usize) -> Scene {
    let mut rng = Rng(seed);
    let mut s = Scene::new(0.005);
    for i in 0..n {
        let mut p = Particle::new(rng.range(0.5, 2.0), rng.v3(1.5)).with_vel(rng.v3(1.0));
        if i % 2 == 0 {
            p.group = Some("gas".into());
        }
        s.add_particle(p);
    }
    for t in 0..3 {
        let ty = LinkType::new(format!("s{t}"), LinkKind::Spring)
            .with("stiffness", rng.range(10.0, 50.0))
            .with("rest_length", rng.range(0.5, 1.5))
            .with("damping", rng.range(0.05, 0.5));
        s.add_type(ty);
    }
    s.add_type(
        LinkType::new("bend", LinkKind::Angle)
            .with("stiffness", rng.range(1.0, 5.0))
            .with("rest_cos", rng.range(-0.9, 0.9)),
    );
    for i in 1..n {
        let t = format!("s{}", rng.below(3));
        s.add_link(&t, &[i - 1, i]);
    }
    for _ in 0..n {
        let (i, j) = (rng.below(n), rng.below(n));
        if i != j {
            let t = format!("s{}", rng.below(3));
            s.add_link(&t, &[i, j]);
        }
    }
    for i in 2..n {
        if rng.next() < 0.6 {
            s.add_link("bend", &[i - 2, i - 1, i]);
        }
    }
    s.add_type(LinkType::new("d", LinkKind::Damper).with("damping", 0.3));
    for _ in 0..n / 2 {
        let (i, j) = (rng.below(n), rng.below(n));
        if i != j {
            s.add_link("d", &[i, j]);
        }
    }
    let mut c = LinkType::new("near", LinkKind::Conditional)
        .with("stiffness", 20.0)
        .with("rest_length", 0.6)
        .with("damping", 0.2)
        .with("range", 0.8);
    c.groups = vec!["gas".into()];
    s.add_type(c);
    s.validate().unwrap();
    s
}

fn masses(s: &Scene) -> Vec<f64> {
    s.particles.iter().map(|p| p.mass.value()).collect()
}

#[test]
fn internal_links_conserve_momentum() {
    for seed in [1, 2, 3] {
        let s = network(seed, 24);
        let m = masses(&s);
        let dt = s.dt;
        let mut sim = Simulator::new(&s).unwrap();
        let mut prev = sim.positions().to_vec();
        let mut p0 = None;
        let mut active = 0usize;
        for _ in 0..1500 {
            sim.step().unwrap();
            let x = sim.positions();
            let (mut p, mut scale) = (Vec3::zeros(), 0.0);
            for i in 0..x.len() {
                let v = (x[i] - prev[i]) / dt;
                p += v * m[i];
                scale += m[i] * v.norm();
            }
            let p0 = *p0.get_or_insert(p);
            // Rounding budget: each x(n) carries ~ε|x| ≈ 4e-16 m, so each v(n) ~ 1e-13 m/s;
            // summed over 24 particles and random-walking over 1500 steps that stays below
            // ~1e-12 of Σ m|v| ≈ 40 (observed worst: 4e-13).
            assert!(
                (p - p0).norm() <= 1e-12 * scale,
                "momentum drifted by {:e} (scale {scale})",
                (p - p0).norm()
            );
            // Count conditional pairs so the test knows that type took part.
            for i in (0..x.len()).step_by(2) {
                for j in (i + 2..x.len()).step_by(2) {
                    active += usize::from((x[j] - x[i]).norm() < 0.8);
                }
            }
            prev.copy_from_slice(x);
        }
        assert!(
            active > 100,
            "seed {seed}: the conditional type never acted"
        );
    }
}

/// Potential energy of the springs and angles at positions x.
fn potential(s: &Scene, x: &[Vec3]) -> f64 {
    let mut e = 0.0;
    for l in &s.links {
        let t = &s.types[l.type_index];
        let k = t.value("stiffness").unwrap();
        let p = &l.particles;
        match t.kind {
            LinkKind::Spring => {
                let len = (x[p[1]] - x[p[0]]).norm();
                e += 0.5 * k * (len - t.value("rest_length").unwrap()).powi(2);
            }
            LinkKind::Angle => {
                let (a, b) = (x[p[0]] - x[p[1]], x[p[2]] - x[p[1]]);
                let c = a.dot(&b) / (a.norm() * b.norm());
                e += 0.5 * k * (c - t.value("rest_cos").unwrap()).powi(2);
            }
            other => panic!("not a conservative link: {other}"),
        }
    }
    e
}

/// A jittered 2×2×3 lattice of springs between all particles closer than 1.8 (so it is rigid)
/// and angles along its edges, each link its own type with rest values a few percent off the
/// initial geometry: an undamped network vibrating around equilibrium in all its modes.
fn lattice(seed: u64, damping: f64) -> Scene {
    let mut rng = Rng(seed);
    let mut s = Scene::new(0.002);
    for i in 0..12 {
        let base = [(i % 2) as f64, ((i / 2) % 2) as f64, (i / 4) as f64];
        let j = rng.v3(0.1);
        let pos = [base[0] + j[0], base[1] + j[1], base[2] + j[2]];
        s.add_particle(Particle::new(rng.range(0.5, 2.0), pos).with_vel(rng.v3(0.3)));
    }
    let x: Vec<[f64; 3]> = s.particles.iter().map(|p| p.pos).collect();
    for i in 0..12 {
        for j in i + 1..12 {
            let l = dist(x[i], x[j]);
            if l < 1.8 {
                let name = format!("s{i}-{j}");
                s.add_type(
                    LinkType::new(&name, LinkKind::Spring)
                        .with("stiffness", rng.range(20.0, 60.0))
                        .with("rest_length", l * rng.range(0.95, 1.05))
                        .with("damping", damping),
                );
                s.add_link(&name, &[i, j]);
            }
        }
    }
    // Angles at every particle between its lattice neighbours along two different axes.
    for i in 0..12 {
        for (a, b) in [(1, 2), (1, 4), (2, 4)] {
            let (j, k) = (i ^ a, if b == 4 { i + 4 } else { i ^ b });
            if k >= 12 {
                continue;
            }
            let (u, w) = (
                Vec3::from(x[j]) - Vec3::from(x[i]),
                Vec3::from(x[k]) - Vec3::from(x[i]),
            );
            let c = u.dot(&w) / (u.norm() * w.norm());
            let name = format!("a{j}-{i}-{k}");
            s.add_type(
                LinkType::new(&name, LinkKind::Angle)
                    .with("stiffness", rng.range(1.0, 5.0))
                    .with("rest_cos", (c + rng.range(-0.05, 0.05)).clamp(-1.0, 1.0)),
            );
            s.add_link(&name, &[j, i, k]);
        }
    }
    s.validate().unwrap();
    s
}

/// Energy E(n) = ½ Σ m |(x(n+1) - x(n-1)) / 2dt|² + V(x(n)) over `steps` steps.
fn energy_series(s: &Scene, steps: usize) -> Vec<f64> {
    let m = masses(s);
    let dt = s.dt;
    let mut sim = Simulator::new(s).unwrap();
    let mut before = sim.positions().to_vec();
    sim.step().unwrap();
    let mut now = sim.positions().to_vec();
    let mut energy = Vec::with_capacity(steps);
    for _ in 0..steps {
        sim.step().unwrap();
        let after = sim.positions();
        let kinetic: f64 = (0..m.len())
            .map(|i| 0.5 * m[i] * ((after[i] - before[i]) / (2.0 * dt)).norm_squared())
            .sum();
        energy.push(kinetic + potential(s, &now));
        before = std::mem::replace(&mut now, after.to_vec());
    }
    energy
}

/// (mean of the first 10%, mean of the last 10%, max - min) of a series.
fn windows(e: &[f64]) -> (f64, f64, f64) {
    let mean = |w: &[f64]| w.iter().sum::<f64>() / w.len() as f64;
    let tenth = e.len() / 10;
    let lo = e.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = e.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    (mean(&e[..tenth]), mean(&e[e.len() - tenth..]), hi - lo)
}

const STEPS: usize = 100_000;

#[test]
#[cfg_attr(debug_assertions, ignore = "10^5 steps: run with cargo test --release")]
fn undamped_network_energy_oscillates_without_drift() {
    for seed in [42, 43] {
        let (first, last, swing) = windows(&energy_series(&lattice(seed, 0.0), STEPS));
        let drift = (last - first).abs();
        eprintln!(
            "seed {seed}: E ≈ {first:.6}, swing {:.3e}, drift of the window means {:.3e} \
             (relative to E)",
            swing / first,
            drift / first
        );
        // The network is excited and the scheme's energy error is visible at all.
        assert!(first > 0.05 && swing > 0.0);
        // Bounded oscillation: Verlet's energy error is O((ω dt)²) E; with ω ≲ 20 rad/s and
        // dt = 2 ms, (ω dt)² ≲ 2e-3.
        assert!(swing < 2e-3 * first, "energy swing {swing:e} of {first}");
        // No drift. Near equilibrium the motion is quasi-periodic, so the energy error is a
        // sum of oscillations of periods ≤ a few s; a window of 20 s averages them down to
        // ~ swing × period / window ≈ swing / 10. A force that is not exactly -∇E, or a
        // scheme that is not symplectic, changes the energy by the same sign every period
        // and the window means then differ by more than the swing (see the damped test).
        assert!(
            drift < 0.2 * swing,
            "window means differ by {drift:e}, swing {swing:e}"
        );
    }
}

#[test]
#[cfg_attr(debug_assertions, ignore = "10^5 steps: run with cargo test --release")]
fn the_drift_criterion_catches_a_tiny_dissipation() {
    // Spring damping of 1e-7 N·s/m removes only ~4e-5 of the energy over the run, less than
    // the scheme's own energy swing, and the same criterion catches it.
    let (first, last, swing) = windows(&energy_series(&lattice(42, 1e-7), STEPS));
    assert!(
        (last - first).abs() > 0.2 * swing,
        "window means differ by {:e}, swing {swing:e}",
        (last - first).abs()
    );
    assert!(last < first);
}
