//! Structure discovery on networks of a generator it was not calibrated on (issue 20):
//! `cordis_core::examples::varied_network` — degrees 1–6, pre-stress, planar and 3-D, gravity
//! on and off, fixed particles, dampers, anchors.

mod common;

use common::free_total;
use std::collections::HashSet;

use cordis_core::examples::{varied_network, VariedKinds};
use cordis_core::{LinkKind, Scene, Trajectory};
use cordis_es::discover::{discover, DiscoverOptions, Discovery, Kinds};
use cordis_es::identify::add_noise;

const FRAMES: usize = 300;

/// A link as discovery reports it: its pair and its kind (`spring`, `anchor`, `damper`). A
/// damper to a fixed particle pulls `−Z v` whichever fixed particle it ends on (the data
/// cannot tell them apart): its fixed end is [`ANY_FIXED`].
type Found = ([usize; 2], &'static str);

const ANY_FIXED: usize = usize::MAX;

fn found(scene: &Scene, [a, b]: [usize; 2], kind: &'static str) -> Found {
    let fixed = |i: usize| scene.particles[i].fixed;
    let (a, b) = match kind {
        "damper" if fixed(a) => (b, ANY_FIXED),
        "damper" if fixed(b) => (a, ANY_FIXED),
        _ => (a, b),
    };
    ([a.min(b), a.max(b)], kind)
}

/// The links discovery can see, with their kinds: links between two particles, not both fixed
/// (a spring with a fixed end is an anchor), and anchors to a point a fixed particle marks.
fn true_links(scene: &Scene) -> HashSet<Found> {
    let fixed = |i: usize| scene.particles[i].fixed;
    let mut out = HashSet::new();
    for l in &scene.links {
        let kind = scene.types[l.type_index].kind;
        let ends = match (l.particles.as_slice(), l.point) {
            (&[a, b], _) if !(fixed(a) && fixed(b)) => [a, b],
            (&[a], Some(point)) => {
                let marker = (0..scene.num_particles())
                    .find(|&m| fixed(m) && scene.particles[m].pos == point)
                    .expect("an anchor's point is marked by a fixed particle");
                [a, marker]
            }
            _ => continue,
        };
        let name = match kind {
            LinkKind::Damper => "damper",
            _ if fixed(ends[0]) || fixed(ends[1]) => "anchor",
            _ => "spring",
        };
        out.insert(found(scene, ends, name));
    }
    out
}

fn found_links(d: &Discovery) -> HashSet<Found> {
    d.links
        .iter()
        .map(|l| found(&d.scene, l.particles, l.kind))
        .collect()
}

struct Outcome {
    missing: Vec<Found>,
    extra: Vec<Found>,
    links: usize,
    worst_mass: f64,
    /// The discovery, or the error it refused with.
    d: Result<Discovery, String>,
}

fn survey_one(truth: &Scene, traj: &Trajectory, noise: f64, given: bool) -> Outcome {
    let opt = DiscoverOptions {
        total_mass: Some(free_total(truth)),
        noise_level: if given { Some(noise) } else { None },
        // LOOK_FOR=spring,anchor: the kinds discovery looks for (default all).
        kinds: std::env::var("LOOK_FOR")
            .ok()
            .map(|k| Kinds::parse(&k.split(',').collect::<Vec<_>>()).expect("LOOK_FOR")),
        ..DiscoverOptions::default()
    };
    let want = true_links(truth);
    let d = match discover(traj, truth.dt, &opt) {
        Ok(d) => d,
        // A refusal (no link explains the motion) says so: every link is missed, none silently.
        Err(e) => {
            let mut missing: Vec<_> = want.iter().copied().collect();
            missing.sort();
            return Outcome {
                missing,
                extra: Vec::new(),
                links: want.len(),
                worst_mass: f64::INFINITY,
                d: Err(e.to_string()),
            };
        }
    };
    // LINK_TEST=1: the graph of the output-error link test instead (when the discovery
    // determined everything; otherwise the test refuses and the discovery stands).
    let d = match std::env::var("LINK_TEST").is_ok() && d.undetermined.is_empty() {
        true => match cordis_es::discover::link_test::link_test(traj, &d, &opt) {
            Ok(t) => {
                println!(
                    "  link test: {} from {}, σ̂ {:.3e} m (noise {:.3e}), kept {} of {}",
                    t.report.end,
                    t.report.start,
                    t.report.sigma,
                    t.report.noise_level,
                    t.report.kept,
                    t.report.pairs.len()
                );
                t.discovery
            }
            Err(e) => {
                println!("  link test failed ({e}): the selection's graph kept");
                d
            }
        },
        false => d,
    };
    let got = found_links(&d);
    let mut missing: Vec<_> = want.difference(&got).copied().collect();
    let mut extra: Vec<_> = got.difference(&want).copied().collect();
    missing.sort();
    extra.sort();
    let worst_mass = truth
        .particles
        .iter()
        .zip(&d.scene.particles)
        .filter(|(p, _)| !p.fixed)
        .map(|(p, q)| (p.mass.value() - q.mass.value()).abs() / p.mass.value())
        .fold(0.0, f64::max);
    Outcome {
        missing,
        extra,
        links: want.len(),
        worst_mass,
        d: Ok(d),
    }
}

/// Per-network verdicts of a survey.
#[derive(Default, Debug)]
struct Rates {
    networks: usize,
    exact_links: usize,
    exact_masses: usize,
    /// Networks whose every mass off by more than 0.1 % is named in `undetermined`.
    wrong_masses_named: usize,
    silently_wrong: Vec<u64>,
    /// Networks discovery refused (no link found), by seed.
    refused: Vec<u64>,
    links: usize,
    found: usize,
    extra: usize,
}

/// `given`: the noise level is told to discovery; otherwise it estimates it.
fn survey(
    seeds: std::ops::Range<u64>,
    kinds: VariedKinds,
    noise: f64,
    given: bool,
    print: bool,
) -> Rates {
    let mut r = Rates::default();
    for seed in seeds {
        let (truth, case) = varied_network(seed, kinds);
        let traj = truth.simulate(FRAMES).unwrap();
        let sigma = noise * traj.scale();
        let obs = if noise > 0.0 {
            add_noise(&traj, sigma, seed)
        } else {
            traj.clone()
        };
        let o = survey_one(&truth, &obs, sigma, given);
        r.networks += 1;
        let d = match &o.d {
            Ok(d) => d,
            Err(e) => {
                if print {
                    println!("seed {seed} {case:?} refused: {e}");
                }
                r.refused.push(seed);
                r.links += o.links;
                continue;
            }
        };
        let flagged: HashSet<usize> = d
            .undetermined
            .iter()
            .filter(|u| u.what == "masses")
            .flat_map(|u| u.particles.iter().copied())
            .collect();
        let wrong: Vec<usize> = (0..truth.num_particles())
            .filter(|&i| !truth.particles[i].fixed)
            .filter(|&i| {
                let (a, b) = (
                    truth.particles[i].mass.value(),
                    d.scene.particles[i].mass.value(),
                );
                (a - b).abs() > 1e-3 * a
            })
            .collect();
        let exact = o.missing.is_empty() && o.extra.is_empty();
        r.exact_links += exact as usize;
        r.exact_masses += (exact && wrong.is_empty()) as usize;
        let named = wrong.iter().all(|i| flagged.contains(i));
        r.wrong_masses_named += (!wrong.is_empty() && named) as usize;
        if !exact || !named {
            r.silently_wrong.push(seed);
        }
        r.links += o.links;
        r.found += o.links - o.missing.len();
        r.extra += o.extra.len();
        if print {
            println!(
                "seed {seed} n {} {case:?} links {} missing {:?} extra {:?} worst mass {:.2e} \
                 wrong masses {wrong:?} named {:?}",
                truth.num_particles(),
                o.links,
                o.missing,
                o.extra,
                o.worst_mass,
                d.undetermined.iter().map(|u| u.line()).collect::<Vec<_>>()
            );
        }
    }
    r
}

/// Issue 20's acceptance on a CI-sized survey: 40 noiseless spring networks of the varied
/// generator (degrees 1–6, pre-stress, planar and 3-D, gravity on and off, fixed particles).
/// Every network gets the exact link set; every mass off by more than 0.1 % is named as not
/// determined; at least 90 % of the networks get every mass within 0.1 %.
#[test]
fn noiseless_varied_networks_are_exact_or_named_as_not_determined() {
    let r = survey(0..40, VariedKinds::SPRINGS, 0.0, false, false);
    assert!(r.silently_wrong.is_empty(), "silently wrong: {r:?}");
    assert_eq!(r.exact_links, r.networks, "{r:?}");
    assert!(r.exact_masses * 10 >= r.networks * 9, "{r:?}");
}

/// Issue 20's noiseless line with dampers and anchors, on draws the damper search was not
/// developed on (seeds 300–324; development used 0–99): every network gets the exact link set
/// with each link's kind (spring, anchor: a spring to a fixed particle, damper; a damper's
/// fixed end counts as "a fixed particle", which the data cannot tell apart), and every mass
/// off by more than 0.1 % is named.
#[test]
fn noiseless_varied_networks_with_dampers_and_anchors_get_every_link_and_its_kind() {
    let r = survey(300..325, VariedKinds::ALL, 0.0, false, false);
    assert!(r.silently_wrong.is_empty(), "silently wrong: {r:?}");
    assert_eq!(r.exact_links, r.networks, "{r:?}");
    assert!(r.exact_masses * 10 >= r.networks * 9, "{r:?}");
}

#[test]
fn an_unknown_link_kind_is_refused_in_one_line_naming_it() {
    let e = Kinds::parse(&["spring", "dumper"]).unwrap_err().to_string();
    assert!(e.contains("kinds") && e.contains("`dumper`"), "{e}");
    assert!(!e.contains('\n'), "{e}");
    assert!(Kinds::parse::<&str>(&[]).is_err());
    assert_eq!(
        Kinds::parse(&["damper", " spring"]).unwrap(),
        Kinds {
            spring: true,
            damper: true,
            anchor: false
        }
    );
}

/// Issue 20's noise line on a CI-sized survey of draws the method was not developed on (seeds
/// 200–229; development used 0–39 and 100–139): springs, anchors and dampers, positions with
/// Gaussian noise of 1e-4 of the motion's size, the noise level not given. Discovery
/// estimates it (within 10 %, and says so in a warning) and keeps ≥ 95 % of the links with
/// their kinds, with ≤ 5 % extra.
#[test]
fn noisy_varied_networks_keep_their_links_with_the_noise_estimated() {
    let mut r = Rates::default();
    let mut worst_noise: f64 = 0.0;
    for seed in 200..230 {
        let (truth, _) = varied_network(seed, VariedKinds::ALL);
        let traj = truth.simulate(FRAMES).unwrap();
        let sigma = 1e-4 * traj.scale();
        let o = survey_one(&truth, &add_noise(&traj, sigma, seed), sigma, false);
        let d = o.d.as_ref().expect("a network is found");
        assert!(d.estimated_noise && d.data_warnings.iter().any(|w| w.contains("noisy")));
        worst_noise = worst_noise.max((d.noise_level / sigma - 1.0).abs());
        r.networks += 1;
        r.links += o.links;
        r.found += o.links - o.missing.len();
        r.extra += o.extra.len();
    }
    assert!(worst_noise < 0.1, "noise estimated {worst_noise:.3} off");
    assert!(r.found * 100 >= r.links * 95, "{r:?}");
    assert!(r.extra * 100 <= r.links * 5, "{r:?}");
}

/// The full survey (BENCHMARKS.md): `COUNT=200 NOISE=1e-4 cargo test --release -p cordis-es
/// --test discover_varied varied_survey -- --ignored --nocapture` (KINDS=springs for springs
/// only; PRINT=1 for every network).
#[test]
#[ignore]
fn varied_survey() {
    let env = |k: &str, d: f64| {
        std::env::var(k)
            .ok()
            .and_then(|s| s.parse().ok())
            .unwrap_or(d)
    };
    let noise = env("NOISE", 0.0);
    let first = env("FIRST", 0.0) as u64;
    let count = env("COUNT", 100.0) as u64;
    let kinds = match std::env::var("KINDS").as_deref() {
        Ok("springs") => VariedKinds::SPRINGS,
        _ => VariedKinds::ALL,
    };
    let t0 = std::time::Instant::now();
    let given = env("GIVEN", 0.0) > 0.0;
    let r = survey(
        first..first + count,
        kinds,
        noise,
        given,
        env("PRINT", 0.0) > 0.0,
    );
    println!(
        "{kinds:?} noise {noise:e} ({}): {} networks, exact links {} ({:.1} %), exact links and \
         masses {} ({:.1} %), wrong masses all named {}, silently wrong {} {:?}, refused {:?}; links found \
         {:.2} %, extra {:.2} % of {}; {:.1} s",
        if given { "given" } else { "estimated" },
        r.networks,
        r.exact_links,
        100.0 * r.exact_links as f64 / r.networks as f64,
        r.exact_masses,
        100.0 * r.exact_masses as f64 / r.networks as f64,
        r.wrong_masses_named,
        r.silently_wrong.len(),
        r.silently_wrong,
        r.refused,
        100.0 * r.found as f64 / r.links as f64,
        100.0 * r.extra as f64 / r.links as f64,
        r.links,
        t0.elapsed().as_secs_f64()
    );
}

#[test]
#[ignore]
fn varied_debug() {
    let seed: u64 = std::env::var("SEED").unwrap().parse().unwrap();
    let (truth, case) = varied_network(seed, VariedKinds::SPRINGS);
    let traj = truth.simulate(FRAMES).unwrap();
    let noise: f64 = std::env::var("NOISE").map_or(0.0, |s| s.parse().unwrap());
    let sigma = noise * traj.scale();
    let obs = if noise > 0.0 {
        add_noise(&traj, sigma, seed)
    } else {
        traj.clone()
    };
    println!("sigma {sigma:e} scale {}", traj.scale());
    let o = survey_one(&truth, &obs, sigma, std::env::var("GIVEN").is_ok());
    let d = o.d.as_ref().expect("discovery");
    println!("{case:?} missing {:?} extra {:?}", o.missing, o.extra);
    for (i, p) in truth.particles.iter().enumerate() {
        let deg: Vec<usize> = truth
            .links
            .iter()
            .filter(|l| l.particles.contains(&i))
            .map(|l| l.particles[0] + l.particles[1] - i)
            .collect();
        println!(
            "p{i} fixed {} m {:.3} -> {:.3} links {deg:?}",
            p.fixed,
            p.mass.value(),
            d.scene.particles[i].mass.value()
        );
    }
    for l in &d.links {
        println!(
            "{:?} {} {} K {:.4} l0 {:.4} Z {:.4} score {:.3e} thr {:.1}",
            l.particles,
            l.kind,
            l.type_name,
            l.stiffness,
            l.rest_length,
            l.damping,
            l.score,
            l.threshold
        );
    }
    for t in &truth.types {
        println!(
            "truth type {} {:?}",
            t.name,
            t.params.iter().map(|p| p.value()).collect::<Vec<_>>()
        );
    }
    println!("notes {:?} solver {:?}", d.notes, d.solver);
}
