//! The frog (thesis §5.1, Figure 5.2): straight when both TGRs run alike, turning when one
//! runs faster.

use cordis_core::examples::{frog, frog_heading, frog_with, FROG_FRAMES};
use cordis_core::Trajectory;

fn centre_travel(traj: &Trajectory) -> f64 {
    let c = |t: usize| (0..4).map(|i| traj.pos(t, i)).sum::<cordis_core::Vec3>() / 4.0;
    (c(traj.frames() - 1) - c(0)).norm()
}

#[test]
fn driven_alike_it_swims_straight() {
    let traj = frog().simulate(FROG_FRAMES).unwrap();
    let h = frog_heading(&traj, FROG_FRAMES - 1);
    assert!(h.abs() < 2f64.to_radians(), "heading {}°", h.to_degrees());
    assert!(
        centre_travel(&traj) >= 1.5,
        "travel {}",
        centre_travel(&traj)
    );
}

#[test]
fn a_faster_side_turns_it_towards_the_other_side() {
    // The right side strokes faster: the frog turns left (counter-clockwise), and the mirror
    // image turns right by the same angle.
    let right_fast = frog_with(4.0, 3.0).simulate(FROG_FRAMES).unwrap();
    let left_fast = frog_with(3.0, 4.0).simulate(FROG_FRAMES).unwrap();
    let (a, b) = (
        frog_heading(&right_fast, FROG_FRAMES - 1),
        frog_heading(&left_fast, FROG_FRAMES - 1),
    );
    assert!(
        a > 20f64.to_radians(),
        "right faster: heading {}°",
        a.to_degrees()
    );
    assert!((a + b).abs() < 1e-6, "mirror images: {a} vs {b}");
}
