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
        self.pass(p, x, free, factor, |c| {
            let (i, j) = self.ends(c.link);
            if free[i] {
                moved(i);
            }
            if free[j] {
                moved(j);
            }
        });
    }

    /// The pass (limits × 1, the same bits as [`ProvotPass::apply`]), calling `record` with
    /// every correction it applies, in order, at the positions it saw (a correction moving at
    /// least one free end): what the output-error tangent differentiates.
    #[inline(always)]
    pub fn apply_recorded(
        &self,
        p: &[f64],
        x: &mut [Vec3],
        free: &[bool],
        record: impl FnMut(Correction),
    ) {
        self.pass(p, x, free, 1.0, record);
    }

    /// Link `l`'s ends.
    #[inline(always)]
    pub fn ends(&self, l: usize) -> (usize, usize) {
        (self.links[l].i as usize, self.links[l].j as usize)
    }

    #[inline(always)]
    fn pass(
        &self,
        p: &[f64],
        x: &mut [Vec3],
        free: &[bool],
        factor: f64,
        mut on: impl FnMut(Correction),
    ) {
        for (k, l) in self.links.iter().enumerate() {
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
                }
                (true, false) => {
                    x[i] += u * excess;
                }
                (false, true) => {
                    x[j] -= u * excess;
                }
                (false, false) => continue,
            }
            on(Correction {
                link: k,
                u,
                len,
                limit,
            });
        }
    }
}

/// One correction of the pass: link `link` (index in [`ProvotPass::links`]) was `len` long
/// along the unit vector `u` (from i to j) when the pass reached it, beyond its `limit`
/// `(1 + τc) l0` (m); its free ends moved by the excess `len - limit` toward each other (half
/// each when both are free).
#[derive(Clone, Copy, Debug)]
pub struct Correction {
    pub link: usize,
    pub u: Vec3,
    pub len: f64,
    pub limit: f64,
}
