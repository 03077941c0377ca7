//! The output-error estimator on data it was not tuned on: generated networks through noise,
//! gaps and hidden particles, measured against the Cramér–Rao bound; the soft block with the
//! defaults.

use cordis_core::examples::random_network;
use cordis_core::io::read_trajectory;
use cordis_core::{LinkKind, LinkType, Param, Scene, Trajectory};
use cordis_es::identify::{add_noise, with_unknown_boxes};
use cordis_es::output_error::{
    cramer_rao, estimate, expected_error_pct, identified_scene, Config, Estimate, Loss, Prepared,
    Progress, Step, Take,
};
use cordis_es::space::ParameterSpace;

/// A network of `masses` particles: springs of `types` types, every one damped (0.02–0.3
/// N·s/m, from the seed), a damper between two particles and air drag on two; boxes 25× wide.
fn network(seed: u64, masses: usize, types: usize) -> (Scene, Scene) {
    let mut truth = random_network(1000 + seed, masses, types);
    for (k, t) in truth.types.iter_mut().enumerate() {
        let u = ((seed * 7 + k as u64 * 13) % 29) as f64 / 29.0;
        t.params[2] = Param::Known(0.02 + 0.28 * u);
    }
    truth.add_type(LinkType::new("dashpot", LinkKind::Damper).with("damping", 0.15));
    truth.add_type(LinkType::new("air", LinkKind::Drag).with("damping", 0.04));
    truth.add_link("dashpot", &[1, masses - 1]);
    truth.add_link("air", &[2]);
    truth.add_link("air", &[masses - 2]);
    let guess = with_unknown_boxes(&truth, 25.0, seed);
    (truth, guess)
}

struct Draw {
    error: f64,
    bound: f64,
    estimate: Estimate,
}

fn draw(seed: u64, rel_noise: f64, keep: impl Fn(usize, usize, usize) -> bool) -> Draw {
    let (truth, guess) = network(seed % 5, 12, 7);
    let traj = truth.simulate(200).unwrap();
    let sigma = rel_noise * traj.scale();
    let noisy = add_noise(&traj, sigma, seed);
    let take = Take::complete(&noisy).masked(keep);
    let space = ParameterSpace::from_scene(&guess);
    let e = estimate(
        &guess,
        &space,
        std::slice::from_ref(&take),
        &Config::default(),
    )
    .unwrap();
    let tv = truth.param_values();
    let values: Vec<f64> = space.unknowns.iter().map(|u| tv[u.slot]).collect();
    let sd = cramer_rao(&truth, &space, &[take], sigma.max(1e-300)).unwrap();
    Draw {
        error: space.error_pct(&e.genome, &tv),
        bound: expected_error_pct(&sd, &values),
        estimate: e,
    }
}

fn hash(t: usize, i: usize, c: usize, seed: u64) -> u64 {
    let mut h = (t as u64)
        ^ ((i as u64) << 20)
        ^ ((c as u64) << 40)
        ^ seed.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    h ^= h >> 33;
    h = h.wrapping_mul(0xff51_afd7_ed55_8ccd);
    h ^= h >> 33;
    h
}

#[test]
fn noiseless_networks_are_identified_to_rounding() {
    for seed in 0..3 {
        let d = draw(seed, 0.0, |_, _, _| true);
        assert!(d.error < 1e-6, "seed {seed}: {} %", d.error);
        assert!(d.estimate.converged, "seed {seed}: {}", d.estimate.end);
    }
}

/// Mean error over draws against the mean bound: within 1.2× at σ = 1e-3 of the size.
fn assert_at_bound(label: &str, draws: &[Draw], factor: f64) {
    let err: f64 = draws.iter().map(|d| d.error).sum::<f64>() / draws.len() as f64;
    let bound: f64 = draws.iter().map(|d| d.bound).sum::<f64>() / draws.len() as f64;
    for d in draws {
        assert!(
            d.estimate.converged,
            "{label}: a fit ended by {}",
            d.estimate.end
        );
    }
    assert!(
        err <= factor * bound,
        "{label}: mean error {err:.4} % against a Cramér–Rao bound of {bound:.4} %"
    );
}

#[test]
fn noisy_networks_reach_the_cramer_rao_bound() {
    let draws: Vec<Draw> = (0..8).map(|s| draw(s, 1e-3, |_, _, _| true)).collect();
    assert_at_bound("σ = 1e-3", &draws, 1.2);
}

#[test]
fn a_fifth_of_the_coordinates_missing_still_reaches_the_bound() {
    let draws: Vec<Draw> = (0..8)
        .map(|s| draw(s, 1e-3, move |t, i, c| hash(t, i, c, s) % 5 != 0))
        .collect();
    assert_at_bound("20 % missing", &draws, 1.2);
}

#[test]
fn noise_level_is_estimated_from_the_residuals() {
    let (truth, guess) = network(1, 12, 7);
    let traj = truth.simulate(200).unwrap();
    let sigma = 1e-3 * traj.scale();
    let take = Take::complete(&add_noise(&traj, sigma, 4));
    let space = ParameterSpace::from_scene(&guess);
    let e = estimate(&guess, &space, &[take], &Config::default()).unwrap();
    assert!(
        (e.sigma / sigma - 1.0).abs() < 0.05,
        "σ̂/σ = {}",
        e.sigma / sigma
    );
    assert!(
        (e.noise_level[0] / sigma - 1.0).abs() < 0.15,
        "{}",
        e.noise_level[0] / sigma
    );
}

/// On clean Gaussian noise a robust loss reads the noise level as least squares does and
/// widens the standard errors by its efficiency loss (1/√0.95, 1.026), within this draw's
/// spread: its last IRLS normal equations alone read σ̂ 0.83–0.90 σ and standard errors 8–11 %
/// below least squares' (a new user's finding).
#[test]
fn a_robust_loss_on_clean_noise_reports_the_noise_and_its_efficiency_loss() {
    let (truth, guess) = network(1, 12, 7);
    let traj = truth.simulate(200).unwrap();
    let sigma = 1e-3 * traj.scale();
    let take = Take::complete(&add_noise(&traj, sigma, 4));
    let space = ParameterSpace::from_scene(&guess);
    let fit = |loss: Loss| {
        let config = Config {
            loss,
            ..Config::default()
        };
        estimate(&guess, &space, std::slice::from_ref(&take), &config).unwrap()
    };
    let squared = fit(Loss::Squared);
    for loss in [Loss::Huber, Loss::Cauchy] {
        let e = fit(loss);
        assert!(e.converged, "{loss}: {}", e.end);
        assert!(
            (e.sigma / sigma - 1.0).abs() < 0.05,
            "{loss}: σ̂/σ = {}",
            e.sigma / sigma
        );
        let ratios: Vec<f64> = e
            .stderr
            .iter()
            .zip(&squared.stderr)
            .map(|(r, s)| r / s)
            .collect();
        let mean = ratios.iter().sum::<f64>() / ratios.len() as f64;
        assert!(
            (0.98..1.10).contains(&mean),
            "{loss}: standard errors × {mean} ({ratios:?})"
        );
    }
}

/// 95 % intervals contain the truth in 90–98 % of the draws, over every parameter kind, on a
/// small network (60 noise draws, one structure, so the bound is the same for each).
#[test]
fn intervals_cover_the_truth_at_their_level() {
    let (truth, guess) = network(2, 6, 3);
    let traj = truth.simulate(150).unwrap();
    let sigma = 1e-3 * traj.scale();
    let space = ParameterSpace::from_scene(&guess);
    let tv = truth.param_values();
    let (mut inside, mut total) = (0usize, 0usize);
    for seed in 0..60 {
        let take = Take::complete(&add_noise(&traj, sigma, 100 + seed));
        let e = estimate(&guess, &space, &[take], &Config::default()).unwrap();
        for (u, (lo, hi)) in space.unknowns.iter().zip(&e.intervals) {
            total += 1;
            if (*lo..=*hi).contains(&tv[u.slot]) {
                inside += 1;
            }
        }
    }
    let rate = inside as f64 / total as f64;
    eprintln!("coverage {rate:.3} over {total} intervals");
    assert!(
        (0.90..=0.98).contains(&rate),
        "coverage {rate:.3} over {total} intervals"
    );
}

fn soft_block() -> (Scene, Scene, Trajectory) {
    let dir =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/data/soft-block");
    let guess = Scene::from_json_path(dir.join("guess.json")).unwrap();
    let truth = Scene::from_json_path(dir.join("truth.json")).unwrap();
    let obs = read_trajectory(&dir.join("markers.csv")).unwrap();
    (guess, truth, obs)
}

fn replay_rms(scene: &Scene, obs: &Trajectory) -> f64 {
    let sim = scene.simulate(obs.frames()).unwrap();
    let sq: f64 = sim
        .as_flat()
        .iter()
        .zip(obs.as_flat())
        .map(|(a, b)| (a - b) * (a - b))
        .sum();
    (sq / obs.as_flat().len() as f64).sqrt()
}

#[test]
fn soft_block_with_the_defaults_is_within_5_pct_and_replays_like_the_truth() {
    let (guess, truth, obs) = soft_block();
    let space = ParameterSpace::from_scene(&guess);
    let e = estimate(&guess, &space, &[Take::complete(&obs)], &Config::default()).unwrap();
    let error = space.error_pct(&e.genome, &truth.param_values());
    assert!(error < 5.0, "mean parameter error {error} %");
    let identified = identified_scene(&guess, &e, 0);
    let (mine, true_model) = (replay_rms(&identified, &obs), replay_rms(&truth, &obs));
    assert!(
        mine <= 1.2 * true_model,
        "replay {mine} m against the truth's {true_model} m"
    );
    // The guess's own initial state (v = 0) is far off: the estimated state is what replays.
    assert!(replay_rms(&space.scene_with(&guess, &e.genome), &obs) > 3.0 * mine);
}

/// The soft block with its centre particle (13, linked to all 26 others) or its bottom face's
/// centre (22) never observed: holding a hidden particle's neighbours left the short-cost start
/// no row, the heuristic start from the 25×-wide boxes diverged from every start and the fit
/// gave no estimate. The start now also solves with the hidden particle's motion imputed from
/// the deformation of the particles seen around it, and keeps whichever start's first window
/// costs less: here the imputed one (the heuristic diverges there).
#[test]
fn a_hidden_particle_linked_to_every_free_one_still_gets_a_short_cost_start() {
    let (guess, truth, obs) = soft_block();
    let space = ParameterSpace::from_scene(&guess);
    for hidden in [13, 22] {
        let markers: Vec<usize> = (0..obs.particles()).filter(|&i| i != hidden).collect();
        let mut data = Vec::new();
        for t in 0..obs.frames() {
            for &i in &markers {
                data.extend(obs.pos(t, i).iter());
            }
        }
        let take = Take::from_markers(
            obs.frames(),
            &data,
            guess.particles.len(),
            Some(&markers),
            None,
            None,
        )
        .unwrap();
        let e = estimate(&guess, &space, &[take], &Config::default()).unwrap();
        assert!(
            e.start.contains("imputed"),
            "particle {hidden}: {}",
            e.start
        );
        assert!(e.start.contains("chosen over “heuristic"), "{}", e.start);
        assert!(e.converged, "particle {hidden}: {}", e.end);
        let error = space.error_pct(&e.genome, &truth.param_values());
        assert!(
            error < 5.0,
            "particle {hidden}: mean parameter error {error} %"
        );
    }
}

/// Several takes: each one's starts compete. Take 0 hides the soft block's centre (its own
/// start can only be imputed or heuristic); take 1 tracks every particle, so its plain
/// short-cost start reads no imputed position. The start once came from take 0 alone.
#[test]
fn every_takes_start_competes_so_a_take_that_tracks_all_gives_the_start() {
    let (guess, truth, obs) = soft_block();
    let space = ParameterSpace::from_scene(&guess);
    let markers: Vec<usize> = (0..obs.particles()).filter(|&i| i != 13).collect();
    let mut data = Vec::new();
    for t in 0..obs.frames() {
        for &i in &markers {
            data.extend(obs.pos(t, i).iter());
        }
    }
    let n = guess.particles.len();
    let hiding = Take::from_markers(obs.frames(), &data, n, Some(&markers), None, None).unwrap();
    let takes = [hiding, Take::complete(&obs)];
    let e = estimate(&guess, &space, &takes, &Config::default()).unwrap();
    assert!(
        e.start
            .starts_with("short-cost least squares on smoothed positions, take 1;"),
        "{}",
        e.start
    );
    assert!(e.converged, "{}", e.end);
    let error = space.error_pct(&e.genome, &truth.param_values());
    assert!(error < 5.0, "mean parameter error {error} %");
}

/// The take of `obs` in scene order with a weight per marker.
fn weighted(
    guess: &Scene,
    obs: &Trajectory,
    weights: &[f64],
) -> Result<Take, cordis_es::CostError> {
    let n = guess.particles.len();
    Take::from_markers(obs.frames(), obs.as_flat(), n, None, Some(weights), None)
}

/// Weights are 1/σ relative: scaling every one by the same factor changes nothing but the
/// unit of σ̂ and of the noise level (the soft block with every weight 2 once failed, "diverged
/// within 32 frames": the windows compared weighted residuals to the unweighted noise level).
#[test]
fn uniformly_scaled_weights_give_the_same_estimate() {
    let (guess, _, obs) = soft_block();
    let space = ParameterSpace::from_scene(&guess);
    let fit = |w: f64| {
        let take = weighted(&guess, &obs, &vec![w; obs.particles()]).unwrap();
        estimate(&guess, &space, &[take], &Config::default()).unwrap()
    };
    let one = fit(1.0);
    // To the ends of the range weights are read in (`arg::WEIGHT_RANGE`).
    for w in [2.0, 10.0, 0.5, 1e6, 1e-6, 1e30, 1e-30] {
        let e = fit(w);
        for (a, b) in e.genome.iter().zip(&one.genome) {
            assert!(
                (a - b).abs() <= 1e-9 * (1.0 + b.abs()),
                "weights {w}: {a} against {b}"
            );
        }
        for (a, b) in e.stderr.iter().zip(&one.stderr) {
            assert!(
                (a / b - 1.0).abs() < 1e-6,
                "weights {w}: standard error {a} against {b}"
            );
        }
        assert!(
            (e.sigma / (w * one.sigma) - 1.0).abs() < 1e-9,
            "σ̂ {}",
            e.sigma
        );
        // Weighted takes read their level per coordinate series (`unit_weight_noise_level`),
        // unweighted ones from one median over all: the same noise to a percent or so.
        let level = e.noise_level[0] / (w * one.noise_level[0]);
        assert!((level - 1.0).abs() < 0.05, "noise level ×{level}");
    }
}

/// Weights of 1e150 were squared to overflow and the fit went elsewhere (its parameters 270 %
/// off those of weight 1): a scale beyond the range is refused by index, with what to do.
#[test]
fn weights_beyond_their_range_are_refused_not_overflowed() {
    let (guess, _, obs) = soft_block();
    for w in [1e150, 1e-150] {
        let mut weights = vec![1.0; obs.particles()];
        weights[3] = w;
        let e = weighted(&guess, &obs, &weights).unwrap_err().to_string();
        assert!(
            e.starts_with(&format!("weights[3]: {w:e} is outside [1e-30, 1e30]")),
            "{e}"
        );
        assert!(e.contains("scale them all by one factor"), "{e}");
    }
}

#[test]
fn a_free_particle_no_observation_reaches_is_refused_by_name() {
    let (truth, guess) = network(0, 6, 2);
    let traj = truth.simulate(30).unwrap();
    let mut isolated = guess.clone();
    isolated.add_particle(cordis_core::Particle::new(1.0, [5.0, 5.0, 5.0]));
    let n = isolated.num_particles();
    let mut data = traj.as_flat().to_vec();
    let mut padded = Vec::new();
    for t in 0..30 {
        padded.extend_from_slice(&data[t * 18..(t + 1) * 18]);
        padded.extend_from_slice(&[f64::NAN; 3]);
    }
    data = padded;
    let take = Take::from_markers(30, &data, n, None, None, None).unwrap();
    let space = ParameterSpace::from_scene(&isolated);
    let e = estimate(&isolated, &space, &[take], &Config::default()).unwrap_err();
    assert!(
        e.to_string()
            .starts_with("take 0, particle 6: has no visible frame"),
        "{e}"
    );
}

/// A take that tracks the fixed particles only (a user whose marker map put the free markers
/// elsewhere), and a free particle hidden behind a fixed one: both refused by name. Before,
/// a tracked fixed particle counted as an observation of every particle linked to it, and
/// the fit ran to "diverges … narrow the boxes".
#[test]
fn a_take_of_fixed_particles_only_or_a_particle_behind_a_fixed_one_is_refused() {
    let mut truth = cordis_core::examples::random_network(0, 6, 2);
    let n0 = truth.num_particles();
    let fixed: Vec<usize> = (0..n0).filter(|&i| truth.particles[i].fixed).collect();
    assert!(!fixed.is_empty());
    // A free particle linked to a fixed one only: whatever its state, nothing else moves.
    let lone = truth.add_particle(cordis_core::Particle::new(1.0, [9.0, 9.0, 9.0]));
    let ty = truth.types[truth.links[0].type_index].name.clone();
    truth.add_link(&ty, &[fixed[0], lone]);
    let n = truth.num_particles();
    let traj = truth.simulate(30).unwrap();
    let guess = cordis_es::identify::with_unknown_boxes(&truth, 25.0, 0);
    let space = ParameterSpace::from_scene(&guess);
    let refusal = |hidden: &dyn Fn(usize) -> bool| {
        let mut data = traj.as_flat().to_vec();
        for t in 0..30 {
            for i in (0..n).filter(|&i| hidden(i)) {
                data[(t * n + i) * 3..(t * n + i) * 3 + 3].fill(f64::NAN);
            }
        }
        let take = Take::from_markers(30, &data, n, None, None, None).unwrap();
        estimate(&guess, &space, &[take], &Config::default())
            .unwrap_err()
            .to_string()
    };
    let e = refusal(&|i| !fixed.contains(&i));
    assert!(
        e.starts_with("take 0: observes none of the scene's free particles"),
        "{e}"
    );
    let e = refusal(&|i| i == lone);
    assert!(
        e.starts_with(&format!("take 0, particle {lone}: has no visible frame")),
        "{e}"
    );
}

#[test]
fn kinds_without_sensitivities_are_refused_by_name() {
    let mut s = cordis_core::examples::rigid();
    s.add_type(
        LinkType::new("swirl", LinkKind::NonlinearDrag)
            .with("z1", 0.1)
            .with("z2", 0.2)
            .with("v_max", 1.0),
    );
    s.add_link("swirl", &[1]);
    let traj = s.simulate(10).unwrap();
    let space = ParameterSpace::from_scene(&s);
    let e = estimate(&s, &space, &[Take::complete(&traj)], &Config::default()).unwrap_err();
    assert!(
        e.to_string()
            .starts_with("types.swirl: kind `nonlinear_drag`"),
        "{e}"
    );
}

#[test]
fn several_takes_share_one_parameter_set_each_with_its_own_start() {
    let (truth, guess) = network(3, 8, 3);
    let space = ParameterSpace::from_scene(&guess);
    let mut second = truth.clone();
    for p in second.particles.iter_mut() {
        p.vel = [-p.vel[1], p.vel[0], 0.3];
    }
    let tv = truth.param_values();
    let values: Vec<f64> = space.unknowns.iter().map(|u| tv[u.slot]).collect();
    let (mut err, mut bound, mut bound_one) = (0.0, 0.0, 0.0);
    for seed in 0..4u64 {
        let mut takes = Vec::new();
        for (k, s) in [&truth, &second].into_iter().enumerate() {
            let traj = s.simulate(120).unwrap();
            let sigma = 1e-3 * traj.scale();
            takes.push(Take::complete(&add_noise(
                &traj,
                sigma,
                10 * seed + k as u64,
            )));
        }
        let sigma = 1e-3 * truth.simulate(120).unwrap().scale();
        let e = estimate(&guess, &space, &takes, &Config::default()).unwrap();
        assert_eq!(e.states.len(), 2);
        assert!(e.converged);
        // Each take's own start is estimated: the second's velocities are not the first's.
        assert!((e.states[0][3] - truth.particles[1].vel[0]).abs() < 0.05);
        assert!((e.states[1][3] - second.particles[1].vel[0]).abs() < 0.05);
        err += space.error_pct(&e.genome, &tv);
        // Both takes in the bound need the second's true start.
        let sd = cramer_rao_two(&truth, &second, &space, &takes, sigma);
        bound += expected_error_pct(&sd, &values);
        let sd1 = cramer_rao(&truth, &space, &takes[..1], sigma).unwrap();
        bound_one += expected_error_pct(&sd1, &values);
    }
    assert!(
        bound < bound_one,
        "two takes bound {bound} against one {bound_one}"
    );
    assert!(
        err <= 1.5 * bound,
        "two takes: mean error {} % against a bound of {} %",
        err / 4.0,
        bound / 4.0
    );
}

/// The bound of two takes that start from the two scenes' initial states.
fn cramer_rao_two(
    first: &Scene,
    second: &Scene,
    space: &ParameterSpace,
    takes: &[Take],
    sigma: f64,
) -> Vec<f64> {
    cordis_es::output_error::cramer_rao_takes(&[first, second], space, takes, sigma).unwrap()
}

#[test]
fn a_fit_stopped_midway_and_resumed_from_its_saved_progress_ends_bit_for_bit_where_an_uninterrupted_fit_ends(
) {
    let (truth, guess) = network(2, 12, 7);
    let traj = truth.simulate(200).unwrap();
    let noisy = add_noise(&traj, 1e-3 * traj.scale(), 2);
    let take = Take::complete(&noisy);
    let space = ParameterSpace::from_scene(&guess);
    let config = Config::default();
    let whole = estimate(&guess, &space, std::slice::from_ref(&take), &config).unwrap();

    // Stopped at the 3rd and the 20th iteration (inside windows), each time saved to JSON and
    // read back as a checkpoint would be, then resumed.
    let prepared = Prepared::new(&guess, &space, vec![take], &config).unwrap();
    let mut progress = prepared.start(&guess, &space, &config).unwrap();
    let asked = std::cell::Cell::new(0usize);
    let halt = || {
        asked.set(asked.get() + 1);
        [3, 20].contains(&asked.get())
    };
    let mut stops = 0;
    loop {
        match prepared.stage(&space, &mut progress, &halt).unwrap() {
            Step::Done => break,
            Step::More => {}
            Step::Stopped => {
                stops += 1;
                let (cost_best, ..) = prepared.measure(&space, progress.best());
                assert!(cost_best.is_finite(), "the best point so far diverges");
                let saved = serde_json::to_string(&progress).unwrap();
                progress = serde_json::from_str::<Progress>(&saved).unwrap();
                prepared.check(&space, &progress).unwrap();
                progress.rerun_stopped_stage();
            }
        }
    }
    assert_eq!(stops, 2, "both stops fell inside a window");
    let resumed = prepared
        .finish(&guess, &space, &progress, &|| false)
        .unwrap();
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&resumed.genome), bits(&whole.genome));
    assert_eq!(bits(&resumed.states[0]), bits(&whole.states[0]));
    assert_eq!(bits(&resumed.stderr), bits(&whole.stderr));
    assert_eq!(resumed.windows, whole.windows);
}

#[test]
fn a_fit_stuck_in_a_wrong_basin_restarts_and_reaches_the_noise_level() {
    // A generated 12-mass network with a quarter of the particles hidden at σ = 1e-3 of the
    // size whose first attempt sticks in a wrong basin: seed 14 until the start learnt to
    // impute hidden particles (from the heuristic start every window past 64 frames stayed far
    // above the noise, 122 % error, σ̂ = 17 σ); from the imputed start seed 14 converges at
    // once and seed 8 is one that sticks (12 of seeds 0–39 restart, all converge).
    let seed = 8;
    let truth = cordis_core::examples::tracked_network(seed, 12, 7);
    let guess = with_unknown_boxes(&truth, 25.0, seed);
    let traj = truth.simulate(200).unwrap();
    let sigma = 1e-3 * traj.scale();
    let take = Take::complete(&add_noise(&traj, sigma, seed)).masked(|_, i, _| i % 4 != 3);
    let space = ParameterSpace::from_scene(&guess);
    let e = estimate(
        &guess,
        &space,
        std::slice::from_ref(&take),
        &Config::default(),
    )
    .unwrap();
    assert!(e.start.contains("restarted"), "{}", e.start);
    assert!(e.converged, "{}", e.end);
    assert!(e.sigma < 1.2 * sigma, "σ̂ {} against σ {sigma}", e.sigma);
    let tv = truth.param_values();
    let values: Vec<f64> = space.unknowns.iter().map(|u| tv[u.slot]).collect();
    let bound = expected_error_pct(
        &cramer_rao(&truth, &space, &[take], sigma).unwrap(),
        &values,
    );
    let error = space.error_pct(&e.genome, &tv);
    assert!(error < 2.0 * bound, "{error} % against the bound {bound} %");
}

#[test]
fn a_robust_loss_shrugs_off_a_marker_swap_that_pulls_least_squares_away() {
    let (guess, truth, obs) = soft_block();
    // The tracker swaps two neighbouring free markers (13 and 14) for frames 60–99: positions
    // 10 cm off for 2 × 40 frames, 1.5 % of the data.
    let n = obs.particles();
    let mut flat = obs.as_flat().to_vec();
    for t in 60..100 {
        for c in 0..3 {
            flat.swap((t * n + 13) * 3 + c, (t * n + 14) * 3 + c);
        }
    }
    let take = Take::from_markers(obs.frames(), &flat, n, None, None, None).unwrap();
    let space = ParameterSpace::from_scene(&guess);
    let tv = truth.param_values();
    let fit = |loss: Loss| {
        let config = Config {
            loss,
            ..Config::default()
        };
        let e = estimate(&guess, &space, std::slice::from_ref(&take), &config).unwrap();
        (space.error_pct(&e.genome, &tv), e)
    };
    // Least squares on the same data: 26.7 % off (measured once, 133 s: the swap puts every
    // window past frame 60 above the noise, so it restarts to the end; too long for a test).
    for loss in [Loss::Cauchy, Loss::Huber] {
        let (robust, e) = fit(loss);
        assert!(robust < 5.0, "{loss}: {robust} %");
        assert!(e.converged, "{loss}: {}", e.end);
        assert!(
            e.downweighted >= 200,
            "{loss}: {} coordinates downweighted",
            e.downweighted
        );
    }
}
