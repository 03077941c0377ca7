//! `cordis-bench`: the experiments that reproduce the thesis' results and guard the stability
//! bound, apart from the `cordis` binary users install (which keeps `cordis bench cost` and
//! `cordis bench noise` as user tools).
//!
//! - `cordis-bench pareto`: every identification strategy on every shipped example at several
//!   budgets, and the speed-up over the thesis' strategy ([`pareto`]).
//! - `cordis-bench stability`: the stability bound against measured limits, long undamped
//!   runs, large scenes and extreme values ([`stability`]).
//!
//! Errors are one line on stderr, exit code 1 (2 for a bad command line, from clap).
#![forbid(unsafe_code)]

mod pareto;
mod stability;

use std::process::ExitCode;

use clap::Parser;

#[derive(Parser, Debug)]
#[command(
    name = "cordis-bench",
    version,
    about = "The thesis-reproduction benchmarks of cordis"
)]
struct Cli {
    /// stdout holds JSON objects only, one per line (`pareto`: its records; the tables go to
    /// stderr).
    #[arg(long, global = true)]
    json: bool,
    /// Nothing on stderr but errors (`stability` keeps its table on stderr).
    #[arg(long, short, global = true)]
    quiet: bool,
    #[command(subcommand)]
    mode: Mode,
}

#[derive(clap::Subcommand, Debug)]
enum Mode {
    /// Every identification strategy on every shipped example at several budgets: run time,
    /// evaluations, cost and parameter error, and the speed-up over the thesis' strategy.
    #[command(
        after_help = "Example:\n  cordis-bench pareto --scenes rigid --strategies cmaes,thesis --budgets 1000,100000"
    )]
    Pareto(pareto::Args),
    /// The stability bound against measured limits, long undamped runs, large scenes and
    /// extreme values.
    #[command(after_help = "Example:\n  cordis-bench stability --quick")]
    Stability(stability::Args),
}

/// Where human-readable output goes (the global `--json` and `--quiet`).
#[derive(Clone, Copy, Debug)]
pub struct Output {
    /// `--json`: stdout holds JSON objects only, one per line.
    pub json: bool,
    /// `--quiet`: no human-readable report on stderr.
    pub quiet: bool,
}

impl Output {
    /// Whether to write the human-readable report on stderr.
    pub fn human(&self) -> bool {
        !self.quiet
    }
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let output = Output {
        json: cli.json,
        quiet: cli.quiet,
    };
    let result = match cli.mode {
        Mode::Pareto(a) => pareto::run(a, output),
        Mode::Stability(a) => stability::run(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            let text = format!("{e:#}").replace('\n', " ");
            eprintln!("error: {text}");
            ExitCode::from(1)
        }
    }
}
