//! The central-control muscle (thesis §5.4): a TGR whose tendon a controller world's dipole
//! drives and which feeds the reaction back (`"controller": [c, d]` on a `tgr` coupling); the
//! TGR's world's own dt for its tendon and signal; couplings validated against worlds.
//!
//! `cargo test --release -p cordis-core --test central_muscle`

use cordis_core::examples::{central_idx, central_muscle, tadpole, CENTRAL_MUSCLE_FRAMES};
use cordis_core::{
    CordisError, LinkKind, LinkType, Particle, Scene, Shape, Signal, Simulator, Trajectory,
};
use serde_json::{json, Value};

const MAIN_DT: f64 = 0.01;
const CTRL_DT: f64 = 0.0037;

/// Mass-weighted x of the mobile (particles 0 and 1), m.
fn mobile_x(s: &Scene, traj: &Trajectory, t: usize) -> f64 {
    let m = |i: usize| s.particles[i].mass.value();
    (m(0) * traj.pos(t, 0).x + m(1) * traj.pos(t, 1).x) / (m(0) + m(1))
}

#[test]
fn the_controller_moves_the_mobile_through_the_tgr_alone() {
    let s = central_muscle();
    // The mobile's only actuator is the muscle, and it has no signal: only its controller
    // drives it.
    let muscle = &s.types[s.type_index("muscle").unwrap()];
    assert_eq!(muscle.signal, None);
    let on_mobile: Vec<_> = s
        .couplings
        .iter()
        .filter(|c| c.particles.contains(&central_idx::HEAVY))
        .collect();
    assert_eq!(on_mobile.len(), 1);
    assert_eq!(
        on_mobile[0].controller,
        Some([central_idx::MIND_FOOT, central_idx::MIND_NECK])
    );
    let traj = s.simulate(CENTRAL_MUSCLE_FRAMES).unwrap();
    let travel = mobile_x(&s, &traj, CENTRAL_MUSCLE_FRAMES - 1) - mobile_x(&s, &traj, 0);
    // Ten strokes: it swims towards its light end (+x) like the signal-driven tadpole.
    let tp = tadpole();
    let tp_traj = tp.simulate(CENTRAL_MUSCLE_FRAMES).unwrap();
    let tp_travel = mobile_x(&tp, &tp_traj, CENTRAL_MUSCLE_FRAMES - 1) - mobile_x(&tp, &tp_traj, 0);
    eprintln!("central muscle: {travel:.3} m; signal-driven tadpole: {tp_travel:.3} m");
    assert!(travel > 2.0, "the mobile swam only {travel} m");

    // The controller held still (its virtual neck fixed): the mobile does not move at all.
    let mut held = s.clone();
    held.particles[central_idx::MIND_NECK].fixed = true;
    let still = held.simulate(CENTRAL_MUSCLE_FRAMES).unwrap();
    for t in 0..CENTRAL_MUSCLE_FRAMES {
        assert_eq!(still.pos(t, 0), still.pos(0, 0), "frame {t}");
        assert_eq!(still.pos(t, 1), still.pos(0, 1), "frame {t}");
    }
}

#[test]
fn the_controller_feels_the_mobile() {
    // The same controller drives a mobile in a medium ten times thicker: the controller's
    // dipole moves differently (the tendon's spring pulls its virtual neck with the muscle's
    // tension), while with the muscle's link cut (K = 0) the medium does not matter to it.
    let dipole = |s: &Scene| {
        let traj = s.simulate(800).unwrap();
        let (c, d) = (central_idx::MIND_FOOT, central_idx::MIND_NECK);
        (0..800)
            .map(|t| (traj.pos(t, d) - traj.pos(t, c)).norm())
            .collect::<Vec<f64>>()
    };
    let thick = |mut s: Scene| {
        let w = s.type_index("water").unwrap();
        for name in ["z1", "z2"] {
            let z = s.types[w].value(name).unwrap();
            s.types[w] = s.types[w].clone().with(name, 10.0 * z);
        }
        s
    };
    let gap = |a: &[f64], b: &[f64]| {
        a.iter()
            .zip(b)
            .map(|(x, y)| (x - y).abs())
            .fold(0.0, f64::max)
    };
    let s = central_muscle();
    let felt = gap(&dipole(&s), &dipole(&thick(s.clone())));
    let mut cut = s.clone();
    let m = cut.type_index("muscle").unwrap();
    cut.types[m] = cut.types[m].clone().with("stiffness", 0.0);
    let unfelt = gap(&dipole(&cut), &dipole(&thick(cut.clone())));
    eprintln!("controller dipole: {felt:.3e} m apart with the load changed, {unfelt:e} with K = 0");
    assert!(felt > 1e-3, "the controller did not feel the load: {felt}");
    assert_eq!(unfelt, 0.0);
}

/// A muscle between a fixed particle 0 and a free particle 1 (main world, along x), its tendon
/// anchored on the dipole (2, 3) of world `ctrl` (2 fixed, 3 free on a spring, along y).
fn pair(damped: bool, signal: bool) -> Scene {
    let mut s = Scene::new(MAIN_DT);
    s.add_world("ctrl", CTRL_DT);
    s.add_particle(Particle::new(1.0, [0.0; 3]).fixed());
    s.add_particle(Particle::new(0.7, [1.3, 0.0, 0.0]).with_vel([0.4, 0.0, 0.0]));
    s.add_particle(Particle::new(1.0, [0.0, 5.0, 0.0]).fixed().in_world("ctrl"));
    s.add_particle(
        Particle::new(0.4, [0.0, 5.6, 0.0])
            .with_vel([0.0, 1.5, 0.0])
            .in_world("ctrl"),
    );
    let z = |v: f64| if damped { v } else { 0.0 };
    let mut muscle = LinkType::new("m", LinkKind::Tgr)
        .with("stiffness", 20.0)
        .with("rest_length", 0.6)
        .with("damping", z(0.4))
        .with("tendon_mass", 0.05)
        .with("tendon_stiffness", 8.0)
        .with("tendon_damping", z(0.2));
    if signal {
        s.add_signal(Signal::new("cmd", Shape::Sawtooth, 2.0, 0.37).with_rise(0.7));
        muscle = muscle.with_signal("cmd");
    }
    s.add_type(muscle);
    s.add_type(
        LinkType::new("hold", LinkKind::Spring)
            .with("stiffness", 30.0)
            .with("rest_length", 0.6),
    );
    s.add_link("hold", &[2, 3]);
    s.add_controlled_tgr("m", [0, 1], [2, 3]);
    s
}

#[test]
fn muscle_tendon_and_controller_follow_the_equations_by_hand() {
    let s = pair(true, true);
    let (mt, k, l0, z, kt, zt) = (0.05, 20.0, 0.6, 0.4, 8.0, 0.2);
    let signal = s.signals[0].clone();
    let mut sim = Simulator::new(&s).unwrap();
    // By hand: particle 1's x (main dt), particle 3's y (ctrl dt), the tendon (main dt).
    let (mut x, mut xp) = (1.3f64, 1.3 - 0.4 * MAIN_DT);
    let (mut a, mut ap) = (0.6f64, 0.6 - 1.5 * CTRL_DT);
    let (mut y, mut yp, mut a_prev) = (0.6f64, 0.6f64, 0.6f64);
    for n in 0..400 {
        let v = (x - xp) / MAIN_DT;
        let tension = k * (x - (l0 + y)) + z * v;
        let hold = kt * (y - a) + zt * ((y - a) - (yp - a_prev)) / MAIN_DT;
        let xn = 2.0 * x - xp + MAIN_DT * MAIN_DT * (-tension / 0.7);
        // Particle 3: its spring to 2 (30 N/m, l0 0.6) and the tendon's pull `hold` along +y.
        let an = 2.0 * a - ap + CTRL_DT * CTRL_DT * ((-30.0 * (a - 0.6) + hold) / 0.4);
        let force = signal.value(n as f64 * MAIN_DT) + tension - hold;
        let yn = 2.0 * y - yp + MAIN_DT * MAIN_DT / mt * force;
        (xp, x, ap, a_prev, a, yp, y) = (x, xn, a, a, an, y, yn);
        sim.step().unwrap();
        let close = |got: f64, want: f64| (got - want).abs() <= 1e-12 + 1e-10 * want.abs();
        let got = sim.positions();
        assert!(close(got[1].x, x), "frame {n}: x {} vs {x}", got[1].x);
        assert!(
            close(got[3].y - 5.0, a),
            "frame {n}: a {} vs {a}",
            got[3].y - 5.0
        );
        let st = sim.state();
        assert!(
            close(st[0], y) && close(st[1], yp) && close(st[2], a_prev),
            "state at {n}"
        );
    }
    assert!((y - 0.6).abs() > 0.01, "the tendon moved: {y}");
}

/// Kinetic energy of particle i at frame t (central velocity in its world's time), J.
fn kinetic(s: &Scene, traj: &Trajectory, t: usize, i: usize) -> f64 {
    let dt = s.particle_dt(i);
    let v = (traj.pos(t + 1, i) - traj.pos(t - 1, i)) / (2.0 * dt);
    0.5 * s.particles[i].mass.value() * v.norm_squared()
}

#[test]
fn an_undamped_central_muscle_conserves_both_worlds_energy() {
    // No damping and no signal: muscle, tendon and controller exchange energy through the
    // coupling's potential ½K(L - l0 - y)² + ½K_t(y - a)², so the sum is conserved — which
    // holds only if the controller receives exactly the reaction the tendon feels.
    let s = pair(false, false);
    let frames = 60_000;
    let mut sim = Simulator::new(&s).unwrap();
    let mut ys = vec![sim.state()[0]];
    for _ in 1..frames {
        sim.step().unwrap();
        ys.push(sim.state()[0]);
    }
    let traj = s.simulate(frames).unwrap();
    let len = |t: usize, i: usize, j: usize| (traj.pos(t, j) - traj.pos(t, i)).norm();
    let energy: Vec<f64> = (1..frames - 1)
        .map(|t| {
            let (l, a, y) = (len(t, 0, 1), len(t, 2, 3), ys[t]);
            let ty = (ys[t + 1] - ys[t - 1]) / (2.0 * MAIN_DT);
            kinetic(&s, &traj, t, 1)
                + kinetic(&s, &traj, t, 3)
                + 0.5 * 0.05 * ty * ty
                + 0.5 * 20.0 * (l - 0.6 - y).powi(2)
                + 0.5 * 8.0 * (y - a).powi(2)
                + 0.5 * 30.0 * (a - 0.6).powi(2)
        })
        .collect();
    let e0 = energy[0];
    let worst = energy.iter().map(|e| (e - e0).abs()).fold(0.0, f64::max);
    let tenth = energy.len() / 10;
    let mean = |e: &[f64]| e.iter().sum::<f64>() / e.len() as f64;
    let drift = mean(&energy[energy.len() - tenth..]) - mean(&energy[..tenth]);
    eprintln!("energy {e0:.6} J: wanders by {worst:.2e}, drifts by {drift:.2e}");
    // The scheme's bounded oscillation (measured 1.8e-3 of e0) and no drift (measured 7e-7):
    // without the reaction on the controller, or with it of the wrong sign, the sum drifts.
    assert!(worst < 5e-3 * e0, "energy wanders by {worst:e} of {e0}");
    assert!(drift.abs() < 1e-5 * e0, "drift {drift:e} of {e0}");
    // And the controller's share did change (the worlds exchange energy).
    let ctrl: Vec<f64> = (1..frames - 1)
        .step_by(7)
        .map(|t| kinetic(&s, &traj, t, 3) + 0.5 * 30.0 * (len(t, 2, 3) - 0.6).powi(2))
        .collect();
    let (lo, hi) = ctrl
        .iter()
        .fold((f64::MAX, 0.0_f64), |(a, b), &e| (a.min(e), b.max(e)));
    assert!(hi - lo > 0.1 * e0, "controller energy {lo}..{hi} of {e0}");
}

/// A signal-driven TGR between a fixed and a free particle, in world `w` (dt `dt`), with a
/// main-world bystander when `w` is not main.
fn tgr_in_world(w: &str, dt: f64) -> Scene {
    let mut s = Scene::new(if w == "main" { dt } else { MAIN_DT });
    if w != "main" {
        s.add_world(w, dt);
        s.add_particle(Particle::new(1.0, [9.0, 0.0, 0.0]).fixed());
    }
    s.add_particle(Particle::new(1.0, [0.0; 3]).fixed().in_world(w));
    s.add_particle(Particle::new(0.7, [1.3, 0.0, 0.0]).in_world(w));
    s.add_signal(Signal::new("cmd", Shape::Sawtooth, 2.0, 0.37).with_rise(0.7));
    s.add_type(
        LinkType::new("t", LinkKind::Tgr)
            .with("stiffness", 20.0)
            .with("rest_length", 1.0)
            .with("damping", 0.4)
            .with("tendon_mass", 0.05)
            .with("tendon_stiffness", 3.0)
            .with("tendon_damping", 0.2)
            .with_signal("cmd"),
    );
    let n = s.particles.len();
    s.add_coupling("t", &[n - 2, n - 1]);
    s
}

#[test]
fn a_tgr_in_a_controller_world_steps_its_tendon_and_signal_with_that_worlds_dt() {
    let frames = 500;
    let there = tgr_in_world("ctrl", CTRL_DT).simulate(frames).unwrap();
    let alone = tgr_in_world("main", CTRL_DT).simulate(frames).unwrap();
    for t in 0..frames {
        // Bit for bit: the tendon's dt and the signal's clock are the ctrl world's.
        assert_eq!(there.pos(t, 2), alone.pos(t, 1), "frame {t}");
    }
    let wrong = tgr_in_world("main", MAIN_DT).simulate(frames).unwrap();
    assert_ne!(there.pos(frames - 1, 2), wrong.pos(frames - 1, 1));
}

#[test]
fn json_round_trips_the_controller() {
    let s = central_muscle();
    let v: Value = serde_json::from_str(&s.to_json_string()).unwrap();
    assert_eq!(v["couplings"][0]["controller"], json!([2, 3]));
    assert!(v["types"]["muscle"].get("signal").is_none());
    let back = Scene::from_json_str(&s.to_json_string()).unwrap();
    assert!(back == s);
    assert_eq!(
        back.simulate(300).unwrap().as_flat(),
        s.simulate(300).unwrap().as_flat()
    );
}

fn scene_error(v: &Value) -> String {
    match Scene::from_json_value(v) {
        Err(e @ CordisError::Scene { .. }) => e.to_string(),
        other => panic!("expected a scene error, got {other:?}"),
    }
}

#[test]
fn bad_couplings_against_worlds_are_refused_with_their_place() {
    let base = central_muscle().to_json_value();
    let edit = |f: &dyn Fn(&mut Value)| {
        let mut v = base.clone();
        f(&mut v);
        v
    };
    let quad = |v: &mut Value| {
        v["types"]["q"] = json!({"kind": "quadripole", "stiffness": 1.0});
        v["couplings"]
            .as_array_mut()
            .unwrap()
            .push(json!({"type": "q", "particles": [0, 2, 1, 3]}));
    };
    let cases: [(Value, &str); 9] = [
        (
            edit(&|v| v["couplings"][0]["particles"] = json!([0, 3])),
            "couplings[0].particles[1]: particle 3 is in world `mind` but particle 0 in `main`: \
             a TGR's link stays inside one world",
        ),
        (
            edit(&|v| v["couplings"][0]["controller"] = json!([2, 1])),
            "couplings[0].controller[1]: particle 1 is in the muscle's own world `main`: a \
             controller lives in another world",
        ),
        (
            edit(&|v| v["couplings"][0]["controller"] = json!([0, 3])),
            "couplings[0].controller[0]: particle 0 is in the muscle's own world `main`",
        ),
        (
            edit(&|v| {
                v["worlds"]["other"] = json!({"dt": 0.01});
                v["particles"][3]["world"] = json!("other");
            }),
            // The controller dipole straddles two worlds (couplings[0], checked first).
            "couplings[0].controller[1]: particle 3 is in world `other` but particle 2 in \
             `mind`: a controller dipole stays inside one world",
        ),
        (
            edit(&|v| v["couplings"][0]["controller"] = json!([2, 9])),
            "couplings[0].controller[1]: particle 9 does not exist",
        ),
        (
            edit(&|v| v["couplings"][0]["controller"] = json!([3, 3])),
            "couplings[0].controller[1]: particle 3 twice",
        ),
        (
            edit(&|v| v["couplings"][0]["controller"] = json!([2, 3, 1])),
            "couplings[0].controller: expected two particle indices [c, d], got 3",
        ),
        (
            edit(&|v| {
                v["couplings"][0]
                    .as_object_mut()
                    .unwrap()
                    .remove("controller");
            }),
            "types.muscle: a `tgr` type needs `signal` (the name of its command signal) unless \
             every coupling of it has a `controller` (couplings[0] has none)",
        ),
        (
            edit(&|v| {
                quad(v);
                v["couplings"][2]["controller"] = json!([2, 3]);
            }),
            "couplings[2].controller: only tgr couplings have it",
        ),
    ];
    for (v, want) in cases {
        let e = scene_error(&v);
        eprintln!("{e}");
        assert!(e.starts_with(want), "{e}\n  wanted: {want}");
        assert!(!e.contains('\n'), "one line: {e}");
    }
    // A quadripole's dipole across worlds, and a valid one between them.
    let e = scene_error(&edit(&quad));
    assert!(
        e.starts_with("couplings[2].particles[1]: particle 2 is in world `mind` but particle 0 in `main`: a coupling's dipole stays inside one world"),
        "{e}"
    );
    let ok = edit(&|v| {
        v["types"]["q"] = json!({"kind": "quadripole", "stiffness": 1.0});
        v["couplings"]
            .as_array_mut()
            .unwrap()
            .push(json!({"type": "q", "particles": [0, 1, 2, 3]}));
    });
    Scene::from_json_value(&ok).unwrap();
}
