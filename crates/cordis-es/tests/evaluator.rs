//! Where costs are computed must not change a run: a foreign evaluator (here one that evaluates
//! sequentially, last genome first, as a remote pool may) gives bit-identical runs; a failing
//! one stops the run with its message. Islands are deterministic, migrate, and resume.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

use cordis_es::cost::CostKind;
use cordis_es::evaluator::Evaluator;
use cordis_es::executor::{self, RunConfig, RunResult, StopRules};
use cordis_es::identify::{make_islands, make_strategy, with_unknown_boxes};
use cordis_es::identify::{StrategyName, StrategyOptions};
use cordis_es::problem::Problem;
use cordis_es::strategies::islands::IslandConfig;

mod common;
use common::rigid_problem;

/// Evaluates one genome at a time in reverse order, counting its batches.
#[derive(Default)]
struct Reversed {
    batches: AtomicUsize,
}

impl Evaluator for Reversed {
    fn evaluate(
        &self,
        problem: &Problem,
        genomes: &[f64],
        costs: &mut [f64],
        mut local: Option<&mut [f64]>,
    ) -> Result<(), cordis_es::CostError> {
        self.batches.fetch_add(1, Ordering::Relaxed);
        let (dim, n) = (problem.dim(), problem.num_particles);
        let mut s = problem.scratch();
        let mut scratch_local = vec![0.0; n];
        for k in (0..costs.len()).rev() {
            let l = match local.as_deref_mut() {
                Some(l) => &mut l[k * n..(k + 1) * n],
                None => &mut scratch_local[..],
            };
            costs[k] = problem.evaluate_uncounted(&genomes[k * dim..(k + 1) * dim], &mut s, l);
        }
        Ok(())
    }
}

/// Fails from its `after`-th batch on.
struct Failing {
    after: usize,
    batches: AtomicUsize,
}

impl Evaluator for Failing {
    fn evaluate(
        &self,
        problem: &Problem,
        genomes: &[f64],
        costs: &mut [f64],
        local: Option<&mut [f64]>,
    ) -> Result<(), cordis_es::CostError> {
        if self.batches.fetch_add(1, Ordering::Relaxed) >= self.after {
            return Err(cordis_es::CostError::evaluation("worker lost"));
        }
        cordis_es::evaluator::Local.evaluate(problem, genomes, costs, local)
    }
}

fn config(seed: u64, g: u64) -> RunConfig {
    RunConfig {
        seed,
        stop: StopRules {
            generations: Some(g),
            ..StopRules::default()
        },
        ..RunConfig::default()
    }
}

fn options() -> StrategyOptions {
    StrategyOptions {
        population: 24,
        ..StrategyOptions::default()
    }
}

fn run(
    problem: &mut Problem,
    name: StrategyName,
    islands: Option<IslandConfig>,
    c: &RunConfig,
) -> RunResult {
    let (mut s, _) = match islands {
        Some(i) => make_islands(name, problem, &options(), i).expect("islands"),
        None => make_strategy(name, problem, &options()),
    };
    executor::run(problem, s.as_mut(), c, &mut [], None).expect("run")
}

/// Everything but the wall-clock seconds, bit for bit.
fn fingerprint(r: &RunResult) -> (Vec<u64>, u64, u64, Vec<[u64; 4]>) {
    (
        r.genome.iter().map(|x| x.to_bits()).collect(),
        r.cost.to_bits(),
        r.evals,
        r.history
            .iter()
            .map(|h| {
                [
                    h.evals,
                    h.best_cost.to_bits(),
                    h.mean_cost.to_bits(),
                    h.mean_mutability.to_bits(),
                ]
            })
            .collect(),
    )
}

#[test]
fn a_foreign_evaluator_changes_nothing() {
    for name in [
        StrategyName::Thesis,
        StrategyName::T2m,
        StrategyName::Cmaes,
        StrategyName::Parisian,
    ] {
        let mut local = rigid_problem();
        let a = run(&mut local, name, None, &config(7, 15));
        let reversed = Arc::new(Reversed::default());
        let mut remote = rigid_problem().with_evaluator(reversed.clone());
        let b = run(&mut remote, name, None, &config(7, 15));
        // One batch per generation; the text's ES skips a generation that drew no child.
        let batches = match name {
            StrategyName::Thesis => {
                1 + b
                    .history
                    .windows(2)
                    .filter(|w| w[1].evals > w[0].evals)
                    .count()
            }
            _ => 16,
        };
        assert!(batches >= 8, "{name:?}: {batches} batches");
        assert!(
            reversed.batches.load(Ordering::Relaxed) >= batches,
            "{name:?}: evaluator unused"
        );
        assert_eq!(fingerprint(&a), fingerprint(&b), "{name:?}");
        // The text's ES changes a sixth of its population per generation, mostly by means of
        // fathers: 15 generations need not beat the initial best, but they move the mean.
        match name {
            StrategyName::Thesis => assert_ne!(
                a.history[0].mean_cost, a.history[15].mean_cost,
                "{name:?}: the population never changed"
            ),
            _ => assert!(a.cost < a.history[0].best_cost, "{name:?}: no progress"),
        }
    }
}

#[test]
fn a_failing_evaluator_stops_the_run_naming_the_generation() {
    let failing = Arc::new(Failing {
        after: 3,
        batches: AtomicUsize::new(0),
    });
    let mut problem = rigid_problem().with_evaluator(failing);
    let (mut s, _) = make_strategy(StrategyName::Thesis, &problem, &options());
    let err = executor::run(&mut problem, s.as_mut(), &config(1, 10), &mut [], None)
        .expect_err("the evaluator failed");
    // A failed run (exit 1 in the CLI) whose source is the evaluator's own error.
    assert!(matches!(err, cordis_es::CostError::Run { .. }), "{err:?}");
    let source = std::error::Error::source(&err).expect("the evaluation as source");
    assert_eq!(source.to_string(), "worker lost");
    let err = err.to_string();
    assert!(
        err.contains("generation 3") && err.contains("worker lost"),
        "{err}"
    );
}

fn islands(k: usize) -> IslandConfig {
    IslandConfig {
        islands: k,
        migrate_every: 4,
        migrants: 2,
    }
}

#[test]
fn islands_are_deterministic_and_independent_of_threads_and_evaluator() {
    let mut problem = rigid_problem();
    let c = config(11, 12);
    let a = run(&mut problem, StrategyName::Thesis, Some(islands(3)), &c);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .expect("pool");
    let mut remote = rigid_problem().with_evaluator(Arc::new(Reversed::default()));
    let b = pool.install(|| run(&mut remote, StrategyName::Thesis, Some(islands(3)), &c));
    assert_eq!(fingerprint(&a), fingerprint(&b));
    // Three islands of 24 evaluate 3 × 24 at generation 0, then 3 × 60% of 24 per generation.
    assert_eq!(a.history[0].evals, 72);
    let other = run(&mut problem, StrategyName::Thesis, Some(islands(2)), &c);
    assert_ne!(
        fingerprint(&a).3,
        fingerprint(&other).3,
        "island count ignored"
    );
    assert!(a.cost < a.history[0].best_cost, "no progress");
}

#[test]
fn islands_resume_from_a_checkpoint_exactly() {
    let mut problem = rigid_problem();
    let dir = std::env::temp_dir().join(format!("cordis-es-islands-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join("islands.json");
    let whole = run(
        &mut problem,
        StrategyName::Thesis,
        Some(islands(2)),
        &config(5, 12),
    );
    let first = RunConfig {
        checkpoint: Some(path.clone()),
        checkpoint_every: 6,
        ..config(5, 6)
    };
    run(&mut problem, StrategyName::Thesis, Some(islands(2)), &first);
    let second = RunConfig {
        resume: Some(path.clone()),
        ..config(5, 12)
    };
    let resumed = run(
        &mut problem,
        StrategyName::Thesis,
        Some(islands(2)),
        &second,
    );
    assert_eq!(fingerprint(&whole), fingerprint(&resumed));
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_strategy_that_cannot_migrate_is_refused() {
    let problem = rigid_problem();
    let err = make_islands(StrategyName::Cmaes, &problem, &options(), islands(2))
        .err()
        .expect("cmaes cannot migrate");
    assert!(
        matches!(err, cordis_es::CostError::Refused { .. }),
        "{err:?}"
    );
    assert!(err.to_string().contains("cmaes"), "{err}");
}

#[test]
fn islands_with_auto_run_thesis_populations_even_where_auto_alone_would_not() {
    // Alone, `auto` picks least-squares on the rigid scene and levenberg-marquardt on the
    // muscle: neither has a population to exchange. With islands it means the thesis ES (its
    // `t2m` variant, what `auto` falls back to alone).
    for truth in [
        cordis_core::examples::rigid(),
        cordis_core::examples::muscle(),
    ] {
        let traj = truth.simulate(40).unwrap();
        let problem =
            Problem::new(&with_unknown_boxes(&truth, 25.0, 2), &traj, CostKind::Short).unwrap();
        let (_, alone) = make_strategy(StrategyName::Auto, &problem, &options());
        assert_ne!(alone, "t2m");
        let (_, ran) = make_islands(StrategyName::Auto, &problem, &options(), islands(2))
            .expect("auto islands");
        assert_eq!(ran, "t2m");
    }
}
