use std::path::PathBuf;

use anyhow::Result;
use cordis_core::io::{read_trajectory, write_atomic};
use cordis_core::{CordisError, Scene};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scene file (JSON, cordis-scene/1): gives the links to draw and the time step.
    scene: PathBuf,
    /// The motion to show (.csv, .npy or .tra), drawn solid.
    #[arg(long, short = 't')]
    trajectory: PathBuf,
    /// A second motion of the same scene (e.g. the identified model's), drawn dashed in a
    /// lighter shade over the first, or side by side.
    #[arg(long, short = 'c')]
    compare: Option<PathBuf>,
    /// The page to write: one self-contained HTML file, nothing loaded from the network.
    #[arg(long)]
    html: PathBuf,
    /// Page title (default: the file names).
    #[arg(long)]
    title: Option<String>,
}

pub fn run(a: Args) -> Result<()> {
    let scene = Scene::from_json_path(&a.scene)?;
    let traj = read_trajectory(&a.trajectory)?;
    let compare = a.compare.as_deref().map(read_trajectory).transpose()?;
    let title = a.title.clone().unwrap_or_else(|| {
        let name = |p: &PathBuf| {
            p.file_name().map_or_else(
                || p.display().to_string(),
                |n| n.to_string_lossy().into_owned(),
            )
        };
        match &a.compare {
            Some(c) => format!(
                "{} — {} vs {}",
                name(&a.scene),
                name(&a.trajectory),
                name(c)
            ),
            None => format!("{} — {}", name(&a.scene), name(&a.trajectory)),
        }
    });
    let page = crate::render::render_html(&scene, &traj, compare.as_ref(), &title)
        .map_err(|e| name_files(e, &a))?;
    write_atomic(&a.html, page.as_bytes())?;
    eprintln!(
        "wrote {} ({:.1} MB; {} frames of {} particles{})",
        a.html.display(),
        page.len() as f64 / 1e6,
        traj.frames(),
        traj.particles(),
        if compare.is_some() { ", 2 motions" } else { "" }
    );
    Ok(())
}

/// `render_html` calls the motions "trajectory A" and "trajectory B": name their files instead.
fn name_files(e: CordisError, a: &Args) -> CordisError {
    match e {
        CordisError::Trajectory { place, message } => {
            let mut place = place.replacen("trajectory A", &a.trajectory.display().to_string(), 1);
            if let Some(c) = &a.compare {
                place = place.replacen("trajectory B (--compare)", &c.display().to_string(), 1);
            }
            CordisError::trajectory(place, message)
        }
        other => other,
    }
}
