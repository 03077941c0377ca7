//! The `hybrid` strategy's fast path for conditional ranges (known masses, every nonlinear
//! unknown a range): every interval of one range is scored for about the price of one inner
//! solve, and only the few intervals that can win are solved exactly.
//!
//! **Why it is cheap.** For fixed ranges the short cost is `|W [θ; 1]|²` with one row of `W`
//! per free particle, force frame and axis (position weighting: the θ part divided by the
//! known mass, [`crate::exact`]). A conditional type's range only decides which of its pairs
//! enter its own three columns (K, K·l0, Z). So the rows of everything else (`w0`: every other
//! force, every other type) are built once by the scene's own force passes, and each candidate
//! pair of a type with unknown range (every pair closer than the top of its box, at every force
//! frame) is computed once: its distance and its force per unit K, K·l0 and Z on each end.
//! Sweeping a range up its sorted observed distances then adds pairs one at a time, and each
//! pair changes the rows of its two particles only; the normal matrix `G = WᵀW` is updated by
//! `G += δwᵀ + wδᵀ + δδᵀ` per changed row (4 nonzero entries in δ), so that every interval's
//! least-squares minimum (a Schur complement of the reduced normal matrix, 9×9 for the fluid)
//! is known after one pass.
//!
//! **Why it stays exact.** Normal equations lose digits, so the sweep's scores are only used
//! as lower bounds: the intervals are then solved exactly (the same solver as every other inner
//! solve, `exact::solve`, with box clamping and rank handling), best bound first, until the
//! next bound exceeds the best exact score; the chosen interval is the best exactly scored one,
//! over *every* interval rather than a coarse-to-fine grid's. To keep the bounds sharp the
//! rows are expressed around the latest exact solution θ̂ (last column `a + Φθ̂`), so the
//! rounding of `G` scales with the current residual, not with the accelerations.

use cordis_core::forces::grid::Grid;
use cordis_core::forces::spring::{spring_force, spring_force_quadratic};
use cordis_core::Vec3;
use nalgebra::DMatrix;

use crate::exact::{self, Block, Col, Reduction, Spec, System, Weighting};
use crate::problem::space::Role;
use crate::problem::Problem;

/// Most intervals solved exactly per sweep: the bounds are sharp enough that a handful is the
/// rule; the cap only bounds the time when many intervals fit equally (then the best of those
/// solved is kept).
pub const MAX_EXACT_PER_SWEEP: usize = 48;

const GIB: f64 = 1024.0 * 1024.0 * 1024.0;

/// The most candidate pairs of a range's box that `memory` bytes hold while the sweep is
/// built: a third of it at 24 bytes each (a vector doubling and the sort's buffer take the
/// rest; the candidate distances listed before, 8 bytes each, are freed by then).
pub(crate) fn max_pairs(memory: f64) -> usize {
    (memory / (3.0 * std::mem::size_of::<Pair>() as f64)) as usize
}

/// The refusal of a range whose box holds more candidate pairs than [`max_pairs`]: `found`
/// pairs counted in the first `frames_seen` of `frames` force frames (the count stops there).
pub(crate) fn too_many_pairs(
    name: &str,
    max: f64,
    found: usize,
    frames_seen: usize,
    frames: usize,
    memory: f64,
) -> String {
    let counted = match frames_seen < frames {
        true => {
            format!("{found} candidate pairs in its first {frames_seen} of {frames} force frames")
        }
        false => format!("{found} candidate pairs over its {frames} force frames"),
    };
    format!(
        "range sweep: {name} up to its box's max {} m holds {counted}, {}{:.2} GiB to sweep (24 \
         bytes each, sorted), more than a third of the {:.2} GiB available: lower the box's \
         max, or use --strategy cmaes",
        cordis_core::arg::short(max),
        if frames_seen < frames { "over " } else { "" },
        found as f64 * 3.0 * std::mem::size_of::<Pair>() as f64 / GIB,
        memory / GIB
    )
}

/// Relative slack on the bounds: an interval is solved exactly while its bound is below
/// `(1 + BOUND_SLACK) · best + BOUND_FLOOR · scale` (rounding of the normal equations).
const BOUND_SLACK: f64 = 1e-6;
const BOUND_FLOOR: f64 = 1e-12;

/// One candidate pair of a type whose range is unknown, at one force frame: it interacts at
/// every range above `d`. 24 bytes: its [`Terms`] are recomputed from the observed frame when
/// a sweep uses them (stored, at 112 bytes per pair and frame, they made the sweep's memory
/// 2.76 GB for 2,000 particles × 10 frames, issue 17).
struct Pair {
    /// Distance, m (as the candidates list computes it).
    d: f64,
    /// The force frame.
    frame: u32,
    /// The two particles.
    ends: [u32; 2],
}

/// What a [`Pair`] adds to the rows.
struct Terms {
    /// Row of the first axis of each free end (`usize::MAX`: the end is fixed).
    rows: [usize; 2],
    /// dt² × force on the first end per unit K, K·l0, Z and Z₂ (the second end gets minus
    /// it; Z₂'s is 0 unless the type has one).
    f: [Vec3; 4],
    /// Factor of `f` in each end's rows: `1/m_i` and `-1/m_j` (position weighting).
    inv: [f64; 2],
}

/// One nonlinear unknown: a conditional type's range.
pub(crate) struct Dim {
    /// Index into `space.unknowns`.
    unknown: usize,
    /// Columns of the type's K, K·l0 and Z, and Z₂ when it has a `damping_quadratic`.
    cols: Vec<usize>,
    /// Candidate pairs, by increasing distance.
    pairs: Vec<Pair>,
    /// Sorted distinct observed distances inside the box (the interval bounds).
    pub c: Vec<f64>,
}

/// What the fast path needs, built once per solve.
pub(crate) struct Sweeper<'a> {
    problem: &'a Problem,
    cols: &'a [Col],
    /// Row width: θ columns + 1.
    width: usize,
    /// Each particle's index among the free ones (`usize::MAX`: fixed).
    free_index: Vec<usize>,
    /// Rows of every force but the unknown-range types', row-major, unshifted.
    w0: Vec<f64>,
    pub dims: Vec<Dim>,
    red: Reduction,
    linear: Vec<usize>,
    /// Exact inner solves so far.
    pub exact_solves: u64,
    /// Sweeps so far.
    pub sweeps: u64,
    /// Intervals bounded by the sweeps so far.
    pub scored: u64,
    /// Sweeps whose exact solves stopped at [`MAX_EXACT_PER_SWEEP`].
    pub capped: u64,
    /// The rounding allowance subtracted from the last sweep's bounds, m².
    pub floor: f64,
}

/// Most values of the uncompressed rows `W` (8 bytes each; a sweep holds about three copies):
/// beyond this (e.g. the default 80×48 fluid over 400 frames, ~10⁸) the grid of per-particle
/// factors is used instead.
pub const MAX_ROW_VALUES: usize = 1 << 23;

/// Whether the fast path applies: known masses (position weighting), only ranges searched, and
/// rows small enough to hold ([`MAX_ROW_VALUES`]).
pub(crate) fn applies(
    problem: &Problem,
    cols: usize,
    nonlinear: &[usize],
    free_masses: bool,
) -> bool {
    let obj = &problem.objective;
    let values = obj
        .frames()
        .saturating_sub(2)
        .saturating_mul(obj.free.len() * 3)
        .saturating_mul(cols + 1);
    !free_masses
        && values <= MAX_ROW_VALUES
        && !nonlinear.is_empty()
        && nonlinear
            .iter()
            .all(|&k| problem.space.unknowns[k].role == Role::Range)
}

/// Each particle's index among the free ones (`usize::MAX`: fixed): the row block of its
/// equations.
fn free_indices(problem: &Problem) -> Vec<usize> {
    let mut free_index = vec![usize::MAX; problem.objective.plan().n];
    for (l, &i) in problem.objective.free.iter().enumerate() {
        free_index[i] = l;
    }
    free_index
}

/// The position-weighted rows of every force but the searched types' (their ranges at 0: no
/// pair is closer), row-major: built once, the sweeps add the searched types' pairs to them.
fn rows_but_searched(problem: &Problem, cols: &[Col], dims: &[(usize, Vec<f64>)]) -> Vec<f64> {
    let obj = &problem.objective;
    let space = &problem.space;
    let mass_offset = problem.scene.param_layout().mass_offset;
    let width = cols.len() + 1;
    let mut p0 = space.base.clone();
    for (k, _) in dims {
        p0[space.unknowns[*k].slot] = 0.0;
    }
    let per_frame = obj.free.len() * 3;
    let mut w0 = Vec::with_capacity(obj.frames().saturating_sub(2) * per_frame * width);
    let searched: Vec<usize> = dims
        .iter()
        .filter_map(|(k, _)| space.unknowns[*k].type_index)
        .collect();
    let zero_cols: Vec<bool> = cols
        .iter()
        .map(|c| match *c {
            Col::K(t) | Col::KRest(t) | Col::Z(t) | Col::Z2(t) | Col::Quadratic(t) => {
                searched.contains(&t)
            }
            // A TGR's columns never depend on a range.
            Col::G(_) | Col::Rest(_) | Col::Known => false,
        })
        .collect();
    exact::design_rows(
        obj,
        &problem.scene,
        cols,
        &p0,
        &zero_cols,
        None,
        |_, l, row| {
            let inv = 1.0 / space.base[mass_offset + obj.free[l]];
            for v in &mut row[..width - 1] {
                *v *= inv;
            }
            w0.extend_from_slice(row);
        },
    );
    w0
}

/// The columns of type `t`'s K, K·l0 and Z, and Z₂ when it has a `damping_quadratic`: those a
/// pair entering its range changes.
fn range_columns(cols: &[Col], t: usize) -> Vec<usize> {
    // `generic_cols` gives every conditional type these three: a missing one would put a
    // pair's terms into another unknown's column, so it is an invariant, not a fallback.
    let col = |want: Col| {
        cols.iter()
            .position(|&c| c == want)
            .expect("generic_cols gives a conditional type its K, K·l0 and Z columns")
    };
    let mut dim_cols = vec![col(Col::K(t)), col(Col::KRest(t)), col(Col::Z(t))];
    if let Some(q) = cols.iter().position(|&c| c == Col::Quadratic(t)) {
        dim_cols.push(q);
    }
    dim_cols
}

/// The candidate pairs of range unknown `k` (of type `t`) with a free end, at every force
/// frame, by increasing distance; refused with [`too_many_pairs`] when they and the `held`
/// pairs of the ranges before pass [`max_pairs`] of `memory` (counted on, but not stored, past
/// it).
fn candidate_pairs(
    problem: &Problem,
    k: usize,
    t: usize,
    free_index: &[usize],
    grid: &mut Grid,
    held: usize,
    memory: f64,
) -> Result<Vec<Pair>, String> {
    let max_pairs = max_pairs(memory);
    let obj = &problem.objective;
    let frames = obj.frames();
    let u = &problem.space.unknowns[k];
    let o = problem.scene.param_layout().type_offsets[t];
    let mut p = problem.space.base.clone();
    p[u.slot] = u.max;
    let mut pairs = Vec::new();
    let mut found = 0usize;
    for pass in obj.plan().conditionals.iter().filter(|c| c.param == o) {
        for f in 1..frames.saturating_sub(1) {
            let x = obj.obs.frame(f);
            pass.for_each_active_pair(&p, x, grid, |i, j, d| {
                if free_index[i] == usize::MAX && free_index[j] == usize::MAX {
                    return;
                }
                found += 1;
                if held + pairs.len() >= max_pairs {
                    return; // counted, not stored: refused below
                }
                // A frame or particle count beyond u32 would not fit in memory.
                pairs.push(Pair {
                    d: d.norm(),
                    frame: f as u32,
                    ends: [i as u32, j as u32],
                });
            });
        }
    }
    if held + found > max_pairs {
        let f = frames.saturating_sub(2);
        return Err(too_many_pairs(&u.name, u.max, found, f, f, memory));
    }
    pairs.sort_by(|a, b| a.d.total_cmp(&b.d));
    Ok(pairs)
}

/// The reduction θ = Aξ + c of the columns with the `linear` unknowns free: the sweep's bounds
/// minimise over ξ, as the exact solves do.
fn linear_reduction(problem: &Problem, cols: &[Col], linear: &[usize]) -> Reduction {
    let space = &problem.space;
    let mut is_free = vec![false; space.base.len()];
    for &k in linear {
        is_free[space.unknowns[k].slot] = true;
    }
    exact::reduce(&problem.scene, cols, &space.base, &is_free)
}

impl<'a> Sweeper<'a> {
    /// `dims`: (unknown index, its candidates) per nonlinear unknown, all ranges.
    /// The sweeper of `dims`, its candidate pairs held within the memory available now.
    pub fn new(
        problem: &'a Problem,
        cols: &'a [Col],
        linear: &[usize],
        dims: Vec<(usize, Vec<f64>)>,
    ) -> Result<Self, String> {
        let memory = cordis_core::arg::available_memory().map_or(isize::MAX as f64, |m| m as f64);
        Self::within(problem, cols, linear, dims, memory)
    }

    /// [`Sweeper::new`] in `memory` bytes: the pairs within a box's top range grow as N²·T for
    /// a box reaching across the scene, so they are counted as they are stored and the sweep
    /// is refused, naming the range and the estimate, before they pass a third of `memory`
    /// (a vector doubling and the sort's buffer take the rest).
    pub fn within(
        problem: &'a Problem,
        cols: &'a [Col],
        linear: &[usize],
        dims: Vec<(usize, Vec<f64>)>,
        memory: f64,
    ) -> Result<Self, String> {
        let free_index = free_indices(problem);
        let w0 = rows_but_searched(problem, cols, &dims);
        let mut grid = Grid::default();
        let mut held = 0usize;
        let dims = dims
            .into_iter()
            .map(|(k, c)| {
                let t = problem.space.unknowns[k]
                    .type_index
                    .expect("a range belongs to a type");
                let dim_cols = range_columns(cols, t);
                let pairs = candidate_pairs(problem, k, t, &free_index, &mut grid, held, memory)?;
                held += pairs.len();
                Ok(Dim {
                    unknown: k,
                    cols: dim_cols,
                    pairs,
                    c,
                })
            })
            .collect::<Result<Vec<_>, String>>()?;
        let red = linear_reduction(problem, cols, linear);
        Ok(Sweeper {
            problem,
            cols,
            width: cols.len() + 1,
            free_index,
            w0,
            dims,
            red,
            linear: linear.to_vec(),
            exact_solves: 0,
            sweeps: 0,
            scored: 0,
            capped: 0,
            floor: 0.0,
        })
    }

    fn rows(&self) -> usize {
        self.w0.len() / self.width
    }

    /// The rows' terms of `pair`, from its observed frame (the same operations, in the same
    /// order, as when they were stored: the same bits).
    fn terms(&self, pair: &Pair, quadratic: bool) -> Terms {
        let obj = &self.problem.objective;
        let space = &self.problem.space;
        let mass_offset = self.problem.scene.param_layout().mass_offset;
        let mass = |i: usize| space.base[mass_offset + i];
        let f = pair.frame as usize;
        let [i, j] = pair.ends.map(|e| e as usize);
        let (x, v) = (obj.obs.frame(f), obj.obs.velocity(f));
        let (xi, xj, vi, vj) = (&x[i], &x[j], &v[i], &v[j]);
        let fk = spring_force::<false>(xi, xj, vi, vj, 1.0, 0.0, 0.0);
        let fr = spring_force::<false>(xi, xj, vi, vj, 1.0, 1.0, 0.0) - fk;
        let fz = spring_force::<true>(xi, xj, vi, vj, 0.0, 0.0, 1.0);
        let fq = if quadratic {
            spring_force_quadratic((xi, xj), (vi, vj), [0.0, 0.0, 0.0, 1.0])
        } else {
            Vec3::zeros()
        };
        let base = (f - 1) * obj.free.len() * 3;
        let row = |l: usize| {
            if l == usize::MAX {
                usize::MAX
            } else {
                base + l * 3
            }
        };
        let dt = obj.plan().dt;
        let dt2 = dt * dt;
        Terms {
            rows: [row(self.free_index[i]), row(self.free_index[j])],
            f: [fk * dt2, fr * dt2, fz * dt2, fq * dt2],
            inv: [1.0 / mass(i), -1.0 / mass(j)],
        }
    }

    /// The middle of interval `j` of dim `d`.
    pub fn middle(&self, d: usize, j: usize) -> f64 {
        let u = &self.problem.space.unknowns[self.dims[d].unknown];
        let c = &self.dims[d].c;
        let lo = if j == 0 { u.min } else { c[j - 1] };
        let hi = if j == c.len() { u.max } else { c[j] };
        0.5 * (lo + hi)
    }

    /// The full parameter vector at the intervals `at` (linear unknowns at their start).
    pub fn params_at(&self, at: &[usize]) -> Vec<f64> {
        let space = &self.problem.space;
        let mut p = space.base.clone();
        for (d, &j) in at.iter().enumerate() {
            p[space.unknowns[self.dims[d].unknown].slot] = self.middle(d, j);
        }
        p
    }

    /// Adds the pairs of dim `d` closer than `range` to the rows.
    fn add_pairs(&self, w: &mut [f64], d: usize, range: f64) {
        let dim = &self.dims[d];
        let wd = self.width;
        for pair in dim.pairs.iter().take_while(|p| p.d < range) {
            let pair = self.terms(pair, dim.cols.len() == 4);
            for (&r0, &sign) in pair.rows.iter().zip(&pair.inv) {
                if r0 == usize::MAX {
                    continue;
                }
                for axis in 0..3 {
                    let row = &mut w[(r0 + axis) * wd..(r0 + axis + 1) * wd];
                    for (c, f) in dim.cols.iter().zip(&pair.f) {
                        row[*c] += sign * f[axis];
                    }
                }
            }
        }
    }

    /// The rows at the intervals `at`, unshifted.
    fn rows_at(&self, at: &[usize]) -> Vec<f64> {
        let mut w = self.w0.clone();
        for (d, &j) in at.iter().enumerate() {
            self.add_pairs(&mut w, d, self.middle(d, j));
        }
        w
    }

    /// The short cost's system at the intervals `at`: one position-space block of all rows.
    pub fn system_at(&self, at: &[usize]) -> System {
        let w = self.rows_at(at);
        System {
            cols: self.cols.to_vec(),
            blocks: vec![Block {
                particle: None,
                rows: DMatrix::from_row_slice(self.rows(), self.width, &w),
            }],
            partial: false,
        }
    }

    /// The exact inner solve at the intervals `at`: its residual (`inf` when it fails) and
    /// parameters.
    pub fn exact(&mut self, at: &[usize]) -> (f64, Vec<f64>) {
        self.exact_solves += 1;
        let system = self.system_at(at);
        let p = self.params_at(at);
        let spec = Spec {
            problem: self.problem,
            system: &system,
            p: p.clone(),
            linear: self.linear.clone(),
            weighting: Weighting::Position,
        };
        match exact::solve(&spec) {
            Ok(o) if o.residual.is_finite() => (o.residual, o.params),
            _ => (f64::INFINITY, p),
        }
    }

    /// Lower bounds of the short cost on every interval of dim `d`, the others at `at`, rows
    /// shifted by θ̂ = the θ of `p_hat`. `out[j]` for interval j.
    ///
    /// Only the columns of unknowns are kept (`ucols`): with the rows shifted, a known column's
    /// contribution is already in the last one, so the normal matrix is (unknowns + 1)² wide
    /// (10 for the fluid rather than 25) and a pair costs a few dozen flops.
    pub fn bounds(&mut self, d: usize, at: &[usize], p_hat: &[f64], out: &mut Vec<f64>) {
        self.sweeps += 1;
        let scene = &self.problem.scene;
        let theta: Vec<f64> = self
            .cols
            .iter()
            .map(|&c| exact::theta_of(scene, c, p_hat))
            .collect();
        // Compact columns: those with a reduced unknown, then the shifted constant.
        let ucols: Vec<usize> = (0..self.width - 1)
            .filter(|&k| self.red.terms[k].is_some())
            .collect();
        let cw = ucols.len() + 1;
        let mut wc = self.shifted_rows(d, at, &theta, &ucols);
        let mut g = normal_matrix(&wc, cw);
        let terms: Vec<(usize, f64)> = ucols.iter().filter_map(|&k| self.red.terms[k]).collect();
        let mut schur = Schur::new(self.red.len(), terms);
        let dim = &self.dims[d];
        let n = dim.c.len() + 1;
        out.clear();
        out.push(schur.bound(&g, cw));
        let changing = Changing::new(dim, &ucols, &theta, cw);
        let mut next = dim.pairs.partition_point(|p| p.d < self.middle(d, 0));
        for j in 1..n {
            let range = self.middle(d, j);
            let first = next;
            while next < dim.pairs.len() && dim.pairs[next].d < range {
                let pair = self.terms(&dim.pairs[next], dim.cols.len() == 4);
                next += 1;
                changing.add(&pair, &mut wc, &mut g);
            }
            if next > first {
                changing.mirror(&mut g);
            }
            out.push(schur.bound(&g, cw));
        }
        self.scored += n as u64;
        // The floor of the bounds' rounding, relative to the shifted residual's scale.
        let floor = BOUND_FLOOR * g[cw * cw - 1].abs();
        self.floor = floor;
        for v in out.iter_mut() {
            *v -= floor;
        }
    }

    /// The rows with dim `d` at the bottom of its box and the others at `at`, compacted to the
    /// columns `ucols` and shifted by `theta` (last column `a + Φθ̂`): the sweep's start.
    fn shifted_rows(&self, d: usize, at: &[usize], theta: &[f64], ucols: &[usize]) -> Vec<f64> {
        let wd = self.width;
        let nc = wd - 1;
        let cw = ucols.len() + 1;
        let mut w = self.w0.clone();
        for (e, &j) in at.iter().enumerate() {
            let range = self.middle(e, if e == d { 0 } else { j });
            self.add_pairs(&mut w, e, range);
        }
        let mut wc = vec![0.0; self.rows() * cw];
        for (row, out_row) in w.chunks_exact(wd).zip(wc.chunks_exact_mut(cw)) {
            for (m, &k) in ucols.iter().enumerate() {
                out_row[m] = row[k];
            }
            let s: f64 = row[..nc].iter().zip(theta).map(|(a, b)| a * b).sum();
            out_row[cw - 1] = row[nc] + s;
        }
        wc
    }

    /// The best interval of dim `d` (the others at `at`): bounds for all, exact solves in
    /// order of bound until no other can win. Returns (interval, exact residual, parameters);
    /// `best` is the current point's exact result (interval `at[d]`).
    pub fn search(
        &mut self,
        d: usize,
        at: &[usize],
        best: (f64, Vec<f64>),
        bounds: &mut Vec<f64>,
    ) -> (usize, f64, Vec<f64>) {
        self.bounds(d, at, &best.1, bounds);
        let mut order: Vec<usize> = (0..bounds.len()).collect();
        order.sort_by(|&a, &b| bounds[a].total_cmp(&bounds[b]).then(a.cmp(&b)));
        let (mut j_best, mut v_best, mut p_best) = (at[d], best.0, best.1);
        let mut point = at.to_vec();
        let mut solved = 0;
        for &j in &order {
            if bounds[j] > v_best + BOUND_SLACK * v_best.abs() {
                break;
            }
            if j == at[d] {
                continue;
            }
            if solved == MAX_EXACT_PER_SWEEP {
                self.capped += 1;
                break;
            }
            solved += 1;
            point[d] = j;
            let (v, p) = self.exact(&point);
            if v < v_best || (v == v_best && j < j_best) {
                (j_best, v_best, p_best) = (j, v, p);
            }
        }
        (j_best, v_best, p_best)
    }
}

/// `G = WᵀW` of the row-major rows `wc`, `cw` wide (the upper triangle summed, then mirrored).
fn normal_matrix(wc: &[f64], cw: usize) -> Vec<f64> {
    let mut g = vec![0.0; cw * cw];
    for row in wc.chunks_exact(cw) {
        for a in 0..cw {
            let ra = row[a];
            if ra == 0.0 {
                continue;
            }
            for (x, &rb) in g[a * cw + a..(a + 1) * cw].iter_mut().zip(&row[a..]) {
                *x += ra * rb;
            }
        }
    }
    for a in 0..cw {
        for b in 0..a {
            g[a * cw + b] = g[b * cw + a];
        }
    }
    g
}

/// The compact columns a dim's pairs change, and the rank update of `G` that adding a pair
/// makes: a pair touches the rows of its two ends only.
struct Changing {
    /// Per column of the type that moves a row: (index into the pair's [`Terms::f`], its
    /// compact column when it is an unknown's, its θ̂ for the shifted constant).
    cols: Vec<(usize, Option<usize>, f64)>,
    /// The compact columns changed: the unknowns' in `cols` order, then the constant; `len`
    /// of them.
    changed: [usize; 5],
    len: usize,
    /// Compact row width.
    cw: usize,
}

impl Changing {
    /// The changing columns of `dim` among the compact columns `ucols` (`cw` wide with the
    /// shifted constant), rows shifted by `theta`.
    fn new(dim: &Dim, ucols: &[usize], theta: &[f64], cw: usize) -> Self {
        let mut pos = vec![usize::MAX; theta.len()];
        for (m, &k) in ucols.iter().enumerate() {
            pos[k] = m;
        }
        let mut cols: Vec<(usize, Option<usize>, f64)> = Vec::with_capacity(4);
        for (c, &k) in dim.cols.iter().enumerate() {
            let m = (pos[k] != usize::MAX).then_some(pos[k]);
            if m.is_some() || theta[k] != 0.0 {
                cols.push((c, m, theta[k]));
            }
        }
        let mut changed = [0usize; 5];
        let mut len = 0;
        for &(_, m, _) in &cols {
            if let Some(m) = m {
                changed[len] = m;
                len += 1;
            }
        }
        changed[len] = cw - 1;
        Changing {
            cols,
            changed,
            len: len + 1,
            cw,
        }
    }

    /// Adds `pair` to the compact rows `wc` and to `g`: `G += δwᵀ + wδᵀ + δδᵀ` with the old w
    /// per changed row, in the rows of the changed columns only (see [`Self::mirror`]).
    fn add(&self, pair: &Terms, wc: &mut [f64], g: &mut [f64]) {
        let (cw, nd) = (self.cw, self.len);
        let dpos = &self.changed[..nd];
        let mut delta = [0.0; 5];
        for (&r0, &sign) in pair.rows.iter().zip(&pair.inv) {
            if r0 == usize::MAX {
                continue;
            }
            for axis in 0..3 {
                delta[..nd].fill(0.0);
                let mut shift = 0.0;
                let mut q = 0;
                for &(c, m, th) in &self.cols {
                    let v = sign * pair.f[c][axis];
                    shift += v * th;
                    if m.is_some() {
                        delta[q] = v;
                        q += 1;
                    }
                }
                delta[nd - 1] = shift;
                let row = &mut wc[(r0 + axis) * cw..(r0 + axis + 1) * cw];
                // G += δwᵀ + wδᵀ + δδᵀ with the old w (rows of the changed columns only;
                // mirrored before scoring), then w += δ.
                for (&c, &dc) in dpos.iter().zip(&delta[..nd]) {
                    let gr = &mut g[c * cw..(c + 1) * cw];
                    for (x, &wk) in gr.iter_mut().zip(row.iter()) {
                        *x += dc * wk;
                    }
                }
                for (&c, &dc) in dpos.iter().zip(&delta[..nd]) {
                    for (&e, &de) in dpos.iter().zip(&delta[..nd]) {
                        g[c * cw + e] += de * (row[c] + dc);
                    }
                }
                for (&c, &dc) in dpos.iter().zip(&delta[..nd]) {
                    row[c] += dc;
                }
            }
        }
    }

    /// Rows of the changed columns into their columns (δwᵀ's transpose): `g` symmetric again
    /// after [`Self::add`].
    fn mirror(&self, g: &mut [f64]) {
        let cw = self.cw;
        for &c in &self.changed[..self.len] {
            for k in 0..cw {
                g[k * cw + c] = g[c * cw + k];
            }
        }
    }
}

/// `min_ξ |W T [ξ; 1]|²` from `G = WᵀW` over the compact columns (the last row and column:
/// the shifted constant column): the Schur complement of the reduced normal matrix, by a
/// Cholesky factorisation that skips directions the data do not determine. Scratch
/// preallocated: no allocation per interval.
struct Schur {
    /// Per compact column but the last: (reduced unknown, coefficient).
    terms: Vec<(usize, f64)>,
    p: usize,
    m: Vec<f64>,
    b: Vec<f64>,
    diag: Vec<f64>,
}

impl Schur {
    fn new(p: usize, terms: Vec<(usize, f64)>) -> Self {
        Schur {
            terms,
            p,
            m: vec![0.0; p * p],
            b: vec![0.0; p],
            diag: vec![0.0; p],
        }
    }

    fn bound(&mut self, g: &[f64], cw: usize) -> f64 {
        let p = self.p;
        let last = cw - 1;
        let (m, b) = (&mut self.m, &mut self.b);
        m.fill(0.0);
        b.fill(0.0);
        // With the rows shifted by θ̂ = Aξ̂ + c, the reduced problem in ξ - ξ̂ has no constant
        // column but the last one.
        for (k, &(a, ca)) in self.terms.iter().enumerate() {
            b[a] += ca * g[k * cw + last];
            for (l, &(bb, cb)) in self.terms.iter().enumerate() {
                m[a * p + bb] += ca * cb * g[k * cw + l];
            }
        }
        let mut s = g[last * cw + last];
        for a in 0..p {
            self.diag[a] = m[a * p + a];
        }
        // In-place Cholesky (lower), then s -= |L⁻¹ b|².
        for a in 0..p {
            let mut piv = m[a * p + a];
            for k in 0..a {
                piv -= m[a * p + k] * m[a * p + k];
            }
            // A NaN pivot counts as undetermined too.
            if piv.is_nan() || piv <= 1e-13 * self.diag[a] {
                for x in 0..p {
                    m[x * p + a] = 0.0;
                    m[a * p + x] = 0.0;
                }
                b[a] = 0.0;
                continue;
            }
            let l = piv.sqrt();
            m[a * p + a] = l;
            for r in a + 1..p {
                let mut v = m[r * p + a];
                for k in 0..a {
                    v -= m[r * p + k] * m[a * p + k];
                }
                m[r * p + a] = v / l;
            }
            let mut y = b[a];
            for k in 0..a {
                y -= m[a * p + k] * b[k];
            }
            b[a] = y / l;
            s -= b[a] * b[a];
        }
        if s.is_nan() {
            f64::NEG_INFINITY
        } else {
            s
        }
    }
}

#[cfg(test)]
mod tests {

    #[test]
    fn a_candidate_pair_takes_24_bytes_not_112() {
        // Issue 17: the sweep holds one per pair within the box's top range and force frame.
        assert_eq!(std::mem::size_of::<super::Pair>(), 24);
    }

    /// Issue 17: a box reaching across the scene holds N²·T pairs (3,000 particles aborted
    /// the process). Past the memory given, the sweep is refused naming the range and the
    /// estimate, having stored no more than its share; within it, it is built.
    #[test]
    fn pairs_beyond_the_memory_are_refused_with_the_estimate() {
        let (_, problem) = gas_problem();
        let cols = exact::generic_cols(&problem.scene).unwrap();
        let sp = split(&problem);
        let dims = range_dims(&problem, &sp.nonlinear);
        let pairs = |memory| {
            Sweeper::within(&problem, &cols, &sp.linear, dims.clone(), memory)
                .map(|s| s.dims.iter().map(|d| d.pairs.len()).sum::<usize>())
        };
        let all = pairs(1e12).unwrap();
        assert!(all > 100, "{all}");
        // Room for exactly the pairs (a third of the memory at 24 bytes each): built.
        assert_eq!(pairs(72.0 * all as f64).unwrap(), all);
        let e = pairs(72.0 * (all - 1) as f64).unwrap_err();
        assert!(e.starts_with("range sweep: types."), "{e}");
        assert!(
            e.contains("candidate pairs over its 58 force frames"),
            "{e}"
        );
        assert!(e.contains("lower the box's max"), "{e}");
        // The candidate distances listed before the sweep stop as soon as the count passes
        // the same share: refused after the frame that passed it, not after all of them.
        let k = dims[0].0;
        let listed = crate::strategies::hybrid::candidates_within(&problem, k, 72.0 * 10.0);
        let e = listed.unwrap_err();
        assert!(e.contains("in its first 1 of 58 force frames"), "{e}");
        assert!(crate::strategies::hybrid::candidates_within(&problem, k, 1e12).is_ok());
    }

    use cordis_core::Scene;

    use super::*;
    use crate::cost::CostKind;
    use crate::identify::with_unknown_boxes;
    use crate::strategies::exact::split;

    /// Eight particles of one group held by anchors, a conditional type between them (K, l0,
    /// range unknown) and a second one reaching further, damped (Z, range unknown): pairs
    /// come in and out of both ranges all the time.
    fn gas() -> Scene {
        let pts = [
            [0.0, 0.0, 0.0],
            [0.4, 0.1, 0.0],
            [-0.3, 0.35, 0.1],
            [0.1, -0.4, -0.1],
            [0.5, 0.5, 0.2],
            [-0.45, -0.2, 0.3],
            [0.2, 0.3, -0.4],
            [-0.1, -0.1, 0.5],
        ];
        crate::strategies::test_scenes::anchored_gas(&pts, true)
    }

    /// The gas with every parameter of its types unknown (boxes 25× wide), over 60 frames.
    fn gas_problem() -> (Scene, Problem) {
        let truth = gas();
        let unknown = with_unknown_boxes(&truth, 25.0, 5);
        let traj = truth.simulate(60).unwrap();
        let problem = Problem::new(&unknown, &traj, CostKind::Short).unwrap();
        (truth, problem)
    }

    /// Each range unknown of `nonlinear` with its candidate values.
    fn range_dims(problem: &Problem, nonlinear: &[usize]) -> Vec<(usize, Vec<f64>)> {
        nonlinear
            .iter()
            .map(|&k| {
                (
                    k,
                    crate::strategies::hybrid::candidates(problem, k).unwrap().0,
                )
            })
            .collect()
    }

    /// The sweep's bound of every interval against a full inner solve built the old way
    /// (the scene's force passes per column, per-particle factors, [`exact::solve`]): never
    /// above it, and equal to it wherever the full solve clamped and held nothing.
    #[test]
    fn sweep_bounds_match_full_solves_on_every_interval() {
        let (truth, problem) = gas_problem();
        let cols = exact::generic_cols(&problem.scene).unwrap();
        let sp = split(&problem);
        assert!(applies(&problem, cols.len(), &sp.nonlinear, sp.free_masses));
        let dims = range_dims(&problem, &sp.nonlinear);
        assert_eq!(dims.len(), 2);
        let mut sw = Sweeper::new(&problem, &cols, &sp.linear, dims).unwrap();
        let space = &problem.space;
        // Both ranges in the interval holding the truth's value.
        let t = truth.param_values();
        let mut at: Vec<usize> = sw
            .dims
            .iter()
            .map(|d| {
                let slot = space.unknowns[d.unknown].slot;
                d.c.partition_point(|&v| v < t[slot])
            })
            .collect();
        let (_, p_hat) = sw.exact(&at);
        let mut compared = 0;
        for d in 0..2 {
            let mut bounds = Vec::new();
            sw.bounds(d, &at, &p_hat, &mut bounds);
            assert_eq!(bounds.len(), sw.dims[d].c.len() + 1);
            assert!(bounds.len() > 50, "{} intervals", bounds.len());
            let keep = at[d];
            for (j, &bound) in bounds.iter().enumerate() {
                at[d] = j;
                let p = sw.params_at(&at);
                let system = exact::assemble(&problem.objective, &problem.scene, &cols, &p);
                let full = exact::solve(&Spec {
                    problem: &problem,
                    system: &system,
                    p,
                    linear: sp.linear.clone(),
                    weighting: Weighting::Position,
                })
                .unwrap();
                let tol = 1e-7 * full.residual;
                assert!(
                    bound <= full.residual + tol,
                    "dim {d} interval {j}: {bound} > {}",
                    full.residual
                );
                if full.clamped.is_empty() && full.undetermined.is_empty() {
                    // Equal up to the allowance the sweep subtracts for its rounding.
                    assert!(
                        (bound + sw.floor - full.residual).abs() <= sw.floor + tol,
                        "dim {d} interval {j}: bound {bound}, full solve {}",
                        full.residual
                    );
                    compared += 1;
                }
            }
            at[d] = keep;
            eprintln!(
                "dim {d}: {} intervals, rounding allowance {:.3e} m², {compared} compared so far",
                bounds.len(),
                sw.floor
            );
        }
        assert!(compared > 100, "only {compared} intervals compared");
    }
}
