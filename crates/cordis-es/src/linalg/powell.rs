//! Powell's conjugate-direction descent with bounded Brent line searches: the thesis' local
//! "descente" (Annexe 1: "méthode de Powell"), applied to the best individual. Derivative-free,
//! and exact on a quadratic after n sweeps with exact line searches.

use super::line_search::brent;

/// Result of a descent.
#[derive(Clone, Debug)]
pub struct Descent {
    pub x: Vec<f64>,
    pub fx: f64,
    pub evals: usize,
}

/// Settings of a descent: the box `[lo, hi]`, initial steps (one per coordinate), and the
/// stop: a sweep improving by less than `rtol` (relative), or `max_evals` spent.
#[derive(Clone, Copy, Debug)]
pub struct Powell<'a> {
    pub lo: &'a [f64],
    pub hi: &'a [f64],
    pub step: &'a [f64],
    pub rtol: f64,
    pub max_evals: usize,
}

/// Minimises `f` from `x0` (where it is `fx0`) with the settings `o`.
pub fn powell(mut f: impl FnMut(&[f64]) -> f64, x0: &[f64], fx0: f64, o: Powell) -> Descent {
    let Powell {
        lo,
        hi,
        step,
        rtol,
        max_evals,
    } = o;
    let n = x0.len();
    let mut x = x0.to_vec();
    let mut fx = fx0;
    let mut evals = 0usize;
    let mut dirs: Vec<Vec<f64>> = (0..n)
        .map(|i| {
            let mut d = vec![0.0; n];
            d[i] = step[i].max(1e-12);
            d
        })
        .collect();
    let mut trial = vec![0.0; n];
    while evals < max_evals {
        let (x_start, f_start) = (x.clone(), fx);
        let (mut best_drop, mut best_dir) = (0.0, 0);
        for (k, d) in dirs.iter().enumerate() {
            let before = fx;
            let (t, ft, used) = line_min(&mut f, &x, fx, d, lo, hi, &mut trial, max_evals - evals);
            evals += used;
            if ft < fx {
                for i in 0..n {
                    x[i] = (x[i] + t * d[i]).clamp(lo[i], hi[i]);
                }
                fx = ft;
            }
            if before - fx > best_drop {
                best_drop = before - fx;
                best_dir = k;
            }
            if evals >= max_evals {
                break;
            }
        }
        let converged = 2.0 * (f_start - fx) <= rtol * (f_start.abs() + fx.abs()) + 1e-300;
        if converged || evals >= max_evals {
            break;
        }
        // Replace the direction of largest decrease by the sweep's net move (Powell 1964).
        let net: Vec<f64> = (0..n).map(|i| x[i] - x_start[i]).collect();
        if net.iter().any(|v| *v != 0.0) {
            let (t, ft, used) =
                line_min(&mut f, &x, fx, &net, lo, hi, &mut trial, max_evals - evals);
            evals += used;
            if ft < fx {
                for i in 0..n {
                    x[i] = (x[i] + t * net[i]).clamp(lo[i], hi[i]);
                }
                fx = ft;
            }
            dirs.remove(best_dir);
            dirs.push(net);
        }
    }
    Descent { x, fx, evals }
}

/// Minimises `f(x + t d)` over the t keeping x + t d in the box: bracket from t = ±1, then
/// Brent's parabolic/golden search. Returns (t, f, evaluations).
#[allow(clippy::too_many_arguments)]
fn line_min(
    f: &mut impl FnMut(&[f64]) -> f64,
    x: &[f64],
    fx: f64,
    d: &[f64],
    lo: &[f64],
    hi: &[f64],
    trial: &mut [f64],
    budget: usize,
) -> (f64, f64, usize) {
    // Feasible interval of t.
    let (mut tmin, mut tmax) = (f64::NEG_INFINITY, f64::INFINITY);
    for i in 0..x.len() {
        if d[i] > 0.0 {
            tmin = tmin.max((lo[i] - x[i]) / d[i]);
            tmax = tmax.min((hi[i] - x[i]) / d[i]);
        } else if d[i] < 0.0 {
            tmin = tmin.max((hi[i] - x[i]) / d[i]);
            tmax = tmax.min((lo[i] - x[i]) / d[i]);
        }
    }
    if !(tmin <= 0.0 && tmax >= 0.0) || tmax - tmin <= 0.0 {
        return (0.0, fx, 0);
    }
    let mut evals = 0usize;
    let mut eval = |t: f64, evals: &mut usize| -> f64 {
        *evals += 1;
        for i in 0..x.len() {
            trial[i] = (x[i] + t * d[i]).clamp(lo[i], hi[i]);
        }
        let v = f(trial);
        if v.is_nan() {
            f64::INFINITY
        } else {
            v
        }
    };
    // Bracket a minimum: a < b < c with f(b) ≤ f(a), f(c).
    let (mut a, mut fa) = (0.0, fx);
    let mut b = 1.0f64.min(tmax);
    if b <= 0.0 {
        b = (-1.0f64).max(tmin);
    }
    let mut fb = eval(b, &mut evals);
    if fb > fa {
        std::mem::swap(&mut a, &mut b);
        std::mem::swap(&mut fa, &mut fb);
    }
    // Now f(b) ≤ f(a): walk from a through b.
    let mut c;
    let mut fc;
    loop {
        c = b + 1.618_033_988_75 * (b - a);
        c = c.clamp(tmin, tmax);
        if c == b {
            // Against the boundary: the minimum is there.
            return if fb < fx {
                (b, fb, evals)
            } else {
                (0.0, fx, evals)
            };
        }
        fc = eval(c, &mut evals);
        if fc >= fb || evals >= budget {
            break;
        }
        a = b;
        fa = fb;
        b = c;
        fb = fc;
    }
    let _ = fa;
    let (lo_t, hi_t) = if a < c { (a, c) } else { (c, a) };
    let (t, ft) = brent(
        |t| (evals < budget).then(|| eval(t, &mut evals)),
        lo_t,
        b,
        fb,
        hi_t,
        1e-14,
        1e-10,
        100,
    );
    if ft < fx {
        (t, ft, evals)
    } else {
        (0.0, fx, evals)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn powell_solves_an_ill_conditioned_rotated_quadratic() {
        let f = |x: &[f64]| {
            let (u, v) = (x[0] + x[1] - 3.0, x[0] - x[1] + 1.0);
            1000.0 * u * u + v * v + (x[2] - 0.5).powi(2)
        };
        let o = Powell {
            lo: &[-10.0; 3],
            hi: &[10.0; 3],
            step: &[0.1; 3],
            rtol: 1e-15,
            max_evals: 20_000,
        };
        let d = powell(f, &[0.0, 0.0, 0.0], f(&[0.0, 0.0, 0.0]), o);
        assert!(d.fx < 1e-12, "f = {}", d.fx);
        approx::assert_abs_diff_eq!(d.x[0], 1.0, epsilon = 1e-6);
        approx::assert_abs_diff_eq!(d.x[1], 2.0, epsilon = 1e-6);
    }

    #[test]
    fn powell_stays_in_the_box() {
        let f = |x: &[f64]| (x[0] - 5.0).powi(2) + (x[1] + 5.0).powi(2);
        let o = Powell {
            lo: &[-1.0; 2],
            hi: &[1.0; 2],
            step: &[0.1; 2],
            rtol: 1e-12,
            max_evals: 5000,
        };
        let d = powell(f, &[0.0, 0.0], f(&[0.0, 0.0]), o);
        approx::assert_abs_diff_eq!(d.x[0], 1.0, epsilon = 1e-9);
        approx::assert_abs_diff_eq!(d.x[1], -1.0, epsilon = 1e-9);
    }
}
