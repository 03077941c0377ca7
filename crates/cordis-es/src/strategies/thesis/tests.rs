//! One test per operator of the thesis ES (`thesis` variant), each on a tiny population of the
//! rigid truss (10 types × (K, l0)), asserting the property the text gives the operator.

use super::config::{Crossover, ThesisConfig};
use super::operators::{child, plan, protected, Application, Parents, Rankings};
use super::population::{evaluate, fresh, Individual, Layout, Op};
use super::Thesis;
use crate::cost::CostKind;
use crate::identify::with_unknown_boxes;
use crate::problem::Problem;
use crate::run::rng;
use crate::run::strategy::Strategy;

fn truss() -> Problem {
    let truth = cordis_core::examples::rigid();
    let traj = truth.simulate(12).expect("rigid simulates");
    Problem::new(&with_unknown_boxes(&truth, 25.0, 7), &traj, CostKind::Short).expect("problem")
}

/// `n` evaluated heuristic individuals sorted by global cost, their mutabilities set to
/// `sigma` (0: a child's genes show exactly where they came from); every gene is moved by a
/// per-individual step so that no two individuals share one (the heuristic puts every rest
/// length at its observed mean).
fn population(problem: &Problem, n: usize, sigma: f64) -> Vec<Individual> {
    let mut pop: Vec<Individual> = (0..n)
        .map(|k| {
            let mut i = fresh(problem, &mut rng::stream(3, 0, k as u64 + 1));
            i.sigma.iter_mut().for_each(|s| *s = sigma);
            for (z, u) in i.genes.iter_mut().zip(&problem.space.unknowns) {
                let (lo, hi) = u.internal_bounds();
                *z = u
                    .clamp_internal(lo + (*z - lo + 1e-3 * (k + 1) as f64 * (hi - lo)) % (hi - lo));
            }
            i
        })
        .collect();
    evaluate(problem, &mut pop);
    pop.sort_by(|a, b| a.cost.total_cmp(&b.cost));
    pop
}

/// Builds `draws` children of `op` on son `son`, each from its own stream.
fn children(
    problem: &Problem,
    pop: &[Individual],
    config: &ThesisConfig,
    op: Op,
    son: usize,
    draws: u64,
) -> Vec<Individual> {
    let layout = Layout::new(problem);
    let ranks = Rankings::new(pop, &layout);
    let parents = Parents {
        pop,
        layout: &layout,
        ranks: &ranks,
        cost_ref: pop[0].cost,
    };
    (0..draws)
        .map(|d| {
            child(
                &parents,
                config,
                problem,
                Application { op, son },
                &mut rng::stream(11, d, 1),
            )
        })
        .collect()
}

/// Which individual of `pop` has exactly these genes.
fn whose(pop: &[Individual], genes: &[f64], ks: &[usize]) -> Option<usize> {
    pop.iter()
        .position(|i| ks.iter().all(|&k| i.genes[k] == genes[k]))
}

/// `count` within `sds` binomial standard deviations of `n · p`.
fn binomial_band(count: usize, n: usize, p: f64, sds: f64) -> bool {
    let (mean, sd) = (n as f64 * p, (n as f64 * p * (1.0 - p)).sqrt());
    (count as f64 - mean).abs() <= sds * sd
}

/// §3.2.1: the global cost protects the best 5 %; Annexe 1: the sons of re-injection, noisy
/// inheritance and pure mutation are in the worse half, those of local mutation and crossover
/// in the rest ("la 2ème partie"); no individual is a son twice in a generation.
#[test]
fn selection_protects_the_best_5_percent() {
    let c = ThesisConfig {
        pcross: 40.0,
        pmut: 30.0,
        ..ThesisConfig::thesis()
    };
    let n = 40;
    assert_eq!(protected(&c, n), 2);
    let mut local_sons = vec![0usize; n];
    for g in 0..500 {
        let apps = plan(&c, n, &mut rng::stream(5, g, 0));
        let mut seen = vec![false; n];
        for a in apps {
            assert!(!seen[a.son], "son {} twice", a.son);
            seen[a.son] = true;
            match a.op {
                Op::Reinject | Op::Inherit | Op::Pure => assert!(a.son >= n / 2, "{a:?}"),
                Op::Local | Op::Crossover => {
                    assert!(a.son >= 2, "{a:?}");
                    local_sons[a.son] += 1;
                }
            }
        }
    }
    // The better half outside the protected 5 % is not spared by the global ranking.
    assert!(
        local_sons[2..n / 2].iter().all(|&c| c > 0),
        "{local_sons:?}"
    );
}

/// §3.2: mutations hit each individual with probability `pmut` % (1 %), crossovers with
/// `pcross` % (15 %, Param.gene): the counts over many generations lie in their binomial
/// bands; re-injection is a tenth of the mutations.
#[test]
fn mutation_and_crossover_rates_are_binomial() {
    let c = ThesisConfig::thesis();
    let (n, gens) = (100, 3000);
    let (mut cross, mut muts, mut reinject) = (0, 0, 0);
    for g in 0..gens {
        for a in plan(&c, n, &mut rng::stream(9, g, 0)) {
            match a.op {
                Op::Crossover => cross += 1,
                Op::Reinject => {
                    reinject += 1;
                    muts += 1
                }
                _ => muts += 1,
            }
        }
    }
    let trials = n * gens as usize;
    assert!(
        binomial_band(cross, trials, 0.15, 4.0),
        "{cross} crossovers in {trials}"
    );
    assert!(
        binomial_band(muts, trials, 0.01, 4.0),
        "{muts} mutations in {trials}"
    );
    assert!(
        binomial_band(reinject, muts, 0.1, 4.0),
        "{reinject} of {muts}"
    );
}

/// Annexe 1, noisy inheritance: "father avec une probabilité équirépartie dans la
/// population": with zero mutabilities the child is its father's copy, and every individual
/// is the father as often (a rank bias would give the best 7/16 of a population of 4).
#[test]
fn noisy_inheritance_father_is_uniform() {
    let problem = truss();
    let pop = population(&problem, 4, 0.0);
    let all: Vec<usize> = (0..problem.dim()).collect();
    let mut counts = [0usize; 4];
    for c in children(
        &problem,
        &pop,
        &ThesisConfig::thesis(),
        Op::Inherit,
        3,
        4000,
    ) {
        counts[whose(&pop, &c.genes, &all).expect("a copy of a father")] += 1;
        // σ_son = (σ_father + |draw|) / 2, the draw's scale following the father's cost.
        assert!(c.sigma.iter().all(|&s| s >= 0.0 && s.is_finite()));
        assert!(c.sigma.iter().any(|&s| s > 0.0));
    }
    for (f, &k) in counts.iter().enumerate() {
        assert!(binomial_band(k, 4000, 0.25, 4.0), "father {f}: {counts:?}");
    }
}

/// Annexe 1, re-injection: a uniform father's genes, but for one type re-initialised by the
/// heuristic (its rest length back at the observed mean).
#[test]
fn reinjection_reinitialises_one_type_of_a_uniform_father() {
    let problem = truss();
    let layout = Layout::new(&problem);
    let pop = population(&problem, 4, 0.0);
    let mut counts = [0usize; 4];
    for c in children(
        &problem,
        &pop,
        &ThesisConfig::thesis(),
        Op::Reinject,
        3,
        2000,
    ) {
        let changed: Vec<usize> = (0..layout.groups.len())
            .filter(|&g| {
                layout.groups[g]
                    .iter()
                    .any(|&k| pop.iter().all(|i| i.genes[k] != c.genes[k]))
            })
            .collect();
        assert!(changed.len() <= 1, "types {changed:?} changed");
        let kept: Vec<usize> = (0..layout.groups.len())
            .filter(|g| !changed.contains(g))
            .flat_map(|g| layout.groups[g].clone())
            .collect();
        let f = whose(&pop, &c.genes, &kept).expect("the other types from one father");
        counts[f] += 1;
        for &k in changed.iter().flat_map(|&g| &layout.groups[g]) {
            if let Some(m) = problem.observed[k] {
                let u = &problem.space.unknowns[k];
                assert_eq!(c.genes[k], u.clamp_internal(u.to_internal(m)));
            }
        }
    }
    for (f, &k) in counts.iter().enumerate() {
        assert!(binomial_band(k, 2000, 0.25, 4.0), "father {f}: {counts:?}");
    }
}

/// Annexe 1, pure mutation: "des individus entièrement nouveaux": in the box, rest lengths
/// at their observed means, unrelated to the population.
#[test]
fn pure_mutation_makes_a_new_individual() {
    let problem = truss();
    let pop = population(&problem, 4, 0.0);
    let all: Vec<usize> = (0..problem.dim()).collect();
    for c in children(&problem, &pop, &ThesisConfig::thesis(), Op::Pure, 3, 50) {
        assert!(whose(&pop, &c.genes, &all).is_none());
        for (k, u) in problem.space.unknowns.iter().enumerate() {
            let (lo, hi) = u.internal_bounds();
            assert!((lo..=hi).contains(&c.genes[k]), "{}", u.name);
            if let Some(m) = problem.observed[k] {
                assert_eq!(c.genes[k], u.clamp_internal(u.to_internal(m)));
            }
        }
    }
}

/// Annexe 1, local mutation: the **son** keeps every parameter but those of one link ending
/// at the chosen particle, which come from a father (zero mutabilities: exactly).
#[test]
fn local_mutation_changes_one_type_of_the_son() {
    let problem = truss();
    let layout = Layout::new(&problem);
    let pop = population(&problem, 6, 0.0);
    let son = 4;
    let mut from_others = 0;
    for c in children(&problem, &pop, &ThesisConfig::thesis(), Op::Local, son, 500) {
        let changed: Vec<usize> = (0..layout.groups.len())
            .filter(|&g| {
                layout.groups[g]
                    .iter()
                    .any(|&k| c.genes[k] != pop[son].genes[k])
            })
            .collect();
        assert!(changed.len() <= 1, "types {changed:?} changed");
        if let Some(&g) = changed.first() {
            assert!(
                whose(&pop, &c.genes, &layout.groups[g]).is_some(),
                "type {g} from a father"
            );
            from_others += 1;
        }
    }
    assert!(
        from_others > 300,
        "only {from_others} of 500 took another father's type"
    );
}

/// Annexe 1, crossover: each type of the son takes "les moyennes des valeurs des paramètres
/// homologues de tous les pères": with fathers holding only a or b, a child's value times
/// the number of fathers m is k·a + (m−k)·b for an integer k (a geometric mean is not).
#[test]
fn crossover_child_is_the_mean_of_its_fathers_values() {
    let problem = truss();
    let layout = Layout::new(&problem);
    let mut pop = population(&problem, 6, 0.0);
    let two = |k: usize| {
        let u = &problem.space.unknowns[k];
        (u.min + 0.1 * (u.max - u.min), u.max - 0.1 * (u.max - u.min))
    };
    for (j, ind) in pop.iter_mut().enumerate() {
        for k in 0..problem.dim() {
            let (a, b) = two(k);
            ind.genes[k] =
                problem.space.unknowns[k].to_internal(if (j + k) % 2 == 0 { a } else { b });
        }
    }
    evaluate(&problem, &mut pop);
    let logs = problem.space.unknowns.iter().filter(|u| u.log).count();
    assert!(logs > 0, "a log parameter is tested");
    for c in children(
        &problem,
        &pop,
        &ThesisConfig::thesis(),
        Op::Crossover,
        5,
        100,
    ) {
        for (g, ks) in layout.groups.iter().enumerate() {
            let m = layout.group_particles[g].len() as f64;
            for &k in ks {
                let (a, b) = two(k);
                let v = problem.space.unknowns[k].from_internal(c.genes[k]);
                let fathers_at_a = m * (b - v) / (b - a);
                assert!(
                    (fathers_at_a - fathers_at_a.round()).abs() < 1e-6 * m,
                    "{}: {v} is no arithmetic mean of {m} values in {{{a}, {b}}}",
                    problem.space.unknowns[k].name
                );
            }
        }
    }
}

/// §3.2's uniform n-parent crossover: all parameters of a type from one father; m·n-parent:
/// each parameter from its own father (so some types mix fathers).
#[test]
fn n_parent_crossovers_take_whole_types_or_single_genes() {
    let problem = truss();
    let layout = Layout::new(&problem);
    let pop = population(&problem, 6, 0.0);
    let mut mixed = 0;
    for (kind, draws) in [(Crossover::NParent, 200), (Crossover::MnParent, 200)] {
        let c = ThesisConfig {
            crossover: kind,
            ..ThesisConfig::thesis()
        };
        for child in children(&problem, &pop, &c, Op::Crossover, 5, draws) {
            for ks in &layout.groups {
                for &k in ks {
                    assert!(
                        whose(&pop, &child.genes, &[k]).is_some(),
                        "gene {k} from a father"
                    );
                }
                let whole = whose(&pop, &child.genes, ks).is_some();
                match kind {
                    Crossover::NParent => assert!(whole, "type {ks:?} from one father"),
                    _ => mixed += usize::from(!whole),
                }
            }
        }
    }
    assert!(mixed > 0, "m·n-parent never mixed fathers within a type");
}

/// One generation: the protected best 5 % are still there unchanged; décadence: every
/// unchanged individual's mutabilities shrink by `reducer`.
#[test]
fn a_generation_keeps_the_elite_and_decays_unchanged_mutabilities() {
    let problem = truss();
    let c = ThesisConfig {
        population: 40,
        pcross: 30.0,
        pmut: 5.0,
        ..ThesisConfig::thesis()
    };
    let mut s = Thesis::new(c);
    s.init(&problem, 2);
    let pop = |s: &Thesis| -> Vec<Individual> {
        serde_json::from_value(s.save_state()["population"].clone()).expect("population")
    };
    let before = pop(&s);
    s.next_generation(&problem, 2, 1);
    let after = pop(&s);
    let all: Vec<usize> = (0..problem.dim()).collect();
    for elite in &before[..2] {
        assert!(
            whose(&after, &elite.genes, &all).is_some(),
            "an elite individual was replaced"
        );
    }
    let mut unchanged = 0;
    for old in &before {
        if let Some(j) = whose(&after, &old.genes, &all) {
            unchanged += 1;
            for (a, b) in after[j].sigma.iter().zip(&old.sigma) {
                assert_eq!(*a, b * 0.99);
            }
        }
    }
    assert!((20..40).contains(&unchanged), "{unchanged} of 40 unchanged");
    assert!(after.windows(2).all(|w| w[0].cost <= w[1].cost));
    assert!(after[0].cost <= before[0].cost);
}
