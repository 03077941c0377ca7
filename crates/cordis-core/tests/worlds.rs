//! Worlds (SPEC §2.5): particles of an extra world step with that world's own `dt`, one step per
//! main frame; gravity acts on the main world only; plain links stay inside one world.
//!
//! `cargo test --release -p cordis-core --test worlds`

use cordis_core::{stability, CordisError, LinkKind, LinkType, Particle, Plan, Scene};
use serde_json::{json, Value};

const MAIN_DT: f64 = 0.01;
const CTRL_DT: f64 = 0.0023;

/// Two damped oscillators hanging from fixed particles, with initial velocities (so x(-1)
/// depends on dt) and an angle (three particles in one world).
fn oscillator(scene: &mut Scene, world: &str, x: f64) {
    let w = |p: Particle| p.in_world(world);
    let a = scene.add_particle(w(Particle::new(1.0, [x, 0.0, 0.0]).fixed()));
    let b = scene.add_particle(w(
        Particle::new(0.7, [x + 1.3, 0.0, 0.0]).with_vel([0.1, 0.4, 0.0])
    ));
    let c = scene.add_particle(w(
        Particle::new(1.2, [x + 1.3, 1.1, 0.2]).with_vel([0.0, -0.3, 0.2])
    ));
    scene.add_link("rib", &[a, b]);
    scene.add_link("rib", &[b, c]);
    scene.add_link("bend", &[a, b, c]);
}

fn catalogue(scene: &mut Scene) {
    scene.add_type(
        LinkType::new("rib", LinkKind::Spring)
            .with("stiffness", 30.0)
            .with("rest_length", 1.0)
            .with("damping", 0.2),
    );
    scene.add_type(
        LinkType::new("bend", LinkKind::Angle)
            .with("stiffness", 0.5)
            .with("rest_cos", 0.0),
    );
}

/// One world: an oscillator in the main world at `dt`, with `gravity`.
fn single(dt: f64, gravity: [f64; 3]) -> Scene {
    let mut s = Scene::new(dt);
    s.gravity = gravity;
    catalogue(&mut s);
    oscillator(&mut s, "main", 0.0);
    s
}

/// Both oscillators: the first in the main world (with gravity), the second in `ctrl`.
fn two_worlds() -> Scene {
    let mut s = Scene::new(MAIN_DT);
    s.gravity = [0.0, 0.0, -9.81];
    s.add_world("ctrl", CTRL_DT);
    catalogue(&mut s);
    oscillator(&mut s, "main", 0.0);
    oscillator(&mut s, "ctrl", 0.0);
    s
}

#[test]
fn each_world_steps_with_its_own_dt_and_gravity_only_in_main() {
    let frames = 400;
    let both = two_worlds().simulate(frames).unwrap();
    let main = single(MAIN_DT, [0.0, 0.0, -9.81]).simulate(frames).unwrap();
    // The ctrl world alone is a gravity-free scene at its own dt.
    let ctrl = single(CTRL_DT, [0.0; 3]).simulate(frames).unwrap();
    assert_eq!(both.dt, Some(MAIN_DT), "frames are main steps");
    for t in 0..frames {
        for i in 0..3 {
            // Bit for bit: the same arithmetic with the world's dt.
            assert_eq!(
                both.pos(t, i),
                main.pos(t, i),
                "main, frame {t}, particle {i}"
            );
            assert_eq!(
                both.pos(t, 3 + i),
                ctrl.pos(t, i),
                "ctrl, frame {t}, particle {i}"
            );
        }
    }
    // And the worlds did differ: with the main dt and gravity the ctrl oscillator would not move
    // the same way.
    let wrong = single(MAIN_DT, [0.0; 3]).simulate(frames).unwrap();
    assert_ne!(wrong.pos(frames - 1, 1), ctrl.pos(frames - 1, 1));
}

#[test]
fn one_world_scenes_keep_the_uniform_plan() {
    let mut s = single(MAIN_DT, [0.0; 3]);
    // A declared world without particles changes nothing.
    s.add_world("ctrl", CTRL_DT);
    assert!(Plan::compile(&s).unwrap().worlds.is_none());
    assert_eq!(
        s.simulate(50).unwrap().as_flat(),
        single(MAIN_DT, [0.0; 3]).simulate(50).unwrap().as_flat()
    );
    let plan = Plan::compile(&two_worlds()).unwrap();
    let w = plan.worlds.as_ref().unwrap();
    assert_eq!(w.dts, vec![MAIN_DT, CTRL_DT]);
    assert_eq!(plan.dt_of(0), MAIN_DT);
    assert_eq!(plan.dt_of(4), CTRL_DT);
}

#[test]
fn stability_uses_each_particles_world_dt() {
    let both = stability(&two_worlds()).unwrap();
    let main = stability(&single(MAIN_DT, [0.0; 3])).unwrap();
    let ctrl = stability(&single(CTRL_DT, [0.0; 3])).unwrap();
    for i in 0..3 {
        assert_eq!(both.per_particle[i], main.per_particle[i]);
        assert_eq!(both.per_particle[3 + i], ctrl.per_particle[i]);
    }
    // dt 0.0023 vs 0.01: the ctrl ratios are several times smaller.
    assert!(both.per_particle[4].unwrap() < 0.5 * both.per_particle[1].unwrap());
}

#[test]
fn json_round_trip_keeps_worlds() {
    let s = two_worlds();
    let text = s.to_json_string();
    let v: Value = serde_json::from_str(&text).unwrap();
    assert_eq!(v["worlds"], json!({"ctrl": {"dt": CTRL_DT}}));
    assert_eq!(v["particles"][4]["world"], json!("ctrl"));
    assert!(
        v["particles"][1].get("world").is_none(),
        "main is the default"
    );
    let back = Scene::from_json_str(&text).unwrap();
    assert_eq!(back, s);
    assert_eq!(
        back.simulate(30).unwrap().as_flat(),
        s.simulate(30).unwrap().as_flat()
    );
}

#[test]
fn explicit_main_world_is_the_default() {
    let mut v = two_worlds().to_json_value();
    v["particles"][1]["world"] = json!("main");
    let s = Scene::from_json_value(&v).unwrap();
    assert_eq!(s, two_worlds());
}

fn scene_error(v: &Value) -> (String, String) {
    match Scene::from_json_value(v) {
        Err(CordisError::Scene { place, message }) => (place, message),
        other => panic!("expected a scene error, got {other:?}"),
    }
}

#[test]
fn a_link_across_worlds_is_an_error_naming_the_link() {
    let mut v = two_worlds().to_json_value();
    v["links"][4]["particles"] = json!([1, 4]);
    let (place, message) = scene_error(&v);
    assert_eq!(place, "links[4].particles[1]");
    assert!(
        message.contains("`ctrl`") && message.contains("`main`"),
        "{message}"
    );
    assert!(message.contains("coupling"), "{message}");
    // Three-particle links too.
    let mut v = two_worlds().to_json_value();
    v["links"][2]["particles"] = json!([0, 1, 5]);
    assert_eq!(scene_error(&v).0, "links[2].particles[2]");
}

#[test]
fn a_conditional_across_worlds_is_an_error() {
    let mut v = two_worlds().to_json_value();
    v["types"]["near"] = json!({"kind": "conditional", "stiffness": 1.0, "rest_length": 0.5,
                               "range": 0.6, "groups": ["gas"]});
    v["particles"][1]["group"] = json!("gas");
    v["particles"][2]["group"] = json!("gas");
    Scene::from_json_value(&v).unwrap();
    v["particles"][4]["group"] = json!("gas");
    let (place, message) = scene_error(&v);
    assert_eq!(place, "types.near.groups");
    assert!(message.contains("particle 4"), "{message}");
}

#[test]
fn world_declarations_are_validated() {
    let cases = [
        ("/worlds", json!([1]), "worlds", "expected an object"),
        (
            "/worlds",
            json!({"ctrl": {"dt": 0}}),
            "worlds.ctrl.dt",
            "positive",
        ),
        (
            "/worlds",
            json!({"ctrl": {"dt": -1.0}}),
            "worlds.ctrl.dt",
            "positive",
        ),
        (
            "/worlds",
            json!({"ctrl": {}}),
            "worlds.ctrl",
            "missing `dt`",
        ),
        (
            "/worlds",
            json!({"ctrl": {"dt": "x"}}),
            "worlds.ctrl.dt",
            "expected a number",
        ),
        (
            "/worlds",
            json!({"ctrl": {"dt": 0.1, "g": 1}}),
            "worlds.ctrl.g",
            "unknown key",
        ),
        (
            "/worlds",
            json!({"ctrl": {"dt": 0.1}, "main": {"dt": 0.1}}),
            "worlds.main",
            "scene `dt`",
        ),
        (
            "/particles/3/world",
            json!("brain"),
            "particles[3].world",
            "no world named `brain`",
        ),
        (
            "/particles/3/world",
            json!(3),
            "particles[3].world",
            "expected a string",
        ),
    ];
    for (pointer, value, place, what) in cases {
        let mut v = two_worlds().to_json_value();
        *v.pointer_mut(pointer).unwrap() = value;
        let (p, m) = scene_error(&v);
        assert_eq!(p, place, "{pointer}: {m}");
        assert!(m.contains(what), "{pointer}: {m}");
    }
}
