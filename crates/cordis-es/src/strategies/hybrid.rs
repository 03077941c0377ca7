//! `hybrid`: variable projection (SPEC §4). The unknowns that enter the short cost
//! nonlinearly — a nonlinear drag's `v_max`, a conditional type's `range` — are searched; for
//! each candidate the linear ones (K, l0, Z, c0, z1, z2, masses) are solved exactly
//! ([`crate::exact`]): for a fixed v_max the drag force is linear in z1 and z2, for a fixed
//! range the set of interacting pairs at every frame is fixed. The outer cost is the inner
//! least-squares minimum.
//!
//! **The outer search** uses the structure of these parameters instead of a general-purpose
//! optimiser: the short cost reads v_max only through `|v_i(t)| < v_max` and a range only
//! through `L_ij(t) < range`, on observed velocities and distances. Between two consecutive
//! observed values the cost is therefore constant, and the search is over those intervals:
//! the observed speeds (distances) within the box are sorted, an interval is scored at its
//! middle, and the best one is found by a coarse-to-fine grid over the interval index (24
//! points, then the bracket around the best, until ≤ 48 intervals remain and all are
//! scored; the points of a grid are scored in parallel). Several nonlinear unknowns are
//! searched one at a time, cycling until none moves (coordinate descent, at most
//! [`MAX_CYCLES`] cycles). The answer is the middle of the
//! best interval; every value in it fits the data equally, and the report gives it. A
//! landscape with several separate basins can trap the grid in the wrong one; this has not
//! been seen on driven scenes, where misclassified samples grow steadily away from the truth.
//!
//! **Ranges only, masses known, no Provot limit** (the fluids): [`crate::exact::range_sweep`] replaces the grid. One
//! sweep per range bounds *every* interval (normal equations updated pair by pair), the
//! intervals are solved exactly in order of bound until none can beat the best, so each
//! coordinate step finds the best interval of all, not of a grid; a range whose neighbours'
//! intervals have not moved since its last sweep is not swept again. It holds every row of the
//! short cost uncompressed, so scenes beyond [`range_sweep::MAX_ROW_VALUES`] keep the grid.
//!
//! **Continuous unknowns** — a TGR's K and tendon parameters ([`crate::exact::tgr_cols`]: at a fixed K
//! the TGR's force is affine in l0 and Z) — are searched by a 1-D profile search over the box
//! ([`crate::exact::profile`]: coarse grid, then Brent) as further coordinates of the same descent,
//! which stops when an interval search at the settled continuous values moves nothing. When
//! every column has a typed kernel the inner solves use the cached design of
//! [`crate::exact::design`] (serial, ~15 µs each on the tadpole); the final answer is solved from an
//! orthogonal (Givens) factor of the rows, never the normal equations.
//!
//! With Provot limits the inner solve is [`crate::exact::provot_rows`]'s iteration, and candidates are
//! compared by the problem's own cost (each one drops its own rows, so the inner minima are
//! sums over different rows).

use std::collections::HashMap;

use cordis_core::forces::grid::Grid;
use rayon::prelude::*;

use crate::exact::design::Design;
use crate::exact::profile;
use crate::exact::provot_rows;
use crate::exact::range_sweep::{self, Sweeper, MAX_EXACT_PER_SWEEP};
use crate::exact::{self, ExactReport, OneShot, Solution, Spec, Weighting};
use crate::problem::space::Role;
use crate::problem::Problem;

/// Most coordinate-descent cycles over the nonlinear unknowns.
pub const MAX_CYCLES: usize = 6;
/// Observed values kept per nonlinear unknown (more are subsampled evenly: the final
/// interval is then wider than the data's resolution, and the report says so).
pub const MAX_CANDIDATES: usize = 1 << 18;

/// The sorted distinct observed values of a nonlinear unknown inside its box: speeds of the
/// nonlinear drag's particles, or distances of the conditional type's candidate pairs, at the
/// frames the short cost computes forces at (1 … T-2).
pub(crate) fn candidates(problem: &Problem, k: usize) -> Result<(Vec<f64>, bool), String> {
    let memory = cordis_core::arg::available_memory().map_or(isize::MAX as f64, |m| m as f64);
    candidates_within(problem, k, memory)
}

/// [`candidates`] with `memory` bytes: a range's distances are listed pair by pair and frame
/// by frame (O(N²·T) for a box reaching across the scene, which listed 12.8 GB of them for
/// 20,000 particles before the sweep was refused), so the listing stops, refused, as soon as
/// the pairs counted exceed what the sweep could hold ([`range_sweep::max_pairs`]).
pub(crate) fn candidates_within(
    problem: &Problem,
    k: usize,
    memory: f64,
) -> Result<(Vec<f64>, bool), String> {
    let u = &problem.space.unknowns[k];
    let obj = &problem.objective;
    let plan = obj.plan();
    let frames = obj.frames();
    let Some(t) = u.type_index else {
        return Ok((Vec::new(), false));
    };
    let o = problem.scene.param_layout().type_offsets[t];
    let mut c = Vec::new();
    match u.role {
        Role::Speed => {
            let drags = &plan.nonlinear_drags;
            for r in drags.runs.iter().filter(|r| r.param == o) {
                for &i in &drags.particles[r.start..r.end] {
                    for f in 1..frames - 1 {
                        c.push(obj.obs.velocity(f)[i as usize].norm());
                    }
                }
            }
        }
        Role::Range => {
            let mut p = problem.space.base.clone();
            p[u.slot] = u.max;
            let mut grid = Grid::default();
            let cap = range_sweep::max_pairs(memory);
            let mut found = 0usize;
            for pass in plan.conditionals.iter().filter(|c| c.param == o) {
                for f in 1..frames - 1 {
                    pass.for_each_active_pair(&p, obj.obs.frame(f), &mut grid, |_, _, d| {
                        found += 1;
                        if found <= cap {
                            c.push(d.norm());
                        }
                    });
                    if found > cap {
                        let all = frames - 2;
                        return Err(range_sweep::too_many_pairs(
                            &u.name, u.max, found, f, all, memory,
                        ));
                    }
                }
            }
        }
        _ => {}
    }
    c.retain(|&v| v > u.min && v < u.max);
    c.sort_by(f64::total_cmp);
    c.dedup();
    let thinned = c.len() > MAX_CANDIDATES;
    if thinned {
        let stride = c.len().div_ceil(MAX_CANDIDATES);
        c = c.into_iter().step_by(stride).collect();
    }
    Ok((c, thinned))
}

/// Interval j (0 …= n) of a sorted candidate list inside the box [min, max].
fn interval(c: &[f64], min: f64, max: f64, j: usize) -> (f64, f64) {
    let lo = if j == 0 { min } else { c[j - 1] };
    let hi = if j == c.len() { max } else { c[j] };
    (lo, hi)
}

/// Index in `0..n` of the least `f`, by a coarse-to-fine grid (see the module docs); `f`
/// scores a batch of indices (in parallel).
fn search(n: usize, mut f: impl FnMut(&[usize]) -> Vec<f64>) -> usize {
    let (mut lo, mut hi) = (0, n - 1);
    let mut best_of = |idx: &[usize]| {
        let mut best = (idx[0], f64::INFINITY);
        for (&j, v) in idx.iter().zip(f(idx)) {
            if v < best.1 {
                best = (j, v);
            }
        }
        best.0
    };
    loop {
        if hi - lo < 48 {
            let all: Vec<usize> = (lo..=hi).collect();
            return best_of(&all);
        }
        let mut idx: Vec<usize> = (0..=24).map(|k| lo + (hi - lo) * k / 24).collect();
        idx.dedup();
        let b = best_of(&idx);
        let at = idx.iter().position(|&j| j == b).unwrap_or(0);
        lo = idx[at.saturating_sub(1)];
        hi = idx[(at + 1).min(idx.len() - 1)];
    }
}

/// Solves `problem` by variable projection; `Err` when the exact solvers do not apply.
pub fn solve(problem: &Problem) -> Result<Solution, String> {
    solve_with(problem, true)
}

/// [`solve`], with the range sweeps only where `sweeps` allows them (false: always the
/// coarse-to-fine grid, as before the sweeps existed; kept to check one against the other).
fn solve_with(problem: &Problem, sweeps: bool) -> Result<Solution, String> {
    let outer = Outer::new(problem)?;
    if sweeps
        && !outer.provot
        && range_sweep::applies(
            problem,
            outer.cols.len(),
            &outer.split.nonlinear,
            outer.split.free_masses,
        )
    {
        return outer.by_sweeps();
    }
    outer.by_grid()
}

/// An interval unknown: its index, its sorted observed values, whether they were thinned.
type Dim = (usize, Vec<f64>, bool);

/// A point of the outer search: an interval index per interval unknown, an internal
/// coordinate per continuous one.
type Point = (Vec<usize>, Vec<f64>);

/// The outer problem: the exact solvers' split of the unknowns and the nonlinear ones to
/// search.
struct Outer<'a> {
    problem: &'a Problem,
    cols: Vec<exact::Col>,
    split: exact::Split,
    weighting: Weighting,
    /// The unknowns searched over observed intervals (v_max, ranges).
    dims: Vec<Dim>,
    /// The continuous nonlinear unknowns (a TGR's K, its tendon): 1-D profile searches in
    /// their internal coordinates.
    conts: Vec<usize>,
    /// With Provot limits candidates drop different rows: they are compared by the problem's
    /// own cost.
    provot: bool,
}

impl<'a> Outer<'a> {
    fn new(problem: &'a Problem) -> Result<Self, String> {
        exact::supported(problem)?;
        let cols = exact::generic_cols(&problem.scene)?;
        let split = exact::split(problem);
        exact::check_scale(problem, &split, &cols)?;
        let weighting = if split.free_masses {
            Weighting::Force
        } else {
            Weighting::Position
        };
        let space = &problem.space;
        let (interval_dims, conts): (Vec<usize>, Vec<usize>) = split
            .nonlinear
            .iter()
            .partition(|&&k| matches!(space.unknowns[k].role, Role::Range | Role::Speed));
        let dims: Vec<Dim> = interval_dims
            .iter()
            .map(|&k| candidates(problem, k).map(|(c, thinned)| (k, c, thinned)))
            .collect::<Result<_, _>>()?;
        let provot = provot_rows::applies(&problem.objective);
        Ok(Outer {
            problem,
            cols,
            split,
            weighting,
            dims,
            conts,
            provot,
        })
    }

    /// The interval holding each interval unknown's starting value.
    fn start_intervals(&self) -> Vec<usize> {
        let space = &self.problem.space;
        self.dims
            .iter()
            .map(|(k, c, _)| c.partition_point(|&v| v < space.base[space.unknowns[*k].slot]))
            .collect()
    }

    /// The continuous unknowns' starting values, in internal coordinates.
    fn start_values(&self) -> Vec<f64> {
        let space = &self.problem.space;
        self.conts
            .iter()
            .map(|&k| {
                let u = &space.unknowns[k];
                let (lo, hi) = u.internal_bounds();
                u.to_internal(space.base[u.slot]).clamp(lo, hi)
            })
            .collect()
    }

    /// The scene's parameters at intervals `at` (their middles) and continuous values `vals`.
    fn params_at(&self, at: &[usize], vals: &[f64]) -> Vec<f64> {
        let space = &self.problem.space;
        let mut p = space.base.clone();
        for ((k, c, _), &j) in self.dims.iter().zip(at) {
            let u = &space.unknowns[*k];
            let (lo, hi) = interval(c, u.min, u.max, j);
            p[u.slot] = 0.5 * (lo + hi);
        }
        for (&k, &z) in self.conts.iter().zip(vals) {
            let u = &space.unknowns[k];
            p[u.slot] = u.from_internal(z);
        }
        p
    }

    /// The inner problem at parameters `p` on `system`: the linear unknowns to solve for.
    fn spec<'s>(&'s self, system: &'s exact::System, p: Vec<f64>) -> Spec<'s> {
        Spec {
            problem: self.problem,
            system,
            p,
            linear: self.split.linear.clone(),
            weighting: self.weighting,
        }
    }

    /// The inner least-squares minimum at a point (the generic assembly), or with Provot
    /// limits the problem's own cost after the inner solve ([`provot_rows::solve`]).
    fn score(&self, (at, vals): &Point) -> f64 {
        let problem = self.problem;
        let p = self.params_at(at, vals);
        if self.provot {
            let mut r = ExactReport::default();
            return match provot_rows::solve(problem, &self.cols, p, &self.split, &mut r) {
                Ok((_, cost)) if cost.is_finite() => cost,
                _ => f64::INFINITY,
            };
        }
        let system = exact::assemble(&problem.objective, &problem.scene, &self.cols, &p);
        match exact::solve(&self.spec(&system, p)) {
            Ok(o) if o.residual.is_finite() => o.residual,
            _ => f64::INFINITY,
        }
    }

    /// [`Self::score`] on the cached typed design.
    fn score_design(&self, d: &mut Design, (at, vals): &Point) -> f64 {
        let problem = self.problem;
        let p = self.params_at(at, vals);
        d.update(&problem.objective, &problem.scene, &p);
        let system = d.system();
        match exact::solve(&self.spec(&system, p)) {
            Ok(o) => d.residual(&problem.scene, &o.params, self.weighting),
            _ => f64::INFINITY,
        }
    }

    /// Ranges only, masses known, no Provot limit: coordinate descent by range sweeps.
    fn by_sweeps(&self) -> Result<Solution, String> {
        let problem = self.problem;
        let dims = &self.dims;
        let mut sweeper = Sweeper::new(
            problem,
            &self.cols,
            &self.split.linear,
            dims.iter().map(|(k, c, _)| (*k, c.clone())).collect(),
        )?;
        let mut at = self.start_intervals();
        let mut best = sweeper.exact(&at);
        let mut bounds = Vec::new();
        // A dim swept with every other interval as now would give the same answer.
        let mut swept_at: Vec<Option<Vec<usize>>> = vec![None; dims.len()];
        let mut capped = true;
        for _ in 0..MAX_CYCLES {
            let before = at.clone();
            for d in 0..dims.len() {
                if swept_at[d].as_ref() == Some(&at) {
                    continue;
                }
                let (j, v, p) = sweeper.search(d, &at, best, &mut bounds);
                at[d] = j;
                best = (v, p);
                swept_at[d] = Some(at.clone());
            }
            if at == before {
                capped = false;
                break;
            }
        }
        let evals = sweeper.exact_solves + sweeper.sweeps;
        problem.set_evals(problem.evals() + evals);
        let note = format!(
            "variable projection by range sweeps: {} intervals bounded in {} incremental sweeps, \
             {} exact inner least-squares solves{} over {} ranges",
            sweeper.scored,
            sweeper.sweeps,
            sweeper.exact_solves,
            if sweeper.capped > 0 {
                format!(
                    " ({} sweeps stopped at {MAX_EXACT_PER_SWEEP} exact solves)",
                    sweeper.capped
                )
            } else {
                String::new()
            },
            dims.len()
        );
        let system = sweeper.system_at(&at);
        let solution = self.finish(&at, &[], note, Some(system));
        solution.map(|s| at_cap(s, capped))
    }

    /// Coordinate descent: a coarse-to-fine grid over each interval unknown, a profile search
    /// over each continuous one.
    fn by_grid(&self) -> Result<Solution, String> {
        let problem = self.problem;
        // With continuous unknowns, the cached typed design when every column has one: the
        // same inner solve at a fraction of the cost (see `crate::exact::design`); serial, it
        // is ~15 µs.
        let design = if self.conts.is_empty() || self.provot {
            None
        } else {
            Design::new(&problem.objective, &problem.scene, &self.cols)
        };
        let mut scores = Scores {
            outer: self,
            design,
            cache: HashMap::new(),
            evals: 0,
        };
        let mut at = self.start_intervals();
        let mut vals = self.start_values();
        let capped = self.descend(&mut at, &mut vals, &mut scores);
        let evals = scores.evals;
        problem.set_evals(problem.evals() + evals);
        let note = format!(
            "variable projection: {evals} inner least-squares solves over {} nonlinear unknowns",
            self.dims.len() + self.conts.len()
        );
        // The answer from an orthogonal factor of the rows (not the normal equations): the
        // design's own rows when it has them, else (in `finish`) the generic assembly.
        let system = scores.design.as_mut().map(|d| {
            d.update(
                &problem.objective,
                &problem.scene,
                &self.params_at(&at, &vals),
            );
            d.qr_system()
        });
        let conts: Vec<(usize, f64)> = self.conts.iter().copied().zip(vals).collect();
        self.finish(&at, &conts, note, system)
            .map(|s| at_cap(s, capped))
    }

    /// The descent of [`Self::by_grid`] from `at`, `vals`; true when it was still moving at
    /// its [`MAX_CYCLES`] cap.
    ///
    /// It stops when an interval search at settled continuous values moves nothing: a
    /// full-box profile search depends only on the other unknowns, so one pass settles one
    /// continuous unknown (several must also stand still through a pass). A repeated profile
    /// search at unchanged intervals finds its grid in the cache: only Brent's steps cost.
    fn descend(&self, at: &mut Vec<usize>, vals: &mut Vec<f64>, scores: &mut Scores) -> bool {
        let space = &self.problem.space;
        let mut settled = self.conts.is_empty();
        for _ in 0..MAX_CYCLES {
            let before = at.clone();
            for d in 0..self.dims.len() {
                let n = self.dims[d].1.len() + 1;
                let base = at.clone();
                at[d] = search(n, |js| {
                    let points = js
                        .iter()
                        .map(|&j| {
                            let mut a = base.clone();
                            a[d] = j;
                            (a, vals.clone())
                        })
                        .collect();
                    scores.batch(points)
                });
            }
            if *at == before && settled {
                return false;
            }
            let vals_before = vals.clone();
            for c in 0..self.conts.len() {
                let u = &space.unknowns[self.conts[c]];
                let (lo, hi) = u.internal_bounds();
                let base = vals.clone();
                vals[c] = profile::minimize(lo, hi, profile::TOL, |zs| {
                    let points = zs
                        .iter()
                        .map(|&z| {
                            let mut v = base.clone();
                            v[c] = z;
                            (at.clone(), v)
                        })
                        .collect();
                    scores.batch(points)
                })
                .0;
            }
            settled = self.conts.len() <= 1 || *vals == vals_before;
        }
        true
    }

    /// The answer at the chosen intervals `at` and values of the continuous unknowns `conts`
    /// ((unknown, internal coordinate)): the intervals' middles, the linear unknowns solved
    /// there (on `system`, the short cost's system at that point, when the caller has it).
    fn finish(
        &self,
        at: &[usize],
        conts: &[(usize, f64)],
        note: String,
        system: Option<exact::System>,
    ) -> Result<Solution, String> {
        let problem = self.problem;
        let space = &problem.space;
        let mut report = ExactReport::default();
        report.notes.push(note);
        for ((k, c, thinned), &j) in self.dims.iter().zip(at) {
            let u = &space.unknowns[*k];
            let (lo, hi) = interval(c, u.min, u.max, j);
            report.notes.push(format!(
                "{}: every value in ({lo:.9e}, {hi:.9e}) fits the data equally ({} observed \
                 values in the box{}); reported the middle",
                u.name,
                c.len(),
                if *thinned { ", evenly subsampled" } else { "" }
            ));
        }
        for &(k, z) in conts {
            let u = &space.unknowns[k];
            report.notes.push(format!(
                "{}: least profile cost at {:.12e} (1-D search over the box: {} grid points, \
                 then Brent)",
                u.name,
                u.from_internal(z),
                profile::GRID
            ));
        }
        let mut p = self.params_at(at, &[]);
        for &(k, z) in conts {
            let u = &space.unknowns[k];
            p[u.slot] = u.from_internal(z);
        }
        let (genome, cost) = if self.provot {
            provot_rows::solve(problem, &self.cols, p, &self.split, &mut report)?
        } else {
            let system = system.unwrap_or_else(|| {
                exact::assemble(&problem.objective, &problem.scene, &self.cols, &p)
            });
            exact::solve_linear(problem, &system, p, &self.split, &mut report)?
        };
        Ok(Solution {
            genome,
            cost,
            report,
        })
    }
}

/// The grid descent's scores: each point solved once (cached by its bits), on the typed
/// design when there is one (serial), else the points of a batch in parallel.
struct Scores<'o, 'a> {
    outer: &'o Outer<'a>,
    design: Option<Design>,
    cache: HashMap<(Vec<usize>, Vec<u64>), f64>,
    /// Inner solves run (cache misses).
    evals: u64,
}

impl Scores<'_, '_> {
    fn key((a, v): &Point) -> (Vec<usize>, Vec<u64>) {
        (a.clone(), v.iter().map(|x| x.to_bits()).collect())
    }

    fn batch(&mut self, points: Vec<Point>) -> Vec<f64> {
        let todo: Vec<&Point> = points
            .iter()
            .filter(|a| !self.cache.contains_key(&Self::key(a)))
            .collect();
        self.evals += todo.len() as u64;
        let outer = self.outer;
        let scores: Vec<f64> = match &mut self.design {
            Some(d) => todo.iter().map(|a| outer.score_design(d, a)).collect(),
            None if todo.len() > 1 => todo.par_iter().map(|a| outer.score(a)).collect(),
            None => todo.iter().map(|a| outer.score(a)).collect(),
        };
        for (a, v) in todo.into_iter().zip(scores) {
            self.cache.insert(Self::key(a), v);
        }
        points.iter().map(|a| self.cache[&Self::key(a)]).collect()
    }
}

/// The solution, marked unconverged when the coordinate descent was still moving at its
/// [`MAX_CYCLES`] cap: its answer is then not a point where no coordinate can improve.
fn at_cap(mut s: Solution, capped: bool) -> Solution {
    if capped {
        s.report.unconverged = Some(format!(
            "hybrid: the coordinate descent over the nonlinear unknowns was still moving after \
             its {MAX_CYCLES}-cycle cap (the answer may not be the best interval)"
        ));
    }
    s
}

/// The `hybrid` strategy: everything happens in generation 0.
pub fn strategy() -> OneShot {
    OneShot::new("hybrid", solve)
}

#[cfg(test)]
mod tests {
    use cordis_core::Scene;

    use super::*;
    use crate::cost::CostKind;
    use crate::identify::with_unknown_boxes;

    /// Eight particles held by anchors, one conditional type (K, l0, range unknown).
    fn gas() -> Scene {
        let pts: Vec<[f64; 3]> = (0..8)
            .map(|n| {
                let a = n as f64;
                [
                    0.4 * (2.0 * a).cos(),
                    0.4 * (3.0 * a).sin(),
                    0.3 * (a).sin(),
                ]
            })
            .collect();
        crate::strategies::test_scenes::anchored_gas(&pts, false)
    }

    /// The range sweeps pick the same interval as the coarse-to-fine grid of exact solves
    /// (the grid scores every interval of the final bracket exactly) and end at the same
    /// cost, with fewer exact inner solves.
    #[test]
    fn range_sweeps_pick_the_grids_interval() {
        let truth = gas();
        let unknown = with_unknown_boxes(&truth, 25.0, 5);
        let traj = truth.simulate(200).unwrap();
        let problem = Problem::new(&unknown, &traj, CostKind::Short).unwrap();
        let grid = solve_with(&problem, false).unwrap();
        let grid_evals = problem.evals();
        let sweep = solve_with(&problem, true).unwrap();
        let sweep_evals = problem.evals() - grid_evals;
        let interval = |s: &Solution| s.report.notes[1].clone();
        assert!(interval(&grid).contains("types.pair.range: every value in ("));
        assert_eq!(interval(&grid), interval(&sweep));
        assert_eq!(grid.genome.len(), sweep.genome.len());
        // Equal, or both the rounding of an exact fit (rmse below 1e-10 m).
        let floor = 1e-20 * problem.objective.terms() as f64;
        assert!(
            (grid.cost - sweep.cost).abs() <= 1e-9 * grid.cost || grid.cost.max(sweep.cost) < floor,
            "grid {} sweep {}",
            grid.cost,
            sweep.cost
        );
        assert!(sweep.report.notes[0].contains("range sweeps"));
        assert!(
            sweep_evals < grid_evals,
            "{sweep_evals} against {grid_evals}"
        );
    }
}
