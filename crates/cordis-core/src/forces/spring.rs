//! `spring`: `F_i = (K (L - l0) + Z s + Z₂ s |s|) u`, `F_j = -F_i` (SPEC §2.2, thesis eq
//! 2.13), `s = (v_j - v_i) · u` the rate of elongation (m/s). The quadratic viscosity Z₂
//! (N·s²/m², key `damping_quadratic`, thesis §4.3's "visc n.l") is optional: a type without
//! it takes the kernels below with `QUADRATIC = false`, the same arithmetic as before it
//! existed, so its motion is bit for bit unchanged.

use super::{unit_and_length, Run, MIN_LENGTH};
use crate::Vec3;

/// Binary links in runs of one type; also used for `damper`-free conditional pairs' kernel.
#[derive(Clone, Debug, Default)]
pub struct SpringPass {
    pub runs: Vec<Run>,
    pub pairs: Vec<[u32; 2]>,
    /// Per run: the slot of its type's Z₂ in the parameter vector, when the type has one.
    pub quadratic: Vec<Option<usize>>,
}

impl SpringPass {
    /// Parameters per type: `p[run.param..]` = stiffness K (N/m), rest length l0 (m), damping
    /// Z (N·s/m), and Z₂ (N·s²/m²) at the run's `quadratic` slot. Runs whose Z and Z₂ are 0
    /// skip the velocity terms, runs without Z₂ (or Z₂ = 0) the quadratic one: one branch
    /// per run, none per link.
    pub fn accumulate(&self, p: &[f64], x: &[Vec3], v: &[Vec3], f: &mut [Vec3]) {
        for (ri, r) in self.runs.iter().enumerate() {
            let (k, l0, z) = (p[r.param], p[r.param + 1], p[r.param + 2]);
            let z2 = self
                .quadratic
                .get(ri)
                .copied()
                .flatten()
                .map_or(0.0, |s| p[s]);
            let pairs = &self.pairs[r.start..r.end];
            if z2 != 0.0 {
                spring_run::<true, true>(pairs, [k, l0, z, z2], x, v, f);
            } else if z == 0.0 {
                spring_run::<false, false>(pairs, [k, l0, 0.0, 0.0], x, v, f);
            } else {
                spring_run::<true, false>(pairs, [k, l0, z, 0.0], x, v, f);
            }
        }
    }
}

/// One run's forces; `c = [K, l0, Z, Z₂]`.
#[inline(always)]
pub(crate) fn spring_run<const DAMPED: bool, const QUADRATIC: bool>(
    pairs: &[[u32; 2]],
    c: [f64; 4],
    x: &[Vec3],
    v: &[Vec3],
    f: &mut [Vec3],
) {
    // Blocks of links in three sweeps: gather the ends' differences into lanes, compute every
    // link's force lane-wise (independent arithmetic the compiler vectorises: square roots and
    // divisions two or four at a time), then scatter in link order — the same operations in
    // the same order as one link at a time, so the sums are bit for bit the same.
    let [k, l0, z, z2] = c;
    const LANES: usize = 32;
    let mut d = [[0.0f64; LANES]; 3];
    let mut w = [[0.0f64; LANES]; 3];
    let mut mag = [0.0f64; LANES];
    for block in pairs.chunks(LANES) {
        for (n, &[i, j]) in block.iter().enumerate() {
            let (i, j) = (i as usize, j as usize);
            let (dd, ww) = (x[j] - x[i], v[j] - v[i]);
            for c in 0..3 {
                d[c][n] = dd[c];
                w[c][n] = ww[c];
            }
        }
        for n in 0..block.len() {
            let l = (d[0][n] * d[0][n] + d[1][n] * d[1][n] + d[2][n] * d[2][n]).sqrt();
            let inv = if l >= MIN_LENGTH { 1.0 / l } else { 0.0 };
            for dc in d.iter_mut() {
                dc[n] *= inv;
            }
            let mut m = k * (l - l0);
            if DAMPED {
                let s = w[0][n] * d[0][n] + w[1][n] * d[1][n] + w[2][n] * d[2][n];
                m += z * s;
                if QUADRATIC {
                    m += z2 * (s * s.abs());
                }
            }
            mag[n] = m;
        }
        for (n, &[i, j]) in block.iter().enumerate() {
            let fi = Vec3::new(d[0][n], d[1][n], d[2][n]) * mag[n];
            f[i as usize] += fi;
            f[j as usize] -= fi;
        }
    }
}

/// Force on the first end of a spring from `xi` to `xj`.
#[inline(always)]
pub fn spring_force<const DAMPED: bool>(
    xi: &Vec3,
    xj: &Vec3,
    vi: &Vec3,
    vj: &Vec3,
    k: f64,
    l0: f64,
    z: f64,
) -> Vec3 {
    let (u, l) = unit_and_length(&(xj - xi));
    let mut mag = k * (l - l0);
    if DAMPED {
        mag += z * (vj - vi).dot(&u);
    }
    u * mag
}

/// [`spring_force`] with the quadratic viscosity: `(K (L - l0) + Z s + Z₂ s |s|) u`.
#[inline(always)]
pub fn spring_force_quadratic(
    (xi, xj): (&Vec3, &Vec3),
    (vi, vj): (&Vec3, &Vec3),
    [k, l0, z, z2]: [f64; 4],
) -> Vec3 {
    let (u, l) = unit_and_length(&(xj - xi));
    let s = (vj - vi).dot(&u);
    u * (k * (l - l0) + z * s + z2 * (s * s.abs()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;

    /// Two ends 0.5 m apart along x, separating at 2 m/s: s = 2, so the force on i is
    /// `(K (0.5 - l0) + 2 Z + 4 Z₂) x̂` by hand.
    #[test]
    fn quadratic_viscosity_adds_z2_s_abs_s_along_the_link() {
        let x = [Vec3::zeros(), Vec3::new(0.5, 0.0, 0.0)];
        let v = [Vec3::new(-0.5, 0.3, 0.0), Vec3::new(1.5, -0.2, 0.0)];
        let (k, l0, z, z2) = (10.0, 0.4, 0.7, 0.25);
        let mut f = [Vec3::zeros(); 2];
        let pass = SpringPass {
            runs: vec![Run {
                param: 0,
                start: 0,
                end: 1,
            }],
            pairs: vec![[0, 1]],
            quadratic: vec![Some(3)],
        };
        pass.accumulate(&[k, l0, z, z2], &x, &v, &mut f);
        let by_hand = 10.0 * 0.1 + 0.7 * 2.0 + 0.25 * 4.0;
        assert_relative_eq!(f[0].x, by_hand, max_relative = 1e-15);
        assert_relative_eq!(f[1].x, -by_hand, max_relative = 1e-15);
        assert_eq!((f[0].y, f[0].z), (0.0, 0.0));
        // Closing at the same speed: the quadratic term changes sign with s (s |s|, not s²).
        let closing = [v[1], v[0]];
        let mut g = [Vec3::zeros(); 2];
        pass.accumulate(&[k, l0, z, z2], &x, &closing, &mut g);
        assert_relative_eq!(
            g[0].x,
            10.0 * 0.1 - 0.7 * 2.0 - 0.25 * 4.0,
            max_relative = 1e-15
        );
        let one = spring_force_quadratic((&x[0], &x[1]), (&v[0], &v[1]), [k, l0, z, z2]);
        assert_relative_eq!(one.x, by_hand, max_relative = 1e-15);
    }

    /// The force's derivative in the rate, `Z + 2 Z₂ |s|` (what the stability bound counts),
    /// against central differences of the kernel on both sides of s = 0.
    #[test]
    fn quadratic_viscosity_rate_derivative_matches_finite_differences() {
        let x = [Vec3::new(0.1, 0.2, -0.1), Vec3::new(0.7, -0.1, 0.3)];
        let (k, l0, z, z2) = (3.0, 0.5, 0.2, 1.3);
        let u = (x[1] - x[0]).normalize();
        for s0 in [-1.7, -0.2, 0.3, 2.5] {
            let force = |s: f64| {
                let v = [Vec3::zeros(), u * s];
                spring_force_quadratic((&x[0], &x[1]), (&v[0], &v[1]), [k, l0, z, z2]).dot(&u)
            };
            let h = 1e-6;
            let fd = (force(s0 + h) - force(s0 - h)) / (2.0 * h);
            assert_relative_eq!(fd, z + 2.0 * z2 * f64::abs(s0), max_relative = 1e-8);
        }
    }

    /// Z₂ = 0 takes the kernel without the quadratic term: the same bits as a type without it.
    #[test]
    fn a_zero_quadratic_viscosity_gives_the_plain_springs_bits() {
        let x = [Vec3::new(0.0, 0.1, 0.0), Vec3::new(0.9, 0.3, -0.2)];
        let v = [Vec3::new(0.3, -0.1, 0.2), Vec3::new(-0.4, 0.5, 0.1)];
        let mut with = [Vec3::zeros(); 2];
        let mut without = [Vec3::zeros(); 2];
        let run = Run {
            param: 0,
            start: 0,
            end: 1,
        };
        let p = [4.0, 0.8, 0.3, 0.0];
        SpringPass {
            runs: vec![run],
            pairs: vec![[0, 1]],
            quadratic: vec![Some(3)],
        }
        .accumulate(&p, &x, &v, &mut with);
        SpringPass {
            runs: vec![run],
            pairs: vec![[0, 1]],
            quadratic: vec![None],
        }
        .accumulate(&p[..3], &x, &v, &mut without);
        assert_eq!(with, without);
    }
}
