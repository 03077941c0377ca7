//! The matrix-free output-error estimate on Provot's cloth (issue 16's large-scene benchmark):
//! `cargo run --release -p cordis-es --example oe_cloth -- [side] [frames] [seeds] [rel_noise] [damping] [limit]`
//! (`seeds`: a count n for seeds 0..n, or a range `a..b`).
//!
//! `limit` is `without` (default: the cloth without its Provot limit `max_elongation`, the
//! benchmark as first measured) or `with` (the example's own cloth, τc = 0.1 on the structural
//! springs, known: the tangent differentiates the projection). Unknowns: every link-type parameter, boxes 25× wide; noise σ =
//! `rel_noise` × the trajectory's size. `damping` is `unknown` (default: every link-type
//! parameter in a box) or `known` (the thesis' Table 4.1 protocol: each type's damping at its
//! true value, stiffness and rest length identified — over 100 frames the cloth's light dampings
//! are barely excited, their standard errors exceed 60 %). With `FROM_TRUTH` set in the
//! environment each seed is also fitted from the truth (parameters and initial state): a
//! diagnosis of whether the estimate is the likelihood's optimum or a search failure. Prints seconds, the mean parameter error, the
//! short-cost least-squares error on the same noisy data and the Cramér–Rao bound on the mean
//! error (`cramer_rao` at the truth, matrix-free on the cloth; not part of the timed fit).
use std::time::Instant;

use cordis_core::examples::cloth;
use cordis_es::cost::CostKind;
use cordis_es::identify::{add_noise, with_unknown_boxes};
use cordis_es::output_error::{cramer_rao, estimate, expected_error_pct, Config, Take};
use cordis_es::problem::Problem;
use cordis_es::run::cpu_time::process_cpu_seconds as cpu_seconds;
use cordis_es::space::ParameterSpace;
use cordis_es::strategies::least_squares;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let side: usize = args.get(1).map_or(32, |s| s.parse().unwrap());
    let frames: usize = args.get(2).map_or(100, |s| s.parse().unwrap());
    // `seeds`: a count n (seeds 0..n) or a range `a..b`.
    let seeds: std::ops::Range<u64> = match args.get(3).map(|s| s.split_once("..")) {
        None => 0..3,
        Some(Some((a, b))) => a.parse().unwrap()..b.parse().unwrap(),
        Some(None) => 0..args[3].parse().unwrap(),
    };
    let rel: f64 = args.get(4).map_or(1e-3, |s| s.parse().unwrap());
    let damping_known = match args.get(5).map_or("unknown", String::as_str) {
        "known" => true,
        "unknown" => false,
        other => panic!("damping must be `known` or `unknown`, not {other:?}"),
    };
    let limit = match args.get(6).map_or("without", String::as_str) {
        "with" => true,
        "without" => false,
        other => panic!("limit must be `with` or `without`, not {other:?}"),
    };
    let mut truth = cloth(side, side);
    if !limit {
        for t in &mut truth.types {
            t.set_optional(cordis_core::OptionalParam::MaxElongation, None);
        }
    }
    let traj = truth.simulate(frames).unwrap();
    let sigma = rel * traj.scale();
    let tv = truth.param_values();
    for seed in seeds {
        let noisy = add_noise(&traj, sigma, seed);
        let mut guess = with_unknown_boxes(&truth, 25.0, seed);
        if damping_known {
            for (g, t) in guess.types.iter_mut().zip(&truth.types) {
                for k in 0..g.params.len() {
                    if g.param_name(k) == "damping" {
                        g.params[k] = t.params[k];
                    }
                }
            }
        }
        let space = ParameterSpace::from_scene(&guess);
        let t0 = Instant::now();
        let short = Problem::new(&guess, &noisy, CostKind::Short)
            .map_err(|e| e.to_string())
            .and_then(|p| least_squares::solve(&p));
        let short_secs = t0.elapsed().as_secs_f64();
        let short_err = short.map_or(f64::NAN, |s| space.error_pct(&s.genome, &tv));
        let take = Take::complete(&noisy);
        if std::env::var_os("FROM_TRUTH").is_some() {
            // Diagnosis: the fit started at the truth (parameters and initial state).
            let cfg = Config {
                start: Some(space.genome_of(&tv)),
                start_states: Some(vec![cordis_es::output_error::start::scene_state(&truth)]),
                ..Config::default()
            };
            let e = estimate(&guess, &space, std::slice::from_ref(&take), &cfg).unwrap();
            println!(
                "  from the truth: {:.4} % cost {:.6e} ({})",
                space.error_pct(&e.genome, &tv),
                e.cost,
                e.end
            );
        }
        let t0 = Instant::now();
        let c0 = cpu_seconds();
        // In a pool, as `cordis identify` and the Python session run a strategy: the
        // matrix-free passes split their steps over its threads (RAYON_NUM_THREADS sets them).
        let pool = rayon::ThreadPoolBuilder::new().build().unwrap();
        let e = pool
            .install(|| {
                estimate(
                    &guess,
                    &space,
                    std::slice::from_ref(&take),
                    &Config::default(),
                )
            })
            .unwrap();
        println!("  cost {:.6e}", e.cost);
        let secs = t0.elapsed().as_secs_f64();
        let cpu = cpu_seconds() - c0;
        let err = space.error_pct(&e.genome, &tv);
        let at_bound: Vec<&str> = space
            .unknowns
            .iter()
            .zip(&e.genome)
            .filter(|(u, z)| {
                let (lo, hi) = u.internal_bounds();
                (**z - lo).abs() < 1e-9 * (hi - lo) || (hi - **z).abs() < 1e-9 * (hi - lo)
            })
            .map(|(u, _)| u.name.as_str())
            .collect();
        println!("  at a bound: {at_bound:?}");
        let errs: Vec<String> = space
            .unknowns
            .iter()
            .zip(&e.genome)
            .map(|(u, z)| format!("{:.2}", 100.0 * (u.from_internal(*z) / tv[u.slot] - 1.0)))
            .collect();
        println!("  error % {}", errs.join(" "));
        // The intervals the line check widened, with the truth: inside or not.
        for w in &e.widened {
            let u = &space.unknowns[w.unknown];
            println!(
                "  widened {}: Wald [{:.4e}, {:.4e}] -> [{:.4e}, {:.4e}] (rises {:.2}/{:.2}), truth {:.4e}",
                u.name, w.wald.0, w.wald.1, e.intervals[w.unknown].0, e.intervals[w.unknown].1,
                w.rise[0], w.rise[1], tv[u.slot]
            );
        }
        let rel_se: Vec<String> = space
            .unknowns
            .iter()
            .zip(&e.stderr)
            .map(|(u, s)| format!("{:.2}", 100.0 * s / tv[u.slot]))
            .collect();
        // The Cramér–Rao bound on the mean parameter error for this observation pattern (the
        // noise bench's formula), at the truth, after the timed fit.
        let t0 = Instant::now();
        let truths: Vec<f64> = space.unknowns.iter().map(|u| tv[u.slot]).collect();
        let bound = pool
            .install(|| cramer_rao(&truth, &space, std::slice::from_ref(&take), sigma))
            .map_or(f64::NAN, |sd| expected_error_pct(&sd, &truths));
        let bound_secs = t0.elapsed().as_secs_f64();
        println!(
            "{side}x{side} x {frames} frames{}, seed {seed}, σ = {rel:e} of {:.3} m: \
             output-error {err:.4} % in {secs:.1} s wall, {cpu:.1} s CPU ({}, {} it, {} ev, σ̂/σ {:.3}) | \
             short-cost {short_err:.2} % in {short_secs:.1} s | ratio {:.0}× | Cramér–Rao bound \
             {bound:.2} % ({:.1}× the bound; {bound_secs:.0} s)\n  stderr % {}\n  {}",
            if limit { " (Provot limit)" } else { "" },
            traj.scale(),
            e.end,
            e.iterations,
            e.evaluations,
            e.sigma / sigma,
            short_err / err,
            err / bound,
            rel_se.join(" "),
            e.start
        );
    }
}
