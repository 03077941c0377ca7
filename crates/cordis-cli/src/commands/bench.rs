//! `cordis bench MODE`: benchmarks that print one JSON line per measurement on stdout and a
//! readable table on stderr. One file per mode under `bench/`.

mod cost;
mod stability;

use anyhow::Result;

#[derive(clap::Args, Debug)]
pub struct Args {
    #[command(subcommand)]
    mode: Mode,
}

#[derive(clap::Subcommand, Debug)]
pub enum Mode {
    /// Cost-function throughput (link evaluations per second) on the shipped examples.
    Cost(cost::Args),
    /// The stability bound against measured limits, long undamped runs, large scenes and
    /// extreme values.
    Stability(stability::Args),
}

/// Benchmarks print JSON lines whatever `--json` says; `--quiet` is not honoured by their
/// tables (a benchmark run is read by a person or a script that keeps stdout only).
pub fn run(a: Args, _output: super::Output) -> Result<()> {
    match a.mode {
        Mode::Cost(a) => cost::run(a),
        Mode::Stability(a) => stability::run(a),
    }
}
