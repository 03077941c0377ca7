//! The cost function, the identification bottleneck (SPEC §3, Annex 2): the generic short cost
//! on a 32×32 cloth over 100 frames (≈5,800 springs), single and batched on 2 threads, and the
//! precomputed linear path. Throughput is in link evaluations (links × predicted frames). The
//! generic path runs with and without its precomputed spring geometry.
//!
//! A second group runs every cost kind on every shipped example (rigid, cloth 32×32, fluid,
//! horse) on the generic path, plus the precomputed path where the scene allows it, single
//! evaluation and a batch of 16 on 2 threads. `cordis bench cost` prints the same measurements
//! as JSON lines.
//!
//! `cargo bench --bench cost` (add `-- --quick` for a short run).

use cordis_core::{examples, LinkKind, LinkType, Particle, Scene};
use cordis_es::cost::{CostKind, Objective};
use criterion::{criterion_group, criterion_main, Criterion, Throughput};

/// A `w × w` cloth hanging from two corners: structural, shear and bend springs, gravity.
fn cloth(w: usize) -> Scene {
    let mut s = Scene::new(0.005);
    s.gravity = [0.0, -9.81, 0.0];
    let a = 0.1;
    for r in 0..w {
        for c in 0..w {
            let mut p = Particle::new(0.01, [c as f64 * a, 0.0, r as f64 * a * 0.9]);
            if r == 0 && (c == 0 || c == w - 1) {
                p = p.fixed();
            }
            s.add_particle(p);
        }
    }
    for (name, k, l0, z) in [
        ("structural", 40.0, a, 0.02),
        ("shear", 15.0, a * 2f64.sqrt(), 0.01),
        ("bend", 5.0, 2.0 * a, 0.0),
    ] {
        s.add_type(
            LinkType::new(name, LinkKind::Spring)
                .with("stiffness", k)
                .with("rest_length", l0)
                .with("damping", z),
        );
    }
    let id = |r: usize, c: usize| r * w + c;
    for r in 0..w {
        for c in 0..w {
            if c + 1 < w {
                s.add_link("structural", &[id(r, c), id(r, c + 1)]);
            }
            if r + 1 < w {
                s.add_link("structural", &[id(r, c), id(r + 1, c)]);
            }
            if r + 1 < w && c + 1 < w {
                s.add_link("shear", &[id(r, c), id(r + 1, c + 1)]);
                s.add_link("shear", &[id(r, c + 1), id(r + 1, c)]);
            }
            if c + 2 < w {
                s.add_link("bend", &[id(r, c), id(r, c + 2)]);
            }
            if r + 2 < w {
                s.add_link("bend", &[id(r, c), id(r + 2, c)]);
            }
        }
    }
    s
}

fn bench_cost(c: &mut Criterion) {
    let scene = cloth(32);
    let traj = scene.simulate(100).unwrap();
    let mut obj = Objective::new(&scene, &traj, CostKind::Short).unwrap();
    let p = scene.param_values();
    let mut g = c.benchmark_group("cost/cloth32x32/100 frames");
    g.throughput(Throughput::Elements(obj.link_evaluations() as u64));

    let mut s = obj.scratch();
    let mut per = vec![0.0; obj.particles()];
    g.bench_function("linear short, local costs", |b| {
        b.iter(|| obj.evaluate(&p, &mut s, &mut per).unwrap())
    });
    g.bench_function("linear short, total", |b| {
        b.iter(|| obj.total(&p, &mut s).unwrap())
    });

    obj.set_linear(false);
    obj.set_geometry_budget(0);
    g.bench_function("generic short, geometry computed, 1 thread", |b| {
        b.iter(|| obj.evaluate(&p, &mut s, &mut per).unwrap())
    });
    obj.set_geometry_budget(cordis_es::cost::GEOMETRY_BUDGET_BYTES);
    g.bench_function("generic short, geometry precomputed, 1 thread", |b| {
        b.iter(|| obj.evaluate(&p, &mut s, &mut per).unwrap())
    });

    let k = 8;
    let pop: Vec<f64> = (0..k).flat_map(|_| p.iter().copied()).collect();
    let mut out = vec![0.0; k];
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap();
    g.throughput(Throughput::Elements((k * obj.link_evaluations()) as u64));
    g.bench_function("generic short, batch of 8 on 2 threads", |b| {
        b.iter(|| pool.install(|| obj.evaluate_batch(&pop, &mut out).unwrap()))
    });
    g.finish();
}

fn bench_examples(c: &mut Criterion) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(2)
        .build()
        .unwrap();
    for (name, frames) in [("rigid", 100), ("cloth", 100), ("fluid", 20), ("horse", 53)] {
        let scene = examples::by_name(name).unwrap();
        let traj = scene.simulate(frames).unwrap();
        let p = scene.param_values();
        for kind in ["short", "horizon:5", "long", "harmonic"] {
            let mut obj = Objective::new(&scene, &traj, kind.parse().unwrap()).unwrap();
            let mut paths = vec![("generic", false)];
            if obj.uses_linear(&p) {
                paths.push(("precomputed", true));
            }
            let mut g = c.benchmark_group(format!("cost/{name}/{kind}"));
            g.sample_size(10);
            for (path, linear) in paths {
                obj.set_linear(linear);
                let mut s = obj.scratch();
                let mut per = vec![0.0; obj.particles()];
                g.throughput(Throughput::Elements(obj.link_evaluations().max(1) as u64));
                g.bench_function(format!("{path}, single"), |b| {
                    b.iter(|| obj.evaluate(&p, &mut s, &mut per).unwrap())
                });
                let k = 16;
                let pop: Vec<f64> = (0..k).flat_map(|_| p.iter().copied()).collect();
                let mut out = vec![0.0; k];
                g.throughput(Throughput::Elements(
                    (k * obj.link_evaluations().max(1)) as u64,
                ));
                g.bench_function(format!("{path}, batch of 16 on 2 threads"), |b| {
                    b.iter(|| pool.install(|| obj.evaluate_batch(&pop, &mut out).unwrap()))
                });
            }
            g.finish();
        }
    }
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20);
    targets = bench_cost, bench_examples
}
criterion_main!(benches);
