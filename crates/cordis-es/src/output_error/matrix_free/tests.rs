//! The matrix-free products against the dense sensitivities of [`super::super::tangent`].

use approx::assert_relative_eq;
use cordis_core::{Bounds, Param, Scene, Vec3};
use nalgebra::DVector;

use super::super::fit::{self, Counts, Fitter, LmSettings};
use super::super::observations::Take;
use super::super::tangent::{Sens, Tangent};
use super::cg::{pcg, CgSettings, CgWork};
use super::preconditioner::Pre;
use super::stage::{approx_diag, pattern_move, step_deflation, Lm};
use super::standard_errors::{theta_inverse, StderrStop, STDERR_STOP};
use super::*;
use crate::identify::{add_noise, with_unknown_boxes};
use crate::linalg::deflation::Deflation;
use crate::linalg::dot;
use crate::space::ParameterSpace;

/// Damped springs (A not symmetric) with a quadratic viscosity, a damper, an anchor, a drag,
/// angles, an unknown mass, a fixed particle: every term of the recursion.
fn truth() -> Scene {
    let mut s = super::super::tests::every_term_scene(7);
    s.particles[5].fixed = true;
    s
}

struct Setup {
    tangent: Tangent,
    space: ParameterSpace,
    base: Vec<f64>,
    takes: Vec<Take>,
    q: Vec<f64>,
}

fn setup(noise: f64) -> Setup {
    let truth = truth();
    let mut guess = with_unknown_boxes(&truth, 25.0, 3);
    guess.particles[2].mass = Param::Unknown(Bounds {
        min: 0.1,
        max: 10.0,
        init: None,
    });
    // The quadratic viscosity and the angles' rest cosine unknown too: every θ column.
    let quadratic = Param::Unknown(Bounds {
        min: 0.01,
        max: 5.0,
        init: None,
    });
    guess.types[0].set_optional(
        cordis_core::OptionalParam::DampingQuadratic,
        Some(quadratic),
    );
    // A conditional range is refused unknown (a step in the cost).
    let touch = guess.types.iter_mut().find(|t| t.name == "touch").unwrap();
    touch.params[3] = Param::Known(touch.params[3].value());
    let bend = guess.types.iter_mut().find(|t| t.name == "bend").unwrap();
    let c0 = bend.params[1].value();
    bend.params[1] = Param::Unknown(Bounds {
        min: c0 - 0.5,
        max: c0 + 0.5,
        init: None,
    });
    setup_of(&truth, &guess, 60, noise)
}

/// The Provot patch ([`super::super::tests::provot_scene`]): K, l0, Z of every type, τc of
/// one structural type and one mass unknown.
fn provot_setup(noise: f64) -> Setup {
    let truth = super::super::tests::provot_scene();
    let mut guess = with_unknown_boxes(&truth, 25.0, 3);
    guess.particles[6].mass = Param::Unknown(Bounds {
        min: 1e-4,
        max: 1e-2,
        init: None,
    });
    let tau = Param::Unknown(Bounds {
        min: 0.02,
        max: 0.5,
        init: None,
    });
    guess.types[0].set_optional(cordis_core::OptionalParam::MaxElongation, Some(tau));
    setup_of(&truth, &guess, 60, noise)
}

/// Two takes of `truth`'s `frames` frames (the second with gaps) for the unknowns of
/// `guess`, at an iterate slightly off the truth.
fn setup_of(truth: &Scene, guess: &Scene, frames: usize, noise: f64) -> Setup {
    let tangent = Tangent::new(guess).unwrap();
    let space = ParameterSpace::from_scene(guess);
    let traj = truth.simulate(frames).unwrap();
    let noisy = add_noise(&traj, noise * traj.scale(), 1);
    // Two takes, the second with gaps: the θ block sums over takes.
    let t0 = Take::complete(&noisy);
    let t1 = Take::complete(&noisy.clone()).masked(|t, i, c| (t * 7 + i * 3 + c) % 5 != 0);
    let base = truth.param_values();
    let mut q: Vec<f64> = space
        .unknowns
        .iter()
        .map(|u| u.to_internal(base[u.slot]) + 0.01)
        .collect();
    for k in 0..2 {
        for &i in &tangent.free {
            let p = truth.particles[i].pos;
            let v = truth.particles[i].vel;
            q.extend([p[0], p[1] + 0.001 * k as f64, p[2], v[0], v[1], v[2] + 0.01]);
        }
    }
    Setup {
        tangent,
        space,
        base,
        takes: vec![t0, t1],
        q,
    }
}

fn fitter(s: &Setup) -> Fitter<'_> {
    let slots: Vec<usize> = s.space.unknowns.iter().map(|u| u.slot).collect();
    Fitter {
        tangent: &s.tangent,
        unknowns: &s.space.unknowns,
        base: &s.base,
        takes: &s.takes,
        cols: s.tangent.columns(&slots),
        continuity: None,
    }
}

/// Deterministic pseudo-random numbers in [-1, 1].
fn noise(k: usize, salt: u64) -> f64 {
    let mut h = (k as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ salt;
    h ^= h >> 31;
    h = h.wrapping_mul(0xBF58_476D_1CE4_E5B9);
    h ^= h >> 29;
    (h >> 11) as f64 / (1u64 << 52) as f64 - 1.0
}

/// The dense sensitivities S(t) of take k, frames × 3N × P.
fn dense(fit: &Fitter<'_>, q: &[f64], k: usize, frames: usize) -> Vec<f64> {
    let p = fit.params(q);
    let (nt, ns) = (fit.theta(), fit.state_len());
    let mut out = Vec::new();
    let mut visit = |_: usize, _: &[Vec3], s: Option<&[f64]>| out.extend_from_slice(s.unwrap());
    fit.tangent
        .rollout(
            &p,
            &q[nt + k * ns..][..ns],
            frames,
            Some(&fit.cols),
            &mut Sens::default(),
            &mut visit,
        )
        .unwrap();
    out
}

#[test]
fn directional_rollout_is_the_dense_sensitivities_times_v() {
    forward_matches_dense(&setup(0.0));
}

#[test]
fn directional_rollout_through_provot_is_the_dense_sensitivities_times_v() {
    forward_matches_dense(&provot_setup(0.0));
}

fn forward_matches_dense(s: &Setup) {
    let fit = fitter(s);
    let mut mf = Mf::new(&fit);
    let mut work = Work::default();
    let frames = 60;
    assert!(mf.linearise(&s.q, frames, &mut work));
    let (nt, width) = (fit.theta(), fit.cols.len);
    let chain = fit.chain(&s.q);
    let rows = 3 * s.tangent.plan.n;
    for k in 0..2 {
        let v: Vec<f64> = (0..width).map(|a| noise(a, 11 + k as u64)).collect();
        work.dir = v.clone();
        mf.forward(k, 1, &mut work);
        let sens = dense(&fit, &s.q, k, frames);
        let mut worst: f64 = 0.0;
        let mut size: f64 = 0.0;
        for r in 0..frames * rows {
            let row = &sens[r * width..(r + 1) * width];
            let exact: f64 = (0..width)
                .map(|a| row[a] * v[a] * if a < nt { chain[a] } else { 1.0 })
                .sum();
            worst = worst.max((exact - work.out[r]).abs());
            size = size.max(exact.abs());
        }
        assert!(worst <= 1e-12 * size, "take {k}: {worst:e} of {size:e}");
    }
}

#[test]
fn adjoint_is_the_transpose_of_the_directional_rollout() {
    adjoint_matches_forward(&setup(1e-3));
}

#[test]
fn adjoint_through_provot_is_the_transpose_of_the_directional_rollout() {
    adjoint_matches_forward(&provot_setup(1e-3));
}

fn adjoint_matches_forward(s: &Setup) {
    let fit = fitter(s);
    let mut mf = Mf::new(&fit);
    let mut work = Work::default();
    let frames = 60;
    assert!(mf.linearise(&s.q, frames, &mut work));
    let (nt, width) = (fit.theta(), fit.cols.len);
    let chain = fit.chain(&s.q);
    let rows = 3 * s.tangent.plan.n;
    for k in 0..2 {
        let v: Vec<f64> = (0..width).map(|a| noise(a, 21 + k as u64)).collect();
        let u: Vec<f64> = (0..frames * rows)
            .map(|a| noise(a, 31 + k as u64))
            .collect();
        work.dir = v.clone();
        mf.forward(k, 1, &mut work);
        let jv_u = dot(&work.out, &u);
        mf.adjoint(k, 1, &u, &mut work);
        let v_jtu = dot(&v, &work.grad);
        // The forward applies A as β d + u (α u·d + q·d), the adjoint Aᵀ as
        // β δ + (α u + q)(u·δ): the same operator rounded differently over 60 frames
        // (measured 1.05e-12 relative here); a wrong transpose shows at 1e-3 and above.
        assert!(
            (jv_u - v_jtu).abs() <= 1e-11 * jv_u.abs().max(v_jtu.abs()),
            "take {k}: <Jv,u> = {jv_u:e}, <v,J'u> = {v_jtu:e}"
        );
        // And against the dense transpose, column by column.
        let sens = dense(&fit, &s.q, k, frames);
        for a in 0..width {
            let exact: f64 = (0..frames * rows)
                .map(|r| sens[r * width + a] * u[r])
                .sum::<f64>()
                * if a < nt { chain[a] } else { 1.0 };
            let got = work.grad[a];
            assert!(
                (exact - got).abs() <= 1e-11 * exact.abs().max(1.0),
                "take {k}, column {a}: dense {exact:e}, adjoint {got:e}"
            );
        }
    }
}

/// The box bookkeeping of a step: a coordinate on its bound that the step pushes out is
/// named (unless already held), one the step moves inward is not; the fraction to the box
/// lands the first coordinate to leave exactly on its bound.
#[test]
fn a_step_pushing_a_coordinate_out_of_its_box_is_caught() {
    let s = setup(1e-3);
    let fit = fitter(&s);
    let (lo, hi) = s.space.unknowns[0].internal_bounds();
    let mut q = s.q.clone();
    q[0] = lo;
    let mut delta = vec![0.0; q.len()];
    delta[0] = -1.0;
    let mut held = vec![false; q.len()];
    assert_eq!(fit.pushed_out(&q, &delta, &held), vec![0]);
    held[0] = true;
    assert!(fit.pushed_out(&q, &delta, &held).is_empty());
    delta[0] = 1.0;
    assert!(fit
        .pushed_out(&q, &vec![0.0; q.len()], &[false].repeat(q.len()))
        .is_empty());
    q[0] = lo + 0.25 * (hi - lo);
    delta[0] = hi - lo;
    assert!((fit.fraction_to_bounds(&q, &delta) - 0.75).abs() < 1e-12);
    delta[0] = -(hi - lo);
    assert!((fit.fraction_to_bounds(&q, &delta) - 0.25).abs() < 1e-12);
    delta[0] = 0.1 * (hi - lo);
    assert_eq!(fit.fraction_to_bounds(&q, &delta), 1.0);
}

/// A step split over two threads sums as the unsplit one to rounding, and bit for bit the
/// same whatever the thread count (guards determinism and the halves' bookkeeping: a
/// half skipped or added twice, anchors in both halves).
#[test]
fn split_steps_match_the_unsplit_ones_and_not_the_thread_count() {
    let s = setup(1e-3);
    let fit = fitter(&s);
    let frames = 40;
    let rows = 3 * s.tangent.plan.n;
    let width = fit.cols.len;
    let v: Vec<f64> = (0..width).map(|a| noise(a, 7)).collect();
    let u: Vec<f64> = (0..frames * rows).map(|a| noise(a, 8)).collect();
    let run = |split_min: usize, threads: usize| {
        let mut mf = Mf::new(&fit);
        mf.split_min_springs = split_min;
        let mut work = Work::default();
        assert!(mf.linearise(&s.q, frames, &mut work));
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            work.dir = v.clone();
            mf.forward(1, 1, &mut work);
            let jv = work.out.clone();
            mf.adjoint(1, 1, &u, &mut work);
            (jv, work.grad.clone())
        })
    };
    let (jv, jtu) = run(usize::MAX, 1);
    let (jv1, jtu1) = run(1, 1);
    let (jv2, jtu2) = run(1, 2);
    assert!(
        jv1 == jv2 && jtu1 == jtu2,
        "the thread count changed a split pass"
    );
    let close = |a: &[f64], b: &[f64]| {
        let scale = a.iter().fold(0.0f64, |m, x| m.max(x.abs()));
        a.iter().zip(b).all(|(x, y)| (x - y).abs() <= 1e-12 * scale)
    };
    assert!(
        close(&jv, &jv1),
        "split forward differs from the unsplit one"
    );
    assert!(
        close(&jtu, &jtu1),
        "split adjoint differs from the unsplit one"
    );
}

#[test]
fn gauss_newton_products_match_the_dense_normal_equations() {
    products_match_dense(&setup(1e-3));
}

#[test]
fn gauss_newton_products_through_provot_match_the_dense_normal_equations() {
    products_match_dense(&provot_setup(1e-3));
}

fn products_match_dense(s: &Setup) {
    let fit = fitter(s);
    let frames = 40;
    let ne = fit.normal(&s.q, frames, &mut Sens::default()).unwrap();
    let mut mf = Mf::new(&fit);
    let mut work = Work::default();
    assert!(mf.linearise(&s.q, frames, &mut work));
    assert!((mf.cost() - ne.cost).abs() <= 1e-12 * ne.cost);
    let len = fit.len();
    let mut g = vec![0.0; len];
    mf.gradient(&mut g, &mut work);
    let v: Vec<f64> = (0..len).map(|a| noise(a, 41)).collect();
    let mut hv = vec![0.0; len];
    mf.hv(&v, 1, &mut hv, &mut work);
    let exact = &ne.h * DVector::from_column_slice(&v);
    let hs = exact.amax();
    let gs = ne.g.amax();
    for a in 0..len {
        assert!((exact[a] - hv[a]).abs() <= 1e-10 * hs, "Hv[{a}]");
        assert!((ne.g[a] - g[a]).abs() <= 1e-10 * gs, "g[{a}]");
    }
    // The θ columns the preconditioner uses are H's own.
    let cols = mf.theta_columns(&mut work);
    for a in 0..len {
        for c in 0..fit.theta() {
            let e = ne.h[(a, c)];
            assert!(
                (e - cols[(a, c)]).abs() <= 1e-10 * hs.max(e.abs()),
                "H[{a},{c}]"
            );
        }
    }
}

#[test]
fn a_solve_deflated_by_earlier_steps_reaches_the_same_step_in_fewer_iterations() {
    let s = setup(1e-3);
    let fit = fitter(&s);
    let frames = 40;
    let mut mf = Mf::new(&fit);
    let mut work = Work::default();
    assert!(mf.linearise(&s.q, frames, &mut work));
    let len = fit.len();
    let mut g = vec![0.0; len];
    mf.gradient(&mut g, &mut work);
    let rhs: Vec<f64> = g.iter().map(|x| -x).collect();
    let cols = mf.theta_columns(&mut work);
    let scale = approx_diag(&mf, &cols);
    let held = vec![false; len];
    let lambda = 1e-6;
    let pre = Pre::new(&mf, &cols, &scale, &held, lambda);
    let set = CgSettings {
        tol: 1e-10,
        max_iterations: 2000,
    };
    let mut cg = CgWork::default();
    let mut solve = |x: &mut [f64], deflation: Option<&Deflation>, work: &mut Work| {
        let (mf, pre, scale, held, rhs) = (&mf, &pre, &scale, &held, &rhs);
        pcg(
            mf,
            pre,
            scale,
            held,
            lambda,
            rhs,
            x,
            set,
            deflation,
            &mut cg,
            work,
            &mut |_| false,
        )
    };
    let mut plain = vec![0.0; len];
    let (its_plain, ok) = solve(&mut plain, None, &mut work);
    assert!(ok);
    // Earlier "steps": the solution seen through two perturbed copies, as the last steps
    // of a window approximate the next one.
    let recent: std::collections::VecDeque<Vec<f64>> = [3, 5]
        .iter()
        .map(|&salt| {
            (0..len)
                .map(|a| plain[a] * (1.0 + 0.3 * noise(a, salt)))
                .collect()
        })
        .collect();
    let d = step_deflation(&mf, &recent, &scale, &held, lambda, &mut work).unwrap();
    assert_eq!(d.dim(), 2);
    let mut deflated = vec![0.0; len];
    let (its_deflated, ok) = solve(&mut deflated, Some(&d), &mut work);
    assert!(ok);
    let scale_x = plain.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    for a in 0..len {
        assert!((plain[a] - deflated[a]).abs() <= 1e-6 * scale_x, "x[{a}]");
    }
    assert!(
        its_deflated < its_plain,
        "deflated {its_deflated} against plain {its_plain} iterations"
    );
}

/// Guards the matrix-free Cramér–Rao bound (large scenes) against the dense one.
#[test]
fn the_matrix_free_bound_is_the_dense_one() {
    let s = setup(0.0);
    let fit = fitter(&s);
    let frames = 60;
    let sigma = 1e-3;
    let sd = cramer_rao_sd(&fit, &s.q, frames, sigma).unwrap();
    let ne = fit.normal(&s.q, frames, &mut Sens::default()).unwrap();
    let (cov, _) = super::super::uncertainty::covariance(&ne.h, sigma * sigma);
    let cov = super::super::uncertainty::physical(&cov, &fit.chain(&s.q));
    assert_eq!(sd.len(), fit.theta());
    for (a, sd) in sd.iter().enumerate() {
        // Variances settled to 0.1 %: standard deviations within 0.5 %.
        let dense = cov[(a, a)].sqrt();
        assert!(
            (sd / dense - 1.0).abs() <= 5e-3,
            "θ {a}: {sd} against {dense}"
        );
    }
}

/// Guards the pattern move's rule: doubling along the direction while the cost falls,
/// keeping the best point, and leaving the iterate alone when the first trial does not gain.
#[test]
fn a_pattern_move_doubles_along_the_valley_while_the_cost_falls() {
    // A long valley along x with its floor's minimum at x = 10.
    let valley = |x: &mut [f64]| (x[0] - 10.0).powi(2) / 100.0 + x[1] * x[1];
    let mut at = vec![0.0, 0.0];
    let c0 = valley(&mut at.clone());
    let (c, evaluations) = pattern_move(&mut at, c0, &[1.0, 0.0], valley);
    // α = 1, 2, 4, 8 gain; 16 (x = 16, cost 0.36 > 0.04) does not.
    assert_eq!(at, vec![8.0, 0.0]);
    assert_eq!(evaluations, 5);
    assert_relative_eq!(c, 0.04, max_relative = 1e-12);
    let (c, evaluations) = pattern_move(&mut at, c, &[0.0, 1.0], valley);
    assert_eq!((at.clone(), evaluations), (vec![8.0, 0.0], 1));
    assert_relative_eq!(c, 0.04, max_relative = 1e-12);
    // A diverging model (+inf, NaN) is no gain either.
    let (_, evaluations) = pattern_move(&mut at, c, &[1.0, 0.0], |_| f64::NAN);
    assert_eq!((at, evaluations), (vec![8.0, 0.0], 1));
}

/// Tight settings, for fits whose optimum the tests compare.
const TIGHT: LmSettings = LmSettings {
    max_iterations: 100,
    ftol: 1e-10,
    xtol: 1e-10,
    gtol: 1e-10,
    face_steps: true,
};

/// The dense fit's optimum from the setup's start, over the growing windows.
fn dense_optimum(s: &Setup, fit: &Fitter<'_>) -> Vec<f64> {
    let mut qd = s.q.clone();
    let mut counts = Counts::default();
    let mut buf = Sens::default();
    let never = || false;
    super::super::grow_windows(
        fit,
        &mut qd,
        &super::super::Config::default(),
        &mut |q, w| fit::lm_stage(fit, q, w, TIGHT, &mut counts, &mut buf, &never),
    )
    .unwrap();
    qd
}

/// The matrix-free fit from `q0` (growing windows, [`TIGHT`] settings) and its estimate; with
/// the last window's last accepted steps.
fn matrix_free_fit(fit: &Fitter<'_>, q0: &[f64]) -> (crate::output_error::Estimate, Vec<Vec<f64>>) {
    let never = || false;
    let mut q = q0.to_vec();
    let (mut counts, mut cgc) = (Counts::default(), CgCounts::default());
    let mut steps = Vec::new();
    let longest = fit.takes.iter().map(Take::frames).max().unwrap();
    let config = super::super::Config::default();
    let (end, windows) = super::super::grow_windows(fit, &mut q, &config, &mut |q, w| {
        super::stage(
            fit,
            q,
            w,
            longest,
            TIGHT,
            &mut counts,
            &mut cgc,
            &mut steps,
            &never,
        )
    })
    .unwrap();
    let noise_level = fit
        .takes
        .iter()
        .map(super::super::start::noise_level)
        .collect();
    let e = super::finish(
        fit,
        q,
        counts,
        cgc,
        end,
        windows,
        noise_level,
        "test".into(),
        &steps,
        Some(super::super::line_profile::Measure::Line),
        &|| false,
    )
    .unwrap();
    (e, steps)
}

#[test]
fn matrix_free_fit_reaches_the_dense_fits_estimate() {
    let s = setup(1e-3);
    let fit = fitter(&s);
    let qd = dense_optimum(&s, &fit);
    let (e, steps) = matrix_free_fit(&fit, &s.q);
    let nt = fit.theta();
    let moved = (0..nt).map(|a| (qd[a] - s.q[a]).abs()).fold(0.0, f64::max);
    assert!(moved > 1e-3, "the dense fit did not move from its start");
    // The matrix-free fit stops when a step would move the estimate by less than 0.1
    // standard error (FINAL_CHI2): the same optimum within a fraction of its uncertainty.
    let pd = fit.params(&qd);
    for (a, u) in fit.unknowns.iter().enumerate() {
        let (m, d) = (e.params[u.slot], pd[u.slot]);
        assert!(
            (m - d).abs() <= 0.3 * e.stderr[a],
            "θ {a}: matrix-free {m}, dense {d}, standard error {}",
            e.stderr[a]
        );
    }
    // Standard errors against the dense inverse.
    let ne = fit.normal(&qd, 60, &mut Sens::default()).unwrap();
    let dof = (e.observed - e.variables) as f64;
    let (cov, _) = super::super::uncertainty::covariance(&ne.h, ne.cost / dof);
    let cov = super::super::uncertainty::physical(&cov, &fit.chain(&qd));
    for a in 0..nt {
        let sd = cov[(a, a)].sqrt();
        // At its own (slightly different) estimate.
        assert!(
            (e.stderr[a] - sd).abs() <= 1e-2 * sd,
            "stderr {a}: matrix-free {} dense {sd}",
            e.stderr[a]
        );
    }
    // At the same point, the CG solves are the dense inverse's θ block.
    let (hinv, _) = super::super::uncertainty::covariance(&ne.h, 1.0);
    let mut mf = Mf::new(&fit);
    let mut work = Work::default();
    assert!(mf.linearise(&qd, 60, &mut work));
    let exact = StderrStop {
        form: 0.0,
        ..STDERR_STOP
    };
    // Without and with the fit's last steps deflating the solves (exact on any subspace).
    assert!(!steps.is_empty(), "the last stage kept no step");
    let cols = mf.theta_columns(&mut work);
    for recycled in [&[][..], &steps[..]] {
        let (inv, _, _) = theta_inverse(
            &mf,
            &cols,
            &vec![false; nt],
            exact,
            recycled,
            &mut CgCounts::default(),
            &mut work,
        );
        for a in 0..nt {
            for b in 0..nt {
                let scale = (hinv[(a, a)] * hinv[(b, b)]).sqrt();
                assert!(
                    (inv[(a, b)] - hinv[(a, b)]).abs() <= 1e-6 * scale,
                    "H⁻¹[{a},{b}]: CG {} dense {} ({} steps)",
                    inv[(a, b)],
                    hinv[(a, b)],
                    recycled.len()
                );
            }
        }
        // The default stop (the variances settled): variances within 1 % (standard errors
        // within 0.5 %), covariances within 0.1 of their scale (correlations within 0.1).
        let (inv, _, _) = theta_inverse(
            &mf,
            &cols,
            &vec![false; nt],
            STDERR_STOP,
            recycled,
            &mut CgCounts::default(),
            &mut work,
        );
        for a in 0..nt {
            assert!((inv[(a, a)] / hinv[(a, a)] - 1.0).abs() <= 1e-2);
            for b in 0..nt {
                let scale = (hinv[(a, a)] * hinv[(b, b)]).sqrt();
                assert!((inv[(a, b)] - hinv[(a, b)]).abs() <= 0.1 * scale);
            }
        }
        // Solves stopped after 2 iterations: not computed (NaN), each with a positive lower
        // bound on its variance (CG's monotone rise), below the dense inverse's.
        let cut = StderrStop {
            residual: 0.0,
            form: 0.0,
            max_iterations: 2,
        };
        let (inv, at_least, _) = theta_inverse(
            &mf,
            &cols,
            &vec![false; nt],
            cut,
            recycled,
            &mut CgCounts::default(),
            &mut work,
        );
        for a in 0..nt {
            assert!(
                inv[(a, a)].is_nan(),
                "column {a} reported after 2 iterations"
            );
            assert!(
                at_least[a] > 0.0 && at_least[a] <= hinv[(a, a)] * (1.0 + 1e-9),
                "bound {} against the variance {} ({a})",
                at_least[a],
                hinv[(a, a)]
            );
        }
    }
}

/// The last window's Newton confirmation decides from CG's monotone model decrease: at the
/// dense fit's optimum it confirms (the undamped decrement is below 0.01 σ̂²); at the start,
/// far from it, it refuses as soon as the decrement exceeds the criterion instead of solving on
/// to the residual tolerance (seed 5 of the 32 × 32 cloth spent 2,400 CG iterations on such
/// solves, BENCHMARKS.md "Settled decrements").
#[test]
fn the_newton_confirmation_stops_once_the_decrement_decides() {
    let s = setup(1e-3);
    let fit = fitter(&s);
    let qd = dense_optimum(&s, &fit);
    let longest = fit.takes.iter().map(Take::frames).max().unwrap();
    let recent = std::collections::VecDeque::new();
    let mut mf = Mf::new(&fit);
    let mut work = Work::default();

    assert!(mf.linearise(&qd, longest, &mut work));
    let mut at_optimum = CgCounts::default();
    let confirmed = Lm::new(&mf, &mut work).newton_confirms(
        &mf,
        &qd,
        FINAL_CHI2,
        &recent,
        &mut at_optimum,
        &mut work,
    );
    assert!(confirmed, "not confirmed at the optimum ({at_optimum:?})");

    assert!(mf.linearise(&s.q, longest, &mut work));
    let mut at_start = CgCounts::default();
    let confirmed = Lm::new(&mf, &mut work).newton_confirms(
        &mf,
        &s.q,
        FINAL_CHI2,
        &recent,
        &mut at_start,
        &mut work,
    );
    assert!(!confirmed, "confirmed at the start ({at_start:?})");
    assert!(
        at_start.iterations <= 2,
        "the refusal took {} CG iterations",
        at_start.iterations
    );
    assert_eq!(
        at_start.unconverged, 0,
        "a decided refusal counted as unconverged"
    );
}

/// Guards the matrix-free path's undetermined directions: a spring type no link uses has an
/// unknown stiffness the motion cannot see. The fit names it (by the unknown's own name), gives
/// it an infinite standard error, its box as its interval and no correlation, and still gives
/// every other unknown a finite one — as the dense path reports such a parameter.
#[test]
fn an_unknown_no_motion_sees_is_named_undetermined_on_the_matrix_free_path() {
    let spare = |k: Param| {
        cordis_core::LinkType::new("unused", cordis_core::LinkKind::Spring)
            .with("stiffness", k)
            .with("rest_length", 0.1)
    };
    let mut truth = truth();
    truth.add_type(spare(Param::Known(3.0)));
    let mut guess = with_unknown_boxes(&truth, 25.0, 3);
    let touch = guess.types.iter_mut().find(|t| t.name == "touch").unwrap();
    touch.params[3] = Param::Known(touch.params[3].value());
    let unused = guess.types.len() - 1;
    guess.types[unused] = spare(Param::Unknown(Bounds {
        min: 0.5,
        max: 20.0,
        init: None,
    }));
    let s = setup_of(&truth, &guess, 40, 1e-3);
    let fit = fitter(&s);
    let (e, _) = matrix_free_fit(&fit, &s.q);
    let a = fit
        .unknowns
        .iter()
        .position(|u| u.name.contains("unused"))
        .expect("the spare type's stiffness is an unknown");
    assert_eq!(e.undetermined, vec![vec![fit.unknowns[a].name.clone()]]);
    assert_eq!(e.stderr[a], f64::INFINITY);
    // Its interval is its box, not the Wald interval's (0, inf) past the box's floor.
    assert_eq!(e.intervals[a], (0.5, 20.0));
    for b in 0..fit.theta() {
        if b != a {
            assert!(
                e.stderr[b].is_finite() && e.stderr[b] > 0.0,
                "{}: {}",
                fit.unknowns[b].name,
                e.stderr[b]
            );
            assert_eq!(e.correlation[(a, b)], 0.0);
        }
    }
    assert!(e
        .start
        .contains("undetermined directions from the parameters' own block"));
    // The undetermined unknown's solve is skipped, not reported as one that did not converge.
    assert!(!e.start.contains("did not converge"), "{}", e.start);
    for b in 0..fit.theta() {
        if b != a {
            assert_eq!(e.covariance[(a, b)], 0.0);
        }
    }
}
