//! The geometry of the listed pairs at every observed frame, precomputed once for the generic
//! short cost ([`super::Objective`] builds it on its first evaluation): springs and the
//! conditional pairs of a known range, within the objective's memory budget.

use super::kernels::PairGeometry;
use super::observed::Observed;

/// Precomputed geometry of the listed pairs, per pass: `None` where it would not fit
/// the objective's budget (that pass then computes its geometry at every evaluation).
#[derive(Clone, Debug, Default)]
pub(crate) struct Geometry {
    pub springs: Option<PairGeometry>,
    /// One per conditional pass (`None` also when its range is not known).
    pub conditionals: Vec<Option<PairGeometry>>,
}

impl Geometry {
    /// No precomputed geometry: every pass computes it at each evaluation (the static cost,
    /// whose frames are poses at rest that the precomputed blocks, built for the frames that
    /// start a step with their observed velocities, do not cover).
    pub(crate) fn none(conditionals: usize) -> Geometry {
        Geometry {
            springs: None,
            conditionals: vec![None; conditionals],
        }
    }

    /// The geometry of the `springs` pairs and of every conditional pass whose pairs `obs`
    /// knows, each pass while `budget` bytes last (springs first, then the conditional passes
    /// in plan order).
    pub(crate) fn build(obs: &Observed, springs: &[[u32; 2]], mut budget: usize) -> Geometry {
        let frames = obs.frames;
        let mut fits = |bytes: usize| {
            let ok = bytes <= budget;
            if ok {
                budget -= bytes;
            }
            ok
        };
        let x_at = |t: usize| obs.frame(t);
        let v_at = |t: usize| obs.velocity(t);
        let spring_geometry = (!springs.is_empty()
            && fits(PairGeometry::bytes((1..frames - 1).map(|_| springs.len()))))
        .then(|| PairGeometry::new(frames, |_| springs, x_at, v_at));
        let conditionals = obs
            .pairs
            .iter()
            .map(|known| {
                let known = known.as_ref()?;
                fits(PairGeometry::bytes(
                    (1..frames - 1).map(|t| known.at(t).len()),
                ))
                .then(|| PairGeometry::new(frames, |t| known.at(t), x_at, v_at))
            })
            .collect();
        Geometry {
            springs: spring_geometry,
            conditionals,
        }
    }
}
