pub mod bench;
pub mod check;
pub mod cost;
pub mod discover;
pub mod example;
pub mod identify;
pub mod import;
pub mod render;
pub mod simulate;

use std::path::Path;

use anyhow::Result;
use cordis_core::Scene;

/// Refuses a trajectory whose time step (from its file, or `--dt`) is not the scene's: the
/// costs predict with the scene's dt.
pub fn check_dt(scene: &Scene, traj_dt: Option<f64>, traj_path: &Path) -> Result<()> {
    if let Some(dt) = traj_dt {
        if (dt - scene.dt).abs() > 1e-12 * scene.dt {
            anyhow::bail!(
                "{}: trajectory dt {dt} differs from the scene's dt {}",
                traj_path.display(),
                scene.dt
            );
        }
    }
    Ok(())
}

/// Writes a scene as JSON (atomically) or to stdout when no path is given.
pub fn write_scene(scene: &Scene, out: Option<&Path>) -> Result<()> {
    let text = scene.to_json_string();
    match out {
        Some(path) => cordis_core::io::write_atomic(path, text.as_bytes())?,
        None => print_stdout(&text)?,
    }
    Ok(())
}

/// Writes to stdout; a closed pipe (`cordis example fluid | head`) ends the output quietly
/// instead of panicking like `print!` does.
pub fn print_stdout(text: &str) -> Result<()> {
    use std::io::Write;
    let mut out = std::io::stdout().lock();
    match out.write_all(text.as_bytes()).and_then(|()| out.flush()) {
        Err(e) if e.kind() != std::io::ErrorKind::BrokenPipe => Err(e.into()),
        _ => Ok(()),
    }
}
