//! The thesis strategy end to end: thesis §4.1's accuracy on `rigid`, determinism across
//! thread counts, and checkpoint/resume.

use std::time::Instant;

use cordis_core::examples;
use cordis_es::cost::CostKind;
use cordis_es::executor::{self, RunConfig, RunResult, StopRules};
use cordis_es::identify::with_unknown_boxes;
use cordis_es::problem::Problem;
use cordis_es::strategies::thesis::{Thesis, ThesisConfig};

fn rigid_problem() -> Problem {
    let truth = examples::rigid();
    let traj = truth.simulate(100).unwrap();
    let unknown = with_unknown_boxes(&truth, 25.0, 7);
    Problem::new(&unknown, &traj, CostKind::Short)
        .unwrap()
        .with_truth(&truth)
        .unwrap()
}

fn run(problem: &mut Problem, config: &RunConfig, threads: usize) -> RunResult {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    let mut strategy = Thesis::new(ThesisConfig::default());
    pool.install(|| executor::run(problem, &mut strategy, config, &mut [], None))
        .unwrap()
}

fn generations(g: u64, seed: u64) -> RunConfig {
    RunConfig {
        seed,
        stop: StopRules {
            generations: Some(g),
            ..StopRules::default()
        },
        ..RunConfig::default()
    }
}

#[test]
fn rigid_reaches_the_thesis_accuracy_in_1000_generations() {
    let mut problem = rigid_problem();
    assert_eq!(problem.dim(), 20, "10 types × (K, l0)");
    let start = Instant::now();
    let r = run(&mut problem, &generations(1000, 1), 2);
    let seconds = start.elapsed().as_secs_f64();
    let err = r.param_error_pct.unwrap();
    assert!(
        err < 0.01,
        "mean parameter error {err} % (thesis §4.1: < 0.01 %)"
    );
    assert!(seconds < 10.0, "took {seconds} s");
    assert_eq!(r.generations, 1000);
    assert_eq!(r.history.len(), 1001);
    // Elitism: the best cost never rises.
    for w in r.history.windows(2) {
        assert!(w[1].best_cost <= w[0].best_cost);
    }
}

#[test]
fn same_seed_gives_bit_identical_results_on_1_and_2_threads() {
    let a = run(&mut rigid_problem(), &generations(450, 3), 1);
    let b = run(&mut rigid_problem(), &generations(450, 3), 2);
    assert_eq!(
        a.genome.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
        b.genome.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
    );
    assert_eq!(a.cost.to_bits(), b.cost.to_bits());
    assert_eq!(a.evals, b.evals);
    let c = run(&mut rigid_problem(), &generations(450, 4), 2);
    assert_ne!(a.genome, c.genome, "another seed explores differently");
}

#[test]
fn checkpoint_then_resume_ends_where_an_uninterrupted_run_ends() {
    let dir = tempfile::tempdir().unwrap();
    let cp = dir.path().join("run.checkpoint.json");
    let whole = run(&mut rigid_problem(), &generations(460, 5), 2);
    let mut first = generations(230, 5);
    first.checkpoint = Some(cp.clone());
    run(&mut rigid_problem(), &first, 2);
    let mut second = generations(460, 5);
    second.resume = Some(cp);
    let resumed = run(&mut rigid_problem(), &second, 1);
    assert_eq!(resumed.genome, whole.genome);
    assert_eq!(resumed.cost.to_bits(), whole.cost.to_bits());
    assert_eq!(resumed.evals, whole.evals);
    assert_eq!(resumed.generations, 460);
    assert_eq!(resumed.history.len(), whole.history.len());
}

#[test]
fn resume_refuses_another_seed() {
    let dir = tempfile::tempdir().unwrap();
    let cp = dir.path().join("cp.json");
    let mut first = generations(3, 5);
    first.checkpoint = Some(cp.clone());
    run(&mut rigid_problem(), &first, 1);
    let mut other = generations(6, 6);
    other.resume = Some(cp);
    let mut strategy = Thesis::new(ThesisConfig::default());
    let err =
        executor::run(&mut rigid_problem(), &mut strategy, &other, &mut [], None).unwrap_err();
    assert!(err.contains("seed 5"), "{err}");
}

#[test]
fn generated_networks_reach_the_thesis_accuracy_too() {
    // Networks the strategy was never tuned on: 10–15 masses, 8–10 types, 20–30 unknowns in
    // boxes 25× wide, 100 frames, population 100, 1000 generations.
    for (seed, masses, types) in [(11, 10, 8), (12, 12, 9), (13, 15, 10), (14, 14, 10)] {
        let truth = examples::random_network(seed, masses, types);
        let traj = truth.simulate(100).unwrap();
        let unknown = with_unknown_boxes(&truth, 25.0, seed);
        let mut problem = Problem::new(&unknown, &traj, CostKind::Short)
            .unwrap()
            .with_truth(&truth)
            .unwrap();
        let dim = problem.dim();
        assert!((20..=30).contains(&dim), "seed {seed}: {dim} unknowns");
        let r = run(&mut problem, &generations(1000, seed), 2);
        let err = r.param_error_pct.unwrap();
        assert!(
            err < 0.01,
            "seed {seed} ({masses} masses, {types} types, {dim} unknowns): {err} %"
        );
    }
}
