//! `cordis bench cost`: cost-function throughput on the shipped examples (SPEC §3; the
//! bottleneck of identification, thesis Annexe 2).
//!
//! One JSON line per measurement: `scene, kind, path (generic | precomputed), links, frames,
//! evals, seconds, link_evals_per_s, threads, batch`. A link evaluation is one link (or one
//! active conditional pair, counted on the observed frames) at one predicted step. Each figure
//! is the median of `--repeats` timings of at least `--min-seconds` each.

use std::time::Instant;

use anyhow::Result;
use cordis_core::{examples, Plan, Scene};
use cordis_es::cost::{CostKind, Objective};
use serde_json::json;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scenes (shipped examples): rigid, cloth, fluid, horse.
    #[arg(long, value_delimiter = ',', default_value = "rigid,cloth,fluid,horse")]
    scenes: Vec<String>,
    /// Cost kinds.
    #[arg(
        long,
        value_delimiter = ',',
        default_value = "short,horizon:5,long,harmonic"
    )]
    kinds: Vec<String>,
    /// Observed frames (fluid: at most 20 by default, it is heavy).
    #[arg(long, default_value_t = 100)]
    frames: usize,
    /// Population size of the batch measurements.
    #[arg(long, default_value_t = 16)]
    batch: usize,
    /// Timings per figure (the median is reported).
    #[arg(long, default_value_t = 5)]
    repeats: usize,
    /// Minimum duration of one timing, s.
    #[arg(long, default_value_t = 0.2)]
    min_seconds: f64,
}

pub fn run(a: Args) -> Result<()> {
    eprintln!(
        "{:<7} {:<10} {:<11} {:>7} {:>6} {:>8} {:>12} {:>14}",
        "scene", "kind", "path", "threads", "batch", "frames", "s/eval", "link-evals/s"
    );
    for name in &a.scenes {
        let scene = examples::by_name(name)
            .ok_or_else(|| anyhow::anyhow!("--scenes: no example named `{name}`"))?;
        let frames = if name == "fluid" {
            a.frames.min(20)
        } else {
            a.frames
        };
        let traj = scene.simulate(frames)?;
        let pairs = observed_pairs(&scene, &traj);
        let p = scene.param_values();
        for kind in &a.kinds {
            let kind: CostKind = kind.parse().map_err(|e| anyhow::anyhow!("--kinds: {e}"))?;
            let mut objective = Objective::new(&scene, &traj, kind)?;
            let mut paths = vec![("generic", false)];
            if objective.uses_linear(&p) {
                paths.push(("precomputed", true));
            }
            for (path, linear) in paths {
                objective.set_linear(linear);
                let steps = objective.terms() / count_free(&scene).max(1);
                let link_evals = (Plan::compile(&scene)?.num_links() as f64
                    + pairs / traj.frames().max(1) as f64)
                    * steps as f64;
                for threads in [1, 2] {
                    for batch in [1, a.batch] {
                        if batch == 1 && threads == 2 {
                            continue; // one evaluation runs on one thread
                        }
                        let pool = rayon::ThreadPoolBuilder::new()
                            .num_threads(threads)
                            .build()?;
                        let per_eval = pool.install(|| time_per_eval(&objective, &p, batch, &a))?;
                        let rate = link_evals / per_eval;
                        eprintln!(
                            "{:<7} {:<10} {:<11} {:>7} {:>6} {:>8} {:>12.3e} {:>14.3e}",
                            name,
                            kind.to_string(),
                            path,
                            threads,
                            batch,
                            traj.frames(),
                            per_eval,
                            rate
                        );
                        println!(
                            "{}",
                            json!({
                                "bench": "cost", "scene": name, "kind": kind.to_string(),
                                "path": path, "links": link_evals / steps.max(1) as f64,
                                "frames": traj.frames(), "evals": 1, "seconds": per_eval,
                                "link_evals_per_s": rate, "threads": threads, "batch": batch,
                            })
                        );
                    }
                }
            }
        }
    }
    Ok(())
}

fn count_free(scene: &Scene) -> usize {
    scene.particles.iter().filter(|p| !p.fixed).count()
}

/// Active conditional pairs summed over the observed frames.
fn observed_pairs(scene: &Scene, traj: &cordis_core::Trajectory) -> f64 {
    let Ok(plan) = Plan::compile(scene) else {
        return 0.0;
    };
    let p = scene.param_values();
    let mut grids = plan.scratch().grids;
    let mut x = vec![cordis_core::Vec3::zeros(); plan.n];
    let mut n = 0usize;
    for t in 0..traj.frames() {
        traj.frame_into(t, &mut x);
        for (c, g) in plan.conditionals.iter().zip(grids.iter_mut()) {
            c.for_each_active_pair(&p, &x, g, |_, _, _| n += 1);
        }
    }
    n as f64
}

/// Median wall time of one evaluation: single calls (batch 1) or `evaluate_batch`.
fn time_per_eval(objective: &Objective, p: &[f64], batch: usize, a: &Args) -> Result<f64> {
    let mut scratch = objective.scratch();
    let mut local = vec![0.0; objective.particles()];
    let population: Vec<f64> = (0..batch).flat_map(|_| p.iter().copied()).collect();
    let mut out = vec![0.0; batch];
    let mut once = || -> Result<()> {
        if batch == 1 {
            std::hint::black_box(objective.evaluate(p, &mut scratch, &mut local)?);
        } else {
            objective.evaluate_batch(&population, &mut out)?;
            std::hint::black_box(&out);
        }
        Ok(())
    };
    once()?; // warm-up (builds lazily precomputed geometry)
    let mut samples = Vec::with_capacity(a.repeats);
    for _ in 0..a.repeats.max(1) {
        let start = Instant::now();
        let mut n = 0usize;
        while start.elapsed().as_secs_f64() < a.min_seconds || n == 0 {
            once()?;
            n += batch;
        }
        samples.push(start.elapsed().as_secs_f64() / n as f64);
    }
    samples.sort_by(f64::total_cmp);
    Ok(samples[samples.len() / 2])
}
