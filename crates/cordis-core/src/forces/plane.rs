//! `plane`: contact with a half-space — the ground, a table — as Cordis-Anima's buffer
//! interaction with a fixed surface (SPEC §7.2).
//!
//! A plane type holds a point `p` of the surface (m) and its outward normal `n` (normalised at
//! compile time; it points from the solid into the free space). For a particle at `x` with
//! velocity `v` (the scheme's `v(n) = (x(n) - x(n-1))/dt`):
//!
//! ```text
//! depth        d   = (p - x)·n                      m     (> 0: below the surface)
//! normal speed v_n = v·n                            m/s   (< 0: moving into the solid)
//! normal force F_n = max(0, K d - Z v_n)            N     while d > 0, else no force at all
//! friction     F_t = -(v_t/|v_t|) · c a / √(a² + c²) N    c = μ F_n,  a = m |v_t| / dt
//! force on i   F   = F_n n + F_t,                   v_t = v - v_n n
//! ```
//!
//! with K the `stiffness` (N/m), Z the `damping` (N·s/m), μ the `friction` coefficient
//! (dimensionless), m the particle's mass (kg) and dt its world's time step (s).
//!
//! **Why the clamp at 0.** A linear spring-damper `K d - Z v_n` turns negative near the end of
//! a contact, when the particle leaves faster than `K d / Z`: it would pull the particle back
//! into the ground, an adhesion no real buffer has. The buffer therefore only pushes; the
//! contact ends when its force reaches zero, slightly before the particle is back at the
//! surface, and the particle leaves in free flight. For a mass m dropped at speed v₀ on the
//! buffer (no gravity during the contact, continuous time), with `ζ = Z / (2√(K m))`,
//! `ω₀ = √(K/m)`, `β = ζ ω₀`, `ω = ω₀ √(1 - ζ²)`, the force vanishes at
//! `ω t* = π - atan(2βω / (ω² - β²))` (for `ζ < 1/√2`), where the exit speed is exactly
//! `v₀ e^{-β t*}`: the coefficient of restitution is
//!
//! ```text
//! e = exp(-(ζ/√(1-ζ²)) (π - atan(2ζ√(1-ζ²) / (1 - 2ζ²))))
//! ```
//!
//! (Schwager & Pöschel 2007), above the unclamped spring-damper's `exp(-ζπ/√(1-ζ²))`, which
//! counts the pull at the end of the contact (at ζ = 0.1: 0.744 against 0.729). The example
//! `cordis_core::examples::bouncing_ball` and the test `tests/ground_contact.rs` check both.
//!
//! **Why this regularisation of Coulomb's law.** The friction's size is a smooth minimum of the
//! Coulomb force `c = μ F_n` and `a = m |v_t| / dt`, the force that stops the tangential motion
//! in one step: `c a / √(a² + c²) ≤ min(a, c)`. So friction never reverses the tangential
//! velocity within a step (the step changes it by `dt |F_t| / m < |v_t|`), sliding at speeds
//! well above `μ F_n dt / m` is Coulomb's law to second order in their ratio, and as dt → 0 it
//! is Coulomb's law itself. The usual alternative, a fixed slip speed ε in `v_t/√(|v_t|²+ε²)`,
//! acts near rest as a damper of `μ F_n / ε`, which grows with the normal force without
//! bound: an explicit scheme chatters or explodes under a stiff contact unless ε is so large
//! that slow sliding is far from Coulomb's law. Here the friction's slope at rest is `m / dt`
//! whatever the normal force, a damping the stability bound counts exactly
//! ([`crate::stability`]).
//!
//! Nothing is computed for a particle above the surface but its depth; a run whose friction is
//! 0 takes the kernel without friction (one branch per run).

use super::Run;
use crate::Vec3;

/// The surface of one plane type: a point on it (m) and its unit outward normal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Surface {
    pub point: Vec3,
    pub normal: Vec3,
}

#[derive(Clone, Debug, Default)]
pub struct PlanePass {
    /// Parameters `p[run.param..]` = K (N/m), Z (N·s/m), μ.
    pub runs: Vec<Run>,
    /// The surface of each run's type (same order as `runs`).
    pub surfaces: Vec<Surface>,
    pub particles: Vec<u32>,
    /// Each instance's particle's world time step, s (the friction's `a = m |v_t| / dt`).
    pub dt: Vec<f64>,
    /// Where the masses start in the parameter vector.
    pub mass_offset: usize,
}

impl PlanePass {
    pub fn accumulate(&self, p: &[f64], x: &[Vec3], v: &[Vec3], f: &mut [Vec3]) {
        let mass = &p[self.mass_offset..];
        for (r, s) in self.runs.iter().zip(&self.surfaces) {
            let (k, z, mu) = (p[r.param], p[r.param + 1], p[r.param + 2]);
            let items = self.particles[r.start..r.end]
                .iter()
                .zip(&self.dt[r.start..r.end]);
            if mu == 0.0 {
                for (&i, _) in items {
                    let i = i as usize;
                    if let Some(f_n) = normal_force(s, k, z, &x[i], &v[i]) {
                        f[i] += s.normal * f_n;
                    }
                }
            } else {
                for (&i, &dt) in items {
                    let i = i as usize;
                    if let Some(f_n) = normal_force(s, k, z, &x[i], &v[i]) {
                        f[i] += s.normal * f_n + friction(&s.normal, &v[i], mu * f_n, mass[i], dt);
                    }
                }
            }
        }
    }

    pub fn len(&self) -> usize {
        self.particles.len()
    }

    pub fn is_empty(&self) -> bool {
        self.particles.is_empty()
    }
}

/// `F_n = max(0, K d - Z v_n)` (N) while the depth `d > 0`, `None` above the surface.
#[inline(always)]
pub fn normal_force(s: &Surface, k: f64, z: f64, x: &Vec3, v: &Vec3) -> Option<f64> {
    let d = (s.point - x).dot(&s.normal);
    if d > 0.0 {
        Some((k * d - z * v.dot(&s.normal)).max(0.0))
    } else {
        None
    }
}

/// The regularised Coulomb friction (N) of a particle of mass `m` pressed with `c = μ F_n`:
/// `-(v_t/|v_t|) c a / √(a² + c²)`, `a = m |v_t| / dt`; zero when `c` or `v_t` is.
#[inline(always)]
pub fn friction(n: &Vec3, v: &Vec3, c: f64, m: f64, dt: f64) -> Vec3 {
    let vt = v - n * v.dot(n);
    let speed = vt.norm();
    let a = m * speed / dt;
    if !(c > 0.0 && a > 0.0) {
        return Vec3::zeros();
    }
    // a / √(a² + c²) as 1 / √(1 + (c/a)²): finite even when a overflows.
    let ratio = c / a;
    vt * (-c / (speed * (1.0 + ratio * ratio).sqrt()))
}

/// The unit vector along `n`, or `None` when `n` is zero or not finite. Scaled by its largest
/// component first, so that neither tiny nor huge components under- or overflow.
pub fn unit_normal(n: [f64; 3]) -> Option<Vec3> {
    let big = n.iter().fold(0.0_f64, |m, c| m.max(c.abs()));
    if !(big > 0.0 && n.iter().all(|c| c.is_finite())) {
        return None;
    }
    let scaled = Vec3::from(n) / big;
    Some(scaled / scaled.norm())
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    fn ground() -> Surface {
        Surface {
            point: Vec3::zeros(),
            normal: Vec3::new(0.0, 0.0, 1.0),
        }
    }

    #[test]
    fn buffer_pushes_only_while_below_and_never_pulls() {
        let s = ground();
        let still = Vec3::zeros();
        assert_eq!(
            normal_force(&s, 100.0, 1.0, &Vec3::new(0.0, 0.0, 0.1), &still),
            None
        );
        let f = normal_force(&s, 100.0, 1.0, &Vec3::new(0.0, 0.0, -0.01), &still).unwrap();
        assert_relative_eq!(f, 1.0, max_relative = 1e-12);
        // Leaving fast: K d - Z v_n = 1 - 5 < 0, clamped.
        let up = Vec3::new(0.0, 0.0, 5.0);
        assert_eq!(
            normal_force(&s, 100.0, 1.0, &Vec3::new(0.0, 0.0, -0.01), &up),
            Some(0.0)
        );
    }

    #[test]
    fn friction_is_coulomb_when_sliding_and_never_reverses_a_step() {
        let n = Vec3::new(0.0, 0.0, 1.0);
        let (m, dt, c) = (2.0, 1e-3, 4.0);
        // Fast sliding: a = 2 * 3 / 1e-3 = 6000 >> c, the force is Coulomb's to (c/a)²/2.
        let f = friction(&n, &Vec3::new(3.0, 0.0, -1.0), c, m, dt);
        assert_relative_eq!(f.x, -c, max_relative = 1e-6);
        assert_eq!((f.y, f.z), (0.0, 0.0));
        // Slow: one step changes v_t by less than v_t.
        for vt in [1e-6, 1e-3, 2e-3, 1e-1] {
            let f = friction(&n, &Vec3::new(0.0, vt, 0.0), c, m, dt);
            let dv = f.y * dt / m;
            assert!(dv < 0.0 && -dv < vt, "v_t {vt}: step change {dv}");
            assert!(f.norm() <= c);
        }
        assert_eq!(
            friction(&n, &Vec3::new(0.0, 0.0, -3.0), c, m, dt),
            Vec3::zeros()
        );
        assert_eq!(
            friction(&n, &Vec3::new(1.0, 0.0, 0.0), 0.0, m, dt),
            Vec3::zeros()
        );
    }

    #[test]
    fn unit_normal_refuses_zero_and_survives_extreme_components() {
        assert_eq!(unit_normal([0.0; 3]), None);
        assert_eq!(unit_normal([f64::NAN, 0.0, 1.0]), None);
        let u = unit_normal([0.0, 1e-310, 0.0]).unwrap();
        assert_eq!(u, Vec3::new(0.0, 1.0, 0.0));
        let u = unit_normal([1e308, 1e308, 0.0]).unwrap();
        assert_relative_eq!(u.norm(), 1.0, max_relative = 1e-15);
    }
}
