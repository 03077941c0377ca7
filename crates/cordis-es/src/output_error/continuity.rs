//! Continuity of multiple shooting's segments ([`super::shooting`]): the defects between a
//! segment's end and the next segment's initial state, and their rows in the Gauss–Newton
//! system the fit assembles ([`super::fit::Fitter::normal`]).
//!
//! The CORDIS step's state is `(x(n), x(n-1))`; a segment's state is `[x0, v0]` with
//! `x(-1) = x0 - v0 dt`. Segment k ending at frame b continues into segment k+1 when
//! `x_k(b) = x0_(k+1)` and `x_k(b-1) = x0_(k+1) - v0_(k+1) dt`: the two defects, each weighted
//! by [`Continuity::weight`], with the rows `∂x_k/∂(θ, s_k)` of segment k's own tangent rollout
//! and `-1` (and `dt` on v0) on segment k+1's state.

use cordis_core::Vec3;
use nalgebra::{DMatrix, DVector};

use super::observations::Take;

/// Where the fit's variables are: θ first, then one state per segment.
pub(crate) struct Layout<'a> {
    /// Free particles in scene order (their index in the rollout's positions).
    pub free: &'a [usize],
    /// θ's length, one state's length (`6 × free`), and a rollout's sensitivity columns.
    pub theta: usize,
    pub state: usize,
    pub width: usize,
}

/// The continuity of segments: which segment each one's end state continues into, and the
/// weight of a defect.
#[derive(Clone, Debug)]
pub(crate) struct Continuity {
    /// `next[k]`: the segment (a take of the fitter) whose initial state segment k's end must
    /// equal; `None` for a take's last segment.
    pub next: Vec<Option<usize>>,
    /// `√ρ w̄`: multiplies each defect (m) into a residual of the observations' scale.
    pub weight: f64,
    /// Per free particle, a factor on `weight` (empty: all 1).
    pub factor: Vec<f64>,
    /// Time step, s.
    pub dt: f64,
}

/// The end of one segment's rollout: its last two frames' positions and, with sensitivities,
/// their rows (`3N × width`, row-major); caller-owned, reused from segment to segment.
#[derive(Default)]
pub(crate) struct SegmentEnd {
    pub x_before: Vec<Vec3>,
    pub x_last: Vec<Vec3>,
    pub s_before: Vec<f64>,
    pub s_last: Vec<f64>,
    /// One continuity row being assembled (scratch of [`Continuity::accumulate`]).
    row: Vec<(usize, f64)>,
}

impl SegmentEnd {
    /// Records frame `t` of a rollout of `frames` frames when it is one of the last two.
    pub fn record(&mut self, t: usize, frames: usize, x: &[Vec3], s: Option<&[f64]>) {
        let (xs, ss) = match frames - t {
            2 => (&mut self.x_before, &mut self.s_before),
            1 => (&mut self.x_last, &mut self.s_last),
            _ => return,
        };
        xs.clear();
        xs.extend_from_slice(x);
        if let Some(s) = s {
            ss.clear();
            ss.extend_from_slice(s);
        }
    }
}

impl Continuity {
    /// The segment take `k`'s end is tied to (`None`: a take's last segment, or the window
    /// does not reach the segment's end).
    pub fn tied(&self, k: usize, window: usize, take: &Take) -> Option<usize> {
        self.next
            .get(k)
            .copied()
            .flatten()
            .filter(|_| window >= take.frames() && take.frames() >= 2)
    }

    /// The weight of free particle `f`'s defects.
    fn weight_of(&self, f: usize) -> f64 {
        self.weight * self.factor.get(f).copied().unwrap_or(1.0)
    }

    /// The weighted defects of a segment's end against the next segment's `state` (free
    /// particles `free`, `[x0, v0]` each):
    /// `(particle f, coordinate c, position defect, previous-position defect)`.
    fn defects<'e>(
        &'e self,
        free: &'e [usize],
        state: &'e [f64],
        end: &'e SegmentEnd,
    ) -> impl Iterator<Item = (usize, usize, f64, f64)> + 'e {
        free.iter().enumerate().flat_map(move |(f, &i)| {
            (0..3).map(move |c| {
                let (x0, v0) = (state[6 * f + c], state[6 * f + 3 + c]);
                let d_last = end.x_last[i][c] - x0;
                let d_before = end.x_before[i][c] - (x0 - v0 * self.dt);
                let w = self.weight_of(f);
                (f, c, w * d_last, w * d_before)
            })
        })
    }

    /// `w² Σ defects²` of a segment ended as `end` against the next one's `state`.
    pub fn cost(&self, free: &[usize], state: &[f64], end: &SegmentEnd) -> f64 {
        self.defects(free, state, end)
            .map(|(_, _, a, b)| a * a + b * b)
            .sum()
    }

    /// Adds segment `k`'s continuity rows against segment `j` (whose state is `q`'s) to the
    /// Gauss–Newton system (`h`, `g` in the fit's variables laid out as `at` says; `chain` the
    /// θ columns' `dp/dz`); returns their cost.
    pub fn accumulate(
        &self,
        at: &Layout<'_>,
        (k, j): (usize, usize),
        (q, end): (&[f64], &mut SegmentEnd),
        chain: &[f64],
        h: &mut DMatrix<f64>,
        g: &mut DVector<f64>,
    ) -> f64 {
        let (nt, ns, width) = (at.theta, at.state, at.width);
        let global = |a: usize| if a < nt { a } else { nt + k * ns + (a - nt) };
        let next = nt + j * ns;
        let mut cost = 0.0;
        // One row: the segment's local columns, then the next state's x0 (and v0) entries.
        let mut row = std::mem::take(&mut end.row);
        let ended: &SegmentEnd = end;
        let state = &q[next..][..ns];
        for (f, c, d_last, d_before) in self.defects(at.free, state, ended) {
            let i = at.free[f];
            let w = self.weight_of(f);
            for (rows, d, v0) in [
                (&ended.s_last, d_last, 0.0),
                (&ended.s_before, d_before, self.dt),
            ] {
                row.clear();
                let src = &rows[(3 * i + c) * width..][..width];
                for (a, &s) in src.iter().enumerate() {
                    let dz = if a < nt { chain[a] } else { 1.0 };
                    row.push((global(a), w * s * dz));
                }
                row.push((next + 6 * f + c, -w));
                if v0 != 0.0 {
                    row.push((next + 6 * f + 3 + c, w * v0));
                }
                cost += d * d;
                for &(a, ra) in &row {
                    g[a] += ra * d;
                }
                // Down each column of the column-major `h` (the same sums in the same order
                // as row by row, which strode across columns: 42 % of a shooting fit with
                // 360 variables, under perf).
                for &(b, rb) in &row {
                    let mut column = h.column_mut(b);
                    for &(a, ra) in &row {
                        column[a] += ra * rb;
                    }
                }
            }
        }
        end.row = row;
        cost
    }
}
