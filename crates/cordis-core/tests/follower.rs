//! The follower (thesis §6.1.2): the visio-motor loop brings the mobile to its target.
//!
//! `cargo test --release -p cordis-core --test follower`

use cordis_core::examples::{
    follower_distance, follower_moving, follower_with_target, FOLLOWER_BODY_LENGTH,
    FOLLOWER_FRAMES,
};

#[test]
fn probe() {
    let d = 10.0 * FOLLOWER_BODY_LENGTH;
    for deg in [0.0f64, 90.0, 180.0, 270.0] {
        let a = deg.to_radians();
        let traj = follower_with_target([d * a.cos(), d * a.sin(), 0.0])
            .simulate(FOLLOWER_FRAMES)
            .unwrap();
        let ds: Vec<String> = (0..=8)
            .map(|k| format!("{:.2}", follower_distance(&traj, (k * 1000).min(FOLLOWER_FRAMES - 1))))
            .collect();
        println!("{deg}: {}", ds.join(" "));
    }
    let _ = follower_moving;
}
