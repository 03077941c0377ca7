//! Discovered graph → identified model in one call (issue 20, `cordis discover --identify`):
//! on generated networks the output-error fit started from the discovered values lands
//! closer to the truth than discovery's own (short-cost, smoothed) values, and its 95 %
//! intervals hold the truth.

mod common;

use common::free_total;
use std::collections::HashMap;

use cordis_core::examples::random_network;
use cordis_core::{LinkKind, Scene, Trajectory};
use cordis_es::discover::identify::{identify_discovered, Identified};
use cordis_es::discover::{discover, DiscoverOptions, Discovery, Undetermined};
use cordis_es::identify::add_noise;

const FRAMES: usize = 300;

fn pair(l: &cordis_core::Link) -> [usize; 2] {
    let (a, b) = (l.particles[0], l.particles[1]);
    [a.min(b), a.max(b)]
}

/// Every spring's (K, l0, Z) by particle pair (dampers left out).
fn params_by_pair(scene: &Scene) -> HashMap<[usize; 2], [f64; 3]> {
    scene
        .links
        .iter()
        .filter(|l| scene.types[l.type_index].kind == LinkKind::Spring)
        .map(|l| {
            let ty = &scene.types[l.type_index];
            let v = |k: usize| ty.params[k].value();
            (pair(l), [v(0), v(1), v(2)])
        })
        .collect()
}

/// Mean relative error (%) of a scene's link parameters (links the truth has too; components
/// whose truth is 0 left out) and moving masses against the truth.
fn error_pct(truth: &Scene, found: &Scene) -> f64 {
    let (tp, fp) = (params_by_pair(truth), params_by_pair(found));
    let mut errs = Vec::new();
    for (p, t) in &tp {
        if let Some(f) = fp.get(p) {
            for c in 0..3 {
                if t[c] != 0.0 {
                    errs.push(((f[c] - t[c]) / t[c]).abs());
                }
            }
        }
    }
    for (p, q) in truth.particles.iter().zip(&found.particles) {
        if !p.fixed {
            let (a, b) = (p.mass.value(), q.mass.value());
            errs.push(((b - a) / a).abs());
        }
    }
    100.0 * errs.iter().sum::<f64>() / errs.len() as f64
}

/// The truth of an identified unknown: a mass, or the true value shared by every link of the
/// discovered type (`None` when the type mixes links of different true values).
fn truth_of(truth: &Scene, found: &Scene, name: &str) -> Option<f64> {
    if let Some(i) = name
        .strip_prefix("particles[")
        .and_then(|s| s.strip_suffix("].mass"))
    {
        return Some(truth.particles[i.parse::<usize>().ok()?].mass.value());
    }
    if let Some(axis) = name.strip_prefix("gravity.") {
        return Some(truth.gravity[["x", "y", "z"].iter().position(|a| *a == axis)?]);
    }
    let rest = name.strip_prefix("types.")?;
    let (ty, param) = rest.split_once('.')?;
    let t = found.types.iter().position(|t| t.name == ty)?;
    let c = ["stiffness", "rest_length", "damping"]
        .iter()
        .position(|p| *p == param)?;
    let tp = params_by_pair(truth);
    let values: Vec<f64> = found
        .links
        .iter()
        .filter(|l| l.type_index == t)
        .filter_map(|l| tp.get(&pair(l)).map(|v| v[c]))
        .collect();
    let first = *values.first()?;
    values
        .iter()
        .all(|v| (v - first).abs() <= 1e-12 * first.abs())
        .then_some(first)
}

/// A generated network, its motion at `rel_noise` of its size (seeded), the discovery under the
/// true total mass with the noise estimated, and the identification.
fn one(
    seed: u64,
    masses: usize,
    types: usize,
    rel_noise: f64,
) -> (Scene, Trajectory, Discovery, Identified) {
    let truth = random_network(seed, masses, types);
    let clean = truth.simulate(FRAMES).unwrap();
    let sigma = rel_noise * clean.scale();
    let traj = if sigma > 0.0 {
        add_noise(&clean, sigma, seed)
    } else {
        clean
    };
    let total = free_total(&truth);
    let opt = DiscoverOptions {
        total_mass: Some(total),
        ..DiscoverOptions::default()
    };
    let d = discover(&traj, truth.dt, &opt).unwrap();
    let id = identify_discovered(&traj, &d, &opt).unwrap();
    (truth, traj, d, id)
}

/// `NOISE=1e-3 SEEDS=1,2,3 cargo test --release -p cordis-es --test discover_identify
/// survey -- --ignored --nocapture`: per seed, the link set, both errors, the coverage and
/// the estimator's status (BENCHMARKS.md).
#[test]
#[ignore]
fn survey_discover_identify() {
    let noise: f64 = std::env::var("NOISE")
        .ok()
        .and_then(|s| s.parse().ok())
        .unwrap_or(1e-4);
    let seeds: Vec<u64> = std::env::var("SEEDS")
        .map(|s| s.split(',').map(|x| x.parse().unwrap()).collect())
        .unwrap_or_else(|_| vec![6, 13, 34]);
    for seed in seeds {
        let masses = 8 + (seed as usize * 7) % 10;
        let types = 3 + (seed as usize) % 3;
        let t0 = std::time::Instant::now();
        let (truth, _traj, d, id) = one(seed, masses, types, noise);
        let (ed, ei) = (error_pct(&truth, &d.scene), error_pct(&truth, &id.scene));
        let (inside, judged) = coverage(&truth, &d, &id);
        let (want, got) = (params_by_pair(&truth), params_by_pair(&d.scene));
        let missing = want.keys().filter(|p| !got.contains_key(*p)).count();
        let extra = d.scene.links.len() - (want.len() - missing);
        println!(
            "seed {seed} ({masses} masses, {types} types) noise {noise}: links missed {missing}, extra {extra}; {} at a box edge; discovered {ed:.4} %, identified {ei:.4} %, {inside}/{judged} truths in their 95 % intervals, {} unknowns, end {}, {:.1} s",
            id.params.iter().filter(|p| p.at_bound).count(),
            id.params.len(),
            id.end,
            t0.elapsed().as_secs_f64()
        );
    }
}

/// (inside, judged): the identified unknowns whose truth is one number (a mass, gravity, a
/// type whose links share their true value) and how many of those truths lie in the 95 %
/// interval.
fn coverage(truth: &Scene, d: &Discovery, id: &Identified) -> (usize, usize) {
    let (mut inside, mut judged) = (0, 0);
    for p in &id.params {
        if let Some(t) = truth_of(truth, &d.scene, &p.name) {
            judged += 1;
            inside += usize::from(p.low <= t && t <= p.high);
        }
    }
    (inside, judged)
}

/// At noise 1e-4 of the size discovery's values are biased by its smoothing (1–18 % mean
/// error on these seeds, gravity ~1 % off); the one-command identification converges (its own
/// criterion), lands at least 20 times closer (measured: 0.008–0.017 %, 140–1,400× closer),
/// holds ≥ 80 % of the judged truths in its 95 % intervals (measured 90–96 %), and its masses
/// sum to the given total.
#[test]
fn identify_after_discovery_beats_the_discovered_values_at_noise_1e_4() {
    for (seed, masses, types) in [(6, 10, 3), (13, 9, 4), (3, 9, 3)] {
        let (truth, _, d, id) = one(seed, masses, types, 1e-4);
        let (ed, ei) = (error_pct(&truth, &d.scene), error_pct(&truth, &id.scene));
        let (inside, judged) = coverage(&truth, &d, &id);
        let tag = format!("seed {seed}: discovered {ed:.4} %, identified {ei:.4} %, {inside}/{judged} in intervals, end {}", id.end);
        assert!(id.converged && id.end == "converged", "{tag}");
        assert!(id.gravity_fitted, "{tag}: gravity held");
        assert!(ei * 20.0 < ed, "{tag}");
        assert!(judged >= 15 && inside * 5 >= judged * 4, "{tag}");
        let total: f64 = free_total(&id.scene);
        assert!(
            (total - free_total(&truth)).abs() <= 1e-9 * total,
            "{tag}: total {total}"
        );
        for p in &id.params {
            // A damping found absent (0, its physical floor) has its interval cut there: no
            // negative damping is a candidate.
            let low_ok = p.low < p.value || (p.value == 0.0 && p.low == 0.0);
            assert!(
                p.stderr.is_finite() && low_ok && p.value < p.high && !p.at_bound,
                "{tag}: {p:?}"
            );
        }
    }
}

/// Noiseless: discovery is exact already, and the fit from there stays exact and converges.
#[test]
fn noiseless_discovery_then_identify_stays_exact() {
    for (seed, masses, types) in [(6, 10, 3), (13, 9, 4)] {
        let (truth, _, d, id) = one(seed, masses, types, 0.0);
        let ei = error_pct(&truth, &id.scene);
        assert!(id.converged, "seed {seed}: end {}", id.end);
        assert!(error_pct(&truth, &d.scene) < 1e-6, "seed {seed}");
        assert!(ei < 1e-6, "seed {seed}: identified {ei} %");
    }
}

/// A given noise level (`--noise-level`) is the estimator's too: the fit is judged against it
/// and reports it, so a level ten times below the data's own makes the same fit end
/// `above_noise` instead of `converged` (before, the estimator read its own level and ignored
/// the given one).
#[test]
fn a_given_noise_level_is_the_one_the_fit_is_judged_against() {
    let truth = random_network(6, 10, 3);
    let clean = truth.simulate(FRAMES).unwrap();
    let sigma = 1e-4 * clean.scale();
    let traj = add_noise(&clean, sigma, 6);
    let opt = |noise: f64| DiscoverOptions {
        total_mass: Some(free_total(&truth)),
        noise_level: Some(noise),
        ..DiscoverOptions::default()
    };
    let d = discover(&traj, truth.dt, &opt(sigma)).unwrap();
    for (given, end) in [(sigma, "converged"), (sigma / 10.0, "above_noise")] {
        let id = identify_discovered(&traj, &d, &opt(given)).unwrap();
        assert_eq!(id.noise_level, given);
        assert_eq!(id.end, end, "given {given:e} m: σ̂ {:e} m", id.sigma);
    }
}

/// Given masses and a given gravity are the scene's as given: not among the unknowns.
#[test]
fn given_masses_and_gravity_stay_known() {
    let truth = random_network(3, 9, 3);
    let traj = truth.simulate(FRAMES).unwrap();
    let masses: Vec<f64> = truth.particles.iter().map(|p| p.mass.value()).collect();
    let opt = DiscoverOptions {
        masses: Some(masses.clone()),
        gravity: Some(truth.gravity),
        ..DiscoverOptions::default()
    };
    let d = discover(&traj, truth.dt, &opt).unwrap();
    let id = identify_discovered(&traj, &d, &opt).unwrap();
    assert!(
        id.converged && !id.gravity_fitted && id.reference.is_none(),
        "end {}",
        id.end
    );
    assert!(
        id.params.iter().all(|p| p.name.starts_with("types.")),
        "{:?}",
        id.params.iter().map(|p| &p.name).collect::<Vec<_>>()
    );
    assert_eq!(id.scene.gravity, truth.gravity);
    for (p, m) in id.scene.particles.iter().zip(&masses) {
        assert_eq!(p.mass.value(), *m);
    }
}

/// A discovery that names something as not determined is not identified: the error names it.
#[test]
fn an_undetermined_discovery_is_refused_by_name() {
    let truth = random_network(3, 9, 3);
    let traj = truth.simulate(FRAMES).unwrap();
    let opt = DiscoverOptions {
        total_mass: Some(free_total(&truth)),
        ..DiscoverOptions::default()
    };
    let mut d = discover(&traj, truth.dt, &opt).unwrap();
    d.undetermined.push(Undetermined {
        what: "masses".into(),
        particles: vec![4, 7],
        links: Vec::new(),
        why: "joined only through fixed particles".into(),
    });
    let e = identify_discovered(&traj, &d, &opt)
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("masses of particles [4, 7]: not determined"),
        "{e}"
    );
    assert!(e.contains("refused"), "{e}");
}
