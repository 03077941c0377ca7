//! Positions for the particles a take never observes, for the short-cost start only: each
//! hidden particle follows the local deformation of the known particles around it.
//!
//! Why: the short cost reads every particle's positions, so a hidden particle leaves no row for
//! itself nor for its neighbours. Holding them (what [`super::start`] does first) leaves no row
//! at all when the hidden particle is linked to every free one — the soft block's centre, whose
//! edge, face and body springs reach all 26 others — and the heuristic start from 25×-wide boxes
//! then diverges from every start. Imputed positions give the neighbours their rows back; the
//! fit itself never sees them (it simulates hidden particles).
//!
//! For a hidden particle laid out at `p_h` in the scene, with donors `j` (the known — tracked or
//! fixed — particles nearest in the layout: the 4 nearest and every one within 1.5 × the 4th's
//! distance, weighted `w_j = 1/|p_j − p_h|²`):
//!
//! ```text
//! p̄ = Σ w_j p_j / Σ w_j,   a_j = p_j − p̄,   A = Σ w_j a_j a_jᵀ
//! c(t) = Σ w_j x_j(t) / Σ w_j,   b_j(t) = x_j(t) − c(t),   B(t) = Σ w_j b_j a_jᵀ
//! x_h(t) = c(t) + (B(t) A⁺ + R(t) (1 − A A⁺)) (p_h − p̄)
//! ```
//!
//! the weighted affine map of the donors' layout onto their frame-t positions, on the directions
//! the donors span; on the others (donors on a plane or a line) the Kabsch rotation `R(t)` of
//! `a` onto `b` carries the offset rigidly, so a particle off a plane of donors stays off it.

use cordis_core::{Scene, Trajectory, Vec3};
use nalgebra::Matrix3;

/// How many nearest known particles every hidden one reads at least.
const MIN_DONORS: usize = 4;
/// Donors reach out to this factor times the `MIN_DONORS`-th nearest distance, so a symmetric
/// shell of neighbours is taken whole (the block's centre reads its 6 face and 12 edge
/// neighbours, not 4 of the 6 picked by index).
const SHELL: f64 = 1.5;

/// `traj` with the positions of every `hidden` particle replaced by the local deformation of
/// the known particles around it (module docs). `known[i]` says particle i's positions in
/// `traj` are data (tracked or fixed). None when no particle is known.
pub fn with_hidden_imputed(
    scene: &Scene,
    traj: &Trajectory,
    hidden: &[usize],
    known: &[bool],
) -> Option<Trajectory> {
    let layout: Vec<Vec3> = scene.particles.iter().map(|p| Vec3::from(p.pos)).collect();
    let maps: Vec<LocalMap> = hidden
        .iter()
        .map(|&h| LocalMap::new(&layout, known, h))
        .collect::<Option<_>>()?;
    let mut out = traj.clone();
    let mut frame = vec![Vec3::zeros(); traj.particles()];
    for t in 0..traj.frames() {
        traj.frame_into(t, &mut frame);
        // In place: a map reads its donors, known particles, never a hidden one.
        for (m, &h) in maps.iter().zip(hidden) {
            frame[h] = m.position(&frame);
        }
        out.set_frame(t, &frame);
    }
    Some(out)
}

/// A spread's eigenvalue below this fraction of its norm is a direction the donors do not span
/// (`1e-6` of squared lengths: donors thinner than 0.1 % of their size count as flat, so the
/// noise across a nearly flat layer is not amplified by size/thickness off it).
const FLAT: f64 = 1e-6;

/// How many directions a donors' spread `A` (symmetric, positive semi-definite) spans.
fn flat_rank(spread: &Matrix3<f64>) -> usize {
    let scale = spread.norm();
    spread
        .symmetric_eigenvalues()
        .iter()
        .filter(|&&l| l > FLAT * scale)
        .count()
}

/// Donors: (particle, normalised weight, layout offset from their weighted centre).
type Donors = Vec<(usize, f64, Vec3)>;

/// One hidden particle's donors and the parts of its map that do not change over frames.
struct LocalMap {
    donors: Donors,
    /// `A⁺` and the projector `A A⁺` on the donors' span.
    spread_inverse: Matrix3<f64>,
    span: Matrix3<f64>,
    /// `p_h − p̄`.
    offset: Vec3,
}

impl LocalMap {
    fn new(layout: &[Vec3], known: &[bool], hidden: usize) -> Option<Self> {
        let home = layout[hidden];
        let mut near: Vec<(usize, f64)> = (0..layout.len())
            .filter(|&j| known[j])
            .map(|j| (j, (layout[j] - home).norm()))
            .collect();
        if near.is_empty() {
            return None;
        }
        near.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
        let reach = SHELL * near[near.len().min(MIN_DONORS) - 1].1;
        let mut count = near.iter().take_while(|n| n.1 <= reach).count();
        // Donors on a line leave the turn about it free (Kabsch cannot fix it, and its SVD
        // would pick one per frame at random): the next nearest join until they span a plane,
        // their count doubling so that a long straight chain costs log n tries, not n.
        loop {
            let (donors, centre, spread) = Self::weighed(layout, &near[..count]);
            if count == near.len() || flat_rank(&spread) >= 2 {
                let scale = spread.norm().max(f64::MIN_POSITIVE);
                let spread_inverse = spread.pseudo_inverse(FLAT * scale).ok()?;
                return Some(LocalMap {
                    span: spread * spread_inverse,
                    spread_inverse,
                    offset: home - centre,
                    donors,
                });
            }
            count = (2 * count).min(near.len());
        }
    }

    /// The donors `near` (particle, layout distance) with their normalised weights `1/d²` and
    /// layout offsets, their weighted centre and spread `A`.
    fn weighed(layout: &[Vec3], near: &[(usize, f64)]) -> (Donors, Vec3, Matrix3<f64>) {
        // A donor laid out where the hidden particle is would take infinite weight: the
        // smallest positive distance stands in for it.
        let floor = near.iter().map(|n| n.1).find(|&d| d > 0.0).unwrap_or(1.0);
        let weights: Vec<f64> = near.iter().map(|n| 1.0 / n.1.max(floor).powi(2)).collect();
        let total: f64 = weights.iter().sum();
        let centre = near
            .iter()
            .zip(&weights)
            .map(|(n, w)| layout[n.0] * *w)
            .sum::<Vec3>()
            / total;
        let donors: Donors = near
            .iter()
            .zip(&weights)
            .map(|(n, &w)| (n.0, w / total, layout[n.0] - centre))
            .collect();
        let spread = donors.iter().map(|(_, w, a)| a * a.transpose() * *w).sum();
        (donors, centre, spread)
    }

    /// The hidden particle's position when the particles are at `frame`.
    fn position(&self, frame: &[Vec3]) -> Vec3 {
        let centre: Vec3 = self.donors.iter().map(|(j, w, _)| frame[*j] * *w).sum();
        let mut cross = Matrix3::zeros();
        for (j, w, a) in &self.donors {
            cross += (frame[*j] - centre) * a.transpose() * *w;
        }
        let affine = cross * self.spread_inverse;
        let rotation = kabsch(&cross.transpose());
        centre + (affine + rotation * (Matrix3::identity() - self.span)) * self.offset
    }
}

/// The rotation `R` carrying layout offsets `a` onto current offsets `b` best, from
/// `cross = Σ w a bᵀ` (Kabsch: with `cross = U S Vᵀ`, `R = V diag(1, 1, d) Uᵀ`, `d` excluding
/// reflections); the identity when that is not finite. Shared with the rigid start.
pub(super) fn kabsch(cross: &Matrix3<f64>) -> Matrix3<f64> {
    let svd = cross.svd(true, true);
    let (Some(u), Some(vt)) = (svd.u, svd.v_t) else {
        return Matrix3::identity();
    };
    let d = (vt.transpose() * u.transpose()).determinant().signum();
    let rotation = vt.transpose() * Matrix3::from_diagonal(&Vec3::new(1.0, 1.0, d)) * u.transpose();
    match rotation.iter().all(|x| x.is_finite()) {
        true => rotation,
        false => Matrix3::identity(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use approx::assert_relative_eq;
    use cordis_core::Particle;

    /// A 3 × 3 × 3 lattice of pitch 0.1 m.
    fn block() -> Scene {
        let mut s = Scene::new(0.01);
        for z in 0..3 {
            for y in 0..3 {
                for x in 0..3 {
                    let p = [0.1 * x as f64, 0.1 * y as f64, 0.1 * z as f64];
                    s.add_particle(Particle::new(0.02, p));
                }
            }
        }
        s
    }

    /// Every particle moved by `f(p)` at each of 4 frames scaled by `t`.
    fn moved(s: &Scene, f: impl Fn(Vec3, f64) -> Vec3) -> Trajectory {
        let n = s.particles.len();
        let mut data = Vec::new();
        for t in 0..4 {
            for p in &s.particles {
                data.extend(f(Vec3::from(p.pos), t as f64).iter());
            }
        }
        Trajectory::from_flat(4, n, data).unwrap()
    }

    /// `p` turned by 0.5 t rad about the x axis.
    fn turn_about_x(p: Vec3, t: f64) -> Vec3 {
        let a = 0.5 * t;
        Matrix3::new(1.0, 0.0, 0.0, 0.0, a.cos(), -a.sin(), 0.0, a.sin(), a.cos()) * p
    }

    fn hidden_error(s: &Scene, truth: &Trajectory, hidden: &[usize]) -> f64 {
        let mut known = vec![true; s.particles.len()];
        let mut garbled = truth.clone();
        let mut frame = vec![Vec3::zeros(); s.particles.len()];
        for t in 0..truth.frames() {
            truth.frame_into(t, &mut frame);
            for &h in hidden {
                frame[h] = Vec3::new(9.0, 9.0, 9.0);
            }
            garbled.set_frame(t, &frame);
        }
        for &h in hidden {
            known[h] = false;
        }
        let out = with_hidden_imputed(s, &garbled, hidden, &known).unwrap();
        let mut worst: f64 = 0.0;
        for t in 0..truth.frames() {
            for &h in hidden {
                worst = worst.max((out.pos(t, h) - truth.pos(t, h)).norm());
            }
        }
        worst
    }

    #[test]
    fn any_affine_motion_is_imputed_exactly() {
        let s = block();
        let shear = |p: Vec3, t: f64| {
            let m = Matrix3::new(1.0, 0.3 * t, 0.0, 0.0, 1.0 + 0.1 * t, 0.0, 0.2, 0.0, 0.9);
            m * p + Vec3::new(0.05 * t, -0.02, 0.1)
        };
        let truth = moved(&s, shear);
        // The centre, a face centre and a corner (its donors lie on one side only).
        assert!(hidden_error(&s, &truth, &[13]) < 1e-12);
        assert!(hidden_error(&s, &truth, &[13, 22]) < 1e-12);
        assert!(hidden_error(&s, &truth, &[26]) < 1e-12);
    }

    #[test]
    fn a_particle_off_its_donors_plane_turns_with_them() {
        // A flat 3 × 3 sheet at z = 0 and one particle 0.1 m above its centre; the whole thing
        // turns a quarter about x: the imputed particle must leave the sheet's plane with it.
        let mut s = Scene::new(0.01);
        for y in 0..3 {
            for x in 0..3 {
                s.add_particle(Particle::new(0.02, [0.1 * x as f64, 0.1 * y as f64, 0.0]));
            }
        }
        s.add_particle(Particle::new(0.02, [0.1, 0.1, 0.1]));
        let truth = moved(&s, turn_about_x);
        assert!(hidden_error(&s, &truth, &[9]) < 1e-12);
    }

    #[test]
    fn donors_on_a_line_take_the_next_nearest_until_they_span_a_plane() {
        // Five particles on the x axis and two 0.5 m off it; the hidden one 5 cm off the axis.
        // The whole turns about x: the five nearest, on the axis, cannot see that turn.
        let mut s = Scene::new(0.01);
        for x in 0..5 {
            s.add_particle(Particle::new(0.02, [0.1 * x as f64, 0.0, 0.0]));
        }
        s.add_particle(Particle::new(0.02, [0.0, 0.5, 0.0]));
        s.add_particle(Particle::new(0.02, [0.4, 0.5, 0.0]));
        s.add_particle(Particle::new(0.02, [0.2, 0.05, 0.0]));
        let truth = moved(&s, turn_about_x);
        assert!(hidden_error(&s, &truth, &[7]) < 1e-12);
    }

    #[test]
    fn no_known_particle_gives_no_imputation() {
        let s = block();
        let traj = moved(&s, |p, _| p);
        let hidden: Vec<usize> = (0..27).collect();
        assert!(with_hidden_imputed(&s, &traj, &hidden, &[false; 27]).is_none());
        // Known particles keep their positions bit for bit.
        let mut known = vec![true; 27];
        known[13] = false;
        let out = with_hidden_imputed(&s, &traj, &[13], &known).unwrap();
        for t in 0..4 {
            for i in (0..27).filter(|&i| i != 13) {
                assert_relative_eq!(out.pos(t, i), traj.pos(t, i), epsilon = 0.0);
            }
        }
    }
}
