//! The CORDIS scheme (SPEC §2.1) against closed forms of its own recurrence: not the continuous
//! ODE's solution, but the exact solution of the discrete scheme, so the tolerances are those
//! of rounding alone.

use cordis_core::{LinkKind, LinkType, Particle, Scene, Trajectory};

/// A particle of mass `m` at `pos` with velocity `vel` on an anchor at `point` (rest length
/// 0, stiffness `k`, anchor damping `z_anchor`), plus a drag `z_drag` when it is not 0.
struct Oscillator {
    dt: f64,
    m: f64,
    k: f64,
    z_anchor: f64,
    z_drag: f64,
    point: [f64; 3],
    pos: [f64; 3],
    vel: [f64; 3],
}

impl Oscillator {
    fn scene(&self) -> Scene {
        let mut s = Scene::new(self.dt);
        s.add_particle(Particle::new(self.m, self.pos).with_vel(self.vel));
        let mut t = LinkType::new("a", LinkKind::Anchor)
            .with("stiffness", self.k)
            .with("damping", self.z_anchor);
        t.point = Some(self.point);
        s.add_type(t);
        s.add_link("a", &[0]);
        if self.z_drag > 0.0 {
            s.add_type(LinkType::new("air", LinkKind::Drag).with("damping", self.z_drag));
            s.add_link("air", &[0]);
        }
        s
    }
}

/// Closed form of `y(n+1) = 2 y(n) - y(n-1) - a y(n) - b (y(n) - y(n-1))`, `a = K dt²/m`,
/// `b = Z dt/m`: characteristic roots `ρ e^{±iφ}` with `ρ² = 1 - b`,
/// `2ρ cos φ = 2 - a - b`, so `y(n) = ρ^n (A cos nφ + B sin nφ)`; A and B from y(0) and y(-1).
struct Discrete {
    rho: f64,
    phi: f64,
    a: f64,
    b: f64,
}

impl Discrete {
    fn new(k: f64, z: f64, m: f64, dt: f64, y0: f64, y_minus1: f64) -> Self {
        let (ka, kb) = (k * dt * dt / m, z * dt / m);
        let rho = (1.0 - kb).sqrt();
        // sin²φ = 1 - cos²φ = (4a - (a + b)²) / (4ρ²), computed without cancellation: acos of
        // a cosine near 1 would lose ε/φ in φ, i.e. n ε/φ in the phase after n steps.
        let sin_phi = (4.0 * ka - (ka + kb).powi(2)).sqrt() / (2.0 * rho);
        let cos_phi = (2.0 - ka - kb) / (2.0 * rho);
        let phi = sin_phi.atan2(cos_phi);
        let a = y0;
        // y(-1) = ρ^{-1} (A cos φ - B sin φ)
        let b = (a * phi.cos() - rho * y_minus1) / phi.sin();
        Discrete { rho, phi, a, b }
    }

    fn at(&self, n: usize) -> f64 {
        let nf = n as f64;
        self.rho.powi(n as i32) * (self.a * (nf * self.phi).cos() + self.b * (nf * self.phi).sin())
    }

    fn amplitude(&self) -> f64 {
        self.a.hypot(self.b)
    }
}

fn coords(traj: &Trajectory, t: usize, i: usize) -> [f64; 3] {
    traj.pos(t, i).into()
}

#[test]
fn undamped_anchor_matches_the_discrete_closed_form_in_3d() {
    let (dt, m, k) = (0.01, 2.0, 50.0);
    let point = [0.3, -0.2, 1.0];
    let (pos, vel) = ([1.0, 0.5, 0.0], [0.0, 2.0, -1.0]);
    let frames = 6000;
    let traj = Oscillator {
        dt,
        m,
        k,
        z_anchor: 0.0,
        z_drag: 0.0,
        point,
        pos,
        vel,
    }
    .scene()
    .simulate(frames)
    .unwrap();
    for c in 0..3 {
        let y0 = pos[c] - point[c];
        let sol = Discrete::new(k, 0.0, m, dt, y0, y0 - vel[c] * dt);
        let scale = sol.amplitude();
        for n in 0..frames {
            let y = coords(&traj, n, 0)[c] - point[c];
            assert!(
                (y - sol.at(n)).abs() <= 1e-12 * scale,
                "coordinate {c}, frame {n}: {y} vs closed form {}",
                sol.at(n)
            );
        }
    }
}

#[test]
fn undamped_spring_with_rest_length_matches_the_closed_form() {
    // 1-D: a particle on a spring to a fixed particle stays on one side, so the spring is
    // linear in the displacement from x = l0.
    let (dt, m, k, l0) = (0.005, 0.7, 90.0, 1.5);
    let mut s = Scene::new(dt);
    s.add_particle(Particle::new(1.0, [0.0; 3]).fixed());
    s.add_particle(Particle::new(m, [1.9, 0.0, 0.0]).with_vel([1.0, 0.0, 0.0]));
    s.add_type(
        LinkType::new("s", LinkKind::Spring)
            .with("stiffness", k)
            .with("rest_length", l0),
    );
    s.add_link("s", &[0, 1]);
    let frames = 5000;
    let traj = s.simulate(frames).unwrap();
    let y0 = 1.9 - l0;
    let sol = Discrete::new(k, 0.0, m, dt, y0, y0 - 1.0 * dt);
    for n in 0..frames {
        let y = traj.pos(n, 1).x - l0;
        assert!(
            (y - sol.at(n)).abs() <= 1e-12 * sol.amplitude(),
            "frame {n}"
        );
    }
}

/// Frames where y changes sign from + to -, by linear interpolation, in frames.
fn downward_crossings(y: &[f64]) -> Vec<f64> {
    (1..y.len())
        .filter(|&n| y[n - 1] > 0.0 && y[n] <= 0.0)
        .map(|n| (n - 1) as f64 + y[n - 1] / (y[n - 1] - y[n]))
        .collect()
}

/// `y` against the closed form point by point, then its period and decay envelope.
fn check_damped(y: &[f64], sol: &Discrete) {
    let scale = sol.amplitude();
    for (n, &yn) in y.iter().enumerate() {
        assert!(
            (yn - sol.at(n)).abs() <= 1e-12 * scale,
            "frame {n}: {yn} vs {}",
            sol.at(n)
        );
    }
    // Period: successive downward zero crossings are 2π/φ frames apart (to the interpolation
    // error, small at ~100 frames per period).
    let period = 2.0 * std::f64::consts::PI / sol.phi;
    let crossings = downward_crossings(y);
    assert!(crossings.len() >= 5, "too few periods to check");
    for w in crossings.windows(2) {
        assert!(
            (w[1] - w[0] - period).abs() < 1e-3 * period,
            "period {} vs {period}",
            w[1] - w[0]
        );
    }
    // Envelope: over one period the amplitude shrinks by ρ^period, ρ = sqrt(1 - Z dt/m).
    // Peaks of |y| one period apart (rounded to a frame) are in that ratio up to the phase
    // drift of rounding the period, i.e. to O(φ²) relative.
    let p = period.round() as usize;
    let peak = y
        .iter()
        .take(p)
        .enumerate()
        .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
        .unwrap()
        .0;
    let ratio = y[peak + 2 * p] / y[peak];
    let want = sol.rho.powf(2.0 * p as f64);
    assert!(
        (ratio - want).abs() < 4.0 * sol.phi * sol.phi * want + 1e-9,
        "envelope ratio {ratio} vs {want}"
    );
}

#[test]
fn drag_damped_oscillator_matches_the_characteristic_roots_in_3d() {
    // Drag is isotropic, so with a zero-rest-length anchor each coordinate is the 1-D
    // recurrence of SPEC §2.1 with backward-difference velocity.
    let (dt, m, k, z) = (0.01, 1.5, 60.0, 0.6);
    let point = [0.0, 0.0, 0.0];
    let (pos, vel) = ([1.0, -0.4, 0.2], [0.5, 1.0, -2.0]);
    let traj = Oscillator {
        dt,
        m,
        k,
        z_anchor: 0.0,
        z_drag: z,
        point,
        pos,
        vel,
    }
    .scene()
    .simulate(3000)
    .unwrap();
    for c in 0..3 {
        let sol = Discrete::new(k, z, m, dt, pos[c], pos[c] - vel[c] * dt);
        assert!(sol.rho < 1.0 && sol.rho > 0.99);
        let y: Vec<f64> = (0..traj.frames())
            .map(|n| coords(&traj, n, 0)[c] - point[c])
            .collect();
        check_damped(&y, &sol);
    }
}

#[test]
fn anchor_damping_on_a_line_matches_the_characteristic_roots() {
    // Motion along one line through the anchor point: the anchor's own damping Z s u is then
    // -Z v, the same recurrence.
    let (dt, m, k, z) = (0.002, 0.4, 200.0, 0.3);
    let point = [1.0, 2.0, 3.0];
    let dir = [2.0f64 / 3.0, -1.0 / 3.0, 2.0 / 3.0];
    let pos: [f64; 3] = std::array::from_fn(|c| point[c] + 0.8 * dir[c]);
    let vel: [f64; 3] = std::array::from_fn(|c| -3.0 * dir[c]);
    let traj = Oscillator {
        dt,
        m,
        k,
        z_anchor: z,
        z_drag: 0.0,
        point,
        pos,
        vel,
    }
    .scene()
    .simulate(4000)
    .unwrap();
    // Signed distance along dir.
    let y: Vec<f64> = (0..traj.frames())
        .map(|n| {
            let x = coords(&traj, n, 0);
            (0..3).map(|c| (x[c] - point[c]) * dir[c]).sum()
        })
        .collect();
    let sol = Discrete::new(k, z, m, dt, 0.8, 0.8 + 3.0 * dt);
    check_damped(&y, &sol);
}

#[test]
fn free_fall_is_exact_with_dyadic_numbers() {
    // dt, g, x0 and v0 are dyadic and every intermediate fits in 53 bits, so the scheme has no
    // rounding at all: x(n) = x0 + v0 n dt + g dt² n(n+1)/2 holds exactly.
    let dt = 1.0 / 64.0;
    let mut s = Scene::new(dt);
    s.gravity = [0.0, -8.0, 0.5];
    let (x0, v0) = ([1.0, 2.0, -3.0], [0.25, 4.0, -0.5]);
    s.add_particle(Particle::new(3.0, x0).with_vel(v0));
    let frames = 2000;
    let traj = s.simulate(frames).unwrap();
    for n in 0..frames {
        let nf = n as f64;
        let want: [f64; 3] = std::array::from_fn(|c| {
            x0[c] + v0[c] * nf * dt + s.gravity[c] * dt * dt * nf * (nf + 1.0) / 2.0
        });
        assert_eq!(coords(&traj, n, 0), want, "frame {n}");
    }
}

#[test]
fn free_fall_matches_to_rounding() {
    // A rounding error δ made at step k shifts x(n) by δ (n - k) (the homogeneous solutions of
    // the scheme are a + b n), so after n steps the error is at most ~ n² ε |x|max / 2.
    let dt = 0.01;
    let mut s = Scene::new(dt);
    s.gravity = [0.0, 0.0, -9.81];
    let (x0, v0) = ([0.1, 0.2, 0.3], [1.1, -0.7, 12.3]);
    s.add_particle(Particle::new(0.3, x0).with_vel(v0));
    let frames = 1000;
    let traj = s.simulate(frames).unwrap();
    let mut worst: f64 = 0.0;
    for n in 0..frames {
        let nf = n as f64;
        let x = coords(&traj, n, 0);
        for c in 0..3 {
            let want = x0[c] + v0[c] * nf * dt + s.gravity[c] * dt * dt * nf * (nf + 1.0) / 2.0;
            let bound = nf * nf * f64::EPSILON * 400.0 / 2.0 + 1e-15;
            assert!((x[c] - want).abs() <= bound, "frame {n}, coordinate {c}");
            worst = worst.max((x[c] - want).abs());
        }
    }
    assert!(worst > 0.0 || frames < 2);
}

#[test]
fn fixed_particles_never_move() {
    let mut s = Scene::new(0.01);
    s.gravity = [1.0, -9.81, 0.5];
    // A fixed particle's `vel` is ignored: it never moves, not even at x(-1).
    s.add_particle(
        Particle::new(1.0, [0.0, 0.0, 0.0])
            .fixed()
            .with_vel([5.0, 0.0, 0.0]),
    );
    s.add_particle(Particle::new(2.0, [1.0, 0.0, 0.0]).with_vel([0.0, 3.0, 0.0]));
    s.add_particle(Particle::new(0.1, [0.5, 0.5, 0.1]).fixed());
    s.add_particle(Particle::new(1.0, [2.0, 0.0, 0.5]).with_vel([-1.0, 0.0, 1.0]));
    let mut spring = LinkType::new("s", LinkKind::Spring)
        .with("stiffness", 300.0)
        .with("rest_length", 0.5)
        .with("damping", 2.0);
    spring.set_optional(cordis_core::OptionalParam::MaxElongation, Some(0.1.into()));
    s.add_type(spring);
    s.add_type(LinkType::new("d", LinkKind::Damper).with("damping", 3.0));
    s.add_type(LinkType::new("a", LinkKind::Anchor).with("stiffness", 100.0));
    s.add_type(LinkType::new("air", LinkKind::Drag).with("damping", 1.0));
    s.add_type(
        LinkType::new("bend", LinkKind::Angle)
            .with("stiffness", 5.0)
            .with("rest_cos", 0.0),
    );
    s.add_link("s", &[0, 1]);
    s.add_link("s", &[1, 2]);
    s.add_link("s", &[2, 3]);
    s.add_link("d", &[0, 3]);
    s.add_link("a", &[2]);
    s.add_link("air", &[0]);
    s.add_link("bend", &[0, 2, 1]);
    let frames = 500;
    let traj = s.simulate(frames).unwrap();
    for n in 0..frames {
        assert_eq!(coords(&traj, n, 0), [0.0, 0.0, 0.0], "frame {n}");
        assert_eq!(coords(&traj, n, 2), [0.5, 0.5, 0.1], "frame {n}");
    }
    assert!((traj.pos(frames - 1, 1) - traj.pos(0, 1)).norm() > 0.1);
}

#[test]
fn gravity_comes_from_the_parameter_vector() {
    // A plan compiled from a scene without gravity must still follow a parameter vector that
    // sets one (the plan is compiled once and stepped with any vector of its layout).
    use cordis_core::{Plan, Simulator};
    let dt = 1.0 / 64.0;
    let mut s = Scene::new(dt);
    s.add_particle(Particle::new(1.0, [0.0; 3]));
    let plan = Plan::compile(&s).unwrap();
    let mut p = s.param_values();
    let o = plan.layout.gravity_offset;
    p[o + 2] = -8.0;
    let traj = Simulator::from_plan(plan, p).run(10).unwrap();
    for n in 0..10 {
        let nf = n as f64;
        assert_eq!(traj.pos(n, 0).z, -8.0 * dt * dt * nf * (nf + 1.0) / 2.0);
    }
}
