//! `damper`: isotropic binary velocity link, `F_i = Z (v_j - v_i)`, `F_j = -F_i`.

use super::Run;
use crate::Vec3;

#[derive(Clone, Debug, Default)]
pub struct DamperPass {
    pub runs: Vec<Run>,
    pub pairs: Vec<[u32; 2]>,
}

impl DamperPass {
    /// `p[run.param]` = damping Z (N·s/m).
    pub fn accumulate(&self, p: &[f64], v: &[Vec3], f: &mut [Vec3]) {
        for r in &self.runs {
            let z = p[r.param];
            for &[i, j] in &self.pairs[r.start..r.end] {
                let (i, j) = (i as usize, j as usize);
                let fi = (v[j] - v[i]) * z;
                f[i] += fi;
                f[j] -= fi;
            }
        }
    }
}
