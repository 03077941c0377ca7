//! `cordis bench MODE`: benchmarks that print one JSON line per measurement on stdout and a
//! readable table on stderr. One file per mode under `bench/`.

mod stability;

use anyhow::Result;

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    mode: Mode,
}

#[derive(clap::Subcommand, Debug)]
pub enum Mode {
    /// The stability bound against measured limits, long undamped runs, large scenes and
    /// extreme values.
    Stability(stability::Args),
}

pub fn run(a: Args) -> Result<()> {
    match a.mode {
        Mode::Stability(a) => stability::run(a),
    }
}
