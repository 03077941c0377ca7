//! Diverging candidates, bad input, cost-kind strings, batch evaluation.

mod common;

use common::{cloth, fluid, noisy, perturbed, zoo};
use cordis_core::Trajectory;
use cordis_es::cost::{CostKind, Objective};
use cordis_es::CostError;
use proptest::prelude::*;

const KINDS: [&str; 6] = [
    "short",
    "horizon:4",
    "long",
    "progressive:10",
    "harmonic",
    "harmonic:1e-8",
];

fn assert_inf_never_nan(obj: &Objective, p: &[f64], what: &str) {
    let rep = obj.report(p).unwrap();
    assert_eq!(rep.total, f64::INFINITY, "{what}: {}", rep.total);
    assert_eq!(rep.rmse, f64::INFINITY, "{what}");
    assert!(rep.per_particle.iter().all(|c| !c.is_nan()), "{what}");
    assert!(rep.per_particle.contains(&f64::INFINITY), "{what}");
    let mut s = obj.scratch();
    assert_eq!(obj.total(p, &mut s).unwrap(), f64::INFINITY, "{what}");
}

#[test]
fn diverging_candidates_cost_plus_infinity_never_nan() {
    let s = cloth(4, 4, false);
    let traj = s.simulate(30).unwrap();
    let layout = s.param_layout();
    for kind in KINDS {
        for linear in [true, false] {
            let mut obj = Objective::new(&s, &traj, kind.parse().unwrap()).unwrap();
            obj.set_linear(linear);
            obj.set_generation(6);
            let what = format!("{kind} linear={linear}");
            // Absurd stiffness: the short step overflows, rollouts run away.
            let mut p = s.param_values();
            p[layout.type_offsets[0]] = 1e300;
            assert_inf_never_nan(&obj, &p, &format!("{what} K=1e300"));
            // NaN parameter.
            let mut p = s.param_values();
            p[layout.type_offsets[1] + 1] = f64::NAN;
            assert_inf_never_nan(&obj, &p, &format!("{what} NaN"));
            // Zero mass of a free particle (falls back to the generic path).
            let mut p = s.param_values();
            p[layout.mass_offset + 5] = 0.0;
            assert_inf_never_nan(&obj, &p, &format!("{what} m=0"));
        }
    }
}

#[test]
fn an_unstable_stiffness_diverges_in_rollouts_but_not_in_the_short_cost() {
    // K = 1e6 N/m with m = 0.01 kg and dt = 5 ms is far beyond the explicit scheme's stability
    // limit: a rollout runs away, one step from real frames does not.
    let s = cloth(4, 4, false);
    let traj = s.simulate(60).unwrap();
    let mut p = s.param_values();
    p[s.param_layout().type_offsets[0]] = 1e6;
    let long = Objective::new(&s, &traj, CostKind::Long).unwrap();
    assert_inf_never_nan(&long, &p, "long K=1e6");
    let short = Objective::new(&s, &traj, CostKind::Short).unwrap();
    let rep = short.report(&p).unwrap();
    assert!(rep.total.is_finite() && rep.total > 0.0);
}

#[test]
fn wrong_lengths_are_errors() {
    let s = zoo(false);
    let traj = s.simulate(10).unwrap();
    let obj = Objective::new(&s, &traj, CostKind::Short).unwrap();
    let n = obj.param_len();
    let mut sc = obj.scratch();
    let short_p = vec![1.0; n - 1];
    let err = obj.total(&short_p, &mut sc).unwrap_err();
    assert!(
        matches!(err, CostError::Length { expected, got, .. } if expected == n && got == n - 1)
    );
    assert!(err.to_string().starts_with("parameter vector: "), "{err}");
    let mut per = vec![0.0; 3];
    let err = obj
        .evaluate(&s.param_values(), &mut sc, &mut per)
        .unwrap_err();
    assert!(matches!(err, CostError::Length { .. }), "{err}");
    let mut out = vec![0.0; 3];
    let err = obj
        .evaluate_batch(&vec![0.0; 3 * n + 1], &mut out)
        .unwrap_err();
    assert!(
        err.to_string().contains("population of 3 individuals"),
        "{err}"
    );
}

#[test]
fn trajectory_scene_mismatches_are_errors_naming_the_place() {
    let s = zoo(false);
    let traj = s.simulate(10).unwrap();
    let other = cloth(3, 3, false).simulate(10).unwrap();
    let err = Objective::new(&s, &other, CostKind::Short).unwrap_err();
    assert_eq!(
        err.to_string(),
        "trajectory: has 9 particles, the scene has 7"
    );
    let two = Trajectory::from_flat(2, 7, traj.as_flat()[..42].to_vec()).unwrap();
    let err = Objective::new(&s, &two, CostKind::Short).unwrap_err();
    assert_eq!(
        err.to_string(),
        "trajectory: has 2 frames, the cost needs at least 3"
    );
    let wrong_dt = traj.clone().with_dt(0.01);
    let err = Objective::new(&s, &wrong_dt, CostKind::Short).unwrap_err();
    assert!(
        err.to_string().starts_with("trajectory.dt: is 0.01 s"),
        "{err}"
    );
    let mut bad = s.clone();
    bad.dt = -1.0;
    let err = Objective::new(&bad, &traj, CostKind::Short).unwrap_err();
    assert!(matches!(err, CostError::Core(_)), "{err}");
}

#[test]
fn kind_strings_parse_and_bad_ones_say_why() {
    assert_eq!("short".parse::<CostKind>().unwrap(), CostKind::Short);
    assert_eq!("long".parse::<CostKind>().unwrap(), CostKind::Long);
    assert_eq!(
        "horizon:7".parse::<CostKind>().unwrap(),
        CostKind::Horizon(7)
    );
    assert_eq!(
        "progressive".parse::<CostKind>().unwrap(),
        CostKind::Progressive {
            start: 1,
            generations_to_full: cordis_es::cost::DEFAULT_GENERATIONS_TO_FULL
        }
    );
    assert_eq!(
        "progressive:50:3".parse::<CostKind>().unwrap(),
        CostKind::Progressive {
            start: 3,
            generations_to_full: 50
        }
    );
    assert_eq!(
        "harmonic".parse::<CostKind>().unwrap(),
        CostKind::Harmonic {
            eps: cordis_es::cost::DEFAULT_HARMONIC_EPS
        }
    );
    for (bad, says) in [
        ("shrt", "unknown cost"),
        ("horizon", "give the horizon"),
        ("horizon:0", "whole number ≥ 1, got `0`"),
        ("horizon:x", "got `x`"),
        ("horizon:2:3", "at most 1"),
        ("short:2", "at most 0"),
        ("harmonic:-1", "positive number"),
        ("harmonic:nan", "positive number"),
        ("progressive:0", "whole number"),
        ("", "unknown cost"),
    ] {
        let err = bad.parse::<CostKind>().unwrap_err().to_string();
        assert!(err.starts_with(&format!("cost kind `{bad}`: ")), "{err}");
        assert!(err.contains(says), "{bad}: {err}");
        assert!(!err.contains('\n'));
    }
}

proptest! {
    #[test]
    fn kind_display_round_trips(
        which in 0..5usize,
        h in 1..10_000usize,
        g in 1..10_000usize,
        eps in 1e-20f64..1e3,
    ) {
        let kind = match which {
            0 => CostKind::Short,
            1 => CostKind::Horizon(h),
            2 => CostKind::Long,
            3 => CostKind::Progressive { start: h, generations_to_full: g },
            _ => CostKind::Harmonic { eps },
        };
        prop_assert_eq!(kind.to_string().parse::<CostKind>().unwrap(), kind);
    }

    #[test]
    fn arbitrary_strings_never_panic(s in ".{0,20}") {
        let _ = s.parse::<CostKind>();
    }

    #[test]
    fn progressive_window_grows_monotonically_to_the_whole_trajectory(
        frames in 3..500usize,
        g_full in 1..300usize,
        start in 1..50usize,
    ) {
        let kind = CostKind::Progressive { start, generations_to_full: g_full };
        let mut last = 0;
        for g in 0..=g_full + 2 {
            let h = kind.window(frames, g).unwrap();
            prop_assert!(h >= last && h >= 1 && h <= frames - 2 || frames == 3 && h == 1);
            last = h;
        }
        prop_assert_eq!(last, (frames - 2).max(1));
    }
}

fn population(s: &cordis_core::Scene, k: usize) -> Vec<f64> {
    (0..k)
        .flat_map(|i| perturbed(s, 0.4, 100 + i as u64))
        .collect()
}

#[test]
fn batch_equals_sequential_and_is_identical_for_1_and_2_threads() {
    for (s, kind, linear) in [
        (cloth(5, 4, false), "short", true),
        (cloth(5, 4, false), "short", false),
        (cloth(5, 4, true), "short", false),
        (fluid(true), "short", false),
        (zoo(true), "horizon:3", false),
        (zoo(false), "harmonic", false),
    ] {
        let data = noisy(&s, &s.simulate(25).unwrap(), 1e-5, 4);
        let mut obj = Objective::new(&s, &data, kind.parse().unwrap()).unwrap();
        obj.set_linear(linear);
        let k = 13;
        let pop = population(&s, k);
        let mut sc = obj.scratch();
        let seq: Vec<f64> = pop
            .chunks(obj.param_len())
            .map(|p| obj.total(p, &mut sc).unwrap())
            .collect();
        let mut by_threads = Vec::new();
        for threads in [1, 2] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut out = vec![0.0; k];
            pool.install(|| obj.evaluate_batch(&pop, &mut out)).unwrap();
            by_threads.push(out);
        }
        let bits = |v: &[f64]| v.iter().map(|c| c.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&by_threads[0]), bits(&seq), "{kind} linear={linear}");
        assert_eq!(bits(&by_threads[1]), bits(&seq), "{kind} linear={linear}");
        assert!(seq.iter().all(|c| c.is_finite() && *c > 0.0));
        // The global-only evaluation agrees with the one that computes local costs.
        for (p, c) in pop.chunks(obj.param_len()).zip(&seq) {
            let rep = obj.report(p).unwrap();
            assert!((rep.total - c).abs() <= 1e-12 * c, "{} vs {c}", rep.total);
        }
    }
}

#[test]
fn runaway_rollouts_below_the_cap_stay_ranked_by_how_far_they_ran() {
    // One particle on an anchor 1 m away, observed at K dt²/m = 1 (stable). Candidates at 4.2
    // and 4.6 grow by 1.56 and 1.94 per step: ~1e11 m and ~1e17 m at frame 59, finite, below
    // the cap, far beyond the simulator's relative guard. The long cost keeps them finite and
    // in order, so that a search over wide boxes, where every first candidate runs away, can
    // climb out (cost/rollout.rs: the thesis strategy's wide-box results depend on it).
    use cordis_core::{LinkKind, LinkType, Particle, Scene};
    let anchored = |kdt2m: f64| {
        let mut s = Scene::new(0.01);
        s.add_particle(Particle::new(1.0, [1.0, 0.0, 0.0]));
        s.add_type(LinkType::new("a", LinkKind::Anchor).with("stiffness", kdt2m / 1e-4));
        s.add_link("a", &[0]);
        s.links[0].point = Some([0.0; 3]);
        s
    };
    let truth = anchored(1.0);
    let traj = truth.simulate(60).unwrap();
    assert!(
        anchored(4.2).simulate(60).is_err(),
        "beyond the simulator's guard"
    );
    let obj = Objective::new(&truth, &traj, CostKind::Long).unwrap();
    let cost = |k: f64| obj.report(&anchored(k).param_values()).unwrap().total;
    let (slow, fast) = (cost(4.2), cost(4.6));
    assert!(slow.is_finite() && slow > 1e20, "{slow}");
    assert!(fast.is_finite() && fast > 1e6 * slow, "{fast} vs {slow}");
    assert_eq!(cost(1.0), 0.0);
    // Beyond the cap (or not finite) it is +inf, as ever.
    assert_inf_never_nan(&obj, &anchored(100.0).param_values(), "K dt²/m = 100");
}
