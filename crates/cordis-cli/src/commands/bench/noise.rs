//! `cordis bench noise`: the output-error estimator against the Cramér–Rao bound on generated
//! networks, through noise, gaps and hidden particles, beside the short cost's exact estimate.
//!
//! Each draw is a network of its own (`tracked_network_with_angles`: 12–30 masses drawn from
//! the seed, gravity, every spring type damped, two angle types, a damper, air drag on two
//! particles and an anchor to a point; boxes 25× wide around the truth at a place drawn from
//! the seed), simulated for `--frames` frames, observed through Gaussian noise
//! of σ = `rel` × the trajectory's size, with every coordinate, 20 % of them missing at random,
//! or a quarter of the free particles hidden. Per cell (noise × pattern) over `--draws` draws:
//! the mean parameter error of `output-error` (the defaults), the Cramér–Rao bound of the same
//! observation pattern (`100 · mean_k √(2/π) sd_k/|θ_k|`, `sd` from the estimator's own
//! sensitivities at the truth, initial state unknown), their ratio (of the means), the
//! fraction of 95 % intervals holding the truth per parameter kind (stiffness, rest length,
//! rest cosine, damping), the median CPU seconds of one fit (and wall seconds in the JSON), how
//! many fits met their criterion, and the short cost's least-squares error on the same data
//! (gap-filled; none with hidden particles).

use std::time::Instant;

use anyhow::Result;
use cordis_core::examples::tracked_network_with_angles;
use cordis_core::{Bounds, LinkKind, Param, Scene, Vec3};
use cordis_es::cost::CostKind;
use cordis_es::identify::{add_noise, with_unknown_boxes};
use cordis_es::output_error::{cramer_rao, estimate, expected_error_pct, Config, Intervals, Take};
use cordis_es::problem::Problem;
use cordis_es::run::cpu_time::process_cpu_seconds;
use cordis_es::space::{ParameterSpace, Role};
use cordis_es::strategies::least_squares;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Draws (networks × noise draws) per cell.
    #[arg(long, default_value_t = 20, value_parser = clap::value_parser!(u64).range(1..=10_000))]
    draws: u64,
    /// Frames per take.
    #[arg(long, default_value_t = 200, value_parser = clap::value_parser!(u64).range(20..=100_000))]
    frames: u64,
    /// Particles per network (the first is fixed): `N`, or `LO-HI` for a count drawn per draw.
    #[arg(long, default_value = "12-30", value_parser = parse_masses)]
    masses: (usize, usize),
    /// Spring types per network.
    #[arg(long, default_value_t = 7, value_parser = clap::value_parser!(u64).range(1..=50))]
    types: u64,
    /// Noise levels σ/size, comma-separated.
    #[arg(long, default_value = "0,1e-4,1e-3,1e-2")]
    noise: String,
    /// Observation patterns, comma-separated: complete | missing | hidden.
    #[arg(long, default_value = "complete,missing,hidden")]
    patterns: String,
    /// The first draw's seed: draws `first_draw .. first_draw + draws` (to split a grid across
    /// processes; the JSON lines carry the counts to merge).
    #[arg(long, default_value_t = 0, value_parser = clap::value_parser!(u64).range(0..=1_000_000))]
    first_draw: u64,
    /// The estimator's first window, frames (its default otherwise).
    #[arg(long, value_parser = clap::value_parser!(u64).range(3..=100_000))]
    first_window: Option<u64>,
    /// The estimator's 95 % intervals: wald | profile (as `identify --intervals`).
    #[arg(long, default_value = "wald", value_parser = parse_intervals)]
    intervals: Intervals,
    /// One line per draw on stderr.
    #[arg(long)]
    verbose: bool,
    /// Start every fit at the truth (its parameters and initial state) instead of from the data:
    /// a diagnosis that separates the maximum-likelihood optimum's own error and interval
    /// coverage from the search's (a fit that leaves the truth's basin shows up as not
    /// converged). Not an estimator: the truth is not known in practice.
    #[arg(long)]
    from_truth: bool,
}

fn parse_intervals(s: &str) -> std::result::Result<Intervals, String> {
    s.parse()
        .map_err(|e: cordis_es::error::CostError| e.to_string())
}

/// `N` or `LO-HI`, 4 ≤ LO ≤ HI ≤ 200.
fn parse_masses(s: &str) -> std::result::Result<(usize, usize), String> {
    let (lo, hi) = s.split_once('-').unwrap_or((s, s));
    let num = |v: &str| {
        v.trim()
            .parse::<usize>()
            .ok()
            .filter(|n| (4..=200).contains(n))
            .ok_or_else(|| format!("`{v}` is not a particle count in 4..=200"))
    };
    let (lo, hi) = (num(lo)?, num(hi)?);
    if lo > hi {
        return Err(format!("`{s}`: the low end is above the high end"));
    }
    Ok((lo, hi))
}

/// The particle count of draw `seed`: uniform in the range, from the seed.
fn masses_of(range: (usize, usize), seed: u64) -> usize {
    let span = (range.1 - range.0 + 1) as u64;
    range.0 + (mix(0, 0, 0, seed ^ 0x4d41_5353) % span) as usize
}

/// One generated network and the guess a user would write for it.
fn network(seed: u64, masses: usize, types: usize) -> (Scene, Scene) {
    let truth = tracked_network_with_angles(seed, masses, types);
    let mut guess = with_unknown_boxes(&truth, 25.0, seed);
    // `with_unknown_boxes` keeps a rest cosine known (it may have either sign): an additive
    // box a cosine wide, clipped to [-1, 1], with the truth off its centre.
    for (k, t) in guess.types.iter_mut().enumerate() {
        if t.kind == LinkKind::Angle {
            let c = truth.types[k].params[1].value();
            let u = 0.1 + 0.8 * (mix(k, 1, 2, seed) % 1000) as f64 / 1000.0;
            t.params[1] = Param::Unknown(Bounds {
                min: (c - u).max(-1.0),
                max: (c + 1.0 - u).min(1.0),
                init: None,
            });
        }
    }
    (truth, guess)
}

fn mix(t: usize, i: usize, c: usize, seed: u64) -> u64 {
    let mut h = (t as u64)
        ^ ((i as u64) << 20)
        ^ ((c as u64) << 40)
        ^ seed.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    h ^= h >> 33;
    h = h.wrapping_mul(0xff51_afd7_ed55_8ccd);
    h ^ (h >> 33)
}

#[derive(Default)]
struct Cell {
    error: Vec<f64>,
    bound: Vec<f64>,
    short: Vec<f64>,
    seconds: Vec<f64>,
    /// CPU seconds of each fit (the wall clock also counts a shared machine's other work).
    cpu: Vec<f64>,
    converged: usize,
    failed: usize,
    /// Per kind (stiffness, rest length, rest cosine, damping): (inside, total).
    coverage: [(usize, usize); 4],
    /// The same with the Wald intervals (before the line-profile widening).
    wald_coverage: [(usize, usize); 4],
    /// Intervals the line profile widened.
    widened: usize,
}

fn kind_index(r: Role) -> usize {
    match r {
        Role::Stiffness => 0,
        Role::RestLength => 1,
        Role::RestCos => 2,
        _ => 3,
    }
}

fn one_draw(a: &Args, seed: u64, rel: f64, pattern: &str, cell: &mut Cell) {
    let (masses, types) = (masses_of(a.masses, seed), a.types as usize);
    let (truth, guess) = network(seed, masses, types);
    let Ok(traj) = truth.simulate(a.frames as usize) else {
        cell.failed += 1;
        return;
    };
    let sigma = rel * traj.scale();
    let noisy = if sigma > 0.0 {
        add_noise(&traj, sigma, seed)
    } else {
        traj.clone()
    };
    let n = truth.num_particles();
    let hidden: Vec<bool> = (0..n).map(|i| pattern == "hidden" && i % 4 == 3).collect();
    let take = Take::complete(&noisy).masked(|t, i, c| {
        let dropped = pattern == "missing" && mix(t, i, c, seed) % 5 == 0;
        !(hidden[i] || dropped)
    });
    let space = ParameterSpace::from_scene(&guess);
    let tv = truth.param_values();
    let defaults = Config::default();
    let config = Config {
        first_window: a.first_window.map_or(defaults.first_window, |w| w as usize),
        intervals: a.intervals,
        start: a.from_truth.then(|| space.genome_of(&tv)),
        start_states: a
            .from_truth
            .then(|| vec![cordis_es::output_error::start::scene_state(&truth)]),
        ..defaults
    };
    let t0 = Instant::now();
    let c0 = process_cpu_seconds();
    let fit = estimate(&guess, &space, std::slice::from_ref(&take), &config);
    let secs = t0.elapsed().as_secs_f64();
    let cpu = process_cpu_seconds() - c0;
    let Ok(e) = fit else {
        cell.failed += 1;
        return;
    };
    cell.seconds.push(secs);
    cell.cpu.push(cpu);
    cell.converged += usize::from(e.converged);
    cell.error.push(space.error_pct(&e.genome, &tv));
    if a.verbose {
        eprintln!(
            "  draw {seed} ({masses} masses, {secs:.2} s, {cpu:.2} CPU s): error {:.3e} %, {} after {} \
             iterations, σ̂ {:.3e} m (σ {sigma:.3e}), intervals widened: [{}], windows {:?}, start: {}",
            space.error_pct(&e.genome, &tv),
            e.end,
            e.iterations,
            e.sigma,
            e.widened
                .iter()
                .map(|w| format!(
                    "{} {:.2}/{:.2}",
                    space.unknowns[w.unknown].name, w.rise[0], w.rise[1]
                ))
                .collect::<Vec<_>>()
                .join(", "),
            e.windows,
            e.start
        );
    }
    if sigma > 0.0 {
        let values: Vec<f64> = space.unknowns.iter().map(|u| tv[u.slot]).collect();
        if let Ok(sd) = cramer_rao(&truth, &space, std::slice::from_ref(&take), sigma) {
            cell.bound.push(expected_error_pct(&sd, &values));
        }
        for (a, (u, &interval)) in space.unknowns.iter().zip(&e.intervals).enumerate() {
            let k = kind_index(u.role);
            let wald = e
                .widened
                .iter()
                .find(|w| w.unknown == a)
                .map_or(interval, |w| w.wald);
            let holds = |(lo, hi): (f64, f64)| usize::from((lo..=hi).contains(&tv[u.slot]));
            cell.coverage[k].1 += 1;
            cell.coverage[k].0 += holds(interval);
            cell.wald_coverage[k].1 += 1;
            cell.wald_coverage[k].0 += holds(wald);
        }
        cell.widened += e.widened.len();
    }
    if pattern != "hidden" {
        let fallback: Vec<Vec3> = guess.particles.iter().map(|p| Vec3::from(p.pos)).collect();
        let filled = take.filled(&fallback).with_dt(guess.dt);
        if let Ok(p) = Problem::new(&guess, &filled, CostKind::Short) {
            if let Ok(sol) = least_squares::solve(&p) {
                cell.short.push(space.error_pct(&sol.genome, &tv));
            }
        }
    }
}

fn mean(v: &[f64]) -> Option<f64> {
    (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
}

fn median(v: &[f64]) -> Option<f64> {
    let mut s = v.to_vec();
    s.sort_by(f64::total_cmp);
    (!s.is_empty()).then(|| s[s.len() / 2])
}

pub fn run(a: Args) -> Result<()> {
    let levels: Vec<f64> = a
        .noise
        .split(',')
        .map(|s| {
            s.trim()
                .parse::<f64>()
                .ok()
                .filter(|v| v.is_finite() && (0.0..=0.5).contains(v))
                .ok_or_else(|| anyhow::anyhow!("--noise: `{s}` is not a level in [0, 0.5]"))
        })
        .collect::<Result<_>>()?;
    let patterns: Vec<&str> = a.patterns.split(',').map(str::trim).collect();
    if let Some(p) = patterns
        .iter()
        .find(|p| !["complete", "missing", "hidden"].contains(p))
    {
        anyhow::bail!("--patterns: `{p}` is not one of complete, missing, hidden");
    }
    eprintln!(
        "{:>8} {:>9} {:>11} {:>11} {:>7} {:>11} {:>22} {:>9} {:>6}",
        "σ/size",
        "pattern",
        "error %",
        "CRB %",
        "ratio",
        "short %",
        "coverage K/l0/c0/Z",
        "med CPU s",
        "conv"
    );
    for &rel in &levels {
        for &pattern in &patterns {
            let mut cell = Cell::default();
            for d in a.first_draw..a.first_draw + a.draws {
                one_draw(&a, d, rel, pattern, &mut cell);
            }
            report(&a, rel, pattern, &cell);
        }
    }
    Ok(())
}

fn report(a: &Args, rel: f64, pattern: &str, cell: &Cell) {
    let err = mean(&cell.error);
    let bound = mean(&cell.bound);
    let ratio = err.zip(bound).map(|(e, b)| e / b);
    let cov: Vec<Option<f64>> = cell
        .coverage
        .iter()
        .map(|&(i, t)| (t > 0).then(|| i as f64 / t as f64))
        .collect();
    let line = serde_json::json!({
        "bench": "noise",
        "noise_rel": rel,
        "pattern": pattern,
        "draws": a.draws,
        "masses": format!("{}-{}", a.masses.0, a.masses.1),
        "types": a.types,
        "frames": a.frames,
        "error_pct": err,
        "crb_pct": bound,
        "ratio": ratio,
        "short_cost_error_pct": mean(&cell.short),
        "coverage95": {
            "stiffness": cov[0], "rest_length": cov[1], "rest_cos": cov[2], "damping": cov[3]
        },
        "intervals": a.intervals.as_str(),
        "coverage_counts": cell.coverage,
        "wald_coverage_counts": cell.wald_coverage,
        "widened_intervals": cell.widened,
        "first_draw": a.first_draw,
        "errors_pct": cell.error,
        "crbs_pct": cell.bound,
        "median_seconds": median(&cell.seconds),
        "median_cpu_seconds": median(&cell.cpu),
        "converged": cell.converged,
        "failed": cell.failed,
    });
    println!("{line}");
    let f = |v: Option<f64>| {
        v.map_or("-".to_string(), |x| match x {
            x if x != 0.0 && x.abs() < 1e-2 => format!("{x:.2e}"),
            x => format!("{x:.4}"),
        })
    };
    let c = |v: Option<f64>| v.map_or("-".to_string(), |x| format!("{:.0}", 100.0 * x));
    eprintln!(
        "{:>8.0e} {:>9} {:>11} {:>11} {:>7} {:>11} {:>22} {:>9} {:>6}",
        rel,
        pattern,
        f(err),
        f(bound),
        ratio.map_or("-".into(), |r| format!("{r:.2}")),
        f(mean(&cell.short)),
        format!("{}/{}/{}/{}", c(cov[0]), c(cov[1]), c(cov[2]), c(cov[3])),
        median(&cell.cpu).map_or("-".into(), |s| format!("{s:.3}")),
        format!("{}/{}", cell.converged, a.draws),
    );
}
