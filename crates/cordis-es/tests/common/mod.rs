//! Test scenes and an independent, naive implementation of SPEC §3 (plain arrays, one `match`
//! per link, brute-force conditional pairs, no `Plan`).
#![allow(dead_code)]

use cordis_core::{Bounds, LinkKind, LinkType, Param, Particle, Scene, Shape, Signal, Trajectory};
use cordis_es::cost::CostKind;
use cordis_es::identify::with_unknown_boxes;
use cordis_es::problem::Problem;

pub type V = [f64; 3];

fn add(a: V, b: V) -> V {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}
fn sub(a: V, b: V) -> V {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
fn mul(a: V, s: f64) -> V {
    [a[0] * s, a[1] * s, a[2] * s]
}
fn dot(a: V, b: V) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
fn norm(a: V) -> f64 {
    dot(a, a).sqrt()
}

// ---------------------------------------------------------------- scenes

/// A `w × h` cloth hanging from its two top corners: structural, shear and bend springs
/// (damped), drag, gravity. `provot` puts a max_elongation on the structural springs.
pub fn cloth(w: usize, h: usize, provot: bool) -> Scene {
    let mut s = Scene::new(0.005);
    s.gravity = [0.0, -9.81, 0.0];
    let a = 0.1;
    for r in 0..h {
        for c in 0..w {
            let mut p = Particle::new(
                0.01 + 0.001 * ((r * w + c) % 3) as f64,
                [
                    c as f64 * a,
                    0.0,
                    r as f64 * a * 0.9, // a bit slack: the cloth falls and swings
                ],
            )
            .with_vel([0.05 * (c as f64).sin(), 0.0, 0.02 * r as f64]);
            if r == 0 && (c == 0 || c == w - 1) {
                p = p.fixed();
            }
            s.add_particle(p);
        }
    }
    let mut structural = LinkType::new("structural", LinkKind::Spring)
        .with("stiffness", 40.0)
        .with("rest_length", a)
        .with("damping", 0.02);
    if provot {
        structural.set_optional(cordis_core::OptionalParam::MaxElongation, Some(0.1.into()));
    }
    s.add_type(structural);
    s.add_type(
        LinkType::new("shear", LinkKind::Spring)
            .with("stiffness", 15.0)
            .with("rest_length", a * 2f64.sqrt())
            .with("damping", 0.01),
    );
    s.add_type(
        LinkType::new("bend", LinkKind::Spring)
            .with("stiffness", 5.0)
            .with("rest_length", 2.0 * a),
    );
    s.add_type(LinkType::new("air", LinkKind::Drag).with("damping", 0.002));
    let id = |r: usize, c: usize| r * w + c;
    for r in 0..h {
        for c in 0..w {
            if c + 1 < w {
                s.add_link("structural", &[id(r, c), id(r, c + 1)]);
            }
            if r + 1 < h {
                s.add_link("structural", &[id(r, c), id(r + 1, c)]);
            }
            if r + 1 < h && c + 1 < w {
                s.add_link("shear", &[id(r, c), id(r + 1, c + 1)]);
                s.add_link("shear", &[id(r, c + 1), id(r + 1, c)]);
            }
            if c + 2 < w {
                s.add_link("bend", &[id(r, c), id(r, c + 2)]);
            }
            if r + 2 < h {
                s.add_link("bend", &[id(r, c), id(r + 2, c)]);
            }
            s.add_link("air", &[id(r, c)]);
        }
    }
    s
}

/// Every listed passive kind on a small 3-D chain: spring, damper, anchor (own point and
/// default point), drag, angle, and `nonlinear` adds a nonlinear drag.
pub fn zoo(nonlinear: bool) -> Scene {
    let mut s = Scene::new(0.002);
    s.gravity = [0.0, 0.0, -2.0];
    let n = 7;
    for k in 0..n {
        let t = k as f64;
        let mut p = Particle::new(
            0.5 + 0.1 * t,
            [0.3 * t, 0.1 * (1.7 * t).sin(), 0.05 * t * t],
        )
        .with_vel([0.0, 0.3 * (t * 0.9).cos(), -0.2 * t]);
        if k == 0 {
            p = p.fixed();
        }
        s.add_particle(p);
    }
    s.add_type(
        LinkType::new("rib", LinkKind::Spring)
            .with("stiffness", 80.0)
            .with("rest_length", 0.28)
            .with("damping", 0.3),
    );
    s.add_type(LinkType::new("goo", LinkKind::Damper).with("damping", 0.4));
    let mut pin = LinkType::new("pin", LinkKind::Anchor)
        .with("stiffness", 30.0)
        .with("rest_length", 0.05)
        .with("damping", 0.1);
    pin.point = Some([1.0, 0.5, 0.0]);
    s.add_type(pin);
    s.add_type(LinkType::new("home", LinkKind::Anchor).with("stiffness", 4.0));
    s.add_type(LinkType::new("air", LinkKind::Drag).with("damping", 0.05));
    s.add_type(
        LinkType::new("elbow", LinkKind::Angle)
            .with("stiffness", 2.0)
            .with("rest_cos", -0.8),
    );
    for k in 0..n - 1 {
        s.add_link("rib", &[k, k + 1]);
    }
    s.add_link("goo", &[1, 3]);
    s.add_link("goo", &[2, 5]);
    s.add_link("pin", &[6]);
    s.add_link("pin", &[3]);
    s.add_link("home", &[4]);
    let l = s.add_link("home", &[5]);
    s.links[l].point = Some([1.2, -0.3, 0.4]);
    for k in 1..n {
        s.add_link("air", &[k]);
    }
    for k in 1..n - 1 {
        s.add_link("elbow", &[k - 1, k, k + 1]);
    }
    if nonlinear {
        s.add_type(
            LinkType::new("tadpole", LinkKind::NonlinearDrag)
                .with("z1", 0.05)
                .with("z2", 0.5)
                .with("v_max", 0.3),
        );
        for k in 1..n {
            s.add_link("tadpole", &[k]);
        }
    }
    s
}

/// A small fluid: `gas` particles among themselves and a `jet` group against the gas, both
/// conditional; a floor spring field by anchors; gravity. `unknown_range` makes the gas
/// range an unknown parameter (so the cost may not precompute its pairs).
pub fn fluid(unknown_range: bool) -> Scene {
    let mut s = Scene::new(0.002);
    s.gravity = [0.0, -9.81, 0.0];
    for k in 0..24 {
        let (r, c) = ((k / 6) as f64, (k % 6) as f64);
        let mut p = Particle::new(0.02, [0.06 * c + 0.01 * r, 0.06 * r, 0.01 * (c * r).sin()])
            .with_vel([
                0.8 * (1.3 * k as f64).sin(),
                0.6 * (0.7 * k as f64).cos(),
                0.05,
            ]);
        p = p.in_group(if k < 20 { "gas" } else { "jet" });
        s.add_particle(p);
    }
    let range: Param = if unknown_range {
        Param::Unknown(Bounds {
            min: 0.03,
            max: 0.2,
            init: Some(0.09),
        })
    } else {
        Param::Known(0.09)
    };
    let mut gas = LinkType::new("gas", LinkKind::Conditional)
        .with("stiffness", 20.0)
        .with("rest_length", 0.07)
        .with("damping", 0.02)
        .with("range", range);
    gas.groups = vec!["gas".into()];
    s.add_type(gas);
    let mut jet = LinkType::new("jet", LinkKind::Conditional)
        .with("stiffness", 10.0)
        .with("rest_length", 0.06)
        .with("range", 0.1);
    jet.groups = vec!["jet".into(), "gas".into()];
    s.add_type(jet);
    s.add_type(LinkType::new("floor", LinkKind::Anchor).with("stiffness", 3.0));
    for k in 0..24 {
        s.add_link("floor", &[k]);
    }
    s
}

// ---------------------------------------------------------------- noise

/// SplitMix64 with Box–Muller: a seeded Gaussian source with no dependency.
pub struct Gauss(u64);

impl Gauss {
    pub fn new(seed: u64) -> Self {
        Gauss(seed)
    }
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    pub fn uniform(&mut self) -> f64 {
        ((self.next_u64() >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    }
    pub fn normal(&mut self) -> f64 {
        let (u, v) = (self.uniform(), self.uniform());
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }
}

/// `traj` with Gaussian noise of standard deviation `sigma` (m) on every coordinate of every
/// free particle (fixed particles stay exact).
/// A free 2-D triangle of three muscles (two types, weights of both signs, threshold, damping)
/// and a spring to a fourth particle, under drag: the neurons act on every particle.
pub fn muscles() -> Scene {
    let mut s = Scene::new(0.01);
    s.add_particle(Particle::new(1.0, [0.0, 0.0, 0.0]).with_vel([-0.2, 0.1, 0.0]));
    s.add_particle(Particle::new(0.8, [1.0, 0.1, 0.0]));
    s.add_particle(Particle::new(1.2, [0.4, 0.9, 0.0]).with_vel([0.1, 0.3, 0.0]));
    s.add_particle(Particle::new(0.6, [1.5, 0.8, 0.0]));
    let w = |v: &[f64]| v.iter().map(|&x| Param::Known(x)).collect::<Vec<_>>();
    s.add_type(
        LinkType::new("m", LinkKind::Muscle)
            .with("stiffness", 30.0)
            .with("rest_length", 0.9)
            .with("damping", 0.4)
            .with("gain", 2.0)
            .with("threshold", 0.1)
            .with_weights(&w(&[1.5, -2.0]), &w(&[-0.8, 0.6])),
    );
    s.add_type(
        LinkType::new("n", LinkKind::Muscle)
            .with("stiffness", 45.0)
            .with("rest_length", 1.1)
            .with("gain", 1.5)
            .with_weights(&w(&[-1.2, 0.7]), &w(&[0.5, 0.9])),
    );
    s.add_type(
        LinkType::new("s", LinkKind::Spring)
            .with("stiffness", 20.0)
            .with("rest_length", 0.8),
    );
    s.add_type(LinkType::new("air", LinkKind::Drag).with("damping", 0.05));
    s.add_link("m", &[0, 1]);
    s.add_link("s", &[1, 3]);
    s.add_link("n", &[1, 2]);
    s.add_link("m", &[2, 0]);
    for i in 0..4 {
        s.add_link("air", &[i]);
    }
    s
}

pub fn noisy(scene: &Scene, traj: &Trajectory, sigma: f64, seed: u64) -> Trajectory {
    let mut g = Gauss::new(seed);
    let n = traj.particles();
    let mut data = traj.as_flat().to_vec();
    for (k, v) in data.iter_mut().enumerate() {
        if !scene.particles[(k / 3) % n].fixed {
            *v += sigma * g.normal();
        }
    }
    Trajectory::from_flat(traj.frames(), n, data)
        .unwrap()
        .with_dt(scene.dt)
}

/// The scene's parameters with every type parameter scaled by `1 + f·(k-th pseudo-random)`,
/// keeping rest cosines in [-1, 1] and leaving ranges, masses and gravity alone.
pub fn perturbed(scene: &Scene, f: f64, seed: u64) -> Vec<f64> {
    let mut g = Gauss::new(seed);
    let mut p = Vec::new();
    for t in &scene.types {
        for (k, q) in t.params.iter().enumerate() {
            let name = t.param_name(k);
            let name = name.as_str();
            let v = q.value();
            let scaled = v * (1.0 + f * (2.0 * g.uniform() - 1.0));
            p.push(match name {
                "range" => v,
                "rest_cos" => scaled.clamp(-1.0, 1.0),
                _ => scaled,
            });
        }
    }
    p.extend(scene.particles.iter().map(|q| q.mass.value()));
    p.extend_from_slice(&scene.gravity);
    p
}

// ---------------------------------------------------------------- naive SPEC §3

/// Offsets of each type's parameters in the flat vector, computed from the SPEC's layout
/// (types in catalogue order, then masses, then gravity).
fn offsets(scene: &Scene) -> (Vec<usize>, usize, usize) {
    let mut at = 0;
    let mut off = Vec::new();
    for t in &scene.types {
        off.push(at);
        at += t.params.len();
    }
    (off, at, at + scene.particles.len())
}

fn unit(d: V) -> (V, f64) {
    let l = norm(d);
    if l < 1e-12 {
        ([0.0; 3], l)
    } else {
        (mul(d, 1.0 / l), l)
    }
}

fn spring(xi: V, xj: V, vi: V, vj: V, k: f64, l0: f64, z: f64) -> V {
    let (u, l) = unit(sub(xj, xi));
    let s = dot(sub(vj, vi), u);
    mul(u, k * (l - l0) + z * s)
}

/// Total link force on every particle at positions `x`, velocities `v`.
pub fn naive_forces(scene: &Scene, p: &[f64], x: &[V], v: &[V]) -> Vec<V> {
    let (off, _, _) = offsets(scene);
    let mut f = vec![[0.0; 3]; x.len()];
    for l in &scene.links {
        let t = &scene.types[l.type_index];
        let q = &p[off[l.type_index]..];
        let ps = &l.particles;
        match t.kind {
            LinkKind::Spring => {
                let (i, j) = (ps[0], ps[1]);
                let fi = spring(x[i], x[j], v[i], v[j], q[0], q[1], q[2]);
                f[i] = add(f[i], fi);
                f[j] = sub(f[j], fi);
            }
            LinkKind::Damper => {
                let (i, j) = (ps[0], ps[1]);
                let fi = mul(sub(v[j], v[i]), q[0]);
                f[i] = add(f[i], fi);
                f[j] = sub(f[j], fi);
            }
            LinkKind::Anchor => {
                let i = ps[0];
                let point = l.point.or(t.point).unwrap_or(scene.particles[i].pos);
                let fi = spring(x[i], point, v[i], [0.0; 3], q[0], q[1], q[2]);
                f[i] = add(f[i], fi);
            }
            LinkKind::Drag => {
                let i = ps[0];
                f[i] = sub(f[i], mul(v[i], q[0]));
            }
            LinkKind::NonlinearDrag => {
                let i = ps[0];
                let z = if norm(v[i]) < q[2] { q[0] } else { q[1] };
                f[i] = sub(f[i], mul(v[i], z));
            }
            LinkKind::Angle => {
                let (i, j, k) = (ps[0], ps[1], ps[2]);
                // -∇ of ½K(cosθ - c0)², cosθ = a·b/(|a||b|).
                let (a, b) = (sub(x[i], x[j]), sub(x[k], x[j]));
                let (la, lb) = (norm(a), norm(b));
                if la > 1e-12 && lb > 1e-12 {
                    let c = dot(a, b) / (la * lb);
                    let dca = sub(mul(b, 1.0 / (la * lb)), mul(a, c / (la * la)));
                    let dcb = sub(mul(a, 1.0 / (la * lb)), mul(b, c / (lb * lb)));
                    let g = -q[0] * (c - q[1]);
                    f[i] = add(f[i], mul(dca, g));
                    f[k] = add(f[k], mul(dcb, g));
                    f[j] = sub(f[j], mul(add(dca, dcb), g));
                }
            }
            LinkKind::Muscle => {
                // SPEC §2.4: q = [K, l0, Z, G, θ, w_len[0..m], w_rate[0..m]]; the neuron sees
                // the listed links, else every other muscle link in file order.
                let (i, j) = (ps[0], ps[1]);
                let me = l as *const _;
                let seen: Vec<usize> = match l.observes.as_ref().or(t.observes.as_ref()) {
                    Some(list) => list.clone(),
                    None => (0..scene.links.len())
                        .filter(|&k| {
                            !std::ptr::eq(&scene.links[k], me)
                                && scene.types[scene.links[k].type_index].kind == LinkKind::Muscle
                        })
                        .collect(),
                };
                let m = seen.len();
                let mut h = -q[4];
                for (k, &o) in seen.iter().enumerate() {
                    let ol = &scene.links[o];
                    let (a, b) = (ol.particles[0], ol.particles[1]);
                    let (u, len) = unit(sub(x[b], x[a]));
                    let l0 = p[off[ol.type_index] + 1];
                    h += q[5 + k] * (len - l0) + q[5 + m + k] * dot(sub(v[b], v[a]), u);
                }
                let (u, _) = unit(sub(x[j], x[i]));
                let fi = add(
                    spring(x[i], x[j], v[i], v[j], q[0], q[1], q[2]),
                    mul(u, q[3] * h.tanh()),
                );
                f[i] = add(f[i], fi);
                f[j] = sub(f[j], fi);
            }
            other => panic!("naive: links of kind {other} are not listed"),
        }
    }
    // Conditional types: brute force over every pair of the group(s).
    for (ti, t) in scene.types.iter().enumerate() {
        if t.kind != LinkKind::Conditional {
            continue;
        }
        let q = &p[off[ti]..];
        let range = q[3];
        let group = |g: &str| -> Vec<usize> {
            (0..x.len())
                .filter(|&i| scene.particles[i].group.as_deref() == Some(g))
                .collect()
        };
        let a = group(&t.groups[0]);
        let pairs: Vec<(usize, usize)> = if t.groups.len() == 1 || t.groups[1] == t.groups[0] {
            let mut v = Vec::new();
            for (k, &i) in a.iter().enumerate() {
                for &j in &a[k + 1..] {
                    v.push((i, j));
                }
            }
            v
        } else {
            let b = group(&t.groups[1]);
            a.iter()
                .flat_map(|&i| b.iter().map(move |&j| (i, j)))
                .collect()
        };
        for (i, j) in pairs {
            if norm(sub(x[j], x[i])) < range {
                let fi = spring(x[i], x[j], v[i], v[j], q[0], q[1], q[2]);
                f[i] = add(f[i], fi);
                f[j] = sub(f[j], fi);
            }
        }
    }
    f
}

/// One step from (x(n), x(n-1)) to x(n+1), fixed particles at `fixed_next`, then Provot.
pub fn naive_step(scene: &Scene, p: &[f64], x: &[V], xp: &[V], fixed_next: &[V]) -> Vec<V> {
    let (off, mass_off, grav_off) = offsets(scene);
    let dt = scene.dt;
    let v: Vec<V> = x
        .iter()
        .zip(xp)
        .map(|(a, b)| mul(sub(*a, *b), 1.0 / dt))
        .collect();
    let f = naive_forces(scene, p, x, &v);
    let g = [p[grav_off], p[grav_off + 1], p[grav_off + 2]];
    let mut next: Vec<V> = (0..x.len())
        .map(|i| {
            if scene.particles[i].fixed {
                fixed_next[i]
            } else {
                let acc = add(mul(f[i], 1.0 / p[mass_off + i]), g);
                add(sub(mul(x[i], 2.0), xp[i]), mul(acc, dt * dt))
            }
        })
        .collect();
    for l in &scene.links {
        let t = &scene.types[l.type_index];
        // τc is a parameter (thesis Table 4.1): read from p, after the spring's three.
        let Some(k) = t.optional_index(cordis_core::OptionalParam::MaxElongation) else {
            continue;
        };
        let tau = p[off[l.type_index] + k];
        let (i, j) = (l.particles[0], l.particles[1]);
        let limit = (1.0 + tau) * p[off[l.type_index] + 1];
        let (u, len) = unit(sub(next[j], next[i]));
        let excess = len - limit;
        if excess > 0.0 {
            let (fi, fj) = (!scene.particles[i].fixed, !scene.particles[j].fixed);
            let (si, sj) = match (fi, fj) {
                (true, true) => (0.5, 0.5),
                (true, false) => (1.0, 0.0),
                (false, true) => (0.0, 1.0),
                _ => (0.0, 0.0),
            };
            next[i] = add(next[i], mul(u, si * excess));
            next[j] = sub(next[j], mul(u, sj * excess));
        }
    }
    next
}

fn frame(traj: &Trajectory, t: usize) -> Vec<V> {
    (0..traj.particles())
        .map(|i| {
            let q = traj.pos(t, i);
            [q.x, q.y, q.z]
        })
        .collect()
}

/// The kind of cost, as the naive implementation understands SPEC §3.
#[derive(Clone, Copy, Debug)]
pub enum Naive {
    /// Windows of h steps from every real start (h = 1: short).
    Windows(usize),
    /// One rollout from frames 0 and 1.
    Long,
    /// Long rollout, `1 / Σ 1/(e + ε)`.
    Harmonic(f64),
}

/// (global cost, local costs) of `p` on `traj`.
pub fn naive_cost(scene: &Scene, traj: &Trajectory, p: &[f64], kind: Naive) -> (f64, Vec<f64>) {
    let t_len = traj.frames();
    let n = traj.particles();
    let frames: Vec<Vec<V>> = (0..t_len).map(|t| frame(traj, t)).collect();
    let (h, starts) = match kind {
        Naive::Windows(h) => (h, (2..t_len).collect::<Vec<_>>()),
        Naive::Long | Naive::Harmonic(_) => (t_len - 2, vec![2]),
    };
    let mut errors: Vec<Vec<f64>> = vec![Vec::new(); n];
    for t0 in starts {
        let (mut x, mut xp) = (frames[t0 - 1].clone(), frames[t0 - 2].clone());
        for real in &frames[t0..(t0 + h).min(t_len)] {
            let next = naive_step(scene, p, &x, &xp, real);
            xp = std::mem::replace(&mut x, next);
            for i in (0..n).filter(|&i| !scene.particles[i].fixed) {
                errors[i].push(norm(sub(x[i], real[i])).powi(2));
            }
        }
    }
    match kind {
        Naive::Harmonic(eps) => {
            let inv: Vec<f64> = errors
                .iter()
                .map(|e| e.iter().map(|e| 1.0 / (e + eps)).sum())
                .collect();
            let per = inv
                .iter()
                .map(|&s: &f64| if s > 0.0 { 1.0 / s } else { 0.0 })
                .collect();
            (1.0 / inv.iter().sum::<f64>(), per)
        }
        _ => {
            let per: Vec<f64> = errors.iter().map(|e| e.iter().sum()).collect();
            (per.iter().sum(), per)
        }
    }
}

/// The `rigid` example (15 particles, 10 link types) over 40 frames, every positive link
/// parameter unknown in a box 10× wide, the truth attached.
pub fn rigid_problem() -> Problem {
    let truth = cordis_core::examples::rigid();
    let traj = truth.simulate(40).expect("rigid simulates");
    let scene = with_unknown_boxes(&truth, 10.0, 3);
    Problem::new(&scene, &traj, CostKind::Short)
        .expect("problem")
        .with_truth(&truth)
        .expect("truth")
}

/// Two free particles in a linear drag, driven by a damped TGR with a damped, sprung tendon
/// (signal `cmd`: a sawtooth).
pub fn driven_tgr_pair() -> Scene {
    let mut s = Scene::new(0.01);
    s.add_particle(Particle::new(1.0, [0.0; 3]));
    s.add_particle(Particle::new(2.0, [1.1, 0.2, 0.0]));
    s.add_signal(Signal::new("cmd", Shape::Sawtooth, 3.0, 0.6).with_rise(0.8));
    s.add_type(LinkType::new("water", LinkKind::Drag).with("damping", 0.5));
    s.add_type(
        LinkType::new("t", LinkKind::Tgr)
            .with("stiffness", 20.0)
            .with("rest_length", 1.0)
            .with("damping", 0.3)
            .with("tendon_mass", 0.05)
            .with("tendon_stiffness", 10.0)
            .with("tendon_damping", 0.5)
            .with_signal("cmd"),
    );
    s.add_link("water", &[0]);
    s.add_link("water", &[1]);
    s.add_coupling("t", &[0, 1]);
    s
}

/// The total mass of a scene's free particles, kg: what `--total-mass` gives discovery.
pub fn free_total(scene: &Scene) -> f64 {
    scene
        .particles
        .iter()
        .filter(|p| !p.fixed)
        .map(|p| p.mass.value())
        .sum()
}
