//! Where the output-error fit starts: a noise level read from the data, the short-cost estimate
//! on smoothed positions, and each take's initial state from its first frames.

use cordis_core::{Scene, Trajectory, Vec3};

use super::observations::Take;
use crate::cost::CostKind;
use crate::discover::smooth::smooth;
use crate::problem::Problem;
use crate::space::ParameterSpace;
use crate::strategies::least_squares;

/// The noise level of a take's positions (m), from third differences: for a motion sampled far
/// above its frequencies, `Δ³x` is the noise's `e(t+3) - 3e(t+2) + 3e(t+1) - e(t)`, of variance
/// `20 σ²`. The median of `(Δ³x)²` (divided by 0.455, the median of χ²₁) keeps the estimate
/// robust to the motion's own sharp moments and to outliers. 0 for noiseless smooth motion.
pub fn noise_level(take: &Take) -> f64 {
    noise_level_and_samples(take).0
}

/// [`noise_level`] and the number of third differences it was read from (its precision: the
/// median's relative standard deviation is `1.17/√n` for independent samples, about `2/√n`
/// for these overlapping ones, whose neighbours correlate at −0.75).
pub fn noise_level_and_samples(take: &Take) -> (f64, usize) {
    let mut sq = Vec::new();
    for i in 0..take.particles() {
        for c in 0..3 {
            for t in 3..take.frames() {
                let at = |k: usize| take.at(k, i, c);
                let q = [at(t - 3), at(t - 2), at(t - 1), at(t)];
                if q.iter().all(|(_, w)| *w > 0.0) {
                    let d = q[3].0 - 3.0 * q[2].0 + 3.0 * q[1].0 - q[0].0;
                    sq.push(d * d);
                }
            }
        }
    }
    if sq.is_empty() {
        return (0.0, 0);
    }
    sq.sort_by(f64::total_cmp);
    let median = sq[sq.len() / 2];
    ((median / 0.455 / 20.0).sqrt(), sq.len())
}

/// The starting genome: the short cost's exact minimum on smoothed, gap-filled positions when
/// the scene is linear in its unknowns and every particle is tracked (clamped into the boxes);
/// otherwise (or when that solve fails) the heuristic start every strategy uses.
pub fn start_genome(
    scene: &Scene,
    space: &ParameterSpace,
    take: &Take,
    noise: f64,
) -> (Vec<f64>, String) {
    let fallback: Vec<Vec3> = scene.particles.iter().map(|p| Vec3::from(p.pos)).collect();
    let filled = take.filled(&fallback).with_dt(scene.dt);
    let heuristic = |why: String| -> (Vec<f64>, String) {
        let problem = Problem::new(scene, &filled, CostKind::Short).ok();
        let genome = match problem {
            Some(mut pr) => {
                pr.space = space.clone();
                crate::strategies::common::start_genome(&pr)
            }
            None => space
                .unknowns
                .iter()
                .map(|u| {
                    let (lo, hi) = u.internal_bounds();
                    0.5 * (lo + hi)
                })
                .collect(),
        };
        (genome, why)
    };
    // A hidden particle's positions are unknown, so the short cost cannot use the rows of its
    // neighbours either: the start solves on the scene with the hidden particles and their
    // neighbours held (a fixed particle has no row), so every row left reads observed
    // positions only. An unknown no remaining row sees is one the solve reports undetermined
    // and holds at its starting value.
    let hidden: Vec<usize> = (0..take.particles())
        .filter(|&i| !take.tracks(i) && !scene.particles[i].fixed)
        .collect();
    let mut scene_rows = scene.clone();
    for &h in &hidden {
        scene_rows.particles[h].fixed = true;
        for l in &scene.links {
            if l.particles.contains(&h) {
                for &j in &l.particles {
                    scene_rows.particles[j].fixed = true;
                }
            }
        }
    }
    if !hidden.is_empty() && scene_rows.particles.iter().all(|p| p.fixed) {
        return heuristic("heuristic start (hidden particles leave no short-cost row)".into());
    }
    let scene = &scene_rows;
    let fixed: Vec<bool> = scene.particles.iter().map(|p| p.fixed).collect();
    let smoothed: Trajectory = match smooth(&filled, &fixed, noise) {
        Some((s, _)) if noise > 0.0 => s,
        _ => filled.clone(),
    };
    let Ok(mut problem) = Problem::new(scene, &smoothed, CostKind::Short) else {
        return heuristic("heuristic start (no short cost on this take)".into());
    };
    problem.space = space.clone();
    match least_squares::solve(&problem) {
        Ok(sol) => {
            let genome = space
                .unknowns
                .iter()
                .zip(&sol.genome)
                .map(|(u, &z)| u.clamp_internal(z))
                .collect();
            (
                genome,
                "short-cost least squares on smoothed positions".into(),
            )
        }
        Err(why) => heuristic(format!("heuristic start (short-cost solve refused: {why})")),
    }
}

/// The start of restart `attempt` (1, 2, …) after a fit stuck in a wrong basin: the unknowns a
/// heuristic reads from the data (rest lengths from the observed lengths) keep that value, the
/// others (stiffness, damping, masses) are drawn uniformly in their internal boxes (log-uniform
/// for wide positive ones) from a stream fixed by `attempt`, so a fit is reproducible.
pub fn restart_genome(
    scene: &Scene,
    space: &ParameterSpace,
    take: &Take,
    attempt: usize,
) -> Vec<f64> {
    use rand::Rng;
    const RESTART_STREAM: u64 = 0x5EED_0E57;
    let fallback: Vec<Vec3> = scene.particles.iter().map(|p| Vec3::from(p.pos)).collect();
    let filled = take.filled(&fallback).with_dt(scene.dt);
    let observed = match Problem::new(scene, &filled, CostKind::Short) {
        Ok(pr) if pr.observed.len() == space.dim() => pr.observed,
        _ => vec![None; space.dim()],
    };
    let mut draw = crate::rng::stream(RESTART_STREAM, attempt as u64, 0);
    space
        .unknowns
        .iter()
        .zip(&observed)
        .map(|(u, seen)| {
            let (lo, hi) = u.internal_bounds();
            let random = lo + (hi - lo) * draw.random::<f64>();
            u.clamp_internal(seen.map_or(random, |m| u.to_internal(m)))
        })
        .collect()
}

/// Each free particle's `[x0, v0]` from the take's first frames: a least-squares quadratic in
/// time through its first (at least 3) observed frames per coordinate, `x0` its value at frame
/// 0 and `v0 = (x(0) - x(-1))/dt` (the scheme's backward difference). A coordinate observed in
/// fewer than 3 frames starts at the scene's value with no velocity.
pub fn initial_state(scene: &Scene, free: &[usize], take: &Take) -> Vec<f64> {
    let dt = scene.dt;
    let mut out = Vec::with_capacity(6 * free.len());
    let mut vel = [0.0; 3];
    for &i in free {
        let p = &scene.particles[i];
        let mut pos = p.pos;
        for c in 0..3 {
            vel[c] = p.vel[c];
            let seen: Vec<(f64, f64)> = (0..take.frames())
                .filter_map(|t| {
                    let (x, w) = take.at(t, i, c);
                    (w > 0.0).then_some((t as f64, x))
                })
                .take(9)
                .collect();
            if seen.len() < 3 {
                continue;
            }
            let (a, b, q) = quadratic(&seen);
            pos[c] = a;
            vel[c] = (b - q) / dt;
        }
        out.extend_from_slice(&pos);
        out.extend_from_slice(&vel);
    }
    out
}

/// Least-squares `x = a + b t + c t²` through the points.
fn quadratic(pts: &[(f64, f64)]) -> (f64, f64, f64) {
    let mut m = nalgebra::Matrix3::zeros();
    let mut r = nalgebra::Vector3::zeros();
    for &(t, x) in pts {
        let phi = nalgebra::Vector3::new(1.0, t, t * t);
        m += phi * phi.transpose();
        r += phi * x;
    }
    match m.cholesky() {
        Some(ch) => {
            let s = ch.solve(&r);
            (s[0], s[1], s[2])
        }
        None => (pts[0].1, 0.0, 0.0),
    }
}
