//! `total_mass` (issue 19 item 7): the exact solvers put Σm = M into their solve; every other
//! strategy used to run as if it were not given. It is now refused by name for them, before
//! any work, and honoured by `least-squares` and `hybrid`.

use cordis_core::{examples, Bounds, Param, Scene, Trajectory};
use cordis_es::identify::{with_unknown_boxes, StrategyName};
use cordis_es::session::{Generations, IdentifyRequest, Session};

/// The rigid object with its ten types' parameters and every mass unknown.
fn rigid_with_masses() -> (Scene, Scene, Trajectory, f64) {
    let truth = examples::rigid();
    let traj = truth.simulate(40).expect("rigid simulates");
    let mut scene = with_unknown_boxes(&truth, 10.0, 3);
    for p in &mut scene.particles {
        p.mass = Param::Unknown(Bounds {
            min: 0.3,
            max: 3.0,
            init: None,
        });
    }
    let total = truth.particles.iter().map(|p| p.mass.value()).sum();
    (truth, scene, traj, total)
}

fn request(
    scene: &Scene,
    traj: &Trajectory,
    strategy: StrategyName,
    total: f64,
) -> IdentifyRequest {
    let mut req = IdentifyRequest::new(scene.clone(), traj.clone());
    req.strategy = strategy;
    req.total_mass = Some(total);
    req.generations = Generations::Limit(2);
    req
}

#[test]
fn strategies_that_ignore_the_total_mass_refuse_it_by_name() {
    let (_, scene, traj, total) = rigid_with_masses();
    for name in [
        StrategyName::Thesis,
        StrategyName::Cmaes,
        StrategyName::SelfAdaptive,
        StrategyName::Annealing,
        StrategyName::Parisian,
        StrategyName::LevenbergMarquardt,
        StrategyName::OutputError,
    ] {
        let e = Session::new(request(&scene, &traj, name, total))
            .err()
            .unwrap_or_else(|| panic!("{}: accepted a total mass it ignores", name.name()))
            .to_string();
        eprintln!("{e}");
        assert!(e.starts_with("--total-mass: "), "{e}");
        assert!(
            e.contains(&format!("`{}` would ignore it", name.name())),
            "{e}"
        );
        assert!(!e.contains('\n'), "{e}");
    }
}

#[test]
fn the_exact_solvers_honour_it() {
    let (truth, scene, traj, total) = rigid_with_masses();
    let mut req = request(&scene, &traj, StrategyName::LeastSquares, total);
    req.truth = Some(truth);
    let out = Session::new(req)
        .expect("least-squares takes it")
        .run(&mut [], None)
        .expect("runs");
    let sum: f64 = out.scene().particles.iter().map(|p| p.mass.value()).sum();
    assert!(
        (sum - total).abs() < 1e-9 * total,
        "Σm = {sum}, M = {total}"
    );
}
