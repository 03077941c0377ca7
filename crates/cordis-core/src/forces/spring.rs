//! `spring`: `F_i = (K (L - l0) + Z s) u`, `F_j = -F_i` (SPEC §2.2, thesis eq 2.13).

use super::{unit_and_length, Run, MIN_LENGTH};
use crate::Vec3;

/// Binary links in runs of one type; also used for `damper`-free conditional pairs' kernel.
#[derive(Clone, Debug, Default)]
pub struct SpringPass {
    pub runs: Vec<Run>,
    pub pairs: Vec<[u32; 2]>,
}

impl SpringPass {
    /// Parameters per type: `p[run.param..]` = stiffness K (N/m), rest length l0 (m), damping
    /// Z (N·s/m). Runs whose Z is 0 skip the velocity terms.
    pub fn accumulate(&self, p: &[f64], x: &[Vec3], v: &[Vec3], f: &mut [Vec3]) {
        for r in &self.runs {
            let (k, l0, z) = (p[r.param], p[r.param + 1], p[r.param + 2]);
            let pairs = &self.pairs[r.start..r.end];
            if z == 0.0 {
                spring_run::<false>(pairs, k, l0, 0.0, x, v, f);
            } else {
                spring_run::<true>(pairs, k, l0, z, x, v, f);
            }
        }
    }
}

#[inline(always)]
pub(crate) fn spring_run<const DAMPED: bool>(
    pairs: &[[u32; 2]],
    k: f64,
    l0: f64,
    z: f64,
    x: &[Vec3],
    v: &[Vec3],
    f: &mut [Vec3],
) {
    // Blocks of links in three sweeps: gather the ends' differences into lanes, compute every
    // link's force lane-wise (independent arithmetic the compiler vectorises: square roots and
    // divisions two or four at a time), then scatter in link order — the same operations in
    // the same order as one link at a time, so the sums are bit for bit the same.
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
                m += z * (w[0][n] * d[0][n] + w[1][n] * d[1][n] + w[2][n] * d[2][n]);
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
