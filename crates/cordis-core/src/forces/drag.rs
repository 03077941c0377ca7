//! `drag`: viscosity of the environment, `F_i = -Z v_i`.

use super::Run;
use crate::Vec3;

#[derive(Clone, Debug, Default)]
pub struct DragPass {
    pub runs: Vec<Run>,
    pub particles: Vec<u32>,
}

impl DragPass {
    /// `p[run.param]` = damping Z (N·s/m).
    pub fn accumulate(&self, p: &[f64], v: &[Vec3], f: &mut [Vec3]) {
        for r in &self.runs {
            let z = p[r.param];
            for &i in &self.particles[r.start..r.end] {
                let i = i as usize;
                f[i] -= v[i] * z;
            }
        }
    }
}
