//! `least-squares` on noiseless linear scenes: the generating parameters to rounding, fast;
//! free masses under a known total; undetermined unknowns named; noise degrades gracefully.

mod common;

use common::free_total;
use std::time::Instant;

use cordis_core::examples::{cloth, horse, muscle, random_network, rigid};
use cordis_core::{Bounds, Param, Scene};
use cordis_es::cost::CostKind;
use cordis_es::executor::{self, RunConfig, StopRules};
use cordis_es::identify::{
    add_noise, make_strategy, with_unknown_boxes, StrategyName, StrategyOptions,
};
use cordis_es::problem::Problem;
use cordis_es::strategies::least_squares;
use cordis_es::strategy::Strategy;

/// Mean error (%) and seconds of the whole process (objective construction + solve).
fn identify(
    truth: &Scene,
    unknown: &Scene,
    frames: usize,
    total: Option<f64>,
) -> (f64, f64, least_squares_report::R) {
    let traj = truth.simulate(frames).unwrap();
    let start = Instant::now();
    let mut problem = Problem::new(unknown, &traj, CostKind::Short)
        .unwrap()
        .with_truth(truth)
        .unwrap();
    if let Some(m) = total {
        problem = problem.with_total_mass(m).unwrap();
    }
    let built = start.elapsed().as_secs_f64();
    let sol = least_squares::solve(&problem).unwrap();
    let seconds = start.elapsed().as_secs_f64();
    eprintln!("  (objective {built:.3} s, solve {:.3} s)", seconds - built);
    let err = problem.error_pct(&sol.genome).unwrap();
    (err, seconds, sol.report)
}

mod least_squares_report {
    pub type R = cordis_es::strategies::exact::ExactReport;
}

/// The Provot limit makes the short cost nonlinear in l0: the linear cloth is the same mesh
/// without it.
fn linear_cloth(nx: usize, ny: usize) -> Scene {
    let mut s = cloth(nx, ny);
    for t in &mut s.types {
        t.set_optional(cordis_core::OptionalParam::MaxElongation, None);
    }
    s
}

/// Time bounds only where the code is optimised.
fn assert_fast(name: &str, seconds: f64, bound: f64) {
    if !cfg!(debug_assertions) {
        assert!(seconds < bound, "{name}: {seconds:.3} s");
    }
}

#[test]
fn noiseless_examples_are_identified_to_rounding() {
    let scenes: Vec<(&str, Scene, usize)> = vec![
        ("rigid", rigid(), 100),
        ("cloth 12x12", linear_cloth(12, 12), 400),
        ("horse", horse(), 53),
    ];
    for (name, truth, frames) in scenes {
        let unknown = with_unknown_boxes(&truth, 25.0, 11);
        let (err, seconds, report) = identify(&truth, &unknown, frames, None);
        eprintln!(
            "{name:<14} unknowns {:>3}  error {err:.3e} %  {seconds:.3} s  condition {:.2e}",
            Problem::new(&unknown, &truth.simulate(3).unwrap(), CostKind::Short)
                .unwrap()
                .dim(),
            report.condition
        );
        assert!(err < 1e-6, "{name}: {err} %");
        assert!(
            report.undetermined.is_empty() && report.clamped.is_empty(),
            "{name}: {report:?}"
        );
        assert!(report.error.is_none());
        assert_fast(name, seconds, 10.0);
    }
}

#[test]
fn noiseless_shipped_cloth_is_identified_to_rounding() {
    let truth = linear_cloth(32, 32);
    let unknown = with_unknown_boxes(&truth, 25.0, 5);
    let (err, seconds, report) = identify(&truth, &unknown, 400, None);
    eprintln!(
        "cloth 32x32    error {err:.3e} %  {seconds:.3} s  condition {:.2e}",
        report.condition
    );
    assert!(err < 1e-6, "{err} %");
    assert_fast("cloth 32x32", seconds, 10.0);
}

#[test]
fn noiseless_random_networks_are_identified_to_rounding() {
    for (seed, masses, types) in [(1, 10, 3), (2, 16, 5), (3, 24, 6), (4, 30, 8), (5, 20, 4)] {
        let truth = random_network(seed, masses, types);
        let unknown = with_unknown_boxes(&truth, 25.0, seed);
        let (err, seconds, report) = identify(&truth, &unknown, 300, None);
        eprintln!(
            "random {seed} ({masses} masses, {types} types)  error {err:.3e} %  {seconds:.3} s  condition {:.2e}",
            report.condition
        );
        assert!(err < 1e-6, "seed {seed}: {err} %");
        assert_fast("random", seconds, 10.0);
    }
}

/// Every mass unknown in a box 25× wide, like the link parameters.
fn with_unknown_masses(scene: &Scene) -> Scene {
    let mut s = scene.clone();
    for (i, p) in s.particles.iter_mut().enumerate() {
        let m = p.mass.value();
        let u = 0.2 + 0.6 * ((i * 37) % 11) as f64 / 10.0;
        p.mass = Param::Unknown(Bounds {
            min: m * (-u * 25f64.ln()).exp(),
            max: m * ((1.0 - u) * 25f64.ln()).exp(),
            init: None,
        });
    }
    s
}

#[test]
fn free_masses_under_a_known_total() {
    let scenes: Vec<(&str, Scene, usize)> = vec![
        ("rigid", rigid(), 100),
        ("random 7", random_network(7, 20, 5), 300),
        ("horse", horse(), 53),
    ];
    for (name, truth, frames) in scenes {
        let unknown = with_unknown_masses(&with_unknown_boxes(&truth, 25.0, 3));
        let traj = truth.simulate(frames).unwrap();
        let start = Instant::now();
        let problem = Problem::new(&unknown, &traj, CostKind::Short)
            .unwrap()
            .with_truth(&truth)
            .unwrap()
            .with_total_mass(free_total(&truth))
            .unwrap();
        eprintln!("  (objective {:.3} s)", start.elapsed().as_secs_f64());
        let sol = least_squares::solve(&problem).unwrap();
        let seconds = start.elapsed().as_secs_f64();
        let err = problem.error_pct(&sol.genome).unwrap();
        // The masses alone (fixed particles' masses enter no cost: reported undetermined).
        let truth_p = truth.param_values();
        let values = problem.space.values(&sol.genome);
        let mass_err: Vec<f64> = problem
            .space
            .unknowns
            .iter()
            .zip(&values)
            .filter(|(u, _)| u.role == cordis_es::space::Role::Mass)
            .filter(|(u, _)| !report_names_fixed(&truth, &u.name))
            .map(|(u, v)| 100.0 * ((v - truth_p[u.slot]) / truth_p[u.slot]).abs())
            .collect();
        let worst = mass_err.iter().cloned().fold(0.0, f64::max);
        eprintln!(
            "{name:<10} free masses: worst mass error {worst:.3e} %, mean error {err:.3e} %, {seconds:.3} s, condition {:.2e}",
            sol.report.condition
        );
        assert!(worst < 1e-6, "{name}: {worst} %");
        assert_fast(name, seconds, 10.0);
        for u in &problem.space.unknowns {
            let fixed = report_names_fixed(&truth, &u.name);
            assert_eq!(
                sol.report.undetermined.contains(&u.name),
                fixed,
                "{name}: {}",
                u.name
            );
        }
    }
}

fn report_names_fixed(scene: &Scene, name: &str) -> bool {
    scene
        .particles
        .iter()
        .enumerate()
        .any(|(i, p)| p.fixed && name == format!("particles[{i}].mass"))
}

#[test]
fn free_masses_without_a_total_is_an_error() {
    let truth = rigid();
    let unknown = with_unknown_masses(&with_unknown_boxes(&truth, 25.0, 3));
    let traj = truth.simulate(50).unwrap();
    let problem = Problem::new(&unknown, &traj, CostKind::Short).unwrap();
    let e = least_squares::solve(&problem).unwrap_err();
    assert!(e.contains("total mass"), "{e}");
    // As a strategy: the start point, with the error in the report.
    let mut s = least_squares::strategy();
    s.init(&problem, 0);
    assert!(s
        .report()
        .error
        .as_ref()
        .is_some_and(|m| m.contains("total mass")));
}

#[test]
fn a_never_stretched_type_is_reported_undetermined() {
    // Two extra particles falling side by side at the rest length of their own spring type:
    // the spring never works, so its stiffness and rest length are invisible.
    let truth = {
        let mut s = random_network(9, 12, 4);
        let a = s.add_particle(
            cordis_core::Particle::new(1.0, [5.0, 0.0, 0.0]).with_vel([0.3, 0.1, 0.0]),
        );
        let b = s.add_particle(
            cordis_core::Particle::new(1.0, [5.4, 0.0, 0.0]).with_vel([0.3, 0.1, 0.0]),
        );
        s.add_type(
            cordis_core::LinkType::new("idle", cordis_core::LinkKind::Spring)
                .with("stiffness", 80.0)
                .with("rest_length", 0.4),
        );
        s.add_link("idle", &[a, b]);
        s
    };
    let unknown = with_unknown_boxes(&truth, 25.0, 2);
    let traj = truth.simulate(200).unwrap();
    let problem = Problem::new(&unknown, &traj, CostKind::Short)
        .unwrap()
        .with_truth(&truth)
        .unwrap();
    let sol = least_squares::solve(&problem).unwrap();
    eprintln!("undetermined: {:?}", sol.report.undetermined);
    assert!(
        sol.report
            .undetermined
            .iter()
            .any(|n| n.starts_with("types.idle.")),
        "{:?}",
        sol.report
    );
    assert!(sol
        .report
        .warnings()
        .iter()
        .any(|w| w.contains("types.idle.")));
    // Every other unknown is still exact.
    let t = truth.param_values();
    for (u, v) in problem
        .space
        .unknowns
        .iter()
        .zip(problem.space.values(&sol.genome))
    {
        if !u.name.starts_with("types.idle.") {
            assert!(
                ((v - t[u.slot]) / t[u.slot]).abs() < 1e-8,
                "{}: {v} vs {}",
                u.name,
                t[u.slot]
            );
        } else {
            assert!(v >= u.min && v <= u.max);
        }
    }
}

#[test]
fn noise_degrades_the_answer_gracefully() {
    let truth = rigid();
    let unknown = with_unknown_boxes(&truth, 25.0, 4);
    let clean = truth.simulate(100).unwrap();
    let mut errors = Vec::new();
    for sigma in [1e-7, 1e-6, 1e-5] {
        let data = add_noise(&clean, sigma, 8);
        let problem = Problem::new(&unknown, &data, CostKind::Short)
            .unwrap()
            .with_truth(&truth)
            .unwrap();
        let sol = least_squares::solve(&problem).unwrap();
        let err = problem.error_pct(&sol.genome).unwrap();
        eprintln!(
            "rigid, noise {sigma:e} m: error {err:.3e} %, clamped {:?}",
            sol.report.clamped
        );
        // Never worse than the start point, and the cost is the problem's own.
        assert!(sol.cost.is_finite());
        errors.push(err);
    }
    assert!(errors[0] < 1.0, "{errors:?}");
    assert!(errors[0] < errors[2], "{errors:?}");
}

#[test]
fn auto_runs_least_squares_through_the_executor() {
    let truth = rigid();
    let unknown = with_unknown_boxes(&truth, 25.0, 1);
    let traj = truth.simulate(100).unwrap();
    let mut problem = Problem::new(&unknown, &traj, CostKind::Short)
        .unwrap()
        .with_truth(&truth)
        .unwrap();
    let (mut s, ran) = make_strategy(
        StrategyName::Auto,
        &problem,
        &StrategyOptions {
            population: 100,
            ..StrategyOptions::default()
        },
    );
    assert_eq!(ran, "least-squares");
    let config = RunConfig {
        stop: StopRules {
            generations: Some(2),
            ..StopRules::default()
        },
        ..RunConfig::default()
    };
    let r = executor::run(&mut problem, s.as_mut(), &config, &mut [], None).unwrap();
    assert_eq!(r.strategy, "least-squares");
    assert!(r.param_error_pct.unwrap() < 1e-6);
    assert!(s.report().as_exact().unwrap().condition >= 1.0);
    // The Provot cloth is solved exactly on the rows the limit leaves (provot_rows), a
    // muscle's neuron is not linear but smooth: auto takes levenberg-marquardt.
    for (c, expected) in [
        (cloth(5, 5), "least-squares"),
        (muscle(), "levenberg-marquardt"),
    ] {
        let p = Problem::new(
            &with_unknown_boxes(&c, 25.0, 1),
            &c.simulate(20).unwrap(),
            CostKind::Short,
        )
        .unwrap();
        assert_eq!(auto_pick(&p), expected);
    }
    // A long-term cost is not the short cost.
    let p = Problem::new(&unknown, &traj, CostKind::Long).unwrap();
    assert_eq!(auto_pick(&p), "t2m");
}

/// What `--strategy auto` runs on `p`.
fn auto_pick(p: &Problem) -> &'static str {
    let options = StrategyOptions {
        population: 10,
        ..StrategyOptions::default()
    };
    make_strategy(StrategyName::Auto, p, &options).1
}

#[test]
fn known_stiffness_or_known_rest_length_couplings() {
    // Alternate types: K known with l0 unknown (θ = K·l0 is free alone), K unknown with l0
    // known (K and K·l0 tied), both unknown.
    let truth = random_network(12, 20, 6);
    let mut unknown = with_unknown_boxes(&truth, 25.0, 6);
    for (t, ty) in unknown.types.iter_mut().enumerate() {
        let known = match t % 3 {
            0 => "stiffness",
            1 => "rest_length",
            _ => continue,
        };
        let k = ty.kind.param_index(known).unwrap();
        ty.params[k] = truth.types[t].params[k];
    }
    let (err, _, report) = identify(&truth, &unknown, 300, None);
    assert!(err < 1e-6, "{err} % {report:?}");
    // With every stiffness known, the scale comes from them: free masses need no total.
    let mut unknown = with_unknown_masses(&with_unknown_boxes(&truth, 25.0, 6));
    for (t, ty) in unknown.types.iter_mut().enumerate() {
        ty.params[0] = truth.types[t].params[0];
    }
    let traj = truth.simulate(300).unwrap();
    let problem = Problem::new(&unknown, &traj, CostKind::Short).unwrap();
    let sol = least_squares::solve(&problem).unwrap();
    let t = truth.param_values();
    for (u, v) in problem
        .space
        .unknowns
        .iter()
        .zip(problem.space.values(&sol.genome))
    {
        if !report_names_fixed(&truth, &u.name) {
            assert!(
                ((v - t[u.slot]) / t[u.slot]).abs() < 1e-8,
                "{}: {v} vs {}",
                u.name,
                t[u.slot]
            );
        }
    }
}
