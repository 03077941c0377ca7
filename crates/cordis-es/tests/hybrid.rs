//! `hybrid`: variable projection finds the nonlinear parameters (a nonlinear drag's v_max, a
//! conditional link's range) to the data's resolution and the linear ones exactly.

use std::time::Instant;

use cordis_core::{LinkKind, LinkType, Particle, Scene};
use cordis_es::cost::CostKind;
use cordis_es::identify::{make_strategy, with_unknown_boxes, StrategyName};
use cordis_es::problem::Problem;
use cordis_es::space::Role;
use cordis_es::strategies::hybrid;

/// Three masses on two springs in a two-regime medium; launched fast, they oscillate and slow
/// down, so their speeds cross v_max both ways many times.
fn tadpole_medium() -> Scene {
    let mut s = Scene::new(0.005);
    s.add_particle(Particle::new(1.0, [0.0, 0.0, 0.0]).with_vel([2.0, 0.0, 0.0]));
    s.add_particle(Particle::new(0.5, [1.0, 0.0, 0.0]).with_vel([0.0, 1.5, 0.0]));
    s.add_particle(Particle::new(0.8, [1.5, 0.8, 0.0]).with_vel([-1.0, 0.0, 1.0]));
    s.add_type(
        LinkType::new("body", LinkKind::Spring)
            .with("stiffness", 50.0)
            .with("rest_length", 0.9),
    );
    s.add_type(
        LinkType::new("medium", LinkKind::NonlinearDrag)
            .with("z1", 0.8)
            .with("z2", 0.3)
            .with("v_max", 0.9),
    );
    s.add_link("body", &[0, 1]);
    s.add_link("body", &[1, 2]);
    for i in 0..3 {
        s.add_link("medium", &[i]);
    }
    s
}

/// Eight particles of one group held loosely around a centre by anchors: pairs come in and out
/// of the conditional range all the time.
fn gas() -> Scene {
    let mut s = Scene::new(0.005);
    let pts = [
        [0.0, 0.0, 0.0],
        [0.4, 0.1, 0.0],
        [-0.3, 0.35, 0.1],
        [0.1, -0.4, -0.1],
        [0.5, 0.5, 0.2],
        [-0.45, -0.2, 0.3],
        [0.2, 0.3, -0.4],
        [-0.1, -0.1, 0.5],
    ];
    for (n, p) in pts.iter().enumerate() {
        let a = n as f64;
        s.add_particle(
            Particle::new(0.5 + 0.1 * a, *p)
                .with_vel([(1.3 * a).sin(), (0.7 * a).cos(), (2.1 * a).sin() * 0.5])
                .in_group("gas"),
        );
    }
    let mut pair = LinkType::new("pair", LinkKind::Conditional)
        .with("stiffness", 40.0)
        .with("rest_length", 0.3)
        .with("range", 0.45);
    pair.groups = vec!["gas".into()];
    s.add_type(pair);
    let mut hold = LinkType::new("hold", LinkKind::Anchor).with("stiffness", 6.0);
    hold.point = Some([0.0, 0.0, 0.0]);
    s.add_type(hold);
    for i in 0..pts.len() {
        s.add_link("hold", &[i]);
    }
    s
}

/// Per unknown: relative error (%) against the truth.
fn errors(problem: &Problem, genome: &[f64], truth: &Scene) -> Vec<(String, Role, f64)> {
    let t = truth.param_values();
    problem
        .space
        .unknowns
        .iter()
        .zip(problem.space.values(genome))
        .map(|(u, v)| {
            (
                u.name.clone(),
                u.role,
                100.0 * ((v - t[u.slot]) / t[u.slot]).abs(),
            )
        })
        .collect()
}

fn check(name: &str, truth: Scene, frames: usize, seed: u64) {
    check_with(name, truth, frames, seed, false)
}

fn check_with(name: &str, truth: Scene, frames: usize, seed: u64, free_masses: bool) {
    truth.validate().unwrap();
    let mut unknown = with_unknown_boxes(&truth, 25.0, seed);
    if free_masses {
        for p in &mut unknown.particles {
            let m = p.mass.value();
            p.mass = cordis_core::Param::Unknown(cordis_core::Bounds {
                min: m / 5.0,
                max: m * 4.0,
                init: None,
            });
        }
    }
    let traj = truth.simulate(frames).unwrap();
    let start = Instant::now();
    let mut problem = Problem::new(&unknown, &traj, CostKind::Short)
        .unwrap()
        .with_truth(&truth)
        .unwrap();
    if free_masses {
        let total = truth.particles.iter().map(|p| p.mass.value()).sum();
        problem = problem.with_total_mass(total).unwrap();
    }
    assert_eq!(
        make_strategy(
            StrategyName::Auto,
            &problem,
            &cordis_es::identify::StrategyOptions::default(),
        )
        .1,
        "hybrid"
    );
    let sol = hybrid::solve(&problem).unwrap();
    let seconds = start.elapsed().as_secs_f64();
    let errs = errors(&problem, &sol.genome, &truth);
    eprintln!(
        "{name}: {seconds:.3} s, {} evaluations, condition {:.2e}",
        problem.evals(),
        sol.report.condition
    );
    for n in &sol.report.notes {
        eprintln!("  {n}");
    }
    for (n, role, e) in &errs {
        eprintln!("  {n:<28} {e:.3e} %");
        // The nonlinear ones to the data's resolution, the linear ones to rounding.
        let bound = if matches!(role, Role::Range | Role::Speed) {
            1.0
        } else {
            1e-6
        };
        assert!(*e < bound, "{name}: {n} off by {e} %");
    }
    assert!(errs
        .iter()
        .any(|(_, r, _)| matches!(r, Role::Range | Role::Speed)));
    assert!(sol.report.error.is_none() && sol.report.undetermined.is_empty());
    if !cfg!(debug_assertions) {
        assert!(seconds < 20.0, "{name}: {seconds} s");
    }
}

#[test]
fn nonlinear_drag_v_max_z1_z2_to_one_percent() {
    check("nonlinear drag", tadpole_medium(), 400, 3);
}

#[test]
fn conditional_range_to_one_percent() {
    check("conditional", gas(), 400, 5);
}

#[test]
fn two_nonlinear_unknowns_at_once() {
    // The gas in the two-regime medium: a range and a v_max searched together.
    let mut s = gas();
    s.add_type(
        LinkType::new("medium", LinkKind::NonlinearDrag)
            .with("z1", 0.4)
            .with("z2", 0.15)
            .with("v_max", 0.7),
    );
    for i in 0..s.particles.len() {
        s.add_link("medium", &[i]);
    }
    check("conditional + nonlinear drag", s, 400, 7);
}

#[test]
fn free_masses_with_a_nonlinear_drag() {
    check_with(
        "nonlinear drag, free masses",
        tadpole_medium(),
        400,
        3,
        true,
    );
}
