//! Which local cost the short cost writes per particle (thesis §3.2.1): the position error
//! (the default) or eq 3.3 as printed, the error of the distances to the particle's neighbours.
//!
//! §3.2.1 introduces the local cost with « La fonction de coût locale associée à chaque
//! particule s'exprime comme somme temporelle des erreurs de prédiction des positions de cette
//! particule », then prints
//!
//! ```text
//! Fcoût_locale(part, i, modèle) = Σ_temps Σ_{j voisin de i} (DistPred_ij − DistRéelle_ij)²   (3.3)
//! ```
//!
//! The sentence describes [`LocalCost::Positions`], `c_i = Σ_t |x̂_i(t) − x_i(t)|²` (whose sum
//! over the particles is eq 3.1's short cost); the formula is [`LocalCost::Distances`]:
//! `c_i = Σ_t Σ_{j ∈ N(i)} (|x̂_i(t) − x̂_j(t)| − |x_i(t) − x_j(t)|)²` (m²), with `x̂` the
//! short cost's one-step predictions from the observed frames t−1 and t−2 (a fixed particle's
//! prediction is its observed position) and `N(i)` the particles that share a link with i
//! (« voisines (en termes de liaisons) »: the scene's links of two or more particles, every
//! pair of an instance; a conditional's pairs come and go with the motion and are not counted,
//! nor couplings). Either way the global cost stays eq 3.1 (the position error summed over
//! the particles): the run reports, compares and stops on it, and the thesis ES ranks its
//! protected 5 % by it; only the local operators' rankings read `c_i`.

use super::objective::{CostScratch, Objective};
use super::short::squared_error;
use crate::error::CostError;
use cordis_core::world::{OneClock, WorldClock};
use cordis_core::{LinkKind, Scene, Vec3};

/// The per-particle local cost of the short cost ([module docs](self)).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum LocalCost {
    /// `c_i = Σ_t |x̂_i(t) − x_i(t)|²`: the position error, the sentence of §3.2.1.
    #[default]
    Positions,
    /// Eq 3.3 as printed: `c_i = Σ_t Σ_{j ∈ N(i)} (|x̂_i − x̂_j| − |x_i − x_j|)²`.
    Distances,
}

impl LocalCost {
    /// The `--local-cost` names.
    pub const NAMES: [(LocalCost, &'static str); 2] = [
        (LocalCost::Positions, "positions"),
        (LocalCost::Distances, "distances"),
    ];

    pub fn name(self) -> &'static str {
        crate::named::name_of(&Self::NAMES, self)
    }

    /// The local cost named `s`, or a line listing the names.
    pub fn parse(s: &str) -> Result<Self, String> {
        crate::named::parse_name(&Self::NAMES, "local cost", s)
    }
}

/// Every pair of particles that share a link of two or more particles (conditionals aside),
/// `[i, j]` with `i < j`, sorted, each once.
pub(crate) fn linked_pairs(scene: &Scene) -> Vec<[u32; 2]> {
    let mut pairs = Vec::new();
    for link in &scene.links {
        if scene.types[link.type_index].kind == LinkKind::Conditional {
            continue;
        }
        let ps = &link.particles;
        for (a, &i) in ps.iter().enumerate() {
            for &j in &ps[a + 1..] {
                if i != j {
                    pairs.push([i.min(j) as u32, i.max(j) as u32]);
                }
            }
        }
    }
    pairs.sort_unstable();
    pairs.dedup();
    pairs
}

impl Objective {
    /// Chooses the local cost [`Objective::evaluate`] writes ([`LocalCost`]). `Distances`
    /// needs the short cost (eq 3.3 is defined on its one-step predictions) and a linked
    /// neighbour for every free particle (else its local cost would always be 0); the pairs
    /// are listed here, once. The global cost is the same either way.
    pub fn set_local_cost(&mut self, local: LocalCost, scene: &Scene) -> Result<(), CostError> {
        let Some(pairs) = self.distance_pairs(local, scene)? else {
            self.neighbour_pairs = None;
            return Ok(());
        };
        self.neighbour_pairs = Some(pairs);
        Ok(())
    }

    /// The local cost [`Objective::evaluate`] writes.
    pub fn local_cost(&self) -> LocalCost {
        match self.neighbour_pairs {
            Some(_) => LocalCost::Distances,
            None => LocalCost::Positions,
        }
    }

    /// The linked pairs with a free end, for `Distances`; `None` for `Positions`.
    fn distance_pairs(
        &self,
        local: LocalCost,
        scene: &Scene,
    ) -> Result<Option<Vec<[u32; 2]>>, CostError> {
        if local == LocalCost::Positions {
            return Ok(None);
        }
        if self.kind != super::CostKind::Short {
            return Err(CostError::invalid(
                "local_cost",
                format!(
                    "distances (eq 3.3) is defined on the short cost's one-step predictions, \
                     not the `{}` cost",
                    self.kind
                ),
            ));
        }
        let free = &self.plan.free;
        let mut pairs = linked_pairs(scene);
        pairs.retain(|&[i, j]| free[i as usize] || free[j as usize]);
        let mut linked = vec![false; self.plan.n];
        for &[i, j] in &pairs {
            linked[i as usize] = true;
            linked[j as usize] = true;
        }
        if let Some(&i) = self.free.iter().find(|&&i| !linked[i]) {
            return Err(CostError::invalid(
                "local_cost",
                format!(
                    "distances (eq 3.3): particles[{i}] shares no link with another particle, \
                     so its local cost would always be 0"
                ),
            ));
        }
        Ok(Some(pairs))
    }

    /// The short cost with eq 3.3's local costs into `per` (zeroed by the caller): returns the
    /// global cost, the position error summed as [`Objective::short_generic`] sums it (the same
    /// bits).
    pub(crate) fn short_distances(
        &self,
        p: &[f64],
        pairs: &[[u32; 2]],
        s: &mut CostScratch,
        per: &mut [f64],
    ) -> f64 {
        let (_, g) = self.masses_gravity(p);
        // Buffers the short cost does not use (rollouts' state, harmonic sums): taken, not
        // allocated.
        let mut pred = std::mem::take(&mut s.x);
        let mut pos = std::mem::take(&mut s.inv);
        pos.fill(0.0);
        let last = self.free.last().copied();
        let mut term = |t: usize, i: usize, xh: &Vec3, x0: &Vec3| {
            pos[i] += squared_error(xh, x0);
            pred[i] = *xh;
            // Terms come frame by frame, free particles ascending: frame t is complete.
            if Some(i) == last {
                self.distance_terms(t, pairs, &pred, per);
            }
        };
        match &self.plan.worlds {
            None => self.short_terms(&OneClock::new(self.plan.dt, g), p, s, &mut term),
            Some(steps) => self.short_terms(&WorldClock { steps, g }, p, s, &mut term),
        }
        s.plain = self.free.iter().map(|&i| pos[i]).sum();
        s.x = pred;
        s.inv = pos;
        s.plain
    }

    /// Adds frame `t`'s eq 3.3 terms to `per`: each linked pair's distance error to both of
    /// its free ends (predicted positions of free particles in `pred`, fixed ones observed).
    fn distance_terms(&self, t: usize, pairs: &[[u32; 2]], pred: &[Vec3], per: &mut [f64]) {
        let x = self.obs.frame(t);
        let free = &self.plan.free;
        for &[i, j] in pairs {
            let (i, j) = (i as usize, j as usize);
            let pi = if free[i] { pred[i] } else { x[i] };
            let pj = if free[j] { pred[j] } else { x[j] };
            let d = (pi - pj).norm() - (x[i] - x[j]).norm();
            // A NaN prediction never escapes: +inf, as `squared_error`.
            let e = if d * d < f64::INFINITY {
                d * d
            } else {
                f64::INFINITY
            };
            if free[i] {
                per[i] += e;
            }
            if free[j] {
                per[j] += e;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cost::CostKind;
    use approx::assert_relative_eq;
    use cordis_core::{LinkType, Particle, Trajectory};

    /// Particle 0 fixed at the origin, 1 and 2 free at (1,0,0) and (2,0,0), springs `a` (0-1,
    /// at rest: l0 1) and `b` (1-2, l0 0.9: stretched), K 10, masses 1, gravity −9.81 ŷ.
    fn line() -> Scene {
        let mut s = Scene::new(0.01);
        s.gravity = [0.0, -9.81, 0.0];
        s.add_particle(Particle::new(1.0, [0.0, 0.0, 0.0]).fixed());
        s.add_particle(Particle::new(1.0, [1.0, 0.0, 0.0]));
        s.add_particle(Particle::new(1.0, [2.0, 0.0, 0.0]));
        for (name, l0) in [("a", 1.0), ("b", 0.9)] {
            let t = LinkType::new(name, LinkKind::Spring)
                .with("stiffness", 10.0)
                .with("rest_length", l0);
            s.add_type(t);
        }
        s.add_link("a", &[0, 1]);
        s.add_link("b", &[1, 2]);
        s
    }

    /// The line held still for three frames: frame 2 is the one predicted, from rest.
    fn at_rest(scene: &Scene) -> Trajectory {
        let x0: Vec<f64> = scene.particles.iter().flat_map(|p| p.pos).collect();
        let n = scene.particles.len();
        Trajectory::from_flat(3, n, x0.repeat(3)).unwrap()
    }

    /// Eq 3.3 by hand. From rest, spring `b` (stretched by 0.1) pulls 1 by +a x̂ and 2 by −a x̂,
    /// a = dt² K 0.1 / m = 1e-4 m, and gravity moves both by δ = dt² g = 9.81e-4 m down: x̂_1 =
    /// (1 + a, −δ), x̂_2 = (2 − a, −δ). Pair (0,1): (√((1+a)² + δ²) − 1)²; pair (1,2):
    /// ((1 − 2a) − 1)² = 4a². c_1 holds both, c_2 the second; fixed 0 none.
    #[test]
    fn distances_local_cost_is_eq_3_3_by_hand() {
        let scene = line();
        let mut obj = Objective::new(&scene, &at_rest(&scene), CostKind::Short).unwrap();
        // The generic path, which eq 3.3 takes (the linear one agrees to rounding only).
        obj.set_linear(false);
        let p = scene.param_values();
        let (a, d) = (1e-4, 9.81e-4);
        let positions = obj.report(&p).unwrap();
        // The predictions as read: each free particle a² + δ² off.
        assert_relative_eq!(
            positions.per_particle[1],
            a * a + d * d,
            max_relative = 1e-9
        );
        assert_relative_eq!(
            positions.per_particle[2],
            a * a + d * d,
            max_relative = 1e-9
        );
        obj.set_local_cost(LocalCost::Distances, &scene).unwrap();
        assert_eq!(obj.local_cost(), LocalCost::Distances);
        let distances = obj.report(&p).unwrap();
        let pair01 = (((1.0 + a) * (1.0 + a) + d * d).sqrt() - 1.0).powi(2);
        let pair12 = 4.0 * a * a;
        assert_eq!(distances.per_particle[0], 0.0);
        assert_relative_eq!(
            distances.per_particle[1],
            pair01 + pair12,
            max_relative = 1e-6
        );
        assert_relative_eq!(distances.per_particle[2], pair12, max_relative = 1e-6);
        // The global cost, the RMSE and the term count are eq 3.1's either way, bit for bit.
        assert_eq!(distances.total, positions.total);
        assert_eq!(distances.rmse, positions.rmse);
        assert_eq!(distances.terms, positions.terms);
        // Back to positions.
        obj.set_local_cost(LocalCost::Positions, &scene).unwrap();
        assert_eq!(obj.report(&p).unwrap(), positions);
    }

    /// On noiseless motion of the model itself every prediction is exact: every local cost is
    /// 0 to rounding, and a wrong stiffness makes them grow.
    #[test]
    fn distances_local_cost_is_zero_on_the_truth() {
        let scene = cordis_core::examples::rigid();
        let traj = scene.simulate(40).unwrap();
        let mut obj = Objective::new(&scene, &traj, CostKind::Short).unwrap();
        obj.set_local_cost(LocalCost::Distances, &scene).unwrap();
        let mut p = scene.param_values();
        let truth = obj.report(&p).unwrap();
        let largest = truth.per_particle.iter().fold(0.0_f64, |m, &c| m.max(c));
        assert!(largest < 1e-24, "{largest:e}");
        p[0] *= 1.5;
        let wrong = obj.report(&p).unwrap();
        let largest = wrong.per_particle.iter().fold(0.0_f64, |m, &c| m.max(c));
        assert!(largest > 1e-12, "{largest:e}");
        // The same global cost as the position-error local costs give.
        let mut positions = Objective::new(&scene, &traj, CostKind::Short).unwrap();
        positions.set_linear(false);
        assert_eq!(positions.report(&p).unwrap().total, wrong.total);
    }

    #[test]
    fn distances_are_refused_off_the_short_cost_and_for_unlinked_particles() {
        let scene = line();
        let traj = at_rest(&scene);
        let mut long = Objective::new(&scene, &traj, CostKind::Long).unwrap();
        let e = long
            .set_local_cost(LocalCost::Distances, &scene)
            .unwrap_err();
        assert!(e.to_string().contains("not the `long` cost"), "{e}");
        let mut lone = line();
        lone.add_particle(Particle::new(1.0, [0.0, 2.0, 0.0]));
        lone.add_type(LinkType::new("air", LinkKind::Drag).with("damping", 0.1));
        lone.add_link("air", &[3]);
        let traj = at_rest(&lone);
        let mut obj = Objective::new(&lone, &traj, CostKind::Short).unwrap();
        let e = obj.set_local_cost(LocalCost::Distances, &lone).unwrap_err();
        assert!(e.to_string().contains("particles[3] shares no link"), "{e}");
        assert_eq!(obj.local_cost(), LocalCost::Positions);
    }

    #[test]
    fn linked_pairs_are_every_pair_of_an_instance_once() {
        let mut s = line();
        s.add_type(
            LinkType::new("bend", LinkKind::Angle)
                .with("stiffness", 1.0)
                .with("rest_cos", -1.0),
        );
        s.add_link("bend", &[0, 1, 2]);
        assert_eq!(linked_pairs(&s), vec![[0, 1], [0, 2], [1, 2]]);
        assert_eq!(LocalCost::parse("distances"), Ok(LocalCost::Distances));
        assert!(LocalCost::parse("eq3.3")
            .unwrap_err()
            .contains("positions, distances"));
    }
}
