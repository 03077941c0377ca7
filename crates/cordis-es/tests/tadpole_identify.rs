//! Thesis Table 6.1 beaten: from the first 100 frames of the tadpole (TGR + two-regime medium,
//! the tendon advanced along the observed frames by the cost), CMA-ES recovers z1, z2, v_max,
//! the stiffness and the rest length each within 1% (the thesis: v_max 8% off), from boxes 25
//! times wide placed at random around the truth.

use cordis_core::examples::{tadpole, tadpole_vmax_bracket};
use cordis_es::cost::CostKind;
use cordis_es::executor::{self, RunConfig, StopRules};
use cordis_es::identify::with_unknown_boxes;
use cordis_es::problem::Problem;
use cordis_es::strategies::cmaes::{Cmaes, CmaesConfig};

#[test]
fn cmaes_recovers_table_6_1_within_one_percent_from_100_frames() {
    let truth = tadpole();
    let traj = truth.simulate(100).unwrap();
    let (below, above) = tadpole_vmax_bracket(&traj, 0.5);
    let (below, above) = (below.unwrap(), above.unwrap());
    for seed in [0, 3] {
        let scene = with_unknown_boxes(&truth, 25.0, seed);
        let mut problem = Problem::new(&scene, &traj, CostKind::Short).unwrap();
        let names: Vec<_> = problem
            .space
            .unknowns
            .iter()
            .map(|u| u.name.clone())
            .collect();
        assert_eq!(
            names,
            [
                "types.water.z1",
                "types.water.z2",
                "types.water.v_max",
                "types.muscle.stiffness",
                "types.muscle.rest_length"
            ],
            "exactly Table 6.1's unknowns (the tendon stays known)"
        );
        let config = RunConfig {
            seed,
            stop: StopRules {
                max_evals: Some(20_000),
                ..StopRules::default()
            },
            ..RunConfig::default()
        };
        let mut s = Cmaes::new(CmaesConfig::default());
        let r = executor::run(&mut problem, &mut s, &config, &mut [], None).unwrap();
        let p = &r.params;
        let want = truth.param_values();
        for (u, name) in problem.space.unknowns.iter().zip(&names) {
            let (got, t) = (p[u.slot], want[u.slot]);
            let rel = (got - t).abs() / t;
            assert!(
                rel < 0.01,
                "seed {seed}: {name} = {got}, truth {t} ({:.3}%)",
                100.0 * rel
            );
            if name.ends_with("v_max") {
                // The data cannot say more than this bracket: the estimate lies in it.
                assert!(
                    got > below && got <= above,
                    "{got} outside ({below}, {above}]"
                );
            }
        }
    }
}
