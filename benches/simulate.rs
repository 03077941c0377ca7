//! Simulation throughput (link-steps per second) of the CORDIS integrator on the shipped
//! examples. `cargo bench --bench simulate`; figures in BENCHMARKS.md.

use cordis_core::{examples, Plan, Scene};
use criterion::{criterion_group, criterion_main, Criterion, Throughput};

/// Active link evaluations per step, averaged over the run: listed links plus the conditional
/// pairs found in range (counted once, outside the timed loop).
fn link_evals_per_step(scene: &Scene, plan: &Plan, steps: usize) -> f64 {
    let p = scene.param_values();
    let mut scratch = plan.scratch();
    let (mut x, mut xp) = (plan.x0.clone(), plan.x_minus1.clone());
    let mut pairs = 0usize;
    for _ in 0..steps {
        for (c, grid) in plan.conditionals.iter().zip(scratch.grids.iter_mut()) {
            c.for_each_active_pair(&p, &x, grid, |_, _, _| pairs += 1);
        }
        plan.step(&p, &mut x, &mut xp, &mut scratch);
    }
    plan.num_links() as f64 + pairs as f64 / steps as f64
}

fn bench_scene(c: &mut Criterion, name: &str, scene: Scene, steps: usize) {
    let plan = Plan::compile(&scene).unwrap();
    let p = scene.param_values();
    let per_step = link_evals_per_step(&scene, &plan, steps);
    let mut g = c.benchmark_group("simulate");
    g.throughput(Throughput::Elements((per_step * steps as f64) as u64));
    g.sample_size(20);
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        g.bench_function(format!("{name}_{steps}steps_{threads}thread"), |b| {
            let mut scratch = plan.scratch();
            b.iter(|| {
                pool.install(|| {
                    let mut x = plan.x0.clone();
                    let mut xp = plan.x_minus1.clone();
                    for _ in 0..steps {
                        plan.step(&p, &mut x, &mut xp, &mut scratch);
                    }
                    x
                })
            })
        });
    }
    g.finish();
}

fn benches(c: &mut Criterion) {
    bench_scene(c, "cloth32", examples::cloth(32, 32), 100);
    bench_scene(c, "fluid", examples::by_name("fluid").unwrap(), 20);
}

criterion_group!(simulate, benches);
criterion_main!(simulate);
