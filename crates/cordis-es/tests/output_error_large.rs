//! The matrix-free output-error path on a scene too wide for the dense normal equations: a
//! 10 × 10 cloth (P = 18 + 6·90 = 558 fit variables) without its Provot limit (the tangent has
//! none through it). The 32 × 32 benchmark is `examples/oe_cloth.rs`.

use cordis_core::examples::cloth;
use cordis_es::cost::CostKind;
use cordis_es::identify::{add_noise, with_unknown_boxes};
use cordis_es::output_error::{estimate, expected_error_pct, Config, Take};
use cordis_es::problem::Problem;
use cordis_es::space::ParameterSpace;
use cordis_es::strategies::least_squares;

#[test]
fn a_cloth_beyond_the_dense_threshold_is_fitted_matrix_free_far_below_the_short_cost() {
    let mut truth = cloth(10, 10);
    for t in &mut truth.types {
        t.set_optional(cordis_core::OptionalParam::MaxElongation, None);
    }
    let traj = truth.simulate(60).unwrap();
    let sigma = 1e-3 * traj.scale();
    let noisy = add_noise(&traj, sigma, 4);
    let guess = with_unknown_boxes(&truth, 25.0, 4);
    let space = ParameterSpace::from_scene(&guess);
    let tv = truth.param_values();
    let e = estimate(
        &guess,
        &space,
        &[Take::complete(&noisy)],
        &Config::default(),
    )
    .unwrap();
    assert!(e.start.contains("matrix-free"), "{}", e.start);
    assert!(e.variables > 500);
    let err = space.error_pct(&e.genome, &tv);
    let short = Problem::new(&guess, &noisy, CostKind::Short).unwrap();
    let short_err = space.error_pct(&least_squares::solve(&short).unwrap().genome, &tv);
    assert!(
        err * 3.0 < short_err,
        "output-error {err} %, short cost {short_err} %"
    );
    // σ̂ reads the noise, and the error is what the standard errors predict (within 3×):
    // the standard errors are the θ block of H⁻¹, not a made-up number.
    assert!(
        (e.sigma / sigma - 1.0).abs() < 0.05,
        "σ̂/σ = {}",
        e.sigma / sigma
    );
    let values: Vec<f64> = space.unknowns.iter().map(|u| tv[u.slot]).collect();
    assert!(
        e.stderr.iter().all(|s| s.is_finite() && *s > 0.0),
        "{:?}",
        e.stderr
    );
    let predicted = expected_error_pct(&e.stderr, &values);
    assert!(
        err < 3.0 * predicted,
        "error {err} %, predicted {predicted} %"
    );
}
