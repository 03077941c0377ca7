//! `anchor`: a spring from particle i to a fixed point (unary position link).

use super::{spring::spring_force, Run};
use crate::Vec3;

#[derive(Clone, Debug, Default)]
pub struct AnchorPass {
    pub runs: Vec<Run>,
    pub particles: Vec<u32>,
    /// Anchor point of each instance, m (same order as `particles`).
    pub points: Vec<Vec3>,
}

impl AnchorPass {
    /// Parameters as a spring's: K, l0, Z; the point has zero velocity.
    pub fn accumulate(&self, p: &[f64], x: &[Vec3], v: &[Vec3], f: &mut [Vec3]) {
        let still = Vec3::zeros();
        for r in &self.runs {
            let (k, l0, z) = (p[r.param], p[r.param + 1], p[r.param + 2]);
            let items = self.particles[r.start..r.end]
                .iter()
                .zip(&self.points[r.start..r.end]);
            if z == 0.0 {
                for (&i, point) in items {
                    let i = i as usize;
                    f[i] += spring_force::<false>(&x[i], point, &v[i], &still, k, l0, 0.0);
                }
            } else {
                for (&i, point) in items {
                    let i = i as usize;
                    f[i] += spring_force::<true>(&x[i], point, &v[i], &still, k, l0, z);
                }
            }
        }
    }
}
