//! Costs of scenes with a TGR (hidden tendon state, SPEC §2.5 / §3): every cost kind advances
//! the tendon along the observed frames, so the true parameters predict the simulated motion
//! exactly; `least-squares` refuses an unknown TGR stiffness and names `hybrid`, which takes it.

use cordis_core::{Bounds, Param, Scene};
use cordis_es::cost::{CostKind, Objective};
use cordis_es::identify::check_strategy;
use cordis_es::problem::Problem;

mod common;

/// Two free particles in a drag, driven by a TGR with a damped, sprung tendon.
fn scene() -> Scene {
    common::driven_tgr_pair()
}

const KINDS: [&str; 4] = ["short", "horizon:7", "long", "progressive:3"];

#[test]
fn every_cost_kind_is_zero_at_the_truth_and_grows_off_it() {
    let s = scene();
    // Start at rest: frame 0's observed velocity is taken as zero (see cost::hidden).
    let traj = s.simulate(150).unwrap();
    let truth = s.param_values();
    let k = s.param_layout().param(&s, 1, "stiffness").unwrap();
    let mt = s.param_layout().param(&s, 1, "tendon_mass").unwrap();
    for kind in KINDS {
        let cost = Objective::new(&s, &traj, kind.parse().unwrap()).unwrap();
        let at_truth = cost.report(&truth).unwrap().total;
        assert!(at_truth < 1e-24, "{kind}: {at_truth}");
        for (slot, factor) in [(k, 1.01), (mt, 1.1)] {
            let mut p = truth.clone();
            p[slot] *= factor;
            let off = cost.report(&p).unwrap().total;
            assert!(
                off > 1e6 * at_truth.max(1e-30),
                "{kind}: {off} at slot {slot}"
            );
        }
    }
}

#[test]
fn the_cost_follows_the_signal_driven_tendon() {
    // The driven state matters: the same scene with its signal silenced is another model, and
    // its cost on the driven motion is far from 0 (so the cost does use the signal's state).
    let s = scene();
    let traj = s.simulate(150).unwrap();
    let mut silent = s.clone();
    silent.signals[0].amplitude = 0.0;
    for kind in KINDS {
        let cost = Objective::new(&silent, &traj, kind.parse().unwrap()).unwrap();
        let c = cost.report(&silent.param_values()).unwrap().total;
        assert!(c > 1e-10, "{kind}: {c}");
    }
}

#[test]
fn least_squares_refuses_an_unknown_tgr_stiffness_and_hybrid_takes_it() {
    let mut s = scene();
    s.types[1].params[0] = Param::Unknown(Bounds {
        min: 1.0,
        max: 100.0,
        init: None,
    });
    let traj = scene().simulate(50).unwrap();
    let problem = Problem::new(&s, &traj, CostKind::Short).unwrap();
    let objective = &problem.objective;
    assert!(objective.linear().is_none(), "no linear precomputation");
    let e = check_strategy("least-squares", &problem).unwrap_err();
    assert!(
        e.contains("types.t.stiffness") && e.contains("hybrid"),
        "{e}"
    );
    check_strategy("hybrid", &problem).unwrap();
}
