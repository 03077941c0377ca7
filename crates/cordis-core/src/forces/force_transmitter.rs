//! `force_transmitter` (thesis §5.4.3, SPEC §2.5): a dipole (a, b) that receives `g` times the
//! scalar tension of a source spring, usually in another world:
//!
//! ```text
//! T = K (L - l0) + Z s            of the source spring (i, j): N, positive = pulls together
//! F_a += g T u,  F_b -= g T u     u = unit vector a→b
//! ```
//!
//! The source feels nothing back, so the transmitter injects energy into the receiving world
//! (the thesis' "central control": a controller world drives the body's muscles). Stateless:
//! it reads the source at the same positions and velocities as every other pass.

use super::{unit_and_length, Run};
use crate::Vec3;

/// Instances in runs of one type; a run's parameter is `p[run.param]` = gain g (1).
#[derive(Clone, Debug, Default)]
pub struct ForceTransmitterPass {
    pub runs: Vec<Run>,
    /// `(a, b)` of each instance.
    pub pairs: Vec<[u32; 2]>,
    /// The source spring of each instance: its ends and the offset of its type's [K, l0, Z].
    pub sources: Vec<([u32; 2], usize)>,
}

impl ForceTransmitterPass {
    pub fn len(&self) -> usize {
        self.pairs.len()
    }

    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }

    /// Adds every transmitter's force at positions `x` (m), velocities `v` (m/s) to `f` (N).
    pub fn accumulate(&self, p: &[f64], x: &[Vec3], v: &[Vec3], f: &mut [Vec3]) {
        for r in &self.runs {
            let g = p[r.param];
            for m in r.start..r.end {
                let ([i, j], o) = self.sources[m];
                let (i, j) = (i as usize, j as usize);
                let (us, ls) = unit_and_length(&(x[j] - x[i]));
                let (k, l0, z) = (p[o], p[o + 1], p[o + 2]);
                let tension = k * (ls - l0) + z * (v[j] - v[i]).dot(&us);
                let [a, b] = self.pairs[m].map(|q| q as usize);
                let (u, _) = unit_and_length(&(x[b] - x[a]));
                let fa = u * (g * tension);
                f[a] += fa;
                f[b] -= fa;
            }
        }
    }
}
