//! The precomputed linear short cost equals the generic simulator-step path.

mod common;

use common::{cloth, fluid, noisy, perturbed, zoo};
use cordis_core::Scene;
use cordis_es::cost::{CostKind, LinearShortCost, Objective};

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / a.abs().max(b.abs())
}

fn linear_scenes() -> Vec<(&'static str, Scene, f64)> {
    vec![
        ("cloth", cloth(5, 4, false), 1e-4),
        ("zoo", zoo(false), 1e-5),
        ("fluid", fluid(false), 1e-5),
    ]
}

#[test]
fn linear_path_equals_generic_path_on_noisy_data() {
    for (name, s, sigma) in linear_scenes() {
        let data = noisy(&s, &s.simulate(40).unwrap(), sigma, 3);
        let mut obj = Objective::new(&s, &data, CostKind::Short).unwrap();
        assert!(obj.linear().is_some(), "{name} is linear");
        let params = [
            s.param_values(),
            perturbed(&s, 0.3, 5),
            perturbed(&s, 2.0, 6),
        ];
        let mut scratch = obj.scratch();
        let mut fast = Vec::new();
        for p in &params {
            assert!(obj.uses_linear(p));
            let total = obj.total(p, &mut scratch).unwrap();
            fast.push((total, obj.report(p).unwrap()));
        }
        obj.set_linear(false);
        for (k, (p, (total, lin))) in params.iter().zip(&fast).enumerate() {
            assert!(!obj.uses_linear(p));
            let gen = obj.report(p).unwrap();
            assert!(gen.total > 0.0);
            let what = format!("{name} params#{k}");
            assert!(
                rel(lin.total, gen.total) < 1e-9,
                "{what}: {} vs {}",
                lin.total,
                gen.total
            );
            assert!(rel(*total, gen.total) < 1e-9, "{what}: global form {total}");
            assert_eq!(lin.terms, gen.terms);
            for (i, (a, b)) in lin.per_particle.iter().zip(&gen.per_particle).enumerate() {
                assert!(
                    *a == *b || rel(*a, *b) < 1e-9,
                    "{what} particle {i}: {a} vs {b}"
                );
            }
        }
    }
}

#[test]
fn gram_form_matches_away_from_the_optimum() {
    for (name, s, sigma) in linear_scenes() {
        let data = noisy(&s, &s.simulate(30).unwrap(), sigma, 9);
        let lin = LinearShortCost::new(&s, &data).unwrap().unwrap();
        let (g, h, c) = lin.gram();
        let d = lin.dim();
        let p = perturbed(&s, 0.5, 1);
        let th = lin.theta(&p).unwrap();
        let mut q = c;
        for i in 0..d {
            q += 2.0 * h[i] * th[i];
            for j in 0..d {
                q += th[i] * g[i * d + j] * th[j];
            }
        }
        let direct = lin.total(&th).unwrap();
        assert!(rel(q, direct) < 1e-8, "{name}: gram {q} vs factor {direct}");
        // The factor is the Cholesky factor of G: RᵀR = G.
        let (r, rq, _) = lin.factor();
        for i in 0..d {
            for j in 0..d {
                let rtr: f64 = (0..d).map(|k| r[k * d + i] * r[k * d + j]).sum();
                assert!((rtr - g[i * d + j]).abs() <= 1e-12 * g[i * d + i].abs().max(1e-300));
            }
            let rtq: f64 = (0..d).map(|k| r[k * d + i] * rq[k]).sum();
            assert!((rtq - h[i]).abs() <= 1e-12 * h.iter().fold(0.0f64, |m, v| m.max(v.abs())));
        }
    }
}

#[test]
fn square_root_form_has_no_cancellation_at_the_truth() {
    // Exact data, generating parameters: the generic path gives exactly 0. The factor gives a
    // sum of squares of rounding errors; the Gram form would give rounding of c itself.
    for (name, s, _) in linear_scenes() {
        let traj = s.simulate(40).unwrap();
        let obj = Objective::new(&s, &traj, CostKind::Short).unwrap();
        let lin = obj.linear().unwrap();
        let p = s.param_values();
        let th = lin.theta(&p).unwrap();
        let total = lin.total(&th).unwrap();
        let (g, h, c) = lin.gram();
        let d = lin.dim();
        let mut gram = c;
        for i in 0..d {
            gram += 2.0 * h[i] * th[i];
            for j in 0..d {
                gram += th[i] * g[i * d + j] * th[j];
            }
        }
        let terms = obj.terms() as f64;
        eprintln!("{name}: c = {c:e}, Gram form at truth = {gram:e}, factor = {total:e}");
        // (1e-13 m)² per term: rounding of positions of order 1 m.
        assert!(total <= 1e-26 * terms, "{name}: {total}");
        let mut per = vec![0.0; s.particles.len()];
        let sum = lin.local(&th, &mut per).unwrap();
        assert!(sum <= 1e-26 * terms && per.iter().all(|&v| v >= 0.0));
    }
}

#[test]
fn linear_form_holds_no_per_frame_data() {
    for (name, s, _) in linear_scenes() {
        let short = s.simulate(20).unwrap();
        let long = s.simulate(120).unwrap();
        let a = LinearShortCost::new(&s, &short).unwrap().unwrap();
        let b = LinearShortCost::new(&s, &long).unwrap().unwrap();
        assert_eq!(a.stored_values(), b.stored_values(), "{name}");
        assert_eq!(a.dim(), b.dim());
    }
}

#[test]
fn nonlinear_scenes_have_no_linear_form() {
    for s in [cloth(4, 3, true), zoo(true), fluid(true)] {
        let traj = s.simulate(10).unwrap();
        assert!(LinearShortCost::new(&s, &traj).unwrap().is_none());
        let obj = Objective::new(&s, &traj, CostKind::Short).unwrap();
        assert!(!obj.uses_linear(&s.param_values()));
    }
    let mut s = zoo(false);
    s.particles[2].mass = cordis_core::Param::Unknown(cordis_core::Bounds {
        min: 0.1,
        max: 2.0,
        init: Some(0.7),
    });
    let traj = s.simulate(10).unwrap();
    assert!(LinearShortCost::new(&s, &traj).unwrap().is_none());
}

#[test]
fn rollout_kinds_do_not_use_the_linear_form() {
    let s = zoo(false);
    let traj = s.simulate(12).unwrap();
    for kind in ["horizon:2", "long", "harmonic"] {
        let obj = Objective::new(&s, &traj, kind.parse().unwrap()).unwrap();
        assert!(!obj.uses_linear(&s.param_values()), "{kind}");
    }
    // Progressive uses it at generation 0 (window 1), not once the window has grown.
    let mut obj = Objective::new(&s, &traj, "progressive:10".parse().unwrap()).unwrap();
    assert!(obj.uses_linear(&s.param_values()));
    obj.set_generation(5);
    assert_eq!(obj.window(), Some(5));
    assert!(!obj.uses_linear(&s.param_values()));
}

#[test]
fn a_different_mass_or_range_falls_back_to_the_generic_path() {
    let s = fluid(false);
    let data = noisy(&s, &s.simulate(20).unwrap(), 1e-5, 1);
    let obj = Objective::new(&s, &data, CostKind::Short).unwrap();
    let layout = s.param_layout();
    let mut p = s.param_values();
    p[layout.mass_offset + 3] *= 1.5;
    assert!(!obj.uses_linear(&p));
    let mut q = s.param_values();
    q[layout.type_offsets[0] + 3] = 0.12; // gas range
    assert!(!obj.uses_linear(&q));
    let mut generic = Objective::new(&s, &data, CostKind::Short).unwrap();
    generic.set_linear(false);
    for p in [p, q] {
        assert_eq!(obj.report(&p).unwrap(), generic.report(&p).unwrap());
    }
}

#[test]
fn linear_form_checks_lengths() {
    let s = zoo(false);
    let lin = LinearShortCost::new(&s, &s.simulate(10).unwrap())
        .unwrap()
        .unwrap();
    assert!(lin.theta(&[1.0]).is_err());
    assert!(lin.total(&vec![1.0; lin.dim() + 1]).is_err());
    let th = lin.theta(&s.param_values()).unwrap();
    assert!(lin.local(&th, &mut [0.0; 2]).is_err());
    assert!(!lin.applies_to(&[1.0]));
}
