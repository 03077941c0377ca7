//! The strategies by name: [`StrategyName`] and [`STRATEGIES`], the one list of `--strategy`
//! values that parsing, help texts, errors and checkpoints read. Building a strategy from its
//! name (and `auto`'s choice) is [`crate::identify::make_strategy`].

use std::fmt;
use std::str::FromStr;

use crate::error::CostError;
#[cfg(doc)]
use crate::run::strategy::Strategy;

/// `--strategy` values.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum StrategyName {
    /// `least-squares` when every unknown enters the short cost linearly, `hybrid` when only
    /// ranges, v_max and a TGR's stiffness and tendon do not, `levenberg-marquardt` when the
    /// exact solvers refuse but the short cost is smooth in every unknown (no unknown range
    /// or v_max: muscles, worlds, couplings), else `t2m` (the thesis ES with a
    /// larger share of new individuals: it meets finite costs where the text's rare mutations
    /// do not, e.g. a long cost over wide boxes).
    Auto,
    /// The evolution strategy of thesis §3.2 and Annexe 1, its operators as the text states
    /// them.
    Thesis,
    /// The same ES with this crate's earlier, freer operators (`docs/identification.md`).
    T2m,
    LeastSquares,
    Hybrid,
    Cmaes,
    SelfAdaptive,
    Annealing,
    Parisian,
    LevenbergMarquardt,
    /// The maximum-likelihood fit of simulated to observed positions over the parameters and
    /// the initial state ([`crate::output_error`]); `auto` picks it for noisy or incomplete
    /// data when the scene's kinds have exact sensitivities.
    OutputError,
}

/// Every strategy and its `--strategy` name (also its [`Strategy::name`] and the checkpoint's
/// `strategy`), in the order help texts list them: the one list of names.
pub const STRATEGIES: [(StrategyName, &str); 11] = [
    (StrategyName::Auto, "auto"),
    (StrategyName::Thesis, "thesis"),
    (StrategyName::T2m, "t2m"),
    (StrategyName::LeastSquares, "least-squares"),
    (StrategyName::Hybrid, "hybrid"),
    (StrategyName::Cmaes, "cmaes"),
    (StrategyName::SelfAdaptive, "self-adaptive"),
    (StrategyName::Annealing, "annealing"),
    (StrategyName::Parisian, "parisian"),
    (StrategyName::LevenbergMarquardt, "levenberg-marquardt"),
    (StrategyName::OutputError, "output-error"),
];

impl StrategyName {
    /// The `--strategy` name.
    pub fn name(self) -> &'static str {
        STRATEGIES
            .iter()
            .find(|(s, _)| *s == self)
            .map_or("auto", |(_, n)| n)
    }

    /// Every `--strategy` name, comma-separated, for help texts and errors.
    pub fn list() -> String {
        STRATEGIES.map(|(_, n)| n).join(", ")
    }
}

impl fmt::Display for StrategyName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for StrategyName {
    type Err = CostError;

    fn from_str(s: &str) -> Result<Self, CostError> {
        STRATEGIES
            .iter()
            .find(|(_, n)| *n == s)
            .map(|(k, _)| *k)
            .ok_or_else(|| {
                CostError::unknown_name(
                    s,
                    format!(
                        "unknown strategy `{s}` (expected one of: {})",
                        StrategyName::list()
                    ),
                )
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cost::CostKind;
    use crate::identify::{make_strategy, with_unknown_boxes, StrategyOptions};
    use crate::problem::Problem;
    use crate::strategies::test_scenes::anchored_gas;

    /// Every name parses back to its strategy, and the strategy built from it runs under that
    /// name (what the checkpoint records and the report prints).
    #[test]
    fn every_name_is_the_strategy_it_builds() {
        let scene = anchored_gas(&[[0.2, 0.0, 0.0], [0.0, 0.3, 0.0]], false);
        let traj = scene.simulate(20).expect("simulates");
        let problem =
            Problem::new(&with_unknown_boxes(&scene, 4.0, 0), &traj, CostKind::Short).unwrap();
        for (kind, name) in STRATEGIES {
            assert_eq!(name.parse::<StrategyName>().ok(), Some(kind));
            assert_eq!(kind.to_string(), name);
            if kind == StrategyName::Auto {
                continue;
            }
            let (strategy, ran) = make_strategy(kind, &problem, &StrategyOptions::default());
            assert_eq!((strategy.name(), ran), (name, name));
        }
        let err = "shrt".parse::<StrategyName>().unwrap_err().to_string();
        assert!(
            err.contains("output-error") && err.contains("`shrt`"),
            "{err}"
        );
    }
}
