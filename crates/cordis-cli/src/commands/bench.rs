//! `cordis bench MODE`: benchmarks that print one JSON line per measurement on stdout and a
//! readable table on stderr. One file per mode under `bench/`.

mod cost;
mod noise;
mod pareto;
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
    /// Every identification strategy on every shipped example at several budgets: run time,
    /// evaluations, cost and parameter error, and the speed-up over the thesis' strategy.
    Pareto(pareto::Args),
    /// The output-error estimator against the Cramér–Rao bound on generated networks through
    /// noise, gaps and hidden particles, beside the short cost's estimate.
    Noise(noise::Args),
}

/// `cost` and `stability` print JSON lines on stdout whatever `--json` says, and their table
/// on stderr even with `--quiet` (a script keeps stdout only; docs/cli.md says so). `pareto`
/// writes its records to a file and its tables on stdout; with `--json`, the records on stdout
/// and the tables on stderr.
pub fn run(a: Args, output: super::Output) -> Result<()> {
    match a.mode {
        Mode::Cost(a) => cost::run(a),
        Mode::Stability(a) => stability::run(a),
        Mode::Pareto(a) => pareto::run(a, output),
        Mode::Noise(a) => noise::run(a),
    }
}
