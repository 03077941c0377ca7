//! The thesis ES as a [`Strategy`]: the population sorted by global cost, one generation of
//! operators ([`super::operators`] for `thesis`, [`super::t2m`] for `t2m`), décadence (the
//! mutabilities of unchanged individuals decay by `reducer` per generation), and Powell's
//! descent on the best individual from generation `descent_start`, every `descent_every`
//! (Annexe 1). Genes are internal coordinates ([`crate::problem::space`]).

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use crate::error::CostError;
use crate::linalg::powell::{powell, Powell};
use crate::problem::Problem;
use crate::run::float_json::lossless;
use crate::run::rng;
use crate::run::strategy::{GenerationStats, Strategy};

use super::config::{ThesisConfig, Variant};
use super::operators::{self, Parents, Rankings};
use super::population::{evaluate, fresh, Individual, Layout};
use super::t2m;

#[derive(Clone, Debug, Serialize, Deserialize)]
struct State {
    /// Sorted by cost after every generation.
    population: Vec<Individual>,
    /// The initial best cost: the scale of noisy inheritance's mutability draw.
    #[serde(with = "lossless")]
    cost_ref: f64,
}

pub struct Thesis {
    config: ThesisConfig,
    state: State,
    layout: Layout,
}

impl Thesis {
    pub fn new(config: ThesisConfig) -> Self {
        Thesis {
            config,
            state: State {
                population: Vec::new(),
                cost_ref: 1.0,
            },
            layout: Layout::default(),
        }
    }

    fn sort(&mut self) {
        // Stable sort: ties keep their order, so the ranking is deterministic.
        self.state
            .population
            .sort_by(|a, b| a.cost.total_cmp(&b.cost));
    }

    /// One `t2m` generation: the worst `replacement` fraction replaced by children.
    fn t2m_generation(&mut self, problem: &Problem, seed: u64, generation: u64) {
        let size = self.state.population.len();
        let elite = operators::protected(&self.config, size);
        let replaced = ((self.config.replacement * size as f64).round() as usize).min(size - elite);
        let first = size - replaced;
        let (pop, layout, config) = (&self.state.population, &self.layout, &self.config);
        let cost_ref = self.state.cost_ref;
        let mut children: Vec<Individual> = (first..size)
            .into_par_iter()
            .map(|slot| {
                let mut r = rng::stream(seed, generation, slot as u64 + 1);
                let op = t2m::pick_op(config, &mut r);
                t2m::child(pop, layout, config, cost_ref, problem, op, &mut r)
            })
            .collect();
        evaluate(problem, &mut children);
        self.decay(|slot| slot < first);
        for (slot, c) in (first..size).zip(children) {
            self.state.population[slot] = c;
        }
    }

    /// One `thesis` generation: the planned applications' children replace their sons.
    fn thesis_generation(&mut self, problem: &Problem, seed: u64, generation: u64) {
        let size = self.state.population.len();
        let plan = operators::plan(&self.config, size, &mut rng::stream(seed, generation, 0));
        let ranks = Rankings::new(&self.state.population, &self.layout);
        let parents = Parents {
            pop: &self.state.population,
            layout: &self.layout,
            ranks: &ranks,
            cost_ref: self.state.cost_ref,
        };
        let config = &self.config;
        let mut children: Vec<Individual> = plan
            .par_iter()
            .enumerate()
            .map(|(k, &app)| {
                let mut r = rng::stream(seed, generation, k as u64 + 1);
                operators::child(&parents, config, problem, app, &mut r)
            })
            .collect();
        // A generation may draw no application at all (a small population): no batch then,
        // rather than an empty round trip to a remote evaluator.
        if !children.is_empty() {
            evaluate(problem, &mut children);
        }
        let mut changed = vec![false; size];
        for app in &plan {
            changed[app.son] = true;
        }
        self.decay(|slot| !changed[slot]);
        for (app, c) in plan.iter().zip(children) {
            self.state.population[app.son] = c;
        }
    }

    /// Décadence: the mutabilities of the individuals `unchanged` says are kept decay by
    /// `reducer`.
    fn decay(&mut self, unchanged: impl Fn(usize) -> bool) {
        let keep = 1.0 - self.config.reducer;
        for (slot, ind) in self.state.population.iter_mut().enumerate() {
            if unchanged(slot) {
                for s in &mut ind.sigma {
                    *s *= keep;
                }
            }
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
                // The global cost only: eq 3.3's local costs would cost the generic path.
                |x| problem.evaluate_global(x, &mut s, &mut local),
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
        match self.config.variant {
            Variant::Thesis => "thesis",
            Variant::T2m => "t2m",
        }
    }

    fn init(&mut self, problem: &Problem, seed: u64) {
        self.layout = Layout::new(problem);
        let size = self.config.population.max(2);
        let mut pop: Vec<Individual> = (0..size)
            .into_par_iter()
            .map(|k| fresh(problem, &mut rng::stream(seed, 0, k as u64 + 1)))
            .collect();
        evaluate(problem, &mut pop);
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
        match self.config.variant {
            Variant::Thesis => self.thesis_generation(problem, seed, generation),
            Variant::T2m => self.t2m_generation(problem, seed, generation),
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
        evaluate(problem, &mut self.state.population);
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
        self.layout = Layout::new(problem);
        let name = self.name();
        let (dim, particles) = (problem.dim(), problem.num_particles);
        // A state of another problem would index out of its genes or particles later.
        self.state = crate::strategies::common::load_checked(name, state, |st: &State| {
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
