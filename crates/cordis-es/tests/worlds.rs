//! Costs on scenes with several worlds (SPEC §2.5, §3): observed velocities and predictions use
//! each particle's world dt, and gravity acts on the main world only, so a trajectory simulated
//! with the scene's own parameters costs exactly 0 under every cost kind.
//!
//! `cargo test --release -p cordis-es --test worlds`

use cordis_core::{Bounds, LinkKind, LinkType, Param, Particle, Scene, Trajectory};
use cordis_es::cost::{CostKind, Objective};
use cordis_es::identify::{make_strategy, StrategyName, StrategyOptions};
use cordis_es::problem::Problem;

/// A damped chain in the main world (with gravity) and one in `ctrl`, whose dt is 0.3× the main.
fn scene(ctrl_world: &str) -> Scene {
    let mut s = Scene::new(0.01);
    s.gravity = [0.0, -9.81, 0.0];
    s.add_world("ctrl", 0.003);
    s.add_type(
        LinkType::new("rib", LinkKind::Spring)
            .with("stiffness", 40.0)
            .with("rest_length", 0.8)
            .with("damping", 0.3),
    );
    s.add_type(LinkType::new("air", LinkKind::Drag).with("damping", 0.05));
    for (w, y) in [("main", 0.0), (ctrl_world, 3.0)] {
        let a = s.add_particle(Particle::new(1.0, [0.0, y, 0.0]).fixed().in_world(w));
        let b = s.add_particle(
            Particle::new(0.5, [1.0, y, 0.0])
                .with_vel([0.0, 0.5, 0.2])
                .in_world(w),
        );
        let c = s.add_particle(Particle::new(0.8, [1.9, y + 0.3, 0.0]).in_world(w));
        s.add_link("rib", &[a, b]);
        s.add_link("rib", &[b, c]);
        s.add_link("air", &[c]);
    }
    s
}

fn data() -> (Scene, Trajectory) {
    let s = scene("ctrl");
    let traj = s.simulate(120).unwrap();
    (s, traj)
}

#[test]
fn own_trajectory_costs_zero_under_every_kind() {
    let (s, traj) = data();
    let p = s.param_values();
    for kind in [CostKind::Short, CostKind::Horizon(7), CostKind::Long] {
        let obj = Objective::new(&s, &traj, kind).unwrap();
        assert!(!obj.uses_linear(&p), "several worlds take the generic path");
        let r = obj.report(&p).unwrap();
        assert_eq!(r.total, 0.0, "{kind}: {r:?}");
        assert!(r.terms > 0);
    }
}

#[test]
fn a_cost_that_ignored_the_worlds_would_not_be_zero() {
    let (_, traj) = data();
    // The same network with every particle in the main world (main dt, gravity everywhere).
    let flat = scene("main");
    let mut obj = Objective::new(&flat, &traj, CostKind::Short).unwrap();
    // The generic path, as for the worlds scene (the linear one is exact only to rounding).
    obj.set_linear(false);
    let r = obj.report(&flat.param_values()).unwrap();
    // Only the ctrl chain (particles 4 and 5) is mispredicted.
    assert_eq!(r.per_particle[1], 0.0);
    assert_eq!(r.per_particle[2], 0.0);
    assert!(
        r.per_particle[4] > 1e-8 && r.per_particle[5] > 1e-8,
        "{r:?}"
    );
}

#[test]
fn the_cost_is_minimal_at_the_truth_in_the_ctrl_world() {
    let (s, traj) = data();
    let obj = Objective::new(&s, &traj, CostKind::Short).unwrap();
    let mut p = s.param_values();
    let truth = obj.report(&p).unwrap().total;
    // Damping of the drag acts on both worlds through their own velocities.
    let z = s.param_layout().param(&s, 1, "damping").unwrap();
    for dz in [-0.01, 0.01] {
        p[z] = 0.05 + dz;
        assert!(obj.report(&p).unwrap().total > truth);
    }
}

#[test]
fn auto_picks_levenberg_marquardt_not_the_exact_solvers() {
    let (mut s, traj) = data();
    s.types[0].params[0] = Param::Unknown(Bounds {
        min: 10.0,
        max: 100.0,
        init: None,
    });
    let problem = Problem::new(&s, &traj, CostKind::Short).unwrap();
    let (_, ran) = make_strategy(StrategyName::Auto, &problem, &StrategyOptions::default());
    // The exact solvers assume one world; the cost is smooth in the unknown stiffness.
    assert_eq!(ran, "levenberg-marquardt");
}

/// `scene` plus a damped quadripole and a position transmitter between the worlds' chains
/// (their Δ(n-1) is hidden state) and a force transmitter from a main spring into ctrl.
fn coupled() -> Scene {
    let mut s = scene("ctrl");
    s.add_type(
        LinkType::new("q", LinkKind::Quadripole)
            .with("stiffness", 5.0)
            .with("damping", 2.0)
            .with("ratio", 1.2),
    );
    s.add_type(
        LinkType::new("sense", LinkKind::PositionTransmitter)
            .with("stiffness", 3.0)
            .with("damping", 1.0),
    );
    s.add_type(LinkType::new("tx", LinkKind::ForceTransmitter).with("gain", 0.5));
    s.add_coupling("q", &[1, 2, 4, 5]);
    s.add_coupling("sense", &[0, 2, 3, 5]);
    s.add_force_transmitter("tx", [3, 4], 0);
    s
}

#[test]
fn couplings_with_hidden_state_cost_zero_on_their_own_motion() {
    let s = coupled();
    let traj = s.simulate(150).unwrap();
    let p = s.param_values();
    for kind in [CostKind::Short, CostKind::Horizon(9), CostKind::Long] {
        let obj = Objective::new(&s, &traj, kind).unwrap();
        assert_eq!(obj.report(&p).unwrap().total, 0.0, "{kind}");
    }
    // The quadripole's damping matters (it acts through Δ(n) - Δ(n-1)).
    let obj = Objective::new(&s, &traj, CostKind::Short).unwrap();
    let z = s.param_layout().param(&s, 2, "damping").unwrap();
    let mut q = p.clone();
    q[z] = 2.5;
    assert!(obj.report(&q).unwrap().total > 1e-12);
}
