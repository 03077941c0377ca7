//! Stage 1: which particles never move, and which pairs could be linked (every pair closer
//! than a radius in the first frame, found with a uniform grid: O(N + pairs)).

use std::collections::HashMap;

use cordis_core::{Trajectory, Vec3};

/// The default radius is this many times the median nearest-neighbour distance: on a jittered
/// cubic lattice it holds ~15–30 neighbours per particle in 3-D (~10 in a sheet), enough to
/// include links up to ~2 lattice pitches long.
pub const RADIUS_PER_NEAREST: f64 = 2.2;

/// Particles whose every coordinate stays within `tol` (m, as a standard deviation over the
/// frames) of its mean: fixed points of the scene.
pub fn fixed_particles(traj: &Trajectory, tol: f64) -> Vec<bool> {
    let (t_n, n) = (traj.frames(), traj.particles());
    (0..n)
        .map(|i| {
            let mut mean = Vec3::zeros();
            for t in 0..t_n {
                mean += traj.pos(t, i);
            }
            mean /= t_n as f64;
            let mut var = Vec3::zeros();
            for t in 0..t_n {
                let d = traj.pos(t, i) - mean;
                var += d.component_mul(&d);
            }
            (var / t_n as f64).amax().sqrt() <= tol
        })
        .collect()
}

fn cell(p: &Vec3, h: f64) -> [i64; 3] {
    [
        (p.x / h).floor() as i64,
        (p.y / h).floor() as i64,
        (p.z / h).floor() as i64,
    ]
}

/// Calls `visit(i, j, distance)` for every pair `[i, j]` (`i < j`) closer than `radius` (m),
/// two fixed particles left out (no equation sees them), in no particular order. Holds only
/// the grid (O(N)): a caller can count the pairs before storing any.
pub fn for_each_pair_within(
    x: &[Vec3],
    fixed: &[bool],
    radius: f64,
    mut visit: impl FnMut(usize, usize, f64),
) {
    let mut grid: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    for (i, p) in x.iter().enumerate() {
        grid.entry(cell(p, radius)).or_default().push(i);
    }
    for (i, p) in x.iter().enumerate() {
        let c = cell(p, radius);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let Some(list) = grid.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) else {
                        continue;
                    };
                    for &j in list {
                        if j <= i || (fixed[i] && fixed[j]) {
                            continue;
                        }
                        let d = (x[j] - p).norm();
                        if d < radius {
                            visit(i, j, d);
                        }
                    }
                }
            }
        }
    }
}

/// Every pair `[i, j]` (`i < j`) closer than `radius` (m), with its distance, in `(i, j)`
/// order. Pairs of two fixed particles are left out (no equation sees them).
pub fn pairs_within(x: &[Vec3], fixed: &[bool], radius: f64) -> Vec<([usize; 2], f64)> {
    let mut out = Vec::new();
    for_each_pair_within(x, fixed, radius, |i, j, d| out.push(([i, j], d)));
    out.sort_by_key(|(p, _)| *p);
    out
}

/// How many candidate pairs each particle is an end of (the counts of [`pairs_within`],
/// without storing the pairs).
pub fn degrees_within(x: &[Vec3], fixed: &[bool], radius: f64) -> Vec<usize> {
    let mut degree = vec![0; x.len()];
    for_each_pair_within(x, fixed, radius, |i, j, _| {
        degree[i] += 1;
        degree[j] += 1;
    });
    degree
}

/// [`RADIUS_PER_NEAREST`] × the median distance from a particle to its nearest neighbour in
/// `x` (m); `None` when fewer than two particles or all coincide.
pub fn default_radius(x: &[Vec3]) -> Option<f64> {
    if x.len() < 2 {
        return None;
    }
    let (mut lo, mut hi) = (x[0], x[0]);
    for p in x {
        lo = lo.inf(p);
        hi = hi.sup(p);
    }
    let ext = hi - lo;
    let extent = ext.amax();
    if !(extent > 0.0 && extent.is_finite()) {
        return None;
    }
    // A cell holding about one particle (by the box's non-degenerate dimensions) to start.
    let dims: Vec<f64> = ext.iter().copied().filter(|&e| e > 1e-9 * extent).collect();
    let vol: f64 = dims.iter().product();
    let mut h = (vol / x.len() as f64).powf(1.0 / dims.len() as f64);
    let none = vec![false; x.len()];
    for _ in 0..40 {
        let mut nearest = vec![f64::INFINITY; x.len()];
        for ([i, j], d) in pairs_within(x, &none, h) {
            nearest[i] = nearest[i].min(d);
            nearest[j] = nearest[j].min(d);
        }
        if nearest.iter().all(|d| d.is_finite()) {
            nearest.sort_by(f64::total_cmp);
            let median = nearest[nearest.len() / 2];
            return (median > 0.0).then_some(RADIUS_PER_NEAREST * median);
        }
        h *= 2.0;
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_pairs_match_brute_force() {
        let mut s = 12345u64;
        let mut r = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64
        };
        let x: Vec<Vec3> = (0..200).map(|_| Vec3::new(r(), r(), r() * 0.3)).collect();
        let fixed: Vec<bool> = (0..200).map(|i| i % 17 == 0).collect();
        let got: Vec<[usize; 2]> = pairs_within(&x, &fixed, 0.13)
            .into_iter()
            .map(|(p, _)| p)
            .collect();
        let mut want = Vec::new();
        for i in 0..200 {
            for j in i + 1..200 {
                if (x[i] - x[j]).norm() < 0.13 && !(fixed[i] && fixed[j]) {
                    want.push([i, j]);
                }
            }
        }
        assert_eq!(got, want);
        let degree = degrees_within(&x, &fixed, 0.13);
        for (i, d) in degree.iter().enumerate() {
            assert_eq!(*d, want.iter().filter(|p| p.contains(&i)).count());
        }
        let r = default_radius(&x).unwrap();
        assert!(r > 0.0 && r < 1.0);
    }
}
