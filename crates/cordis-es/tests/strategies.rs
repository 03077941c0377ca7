//! The strategies beyond the thesis (cmaes, self-adaptive, annealing, parisian) through the
//! shared run loop: each improves a small identification, runs identically on 1 and 2 threads,
//! and resumes from a checkpoint exactly where an uninterrupted run would be.

use cordis_core::{Bounds, Param, Scene};
use cordis_es::cost::CostKind;
use cordis_es::executor::{self, RunConfig, RunResult, StopRules};
use cordis_es::identify::with_unknown_boxes;
use cordis_es::problem::Problem;
use cordis_es::strategies::annealing::{Annealing, AnnealingConfig};
use cordis_es::strategies::cmaes::{Cmaes, CmaesConfig};
use cordis_es::strategies::parisian::{Parisian, ParisianConfig};
use cordis_es::strategies::self_adaptive::{SelfAdaptive, SelfAdaptiveConfig};
use cordis_es::strategy::Strategy;

mod common;
use common::rigid_problem;

const NAMES: [&str; 4] = ["cmaes", "self-adaptive", "annealing", "parisian"];

/// Small populations so a few dozen generations do real work in well under a second.
fn strategy(name: &str) -> Box<dyn Strategy> {
    match name {
        "cmaes" => Box::new(Cmaes::new(CmaesConfig::default())),
        "self-adaptive" => Box::new(SelfAdaptive::new(SelfAdaptiveConfig::with_lambda(20))),
        "annealing" => Box::new(Annealing::new(AnnealingConfig {
            chains: 4,
            cooling: 0.9,
            ..AnnealingConfig::default()
        })),
        "parisian" => Box::new(Parisian::new(ParisianConfig {
            population: 40,
            ..ParisianConfig::default()
        })),
        _ => unreachable!(),
    }
}

fn run(problem: &mut Problem, name: &str, config: &RunConfig) -> RunResult {
    // The evaluation counter lives in the problem; a fresh run (not a resume) starts it at 0.
    if config.resume.is_none() {
        problem.set_evals(0);
    }
    let mut s = strategy(name);
    executor::run(problem, s.as_mut(), config, &mut [], None).expect("run")
}

fn generations(seed: u64, g: u64) -> RunConfig {
    RunConfig {
        seed,
        stop: StopRules {
            generations: Some(g),
            ..StopRules::default()
        },
        ..RunConfig::default()
    }
}

fn bits(v: &[f64]) -> Vec<u64> {
    v.iter().map(|x| x.to_bits()).collect()
}

#[test]
fn every_strategy_improves_the_rigid_fit() {
    let mut problem = rigid_problem();
    for name in NAMES {
        let r = run(&mut problem, name, &generations(1, 300));
        let first = r.history[0].best_cost;
        eprintln!(
            "{name}: {first:e} → {:e} in {} evaluations",
            r.cost, r.evals
        );
        assert!(first.is_finite(), "{name}: initial cost {first}");
        // At least a tenfold drop of the cost, and the best never rises along the way.
        assert!(r.cost < 0.1 * first, "{name}: {first:e} → {:e}", r.cost);
        for w in r.history.windows(2) {
            assert!(w[1].best_cost <= w[0].best_cost, "{name}: best rose");
        }
        assert_eq!(r.genome.len(), problem.dim());
        assert!(r.genome.iter().all(|z| z.is_finite()));
        for (u, &z) in problem.space.unknowns.iter().zip(&r.genome) {
            let (lo, hi) = u.internal_bounds();
            assert!(
                lo <= z && z <= hi,
                "{name}: {} = {z} outside [{lo}, {hi}]",
                u.name
            );
        }
    }
}

#[test]
fn same_seed_gives_the_same_best_on_one_and_two_threads() {
    let mut problem = rigid_problem();
    for name in NAMES {
        let mut on = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .expect("pool")
                .install(|| run(&mut problem, name, &generations(7, 20)))
        };
        let a = on(1);
        let b = on(2);
        assert_eq!(bits(&a.genome), bits(&b.genome), "{name}");
        assert_eq!(a.cost.to_bits(), b.cost.to_bits(), "{name}");
        assert_eq!(a.evals, b.evals, "{name}");
        // And another seed is another run.
        let c = run(&mut problem, name, &generations(8, 20));
        let means = |r: &RunResult| -> Vec<u64> {
            r.history.iter().map(|h| h.mean_cost.to_bits()).collect()
        };
        assert_ne!(means(&a), means(&c), "{name}: seed ignored");
    }
}

#[test]
fn checkpoint_then_resume_ends_where_an_uninterrupted_run_does() {
    let mut problem = rigid_problem();
    let dir = std::env::temp_dir().join(format!("cordis-es-strategies-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let k = 12;
    for name in NAMES {
        let whole = run(&mut problem, name, &generations(5, 2 * k));
        let path = dir.join(format!("{name}.json"));
        let first = RunConfig {
            checkpoint: Some(path.clone()),
            checkpoint_every: k,
            ..generations(5, k)
        };
        run(&mut problem, name, &first);
        let second = RunConfig {
            resume: Some(path.clone()),
            ..generations(5, 2 * k)
        };
        let resumed = run(&mut problem, name, &second);
        assert_eq!(bits(&whole.genome), bits(&resumed.genome), "{name}");
        assert_eq!(whole.cost.to_bits(), resumed.cost.to_bits(), "{name}");
        assert_eq!(whole.evals, resumed.evals, "{name}");
        assert_eq!(whole.generations, resumed.generations, "{name}");
        let costs = |r: &RunResult| -> Vec<u64> {
            r.history.iter().map(|h| h.best_cost.to_bits()).collect()
        };
        assert_eq!(costs(&whole), costs(&resumed), "{name}: history");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn resuming_another_strategys_checkpoint_is_an_error() {
    let mut problem = rigid_problem();
    let path = std::env::temp_dir().join(format!("cordis-es-cross-{}.json", std::process::id()));
    let first = RunConfig {
        checkpoint: Some(path.clone()),
        checkpoint_every: 2,
        ..generations(1, 2)
    };
    run(&mut problem, "cmaes", &first);
    let mut other = strategy("annealing");
    let second = RunConfig {
        resume: Some(path.clone()),
        ..generations(1, 4)
    };
    let err = executor::run(&mut problem, other.as_mut(), &second, &mut [], None).unwrap_err();
    assert!(err.to_string().contains("cmaes"), "{err}");
    let _ = std::fs::remove_file(&path);
}

/// Rigid with every mass unknown too (box [0.3, 3] kg), for the total-mass constraint.
fn rigid_with_masses() -> (Scene, Problem) {
    let truth = cordis_core::examples::rigid();
    let traj = truth.simulate(40).expect("rigid simulates");
    let mut scene = with_unknown_boxes(&truth, 10.0, 3);
    for p in &mut scene.particles {
        p.mass = Param::Unknown(Bounds {
            min: 0.3,
            max: 3.0,
            init: None,
        });
    }
    let problem = Problem::new(&scene, &traj, CostKind::Short)
        .expect("problem")
        .with_truth(&truth)
        .expect("truth");
    (scene, problem)
}

#[test]
fn parisian_splits_by_link_type_and_keeps_the_total_mass() {
    let (scene, mut problem) = rigid_with_masses();
    let groups = Parisian::sub_problems(&problem);
    let types_with_unknowns = scene
        .types
        .iter()
        .filter(|t| t.params.iter().any(|p| p.is_unknown()))
        .count();
    assert_eq!(groups.len(), types_with_unknowns);
    // Every unknown is in some sub-problem; every sub-problem holds masses (all are free).
    let mut seen = vec![false; problem.dim()];
    for g in &groups {
        for &k in g {
            seen[k] = true;
        }
        assert!(g
            .iter()
            .any(|&k| problem.space.unknowns[k].name.ends_with(".mass")));
    }
    assert!(seen.iter().all(|&s| s));

    // M: the starting masses (the boxes' middles, 1.65 kg each).
    let total: f64 = scene.particles.iter().map(|p| p.mass.value()).sum();
    let r = run(&mut problem, "parisian", &generations(2, 40));
    assert!(r.cost < r.history[0].best_cost);
    let layout = scene.param_layout();
    let sum: f64 = (0..scene.num_particles())
        .map(|i| r.params[layout.mass_offset + i])
        .sum();
    assert!(
        (sum - total).abs() < 1e-9 * total,
        "Σm = {sum}, M = {total}"
    );
}

/// BIPOP's restart state (the regimes' budgets, the current regime, λ_l) lives in the
/// checkpoint: runs that end after a few generations (TolX at half of σ0) restart on both sides
/// of the checkpoint, and the resumed run ends where the uninterrupted one does. A seed fixes
/// the run on 1 and 2 threads; an IPOP checkpoint holds no BIPOP state.
#[test]
fn bipop_restarts_resume_from_a_checkpoint_and_a_seed_fixes_them() {
    use cordis_es::strategies::cmaes::Restarts;
    let mut problem = rigid_problem();
    let dir = std::env::temp_dir().join(format!("cordis-es-bipop-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let config = |restarts| CmaesConfig {
        tol_x: 0.5,
        restarts,
        ..CmaesConfig::default()
    };
    let mut go = |restarts, run: &RunConfig, threads: usize| {
        if run.resume.is_none() {
            problem.set_evals(0);
        }
        let mut s = Cmaes::new(config(restarts));
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .expect("pool");
        pool.install(|| executor::run(&mut problem, &mut s, run, &mut [], None))
            .expect("run")
    };
    let k = 40;
    let whole = go(Restarts::Bipop, &generations(5, 2 * k), 2);
    assert_eq!(
        bits(&whole.genome),
        bits(&go(Restarts::Bipop, &generations(5, 2 * k), 1).genome)
    );
    let path = dir.join("bipop.json");
    let first = RunConfig {
        checkpoint: Some(path.clone()),
        checkpoint_every: k,
        ..generations(5, k)
    };
    go(Restarts::Bipop, &first, 2);
    let saved: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&path).expect("checkpoint")).unwrap();
    let text = saved.to_string();
    let before = restarts(&saved).expect("the restart count in the checkpoint");
    assert!(before >= 2, "{before} restarts before the checkpoint");
    assert!(text.contains("large_evals") && text.contains("lambda_large"));
    let second = RunConfig {
        resume: Some(path.clone()),
        ..generations(5, 2 * k)
    };
    let resumed = go(Restarts::Bipop, &second, 2);
    assert_eq!(bits(&whole.genome), bits(&resumed.genome));
    assert_eq!(whole.cost.to_bits(), resumed.cost.to_bits());
    assert_eq!(whole.evals, resumed.evals);
    // IPOP's checkpoints are as before: no BIPOP state, and another run.
    let ipop = RunConfig {
        checkpoint: Some(dir.join("ipop.json")),
        checkpoint_every: k,
        ..generations(5, k)
    };
    let i = go(Restarts::Ipop, &ipop, 2);
    let text = std::fs::read_to_string(dir.join("ipop.json")).expect("checkpoint");
    assert!(!text.contains("large_evals"));
    assert_ne!(i.history.len(), 0);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The first `restarts` count anywhere in a checkpoint's JSON.
fn restarts(v: &serde_json::Value) -> Option<u64> {
    match v {
        serde_json::Value::Object(m) => m
            .get("restarts")
            .and_then(|r| r.as_u64())
            .or_else(|| m.values().find_map(restarts)),
        serde_json::Value::Array(a) => a.iter().find_map(restarts),
        _ => None,
    }
}
