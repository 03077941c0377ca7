//! Uniform cell grid for finding all pairs closer than a range in O(N) per step.
//!
//! Cells are at least `range` wide, so a pair within range lies in the same or an adjacent
//! cell. The grid covers the bounding box of its members; when the box is sparse the cells
//! grow so the grid never holds more than a few cells per member (memory stays O(N) however
//! far particles fly). Built by counting sort: no allocation once the buffers have grown.

use crate::Vec3;

#[derive(Clone, Debug, Default)]
pub struct Grid {
    origin: Vec3,
    inv_cell: f64,
    dims: [usize; 3],
    /// `cell_start[c]..cell_start[c + 1]` indexes `sorted` for cell c.
    cell_start: Vec<u32>,
    sorted: Vec<u32>,
    cell_of: Vec<u32>,
    cursor: Vec<u32>,
}

impl Grid {
    /// Sorts `members` (particle indices) into cells of width ≥ `range`. Returns false when the
    /// members' bounding box is not finite (an infinite coordinate: the step is diverging; no
    /// pairs are reported). A NaN coordinate is ignored by the box and lands in a border cell,
    /// where no distance test can pass.
    pub fn build(&mut self, x: &[Vec3], members: &[u32], range: f64) -> bool {
        self.sorted.clear();
        self.cell_start.clear();
        self.cell_of.clear();
        if members.is_empty() {
            self.dims = [0; 3];
            return true;
        }
        let mut lo = Vec3::repeat(f64::INFINITY);
        let mut hi = Vec3::repeat(f64::NEG_INFINITY);
        for &i in members {
            let p = &x[i as usize];
            lo = lo.inf(p);
            hi = hi.sup(p);
        }
        if !(lo.iter().all(|v| v.is_finite()) && hi.iter().all(|v| v.is_finite())) {
            return false;
        }
        let extent = hi - lo;
        let max_cells = 4 * members.len() + 64;
        // Count cells in f64: with a range far below the extent (1e-300 m over 1 m) the count
        // exceeds usize, and converting first would saturate and wrap. Starting at
        // extent / max_cells keeps the doubling loop short.
        let mut cell = range.max(extent.max() / max_cells as f64);
        let dims = loop {
            let d = extent.map(|e| (e / cell).floor() + 1.0);
            if d.x * d.y * d.z <= max_cells as f64 {
                break [d.x as usize, d.y as usize, d.z as usize];
            }
            cell *= 2.0;
        };
        self.origin = lo;
        self.inv_cell = 1.0 / cell;
        self.dims = dims;
        let ncells = dims[0] * dims[1] * dims[2];
        self.cell_start.resize(ncells + 1, 0);
        for &i in members {
            let c = self.cell_index(&x[i as usize]);
            self.cell_of.push(c as u32);
            self.cell_start[c + 1] += 1;
        }
        for c in 0..ncells {
            self.cell_start[c + 1] += self.cell_start[c];
        }
        self.sorted.resize(members.len(), 0);
        // Fill cells in member order so that pair order is deterministic.
        self.cursor.clear();
        self.cursor.extend_from_slice(&self.cell_start);
        for (&i, &c) in members.iter().zip(&self.cell_of) {
            let slot = &mut self.cursor[c as usize];
            self.sorted[*slot as usize] = i;
            *slot += 1;
        }
        true
    }

    fn coords(&self, p: &Vec3) -> [usize; 3] {
        let mut c = [0usize; 3];
        for k in 0..3 {
            let v = ((p[k] - self.origin[k]) * self.inv_cell).floor();
            c[k] = (v.max(0.0) as usize).min(self.dims[k] - 1);
        }
        c
    }

    fn cell_index(&self, p: &Vec3) -> usize {
        let [a, b, c] = self.coords(p);
        (c * self.dims[1] + b) * self.dims[0] + a
    }

    fn cell(&self, c: usize) -> &[u32] {
        &self.sorted[self.cell_start[c] as usize..self.cell_start[c + 1] as usize]
    }

    /// Number of cells (the range of [`Grid::for_each_candidate_pair_in`]).
    pub fn num_cells(&self) -> usize {
        self.dims[0] * self.dims[1] * self.dims[2]
    }

    /// Calls `visit(i, j)` once for every unordered pair of members in the same or adjacent
    /// cells (candidates: the caller tests the distance).
    pub fn for_each_candidate_pair(&self, visit: impl FnMut(u32, u32)) {
        self.for_each_candidate_pair_in(0..self.num_cells(), visit);
    }

    /// The pairs of [`Grid::for_each_candidate_pair`] whose first cell (in linear order) is in
    /// `cells`: disjoint ranges give disjoint pair sets, so threads can share the work.
    pub fn for_each_candidate_pair_in(
        &self,
        cells: std::ops::Range<usize>,
        mut visit: impl FnMut(u32, u32),
    ) {
        let [nx, ny, nz] = self.dims;
        for c in cells {
            let (cx, cy, cz) = (c % nx, (c / nx) % ny, c / (nx * ny));
            let here = self.cell(c);
            if here.is_empty() {
                continue;
            }
            for (a, &i) in here.iter().enumerate() {
                for &j in &here[a + 1..] {
                    visit(i, j);
                }
            }
            // Forward half of the 26 neighbours: each adjacent cell pair once.
            for (dx, dy, dz) in HALF_SHELL {
                let (x2, y2, z2) = (cx as isize + dx, cy as isize + dy, cz as isize + dz);
                if x2 < 0 || y2 < 0 || z2 < 0 {
                    continue;
                }
                let (x2, y2, z2) = (x2 as usize, y2 as usize, z2 as usize);
                if x2 >= nx || y2 >= ny || z2 >= nz {
                    continue;
                }
                let there = self.cell((z2 * ny + y2) * nx + x2);
                for &i in here {
                    for &j in there {
                        visit(i, j);
                    }
                }
            }
        }
    }

    /// Calls `visit(j)` for every member in the cell of `p` and its 26 neighbours.
    pub fn for_each_near(&self, p: &Vec3, mut visit: impl FnMut(u32)) {
        if self.sorted.is_empty() {
            return;
        }
        let [nx, ny, nz] = self.dims;
        // Points outside the box are clamped to the border cells: still correct, since
        // anything within range of them lies in a border cell or its neighbour.
        let [cx, cy, cz] = self.coords(p);
        for z2 in cz.saturating_sub(1)..(cz + 2).min(nz) {
            for y2 in cy.saturating_sub(1)..(cy + 2).min(ny) {
                for x2 in cx.saturating_sub(1)..(cx + 2).min(nx) {
                    for &j in self.cell((z2 * ny + y2) * nx + x2) {
                        visit(j);
                    }
                }
            }
        }
    }
}

/// The 13 neighbour offsets that come "after" a cell in (z, y, x) order.
const HALF_SHELL: [(isize, isize, isize); 13] = [
    (1, 0, 0),
    (-1, 1, 0),
    (0, 1, 0),
    (1, 1, 0),
    (-1, -1, 1),
    (0, -1, 1),
    (1, -1, 1),
    (-1, 0, 1),
    (0, 0, 1),
    (1, 0, 1),
    (-1, 1, 1),
    (0, 1, 1),
    (1, 1, 1),
];
