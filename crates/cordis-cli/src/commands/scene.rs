//! `cordis scene MODE`: scenes built from data. `from-markers` builds a spring network on
//! tracked markers, every parameter unknown in a box (`cordis_core::from_markers`).

use std::path::PathBuf;

use anyhow::{bail, Result};
use cordis_core::from_markers::{scene_from_markers, LinkRule, MarkerScene, TypeRule};

use super::{Output, ReadArgs};

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    mode: Mode,
}

#[derive(clap::Subcommand, Debug)]
pub enum Mode {
    /// A spring network on tracked markers (k nearest neighbours or a radius), one type per
    /// link family or per link, every parameter unknown in a box: ready for `cordis identify`.
    #[command(
        after_help = "Example:\n  cordis scene from-markers markers.csv --dt 0.01 --total-mass 0.54 --radius 0.18 --out scene.json\n  cordis identify scene.json -t markers.csv --out identified.json"
    )]
    FromMarkers(FromMarkers),
}

#[derive(clap::Args, Debug)]
pub struct FromMarkers {
    /// The tracked markers (.csv, .tsv, .npy, .trc, .c3d, .npz; see --columns, --units).
    trajectory: PathBuf,
    /// Each marker linked to its K nearest others (default 6 when --radius is not given).
    #[arg(long, conflicts_with = "radius")]
    neighbours: Option<usize>,
    /// Every pair of markers closer than this in the first frame, m.
    #[arg(long)]
    radius: Option<f64>,
    /// One link type per family of equal observed lengths (`family`) or per link (`link`).
    #[arg(long, default_value = "family", value_parser = ["family", "link"])]
    types: String,
    /// Relative tolerance under which two observed lengths are of one family.
    #[arg(long, default_value_t = 0.05)]
    family_tolerance: f64,
    /// Ratio max/min of the rest-length boxes around the observed lengths.
    #[arg(long, default_value_t = 4.0)]
    width: f64,
    /// Total mass of the markers' body, kg (shared equally).
    #[arg(long)]
    total_mass: f64,
    /// Time step, s (default: the file's rate).
    #[arg(long)]
    dt: Option<f64>,
    /// Gravity, m/s², as gx,gy,gz.
    #[arg(long, default_value = "0,-9.81,0", allow_hyphen_values = true)]
    gravity: String,
    /// A marker whose observations all stay within this of their median is fixed, m (default:
    /// 2 % of the markers' extent).
    #[arg(long)]
    still: Option<f64>,
    /// The scene to write (JSON; stdout when absent).
    #[arg(long, short = 'o')]
    out: Option<PathBuf>,
    #[command(flatten)]
    read: ReadArgs,
}

pub fn run(a: Args, output: Output) -> Result<()> {
    match a.mode {
        Mode::FromMarkers(a) => from_markers(a, output),
    }
}

fn from_markers(a: FromMarkers, output: Output) -> Result<()> {
    super::guard_outputs(
        &[("TRAJ", Some(&a.trajectory))],
        &[("--out", a.out.as_deref())],
    )?;
    let gravity: Vec<f64> = a
        .gravity
        .split(',')
        .map(|g| g.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| anyhow::anyhow!("--gravity: `{}` is not gx,gy,gz", a.gravity))?;
    let [gx, gy, gz] = gravity[..] else {
        bail!("--gravity: `{}` is not three numbers gx,gy,gz", a.gravity);
    };
    for (k, g) in [gx, gy, gz].iter().enumerate() {
        cordis_core::arg::number(
            &format!("--gravity[{k}]"),
            *g,
            cordis_core::arg::Low::AtLeast(-1e6),
            1e6,
            "m/s²",
        )?;
    }
    let imported = cordis_core::io::read_markers(&a.trajectory, &a.read.options()?)?;
    let dt = match (a.dt, imported.observations.dt) {
        (Some(dt), _) | (None, Some(dt)) => dt,
        (None, None) => bail!(
            "{}: the file records no rate: give --dt",
            a.trajectory.display()
        ),
    };
    let links = match (a.neighbours, a.radius) {
        (_, Some(r)) => LinkRule::Radius(r),
        (k, None) => LinkRule::Nearest(k.unwrap_or(6)),
    };
    let options = MarkerScene {
        links,
        types: if a.types == "link" {
            TypeRule::PerLink
        } else {
            TypeRule::Family
        },
        width: a.width,
        total_mass: a.total_mass,
        dt,
        gravity: [gx, gy, gz],
        still: a.still,
        family_tolerance: cordis_core::arg::number(
            "--family-tolerance",
            a.family_tolerance,
            cordis_core::arg::Low::AtLeast(0.0),
            10.0,
            "",
        )?,
    };
    let scene = scene_from_markers(&imported.observations, &options)?;
    let fixed = scene.particles.iter().filter(|p| p.fixed).count();
    let summary = serde_json::json!({
        "particles": scene.num_particles(),
        "fixed": fixed,
        "types": scene.types.len(),
        "links": scene.links.len(),
        "dt": dt,
        "unknowns": scene.has_unknowns(),
    });
    output.scene_result(&scene, a.out.as_deref(), summary)?;
    if output.human() {
        eprintln!(
            "{} markers ({} fixed: they never move), {} links in {} types, dt {dt} s{}",
            scene.num_particles(),
            fixed,
            scene.links.len(),
            scene.types.len(),
            a.out
                .as_ref()
                .map(|p| format!("; wrote {}", p.display()))
                .unwrap_or_default()
        );
    }
    Ok(())
}
