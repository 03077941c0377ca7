//! The cost functions agree with an independent naive implementation of SPEC §3
//! (`common::naive_cost`) on every passive link kind, every cost kind, exact and noisy data.

mod common;

use common::{cloth, fluid, muscles, naive_cost, noisy, perturbed, zoo, Naive};
use cordis_core::Scene;
use cordis_es::cost::{CostKind, Objective};

/// `a ≈ b` to 1e-9 relative, or both below an absolute floor of rounding size: near a cost of
/// 0 (exact data at the truth) both sides are rounding noise and only their smallness matters.
fn close(a: f64, b: f64, floor: f64) -> bool {
    (a - b).abs() <= 1e-9 * a.abs().max(b.abs()) || (a.abs() <= floor && b.abs() <= floor)
}

fn check(scene: &Scene, frames: usize, sigma: f64, kinds: &[(CostKind, Naive)], generation: usize) {
    let exact = scene.simulate(frames).unwrap();
    let data = if sigma > 0.0 {
        noisy(scene, &exact, sigma, 7)
    } else {
        exact
    };
    for (ki, &(kind, naive)) in kinds.iter().enumerate() {
        let mut obj = Objective::new(scene, &data, kind).unwrap();
        obj.set_generation(generation);
        obj.set_linear(false);
        for (pi, p) in [scene.param_values(), perturbed(scene, 0.2, 11 + ki as u64)]
            .iter()
            .enumerate()
        {
            let rep = obj.report(p).unwrap();
            let (total, per) = naive_cost(scene, &data, p, naive);
            // Exact data at the truth: both sides are rounding, (1e-13 m)² per term at most.
            let floor = 1e-26 * rep.terms as f64;
            assert!(
                close(rep.total, total, floor),
                "{kind} params#{pi} σ={sigma}: total {} vs naive {total}",
                rep.total
            );
            assert!(rep.total.is_finite() && rep.total >= 0.0);
            if pi == 1 {
                assert!(
                    rep.total > floor,
                    "{kind}: a perturbed model must cost something"
                );
            }
            for (i, (a, b)) in rep.per_particle.iter().zip(&per).enumerate() {
                assert!(
                    close(*a, *b, floor),
                    "{kind} params#{pi} σ={sigma}: particle {i}: {a} vs naive {b}"
                );
            }
        }
    }
}

fn all_kinds(frames: usize, g_full: usize, generation: usize) -> Vec<(CostKind, Naive)> {
    let full = frames - 2;
    let h_prog = 1 + (full - 1) * generation.min(g_full) / g_full;
    vec![
        (CostKind::Short, Naive::Windows(1)),
        (CostKind::Horizon(3), Naive::Windows(3)),
        (CostKind::Horizon(1000), Naive::Windows(full)),
        (CostKind::Long, Naive::Long),
        (
            CostKind::Progressive {
                start: 1,
                generations_to_full: g_full,
            },
            Naive::Windows(h_prog),
        ),
        (CostKind::Harmonic { eps: 1e-10 }, Naive::Harmonic(1e-10)),
    ]
}

#[test]
fn cloth_with_gravity_drag_and_damped_springs() {
    let s = cloth(5, 4, false);
    check(&s, 24, 0.0, &all_kinds(24, 10, 4), 4);
    check(&s, 24, 1e-4, &all_kinds(24, 10, 4), 4);
}

#[test]
fn cloth_with_provot_limit() {
    let s = cloth(5, 4, true);
    // The limit must actually act, or the test would not test it.
    let traj = s.simulate(24).unwrap();
    let stretched = s.links.iter().filter(|l| l.type_index == 0).any(|l| {
        (1..24).any(|t| (traj.pos(t, l.particles[1]) - traj.pos(t, l.particles[0])).norm() > 0.1099)
    });
    assert!(stretched, "the Provot limit never binds in this scene");
    check(&s, 24, 0.0, &all_kinds(24, 10, 7), 7);
    check(&s, 24, 1e-4, &all_kinds(24, 10, 7), 7);
}

#[test]
fn springs_dampers_anchors_drags_angles_nonlinear_drag() {
    for nonlinear in [false, true] {
        let s = zoo(nonlinear);
        check(&s, 30, 0.0, &all_kinds(30, 20, 25), 25);
        check(&s, 30, 1e-5, &all_kinds(30, 20, 3), 3);
    }
}

#[test]
fn muscles_with_neurons_spring_and_drag() {
    let s = muscles();
    check(&s, 30, 0.0, &all_kinds(30, 20, 25), 25);
    check(&s, 30, 1e-5, &all_kinds(30, 20, 3), 3);
    // The linear precomputation refuses muscles: the neuron's tanh is nonlinear.
    let traj = s.simulate(30).unwrap();
    let obj = Objective::new(&s, &traj, CostKind::Short).unwrap();
    assert!(obj.linear().is_none());
}

#[test]
fn conditional_links_with_known_and_unknown_range() {
    for unknown in [false, true] {
        let s = fluid(unknown);
        check(&s, 20, 0.0, &all_kinds(20, 5, 2), 2);
        check(&s, 20, 1e-5, &all_kinds(20, 5, 2), 2);
    }
}

#[test]
fn conditional_pairs_change_along_the_trajectory() {
    // Guards the fluid test: pairs must appear and vanish, or the precomputed pairs per frame
    // would not be exercised.
    let s = fluid(false);
    let traj = s.simulate(20).unwrap();
    let count = |t: usize| {
        let mut c = 0;
        for i in 0..20 {
            for j in i + 1..20 {
                c += usize::from((traj.pos(t, i) - traj.pos(t, j)).norm() < 0.09);
            }
        }
        c
    };
    let counts: Vec<usize> = (0..20).map(count).collect();
    assert!(counts.iter().any(|&c| c > 0));
    assert!(counts.windows(2).any(|w| w[0] != w[1]), "{counts:?}");
}

#[test]
fn short_cost_of_the_generating_parameters_is_exactly_zero() {
    // One simulator step from the real frames reproduces the simulated frame bit for bit.
    for s in [cloth(4, 4, true), zoo(true), fluid(false), fluid(true)] {
        let traj = s.simulate(15).unwrap();
        let mut obj = Objective::new(&s, &traj, CostKind::Short).unwrap();
        obj.set_linear(false);
        // With and without the precomputed geometry of springs and conditional pairs.
        for budget in [cordis_es::cost::GEOMETRY_BUDGET_BYTES, 0] {
            obj.set_geometry_budget(budget);
            let rep = obj.report(&s.param_values()).unwrap();
            assert_eq!(rep.total, 0.0);
            assert!(rep.per_particle.iter().all(|&c| c == 0.0));
        }
    }
}

#[test]
fn precomputed_geometry_changes_nothing_but_speed() {
    for s in [cloth(5, 4, true), fluid(false), zoo(false)] {
        let data = common::noisy(&s, &s.simulate(20).unwrap(), 1e-4, 2);
        let mut obj = Objective::new(&s, &data, CostKind::Short).unwrap();
        obj.set_linear(false);
        let p = perturbed(&s, 0.3, 8);
        let with = obj.report(&p).unwrap();
        obj.set_geometry_budget(0);
        let without = obj.report(&p).unwrap();
        assert!(with.total > 0.0);
        assert_eq!(with, without);
    }
}
