//! A TGR (SPEC §2.5) in the exact solvers: why its force is linear in (l0, Z) once its K and
//! its tendon are fixed, so that `least-squares` can solve l0 and Z exactly and `hybrid` only
//! has to search K (and any unknown tendon parameter).
//!
//! The short cost drives the tendon along the observed frames ([`crate::cost::hidden`]):
//!
//! ```text
//! f(n)   = K (L(n) - l0 - y(n)) + Z s(n)
//! y(n+1) = 2y(n) - y(n-1) + dt²/m_t (S(t_n) + f(n) - K_t y(n) - Z_t (y(n) - y(n-1))/dt)
//! ```
//!
//! with `y(0) = y(-1) = 0` and `L`, `s` (length, m; elongation speed, m/s) observed, not
//! predicted. For fixed K, m_t, K_t, Z_t this is a linear recursion in y driven by
//! `S + K L` (known), `-K l0` and `Z s`, so `y = y₀ + l0 y_l + Z y_Z` with the three series of
//! [`series`], and `f(n) = K (L - y₀) - l0 K (1 + y_l) + Z (s - K y_Z)` is affine in (l0, Z).
//! The exact solvers do not build these series by hand: [`super::exact::assemble`] runs the
//! cost's own TGR kernel on probe parameter vectors (l0 = 1; Z = 1; both 0), each with its own
//! tendon driven along the observed frames, so the columns are the cost's arithmetic; the
//! series are the proof that this is exact (tested below to 1e-12).

use cordis_core::{LinkKind, Scene};

use super::exact::Col;
use crate::space::Unknown;

/// Offsets of l0 and Z in a TGR type's parameters (K, l0, Z, m_t, K_t, Z_t).
const LINEAR: [usize; 2] = [1, 2];

/// The θ columns of TGR type `t`: its rest length and its damping (at the K and tendon in
/// the parameter vector the system is assembled at).
pub(crate) fn cols(t: usize) -> [Col; 2] {
    [Col::Rest(t), Col::Z(t)]
}

/// True for a TGR's K or tendon parameter: the force depends on them through the tendon's
/// recursion, not linearly, so `hybrid` searches them (`least-squares` refuses them).
pub(crate) fn is_nonlinear(scene: &Scene, u: &Unknown) -> bool {
    let Some(t) = u.type_index else {
        return false;
    };
    if scene.types[t].kind != LinkKind::Tgr {
        return false;
    }
    let o = scene.param_layout().type_offsets[t];
    !LINEAR.contains(&(u.slot - o))
}

/// The tendon's three series `(y₀, y_l, y_Z)(n)`, n = 0 … `l.len()` - 1 (m, m per m of l0,
/// m per N·s/m of Z) into `out`, for stiffness `k` (N/m), tendon `(m_t, K_t, Z_t)`, time step
/// `dt` (s), command `command(n)` = S(n dt) (N) and observed length `l` (m) and elongation
/// speed `s` (m/s) per frame. Allocation-free.
#[allow(dead_code)] // the reference the assembled columns are tested against
pub(crate) fn series(
    k: f64,
    (mt, kt, zt): (f64, f64, f64),
    dt: f64,
    command: impl Fn(usize) -> f64,
    l: &[f64],
    s: &[f64],
    out: &mut [[f64; 3]],
) {
    let c = dt * dt / mt;
    let mut y = [0.0; 3];
    let mut prev = [0.0; 3];
    for n in 0..l.len() {
        out[n] = y;
        // Tension of each series: the S + K L drive goes to y₀, -K l0 to y_l, Z s to y_Z.
        let drive = [command(n) + k * l[n], -k, s[n]];
        for r in 0..3 {
            let force = drive[r] - k * y[r] - kt * y[r] - zt * (y[r] - prev[r]) / dt;
            let next = 2.0 * y[r] - prev[r] + c * force;
            prev[r] = y[r];
            y[r] = next;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cost::CostKind;
    use crate::problem::Problem;
    use cordis_core::examples::tadpole;
    use cordis_core::Param;

    /// The three series recombined at the true l0 and a nonzero Z reproduce the tendon the
    /// short cost drives along the observed frames, frame by frame.
    #[test]
    fn three_series_reproduce_the_short_costs_tendon() {
        let truth = tadpole();
        let traj = truth.simulate(100).unwrap();
        let mut scene = truth.clone();
        let t = scene.type_index("muscle").unwrap();
        let zk = scene.types[t].kind.param_index("damping").unwrap();
        // A damped TGR, so that the Z series is exercised (its value plays no role in y's
        // linearity; the data come from the undamped truth).
        scene.types[t].params[zk] = Param::Known(0.7);
        let problem = Problem::new(&scene, &traj, CostKind::Short).unwrap();
        let obj = &problem.objective;
        let p = scene.param_values();
        let o = scene.param_layout().type_offsets[t];
        let (k, l0, z) = (p[o], p[o + 1], p[o + 2]);
        let tendon = (p[o + 3], p[o + 4], p[o + 5]);
        let frames = obj.obs.frames;
        let (mut l, mut s) = (vec![0.0; frames], vec![0.0; frames]);
        for n in 0..frames {
            let (x, v) = (obj.obs.frame(n), obj.obs.velocity(n));
            let d = x[1] - x[0];
            l[n] = d.norm();
            s[n] = (v[1] - v[0]).dot(&(d / l[n]));
        }
        let signal = &scene.signals[0];
        let dt = scene.dt;
        let mut out = vec![[0.0; 3]; frames];
        series(k, tendon, dt, |n| signal.value(n as f64 * dt), &l, &s, &mut out);

        let mut s_cost = obj.scratch();
        let mut state = vec![0.0; s_cost.hidden.len()];
        obj.reset_hidden(&p, &mut state);
        let mut worst: f64 = 0.0;
        let mut biggest: f64 = 0.0;
        for (n, y) in out.iter().enumerate() {
            let combined = y[0] + l0 * y[1] + z * y[2];
            worst = worst.max((combined - state[0]).abs());
            biggest = biggest.max(state[0].abs());
            obj.advance_hidden_observed(&p, n, &mut state, &mut s_cost.discard);
        }
        assert!(biggest > 0.05, "the tendon moved ({biggest} m)");
        assert!(worst <= 1e-12, "series differ from the cost's tendon by {worst} m");
    }
}
