//! `parisian`: Parisian co-evolution (thesis §3.3, after Marukatat's DEA [M99]).
//!
//! The model is split into sub-problems, one per link type with unknowns: the type's unknown
//! parameters (k, l0, damping…) plus, when masses are unknown, the masses of the particles its
//! instances join — the thesis' (m, k, l0) triplets grouped by type, since every instance of a
//! type shares (k, l0). Masses no such type touches form one last sub-problem. A mass joined by
//! several types belongs to each of their sub-problems.
//!
//! The whole solution B is the current best piece of every sub-population. Each sub-population
//! is a self-adaptive (μ/μ,λ) ES ([`super::self_adaptive::SaEs`], n_σ = its piece length) over
//! its own piece; a child is scored by the global cost of B with the child's piece inserted,
//! i.e. by the improvement it brings to B (ranking by that cost is ranking by the improvement:
//! B is fixed within a generation). B's own piece competes in every selection, so a
//! sub-population never forgets the piece in use. After a generation every sub-population's
//! best improving child is inserted into B together and the result evaluated once (one extra
//! evaluation); B becomes that combination if it beats the best single insertion, else the best
//! single insertion — so B's cost never rises.
//!
//! **Total mass.** When masses are free, every candidate's free masses are rescaled so the
//! scene's total mass stays M (the sum of the scene's starting masses: known ones plus the
//! starting value of each unknown), then clamped into their boxes (a clamp can leave the sum a
//! little off M). Without it, masses and stiffnesses could drift together along the ways that
//! produce the same motion (the thesis' "impedance" remark).
//!
//! Sub-population s draws child k of generation g from stream 1 + s λ_s + k.

use serde::{Deserialize, Serialize};

use super::cmaes::mean_finite;
use super::common::{
    boxes, evaluate_genomes, from_unit, load_checked, start_genome, to_unit, NO_STATS,
};
use super::self_adaptive::{Individual, Recombination, SaEs, SelfAdaptiveConfig};
use crate::error::CostError;
use crate::problem::space::Role;
use crate::problem::Problem;
use crate::run::float_json::{bits, lossless};
use crate::run::strategy::{GenerationStats, Strategy};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct ParisianConfig {
    /// Children per generation, over all sub-populations (at least 4 each).
    pub population: usize,
    /// Initial σ of the pieces, in units of the box width.
    pub sigma0: f64,
    pub sigma_floor: f64,
}

impl Default for ParisianConfig {
    fn default() -> Self {
        ParisianConfig {
            population: 100,
            sigma0: 0.1,
            sigma_floor: 1e-14,
        }
    }
}

#[derive(Clone, Debug, Serialize, Deserialize)]
struct State {
    subs: Vec<SaEs>,
    /// B in the unit box.
    #[serde(with = "bits")]
    whole: Vec<f64>,
    #[serde(with = "bits")]
    best_genome: Vec<f64>,
    #[serde(with = "lossless")]
    best_cost: f64,
    #[serde(with = "lossless")]
    mean_cost: f64,
}

pub struct Parisian {
    config: ParisianConfig,
    boxes: Vec<(f64, f64)>,
    /// Unknown indices of each sub-problem.
    groups: Vec<Vec<usize>>,
    /// Unknown indices of the free masses.
    masses: Vec<usize>,
    /// Total mass the free masses must make up with the known ones (kg), if any is free.
    free_mass: f64,
    state: Option<State>,
}

impl Parisian {
    pub fn new(config: ParisianConfig) -> Self {
        Parisian {
            config,
            boxes: Vec::new(),
            groups: Vec::new(),
            masses: Vec::new(),
            free_mass: 0.0,
            state: None,
        }
    }

    /// The sub-problems of `problem` (see the module doc).
    pub fn sub_problems(problem: &Problem) -> Vec<Vec<usize>> {
        let unknowns = &problem.space.unknowns;
        let mass_offset = problem.scene.param_layout().mass_offset;
        let mass_of_particle = |p: u32| {
            unknowns
                .iter()
                .position(|u| u.role == Role::Mass && u.slot == mass_offset + p as usize)
        };
        let mut groups: Vec<Vec<usize>> = Vec::new();
        let mut group_type: Vec<usize> = Vec::new();
        for (k, u) in unknowns.iter().enumerate() {
            let Some(t) = u.type_index else { continue };
            match group_type.iter().position(|&g| g == t) {
                Some(g) => groups[g].push(k),
                None => {
                    group_type.push(t);
                    groups.push(vec![k]);
                }
            }
        }
        let mut covered = vec![false; unknowns.len()];
        for g in &mut groups {
            let touched = problem.touches[g[0]].clone();
            for p in touched {
                if let Some(m) = mass_of_particle(p) {
                    g.push(m);
                    covered[m] = true;
                }
            }
        }
        let rest: Vec<usize> = (0..unknowns.len())
            .filter(|&k| unknowns[k].role == Role::Mass && !covered[k])
            .collect();
        if !rest.is_empty() {
            groups.push(rest);
        }
        groups
    }

    fn setup(&mut self, problem: &Problem) {
        self.boxes = boxes(problem);
        self.groups = Self::sub_problems(problem);
        let unknowns = &problem.space.unknowns;
        self.masses = (0..unknowns.len())
            .filter(|&k| unknowns[k].role == Role::Mass)
            .collect();
        let layout = problem.scene.param_layout();
        let base = &problem.space.base;
        let total: f64 = (0..problem.num_particles)
            .map(|i| base[layout.mass_offset + i])
            .sum();
        let free_slots: Vec<usize> = self.masses.iter().map(|&k| unknowns[k].slot).collect();
        let known: f64 = (0..problem.num_particles)
            .map(|i| layout.mass_offset + i)
            .filter(|s| !free_slots.contains(s))
            .map(|s| base[s])
            .sum();
        self.free_mass = total - known;
    }

    fn sub_config(&self, len: usize) -> SelfAdaptiveConfig {
        let lambda = (self.config.population / self.groups.len().max(1)).max(4);
        let mu = (lambda / 4).max(2);
        SelfAdaptiveConfig {
            mu,
            lambda,
            rho: mu,
            plus: false,
            per_coordinate: len > 1,
            correlated: false,
            recombine_x: Recombination::Intermediate,
            recombine_strategy: Recombination::Intermediate,
            sigma0: self.config.sigma0,
            sigma_floor: self.config.sigma_floor,
            beta: 0.0873,
        }
    }

    /// Rescales the free masses of a unit-box point so the total mass is M.
    fn fix_mass(&self, problem: &Problem, y: &mut [f64]) {
        if self.masses.is_empty() || self.free_mass <= 0.0 {
            return;
        }
        let unknowns = &problem.space.unknowns;
        let value = |k: usize, y: f64| {
            let (lo, w) = self.boxes[k];
            unknowns[k].from_internal(lo + w * y)
        };
        let sum: f64 = self.masses.iter().map(|&k| value(k, y[k])).sum();
        if !(sum > 0.0 && sum.is_finite()) {
            return;
        }
        let scale = self.free_mass / sum;
        for &k in &self.masses {
            let (lo, w) = self.boxes[k];
            let z = unknowns[k].clamp_internal(unknowns[k].to_internal(value(k, y[k]) * scale));
            y[k] = if w > 0.0 { (z - lo) / w } else { 0.5 };
        }
    }

    fn insert(&self, problem: &Problem, whole: &[f64], s: usize, piece: &[f64]) -> Vec<f64> {
        let mut y = whole.to_vec();
        for (&k, &v) in self.groups[s].iter().zip(piece) {
            y[k] = v;
        }
        self.fix_mass(problem, &mut y);
        y
    }

    fn piece(&self, whole: &[f64], s: usize) -> Vec<f64> {
        self.groups[s].iter().map(|&k| whole[k]).collect()
    }

    /// Evaluates every sub-population's children inserted into B, selects, updates B.
    fn advance(&mut self, problem: &Problem, mut children: Vec<Vec<Individual>>) {
        let Some(st) = self.state.as_ref() else {
            return;
        };
        let whole = st.whole.clone();
        let whole_cost = st.best_cost;
        let mut points: Vec<Vec<f64>> = Vec::new();
        for (s, kids) in children.iter().enumerate() {
            for kid in kids {
                points.push(self.insert(problem, &whole, s, &kid.x));
            }
        }
        let genomes: Vec<Vec<f64>> = points.iter().map(|y| from_unit(&self.boxes, y)).collect();
        let costs = evaluate_genomes(problem, &genomes);
        let mut at = 0;
        // Per sub-population: its best improving child's point and cost.
        let mut winners: Vec<(usize, usize, f64)> = Vec::new();
        for (s, kids) in children.iter_mut().enumerate() {
            let mut best: Option<(usize, f64)> = None;
            for kid in kids.iter_mut() {
                kid.cost = costs[at];
                if kid.cost < whole_cost && best.is_none_or(|(_, c)| kid.cost < c) {
                    best = Some((at, kid.cost));
                }
                at += 1;
            }
            if let Some((i, c)) = best {
                winners.push((s, i, c));
            }
        }
        let mut new_whole = whole.clone();
        let mut new_cost = whole_cost;
        let mut new_genome: Option<Vec<f64>> = None;
        if let Some(&(_, i, c)) = winners.iter().min_by(|a, b| a.2.total_cmp(&b.2)) {
            new_whole = points[i].clone();
            new_cost = c;
            new_genome = Some(genomes[i].clone());
            if winners.len() > 1 {
                let mut combined = whole.clone();
                for &(s, i, _) in &winners {
                    for &k in &self.groups[s] {
                        combined[k] = points[i][k];
                    }
                }
                self.fix_mass(problem, &mut combined);
                let g = from_unit(&self.boxes, &combined);
                let c = evaluate_genomes(problem, std::slice::from_ref(&g))[0];
                if c < new_cost {
                    new_whole = combined;
                    new_cost = c;
                    new_genome = Some(g);
                }
            }
        }
        let pieces: Vec<Vec<f64>> = (0..self.groups.len())
            .map(|s| self.piece(&whole, s))
            .collect();
        let Some(st) = self.state.as_mut() else {
            return;
        };
        for ((sub, kids), piece) in st.subs.iter_mut().zip(children).zip(pieces) {
            // B's own piece competes too, with the σ of the sub-population's best.
            let current = Individual {
                x: piece,
                sigma: sub
                    .parents()
                    .first()
                    .map_or_else(|| kids[0].sigma.clone(), |p| p.sigma.clone()),
                alpha: Vec::new(),
                cost: whole_cost,
            };
            let mut pool = kids;
            pool.push(current);
            sub.select(pool);
        }
        st.whole = new_whole;
        st.best_cost = new_cost;
        if let Some(g) = new_genome {
            st.best_genome = g;
        }
        st.mean_cost = mean_finite(&costs);
    }
}

impl Strategy for Parisian {
    fn name(&self) -> &'static str {
        "parisian"
    }

    fn init(&mut self, problem: &Problem, seed: u64) {
        self.setup(problem);
        let mut whole = to_unit(&self.boxes, &start_genome(problem));
        self.fix_mass(problem, &mut whole);
        let genome = from_unit(&self.boxes, &whole);
        let cost = evaluate_genomes(problem, std::slice::from_ref(&genome))[0];
        let subs: Vec<SaEs> = self
            .groups
            .iter()
            .map(|g| SaEs::new(self.sub_config(g.len()), g.len()))
            .collect();
        let children: Vec<Vec<Individual>> = subs
            .iter()
            .enumerate()
            .map(|(s, es)| {
                let first = 1 + (s * es.config().lambda) as u64;
                es.initial_from(&self.piece(&whole, s), seed, first)
            })
            .collect();
        self.state = Some(State {
            subs,
            whole,
            best_genome: genome,
            best_cost: cost,
            mean_cost: cost,
        });
        self.advance(problem, children);
    }

    fn next_generation(&mut self, problem: &Problem, seed: u64, generation: u64) {
        let Some(st) = &self.state else { return };
        if st.subs.is_empty() {
            // Nothing to search: re-evaluate B so evaluation budgets still advance.
            let c = evaluate_genomes(problem, std::slice::from_ref(&st.best_genome))[0];
            if let Some(st) = self.state.as_mut() {
                st.mean_cost = c;
            }
            return;
        }
        let children: Vec<Vec<Individual>> = st
            .subs
            .iter()
            .enumerate()
            .map(|(s, es)| {
                let first = 1 + (s * es.config().lambda) as u64;
                es.offspring_from(seed, generation, first)
            })
            .collect();
        self.advance(problem, children);
    }

    fn best(&self) -> (&[f64], f64) {
        match &self.state {
            Some(s) => (&s.best_genome, s.best_cost),
            None => (&[], f64::INFINITY),
        }
    }

    fn stats(&self) -> GenerationStats {
        let Some(s) = &self.state else {
            return NO_STATS;
        };
        let (mut sum, mut k) = (0.0, 0usize);
        for (sub, g) in s.subs.iter().zip(&self.groups) {
            if let Some(p) = sub.parents().first() {
                for (i, &u) in g.iter().enumerate() {
                    sum += p.sigma[i.min(p.sigma.len() - 1)] * self.boxes[u].1;
                    k += 1;
                }
            }
        }
        GenerationStats {
            best_cost: s.best_cost,
            mean_cost: s.mean_cost,
            mean_mutability: if k > 0 { sum / k as f64 } else { 0.0 },
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
        self.state = load_checked("parisian", state, |st: &State| {
            st.best_genome.len() == problem.dim()
                && st.whole.len() == problem.dim()
                && st.subs.len() == self.groups.len()
                && st
                    .subs
                    .iter()
                    .zip(&self.groups)
                    .all(|(s, g)| s.fits(g.len()))
        })?;
        Ok(())
    }
}
