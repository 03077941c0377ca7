use std::path::PathBuf;

use anyhow::Result;

#[derive(clap::Args, Debug)]
pub struct Args {
    /// Base name of the thesis files: NAME.mas, NAME.cat, NAME.ini, NAME.tra, NAME.lock.
    name: PathBuf,
    /// Time step in s (the thesis files do not carry it).
    #[arg(long, default_value_t = 0.01)]
    dt: f64,
    /// Output scene (default: stdout).
    #[arg(long, short = 'o')]
    out: Option<PathBuf>,
    /// Also write NAME.tra's trajectory here (.csv, .npy or .tra).
    #[arg(long)]
    trajectory: Option<PathBuf>,
}

pub fn run(a: Args) -> Result<()> {
    let model = cordis_core::thesis::import(&a.name, a.dt)?;
    super::write_scene(&model.scene, a.out.as_deref())?;
    if let Some(path) = &a.trajectory {
        match &model.trajectory {
            Some(t) => cordis_core::io::write_trajectory(path, t)?,
            None => anyhow::bail!("{}.tra: no trajectory to write", a.name.display()),
        }
    }
    Ok(())
}
