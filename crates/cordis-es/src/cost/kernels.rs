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
