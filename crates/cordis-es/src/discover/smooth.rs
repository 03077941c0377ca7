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

use cordis_core::Trajectory;

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
