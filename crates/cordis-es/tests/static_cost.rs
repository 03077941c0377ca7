//! The static cost (`--cost static`): parameters of the forces at rest identified from
//! equilibrium frames alone (thesis §4.2: the cloth from "une seule image correspondant à
//! l'état de l'équilibre"), and the unknowns it refuses by name.

mod common;

use cordis_core::{Bounds, LinkKind, Param, Scene, Trajectory};
use cordis_es::cost::{CostKind, Objective};
use cordis_es::identify::{
    check_strategy, make_strategy, with_unknown_boxes, StrategyName, StrategyOptions,
};
use cordis_es::problem::Problem;
use cordis_es::run::executor::{self, RunConfig, StopReason, StopRules};
use cordis_es::strategies::levenberg_marquardt::{LevenbergMarquardt, LmConfig};

/// The 5×5 hanging cloth of the common scenes (no Provot limit) with a stronger air drag
/// (0.05 N·s/m), so that it settles: its pose after 50 s (10,000 steps), as one frame.
fn sagging_cloth() -> (Scene, Trajectory) {
    settled_cloth(false)
}

/// [`sagging_cloth`], with Provot's limit (τc 0.1) on the structural springs when `provot`.
fn settled_cloth(provot: bool) -> (Scene, Trajectory) {
    let mut truth = common::cloth(5, 5, provot);
    let air = truth.types.iter().position(|t| t.name == "air").unwrap();
    truth.types[air].params[0] = Param::Known(0.05);
    let run = truth.simulate(10_000).expect("the cloth simulates");
    let n = 3 * truth.num_particles();
    let flat = run.as_flat();
    let pose = flat[flat.len() - n..].to_vec();
    let traj = Trajectory::from_flat(1, truth.num_particles(), pose).unwrap();
    (truth, traj)
}

/// K and l0 of the three spring types unknown in boxes 25× wide; dampings, drag and masses
/// known.
fn unknown_stiffness(truth: &Scene) -> Scene {
    let mut unknown = with_unknown_boxes(truth, 25.0, 0);
    for (t, tt) in unknown.types.iter_mut().zip(&truth.types) {
        for (k, p) in t.params.iter_mut().enumerate() {
            if !matches!(tt.param_name(k).as_str(), "stiffness" | "rest_length") {
                *p = tt.params[k];
            }
        }
    }
    unknown
}

#[test]
fn a_sagging_cloth_is_identified_from_one_equilibrium_frame() {
    let (truth, pose) = sagging_cloth();
    let unknown = unknown_stiffness(&truth);
    let mut problem = Problem::new(&unknown, &pose, CostKind::Static)
        .expect("problem")
        .with_truth(&truth)
        .expect("truth");
    assert_eq!(problem.dim(), 6);
    // `auto` takes levenberg-marquardt: the exact solvers minimise the short cost only.
    let (_, ran) = make_strategy(StrategyName::Auto, &problem, &StrategyOptions::default());
    assert_eq!(ran, "levenberg-marquardt");
    let e = check_strategy("least-squares", &problem).unwrap_err();
    assert!(e.contains("`static`"), "{e}");
    assert!(check_strategy("output-error", &problem).is_err());
    problem.set_evals(0);
    let config = RunConfig {
        stop: StopRules {
            generations: Some(2000),
            ..StopRules::default()
        },
        ..RunConfig::default()
    };
    let mut lm = LevenbergMarquardt::new(LmConfig::default());
    let r = executor::run(&mut problem, &mut lm, &config, &mut [], None).expect("run");
    let err = r.param_error_pct.expect("truth known");
    eprintln!(
        "static cloth: error {err:.3e} %, cost {:.3e}, {} evals, {:?}",
        r.cost, r.evals, r.stopped_by
    );
    assert_eq!(r.stopped_by, StopReason::Converged);
    assert!(err < 1e-6, "mean parameter error {err} %");
}

#[test]
fn the_static_cost_is_zero_at_rest_only() {
    let (truth, pose) = sagging_cloth();
    let obj = Objective::new(&truth, &pose, CostKind::Static).unwrap();
    let p = truth.param_values();
    let at_truth = obj.report(&p).unwrap().total;
    assert!(at_truth < 1e-28, "{at_truth:e}");
    // Each stiffness and rest length off by 0.1 % unbalances the pose.
    for k in [0, 1, 3, 4, 6, 7] {
        let mut q = p.clone();
        q[k] *= 1.001;
        let c = obj.report(&q).unwrap().total;
        assert!(c > 1e4 * at_truth.max(1e-30), "slot {k}: {c:e}");
    }
    // The same pose taken as a motion (three frames of it) is a cloth held still: the
    // short cost agrees.
    let held: Vec<f64> = [pose.as_flat(), pose.as_flat(), pose.as_flat()].concat();
    let held = Trajectory::from_flat(3, truth.num_particles(), held).unwrap();
    let mut short = Objective::new(&truth, &held, CostKind::Short).unwrap();
    short.set_linear(false);
    let mut q = p.clone();
    q[0] *= 1.1;
    assert_eq!(
        short.report(&q).unwrap().total.to_bits(),
        obj.report(&q).unwrap().total.to_bits()
    );
}

fn unknown_at(scene: &mut Scene, ty: &str, name: &str) {
    let t = scene.types.iter().position(|t| t.name == ty).unwrap();
    let k = scene.types[t].kind.param_index(name).unwrap();
    scene.types[t].params[k] = Param::Unknown(Bounds {
        min: 1e-3,
        max: 1e3,
        init: None,
    });
}

fn refusal(scene: &Scene, pose: &Trajectory) -> String {
    match Problem::new(scene, pose, CostKind::Static) {
        Ok(_) => panic!("accepted"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn the_static_cost_refuses_what_a_pose_at_rest_cannot_determine() {
    let (truth, pose) = sagging_cloth();
    // A damping: no force at rest.
    let mut s = unknown_stiffness(&truth);
    unknown_at(&mut s, "shear", "damping");
    let e = refusal(&s, &pose);
    assert!(
        e.starts_with("types.shear.damping:") && e.contains("zero velocity"),
        "{e}"
    );
    let mut s = unknown_stiffness(&truth);
    unknown_at(&mut s, "air", "damping");
    assert!(refusal(&s, &pose).starts_with("types.air.damping:"));
    // Masses beside stiffnesses: only K/m.
    let mut s = unknown_stiffness(&truth);
    s.particles[7].mass = Param::Unknown(Bounds {
        min: 1e-3,
        max: 1.0,
        init: None,
    });
    let e = refusal(&s, &pose);
    assert!(
        e.starts_with("particles[7].mass:") && e.contains("types.structural.stiffness"),
        "{e}"
    );
    assert!(e.contains("K/m"), "{e}");
    // Masses alone, stiffnesses known: weighing by balance works.
    let mut s = truth.clone();
    s.particles[7].mass = Param::Unknown(Bounds {
        min: 1e-3,
        max: 1.0,
        init: None,
    });
    assert!(Problem::new(&s, &pose, CostKind::Static).is_ok());
    // Without gravity: masses never enter, and stiffnesses have no scale.
    let mut s = s.clone();
    s.gravity = [0.0; 3];
    assert!(refusal(&s, &pose).starts_with("particles[7].mass:"));
    let mut s = unknown_stiffness(&truth);
    s.gravity = [0.0; 3];
    let e = refusal(&s, &pose);
    assert!(e.contains("common factor"), "{e}");
    // One stiffness known sets the scale.
    let st = s.types.iter().position(|t| t.name == "bend").unwrap();
    s.types[st].params[0] = truth.types[st].params[0];
    assert_eq!(s.types[st].kind, LinkKind::Spring);
    assert!(Problem::new(&s, &pose, CostKind::Static).is_ok());
}

#[test]
fn a_provot_cloth_at_rest_is_a_fixed_point_of_its_limit() {
    // At rest, the structural springs the limit holds carry a reaction the forces do not
    // balance: the static residual includes Provot's pass, as a simulator step does.
    let (truth, pose) = settled_cloth(true);
    let obj = Objective::new(&truth, &pose, CostKind::Static).unwrap();
    let at_truth = obj.report(&truth.param_values()).unwrap().total;
    let mut free = truth.clone();
    free.types[0].set_optional(cordis_core::OptionalParam::MaxElongation, None);
    let unlimited = Objective::new(&free, &pose, CostKind::Static).unwrap();
    let without = unlimited.report(&free.param_values()).unwrap().total;
    eprintln!(
        "Provot cloth at rest: static cost {at_truth:.3e} with its limit, {without:.3e} without"
    );
    assert!(at_truth < 1e-26, "{at_truth:e}");
    assert!(
        without > 1e6 * at_truth.max(1e-30),
        "the limit is active: {without:e}"
    );
}
