//! Couplings between worlds (SPEC §2.5, thesis §5.4.2-5.4.3): quadripole, position transmitter,
//! force transmitter.
//!
//! `cargo test --release -p cordis-core --test couplings`

use cordis_core::{CordisError, LinkKind, LinkType, Particle, Scene, Trajectory, Vec3};
use serde_json::json;

const MAIN_DT: f64 = 0.01;
const CTRL_DT: f64 = 0.004;

fn spring(name: &str, k: f64, l0: f64) -> LinkType {
    LinkType::new(name, LinkKind::Spring)
        .with("stiffness", k)
        .with("rest_length", l0)
}

/// Dipole 1 = (0, 1) in the main world, dipole 2 = (2, 3) in `ctrl`; each an undamped spring
/// oscillator on a fixed end.
fn two_oscillators() -> Scene {
    let mut s = Scene::new(MAIN_DT);
    s.add_world("ctrl", CTRL_DT);
    s.add_type(spring("body", 20.0, 1.0));
    s.add_type(spring("mind", 10.0, 1.0));
    s.add_particle(Particle::new(1.0, [0.0, 0.0, 0.0]).fixed());
    s.add_particle(Particle::new(1.0, [1.3, 0.0, 0.0]));
    s.add_particle(Particle::new(1.0, [0.0, 5.0, 0.0]).fixed().in_world("ctrl"));
    s.add_particle(Particle::new(0.5, [0.0, 5.9, 0.0]).in_world("ctrl"));
    s.add_link("body", &[0, 1]);
    s.add_link("mind", &[2, 3]);
    s
}

fn pos(traj: &Trajectory, t: usize, i: usize) -> Vec3 {
    traj.pos(t, i)
}

fn length(traj: &Trajectory, t: usize, i: usize, j: usize) -> f64 {
    (pos(traj, t, j) - pos(traj, t, i)).norm()
}

/// Kinetic energy of particle i at frame t (central velocity in its world's time), J.
fn kinetic(s: &Scene, traj: &Trajectory, t: usize, i: usize) -> f64 {
    let dt = s.particle_dt(i);
    let v = (pos(traj, t + 1, i) - pos(traj, t - 1, i)) / (2.0 * dt);
    0.5 * s.particles[i].mass.value() * v.norm_squared()
}

#[test]
fn an_undamped_quadripole_conserves_the_energy_of_both_worlds() {
    let mut s = two_oscillators();
    let kq = 15.0;
    s.add_type(LinkType::new("q", LinkKind::Quadripole).with("stiffness", kq));
    s.add_coupling("q", &[0, 1, 2, 3]);
    let frames = 200_000;
    let traj = s.simulate(frames).unwrap();
    let world = |t: usize, w: usize| {
        let (i, j, k) = if w == 0 { (0, 1, 20.0) } else { (2, 3, 10.0) };
        kinetic(&s, &traj, t, j) + 0.5 * k * (length(&traj, t, i, j) - 1.0).powi(2)
    };
    let coupling = |t: usize| 0.5 * kq * (length(&traj, t, 0, 1) - length(&traj, t, 2, 3)).powi(2);
    let energy: Vec<f64> = (1..frames - 1)
        .map(|t| world(t, 0) + world(t, 1) + coupling(t))
        .collect();
    let e0 = energy[0];
    let worst = energy.iter().map(|e| (e - e0).abs()).fold(0.0, f64::max);
    // Bounded oscillation of the scheme: (ω dt)² ≈ 0.35 % in the main world.
    assert!(worst < 1e-2 * e0, "energy wanders by {worst:e} of {e0}");
    // No drift: the mean over the last tenth equals the first tenth's.
    let tenth = energy.len() / 10;
    let mean = |e: &[f64]| e.iter().sum::<f64>() / e.len() as f64;
    let drift = mean(&energy[energy.len() - tenth..]) - mean(&energy[..tenth]);
    assert!(drift.abs() < 1e-4 * e0, "drift {drift:e} of {e0}");
    // And the worlds did exchange energy: each one's share moved by much more than that.
    let share: Vec<f64> = (1..frames - 1).step_by(7).map(|t| world(t, 1)).collect();
    let (lo, hi) = share
        .iter()
        .fold((f64::MAX, 0.0_f64), |(a, b), &e| (a.min(e), b.max(e)));
    assert!(
        hi - lo > 0.1 * e0,
        "ctrl world energy only in [{lo}, {hi}] of {e0}"
    );
}

#[test]
fn a_force_transmitter_injects_energy_into_the_receiving_world() {
    let mut s = Scene::new(MAIN_DT);
    s.add_world("ctrl", CTRL_DT);
    // Source: a compressed spring held between fixed particles of the ctrl world, tension
    // 5 (0.5 - 1) = -2.5 N (pushes apart).
    s.add_type(spring("source", 5.0, 1.0));
    s.add_type(LinkType::new("tx", LinkKind::ForceTransmitter).with("gain", 2.0));
    s.add_particle(Particle::new(1.0, [0.0, 5.0, 0.0]).fixed().in_world("ctrl"));
    s.add_particle(Particle::new(1.0, [0.5, 5.0, 0.0]).fixed().in_world("ctrl"));
    s.add_particle(Particle::new(1.0, [0.0, 0.0, 0.0]));
    s.add_particle(Particle::new(3.0, [1.0, 0.0, 0.0]));
    let src = s.add_link("source", &[0, 1]);
    s.add_force_transmitter("tx", [2, 3], src);
    let frames = 2001;
    let traj = s.simulate(frames + 1).unwrap();
    let energy = |t: usize| kinetic(&s, &traj, t, 2) + kinetic(&s, &traj, t, 3);
    let mut last = 0.0;
    for t in (100..=frames).step_by(100) {
        let e = energy(t);
        assert!(e > last, "frame {t}: energy {e} after {last}");
        last = e;
    }
    // A constant 5 N pushing the pair apart: E(t) = (5 t)² / 2 (1/m_a + 1/m_b).
    // The scheme's central velocity at frame n is that of t = (n + ½) dt (x(1) - x(0) = a dt²).
    let t = (frames as f64 - 0.5) * MAIN_DT;
    let want = 0.5 * (5.0 * t).powi(2) * (1.0 + 1.0 / 3.0);
    assert!(
        (energy(frames - 1) - want).abs() < 1e-6 * want,
        "{} vs {want}",
        energy(frames - 1)
    );
}

#[test]
fn a_position_transmitter_makes_dipole_2_follow_dipole_1() {
    let base = two_oscillators();
    let mut s = base.clone();
    // Dipole 2 gets no spring of its own: only the transmitter drives it.
    s.types[1] = spring("mind", 0.0, 1.0);
    s.add_type(
        LinkType::new("sense", LinkKind::PositionTransmitter)
            .with("stiffness", 5000.0)
            .with("damping", 5000.0),
    );
    s.add_coupling("sense", &[0, 1, 2, 3]);
    let frames = 3000;
    let traj = s.simulate(frames).unwrap();
    let alone = base.simulate(frames).unwrap();
    // Dipole 1 is read, not pushed: its motion is the one without the transmitter, bit for bit.
    for t in 0..frames {
        assert_eq!(pos(&traj, t, 1), pos(&alone, t, 1), "frame {t}");
    }
    let l1: Vec<f64> = (0..frames).map(|t| length(&traj, t, 0, 1)).collect();
    let (lo, hi) = l1
        .iter()
        .fold((f64::MAX, 0.0_f64), |(a, b), &l| (a.min(l), b.max(l)));
    assert!(hi - lo > 0.5, "dipole 1 oscillates: [{lo}, {hi}]");
    let lag = (frames / 2..frames)
        .map(|t| (length(&traj, t, 2, 3) - l1[t]).abs())
        .fold(0.0, f64::max);
    assert!(
        lag < 0.05 * (hi - lo),
        "dipole 2 is {lag} m off dipole 1's length"
    );
    // At first it was 0.4 m off (0.9 vs 1.3).
    assert!((length(&traj, 0, 2, 3) - l1[0]).abs() > 0.3);
}

#[test]
fn couplings_round_trip_and_are_validated() {
    let mut s = two_oscillators();
    s.add_type(
        LinkType::new("q", LinkKind::Quadripole)
            .with("stiffness", 3.0)
            .with("ratio", 2.0),
    );
    s.add_type(LinkType::new("tx", LinkKind::ForceTransmitter));
    s.add_coupling("q", &[0, 1, 2, 3]);
    s.add_force_transmitter("tx", [2, 3], 0);
    let text = s.to_json_string();
    let back = Scene::from_json_str(&text).unwrap();
    assert_eq!(back, s);
    assert_eq!(back.to_json_value()["couplings"][1]["source"], json!(0));
    assert_eq!(back.types[3].value("gain"), Some(1.0), "gain defaults to 1");
    let error = |edit: &dyn Fn(&mut serde_json::Value)| {
        let mut v = s.to_json_value();
        edit(&mut v);
        match Scene::from_json_value(&v) {
            Err(CordisError::Scene { place, message }) => (place, message),
            other => panic!("expected a scene error, got {other:?}"),
        }
    };
    let (p, m) = error(&|v| v["couplings"][1]["source"] = json!(7));
    assert_eq!(p, "couplings[1].source");
    assert!(m.contains("does not exist"), "{m}");
    let (p, _) = error(&|v| {
        v["couplings"][1]
            .as_object_mut()
            .unwrap()
            .remove("source")
            .map(drop)
            .unwrap()
    });
    assert_eq!(p, "couplings[1]");
    let (p, _) = error(&|v| v["couplings"][0]["source"] = json!(0));
    assert_eq!(p, "couplings[0].source");
    let (p, _) = error(&|v| v["couplings"][1]["source"] = json!(-1));
    assert_eq!(p, "couplings[1].source");
    let (p, m) = error(&|v| v["couplings"][0]["particles"] = json!([0, 1, 2]));
    assert_eq!(p, "couplings[0].particles");
    assert!(m.contains('4'), "{m}");
    // A quadripole is not a plain link.
    let (p, _) = error(&|v| {
        v["links"]
            .as_array_mut()
            .unwrap()
            .push(json!({"type": "q", "particles": [0, 1, 2, 3]}))
    });
    assert_eq!(p, "links[2].type");
}

/// A force transmitter sends `K (L - l0) + Z s`: a source spring with a quadratic viscosity
/// would lose its `Z₂ s |s|` on the way, so the scene is refused, naming the coupling.
#[test]
fn a_force_transmitter_refuses_a_source_with_a_quadratic_viscosity() {
    let mut s = Scene::new(MAIN_DT);
    s.add_type(
        spring("source", 5.0, 1.0).with_optional(cordis_core::OptionalParam::DampingQuadratic, 0.3),
    );
    s.add_type(LinkType::new("tx", LinkKind::ForceTransmitter));
    for x in [0.0, 0.5, 2.0, 3.0] {
        s.add_particle(Particle::new(1.0, [x, 0.0, 0.0]));
    }
    let src = s.add_link("source", &[0, 1]);
    s.add_force_transmitter("tx", [2, 3], src);
    let e = s.validate().unwrap_err().to_string();
    assert!(
        e.starts_with("couplings[0].source: link 0's type `source` has a damping_quadratic"),
        "{e}"
    );
}
