//! Provot's elongation limit (SPEC §2.2, thesis §4.2) on hand-computed cases. Numbers are
//! dyadic where possible so the expected positions are exact.

use approx::assert_relative_eq;
use cordis_core::forces::provot::{ProvotLink, ProvotPass};
use cordis_core::{LinkKind, LinkType, OptionalParam, Particle, Scene, Vec3};

/// A pass over `links` (pairs) of one spring type whose parameters start at offset 3 of the
/// parameter vector (rest length at 4), with critical deformation `tau` (slot 6, after the
/// vector of [`params`]).
fn pass(links: &[[u32; 2]], tau: f64) -> Limited {
    Limited(
        ProvotPass {
            links: links
                .iter()
                .map(|&[i, j]| ProvotLink {
                    i,
                    j,
                    param: 3,
                    tau: 6,
                })
                .collect(),
        },
        tau,
    )
}

/// A pass and its τc, appended to the parameter vector it is applied with.
struct Limited(ProvotPass, f64);

impl Limited {
    fn apply(&self, p: &[f64], x: &mut [Vec3], free: &[bool]) {
        let mut with_tau = p.to_vec();
        with_tau.push(self.1);
        self.0.apply(&with_tau, x, free);
    }
}

/// Parameter vector with another type first, then the spring: K, l0, Z.
fn params(l0: f64) -> Vec<f64> {
    vec![7.0, 9.0, 11.0, 20.0, l0, 0.5]
}

fn v(x: f64, y: f64, z: f64) -> Vec3 {
    Vec3::new(x, y, z)
}

#[test]
fn free_free_moves_each_end_half_the_excess() {
    // L = 5 along (0, 0.6, 0.8), limit (1 + 0.5) 2 = 3, excess 2: each end moves 1.
    let mut x = vec![v(0.0, 0.0, 0.0), v(0.0, 3.0, 4.0)];
    pass(&[[0, 1]], 0.5).apply(&params(2.0), &mut x, &[true, true]);
    assert_relative_eq!(x[0], v(0.0, 0.6, 0.8), epsilon = 1e-15);
    assert_relative_eq!(x[1], v(0.0, 2.4, 3.2), epsilon = 1e-15);
    assert_relative_eq!((x[1] - x[0]).norm(), 3.0, epsilon = 1e-15);
}

#[test]
fn free_fixed_moves_the_free_end_the_whole_excess() {
    let start = vec![v(0.0, 0.0, 0.0), v(0.0, 3.0, 4.0)];
    // i fixed: j comes 2 toward i.
    let mut x = start.clone();
    pass(&[[0, 1]], 0.5).apply(&params(2.0), &mut x, &[false, true]);
    assert_eq!(x[0], start[0]);
    assert_relative_eq!(x[1], v(0.0, 1.8, 2.4), epsilon = 1e-15);
    // j fixed: i goes 2 toward j.
    let mut x = start.clone();
    pass(&[[0, 1]], 0.5).apply(&params(2.0), &mut x, &[true, false]);
    assert_relative_eq!(x[0], v(0.0, 1.2, 1.6), epsilon = 1e-15);
    assert_eq!(x[1], start[1]);
    // Both fixed: nothing moves.
    let mut x = start.clone();
    pass(&[[0, 1]], 0.5).apply(&params(2.0), &mut x, &[false, false]);
    assert_eq!(x, start);
}

#[test]
fn links_at_or_under_the_limit_are_left_alone() {
    // Limit (1 + 0.25) 2 = 2.5 exactly; a link of exactly 2.5 and a compressed one.
    let start = vec![v(0.0, 0.0, 0.0), v(2.5, 0.0, 0.0), v(2.5, 0.5, 0.0)];
    let mut x = start.clone();
    pass(&[[0, 1], [1, 2]], 0.25).apply(&params(2.0), &mut x, &[true; 3]);
    assert_eq!(x, start);
}

#[test]
fn a_chain_is_corrected_in_file_order_each_correction_seen_by_the_next() {
    // Limit (1 + 0.25) 1 = 1.25. Start 0, 2, 3.5 on the x axis.
    let start = vec![v(0.0, 0.0, 0.0), v(2.0, 0.0, 0.0), v(3.5, 0.0, 0.0)];
    let p = params(1.0);
    let xs = |x: &[Vec3]| x.iter().map(|q| q.x).collect::<Vec<_>>();

    // [0,1] first: L = 2, excess 0.75 → 0.375, 1.625. Then [1,2] sees 1.625:
    // L = 1.875, excess 0.625 → 1.9375, 3.1875.
    let mut x = start.clone();
    pass(&[[0, 1], [1, 2]], 0.25).apply(&p, &mut x, &[true; 3]);
    assert_eq!(xs(&x), [0.375, 1.9375, 3.1875]);

    // [1,2] first: L = 1.5, excess 0.25 → 2.125, 3.375. Then [0,1] sees 2.125:
    // L = 2.125, excess 0.875 → 0.4375, 1.6875.
    let mut x = start.clone();
    pass(&[[1, 2], [0, 1]], 0.25).apply(&p, &mut x, &[true; 3]);
    assert_eq!(xs(&x), [0.4375, 1.6875, 3.375]);

    // With particle 0 fixed: [0,1] moves 1 the whole 0.75 → 1.25; [1,2]: L = 2.25,
    // excess 1 → 1.75, 3.0. One pass only: [0,1] is left stretched again (1.75 > 1.25).
    let mut x = start.clone();
    pass(&[[0, 1], [1, 2]], 0.25).apply(&p, &mut x, &[false, true, true]);
    assert_eq!(xs(&x), [0.0, 1.75, 3.0]);
}

#[test]
fn the_correction_also_corrects_the_velocity() {
    // K = 0, so only the limit acts. The ends fly apart at 1 m/s each; dt = 0.25 s.
    // Step 1 predicts -0.25 and 1.5 (L = 1.75 > 1.25): each end moves back 0.25, so
    // x(1) = x(0), and since x(0) is not changed, v(1) = 0: the particles stop.
    let mut s = Scene::new(0.25);
    s.add_particle(Particle::new(1.0, [0.0, 0.0, 0.0]).with_vel([-1.0, 0.0, 0.0]));
    s.add_particle(Particle::new(1.0, [1.25, 0.0, 0.0]).with_vel([1.0, 0.0, 0.0]));
    let mut t = LinkType::new("s", LinkKind::Spring)
        .with("stiffness", 0.0)
        .with("rest_length", 1.0);
    t.set_optional(OptionalParam::MaxElongation, Some(0.25.into()));
    s.add_type(t);
    s.add_link("s", &[0, 1]);
    let traj = s.simulate(5).unwrap();
    for n in 0..5 {
        assert_eq!(traj.pos(n, 0), v(0.0, 0.0, 0.0), "frame {n}");
        assert_eq!(traj.pos(n, 1), v(1.25, 0.0, 0.0), "frame {n}");
    }
    // Without the limit they fly apart.
    s.types[0].set_optional(OptionalParam::MaxElongation, None);
    let free = s.simulate(5).unwrap();
    assert_eq!(free.pos(4, 1).x, 1.25 + 4.0 * 0.25);
}

#[test]
fn a_scene_applies_the_limit_after_the_position_update_in_link_order() {
    // The chain case through a scene: K = 0 and no velocity, so x(1) = x(0) before the
    // correction, and the correction gives the hand-computed chain result.
    let mut s = Scene::new(0.01);
    for x in [0.0, 2.0, 3.5] {
        s.add_particle(Particle::new(1.0, [x, 0.0, 0.0]));
    }
    s.particles[0].fixed = true;
    let mut t = LinkType::new("s", LinkKind::Spring)
        .with("stiffness", 0.0)
        .with("rest_length", 1.0);
    t.set_optional(OptionalParam::MaxElongation, Some(0.25.into()));
    s.add_type(t);
    s.add_link("s", &[0, 1]);
    s.add_link("s", &[1, 2]);
    let traj = s.simulate(2).unwrap();
    assert_eq!(traj.pos(0, 1).x, 2.0);
    assert_eq!(
        [traj.pos(1, 0).x, traj.pos(1, 1).x, traj.pos(1, 2).x],
        [0.0, 1.75, 3.0]
    );
}

#[test]
fn coincident_ends_are_never_corrected_into_nan() {
    // A zero rest length with a zero limit: coincident ends have L = 0, no excess; a link
    // shorter than 1e-12 has no direction and must not produce NaN either.
    let mut x = vec![v(1.0, 1.0, 1.0), v(1.0, 1.0, 1.0 + 1e-13)];
    pass(&[[0, 1]], 0.1).apply(&params(0.0), &mut x, &[true, true]);
    assert!(x.iter().all(|q| q.iter().all(|c| c.is_finite())));
}
