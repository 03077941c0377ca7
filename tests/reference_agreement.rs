//! The core (`Plan` and its typed passes) against the naive reference of `reference/mod.rs`,
//! one scene per passive link kind and one that mixes them all. Both follow SPEC §2.1–2.2;
//! only the order of summation may differ, so they must agree to rounding: max |difference|
//! ≤ 1e-9 × the largest displacement of the motion.

mod reference;

use cordis_core::{Link, LinkKind, LinkType, Param, Particle, Scene};

const FRAMES: usize = 400;

/// Positions per frame, per particle.
type Run = Vec<Vec<[f64; 3]>>;

/// Small deterministic generator (xorshift64*), so scenes are reproducible without a dependency.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        let r = self.0.wrapping_mul(0x2545_f491_4f6c_dd1d);
        (r >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.next()
    }
    fn v3(&mut self, h: f64) -> [f64; 3] {
        [self.range(-h, h), self.range(-h, h), self.range(-h, h)]
    }
}

/// Simulates with both and returns (core, reference) positions per frame.
fn both(scene: &Scene, frames: usize) -> (Run, Run) {
    let traj = scene.simulate(frames).expect("the core simulates");
    let core = (0..frames)
        .map(|t| {
            (0..scene.particles.len())
                .map(|i| traj.pos(t, i).into())
                .collect()
        })
        .collect();
    (core, reference::simulate(scene, frames))
}

/// Largest displacement from frame 0 over the run, m.
fn motion_scale(run: &[Vec<[f64; 3]>]) -> f64 {
    let mut s: f64 = 0.0;
    for frame in run {
        for (x, x0) in frame.iter().zip(&run[0]) {
            for k in 0..3 {
                s = s.max((x[k] - x0[k]).abs());
            }
        }
    }
    s
}

fn max_diff(a: &[Vec<[f64; 3]>], b: &[Vec<[f64; 3]>]) -> f64 {
    let mut d: f64 = 0.0;
    for (fa, fb) in a.iter().zip(b) {
        for (xa, xb) in fa.iter().zip(fb) {
            for k in 0..3 {
                d = d.max((xa[k] - xb[k]).abs());
            }
        }
    }
    d
}

/// Asserts agreement and returns the reference run for scene-specific checks.
fn agree(scene: &Scene) -> Run {
    let (core, reference) = both(scene, FRAMES);
    assert_eq!(core.len(), FRAMES);
    let scale = motion_scale(&reference);
    assert!(scale > 1e-3, "the scene barely moves (scale {scale} m)");
    let diff = max_diff(&core, &reference);
    assert!(
        diff <= 1e-9 * scale,
        "core and reference differ by {diff:e} m (scale {scale} m)"
    );
    reference
}

fn spring(k: f64, l0: f64, z: f64) -> LinkType {
    LinkType::new("s", LinkKind::Spring)
        .with("stiffness", k)
        .with("rest_length", l0)
        .with("damping", z)
}

/// A fixed particle and a small 3-D chain of springs hanging from it.
fn chain(z: f64) -> Scene {
    let mut s = Scene::new(0.005);
    s.add_particle(Particle::new(1.0, [0.0, 0.0, 0.0]).fixed());
    s.add_particle(Particle::new(0.5, [1.3, 0.2, 0.0]));
    s.add_particle(Particle::new(0.8, [2.1, -0.4, 0.3]).with_vel([0.0, 0.5, -0.2]));
    s.add_particle(Particle::new(1.2, [2.5, 0.6, -0.5]));
    s.add_type(spring(40.0, 1.0, z));
    s.add_link("s", &[0, 1]);
    s.add_link("s", &[1, 2]);
    s.add_link("s", &[2, 3]);
    s.add_link("s", &[3, 1]);
    s
}

#[test]
fn spring_undamped() {
    agree(&chain(0.0));
}

#[test]
fn spring_damped() {
    let damped = agree(&chain(0.8));
    let undamped = reference::simulate(&chain(0.0), FRAMES);
    assert!(max_diff(&damped, &undamped) > 1e-3, "damping has no effect");
}

#[test]
fn damper() {
    let mut s = Scene::new(0.01);
    s.add_particle(Particle::new(1.0, [0.0, 0.0, 0.0]).with_vel([1.0, 0.0, 0.5]));
    s.add_particle(Particle::new(2.0, [1.0, 0.0, 0.0]).with_vel([-0.5, 1.0, 0.0]));
    s.add_particle(Particle::new(0.5, [0.0, 1.0, 0.0]));
    s.add_type(LinkType::new("d", LinkKind::Damper).with("damping", 0.7));
    s.add_link("d", &[0, 1]);
    s.add_link("d", &[1, 2]);
    let run = agree(&s);
    // The damper pulls the relative velocity of 0 and 1 down.
    let rel = |t: usize| {
        let (a, b) = (&run[t], &run[t - 1]);
        ((a[1][0] - b[1][0]) - (a[0][0] - b[0][0])).abs()
    };
    assert!(rel(FRAMES - 1) < 0.5 * rel(1));
}

fn anchor_scene(type_point: Option<[f64; 3]>, link_point: Option<[f64; 3]>) -> Scene {
    let mut s = Scene::new(0.01);
    s.add_particle(Particle::new(1.0, [1.0, 0.5, 0.0]).with_vel([0.3, -0.8, 0.4]));
    let mut t = LinkType::new("a", LinkKind::Anchor)
        .with("stiffness", 25.0)
        .with("rest_length", 0.2)
        .with("damping", 0.3);
    t.point = type_point;
    s.add_type(t);
    s.links.push(Link {
        type_index: 0,
        particles: vec![0],
        point: link_point,
        observes: None,
    });
    s
}

#[test]
fn anchor_type_point() {
    let run = agree(&anchor_scene(Some([0.0, 0.0, 1.0]), None));
    let other = reference::simulate(&anchor_scene(None, None), FRAMES);
    assert!(max_diff(&run, &other) > 1e-2, "the type point is not used");
}

#[test]
fn anchor_link_point_overrides_type_point() {
    let run = agree(&anchor_scene(Some([0.0, 0.0, 1.0]), Some([2.0, -1.0, 0.0])));
    let other = reference::simulate(&anchor_scene(Some([0.0, 0.0, 1.0]), None), FRAMES);
    assert!(max_diff(&run, &other) > 1e-2, "the link point is not used");
}

#[test]
fn anchor_default_point() {
    agree(&anchor_scene(None, None));
}

#[test]
fn drag() {
    let mut s = Scene::new(0.01);
    s.add_particle(Particle::new(1.0, [0.0, 0.0, 0.0]).with_vel([2.0, -1.0, 0.5]));
    s.add_particle(Particle::new(3.0, [1.0, 0.0, 0.0]).with_vel([0.0, 1.0, 1.0]));
    s.add_type(LinkType::new("air", LinkKind::Drag).with("damping", 0.9));
    s.add_link("air", &[0]);
    s.add_link("air", &[1]);
    agree(&s);
}

#[test]
fn nonlinear_drag_crossing_v_max() {
    let mut s = Scene::new(0.01);
    s.add_particle(Particle::new(1.0, [0.0, 0.0, 0.0]).with_vel([3.0, 1.0, 0.0]));
    s.add_particle(Particle::new(0.5, [0.0, 1.0, 0.0]).with_vel([0.0, 0.0, -2.5]));
    s.add_type(
        LinkType::new("medium", LinkKind::NonlinearDrag)
            .with("z1", 0.2)
            .with("z2", 1.5)
            .with("v_max", 1.0),
    );
    s.add_link("medium", &[0]);
    s.add_link("medium", &[1]);
    let run = agree(&s);
    let speed = |t: usize, i: usize| {
        let d: Vec<f64> = (0..3).map(|k| run[t][i][k] - run[t - 1][i][k]).collect();
        (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt() / s.dt
    };
    for i in 0..2 {
        assert!(
            speed(1, i) > 1.0 && speed(FRAMES - 1, i) < 1.0,
            "no crossing"
        );
    }
}

#[test]
fn angle() {
    let mut s = Scene::new(0.005);
    s.add_particle(Particle::new(1.0, [1.0, 0.0, 0.0]));
    s.add_particle(Particle::new(2.0, [0.0, 0.0, 0.0]).with_vel([0.0, 0.0, 0.3]));
    s.add_particle(Particle::new(1.0, [0.2, 1.0, 0.1]));
    s.add_particle(Particle::new(0.7, [-0.8, 0.9, -0.3]));
    s.add_type(
        LinkType::new("bend", LinkKind::Angle)
            .with("stiffness", 3.0)
            .with("rest_cos", -0.5),
    );
    s.add_link("bend", &[0, 1, 2]);
    s.add_link("bend", &[1, 2, 3]);
    agree(&s);
}

/// A cloud of particles in `groups` (round-robin) flying into each other.
fn cloud(groups: &[&str], seed: u64) -> Scene {
    let mut rng = Rng(seed);
    let mut s = Scene::new(0.005);
    for i in 0..24 {
        let p = Particle::new(rng.range(0.5, 1.5), rng.v3(1.0))
            .with_vel(rng.v3(1.0))
            .in_group(groups[i % groups.len()]);
        s.add_particle(p);
    }
    let mut t = LinkType::new("near", LinkKind::Conditional)
        .with("stiffness", 30.0)
        .with("rest_length", 0.4)
        .with("damping", 0.2)
        .with("range", 0.5);
    t.groups = groups.iter().map(|g| g.to_string()).collect();
    s.add_type(t);
    s
}

/// Active pairs in one frame of the reference run, brute force.
fn active_pairs(scene: &Scene, frame: &[[f64; 3]]) -> usize {
    let r = scene.types[0].value("range").unwrap();
    let g = &scene.types[0].groups;
    let n = frame.len();
    let mut count = 0;
    for i in 0..n {
        for j in i + 1..n {
            let (gi, gj) = (
                scene.particles[i].group.as_deref().unwrap(),
                scene.particles[j].group.as_deref().unwrap(),
            );
            let linked = if g.len() == 1 {
                gi == g[0] && gj == g[0]
            } else {
                (gi == g[0] && gj == g[1]) || (gi == g[1] && gj == g[0])
            };
            let d: f64 = (0..3)
                .map(|k| (frame[j][k] - frame[i][k]).powi(2))
                .sum::<f64>()
                .sqrt();
            count += usize::from(linked && d < r);
        }
    }
    count
}

#[test]
fn conditional_one_group() {
    let s = cloud(&["gas"], 7);
    let run = agree(&s);
    let total: usize = run.iter().map(|f| active_pairs(&s, f)).sum();
    assert!(total > FRAMES / 2, "too few active pairs ({total})");
}

#[test]
fn conditional_two_groups() {
    let s = cloud(&["jet", "gas"], 11);
    let run = agree(&s);
    let total: usize = run.iter().map(|f| active_pairs(&s, f)).sum();
    assert!(total > FRAMES / 2, "too few active pairs ({total})");
}

#[test]
fn conditional_two_groups_ignores_a_third_and_ungrouped_particles() {
    let mut s = cloud(&["jet", "gas", "other"], 13);
    s.types[0].groups.truncate(2);
    s.particles[5].group = None;
    agree(&s);
}

#[test]
fn conditional_naming_one_group_twice_is_one_group() {
    let mut s = cloud(&["gas"], 17);
    s.types[0].groups = vec!["gas".into(), "gas".into()];
    let twice = agree(&s);
    let once = reference::simulate(&cloud(&["gas"], 17), FRAMES);
    assert_eq!(max_diff(&twice, &once), 0.0);
}

#[test]
fn gravity() {
    let mut s = Scene::new(0.01);
    s.gravity = [0.5, -1.0, -9.81];
    s.add_particle(Particle::new(1.0, [0.0, 0.0, 0.0]).with_vel([1.0, 2.0, 3.0]));
    s.add_particle(Particle::new(4.0, [1.0, 1.0, 1.0]));
    s.add_particle(Particle::new(4.0, [2.0, 1.0, 1.0]).fixed());
    let run = agree(&s);
    assert_eq!(run[FRAMES - 1][2], [2.0, 1.0, 1.0]);
}

#[test]
fn fixed_particles() {
    let mut s = chain(0.3);
    s.particles[3].fixed = true;
    s.gravity = [0.0, 0.0, -9.81];
    let run = agree(&s);
    for frame in &run {
        assert_eq!(frame[0], s.particles[0].pos);
        assert_eq!(frame[3], s.particles[3].pos);
    }
}

/// Two springs that stretch fast: one between free ends, one to a fixed end.
fn provot_scene(tau: Option<f64>) -> Scene {
    let mut s = Scene::new(0.01);
    s.add_particle(Particle::new(1.0, [0.0, 0.0, 0.0]).with_vel([-1.0, 0.2, 0.0]));
    s.add_particle(Particle::new(2.0, [1.0, 0.0, 0.0]).with_vel([1.5, 0.0, 0.3]));
    s.add_particle(Particle::new(1.0, [3.0, 0.0, 0.0]).fixed());
    s.add_particle(Particle::new(1.0, [3.0, 1.0, 0.0]).with_vel([0.4, 2.0, 0.0]));
    let mut t = spring(5.0, 1.0, 0.1);
    t.set_optional(
        cordis_core::OptionalParam::MaxElongation,
        tau.map(Into::into),
    );
    s.add_type(t);
    s.add_link("s", &[0, 1]);
    s.add_link("s", &[2, 3]);
    s.add_link("s", &[1, 3]);
    s
}

#[test]
fn max_elongation_free_free_and_free_fixed() {
    let s = provot_scene(Some(0.1));
    let run = agree(&s);
    let unlimited = reference::simulate(&provot_scene(None), FRAMES);
    assert!(
        max_diff(&run, &unlimited) > 1e-2,
        "the limit never acts in this scene"
    );
    // After the last link's correction, the first two links may be stretched again by it, so
    // only the last link in file order is guaranteed within its limit.
    let len = |a: [f64; 3], b: [f64; 3]| {
        ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt()
    };
    for frame in &run[1..] {
        assert!(len(frame[1], frame[3]) <= 1.1 * (1.0 + 1e-12));
    }
}

/// Every passive kind at once, several types of a kind interleaved in the file.
fn mixed() -> Scene {
    let mut rng = Rng(2024);
    let mut s = Scene::new(0.004);
    s.gravity = [0.0, -2.0, -9.81];
    for i in 0..14 {
        let mut p = Particle::new(rng.range(0.5, 2.0), rng.v3(1.5)).with_vel(rng.v3(1.0));
        p.group = Some(["gas", "jet"][i % 2].to_string());
        s.add_particle(p);
    }
    s.particles[0].fixed = true;
    s.particles[0].vel = [0.0; 3];
    s.particles[13].group = None;
    s.add_type(spring(60.0, 0.8, 0.5));
    let mut limited = spring(40.0, 1.0, 0.0);
    limited.name = "limited".into();
    limited.set_optional(cordis_core::OptionalParam::MaxElongation, Some(0.05.into()));
    s.add_type(limited);
    s.add_type(LinkType::new("d", LinkKind::Damper).with("damping", 0.4));
    let mut anchor = LinkType::new("a", LinkKind::Anchor)
        .with("stiffness", 20.0)
        .with("damping", 0.2);
    anchor.point = Some([0.0, 0.0, 2.0]);
    s.add_type(anchor);
    s.add_type(LinkType::new("a0", LinkKind::Anchor).with("stiffness", 10.0));
    s.add_type(LinkType::new("air", LinkKind::Drag).with("damping", 0.1));
    s.add_type(
        LinkType::new("medium", LinkKind::NonlinearDrag)
            .with("z1", 0.05)
            .with("z2", 0.6)
            .with("v_max", 1.2),
    );
    s.add_type(
        LinkType::new("bend", LinkKind::Angle)
            .with("stiffness", 2.0)
            .with("rest_cos", 0.3),
    );
    let mut c1 = LinkType::new("near", LinkKind::Conditional)
        .with("stiffness", 15.0)
        .with("rest_length", 0.5)
        .with("range", 0.6);
    c1.groups = vec!["gas".into()];
    s.add_type(c1);
    let mut c2 = LinkType::new("cross", LinkKind::Conditional)
        .with("stiffness", 10.0)
        .with("rest_length", 0.6)
        .with("damping", 0.3)
        .with("range", 0.8);
    c2.groups = vec!["jet".into(), "gas".into()];
    s.add_type(c2);
    s.add_link("s", &[0, 1]);
    s.add_link("limited", &[1, 2]);
    s.add_link("bend", &[1, 2, 3]);
    s.add_link("s", &[2, 3]);
    s.add_link("d", &[3, 4]);
    s.add_link("limited", &[0, 5]);
    s.add_link("a", &[4]);
    s.add_link("air", &[5]);
    s.add_link("medium", &[6]);
    s.add_link("limited", &[5, 6]);
    s.add_link("s", &[6, 7]);
    s.add_link("bend", &[6, 7, 8]);
    s.add_link("a0", &[8]);
    s.add_link("medium", &[9]);
    s.add_link("d", &[9, 10]);
    s.add_link("s", &[10, 11]);
    s.add_link("limited", &[11, 12]);
    s.add_link("air", &[12]);
    s.add_link("a0", &[13]);
    s.links.push(Link {
        type_index: s.type_index("a").unwrap(),
        particles: vec![11],
        point: Some([1.0, 1.0, -1.0]),
        observes: None,
    });
    s
}

#[test]
fn mixed_scene_of_every_passive_kind() {
    let s = mixed();
    s.validate().unwrap();
    agree(&s);
}

#[test]
fn mixed_scene_through_json() {
    let s = Scene::from_json_str(&mixed().to_json_string()).unwrap();
    agree(&s);
}

/// Muscles (SPEC §2.4) on a 3-D chain with a spring: one type observing every other muscle by
/// default (two instances, so each sees a different pair), one observing a listed link, both
/// with damping, gain, threshold and weights of both signs.
fn muscles() -> Scene {
    let mut s = Scene::new(0.004);
    s.add_particle(Particle::new(1.0, [0.0, 0.0, 0.0]).fixed());
    s.add_particle(Particle::new(0.6, [1.1, 0.1, 0.0]).with_vel([0.0, 0.4, 0.1]));
    s.add_particle(Particle::new(0.9, [2.0, -0.3, 0.2]));
    s.add_particle(Particle::new(0.7, [2.6, 0.5, -0.4]).with_vel([-0.3, 0.0, 0.2]));
    let w = |v: &[f64]| v.iter().map(|&x| Param::Known(x)).collect::<Vec<_>>();
    s.add_type(
        LinkType::new("m2", LinkKind::Muscle)
            .with("stiffness", 30.0)
            .with("rest_length", 1.0)
            .with("damping", 0.2)
            .with("gain", 4.0)
            .with("threshold", -0.3)
            .with_weights(&w(&[2.0, -1.5]), &w(&[0.4, -0.7])),
    );
    let mut one = LinkType::new("m1", LinkKind::Muscle)
        .with("stiffness", 45.0)
        .with("rest_length", 0.9)
        .with("gain", 2.5)
        .with("threshold", 0.2)
        .with_weights(&w(&[-3.0]), &w(&[1.1]));
    one.observes = Some(vec![0]);
    s.add_type(one);
    s.add_type(spring(20.0, 1.2, 0.1));
    s.add_link("m2", &[0, 1]);
    s.add_link("m1", &[1, 2]);
    s.add_link("s", &[2, 3]);
    s.add_link("m2", &[3, 1]);
    s
}

#[test]
fn muscle() {
    let s = muscles();
    s.validate().unwrap();
    let run = agree(&s);
    // The neurons act: the same scene with silent neurons moves differently.
    let mut silent = s.clone();
    for t in silent
        .types
        .iter_mut()
        .filter(|t| t.kind == LinkKind::Muscle)
    {
        let m = t.num_weights();
        let z = vec![Param::Known(0.0); m];
        *t = t.clone().with("gain", 0.0).with_weights(&z, &z);
    }
    let passive = reference::simulate(&silent, FRAMES);
    assert!(
        max_diff(&run, &passive) > 1e-3,
        "the neurons have no effect"
    );
}

#[test]
fn muscle_with_link_observes_through_json() {
    let mut s = muscles();
    // The second m2 instance observes m1 then the first m2, overriding the default order.
    s.links[3].observes = Some(vec![1, 0]);
    let back = Scene::from_json_str(&s.to_json_string()).unwrap();
    assert_eq!(back, s);
    agree(&back);
    let (a, b) = (
        reference::simulate(&s, FRAMES),
        reference::simulate(&muscles(), FRAMES),
    );
    assert!(max_diff(&a, &b) > 1e-6, "the observed order has no effect");
}
