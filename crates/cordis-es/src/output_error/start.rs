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
    difference_noise_level(take, 3)
}

/// The noise level (m) from differences of any `order` ≥ 1: white noise's `Δᵏe` has variance
/// `C(2k, k) σ²` (20 for k = 3), so the estimate is `√(median (Δᵏx)² / 0.455 / C(2k, k))`.
/// A smooth motion's own share falls as `(ω dt)ᵏ` with the order while white noise's estimate
/// stays the same: two orders that agree say the differences are noise (structure discovery
/// reads orders 3 and 6 to tell noisy positions from a smooth noiseless motion).
pub fn difference_noise_level(take: &Take, order: usize) -> (f64, usize) {
    let order = order.max(1);
    // Binomial coefficients of Δᵏ, alternating.
    let mut coef = vec![1.0f64];
    for _ in 0..order {
        let mut next = vec![0.0; coef.len() + 1];
        for (j, c) in coef.iter().enumerate() {
            next[j] -= c;
            next[j + 1] += c;
        }
        coef = next;
    }
    let var_gain: f64 = coef.iter().map(|c| c * c).sum();
    let mut sq = Vec::new();
    for i in 0..take.particles() {
        for c in 0..3 {
            for t in order..take.frames() {
                let mut d = 0.0;
                let mut seen = true;
                // Newest frame first: order 3 sums as `x₃ - 3x₂ + 3x₁ - x₀`, bit for bit the
                // output-error start's noise level as it always was.
                for (j, w) in coef.iter().enumerate().rev() {
                    let (x, weight) = take.at(t - order + j, i, c);
                    seen &= weight > 0.0;
                    d += w * x;
                }
                if seen {
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
    ((median / 0.455 / var_gain).sqrt(), sq.len())
}

/// [`noise_level_and_samples`] in the unit of the fit's weighted residuals: the noise σ̂
/// estimates (weights are 1/σ relative), `√(mean over coordinates of w² σ_k²)` with σ_k each
/// coordinate series' own level (the median of its third differences, a weight the same along
/// a series or scaled per difference by `C(6, 3) / Σ c_j²/w_j²`), each series counted by its
/// differences. Right whether the weights are (every `w σ_k` alike) or not (a uniform σ,
/// weights claimed: the global median of weighted differences then fell below σ̂ and called
/// a fit at the noise "above" it). Without weights, [`noise_level_and_samples`] as it is.
pub fn unit_weight_noise_level(take: &Take) -> (f64, usize) {
    if !take.weighted() {
        return noise_level_and_samples(take);
    }
    const COEF: [f64; 4] = [-1.0, 3.0, -3.0, 1.0];
    const GAIN: f64 = 20.0;
    let (mut total, mut samples) = (0.0, 0usize);
    let mut sq = Vec::new();
    for i in 0..take.particles() {
        for c in 0..3 {
            sq.clear();
            for t in 3..take.frames() {
                let (mut d, mut gain, mut seen) = (0.0, 0.0, true);
                for (j, k) in COEF.iter().enumerate() {
                    let (x, weight) = take.at(t - 3 + j, i, c);
                    seen &= weight > 0.0;
                    d += k * x;
                    gain += k * k / (weight * weight);
                }
                if seen {
                    sq.push(d * d * (GAIN / gain));
                }
            }
            if sq.is_empty() {
                continue;
            }
            sq.sort_by(f64::total_cmp);
            total += sq.len() as f64 * sq[sq.len() / 2] / 0.455 / GAIN;
            samples += sq.len();
        }
    }
    match samples {
        0 => (0.0, 0),
        n => ((total / n as f64).sqrt(), n),
    }
}

/// The starting genomes, each with the note that says where it comes from: the short cost's
/// exact minimum on smoothed, gap-filled positions when the scene is linear in its unknowns
/// (clamped into the boxes); otherwise (or when that solve fails) the heuristic start every
/// strategy uses. Two when hidden particles leave the short cost no row of observed positions
/// alone: the solve on imputed hidden positions ([`imputed_start`]) and the heuristic; the
/// fit keeps the one whose first window costs less (`Prepared::start`), as neither is better
/// everywhere (measured: BENCHMARKS.md "A start for hidden particles").
pub fn start_genomes(
    scene: &Scene,
    space: &ParameterSpace,
    take: &Take,
    noise: f64,
) -> Vec<(Vec<f64>, String)> {
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
    // The smoother puts a "fixed" particle at its mean position and judges its width on the
    // others' residuals: the scene's fixed particles and the hidden ones (at their constant
    // scene positions) are fixed for it, the held neighbours (tracked, moving) are not.
    let mut is_hidden = vec![false; take.particles()];
    for &h in &hidden {
        is_hidden[h] = true;
    }
    let constant: Vec<bool> = scene
        .particles
        .iter()
        .zip(&is_hidden)
        .map(|(p, &h)| p.fixed || h)
        .collect();
    let smoothed: Trajectory = match smooth(&filled, &constant, noise) {
        Some((s, _)) if noise > 0.0 => s,
        _ => filled.clone(),
    };
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
        let no_row = "heuristic start (hidden particles leave no short-cost row";
        return match imputed_start(scene, space, &smoothed, &hidden, &is_hidden) {
            Ok(imputed) => vec![imputed, heuristic(format!("{no_row})"))],
            Err(why) => vec![heuristic(format!("{no_row}; {why})"))],
        };
    }
    let Ok(mut problem) = Problem::new(&scene_rows, &smoothed, CostKind::Short) else {
        return vec![heuristic(
            "heuristic start (no short cost on this take)".into(),
        )];
    };
    problem.space = space.clone();
    vec![match least_squares::solve(&problem) {
        Ok(sol) => (
            clamped(space, &sol.genome),
            "short-cost least squares on smoothed positions".into(),
        ),
        Err(why) => heuristic(format!("heuristic start (short-cost solve refused: {why})")),
    }]
}

/// A solve's genome clamped into the unknowns' internal boxes.
fn clamped(space: &ParameterSpace, genome: &[f64]) -> Vec<f64> {
    space
        .unknowns
        .iter()
        .zip(genome)
        .map(|(u, &z)| u.clamp_internal(z))
        .collect()
}

/// The short cost's exact minimum when holding the hidden particles' neighbours leaves no row
/// (a hidden particle linked to every free one): the hidden particles held on positions
/// imputed from the known particles around them ([`super::impute`]) on the take's `smoothed`
/// positions, so their neighbours keep their rows (`is_hidden`: `hidden` as a mask; every
/// other particle is known, tracked or fixed). Err with why it cannot otherwise.
fn imputed_start(
    scene: &Scene,
    space: &ParameterSpace,
    smoothed: &Trajectory,
    hidden: &[usize],
    is_hidden: &[bool],
) -> Result<(Vec<f64>, String), String> {
    let known: Vec<bool> = is_hidden.iter().map(|&h| !h).collect();
    let Some(imputed) = super::impute::with_hidden_imputed(scene, smoothed, hidden, &known) else {
        return Err("no particle is seen to impute them from".into());
    };
    let mut held = scene.clone();
    for &h in hidden {
        held.particles[h].fixed = true;
    }
    let mut problem = Problem::new(&held, &imputed, CostKind::Short)
        .map_err(|e| format!("with them imputed: {e}"))?;
    problem.space = space.clone();
    let sol = least_squares::solve(&problem)
        .map_err(|e| format!("with them imputed the solve refused: {e}"))?;
    Ok((
        clamped(space, &sol.genome),
        "short-cost least squares on smoothed positions, hidden particles imputed from the \
         deformation of the seen ones around them"
            .into(),
    ))
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
/// fewer than 3 frames (a hidden particle, a marker occluded at the start) follows the rigid
/// motion of the particles that are seen ([`RigidStart`]): its scene position carried by the
/// best rotation and translation of the seen particles' layout onto their frame-0 positions,
/// and the velocity of that rigid motion there. With nothing seen it keeps the scene's value.
pub fn initial_state(scene: &Scene, free: &[usize], take: &Take) -> Vec<f64> {
    let dt = scene.dt;
    let mut out = Vec::with_capacity(6 * free.len());
    // Per free particle, which coordinates the data fixed.
    let mut seen_coords = Vec::with_capacity(free.len());
    let mut vel = [0.0; 3];
    for &i in free {
        let p = &scene.particles[i];
        let mut pos = p.pos;
        let mut seen = [false; 3];
        for c in 0..3 {
            vel[c] = p.vel[c];
            let frames = first_observed(take, i, c);
            if frames.len() < 3 {
                continue;
            }
            let (a, b, q) = quadratic(&frames);
            pos[c] = a;
            vel[c] = (b - q) / dt;
            seen[c] = true;
        }
        out.extend_from_slice(&pos);
        out.extend_from_slice(&vel);
        seen_coords.push(seen);
    }
    if seen_coords.iter().all(|s| s.iter().all(|&c| c)) {
        return out;
    }
    let Some(rigid) = RigidStart::fit(scene, free, &out, &seen_coords) else {
        return out;
    };
    for (k, &i) in free.iter().enumerate() {
        let (x, v) = rigid.at(Vec3::from(scene.particles[i].pos));
        for c in 0..3 {
            if !seen_coords[k][c] {
                out[6 * k + c] = x[c];
                out[6 * k + 3 + c] = v[c];
            }
        }
    }
    out
}

/// `(frame, value)` of the first (at most 9) frames that observe coordinate `c` of particle `i`.
fn first_observed(take: &Take, i: usize, c: usize) -> Vec<(f64, f64)> {
    (0..take.frames())
        .filter_map(|t| {
            let (x, w) = take.at(t, i, c);
            (w > 0.0).then_some((t as f64, x))
        })
        .take(9)
        .collect()
}

/// Which coordinates of each free particle the take observes in at least 3 frames: those
/// [`initial_state`] reads from the data; the others it puts on the seen particles' rigid motion.
pub fn seen_coordinates(free: &[usize], take: &Take) -> Vec<[bool; 3]> {
    free.iter()
        .map(|&i| std::array::from_fn(|c| first_observed(take, i, c).len() >= 3))
        .collect()
}

/// A restart's initial state of one take (`take_index` of the fit): the seen coordinates as
/// the start `start` had them, each unseen one (a hidden particle, a coordinate seen in fewer
/// than 3 frames) drawn about the rigid motion of the seen particles in the stuck fit's state
/// `fitted`, with the spread of the seen particles about that motion: position
/// `x_R + N(0, s_x²)`, velocity `v_R + N(0, s_v²)`, per coordinate, where `s_x`, `s_v` are the
/// rms deviations (m, m/s) of the seen coordinates from the rigid motion in `fitted`.
///
/// Why: with hidden particles the hidden initial state, not the parameters, decides the basin.
/// Measured on a generated 12-mass network with a quarter hidden at σ = 1e-2 (bench noise draw
/// 13): from the true parameters and the rigid hidden state the fit sticks; from the heuristic
/// parameters and the true hidden state it converges. Restarting the parameters only from the
/// same rigid hidden state kept landing in one wrong basin. Without a seen particle, or with
/// every coordinate seen, the start is returned as it is.
pub fn restart_states(
    scene: &Scene,
    free: &[usize],
    take: &Take,
    start: &[f64],
    fitted: &[f64],
    (attempt, take_index): (usize, usize),
) -> Vec<f64> {
    const RESTART_STATES_STREAM: u64 = 0x5EED_57A7;
    let seen = seen_coordinates(free, take);
    let mut out = start.to_vec();
    if seen.iter().all(|s| s.iter().all(|&c| c)) {
        return out;
    }
    let Some(rigid) = RigidStart::fit(scene, free, fitted, &seen) else {
        return out;
    };
    let on_rigid: Vec<(Vec3, Vec3)> = free
        .iter()
        .map(|&i| rigid.at(Vec3::from(scene.particles[i].pos)))
        .collect();
    let (mut sx, mut sv, mut n) = (0.0, 0.0, 0usize);
    for (k, (x, v)) in on_rigid.iter().enumerate() {
        for c in (0..3).filter(|&c| seen[k][c]) {
            sx += (fitted[6 * k + c] - x[c]).powi(2);
            sv += (fitted[6 * k + 3 + c] - v[c]).powi(2);
            n += 1;
        }
    }
    if n == 0 {
        return out;
    }
    let (sx, sv) = ((sx / n as f64).sqrt(), (sv / n as f64).sqrt());
    let mut draw = crate::rng::stream(RESTART_STATES_STREAM, attempt as u64, take_index as u64);
    for (k, (x, v)) in on_rigid.iter().enumerate() {
        for c in (0..3).filter(|&c| !seen[k][c]) {
            out[6 * k + c] = x[c] + sx * crate::rng::normal(&mut draw);
            out[6 * k + 3 + c] = v[c] + sv * crate::rng::normal(&mut draw);
        }
    }
    out
}

/// The rigid motion the seen particles describe at frame 0: positions `x = c₀ + R (p - p̄)`
/// for a particle laid out at `p` in the scene, velocities `v = v̄ + ω × (x - c₀)`. `R` is the
/// Kabsch rotation of the seen particles' scene layout onto their frame-0 positions (fixed
/// particles count as seen where the scene puts them, at rest); `ω` the least-squares angular
/// velocity, `I ω = Σ r × (v - v̄)` with `I = Σ (|r|² 1 - r rᵀ)`, solved by SVD so a line of
/// particles (an axis `I` cannot see) adds no spin about it.
struct RigidStart {
    layout_centre: Vec3,
    centre: Vec3,
    velocity: Vec3,
    rotation: nalgebra::Matrix3<f64>,
    spin: Vec3,
}

impl RigidStart {
    /// `state` is [`initial_state`]'s layout, `seen` which of its coordinates the data gave.
    fn fit(scene: &Scene, free: &[usize], state: &[f64], seen: &[[bool; 3]]) -> Option<Self> {
        use nalgebra::Matrix3;
        // (layout position, frame-0 position, velocity) of every particle seen whole.
        let mut pts: Vec<(Vec3, Vec3, Vec3)> = Vec::new();
        for (k, &i) in free.iter().enumerate() {
            if seen[k].iter().all(|&c| c) {
                let s = &state[6 * k..6 * k + 6];
                pts.push((
                    Vec3::from(scene.particles[i].pos),
                    Vec3::new(s[0], s[1], s[2]),
                    Vec3::new(s[3], s[4], s[5]),
                ));
            }
        }
        for p in scene.particles.iter().filter(|p| p.fixed) {
            let x = Vec3::from(p.pos);
            pts.push((x, x, Vec3::zeros()));
        }
        if pts.is_empty() {
            return None;
        }
        let n = pts.len() as f64;
        let mean = |f: &dyn Fn(&(Vec3, Vec3, Vec3)) -> Vec3| pts.iter().map(f).sum::<Vec3>() / n;
        let (pbar, cbar, vbar) = (mean(&|p| p.0), mean(&|p| p.1), mean(&|p| p.2));
        let mut cross = Matrix3::zeros();
        let mut inertia = Matrix3::zeros();
        let mut moment = Vec3::zeros();
        for (p, x, v) in &pts {
            let (a, b) = (p - pbar, x - cbar);
            cross += a * b.transpose();
            inertia += Matrix3::identity() * b.norm_squared() - b * b.transpose();
            moment += b.cross(&(v - vbar));
        }
        let rotation = super::impute::kabsch(&cross);
        let scale = inertia.norm().max(f64::MIN_POSITIVE);
        let spin = inertia
            .svd(true, true)
            .solve(&moment, 1e-9 * scale)
            .unwrap_or_else(|_| Vec3::zeros());
        Some(RigidStart {
            layout_centre: pbar,
            centre: cbar,
            velocity: vbar,
            rotation,
            spin,
        })
    }

    /// Position and velocity of the particle laid out at `p`.
    fn at(&self, p: Vec3) -> (Vec3, Vec3) {
        let r = self.rotation * (p - self.layout_centre);
        (self.centre + r, self.velocity + self.spin.cross(&r))
    }
}

/// The scene's own initial state in the fit's layout: `[x0, v0]` per free particle, in scene
/// order (what `Config::start_states` takes per take).
pub fn scene_state(scene: &Scene) -> Vec<f64> {
    scene
        .particles
        .iter()
        .filter(|p| !p.fixed)
        .flat_map(|p| p.pos.into_iter().chain(p.vel))
        .collect()
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

#[cfg(test)]
mod tests {
    use super::*;
    use cordis_core::{Particle, Trajectory};

    /// A body spinning at ω about its centre while drifting at u, sampled at dt: positions
    /// `c + u t + Rot(ω t) (p - c)` exactly.
    fn spinning(
        layout: &[[f64; 3]],
        omega: Vec3,
        drift: Vec3,
        dt: f64,
        frames: usize,
    ) -> Trajectory {
        let n = layout.len();
        let c: Vec3 = layout.iter().map(|p| Vec3::from(*p)).sum::<Vec3>() / n as f64;
        let mut traj = Trajectory::zeros(frames, n).with_dt(dt);
        for t in 0..frames {
            let time = t as f64 * dt;
            let rot = nalgebra::Rotation3::new(omega * time);
            let frame: Vec<Vec3> = layout
                .iter()
                .map(|p| c + drift * time + rot * (Vec3::from(*p) - c))
                .collect();
            traj.set_frame(t, &frame);
        }
        traj
    }

    /// Five particles of a body, off any symmetry.
    const BODY: [[f64; 3]; 5] = [
        [0.0, 0.0, 0.0],
        [0.3, 0.0, 0.0],
        [0.0, 0.25, 0.0],
        [0.0, 0.0, 0.2],
        [0.2, 0.2, 0.1],
    ];

    /// The scene of `layout`: it knows the layout, not the motion (at rest).
    fn at_rest(layout: &[[f64; 3]], dt: f64) -> Scene {
        let mut scene = Scene::new(dt);
        for p in layout {
            scene.add_particle(Particle::new(1.0, *p));
        }
        scene
    }

    #[test]
    fn a_hidden_particle_starts_on_the_rigid_motion_of_the_seen_ones() {
        let layout = BODY;
        let dt = 1e-3;
        let (omega, drift) = (Vec3::new(0.4, -1.1, 2.0), Vec3::new(0.5, 0.0, -0.3));
        let traj = spinning(&layout, omega, drift, dt, 20);
        let scene = at_rest(&layout, dt);
        let hidden = 4;
        let take = Take::complete(&traj).masked(|_, i, _| i != hidden);
        let free: Vec<usize> = (0..layout.len()).collect();
        let state = initial_state(&scene, &free, &take);
        let s = &state[6 * hidden..6 * hidden + 6];
        let c: Vec3 = layout.iter().map(|p| Vec3::from(*p)).sum::<Vec3>() / 5.0;
        let r = Vec3::from(layout[hidden]) - c;
        // The seen particles' v0 (and so ω) are backward differences read from quadratics
        // through 9 frames of a rotation: within 0.5 % of the true rigid velocity.
        let v_true = drift + omega.cross(&r);
        // The seen particles' x0 come from quadratics through their first frames: the motion's
        // cubic term leaves ~1e-8 m.
        for k in 0..3 {
            approx::assert_abs_diff_eq!(s[k], layout[hidden][k], epsilon = 1e-7);
            approx::assert_abs_diff_eq!(s[3 + k], v_true[k], epsilon = 5e-3 * v_true.norm());
        }
        // Seen particles keep their own fit: hiding one changes nothing for the others.
        let whole = initial_state(&scene, &free, &Take::complete(&traj));
        assert_eq!(&state[..6 * hidden], &whole[..6 * hidden]);
    }

    #[test]
    fn a_restart_moves_the_hidden_state_by_the_seen_particles_spread() {
        let layout = BODY;
        let dt = 1e-3;
        let traj = spinning(&layout, Vec3::new(0.4, -1.1, 2.0), Vec3::x(), dt, 20);
        let scene = at_rest(&layout, dt);
        let hidden = 4;
        let take = Take::complete(&traj).masked(|_, i, _| i != hidden);
        let free: Vec<usize> = (0..layout.len()).collect();
        assert_eq!(seen_coordinates(&free, &take)[hidden], [false; 3]);
        let start = initial_state(&scene, &free, &take);
        // The rms distance of the hidden particle's restarts from the start, when the stuck
        // fit's seen particles deviate from a rigid motion by ±delta per coordinate.
        let spread_for = |delta: f64| {
            let mut fitted = initial_state(&scene, &free, &Take::complete(&traj));
            for (k, x) in fitted[..6 * hidden].iter_mut().enumerate() {
                *x += if k % 2 == 0 { delta } else { -delta };
            }
            let (mut pos, mut vel) = (0.0, 0.0);
            let attempts = 200;
            for attempt in 1..=attempts {
                let restarted = restart_states(&scene, &free, &take, &start, &fitted, (attempt, 0));
                assert_eq!(&restarted[..6 * hidden], &start[..6 * hidden], "seen kept");
                let (a, b) = (&restarted[6 * hidden..], &start[6 * hidden..]);
                pos += (0..3).map(|c| (a[c] - b[c]).powi(2)).sum::<f64>();
                vel += (3..6).map(|c| (a[c] - b[c]).powi(2)).sum::<f64>();
            }
            let n = (3 * attempts) as f64;
            ((pos / n).sqrt(), (vel / n).sqrt())
        };
        // A rigid stuck fit gives no spread: the restart is the rigid start again.
        let (pos, vel) = spread_for(0.0);
        assert!(pos < 1e-6 && vel < 1e-3, "{pos} {vel}");
        // Deviations of 1 cm spread the hidden particle's restarts by about as much.
        let delta = 1e-2;
        let (pos, vel) = spread_for(delta);
        assert!(pos > 0.3 * delta && pos < 2.0 * delta, "{pos}");
        assert!(vel > 0.3 * delta && vel < 2.0 * delta, "{vel}");
        // A restart is fixed by its attempt and take, and differs between attempts.
        let fitted = start.clone();
        let mut shaken = start.clone();
        shaken[0] += delta;
        let one = restart_states(&scene, &free, &take, &start, &shaken, (3, 1));
        assert_eq!(
            one,
            restart_states(&scene, &free, &take, &start, &shaken, (3, 1))
        );
        assert_ne!(
            one,
            restart_states(&scene, &free, &take, &start, &shaken, (4, 1))
        );
        // With every coordinate seen there is nothing to redraw.
        let whole = Take::complete(&traj);
        let all = initial_state(&scene, &free, &whole);
        assert_eq!(
            restart_states(&scene, &free, &whole, &all, &fitted, (1, 0)),
            all
        );
    }

    #[test]
    fn with_nothing_seen_the_scene_state_is_kept() {
        let traj = spinning(
            &[[0.0; 3], [1.0, 0.0, 0.0]],
            Vec3::zeros(),
            Vec3::x(),
            0.01,
            10,
        );
        let mut scene = Scene::new(0.01);
        scene.add_particle(Particle::new(1.0, [0.0; 3]).with_vel([0.0, 2.0, 0.0]));
        scene.add_particle(Particle::new(1.0, [1.0, 0.0, 0.0]));
        let take = Take::complete(&traj).masked(|_, _, _| false);
        let state = initial_state(&scene, &[0, 1], &take);
        assert_eq!(
            state,
            vec![0.0, 0.0, 0.0, 0.0, 2.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0]
        );
    }
}
