//! Simulation throughput (link-steps per second) of the CORDIS integrator.
//!
//! `cargo bench --bench simulate`. The figure that matters is link-steps/s on a 32×32 cloth
//! (≈5,800 springs): see BENCHMARKS.md.

use cordis_core::{LinkKind, LinkType, Particle, Plan, Scene};
use criterion::{criterion_group, criterion_main, Criterion, Throughput};

/// A plain 32×32 spring cloth (structural, shear, bend), pinned along one edge.
pub fn grid_cloth(nx: usize, ny: usize) -> Scene {
    let mut s = Scene::new(1e-3);
    s.gravity = [0.0, 0.0, -9.81];
    let h = 0.05;
    for j in 0..ny {
        for i in 0..nx {
            let mut p = Particle::new(0.01, [i as f64 * h, j as f64 * h, 0.0]);
            if j == ny - 1 {
                p = p.fixed();
            }
            s.add_particle(p);
        }
    }
    let d = h * std::f64::consts::SQRT_2;
    for (name, l0, z) in [("st", h, 0.01), ("sh", d, 0.0), ("be", 2.0 * h, 0.0)] {
        s.add_type(
            LinkType::new(name, LinkKind::Spring)
                .with("stiffness", 50.0)
                .with("rest_length", l0)
                .with("damping", z),
        );
    }
    let id = |i: usize, j: usize| j * nx + i;
    for j in 0..ny {
        for i in 0..nx {
            if i + 1 < nx {
                s.add_link("st", &[id(i, j), id(i + 1, j)]);
            }
            if j + 1 < ny {
                s.add_link("st", &[id(i, j), id(i, j + 1)]);
            }
            if i + 1 < nx && j + 1 < ny {
                s.add_link("sh", &[id(i, j), id(i + 1, j + 1)]);
                s.add_link("sh", &[id(i + 1, j), id(i, j + 1)]);
            }
            if i + 2 < nx {
                s.add_link("be", &[id(i, j), id(i + 2, j)]);
            }
            if j + 2 < ny {
                s.add_link("be", &[id(i, j), id(i, j + 2)]);
            }
        }
    }
    s
}

fn bench_cloth(c: &mut Criterion) {
    let scene = grid_cloth(32, 32);
    let plan = Plan::compile(&scene).unwrap();
    let p = scene.param_values();
    let steps = 100;
    let mut g = c.benchmark_group("simulate");
    g.throughput(Throughput::Elements((plan.num_links() * steps) as u64));
    g.bench_function("cloth32_100steps_1thread", |b| {
        let mut scratch = plan.scratch();
        b.iter(|| {
            let mut x = plan.x0.clone();
            let mut xp = plan.x_minus1.clone();
            for _ in 0..steps {
                plan.step(&p, &mut x, &mut xp, &mut scratch);
            }
            x
        })
    });
    g.finish();
}

criterion_group!(benches, bench_cloth);
criterion_main!(benches);
