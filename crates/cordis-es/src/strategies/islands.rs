//! `islands`: several populations of one strategy (islands) evolving side by side, each with
//! its own seed, that exchange their best individuals every `migrate_every` generations.
//!
//! Migration follows a ring: island i receives copies of the `migrants` best individuals of
//! island i − 1 (mod K), which replace its worst ones. Every island's emigrants are taken
//! before any island receives, and islands are stepped in index order, so a run depends only
//! on the seed and the number of islands — not on threads, nor on where costs are computed
//! (each island's population is one batch of the problem's evaluator, local or on Ray).
//! Isolated islands keep diversity (each converges on its own); migration spreads a good
//! solution so the others can refine it.

use rand::RngCore;
use serde::{Deserialize, Serialize};

use crate::error::CostError;
use crate::problem::Problem;
use crate::run::rng;
use crate::run::strategy::{GenerationStats, Strategy};

/// How islands are laid out and how often they exchange individuals.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct IslandConfig {
    /// Number of islands K (2 or more).
    pub islands: usize,
    /// Generations between migrations (≥ 1).
    pub migrate_every: u64,
    /// Individuals each island sends to the next one per migration.
    pub migrants: usize,
}

impl Default for IslandConfig {
    fn default() -> Self {
        IslandConfig {
            islands: 4,
            migrate_every: 10,
            migrants: 2,
        }
    }
}

pub struct Islands {
    config: IslandConfig,
    islands: Vec<Box<dyn Strategy>>,
    /// Index of the island holding the best individual (the lowest index on a tie).
    best: usize,
}

#[derive(Serialize, Deserialize)]
struct State {
    config: IslandConfig,
    islands: Vec<serde_json::Value>,
}

/// The seed of island `island` in a run seeded with `seed`: distinct islands draw from
/// unrelated streams. The generation slot `u64::MAX - 2` is one no run reaches.
pub fn island_seed(seed: u64, island: usize) -> u64 {
    rng::stream(seed, u64::MAX - 2, island as u64).next_u64()
}

impl Islands {
    /// Islands running the strategies `islands` (the same strategy, freshly made, K of them).
    /// Errors when the strategy cannot exchange individuals or the layout is degenerate.
    pub fn new(config: IslandConfig, islands: Vec<Box<dyn Strategy>>) -> Result<Self, CostError> {
        if config.islands < 2 || islands.len() != config.islands {
            return Err(CostError::invalid(
                "islands",
                format!("need 2 or more islands, got {}", config.islands),
            ));
        }
        if config.migrate_every == 0 {
            return Err(CostError::invalid(
                "migrate_every",
                "must be 1 or more generations",
            ));
        }
        if let Some(s) = islands.iter().find(|s| !s.migrates()) {
            return Err(CostError::refused(
                "islands",
                format!(
                    "strategy `{}` cannot run on islands (it cannot exchange individuals; use \
                     thesis)",
                    s.name()
                ),
            ));
        }
        Ok(Islands {
            config,
            islands,
            best: 0,
        })
    }

    fn update_best(&mut self) {
        let mut best = 0;
        for (k, s) in self.islands.iter().enumerate() {
            if s.best().1.total_cmp(&self.islands[best].best().1).is_lt() {
                best = k;
            }
        }
        self.best = best;
    }

    fn migrate(&mut self, problem: &Problem) {
        let out: Vec<Vec<serde_json::Value>> = self
            .islands
            .iter()
            .map(|s| s.emigrants(self.config.migrants))
            .collect();
        let k = self.islands.len();
        for (i, s) in self.islands.iter_mut().enumerate() {
            // Emigrants come from the same strategy on the same problem: a refusal is a bug.
            s.immigrate(problem, &out[(i + k - 1) % k])
                .expect("islands exchange individuals of one strategy");
        }
    }
}

impl Strategy for Islands {
    fn name(&self) -> &'static str {
        "islands"
    }

    fn init(&mut self, problem: &Problem, seed: u64) {
        for (i, s) in self.islands.iter_mut().enumerate() {
            s.init(problem, island_seed(seed, i));
        }
        self.update_best();
    }

    fn next_generation(&mut self, problem: &Problem, seed: u64, generation: u64) {
        for (i, s) in self.islands.iter_mut().enumerate() {
            s.next_generation(problem, island_seed(seed, i), generation);
        }
        if generation % self.config.migrate_every == 0 {
            self.migrate(problem);
        }
        self.update_best();
    }

    fn finished(&self) -> bool {
        self.islands.iter().all(|s| s.finished())
    }

    fn reevaluate(&mut self, problem: &Problem) {
        for s in &mut self.islands {
            s.reevaluate(problem);
        }
        self.update_best();
    }

    fn best(&self) -> (&[f64], f64) {
        self.islands[self.best].best()
    }

    fn stats(&self) -> GenerationStats {
        let st: Vec<GenerationStats> = self.islands.iter().map(|s| s.stats()).collect();
        let finite: Vec<f64> = st
            .iter()
            .map(|s| s.mean_cost)
            .filter(|c| c.is_finite())
            .collect();
        GenerationStats {
            best_cost: self.best().1,
            mean_cost: if finite.is_empty() {
                f64::INFINITY
            } else {
                finite.iter().sum::<f64>() / finite.len() as f64
            },
            mean_mutability: st.iter().map(|s| s.mean_mutability).sum::<f64>() / st.len() as f64,
        }
    }

    fn save_state(&self) -> serde_json::Value {
        let state = State {
            config: self.config,
            islands: self.islands.iter().map(|s| s.save_state()).collect(),
        };
        serde_json::to_value(state).expect("state serialises")
    }

    fn load_state(
        &mut self,
        problem: &Problem,
        state: &serde_json::Value,
    ) -> Result<(), CostError> {
        let st: State =
            serde_json::from_value(state.clone()).map_err(|e| CostError::state_json(None, e))?;
        if st.config != self.config || st.islands.len() != self.islands.len() {
            return Err(CostError::state(format!(
                "islands: checkpoint has {} islands migrating {} every {} generations, this run \
                 {} migrating {} every {}",
                st.config.islands,
                st.config.migrants,
                st.config.migrate_every,
                self.config.islands,
                self.config.migrants,
                self.config.migrate_every
            )));
        }
        for (k, (s, v)) in self.islands.iter_mut().zip(&st.islands).enumerate() {
            s.load_state(problem, v)
                .map_err(|e| e.within(format!("islands[{k}]")))?;
        }
        self.update_best();
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cost::CostKind;
    use crate::identify::{make_islands, with_unknown_boxes, StrategyName, StrategyOptions};

    #[test]
    fn each_island_receives_the_best_of_the_previous_one() {
        let truth = cordis_core::examples::rigid();
        let traj = truth.simulate(30).expect("rigid simulates");
        let problem = Problem::new(&with_unknown_boxes(&truth, 10.0, 1), &traj, CostKind::Short)
            .expect("problem");
        let options = StrategyOptions {
            population: 10,
            ..StrategyOptions::default()
        };
        let config = IslandConfig {
            islands: 3,
            migrate_every: 2,
            migrants: 1,
        };
        let (mut s, _) =
            make_islands(StrategyName::Thesis, &problem, &options, config).expect("islands");
        s.init(&problem, 4);
        let state = |s: &dyn Strategy| -> Vec<Vec<serde_json::Value>> {
            let st: State = serde_json::from_value(s.save_state()).expect("state");
            st.islands
                .iter()
                .map(|v| v["population"].as_array().expect("population").clone())
                .collect()
        };
        s.next_generation(&problem, 4, 1);
        let before = state(s.as_ref());
        // Islands evolve apart: their bests differ before any migration.
        assert_ne!(before[0][0], before[1][0]);
        // Generation 2 migrates after stepping: compare with the islands stepped alone.
        let (mut alone, _) = make_islands(
            StrategyName::Thesis,
            &problem,
            &options,
            IslandConfig {
                migrate_every: 1000,
                ..config
            },
        )
        .expect("islands");
        alone.init(&problem, 4);
        alone.next_generation(&problem, 4, 1);
        alone.next_generation(&problem, 4, 2);
        s.next_generation(&problem, 4, 2);
        let (stepped, migrated) = (state(alone.as_ref()), state(s.as_ref()));
        for i in 0..3 {
            let from = &stepped[(i + 2) % 3][0];
            assert!(
                migrated[i].contains(from),
                "island {i} lacks its neighbour's best"
            );
            assert!(!stepped[i].contains(from), "island {i} had it already");
            // The elite stays: the island's own best is still there.
            assert!(
                migrated[i].contains(&stepped[i][0]),
                "island {i} lost its best"
            );
        }
    }
}
