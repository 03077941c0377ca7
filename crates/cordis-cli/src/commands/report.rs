//! `cordis report`: the identification report, one self-contained HTML page
//! (`crate::report`): a model against the motion it was fitted to.

use std::path::PathBuf;

use anyhow::{Context, Result};
use cordis_core::io::{read_observations_with, read_text, write_atomic};
use cordis_core::{CordisError, Scene};

use super::Output;
use crate::report::{parse_convergence, report_html, ReportInput};

#[derive(clap::Args, Debug)]
pub struct Args {
    /// The model (JSON, cordis-scene/1, every parameter known): `cordis identify --out`.
    scene: PathBuf,
    /// The observed motion (.csv, .tsv, .npy, .tra, .trc, .c3d, .npz), gaps allowed; its
    /// particle i is the scene's particle i.
    #[arg(long, short = 't')]
    trajectory: PathBuf,
    /// The page to write.
    #[arg(long)]
    html: PathBuf,
    /// The convergence log of the identification (`cordis identify --log`, .csv or .jsonl).
    #[arg(long)]
    log: Option<PathBuf>,
    /// The identification's summary: the JSON line `cordis identify --json` prints (its
    /// standard errors and intervals fill the parameter table).
    #[arg(long)]
    summary: Option<PathBuf>,
    /// Page title (default: the file names).
    #[arg(long)]
    title: Option<String>,
    #[command(flatten)]
    read: super::ReadArgs,
}

pub fn run(a: Args, output: Output) -> Result<()> {
    super::guard_outputs(
        &[
            ("scene", Some(&a.scene)),
            ("--trajectory", Some(&a.trajectory)),
            ("--log", a.log.as_deref()),
            ("--summary", a.summary.as_deref()),
        ],
        &[("--html", Some(&a.html))],
    )?;
    let scene = Scene::from_json_path(&a.scene)?;
    let observed = read_observations_with(&a.trajectory, &a.read.options()?)?;
    let convergence = a
        .log
        .as_ref()
        .map(|p| parse_convergence(&p.display().to_string(), &read_text(p)?))
        .transpose()?;
    let summary = a.summary.as_deref().map(read_summary).transpose()?;
    let name = |p: &PathBuf| {
        p.file_name().map_or_else(
            || p.display().to_string(),
            |n| n.to_string_lossy().into_owned(),
        )
    };
    let title = a
        .title
        .clone()
        .unwrap_or_else(|| format!("{} — fitted to {}", name(&a.scene), name(&a.trajectory)));
    let page = report_html(&ReportInput {
        scene: &scene,
        observed: &observed,
        convergence: convergence.as_deref(),
        summary: summary.as_ref(),
        title: &title,
    })
    .map_err(|e| match e {
        CordisError::Trajectory { place, message } if place == "trajectory" => {
            CordisError::trajectory(a.trajectory.display().to_string(), message)
        }
        other => other,
    })
    .with_context(|| a.scene.display().to_string())?;
    write_atomic(&a.html, page.as_bytes())?;
    if output.human() {
        eprintln!(
            "wrote {} ({} KB; {} frames of {} particles)",
            a.html.display(),
            page.len().div_ceil(1000),
            observed.frames(),
            observed.particles()
        );
    }
    if output.json {
        output.json_line(&serde_json::json!({
            "html": a.html.display().to_string(),
            "bytes": page.len(),
            "frames": observed.frames(),
            "particles": observed.particles(),
        }))?;
    }
    Ok(())
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
    match parsed {
        Ok(v) if v.is_object() => Ok(v),
        Ok(_) => Err(CordisError::format(
            name,
            "expected the JSON object of `cordis identify --json`",
        )
        .into()),
        Err(e) => Err(CordisError::format(name, format!("invalid JSON: {e}")).into()),
    }
}
