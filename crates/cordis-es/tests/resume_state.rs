//! Every strategy checks the state it loads: a checkpoint's state that does not fit the
//! problem (another particle count, a vector cut short) is refused, not run until it indexes
//! out of bounds generations later.

use cordis_core::examples;
use cordis_es::cost::CostKind;
use cordis_es::identify::{make_strategy, with_unknown_boxes, StrategyName, StrategyOptions};
use cordis_es::problem::Problem;
use serde_json::Value;

fn rigid_problem(frames: usize) -> Problem {
    let truth = examples::rigid();
    let traj = truth.simulate(frames).unwrap();
    Problem::new(&with_unknown_boxes(&truth, 25.0, 1), &traj, CostKind::Short).unwrap()
}

/// The first array of numbers found in `v`, cut by one element.
fn cut_first_vector(v: &mut Value) -> bool {
    match v {
        Value::Array(a) if a.len() > 1 && a.iter().all(Value::is_number) => {
            a.pop();
            true
        }
        Value::Array(a) => a.iter_mut().any(cut_first_vector),
        Value::Object(m) => m.values_mut().any(cut_first_vector),
        _ => false,
    }
}

#[test]
fn a_state_cut_short_is_refused_by_every_strategy() {
    let problem = rigid_problem(40);
    let options = StrategyOptions {
        population: 8,
        ..StrategyOptions::default()
    };
    for name in [
        StrategyName::Thesis,
        StrategyName::Cmaes,
        StrategyName::SelfAdaptive,
        StrategyName::Annealing,
        StrategyName::Parisian,
        StrategyName::LevenbergMarquardt,
        StrategyName::LeastSquares,
    ] {
        let (mut s, ran) = make_strategy(name, &problem, &options);
        s.init(&problem, 3);
        s.next_generation(&problem, 3, 1);
        let good = s.save_state();
        let (mut fresh, _) = make_strategy(name, &problem, &options);
        fresh
            .load_state(&problem, &good)
            .unwrap_or_else(|e| panic!("{ran}: {e}"));
        let mut bad = good.clone();
        assert!(cut_first_vector(&mut bad), "{ran}: no vector in its state");
        let (mut other, _) = make_strategy(name, &problem, &options);
        let err = other
            .load_state(&problem, &bad)
            .expect_err(&format!("{ran}: accepted a state with a vector cut short"));
        // A typed refusal of the state, not a bare string.
        assert!(
            matches!(err, cordis_es::CostError::State { .. }),
            "{ran}: {err:?}"
        );
    }
}

#[test]
fn a_state_that_is_not_json_of_the_strategy_keeps_the_json_error_as_its_source() {
    let problem = rigid_problem(40);
    let options = StrategyOptions {
        population: 8,
        ..StrategyOptions::default()
    };
    let (mut s, _) = make_strategy(StrategyName::Thesis, &problem, &options);
    let err = s
        .load_state(&problem, &serde_json::json!({"population": "many"}))
        .expect_err("a string for the population");
    let source = std::error::Error::source(&err).expect("the JSON error as source");
    assert!(source.is::<serde_json::Error>(), "{source:?}");
    assert_eq!(err.to_string(), source.to_string());
}
