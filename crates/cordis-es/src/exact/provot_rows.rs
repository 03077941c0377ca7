//! The exact solvers on scenes with Provot's elongation limit: the short cost's rows the limit
//! did not act on, found by iteration, and solved exactly.
//!
//! Provot's pass ([`cordis_core::forces::provot`]) moves the predicted positions of the ends of
//! over-stretched springs after the force step; every **other** row of the short cost (particle
//! i, frame t) is still `x̂_i(t) - x_i(t)` with `x̂` one unconstrained step from the observed
//! frames t-1 and t-2, affine in θ. Which rows the pass touches depends on the unknown rest
//! lengths (the limit is `(1 + τ) l0`), so the set is found by iteration on a **mask** of
//! dropped rows:
//!
//! 1. start from every row but those the observation alone points at (`at_limit`: springs
//!    that sit at their type's longest observed length at several frames; without it a rod
//!    always at its limit, in a wide box, is silently fitted as a stiff spring);
//! 2. solve the weighted linear least squares on the other rows ([`crate::exact`]);
//! 3. with that estimate, predict every frame from the observed frames before it and run the
//!    Provot pass on the prediction with every limit shortened by [`MARGIN`], marking each
//!    particle it moves (cascades included): those rows are where the limit may have acted;
//! 4. add them to the mask (the mask only grows, so the iteration ends) and repeat from 2
//!    until the marked rows are all in the mask.
//!
//! The first solve (on nearly every row) is biased by the rows the limit acted on; on the
//! shipped cloth its estimate (≈5 % off) already marks a superset of them, and the second
//! solve is exact. That is not guaranteed in general: a biased estimate that predicts no
//! exceedance where the limit did act would stop the iteration early. The kept rows' rms
//! residual is the check: at rounding on noiseless data (~1e-18 m on the cloth), at the
//! noise otherwise; well above it, the model did not fit the kept rows.
//!
//! At the end the rows the final estimate marks are inside the dropped set by construction,
//! and the report gives the dropped rows, the iterations and the kept rows' rms residual (at
//! the noise level when the model fits). A type whose springs are always at their limit leaves
//! its parameters without rows: they come out **undetermined** (the solvers' rank handling),
//! not silently wrong. The rows the limit acted on carry information too (the limit length
//! gives `l0` once τ is known); this solver does not use it.

use cordis_core::world::{Clock, OneClock};
use cordis_core::Vec3;

use crate::cost::Objective;
use crate::exact::row_mask::RowMask;
use crate::exact::{self, Col, Split};
use crate::problem::Problem;
use crate::report::ExactReport;
pub use crate::report::ProvotRows;

/// Relative shortening of every limit when marking the rows an estimate's Provot pass acts on:
/// the rows whose prediction comes within 0.1 % of the limit are dropped too, so that the
/// estimate's error (and the data's noise) cannot hide a row the limit acted on.
pub const MARGIN: f64 = 1e-3;

/// Relative tolerance of "at the type's longest observed length" for the first mask (rounding
/// of positions of order 1 m, with room for the trajectory's own rounding).
pub const AT_LIMIT: f64 = 1e-12;

/// Most solve–mark rounds (each only grows the mask; the cloth settles in a few).
pub const MAX_ITERATIONS: usize = 50;

/// Whether the objective's scene has a Provot limit on some link.
pub(crate) fn applies(obj: &Objective) -> bool {
    !obj.plan().provot.links.is_empty()
}

/// The first mask, from the observation alone: the rows of the free ends of limited springs
/// observed at their type's longest length (to [`AT_LIMIT`]), when that length is reached at
/// two frames or more. An unconstrained spring's length varies continuously and does not come
/// back to the same maximum; after Provot's pass a corrected spring sits at its limit exactly
/// (unless a later correction in the same pass moved an end). This catches what the iteration
/// alone cannot: a spring always at its limit, whose rows a stiff spring would also fit.
fn at_limit(obj: &Objective) -> RowMask {
    let plan = obj.plan();
    let (frames, n) = (obj.obs.frames, plan.n);
    let links: Vec<_> = plan
        .provot
        .links
        .iter()
        .filter(|l| plan.free[l.i as usize] || plan.free[l.j as usize])
        .collect();
    let len = |t: usize, i: u32, j: u32| {
        let x = obj.obs.frame(t);
        (x[j as usize] - x[i as usize]).norm()
    };
    let mut mask = RowMask::new(frames, n);
    let mut params: Vec<usize> = links.iter().map(|l| l.param).collect();
    params.sort_unstable();
    params.dedup();
    for param in params {
        let of_type = || links.iter().filter(move |l| l.param == param);
        let longest = of_type()
            .flat_map(|l| (2..frames).map(|t| len(t, l.i, l.j)))
            .fold(0.0, f64::max);
        let at = |t: usize, l: &&&cordis_core::forces::provot::ProvotLink| {
            len(t, l.i, l.j) >= (1.0 - AT_LIMIT) * longest
        };
        let at_frames = (2..frames)
            .filter(|&t| of_type().any(|l| at(t, &l)))
            .count();
        if at_frames < 2 || longest == 0.0 {
            continue;
        }
        for l in of_type() {
            for t in (2..frames).filter(|&t| at(t, &l)) {
                for e in [l.i as usize, l.j as usize] {
                    if plan.free[e] {
                        mask.set(t, e);
                    }
                }
            }
        }
    }
    mask
}

/// Step 3 of the module docs at the parameters `p`: the rows the Provot pass (limits
/// shortened by `margin`) moves, and the sum of squares and count of the unconstrained
/// residuals of the rows `dropped` keeps.
fn marked(obj: &Objective, p: &[f64], margin: f64, dropped: &RowMask) -> (RowMask, f64, usize) {
    let plan = obj.plan();
    let (frames, n) = (obj.obs.frames, plan.n);
    let (m, g) = obj.masses_gravity(p);
    let clock = OneClock::new(plan.dt, g);
    let geo = obj.geometry();
    let mut s = obj.scratch();
    let mut xhat = vec![Vec3::zeros(); n];
    let mut mask = RowMask::new(frames, n);
    let (mut sum, mut count) = (0.0, 0);
    for t in 2..frames {
        obj.observed_forces(p, t - 1, &mut s, geo);
        let (x1, x2, x0) = (obj.obs.frame(t - 1), obj.obs.frame(t - 2), obj.obs.frame(t));
        let f = &s.core.f;
        for i in 0..n {
            xhat[i] = if plan.free[i] {
                (x1[i] * 2.0 - x2[i]) + clock.kick(i, f[i] / m[i])
            } else {
                x0[i]
            };
        }
        for &i in &obj.free {
            if !dropped.get(t, i) {
                sum += (xhat[i] - x0[i]).norm_squared();
                count += 1;
            }
        }
        plan.provot
            .apply_with(p, &mut xhat, &plan.free, 1.0 - margin, |i| mask.set(t, i));
    }
    (mask, sum, count)
}

/// The exact solve of a scene with Provot limits (the module docs): the linear unknowns of
/// `split` at the nonlinear values in `p`, on the rows the limit did not act on. Returns the
/// genome and the problem's own cost (limit included), and fills `report`.
pub(crate) fn solve(
    problem: &Problem,
    cols: &[Col],
    p: Vec<f64>,
    split: &Split,
    report: &mut ExactReport,
) -> Result<(Vec<f64>, f64), String> {
    let obj = &problem.objective;
    let rows = obj.free.len() * obj.obs.frames.saturating_sub(2);
    let mut mask = at_limit(obj);
    let at_start = mask.count();
    let mut params = p.clone();
    let mut iteration = 0;
    loop {
        iteration += 1;
        let system = exact::assemble_masked(obj, &problem.scene, cols, &p, Some(&mask));
        let mut round = ExactReport::default();
        let (genome, cost) = exact::solve_linear(problem, &system, p.clone(), split, &mut round)?;
        problem.space.fill_params(&genome, &mut params);
        let (new, sum, count) = marked(obj, &params, MARGIN, &mask);
        let grew = mask.absorb(&new);
        if !grew || iteration == MAX_ITERATIONS {
            let stats = ProvotRows {
                dropped: mask.count(),
                rows,
                iterations: iteration,
                consistent: !grew,
                kept_rmse: if count > 0 {
                    (sum / (3 * count) as f64).sqrt()
                } else {
                    0.0
                },
            };
            round.notes.push(format!(
                "Provot limit: {} of {} rows ({:.1} %) dropped where the limit may act ({at_start} \
                 observed at their type's longest length, the others predicted within {} of \
                 it); {} solve(s); kept rows' rms residual {:.3e} m",
                stats.dropped,
                stats.rows,
                100.0 * stats.dropped as f64 / rows.max(1) as f64,
                MARGIN,
                stats.iterations,
                stats.kept_rmse,
            ));
            if !round.undetermined.is_empty() {
                round.notes.push(format!(
                    "{}: not determined by the rows the Provot limit leaves (a type always at \
                     its limit has no rows of its own)",
                    round.undetermined.join(", ")
                ));
            }
            round.provot = Some(stats);
            let mut notes = std::mem::take(&mut report.notes);
            notes.append(&mut round.notes);
            *report = ExactReport { notes, ..round };
            return Ok((genome, cost));
        }
    }
}
