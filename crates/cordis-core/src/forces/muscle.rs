//! `muscle`: the local-control muscle (SPEC §2.4, thesis §5.5, eq 5.3–5.5). Each muscle link
//! is a spring whose neuron observes other muscle links (elongation `e = L - l0` and rate
//! `s`) and adds `G · tanh(Σ (w_len e + w_rate s) - θ) · u` to the force on its first end.
//!
//! The step runs in two sweeps so that every neuron sees the same instant: first each muscle's
//! `(e, s, u)` into [`MuscleBuf`] (scratch owned by the caller: no allocation per step), then
//! each neuron's output and the forces. With every weight 0 and θ = 0 the output is exactly 0
//! and the force is bit for bit the spring's (same operations in the same order, plus `+ 0`).
//!
//! Cost per step: O(M + Σ observed) for M muscles. By default every muscle observes every
//! other one (thesis §5.5), so Σ observed = M(M − 1): scenes with many muscles should list
//! each one's neighbours in `observes`.

use super::{unit_and_length, Run};
use crate::Vec3;

/// Muscle links in runs of one type. A run's parameters are `p[run.param..]` = stiffness K
/// (N/m), rest length l0 (m), damping Z (N·s/m), gain G (N), threshold θ, then `w_len[0..M]`
/// (1/m) and `w_rate[0..M]` (s/m), M = `weights[run]`.
#[derive(Clone, Debug, Default)]
pub struct MusclePass {
    pub runs: Vec<Run>,
    /// Weights per input (M) of each run's type.
    pub weights: Vec<usize>,
    pub pairs: Vec<[u32; 2]>,
    /// Muscle `m` observes the muscles `observed[start[m]..start[m + 1]]`, as indices into
    /// `pairs` (not link indices), in weight order.
    pub observed: Vec<u32>,
    pub start: Vec<u32>,
}

/// Per-step state of every muscle: elongation e (m), rate s (m/s), direction u.
#[derive(Clone, Debug, Default)]
pub struct MuscleBuf {
    pub e: Vec<f64>,
    pub s: Vec<f64>,
    pub u: Vec<Vec3>,
}

impl MuscleBuf {
    pub fn new(n: usize) -> Self {
        MuscleBuf {
            e: vec![0.0; n],
            s: vec![0.0; n],
            u: vec![Vec3::zeros(); n],
        }
    }
}

impl MusclePass {
    pub fn len(&self) -> usize {
        self.pairs.len()
    }

    pub fn is_empty(&self) -> bool {
        self.pairs.is_empty()
    }

    /// Fills `buf` with every muscle's `(e, s, u)` at positions `x`, velocities `v`.
    pub fn geometry(&self, p: &[f64], x: &[Vec3], v: &[Vec3], buf: &mut MuscleBuf) {
        if buf.e.len() != self.pairs.len() {
            *buf = MuscleBuf::new(self.pairs.len());
        }
        for r in &self.runs {
            let l0 = p[r.param + 1];
            for m in r.start..r.end {
                let [i, j] = self.pairs[m];
                let (i, j) = (i as usize, j as usize);
                let (u, l) = unit_and_length(&(x[j] - x[i]));
                buf.e[m] = l - l0;
                buf.s[m] = (v[j] - v[i]).dot(&u);
                buf.u[m] = u;
            }
        }
    }

    /// The neuron output `tanh(Σ w_len e + w_rate s - θ)` of muscle `m` in run `r`.
    #[inline(always)]
    pub fn output(&self, p: &[f64], r: usize, m: usize, buf: &MuscleBuf) -> f64 {
        let run = &self.runs[r];
        let nw = self.weights[r];
        let w0 = run.param + 5;
        let (w_len, w_rate) = (&p[w0..w0 + nw], &p[w0 + nw..w0 + 2 * nw]);
        let seen = &self.observed[self.start[m] as usize..self.start[m + 1] as usize];
        let mut h = 0.0;
        for ((&k, wl), wr) in seen.iter().zip(w_len).zip(w_rate) {
            let k = k as usize;
            h += wl * buf.e[k] + wr * buf.s[k];
        }
        (h - p[run.param + 4]).tanh()
    }

    /// Adds every muscle's force: `(K e + Z s + G out) u` on i, the opposite on j.
    pub fn accumulate(
        &self,
        p: &[f64],
        x: &[Vec3],
        v: &[Vec3],
        f: &mut [Vec3],
        buf: &mut MuscleBuf,
    ) {
        if self.pairs.is_empty() {
            return;
        }
        self.geometry(p, x, v, buf);
        for (ri, r) in self.runs.iter().enumerate() {
            let (k, z, g) = (p[r.param], p[r.param + 2], p[r.param + 3]);
            for m in r.start..r.end {
                let out = self.output(p, ri, m, buf);
                // Same operations as the spring kernel (`K (L - l0)`, then `+ Z s` when Z ≠ 0),
                // so a silent neuron gives the spring's bits.
                let mut mag = k * buf.e[m];
                if z != 0.0 {
                    mag += z * buf.s[m];
                }
                mag += g * out;
                let fi = buf.u[m] * mag;
                let [i, j] = self.pairs[m];
                f[i as usize] += fi;
                f[j as usize] -= fi;
            }
        }
    }
}
