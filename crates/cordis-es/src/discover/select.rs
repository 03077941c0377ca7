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
//! A candidate is a *group*: a pair with a kind. A damper group (`F_i = Z (v_j − v_i)`) has
//! one unknown `Z/m_i` and the vector feature `v_j − v_i`; a pair may carry both groups, so
//! the factor's size is 3 + Σ widths + 1.
//!
//! **Selection**: the unknowns of a group enter or leave together (three for a spring, one for
//! a damper; the BIC threshold is `ln n` per unknown). For each active pair,
//! its group Wald statistic `W = βᵀ C⁻¹ β / σ²` in each free end's fit (the cost increase when
//! the pair is removed, relative to the noise floor σ² estimated from that fit's residual)
//! is summed over its free ends. Pairs below the threshold (BIC: `3 ln n` per equation, n the
//! equation's rows) are removed — each round, only those that are the weakest among the pairs
//! sharing an end, so that two candidates that can stand in for each other are not both
//! dropped — and the touched fits are solved again, until every pair left is above it.

use cordis_core::{Trajectory, Vec3};
use nalgebra::{DMatrix, DVector, Matrix3, Vector3};
use rayon::prelude::*;

use super::smooth::Accelerations;
use crate::linalg::givens::Factor;

/// What a candidate group stands for: a spring-like link (`(K, K·l0, Z)`, three columns:
/// kind `spring`, or an anchor when one end is fixed) or an isotropic damper (kind `damper`,
/// `F_i = Z (v_j − v_i)`: one column, the relative velocity vector).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GroupKind {
    Spring,
    Damper,
}

impl GroupKind {
    /// Unknowns of the group in one end's equation.
    pub const fn width(self) -> usize {
        match self {
            GroupKind::Spring => 3,
            GroupKind::Damper => 1,
        }
    }
}

/// One free particle's factor: columns `[1x, 1y, 1z, group 0, group 1, …, a]`, a spring
/// group's three columns `(K, K·l0, Z)`, a damper's one.
pub struct Local {
    pub particle: usize,
    /// Indices into the candidate list (groups), in column order.
    pub pairs: Vec<usize>,
    /// Per local group: its first column and its kind.
    pub offsets: Vec<usize>,
    pub kinds: Vec<GroupKind>,
    pub factor: DMatrix<f64>,
    /// Rows of the equation (3 per interior frame).
    pub rows: usize,
    /// Noisy positions: `(Xᵀ R_g X, Xᵀ R_c X)` over the factor's columns (the right-hand
    /// side last), `R_g` and `R_c` the frame-to-frame covariances (per σ²) of the
    /// accelerations' noise and of the smoothed positions' (see [`Noise`]).
    pub meat: Option<(DMatrix<f64>, DMatrix<f64>)>,
}

impl Local {
    /// The factor columns of local group `q`.
    fn group_columns(&self, q: usize) -> std::ops::Range<usize> {
        self.offsets[q]..self.offsets[q] + self.kinds[q].width()
    }
}

/// The position noise the fits are tested against: white, variance `variance` (m²), sampled
/// every `dt` s; the accelerations and features read it through the kernels of
/// [`Accelerations`].
#[derive(Clone, Debug)]
pub struct Noise {
    pub variance: f64,
    pub dt: f64,
    /// The autocorrelations of the two kernels (lags 0, 1, …; see [`Accelerations`]).
    pub accel_autocorrelation: Vec<f64>,
    pub smooth_autocorrelation: Vec<f64>,
}

impl Noise {
    /// The expected `eᵀ R_c e` per row of the noise `e` of an equation whose features carry
    /// `q_feat` × the smoothed noise: `Σ_l (2 - δ_l0) R_c(l) Σ(l)`, `Σ(l) = σ² (R_g(l)/dt⁴ +
    /// q_feat R_c(l))` the noise's covariance at lag l.
    fn smoothed_power_per_row(&self, q_feat: f64) -> f64 {
        let dt4 = self.dt.powi(4);
        let rc = &self.smooth_autocorrelation;
        (0..rc.len())
            .map(|l| {
                let rg = self.accel_autocorrelation.get(l).copied().unwrap_or(0.0);
                let w = if l == 0 { 1.0 } else { 2.0 };
                w * rc[l] * self.variance * (rg / dt4 + q_feat * rc[l])
            })
            .sum()
    }
}

/// A particle's fit on its active pairs.
#[derive(Clone, Debug, Default)]
pub struct Fit {
    /// Per local group: `θ_p / m_i` (zeros for inactive groups; a damper's `Z/m` in the first
    /// component, the others 0).
    pub beta: Vec<Vector3<f64>>,
    /// Per local group: covariance of `beta` (σ² included; a damper's in the first entry).
    pub cov: Vec<Matrix3<f64>>,
    /// Per local pair: Wald statistic (0 for inactive pairs).
    pub wald: Vec<f64>,
    /// The intercepts: the particle's estimate of gravity, m/s².
    pub gravity: Vector3<f64>,
    /// Residual variance per row, (m/s²)².
    pub sigma2: f64,
    /// Noisy positions: the residual's power in the features' band over the noise's (the
    /// covariance was scaled by it where it exceeds 1; below 1 it is reported as is).
    pub inflation: f64,
}

/// Features of pair `[a, b]` seen from its end `i` at frame t: `(u L, -u, u s)`, each a vector.
fn features(traj: &Trajectory, dt: f64, t: usize, i: usize, j: usize) -> [Vec3; 3] {
    let d = traj.pos(t, j) - traj.pos(t, i);
    let l = d.norm();
    let u = if l > 0.0 { d / l } else { Vec3::zeros() };
    let v = (traj.pos(t, j) - traj.pos(t - 1, j) - traj.pos(t, i) + traj.pos(t - 1, i)) / dt;
    [u * l, -u, u * v.dot(&u)]
}

/// The damper's feature of pair `[i, j]` seen from `i` at frame t: the relative velocity
/// `v_j − v_i` (the scheme's backward difference), m/s.
fn damper_feature(traj: &Trajectory, dt: f64, t: usize, i: usize, j: usize) -> Vec3 {
    (traj.pos(t, j) - traj.pos(t - 1, j) - traj.pos(t, i) + traj.pos(t - 1, i)) / dt
}

/// Columns of the factor of a particle whose candidate groups have `group_columns` columns in
/// all: three intercepts, the groups', the right-hand side.
pub fn columns(group_columns: usize) -> usize {
    3 + group_columns + 1
}

/// Bytes the selection holds, estimated before building: each free particle's factor (8 k²,
/// k its [`columns`] from `group_columns`, its groups' columns) and fit (~110 bytes per pair), and per thread the transient of one build
/// or fit (~7 k² of the largest: the Givens factor and its copy, the equilibrated matrix, the
/// SVD's U and Vᵀ, the covariance factor).
///
/// With noisy positions (`noisy`), each factor has two more matrices of its size (the
/// noise's covariance terms) and each thread holds the rows of one particle three times
/// (`3 · rows · k`).
pub fn memory_bytes(
    group_columns: &[usize],
    free: &[bool],
    threads: usize,
    rows: usize,
    noisy: bool,
) -> f64 {
    let (mut held, mut largest) = (0.0, 0.0f64);
    let copies = if noisy { 3.0 } else { 1.0 };
    for (&d, _) in group_columns.iter().zip(free).filter(|(_, &f)| f) {
        let k = columns(d) as f64;
        held += copies * 8.0 * k * k + 40.0 * d as f64;
        largest = largest.max(k);
    }
    let rows_bytes = if noisy {
        8.0 * 3.0 * rows as f64 * largest
    } else {
        0.0
    };
    held + (8.0 * 7.0 * largest * largest + rows_bytes) * threads.max(1) as f64
}

/// `Xᵀ (R ⋆ X)`: the rows `x` (3 per frame, one per axis) against the same axis' rows at
/// every lag `l` weighted by `r[|l|]`, symmetrised.
fn lagged_gram(x: &DMatrix<f64>, r: &[f64]) -> DMatrix<f64> {
    let (rows, k) = (x.nrows(), x.ncols());
    let frames = rows / 3;
    let mut filtered = DMatrix::zeros(rows, k);
    for t in 0..frames {
        for (l, &w) in r.iter().enumerate() {
            for (s, first) in [(t + l, true), (t.wrapping_sub(l), false)] {
                if s >= frames || (l == 0 && !first) {
                    continue;
                }
                for ax in 0..3 {
                    let (to, from) = (3 * t + ax, 3 * s + ax);
                    for c in 0..k {
                        filtered[(to, c)] += w * x[(from, c)];
                    }
                }
            }
        }
    }
    let m = x.transpose() * filtered;
    (&m + m.transpose()) * 0.5
}

/// Builds the factor of every free particle over its candidate pairs (in parallel). The
/// accelerations are the trajectory's second differences, or `accel` (noisy positions: read
/// from the raw ones, uncorrelated with the smoothed positions the features read; see
/// [`super::smooth`]) at its frames only.
pub fn build(
    traj: &Trajectory,
    dt: f64,
    free: &[bool],
    pairs: &[[usize; 2]],
    kinds: &[GroupKind],
    accel: Option<&Accelerations>,
) -> Vec<Local> {
    let n = traj.particles();
    let mut incident: Vec<Vec<usize>> = vec![Vec::new(); n];
    for (k, &[i, j]) in pairs.iter().enumerate() {
        incident[i].push(k);
        incident[j].push(k);
    }
    let frames = traj.frames();
    let row_frames = accel.map_or(1..frames - 1, |a| a.first..a.last);
    let equations = Equations {
        traj,
        dt,
        free,
        pairs,
        accel,
        n_rows: 3 * row_frames.len(),
        row_frames,
    };
    (0..n)
        .into_par_iter()
        .filter(|&i| free[i])
        .map(|i| equations.local(i, incident[i].clone(), kinds))
        .collect()
}

/// What the rows of the free particles' equations are read from, shared by their factors.
struct Equations<'a> {
    traj: &'a Trajectory,
    dt: f64,
    free: &'a [bool],
    pairs: &'a [[usize; 2]],
    accel: Option<&'a Accelerations>,
    /// The frames with an equation, and its rows (3 per frame).
    row_frames: std::ops::Range<usize>,
    n_rows: usize,
}

impl Equations<'_> {
    /// Particle `i`'s factor over its candidate groups `local` (their kinds in `kinds`), with
    /// the noise's covariance terms of its rows when the positions are noisy.
    fn local(&self, i: usize, local: Vec<usize>, kinds: &[GroupKind]) -> Local {
        let n_rows = self.n_rows;
        let local_kinds: Vec<GroupKind> = local.iter().map(|&p| kinds[p]).collect();
        let mut offsets = Vec::with_capacity(local.len());
        let mut at = 3;
        for kind in &local_kinds {
            offsets.push(at);
            at += kind.width();
        }
        let k = columns(at - 3);
        let mut f = Factor::new(k);
        let mut rows = vec![[0.0; 3]; k];
        let mut row = vec![0.0; k];
        // Noisy positions: the rows themselves, for the noise's covariance terms.
        let mut kept = self.accel.map(|_| DMatrix::zeros(n_rows, k));
        let mut r_at = 0;
        for t in self.row_frames.clone() {
            let a = self.acceleration(t, i);
            self.group_rows(t, i, &local, &local_kinds, &offsets, &mut rows);
            for ax in 0..3 {
                for c in 0..k - 1 {
                    row[c] = rows[c][ax];
                }
                for (c, v) in row.iter_mut().enumerate().take(3) {
                    *v = if c == ax { 1.0 } else { 0.0 };
                }
                row[k - 1] = a[ax];
                if let Some(x) = kept.as_mut() {
                    for c in 0..k {
                        x[(r_at, c)] = row[c];
                    }
                }
                r_at += 1;
                f.add_row(&mut row);
            }
        }
        let meat = self.accel.zip(kept).map(|(acc, x)| {
            (
                lagged_gram(&x, &acc.accel_autocorrelation),
                lagged_gram(&x, &acc.smooth_autocorrelation),
            )
        });
        Local {
            particle: i,
            pairs: local,
            offsets,
            kinds: local_kinds,
            factor: f.matrix(),
            rows: n_rows,
            meat,
        }
    }

    /// Particle `i`'s acceleration at frame `t`: `accel`'s, or the second difference.
    fn acceleration(&self, t: usize, i: usize) -> Vec3 {
        let (traj, dt) = (self.traj, self.dt);
        match self.accel {
            Some(acc) => acc.at(t, i),
            None => (traj.pos(t + 1, i) - traj.pos(t, i) * 2.0 + traj.pos(t - 1, i)) / (dt * dt),
        }
    }

    /// The features of particle `i`'s groups `local` at frame `t` into `rows` (per factor
    /// column, per axis; the intercepts' and the right-hand side's left 0).
    fn group_rows(
        &self,
        t: usize,
        i: usize,
        local: &[usize],
        local_kinds: &[GroupKind],
        offsets: &[usize],
        rows: &mut [[f64; 3]],
    ) {
        let (traj, dt, free) = (self.traj, self.dt, self.free);
        for r in rows.iter_mut() {
            *r = [0.0; 3];
        }
        for (q, &p) in local.iter().enumerate() {
            let [pa, pb] = self.pairs[p];
            let other = if pa == i { pb } else { pa };
            let o = offsets[q];
            match local_kinds[q] {
                GroupKind::Spring => {
                    let fe = features(traj, dt, t, i, other);
                    for c in 0..3 {
                        for ax in 0..3 {
                            rows[o + c][ax] = fe[c][ax];
                        }
                    }
                }
                GroupKind::Damper => {
                    // Noisy positions: velocities uncorrelated with the error (see
                    // [`super::smooth::velocity_kernel_uncorrelated`]); a fixed end's 0.
                    let w = match self.accel {
                        Some(acc) => {
                            let vj = if free[other] {
                                acc.velocity(t, other)
                            } else {
                                Vec3::zeros()
                            };
                            vj - acc.velocity(t, i)
                        }
                        None => damper_feature(traj, dt, t, i, other),
                    };
                    for ax in 0..3 {
                        rows[o][ax] = w[ax];
                    }
                }
            }
        }
    }
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
pub fn fit(
    local: &Local,
    active: &[bool],
    floor: f64,
    gravity: Option<Vector3<f64>>,
    noise: Option<&Noise>,
) -> Fit {
    let m = local.pairs.len();
    let k = local.factor.ncols() - 1;
    let mut cols: Vec<usize> = if gravity.is_some() {
        Vec::new()
    } else {
        vec![0, 1, 2]
    };
    for q in (0..m).filter(|&q| active[q]) {
        cols.extend(local.group_columns(q));
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
    let x = &sol.x;
    // The covariance of the solution: white rows of variance σ² (`σ² W Wᵀ`), or with noisy
    // positions the noise's own.
    let (cov_all, inflation) = match (noise, &local.meat, sol.deficient) {
        (Some(nz), Some(meat), false) => {
            noisy_covariance(local, active, &cols, &sol, gravity, nz, meat)
        }
        _ => (&sol.w * sol.w.transpose() * sigma2, 1.0),
    };
    let (gravity, c0) = match gravity {
        Some(g) => (g, 0),
        None => (Vector3::new(x[0], x[1], x[2]), 3),
    };
    let mut out = Fit {
        beta: vec![Vector3::zeros(); m],
        cov: vec![Matrix3::zeros(); m],
        wald: vec![0.0; m],
        gravity,
        sigma2,
        inflation,
    };
    let mut c = c0;
    for q in (0..m).filter(|&q| active[q]) {
        let width = local.kinds[q].width();
        let mut b = Vector3::zeros();
        let mut cov = Matrix3::zeros();
        for a in 0..width {
            b[a] = x[c + a];
            for e in 0..width {
                cov[(a, e)] = cov_all[(c + a, c + e)];
            }
        }
        let wald = if sol.deficient {
            let without: Vec<usize> = cols
                .iter()
                .copied()
                .filter(|col| !local.group_columns(q).contains(col))
                .collect();
            (solve(r, &without, &rhs).rss - sol.rss) / sigma2
        } else {
            group_wald(&b, &cov, width)
        };
        // A damper dissipates: Z/m ≤ 0 is no damper, whatever its size (a one-sided test).
        let dissipates = local.kinds[q] != GroupKind::Damper || b[0] > 0.0;
        out.beta[q] = b;
        out.cov[q] = cov;
        out.wald[q] = if wald.is_finite() && dissipates {
            wald.max(0.0)
        } else {
            0.0
        };
        c += width;
    }
    out
}

/// With noisy positions, the covariance of a fit's solution `sol` on the columns `cols` under
/// the noise's own covariance (module docs), `G Xᵀ Σ X G` with `G = W Wᵀ`, scaled up by a
/// residual above what the noise explains; and the ratio of that residual to the noise's (the
/// [`Fit::inflation`]).
fn noisy_covariance(
    local: &Local,
    active: &[bool],
    cols: &[usize],
    sol: &Solved,
    gravity: Option<Vector3<f64>>,
    nz: &Noise,
    (m_accel, m_smooth): &(DMatrix<f64>, DMatrix<f64>),
) -> (DMatrix<f64>, f64) {
    let (x, w) = (&sol.x, &sol.w);
    let k = local.factor.ncols() - 1;
    let c0 = if gravity.is_some() { 0 } else { 3 };
    let g_inv = w * w.transpose();
    // The features' noise: each stiffness (per mass) times the smoothed noise of the
    // link's vector, the particle's own shared by all its pairs.
    let mut ks: Vec<f64> = Vec::new();
    let mut c = c0;
    for q in (0..local.pairs.len()).filter(|&q| active[q]) {
        if local.kinds[q] == GroupKind::Spring {
            ks.push(x[c]);
        }
        c += local.kinds[q].width();
    }
    let q_feat =
        ks.iter().map(|v| v.abs()).sum::<f64>().powi(2) + ks.iter().map(|v| v * v).sum::<f64>();
    let dt4 = nz.dt.powi(4);
    let n = cols.len();
    let mut meat = DMatrix::zeros(n, n);
    for (a, &ca) in cols.iter().enumerate() {
        for (b, &cb) in cols.iter().enumerate() {
            meat[(a, b)] = nz.variance * (m_accel[(ca, cb)] / dt4 + q_feat * m_smooth[(ca, cb)]);
        }
    }
    // A residual above what the noise explains (a motion the pairs cannot follow, the
    // smoothing's bias) scales the covariance up, as an F-test would. It is measured
    // in the band the features live in (the residual's power through the smoothing,
    // `eᵀ R_c e`): over all frequencies the accelerations' noise would hide it.
    let mut z = DVector::zeros(k + 1);
    z[k] = 1.0;
    for (e, &col) in cols.iter().enumerate() {
        z[col] = -x[e];
    }
    if let Some(g) = gravity {
        for c in 0..3 {
            z[c] = -g[c];
        }
    }
    let observed = (z.transpose() * m_smooth * &z)[0] / local.rows as f64;
    let expected = nz.smoothed_power_per_row(q_feat);
    let inflation = (observed / expected.max(f64::MIN_POSITIVE)).max(1.0);
    let ratio = observed / expected.max(f64::MIN_POSITIVE);
    (&g_inv * meat * &g_inv * inflation, ratio)
}

/// `βᵀ C⁻¹ β` over a group's first `width` unknowns (0 when `C` is singular).
fn group_wald(b: &Vector3<f64>, cov: &Matrix3<f64>, width: usize) -> f64 {
    if width == 1 {
        return if cov[(0, 0)] > 0.0 {
            b[0] * b[0] / cov[(0, 0)]
        } else {
            0.0
        };
    }
    cov.try_inverse()
        .map(|ci| (b.transpose() * ci * b)[0])
        .unwrap_or(0.0)
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
                    cols.extend(loc.offsets[q]..loc.offsets[q] + loc.kinds[q].width());
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

/// Forward steps after the backward elimination has settled (noisy positions only).
const MAX_FORWARD_ROUNDS: usize = 5;

/// One forward step: each removed pair not re-added before is scored as if added alone to
/// its ends' fits (its Wald statistics summed, as in the backward step); per particle the
/// strongest of those above their threshold comes back. Under noise the backward
/// elimination could drop a true link while many candidates stood in for it, and the
/// candidates around its end then stayed in its place (issue 20: varied seeds 8, 11, 21 at
/// noise 1e-4 kept 4–6 extra links about one particle that had lost one).
fn forward_step(
    locals: &[Local],
    seen: &[Vec<(usize, usize)>],
    active: &[bool],
    threshold: &[f64],
    readded: &mut [bool],
    fit_with: impl Fn(&Local, &[bool]) -> Fit + Sync,
) -> Vec<usize> {
    let tries: Vec<(usize, usize, usize)> = (0..active.len())
        .filter(|&p| !active[p] && !readded[p])
        .flat_map(|p| seen[p].iter().map(move |&(l, q)| (p, l, q)))
        .collect();
    let walds: Vec<(usize, usize, f64)> = tries
        .par_iter()
        .map(|&(p, l, q)| {
            let loc = &locals[l];
            let mut act: Vec<bool> = loc.pairs.iter().map(|&r| active[r]).collect();
            act[q] = true;
            (p, l, fit_with(loc, &act).wald[q])
        })
        .collect();
    let mut score = vec![0.0; active.len()];
    for &(p, _, w) in &walds {
        score[p] += w;
    }
    let mut best: Vec<Option<usize>> = vec![None; locals.len()];
    for &(p, l, _) in &walds {
        if score[p] >= threshold[p] && best[l].is_none_or(|b| (score[p], p) > (score[b], b)) {
            best[l] = Some(p);
        }
    }
    let mut add: Vec<usize> = (0..active.len())
        .filter(|&p| score[p] >= threshold[p])
        .filter(|&p| seen[p].iter().all(|&(l, _)| best[l] == Some(p)))
        .collect();
    add.dedup();
    for &p in &add {
        readded[p] = true;
    }
    add
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
    noise: Option<&Noise>,
) -> Selection {
    let mut active = vec![true; num_pairs];
    let mut threshold = vec![0.0; num_pairs];
    // Where each pair sits: (local index, position in it).
    let mut seen: Vec<Vec<(usize, usize)>> = vec![Vec::new(); num_pairs];
    for (l, loc) in locals.iter().enumerate() {
        // BIC: ln n per unknown of the group.
        let per = (loc.rows.max(2) as f64).ln() * threshold_scale;
        for (q, &p) in loc.pairs.iter().enumerate() {
            seen[p].push((l, q));
            threshold[p] += per * loc.kinds[q].width() as f64;
        }
    }
    let mut fits: Vec<Fit> = vec![Fit::default(); locals.len()];
    let mut dirty = vec![true; locals.len()];
    let mut score = vec![0.0; num_pairs];
    let mut rounds = 0;
    let (mut forward_rounds, mut readded) = (0, vec![false; num_pairs]);
    loop {
        rounds += 1;
        let updated: Vec<(usize, Fit)> = locals
            .par_iter()
            .enumerate()
            .filter(|(l, _)| dirty[*l])
            .map(|(l, loc)| {
                let act: Vec<bool> = loc.pairs.iter().map(|&p| active[p]).collect();
                (l, fit(loc, &act, floor, gravity, noise))
            })
            .collect();
        for (l, f) in updated {
            fits[l] = f;
            dirty[l] = false;
        }
        for p in (0..num_pairs).filter(|&p| active[p]) {
            score[p] = seen[p].iter().map(|&(l, q)| fits[l].wald[q]).sum();
        }
        // The weakest pair of each particle (by the score over its threshold, then the index:
        // by the score alone, a pair below its threshold could stay for good behind a weaker
        // one above its own).
        let ratio = |p: usize| score[p] / threshold[p];
        let weaker = |a: usize, b: usize| (ratio(a), a) < (ratio(b), b);
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
            match noise {
                Some(_) if forward_rounds < MAX_FORWARD_ROUNDS => {
                    forward_rounds += 1;
                    let add = forward_step(
                        locals,
                        &seen,
                        &active,
                        &threshold,
                        &mut readded,
                        |loc, act| fit(loc, act, floor, gravity, noise),
                    );
                    if add.is_empty() {
                        break;
                    }
                    for p in add {
                        active[p] = true;
                        for &(l, _) in &seen[p] {
                            dirty[l] = true;
                        }
                    }
                    continue;
                }
                _ => break,
            }
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
