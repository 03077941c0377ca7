//! The operators of the thesis ES as §3.2, §3.2.1 and Annexe 1 state them (the readings of
//! ambiguous sentences are in docs/identification.md, each with the sentence it reads).
//!
//! A generation is a [`plan`] of applications, each an operator and the **son** it overwrites,
//! then the children, all built from the population as it was at the start of the generation
//! (so they can be built in parallel, each from its own random stream):
//!
//! - the global cost only protects the best `elite` (5 %, §3.2.1): no son is drawn there;
//! - crossovers: Binomial(N, `pcross` %); mutations: Binomial(N, `pmut` %) ("appliquées avec
//!   une probabilité assez faible sur la population entière"), of four kinds: re-injection
//!   (a `reinjection` share), noisy inheritance, pure and local mutation (evenly);
//! - the sons of re-injection, noisy inheritance and pure mutation are drawn uniformly in the
//!   worse half by global cost; those of local mutation and crossover in the rest of the
//!   population ("la 2ème partie": all but the protected), distinct within a generation;
//! - fathers: uniform for re-injection and noisy inheritance; rank-biased on the **local** cost
//!   (at the particle, or summed over a type's particles for the n- and m·n-parent crossovers)
//!   for local mutation and crossover.

use crate::problem::Problem;
use crate::run::rng::{self, Rng};

use super::config::{Crossover, ThesisConfig};
use super::population::{cost_scale, fresh, heuristic_gene, heuristic_sigma, Individual};
use super::population::{local_share, Layout, Op};

/// One operator application: what it does and the rank of the son it overwrites.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Application {
    pub op: Op,
    pub son: usize,
}

/// The population's orders by local cost, for the fathers' biased draws: per particle (empty
/// for a particle no unknown touches) and per type (summed over the type's particles).
pub(crate) struct Rankings {
    by_particle: Vec<Vec<usize>>,
    by_group: Vec<Vec<usize>>,
}

impl Rankings {
    pub fn new(pop: &[Individual], layout: &Layout) -> Self {
        // Stable sorts of the global ranking: ties keep the global order.
        let order = |key: &dyn Fn(&Individual) -> f64| {
            let mut idx: Vec<usize> = (0..pop.len()).collect();
            idx.sort_by(|&a, &b| key(&pop[a]).total_cmp(&key(&pop[b])));
            idx
        };
        let by_particle = (0..layout.particle_links.len())
            .map(|p| match layout.particle_links[p].is_empty() {
                true => Vec::new(),
                false => order(&|i: &Individual| i.local[p]),
            })
            .collect();
        let by_group = layout
            .group_particles
            .iter()
            .map(|ps| order(&|i: &Individual| ps.iter().map(|&p| i.local[p as usize]).sum()))
            .collect();
        Rankings {
            by_particle,
            by_group,
        }
    }

    /// A father drawn with a probability decreasing linearly with its rank by local cost at
    /// particle `p` ("un père plutôt performant en termes de fonction de coût locale").
    fn at_particle(&self, p: usize, rng: &mut Rng) -> usize {
        let order = &self.by_particle[p];
        order[rng::biased_rank(rng, order.len())]
    }

    fn for_group(&self, g: usize, rng: &mut Rng) -> usize {
        let order = &self.by_group[g];
        order[rng::biased_rank(rng, order.len())]
    }
}

/// Number of individuals protected by the global cost.
pub(crate) fn protected(config: &ThesisConfig, n: usize) -> usize {
    ((config.elite * n as f64).ceil() as usize).clamp(1, n)
}

/// This generation's applications, drawn from `rng` (the generation's stream 0): mutations
/// first, then crossovers; an application that finds no free son in its pool is dropped.
pub(crate) fn plan(config: &ThesisConfig, n: usize, rng: &mut Rng) -> Vec<Application> {
    let (pc, pm) = (config.pcross / 100.0, config.pmut / 100.0);
    let mut ops = Vec::new();
    let (mut crossovers, mut mutations) = (0, 0);
    for _ in 0..n {
        crossovers += usize::from(rng::uniform(rng) < pc);
        mutations += usize::from(rng::uniform(rng) < pm);
    }
    for _ in 0..mutations {
        let u = rng::uniform(rng);
        let rest = (u - config.reinjection) / (1.0 - config.reinjection).max(f64::MIN_POSITIVE);
        ops.push(match u < config.reinjection {
            true => Op::Reinject,
            false if rest < 1.0 / 3.0 => Op::Inherit,
            false if rest < 2.0 / 3.0 => Op::Pure,
            false => Op::Local,
        });
    }
    ops.extend(std::iter::repeat_n(Op::Crossover, crossovers));
    let first = protected(config, n);
    let worse_half = (n / 2).max(first);
    let mut taken = vec![false; n];
    let mut out = Vec::with_capacity(ops.len());
    for op in ops {
        let from = match op {
            Op::Reinject | Op::Inherit | Op::Pure => worse_half,
            Op::Local | Op::Crossover => first,
        };
        let free: Vec<usize> = (from..n).filter(|&i| !taken[i]).collect();
        if free.is_empty() {
            continue;
        }
        let son = free[rng::index(rng, free.len())];
        taken[son] = true;
        out.push(Application { op, son });
    }
    out
}

/// What a child is built from: the population at the start of the generation (sorted by
/// global cost), its genome layout, the local-cost rankings and the cost of reference of the
/// mutabilities' draw.
pub(crate) struct Parents<'a> {
    pub pop: &'a [Individual],
    pub layout: &'a Layout,
    pub ranks: &'a Rankings,
    pub cost_ref: f64,
}

/// The child that replaces `app.son`.
pub(crate) fn child(
    parents: &Parents,
    config: &ThesisConfig,
    problem: &Problem,
    app: Application,
    rng: &mut Rng,
) -> Individual {
    let Parents { pop, layout, .. } = *parents;
    let mut child = match app.op {
        Op::Pure => return fresh(problem, rng),
        // "father avec une probabilité équirépartie dans la population"
        Op::Reinject | Op::Inherit => pop[rng::index(rng, pop.len())].clone(),
        Op::Local | Op::Crossover => pop[app.son].clone(),
    };
    let father_cost = child.cost;
    child.cost = f64::INFINITY;
    if layout.groups.is_empty() {
        return child;
    }
    match app.op {
        Op::Pure => unreachable!(),
        Op::Reinject => {
            let g = rng::index(rng, layout.groups.len());
            for &k in &layout.groups[g] {
                child.genes[k] = heuristic_gene(problem, k, rng);
                child.sigma[k] = heuristic_sigma(problem, k, rng);
            }
        }
        Op::Inherit => inherit(&mut child, father_cost, parents.cost_ref, problem, rng),
        Op::Local => local_mutation(parents, &mut child, problem, rng),
        Op::Crossover => crossover(parents, config.crossover, &mut child, problem, rng),
    }
    child
}

/// Noisy inheritance on a copy of the father: each gene plus N(0, σ_father); each mutability
/// the mean of the father's and |N(0, s)|, s a tenth of the box scaled by the father's cost.
fn inherit(child: &mut Individual, cost: f64, cost_ref: f64, problem: &Problem, rng: &mut Rng) {
    let scale = cost_scale(cost, cost_ref);
    for (k, u) in problem.space.unknowns.iter().enumerate() {
        let s = child.sigma[k];
        child.genes[k] = u.clamp_internal(child.genes[k] + s * rng::normal(rng));
        let (lo, hi) = u.internal_bounds();
        child.sigma[k] = 0.5 * (s + (0.1 * (hi - lo) * scale * rng::normal(rng)).abs());
    }
}

/// Local mutation on a copy of the son: at a random particle, one link ending there (a type
/// weighted by its instances there) takes the parameters of a father biased by local cost at
/// that particle, plus noise of σ_father times the particle's share of the father's cost.
fn local_mutation(parents: &Parents, child: &mut Individual, problem: &Problem, rng: &mut Rng) {
    let candidates = parents.layout.active_particles();
    let p = candidates[rng::index(rng, candidates.len())];
    let f = &parents.pop[parents.ranks.at_particle(p, rng)];
    let links = &parents.layout.particle_links[p];
    let g = links[rng::index(rng, links.len())];
    let share = local_share(problem, f, p);
    for &k in &parents.layout.groups[g] {
        let u = &problem.space.unknowns[k];
        child.genes[k] = u.clamp_internal(f.genes[k] + f.sigma[k] * share * rng::normal(rng));
        child.sigma[k] = f.sigma[k];
    }
}

/// Crossover on a copy of the son, type by type: the mean of the parameter values (not of
/// their logarithms) of the fathers drawn one per end particle by local cost there; or one
/// father per type (n-parent) or per parameter (m·n-parent) by the type's local cost.
fn crossover(
    parents: &Parents,
    kind: Crossover,
    child: &mut Individual,
    problem: &Problem,
    rng: &mut Rng,
) {
    let (pop, layout, ranks) = (parents.pop, parents.layout, parents.ranks);
    for (g, ks) in layout.groups.iter().enumerate() {
        match kind {
            Crossover::Mean => {
                let fathers: Vec<usize> = layout.group_particles[g]
                    .iter()
                    .map(|&p| ranks.at_particle(p as usize, rng))
                    .collect();
                let m = fathers.len() as f64;
                for &k in ks {
                    let u = &problem.space.unknowns[k];
                    let value = fathers
                        .iter()
                        .map(|&f| u.from_internal(pop[f].genes[k]))
                        .sum::<f64>()
                        / m;
                    child.genes[k] = u.clamp_internal(u.to_internal(value));
                    child.sigma[k] = fathers.iter().map(|&f| pop[f].sigma[k]).sum::<f64>() / m;
                }
            }
            Crossover::NParent | Crossover::MnParent => {
                let mut f = ranks.for_group(g, rng);
                for (j, &k) in ks.iter().enumerate() {
                    if kind == Crossover::MnParent && j > 0 {
                        f = ranks.for_group(g, rng);
                    }
                    child.genes[k] = pop[f].genes[k];
                    child.sigma[k] = pop[f].sigma[k];
                }
            }
        }
    }
}
