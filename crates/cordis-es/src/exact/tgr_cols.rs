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
//! [`Tendon`], and `f(n) = K (L - y₀) - l0 K (1 + y_l) + Z (s - K y_Z)` is affine in (l0, Z).
//! [`crate::exact::assemble`] runs the cost's own TGR kernel on probe parameter vectors
//! (l0 = 1; Z = 1; both 0), each with its own tendon driven along the observed frames, so its
//! columns are the cost's arithmetic; `hybrid`'s cached design ([`crate::exact::design`]) steps the
//! three series directly (one pass per K instead of three). The series reproduce the cost's
//! tendon to 1e-12 (tested below) and the two column builds agree (`design`'s test).

use cordis_core::{LinkKind, OptionalParam, Scene};

use crate::exact::Col;
use crate::problem::space::Unknown;

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

/// Slots in the parameter vector of TGR type `t`'s `tendon_position` and `tendon_velocity`,
/// when it has them: they move the tendon's start, so `y₀`'s series depends on them.
pub(crate) fn initial_slots(scene: &Scene, t: usize) -> [Option<usize>; 2] {
    let o = scene.param_layout().type_offsets[t];
    let ty = &scene.types[t];
    [OptionalParam::TendonPosition, OptionalParam::TendonVelocity]
        .map(|w| ty.optional_index(w).map(|k| o + k))
}

/// `(y(0), y(-1))` (m) of TGR type `t`'s tendons at `p`, time step `dt` (s): the start of
/// `y₀`'s series, what the cost's reset gives (`cordis_core::forces::tgr`).
pub(crate) fn initial_tendon(scene: &Scene, t: usize, p: &[f64], dt: f64) -> (f64, f64) {
    let [y0, v0] = initial_slots(scene, t);
    let y = y0.map_or(0.0, |k| 0.0 + p[k]);
    let y_prev = v0.map_or(y, |k| y - p[k] * dt);
    (y, y_prev)
}

/// One TGR instance's tendon as its three series `(y₀, y_l, y_Z)` (m, m per m of l0, m per
/// N·s/m of Z), driven along the observed frames from `y(0) = y(-1) = 0`. Allocation-free.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Tendon {
    k: f64,
    /// dt²/m_t, s²/kg.
    c: f64,
    kt: f64,
    zt: f64,
    dt: f64,
    y: [f64; 3],
    prev: [f64; 3],
}

impl Tendon {
    /// At rest, for stiffness `k` (N/m), tendon `(m_t, K_t, Z_t)` and time step `dt` (s).
    pub fn new(k: f64, (mt, kt, zt): (f64, f64, f64), dt: f64) -> Self {
        Tendon {
            k,
            c: dt * dt / mt,
            kt,
            zt,
            dt,
            y: [0.0; 3],
            prev: [0.0; 3],
        }
    }

    /// The same tendon starting at `(y(0), y(-1))` (m): the start belongs to `y₀`'s series
    /// (the l0 and Z series start at 0: the recursion is affine).
    pub fn starting_at(mut self, (y, y_prev): (f64, f64)) -> Self {
        self.y[0] = y;
        self.prev[0] = y_prev;
        self
    }

    /// The three series at the current frame.
    #[allow(dead_code)] // read by the test that checks the series against the cost's tendon
    pub fn y(&self) -> [f64; 3] {
        self.y
    }

    /// The tensions of the three series at the current frame, observed length `l` (m) and
    /// elongation speed `s` (m/s) — `f = T₀ + l0 T_l + Z T_Z` (N) — then one step on with the
    /// command `command` = S(t_n) (N), which drives y₀ only.
    pub fn step(&mut self, command: f64, l: f64, s: f64) -> [f64; 3] {
        let k = self.k;
        let t = [
            k * (l - self.y[0]),
            -k * (1.0 + self.y[1]),
            s - k * self.y[2],
        ];
        let drive = [command, 0.0, 0.0];
        for r in 0..3 {
            let (y, prev) = (self.y[r], self.prev[r]);
            let force = drive[r] + t[r] - self.kt * y - self.zt * (y - prev) / self.dt;
            self.prev[r] = y;
            self.y[r] = (2.0 * y - prev) + self.c * force;
        }
        t
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
        let mut tendon = Tendon::new(k, tendon, dt);
        for n in 0..frames {
            out[n] = tendon.y();
            tendon.step(signal.value(n as f64 * dt), l[n], s[n]);
        }

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
        assert!(
            worst <= 1e-12,
            "series differ from the cost's tendon by {worst} m"
        );
    }
}
