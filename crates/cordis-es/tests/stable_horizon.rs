//! Stability-aware identification (issue 7 part 3) and long identification runs over wide
//! boxes (issue 7 part 4), on the horse driven by its leg muscles (`horse-gait`) and on
//! `rigid`.

use cordis_core::examples::{by_name, default_frames, horse_gait, passive, HORSE_FRAMES};
use cordis_core::{Bounds, Param, Scene, Trajectory};
use cordis_es::cost::CostKind;
use cordis_es::executor::{self, RunConfig, RunResult, StopRules};
use cordis_es::identify::{make_strategy, with_unknown_boxes, StrategyName, StrategyOptions};
use cordis_es::problem::Problem;
use cordis_es::stable::{Rejection, StableHorizon, DEFAULT_SPREAD};

/// 10× the observed length, as the thesis' free run of §4.4.
const HORIZON: usize = 10 * HORSE_FRAMES;

fn gait_data() -> (Scene, Trajectory) {
    let truth = horse_gait();
    let traj = truth.simulate(HORSE_FRAMES).unwrap();
    (truth, traj)
}

fn horizon() -> StableHorizon {
    StableHorizon::new(HORIZON, DEFAULT_SPREAD).unwrap()
}

#[test]
fn the_horizon_rejects_unstable_candidates_and_keeps_the_truth() {
    let (truth, traj) = gait_data();
    let scene = with_unknown_boxes(&passive(&truth), 10.0, 0);
    let plain = Problem::new(&scene, &traj, CostKind::Short).unwrap();
    let guarded = Problem::new(&scene, &traj, CostKind::Short)
        .unwrap()
        .with_stable_horizon(horizon());
    let mut s = guarded.scratch();
    let mut local = vec![0.0; guarded.num_particles];

    // The passive horse at the gait's spring values: stable, so the horizon changes nothing.
    let p = passive(&truth).param_values();
    assert_eq!(guarded.stability_check(&p, &mut s), None);
    let g = guarded.space.genome_of(&p);
    let c = guarded.evaluate(&g, &mut s, &mut local);
    let mut s0 = plain.scratch();
    assert_eq!(
        c.to_bits(),
        plain.evaluate(&g, &mut s0, &mut local).to_bits()
    );
    assert!(c.is_finite() && c > 0.0, "{c}");

    // One trunk spring 200× stiffer: beyond the bound (the truth's max ratio is 0.61).
    let t = scene.type_index("withers-midback").unwrap();
    let k = scene.param_layout().type_offsets[t];
    let mut stiff = p.clone();
    stiff[k] *= 200.0;
    match guarded.stability_check(&stiff, &mut s) {
        Some(Rejection::Bound(q)) => assert!(q > 1.0, "{q}"),
        other => panic!("{other:?}"),
    }

    // Every link and angle 10⁶× weaker (stiffness and damping): inside the bound, but the
    // horse comes apart (its parts keep their initial relative velocities, up to 1.2 m/s at
    // a hoof) long before 530 frames.
    let mut soft = p.clone();
    for (ti, ty) in scene.types.iter().enumerate() {
        for name in ["stiffness", "damping"] {
            if let Some(ki) = ty.kind.param_index(name) {
                soft[scene.param_layout().type_offsets[ti] + ki] *= 1e-6;
            }
        }
    }
    match guarded.stability_check(&soft, &mut s) {
        Some(Rejection::Diverged(frame)) => assert!((2..HORIZON).contains(&frame), "{frame}"),
        other => panic!("{other:?}"),
    }
}

#[test]
fn a_rejected_candidate_costs_inf_everywhere() {
    let (truth, traj) = gait_data();
    let mut scene = with_unknown_boxes(&passive(&truth), 10.0, 0);
    // A box for one trunk spring's stiffness that reaches 1000× the truth.
    let t = scene.type_index("withers-midback").unwrap();
    let k = truth.types[t].value("stiffness").unwrap();
    scene.types[t] = scene.types[t].clone().with(
        "stiffness",
        Param::Unknown(Bounds {
            min: 0.5 * k,
            max: 1000.0 * k,
            init: None,
        }),
    );
    let plain = Problem::new(&scene, &traj, CostKind::Short).unwrap();
    let guarded = Problem::new(&scene, &traj, CostKind::Short)
        .unwrap()
        .with_stable_horizon(horizon());
    let mut p = passive(&truth).param_values();
    p[scene.param_layout().type_offsets[t]] = 500.0 * k;
    let g = guarded.space.genome_of(&p);
    let (mut s, mut local) = (guarded.scratch(), vec![0.0; guarded.num_particles]);
    assert_eq!(guarded.evaluate(&g, &mut s, &mut local), f64::INFINITY);
    assert!(local.iter().all(|&l| l == f64::INFINITY), "{local:?}");
    // Without the horizon the same candidate has a finite (if poor) one-step cost: the short
    // cost alone cannot see the instability.
    assert!(plain
        .evaluate(&g, &mut plain.scratch(), &mut local)
        .is_finite());
}

#[test]
fn the_horizon_refuses_a_run_too_short_or_a_spread_below_one() {
    assert!(StableHorizon::new(2, 2.0).is_err());
    assert!(StableHorizon::new(10, 0.5).is_err());
    assert!(StableHorizon::new(10, f64::NAN).is_err());
    assert!(StableHorizon::new(3, 1.0).is_ok());
}

fn run(problem: &mut Problem, strategy: StrategyName, evals: u64, seed: u64) -> RunResult {
    let (mut s, _) = make_strategy(strategy, problem, &StrategyOptions::default());
    let config = RunConfig {
        seed,
        stop: StopRules {
            max_evals: Some(evals),
            ..StopRules::default()
        },
        ..RunConfig::default()
    };
    executor::run(problem, s.as_mut(), &config, &mut [], None).expect("run")
}

/// Issue 7 part 4: the long cost over boxes 1e-3…1e3 × the truth. Most candidates' rollouts
/// explode (`+inf`); no run may produce a NaN or leave its boxes, and the reported cost is the
/// cost of the reported parameters. `t2m` (what `auto` runs for a rollout cost) must end
/// finite. CMA-ES and the text's `thesis` are only held to the first rules: on the horse,
/// every CMA-ES candidate may diverge within the 53 frames (BENCHMARKS.md,
/// `wide_identification`), and the text's ES makes ~0.3 new individuals per generation (a
/// third of its 1 % mutations), too few to meet a finite one in 1,500 evaluations there.
#[test]
fn long_cost_over_wide_boxes_ends_without_nan_on_rigid_and_horse() {
    for name in ["rigid", "horse"] {
        let truth = by_name(name).unwrap();
        let traj = truth.simulate(default_frames(name)).unwrap();
        let scene = with_unknown_boxes(&truth, 1e6, 1);
        for strategy in [StrategyName::T2m, StrategyName::Thesis, StrategyName::Cmaes] {
            let mut problem = Problem::new(&scene, &traj, CostKind::Long).unwrap();
            let r = run(&mut problem, strategy, 1500, 3);
            assert!(!r.cost.is_nan() && !r.rmse.is_nan(), "{name} {strategy:?}");
            if strategy == StrategyName::T2m {
                assert!(
                    r.cost.is_finite() && r.rmse.is_finite(),
                    "{name}: cost {} rmse {}",
                    r.cost,
                    r.rmse
                );
            }
            assert!(
                r.params.iter().all(|v| v.is_finite()),
                "{name} {strategy:?}"
            );
            for (u, v) in problem
                .space
                .unknowns
                .iter()
                .zip(problem.space.values(&r.genome))
            {
                assert!(u.min <= v && v <= u.max, "{name}: {} = {v}", u.name);
            }
            let again = problem.objective.report(&r.params).unwrap();
            assert_eq!(
                again.total.to_bits(),
                r.cost.to_bits(),
                "{name} {strategy:?}"
            );
        }
    }
}

/// Every run checks its identified model's stability bound at the end: the rigid object with
/// its masses ÷ 3 (ratio 1.22, beyond the bound, yet its 40 frames stay bounded), identified
/// exactly by least squares, comes with the warning; the rigid object itself (0.41) without.
#[test]
fn an_identified_model_beyond_the_stability_bound_is_warned_about() {
    use cordis_es::session::{Generations, IdentifyRequest, Session};
    for (divide, warned) in [(1.0, false), (3.0, true)] {
        let mut truth = cordis_core::examples::rigid();
        for p in &mut truth.particles {
            p.mass = Param::Known(p.mass.value() / divide);
        }
        let traj = truth.simulate(40).expect("40 bounded frames");
        let mut req = IdentifyRequest::new(with_unknown_boxes(&truth, 10.0, 3), traj);
        req.strategy = StrategyName::LeastSquares;
        req.generations = Generations::Limit(0);
        let out = Session::new(req)
            .expect("a valid request")
            .run(&mut [], None)
            .expect("an estimate");
        let said = out
            .warnings
            .iter()
            .any(|w| w.starts_with("the identified model is beyond the stability bound"));
        assert_eq!(said, warned, "masses ÷ {divide}: {:?}", out.warnings);
    }
}
