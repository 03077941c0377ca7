//! Bounded one-dimensional minimisation: Brent's method, the line search of Powell's descent
//! ([`super::powell`]) and of `hybrid`'s profile search ([`crate::exact::profile`]).

/// (3 − √5) / 2: the golden section.
const CGOLD: f64 = 0.381_966_011_250_105;

/// Brent's minimisation on `[a, c]` from an interior point `x` where `f` is `fx`, the least
/// known (Numerical Recipes' `brent`: parabolic steps safeguarded by golden sections). The
/// tolerance is `abs + rel·|x|`; at most `max_steps` steps, and it stops early when `f` returns
/// `None` (its caller's budget is spent). A parabolic step that is not finite (a candidate cost
/// +inf) falls back to a golden section. Returns the least point seen and its value. Shared by
/// Powell's line searches and `hybrid`'s profile search
/// ([`crate::strategies::profile`]).
#[allow(clippy::too_many_arguments)]
pub(crate) fn brent(
    mut f: impl FnMut(f64) -> Option<f64>,
    a: f64,
    x: f64,
    fx: f64,
    c: f64,
    abs: f64,
    rel: f64,
    max_steps: usize,
) -> (f64, f64) {
    let (mut a, mut b) = (a, c);
    let (mut x, mut w, mut v) = (x, x, x);
    let (mut fx, mut fw, mut fv) = (fx, fx, fx);
    let mut d: f64 = 0.0;
    let mut e: f64 = 0.0;
    for _ in 0..max_steps {
        let xm = 0.5 * (a + b);
        let tol1 = rel * x.abs() + abs;
        let tol2 = 2.0 * tol1;
        if (x - xm).abs() <= tol2 - 0.5 * (b - a) {
            break;
        }
        let mut golden = true;
        if e.abs() > tol1 {
            let r = (x - w) * (fx - fv);
            let mut q = (x - v) * (fx - fw);
            let mut p = (x - v) * q - (x - w) * r;
            q = 2.0 * (q - r);
            if q > 0.0 {
                p = -p;
            }
            q = q.abs();
            let etemp = e;
            e = d;
            let step = p / q;
            if step.is_finite()
                && p.abs() < (0.5 * q * etemp).abs()
                && p > q * (a - x)
                && p < q * (b - x)
            {
                d = step;
                let u = x + d;
                if u - a < tol2 || b - u < tol2 {
                    d = if xm >= x { tol1 } else { -tol1 };
                }
                golden = false;
            }
        }
        if golden {
            e = if x >= xm { a - x } else { b - x };
            d = CGOLD * e;
        }
        let u = if d.abs() >= tol1 {
            x + d
        } else {
            x + if d >= 0.0 { tol1 } else { -tol1 }
        };
        let Some(fu) = f(u) else {
            break;
        };
        if fu <= fx {
            if u >= x {
                a = x;
            } else {
                b = x;
            }
            (v, fv, w, fw, x, fx) = (w, fw, x, fx, u, fu);
        } else {
            if u < x {
                a = u;
            } else {
                b = u;
            }
            if fu <= fw || w == x {
                (v, fv, w, fw) = (w, fw, u, fu);
            } else if fu <= fv || v == x || v == w {
                (v, fv) = (u, fu);
            }
        }
    }
    (x, fx)
}
