//! What the strategies beyond the thesis share: parallel evaluation of plain genomes, the
//! heuristic starting point, and the unit box every one of them searches in.

use crate::error::CostError;
use crate::problem::Problem;
use crate::run::strategy::GenerationStats;

/// Global costs of `genomes` (internal coordinates), by the problem's evaluator (in parallel).
/// Each evaluation is a pure function of its genome, so the result does not depend on the
/// thread count nor on where the costs are computed.
pub(crate) fn evaluate_genomes(problem: &Problem, genomes: &[Vec<f64>]) -> Vec<f64> {
    let flat: Vec<f64> = genomes.concat();
    let mut costs = vec![f64::INFINITY; genomes.len()];
    problem.evaluate_population(&flat, &mut costs, None);
    costs
}

/// The heuristic starting genome (thesis Annexe 1, without its random spread): rest lengths
/// and cosines at their observed means, otherwise the unknown's `init`, otherwise the middle
/// of its internal box (the geometric middle for log coordinates).
pub(crate) fn start_genome(problem: &Problem) -> Vec<f64> {
    problem
        .space
        .unknowns
        .iter()
        .zip(&problem.observed)
        .map(|(u, obs)| {
            let z = match (obs, u.init) {
                (Some(m), _) => u.to_internal(*m),
                (None, Some(init)) => u.to_internal(init),
                (None, None) => {
                    let (lo, hi) = u.internal_bounds();
                    0.5 * (lo + hi)
                }
            };
            u.clamp_internal(z)
        })
        .collect()
}

/// Internal boxes `(lo, width)` of every unknown.
pub(crate) fn boxes(problem: &Problem) -> Vec<(f64, f64)> {
    problem
        .space
        .unknowns
        .iter()
        .map(|u| {
            let (lo, hi) = u.internal_bounds();
            (lo, (hi - lo).max(0.0))
        })
        .collect()
}

/// Folds any real number into [0, 1] by mirroring at 0 and 1 (period 2): the map is
/// continuous, the identity inside the box, and lets a search roam freely outside it.
pub fn reflect(y: f64) -> f64 {
    if !y.is_finite() {
        return 0.5;
    }
    let r = y.rem_euclid(2.0);
    if r > 1.0 {
        2.0 - r
    } else {
        r
    }
}

/// The genome (internal coordinates) of a point of the unit box, reflected into it first.
pub(crate) fn from_unit(boxes: &[(f64, f64)], y: &[f64]) -> Vec<f64> {
    boxes
        .iter()
        .zip(y)
        .map(|(&(lo, w), &y)| lo + w * reflect(y))
        .collect()
}

/// The unit-box point of a genome (0.5 on a degenerate box).
pub(crate) fn to_unit(boxes: &[(f64, f64)], z: &[f64]) -> Vec<f64> {
    boxes
        .iter()
        .zip(z)
        .map(|(&(lo, w), &z)| {
            if w > 0.0 {
                ((z - lo) / w).clamp(0.0, 1.0)
            } else {
                0.5
            }
        })
        .collect()
}

/// The statistics of a strategy that has no population yet.
pub(crate) const NO_STATS: GenerationStats = GenerationStats {
    best_cost: f64::INFINITY,
    mean_cost: f64::INFINITY,
    mean_mutability: 0.0,
};

/// A checkpointed `Option<State>` read back and checked against the problem by `fits`; the
/// error names the strategy.
pub(crate) fn load_checked<S: serde::de::DeserializeOwned>(
    name: &str,
    state: &serde_json::Value,
    fits: impl FnOnce(&S) -> bool,
) -> Result<Option<S>, CostError> {
    let s: Option<S> =
        serde_json::from_value(state.clone()).map_err(|e| CostError::state_json(None, e))?;
    match &s {
        Some(st) if fits(st) => Ok(s),
        _ => Err(CostError::state(format!(
            "{name} state does not match the problem"
        ))),
    }
}

#[cfg(test)]
mod tests {
    use super::reflect;

    #[test]
    fn reflect_is_identity_inside_and_mirrors_outside() {
        for &(y, r) in &[
            (0.3, 0.3),
            (1.0, 1.0),
            (1.25, 0.75),
            (-0.25, 0.25),
            (2.5, 0.5),
            (-1.75, 0.25),
        ] {
            assert!((reflect(y) - r).abs() < 1e-15, "{y} → {}", reflect(y));
        }
        assert_eq!(reflect(f64::NAN), 0.5);
    }
}
