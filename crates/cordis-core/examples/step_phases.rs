//! Where a simulation step of the 32×32 cloth spends its time, in on-CPU time of this thread
//! (`/proc/thread-self/schedstat`, Linux), so other processes' load does not count.
//!
//! `cargo run --release -p cordis-core --example step_phases`

use cordis_core::{examples, Plan, Vec3};

/// On-CPU time of this thread, s.
fn cpu() -> f64 {
    let s = std::fs::read_to_string("/proc/thread-self/schedstat").expect("Linux schedstat");
    let ns: f64 = s
        .split_whitespace()
        .next()
        .unwrap_or("0")
        .parse()
        .unwrap_or(0.0);
    ns * 1e-9
}

fn per_call(n: usize, mut f: impl FnMut()) -> f64 {
    let start = cpu();
    for _ in 0..n {
        f();
    }
    (cpu() - start) / n as f64
}

fn main() {
    let scene = examples::cloth(32, 32);
    let mut plan = Plan::compile(&scene).expect("valid example");
    plan.split = None; // one thread: the sequential path
    let p = scene.param_values();
    let mut s = plan.scratch();
    let (mut x, mut xp) = (plan.x0.clone(), plan.x_minus1.clone());
    for _ in 0..200 {
        plan.step(&p, &mut x, &mut xp, &mut s);
    }
    let n = 2000;
    let vel = per_call(n, || plan.velocities(&x, &xp, &mut s.v));
    let springs = per_call(n, || {
        s.f.fill(Vec3::zeros());
        plan.springs.accumulate(&p, &x, &s.v, &mut s.f);
    });
    let copy = per_call(n, || {
        std::hint::black_box(x.clone());
    });
    let provot = per_call(n, || {
        let mut y = x.clone();
        plan.provot.apply(&p, &mut y, &plan.free);
        std::hint::black_box(&y);
    }) - copy;
    let step = per_call(n, || {
        plan.step(&p, &mut x, &mut xp, &mut s);
    });
    let links = plan.num_links() as f64;
    println!(
        "cloth 32x32, {} springs, on-CPU per step: velocities {:.1} us, springs {:.1} us \
         ({:.0} M springs/s), Provot pass {:.1} us, whole step {:.1} us ({:.0} M link-steps/s)",
        plan.num_links(),
        vel * 1e6,
        springs * 1e6,
        links / springs / 1e6,
        provot * 1e6,
        step * 1e6,
        links / step / 1e6
    );
}
