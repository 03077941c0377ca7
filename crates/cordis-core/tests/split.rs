//! Large scenes split a step's force work in two fixed halves: the result must not depend on
//! the thread count, and must equal the sequential step up to summation order.

use cordis_core::{examples, Plan, Scene, Simulator, Trajectory};

fn simulate_with(threads: usize, scene: &Scene, frames: usize, split: bool) -> Trajectory {
    let mut plan = Plan::compile(scene).unwrap();
    if !split {
        plan.split = None;
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        Simulator::from_plan(plan, scene.param_values())
            .run(frames)
            .unwrap()
    })
}

fn bits(t: &Trajectory) -> Vec<u64> {
    t.as_flat().iter().map(|v| v.to_bits()).collect()
}

#[test]
fn split_steps_are_bit_identical_on_one_and_two_threads() {
    for (scene, frames) in [(examples::cloth(32, 32), 60), (examples::fluid(40, 24), 30)] {
        assert!(
            Plan::compile(&scene).unwrap().split.is_some(),
            "large enough to split"
        );
        let one = simulate_with(1, &scene, frames, true);
        let two = simulate_with(2, &scene, frames, true);
        assert_eq!(bits(&one), bits(&two));
        // Against the sequential path: only the summation order differs.
        let seq = simulate_with(1, &scene, frames, false);
        let scale = seq.scale();
        let diff = one
            .as_flat()
            .iter()
            .zip(seq.as_flat())
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(diff <= 1e-9 * scale, "diff {diff} vs scale {scale}");
    }
}

#[test]
fn small_scenes_take_the_sequential_path() {
    assert!(Plan::compile(&examples::rigid()).unwrap().split.is_none());
}
