//! Stages 2–3: per free particle, the linear least-squares form of its equation of motion over
//! every candidate pair, then group-sparse backward selection of the pairs.
//!
//! Particle i's equation at frame t (`a_i` from second differences, the CORDIS scheme's own
//! velocity `v = (x(t) - x(t-1))/dt`):
//!
//! `a_i - g = Σ_pairs σ (u L, -u, u s) · θ_p / m_i`, `θ_p = (K, K·l0, Z)`,
//!
//! with `u` the unit vector from i to the other end, `L` the length, `s` the elongation speed
//! and `σ = ±1` (Newton's third law: the pair's force on its other end is the opposite). The
//! unknowns `θ_p / m_i` and `g` (three intercepts) enter linearly; scaled by `dt²` this is the
//! short cost's residual of particle i. The rows of every frame are rotated into one small
//! triangular factor per particle (size 3 + 3·pairs + 1), so memory and time are linear in the
//! number of candidate pairs and every subset of pairs is solved from the factor alone.
//!
//! **Selection**: the three unknowns of a pair enter or leave together. For each active pair,
//! its group Wald statistic `W = βᵀ C⁻¹ β / σ²` in each free end's fit (the cost increase when
//! the pair is removed, relative to the noise floor σ² estimated from that fit's residual)
//! is summed over its free ends. Pairs below the threshold (BIC: `3 ln n` per equation, n the
//! equation's rows) are removed — each round, only those that are the weakest among the pairs
//! sharing an end, so that two candidates that can stand in for each other are not both
//! dropped — and the touched fits are solved again, until every pair left is above it.

use cordis_core::{Trajectory, Vec3};
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use rayon::prelude::*;

use crate::linalg::givens::Factor;

/// One free particle's factor: columns `[1x, 1y, 1z, pair 0 (K, K·l0, Z), pair 1, …, a]`.
pub struct Local {
    pub particle: usize,
    /// Indices into the candidate list, in column order.
    pub pairs: Vec<usize>,
    pub factor: DMatrix<f64>,
    /// Rows of the equation (3 per interior frame).
    pub rows: usize,
}

/// A particle's fit on its active pairs.
#[derive(Clone, Debug, Default)]
pub struct Fit {
    /// Per local pair: `θ_p / m_i` (zeros for inactive pairs).
    pub beta: Vec<Vector3<f64>>,
    /// Per local pair: covariance of `beta` (σ² included).
    pub cov: Vec<Matrix3<f64>>,
    /// Per local pair: Wald statistic (0 for inactive pairs).
    pub wald: Vec<f64>,
    /// The intercepts: the particle's estimate of gravity, m/s².
    pub gravity: Vector3<f64>,
    /// Residual variance per row, (m/s²)².
    pub sigma2: f64,
}

/// Features of pair `[a, b]` seen from its end `i` at frame t: `(u L, -u, u s)`, each a vector.
fn features(traj: &Trajectory, dt: f64, t: usize, i: usize, j: usize) -> [Vec3; 3] {
    let d = traj.pos(t, j) - traj.pos(t, i);
    let l = d.norm();
    let u = if l > 0.0 { d / l } else { Vec3::zeros() };
    let v = (traj.pos(t, j) - traj.pos(t - 1, j) - traj.pos(t, i) + traj.pos(t - 1, i)) / dt;
    [u * l, -u, u * v.dot(&u)]
}

/// Columns of the factor of a particle with `degree` candidate pairs: three intercepts, three
/// per pair, the right-hand side.
pub fn columns(degree: usize) -> usize {
    3 + 3 * degree + 1
}

/// Bytes the selection holds, estimated before building: each free particle's factor (8 k²,
/// k its [`columns`]) and fit (~110 bytes per pair), and per thread the transient of one build
/// or fit (~7 k² of the largest: the Givens factor and its copy, the equilibrated matrix, the
/// SVD's U and Vᵀ, the covariance factor).
pub fn memory_bytes(degree: &[usize], free: &[bool], threads: usize) -> f64 {
    let (mut held, mut largest) = (0.0, 0.0f64);
    for (&d, _) in degree.iter().zip(free).filter(|(_, &f)| f) {
        let k = columns(d) as f64;
        held += 8.0 * k * k + 110.0 * d as f64;
        largest = largest.max(k);
    }
    held + 8.0 * 7.0 * largest * largest * threads.max(1) as f64
}

/// Builds the factor of every free particle over its candidate pairs (in parallel).
pub fn build(traj: &Trajectory, dt: f64, free: &[bool], pairs: &[[usize; 2]]) -> Vec<Local> {
    let n = traj.particles();
    let mut incident: Vec<Vec<usize>> = vec![Vec::new(); n];
    for (k, &[i, j]) in pairs.iter().enumerate() {
        incident[i].push(k);
        incident[j].push(k);
    }
    let frames = traj.frames();
    (0..n)
        .into_par_iter()
        .filter(|&i| free[i])
        .map(|i| {
            let local = incident[i].clone();
            let k = columns(local.len());
            let mut f = Factor::new(k);
            let mut rows = vec![[0.0; 3]; k];
            let mut row = vec![0.0; k];
            for t in 1..frames - 1 {
                let a =
                    (traj.pos(t + 1, i) - traj.pos(t, i) * 2.0 + traj.pos(t - 1, i)) / (dt * dt);
                for r in rows.iter_mut() {
                    *r = [0.0; 3];
                }
                for (q, &p) in local.iter().enumerate() {
                    let [pa, pb] = pairs[p];
                    let other = if pa == i { pb } else { pa };
                    let fe = features(traj, dt, t, i, other);
                    for c in 0..3 {
                        for ax in 0..3 {
                            rows[3 + 3 * q + c][ax] = fe[c][ax];
                        }
                    }
                }
                for ax in 0..3 {
                    for c in 0..k - 1 {
                        row[c] = rows[c][ax];
                    }
                    for (c, v) in row.iter_mut().enumerate().take(3) {
                        *v = if c == ax { 1.0 } else { 0.0 };
                    }
                    row[k - 1] = a[ax];
                    f.add_row(&mut row);
                }
            }
            Local {
                particle: i,
                pairs: local,
                factor: f.matrix(),
                rows: 3 * (frames - 2),
            }
        })
        .collect()
}

/// The residual variance per row, (m/s²)², below which a fit is rounding, not noise: position
/// rounding `ε·|x|` turned into an acceleration by the second difference (`√6/dt²`), times 100
/// for the simulator's own arithmetic. Without it, noiseless data's structured rounding error
/// can be "explained" by a spurious pair.
pub fn rounding_floor(traj: &Trajectory, dt: f64) -> f64 {
    let xmax = traj.as_flat().iter().fold(0.0f64, |m, v| m.max(v.abs()));
    (100.0 * 6f64.sqrt() * f64::EPSILON * xmax / (dt * dt)).powi(2)
}

/// Relative singular-value cutoff of the column-equilibrated local solves.
const RANK_TOL: f64 = 1e-12;

/// A least-squares solve on some columns of a factor.
struct Solved {
    /// The solution and `W` (`W Wᵀ` the unscaled covariance), in the columns' own units.
    x: DVector<f64>,
    w: DMatrix<f64>,
    /// Residual sum of squares.
    rss: f64,
    /// Some singular value fell under the rank cutoff: the columns are not independent.
    deficient: bool,
}

/// Column-equilibrated SVD least squares of `rhs` on the factor's columns `cols`.
fn solve(r: &DMatrix<f64>, cols: &[usize], rhs: &DVector<f64>) -> Solved {
    let rows = r.nrows();
    let mut a = DMatrix::zeros(rows, cols.len());
    let mut scale = vec![1.0; cols.len()];
    for (c, &col) in cols.iter().enumerate() {
        let norm = r.column(col).norm();
        scale[c] = if norm > 0.0 { 1.0 / norm } else { 1.0 };
        for row in 0..rows {
            a[(row, c)] = r[(row, col)] * scale[c];
        }
    }
    let mut x = DVector::zeros(cols.len());
    let mut w = DMatrix::zeros(cols.len(), cols.len());
    let mut deficient = false;
    // Known gravity and no active pair: nothing to solve (an SVD of no columns).
    if !cols.is_empty() {
        let svd = a.clone().svd(true, true);
        let (u, vt, sv) = (
            svd.u.unwrap_or_else(|| DMatrix::zeros(rows, cols.len())),
            svd.v_t
                .unwrap_or_else(|| DMatrix::zeros(cols.len(), cols.len())),
            svd.singular_values,
        );
        let smax = sv.iter().copied().fold(0.0, f64::max);
        for s in 0..sv.len() {
            if sv[s] <= RANK_TOL * smax || sv[s] == 0.0 {
                deficient = true;
                continue;
            }
            let coef = u.column(s).dot(rhs) / sv[s];
            for c in 0..cols.len() {
                x[c] += vt[(s, c)] * coef;
                w[(c, s)] = vt[(s, c)] / sv[s];
            }
        }
    }
    let rss = (&a * &x - rhs).norm_squared();
    for (c, s) in scale.iter().enumerate() {
        x[c] *= s;
        for v in w.row_mut(c).iter_mut() {
            *v *= s;
        }
    }
    Solved {
        x,
        w,
        rss,
        deficient,
    }
}

/// Least squares of the local equation on the pairs with `active[q]`; with `gravity` known
/// (m/s²) the intercepts are not unknowns: their columns times `g` leave the right-hand side.
///
/// A pair's Wald statistic is the cost increase when it is removed only when the columns are
/// independent. When they are not (a pair that others can stand in for, such as two links to
/// fixed particles whose constant ends the intercepts absorb), the pseudo-inverse's
/// "covariance" made every one of them look significant (issue 20: spurious links to fixed
/// particles with l0 = 0 kept at 1e21 × the threshold); the score is then the cost increase
/// itself, from a solve without the pair, so a pair the others can replace scores 0.
pub fn fit(local: &Local, active: &[bool], floor: f64, gravity: Option<Vector3<f64>>) -> Fit {
    let m = local.pairs.len();
    let k = local.factor.ncols() - 1;
    let pair_cols = |q: usize| [3 + 3 * q, 4 + 3 * q, 5 + 3 * q];
    let base: Vec<usize> = if gravity.is_some() {
        Vec::new()
    } else {
        vec![0, 1, 2]
    };
    let mut cols = base.clone();
    for q in (0..m).filter(|&q| active[q]) {
        cols.extend(pair_cols(q));
    }
    let r = &local.factor;
    let mut rhs: DVector<f64> = r.column(k).into_owned();
    if let Some(g) = gravity {
        for c in 0..3 {
            rhs -= r.column(c) * g[c];
        }
    }
    let yy = rhs.norm_squared();
    let sol = solve(r, &cols, &rhs);
    let dof = local.rows.saturating_sub(cols.len()).max(1) as f64;
    let sigma2 = (sol.rss.max(1e-30 * yy).max(f64::MIN_POSITIVE) / dof).max(floor);
    let (x, w) = (&sol.x, &sol.w);
    let (gravity, mut c) = match gravity {
        Some(g) => (g, 0),
        None => (Vector3::new(x[0], x[1], x[2]), 3),
    };
    let mut out = Fit {
        beta: vec![Vector3::zeros(); m],
        cov: vec![Matrix3::zeros(); m],
        wald: vec![0.0; m],
        gravity,
        sigma2,
    };
    for q in (0..m).filter(|&q| active[q]) {
        let b = Vector3::new(x[c], x[c + 1], x[c + 2]);
        let wq = w.rows(c, 3);
        let cov: Matrix3<f64> = (wq * wq.transpose()).fixed_view::<3, 3>(0, 0).into_owned();
        let wald = if sol.deficient {
            let without: Vec<usize> = cols
                .iter()
                .copied()
                .filter(|col| !pair_cols(q).contains(col))
                .collect();
            (solve(r, &without, &rhs).rss - sol.rss) / sigma2
        } else {
            cov.try_inverse()
                .map(|ci| (b.transpose() * ci * b)[0] / sigma2)
                .unwrap_or(0.0)
        };
        out.beta[q] = b;
        out.cov[q] = cov * sigma2;
        out.wald[q] = if wald.is_finite() { wald.max(0.0) } else { 0.0 };
        c += 3;
    }
    out
}

/// Gravity shared by every particle (m/s²) from the fits with intercepts of the first
/// selection: each particle's intercepts `g_i` weighted by their information `N_i = E_Gᵀ E_G`,
/// `E_G` the intercept columns projected off the particle's `active` pair columns:
/// `g = (Σ N_i)⁻¹ Σ N_i g_i`. A direction that a particle's pairs can stand in for (two links
/// to fixed particles: their constant ends differ by a constant force, so its `g_i` there is
/// arbitrary) has no weight for that particle, and the others determine it. (Solving the
/// projected right-hand sides instead lost 2.5e-7 of g to cancellation on a noiseless draw,
/// enough to make every pair significant.) `None` when some direction of g is seen by no
/// particle apart from its links.
pub fn shared_gravity(locals: &[Local], fits: &[Fit], active: &[bool]) -> Option<Vector3<f64>> {
    let parts: Vec<Matrix3<f64>> = locals
        .par_iter()
        .map(|loc| {
            let r = &loc.factor;
            let mut cols = Vec::new();
            for (q, &p) in loc.pairs.iter().enumerate() {
                if active[p] {
                    cols.extend([3 + 3 * q, 4 + 3 * q, 5 + 3 * q]);
                }
            }
            let residual = |target: usize| -> DVector<f64> {
                let t: DVector<f64> = r.column(target).into_owned();
                let sol = solve(r, &cols, &t);
                let mut e = t;
                for (c, &col) in cols.iter().enumerate() {
                    e -= r.column(col) * sol.x[c];
                }
                e
            };
            let eg = [residual(0), residual(1), residual(2)];
            let mut n = Matrix3::zeros();
            for a in 0..3 {
                for b in 0..3 {
                    n[(a, b)] = eg[a].dot(&eg[b]);
                }
            }
            n
        })
        .collect();
    let (mut n, mut v) = (Matrix3::zeros(), Vector3::zeros());
    for (ni, f) in parts.iter().zip(fits) {
        n += ni;
        v += ni * f.gravity;
    }
    let eig = n.symmetric_eigen();
    let (lo, hi) = eig
        .eigenvalues
        .iter()
        .fold((f64::INFINITY, 0.0f64), |(lo, hi), &e| {
            (lo.min(e), hi.max(e))
        });
    if !(hi > 0.0 && lo > 1e-12 * hi) {
        return None;
    }
    n.try_inverse()
        .map(|ni| ni * v)
        .filter(|g| g.iter().all(|c| c.is_finite()))
}

/// The outcome of the selection.
pub struct Selection {
    /// Per candidate pair: kept.
    pub active: Vec<bool>,
    /// Per candidate pair: its summed Wald statistic in the last fits (removed pairs: the
    /// value when removed).
    pub score: Vec<f64>,
    /// Per candidate pair: the threshold it was held to.
    pub threshold: Vec<f64>,
    /// The final fits, per entry of the locals.
    pub fits: Vec<Fit>,
    pub rounds: usize,
}

/// Backward group selection (module docs); `threshold_scale` multiplies the BIC threshold;
/// `floor` is the least residual variance per row, (m/s²)² (see [`rounding_floor`]).
/// `gravity`, when known (m/s²), replaces every particle's intercepts (see [`fit`]).
pub fn select(
    locals: &[Local],
    num_pairs: usize,
    threshold_scale: f64,
    floor: f64,
    gravity: Option<Vector3<f64>>,
) -> Selection {
    let mut active = vec![true; num_pairs];
    let mut threshold = vec![0.0; num_pairs];
    // Where each pair sits: (local index, position in it).
    let mut seen: Vec<Vec<(usize, usize)>> = vec![Vec::new(); num_pairs];
    for (l, loc) in locals.iter().enumerate() {
        let per = 3.0 * (loc.rows.max(2) as f64).ln() * threshold_scale;
        for (q, &p) in loc.pairs.iter().enumerate() {
            seen[p].push((l, q));
            threshold[p] += per;
        }
    }
    let mut fits: Vec<Fit> = vec![Fit::default(); locals.len()];
    let mut dirty = vec![true; locals.len()];
    let mut score = vec![0.0; num_pairs];
    let mut rounds = 0;
    loop {
        rounds += 1;
        let updated: Vec<(usize, Fit)> = locals
            .par_iter()
            .enumerate()
            .filter(|(l, _)| dirty[*l])
            .map(|(l, loc)| {
                let act: Vec<bool> = loc.pairs.iter().map(|&p| active[p]).collect();
                (l, fit(loc, &act, floor, gravity))
            })
            .collect();
        for (l, f) in updated {
            fits[l] = f;
            dirty[l] = false;
        }
        for p in (0..num_pairs).filter(|&p| active[p]) {
            score[p] = seen[p].iter().map(|&(l, q)| fits[l].wald[q]).sum();
        }
        // The weakest pair of each particle (by the score, then the index).
        let weaker = |a: usize, b: usize| (score[a], a) < (score[b], b);
        let mut weakest: Vec<Option<usize>> = vec![None; locals.len()];
        for (l, loc) in locals.iter().enumerate() {
            for &p in loc.pairs.iter().filter(|&&p| active[p]) {
                if weakest[l].is_none_or(|w| weaker(p, w)) {
                    weakest[l] = Some(p);
                }
            }
        }
        let remove: Vec<usize> = (0..num_pairs)
            .filter(|&p| active[p] && score[p] < threshold[p])
            .filter(|&p| seen[p].iter().all(|&(l, _)| weakest[l] == Some(p)))
            .collect();
        if remove.is_empty() {
            break;
        }
        for p in remove {
            active[p] = false;
            for &(l, _) in &seen[p] {
                dirty[l] = true;
            }
        }
    }
    Selection {
        active,
        score,
        threshold,
        fits,
        rounds,
    }
}
