//! Provot's elongation limit (cloth, thesis §4.2): after each position update, one pass over
//! the limited springs in file order, each correction seen by the next. Where
//! `L > (1 + τc) l0`, each free end moves half the excess toward the other; a fixed end stays
//! and the free end takes the whole excess. `x(n)` is left alone, so the velocity is corrected
//! too.

use super::unit_and_length;
use crate::Vec3;

#[derive(Clone, Copy, Debug)]
pub struct ProvotLink {
    pub i: u32,
    pub j: u32,
    /// Offset of the spring type's parameters (rest length at `param + 1`).
    pub param: usize,
    /// Slot of the type's critical deformation rate τc in the parameter vector (an
    /// identifiable parameter, thesis Table 4.1).
    pub tau: usize,
}

#[derive(Clone, Debug, Default)]
pub struct ProvotPass {
    pub links: Vec<ProvotLink>,
}

impl ProvotPass {
    /// `free[i]` is false for fixed particles.
    pub fn apply(&self, p: &[f64], x: &mut [Vec3], free: &[bool]) {
        // × 1.0 is exact: the same bits as a pass without a factor.
        self.apply_with(p, x, free, 1.0, |_| {});
    }

    /// The pass with every limit multiplied by `factor`, calling `moved(i)` for each particle
    /// it moves (cascades included; a particle may be reported more than once). The exact
    /// solvers run it with `factor` slightly below 1 to find, with a safety margin, the
    /// predictions the limit acts on.
    #[inline(always)]
    pub fn apply_with(
        &self,
        p: &[f64],
        x: &mut [Vec3],
        free: &[bool],
        factor: f64,
        mut moved: impl FnMut(usize),
    ) {
        for l in &self.links {
            let (i, j) = (l.i as usize, l.j as usize);
            let limit = (1.0 + p[l.tau]) * p[l.param + 1] * factor;
            let d = x[j] - x[i];
            // Most links are within their limit: skip the square root when the squared length
            // is clearly below (the margin keeps the decision identical to `len > limit`).
            if d.norm_squared() < limit * limit * (1.0 - 1e-12) {
                continue;
            }
            let (u, len) = unit_and_length(&d);
            let excess = len - limit;
            if excess <= 0.0 {
                continue;
            }
            match (free[i], free[j]) {
                (true, true) => {
                    let half = u * (0.5 * excess);
                    x[i] += half;
                    x[j] -= half;
                    moved(i);
                    moved(j);
                }
                (true, false) => {
                    x[i] += u * excess;
                    moved(i);
                }
                (false, true) => {
                    x[j] -= u * excess;
                    moved(j);
                }
                (false, false) => {}
            }
        }
    }
}
