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

use cordis_core::Vec3;

use super::NONE;

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
    damped: bool,
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
        damped: zeff != 0.0,
    }
}

impl SpringLink {
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
        for r in 0..3 {
            let ri = (3 * i + r) * w;
            let rj = j.map(|j| (3 * j + r) * w);
            let a = self.a[r];
            let b = self.b[r];
            let (d0, d1, d2) = (&diff[0..w], &diff[w..2 * w], &diff[2 * w..3 * w]);
            let (e0, e1, e2) = (
                &diff[3 * w..4 * w],
                &diff[4 * w..5 * w],
                &diff[5 * w..6 * w],
            );
            for q in 0..w {
                let mut g = a[0] * d0[q] + a[1] * d1[q] + a[2] * d2[q];
                if self.damped {
                    g += b[0] * e0[q] + b[1] * e1[q] + b[2] * e2[q];
                }
                df[ri + q] += g;
                if let Some(rj) = rj {
                    df[rj + q] -= g;
                }
            }
            for (t, &col) in slots.iter().enumerate() {
                if col != NONE {
                    df[ri + col] += self.dp[t][r];
                    if let Some(rj) = rj {
                        df[rj + col] -= self.dp[t][r];
                    }
                }
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
