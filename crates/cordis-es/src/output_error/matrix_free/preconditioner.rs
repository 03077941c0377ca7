//! The preconditioner: each free particle's local 6×6 block and the θ columns, by a Schur
//! complement (module docs of [`super`]).

use nalgebra::{DMatrix, DVector, Matrix6};

use super::super::tangent::spring::{self, LINK};
use super::super::tangent::{angle, conditional, plane, provot};
use super::operator::{Lin, Mf, Work};

impl<'a, 'b> Mf<'a, 'b> {
    /// The local-model 6×6 block of every free particle (module docs): its own sensitivity
    /// to its own initial state with its neighbours held, accumulated over its observations.
    pub(super) fn local_blocks(&self, lin: &mut Lin, work: &mut Work) {
        let plan = &self.fit.tangent.plan;
        let free = &self.fit.tangent.free;
        let (n, dt, p) = (plan.n, plan.dt, &self.p);
        let rows = 3 * n;
        let (nsp, nan) = (plan.springs.pairs.len(), plan.anchors.particles.len());
        let mo = plan.layout.mass_offset;
        lin.local.clear();
        lin.local.resize(36 * free.len(), 0.0);
        // Particle → its free index (the Provot corrections address particles).
        let mut block_of = vec![None; if plan.provot.links.is_empty() { 0 } else { n }];
        if !block_of.is_empty() {
            for (f, &i) in free.iter().enumerate() {
                block_of[i] = Some(f);
            }
        }
        // Per free particle: S (3×6) and S(n-1), row-major, packed.
        let Work {
            cur,
            prev,
            df,
            kii,
            cii,
            ..
        } = work;
        cur.clear();
        cur.resize(18 * free.len(), 0.0);
        prev.clear();
        prev.resize(18 * free.len(), 0.0);
        df.clear();
        df.resize(18, 0.0);
        for f in 0..free.len() {
            for k in 0..3 {
                cur[18 * f + 6 * k + k] = 1.0;
                prev[18 * f + 6 * k + k] = 1.0;
                prev[18 * f + 6 * k + 3 + k] = -dt;
            }
        }
        for t in 0..lin.frames {
            for (f, &i) in free.iter().enumerate() {
                let s = &cur[18 * f..18 * f + 18];
                let blk = &mut lin.local[36 * f..36 * f + 36];
                for c in 0..3 {
                    let w2 = lin.wsq[t * rows + 3 * i + c];
                    if w2 > 0.0 {
                        let row = &s[6 * c..6 * c + 6];
                        for a in 0..6 {
                            for b in 0..6 {
                                blk[6 * a + b] += w2 * row[a] * row[b];
                            }
                        }
                    }
                }
            }
            if t + 1 == lin.frames {
                break;
            }
            kii.clear();
            kii.resize(9 * n, 0.0);
            cii.clear();
            cii.resize(9 * n, 0.0);
            let sub = |m: &mut Vec<f64>, i: usize, a: &[f64]| {
                for (x, y) in m[9 * i..9 * i + 9].iter_mut().zip(a) {
                    *x -= y;
                }
            };
            let mut bz = [0.0; 9];
            for r in &plan.springs.runs {
                for (l, &[i, j]) in plan.springs.pairs[r.start..r.end].iter().enumerate() {
                    let d = &lin.springs[(t * nsp + r.start + l) * LINK..][..LINK];
                    rank_one(&mut bz, d[spring::ZEFF], spring::unit(d));
                    let a = spring::a_matrix(d);
                    for e in [i as usize, j as usize] {
                        sub(kii, e, &a);
                        sub(cii, e, &bz);
                    }
                }
            }
            for r in &plan.anchors.runs {
                for (l, &i) in plan.anchors.particles[r.start..r.end].iter().enumerate() {
                    let d = &lin.anchors[(t * nan + r.start + l) * LINK..][..LINK];
                    rank_one(&mut bz, d[spring::ZEFF], spring::unit(d));
                    sub(kii, i as usize, &spring::a_matrix(d));
                    sub(cii, i as usize, &bz);
                }
            }
            for r in &plan.dampers.runs {
                let z = p[r.param];
                let id = [z, 0.0, 0.0, 0.0, z, 0.0, 0.0, 0.0, z];
                for &[i, j] in &plan.dampers.pairs[r.start..r.end] {
                    sub(cii, i as usize, &id);
                    sub(cii, j as usize, &id);
                }
            }
            for r in &plan.drags.runs {
                let z = p[r.param];
                let id = [z, 0.0, 0.0, 0.0, z, 0.0, 0.0, 0.0, z];
                for &i in &plan.drags.particles[r.start..r.end] {
                    sub(cii, i as usize, &id);
                }
            }
            let nag = plan.angles.triples.len();
            if nag > 0 {
                let recs = &lin.angles[t * nag * angle::ANGLE..][..nag * angle::ANGLE];
                angle::local(&plan.angles, recs, kii);
            }
            let npl = plan.planes.len();
            if npl > 0 {
                let recs = &lin.planes[t * npl * plane::PLANE..][..npl * plane::PLANE];
                plane::local(&plan.planes, recs, kii, cii);
            }
            if !plan.conditionals.is_empty() {
                conditional::local(&lin.cond, t, kii, cii);
            }
            for (f, &i) in free.iter().enumerate() {
                let h = dt * dt / p[mo + i];
                let (s, sp) = (&cur[18 * f..18 * f + 18], &prev[18 * f..18 * f + 18]);
                let (km, cm) = (&kii[9 * i..9 * i + 9], &cii[9 * i..9 * i + 9]);
                for r in 0..3 {
                    for q in 0..6 {
                        let mut g = 0.0;
                        for c in 0..3 {
                            let sv = s[6 * c + q];
                            g += km[3 * r + c] * sv + cm[3 * r + c] * (sv - sp[6 * c + q]) / dt;
                        }
                        df[6 * r + q] = 2.0 * s[6 * r + q] - sp[6 * r + q] + h * g;
                    }
                }
                prev[18 * f..18 * f + 18].copy_from_slice(&cur[18 * f..18 * f + 18]);
                cur[18 * f..18 * f + 18].copy_from_slice(df);
            }
            if !plan.provot.links.is_empty() {
                let block = |i: usize| block_of[i].map(|f| 18 * f);
                provot::local(&plan.provot, &plan.free, &lin.proj, t, block, cur);
            }
        }
    }
}

/// `z u uᵀ`, row-major.
pub(super) fn rank_one(out: &mut [f64; 9], z: f64, u: &[f64]) {
    for r in 0..3 {
        for c in 0..3 {
            out[3 * r + c] = z * u[r] * u[c];
        }
    }
}

/// The preconditioner `M⁻¹` at one λ (module docs).
pub(crate) struct Pre {
    pub(super) nt: usize,
    /// Inverse of each damped local block, 36 per free particle per take, in state order.
    pub(super) dinv: Vec<f64>,
    /// `Y = D⁻¹ H_sθ` (state rows × nθ), and the Cholesky factor of the θ system.
    pub(super) y: DMatrix<f64>,
    pub(super) hst: DMatrix<f64>,
    pub(super) schur: Option<nalgebra::Cholesky<f64, nalgebra::Dyn>>,
    pub(super) held: Vec<bool>,
}

impl Pre {
    /// Builds `M + λ diag(scale)` restricted to the coordinates not held, and factors it.
    pub fn new(
        mf: &Mf<'_, '_>,
        cols: &DMatrix<f64>,
        scale: &[f64],
        held: &[bool],
        lambda: f64,
    ) -> Pre {
        let nt = mf.fit.theta();
        let len = mf.fit.len();
        let nss = len - nt;
        let mut dinv = vec![0.0; 36 * (nss / 6)];
        let mut b = 0;
        for lin in &mf.lins {
            for blk in lin.local.chunks(36) {
                let mut m = Matrix6::from_row_slice(blk);
                for a in 0..6 {
                    let s = scale[nt + 6 * b + a];
                    m[(a, a)] += lambda * if s > 0.0 { s } else { 1.0 };
                    // A particle its own observations do not see (hidden): keep D invertible.
                    if m[(a, a)] <= 0.0 {
                        m[(a, a)] = 1.0;
                    }
                }
                let inv = m
                    .cholesky()
                    .map(|c| c.inverse())
                    .unwrap_or_else(|| Matrix6::from_diagonal(&m.diagonal().map(|d| 1.0 / d)));
                for r in 0..6 {
                    for c in 0..6 {
                        dinv[36 * b + 6 * r + c] = inv[(r, c)];
                    }
                }
                b += 1;
            }
        }
        let mut hst = cols.rows(nt, nss).into_owned();
        let mut att = cols.rows(0, nt).into_owned();
        for a in 0..nt {
            att[(a, a)] += lambda * if scale[a] > 0.0 { scale[a] } else { 1.0 };
        }
        for a in 0..nt {
            if held[a] {
                for c in 0..nt {
                    att[(a, c)] = 0.0;
                    att[(c, a)] = 0.0;
                }
                att[(a, a)] = 1.0;
                hst.column_mut(a).fill(0.0);
            }
        }
        let att = (&att + att.transpose()) * 0.5;
        let mut y = DMatrix::zeros(nss, nt);
        for p in 0..nss / 6 {
            for c in 0..nt {
                for r in 0..6 {
                    let mut s = 0.0;
                    for q in 0..6 {
                        s += dinv[36 * p + 6 * r + q] * hst[(6 * p + q, c)];
                    }
                    y[(6 * p + r, c)] = s;
                }
            }
        }
        let s = &att - hst.transpose() * &y;
        let s = (&s + s.transpose()) * 0.5;
        let schur = s.cholesky().or_else(|| {
            // The local blocks underestimate the states' information: drop the coupling.
            y.fill(0.0);
            hst.fill(0.0);
            att.clone().cholesky()
        });
        Pre {
            nt,
            dinv,
            y,
            hst,
            schur,
            held: held.to_vec(),
        }
    }

    /// `z = M⁻¹ r` (one vector).
    pub fn apply(&self, r: &[f64], z: &mut [f64]) {
        let nt = self.nt;
        let (rt, rs) = r.split_at(nt);
        let (zt, zs) = z.split_at_mut(nt);
        for (p, (o, x)) in zs.chunks_mut(6).zip(rs.chunks(6)).enumerate() {
            let m = &self.dinv[36 * p..36 * p + 36];
            for a in 0..6 {
                o[a] = (0..6).map(|b| m[6 * a + b] * x[b]).sum();
            }
        }
        if nt == 0 {
            return;
        }
        let mut rhs =
            DVector::from_iterator(nt, (0..nt).map(|a| if self.held[a] { 0.0 } else { rt[a] }));
        let zs_v = DVector::from_column_slice(zs);
        rhs -= self.hst.transpose() * &zs_v;
        let th = match &self.schur {
            Some(c) => c.solve(&rhs),
            None => rhs,
        };
        let corr = &self.y * &th;
        for (o, c) in zs.iter_mut().zip(corr.iter()) {
            *o -= c;
        }
        for a in 0..nt {
            zt[a] = if self.held[a] { 0.0 } else { th[a] };
        }
    }
}
