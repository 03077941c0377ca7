//! What a cost precomputes from the observed trajectory once: positions as vectors, velocities,
//! and the active pairs of conditional links whose range is known.

use crate::error::CostError;
use cordis_core::forces::grid::Grid;
use cordis_core::{Param, Plan, Scene, Trajectory, Vec3};

/// Pairs `(i, j)` of one conditional pass closer than its range, per observed frame, in the
/// order the pass's grid visits them (so forces sum in the same order as a simulator step).
#[derive(Clone, Debug)]
pub(crate) struct ObservedPairs {
    /// The range (m) the pairs were found with; a parameter vector with another range falls
    /// back to the grid.
    pub range: f64,
    /// `pairs[start[t]..start[t + 1]]` are the pairs active at frame t.
    pub start: Vec<usize>,
    pub pairs: Vec<[u32; 2]>,
}

impl ObservedPairs {
    pub fn at(&self, t: usize) -> &[[u32; 2]] {
        &self.pairs[self.start[t]..self.start[t + 1]]
    }
}

#[derive(Clone, Debug)]
pub(crate) struct Observed {
    pub frames: usize,
    pub n: usize,
    /// Positions x(t), frame-major (`xs[t * n + i]`), m.
    pub xs: Vec<Vec3>,
    /// Velocities v(t) = (x(t) - x(t-1)) / dt, frame-major, m/s; frame 0 is zero (never read).
    pub vs: Vec<Vec3>,
    /// One entry per conditional pass of the plan: `Some` when its range is known.
    pub pairs: Vec<Option<ObservedPairs>>,
}

impl Observed {
    /// Checks that `traj` fits `scene` (particles, at least `min_frames` frames — 3 for the
    /// costs that predict motion, 1 for the static cost — same dt when the trajectory states
    /// one) and precomputes.
    pub fn new(
        scene: &Scene,
        plan: &Plan,
        traj: &Trajectory,
        min_frames: usize,
    ) -> Result<Self, CostError> {
        let (frames, n) = (traj.frames(), traj.particles());
        if n != plan.n {
            return Err(CostError::mismatch(
                "trajectory",
                format!("has {n} particles, the scene has {}", plan.n),
            ));
        }
        if frames < min_frames {
            return Err(CostError::mismatch(
                "trajectory",
                format!("has {frames} frames, the cost needs at least {min_frames}"),
            ));
        }
        if let Some(dt) = traj.dt {
            if (dt - plan.dt).abs() > 1e-9 * plan.dt {
                return Err(CostError::mismatch(
                    "trajectory.dt",
                    format!("is {dt} s, the scene's dt is {} s", plan.dt),
                ));
            }
        }
        let mut xs = vec![Vec3::zeros(); frames * n];
        for (t, frame) in xs.chunks_exact_mut(n.max(1)).enumerate().take(frames) {
            traj.frame_into(t, frame);
        }
        let mut vs = vec![Vec3::zeros(); frames * n];
        for t in 1..frames {
            for i in 0..n {
                // The same expression as `Plan::velocities`, so that the bits agree.
                // (each particle's world dt)
                vs[t * n + i] = (xs[t * n + i] - xs[(t - 1) * n + i]) / plan.dt_of(i);
            }
        }
        let layout = &plan.layout;
        let mut pairs = Vec::with_capacity(plan.conditionals.len());
        for c in &plan.conditionals {
            let ty = layout.type_offsets.iter().position(|&o| o == c.param);
            let known = ty.and_then(|t| match scene.types[t].param("range") {
                Some(Param::Known(r)) => Some(*r),
                _ => None,
            });
            pairs.push(known.map(|range| {
                let mut p = scene.param_values();
                p[c.param + 3] = range;
                let mut grid = Grid::default();
                let mut start = vec![0];
                let mut list = Vec::new();
                for t in 0..frames {
                    c.for_each_active_pair(&p, &xs[t * n..(t + 1) * n], &mut grid, |i, j, _| {
                        list.push([i as u32, j as u32]);
                    });
                    start.push(list.len());
                }
                ObservedPairs {
                    range,
                    start,
                    pairs: list,
                }
            }));
        }
        Ok(Observed {
            frames,
            n,
            xs,
            vs,
            pairs,
        })
    }

    pub fn frame(&self, t: usize) -> &[Vec3] {
        &self.xs[t * self.n..(t + 1) * self.n]
    }

    pub fn velocity(&self, t: usize) -> &[Vec3] {
        &self.vs[t * self.n..(t + 1) * self.n]
    }
}
