//! `angle`: ternary link on the angle at the middle particle j of (i, j, k).
//!
//! Energy `E = ½ K (cosθ - c0)²` with `cosθ = a·b / (|a| |b|)`, `a = x_i - x_j`,
//! `b = x_k - x_j`. Forces are `-∇E`:
//! `F_i = -K (c - c0) ∂c/∂a`, `F_k = -K (c - c0) ∂c/∂b`, `F_j = -(F_i + F_k)`, with
//! `∂c/∂a = b/(|a||b|) - c a/|a|²`. A degenerate angle (an arm shorter than 1e-12) has no force.
//!
//! The singular case: `|∂c/∂a| = sinθ/|a|` grows without bound as an arm shrinks (two of the
//! particles at one point), and so does the force, whose stiffness grows as `K/|a|²`: an angle
//! whose arm closes to a millimetre threw its particle metres in one step and the motion
//! exploded. Below [`SINGULAR_ARM`] times the other arm, the whole force is therefore faded by
//! `(|a| / (SINGULAR_ARM |b|))²` (and likewise for `b`): continuous where the zone begins, zero
//! at coincidence as before, its stiffness bounded by `K / (SINGULAR_ARM |b|)²`, and — one
//! common factor on a gradient of a rotation-invariant energy — with no net force or torque.
//! Outside the zone the force is the gradient, bit for bit. The stability bound
//! (`crate::stability`) counts the faded stiffness.

use super::{Run, MIN_LENGTH};
use crate::Vec3;

#[derive(Clone, Debug, Default)]
pub struct AnglePass {
    pub runs: Vec<Run>,
    pub triples: Vec<[u32; 3]>,
}

impl AnglePass {
    /// `p[run.param..]` = stiffness K (N·m), rest cosine c0.
    pub fn accumulate(&self, p: &[f64], x: &[Vec3], f: &mut [Vec3]) {
        for r in &self.runs {
            let (k, c0) = (p[r.param], p[r.param + 1]);
            for &[i, j, m] in &self.triples[r.start..r.end] {
                let (i, j, m) = (i as usize, j as usize, m as usize);
                if let Some((fi, fm)) = angle_forces(&x[i], &x[j], &x[m], k, c0) {
                    f[i] += fi;
                    f[m] += fm;
                    f[j] -= fi + fm;
                }
            }
        }
    }
}

/// An arm shorter than this fraction of the other one is in the singular zone, where the
/// force is faded (module documentation).
pub const SINGULAR_ARM: f64 = 1e-2;

/// Forces on the two outer particles of an angle link (the vertex gets minus their sum).
#[inline(always)]
pub fn angle_forces(xi: &Vec3, xj: &Vec3, xk: &Vec3, k: f64, c0: f64) -> Option<(Vec3, Vec3)> {
    let a = xi - xj;
    let b = xk - xj;
    let (la, lb) = (a.norm(), b.norm());
    if la < MIN_LENGTH || lb < MIN_LENGTH {
        return None;
    }
    let inv_ab = 1.0 / (la * lb);
    let c = a.dot(&b) * inv_ab;
    let g = -k * (c - c0);
    let dc_da = b * inv_ab - a * (c / (la * la));
    let dc_db = a * inv_ab - b * (c / (lb * lb));
    if la < SINGULAR_ARM * lb || lb < SINGULAR_ARM * la {
        let fade = (la / (SINGULAR_ARM * lb)).min(1.0).powi(2)
            * (lb / (SINGULAR_ARM * la)).min(1.0).powi(2);
        let g = g * fade;
        return Some((dc_da * g, dc_db * g));
    }
    Some((dc_da * g, dc_db * g))
}

/// Cosine of the angle at j, or `None` when degenerate.
pub fn cos_angle(xi: &Vec3, xj: &Vec3, xk: &Vec3) -> Option<f64> {
    let a = xi - xj;
    let b = xk - xj;
    let (la, lb) = (a.norm(), b.norm());
    (la >= MIN_LENGTH && lb >= MIN_LENGTH).then(|| a.dot(&b) / (la * lb))
}
