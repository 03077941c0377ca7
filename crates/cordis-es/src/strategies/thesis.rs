//! `thesis`: the T2M evolution strategy of thesis §3.2 and Annexe 1.
//!
//! Each generation, the population is ranked by global cost; the best `elite` fraction is kept
//! untouched (elitism: the best cost never rises) and the worst `replacement` fraction (~60%)
//! is replaced by children. Each child comes from one operator, drawn with these shares:
//!
//! | operator | share | what it does |
//! |---|---|---|
//! | local crossover | `pcross` % | per type: the fathers chosen, one per end particle of the type's instances, by their **local** cost at that particle; the child takes their mean (Annexe 1), or one father per type (n-parent) or per gene (m·n-parent) |
//! | pure mutation | `pmut` % | a new individual from the heuristic initialisation |
//! | re-injection | `reinjection` | a copy of a random father with one type re-initialised heuristically |
//! | noisy inheritance | half the rest | a rank-biased father's genes plus N(0, σ_father); σ_child = mean of σ_father and a draw whose scale follows the father's global cost |
//! | local mutation | half the rest | a rank-biased base; at a random particle, the genes of one of its types from a father chosen by local cost there, plus noise scaled by σ and the particle's share of the father's cost |
//!
//! Unchanged individuals' mutabilities decay by `reducer` per generation (décadence); from
//! generation `descent_start`, every `descent_every` generations, Powell's descent polishes
//! the best individual. Genes are internal coordinates ([`crate::problem::space`]): log for stiffness-
//! and damping-like parameters. Rest lengths (cosines) start at the mean observed length
//! (cosine) of their type's instances.

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::CostError;
use crate::linalg::powell::{powell, Powell};
use crate::problem::Problem;
use crate::run::float_json::{bits, lossless};
use crate::run::rng::{self, Rng};
use crate::run::strategy::{GenerationStats, Strategy};

/// Options of the thesis strategy; the `Param.gene` keys are `population`, `pcross`, `pmut`,
/// `reducer` (and `generation`, which is a stop rule, and `noise`, applied to the data).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ThesisConfig {
    pub population: usize,
    /// Share of children from local crossover, in %.
    pub pcross: f64,
    /// Share of children from pure mutation, in %.
    pub pmut: f64,
    /// Share of children from re-injection (fraction).
    pub reinjection: f64,
    /// Decay of unchanged mutabilities per generation (fraction).
    pub reducer: f64,
    /// Fraction of the population kept as is.
    pub elite: f64,
    /// Fraction of the population replaced each generation.
    pub replacement: f64,
    pub crossover: Crossover,
    pub descent_start: u64,
    pub descent_every: u64,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Crossover {
    /// Mean of the fathers chosen per end particle (Annexe 1).
    Mean,
    /// Uniform n-parent: all genes of a type from one father (§3.2).
    NParent,
    /// Uniform m·n-parent: each gene from its own father (§3.2).
    MnParent,
}

impl Default for ThesisConfig {
    fn default() -> Self {
        ThesisConfig {
            population: 100,
            pcross: 15.0,
            pmut: 1.0,
            reinjection: 0.05,
            reducer: 0.01,
            elite: 0.1,
            replacement: 0.6,
            crossover: Crossover::Mean,
            descent_start: 400,
            descent_every: 100,
        }
    }
}

#[derive(Clone, Debug, Serialize, Deserialize)]
struct Individual {
    #[serde(with = "bits")]
    genes: Vec<f64>,
    #[serde(with = "bits")]
    sigma: Vec<f64>,
    #[serde(with = "lossless")]
    cost: f64,
    #[serde(with = "bits")]
    local: Vec<f64>,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
struct State {
    /// Sorted by cost after every generation.
    population: Vec<Individual>,
    #[serde(with = "lossless")]
    cost_ref: f64,
}

pub struct Thesis {
    config: ThesisConfig,
    state: State,
    /// Unknowns grouped by link type (masses alone), the unit of crossover and re-injection.
    groups: Vec<Vec<usize>>,
    /// Per group: the particles its unknowns touch.
    group_particles: Vec<Vec<u32>>,
    /// Per particle: the groups touching it.
    particle_groups: Vec<Vec<usize>>,
}

#[derive(Clone, Copy)]
enum Op {
    Crossover,
    Pure,
    Reinject,
    Inherit,
    Local,
}

impl Thesis {
    pub fn new(config: ThesisConfig) -> Self {
        Thesis {
            config,
            state: State {
                population: Vec::new(),
                cost_ref: 1.0,
            },
            groups: Vec::new(),
            group_particles: Vec::new(),
            particle_groups: Vec::new(),
        }
    }

    fn setup(&mut self, problem: &Problem) {
        self.groups.clear();
        self.group_particles.clear();
        for (k, u) in problem.space.unknowns.iter().enumerate() {
            let same = self.groups.iter().position(|g| {
                let first = &problem.space.unknowns[g[0]];
                u.type_index.is_some() && first.type_index == u.type_index
            });
            match same {
                Some(g) => self.groups[g].push(k),
                None => {
                    self.groups.push(vec![k]);
                    self.group_particles.push(problem.touches[k].clone());
                }
            }
        }
        self.particle_groups = vec![Vec::new(); problem.num_particles];
        for (g, ps) in self.group_particles.iter().enumerate() {
            for &p in ps {
                self.particle_groups[p as usize].push(g);
            }
        }
    }

    /// Heuristic value of gene k (Annexe 1 initialisation).
    fn heuristic_gene(problem: &Problem, k: usize, rng: &mut Rng) -> f64 {
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

    fn heuristic_sigma(problem: &Problem, k: usize, rng: &mut Rng) -> f64 {
        let (lo, hi) = problem.space.unknowns[k].internal_bounds();
        0.1 * (hi - lo).max(1e-12) * (0.5 * rng::normal(rng)).exp()
    }

    fn fresh(problem: &Problem, rng: &mut Rng) -> Individual {
        let n = problem.dim();
        Individual {
            genes: (0..n)
                .map(|k| Self::heuristic_gene(problem, k, rng))
                .collect(),
            sigma: (0..n)
                .map(|k| Self::heuristic_sigma(problem, k, rng))
                .collect(),
            cost: f64::INFINITY,
            local: vec![0.0; problem.num_particles],
        }
    }

    /// Costs and local costs of `inds`, by the problem's evaluator (one batch: one round trip
    /// for a remote one).
    fn evaluate(problem: &Problem, inds: &mut [Individual]) {
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

    fn sort(&mut self) {
        // Stable sort: ties keep their order, so the ranking is deterministic.
        self.state
            .population
            .sort_by(|a, b| a.cost.total_cmp(&b.cost));
    }

    /// Index (into the sorted population) of the better of `size` random individuals by their
    /// local cost at particle p: the thesis' "father biased toward the best local cost".
    fn local_tournament(&self, p: usize, rng: &mut Rng, size: usize) -> usize {
        let pop = &self.state.population;
        let mut best = rng::index(rng, pop.len());
        for _ in 1..size {
            let c = rng::index(rng, pop.len());
            if pop[c].local[p].total_cmp(&pop[best].local[p]).is_lt() {
                best = c;
            }
        }
        best
    }

    fn group_local_cost(&self, ind: usize, g: usize) -> f64 {
        let ind = &self.state.population[ind];
        self.group_particles[g]
            .iter()
            .map(|&p| ind.local[p as usize])
            .sum()
    }

    fn child(&self, problem: &Problem, op: Op, rng: &mut Rng) -> Individual {
        let pop = &self.state.population;
        let n = pop.len();
        let mut child = match op {
            Op::Pure => return Self::fresh(problem, rng),
            Op::Reinject => pop[rng::index(rng, n)].clone(),
            _ => pop[rng::biased_rank(rng, n)].clone(),
        };
        let father_cost = child.cost;
        child.cost = f64::INFINITY;
        if self.groups.is_empty() {
            return child;
        }
        match op {
            Op::Pure => unreachable!(),
            Op::Reinject => {
                let g = rng::index(rng, self.groups.len());
                for &k in &self.groups[g] {
                    child.genes[k] = Self::heuristic_gene(problem, k, rng);
                    child.sigma[k] = Self::heuristic_sigma(problem, k, rng);
                }
            }
            Op::Inherit => {
                // The mutability drawn follows the father's cost: large while the fit is poor,
                // vanishing as the cost does (the thesis' adaptation of precision).
                let scale = if father_cost.is_finite() {
                    (father_cost.max(0.0) / self.state.cost_ref).min(1.0)
                } else {
                    1.0
                };
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
                let candidates: Vec<usize> = (0..problem.num_particles)
                    .filter(|&p| !self.particle_groups[p].is_empty())
                    .collect();
                let p = candidates[rng::index(rng, candidates.len())];
                let f = &pop[self.local_tournament(p, rng, 3)];
                let gs = &self.particle_groups[p];
                let g = gs[rng::index(rng, gs.len())];
                let share = if f.cost > 0.0 && f.cost.is_finite() {
                    (f.local[p] / f.cost).clamp(0.0, 1.0)
                } else {
                    1.0
                };
                for &k in &self.groups[g] {
                    let u = &problem.space.unknowns[k];
                    child.genes[k] =
                        u.clamp_internal(f.genes[k] + f.sigma[k] * share * rng::normal(rng));
                    child.sigma[k] = f.sigma[k];
                }
            }
            Op::Crossover => {
                for (g, ks) in self.groups.iter().enumerate() {
                    match self.config.crossover {
                        Crossover::Mean => {
                            let ps = &self.group_particles[g];
                            let fathers: Vec<usize> = ps
                                .iter()
                                .map(|&p| self.local_tournament(p as usize, rng, 2))
                                .collect();
                            for &k in ks {
                                let m = fathers.len() as f64;
                                child.genes[k] =
                                    fathers.iter().map(|&f| pop[f].genes[k]).sum::<f64>() / m;
                                child.sigma[k] =
                                    fathers.iter().map(|&f| pop[f].sigma[k]).sum::<f64>() / m;
                            }
                        }
                        Crossover::NParent | Crossover::MnParent => {
                            let per_gene = self.config.crossover == Crossover::MnParent;
                            let pick = |rng: &mut Rng| {
                                let (a, b) = (rng::index(rng, n), rng::index(rng, n));
                                if self.group_local_cost(a, g) <= self.group_local_cost(b, g) {
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
        }
        child
    }

    fn pick_op(&self, rng: &mut Rng) -> Op {
        let c = &self.config;
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

    fn descend(&mut self, problem: &Problem) {
        let n = problem.dim();
        if n == 0 {
            return;
        }
        let best = &self.state.population[0];
        let (lo, hi): (Vec<f64>, Vec<f64>) = problem
            .space
            .unknowns
            .iter()
            .map(|u| u.internal_bounds())
            .unzip();
        let step: Vec<f64> = (0..n)
            .map(|k| best.sigma[k].max(1e-6 * (hi[k] - lo[k])))
            .collect();
        let mut s = problem.scratch();
        let mut local = vec![0.0; problem.num_particles];
        let d = problem.timed(|| {
            powell(
                |x| problem.evaluate(x, &mut s, &mut local),
                &best.genes,
                best.cost,
                Powell {
                    lo: &lo,
                    hi: &hi,
                    step: &step,
                    rtol: 1e-12,
                    max_evals: 50 * n * n + 500,
                },
            )
        });
        if d.fx < best.cost {
            let best = &mut self.state.population[0];
            best.genes = d.x;
            best.cost = problem.evaluate(&best.genes, &mut s, &mut best.local);
        }
    }
}

impl Strategy for Thesis {
    fn name(&self) -> &'static str {
        "thesis"
    }

    fn init(&mut self, problem: &Problem, seed: u64) {
        self.setup(problem);
        let size = self.config.population.max(2);
        let mut pop: Vec<Individual> = (0..size)
            .into_par_iter()
            .map(|k| Self::fresh(problem, &mut rng::stream(seed, 0, k as u64 + 1)))
            .collect();
        Self::evaluate(problem, &mut pop);
        self.state.population = pop;
        self.sort();
        let best = self.state.population[0].cost;
        self.state.cost_ref = if best.is_finite() && best > 0.0 {
            best
        } else {
            1.0
        };
    }

    fn next_generation(&mut self, problem: &Problem, seed: u64, generation: u64) {
        let size = self.state.population.len();
        let elite = ((self.config.elite * size as f64).ceil() as usize).max(1);
        let replaced = ((self.config.replacement * size as f64).round() as usize).min(size - elite);
        let first = size - replaced;
        let mut children: Vec<Individual> = (first..size)
            .into_par_iter()
            .map(|slot| {
                let mut r = rng::stream(seed, generation, slot as u64 + 1);
                let op = self.pick_op(&mut r);
                self.child(problem, op, &mut r)
            })
            .collect();
        Self::evaluate(problem, &mut children);
        let keep = 1.0 - self.config.reducer;
        for ind in &mut self.state.population[..first] {
            for s in &mut ind.sigma {
                *s *= keep;
            }
        }
        for (slot, c) in (first..size).zip(children) {
            self.state.population[slot] = c;
        }
        self.sort();
        let c = &self.config;
        if c.descent_every > 0
            && generation >= c.descent_start
            && (generation - c.descent_start) % c.descent_every == 0
        {
            self.descend(problem);
            self.sort();
        }
    }

    fn reevaluate(&mut self, problem: &Problem) {
        Self::evaluate(problem, &mut self.state.population);
        self.sort();
    }

    fn best(&self) -> (&[f64], f64) {
        let b = &self.state.population[0];
        (&b.genes, b.cost)
    }

    fn stats(&self) -> GenerationStats {
        let pop = &self.state.population;
        let finite: Vec<f64> = pop
            .iter()
            .map(|i| i.cost)
            .filter(|c| c.is_finite())
            .collect();
        let mean_cost = if finite.is_empty() {
            f64::INFINITY
        } else {
            finite.iter().sum::<f64>() / finite.len() as f64
        };
        let (sum, n) = pop
            .iter()
            .flat_map(|i| i.sigma.iter())
            .fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
        GenerationStats {
            best_cost: pop[0].cost,
            mean_cost,
            mean_mutability: if n > 0 { sum / n as f64 } else { 0.0 },
        }
    }

    fn save_state(&self) -> serde_json::Value {
        serde_json::to_value(&self.state).expect("state serialises")
    }

    fn load_state(
        &mut self,
        problem: &Problem,
        state: &serde_json::Value,
    ) -> Result<(), CostError> {
        self.setup(problem);
        let (dim, particles) = (problem.dim(), problem.num_particles);
        // A state of another problem would index out of its genes or particles later.
        self.state = super::common::load_checked("thesis", state, |st: &State| {
            !st.population.is_empty()
                && st.population.iter().all(|i| {
                    i.genes.len() == dim && i.sigma.len() == dim && i.local.len() == particles
                })
        })?
        .ok_or_else(|| CostError::state("thesis state is empty"))?;
        Ok(())
    }

    fn migrates(&self) -> bool {
        true
    }

    fn emigrants(&self, count: usize) -> Vec<serde_json::Value> {
        // The population is sorted by cost: its head is the best.
        self.state
            .population
            .iter()
            .take(count)
            .map(|i| serde_json::to_value(i).expect("individual serialises"))
            .collect()
    }

    fn immigrate(
        &mut self,
        problem: &Problem,
        migrants: &[serde_json::Value],
    ) -> Result<(), CostError> {
        let size = self.state.population.len();
        // The elite stays: at most the non-elite tail is replaced.
        let room = size - ((self.config.elite * size as f64).ceil() as usize).clamp(1, size);
        for (k, m) in migrants.iter().take(room).enumerate() {
            let ind: Individual = serde_json::from_value(m.clone())
                .map_err(|e| CostError::state_json(Some(&format!("migrant {k}")), e))?;
            if ind.genes.len() != problem.dim() || ind.local.len() != problem.num_particles {
                return Err(CostError::state(format!(
                    "migrant {k}: does not match the problem"
                )));
            }
            self.state.population[size - 1 - k] = ind;
        }
        self.sort();
        Ok(())
    }
}
