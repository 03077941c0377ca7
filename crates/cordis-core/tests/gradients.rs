//! Position links are conservative: the force each pass adds is minus the gradient of the
//! link's energy (SPEC §2.2), checked by central finite differences on random geometry; and
//! degenerate geometry gives zero force, never NaN.

use cordis_core::forces::{anchor::AnchorPass, angle::AnglePass, spring::SpringPass, Run};
use cordis_core::Vec3;
use proptest::prelude::*;

const RUN: Run = Run {
    param: 0,
    start: 0,
    end: 1,
};

fn spring_forces(x: &[Vec3], v: &[Vec3], k: f64, l0: f64, z: f64) -> Vec<Vec3> {
    let pass = SpringPass {
        runs: vec![RUN],
        pairs: vec![[0, 1]],
        quadratic: Vec::new(),
    };
    let mut f = vec![Vec3::zeros(); 2];
    pass.accumulate(&[k, l0, z], x, v, &mut f);
    f
}

fn anchor_forces(x: &[Vec3], v: &[Vec3], point: Vec3, k: f64, l0: f64, z: f64) -> Vec<Vec3> {
    let pass = AnchorPass {
        runs: vec![RUN],
        particles: vec![0],
        points: vec![point],
    };
    let mut f = vec![Vec3::zeros(); 1];
    pass.accumulate(&[k, l0, z], x, v, &mut f);
    f
}

fn angle_forces(x: &[Vec3], k: f64, c0: f64) -> Vec<Vec3> {
    let pass = AnglePass {
        runs: vec![RUN],
        triples: vec![[0, 1, 2]],
    };
    let mut f = vec![Vec3::zeros(); 3];
    pass.accumulate(&[k, c0], x, &mut f);
    f
}

fn spring_energy(x: &[Vec3], k: f64, l0: f64) -> f64 {
    0.5 * k * ((x[1] - x[0]).norm() - l0).powi(2)
}

fn anchor_energy(x: &[Vec3], point: Vec3, k: f64, l0: f64) -> f64 {
    0.5 * k * ((point - x[0]).norm() - l0).powi(2)
}

fn angle_energy(x: &[Vec3], k: f64, c0: f64) -> f64 {
    let (a, b) = (x[0] - x[1], x[2] - x[1]);
    let c = a.dot(&b) / (a.norm() * b.norm());
    0.5 * k * (c - c0).powi(2)
}

/// `-∂E/∂x` by central differences with step h.
fn minus_gradient(x: &[Vec3], h: f64, energy: impl Fn(&[Vec3]) -> f64) -> Vec<Vec3> {
    let mut g = vec![Vec3::zeros(); x.len()];
    let mut y = x.to_vec();
    for i in 0..x.len() {
        for c in 0..3 {
            y[i][c] = x[i][c] + h;
            let up = energy(&y);
            y[i][c] = x[i][c] - h;
            let down = energy(&y);
            y[i][c] = x[i][c];
            g[i][c] = -(up - down) / (2.0 * h);
        }
    }
    g
}

fn point() -> impl Strategy<Value = Vec3> {
    prop::array::uniform3(-2.0..2.0f64).prop_map(Vec3::from)
}

/// Asserts `|f - g| ≤ tol` componentwise.
fn assert_close(f: &[Vec3], g: &[Vec3], tol: f64) -> Result<(), TestCaseError> {
    for (i, (a, b)) in f.iter().zip(g).enumerate() {
        prop_assert!(
            (a - b).amax() <= tol,
            "particle {i}: force {a:?} vs -gradient {b:?} (tol {tol:e})"
        );
    }
    Ok(())
}

fn all_finite(f: &[Vec3]) -> bool {
    f.iter().all(|v| v.iter().all(|c| c.is_finite()))
}

// Tolerances: with h = 1e-6 and lengths ≥ 0.1, the truncation error h² E'''/6 is below
// 1e-9 K and the rounding error ε E / h below 1e-8 K; 1e-6 K leaves room and still catches
// any wrong term (a wrong sign or factor errs by ~K × length).
const H: f64 = 1e-6;

proptest! {
    #[test]
    fn spring_force_is_minus_the_energy_gradient(
        xi in point(), xj in point(), v in prop::array::uniform2(point()),
        k in 0.1..100.0f64, l0 in 0.0..3.0f64,
    ) {
        prop_assume!((xj - xi).norm() > 0.1);
        let x = [xi, xj];
        let f = spring_forces(&x, &v, k, l0, 0.0);
        let g = minus_gradient(&x, H, |y| spring_energy(y, k, l0));
        assert_close(&f, &g, 1e-6 * k)?;
        // Newton's third law, exactly.
        prop_assert_eq!(f[0], -f[1]);
    }

    #[test]
    fn anchor_force_is_minus_the_energy_gradient(
        xi in point(), p in point(), v in point(),
        k in 0.1..100.0f64, l0 in 0.0..3.0f64,
    ) {
        prop_assume!((p - xi).norm() > 0.1);
        let x = [xi];
        let f = anchor_forces(&x, &[v], p, k, l0, 0.0);
        let g = minus_gradient(&x, H, |y| anchor_energy(y, p, k, l0));
        assert_close(&f, &g, 1e-6 * k)?;
    }

    #[test]
    fn angle_force_is_minus_the_energy_gradient(
        x in prop::array::uniform3(point()), k in 0.1..100.0f64, c0 in -1.0..=1.0f64,
    ) {
        let (la, lb) = ((x[0] - x[1]).norm(), (x[2] - x[1]).norm());
        prop_assume!(la > 0.1 && lb > 0.1);
        let f = angle_forces(&x, k, c0);
        let g = minus_gradient(&x, H, |y| angle_energy(y, k, c0));
        // |∂E/∂x| scales as K / arm length, E''' as K / arm³: the tolerance follows.
        let tol = 1e-6 * k * (1.0 + 1.0 / la.min(lb)).powi(3);
        assert_close(&f, &g, tol)?;
        // Internal forces: no net force.
        prop_assert!((f[0] + f[1] + f[2]).amax() <= 1e-12 * k * (1.0 + 1.0 / la.min(lb)));
    }

    #[test]
    fn damped_spring_adds_z_times_the_rate_along_the_link(
        xi in point(), xj in point(), v in prop::array::uniform2(point()),
        k in 0.1..100.0f64, l0 in 0.0..3.0f64, z in 0.01..10.0f64,
    ) {
        prop_assume!((xj - xi).norm() > 0.1);
        let x = [xi, xj];
        let u = (xj - xi).normalize();
        let s = (v[1] - v[0]).dot(&u);
        let f = spring_forces(&x, &v, k, l0, z);
        let f0 = spring_forces(&x, &v, k, l0, 0.0);
        let want = f0[0] + u * (z * s);
        prop_assert!((f[0] - want).amax() <= 1e-12 * (f0[0].amax() + z * v[0].amax().max(v[1].amax()) * 2.0 + 1.0));
        prop_assert_eq!(f[0], -f[1]);
    }

    #[test]
    fn coincident_spring_ends_give_zero_force(
        xi in point(), eps in prop::array::uniform3(-5e-13..5e-13f64),
        v in prop::array::uniform2(point()),
        k in 0.0..1e3f64, l0 in 0.0..3.0f64, z in 0.0..10.0f64,
    ) {
        // Within 1e-12 of each other (|eps| < 5e-13·√3 < 1e-12): no direction, no force.
        let x = [xi, xi + Vec3::from(eps)];
        prop_assume!((x[1] - x[0]).norm() < 1e-12);
        let f = spring_forces(&x, &v, k, l0, z);
        prop_assert_eq!(f, vec![Vec3::zeros(); 2]);
    }

    #[test]
    fn anchor_at_its_point_gives_zero_force(
        xi in point(), v in point(), k in 0.0..1e3f64, l0 in 0.0..3.0f64, z in 0.0..10.0f64,
    ) {
        let f = anchor_forces(&[xi], &[v], xi, k, l0, z);
        prop_assert_eq!(f, vec![Vec3::zeros()]);
    }

    #[test]
    fn zero_length_angle_arms_give_zero_force(
        x in prop::array::uniform3(point()), which in 0..3usize,
        k in 0.0..1e3f64, c0 in -1.0..=1.0f64,
    ) {
        let mut x = x;
        match which {
            0 => x[0] = x[1],
            1 => x[2] = x[1],
            _ => { x[0] = x[1]; x[2] = x[1]; }
        }
        let f = angle_forces(&x, k, c0);
        prop_assert_eq!(f, vec![Vec3::zeros(); 3]);
    }

    #[test]
    fn singular_angle_force_is_faded_continuous_and_free_of_net_force_and_torque(
        arm in point(), other in point(), t in 1e-3..1.0f64,
        k in 0.1..100.0f64, c0 in -1.0..=1.0f64,
    ) {
        // Issue 17: arm i–j shrunk into the singular zone (|a| < 1e-2 |b|), at t of its width;
        // the vertex at the origin, so that the short arm is resolved to rounding.
        let lb = other.norm();
        prop_assume!(lb > 0.1 && arm.norm() > 1e-3);
        let zone = cordis_core::forces::angle::SINGULAR_ARM * lb;
        let place = |la: f64| [arm.normalize() * la, Vec3::zeros(), other];
        let y = place(zone * t);
        let f = angle_forces(&y, k, c0);
        // The unfaded force is the energy gradient; the faded one is it times (|a|/zone)².
        // Central differences of step h and h/2 extrapolated (Richardson): the energy varies
        // on the scale of the short arm |a|, so plain central differences err by ~(h/|a|)² of
        // K/|a|, which is not small against a gradient far below K/|a| (c near c0: 3e-5 of
        // it at h = 1e-4 |a|, `arm = [-0.607, 1.178, 1.077]`, `other = [1.789, -0.708,
        // 0.118]`, t = 1e-3, k = 0.1, c0 = -0.545); extrapolated, ~(h/|a|)⁴.
        let h = 1e-4 * zone * t;
        let energy = |z: &[Vec3]| angle_energy(z, k, c0);
        let (g1, g2) = (minus_gradient(&y, h, energy), minus_gradient(&y, h / 2.0, energy));
        let g: Vec<Vec3> = g1.iter().zip(&g2).map(|(a, b)| (4.0 * b - a) / 3.0).collect();
        let fade = t * t;
        let scale = g.iter().map(|v| v.amax()).fold(0.0, f64::max);
        // Truncation ~1e-16 of K/|a|, rounding ~ε |E| / h with |E| ≤ 2K.
        let tol = fade * (1e-5 * scale + 1e-14 * k / h);
        for (fi, gi) in f.iter().zip(&g) {
            prop_assert!((fi - gi * fade).amax() <= tol, "{fi} vs {}", gi * fade);
        }
        // Bounded by 2K/zone, however short the arm (it used to grow as K/|a|).
        prop_assert!(f[0].norm() <= 2.0 * k * 2.0 / zone, "{}", f[0].norm());
        // One factor on the whole gradient: no net force, no net torque about the vertex.
        let torque = y[0].cross(&f[0]) + y[2].cross(&f[2]);
        prop_assert!((f[0] + f[1] + f[2]).amax() <= 1e-9 * k / zone);
        prop_assert!(torque.amax() <= 1e-9 * k * (1.0 + lb / zone));
        // Continuous where the zone begins: just outside equals just inside.
        let inside = angle_forces(&place(zone * (1.0 - 1e-9)), k, c0);
        let outside = angle_forces(&place(zone * (1.0 + 1e-9)), k, c0);
        prop_assert!((inside[0] - outside[0]).amax() <= 1e-6 * outside[0].amax() + 1e-12 * k);
    }

    #[test]
    fn tiny_but_nonzero_geometry_stays_finite(
        x in prop::array::uniform3(point()),
        d in prop::array::uniform3(prop::array::uniform3(-1e-9..1e-9f64)),
        v in prop::array::uniform3(point()),
        k in 0.0..1e3f64, l0 in 0.0..3.0f64, z in 0.0..10.0f64, c0 in -1.0..=1.0f64,
    ) {
        // Everything within a nanometre of x[0]: links of any length around the 1e-12
        // threshold.
        let y: Vec<Vec3> = d.iter().map(|e| x[0] + Vec3::from(*e)).collect();
        prop_assert!(all_finite(&spring_forces(&y[..2], &v[..2], k, l0, z)));
        prop_assert!(all_finite(&anchor_forces(&y[..1], &v[..1], y[1], k, l0, z)));
        prop_assert!(all_finite(&angle_forces(&y, k, c0)));
    }
}
