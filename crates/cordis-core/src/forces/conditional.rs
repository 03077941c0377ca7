//! `conditional`: a spring between every pair of particles of one or two groups while they
//! are closer than `range` (fluids, thesis §4.3). Pairs come from a uniform grid, so a step
//! costs O(N) plus the active pairs, never O(N²).

use super::grid::Grid;
use super::spring::{spring_force, spring_force_quadratic};
use crate::Vec3;

#[derive(Clone, Debug, Default)]
pub struct ConditionalPass {
    /// Offset of the type's parameters: K, l0, Z, range.
    pub param: usize,
    /// Slot of the type's quadratic viscosity Z₂ (N·s²/m²), when it has one: each pair's
    /// force gains `Z₂ s |s|` along it, as a spring's ([`super::spring`]).
    pub quadratic: Option<usize>,
    /// Members of the first group.
    pub a: Vec<u32>,
    /// Members of the second group, or `None` for pairs within `a`.
    pub b: Option<Vec<u32>>,
}

impl ConditionalPass {
    pub fn range(&self, p: &[f64]) -> f64 {
        p[self.param + 3]
    }

    /// Calls `visit(i, j, d)` with `d = x_j - x_i` for every pair closer than the range.
    /// `grid` is scratch owned by the caller (one per pass and thread).
    pub fn for_each_active_pair(
        &self,
        p: &[f64],
        x: &[Vec3],
        grid: &mut Grid,
        visit: impl FnMut(usize, usize, Vec3),
    ) {
        if self.prepare(p, x, grid) {
            self.for_each_active_pair_in(p, x, grid, Part::WHOLE, visit);
        }
    }

    /// Sorts the members into `grid`; false when there is nothing to pair (no valid range,
    /// or a non-finite position).
    pub fn prepare(&self, p: &[f64], x: &[Vec3], grid: &mut Grid) -> bool {
        let range = self.range(p);
        if !(range > 0.0 && range.is_finite()) {
            return false;
        }
        grid.build(x, self.b.as_deref().unwrap_or(&self.a), range)
    }

    /// The active pairs of one part of the work, on a grid made by [`ConditionalPass::prepare`]:
    /// the parts of a split are disjoint and together give every pair once.
    pub fn for_each_active_pair_in(
        &self,
        p: &[f64],
        x: &[Vec3],
        grid: &Grid,
        part: Part,
        mut visit: impl FnMut(usize, usize, Vec3),
    ) {
        let range = self.range(p);
        // Compare squared lengths, except where range² leaves the normal floats (range below
        // ~1e-154 m or above ~1e154 m): there it underflows to 0 or overflows, and
        // `|d|² < range²` would no longer mean `|d| < range` (SPEC §2.2).
        let r2 = range * range;
        let squared = r2.is_normal();
        let near = |d: &Vec3| {
            if squared {
                d.norm_squared() < r2
            } else {
                d.norm() < range
            }
        };
        match &self.b {
            None => {
                grid.for_each_candidate_pair_in(part.of(grid.num_cells()), |i, j| {
                    let (i, j) = (i as usize, j as usize);
                    let d = x[j] - x[i];
                    if near(&d) {
                        visit(i, j, d);
                    }
                });
            }
            Some(_) => {
                for &i in &self.a[part.of(self.a.len())] {
                    let i = i as usize;
                    grid.for_each_near(&x[i], |j| {
                        let j = j as usize;
                        let d = x[j] - x[i];
                        if near(&d) {
                            visit(i, j, d);
                        }
                    });
                }
            }
        }
    }

    /// Adds the spring forces of the active pairs.
    pub fn accumulate(&self, p: &[f64], x: &[Vec3], v: &[Vec3], f: &mut [Vec3], grid: &mut Grid) {
        if self.prepare(p, x, grid) {
            self.accumulate_part(p, x, v, f, grid, Part::WHOLE);
        }
    }

    /// Adds the spring forces of one part's active pairs (grid already prepared).
    pub fn accumulate_part(
        &self,
        p: &[f64],
        x: &[Vec3],
        v: &[Vec3],
        f: &mut [Vec3],
        grid: &Grid,
        part: Part,
    ) {
        let (k, l0, z) = (p[self.param], p[self.param + 1], p[self.param + 2]);
        let z2 = self.quadratic.map_or(0.0, |s| p[s]);
        if z2 != 0.0 {
            self.for_each_active_pair_in(p, x, grid, part, |i, j, _| {
                let fi = spring_force_quadratic((&x[i], &x[j]), (&v[i], &v[j]), [k, l0, z, z2]);
                f[i] += fi;
                f[j] -= fi;
            });
        } else if z == 0.0 {
            self.for_each_active_pair_in(p, x, grid, part, |i, j, _| {
                let fi = spring_force::<false>(&x[i], &x[j], &v[i], &v[j], k, l0, 0.0);
                f[i] += fi;
                f[j] -= fi;
            });
        } else {
            self.for_each_active_pair_in(p, x, grid, part, |i, j, _| {
                let fi = spring_force::<true>(&x[i], &x[j], &v[i], &v[j], k, l0, z);
                f[i] += fi;
                f[j] -= fi;
            });
        }
    }
}

/// Part `index` of `count` equal shares of some work (cells, members).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Part {
    pub index: usize,
    pub count: usize,
}

impl Part {
    pub const WHOLE: Part = Part { index: 0, count: 1 };

    /// This part's share of `0..n`.
    pub fn of(self, n: usize) -> std::ops::Range<usize> {
        (n * self.index / self.count)..(n * (self.index + 1) / self.count)
    }
}
