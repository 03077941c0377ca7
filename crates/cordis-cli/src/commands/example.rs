use std::path::PathBuf;

use anyhow::{anyhow, Result};
use cordis_core::examples;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Example name: rigid | cloth | fluid | horse.
    name: String,
    /// Output file (default: stdout).
    #[arg(long, short = 'o')]
    out: Option<PathBuf>,
}

pub fn run(a: Args) -> Result<()> {
    let scene = examples::by_name(&a.name).ok_or_else(|| {
        anyhow!(
            "example `{}` does not exist (expected one of: {})",
            a.name,
            examples::NAMES.join(", ")
        )
    })?;
    super::write_scene(&scene, a.out.as_deref())?;
    if let Some(out) = &a.out {
        eprintln!(
            "wrote {} ({} particles, {} types, {} links; simulate {} frames)",
            out.display(),
            scene.num_particles(),
            scene.types.len(),
            scene.links.len(),
            examples::default_frames(&a.name)
        );
    }
    Ok(())
}
