//! The tadpole (thesis §5.1): an asymmetric sawtooth on its TGR makes it swim, a symmetric
//! triangle of the same amplitude only makes it oscillate in place; and its first 100 frames
//! bracket the medium's `v_max` within 1% (what Table 6.1's identification needs).

use cordis_core::examples::{
    tadpole, tadpole_vmax_bracket, tadpole_with, TADPOLE_BODY_LENGTH, TADPOLE_FRAMES,
};
use cordis_core::{Scene, Shape, Trajectory};

/// Displacement (m) of the particles' mean position along x between the first and last frame.
fn travel(traj: &Trajectory) -> f64 {
    let last = traj.frames() - 1;
    let mean = |t: usize| 0.5 * (traj.pos(t, 0).x + traj.pos(t, 1).x);
    mean(last) - mean(0)
}

fn run(scene: &Scene) -> Trajectory {
    scene.simulate(TADPOLE_FRAMES).unwrap()
}

#[test]
fn the_sawtooth_swims_at_least_two_body_lengths() {
    let traj = run(&tadpole());
    let d = travel(&traj) / TADPOLE_BODY_LENGTH;
    assert!(d >= 2.0, "travelled {d} body lengths");
    // Towards its light end (+x), on a straight line, and the body holds together.
    for t in 0..traj.frames() {
        let (a, b) = (traj.pos(t, 0), traj.pos(t, 1));
        assert!(a.y == 0.0 && a.z == 0.0 && b.y == 0.0 && b.z == 0.0);
        let l = (b - a).norm();
        assert!((0.5..1.5).contains(&l), "frame {t}: length {l}");
    }
}

#[test]
fn a_symmetric_triangle_only_oscillates_in_place() {
    let traj = run(&tadpole_with(Shape::Triangle));
    let d = travel(&traj).abs() / TADPOLE_BODY_LENGTH;
    assert!(d < 0.2, "travelled {d} body lengths");
    // It does move: the stroke is there, only the net travel is not.
    let swing = (0..traj.frames())
        .map(|t| (traj.pos(t, 1) - traj.pos(t, 0)).norm())
        .fold((f64::MAX, 0.0f64), |(lo, hi), l| (lo.min(l), hi.max(l)));
    assert!(swing.1 - swing.0 > 0.2, "length range {swing:?}");
}

#[test]
fn the_first_hundred_frames_bracket_vmax_within_one_percent() {
    let traj = tadpole().simulate(100).unwrap();
    let (below, above) = tadpole_vmax_bracket(&traj, 0.5);
    let (below, above) = (below.unwrap(), above.unwrap());
    assert!(below >= 0.495 && above <= 0.505, "({below}, {above}]");
}
