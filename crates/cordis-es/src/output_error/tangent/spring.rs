//! A spring's (or an anchor's, or a conditional pair's) force and its derivatives.
//!
//! For a spring from i to j with `d = x_j - x_i`, `l = |d|`, `u = d/l`, `w = v_j - v_i`,
//! `s = w·u` and `f_i = m u = -f_j`, `m = K (l - l0) + Z s + Z₂ s |s|` (the quadratic viscosity
//! Z₂ of `damping_quadratic`, thesis §4.3; 0 for a type without it):
//!
//! ```text
//! ∂f_i/∂d = K u uᵀ + (m/l) (I - u uᵀ) + (Z'/l) u ((I - u uᵀ) w)ᵀ,   Z' = Z + 2 Z₂ |s|
//! ∂f_i/∂w = Z' u uᵀ
//! ∂f_i/∂K = (l - l0) u,  ∂f_i/∂l0 = -K u,  ∂f_i/∂Z = s u,  ∂f_i/∂Z₂ = s |s| u
//! ```
//!
//! `s |s|` is continuously differentiable (its derivative `2 |s|` is continuous at s = 0), so
//! Z₂ adds no switch: the recursion is exact through a rate changing sign. With Z₂ = 0 every
//! number is the one of the plain spring, bit for bit (`Z' = Z` and `m` computed as before).

use cordis_core::forces::spring::SpringPass;
use cordis_core::Vec3;

use super::no_column::NONE;

/// Floats stored per spring or anchor per step by the matrix-free linearisation, A held by
/// its three factors instead of its nine entries:
///
/// ```text
/// A = α u uᵀ + β I + u qᵀ,   α = K - m/l,  β = m/l,  q = (Z'/l) (I - u uᵀ) w
/// ```
///
/// so a record is u (3), q (3), α, β, `l - l0`, `s = w·u` (∂f_i/∂(K, l0, Z, Z₂) =
/// (l - l0, -K, s, s|s|) u) and `Z'` (∂f_i/∂w = Z' u uᵀ). The passes are bound by reading
/// records: 11 floats, not the 15 of A stored whole (nor the 30 of A, B and ∂f/∂θ), and
/// `A d = β d + u (α u·d + q·d)` is three dot products instead of a 3×3 product. Measured on
/// the 32 × 32 cloth's fit (BENCHMARKS, "Large scenes").
pub(crate) const LINK: usize = 11;
/// Where u, q, α, β, `l - l0`, s and `Z'` are in a record.
const U: usize = 0;
const Q: usize = 3;
const ALPHA: usize = 6;
const BETA: usize = 7;
const ELONGATION: usize = 8;
const RATE: usize = 9;
/// Where `Z'` is in a stored record.
pub(crate) const ZEFF: usize = 10;

/// The unit direction u of a stored record.
pub(crate) fn unit(d: &[f64]) -> &[f64] {
    &d[U..U + 3]
}

/// A = ∂f_i/∂d of a stored record, row-major (the preconditioner's local blocks).
pub(crate) fn a_matrix(d: &[f64]) -> [f64; 9] {
    let (u, q, alpha, beta) = (&d[U..U + 3], &d[Q..Q + 3], d[ALPHA], d[BETA]);
    let mut a = [0.0; 9];
    for r in 0..3 {
        for c in 0..3 {
            let id = if r == c { beta } else { 0.0 };
            a[3 * r + c] = alpha * u[r] * u[c] + id + u[r] * q[c];
        }
    }
    a
}

/// The slot of run `ri`'s quadratic viscosity Z₂, when its type has one.
pub(crate) fn quadratic(pass: &SpringPass, ri: usize) -> Option<usize> {
    pass.quadratic.get(ri).copied().flatten()
}

/// The columns of run `ri`'s (K, l0, Z, Z₂) (parameters from `param`).
pub(crate) fn slots(pass: &SpringPass, ri: usize, param: usize, of_slot: &[usize]) -> [usize; 4] {
    [
        of_slot[param],
        of_slot[param + 1],
        of_slot[param + 2],
        quadratic(pass, ri).map_or(NONE, |q| of_slot[q]),
    ]
}

/// One spring's force on its end i and its derivatives (module docs).
pub(crate) struct SpringLink {
    /// ∂f_i/∂d.
    pub a: [[f64; 3]; 3],
    /// ∂f_i/∂w (zero when undamped).
    b: [[f64; 3]; 3],
    /// ∂f_i/∂(K, l0, Z, Z₂).
    pub dp: [Vec3; 4],
    /// The unit direction u (∂f_i/∂w = Z' u uᵀ: the matrix-free passes apply it as a rank
    /// one), the elongation `l - l0` and the rate `s = w·u` (∂f_i/∂θ = (l - l0, -K, s, s|s|) u).
    pub u: Vec3,
    pub e: f64,
    pub s: f64,
    /// The rate's coefficient `Z' = Z + 2 Z₂ |s|`.
    zeff: f64,
    damped: bool,
    /// A's factors (see [`LINK`]): α = K - m/l, β = m/l, q = (Z'/l) (I - u uᵀ) w.
    alpha: f64,
    beta: f64,
    q: Vec3,
}

/// The spring from `xi` to `xj` (the force acts on i): see the module docs. `z2` is the
/// quadratic viscosity (0 for a type without one).
#[allow(clippy::too_many_arguments)]
pub(crate) fn spring_link(
    xj: &Vec3,
    xi: &Vec3,
    vj: &Vec3,
    vi: &Vec3,
    k: f64,
    l0: f64,
    z: f64,
    z2: f64,
) -> SpringLink {
    let d = xj - xi;
    let l = d.norm();
    let inv = if l >= cordis_core::forces::MIN_LENGTH {
        1.0 / l
    } else {
        0.0
    };
    let u = d * inv;
    let wv = vj - vi;
    // The rate is needed even at Z = 0: ∂f/∂Z = s u is what moves an unknown damping off 0.
    let s = wv.dot(&u);
    let mut mag = k * (l - l0) + z * s;
    let mut zeff = z;
    if z2 != 0.0 {
        mag += z2 * (s * s.abs());
        zeff += 2.0 * z2 * s.abs();
    }
    let perp = wv - u * s;
    let mut a = [[0.0; 3]; 3];
    let mut b = [[0.0; 3]; 3];
    for r in 0..3 {
        for c in 0..3 {
            let id = if r == c { 1.0 } else { 0.0 };
            a[r][c] =
                k * u[r] * u[c] + mag * inv * (id - u[r] * u[c]) + zeff * inv * u[r] * perp[c];
            b[r][c] = zeff * u[r] * u[c];
        }
    }
    SpringLink {
        a,
        b,
        dp: [u * (l - l0), -u * k, u * s, u * (s * s.abs())],
        u,
        e: l - l0,
        s,
        zeff,
        damped: zeff != 0.0,
        alpha: k - mag * inv,
        beta: mag * inv,
        q: perp * (zeff * inv),
    }
}

impl SpringLink {
    /// The matrix-free record ([`LINK`] floats).
    pub(crate) fn store(&self, d: &mut [f64]) {
        d[U..U + 3].copy_from_slice(self.u.as_slice());
        d[Q..Q + 3].copy_from_slice(self.q.as_slice());
        d[ALPHA] = self.alpha;
        d[BETA] = self.beta;
        d[ELONGATION] = self.e;
        d[RATE] = self.s;
        d[ZEFF] = self.zeff;
    }

    /// Adds this link's tangent force into `df` rows of i (and minus it into j's); `diff`
    /// holds `S_j - S_i` then `V_j - V_i` (six row blocks of width w), `slots` the columns of
    /// (K, l0, Z, Z₂).
    pub(super) fn add(
        &self,
        df: &mut [f64],
        diff: &[f64],
        w: usize,
        i: usize,
        j: Option<usize>,
        slots: [usize; 4],
    ) {
        let (d0, d1, d2) = (&diff[0..w], &diff[w..2 * w], &diff[2 * w..3 * w]);
        let (e0, e1, e2) = (
            &diff[3 * w..4 * w],
            &diff[4 * w..5 * w],
            &diff[5 * w..6 * w],
        );
        for r in 0..3 {
            let ri = (3 * i + r) * w;
            // Both ends' rows as disjoint slices of exactly w: the loops below then carry no
            // bounds check and vectorise (this was 47 % of a hidden-particle fit under perf,
            // indexed through `df` and the damping test inside the loop).
            let (row_i, row_j) = match j {
                Some(j) => {
                    let rj = (3 * j + r) * w;
                    if ri < rj {
                        let (lo, hi) = df.split_at_mut(rj);
                        (&mut lo[ri..ri + w], Some(&mut hi[..w]))
                    } else {
                        let (lo, hi) = df.split_at_mut(ri);
                        (&mut hi[..w], Some(&mut lo[rj..rj + w]))
                    }
                }
                None => (&mut df[ri..ri + w], None),
            };
            let [a0, a1, a2] = self.a[r];
            let [b0, b1, b2] = self.b[r];
            let force = |q: usize| a0 * d0[q] + a1 * d1[q] + a2 * d2[q];
            let damping = |q: usize| b0 * e0[q] + b1 * e1[q] + b2 * e2[q];
            match (self.damped, row_j) {
                (true, Some(row_j)) => {
                    for q in 0..w {
                        let g = force(q) + damping(q);
                        row_i[q] += g;
                        row_j[q] -= g;
                    }
                }
                (false, Some(row_j)) => {
                    for q in 0..w {
                        let g = force(q);
                        row_i[q] += g;
                        row_j[q] -= g;
                    }
                }
                (true, None) => {
                    for (q, x) in row_i.iter_mut().enumerate() {
                        *x += force(q) + damping(q);
                    }
                }
                (false, None) => {
                    for (q, x) in row_i.iter_mut().enumerate() {
                        *x += force(q);
                    }
                }
            }
            for (t, &col) in slots.iter().enumerate() {
                if col != NONE {
                    df[ri + col] += self.dp[t][r];
                    if let Some(j) = j {
                        df[(3 * j + r) * w + col] -= self.dp[t][r];
                    }
                }
            }
        }
    }
}

/// Matrix-free forward of one link from its record `d` ([`LINK`]): `df += ∂f/∂x s + ∂f/∂v ṡ +
/// ∂f/∂θ dθ` over w directions, for ends `(i, j)` (`j = None`: a fixed point, an anchor's),
/// `(cur, vel)` = (s(t), ṡ(t)), `slots` the columns of (K, l0, Z, Z₂) and `dth` the θ
/// directions (physical units, × w).
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(crate) fn forward(
    d: &[f64],
    k: f64,
    slots: &[usize; 4],
    (i, j): (usize, Option<usize>),
    w: usize,
    (cur, vel): (&[f64], &[f64]),
    df: &mut [f64],
    dth: &[f64],
) {
    let (u, q, z) = (&d[U..U + 3], &d[Q..Q + 3], d[ZEFF]);
    let (alpha, beta) = (d[ALPHA], d[BETA]);
    let (e, sr) = (d[ELONGATION], d[RATE]);
    for col in 0..w {
        let at = |m: &[f64], e: usize, c: usize| m[(3 * e + c) * w + col];
        // Spelled out, not `[0, 1, 2].map(..)`: the array map was not inlined here and took a
        // quarter of a pass as out-of-line calls (perf on the 20 x 20 cloth's fit).
        let (dd, dv) = match j {
            Some(j) => {
                let diff = |m: &[f64], c: usize| at(m, j, c) - at(m, i, c);
                (
                    [diff(cur, 0), diff(cur, 1), diff(cur, 2)],
                    [diff(vel, 0), diff(vel, 1), diff(vel, 2)],
                )
            }
            None => (
                [-at(cur, i, 0), -at(cur, i, 1), -at(cur, i, 2)],
                [-at(vel, i, 0), -at(vel, i, 1), -at(vel, i, 2)],
            ),
        };
        // θ forcing along u: ∂f_i/∂θ · dθ = (e dK - K dl0 + s dZ + s|s| dZ₂) u.
        let th = |s: usize| if s == NONE { 0.0 } else { dth[s * w + col] };
        let mut theta = e * th(slots[0]) - k * th(slots[1]) + sr * th(slots[2]);
        if slots[3] != NONE {
            theta += sr * sr.abs() * th(slots[3]);
        }
        // A dd + B dv + θ forcing = β dd + u (α u·dd + q·dd + Z' u·dv + θ forcing).
        let ud = u[0] * dd[0] + u[1] * dd[1] + u[2] * dd[2];
        let qd = q[0] * dd[0] + q[1] * dd[1] + q[2] * dd[2];
        let uv = u[0] * dv[0] + u[1] * dv[1] + u[2] * dv[2];
        let along = alpha * ud + qd + z * uv + theta;
        for c in 0..3 {
            let g = beta * dd[c] + u[c] * along;
            df[(3 * i + c) * w + col] += g;
            if let Some(j) = j {
                df[(3 * j + c) * w + col] -= g;
            }
        }
    }
}

/// Matrix-free adjoint of one link from its record `d`: `na += (∂f/∂x)ᵀ φ`, `psi += (∂f/∂v)ᵀ φ`
/// and `grad += (∂f/∂θ)ᵀ φ` over w cotangents (as [`forward`]'s arguments). Aᵀ is applied
/// explicitly: A is not symmetric when the link is damped.
#[allow(clippy::too_many_arguments)]
#[inline(always)]
pub(crate) fn adjoint(
    d: &[f64],
    k: f64,
    slots: &[usize; 4],
    (i, j): (usize, Option<usize>),
    w: usize,
    phi: &[f64],
    (na, psi): (&mut [f64], &mut [f64]),
    grad: &mut [f64],
) {
    let (u, q, z) = (&d[U..U + 3], &d[Q..Q + 3], d[ZEFF]);
    let (alpha, beta) = (d[ALPHA], d[BETA]);
    let (e, sr) = (d[ELONGATION], d[RATE]);
    for col in 0..w {
        // Spelled out as in `forward`: the array map was not inlined.
        let at = |e: usize, c: usize| phi[(3 * e + c) * w + col];
        let del = match j {
            Some(j) => [
                at(j, 0) - at(i, 0),
                at(j, 1) - at(i, 1),
                at(j, 2) - at(i, 2),
            ],
            None => [-at(i, 0), -at(i, 1), -at(i, 2)],
        };
        let ud = u[0] * del[0] + u[1] * del[1] + u[2] * del[2];
        for c in 0..3 {
            // Aᵀ δ = β δ + (α u + q) (u·δ).
            let g = beta * del[c] + (alpha * u[c] + q[c]) * ud;
            let h = z * u[c] * ud;
            na[(3 * i + c) * w + col] += g;
            psi[(3 * i + c) * w + col] += h;
            if let Some(j) = j {
                na[(3 * j + c) * w + col] -= g;
                psi[(3 * j + c) * w + col] -= h;
            }
        }
        // θ: -δ·∂f_i/∂θ = -(u·δ) (e, -K, s, s|s|).
        for (s, f) in slots.iter().zip([e, -k, sr, sr * sr.abs()]) {
            if *s != NONE {
                grad[s * w + col] -= f * ud;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use cordis_core::forces::spring::spring_force_quadratic;

    /// ∂f/∂(x_j, v_j) and ∂f/∂(K, l0, Z, Z₂) against central differences of the core's kernel,
    /// for rates of both signs (through the `s |s|` of the quadratic viscosity).
    #[test]
    fn quadratic_spring_derivatives_match_central_differences_of_the_core_kernel() {
        let xi = Vec3::new(0.1, -0.2, 0.05);
        let xj = Vec3::new(0.7, 0.1, -0.3);
        let vi = Vec3::new(0.2, 0.1, -0.4);
        for vj in [Vec3::new(-0.5, 0.9, 0.3), Vec3::new(1.5, -0.2, -0.9)] {
            let c = [35.0, 0.6, 0.3, 1.7];
            let f =
                |xj: &Vec3, vj: &Vec3, c: [f64; 4]| spring_force_quadratic((&xi, xj), (&vi, vj), c);
            let lk = spring_link(&xj, &xi, &vj, &vi, c[0], c[1], c[2], c[3]);
            let h = 1e-6;
            for e in 0..3 {
                let mut dx = Vec3::zeros();
                dx[e] = h;
                let fd_x = (f(&(xj + dx), &vj, c) - f(&(xj - dx), &vj, c)) / (2.0 * h);
                let fd_v = (f(&xj, &(vj + dx), c) - f(&xj, &(vj - dx), c)) / (2.0 * h);
                for r in 0..3 {
                    let scale = 1.0 + lk.a[r][e].abs();
                    assert!((fd_x[r] - lk.a[r][e]).abs() < 1e-7 * scale, "a[{r}][{e}]");
                    assert!((fd_v[r] - lk.b[r][e]).abs() < 1e-7 * scale, "b[{r}][{e}]");
                }
            }
            for t in 0..4 {
                let (mut cp, mut cm) = (c, c);
                cp[t] += h;
                cm[t] -= h;
                let fd = (f(&xj, &vj, cp) - f(&xj, &vj, cm)) / (2.0 * h);
                assert!(
                    (fd - lk.dp[t]).norm() < 1e-7 * (1.0 + lk.dp[t].norm()),
                    "θ {t}"
                );
            }
        }
    }
}

#[cfg(test)]
// Index loops mirror the 3 × 3 and 3 × 4 derivative layouts.
#[allow(clippy::needless_range_loop)]
mod record_tests {
    use super::*;
    use approx::assert_relative_eq;

    /// Links from a damped quadratic spring to an undamped one, and a zero-length one (u = 0).
    fn links() -> Vec<SpringLink> {
        let (xi, vi) = (Vec3::new(0.1, -0.2, 0.05), Vec3::new(0.2, 0.1, -0.4));
        vec![
            spring_link(
                &Vec3::new(0.7, 0.1, -0.3),
                &xi,
                &Vec3::new(-0.5, 0.9, 0.3),
                &vi,
                35.0,
                0.6,
                0.3,
                1.7,
            ),
            spring_link(
                &Vec3::new(-0.4, 0.3, 0.2),
                &xi,
                &vi,
                &vi,
                12.0,
                0.9,
                0.0,
                0.0,
            ),
            spring_link(&xi, &xi, &Vec3::new(1.0, 0.0, 0.0), &vi, 5.0, 0.2, 0.4, 0.0),
        ]
    }

    /// The factored record (α u uᵀ + β I + u qᵀ) rebuilds the link's A, and the record-driven
    /// forward and adjoint apply A, B = Z' u uᵀ and ∂f/∂θ as the link's full matrices do
    /// (guards the 11-float record against the 15-float one it replaced).
    #[test]
    fn a_stored_record_applies_the_links_full_derivatives() {
        let slots = [0, 1, 2, 3];
        let k_of = [35.0, 12.0, 5.0];
        for (lk, k) in links().into_iter().zip(k_of) {
            let mut d = [0.0; LINK];
            lk.store(&mut d);
            let a = a_matrix(&d);
            for r in 0..3 {
                for c in 0..3 {
                    assert_relative_eq!(a[3 * r + c], lk.a[r][c], epsilon = 1e-13);
                }
            }
            // Two particles (rows 0..6), one direction; θ directions in 4 slots.
            let cur = [0.3, -0.7, 0.2, 1.1, 0.4, -0.5];
            let vel = [-0.2, 0.6, 0.9, 0.1, -0.8, 0.3];
            let dth = [0.5, -1.5, 2.0, 0.7];
            let mut df = [0.0; 6];
            forward(&d, k, &slots, (0, Some(1)), 1, (&cur, &vel), &mut df, &dth);
            let mut diff = [0.0; 6];
            for c in 0..3 {
                diff[c] = cur[3 + c] - cur[c];
                diff[3 + c] = vel[3 + c] - vel[c];
            }
            let mut want = [0.0; 3];
            for r in 0..3 {
                let mut g = 0.0;
                for c in 0..3 {
                    g += lk.a[r][c] * diff[c] + lk.b[r][c] * diff[3 + c];
                }
                for t in 0..4 {
                    g += lk.dp[t][r] * dth[t];
                }
                want[r] = g;
            }
            for r in 0..3 {
                assert_relative_eq!(df[r], want[r], epsilon = 1e-12);
                assert_relative_eq!(df[3 + r], -want[r], epsilon = 1e-12);
            }
            // Adjoint: ⟨δ, A dd + B dv + ∂f/∂θ dθ⟩ = ⟨Aᵀδ, dd⟩ + ⟨Bᵀδ, dv⟩ + ⟨∂f/∂θᵀ δ, dθ⟩.
            let phi = [0.0, 0.0, 0.0, 0.4, -0.9, 0.25];
            let (mut na, mut psi, mut grad) = ([0.0; 6], [0.0; 6], [0.0; 4]);
            adjoint(
                &d,
                k,
                &slots,
                (0, Some(1)),
                1,
                &phi,
                (&mut na, &mut psi),
                &mut grad,
            );
            let lhs: f64 = (0..3).map(|c| phi[3 + c] * (-want[c])).sum();
            let rhs: f64 = (0..6)
                .map(|r| na[r] * cur[r] + psi[r] * vel[r])
                .sum::<f64>()
                + (0..4).map(|t| grad[t] * dth[t]).sum::<f64>();
            assert_relative_eq!(lhs, rhs, epsilon = 1e-12);
        }
    }
}
