use std::path::PathBuf;

use anyhow::{anyhow, Result};
use cordis_core::examples;

use super::Output;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Example name: rigid | cloth | fluid | horse | muscle | tadpole | frog.
    name: String,
    /// Write the scene with its positive parameters unknown, in boxes `--width` times wide
    /// around the true values (the truth is the scene written without this flag).
    #[arg(long)]
    unknowns: bool,
    /// Width (max/min) of the unknown boxes.
    #[arg(long, default_value_t = 25.0)]
    width: f64,
    /// Seed placing the truth inside each box.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Output file (default: stdout).
    #[arg(long, short = 'o')]
    out: Option<PathBuf>,
}

pub fn run(a: Args, output: Output) -> Result<()> {
    let scene = examples::by_name(&a.name).ok_or_else(|| {
        anyhow!(
            "example `{}` does not exist (expected one of: {})",
            a.name,
            examples::NAMES.join(", ")
        )
    })?;
    let scene = if a.unknowns {
        cordis_es::identify::with_unknown_boxes(&scene, a.width, a.seed)
    } else {
        scene
    };
    let frames = examples::default_frames(&a.name);
    let summary = serde_json::json!({
        "example": a.name,
        "unknowns": a.unknowns,
        "particles": scene.num_particles(),
        "types": scene.types.len(),
        "links": scene.links.len(),
        "couplings": scene.couplings.len(),
        "frames": frames,
    });
    output.scene_result(&scene, a.out.as_deref(), summary)?;
    if let (Some(out), true) = (&a.out, output.human()) {
        let couplings = match scene.couplings.len() {
            0 => String::new(),
            n => format!(", {n} couplings"),
        };
        eprintln!(
            "wrote {} ({} particles, {} types, {} links{couplings}; simulate {} frames)",
            out.display(),
            scene.num_particles(),
            scene.types.len(),
            scene.links.len(),
            frames
        );
    }
    Ok(())
}
