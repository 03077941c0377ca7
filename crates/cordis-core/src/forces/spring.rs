//! `spring`: `F_i = (K (L - l0) + Z s) u`, `F_j = -F_i` (SPEC §2.2, thesis eq 2.13).

use super::{unit_and_length, Run};
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
    for &[i, j] in pairs {
        let (i, j) = (i as usize, j as usize);
        let fi = spring_force::<DAMPED>(&x[i], &x[j], &v[i], &v[j], k, l0, z);
        f[i] += fi;
        f[j] -= fi;
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
