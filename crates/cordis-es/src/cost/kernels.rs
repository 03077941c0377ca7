//! Cost-specialised spring kernel.
//!
//! A spring costs one square root and one division; done link by link they serialise on the
//! divider and dominate the short cost. This kernel splits each chunk of links into a gather
//! (differences of positions and velocities into arrays), a geometry loop over the arrays that
//! the compiler turns into packed SIMD (square roots and divisions two or four at a time), and a
//! scatter. Every link evaluates the same IEEE operations in the same order as
//! `cordis_core::forces::spring::spring_force`, and forces are added in link order, so the
//! result is bit-for-bit a simulator step's.

use cordis_core::forces::MIN_LENGTH;
use cordis_core::Vec3;

/// Links per chunk: small enough for the arrays to stay in L1, large enough to amortise.
const CHUNK: usize = 64;

/// Per-thread arrays of the spring kernel (part of the cost scratch).
#[derive(Clone, Debug)]
pub(crate) struct SpringBuf {
    d: [[f64; CHUNK]; 3],
    w: [[f64; CHUNK]; 3],
}

impl Default for SpringBuf {
    fn default() -> Self {
        SpringBuf {
            d: [[0.0; CHUNK]; 3],
            w: [[0.0; CHUNK]; 3],
        }
    }
}

/// Adds `F_i = (K (L - l0) + Z s) u`, `F_j = -F_i` of every pair to `f` (`[K, l0, Z]` in N/m,
/// m, N·s/m; `DAMPED = false` skips the velocity term, as the core does when Z = 0).
pub(crate) fn springs<const DAMPED: bool>(
    pairs: &[[u32; 2]],
    [k, l0, z]: [f64; 3],
    x: &[Vec3],
    v: &[Vec3],
    f: &mut [Vec3],
    b: &mut SpringBuf,
) {
    for chunk in pairs.chunks(CHUNK) {
        let m = chunk.len();
        for (a, &[i, j]) in chunk.iter().enumerate() {
            let (i, j) = (i as usize, j as usize);
            let d = x[j] - x[i];
            b.d[0][a] = d.x;
            b.d[1][a] = d.y;
            b.d[2][a] = d.z;
            if DAMPED {
                let w = v[j] - v[i];
                b.w[0][a] = w.x;
                b.w[1][a] = w.y;
                b.w[2][a] = w.z;
            }
        }
        let [dx, dy, dz] = &mut b.d;
        let [wx, wy, wz] = &b.w;
        let (dx, dy, dz) = (&mut dx[..m], &mut dy[..m], &mut dz[..m]);
        for a in 0..m {
            let (ex, ey, ez) = (dx[a], dy[a], dz[a]);
            let l = (ex * ex + ey * ey + ez * ez).sqrt();
            let inv = if l > MIN_LENGTH { 1.0 / l } else { 0.0 };
            let (ux, uy, uz) = (ex * inv, ey * inv, ez * inv);
            let mut mag = k * (l - l0);
            if DAMPED {
                mag += z * (wx[a] * ux + wy[a] * uy + wz[a] * uz);
            }
            dx[a] = ux * mag;
            dy[a] = uy * mag;
            dz[a] = uz * mag;
        }
        for (a, &[i, j]) in chunk.iter().enumerate() {
            let fi = Vec3::new(dx[a], dy[a], dz[a]);
            f[i as usize] += fi;
            f[j as usize] -= fi;
        }
    }
}

/// Upper bound on the memory the short cost spends on precomputed geometry, bytes. Past it, a
/// pass computes its geometry at every evaluation instead (slower, same result).
pub const GEOMETRY_BUDGET_BYTES: usize = 512 << 20;

/// Geometry of listed pairs (springs, or conditional pairs at a known range) at every observed
/// frame that starts a short-term step: unit vector u, length L (m) and elongation rate s
/// (m/s), computed exactly as the spring kernel computes them. They do not depend on the
/// parameters, so the short cost computes them once and each evaluation only streams them:
/// no square root or division is left in its loop.
#[derive(Clone, Debug)]
pub(crate) struct PairGeometry {
    /// Frame t's block starts at `start[t]`: arrays ux, uy, uz, L, s of the frame's pairs.
    start: Vec<usize>,
    data: Vec<f64>,
}

impl PairGeometry {
    /// Bytes that [`PairGeometry::new`] would take for these pair counts per frame.
    pub fn bytes(counts: impl Iterator<Item = usize>) -> usize {
        counts.sum::<usize>() * 5 * std::mem::size_of::<f64>()
    }

    /// Geometry of `pairs_at(t)` at positions `x_at(t)`, velocities `v_at(t)`, for the frames
    /// `t` = 1 … frames-2 (other frames get empty blocks).
    pub fn new<'a>(
        frames: usize,
        pairs_at: impl Fn(usize) -> &'a [[u32; 2]],
        x_at: impl Fn(usize) -> &'a [Vec3],
        v_at: impl Fn(usize) -> &'a [Vec3],
    ) -> Self {
        let used = 1..frames.saturating_sub(1);
        let mut start = vec![0; frames + 1];
        for t in 0..frames {
            let count = if used.contains(&t) {
                pairs_at(t).len()
            } else {
                0
            };
            start[t + 1] = start[t] + 5 * count;
        }
        let mut data = vec![0.0; start[frames]];
        for t in used {
            let (pairs, x, v) = (pairs_at(t), x_at(t), v_at(t));
            let m = pairs.len();
            let block = &mut data[start[t]..start[t + 1]];
            for (a, &[i, j]) in pairs.iter().enumerate() {
                let (i, j) = (i as usize, j as usize);
                let d = x[j] - x[i];
                let w = v[j] - v[i];
                let (ex, ey, ez) = (d.x, d.y, d.z);
                let l = (ex * ex + ey * ey + ez * ez).sqrt();
                let inv = if l > MIN_LENGTH { 1.0 / l } else { 0.0 };
                let (ux, uy, uz) = (ex * inv, ey * inv, ez * inv);
                block[a] = ux;
                block[m + a] = uy;
                block[2 * m + a] = uz;
                block[3 * m + a] = l;
                block[4 * m + a] = w.x * ux + w.y * uy + w.z * uz;
            }
        }
        PairGeometry { start, data }
    }

    /// Frame t's stored columns (u's three components, L, s) of pairs `range`.
    fn columns(&self, t: usize, range: std::ops::Range<usize>) -> [&[f64]; 5] {
        let block = &self.data[self.start[t]..self.start[t + 1]];
        let m = block.len() / 5;
        std::array::from_fn(|c| &block[c * m + range.start..c * m + range.end])
    }

    /// Adds the forces of pairs `range` of frame t's list `pairs` (the list the geometry was
    /// built from) at the step that starts from frame t, with a quadratic viscosity Z₂:
    /// `(K (L - l0) + Z s + Z₂ s |s|) u` (`cordis_core::forces::spring`'s arithmetic).
    pub fn springs_quadratic(
        &self,
        t: usize,
        range: std::ops::Range<usize>,
        pairs: &[[u32; 2]],
        [k, l0, z, z2]: [f64; 4],
        f: &mut [Vec3],
    ) {
        let [ux, uy, uz, l, s] = self.columns(t, range.clone());
        for (a, &[i, j]) in pairs[range].iter().enumerate() {
            let mag = k * (l[a] - l0) + z * s[a] + z2 * (s[a] * s[a].abs());
            let fi = Vec3::new(ux[a] * mag, uy[a] * mag, uz[a] * mag);
            f[i as usize] += fi;
            f[j as usize] -= fi;
        }
    }

    /// Adds the forces of pairs `range` of frame t's list `pairs` (the list the geometry was
    /// built from) at the step that starts from frame t.
    pub fn springs<const DAMPED: bool>(
        &self,
        t: usize,
        range: std::ops::Range<usize>,
        pairs: &[[u32; 2]],
        [k, l0, z]: [f64; 3],
        f: &mut [Vec3],
    ) {
        let [ux, uy, uz, l, s] = self.columns(t, range.clone());
        for (a, &[i, j]) in pairs[range].iter().enumerate() {
            let mut mag = k * (l[a] - l0);
            if DAMPED {
                mag += z * s[a];
            }
            let fi = Vec3::new(ux[a] * mag, uy[a] * mag, uz[a] * mag);
            f[i as usize] += fi;
            f[j as usize] -= fi;
        }
    }
}
