//! The central-control muscle (thesis §5.4, `cordis example central-muscle`) identified from its
//! motion: the muscle's link and tendon (K, l0, m_t, K_t, Z_t), the controller's nerve (K, l0,
//! Z) and the medium's viscosities (z1, z2), with the muscle's tendon advanced along the
//! observed frames by the cost, from the positions of both worlds.
//!
//! `cargo test --release -p cordis-es --test central_muscle`

use cordis_core::examples::central_muscle;
use cordis_core::{Bounds, Param, Scene, Trajectory};
use cordis_es::cost::{CostKind, Objective};
use cordis_es::executor::{self, RunConfig, StopReason, StopRules};
use cordis_es::identify::{make_strategy, with_unknown_boxes, StrategyName, StrategyOptions};
use cordis_es::problem::Problem;

/// Frames observed: 4 s, one stroke of the mobile (two of the controller's clock).
const FRAMES: usize = 400;

fn observed() -> (Scene, Trajectory) {
    let truth = central_muscle();
    let traj = truth.simulate(FRAMES).unwrap();
    (truth, traj)
}

/// Every positive parameter unknown in a box 25× wide around the truth (placed by `seed`),
/// the muscle's tendon included, but for the medium's v_max (a threshold: the short cost is
/// flat between two observed speeds, see the tadpole's tests) and the nerve's tendon (the
/// controller's own transducer).
fn unknowns(truth: &Scene, seed: u64) -> Scene {
    let mut s = with_unknown_boxes(truth, 25.0, seed);
    let water = s.type_index("water").unwrap();
    let v_max = truth.types[water].value("v_max").unwrap();
    s.types[water] = s.types[water].clone().with("v_max", v_max);
    let muscle = s.type_index("muscle").unwrap();
    for (k, name) in ["tendon_mass", "tendon_stiffness", "tendon_damping"]
        .into_iter()
        .enumerate()
    {
        let v = truth.types[muscle].value(name).unwrap();
        // Off-centre, differently for each parameter and seed.
        let u = 0.2 + 0.6 * (((seed + 1) * (k as u64 + 3)) % 7) as f64 / 6.0;
        let (min, max) = (v / 25f64.powf(u), v * 25f64.powf(1.0 - u));
        s.types[muscle] = s.types[muscle].clone().with(
            name,
            Param::Unknown(Bounds {
                min,
                max,
                init: None,
            }),
        );
    }
    s
}

#[test]
fn its_own_motion_costs_exactly_zero() {
    let (truth, traj) = observed();
    let p = truth.param_values();
    for kind in [CostKind::Short, CostKind::Horizon(9), CostKind::Long] {
        let obj = Objective::new(&truth, &traj, kind).unwrap();
        assert_eq!(obj.report(&p).unwrap().total, 0.0, "{kind}");
    }
    // The tendon's stiffness matters through the muscle and through the controller's reaction.
    let obj = Objective::new(&truth, &traj, CostKind::Short).unwrap();
    let kt = truth
        .param_layout()
        .param(&truth, 1, "tendon_stiffness")
        .unwrap();
    let mut q = p.clone();
    q[kt] *= 1.01;
    let r = obj.report(&q).unwrap();
    assert!(r.per_particle[0] > 0.0 && r.per_particle[3] > 0.0, "{r:?}");
}

#[test]
fn levenberg_marquardt_identifies_the_central_muscle_from_its_motion() {
    let (truth, traj) = observed();
    let want = truth.param_values();
    for seed in [0, 3, 7] {
        let scene = unknowns(&truth, seed);
        let mut problem = Problem::new(&scene, &traj, CostKind::Short).unwrap();
        let names: Vec<&str> = problem
            .space
            .unknowns
            .iter()
            .map(|u| u.name.as_str())
            .collect();
        assert_eq!(
            names,
            [
                "types.water.z1",
                "types.water.z2",
                "types.muscle.stiffness",
                "types.muscle.rest_length",
                "types.muscle.tendon_mass",
                "types.muscle.tendon_stiffness",
                "types.muscle.tendon_damping",
                "types.nerve.stiffness",
                "types.nerve.rest_length",
                "types.nerve.damping",
            ]
        );
        let (mut strategy, ran) =
            make_strategy(StrategyName::Auto, &problem, &StrategyOptions::default());
        // Several worlds: the exact solvers refuse; the short cost is smooth in every unknown.
        assert_eq!(ran, "levenberg-marquardt");
        let config = RunConfig {
            seed,
            stop: StopRules {
                generations: Some(2000),
                ..StopRules::default()
            },
            ..RunConfig::default()
        };
        let r = executor::run(&mut problem, strategy.as_mut(), &config, &mut [], None).unwrap();
        assert_eq!(r.stopped_by, StopReason::Converged, "seed {seed}");
        let mut worst = 0.0_f64;
        for u in &problem.space.unknowns {
            let rel = (r.params[u.slot] - want[u.slot]).abs() / want[u.slot];
            worst = worst.max(rel);
            assert!(
                rel < 1e-6,
                "seed {seed}: {} = {}, truth {}",
                u.name,
                r.params[u.slot],
                want[u.slot]
            );
        }
        eprintln!(
            "seed {seed}: {} evaluations, cost {:.2e}, worst relative error {worst:.1e}",
            r.evals, r.cost
        );
    }
}
