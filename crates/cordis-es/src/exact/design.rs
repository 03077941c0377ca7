//! `hybrid`'s cached design for the continuous searches (a TGR's K): the short cost's rows
//! `[Φ | a]` kept column by column, each column recomputed only when a nonlinear parameter it
//! depends on changes, then reduced to one small triangular factor per free particle.
//!
//! [`crate::exact::assemble`] runs every force pass once per column and frame and rotates
//! every row into a factor: ~250 µs per inner solve on the tadpole (loaded 2-core machine),
//! ~100 solves per search. In a search only one nonlinear unknown moves at a time, and its
//! columns have typed kernels:
//!
//! - a nonlinear drag's `(z1, z2)` at a given v_max: `-v_i` in the column of the regime
//!   `|v_i| < v_max` selects (the kernel of `cordis_core::forces::nonlinear_drag`);
//! - a TGR's `(l0, Z)` and the known part at a given K and tendon: the tensions of the three
//!   tendon series of [`Tendon`] along the link's unit vector.
//!
//! Each solve then costs one column group's kernel, the Gram entries touching the changed
//! columns (per particle) and a Cholesky factor (the normal equations: cheap, but they square
//! the condition number): ~15 µs on the tadpole. So the *score*
//! of a candidate is not read from the factor: the inner solution is put back into the rows and
//! the residual summed explicitly, which is exact up to `|Φ δθ|²` (δθ the solution's error),
//! second order. The final answer is solved from a Givens (orthogonal) factor of the same rows
//! ([`Design::qr_system`]), as the generic assembly would, so its precision is the QR's.
//!
//! Applies when every column has a typed kernel ([`Design::new`] says `None` otherwise: the
//! generic path is then used).

use cordis_core::forces::unit_and_length;
use cordis_core::{LinkKind, Scene, Vec3};
use nalgebra::DMatrix;

use crate::cost::Objective;
use crate::exact::tgr_cols::{self, Tendon};
use crate::exact::{self, Block, Col, System, Weighting};
use crate::linalg::givens::Factor;

/// Rows `[Φ | a]` of every free particle, column by column.
#[derive(Clone, Debug)]
pub(crate) struct Design {
    cols: Vec<Col>,
    /// Free particles (one block each), and each particle's block.
    free: Vec<usize>,
    block_of: Vec<Option<usize>>,
    /// Rows per block: 3 per predicted frame.
    rows: usize,
    /// `[block][row][column]`, row-major, `cols.len() + 1` wide: Φ (m per unit of θ), then
    /// `a = dt² g + 2x(t-1) - x(t-2) - x(t)` (m).
    data: Vec<f64>,
    /// Per column: the parameter slots its values depend on, and their bits when computed.
    deps: Vec<Vec<usize>>,
    keys: Vec<Option<Vec<u64>>>,
    /// Per block, the Gram matrix of `[Φ | a]` (upper triangle, `n × n`), and the columns
    /// changed since it was last brought up to date (each entry is the sum over the rows in
    /// row order, so a cached entry has the same bits as a fresh one).
    gram: Vec<f64>,
    dirty: Vec<bool>,
    /// The Gram entries `(k, l)` to bring up to date (scratch of [`Design::system`], kept to
    /// avoid an allocation per inner solve).
    stale: Vec<(usize, usize)>,
    /// Every TGR instance with what its tendon reads at each frame 0 … T-2, which no
    /// parameter changes.
    tgrs: Vec<TgrInstance>,
}

/// A TGR instance: type, particles, and per frame the unit vector i→j, the length (m), the
/// elongation speed (m/s) and the command S(t_n) (N).
#[derive(Clone, Debug)]
struct TgrInstance {
    type_index: usize,
    pair: [usize; 2],
    frames: Vec<(Vec3, f64, f64, f64)>,
}

impl Design {
    /// The design of `cols` (from [`exact::generic_cols`]); `None` unless every column has a
    /// typed kernel (nonlinear drags and TGRs only) and the scene has one clock.
    pub fn new(obj: &Objective, scene: &Scene, cols: &[Col]) -> Option<Self> {
        let plan = obj.plan();
        if plan.worlds.is_some() {
            return None;
        }
        let layout = scene.param_layout();
        let tgr_deps = |t: usize| {
            let o = layout.type_offsets[t];
            let mut d = vec![o, o + 3, o + 4, o + 5];
            d.extend(tgr_cols::initial_slots(scene, t).into_iter().flatten());
            d
        };
        let mut deps = Vec::with_capacity(cols.len());
        for c in cols {
            deps.push(match *c {
                Col::Z(t) | Col::Z2(t) if scene.types[t].kind == LinkKind::NonlinearDrag => {
                    vec![layout.type_offsets[t] + 2]
                }
                Col::Z(t) | Col::Rest(t) if scene.types[t].kind == LinkKind::Tgr => tgr_deps(t),
                Col::Known => (0..scene.types.len())
                    .filter(|&t| scene.types[t].kind == LinkKind::Tgr)
                    .flat_map(tgr_deps)
                    .collect(),
                _ => return None,
            });
        }
        let free = obj.free.clone();
        let mut block_of = vec![None; plan.n];
        for (b, &i) in free.iter().enumerate() {
            block_of[i] = Some(b);
        }
        let frames = obj.obs.frames;
        let rows = 3 * frames.saturating_sub(2);
        let dt2 = plan.dt * plan.dt;
        // Gravity is always known: the scene's value.
        let (_, g) = obj.masses_gravity(&scene.param_values());
        let n = cols.len() + 1;
        let mut data = vec![0.0; free.len() * rows * n];
        for t in 2..frames {
            let (x1, x2, x0) = (obj.obs.frame(t - 1), obj.obs.frame(t - 2), obj.obs.frame(t));
            for (b, &i) in free.iter().enumerate() {
                let d = (x1[i] * 2.0 - x2[i]) - x0[i];
                for r in 0..3 {
                    data[(b * rows + 3 * (t - 2) + r) * n + n - 1] = dt2 * g[r] + d[r];
                }
            }
        }
        let stateful = &plan.stateful;
        let mut tgrs = Vec::new();
        for (run, &sg) in stateful.tgrs.runs.iter().zip(&stateful.tgrs.signals) {
            let Some(t) = (0..scene.types.len()).find(|&t| layout.type_offsets[t] == run.param)
            else {
                continue;
            };
            for &[i, j] in &stateful.tgrs.pairs[run.start..run.end] {
                let (i, j) = (i as usize, j as usize);
                let per = (0..frames.saturating_sub(1))
                    .map(|fr| {
                        let (x, v) = (obj.obs.frame(fr), obj.obs.velocity(fr));
                        let (u, l) = unit_and_length(&(x[j] - x[i]));
                        let command = stateful.signals[sg].value(fr as f64 * plan.dt);
                        (u, l, (v[j] - v[i]).dot(&u), command)
                    })
                    .collect();
                tgrs.push(TgrInstance {
                    type_index: t,
                    pair: [i, j],
                    frames: per,
                });
            }
        }
        Some(Design {
            gram: vec![0.0; free.len() * n * n],
            dirty: vec![true; n],
            stale: Vec::with_capacity(n * (n + 1) / 2),
            tgrs,
            cols: cols.to_vec(),
            free,
            block_of,
            rows,
            data,
            keys: vec![None; cols.len()],
            deps,
        })
    }

    /// Recomputes the columns whose nonlinear parameters in `p` changed.
    pub fn update(&mut self, obj: &Objective, scene: &Scene, p: &[f64]) {
        let n = self.cols.len() + 1;
        let mut stale = vec![false; self.cols.len()];
        for (k, deps) in self.deps.iter().enumerate() {
            let key = deps.iter().map(|&s| p[s].to_bits());
            if !self.keys[k]
                .as_ref()
                .is_some_and(|old| old.iter().copied().eq(key.clone()))
            {
                stale[k] = true;
                self.dirty[k] = true;
                self.keys[k] = Some(key.collect());
                for row in self.data.chunks_exact_mut(n) {
                    row[k] = 0.0;
                }
            }
        }
        let layout = scene.param_layout();
        let plan = obj.plan();
        let dt = plan.dt;
        let dt2 = dt * dt;
        let frames = obj.obs.frames;
        let rows = self.rows;
        let at = |k: usize, b: usize, t: usize, r: usize| (b * rows + 3 * (t - 2) + r) * n + k;
        let col_of = |c: Col| self.cols.iter().position(|&x| x == c);
        for (t, ty) in scene.types.iter().enumerate() {
            let o = layout.type_offsets[t];
            match ty.kind {
                LinkKind::NonlinearDrag => {
                    let (Some(k1), Some(k2)) = (col_of(Col::Z(t)), col_of(Col::Z2(t))) else {
                        continue;
                    };
                    if !stale[k1] && !stale[k2] {
                        continue;
                    }
                    let v_max = p[o + 2];
                    let drags = &plan.nonlinear_drags;
                    for run in drags.runs.iter().filter(|r| r.param == o) {
                        for &i in &drags.particles[run.start..run.end] {
                            let Some(b) = self.block_of[i as usize] else {
                                continue;
                            };
                            for tt in 2..frames {
                                let v = obj.obs.velocity(tt - 1)[i as usize];
                                let k = if v.norm() < v_max { k1 } else { k2 };
                                for r in 0..3 {
                                    self.data[at(k, b, tt, r)] -= dt2 * v[r];
                                }
                            }
                        }
                    }
                }
                LinkKind::Tgr => {
                    let (Some(kl), Some(kz)) = (col_of(Col::Rest(t)), col_of(Col::Z(t))) else {
                        continue;
                    };
                    let known = col_of(Col::Known);
                    let known_stale = known.is_some_and(|k| stale[k]);
                    if !stale[kl] && !stale[kz] && !known_stale {
                        continue;
                    }
                    for inst in self.tgrs.iter().filter(|g| g.type_index == t) {
                        let [i, j] = inst.pair;
                        let mut tendon = Tendon::new(p[o], (p[o + 3], p[o + 4], p[o + 5]), dt)
                            .starting_at(tgr_cols::initial_tendon(scene, t, p, dt));
                        for (fr, &(u, l, s, command)) in inst.frames.iter().enumerate() {
                            let tension = tendon.step(command, l, s);
                            if fr == 0 {
                                continue; // frame 0's forces predict no frame
                            }
                            let targets = [
                                (known, tension[0]),
                                (Some(kl), tension[1]),
                                (Some(kz), tension[2]),
                            ];
                            for (k, tv) in targets {
                                let Some(k) = k.filter(|&k| stale[k]) else {
                                    continue;
                                };
                                let f: Vec3 = u * (dt2 * tv);
                                for (pp, sign) in [(i, 1.0), (j, -1.0)] {
                                    if let Some(b) = self.block_of[pp] {
                                        for r in 0..3 {
                                            self.data[at(k, b, fr + 1, r)] += sign * f[r];
                                        }
                                    }
                                }
                            }
                        }
                    }
                }
                _ => {}
            }
        }
    }

    /// The system of the current columns: per free particle, the Cholesky factor of the Gram
    /// matrix of `[Φ | a]` (semi-definite: a pivot that vanishes gives a zero row). Rows that
    /// are all zero (an axis the motion never uses) are skipped.
    pub fn system(&mut self) -> System {
        let n = self.cols.len() + 1;
        let dirty = &self.dirty;
        self.stale.clear();
        self.stale.extend(
            (0..n)
                .flat_map(|k| (k..n).map(move |l| (k, l)))
                .filter(|&(k, l)| dirty[k] || dirty[l]),
        );
        let pairs = &self.stale;
        let mut blocks = Vec::with_capacity(self.free.len());
        for (b, &i) in self.free.iter().enumerate() {
            let g = &mut self.gram[b * n * n..(b + 1) * n * n];
            if !pairs.is_empty() {
                for &(k, l) in pairs {
                    g[k * n + l] = 0.0;
                }
                let block = &self.data[b * self.rows * n..(b + 1) * self.rows * n];
                for row in block.chunks_exact(n) {
                    if row.iter().all(|&v| v == 0.0) {
                        continue;
                    }
                    for &(k, l) in pairs {
                        g[k * n + l] += row[k] * row[l];
                    }
                }
            }
            let mut r = DMatrix::zeros(n, n);
            for k in 0..n {
                let mut d = g[k * n + k];
                for m in 0..k {
                    d -= r[(m, k)] * r[(m, k)];
                }
                if d.is_nan() || d <= 1e-13 * g[k * n + k] {
                    continue; // dependent (or empty) column: a zero row
                }
                let dk = d.sqrt();
                r[(k, k)] = dk;
                for l in k + 1..n {
                    let mut v = g[k * n + l];
                    for m in 0..k {
                        v -= r[(m, k)] * r[(m, l)];
                    }
                    r[(k, l)] = v / dk;
                }
            }
            blocks.push(Block {
                particle: Some(i),
                rows: r,
            });
        }
        self.dirty.fill(false);
        System {
            cols: self.cols.clone(),
            blocks,
            partial: false,
        }
    }

    /// The system of the current columns by Givens rotations of the rows themselves, as
    /// [`exact::assemble`] builds it: the condition number is not squared (the final solve).
    pub fn qr_system(&self) -> System {
        let n = self.cols.len() + 1;
        let mut row = vec![0.0; n];
        let blocks = self
            .free
            .iter()
            .enumerate()
            .map(|(b, &i)| {
                let mut f = Factor::new(n);
                let block = &self.data[b * self.rows * n..(b + 1) * self.rows * n];
                for r in block.chunks_exact(n) {
                    row.copy_from_slice(r);
                    f.add_row(&mut row);
                }
                Block {
                    particle: Some(i),
                    rows: f.matrix(),
                }
            })
            .collect();
        System {
            cols: self.cols.clone(),
            blocks,
            partial: false,
        }
    }

    /// The cost of the full parameter vector `p` in `weighting`, summed row by row.
    pub fn residual(&self, scene: &Scene, p: &[f64], weighting: Weighting) -> f64 {
        let theta: Vec<f64> = self
            .cols
            .iter()
            .map(|&c| exact::theta_of(scene, c, p))
            .collect();
        let mass_offset = scene.param_layout().mass_offset;
        let n = self.cols.len() + 1;
        let mut sum = 0.0;
        for (b, &i) in self.free.iter().enumerate() {
            let m = p[mass_offset + i];
            let (scale, ma) = match weighting {
                Weighting::Position => (1.0 / m, 1.0),
                Weighting::Force => (1.0, m),
            };
            let block = &self.data[b * self.rows * n..(b + 1) * self.rows * n];
            for row in block.chunks_exact(n) {
                let f: f64 = row.iter().zip(&theta).map(|(d, th)| d * th).sum();
                let e = scale * f + ma * row[n - 1];
                sum += e * e;
            }
        }
        if sum.is_finite() {
            sum
        } else {
            f64::INFINITY
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cost::CostKind;
    use crate::problem::Problem;
    use cordis_core::examples::tadpole;

    /// The typed columns are the generic assembly's: at any θ the sum of squares of the rows
    /// agrees with the assembled factor's, and the Cholesky factor's.
    #[test]
    fn typed_columns_reproduce_the_generic_assembly() {
        let truth = tadpole();
        let traj = truth.simulate(100).unwrap();
        let problem = Problem::new(&truth, &traj, CostKind::Short).unwrap();
        let obj = &problem.objective;
        let cols = exact::generic_cols(&truth).unwrap();
        let mut design = Design::new(obj, &truth, &cols).expect("typed columns only");
        let mut p = truth.param_values();
        // Off the truth: another K (the tendon's series change) and another v_max.
        let o = truth.param_layout().type_offsets[1];
        p[o] = 13.0;
        p[truth.param_layout().type_offsets[0] + 2] = 0.3;
        design.update(obj, &truth, &p);
        let exact_sys = exact::assemble(obj, &truth, &cols, &p);
        let chol = design.system();
        let sq = |sys: &System, theta: &[f64]| -> f64 {
            sys.blocks
                .iter()
                .map(|b| {
                    let m = truth.particles[b.particle.unwrap()].mass.value();
                    let mut x: Vec<f64> = theta.to_vec();
                    x.push(m);
                    (&b.rows * nalgebra::DVector::from_vec(x)).norm_squared() / (m * m)
                })
                .sum()
        };
        let w = truth.param_layout().type_offsets[0];
        for theta in [[0.1, 1.0, 1.0, 0.0, 1.0], [0.3, 0.2, 0.7, 0.4, 1.0]] {
            let mut q = p.clone();
            q[w] = theta[0];
            q[w + 1] = theta[1];
            q[o + 1] = theta[2];
            q[o + 2] = theta[3];
            let direct = design.residual(&truth, &q, Weighting::Position);
            let assembled = sq(&exact_sys, &theta);
            let factored = sq(&chol, &theta);
            approx::assert_relative_eq!(
                direct,
                sq(&design.qr_system(), &theta),
                max_relative = 1e-10
            );
            assert!(direct > 0.0);
            approx::assert_relative_eq!(direct, assembled, max_relative = 1e-10);
            approx::assert_relative_eq!(direct, factored, max_relative = 1e-6);
        }
    }
}
