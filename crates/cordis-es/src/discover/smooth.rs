//! Noisy positions: a Savitzky–Golay filter before differentiating.
//!
//! Second differences amplify position noise S into acceleration noise `√6 S/dt²`, mostly at
//! high frequency, while a spring network's motion lives far below the sampling rate. A cubic
//! Savitzky–Golay filter (window 2h+1 frames) keeps polynomials up to degree 3 and removes most
//! of that noise. The half-width h is the largest whose residual `x - smooth(x)` stays within
//! what pure noise would leave (`S² (1 - c0)`, c0 the filter's centre weight) plus a small
//! allowance for the signal (10% of S in rms): the motion itself is barely touched. The `h`
//! first and last frames, which the filter cannot reach, are dropped; fixed particles are set
//! to their mean position.

use cordis_core::{Trajectory, Vec3};
use nalgebra::{DMatrix, DVector};

/// Half-widths tried, frames.
const HALF_WIDTHS: [usize; 10] = [2, 3, 4, 5, 6, 8, 10, 13, 16, 20];

/// Cubic Savitzky–Golay smoothing weights, `c[k + h]` for k in -h..=h.
fn weights(h: usize) -> Vec<f64> {
    let hf = h as f64;
    let den = (2.0 * hf + 1.0) * (4.0 * hf * hf + 4.0 * hf - 3.0);
    (0..=2 * h)
        .map(|k| {
            let k = k as f64 - hf;
            (3.0 * (3.0 * hf * hf + 3.0 * hf - 1.0) - 15.0 * k * k) / den
        })
        .collect()
}

/// Half-width of the smoothing `c'` inside the acceleration kernel for a position smoothing of
/// half-width `h`: ⌊1.5 h⌋ + 1 (module docs; at `h` itself the orthogonality costs up to 80 ×
/// the noise variance at h = 2, at 1.5 h + 1 it costs 0.9–5 × that of `D² ∘ S`).
pub fn acceleration_half_width(h: usize) -> usize {
    h + h / 2 + 1
}

/// The acceleration kernel `g = D² c'` (over frames `-(h₂+1) ..= h₂+1`, h₂ from
/// [`acceleration_half_width`]) uncorrelated with the position smoothing `S` of half-width `h`
/// (module docs): `c'` keeps cubics, has the 4th moment of `S`'s own weights (the same
/// smoothing bias), and `Σ g_k c_k = Σ g_k c_{k+1} = 0` (no covariance with the smoothed
/// position at the frame and the one before, which the features read); of those, the one of
/// least noise `Σ g²`. `None` when the constraints are singular.
pub fn acceleration_kernel_uncorrelated(h: usize) -> Option<Vec<f64>> {
    let h2 = acceleration_half_width(h);
    let (n, big) = (2 * h2 + 1, 2 * h2 + 3);
    let c = weights(h);
    // D: c' (n) → g (n + 2).
    let mut d = DMatrix::zeros(big, n);
    for j in 0..n {
        d[(j, j)] += 1.0;
        d[(j + 1, j)] -= 2.0;
        d[(j + 2, j)] += 1.0;
    }
    // The smoothing weights at the frame (f) and at the frame before (f₋) on g's support.
    let (mut f, mut f_prev) = (DVector::zeros(big), DVector::zeros(big));
    for (k, w) in c.iter().enumerate() {
        f[h2 + 1 - h + k] = *w;
        f_prev[h2 - h + k] = *w;
    }
    let moment =
        |p: i32| -> DVector<f64> { DVector::from_fn(n, |j, _| (j as f64 - h2 as f64).powi(p)) };
    let m4: f64 = c
        .iter()
        .enumerate()
        .map(|(k, w)| w * (k as f64 - h as f64).powi(4))
        .sum();
    let rows = [
        moment(0),
        moment(1),
        moment(2),
        moment(3),
        moment(4),
        d.transpose() * &f,
        d.transpose() * &f_prev,
    ];
    let b = [1.0, 0.0, 0.0, 0.0, m4, 0.0, 0.0];
    let m = rows.len();
    // KKT: [2 DᵀD  Cᵀ; C  0] [c'; λ] = [0; b].
    let mut kkt = DMatrix::zeros(n + m, n + m);
    kkt.view_mut((0, 0), (n, n))
        .copy_from(&(d.transpose() * &d * 2.0));
    let mut rhs = DVector::zeros(n + m);
    for (r, (row, v)) in rows.iter().zip(b).enumerate() {
        for j in 0..n {
            kkt[(n + r, j)] = row[j];
            kkt[(j, n + r)] = row[j];
        }
        rhs[n + r] = v;
    }
    let sol = kkt.lu().solve(&rhs)?;
    let g = &d * sol.rows(0, n);
    let ok = g.iter().all(|v| v.is_finite())
        && (g.dot(&f)).abs() < 1e-9 * g.norm()
        && (g.dot(&f_prev)).abs() < 1e-9 * g.norm();
    ok.then(|| g.iter().copied().collect())
}

/// The velocity kernel `k` (over `g`'s support, `g` the acceleration kernel of
/// [`acceleration_kernel_uncorrelated`]) that a damper's feature reads from the raw positions:
/// it has the moments 0–4 of the smoothed backward difference `S x(t) − S x(t−1)` (the
/// scheme's velocity, with the smoothing's bias), and `Σ k_s c_s = Σ k_s c_{s+1} = Σ k_s g_s =
/// 0`: no covariance with the smoothed positions at the frame and the one before (the spring
/// features' noise, which stands in the equation's error) nor with the particle's own
/// acceleration. Read from the smoothed positions instead, a damper's velocity shared the
/// particle's own smoothed noise with the error, and spurious dampers were kept (issue 20:
/// 9 % extra links at noise 1e-4). Of those kernels, the one of least noise `Σ k²`.
pub fn velocity_kernel_uncorrelated(h: usize, g: &[f64]) -> Option<Vec<f64>> {
    let n = g.len();
    let reach = n / 2;
    let c = weights(h);
    // The smoothing at the frame (f) and the one before (f₋) on the support, and the smoothed
    // backward difference f − f₋.
    let (mut f, mut f_prev) = (DVector::zeros(n), DVector::zeros(n));
    for (k, w) in c.iter().enumerate() {
        f[reach - h + k] = *w;
        f_prev[reach - h - 1 + k] = *w;
    }
    let diff = &f - &f_prev;
    let moment =
        |p: i32| -> DVector<f64> { DVector::from_fn(n, |j, _| (j as f64 - reach as f64).powi(p)) };
    let mut rows: Vec<DVector<f64>> = (0..5).map(moment).collect();
    let mut b: Vec<f64> = rows.iter().map(|r| r.dot(&diff)).collect();
    rows.extend([f.clone(), f_prev.clone(), DVector::from_column_slice(g)]);
    b.extend([0.0, 0.0, 0.0]);
    let m = rows.len();
    // KKT: [2 I  Cᵀ; C  0] [k; λ] = [0; b].
    let mut kkt = DMatrix::zeros(n + m, n + m);
    for j in 0..n {
        kkt[(j, j)] = 2.0;
    }
    let mut rhs = DVector::zeros(n + m);
    for (r, (row, v)) in rows.iter().zip(&b).enumerate() {
        for j in 0..n {
            kkt[(n + r, j)] = row[j];
            kkt[(j, n + r)] = row[j];
        }
        rhs[n + r] = *v;
    }
    let sol = kkt.lu().solve(&rhs)?;
    let k: Vec<f64> = sol.rows(0, n).iter().copied().collect();
    let norm = k.iter().map(|v| v * v).sum::<f64>().sqrt();
    let dot = |a: &DVector<f64>| a.iter().zip(&k).map(|(x, y)| x * y).sum::<f64>();
    let ok = k.iter().all(|v| v.is_finite())
        && dot(&f).abs() < 1e-9 * norm
        && dot(&f_prev).abs() < 1e-9 * norm
        && g.iter().zip(&k).map(|(x, y)| x * y).sum::<f64>().abs() < 1e-9 * norm;
    ok.then_some(k)
}

/// Accelerations read from the raw positions by [`acceleration_kernel_uncorrelated`], at the
/// frames of a trajectory smoothed with half-width `h` (its frame t is raw frame t + h).
pub struct Accelerations {
    /// The frames of the smoothed trajectory that have an acceleration: `first..last`.
    pub first: usize,
    pub last: usize,
    /// Per such frame and particle (`(t - first) · particles + i`), m/s².
    values: Vec<Vec3>,
    /// The same frames' velocities by [`velocity_kernel_uncorrelated`], m/s (dampers' features).
    velocities: Vec<Vec3>,
    particles: usize,
    /// `Σ g²`: a coordinate's acceleration noise has variance `σ² gain / dt⁴` for white
    /// position noise σ.
    pub gain: f64,
    /// Autocorrelations at lags 0, 1, … of the acceleration kernel (`Σ_k g_k g_{k+l}`) and of
    /// the position smoothing (`Σ_k c_k c_{k+l}`): the covariance, over frames, of the noise
    /// the accelerations and the smoothed positions carry, per σ².
    pub accel_autocorrelation: Vec<f64>,
    pub smooth_autocorrelation: Vec<f64>,
}

fn autocorrelation(w: &[f64]) -> Vec<f64> {
    (0..w.len())
        .map(|l| w.iter().zip(&w[l..]).map(|(a, b)| a * b).sum())
        .collect()
}

impl Accelerations {
    /// Particle `i`'s acceleration at smoothed frame `t` (in `first..last`), m/s².
    pub fn at(&self, t: usize, i: usize) -> Vec3 {
        self.values[(t - self.first) * self.particles + i]
    }

    /// Particle `i`'s velocity at smoothed frame `t` (in `first..last`), m/s.
    pub fn velocity(&self, t: usize, i: usize) -> Vec3 {
        self.velocities[(t - self.first) * self.particles + i]
    }

    /// From the raw trajectory for a smoothing of half-width `h` (`None` when the trajectory
    /// leaves fewer than 4 frames or the kernel is singular).
    pub fn new(raw: &Trajectory, h: usize, dt: f64) -> Option<Accelerations> {
        let g = acceleration_kernel_uncorrelated(h)?;
        let kv = velocity_kernel_uncorrelated(h, &g)?;
        let reach = g.len() / 2;
        let (frames, n) = (raw.frames(), raw.particles());
        // Smoothed frame t is raw t + h; the kernel reaches raw t + h ± reach.
        let first = reach.saturating_sub(h).max(1);
        let last = frames
            .checked_sub(h + reach)?
            .min(frames.checked_sub(2 * h + 1)?);
        if last < first + 4 {
            return None;
        }
        let mut values = Vec::with_capacity((last - first) * n);
        let mut velocities = Vec::with_capacity((last - first) * n);
        for t in first..last {
            let centre = t + h;
            for i in 0..n {
                let (mut a, mut v) = (Vec3::zeros(), Vec3::zeros());
                for (k, (w, u)) in g.iter().zip(&kv).enumerate() {
                    let x = raw.pos(centre + k - reach, i);
                    a += x * *w;
                    v += x * *u;
                }
                values.push(a / (dt * dt));
                velocities.push(v / dt);
            }
        }
        Some(Accelerations {
            first,
            last,
            values,
            velocities,
            particles: n,
            gain: g.iter().map(|w| w * w).sum(),
            accel_autocorrelation: autocorrelation(&g),
            smooth_autocorrelation: autocorrelation(&weights(h)),
        })
    }
}

/// The first raw frame's position of particle `i` and the one a frame before it (m), from the
/// cubic least-squares fit to raw frames `0 ..= 2h` evaluated at frames 0 and −1: the
/// Savitzky–Golay filter's end-point form. [`smooth`] drops the `h` first frames, which its
/// centred window cannot reach, so a scene started from the first smoothed frame would start
/// `h` frames into the take; this starts it at the take's own first frame, with the same
/// polynomial degree and window as the smoothing. `None` when the take has fewer than `2h + 1`
/// frames.
pub fn start_positions(traj: &Trajectory, i: usize, h: usize) -> Option<(Vec3, Vec3)> {
    let len = 2 * h + 1;
    if traj.frames() < len.max(4) {
        return None;
    }
    let basis = |t: f64| [1.0, t, t * t, t * t * t];
    let mut normal = nalgebra::Matrix4::<f64>::zeros();
    let mut rhs = nalgebra::Matrix4x3::<f64>::zeros();
    let x0 = traj.pos(0, i);
    for t in 0..len {
        let b = nalgebra::Vector4::from(basis(t as f64));
        normal += b * b.transpose();
        // Offsets from frame 0: the fit's rounding scales with the motion, not the position.
        let d = traj.pos(t, i) - x0;
        rhs += b * nalgebra::RowVector3::new(d.x, d.y, d.z);
    }
    let coef = normal.cholesky()?.solve(&rhs);
    let at = |t: f64| {
        let b = nalgebra::RowVector4::from(basis(t));
        let v = b * coef;
        x0 + Vec3::new(v[0], v[1], v[2])
    };
    Some((at(0.0), at(-1.0)))
}

fn apply(traj: &Trajectory, fixed: &[bool], h: usize) -> (Trajectory, f64) {
    let (frames, n) = (traj.frames(), traj.particles());
    let c = weights(h);
    let out_frames = frames - 2 * h;
    let src = traj.as_flat();
    let mut data = vec![0.0; out_frames * n * 3];
    let (mut sq, mut count) = (0.0, 0usize);
    for i in 0..n {
        for ax in 0..3 {
            let at = |t: usize| src[(t * n + i) * 3 + ax];
            if fixed[i] {
                let mean = (0..frames).map(at).sum::<f64>() / frames as f64;
                for t in 0..out_frames {
                    data[(t * n + i) * 3 + ax] = mean;
                }
                continue;
            }
            for t in 0..out_frames {
                let v: f64 = c.iter().enumerate().map(|(k, w)| w * at(t + k)).sum();
                let r = at(t + h) - v;
                sq += r * r;
                count += 1;
                data[(t * n + i) * 3 + ax] = v;
            }
        }
    }
    let mut out = Trajectory::from_flat(out_frames, n, data)
        .unwrap_or_else(|_| Trajectory::zeros(out_frames, n));
    out.dt = traj.dt;
    (out, (sq / count.max(1) as f64).sqrt())
}

/// The smoothed trajectory (module docs) and the half-width used, or `None` when the
/// trajectory is too short for the smallest filter.
pub fn smooth(traj: &Trajectory, fixed: &[bool], noise: f64) -> Option<(Trajectory, usize)> {
    let mut best = None;
    for &h in &HALF_WIDTHS {
        if traj.frames() < 2 * h + 8 {
            break;
        }
        let (out, rms) = apply(traj, fixed, h);
        let c0 = weights(h)[h];
        let allowed = (noise * noise * (1.0 - c0) + (0.1 * noise).powi(2)).sqrt();
        if best.is_some() && rms > allowed {
            break;
        }
        best = Some((out, h));
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The end-point fit reproduces a cubic at frames 0 and −1, and on noisy frames lands
    /// within its own spread of the truth (guards the discovered scene's start: the smoothed
    /// trajectory starts h frames into the take).
    #[test]
    fn the_start_positions_extrapolate_cubics_to_frame_zero_and_before() {
        let cubic = |t: f64| {
            Vec3::new(
                0.3 + 0.02 * t - 1e-3 * t * t + 2e-5 * t * t * t,
                -1.0,
                0.5 * t,
            )
        };
        for h in HALF_WIDTHS {
            let frames = 2 * h + 9;
            let data: Vec<f64> = (0..frames)
                .flat_map(|t| {
                    let x = cubic(t as f64);
                    [x.x, x.y, x.z]
                })
                .collect();
            let traj = Trajectory::from_flat(frames, 1, data).unwrap();
            let (x0, xm1) = start_positions(&traj, 0, h).unwrap();
            assert!((x0 - cubic(0.0)).norm() < 1e-12, "h {h}: {x0:?}");
            assert!((xm1 - cubic(-1.0)).norm() < 1e-12, "h {h}: {xm1:?}");
        }
        let short = Trajectory::from_flat(4, 1, vec![0.0; 12]).unwrap();
        assert!(start_positions(&short, 0, 2).is_none());
    }

    /// The dampers' velocity kernel: the scheme's backward difference on cubics, and no
    /// covariance with the smoothed positions at the frame and the one before, nor with the
    /// acceleration kernel (the equation's error).
    #[test]
    fn the_velocity_kernel_is_the_backward_difference_on_cubics_and_uncorrelated() {
        for h in HALF_WIDTHS {
            let g = acceleration_kernel_uncorrelated(h).expect("acceleration kernel");
            let k = velocity_kernel_uncorrelated(h, &g).expect("velocity kernel");
            let reach = k.len() / 2;
            let c = weights(h);
            let norm = k.iter().map(|w| w * w).sum::<f64>().sqrt();
            let with_c = |shift: usize| -> f64 {
                c.iter()
                    .enumerate()
                    .map(|(j, w)| w * k[reach - h - shift + j])
                    .sum()
            };
            let with_g: f64 = g.iter().zip(&k).map(|(a, b)| a * b).sum();
            for v in [with_c(0), with_c(1), with_g] {
                assert!(v.abs() < 1e-10 * norm, "h {h}: {v}");
            }
            let cubic = |t: f64| 0.3 - 2.0 * t + 0.7 * t * t - 0.05 * t * t * t;
            let v: f64 = k
                .iter()
                .enumerate()
                .map(|(j, w)| w * cubic(j as f64 - reach as f64))
                .sum();
            assert!((v - (cubic(0.0) - cubic(-1.0))).abs() < 1e-8, "h {h}: {v}");
        }
    }

    #[test]
    fn the_acceleration_kernel_is_uncorrelated_with_the_smoothing_and_exact_on_quartics() {
        for h in HALF_WIDTHS {
            let g = acceleration_kernel_uncorrelated(h).expect("kernel");
            let reach = (g.len() / 2) as f64;
            let c = weights(h);
            let off = g.len() / 2 - h;
            let at = |k: usize| g[off + k];
            let lag0: f64 = c.iter().enumerate().map(|(k, w)| w * at(k)).sum();
            let lag1: f64 = c.iter().enumerate().map(|(k, w)| w * g[off - 1 + k]).sum();
            let norm = g.iter().map(|w| w * w).sum::<f64>().sqrt();
            assert!(
                lag0.abs() < 1e-10 * norm && lag1.abs() < 1e-10 * norm,
                "h {h}"
            );
            // The second difference of a cubic is exact: 2·a₂ + 6·a₃·t at t = 0.
            let cubic = |t: f64| 0.3 - 2.0 * t + 0.7 * t * t - 0.05 * t * t * t;
            let v: f64 = g
                .iter()
                .enumerate()
                .map(|(k, w)| w * cubic(k as f64 - reach))
                .sum();
            assert!((v - 1.4).abs() < 1e-8, "h {h}: {v}");
        }
    }

    #[test]
    fn weights_keep_cubics_and_sum_to_one() {
        for h in HALF_WIDTHS {
            let c = weights(h);
            assert!((c.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            let cubic = |t: f64| 0.3 - 2.0 * t + 0.7 * t * t - 0.05 * t * t * t;
            let v: f64 = c.iter().enumerate().map(|(k, w)| w * cubic(k as f64)).sum();
            assert!((v - cubic(h as f64)).abs() < 1e-9, "h {h}");
        }
    }
}
