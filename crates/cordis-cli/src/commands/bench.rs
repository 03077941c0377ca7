//! `cordis bench MODE`: benchmarks a user runs on their machine and data, printing one JSON
//! line per measurement on stdout and a readable table on stderr. One file per mode under
//! `bench/`. The thesis-reproduction harness (`pareto`, `stability`) is the `cordis-bench`
//! binary of `crates/cordis-bench`, not part of this one.

mod cost;
mod noise;

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
    /// The output-error estimator against the Cramér–Rao bound on generated networks through
    /// noise, gaps and hidden particles, beside the short cost's estimate.
    Noise(noise::Args),
}

/// `cost` prints JSON lines on stdout whatever `--json` says, and its table on stderr even
/// with `--quiet` (a script keeps stdout only; docs/cli.md says so).
pub fn run(a: Args, _output: super::Output) -> Result<()> {
    match a.mode {
        Mode::Cost(a) => cost::run(a),
        Mode::Noise(a) => noise::run(a),
    }
}
