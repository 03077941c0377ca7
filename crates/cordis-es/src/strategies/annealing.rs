//! `annealing`: simulated annealing, the baseline of the thesis' chapter 3 introduction.
//!
//! A generation moves `chains` independent Metropolis chains by one step each; their proposals
//! are evaluated in parallel. Chain k moves one coordinate i, drawn uniformly, of its state in
//! the unit box of the internal coordinates (each internal box mapped to [0, 1]):
//! x_i' = reflect(x_i + s_i N(0, 1)), folded back into the box by reflection; it accepts it when its cost is lower, else with probability
//! exp(−(E' − E) / T_g), the energy being E = ln C ([`energy`]). Cooling is exponential, T_g = T0 α^g, with T0 read from the spread of
//! the initial chains' costs ([`initial_temperature`]). Each chain adapts the scale s_i of the
//! coordinate it moved to keep about a quarter of its proposals accepted (Corana et al. 1987):
//! s_i ← s_i exp(γ (accepted − 0.25)), within [`step_floor`, 1]. Measured on the `rigid`
//! example, moving every coordinate at once with one scale tied to the temperature (s ∝ √T)
//! froze every chain near cost 1e-2 after 3·10^5 evaluations; one adaptive scale for all
//! coordinates stalled at 3e-5 after 10^6; one coordinate at a time reached 1e-6: the cost is
//! too ill-conditioned for isotropic moves.
//! Chains never exchange states: more chains are independent restarts, not a population. The
//! best state ever visited is kept.
//!
//! Chain k draws its proposal and its acceptance test from
//! [`crate::run::rng::stream`]`(seed, g, k + 1)`.

use serde::{Deserialize, Serialize};

use super::cmaes::mean_finite;
use super::common::{
    boxes, evaluate_genomes, from_unit, load_checked, reflect, start_genome, to_unit, NO_STATS,
};
use crate::error::CostError;
use crate::problem::Problem;
use crate::run::float_json::{bits, lossless};
use crate::run::rng;
use crate::run::strategy::{GenerationStats, Strategy};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AnnealingConfig {
    pub chains: usize,
    /// α: the temperature is multiplied by it every generation.
    pub cooling: f64,
    /// Initial proposal standard deviation, in units of the box width.
    pub step0: f64,
    /// γ: the rate of the step-size adaptation.
    pub adapt: f64,
    /// The acceptance rate the step size is steered to.
    pub target_acceptance: f64,
    /// Smallest proposal standard deviation, in units of the box width.
    pub step_floor: f64,
}

impl Default for AnnealingConfig {
    fn default() -> Self {
        AnnealingConfig {
            chains: 100,
            cooling: 0.99,
            step0: 0.1,
            adapt: 0.2,
            target_acceptance: 0.25,
            step_floor: 1e-9,
        }
    }
}

#[derive(Clone, Debug, Serialize, Deserialize)]
struct Chain {
    /// State in the unit box.
    #[serde(with = "bits")]
    x: Vec<f64>,
    #[serde(with = "lossless")]
    cost: f64,
    /// Proposal standard deviation of each coordinate, box widths.
    #[serde(with = "bits")]
    steps: Vec<f64>,
}

#[derive(Clone, Debug, Serialize, Deserialize)]
struct State {
    chains: Vec<Chain>,
    #[serde(with = "lossless")]
    t0: f64,
    #[serde(with = "lossless")]
    temperature: f64,
    #[serde(with = "bits")]
    best_genome: Vec<f64>,
    #[serde(with = "lossless")]
    best_cost: f64,
    #[serde(with = "lossless")]
    mean_cost: f64,
}

pub struct Annealing {
    config: AnnealingConfig,
    boxes: Vec<(f64, f64)>,
    state: Option<State>,
}

impl Annealing {
    pub fn new(config: AnnealingConfig) -> Self {
        Annealing {
            config,
            boxes: Vec::new(),
            state: None,
        }
    }

    fn record(&mut self, genomes: &[Vec<f64>], costs: &[f64]) {
        let Some(st) = self.state.as_mut() else {
            return;
        };
        for (g, &c) in genomes.iter().zip(costs) {
            if c < st.best_cost {
                st.best_cost = c;
                st.best_genome = g.clone();
            }
        }
        st.mean_cost = mean_finite(costs);
    }
}

/// T0: the median energy change between the starting point (chain 0) and the other chains, one
/// initial step away — a typical uphill move is then accepted with probability 1/e. The median,
/// not the standard deviation, because a few exploding proposals (an unstable stiffness) would
/// set T0 far above every useful move. With one chain, or no spread, T0 = 1 (a factor e).
pub fn initial_temperature(energies: &[f64]) -> f64 {
    let c0 = energies.first().copied().unwrap_or(f64::INFINITY);
    let mut d: Vec<f64> = energies
        .iter()
        .skip(1)
        .map(|c| (c - c0).abs())
        .filter(|d| d.is_finite() && *d > 0.0)
        .collect();
    d.sort_by(f64::total_cmp);
    d.get(d.len() / 2).copied().unwrap_or(1.0)
}

/// The energy annealed: ln C. Identification costs span many decades (1 at the start, 1e-20
/// near the truth on noise-free data), so no single temperature scale of C itself fits a whole
/// run; on ln C a temperature is a *ratio* of costs. (On C itself every chain drifted far from
/// the start while hot, then froze at costs near 1e-2 on the `rigid` example.) C = 0 gives −∞,
/// below every other energy.
pub fn energy(cost: f64) -> f64 {
    if cost.is_nan() {
        f64::INFINITY
    } else {
        cost.max(0.0).ln()
    }
}

/// Metropolis: always downhill; uphill with probability exp(−Δ/T); a finite cost always
/// replaces an infinite one and an infinite one never replaces a finite one.
pub fn metropolis(current: f64, proposed: f64, temperature: f64, u: f64) -> bool {
    if proposed <= current || current == f64::INFINITY {
        return true;
    }
    if proposed == f64::INFINITY || current == f64::NEG_INFINITY {
        return false;
    }
    temperature > 0.0 && u < (-(proposed - current) / temperature).exp()
}

impl Strategy for Annealing {
    fn name(&self) -> &'static str {
        "annealing"
    }

    fn init(&mut self, problem: &Problem, seed: u64) {
        self.boxes = boxes(problem);
        let start = start_genome(problem);
        let x0 = to_unit(&self.boxes, &start);
        let c = &self.config;
        let chains = c.chains.max(1);
        // Chain 0 starts at the heuristic point; chain k at it with coordinate (k − 1) mod n
        // moved by one initial proposal: a sample of the very moves the chains make, which is
        // what T0 must be read from.
        let n = x0.len();
        let xs: Vec<Vec<f64>> = (0..chains)
            .map(|k| {
                let mut r = rng::stream(seed, 0, k as u64 + 1);
                let mut x = x0.clone();
                if k > 0 && n > 0 {
                    let i = (k - 1) % n;
                    x[i] = reflect(x[i] + c.step0 * rng::normal(&mut r));
                }
                x
            })
            .collect();
        let genomes: Vec<Vec<f64>> = xs.iter().map(|x| from_unit(&self.boxes, x)).collect();
        let costs = evaluate_genomes(problem, &genomes);
        let energies: Vec<f64> = costs.iter().map(|&c| energy(c)).collect();
        let t0 = initial_temperature(&energies);
        self.state = Some(State {
            chains: xs
                .into_iter()
                .zip(&costs)
                .map(|(x, &cost)| Chain {
                    steps: vec![c.step0; x.len()],
                    x,
                    cost,
                })
                .collect(),
            t0,
            temperature: t0,
            best_genome: start,
            best_cost: f64::INFINITY,
            mean_cost: f64::INFINITY,
        });
        self.record(&genomes, &costs);
    }

    fn next_generation(&mut self, problem: &Problem, seed: u64, generation: u64) {
        let c = self.config.clone();
        let Some(st) = self.state.as_mut() else {
            return;
        };
        let temperature = st.t0 * c.cooling.powf(generation as f64);
        let mut rngs: Vec<rng::Rng> = (0..st.chains.len())
            .map(|k| rng::stream(seed, generation, k as u64 + 1))
            .collect();
        let n = self.boxes.len();
        let moved: Vec<usize> = rngs.iter_mut().map(|r| rng::index(r, n.max(1))).collect();
        let proposals: Vec<Vec<f64>> = st
            .chains
            .iter()
            .zip(&mut rngs)
            .zip(&moved)
            .map(|((ch, r), &i)| {
                let mut x = ch.x.clone();
                if let Some(xi) = x.get_mut(i) {
                    *xi = reflect(*xi + ch.steps[i] * rng::normal(r));
                }
                x
            })
            .collect();
        let genomes: Vec<Vec<f64>> = proposals
            .iter()
            .map(|x| from_unit(&self.boxes, x))
            .collect();
        let costs = evaluate_genomes(problem, &genomes);
        for (((ch, r), (x, &cost)), &i) in st
            .chains
            .iter_mut()
            .zip(&mut rngs)
            .zip(proposals.into_iter().zip(&costs))
            .zip(&moved)
        {
            let u = rng::uniform(r);
            let accepted = metropolis(energy(ch.cost), energy(cost), temperature, u);
            if accepted {
                ch.x = x;
                ch.cost = cost;
            }
            let hit = if accepted { 1.0 } else { 0.0 };
            if let Some(s) = ch.steps.get_mut(i) {
                *s = (*s * (c.adapt * (hit - c.target_acceptance)).exp()).clamp(c.step_floor, 1.0);
            }
        }
        st.temperature = temperature;
        self.record(&genomes, &costs);
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
        let width = if self.boxes.is_empty() {
            0.0
        } else {
            self.boxes.iter().map(|(_, w)| w).sum::<f64>() / self.boxes.len() as f64
        };
        let (sum, k) = s
            .chains
            .iter()
            .flat_map(|c| c.steps.iter())
            .fold((0.0, 0usize), |(s, k), v| (s + v, k + 1));
        let step = if k > 0 { sum / k as f64 } else { 0.0 };
        GenerationStats {
            best_cost: s.best_cost,
            mean_cost: s.mean_cost,
            mean_mutability: step * width,
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
        self.boxes = boxes(problem);
        self.state = load_checked("annealing", state, |st: &State| {
            st.best_genome.len() == problem.dim()
                && st.chains.iter().all(|c| c.x.len() == problem.dim())
        })?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::metropolis;

    #[test]
    fn metropolis_accepts_downhill_and_uphill_at_the_boltzmann_rate() {
        assert!(metropolis(2.0, 1.0, 0.0, 0.99));
        assert!(!metropolis(1.0, 2.0, 0.0, 0.0));
        assert!(metropolis(f64::INFINITY, f64::INFINITY, 1.0, 0.5));
        assert!(!metropolis(f64::NEG_INFINITY, -1e300, 1e300, 0.0));
        assert!(!metropolis(1.0, f64::INFINITY, 1e300, 0.0));
        // exp(-1) ≈ 0.3679
        assert!(metropolis(1.0, 2.0, 1.0, 0.36));
        assert!(!metropolis(1.0, 2.0, 1.0, 0.37));
    }
}
