//! The tangent recursion against finite differences and the core's simulation.

use cordis_core::examples::random_network;
use cordis_core::{Bounds, LinkKind, LinkType, OptionalParam, Param, Scene, Vec3};

use super::tangent::{Sens, Tangent};

/// One 1 kg particle at (1, 0, 0) on an anchor to the origin (type "a": stiffness 10 N/m,
/// rest length 0.5 m, known): the smallest scene a fit's bookkeeping can be tested on.
pub(super) fn anchored_particle() -> Scene {
    let mut scene = Scene::new(0.01);
    scene.add_particle(cordis_core::Particle::new(1.0, [1.0, 0.0, 0.0]));
    scene.add_type(
        LinkType::new("a", LinkKind::Anchor)
            .with("stiffness", 10.0)
            .with("rest_length", 0.5),
    );
    scene.add_link("a", &[0]);
    scene.links[0].point = Some([0.0; 3]);
    scene
}

/// The single-shooting fitter of `space`'s unknowns over `takes`.
pub(super) fn fitter_of<'a>(
    tangent: &'a Tangent,
    space: &'a crate::space::ParameterSpace,
    base: &'a [f64],
    takes: &'a [super::observations::Take],
) -> super::fit::Fitter<'a> {
    let slots: Vec<usize> = space.unknowns.iter().map(|u| u.slot).collect();
    super::fit::Fitter {
        cols: tangent.columns(&slots),
        tangent,
        unknowns: &space.unknowns,
        base,
        takes,
        continuity: None,
    }
}

/// A random network with every damping non-zero, a quadratic viscosity, a damper, an anchor, a
/// drag, two angles, a ground with friction and conditional links
/// (one at a free vertex, one with a fixed end): every term of the tangent recursion (also the
/// matrix-free path's test scene).
pub(super) fn every_term_scene(seed: u64) -> Scene {
    let mut s = random_network(seed, 6, 2);
    for t in &mut s.types {
        t.params[2] = Param::Known(0.2);
    }
    // A quadratic viscosity on the first spring type (Z₂ s |s|).
    s.types[0].set_optional(OptionalParam::DampingQuadratic, Some(Param::Known(0.3)));
    s.add_type(LinkType::new("d", LinkKind::Damper).with("damping", 0.3));
    s.add_type(
        LinkType::new("a", LinkKind::Anchor)
            .with("stiffness", 30.0)
            .with("rest_length", 0.1)
            .with("damping", 0.1),
    );
    s.add_type(LinkType::new("air", LinkKind::Drag).with("damping", 0.05));
    s.add_link("d", &[1, 2]);
    let a = s.add_link("a", &[3]);
    // Away from the particle: an anchor at its own position with l0 > 0 has no direction.
    let x = s.particles[3].pos;
    s.links[a].point = Some([x[0] + 0.2, x[1] - 0.1, x[2] + 0.05]);
    s.add_link("air", &[4]);
    // Rest cosines off the initial ones, so the angles push from frame 0.
    let c = |s: &Scene, [i, j, k]: [usize; 3]| {
        let x = |n: usize| Vec3::from(s.particles[n].pos);
        cordis_core::forces::angle::cos_angle(&x(i), &x(j), &x(k)).unwrap()
    };
    let rest = 0.5 * (c(&s, [1, 2, 3]) + c(&s, [0, 4, 5]));
    s.add_type(
        LinkType::new("bend", LinkKind::Angle)
            .with("stiffness", 5.0)
            .with("rest_cos", rest - 0.1),
    );
    s.add_link("bend", &[1, 2, 3]);
    s.add_link("bend", &[0, 4, 5]);
    // A tilted ground 1 cm above the lowest free particle: it starts in contact, sliding, and
    // others land as the network swings.
    let low = (1..s.particles.len())
        .map(|i| s.particles[i].pos[1])
        .fold(f64::INFINITY, f64::min);
    s.add_type(
        LinkType::new("ground", LinkKind::Plane)
            .with("stiffness", 500.0)
            .with("damping", 2.0)
            .with("friction", 0.5)
            .with_surface([0.0, low + 0.01, 0.0], [0.05, 1.0, -0.1]),
    );
    for i in 1..s.particles.len() {
        s.add_link("ground", &[i]);
    }
    // Conditional links among the free particles, with a quadratic viscosity: the lattice
    // neighbours (0.5 m apart, jittered) are within range, and pairs come and go as it swings.
    for p in &mut s.particles[1..] {
        p.group = Some("g".into());
    }
    let mut touch = LinkType::new("touch", LinkKind::Conditional)
        .with("stiffness", 20.0)
        .with("rest_length", 0.6)
        .with("damping", 0.1)
        .with("range", 0.65)
        .with_optional(OptionalParam::DampingQuadratic, 0.2);
    touch.groups = vec!["g".into()];
    s.add_type(touch);
    s
}

fn scene() -> Scene {
    every_term_scene(3)
}

fn state_of(s: &Scene, t: &Tangent) -> Vec<f64> {
    let mut q = Vec::new();
    for &i in &t.free {
        q.extend_from_slice(&s.particles[i].pos);
        q.extend_from_slice(&s.particles[i].vel);
    }
    q
}

fn positions(t: &Tangent, p: &[f64], q: &[f64], frames: usize) -> Vec<f64> {
    let mut out = Vec::new();
    let mut visit = |_: usize, x: &[Vec3], _: Option<&[f64]>| {
        out.extend(x.iter().flat_map(|v| [v[0], v[1], v[2]]));
    };
    t.rollout(p, q, frames, None, &mut Sens::default(), &mut visit)
        .unwrap();
    out
}

#[test]
fn rollout_is_the_cores_simulation_bit_for_bit() {
    let s = scene();
    let t = Tangent::new(&s).unwrap();
    let x = positions(&t, &s.param_values(), &state_of(&s, &t), 60);
    assert_eq!(x, s.simulate(60).unwrap().as_flat());
}

#[test]
fn sensitivities_match_central_differences() {
    let mut s = scene();
    s.particles[2].mass = Param::Unknown(Bounds {
        min: 0.1,
        max: 10.0,
        init: None,
    });
    against_central_differences(&s, 2, 40, 1e-6);
}

/// A 4 × 4 patch of Provot's cloth (its pinned edge, structural springs limited at τc = 0.1)
/// thrown sideways and up, so its links reach the limit in some frames and not in others, on
/// both kinds of links (both ends free, one end pinned). τc unknown on one structural type.
pub(super) fn provot_scene() -> Scene {
    let mut s = cordis_core::examples::cloth(4, 4);
    for (i, p) in s.particles.iter_mut().enumerate() {
        if !p.fixed {
            let k = i as f64;
            p.vel = [0.4 * (k * 0.7).sin(), 0.6 + 0.3 * (k * 1.3).cos(), 0.5];
        }
    }
    s
}

/// How many of `s`'s first `frames - 1` steps apply a Provot correction, and how many
/// corrections in all (the scene's own simulation, recorded).
pub(super) fn provot_activity(s: &Scene, frames: usize) -> (usize, usize) {
    let plan = cordis_core::plan::Plan::compile(s).unwrap();
    let p = s.param_values();
    let mut sc = plan.scratch();
    let (mut x, mut xp) = (plan.x0.clone(), plan.x_minus1.clone());
    let (mut steps, mut all) = (0, 0);
    for _ in 1..frames {
        plan.step_unprojected(&p, &mut x, &mut xp, &mut sc);
        let mut k = 0;
        plan.provot
            .apply_recorded(&p, &mut x, &plan.free, |_| k += 1);
        steps += usize::from(k > 0);
        all += k;
    }
    (steps, all)
}

#[test]
fn provot_scene_has_active_and_inactive_frames() {
    let (steps, all) = provot_activity(&provot_scene(), 60);
    assert!(steps > 10 && steps < 59, "{steps} of 59 steps corrected");
    assert!(all > 2 * steps, "{all} corrections in {steps} steps");
}

#[test]
fn rollout_with_provot_is_the_cores_simulation_bit_for_bit() {
    // With columns the rollout runs the projection itself (recording it): the same bits.
    let s = provot_scene();
    let t = Tangent::new(&s).unwrap();
    let cols = t.columns(&[0, 1]);
    let mut x = Vec::new();
    let mut visit = |_: usize, xs: &[Vec3], _: Option<&[f64]>| {
        x.extend(xs.iter().flat_map(|v| [v[0], v[1], v[2]]));
    };
    let (p, q) = (s.param_values(), state_of(&s, &t));
    t.rollout(&p, &q, 60, Some(&cols), &mut Sens::default(), &mut visit)
        .unwrap();
    assert_eq!(x, s.simulate(60).unwrap().as_flat());
}

#[test]
fn sensitivities_through_provot_match_central_differences() {
    let mut s = provot_scene();
    s.particles[6].mass = Param::Unknown(Bounds {
        min: 1e-4,
        max: 1e-2,
        init: None,
    });
    // Every parameter (τc of both structural types included), one mass, every state.
    against_central_differences(&s, 6, 60, 1e-7);
}

/// The rollout's sensitivity columns (every type parameter, particle `mass`'s mass, gravity,
/// every free particle's initial state) against central differences of the rollout, relative step
/// `h`, over `frames` frames.
fn against_central_differences(s: &Scene, mass: usize, frames: usize, h: f64) {
    let t = Tangent::new(s).unwrap();
    let layout = s.param_layout();
    let mut slots: Vec<usize> = (0..layout.mass_offset).collect();
    slots.push(layout.mass_offset + mass);
    // Gravity's three components (`discover --identify` fits them).
    slots.extend(layout.gravity_offset..layout.gravity_offset + 3);
    let cols = t.columns(&slots);
    let p = s.param_values();
    let q = state_of(s, &t);
    let mut sens = Vec::new();
    let mut visit = |_: usize, _: &[Vec3], m: Option<&[f64]>| sens.extend_from_slice(m.unwrap());
    t.rollout(
        &p,
        &q,
        frames,
        Some(&cols),
        &mut Sens::default(),
        &mut visit,
    )
    .unwrap();
    let rows = 3 * t.plan.n;
    #[allow(clippy::needless_range_loop)] // col indexes the tangent's columns, not only slots
    for col in 0..cols.len {
        let (mut pp, mut pm, mut qp, mut qm) = (p.clone(), p.clone(), q.clone(), q.clone());
        if col < cols.theta {
            let k = slots[col];
            let step = h * p[k].abs().max(1.0);
            pp[k] += step;
            pm[k] -= step;
            let (a, b) = (
                positions(&t, &pp, &q, frames),
                positions(&t, &pm, &q, frames),
            );
            check(&sens, &a, &b, 2.0 * step, rows, cols.len, col);
        } else {
            let k = col - cols.theta;
            qp[k] += h;
            qm[k] -= h;
            let (a, b) = (
                positions(&t, &p, &qp, frames),
                positions(&t, &p, &qm, frames),
            );
            check(&sens, &a, &b, 2.0 * h, rows, cols.len, col);
        }
    }
}

fn check(sens: &[f64], a: &[f64], b: &[f64], step: f64, rows: usize, width: usize, col: usize) {
    let scale = a
        .iter()
        .zip(b)
        .map(|(x, y)| ((x - y) / step).abs())
        .fold(1e-3, f64::max);
    for (r, (x, y)) in a.iter().zip(b).enumerate() {
        let fd = (x - y) / step;
        let exact = sens[(r / rows) * rows * width + (r % rows) * width + col];
        assert!(
            (fd - exact).abs() <= 1e-5 * scale,
            "column {col}, row {r}: tangent {exact}, central difference {fd}"
        );
    }
}

/// One particle on an anchor 1 m away, `k = K dt²/m` (dt = 10 ms, m = 1 kg): the scheme grows by
/// `λ = (2 - k + √(k² - 4k)) / 2` per step above k = 4 (1.558 at k = 4.2).
fn anchored(kdt2m: f64) -> Scene {
    let mut s = Scene::new(0.01);
    s.add_particle(cordis_core::Particle::new(1.0, [1.0, 0.0, 0.0]));
    s.add_type(LinkType::new("a", LinkKind::Anchor).with("stiffness", kdt2m / 1e-4));
    s.add_link("a", &[0]);
    s.links[0].point = Some([0.0; 3]);
    s
}

#[test]
fn a_runaway_replay_costs_infinity_though_its_positions_stay_finite() {
    // The MuJoCo cable's output-error fit ended on a model that replayed to 5e44 m, finite and
    // below the old absolute 1e100 m guard, so `Fitter::cost` was finite and the model came
    // back as an estimate. The guard is now relative to the observed motion.
    use super::fit::Fitter;
    use crate::space::ParameterSpace;
    let truth = anchored(1.0);
    let traj = truth.simulate(60).unwrap();
    let mut guess = truth.clone();
    guess.types[0].params[0] = Param::Unknown(Bounds {
        min: 1.0,
        max: 1e6,
        init: None,
    });
    let takes = vec![super::observations::Take::complete(&traj)];
    let mut tangent = Tangent::new(&guess).unwrap();
    let space = ParameterSpace::from_scene(&guess);
    let base = guess.param_values();
    let runaway_k = 4.2 / 1e-4;
    let mut q = vec![space.unknowns[0].to_internal(runaway_k)];
    q.extend(state_of(&truth, &tangent));
    let mut p = base.clone();
    p[space.unknowns[0].slot] = runaway_k;
    // Without a relative guard (the cap alone) the replay runs to the end, finite.
    let own = tangent.runaway;
    tangent.runaway = cordis_core::Runaway::default();
    let x = positions(&tangent, &p, &q[1..], 60);
    let far = x.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
    assert!(far.is_finite() && far > 1e10 && far < 1e100, "{far}");
    tangent.runaway = own;
    tangent.guard_by(&takes);
    let fitter = Fitter {
        cols: tangent.columns(&[space.unknowns[0].slot]),
        tangent: &tangent,
        unknowns: &space.unknowns,
        base: &base,
        takes: &takes,
        continuity: None,
    };
    assert_eq!(fitter.cost(&q, 60, &mut Sens::default()), f64::INFINITY);
    // The true stiffness is no runaway: its cost is the exact fit's.
    let mut q_true = q.clone();
    q_true[0] = space.unknowns[0].to_internal(1.0 / 1e-4);
    let c = fitter.cost(&q_true, 60, &mut Sens::default());
    assert!(c < 1e-20, "{c}");
}
