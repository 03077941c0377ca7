//! Stability of the CORDIS scheme: how close a scene is to the step size at which it explodes.
//!
//! # The bound
//!
//! For one mass m on a spring K with damping Z to a fixed point, the scheme of SPEC §2.1 is
//! `x(n+1) = (2 - k - z) x(n) - (1 - z) x(n-1)` with `k = K dt²/m`, `z = Z dt/m`, whose roots
//! stay in the unit disc exactly when `k + 2z < 4`: the classical CORDIS condition
//! `4M > K + 2Z` in discrete units (`M = m`, `K = K dt²`, `Z = Z dt`, all in kg). Its ratio
//! `q = (K dt² + 2 Z dt) / (4 m)` is therefore exact for a particle whose neighbours do not move.
//!
//! For a network the same energy argument (the scheme keeps
//! `E = dᵀ(M - G/4)d + ¼ sᵀ(dt²K)s`, `d = x(n) - x(n-1)`, `s = x(n) + x(n-1)`, from growing)
//! gives the sufficient condition `G = dt² K + 2 dt C < 4 M` as quadratic forms, with K and C
//! the linearised stiffness and damping matrices. Its largest eigenvalue is bounded per
//! particle by Gershgorin's theorem on `M^-½ G M^-½`, 3×3 block per particle:
//!
//! ```text
//! q_i = ( Σ_links at i g_own  +  Σ_links to a free j g_ij √(m_i / m_j) ) / (4 m_i)
//! ```
//!
//! where `g = dt² K + 2 dt Z` of the link (in kg). The first sum is the per-particle CORDIS
//! condition above (the ratio with every neighbour held fixed); the second counts that free
//! neighbours move against i. Hence:
//!
//! - `max q_i < 1` guarantees stability of the linearised scheme ([`StabilityReport::stable`]);
//! - the first sum alone ([`StabilityReport::local_max_ratio`], the issue's per-particle
//!   `(dt² ΣK + 2 dt ΣZ) / 4m`) bounds the diagonal block; where that block is `ΣK · I` (links
//!   at the particle all aligned, as in a 1-D chain, or isotropic: dampers, zero-rest-length
//!   springs) it is a diagonal entry of the matrix, so `≥ 1` then means the undamped
//!   linearisation explodes. With links in several directions the true block is smaller and
//!   the local figure may overestimate too (a cloth is stable slightly beyond it).
//!
//! For two equal free masses on one spring the Gershgorin ratio is exact (twice the local
//! one); for a mass joined only to fixed points both are exact. `cordis-bench stability`
//! measures how conservative the bound is on larger networks.
//!
//! # Local stiffness of each kind
//!
//! - spring, anchor, conditional pair: K along the link and Z on the rate of elongation. The
//!   transverse stiffness `K (1 - l0/L)` is below K whenever `L ≥ l0/2`, so K bounds the block.
//! - quadratic viscosity (`damping_quadratic` Z₂ of a spring or conditional type): the force
//!   `Z s + Z₂ s |s|` has the slope `Z + 2 Z₂ |s|` in the rate s, which grows without bound
//!   with the speed, so no bound holds over every motion. It is counted at the start's rates
//!   (`s` from `(x(0) - x(-1)) / dt`): the bound is that of the start, and a motion whose
//!   links separate or close faster than there may need a smaller step (each link stays
//!   stable while `Z + 2 Z₂ |s|` keeps its row below the bound).
//! - damper `Z w` (isotropic): Z; drag: Z on its particle; nonlinear drag: `max(z1, z2)`.
//! - angle (i, j, k), energy `½K(cosθ - c0)²`: the Hessian's rank-one part `K ∇c ∇cᵀ`, with
//!   `|∂c/∂x_i| = sinθ / |a|`, `|∂c/∂x_k| = sinθ / |b|`, `|∂c/∂x_j| ≤ |∂c/∂x_i| + |∂c/∂x_k|`,
//!   taken at `sinθ = 1` (its largest value over the motion) with the initial arm lengths
//!   `|a|`, `|b|`. The curvature part `K (c - c0) ∇²c` vanishes at rest and is not counted, so
//!   for angles the bound is that of small motions around the rest angle.
//! - conditional types: one spring per pair within `range` at the initial positions.
//! - plane (contact): K and Z along the normal, as an anchor's, counted whether or not the
//!   particle touches (the bound holds in every contact state). Its friction acts in the
//!   tangent plane as a damper of slope `m / dt` near rest ([`crate::forces::plane`]: the
//!   regularisation's `a = m |v_t| / dt`), `g = 2 dt (m/dt) = 2m`, whatever the normal force:
//!   it alone takes 0.5 of the ratio (at sliding speeds its slope is smaller). The two act in
//!   orthogonal directions, so the plane's 3×3 block is `g_n n nᵀ + g_t (I - n nᵀ)`, of norm
//!   `max(g_n, g_t)`, which is what it adds to the particle's row.
//! - tgr: its link like a spring (K, Z). The tendon (a 1-D mass m_t under K + K_t) is not a
//!   particle and is not reported: keep `(K + K_t) dt² + 2 Z_t dt < 4 m_t` by hand.
//! - Provot's elongation limit is a projection, not a force: it only removes energy.
//! - muscle: its spring (K, Z) plus its neuron's slopes, next section.
//!
//! # Neurons
//!
//! A muscle link m pulls its ends together with `f_m = K e_m + Z s_m + G tanh(h_m - θ)`,
//! `h_m = Σ_k (w_len[k] e_k + w_rate[k] s_k)` over the links k it observes (SPEC §2.4). Its
//! linearisation about any state adds to the spring's `K δe_m + Z δs_m` the neuron's
//! `Σ_k D_mk δs_k + Σ_k E_mk δe_k` with `D_mk = G c_m w_rate[k]`, `E_mk = G c_m w_len[k]`
//! and `c_m = tanh'(h_m - θ) ∈ (0, 1]`: a damping (and a stiffness) between links, of either
//! sign and not symmetric, at most `|G w|` whatever the state. The rate part injects energy
//! in some modes (the `muscle` example's negative weights feed the muscles' in-phase stretch:
//! a negative damping) and damps others (its anti-phase stretch gets `+G |w|`), and the
//! scheme's flip limit `k + 2z < 4` sees the latter. With `s_m` the link's rate, the
//! neurons' damping form is `Σ_mk D_mk s_m s_k`, and `|D_mk s_m s_k| ≤ ½ |D_mk| (s_m² + s_k²)`
//! gives
//!
//! ```text
//! -Σ_m a_m s_m²  ≤  Σ_mk D_mk s_m s_k  ≤  Σ_m a_m s_m²,   a_m = Σ ½ |G w_rate|
//! ```
//!
//! the sum over every (neuron, observed link) pair in which m is the neuron's muscle or the
//! observed link. So the neurons' damping is, as a quadratic form, at most a damper `a_m`
//! (N·s/m) on each muscle link, and the bound counts each muscle as a spring of damping
//! `Z + a_m` — and of stiffness `K + b_m`, `b_m` the same sum of `½ |G w_len|` (the length
//! weights' slope, bounded the same way). It is a bound: sufficient, not necessary. It is
//! exact for one mass held by muscles that observe each other's rate at `tanh' = 1` (the test
//! `neurons_rate_damping_counts_in_the_bound_and_matches_the_measured_limit`: ratio 1.5,
//! measured 1.5 to 0.2 %, where the spring part alone read 0.005), and conservative when
//! weights of opposite signs cancel or `tanh` saturates.
//!
//! What `q < 1` then guarantees is that the scheme adds no growth of its own; the model may
//! still grow. In one dimension (one mass, `k = K dt²/m`, passive `z = Z dt/m`, neuron slope
//! `ζ ∈ [-α, α]`, `α = a dt/m`): `q = (k + 2z + 2α)/4 < 1` keeps `k + 2(z + ζ) < 4` (no flip)
//! for every slope; where `z + ζ < 0` (the neuron injects more than Z removes) the roots'
//! product `1 - (z + ζ) ≤ 1 + α` bounds the growth by `√(1 + α) ≈ 1 + a dt / 2m` per step,
//! the rate `a / 2m` per second that the continuous model's negative damping has, whatever
//! the step. (In a network the energy `E` above, built on the bound's matrix, is positive
//! definite when `q < 1`, and the neurons change it per step only by the difference between
//! their slopes and the bound's, of order `dt a / m` relative: again a rate per second, not a
//! factor per step.) That growth is the limit cycle the `muscle` and `horse-gait` examples
//! are built on (tanh saturates it), and no step removes it, so the bound does not report it.
//! `bound_keeps_random_muscle_chains_from_blowing_up` checks the claim on random chains whose
//! passive damping covers the neurons': at ratios 0.3–0.95 of this bound none gains energy
//! (at most ×1.04 over 1,000 frames), while scaled to 0.95 of the spring-only bound 79 of 200
//! blow up.
//!
//! Fixed particles have no ratio. Unknown parameters count at [`crate::Param::value`].
//!
//! # Divergence
//!
//! The simulator stops with [`crate::CordisError::Diverged`] (frame, particle) at the first
//! position that is not finite or beyond the guard of [`crate::runaway`], and writes nothing.
//! The guard is relative to the scene's start, 10⁶ times the size, reach and speeds a stable
//! model from it can have at that time (`R(t)`, capped at 10¹⁰⁰ m), so it grows with time as a
//! long free fall or a thrown particle does and flags neither, while an exponential instability
//! passes it a few hundred frames after it starts (frame 422 for a growth of 1.05 per step
//! from 1 m, where 10¹⁰⁰ m took 4,719).

use crate::error::Result;
use crate::forces::grid::Grid;
use crate::{Plan, Scene, Vec3};

/// Per-particle ratios to the stability bound (see the module documentation).
#[derive(Clone, Debug, PartialEq)]
pub struct StabilityReport {
    /// `q_i` per particle (`None` for fixed particles): below 1 for every particle, the
    /// linearised scheme cannot explode. May be `+inf` for absurd values, never NaN.
    pub per_particle: Vec<Option<f64>>,
    /// `max q_i` (0 when no particle is free).
    pub max_ratio: f64,
    /// The particle with the largest `q_i`.
    pub worst_particle: Option<usize>,
    /// `max_ratio < 1`.
    pub stable: bool,
    /// Largest ratio with every neighbour held fixed (the issue's per-particle
    /// `(dt² ΣK + 2 dt ΣZ) / 4m`): at or above 1 the undamped scheme explodes when the links
    /// at that particle are aligned or isotropic (see the module documentation).
    pub local_max_ratio: f64,
}

/// The stability report of a scene at its parameter values. Fails only on an invalid scene.
pub fn stability(scene: &Scene) -> Result<StabilityReport> {
    let plan = Plan::compile(scene)?;
    Ok(plan_stability(&plan, &scene.param_values()))
}

/// The stability report of a compiled plan with any parameter vector of its layout (for
/// example an identification candidate), at the plan's initial positions. Panics on a vector
/// of the wrong length, as [`crate::Simulator::from_plan`] does (a caller's bug, not input).
pub fn plan_stability(plan: &Plan, p: &[f64]) -> StabilityReport {
    let mut ws = StabilityScratch::default();
    row_sums(plan, p, &mut ws);
    let mass = &p[plan.layout.mass_offset..plan.layout.mass_offset + plan.n];
    let mut per_particle = vec![None; plan.n];
    let (mut max_ratio, mut worst, mut local_max) = (0.0_f64, None, 0.0_f64);
    for i in (0..plan.n).filter(|&i| plan.free[i]) {
        // Divide by m before 4: `4 m` overflows for m above ~4.5e307 kg, and ∞/∞ is NaN.
        let q = (ws.own[i] + ws.coupled[i]) / mass[i] / 4.0;
        local_max = local_max.max(ws.own[i] / mass[i] / 4.0);
        per_particle[i] = Some(q);
        if worst.is_none() || q > max_ratio {
            max_ratio = q;
            worst = Some(i);
        }
    }
    StabilityReport {
        per_particle,
        max_ratio,
        worst_particle: worst,
        stable: max_ratio < 1.0,
        local_max_ratio: local_max,
    }
}

/// Buffers of [`plan_max_ratio`] (row sums, square roots of the masses, the conditional grid),
/// so that checking many parameter vectors allocates nothing after the first.
#[derive(Clone, Debug, Default)]
pub struct StabilityScratch {
    own: Vec<f64>,
    coupled: Vec<f64>,
    root: Vec<f64>,
    /// Per muscle link, the neurons' `[stiffness, damping]` it carries (`neural_slopes`).
    neural: Vec<[f64; 2]>,
    grid: Grid,
}

/// [`StabilityReport::max_ratio`] of `p` alone, with reusable buffers: what an identification
/// checks on every candidate (`--stable-horizon`). Equal to [`plan_stability`]'s figure.
pub fn plan_max_ratio(plan: &Plan, p: &[f64], ws: &mut StabilityScratch) -> f64 {
    row_sums(plan, p, ws);
    let mass = &p[plan.layout.mass_offset..plan.layout.mass_offset + plan.n];
    (0..plan.n)
        .filter(|&i| plan.free[i])
        .map(|i| (ws.own[i] + ws.coupled[i]) / mass[i] / 4.0)
        .fold(0.0, f64::max)
}

/// Fills `ws.own` and `ws.coupled` with every particle's Gershgorin row sums (kg).
fn row_sums(plan: &Plan, p: &[f64], ws: &mut StabilityScratch) {
    assert_eq!(
        p.len(),
        plan.layout.len,
        "parameter vector of the wrong length"
    );
    let n = plan.n;
    let mass = &p[plan.layout.mass_offset..plan.layout.mass_offset + n];
    // √m once per particle: √(m_i/m_j) as a quotient of roots cannot overflow where the
    // quotient itself would (masses span the whole f64 range).
    ws.root.clear();
    ws.root.extend(mass.iter().map(|m| m.sqrt()));
    ws.own.clear();
    ws.own.resize(n, 0.0);
    ws.coupled.clear();
    ws.coupled.resize(n, 0.0);
    let mut acc = Acc {
        own: &mut ws.own,
        coupled: &mut ws.coupled,
        free: &plan.free,
        root: &ws.root,
    };
    binary_links(plan, p, &mut ws.neural, &mut acc);
    one_particle_links(plan, p, mass, &mut acc);
    shape_links(plan, p, &mut ws.grid, &mut acc);
}

/// A link's weight (kg) in the Gershgorin rows: `K dt² + 2 Z dt`, the dt of its first
/// particle's world (a link lies inside one world, validated).
fn link_weight(plan: &Plan, k: f64, z: f64, i: u32) -> f64 {
    let dt = plan.dt_of(i as usize);
    mul(k, dt * dt) + mul(2.0 * z, dt)
}

/// The row sums of the links between two particles: springs, TGRs, central-control muscles
/// (and their controller dipoles), local-control muscles (with their neurons' slopes, in
/// `neural`) and dampers.
fn binary_links(plan: &Plan, p: &[f64], neural: &mut Vec<[f64; 2]>, acc: &mut Acc<'_>) {
    for (ri, r) in plan.springs.runs.iter().enumerate() {
        let (k, z) = (p[r.param], p[r.param + 2]);
        let z2 = plan
            .springs
            .quadratic
            .get(ri)
            .copied()
            .flatten()
            .map_or(0.0, |s| p[s]);
        for &[i, j] in &plan.springs.pairs[r.start..r.end] {
            let (i, j) = (i as usize, j as usize);
            let z = if z2 != 0.0 {
                z + 2.0 * z2 * start_rate(plan, i, j)
            } else {
                z
            };
            acc.pair(i, j, link_weight(plan, k, z, i as u32));
        }
    }
    // A TGR's link is a spring whose rest length moves: the same local stiffness. Its tendon
    // is a 1-D mass outside the particle system and is not reported.
    let tgrs = &plan.stateful.tgrs;
    for r in &tgrs.runs {
        let (k, z) = (p[r.param], p[r.param + 2]);
        for &[i, j] in &tgrs.pairs[r.start..r.end] {
            acc.pair(i as usize, j as usize, link_weight(plan, k, z, i));
        }
    }
    // A central-control muscle's link likewise; its controller dipole feels the tendon's spring
    // K_t on its length (the other end is the tendon, not a particle), with Z_t written on the
    // change per muscle step: a rate coefficient Z_t dt_c / dt_muscle in the controller's time.
    let controlled = &plan.stateful.controlled_tgrs;
    for (r, &dt) in controlled.runs.iter().zip(&controlled.dts) {
        let (k, z, kt, zt) = (p[r.param], p[r.param + 2], p[r.param + 4], p[r.param + 5]);
        for m in r.start..r.end {
            let [i, j] = controlled.pairs[m];
            acc.pair(i as usize, j as usize, link_weight(plan, k, z, i));
            let [c, d] = controlled.controllers[m];
            let zc = zt * (plan.dt_of(c as usize) / dt);
            acc.pair(c as usize, d as usize, link_weight(plan, kt, zc, c));
        }
    }
    // A muscle is a spring (K, l0, Z first in its parameters) plus a neuron whose slopes in
    // the observed links' elongations and rates are bounded by `|G w|`: each muscle link
    // counts the share of them it carries (`neural_slopes`) on top of its K and Z.
    neural_slopes(plan, p, neural);
    for r in &plan.muscles.runs {
        let (k, z) = (p[r.param], p[r.param + 2]);
        let muscles = plan.muscles.pairs[r.start..r.end].iter();
        for (&[i, j], &[kn, zn]) in muscles.zip(&neural[r.start..r.end]) {
            acc.pair(i as usize, j as usize, link_weight(plan, k + kn, z + zn, i));
        }
    }
    for r in &plan.dampers.runs {
        for &[i, j] in &plan.dampers.pairs[r.start..r.end] {
            acc.pair(
                i as usize,
                j as usize,
                link_weight(plan, 0.0, p[r.param], i),
            );
        }
    }
}

/// The row sums of the links of one particle: anchors, drags (linear and not) and planes
/// (a plane with friction bounded by its tangential slope, `2 m`).
fn one_particle_links(plan: &Plan, p: &[f64], mass: &[f64], acc: &mut Acc<'_>) {
    for r in &plan.anchors.runs {
        let (k, z) = (p[r.param], p[r.param + 2]);
        for &i in &plan.anchors.particles[r.start..r.end] {
            acc.own[i as usize] += link_weight(plan, k, z, i);
        }
    }
    for r in &plan.drags.runs {
        for &i in &plan.drags.particles[r.start..r.end] {
            acc.own[i as usize] += link_weight(plan, 0.0, p[r.param], i);
        }
    }
    for r in &plan.nonlinear_drags.runs {
        let z = p[r.param].max(p[r.param + 1]);
        for &i in &plan.nonlinear_drags.particles[r.start..r.end] {
            acc.own[i as usize] += link_weight(plan, 0.0, z, i);
        }
    }
    for r in &plan.planes.runs {
        let (k, z, mu) = (p[r.param], p[r.param + 1], p[r.param + 2]);
        for &i in &plan.planes.particles[r.start..r.end] {
            let normal = link_weight(plan, k, z, i);
            let tangent = if mu > 0.0 {
                2.0 * mass[i as usize]
            } else {
                0.0
            };
            acc.own[i as usize] += normal.max(tangent);
        }
    }
}

/// The row sums of the links whose weight depends on the shape at the start: angles and
/// conditional links (the pairs active there, found on `grid`).
fn shape_links(plan: &Plan, p: &[f64], grid: &mut Grid, acc: &mut Acc<'_>) {
    for r in &plan.angles.runs {
        for &[i, j, k] in &plan.angles.triples[r.start..r.end] {
            let w = link_weight(plan, p[r.param], 0.0, i);
            acc.angle([i as usize, j as usize, k as usize], &plan.x0, w);
        }
    }
    for c in &plan.conditionals {
        let (k, z) = (p[c.param], p[c.param + 2]);
        let z2 = c.quadratic.map_or(0.0, |s| p[s]);
        c.for_each_active_pair(p, &plan.x0, grid, |i, j, _| {
            let z = if z2 != 0.0 {
                z + 2.0 * z2 * start_rate(plan, i, j)
            } else {
                z
            };
            acc.pair(i, j, link_weight(plan, k, z, i as u32))
        });
    }
}

/// Per muscle link m, `[Σ ½|G w_len|, Σ ½|G w_rate|]` over every (neuron, observed link) pair
/// it is one side of: the stiffness (N/m) and damping (N·s/m) that bound, as quadratic forms,
/// what the neurons add to the linearised scheme (module documentation, "Neurons"). Zero for
/// a muscle whose neuron and observers have every weight 0, so it then counts as its spring
/// bit for bit (`k + 0.0`, `z + 0.0`).
fn neural_slopes(plan: &Plan, p: &[f64], out: &mut Vec<[f64; 2]>) {
    let muscles = &plan.muscles;
    out.clear();
    out.resize(muscles.len(), [0.0; 2]);
    for (ri, r) in muscles.runs.iter().enumerate() {
        let gain = p[r.param + 3].abs();
        let nw = muscles.weights[ri];
        let w0 = r.param + 5;
        let (w_len, w_rate) = (&p[w0..w0 + nw], &p[w0 + nw..w0 + 2 * nw]);
        for m in r.start..r.end {
            let seen = &muscles.observed[muscles.start[m] as usize..muscles.start[m + 1] as usize];
            for ((&k, wl), wr) in seen.iter().zip(w_len).zip(w_rate) {
                // ½ on each side: |D s_m s_k| ≤ ½|D| (s_m² + s_k²).
                let (kn, zn) = (0.5 * mul(gain, wl.abs()), 0.5 * mul(gain, wr.abs()));
                for side in [m, k as usize] {
                    out[side][0] += kn;
                    out[side][1] += zn;
                }
            }
        }
    }
}

/// `|s|` of the link (i, j) at the start, m/s: its rate of elongation from
/// `v = (x(0) - x(-1)) / dt`, each particle in its own world's time (0 for a degenerate link).
fn start_rate(plan: &Plan, i: usize, j: usize) -> f64 {
    let v = |k: usize| (plan.x0[k] - plan.x_minus1[k]) / plan.dt_of(k);
    let (u, _) = crate::forces::unit_and_length(&(plan.x0[j] - plan.x0[i]));
    (v(j) - v(i)).dot(&u).abs()
}

/// The largest time step (s) at which the bound still holds (`max_ratio < 1` just below it),
/// the other values of the scene unchanged; `None` when no free particle has a stiffness or
/// a damping (any step passes). Each `q_i(dt) = a_i dt² + b_i dt` is a quadratic in dt, so
/// two reports (at dt and dt/2) give every particle's `a_i`, `b_i` and its own root. With
/// several worlds each particle's `dt` is its world's, and every world's `dt` scales with the
/// main one (the answer is the main `dt`).
///
/// A plane's friction adds `max(g_n, 2m)` to its particle's row, not a quadratic in dt: a
/// scene with one is solved by bisection on the ratio, which grows monotonically with dt
/// (every term does), to a relative 1e-12 — about 45 reports after the bracket.
pub fn max_stable_dt(scene: &Scene) -> Result<Option<f64>> {
    let has_friction = scene.types.iter().enumerate().any(|(ti, t)| {
        t.kind == crate::LinkKind::Plane
            && t.param("friction").is_some_and(|m| !m.is_known_zero())
            && scene.links.iter().any(|l| l.type_index == ti)
    });
    if has_friction {
        return bisected_stable_dt(scene);
    }
    let full = stability(scene)?;
    let half = stability(&scaled_dt(scene, 0.5))?;
    let mut best: Option<f64> = None;
    for (q1, q2) in full.per_particle.iter().zip(&half.per_particle) {
        let (Some(q1), Some(q2)) = (*q1, *q2) else {
            continue;
        };
        // In units of the scene's dt: q(r) = a r² + b r with r = dt'/dt.
        let a = (2.0 * (q1 - 2.0 * q2)).max(0.0);
        let b = (q1 - a).max(0.0);
        let r = if a > 0.0 {
            // The stable root of a r² + b r - 1 = 0, written without cancellation.
            2.0 / (b + (b * b + 4.0 * a).sqrt())
        } else if b > 0.0 {
            1.0 / b
        } else {
            continue;
        };
        if r.is_finite() {
            let dt = r * scene.dt;
            best = Some(best.map_or(dt, |d| d.min(dt)));
        }
    }
    Ok(best)
}

/// The scene with every world's dt (the main one included) multiplied by `r`.
fn scaled_dt(scene: &Scene, r: f64) -> Scene {
    let mut s = scene.clone();
    s.dt *= r;
    for w in &mut s.worlds {
        w.dt *= r;
    }
    s
}

/// [`max_stable_dt`] by bisection on `r = dt'/dt`: `max_ratio(r)` is non-decreasing in r.
fn bisected_stable_dt(scene: &Scene) -> Result<Option<f64>> {
    let ratio = |r: f64| stability(&scaled_dt(scene, r)).map(|s| s.max_ratio);
    let (mut lo, mut hi) = (0.0, 1.0);
    while ratio(hi)? < 1.0 {
        lo = hi;
        hi *= 2.0;
        if hi > 1e150 || scene.dt * hi > 1e300 {
            return Ok(None);
        }
    }
    while hi - lo > 1e-12 * hi {
        let mid = 0.5 * (lo + hi);
        if ratio(mid)? < 1.0 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Ok(Some(lo * scene.dt))
}

/// `a · b` with `0 · ∞ = 0`: a zero stiffness contributes nothing whatever `dt²` is.
fn mul(a: f64, b: f64) -> f64 {
    if a == 0.0 || b == 0.0 {
        0.0
    } else {
        a * b
    }
}

/// Gershgorin row sums in kg: `own` is the diagonal block's bound, `coupled` the off-diagonal
/// blocks' norms already weighted by `√(m_i/m_j)`.
struct Acc<'a> {
    own: &'a mut [f64],
    coupled: &'a mut [f64],
    free: &'a [bool],
    root: &'a [f64],
}

impl Acc<'_> {
    /// A binary link of weight `w` (kg) between i and j: `[[w, -w], [-w, w]]`.
    fn pair(&mut self, i: usize, j: usize, w: f64) {
        if w == 0.0 {
            return;
        }
        self.own[i] += w;
        self.own[j] += w;
        if self.free[i] && self.free[j] {
            self.coupled[i] += w * (self.root[i] / self.root[j]);
            self.coupled[j] += w * (self.root[j] / self.root[i]);
        }
    }

    /// An angle of weight `w = K dt²` (kg·m²): blocks `w n_p n_q` with `n` the gradient norms
    /// of cosθ at sinθ = 1 (1/m).
    fn angle(&mut self, ids: [usize; 3], x: &[Vec3], w: f64) {
        let [i, j, k] = ids;
        let (la, lb) = ((x[i] - x[j]).norm(), (x[k] - x[j]).norm());
        if w == 0.0 {
            return;
        }
        // An arm in the singular zone (forces/angle.rs) has the faded force, whose gradient
        // norm is at most 1 / (SINGULAR_ARM × the other arm): an angle that starts with two
        // particles at one point is not free of force, it has its stiffest one as soon as they
        // part. Three particles at one point have no length to bound it with: infinite.
        let s = crate::forces::angle::SINGULAR_ARM;
        let (la, lb) = (la.max(s * lb), lb.max(s * la));
        let norms = if la < crate::forces::MIN_LENGTH || lb < crate::forces::MIN_LENGTH {
            [f64::INFINITY; 3]
        } else {
            [1.0 / la, 1.0 / la + 1.0 / lb, 1.0 / lb]
        };
        for (a, &pa) in ids.iter().enumerate() {
            self.own[pa] += mul(w, norms[a] * norms[a]);
            if !self.free[pa] {
                continue;
            }
            for (b, &pb) in ids.iter().enumerate() {
                if b != a && self.free[pb] {
                    let c = mul(w, norms[a] * norms[b]);
                    self.coupled[pa] += mul(c, self.root[pa] / self.root[pb]);
                }
            }
        }
    }
}

/// Empirical counterpart of the bound: the largest factor `s` such that the plan, with every
/// mass divided by `s` (the same as every stiffness and damping times `s`: ratios scale as
/// `s`), keeps small motions around its initial state small for `frames` frames; `None` when
/// it still does at `s = 2^40`. Compare with `1 / max_ratio` (what the bound allows) and
/// `1 / local_max_ratio`.
///
/// Each probe runs the scene twice from rest (no initial velocity, no gravity: neither changes
/// stability, and both move a scene by legitimate, unbounded amounts): once from the initial
/// positions, once from positions and previous positions perturbed by a fixed pseudo-random
/// `ε = 1e-9` of the scene's extent, which excites every mode, the fastest included. It fails
/// when either run diverges or the two runs separate by more than `1e6 ε`. Comparing twins
/// rather than bounding the motion also catches instabilities that saturate (an angle link's
/// force is bounded, so an unstable vertex rattles around without ever leaving), and does not
/// mistake a scene released out of equilibrium for an unstable one. Near the limit an unstable
/// mode grows by `1 + 2√(q - 1)` per step (a drag's by `1 + 2(q - 1)`), so with 5000 frames
/// the limit is resolved to about 1e-5 (1e-3 for drags). Bisection (geometric) stops when the
/// bracket is narrower than the relative `tol`.
pub fn measured_limit(plan: &Plan, p: &[f64], frames: usize, tol: f64) -> Option<f64> {
    assert_eq!(
        p.len(),
        plan.layout.len,
        "parameter vector of the wrong length"
    );
    let tol = if tol > 1e-12 { tol } else { 1e-12 }; // a zero or NaN tolerance would not end
    let probe = Probe::new(plan, p);
    let (mut lo, mut hi);
    if probe.holds(1.0, frames) {
        lo = 1.0;
        hi = 2.0;
        while probe.holds(hi, frames) {
            lo = hi;
            hi *= 2.0;
            if hi > 2f64.powi(40) {
                return None;
            }
        }
    } else {
        hi = 1.0;
        lo = 0.5;
        while !probe.holds(lo, frames) {
            hi = lo;
            lo *= 0.5;
            if lo < 2f64.powi(-60) {
                return Some(0.0);
            }
        }
    }
    while hi / lo > 1.0 + tol {
        let mid = (lo * hi).sqrt();
        if probe.holds(mid, frames) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    Some(lo)
}

/// One scene prepared for [`measured_limit`] probes: the plan at rest and its perturbed twin.
struct Probe {
    plan: Plan,
    twin: Plan,
    p: Vec<f64>,
    /// Largest separation (m) between the twins that still counts as small.
    reach: f64,
}

impl Probe {
    fn new(plan: &Plan, p: &[f64]) -> Probe {
        let mut plan = plan.clone();
        let (mut lo, mut hi) = (Vec3::repeat(f64::INFINITY), Vec3::repeat(f64::NEG_INFINITY));
        for x in &plan.x0 {
            lo = lo.inf(x);
            hi = hi.sup(x);
        }
        let extent = if plan.n > 0 { (hi - lo).norm() } else { 0.0 };
        let extent = if extent > 0.0 && extent.is_finite() {
            extent
        } else {
            1.0
        };
        plan.x_minus1.clone_from(&plan.x0);
        let mut twin = plan.clone();
        let eps = 1e-9 * extent;
        let mut seed = 0x9e37_79b9_7f4a_7c15_u64;
        let mut noise = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            ((seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 2.0 * eps
        };
        for i in (0..plan.n).filter(|&i| plan.free[i]) {
            twin.x0[i] += Vec3::from_fn(|_, _| noise());
            twin.x_minus1[i] += Vec3::from_fn(|_, _| noise());
        }
        let mut p = p.to_vec();
        let g = plan.layout.gravity_offset;
        p[g..g + 3].fill(0.0);
        Probe {
            plan,
            twin,
            p,
            reach: 1e6 * eps,
        }
    }

    fn holds(&self, scale: f64, frames: usize) -> bool {
        let mut p = self.p.clone();
        let m = self.plan.layout.mass_offset;
        for mass in &mut p[m..m + self.plan.n] {
            *mass /= scale;
        }
        let mut a = crate::Simulator::from_plan(self.plan.clone(), p.clone());
        let mut b = crate::Simulator::from_plan(self.twin.clone(), p);
        for _ in 1..frames {
            if a.step().is_err() || b.step().is_err() {
                return false;
            }
            let apart = a
                .positions()
                .iter()
                .zip(b.positions())
                .any(|(xa, xb)| (xa - xb).norm() > self.reach);
            if apart {
                return false;
            }
        }
        true
    }
}

/// The angle links (by index in `scene.links`) that start in the singular zone: an arm shorter
/// than [`crate::forces::angle::SINGULAR_ARM`] times the other at the initial positions (two
/// of the particles at, or nearly at, one point: the angle is barely defined, its force faded
/// and its stiffness the largest it can be). `cordis check` lists them.
pub fn degenerate_angles(scene: &Scene) -> Vec<usize> {
    let s = crate::forces::angle::SINGULAR_ARM;
    let at = |p: usize| Vec3::from(scene.particles[p].pos);
    scene
        .links
        .iter()
        .enumerate()
        .filter(|(_, l)| {
            scene.types[l.type_index].kind == crate::LinkKind::Angle && l.particles.len() == 3
        })
        .filter(|(_, l)| {
            let [i, j, k] = [l.particles[0], l.particles[1], l.particles[2]];
            let (la, lb) = ((at(i) - at(j)).norm(), (at(k) - at(j)).norm());
            la < s * lb || lb < s * la || la.max(lb) < crate::forces::MIN_LENGTH
        })
        .map(|(n, _)| n)
        .collect()
}
