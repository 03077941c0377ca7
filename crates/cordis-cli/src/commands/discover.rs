use std::path::PathBuf;
use std::sync::atomic::Ordering;
use std::time::Instant;

use anyhow::{anyhow, bail, Result};
use cordis_es::discover::identify::{identify_discovered_until, Identified};
use cordis_es::discover::link_test::link_test;
use cordis_es::discover::{discover, DiscoverOptions, Discovery, Kinds};

use super::Output;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Observed trajectory (.csv, .tsv, .npy, .tra, .trc, .c3d, .npz; see --columns, --units):
    /// positions only.
    #[arg(long, short = 't')]
    trajectory: PathBuf,
    /// Time step, s (default: the trajectory's own, when its format records one).
    #[arg(long)]
    dt: Option<f64>,
    #[command(flatten)]
    read: super::ReadArgs,
    /// Total mass of the moving particles, kg (masses and stiffnesses share one scale).
    #[arg(long, conflicts_with = "masses")]
    total_mass: Option<f64>,
    /// Every particle's mass, kg: a file of numbers (one per particle, separated by spaces,
    /// commas or newlines; a JSON array also reads).
    #[arg(long)]
    masses: Option<PathBuf>,
    /// Candidate pairs are those closer than this in the first frame, m (default: 2.2 × the
    /// median nearest-neighbour distance).
    #[arg(long)]
    max_range: Option<f64>,
    /// Standard deviation of the position noise, m (0: noiseless; > 0 smooths first; default:
    /// estimated from the positions' differences, with a warning when they look noisy).
    #[arg(long)]
    noise_level: Option<f64>,
    /// Multiplies the selection threshold (lower keeps more links).
    #[arg(long, default_value_t = 1.0)]
    threshold_scale: f64,
    /// Relative tolerance under which two links are of one type.
    #[arg(long, default_value_t = 1e-3)]
    type_tolerance: f64,
    /// Gravity when known, m/s²: `X,Y,Z` (default: estimated, shared by every particle).
    #[arg(
        long,
        value_delimiter = ',',
        num_args = 1..=3,
        allow_negative_numbers = true
    )]
    gravity: Option<Vec<f64>>,
    /// Link kinds to look for, comma-separated: spring (between moving particles), anchor (to a
    /// fixed particle), damper (isotropic, F = Z (v_j - v_i)). Default: all three.
    #[arg(long, value_delimiter = ',', num_args = 1..)]
    kinds: Option<Vec<String>>,
    /// Where to write the proposed scene (JSON; stdout when absent).
    #[arg(long, short = 'o')]
    out: Option<PathBuf>,
    /// Where to write the per-link scores and the near misses (JSON).
    #[arg(long)]
    scores: Option<PathBuf>,
    /// Then test every candidate pair again by output error: each pair a spring of its own,
    /// all fitted at once to the positions (never differentiated), a pair kept as a link when
    /// its stiffness stands clear of 0 against its standard error at a 5 % false discovery
    /// rate (`docs/discover.md`, Link test).
    /// Slower (a fit of 3 unknowns per candidate pair), more powerful under noise.
    #[arg(long)]
    link_test: bool,
    /// Then identify the discovered network by output-error on the same motion (link
    /// parameters, gravity and discovered masses in boxes around the discovered values) and
    /// write the identified scene here (JSON). Refused when the discovery names something as
    /// not determined.
    #[arg(long, value_name = "OUT")]
    identify: Option<PathBuf>,
}

fn read_masses(path: &std::path::Path) -> Result<Vec<f64>> {
    // A missing or unreadable file is an I/O error (exit 1), as for every input.
    let text = cordis_core::io::read_text(path)?;
    text.split(|c: char| c.is_whitespace() || c == ',' || c == '[' || c == ']')
        .filter(|s| !s.is_empty())
        .enumerate()
        .map(|(k, s)| {
            s.parse::<f64>()
                .map_err(|_| anyhow!("{}: value {k} `{s}` is not a number", path.display()))
        })
        .collect()
}

pub fn run(a: Args, output: Output) -> Result<()> {
    super::guard_outputs(
        &[
            ("--trajectory", Some(&a.trajectory)),
            ("--masses", a.masses.as_deref()),
        ],
        &[
            ("--out", a.out.as_deref()),
            ("--scores", a.scores.as_deref()),
            ("--identify", a.identify.as_deref()),
        ],
    )?;
    let traj = cordis_core::io::read_trajectory_with(&a.trajectory, &a.read.options()?)?;
    let dt = match (a.dt, traj.dt) {
        (Some(dt), _) => dt,
        (None, Some(dt)) => dt,
        (None, None) => bail!(
            "{}: the file records no time step: give --dt",
            a.trajectory.display()
        ),
    };
    let opt = options(&a)?;
    let start = Instant::now();
    let d = discover(&traj, dt, &opt)?;
    let (d, tested) = match a.link_test {
        true => {
            let t = link_test(&traj, &d, &opt)?;
            let summary = serde_json::to_value(&t.report)?;
            (t.discovery, Some(summary))
        }
        false => (d, None),
    };
    let seconds = start.elapsed().as_secs_f64();
    let scores = scores_json(&d, seconds, tested);
    if let Some(path) = &a.scores {
        let text = serde_json::to_string_pretty(&scores)?;
        cordis_core::io::write_atomic(path, text.as_bytes())?;
    }
    let mut summary = scores;
    summary["particles"] = d.scene.num_particles().into();
    summary["types"] = d.scene.types.len().into();
    summary["num_links"] = d.scene.links.len().into();
    let Some(id_path) = &a.identify else {
        output.scene_result(&d.scene, a.out.as_deref(), summary)?;
        if output.human() {
            report_discovery(&d, seconds, a.link_test);
        }
        return Ok(());
    };
    // The discovery is kept before the fit starts: an identification that is refused, fails
    // or is stopped by Ctrl-C (it can run for minutes) loses nothing of it. Without --out
    // the scene goes to stdout first, as it would without --identify; with --json it rides
    // on the summary line, which a stopped fit does not print.
    let kept = match &a.out {
        Some(out) => {
            super::write_scene(&d.scene, Some(out))?;
            format!("the discovered scene is in {}", out.display())
        }
        None if !output.json => {
            super::write_scene(&d.scene, None)?;
            "the discovered scene was printed".to_string()
        }
        None => "the discovery was not written (no --out)".to_string(),
    };
    if output.human() {
        report_discovery(&d, seconds, a.link_test);
        eprintln!("identifying the discovered network by output-error (Ctrl-C stops it; {kept})…");
    }
    super::catch_ctrl_c();
    let t = Instant::now();
    let halt = || super::INTERRUPTED.load(Ordering::Relaxed);
    let id = match identify_discovered_until(&traj, &d, &opt, &halt) {
        Ok(Some(id)) => id,
        Ok(None) => {
            let msg = format!(
                "{kept}; the identification was stopped before its estimate, nothing written to {}",
                id_path.display()
            );
            return Err(super::Interrupted(msg).into());
        }
        Err(e) => {
            return Err(anyhow::Error::from(e).context(format!("--identify ({kept})")));
        }
    };
    let secs = t.elapsed().as_secs_f64();
    cordis_core::io::write_atomic(id_path, id.scene.to_json_string().as_bytes())?;
    let warnings = id.warnings();
    let mut v = id.to_json(&warnings);
    v["out"] = id_path.display().to_string().into();
    v["seconds"] = secs.into();
    summary["identify"] = v;
    if output.json {
        summary["out"] = a.out.as_ref().map(|p| p.display().to_string()).into();
        if a.out.is_none() {
            summary["scene"] = d.scene.to_json_value();
        }
        output.json_line(&summary)?;
    }
    if output.human() {
        report_identified(&id, id_path, secs);
    }
    // Warnings print even with --quiet or --json, as identify's: the answer is not to be
    // trusted as it is.
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    Ok(())
}

/// The discovery's options from the command line (a mass scale required, gravity three
/// finite numbers, the kinds' names known).
fn options(a: &Args) -> Result<DiscoverOptions> {
    if a.total_mass.is_none() && a.masses.is_none() {
        bail!("--total-mass or --masses: masses and stiffnesses are only determined up to a common scale");
    }
    let masses = a.masses.as_deref().map(read_masses).transpose()?;
    let gravity = match a.gravity.as_deref() {
        None => None,
        Some(&[x, y, z]) if [x, y, z].iter().all(|v| v.is_finite()) => Some([x, y, z]),
        Some(g) => bail!("--gravity: three finite numbers X,Y,Z in m/s², got {g:?}"),
    };
    let kinds = match &a.kinds {
        Some(k) => Some(Kinds::parse(k)?),
        None => None,
    };
    Ok(DiscoverOptions {
        total_mass: a.total_mass,
        masses,
        max_range: a.max_range,
        noise_level: a.noise_level,
        threshold_scale: a.threshold_scale,
        type_tolerance: a.type_tolerance,
        gravity,
        kinds,
        style: cordis_es::session::Style::Cli,
    })
}

/// The `--scores` file (and the JSON line's start): per-link scores, near misses, the
/// solver's account, the noise level and the link test's report.
fn scores_json(
    d: &Discovery,
    seconds: f64,
    tested: Option<serde_json::Value>,
) -> serde_json::Value {
    serde_json::json!({
        "radius": d.radius,
        "candidates": d.candidates,
        "rounds": d.rounds,
        "cost": d.cost,
        "rmse": d.rmse,
        "links": d.links,
        "near_misses": d.near_misses,
        "solver": d.solver,
        "undetermined": d.undetermined,
        "noise_level": d.noise_level,
        "noise_estimated": d.estimated_noise,
        "notes": d.notes,
        "seconds": seconds,
        "link_test": tested,
    })
}

/// The discovery's lines for a terminal: counts, the weakest kept and strongest rejected
/// pairs, notes and warnings.
fn report_discovery(d: &Discovery, seconds: f64, link_test: bool) {
    eprintln!(
        "{} particles, {} candidate pairs (radius {:.4} m) -> {} links of {} types in {:.2} s; {} {:.3e} m",
        d.scene.num_particles(),
        d.candidates,
        d.radius,
        d.scene.links.len(),
        d.scene.types.len(),
        seconds,
        if link_test { "position σ̂" } else { "short-cost rmse" },
        d.rmse
    );
    let weakest = d
        .links
        .iter()
        .min_by(|x, y| (x.score / x.threshold).total_cmp(&(y.score / y.threshold)));
    if let Some(l) = weakest {
        eprintln!(
            "weakest link {:?}: score {:.3e} (threshold {:.3e})",
            l.particles, l.score, l.threshold
        );
    }
    if let Some(m) = d.near_misses.first() {
        eprintln!(
            "strongest rejected pair {:?}: score {:.3e} (threshold {:.3e})",
            m.particles, m.score, m.threshold
        );
    }
    for n in &d.notes {
        eprintln!("note: {n}");
    }
    for w in d.warnings() {
        eprintln!("warning: {w}");
    }
}

/// The identification's lines for a terminal: status, each unknown with its interval.
fn report_identified(id: &Identified, path: &std::path::Path, seconds: f64) {
    eprintln!(
        "identified (output-error, {} unknowns) in {seconds:.2} s: end {}, residual σ̂ {:.3e} m (noise read from the data {:.3e} m) -> {}",
        id.params.len(),
        id.end,
        id.sigma,
        id.noise_level,
        path.display()
    );
    for p in &id.params {
        // A not determined unknown's range is its box (the held mass, which has none: [0, inf]).
        let spread = match p.stderr.is_finite() {
            true => format!("95 % [{:.6e}, {:.6e}]", p.low, p.high),
            false => format!("not determined, in [{:.6e}, {:.6e}]", p.low, p.high),
        };
        eprintln!(
            "  {}: {:.6e} (discovered {:.6e}), {spread}{}",
            p.name,
            p.value,
            p.discovered,
            if p.at_bound { " at its box's edge" } else { "" }
        );
    }
    if !id.gravity_fitted {
        eprintln!(
            "note: gravity held at {:?} m/s² (given, none found, or a fit too large for gravity's \
             dense sensitivities)",
            id.scene.gravity
        );
    }
    if let Some(r) = id.reference {
        eprintln!(
            "note: masses fitted with particles[{r}].mass held, then every mass, stiffness and \
             damping rescaled to the total mass (the motion does not change)"
        );
    }
}
