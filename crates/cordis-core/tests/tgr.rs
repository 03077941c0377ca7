//! The `tgr` coupling (SPEC §2.5, thesis §5.4.1): JSON schema (signals, couplings), validation
//! with places, the tendon's equation redone by hand, and the stateful-pass machinery of the
//! simulator (state outside the plan, undone with a diverged step).

use cordis_core::{CordisError, LinkKind, LinkType, Particle, Scene, Shape, Signal, Simulator};
use serde_json::{json, Value};

fn base() -> Value {
    json!({
        "format": "cordis-scene/1",
        "dt": 0.01,
        "particles": [
            {"mass": 1.0, "pos": [0, 0, 0]},
            {"mass": 2.0, "pos": [1.2, 0, 0]}
        ],
        "signals": {
            "stroke": {"shape": "sawtooth", "amplitude": 3.0, "period": 0.5, "rise": 0.8,
                       "phase": 0.25, "offset": 0.5},
            "calm": {"shape": "sine", "amplitude": 1.0, "period": 2.0}
        },
        "types": {
            "drive": {"kind": "tgr", "stiffness": 20.0, "rest_length": 1.0, "damping": 0.3,
                      "tendon_mass": {"min": 0.01, "max": 1.0, "init": 0.1},
                      "tendon_stiffness": 5.0, "tendon_damping": 0.2, "signal": "stroke"},
            "water": {"kind": "drag", "damping": 0.5}
        },
        "links": [
            {"type": "water", "particles": [0]},
            {"type": "water", "particles": [1]}
        ],
        "couplings": [
            {"type": "drive", "particles": [0, 1]}
        ]
    })
}

fn read(v: &Value) -> Result<Scene, CordisError> {
    Scene::from_json_str(&v.to_string())
}

fn edit(f: impl FnOnce(&mut Value)) -> Value {
    let mut v = base();
    f(&mut v);
    v
}

fn scene_error(v: &Value, place: &str, says: &str) {
    match read(v) {
        Err(CordisError::Scene { place: p, message }) => {
            assert_eq!(p, place, "{message}");
            assert!(message.contains(says), "`{message}` does not say `{says}`");
        }
        other => panic!("expected a scene error at {place}, got {other:?}"),
    }
}

#[test]
fn json_reads_signals_couplings_and_round_trips() {
    let s = read(&base()).unwrap();
    assert_eq!(s.signals.len(), 2);
    let stroke = &s.signals[0];
    assert_eq!(
        (stroke.shape, stroke.rise, stroke.phase, stroke.offset),
        (Shape::Sawtooth, 0.8, 0.25, 0.5)
    );
    assert_eq!(s.couplings.len(), 1);
    let t = &s.types[s.couplings[0].type_index];
    assert_eq!(
        (t.kind, t.signal.as_deref()),
        (LinkKind::Tgr, Some("stroke"))
    );
    let again = Scene::from_json_str(&s.to_json_string()).unwrap();
    assert_eq!(again, s);
    // Defaults: a sawtooth without rise has 0.9; tgr's damping and tendon terms default to 0.
    let v = edit(|v| {
        v["signals"]["stroke"] = json!({"shape": "sawtooth", "amplitude": 1, "period": 1});
        v["types"]["drive"] = json!({"kind": "tgr", "stiffness": 1, "rest_length": 1,
                                     "tendon_mass": 1, "signal": "stroke"});
    });
    let s = read(&v).unwrap();
    assert_eq!(s.signals[0].rise, 0.9);
    let t = &s.types[0];
    for name in ["damping", "tendon_stiffness", "tendon_damping"] {
        assert_eq!(t.value(name), Some(0.0), "{name}");
    }
}

#[test]
fn validation_names_the_place() {
    scene_error(
        &edit(|v| v["couplings"][0]["particles"] = json!([0, 7])),
        "couplings[0].particles[1]",
        "particle 7 does not exist",
    );
    scene_error(
        &edit(|v| v["couplings"][0]["particles"] = json!([1, 1])),
        "couplings[0].particles[1]",
        "linked to itself",
    );
    scene_error(
        &edit(|v| v["couplings"][0]["particles"] = json!([1])),
        "couplings[0].particles",
        "join 2 particle(s), got 1",
    );
    scene_error(
        &edit(|v| v["couplings"][0]["type"] = json!("water")),
        "couplings[0].type",
        "list it in `links`",
    );
    scene_error(
        &edit(|v| v["couplings"][0]["type"] = json!("nope")),
        "couplings[0].type",
        "no type named `nope`",
    );
    scene_error(
        &edit(|v| v["links"][0] = json!({"type": "drive", "particles": [0, 1]})),
        "links[0].type",
        "list it in `couplings`",
    );
    scene_error(
        &edit(|v| v["types"]["drive"]["signal"] = json!("gone")),
        "types.drive.signal",
        "no signal named `gone`",
    );
    scene_error(
        &edit(|v| {
            v["types"]["drive"]
                .as_object_mut()
                .unwrap()
                .remove("signal");
        }),
        "types.drive",
        "needs `signal`",
    );
    scene_error(
        &edit(|v| v["types"]["water"]["signal"] = json!("stroke")),
        "types.water.signal",
        "unknown key",
    );
    scene_error(
        &edit(|v| v["types"]["drive"]["tendon_mass"] = json!(0.0)),
        "types.drive.tendon_mass",
        "positive",
    );
    scene_error(
        &edit(|v| v["signals"]["stroke"]["rise"] = json!(1.0)),
        "signals.stroke.rise",
        "(0, 1)",
    );
    scene_error(
        &edit(|v| v["signals"]["calm"]["rise"] = json!(0.3)),
        "signals.calm.rise",
        "unknown key",
    );
    scene_error(
        &edit(|v| v["signals"]["calm"]["period"] = json!(0)),
        "signals.calm.period",
        "positive",
    );
    scene_error(
        &edit(|v| v["signals"]["calm"]["shape"] = json!("square")),
        "signals.calm.shape",
        "unknown shape `square`",
    );
    scene_error(
        &edit(|v| {
            v["signals"]["calm"]
                .as_object_mut()
                .unwrap()
                .remove("period");
        }),
        "signals.calm",
        "needs `period`",
    );
    scene_error(
        &edit(|v| v["couplings"][0]["point"] = json!([0, 0, 0])),
        "couplings[0].point",
        "unknown key",
    );
}

/// One TGR between a fixed and a free particle, 1-D along x.
fn pair(tendon_mass: f64, amplitude: f64) -> Scene {
    let mut s = Scene::new(0.01);
    s.add_particle(Particle::new(1.0, [0.0; 3]).fixed());
    s.add_particle(Particle::new(0.7, [1.3, 0.0, 0.0]));
    s.add_signal(Signal::new("cmd", Shape::Sawtooth, amplitude, 0.37).with_rise(0.7));
    s.add_type(
        LinkType::new("t", LinkKind::Tgr)
            .with("stiffness", 20.0)
            .with("rest_length", 1.0)
            .with("damping", 0.4)
            .with("tendon_mass", tendon_mass)
            .with("tendon_stiffness", 3.0)
            .with("tendon_damping", 0.2)
            .with_signal("cmd"),
    );
    s.add_coupling("t", &[0, 1]);
    s
}

#[test]
fn tendon_and_link_follow_the_equations_by_hand() {
    let s = pair(0.05, 2.0);
    let (dt, mt, k, l0, z, kt, zt) = (0.01, 0.05, 20.0, 1.0, 0.4, 3.0, 0.2);
    let signal = s.signals[0].clone();
    let mut sim = Simulator::new(&s).unwrap();
    // By hand: particle 1's x and the tendon, SPEC §2.1 + the TGR equations.
    let (mut x, mut xp) = (1.3f64, 1.3f64);
    let (mut y, mut yp) = (0.0f64, 0.0f64);
    for n in 0..300 {
        let v = (x - xp) / dt;
        let tension = k * (x - (l0 + y)) + z * v;
        // Force on particle 1 (the link's second end): -tension along +x.
        let xn = 2.0 * x - xp + dt * dt * (-tension / 0.7);
        let force = signal.value(n as f64 * dt) + tension - kt * y - zt * (y - yp) / dt;
        let yn = 2.0 * y - yp + dt * dt / mt * force;
        (xp, x, yp, y) = (x, xn, y, yn);
        sim.step().unwrap();
        let got = sim.positions()[1].x;
        assert!(
            (got - x).abs() <= 1e-12 * x.abs(),
            "frame {n}: {got} vs {x}"
        );
        let st = sim.state();
        assert!((st[0] - y).abs() <= 1e-12 + 1e-9 * y.abs(), "y at {n}");
        assert!(
            (st[1] - yp).abs() <= 1e-12 + 1e-9 * yp.abs(),
            "y_prev at {n}"
        );
    }
    assert!(y.abs() > 0.01, "the tendon moved: {y}");
}

#[test]
fn a_frozen_tendon_is_a_spring_bit_for_bit() {
    // A tendon too heavy to move (y stays below an ulp of l0) and no command: a damped spring.
    let tgr = pair(1e300, 0.0);
    let mut spring = Scene::new(0.01);
    spring.particles = tgr.particles.clone();
    spring.add_type(
        LinkType::new("s", LinkKind::Spring)
            .with("stiffness", 20.0)
            .with("rest_length", 1.0)
            .with("damping", 0.4),
    );
    spring.add_link("s", &[0, 1]);
    let (a, b) = (tgr.simulate(400).unwrap(), spring.simulate(400).unwrap());
    assert_eq!(a.as_flat(), b.as_flat());
}

#[test]
fn a_faster_signal_changes_the_motion_and_state_is_per_simulator() {
    let s = pair(0.05, 2.0);
    let mut fast = s.clone();
    fast.signals[0].period = 0.2;
    let (a, b) = (s.simulate(200).unwrap(), fast.simulate(200).unwrap());
    assert_ne!(a.as_flat(), b.as_flat());
    // Two simulators of one plan do not share tendon state: interleaving changes nothing.
    let mut one = Simulator::new(&s).unwrap();
    let mut two = Simulator::new(&s).unwrap();
    for _ in 0..50 {
        one.step().unwrap();
        one.step().unwrap();
        two.step().unwrap();
    }
    for _ in 0..50 {
        two.step().unwrap();
    }
    assert_eq!(one.positions(), two.positions());
    assert_eq!(one.state(), two.state());
}

#[test]
fn a_diverged_step_restores_the_tendon() {
    // A tendon far too light for its stiffness explodes; the failed step leaves the state as
    // it was before it.
    let s = pair(1e-9, 2.0);
    let mut sim = Simulator::new(&s).unwrap();
    let mut last = (sim.positions().to_vec(), sim.state().to_vec(), sim.frame());
    loop {
        match sim.step() {
            Ok(()) => last = (sim.positions().to_vec(), sim.state().to_vec(), sim.frame()),
            Err(CordisError::Diverged { .. }) => break,
            Err(e) => panic!("{e}"),
        }
        assert!(sim.frame() < 100_000, "never diverged");
    }
    assert_eq!(
        (sim.positions().to_vec(), sim.state().to_vec(), sim.frame()),
        last
    );
}
