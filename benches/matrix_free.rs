//! The matrix-free Gauss–Newton product `H v = Jᵀ W² J v` of a large output-error fit: one
//! directional tangent rollout and one adjoint pass over the stored linearisation
//! (`cordis_es::output_error::matrix_free`), what every conjugate-gradient iteration of the
//! 32×32 cloth's fit applies (~6,000 times per fit) and the standard-error solves apply 12 wide.
//! The cloth example without its Provot limit, 100 frames, σ = 1e-3 of its size, every link
//! parameter unknown (5,976 variables), at the fit's start point. Throughput is in link
//! evaluations (springs × steps × 2 passes × width); on 2 threads, as `cordis identify` runs.
//!
//! `cargo bench --bench matrix_free` (add `-- --quick` for a short run).

use cordis_core::examples::cloth;
use cordis_core::OptionalParam;
use cordis_es::identify::{add_noise, with_unknown_boxes};
use cordis_es::output_error::{Config, Prepared, Take};
use cordis_es::space::ParameterSpace;
use criterion::{criterion_group, criterion_main, Criterion, Throughput};

const FRAMES: usize = 100;

fn bench_product(c: &mut Criterion) {
    let mut truth = cloth(32, 32);
    for t in &mut truth.types {
        t.set_optional(OptionalParam::MaxElongation, None);
    }
    let traj = truth.simulate(FRAMES).expect("the cloth simulates");
    let noisy = add_noise(&traj, 1e-3 * traj.scale(), 0);
    let guess = with_unknown_boxes(&truth, 25.0, 0);
    let space = ParameterSpace::from_scene(&guess);
    let config = Config::default();
    let prepared = Prepared::new(&guess, &space, vec![Take::complete(&noisy)], &config)
        .expect("the fit prepares");
    let progress = prepared
        .start(&guess, &space, &config)
        .expect("the fit starts");
    let springs = guess.links.len() as u64;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .expect("a pool of 2 threads");
    let mut g = c.benchmark_group("matrix-free/cloth32x32/100 frames");
    g.sample_size(20);
    prepared
        .with_gauss_newton_product(&space, &progress, |len, hv| {
            for width in [1usize, 12] {
                let v: Vec<f64> = (0..len * width)
                    .map(|a| ((a * 7919) % 1000) as f64 / 500.0 - 1.0)
                    .collect();
                let mut out = vec![0.0; len * width];
                let links = springs * (FRAMES as u64 - 1) * 2 * width as u64;
                g.throughput(Throughput::Elements(links));
                g.bench_function(format!("H v, width {width}, 2 threads"), |b| {
                    b.iter(|| pool.install(|| hv(&v, width, &mut out)))
                });
            }
        })
        .expect("the rollout at the start point does not diverge");
    g.finish();
}

criterion_group!(benches, bench_product);
criterion_main!(benches);
