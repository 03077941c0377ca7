//! Probe: output-error estimates against the Cramér–Rao bound on generated networks.
use std::time::Instant;

use cordis_core::examples::random_network;
use cordis_core::Param;
use cordis_es::identify::{add_noise, with_unknown_boxes};
use cordis_es::output_error::{cramer_rao, estimate, expected_error_pct, Config, Take};
use cordis_es::space::ParameterSpace;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let rel: f64 = args.get(1).map_or(1e-3, |s| s.parse().unwrap());
    let seeds: u64 = args.get(2).map_or(5, |s| s.parse().unwrap());
    let masses: usize = args.get(3).map_or(12, |s| s.parse().unwrap());
    let missing: f64 = args.get(4).map_or(0.0, |s| s.parse().unwrap());
    let hidden: f64 = args.get(5).map_or(0.0, |s| s.parse().unwrap());
    for seed in 0..seeds {
        let mut truth = random_network(100 + seed, masses, 7);
        for (k, t) in truth.types.iter_mut().enumerate() {
            t.params[2] = Param::Known(0.05 + 0.04 * k as f64);
        }
        let traj = truth.simulate(200).unwrap();
        let sigma = rel * traj.scale();
        let noisy = if sigma > 0.0 {
            add_noise(&traj, sigma, seed)
        } else {
            traj.clone()
        };
        let guess = with_unknown_boxes(&truth, 25.0, seed);
        let space = ParameterSpace::from_scene(&guess);
        let n = truth.num_particles();
        let hide: Vec<bool> = (0..n)
            .map(|i| i > 0 && (i as f64) < 1.0 + hidden * (n as f64))
            .collect();
        let take = Take::complete(&noisy).masked(|t, i, c| {
            let h =
                (t as u64 * 7919 + i as u64 * 104729 + c as u64 * 1299709 + seed * 15485863) % 1000;
            !hide[i] && (h as f64) >= missing * 1000.0
        });
        let t0 = Instant::now();
        let est = estimate(
            &guess,
            &space,
            std::slice::from_ref(&take),
            &Config::default(),
        );
        let secs = t0.elapsed().as_secs_f64();
        let tv = truth.param_values();
        let values: Vec<f64> = space.unknowns.iter().map(|u| tv[u.slot]).collect();
        let crb = if sigma > 0.0 {
            let sd = cramer_rao(&truth, &space, &[take], sigma).unwrap();
            expected_error_pct(&sd, &values)
        } else {
            0.0
        };
        match est {
            Ok(e) => {
                let err = space.error_pct(&e.genome, &tv);
                println!(
                    "seed {seed} σ/size {rel:e}: error {err:.4} % CRB {crb:.4} % ratio {:.2} | σ̂/σ {:.3} noise0/σ {:.3} {} it {} ev {} {:.3} s | {}",
                    err / crb,
                    e.sigma / sigma,
                    e.noise_level[0] / sigma,
                    e.end,
                    e.iterations,
                    e.evaluations,
                    secs,
                    e.start
                );
            }
            Err(er) => println!("seed {seed}: error {er}"),
        }
    }
}
