//! `cordis report`: the identification report, one self-contained HTML page
//! (`crate::report`): a model against the motion it was fitted to.

use std::path::PathBuf;

use anyhow::{Context, Result};
use cordis_core::io::{read_observations_with, read_text, write_atomic};
use cordis_core::CordisError;

use super::Output;
use crate::report::{
    fixed_far_warning, in_scene_order, json_kind, parse_convergence, report_html, ReportInput,
};

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(flatten)]
    page: super::PageArgs,
    /// The convergence log of the identification (`cordis identify --log`, .csv or .jsonl).
    #[arg(long)]
    log: Option<PathBuf>,
    /// The identification's summary: the JSON line `cordis identify --json` prints (its
    /// standard errors and intervals fill the parameter table).
    #[arg(long)]
    summary: Option<PathBuf>,
    /// Which scene particle each of the file's markers is, comma-separated, as given to
    /// `identify --markers` (without it, the file's particle i is the scene's particle i).
    /// Particles no marker names are shown unobserved.
    #[arg(long, allow_hyphen_values = true, value_parser = super::particle_indices)]
    markers: Option<super::ParticleIndices>,
    /// Each marker's weight, 1/σ relative, as given to `identify --weights` (one per marker,
    /// or three: x, y, z): the fit is also reported weighted.
    #[arg(long, value_delimiter = ',', num_args = 1.., allow_negative_numbers = true)]
    weights: Option<Vec<f64>>,
}

pub fn run(a: Args, output: Output) -> Result<()> {
    let scene = a.page.guarded_scene(&[
        ("--log", a.log.as_deref()),
        ("--summary", a.summary.as_deref()),
    ])?;
    let read = read_observations_with(&a.page.trajectory, &a.page.read.options()?)?;
    let file = a.page.trajectory.display().to_string();
    let (observed, weights) = match a.markers.is_some() || a.weights.is_some() {
        true => in_scene_order(
            &read,
            scene.num_particles(),
            a.markers.as_ref().map(|m| m.0.as_slice()),
            a.weights.as_deref(),
            ["--markers", "--weights", &file],
        )?,
        false => (read, None),
    };
    if let Some(w) = fixed_far_warning(&scene, &observed, &file, "--markers") {
        eprintln!("warning: {w}");
    }
    let convergence = a
        .log
        .as_ref()
        .map(|p| parse_convergence(&p.display().to_string(), &read_text(p)?))
        .transpose()?;
    let summary = a.summary.as_deref().map(read_summary).transpose()?;
    let title = a
        .page
        .title_or(|scene, motion| format!("{scene} — fitted to {motion}"));
    let page = report_html(&ReportInput {
        scene: &scene,
        observed: &observed,
        convergence: convergence.as_deref(),
        summary: summary.as_ref(),
        weights: weights.as_deref(),
        title: &title,
    })
    .map_err(|e| name_trajectory(e, &a))
    .with_context(|| a.page.scene.display().to_string())?;
    write_atomic(&a.page.html, page.as_bytes())?;
    if output.human() {
        eprintln!(
            "wrote {} ({} KB; {} frames of {} particles)",
            a.page.html.display(),
            page.len().div_ceil(1000),
            observed.frames(),
            observed.particles()
        );
    }
    if output.json {
        output.json_line(&serde_json::json!({
            "html": a.page.html.display().to_string(),
            "bytes": page.len(),
            "frames": observed.frames(),
            "particles": observed.particles(),
        }))?;
    }
    Ok(())
}

/// The report calls the observed motion "trajectory": name its file instead.
fn name_trajectory(e: CordisError, a: &Args) -> CordisError {
    match e {
        CordisError::Trajectory { place, message } if place == "trajectory" => {
            CordisError::trajectory(a.page.trajectory.display().to_string(), message)
        }
        other => other,
    }
}

/// The summary file: one JSON object, or JSON lines whose last object is the summary.
fn read_summary(path: &std::path::Path) -> Result<serde_json::Value> {
    let text = read_text(path)?;
    let name = path.display().to_string();
    let parsed = serde_json::from_str::<serde_json::Value>(&text).or_else(|e| {
        text.lines()
            .rev()
            .find(|l| !l.trim().is_empty())
            .and_then(|l| serde_json::from_str(l).ok())
            .ok_or(e)
    });
    // A scene or a log row is an object too: the report read such a file as a summary
    // without parameters' intervals, and said nothing.
    match parsed {
        Ok(v) if v.get("strategy").is_some() && v.get("stopped_by").is_some() => Ok(v),
        Ok(v) => Err(CordisError::format(
            name,
            format!(
                "expected a run's summary (the JSON line of `cordis identify --json`), got {}",
                json_kind(&v)
            ),
        )
        .into()),
        Err(e) => Err(CordisError::format(name, format!("invalid JSON: {e}")).into()),
    }
}
