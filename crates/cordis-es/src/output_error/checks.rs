//! Up-front refusals of an output-error fit: takes that do not fit the scene or leave a
//! particle's initial state unestimable, and fits that would not fit in memory.

use std::collections::VecDeque;

use cordis_core::Scene;

use crate::error::CostError;

use super::observations::Take;
use super::tangent::{self, Tangent};

/// Every take fits the scene, has 3 frames, observes some free particle, and every free
/// particle it does not observe is tied by a chain of links to a free one it observes:
/// otherwise nothing can estimate that particle's initial state (a fixed particle, observed
/// or not, stays where it is whatever the state).
pub(crate) fn check_takes(
    scene: &Scene,
    tangent: &Tangent,
    takes: &[Take],
) -> Result<(), CostError> {
    if takes.is_empty() {
        return Err(CostError::mismatch("trajectory", "no take given"));
    }
    let n = scene.num_particles();
    let adjacency = linked(scene);
    for (k, take) in takes.iter().enumerate() {
        if take.particles() != n {
            return Err(CostError::mismatch(
                format!("take {k}"),
                format!("has {} particles, the scene {n}", take.particles()),
            ));
        }
        if take.frames() < 3 {
            return Err(CostError::mismatch(
                format!("take {k}"),
                format!("has {} frames, at least 3 are needed", take.frames()),
            ));
        }
        if let Some((particle, why)) = unestimable_state(scene, &adjacency, &tangent.free, take) {
            let place = match particle {
                Some(i) => format!("take {k}, particle {i}"),
                None => format!("take {k}"),
            };
            return Err(CostError::mismatch(place, why));
        }
    }
    Ok(())
}

/// Why a take (of the scene's particle count) leaves an initial state unestimable, and the
/// particle when it is one: the take observes none of the `free` particles, or a free particle
/// has no visible frame and no chain of links to an observed free one. The session asks it
/// before any run, so that the message names the take's file ([`check_takes`] names its
/// index, for callers of the estimator itself).
pub(crate) fn unestimable_state(
    scene: &Scene,
    adj: &[Vec<usize>],
    free: &[usize],
    take: &Take,
) -> Option<(Option<usize>, &'static str)> {
    let n = scene.num_particles();
    let mut seen = vec![false; n];
    for &i in free {
        seen[i] = take.tracks(i);
    }
    if !free.is_empty() && !seen.iter().any(|&s| s) {
        return Some((
            None,
            "observes none of the scene's free particles (only fixed ones, or none): \
             nothing in it shows the motion — check the marker map, or the file",
        ));
    }
    let mut queue: VecDeque<usize> = (0..n).filter(|&i| seen[i]).collect();
    while let Some(i) = queue.pop_front() {
        for &j in &adj[i] {
            if !seen[j] && !scene.particles[j].fixed {
                seen[j] = true;
                queue.push_back(j);
            }
        }
    }
    free.iter().find(|&&i| !seen[i]).map(|&i| {
        (
            Some(i),
            "has no visible frame and no chain of links to an observed free particle: its \
             initial state cannot be estimated",
        )
    })
}

/// Each particle's link neighbours ([`unestimable_state`]'s chains), built once for every take.
pub(crate) fn linked(scene: &Scene) -> Vec<Vec<usize>> {
    let mut adj = vec![Vec::new(); scene.num_particles()];
    for l in &scene.links {
        // Every pair of a link's particles (an angle ties its three).
        for (n, &a) in l.particles.iter().enumerate() {
            for &b in &l.particles[n + 1..] {
                adj[a].push(b);
                adj[b].push(a);
            }
        }
    }
    adj
}

/// Refuses fits whose sensitivity matrices and normal equations would not fit in memory.
pub(crate) fn check_memory(
    tangent: &Tangent,
    cols: &tangent::Columns,
    takes: usize,
) -> Result<(), CostError> {
    const LIMIT: f64 = 8.0 * (1u64 << 30) as f64;
    let rows = 3.0 * tangent.plan.n as f64;
    let width = cols.len as f64;
    let total = cols.theta as f64 + takes as f64 * (cols.len - cols.theta) as f64;
    let bytes = 8.0 * (6.0 * rows * width + 2.0 * width * width + total * total);
    if bytes > LIMIT {
        return Err(CostError::mismatch(
            "output-error",
            format!(
                "needs about {:.1} GB for {} sensitivity columns over {} coordinates \
                 (limit {:.0} GB)",
                bytes / 1e9,
                cols.len,
                rows,
                LIMIT / 1e9
            ),
        ));
    }
    Ok(())
}
