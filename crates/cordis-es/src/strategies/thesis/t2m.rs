//! `t2m`: the operators of this crate's first reading of the thesis ES, kept because it
//! measures better than the text's own operators on the bench's examples (BENCHMARKS.md).
//!
//! The worst `replacement` fraction (~60 %) of the population ranked by global cost is replaced
//! each generation; each child comes from one operator, drawn with these shares:
//!
//! | operator | share | what it does |
//! |---|---|---|
//! | local crossover | `pcross` % | a rank-biased individual's genes, then per type: the fathers chosen, one per end particle, by a tournament on their **local** cost at that particle; the type's genes are their mean in internal coordinates (geometric for log parameters); or one father per type (n-parent) or per gene (m·n-parent) |
//! | pure mutation | `pmut` % | a new individual from the heuristic initialisation |
//! | re-injection | `reinjection` | a copy of a random father with one type re-initialised heuristically |
//! | noisy inheritance | half the rest | a rank-biased father's genes plus N(0, σ_father); σ_child = mean of σ_father and a draw whose scale follows the father's global cost |
//! | local mutation | half the rest | a rank-biased base; at a random particle, the genes of one of its types from a father chosen by local cost there, plus noise scaled by σ and the particle's share of the father's cost |
//!
//! What departs from the text ([`super::operators`] follows it): the mutation shares (~79 %
//! of the children are mutations, the text's rate is 1–5 %), the rank-biased base of local
//! mutation and crossover (the text modifies a son drawn in the second part of the
//! population), the rank-biased father of noisy inheritance (the text: uniform), the mean in
//! internal coordinates, and the global cost choosing who is replaced.

use crate::problem::Problem;
use crate::run::rng::{self, Rng};

use super::config::{Crossover, ThesisConfig};
use super::population::{cost_scale, fresh, heuristic_gene, heuristic_sigma, Individual};
use super::population::{local_share, Layout, Op};

/// Index (into the sorted population) of the better of `size` random individuals by their
/// local cost at particle p.
fn local_tournament(pop: &[Individual], p: usize, rng: &mut Rng, size: usize) -> usize {
    let mut best = rng::index(rng, pop.len());
    for _ in 1..size {
        let c = rng::index(rng, pop.len());
        if pop[c].local[p].total_cmp(&pop[best].local[p]).is_lt() {
            best = c;
        }
    }
    best
}

fn group_local_cost(layout: &Layout, ind: &Individual, g: usize) -> f64 {
    layout.group_particles[g]
        .iter()
        .map(|&p| ind.local[p as usize])
        .sum()
}

/// The operator of one child: shares `pcross` %, `pmut` %, `reinjection`, then half each.
pub(crate) fn pick_op(c: &ThesisConfig, rng: &mut Rng) -> Op {
    let u = rng::uniform(rng);
    let (pc, pm, pr) = (c.pcross / 100.0, c.pmut / 100.0, c.reinjection);
    if u < pc {
        Op::Crossover
    } else if u < pc + pm {
        Op::Pure
    } else if u < pc + pm + pr {
        Op::Reinject
    } else if u < pc + pm + pr + 0.5 * (1.0 - pc - pm - pr) {
        Op::Inherit
    } else {
        Op::Local
    }
}

/// A child of the sorted population `pop` by operator `op`.
pub(crate) fn child(
    pop: &[Individual],
    layout: &Layout,
    config: &ThesisConfig,
    cost_ref: f64,
    problem: &Problem,
    op: Op,
    rng: &mut Rng,
) -> Individual {
    let n = pop.len();
    let mut child = match op {
        Op::Pure => return fresh(problem, rng),
        Op::Reinject => pop[rng::index(rng, n)].clone(),
        _ => pop[rng::biased_rank(rng, n)].clone(),
    };
    let father_cost = child.cost;
    child.cost = f64::INFINITY;
    if layout.groups.is_empty() {
        return child;
    }
    match op {
        Op::Pure => unreachable!(),
        Op::Reinject => {
            let g = rng::index(rng, layout.groups.len());
            for &k in &layout.groups[g] {
                child.genes[k] = heuristic_gene(problem, k, rng);
                child.sigma[k] = heuristic_sigma(problem, k, rng);
            }
        }
        Op::Inherit => {
            // The mutability drawn follows the father's cost: large while the fit is poor,
            // vanishing as the cost does (the thesis' adaptation of precision).
            let scale = cost_scale(father_cost, cost_ref);
            for k in 0..child.genes.len() {
                let u = &problem.space.unknowns[k];
                let s = child.sigma[k];
                child.genes[k] = u.clamp_internal(child.genes[k] + s * rng::normal(rng));
                let (lo, hi) = u.internal_bounds();
                let drawn = (0.1 * (hi - lo) * scale * rng::normal(rng)).abs();
                child.sigma[k] = 0.5 * (s + drawn);
            }
        }
        Op::Local => {
            let candidates = layout.active_particles();
            let p = candidates[rng::index(rng, candidates.len())];
            let f = &pop[local_tournament(pop, p, rng, 3)];
            let gs = &layout.particle_groups[p];
            let g = gs[rng::index(rng, gs.len())];
            let share = local_share(problem, f, p);
            for &k in &layout.groups[g] {
                let u = &problem.space.unknowns[k];
                child.genes[k] =
                    u.clamp_internal(f.genes[k] + f.sigma[k] * share * rng::normal(rng));
                child.sigma[k] = f.sigma[k];
            }
        }
        Op::Crossover => crossover(pop, layout, config.crossover, &mut child, rng),
    }
    child
}

fn crossover(
    pop: &[Individual],
    layout: &Layout,
    kind: Crossover,
    child: &mut Individual,
    rng: &mut Rng,
) {
    let n = pop.len();
    for (g, ks) in layout.groups.iter().enumerate() {
        match kind {
            Crossover::Mean => {
                let fathers: Vec<usize> = layout.group_particles[g]
                    .iter()
                    .map(|&p| local_tournament(pop, p as usize, rng, 2))
                    .collect();
                let m = fathers.len() as f64;
                for &k in ks {
                    child.genes[k] = fathers.iter().map(|&f| pop[f].genes[k]).sum::<f64>() / m;
                    child.sigma[k] = fathers.iter().map(|&f| pop[f].sigma[k]).sum::<f64>() / m;
                }
            }
            Crossover::NParent | Crossover::MnParent => {
                let per_gene = kind == Crossover::MnParent;
                let pick = |rng: &mut Rng| {
                    let (a, b) = (rng::index(rng, n), rng::index(rng, n));
                    let cost = |i: usize| group_local_cost(layout, &pop[i], g);
                    if cost(a) <= cost(b) {
                        a
                    } else {
                        b
                    }
                };
                let mut f = pick(rng);
                for &k in ks {
                    if per_gene {
                        f = pick(rng);
                    }
                    child.genes[k] = pop[f].genes[k];
                    child.sigma[k] = pop[f].sigma[k];
                }
            }
        }
    }
}
