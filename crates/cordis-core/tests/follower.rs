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
            .map(|k| {
                let t = (k * 1000).min(FOLLOWER_FRAMES - 1);
                let ax = traj.pos(t, 0) - traj.pos(t, 1);
                let to = traj.pos(t, 5) - traj.pos(t, 0);
                let g = traj.pos(t, 11) - traj.pos(t, 6);
                let vt = traj.pos(t, 10) - traj.pos(t, 6);
                format!(
                    "{:.2}[ax{:.0} to{:.0} g{:.0} vt{:.0} {:.1}]",
                    follower_distance(&traj, t),
                    ax.y.atan2(ax.x).to_degrees(),
                    to.y.atan2(to.x).to_degrees(),
                    g.y.atan2(g.x).to_degrees(),
                    vt.y.atan2(vt.x).to_degrees(),
                    vt.norm()
                )
            })
            .collect();
        println!("{deg}: {}", ds.join(" "));
    }
    let _ = follower_moving;
}
