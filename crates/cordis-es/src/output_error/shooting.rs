//! Multiple shooting: the take cut into segments, each simulated from its own initial state,
//! the segments tied by continuity (issue 16, Bock's method in penalty form).
//!
//! One long rollout from a poor start has local minima: a wrong frequency, or a hidden
//! particle started on the wrong side, puts the whole simulated motion out of phase, and no
//! small step brings it back. Cut into segments of `L` frames, each started from the data at
//! its own first frame, every segment stays near the observed motion whatever θ is, so the
//! cost in θ is nearly quadratic over a much wider region. The segments are then tied:
//!
//! ```text
//! C_ρ = Σ_segments Σ_t w² (x(t) - y(t))²
//!     + ρ w̄² Σ_boundaries |x_k(b) - x0_(k+1)|² + |x_k(b-1) - (x0_(k+1) - v0_(k+1) dt)|²
//! ```
//!
//! where segment k runs over frames `a_k ..= b` (`b = a_(k+1)`, its last frame not observed:
//! the next segment observes it), `x0_(k+1)`, `v0_(k+1)` are the next segment's initial state
//! and `w̄` the rms observation weight. The two defects are exactly the CORDIS step's state
//! `(x(n), x(n-1))`: with both zero the segments are one rollout of the whole take. `ρ` grows
//! over [`PENALTIES`] (each stage a Levenberg–Marquardt fit from the last), and the fit goes on
//! by single shooting from θ and the first segment's state, which removes the defects the
//! penalty leaves (a long rollout amplifies them: right after shooting its rms can be a few
//! times the noise, BENCHMARKS.md; pairwise merging of the segments instead lost the data).
//!
//! Each attempt of a fit runs it once, at the attempt's first stuck window ([`super::run`]):
//! the first from the fit's start θ, each seeded restart from its own seeded θ; the next
//! seeded restart follows when single shooting from its optimum is still above the noise.
//!
//! Hidden particles have no data to start a segment from: each segment's hidden state comes
//! from the rigid motion of the seen particles ([`super::start::initial_state`]), and their
//! continuity is held at the tightest penalty from the first stage on. Tied loosely, their
//! per-segment states absorb the misfit of a wrong θ (traced on two draws with a quarter
//! hidden at σ = 1e-2: data rms below σ at ρ ≤ 1, then 1.4 σ as ρ reached 1e4, and single
//! shooting from there 3–6 σ); tied, a hidden particle is one trajectory driven by its seen
//! neighbours, which every segment re-anchors to the data (those two draws then converged
//! straight after shooting, BENCHMARKS.md).

use super::continuity::Continuity;
use super::fit::{lm_stage, Counts, Fitter, LmSettings, StageEnd};
use super::observations::Take;
use super::tangent::Sens;

/// The continuity weights `ρ` of the penalty stages, relative to an observation of the rms
/// weight: from segments that barely see each other (the data decide θ and each segment's
/// state) to ones tied far below the noise.
pub(crate) const PENALTIES: [f64; 4] = [1e-2, 1.0, 1e2, 1e4];

/// A segmentation of takes.
pub(crate) struct Segments {
    /// The segments, as takes of their own.
    pub takes: Vec<Take>,
    /// For each segment, the take it came from and its first frame there.
    pub origin: Vec<(usize, usize)>,
    /// For each segment, the segment its end continues into (`None`: a take's last).
    pub next: Vec<Option<usize>>,
}

/// The segments of `takes`: each take cut at every `length` frames into segments that share
/// their boundary frame (observed by the later one only), the last segment at least `length`/2
/// frames long.
pub(crate) fn segments(takes: &[Take], length: usize) -> Segments {
    let length = length.max(3);
    let (mut out, mut origin, mut next) = (Vec::new(), Vec::new(), Vec::new());
    for (k, take) in takes.iter().enumerate() {
        let frames = take.frames();
        let mut cuts = vec![0];
        while frames - 1 - cuts[cuts.len() - 1] >= length + length / 2 {
            cuts.push(cuts[cuts.len() - 1] + length);
        }
        cuts.push(frames - 1);
        for s in 0..cuts.len() - 1 {
            let (a, b) = (cuts[s], cuts[s + 1]);
            let last = s + 2 == cuts.len();
            let seg = take.frame_range(a, b + 1);
            // The boundary frame is the next segment's first: observed there only.
            let seg = match last {
                true => seg,
                false => seg.masked(|t, _, _| t + 1 < seg.frames()),
            };
            out.push(seg);
            origin.push((k, a));
            next.push((!last).then_some(out.len()));
        }
    }
    Segments {
        takes: out,
        origin,
        next,
    }
}

/// The rms of the observed weights of `takes` (1 for unweighted data).
pub(crate) fn rms_weight(takes: &[Take]) -> f64 {
    let observed = takes
        .iter()
        .flat_map(|t| (0..t.frames() * t.particles() * 3).map(|k| t.weight_at(k)))
        .filter(|&w| w > 0.0);
    let (sum, count) = observed.fold((0.0, 0usize), |(s, n), w| (s + w * w, n + 1));
    match count {
        0 => 1.0,
        _ => (sum / count as f64).sqrt(),
    }
}

/// Multiple shooting from θ = `genome` over `whole`'s takes (module docs): segments of
/// `length` frames, each started by `initial` from its own data, fitted over the
/// [`PENALTIES`], each stage a Levenberg–Marquardt fit with `set`'s budget. Returns θ and each
/// take's first state for single shooting to finish from.
pub(crate) fn shoot(
    whole: &Fitter<'_>,
    genome: &[f64],
    length: usize,
    initial: &dyn Fn(&Take) -> Vec<f64>,
    (set, counts): (LmSettings, &mut Counts),
    halt: &dyn Fn() -> bool,
) -> Shot {
    let (nt, ns) = (whole.theta(), whole.state_len());
    let weight = rms_weight(whole.takes);
    let dt = whole.tangent.plan.dt;
    let longest = whole.takes.iter().map(Take::frames).max().unwrap_or(0);
    let Segments {
        takes: segs,
        origin,
        next,
    } = segments(whole.takes, length);
    let mut q = genome.to_vec();
    for seg in &segs {
        q.extend(initial(seg));
    }
    whole.project(&mut q);
    let hidden: Vec<bool> = whole
        .tangent
        .free
        .iter()
        .map(|&i| !whole.takes.iter().any(|t| t.tracks(i)))
        .collect();
    let tightest = PENALTIES[PENALTIES.len() - 1];
    for rho in PENALTIES {
        // Hidden particles are tied at the tightest penalty from the first stage on.
        let factor = hidden
            .iter()
            .map(|&h| if h { (tightest / rho).sqrt() } else { 1.0 })
            .collect();
        let tied = Continuity {
            next: next.clone(),
            weight: weight * rho.sqrt(),
            factor,
            dt,
        };
        let stage = Fitter {
            takes: &segs,
            continuity: Some(&tied),
            cols: whole.cols.clone(),
            ..*whole
        };
        let buf = &mut Sens::default();
        match lm_stage(&stage, &mut q, longest, set, counts, buf, halt) {
            StageEnd::Diverged => return Shot::Diverged,
            StageEnd::Interrupted => return Shot::Interrupted,
            _ => {}
        }
    }
    let mut out = q[..nt].to_vec();
    for (s, &(_, first)) in origin.iter().enumerate() {
        if first == 0 {
            out.extend_from_slice(&q[nt + s * ns..][..ns]);
        }
    }
    Shot::Done(out)
}

/// How [`shoot`] ended.
pub(crate) enum Shot {
    /// θ and each take's first state.
    Done(Vec<f64>),
    /// A stage diverged from its start.
    Diverged,
    /// Told to stop: nothing to keep (the caller reruns its stage).
    Interrupted,
}

#[cfg(test)]
mod tests {
    use super::super::continuity::Continuity;
    use super::*;
    use crate::output_error::tangent::Tangent;
    use crate::space::ParameterSpace;
    use approx::assert_relative_eq;
    use cordis_core::{Bounds, LinkKind, LinkType, Param, Particle, Scene, Vec3};

    fn chain_scene() -> Scene {
        let mut scene = Scene::new(0.01);
        scene.add_particle(Particle::new(1.0, [0.0, 0.0, 0.0]).fixed());
        scene.add_particle(Particle::new(0.5, [1.1, 0.0, 0.0]).with_vel([0.0, 0.3, 0.0]));
        scene.add_particle(Particle::new(0.8, [2.0, 0.2, 0.0]));
        scene.add_type(
            LinkType::new("s", LinkKind::Spring)
                .with("stiffness", 20.0)
                .with("rest_length", 1.0)
                .with("damping", 0.05),
        );
        scene.add_link("s", &[0, 1]);
        scene.add_link("s", &[1, 2]);
        scene
    }

    /// The guard of [`shoot`]: from a stiffness 4× the truth (twice the frequency) the one
    /// long rollout's Levenberg–Marquardt stays out of phase, while the segments, each started
    /// from its own data, bring the stiffness to the truth's basin, where single shooting
    /// finishes to the noiseless optimum.
    #[test]
    fn shooting_reaches_the_truth_from_a_start_out_of_phase() {
        out_of_phase(false);
    }

    /// The same on a longer chain with a particle between two seen ones hidden (its segments'
    /// states started on the seen ones' rigid motion, tied at the tightest penalty). The loose
    /// ties pass here too: what the tight ones change is measured on the generated networks
    /// (BENCHMARKS.md).
    #[test]
    fn shooting_reaches_the_truth_with_a_hidden_particle() {
        out_of_phase(true);
    }

    fn out_of_phase(hide_middle: bool) {
        let mut scene = chain_scene();
        if hide_middle {
            scene.add_particle(Particle::new(0.6, [3.0, 0.1, 0.1]).with_vel([0.0, 0.0, 0.2]));
            scene.add_link("s", &[2, 3]);
        }
        let traj = scene.simulate(200).unwrap();
        let take = Take::complete(&traj).masked(|_, i, _| !(hide_middle && i == 2));
        scene.types[0].params[0] = Param::Unknown(Bounds {
            min: 5.0,
            max: 200.0,
            init: None,
        });
        let tangent = Tangent::new(&scene).unwrap();
        let space = ParameterSpace::from_scene(&scene);
        let base = scene.param_values();
        let slots: Vec<usize> = space.unknowns.iter().map(|u| u.slot).collect();
        let takes = vec![take];
        let whole = Fitter {
            cols: tangent.columns(&slots),
            tangent: &tangent,
            unknowns: &space.unknowns,
            base: &base,
            takes: &takes,
            continuity: None,
        };
        let set = LmSettings {
            max_iterations: 100,
            ftol: 1e-10,
            xtol: 1e-10,
            gtol: 1e-10,
            face_steps: true,
        };
        let initial = |t: &Take| super::super::start::initial_state(&scene, &tangent.free, t);
        let genome = vec![space.unknowns[0].to_internal(80.0)];
        let stiffness = |q: &[f64]| space.unknowns[0].from_internal(q[0]);
        // One long rollout from there.
        let mut single = genome.clone();
        single.extend(initial(&takes[0]));
        let buf = &mut Sens::default();
        lm_stage(
            &whole,
            &mut single,
            200,
            set,
            &mut Counts::default(),
            buf,
            &|| false,
        );
        assert!(
            (stiffness(&single) / 20.0 - 1.0).abs() > 0.1,
            "single shooting found the truth (hidden {hide_middle}): {}",
            stiffness(&single)
        );
        // Shooting, then single shooting from its θ and first state.
        let mut counts = Counts::default();
        let Shot::Done(mut q) = shoot(&whole, &genome, 32, &initial, (set, &mut counts), &|| false)
        else {
            panic!("shooting did not end")
        };
        assert!(
            (stiffness(&q) / 20.0 - 1.0).abs() < 1e-2,
            "shooting (hidden {hide_middle}): {}",
            stiffness(&q)
        );
        let end = lm_stage(&whole, &mut q, 200, set, &mut counts, buf, &|| false);
        assert_eq!(end, StageEnd::Converged);
        assert_relative_eq!(stiffness(&q), 20.0, max_relative = 1e-8);
    }

    /// Segments cut every `length` frames share their boundary frame, observed by the later
    /// segment only, and the last one is never shorter than half a segment.
    #[test]
    fn segments_share_their_boundary_frame_observed_once() {
        let traj = chain_scene().simulate(50).unwrap();
        let take = Take::complete(&traj);
        let Segments {
            takes: segs,
            origin,
            next,
        } = segments(std::slice::from_ref(&take), 16);
        assert_eq!(origin, vec![(0, 0), (0, 16), (0, 32)]);
        assert_eq!(next, vec![Some(1), Some(2), None]);
        assert_eq!(
            segs.iter().map(Take::frames).collect::<Vec<_>>(),
            vec![17, 17, 18]
        );
        let observed: usize = segs.iter().map(Take::observed).sum();
        assert_eq!(observed, take.observed());
        assert_eq!(segs[1].at(0, 2, 1), take.at(16, 2, 1));
        assert_eq!(segs[0].at(16, 2, 1).1, 0.0);
    }

    /// Segments started from the true states at their first frames have no defect, and the
    /// continuity rows are the derivative of the defects: the Gauss–Newton gradient `g`
    /// matches central differences of the cost with the continuity terms.
    #[test]
    fn continuity_rows_are_the_derivative_of_the_defects() {
        let mut scene = chain_scene();
        let traj = scene.simulate(40).unwrap();
        let take = Take::complete(&traj);
        let Segments {
            takes: segs, next, ..
        } = segments(std::slice::from_ref(&take), 12);
        scene.types[0].params[0] = Param::Unknown(Bounds {
            min: 5.0,
            max: 80.0,
            init: None,
        });
        let tangent = Tangent::new(&scene).unwrap();
        let space = ParameterSpace::from_scene(&scene);
        let base = scene.param_values();
        let slots: Vec<usize> = space.unknowns.iter().map(|u| u.slot).collect();
        let continuity = Continuity {
            next,
            weight: 3.0,
            factor: vec![1.0, 2.0],
            dt: scene.dt,
        };
        let fit = Fitter {
            cols: tangent.columns(&slots),
            tangent: &tangent,
            unknowns: &space.unknowns,
            base: &base,
            takes: &segs,
            continuity: Some(&continuity),
        };
        // The true states at each segment's first frame: x(a) and (x(a) - x(a-1))/dt.
        let mut q = vec![space.unknowns[0].to_internal(20.0)];
        let cuts = [0usize, 12, 24];
        for &a in &cuts {
            for &i in &tangent.free {
                let x = traj.pos(a, i);
                let v = match a {
                    0 => Vec3::from(scene.particles[i].vel),
                    _ => (x - traj.pos(a - 1, i)) / scene.dt,
                };
                q.extend_from_slice(&[x[0], x[1], x[2], v[0], v[1], v[2]]);
            }
        }
        let longest = 20;
        let exact = fit.cost(&q, longest, &mut Sens::default());
        assert!(exact < 1e-20, "{exact}");
        // Away from the truth, central differences of the cost against 2 g.
        let mut p = q.clone();
        p[0] = space.unknowns[0].to_internal(26.0);
        for (a, v) in p.iter_mut().enumerate().skip(1) {
            *v += 1e-3 * ((a * 7919) % 13) as f64 / 13.0;
        }
        let ne = fit.normal(&p, longest, &mut Sens::default()).unwrap();
        assert_relative_eq!(
            ne.cost,
            fit.cost(&p, longest, &mut Sens::default()),
            max_relative = 1e-12
        );
        for a in [0, 1, 4, 7 + 6, 1 + 12, 1 + 12 + 5, 1 + 24 + 3] {
            let hstep = 1e-6;
            let (mut up, mut down) = (p.clone(), p.clone());
            up[a] += hstep;
            down[a] -= hstep;
            let buf = &mut Sens::default();
            let fd = (fit.cost(&up, longest, buf) - fit.cost(&down, longest, buf)) / (2.0 * hstep);
            assert_relative_eq!(2.0 * ne.g[a], fd, max_relative = 1e-5, epsilon = 1e-9);
        }
    }
}
