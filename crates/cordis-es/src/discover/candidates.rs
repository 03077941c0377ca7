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

/// Each particle's candidates include its this many nearest neighbours, whatever the radius:
/// on irregular networks (issue 20: random points, each linked to its nearest 1–6) a sparse
/// region's particles had none of their links within 2.2 × the *median* nearest distance
/// (a 10-particle draw: 9 candidates for 24 links).
pub const NEAREST_CANDIDATES: usize = 10;

/// Every particle's `k` nearest others (ties by index), as pairs `[i, j]` (`i < j`) with their
/// distance, pairs of two fixed particles left out. A grid of cell `h` (m) searched ring by
/// ring until the k-th distance is inside the rings seen: O(N k) for spread points.
pub fn nearest_pairs(x: &[Vec3], fixed: &[bool], k: usize, h: f64) -> Vec<([usize; 2], f64)> {
    let n = x.len();
    let k = k.min(n.saturating_sub(1));
    if k == 0 || !(h > 0.0 && h.is_finite()) {
        return Vec::new();
    }
    let mut grid: HashMap<[i64; 3], Vec<usize>> = HashMap::new();
    let (mut lo, mut hi) = ([i64::MAX; 3], [i64::MIN; 3]);
    for (i, p) in x.iter().enumerate() {
        let c = cell(p, h);
        for a in 0..3 {
            lo[a] = lo[a].min(c[a]);
            hi[a] = hi[a].max(c[a]);
        }
        grid.entry(c).or_default().push(i);
    }
    let span = (0..3).map(|a| hi[a] - lo[a]).max().unwrap_or(0);
    let mut out = Vec::new();
    let mut best: Vec<(f64, usize)> = Vec::with_capacity(k + 1);
    for (i, p) in x.iter().enumerate() {
        let c = cell(p, h);
        best.clear();
        for ring in 0..=span + 1 {
            // Far from the others (an outlier, a sparse corner): every particle at once,
            // rather than ring after ring of empty cells.
            if ring > 3 {
                best.clear();
                best.extend((0..n).filter(|&j| j != i).map(|j| ((x[j] - p).norm(), j)));
                best.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                best.truncate(k);
                break;
            }
            for dx in -ring..=ring {
                for dy in -ring..=ring {
                    for dz in -ring..=ring {
                        if dx.abs().max(dy.abs()).max(dz.abs()) != ring {
                            continue;
                        }
                        let Some(list) = grid.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) else {
                            continue;
                        };
                        for &j in list.iter().filter(|&&j| j != i) {
                            best.push(((x[j] - p).norm(), j));
                        }
                    }
                }
            }
            best.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
            best.truncate(k);
            // Points outside the rings seen are farther than `ring × h`.
            if best.len() == k && best[k - 1].0 <= ring as f64 * h {
                break;
            }
        }
        for &(d, j) in &best {
            if !(fixed[i] && fixed[j]) {
                out.push(([i.min(j), i.max(j)], d));
            }
        }
    }
    out.sort_by_key(|a| a.0);
    out.dedup_by(|a, b| a.0 == b.0);
    out
}

/// The candidate pairs, in `(i, j)` order, with their distances: those within `radius`, and
/// with `nearest` (the default radius, [`default_radius`], not one the user gave as a bound)
/// each particle's [`NEAREST_CANDIDATES`] nearest too.
pub fn candidate_pairs(
    x: &[Vec3],
    fixed: &[bool],
    radius: f64,
    nearest: bool,
) -> Vec<([usize; 2], f64)> {
    let mut all = pairs_within(x, fixed, radius);
    if nearest {
        all.extend(nearest_pairs(x, fixed, NEAREST_CANDIDATES, radius));
    }
    all.sort_by_key(|a| a.0);
    all.dedup_by(|a, b| a.0 == b.0);
    all
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
        let near = nearest_pairs(&x, &fixed, 5, 0.05);
        let mut want_near = Vec::new();
        for i in 0..200 {
            let mut others: Vec<usize> = (0..200).filter(|&j| j != i).collect();
            others.sort_by(|&a, &b| {
                (x[a] - x[i])
                    .norm()
                    .total_cmp(&(x[b] - x[i]).norm())
                    .then(a.cmp(&b))
            });
            for &j in &others[..5] {
                if !(fixed[i] && fixed[j]) {
                    want_near.push([i.min(j), i.max(j)]);
                }
            }
        }
        want_near.sort();
        want_near.dedup();
        let got_near: Vec<[usize; 2]> = near.into_iter().map(|(p, _)| p).collect();
        assert_eq!(got_near, want_near);
    }
}
