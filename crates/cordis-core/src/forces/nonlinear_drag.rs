//! `nonlinear_drag`: two-regime viscosity of the tadpole's medium (thesis §6.1.1):
//! `F_i = -z v_i` with `z = z1` while `|v_i| < v_max`, else `z2`.

use super::Run;
use crate::Vec3;

#[derive(Clone, Debug, Default)]
pub struct NonlinearDragPass {
    pub runs: Vec<Run>,
    pub particles: Vec<u32>,
}

impl NonlinearDragPass {
    /// `p[run.param..]` = z1, z2 (N·s/m), v_max (m/s).
    pub fn accumulate(&self, p: &[f64], v: &[Vec3], f: &mut [Vec3]) {
        for r in &self.runs {
            let (z1, z2, v_max) = (p[r.param], p[r.param + 1], p[r.param + 2]);
            for &i in &self.particles[r.start..r.end] {
                let i = i as usize;
                let z = if v[i].norm() < v_max { z1 } else { z2 };
                f[i] -= v[i] * z;
            }
        }
    }
}
