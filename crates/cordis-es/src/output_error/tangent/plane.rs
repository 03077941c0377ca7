//! A plane's contact force (`cordis_core::forces::plane`) and its derivatives, piece by piece
//! as the core computes it.
//!
//! With the depth `d = (p - x)·n`, the normal speed `v_n = v·n`, the buffer's raw force
//! `r = K d - Z v_n`, `F_n = max(0, r)`, and the regularised Coulomb friction
//! `F_t = -t g`, `t = v_t/|v_t|`, `g = c a/√(a² + c²) = c q`, `q = 1/√(1 + ρ²)`, `ρ = c/a`,
//! `c = μ F_n`, `a = m |v_t|/dt` (P = I - n nᵀ, `v_t = P v`), the force `F = F_n n + F_t` has
//! three pieces:
//!
//! - **above the surface** (`d ≤ 0`) or **leaving faster than the buffer pushes** (`r ≤ 0`): no
//!   force, no derivative;
//! - **in contact without friction** (μ = 0, or no sliding: `v_t = 0`):
//!   `∂F/∂x = -K n nᵀ`, `∂F/∂v = -Z n nᵀ`, `∂F/∂K = d n`, `∂F/∂Z = -v_n n`;
//! - **sliding** (`c > 0`, `a > 0`), with `ν = n - μ q³ t` (∂g/∂c = q³, ∂g/∂a = ρ³ q³):
//!
//! ```text
//! ∂F/∂x = -K ν nᵀ
//! ∂F/∂v = -Z ν nᵀ - (g/|v_t|) (P - t tᵀ) - ρ³ q³ (m/dt) t tᵀ
//! ∂F/∂K = d ν,  ∂F/∂Z = -v_n ν,  ∂F/∂μ = -q³ F_n t,  ∂F/∂m = -ρ³ q³ (|v_t|/dt) t
//! ```
//!
//! The friction reads the particle's mass, so an unknown mass gets this column beside the
//! scheme's `-F/m²`. At μ = 0 the force is not differentiable in μ (a negative μ would give no
//! friction): the tangent takes the derivative from above, `-F_n t`, the side a box on μ ≥ 0
//! allows, so a fit can move an unknown friction off 0. The switches (touching the surface,
//! the clamp at `r = 0`, the onset of sliding) are where the trajectory's derivative is
//! one-sided; the contact onset is even a jump of the force (`F_n = max(0, -Z v_n)` as the
//! particle crosses the surface), so a parameter change that moves a contact across a step
//! moves the trajectory by a step: the Gauss–Newton model holds between such events.

use cordis_core::forces::plane::PlanePass;
use cordis_core::Vec3;

use super::no_column::NONE;

/// Floats stored per plane instance and step by the matrix-free linearisation: ∂F/∂x and
/// ∂F/∂v (row-major 3×3 each), ∂F/∂(K, Z, μ, m) (3 each); zeros out of contact.
pub(crate) const PLANE: usize = 30;

/// One contact's linearisation (module docs).
#[derive(Default)]
pub(crate) struct PlaneLink {
    pub jx: [[f64; 3]; 3],
    pub jv: [[f64; 3]; 3],
    /// ∂F/∂(K, Z, μ, m).
    pub dp: [Vec3; 4],
}

/// The contact of a particle at `x` with velocity `v`, mass `m` and time step `dt` with the
/// surface through `point` with unit normal `n`; `None` out of contact.
#[allow(clippy::too_many_arguments)]
pub(crate) fn plane_link(
    (point, n): (&Vec3, &Vec3),
    [k, z, mu]: [f64; 3],
    x: &Vec3,
    v: &Vec3,
    m: f64,
    dt: f64,
) -> Option<PlaneLink> {
    let d = (point - x).dot(n);
    if d <= 0.0 {
        return None;
    }
    let vn = v.dot(n);
    let f_n = k * d - z * vn;
    if f_n <= 0.0 {
        return None;
    }
    let vt = v - n * vn;
    let speed = vt.norm();
    let c = mu * f_n;
    let a = m * speed / dt;
    let mut out = PlaneLink::default();
    let nn = n * n.transpose();
    if !(c > 0.0 && a > 0.0) {
        // No friction force; at μ = 0 while sliding, the derivative in μ from above.
        for r in 0..3 {
            for q in 0..3 {
                out.jx[r][q] = -k * nn[(r, q)];
                out.jv[r][q] = -z * nn[(r, q)];
            }
        }
        out.dp[0] = n * d;
        out.dp[1] = -n * vn;
        if mu == 0.0 && speed > 0.0 {
            out.dp[2] = -(vt / speed) * f_n;
        }
        return Some(out);
    }
    let t = vt / speed;
    let rho = c / a;
    let q = 1.0 / (1.0 + rho * rho).sqrt();
    let (q3, g) = (q * q * q, c * q);
    let nu = n - t * (mu * q3);
    let tt = t * t.transpose();
    let p = nalgebra::Matrix3::identity() - nn;
    let slide = (p - tt) * (g / speed) + tt * (rho * rho * rho * q3 * m / dt);
    for r in 0..3 {
        for col in 0..3 {
            out.jx[r][col] = -k * nu[r] * n[col];
            out.jv[r][col] = -z * nu[r] * n[col] - slide[(r, col)];
        }
    }
    out.dp = [
        nu * d,
        -nu * vn,
        -t * (q3 * f_n),
        -t * (rho * rho * rho * q3 * speed / dt),
    ];
    Some(out)
}

impl PlaneLink {
    fn store(&self, d: &mut [f64]) {
        for r in 0..3 {
            d[3 * r..3 * r + 3].copy_from_slice(&self.jx[r]);
            d[9 + 3 * r..9 + 3 * r + 3].copy_from_slice(&self.jv[r]);
        }
        for (k, dp) in self.dp.iter().enumerate() {
            d[18 + 3 * k..18 + 3 * k + 3].copy_from_slice(dp.as_slice());
        }
    }
}

/// Calls `visit(index in the pass, particle, its type's parameter offset, link)` for every
/// instance in contact at `(x, v)`.
fn each_contact(
    pass: &PlanePass,
    p: &[f64],
    (x, v): (&[Vec3], &[Vec3]),
    mut visit: impl FnMut(usize, usize, usize, PlaneLink),
) {
    let mo = pass.mass_offset;
    for (r, s) in pass.runs.iter().zip(&pass.surfaces) {
        let c = [p[r.param], p[r.param + 1], p[r.param + 2]];
        for l in r.start..r.end {
            let i = pass.particles[l] as usize;
            let surface = (&s.point, &s.normal);
            if let Some(lk) = plane_link(surface, c, &x[i], &v[i], p[mo + i], pass.dt[l]) {
                visit(l, i, r.param, lk);
            }
        }
    }
}

/// Dense tangent: adds every contact's `∂F/∂x S + ∂F/∂v V + ∂F/∂θ` into `df` (rows of width w).
#[allow(clippy::too_many_arguments)]
pub(super) fn dense(
    pass: &PlanePass,
    p: &[f64],
    of_slot: &[usize],
    xv: (&[Vec3], &[Vec3]),
    (s, vel): (&[f64], &[f64]),
    w: usize,
    df: &mut [f64],
) {
    each_contact(pass, p, xv, |l, i, param, lk| {
        let slots = slots_of(pass, l, param, of_slot);
        for r in 0..3 {
            let ri = (3 * i + r) * w;
            let (jx, jv) = (lk.jx[r], lk.jv[r]);
            for q in 0..w {
                let mut g = 0.0;
                for c in 0..3 {
                    let rc = (3 * i + c) * w + q;
                    g += jx[c] * s[rc] + jv[c] * vel[rc];
                }
                df[ri + q] += g;
            }
            for (col, dp) in slots.iter().zip(&lk.dp) {
                if *col != NONE {
                    df[ri + col] += dp[r];
                }
            }
        }
    });
}

/// Matrix-free linearisation of one step: every instance's record (`PLANE` floats, in pass
/// order) into `out`.
pub(crate) fn store(pass: &PlanePass, p: &[f64], xv: (&[Vec3], &[Vec3]), out: &mut [f64]) {
    out.fill(0.0);
    each_contact(pass, p, xv, |l, _, _, lk| {
        lk.store(&mut out[l * PLANE..(l + 1) * PLANE]);
    });
}

/// The columns of instance `l`'s (K, Z, μ, m).
fn slots_of(pass: &PlanePass, l: usize, param: usize, of_slot: &[usize]) -> [usize; 4] {
    let i = pass.particles[l] as usize;
    [
        of_slot[param],
        of_slot[param + 1],
        of_slot[param + 2],
        of_slot[pass.mass_offset + i],
    ]
}

/// Matrix-free forward from one step's records: `df += ∂F/∂x s + ∂F/∂v ṡ + ∂F/∂θ dθ` over w
/// directions (`dth` physical, × w).
#[allow(clippy::too_many_arguments)]
pub(crate) fn forward(
    pass: &PlanePass,
    lin: &[f64],
    of_slot: &[usize],
    w: usize,
    (cur, vel): (&[f64], &[f64]),
    df: &mut [f64],
    dth: &[f64],
) {
    for r in &pass.runs {
        for l in r.start..r.end {
            let d = &lin[l * PLANE..(l + 1) * PLANE];
            if d.iter().all(|&v| v == 0.0) {
                continue;
            }
            let i = pass.particles[l] as usize;
            let slots = slots_of(pass, l, r.param, of_slot);
            for col in 0..w {
                let at = |m: &[f64], c: usize| m[(3 * i + c) * w + col];
                for rr in 0..3 {
                    let mut g = 0.0;
                    for c in 0..3 {
                        g += d[3 * rr + c] * at(cur, c) + d[9 + 3 * rr + c] * at(vel, c);
                    }
                    for (k, s) in slots.iter().enumerate() {
                        if *s != NONE {
                            g += d[18 + 3 * k + rr] * dth[s * w + col];
                        }
                    }
                    df[(3 * i + rr) * w + col] += g;
                }
            }
        }
    }
}

/// Matrix-free adjoint from one step's records: `na += (∂F/∂x)ᵀ φ`, `psi += (∂F/∂v)ᵀ φ`,
/// `grad += (∂F/∂θ)ᵀ φ` over w cotangents.
#[allow(clippy::too_many_arguments)]
pub(crate) fn adjoint(
    pass: &PlanePass,
    lin: &[f64],
    of_slot: &[usize],
    w: usize,
    phi: &[f64],
    (na, psi): (&mut [f64], &mut [f64]),
    grad: &mut [f64],
) {
    for r in &pass.runs {
        for l in r.start..r.end {
            let d = &lin[l * PLANE..(l + 1) * PLANE];
            if d.iter().all(|&v| v == 0.0) {
                continue;
            }
            let i = pass.particles[l] as usize;
            let slots = slots_of(pass, l, r.param, of_slot);
            for col in 0..w {
                let at = |c: usize| phi[(3 * i + c) * w + col];
                let ph = [at(0), at(1), at(2)];
                for c in 0..3 {
                    let (mut gx, mut gv) = (0.0, 0.0);
                    for (rr, f) in ph.iter().enumerate() {
                        gx += d[3 * rr + c] * f;
                        gv += d[9 + 3 * rr + c] * f;
                    }
                    na[(3 * i + c) * w + col] += gx;
                    psi[(3 * i + c) * w + col] += gv;
                }
                for (k, s) in slots.iter().enumerate() {
                    if *s != NONE {
                        let dp = &d[18 + 3 * k..18 + 3 * k + 3];
                        grad[s * w + col] += dp[0] * ph[0] + dp[1] * ph[1] + dp[2] * ph[2];
                    }
                }
            }
        }
    }
}

/// The preconditioner's local model: each contact's ∂F/∂x and ∂F/∂v added to its particle's
/// 3×3 blocks.
pub(crate) fn local(pass: &PlanePass, lin: &[f64], kii: &mut [f64], cii: &mut [f64]) {
    for (l, &i) in pass.particles.iter().enumerate() {
        let d = &lin[l * PLANE..(l + 1) * PLANE];
        let i = i as usize;
        for e in 0..9 {
            kii[9 * i + e] += d[e];
            cii[9 * i + e] += d[9 + e];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use cordis_core::forces::plane::{friction, normal_force, Surface};

    fn force(s: &Surface, c: [f64; 3], x: &Vec3, v: &Vec3, m: f64, dt: f64) -> Vec3 {
        match normal_force(s, c[0], c[1], x, v) {
            Some(f_n) if c[2] == 0.0 => s.normal * f_n,
            Some(f_n) => s.normal * f_n + friction(&s.normal, v, c[2] * f_n, m, dt),
            None => Vec3::zeros(),
        }
    }

    /// Every derivative against central differences of the core's kernels, sliding fast
    /// (Coulomb), slowly (the regularisation) and without friction; and the derivative in μ
    /// at μ = 0 against a forward difference (the side a box μ ≥ 0 allows).
    #[test]
    fn plane_derivatives_match_central_differences_of_the_core_kernels() {
        let s = Surface {
            point: Vec3::new(0.0, 0.1, 0.0),
            normal: Vec3::new(0.1, 1.0, -0.2).normalize(),
        };
        let x = Vec3::new(0.3, 0.05, 0.2);
        let (m, dt) = (0.7, 2e-3);
        let cases = [
            ([3e3, 4.0, 0.4], Vec3::new(0.8, -0.3, 0.5)),
            ([3e3, 4.0, 0.4], Vec3::new(2e-3, -0.3, 1e-3)),
            ([3e3, 4.0, 0.0], Vec3::new(0.8, -0.3, 0.5)),
        ];
        for (n, (c, v)) in cases.into_iter().enumerate() {
            let surface = (&s.point, &s.normal);
            let lk = plane_link(surface, c, &x, &v, m, dt).unwrap();
            let size = 1.0
                + lk.jx
                    .iter()
                    .chain(&lk.jv)
                    .flatten()
                    .fold(0.0_f64, |a, b| a.max(b.abs()));
            let h = 1e-7;
            for e in 0..3 {
                let mut dx = Vec3::zeros();
                dx[e] = h;
                let fx = (force(&s, c, &(x + dx), &v, m, dt) - force(&s, c, &(x - dx), &v, m, dt))
                    / (2.0 * h);
                let fv = (force(&s, c, &x, &(v + dx), m, dt) - force(&s, c, &x, &(v - dx), m, dt))
                    / (2.0 * h);
                for r in 0..3 {
                    assert!(
                        (fx[r] - lk.jx[r][e]).abs() < 1e-6 * size,
                        "case {n}: jx[{r}][{e}]"
                    );
                    assert!(
                        (fv[r] - lk.jv[r][e]).abs() < 1e-6 * size,
                        "case {n}: jv[{r}][{e}]"
                    );
                }
            }
            for t in 0..4 {
                let (mut cp, mut cm, mut mp, mut mm) = (c, c, m, m);
                let step = 1e-6 * if t == 0 { c[0] } else { 1.0 };
                match t {
                    3 => {
                        mp += step;
                        mm -= step;
                    }
                    _ => {
                        cp[t] += step;
                        cm[t] -= step;
                    }
                }
                let fd = if t == 2 && c[2] == 0.0 {
                    // μ = 0: from above.
                    (force(&s, cp, &x, &v, m, dt) - force(&s, c, &x, &v, m, dt)) / step
                } else {
                    (force(&s, cp, &x, &v, mp, dt) - force(&s, cm, &x, &v, mm, dt)) / (2.0 * step)
                };
                assert!(
                    (fd - lk.dp[t]).norm() < 1e-5 * (1.0 + fd.norm()),
                    "case {n}, θ {t}: {fd} vs {}",
                    lk.dp[t]
                );
            }
        }
        // Above the surface, and leaving faster than the buffer pushes: no contact.
        let above = Vec3::new(0.3, 0.5, 0.2);
        let surface = (&s.point, &s.normal);
        assert!(plane_link(surface, [3e3, 4.0, 0.4], &above, &Vec3::zeros(), m, dt).is_none());
        let leaving = s.normal * 1e3;
        assert!(plane_link(surface, [3e3, 4.0, 0.4], &x, &leaving, m, dt).is_none());
    }
}
