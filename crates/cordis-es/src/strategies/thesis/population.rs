//! What both variants of the thesis ES share: the individual (genes and their mutabilities,
//! global and local costs), the genome's layout by link type, the heuristic initialisation of
//! Annexe 1, and the biased draws ("tirage biaisé en faveur des plus performants").

use serde::{Deserialize, Serialize};

use crate::problem::Problem;
use crate::run::float_json::{bits, lossless};
use crate::run::rng::{self, Rng};

#[derive(Clone, Debug, Serialize, Deserialize)]
pub(crate) struct Individual {
    /// Internal coordinates ([`crate::problem::space`]).
    #[serde(with = "bits")]
    pub genes: Vec<f64>,
    /// Mutabilities (standard deviations of the noise), in internal coordinates.
    #[serde(with = "bits")]
    pub sigma: Vec<f64>,
    #[serde(with = "lossless")]
    pub cost: f64,
    /// Per-particle local costs (m²): the position error, whose sum is the global cost, or
    /// eq 3.3's neighbour distances ([`crate::cost::LocalCost`]).
    #[serde(with = "bits")]
    pub local: Vec<f64>,
}

/// The operators' choices, one per child.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Op {
    Crossover,
    Pure,
    Reinject,
    Inherit,
    Local,
}

/// The genome by link type: the unit of crossover, re-injection and local mutation.
#[derive(Clone, Debug, Default)]
pub(crate) struct Layout {
    /// Unknowns grouped by link type (a mass alone).
    pub groups: Vec<Vec<usize>>,
    /// Per group: the particles its unknowns touch (its instances' ends).
    pub group_particles: Vec<Vec<u32>>,
    /// Per particle: the group of every link instance it is an end of (a type repeated once
    /// per instance; a conditional type or a mass once).
    pub particle_links: Vec<Vec<usize>>,
    /// Per particle: the groups touching it, each once.
    pub particle_groups: Vec<Vec<usize>>,
}

impl Layout {
    pub fn new(problem: &Problem) -> Self {
        let mut groups: Vec<Vec<usize>> = Vec::new();
        let mut group_particles = Vec::new();
        for (k, u) in problem.space.unknowns.iter().enumerate() {
            let same = groups.iter().position(|g| {
                let first = &problem.space.unknowns[g[0]];
                u.type_index.is_some() && first.type_index == u.type_index
            });
            match same {
                Some(g) => groups[g].push(k),
                None => {
                    groups.push(vec![k]);
                    group_particles.push(problem.touches[k].clone());
                }
            }
        }
        let mut particle_links = vec![Vec::new(); problem.num_particles];
        for (g, ps) in group_particles.iter().enumerate() {
            let t = problem.space.unknowns[groups[g][0]].type_index;
            for &p in ps {
                let count = t.map_or(0, |t| instances_at(problem, t, p as usize));
                for _ in 0..count.max(1) {
                    particle_links[p as usize].push(g);
                }
            }
        }
        let particle_groups = particle_links
            .iter()
            .map(|gs| {
                let mut gs = gs.clone();
                gs.dedup();
                gs
            })
            .collect();
        Layout {
            groups,
            group_particles,
            particle_links,
            particle_groups,
        }
    }

    /// Particles some unknown touches (where a local mutation can happen).
    pub fn active_particles(&self) -> Vec<usize> {
        (0..self.particle_links.len())
            .filter(|&p| !self.particle_links[p].is_empty())
            .collect()
    }
}

/// Links and couplings of type `t` with particle `p` among their ends.
fn instances_at(problem: &Problem, t: usize, p: usize) -> usize {
    let s = &problem.scene;
    let links = s.links.iter().filter(|l| l.type_index == t);
    let couplings = s.couplings.iter().filter(|c| c.type_index == t);
    links
        .map(|l| &l.particles)
        .chain(couplings.map(|c| &c.particles))
        .filter(|ps| ps.contains(&p))
        .count()
}

/// Heuristic value of gene k (Annexe 1 initialisation): a rest length (cosine) at its observed
/// mean, otherwise around the unknown's `init`, log-normally around the box's centre for log
/// coordinates, uniformly in the box otherwise.
/// Particle `p`'s share of `f`'s cost, in [0, 1] (1 when the cost is 0 or not finite): its
/// local cost over the global cost, or with eq 3.3's distances (which do not sum to the
/// global cost) over their own sum.
pub(crate) fn local_share(problem: &Problem, f: &Individual, p: usize) -> f64 {
    let total = match problem.objective.local_cost() {
        crate::cost::LocalCost::Positions => f.cost,
        crate::cost::LocalCost::Distances => f.local.iter().sum(),
    };
    if total > 0.0 && total.is_finite() {
        (f.local[p] / total).clamp(0.0, 1.0)
    } else {
        1.0
    }
}

pub(crate) fn heuristic_gene(problem: &Problem, k: usize, rng: &mut Rng) -> f64 {
    let u = &problem.space.unknowns[k];
    if let Some(m) = problem.observed[k] {
        return u.clamp_internal(u.to_internal(m));
    }
    let (lo, hi) = u.internal_bounds();
    let z = match u.init {
        Some(init) => u.to_internal(init) + 0.25 * (hi - lo) * rng::normal(rng),
        None if u.log => 0.5 * (lo + hi) + 0.25 * (hi - lo) * rng::normal(rng),
        None => lo + (hi - lo) * rng::uniform(rng),
    };
    u.clamp_internal(z)
}

/// Heuristic mutability of gene k: a tenth of its internal box, log-normally spread
/// ("initialisées au hasard de la même manière").
pub(crate) fn heuristic_sigma(problem: &Problem, k: usize, rng: &mut Rng) -> f64 {
    let (lo, hi) = problem.space.unknowns[k].internal_bounds();
    0.1 * (hi - lo).max(1e-12) * (0.5 * rng::normal(rng)).exp()
}

/// An individual from the heuristic initialisation (unevaluated).
pub(crate) fn fresh(problem: &Problem, rng: &mut Rng) -> Individual {
    let n = problem.dim();
    Individual {
        genes: (0..n).map(|k| heuristic_gene(problem, k, rng)).collect(),
        sigma: (0..n).map(|k| heuristic_sigma(problem, k, rng)).collect(),
        cost: f64::INFINITY,
        local: vec![0.0; problem.num_particles],
    }
}

/// Costs and local costs of `inds`, by the problem's evaluator (one batch: one round trip for
/// a remote one).
pub(crate) fn evaluate(problem: &Problem, inds: &mut [Individual]) {
    let n = problem.num_particles;
    let genomes: Vec<f64> = inds.iter().flat_map(|i| i.genes.iter().copied()).collect();
    let mut costs = vec![f64::INFINITY; inds.len()];
    let mut local = vec![0.0; inds.len() * n];
    problem.evaluate_population(&genomes, &mut costs, Some(&mut local));
    for (k, ind) in inds.iter_mut().enumerate() {
        ind.cost = costs[k];
        ind.local.clear();
        ind.local.extend_from_slice(&local[k * n..(k + 1) * n]);
    }
}

/// The noisy-inheritance mutability draw's scale: proportional to the individual's global
/// cost, relative to the initial best (`cost_ref`), capped at 1 (a tenth of the box).
pub(crate) fn cost_scale(cost: f64, cost_ref: f64) -> f64 {
    if cost.is_finite() {
        (cost.max(0.0) / cost_ref).min(1.0)
    } else {
        1.0
    }
}
