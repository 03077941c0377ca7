//! An angle link's force (`cordis_core::forces::angle`) and its derivatives.
//!
//! With `a = x_i - x_j`, `b = x_k - x_j` (j the vertex), `c = a·b / (|a| |b|)`,
//! `g_a = ∂c/∂a = b/(|a||b|) - c a/|a|²`, `g_b = ∂c/∂b = a/(|a||b|) - c b/|b|²`, the core
//! computes `f_i = G g_a`, `f_k = G g_b`, `f_j = -(f_i + f_k)` with `G = -K (c - c0) φ` and the
//! fade φ of its singular zone: `φ = (|a| / (ε |b|))²` when `|a| < ε |b|`, `(|b| / (ε |a|))²`
//! when `|b| < ε |a|`, else 1 (ε = `SINGULAR_ARM`). Its derivatives in (a, b):
//!
//! ```text
//! ∂f_i/∂a = G H_aa + g_a (∂G/∂a)ᵀ        ∂f_i/∂b = G H_ab + g_a (∂G/∂b)ᵀ
//! ∂f_k/∂a = G H_ba + g_b (∂G/∂a)ᵀ        ∂f_k/∂b = G H_bb + g_b (∂G/∂b)ᵀ
//! ∂G/∂a = -K φ g_a - K (c - c0) ∂φ/∂a     ∂φ/∂a = ±2 φ a/|a|² (+ when |a| is the short arm)
//! H_aa = -b aᵀ/(|a|³|b|) - a g_aᵀ/|a|² - c (I/|a|² - 2 a aᵀ/|a|⁴)
//! H_ab = I/(|a||b|) - b bᵀ/(|a||b|³) - a g_bᵀ/|a|²,   H_ba = H_abᵀ
//! H_bb = -a bᵀ/(|a||b|³) - b g_bᵀ/|b|² - c (I/|b|² - 2 b bᵀ/|b|⁴)
//! ∂(f_i, f_k)/∂K = -(c - c0) φ (g_a, g_b),   ∂(f_i, f_k)/∂c0 = K φ (g_a, g_b)
//! ```
//!
//! (the H are the Hessian blocks of c). Outside the fade zone the force is minus the gradient
//! of an energy and the 6×6 Jacobian is symmetric; inside it is not (one factor on a
//! gradient), so the matrix-free adjoint applies the transpose explicitly. A degenerate angle
//! (an arm shorter than `MIN_LENGTH`) has no force and no derivative, as in the core; the
//! boundaries of the fade zone and of degeneracy are switches (the derivative of the branch the
//! core takes). The angle force reads no velocity.
//!
//! Since `f_j = -(f_i + f_k)` and the force depends on positions only through a and b, with
//! `δa = s_i - s_j`, `δb = s_k - s_j` the tangent is `δf_i = J_i (δa, δb)`, `δf_k = J_k (δa, δb)`,
//! `δf_j = -(δf_i + δf_k)`; its adjoint, with `α = φ_i - φ_j`, `β = φ_k - φ_j`, `h = Jᵀ (α, β)`,
//! adds `h_a` to particle i, `h_b` to k and `-(h_a + h_b)` to j.

use cordis_core::forces::angle::{AnglePass, SINGULAR_ARM};
use cordis_core::forces::MIN_LENGTH;
use cordis_core::Vec3;
use nalgebra::Matrix3;

use super::no_column::NONE;

/// Floats stored per angle and step by the matrix-free linearisation: the 6×6 Jacobian
/// ∂(f_i, f_k)/∂(a, b) row-major, `φ (g_a, g_b)` and `c - c0` (zeros: a degenerate angle).
pub(crate) const ANGLE: usize = 43;

/// One angle's linearisation (module docs).
pub(crate) struct AngleLink {
    /// ∂(f_i, f_k)/∂(a, b): rows f_i then f_k, columns a then b.
    pub jac: [[f64; 6]; 6],
    /// `φ (g_a, g_b)`: ∂f/∂K = -e · this, ∂f/∂c0 = K · this.
    pub g0: [f64; 6],
    /// `c - c0`.
    pub e: f64,
}

/// The angle at `xj` between `xi` and `xk` (module docs); `None` when degenerate.
pub(crate) fn angle_link(xi: &Vec3, xj: &Vec3, xk: &Vec3, k: f64, c0: f64) -> Option<AngleLink> {
    let a = xi - xj;
    let b = xk - xj;
    let (la, lb) = (a.norm(), b.norm());
    if la < MIN_LENGTH || lb < MIN_LENGTH {
        return None;
    }
    let inv_ab = 1.0 / (la * lb);
    let (la2, lb2) = (la * la, lb * lb);
    let c = a.dot(&b) * inv_ab;
    let ga = b * inv_ab - a * (c / la2);
    let gb = a * inv_ab - b * (c / lb2);
    // The fade of the singular zone, as the core decides it.
    let (phi, dphi_a, dphi_b) = if la < SINGULAR_ARM * lb {
        let f = (la / (SINGULAR_ARM * lb)).powi(2);
        (f, a * (2.0 * f / la2), b * (-2.0 * f / lb2))
    } else if lb < SINGULAR_ARM * la {
        let f = (lb / (SINGULAR_ARM * la)).powi(2);
        (f, a * (-2.0 * f / la2), b * (2.0 * f / lb2))
    } else {
        (1.0, Vec3::zeros(), Vec3::zeros())
    };
    let e = c - c0;
    let g = -k * e * phi;
    let dg_a = ga * (-k * phi) + dphi_a * (-k * e);
    let dg_b = gb * (-k * phi) + dphi_b * (-k * e);
    let id = Matrix3::<f64>::identity();
    let haa = -(b * a.transpose()) / (la2 * la * lb)
        - (a * ga.transpose()) / la2
        - (id / la2 - a * a.transpose() * (2.0 / (la2 * la2))) * c;
    let hab = id * inv_ab - (b * b.transpose()) / (la * lb2 * lb) - (a * gb.transpose()) / la2;
    let hbb = -(a * b.transpose()) / (la * lb2 * lb)
        - (b * gb.transpose()) / lb2
        - (id / lb2 - b * b.transpose() * (2.0 / (lb2 * lb2))) * c;
    let blocks = [
        [
            haa * g + ga * dg_a.transpose(),
            hab * g + ga * dg_b.transpose(),
        ],
        [
            hab.transpose() * g + gb * dg_a.transpose(),
            hbb * g + gb * dg_b.transpose(),
        ],
    ];
    let mut jac = [[0.0; 6]; 6];
    for (bi, row) in blocks.iter().enumerate() {
        for (bj, m) in row.iter().enumerate() {
            for r in 0..3 {
                for q in 0..3 {
                    jac[3 * bi + r][3 * bj + q] = m[(r, q)];
                }
            }
        }
    }
    let mut g0 = [0.0; 6];
    for r in 0..3 {
        g0[r] = ga[r] * phi;
        g0[3 + r] = gb[r] * phi;
    }
    Some(AngleLink { jac, g0, e })
}

impl AngleLink {
    fn store(&self, d: &mut [f64]) {
        for (r, row) in self.jac.iter().enumerate() {
            d[6 * r..6 * r + 6].copy_from_slice(row);
        }
        d[36..42].copy_from_slice(&self.g0);
        d[42] = self.e;
    }
}

/// Dense tangent: adds every angle's `∂F/∂x S + ∂F/∂θ` into `df` (rows of width w). `diff` is
/// scratch of 6 w.
#[allow(clippy::too_many_arguments)]
pub(super) fn dense(
    pass: &AnglePass,
    p: &[f64],
    of_slot: &[usize],
    x: &[Vec3],
    s: &[f64],
    w: usize,
    df: &mut [f64],
    diff: &mut [f64],
) {
    for r in &pass.runs {
        let (k, c0) = (p[r.param], p[r.param + 1]);
        let (ck, cc) = (of_slot[r.param], of_slot[r.param + 1]);
        for &[i, j, m] in &pass.triples[r.start..r.end] {
            let (i, j, m) = (i as usize, j as usize, m as usize);
            let Some(lk) = angle_link(&x[i], &x[j], &x[m], k, c0) else {
                continue;
            };
            for c in 0..3 {
                let (ri, rj, rm) = ((3 * i + c) * w, (3 * j + c) * w, (3 * m + c) * w);
                for q in 0..w {
                    diff[c * w + q] = s[ri + q] - s[rj + q];
                    diff[(3 + c) * w + q] = s[rm + q] - s[rj + q];
                }
            }
            for c in 0..3 {
                let (ri, rj, rm) = ((3 * i + c) * w, (3 * j + c) * w, (3 * m + c) * w);
                let (ji, jm) = (&lk.jac[c], &lk.jac[3 + c]);
                for q in 0..w {
                    let (mut gi, mut gm) = (0.0, 0.0);
                    for e in 0..6 {
                        let d = diff[e * w + q];
                        gi += ji[e] * d;
                        gm += jm[e] * d;
                    }
                    df[ri + q] += gi;
                    df[rm + q] += gm;
                    df[rj + q] -= gi + gm;
                }
                for (col, factor) in [(ck, -lk.e), (cc, k)] {
                    if col != NONE {
                        let (fi, fm) = (factor * lk.g0[c], factor * lk.g0[3 + c]);
                        df[ri + col] += fi;
                        df[rm + col] += fm;
                        df[rj + col] -= fi + fm;
                    }
                }
            }
        }
    }
}

/// Matrix-free linearisation of one step: every angle's record (`ANGLE` floats each, in
/// pass order) into `out`.
pub(crate) fn store(pass: &AnglePass, p: &[f64], x: &[Vec3], out: &mut [f64]) {
    for r in &pass.runs {
        let (k, c0) = (p[r.param], p[r.param + 1]);
        for (l, &[i, j, m]) in pass.triples[r.start..r.end].iter().enumerate() {
            let d = &mut out[(r.start + l) * ANGLE..][..ANGLE];
            match angle_link(&x[i as usize], &x[j as usize], &x[m as usize], k, c0) {
                Some(lk) => lk.store(d),
                None => d.fill(0.0),
            }
        }
    }
}

/// Matrix-free forward: `df += ∂F/∂x s + ∂F/∂θ dθ` over w directions, from one step's
/// records `lin` (`dth`: the θ directions in physical units, row-major × w).
#[allow(clippy::too_many_arguments)]
pub(crate) fn forward(
    pass: &AnglePass,
    lin: &[f64],
    p: &[f64],
    of_slot: &[usize],
    w: usize,
    cur: &[f64],
    df: &mut [f64],
    dth: &[f64],
) {
    for r in &pass.runs {
        let k = p[r.param];
        let (ck, cc) = (of_slot[r.param], of_slot[r.param + 1]);
        for (l, &[i, j, m]) in pass.triples[r.start..r.end].iter().enumerate() {
            let (i, j, m) = (i as usize, j as usize, m as usize);
            let d = &lin[(r.start + l) * ANGLE..][..ANGLE];
            let (jac, g0, e) = (&d[..36], &d[36..42], d[42]);
            for col in 0..w {
                let y = arms(cur, (i, j, m), w, col);
                let th = |s: usize| if s == NONE { 0.0 } else { dth[s * w + col] };
                let sigma = k * th(cc) - e * th(ck);
                let mut g = [0.0; 6];
                for (rr, gr) in g.iter_mut().enumerate() {
                    let row = &jac[6 * rr..6 * rr + 6];
                    *gr = row.iter().zip(&y).map(|(a, b)| a * b).sum::<f64>() + sigma * g0[rr];
                }
                for c in 0..3 {
                    df[(3 * i + c) * w + col] += g[c];
                    df[(3 * m + c) * w + col] += g[3 + c];
                    df[(3 * j + c) * w + col] -= g[c] + g[3 + c];
                }
            }
        }
    }
}

/// Column `col` of the two arms `(v_i - v_j, v_m - v_j)` of an angle i–j–m (vertex j) in rows
/// of width w. Spelled out, not `[..].map(..)`, which was not inlined in the springs' passes.
#[inline(always)]
fn arms(v: &[f64], (i, j, m): (usize, usize, usize), w: usize, col: usize) -> [f64; 6] {
    let at = |e: usize, c: usize| v[(3 * e + c) * w + col];
    [
        at(i, 0) - at(j, 0),
        at(i, 1) - at(j, 1),
        at(i, 2) - at(j, 2),
        at(m, 0) - at(j, 0),
        at(m, 1) - at(j, 1),
        at(m, 2) - at(j, 2),
    ]
}

/// Matrix-free adjoint: `na += (∂F/∂x)ᵀ φ` and the θ gradient `grad += (∂F/∂θ)ᵀ φ` (θ rows in
/// physical units, × w) from one step's records.
#[allow(clippy::too_many_arguments)]
pub(crate) fn adjoint(
    pass: &AnglePass,
    lin: &[f64],
    p: &[f64],
    of_slot: &[usize],
    w: usize,
    phi: &[f64],
    na: &mut [f64],
    grad: &mut [f64],
) {
    for r in &pass.runs {
        let k = p[r.param];
        let (ck, cc) = (of_slot[r.param], of_slot[r.param + 1]);
        for (l, &[i, j, m]) in pass.triples[r.start..r.end].iter().enumerate() {
            let (i, j, m) = (i as usize, j as usize, m as usize);
            let d = &lin[(r.start + l) * ANGLE..][..ANGLE];
            let (jac, g0, e) = (&d[..36], &d[36..42], d[42]);
            for col in 0..w {
                let y = arms(phi, (i, j, m), w, col);
                let mut h = [0.0; 6];
                for (rr, yr) in y.iter().enumerate() {
                    let row = &jac[6 * rr..6 * rr + 6];
                    for (hc, a) in h.iter_mut().zip(row) {
                        *hc += a * yr;
                    }
                }
                for c in 0..3 {
                    na[(3 * i + c) * w + col] += h[c];
                    na[(3 * m + c) * w + col] += h[3 + c];
                    na[(3 * j + c) * w + col] -= h[c] + h[3 + c];
                }
                let sigma: f64 = g0.iter().zip(&y).map(|(a, b)| a * b).sum();
                if ck != NONE {
                    grad[ck * w + col] -= e * sigma;
                }
                if cc != NONE {
                    grad[cc * w + col] += k * sigma;
                }
            }
        }
    }
}

/// The preconditioner's local model: adds each angle's `∂f_e/∂x_e` to its particles' 3×3
/// blocks `kii` (row-major, 9 per particle).
pub(crate) fn local(pass: &AnglePass, lin: &[f64], kii: &mut [f64]) {
    for (l, &[i, j, m]) in pass.triples.iter().enumerate() {
        let d = &lin[l * ANGLE..][..ANGLE];
        let at = |r: usize, c: usize| d[6 * r + c];
        for r in 0..3 {
            for c in 0..3 {
                let (aa, ab, ba, bb) = (at(r, c), at(r, 3 + c), at(3 + r, c), at(3 + r, 3 + c));
                kii[9 * i as usize + 3 * r + c] += aa;
                kii[9 * m as usize + 3 * r + c] += bb;
                kii[9 * j as usize + 3 * r + c] += aa + ab + ba + bb;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use cordis_core::forces::angle::angle_forces;

    /// The Jacobian and the θ derivatives against central differences of the core's kernel,
    /// outside and inside the singular zone (each arm the short one).
    #[test]
    fn angle_derivatives_match_central_differences_of_the_core_kernel() {
        let xj = Vec3::new(0.1, 0.2, -0.1);
        let cases = [
            (Vec3::new(0.8, 0.3, 0.1), Vec3::new(-0.2, 0.9, 0.4)),
            (Vec3::new(0.104, 0.203, -0.098), Vec3::new(-0.2, 0.9, 0.4)),
            (Vec3::new(0.8, 0.3, 0.1), Vec3::new(0.102, 0.196, -0.097)),
        ];
        let (k, c0) = (2.5, 0.3);
        for (n, (xi, xk)) in cases.into_iter().enumerate() {
            let lk = angle_link(&xi, &xj, &xk, k, c0).unwrap();
            let f = |a: Vec3, b: Vec3, k: f64, c0: f64| {
                let (fi, fk) = angle_forces(&(xj + a), &xj, &(xj + b), k, c0).unwrap();
                [fi[0], fi[1], fi[2], fk[0], fk[1], fk[2]]
            };
            let (a, b) = (xi - xj, xk - xj);
            let h = 1e-7 * a.norm().min(b.norm());
            let size = lk.jac.iter().flatten().fold(0.0_f64, |m, v| m.max(v.abs()));
            for c in 0..6 {
                let mut d = Vec3::zeros();
                d[c % 3] = h;
                let (p, m) = if c < 3 {
                    (f(a + d, b, k, c0), f(a - d, b, k, c0))
                } else {
                    (f(a, b + d, k, c0), f(a, b - d, k, c0))
                };
                for r in 0..6 {
                    let fd = (p[r] - m[r]) / (2.0 * h);
                    assert!(
                        (fd - lk.jac[r][c]).abs() <= 1e-6 * size,
                        "case {n}: J[{r}][{c}] = {}, central difference {fd}",
                        lk.jac[r][c]
                    );
                }
            }
            let h = 1e-6;
            let (dk_p, dk_m) = (f(a, b, k + h, c0), f(a, b, k - h, c0));
            let (dc_p, dc_m) = (f(a, b, k, c0 + h), f(a, b, k, c0 - h));
            for r in 0..6 {
                let fd_k = (dk_p[r] - dk_m[r]) / (2.0 * h);
                let fd_c = (dc_p[r] - dc_m[r]) / (2.0 * h);
                assert!((fd_k + lk.e * lk.g0[r]).abs() <= 1e-7 * (1.0 + fd_k.abs()));
                assert!((fd_c - k * lk.g0[r]).abs() <= 1e-7 * (1.0 + fd_c.abs()));
            }
        }
        assert!(angle_link(&xj, &xj, &Vec3::new(1.0, 0.0, 0.0), k, c0).is_none());
    }
}
