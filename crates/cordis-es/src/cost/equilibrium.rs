//! The static cost ([`super::CostKind::Static`]): frames that are equilibrium poses (thesis §4.2,
//! the cloth identified from "une seule image correspondant à l'état de l'équilibre").
//!
//! At rest the net force on every free particle is zero, so each frame gives equations in the
//! parameters of the forces at rest (stiffnesses, rest lengths, rest cosines) without any
//! motion. The residual of free particle i at frame t is the displacement one simulator step
//! would make from rest at the pose, `dt_i² (F_i(x(t), 0) / m_i + g)` (m), followed by
//! Provot's pass when the scene has one: the short cost of the pose held for three frames, bit
//! for bit, and 0 exactly at a fixed point of the simulator. Velocity-dependent forces vanish
//! at rest; their parameters are refused by [`crate::problem::Problem::new`].

use super::objective::{CostScratch, Objective};
use super::short::squared_error;
use cordis_core::world::{Clock, OneClock, WorldClock};
use cordis_core::Vec3;

impl Objective {
    /// The static cost: local costs into `per` (zeroed by the caller), returns their sum.
    pub(crate) fn static_cost(&self, p: &[f64], s: &mut CostScratch, per: &mut [f64]) -> f64 {
        let (_, g) = self.masses_gravity(p);
        let mut term = |i: usize, xh: &Vec3, x: &Vec3| per[i] += squared_error(xh, x);
        match &self.plan.worlds {
            None => self.static_terms(&OneClock::new(self.plan.dt, g), p, s, &mut term),
            Some(steps) => self.static_terms(&WorldClock { steps, g }, p, s, &mut term),
        }
        s.plain = self.free.iter().map(|&i| per[i]).sum();
        s.plain
    }

    /// Every term of the static cost, in order (frame t = 0 … T-1, then free particle
    /// ascending): `term(i, x̂_i, x_i(t))` with `x̂_i = x_i(t) + dt_i² (F_i/m_i + g)` the step
    /// from rest at the pose (then Provot's pass). The one loop behind the cost and its
    /// residuals. The observed velocities are zero for this kind ([`Objective::new`]), so
    /// `observed_forces` is the force at rest.
    #[inline(always)]
    pub(crate) fn static_terms<C: Clock>(
        &self,
        clock: &C,
        p: &[f64],
        s: &mut CostScratch,
        mut term: impl FnMut(usize, &Vec3, &Vec3),
    ) {
        let (m, _) = self.masses_gravity(p);
        let provot = !self.plan.provot.links.is_empty();
        let geo = self.geometry();
        for t in 0..self.obs.frames {
            self.observed_forces(p, t, s, geo);
            let x = self.obs.frame(t);
            let f = &s.core.f;
            if provot {
                // Provot needs every predicted position (fixed ones exact) before scoring.
                for (i, xh) in s.xhat.iter_mut().enumerate() {
                    *xh = if self.plan.free[i] {
                        x[i] + clock.kick(i, f[i] / m[i])
                    } else {
                        x[i]
                    };
                }
                self.plan.provot.apply(p, &mut s.xhat, &self.plan.free);
                for &i in &self.free {
                    term(i, &s.xhat[i], &x[i]);
                }
            } else {
                for &i in &self.free {
                    let xh = x[i] + clock.kick(i, f[i] / m[i]);
                    term(i, &xh, &x[i]);
                }
            }
        }
    }

    /// The static cost of a model with no link force, `Σ_t Σ_i |dt_i² g|²` (m²) with the
    /// scene's gravity (gravity only on the main world): the scale of what the forces at rest
    /// must balance. 0 without gravity.
    pub(crate) fn static_scale(&self) -> f64 {
        let g = self.gravity;
        let kick = |i: usize| match &self.plan.worlds {
            None => OneClock::new(self.plan.dt, g).kick(i, Vec3::zeros()),
            Some(steps) => WorldClock { steps, g }.kick(i, Vec3::zeros()),
        };
        let per_frame: f64 = self.free.iter().map(|&i| kick(i).norm_squared()).sum();
        per_frame * self.obs.frames as f64
    }
}

#[cfg(test)]
mod tests {
    use crate::cost::{CostKind, Objective};
    use cordis_core::{LinkKind, LinkType, Particle, Scene, Trajectory};

    /// A chain of 5 free beads (0.1 kg) between two fixed ends `span` m apart, 6 springs
    /// (K 40 N/m, l0 0.2 m, Z 0.3 N·s/m) and air drag (0.3 N·s/m) on every bead, under
    /// gravity: it sags, then settles.
    fn chain(span: f64) -> Scene {
        let mut s = Scene::new(0.01);
        s.gravity = [0.0, 0.0, -9.81];
        s.add_particle(Particle::new(1.0, [0.0, 0.0, 0.0]).fixed());
        for k in 1..6 {
            s.add_particle(Particle::new(0.1, [span * k as f64 / 6.0, 0.0, 0.0]));
        }
        s.add_particle(Particle::new(1.0, [span, 0.0, 0.0]).fixed());
        let link = LinkType::new("link", LinkKind::Spring)
            .with("stiffness", 40.0)
            .with("rest_length", 0.2)
            .with("damping", 0.3);
        s.add_type(link);
        s.add_type(LinkType::new("air", LinkKind::Drag).with("damping", 0.3));
        for i in 0..6 {
            s.add_link("link", &[i, i + 1]);
        }
        for i in 1..6 {
            s.add_link("air", &[i]);
        }
        s
    }

    /// The chain's pose at rest: its last frame after 60 s of damped motion, as one frame.
    fn at_rest(scene: &Scene) -> Vec<f64> {
        let traj = scene.simulate(6000).expect("the chain simulates");
        let n = 3 * scene.num_particles();
        traj.as_flat()[traj.as_flat().len() - n..].to_vec()
    }

    fn poses(flat: Vec<f64>, n: usize) -> Trajectory {
        Trajectory::from_flat(flat.len() / (3 * n), n, flat).expect("finite")
    }

    #[test]
    fn static_cost_is_zero_at_rest_and_positive_elsewhere() {
        let truth = chain(1.2);
        let pose = poses(at_rest(&truth), 7);
        let obj = Objective::new(&truth, &pose, CostKind::Static).expect("objective");
        assert_eq!(obj.terms(), 5);
        let p = truth.param_values();
        let at_truth = obj.report(&p).expect("cost").total;
        // The damped run leaves motion of ~1e-13 m: its accelerations are what remains.
        assert!(at_truth < 1e-26, "cost at the truth {at_truth:e}");
        // The rest length (slot 1) and stiffness (slot 0) off by 1 %: the beads are pulled.
        for (slot, factor) in [(0, 1.01), (1, 1.01), (0, 0.99)] {
            let mut q = p.clone();
            q[slot] *= factor;
            let c = obj.report(&q).expect("cost").total;
            assert!(c > 1e6 * at_truth && c > 1e-14, "slot {slot}: {c:e}");
        }
        // Damping and drag act on nothing at rest.
        let mut q = p.clone();
        q[2] *= 10.0;
        q[3] *= 10.0;
        assert_eq!(obj.report(&q).unwrap().total.to_bits(), at_truth.to_bits());
    }

    #[test]
    fn static_cost_is_the_short_cost_of_the_pose_held_still() {
        let truth = chain(1.2);
        let pose = at_rest(&truth);
        let held = poses([pose.clone(), pose.clone(), pose.clone()].concat(), 7);
        let stat = Objective::new(&truth, &poses(pose, 7), CostKind::Static).unwrap();
        let mut short = Objective::new(&truth, &held, CostKind::Short).unwrap();
        short.set_linear(false);
        let mut p = truth.param_values();
        p[0] = 37.0;
        p[1] = 0.21;
        let (a, b) = (stat.report(&p).unwrap(), short.report(&p).unwrap());
        assert!(a.total > 1e-10);
        assert_eq!(a.total.to_bits(), b.total.to_bits());
        assert_eq!(a.per_particle, b.per_particle);
        // And the residuals sum to it.
        let mut s = stat.scratch();
        let mut r = vec![0.0; stat.residual_len()];
        assert_eq!(r.len(), 15);
        let c = stat.residuals(&p, &mut s, &mut r).unwrap();
        assert_eq!(c.to_bits(), a.total.to_bits());
        let sum: f64 = r.iter().map(|x| x * x).sum();
        approx::assert_relative_eq!(sum, c, max_relative = 1e-12);
    }

    #[test]
    fn static_cost_takes_one_frame_and_refuses_couplings_by_name() {
        let truth = chain(1.2);
        let one = poses(at_rest(&truth), 7);
        assert!(Objective::new(&truth, &one, CostKind::Short).is_err());
        assert_eq!("static".parse::<CostKind>().unwrap(), CostKind::Static);
        assert_eq!(CostKind::Static.to_string(), "static");
        assert!("static:2".parse::<CostKind>().is_err());
        let mut tgr = truth.clone();
        let t = LinkType::new("tendon", LinkKind::Tgr)
            .with("stiffness", 1.0)
            .with("rest_length", 0.2)
            .with("tendon_mass", 0.1);
        tgr.add_type(t);
        let e = Objective::new(&tgr, &one, CostKind::Static).unwrap_err();
        assert!(e.to_string().contains("types.tendon (tgr)"), "{e}");
    }
}
