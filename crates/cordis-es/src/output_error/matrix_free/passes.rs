//! The forward (`J v`) and adjoint (`Jᵀ u`) passes through a take's stored linearisation.

use std::ops::Range;

use super::super::tangent::spring::{self, LINK};
use super::super::tangent::{angle, conditional, plane, provot, NONE};
use super::operator::{Half, Lin, Mf, Work};

impl<'a, 'b> Mf<'a, 'b> {
    /// `J v` for one take, `w` directions at once: `dir` holds the take's local variables
    /// (θ in internal coordinates, then the take's state) × `w`, row-major; the raw position
    /// sensitivities s(t) (frames × 3N × w) go to `work.out`.
    pub fn forward(&self, k: usize, w: usize, work: &mut Work) {
        let plan = &self.fit.tangent.plan;
        let lin = &self.lins[k];
        let (n, dt, nt) = (plan.n, plan.dt, self.fit.theta());
        let rows = 3 * n;
        let Work {
            cur,
            prev,
            vel,
            df,
            dth,
            dir,
            out,
            half,
            ..
        } = work;
        for b in [&mut *cur, &mut *prev, &mut *vel, &mut *df] {
            b.clear();
            b.resize(rows * w, 0.0);
        }
        out.clear();
        out.resize(lin.frames * rows * w, 0.0);
        dth.clear();
        dth.extend((0..nt * w).map(|a| dir[a] * self.chain[a / w]));
        for (f, &i) in self.fit.tangent.free.iter().enumerate() {
            for c in 0..3 {
                for col in 0..w {
                    let x0 = dir[(nt + 6 * f + c) * w + col];
                    let v0 = dir[(nt + 6 * f + 3 + c) * w + col];
                    cur[(3 * i + c) * w + col] = x0;
                    prev[(3 * i + c) * w + col] = x0 - dt * v0;
                }
            }
        }
        for t in 0..lin.frames {
            out[t * rows * w..(t + 1) * rows * w].copy_from_slice(cur);
            if t + 1 == lin.frames {
                break;
            }
            self.forward_step(lin, t, w, cur, prev, vel, (df, &mut half.df), dth);
            std::mem::swap(cur, prev);
            let pass = &plan.provot;
            if !pass.links.is_empty() {
                let of_slot = &self.fit.cols.of_slot;
                provot::forward(
                    pass, &plan.free, &lin.proj, t, &self.p, of_slot, w, cur, dth,
                );
            }
        }
    }

    /// Calls `f(K, columns of (K, l0, Z, Z₂), ends, record)` for the springs in `springs`
    /// (indices into the pass) and, if `anchors`, every anchor (`j = None`) at step t: the
    /// walk the forward and adjoint passes share, inlined into each.
    #[inline(always)]
    pub(super) fn each_link(
        &self,
        lin: &Lin,
        t: usize,
        (springs, anchors): (Range<usize>, bool),
        mut f: impl FnMut(f64, &[usize; 4], (usize, Option<usize>), &[f64]),
    ) {
        let plan = &self.fit.tangent.plan;
        let (of_slot, p) = (&self.fit.cols.of_slot, &self.p);
        let (nsp, nan) = (plan.springs.pairs.len(), plan.anchors.particles.len());
        for (ri, r) in plan.springs.runs.iter().enumerate() {
            let (a, b) = (r.start.max(springs.start), r.end.min(springs.end));
            if a >= b {
                continue;
            }
            let slots = spring::slots(&plan.springs, ri, r.param, of_slot);
            let recs = &lin.springs[(t * nsp + a) * LINK..(t * nsp + b) * LINK];
            for (&[i, j], d) in plan.springs.pairs[a..b].iter().zip(recs.chunks_exact(LINK)) {
                f(p[r.param], &slots, (i as usize, Some(j as usize)), d);
            }
        }
        if !anchors {
            return;
        }
        for r in &plan.anchors.runs {
            let slots = [r.param, r.param + 1, r.param + 2].map(|q| of_slot[q]);
            let slots = [slots[0], slots[1], slots[2], NONE];
            let recs = &lin.anchors[(t * nan + r.start) * LINK..(t * nan + r.end) * LINK];
            for (&i, d) in plan.anchors.particles[r.start..r.end]
                .iter()
                .zip(recs.chunks_exact(LINK))
            {
                f(p[r.param], &slots, (i as usize, None), d);
            }
        }
    }

    /// The springs' and anchors' share of one forward step into `df`: split over two threads
    /// from [`SPLIT_MIN_SPRINGS`] springs (the second half summed in `df2`, then added).
    #[allow(clippy::too_many_arguments)]
    pub(super) fn forward_links_step(
        &self,
        lin: &Lin,
        t: usize,
        w: usize,
        sv: (&[f64], &[f64]),
        df: &mut [f64],
        df2: &mut Vec<f64>,
        dth: &[f64],
    ) {
        let nsp = self.fit.tangent.plan.springs.pairs.len();
        // One direction (every CG iteration) gets its own instance of the link loops, the
        // width a constant (BENCHMARKS, "Large scenes"). The kernels are forced inline: left
        // to itself the compiler called each link's as a function, reloading the environment
        // (perf, 32 x 32 cloth: a single-thread product 21 → 17 ms; BENCHMARKS, "Lean passes").
        let run = |springs: (Range<usize>, bool), df: &mut [f64]| {
            if w == 1 {
                self.each_link(
                    lin,
                    t,
                    springs,
                    #[inline(always)]
                    |k, slots, ends, d| spring::forward(d, k, slots, ends, 1, sv, df, dth),
                );
            } else {
                self.each_link(
                    lin,
                    t,
                    springs,
                    #[inline(always)]
                    |k, slots, ends, d| spring::forward(d, k, slots, ends, w, sv, df, dth),
                );
            }
        };
        if nsp < self.split_min_springs {
            run((0..nsp, true), df);
            return;
        }
        let half = nsp / 2;
        df2.clear();
        df2.resize(df.len(), 0.0);
        if rayon::current_thread_index().is_some() {
            rayon::join(
                || run((0..half, true), &mut *df),
                || run((half..nsp, false), &mut df2[..]),
            );
        } else {
            // Outside a pool a join would hand every step to the global pool and block on
            // it (measured: 78 s of system time on the 32 x 32 fit); the same two sums, in turn.
            run((0..half, true), &mut *df);
            run((half..nsp, false), &mut df2[..]);
        }
        for (a, b) in df.iter_mut().zip(df2.iter()) {
            *a += b;
        }
    }

    /// The springs' and anchors' share of one adjoint step: split as
    /// [`Self::forward_links_step`], the second half's `na`, `psi` and θ gradient in `half`.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn adjoint_links_step(
        &self,
        lin: &Lin,
        t: usize,
        w: usize,
        phi: &[f64],
        (na, psi): (&mut [f64], &mut [f64]),
        grad: &mut [f64],
        half: &mut Half,
    ) {
        let nsp = self.fit.tangent.plan.springs.pairs.len();
        let run =
            |springs: (Range<usize>, bool), (na, psi): (&mut [f64], &mut [f64]), g: &mut [f64]| {
                if w == 1 {
                    self.each_link(
                        lin,
                        t,
                        springs,
                        #[inline(always)]
                        |k, slots, ends, d| {
                            spring::adjoint(d, k, slots, ends, 1, phi, (&mut *na, &mut *psi), g)
                        },
                    );
                } else {
                    self.each_link(
                        lin,
                        t,
                        springs,
                        #[inline(always)]
                        |k, slots, ends, d| {
                            spring::adjoint(d, k, slots, ends, w, phi, (&mut *na, &mut *psi), g)
                        },
                    );
                }
            };
        if nsp < self.split_min_springs {
            run((0..nsp, true), (na, psi), grad);
            return;
        }
        let mid = nsp / 2;
        // Spring parameters are θ columns: the second half's gradient is nθ × w wide.
        let nt = self.fit.theta() * w;
        let Half {
            na: na2,
            psi: psi2,
            grad: grad2,
            ..
        } = half;
        for (b, len) in [
            (&mut *na2, na.len()),
            (&mut *psi2, psi.len()),
            (&mut *grad2, nt),
        ] {
            b.clear();
            b.resize(len, 0.0);
        }
        let second = (&mut na2[..], &mut psi2[..]);
        if rayon::current_thread_index().is_some() {
            rayon::join(
                || run((0..mid, true), (&mut *na, &mut *psi), &mut *grad),
                || run((mid..nsp, false), second, &mut grad2[..]),
            );
        } else {
            run((0..mid, true), (&mut *na, &mut *psi), &mut *grad);
            run((mid..nsp, false), second, &mut grad2[..]);
        }
        for (a, b) in na.iter_mut().zip(na2.iter()) {
            *a += b;
        }
        for (a, b) in psi.iter_mut().zip(psi2.iter()) {
            *a += b;
        }
        for (a, b) in grad[..nt].iter_mut().zip(grad2.iter()) {
            *a += b;
        }
    }

    /// One step of the directional tangent recursion: writes s(t+1) into `prev`.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn forward_step(
        &self,
        lin: &Lin,
        t: usize,
        w: usize,
        cur: &[f64],
        prev: &mut [f64],
        vel: &mut [f64],
        (df, df2): (&mut [f64], &mut Vec<f64>),
        dth: &[f64],
    ) {
        let plan = &self.fit.tangent.plan;
        let of_slot = &self.fit.cols.of_slot;
        let (n, dt, p) = (plan.n, plan.dt, &self.p);
        let rows = 3 * n;
        let inv_dt = 1.0 / dt;
        for ((v, a), b) in vel.iter_mut().zip(cur).zip(prev.iter()) {
            *v = (a - b) * inv_dt;
        }
        df.iter_mut().for_each(|x| *x = 0.0);
        let nd = plan.dampers.pairs.len();
        self.forward_links_step(lin, t, w, (cur, vel), df, df2, dth);
        for r in &plan.dampers.runs {
            let z = p[r.param];
            let s = of_slot[r.param];
            for (l, &[i, j]) in plan.dampers.pairs[r.start..r.end].iter().enumerate() {
                let (i, j) = (i as usize, j as usize);
                let rel = &lin.dampers[(t * nd + r.start + l) * 3..][..3];
                for col in 0..w {
                    let dz = if s != NONE { dth[s * w + col] } else { 0.0 };
                    for c in 0..3 {
                        let (ri, rj) = ((3 * i + c) * w + col, (3 * j + c) * w + col);
                        let g = z * (vel[rj] - vel[ri]) + rel[c] * dz;
                        df[ri] += g;
                        df[rj] -= g;
                    }
                }
            }
        }
        for r in &plan.drags.runs {
            let z = p[r.param];
            let s = of_slot[r.param];
            for &i in &plan.drags.particles[r.start..r.end] {
                let i = i as usize;
                for col in 0..w {
                    let dz = if s != NONE { dth[s * w + col] } else { 0.0 };
                    for c in 0..3 {
                        let ri = (3 * i + c) * w + col;
                        df[ri] -= z * vel[ri] + lin.vel[t * rows + 3 * i + c] * dz;
                    }
                }
            }
        }
        let nag = plan.angles.triples.len();
        if nag > 0 {
            let recs = &lin.angles[t * nag * angle::ANGLE..][..nag * angle::ANGLE];
            angle::forward(&plan.angles, recs, p, of_slot, w, cur, df, dth);
        }
        let npl = plan.planes.len();
        if npl > 0 {
            let recs = &lin.planes[t * npl * plane::PLANE..][..npl * plane::PLANE];
            plane::forward(&plan.planes, recs, of_slot, w, (cur, vel), df, dth);
        }
        if !plan.conditionals.is_empty() {
            let cs = (cur, &*vel);
            conditional::forward(&plan.conditionals, &lin.cond, t, p, of_slot, w, cs, df, dth);
        }
        // Slices zipped per particle, not indexed: the indexed loop, generic in w, spent more
        // time on bounds and overlap checks than on the update (perf, 32 x 32 cloth).
        let particles = prev
            .chunks_exact_mut(3 * w)
            .zip(cur.chunks_exact(3 * w))
            .zip(df.chunks_exact(3 * w));
        for (((next, cur), df), &h) in particles.zip(&self.h) {
            // h = 0 on fixed particles, whose rows are 0.
            for ((x, &c), &f) in next.iter_mut().zip(cur).zip(df) {
                *x = 2.0 * c - *x + h * f;
            }
        }
        for &(i, ms) in &self.unknown_masses {
            let h = self.h[i];
            let m = p[plan.layout.mass_offset + i];
            for c in 0..3 {
                let fm = h * lin.force[t * rows + 3 * i + c] / m;
                let row = &mut prev[(3 * i + c) * w..(3 * i + c + 1) * w];
                for (x, &d) in row.iter_mut().zip(&dth[ms * w..(ms + 1) * w]) {
                    *x -= fm * d;
                }
            }
        }
    }

    /// `Jᵀ u` for one take, `w` cotangents at once: `cot` holds u(t) (frames × 3N × w, raw
    /// positions); the local gradient (θ in internal coordinates, then the take's state) × w
    /// goes to `work.grad`. The adjoint recursion of the module docs.
    pub fn adjoint(&self, k: usize, w: usize, cot: &[f64], work: &mut Work) {
        let plan = &self.fit.tangent.plan;
        let of_slot = &self.fit.cols.of_slot;
        let lin = &self.lins[k];
        let (n, dt, p, nt) = (plan.n, plan.dt, &self.p, self.fit.theta());
        let rows = 3 * n;
        let frames = lin.frames;
        let Work {
            cur: a,
            prev: b,
            vel: psi,
            df: na,
            phi,
            grad,
            half,
            ..
        } = work;
        for buf in [&mut *b, &mut *psi, &mut *na, &mut *phi] {
            buf.clear();
            buf.resize(rows * w, 0.0);
        }
        grad.clear();
        grad.resize(self.local_len() * w, 0.0);
        a.clear();
        a.extend_from_slice(&cot[(frames - 1) * rows * w..frames * rows * w]);
        let nd = plan.dampers.pairs.len();
        let mo = plan.layout.mass_offset;
        let inv_dt = 1.0 / dt;
        for t in (0..frames.saturating_sub(1)).rev() {
            if !plan.provot.links.is_empty() {
                // a(t+1) is the cotangent of the projected x(t+1): through the corrections.
                provot::adjoint(
                    &plan.provot,
                    &plan.free,
                    &lin.proj,
                    t,
                    p,
                    of_slot,
                    w,
                    a,
                    grad,
                );
            }
            // φ = h ⊙ P a(t+1); a(t) starts as u(t) + 2 P a(t+1) + b(t+1), b(t) as -P a(t+1).
            let u = &cot[t * rows * w..(t + 1) * rows * w];
            let particles = phi
                .chunks_exact_mut(3 * w)
                .zip(na.chunks_exact_mut(3 * w))
                .zip(b.chunks_exact_mut(3 * w))
                .zip(a.chunks_exact(3 * w).zip(u.chunks_exact(3 * w)));
            for ((((phi, na), b), (a, u)), (&h, &free)) in
                particles.zip(self.h.iter().zip(&plan.free))
            {
                let rows = phi.iter_mut().zip(na.iter_mut()).zip(b.iter_mut());
                let rows = rows.zip(a.iter().zip(u));
                if free {
                    for (((phi, na), b), (&a, &u)) in rows {
                        *phi = h * a;
                        *na = u + 2.0 * a + *b;
                        *b = -a;
                    }
                } else {
                    // The free-row mask P is 0 on a fixed particle.
                    for (((phi, na), b), (_, &u)) in rows {
                        *phi = 0.0;
                        *na = u + *b;
                        *b = 0.0;
                    }
                }
            }
            psi.iter_mut().for_each(|x| *x = 0.0);
            self.adjoint_links_step(lin, t, w, phi, (na, psi), grad, half);
            for r in &plan.dampers.runs {
                let z = p[r.param];
                let s = of_slot[r.param];
                for (l, &[i, j]) in plan.dampers.pairs[r.start..r.end].iter().enumerate() {
                    let (i, j) = (i as usize, j as usize);
                    let rel = &lin.dampers[(t * nd + r.start + l) * 3..][..3];
                    for col in 0..w {
                        for c in 0..3 {
                            let (ri, rj) = ((3 * i + c) * w + col, (3 * j + c) * w + col);
                            let del = phi[rj] - phi[ri];
                            psi[ri] += z * del;
                            psi[rj] -= z * del;
                            if s != NONE {
                                grad[s * w + col] -= rel[c] * del;
                            }
                        }
                    }
                }
            }
            for r in &plan.drags.runs {
                let z = p[r.param];
                let s = of_slot[r.param];
                for &i in &plan.drags.particles[r.start..r.end] {
                    let i = i as usize;
                    for col in 0..w {
                        for c in 0..3 {
                            let ri = (3 * i + c) * w + col;
                            psi[ri] -= z * phi[ri];
                            if s != NONE {
                                grad[s * w + col] -= lin.vel[t * rows + 3 * i + c] * phi[ri];
                            }
                        }
                    }
                }
            }
            let nag = plan.angles.triples.len();
            if nag > 0 {
                let recs = &lin.angles[t * nag * angle::ANGLE..][..nag * angle::ANGLE];
                angle::adjoint(&plan.angles, recs, p, of_slot, w, phi, na, grad);
            }
            let npl = plan.planes.len();
            if npl > 0 {
                let recs = &lin.planes[t * npl * plane::PLANE..][..npl * plane::PLANE];
                plane::adjoint(&plan.planes, recs, of_slot, w, phi, (na, psi), grad);
            }
            if !plan.conditionals.is_empty() {
                let cond = &plan.conditionals;
                conditional::adjoint(cond, &lin.cond, t, p, of_slot, w, phi, (na, psi), grad);
            }
            for &(i, ms) in &self.unknown_masses {
                let m = p[mo + i];
                for c in 0..3 {
                    let fm = lin.force[t * rows + 3 * i + c] / m;
                    for col in 0..w {
                        grad[ms * w + col] -= fm * phi[(3 * i + c) * w + col];
                    }
                }
            }
            for ((x, y), s) in na.iter_mut().zip(b.iter_mut()).zip(psi.iter()) {
                *x += s * inv_dt;
                *y -= s * inv_dt;
            }
            std::mem::swap(a, na);
        }
        for (g, c) in grad[..nt * w].iter_mut().zip(0..) {
            *g *= self.chain[c / w];
        }
        for (f, &i) in self.fit.tangent.free.iter().enumerate() {
            for c in 0..3 {
                for col in 0..w {
                    let q = (3 * i + c) * w + col;
                    grad[(nt + 6 * f + c) * w + col] = a[q] + b[q];
                    grad[(nt + 6 * f + 3 + c) * w + col] = -dt * b[q];
                }
            }
        }
    }
}
