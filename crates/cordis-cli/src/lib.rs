//! The `cordis` command line (SPEC §5.4). A library so that the Python package can expose the
//! same command as a console script; `main.rs` only calls [`run`].
//!
//! Errors print one line on stderr (`error: <place>: <what>`) and exit with a non-zero code:
//! 1 for a failed run (diverged, I/O), 2 for bad input or usage, 130 when Ctrl-C stopped an
//! identification. `--json` makes stdout JSON lines only; `--quiet` silences the human report
//! (see [`commands::Output`]).

mod commands;
pub mod render;
pub mod report;

use std::ffi::OsString;

use clap::{Parser, Subcommand};

#[derive(Parser, Debug)]
#[command(
    name = "cordis",
    version,
    about = "Simulate Cordis-Anima mass-interaction networks and identify their parameters",
    after_help = "Example:\n  cordis example rigid --out rigid.json\n  cordis simulate rigid.json --frames 100 --out rigid.csv\n\nExit codes: 0 success, 1 the run failed (a file, a divergence), 2 bad input or usage,\n130 interrupted by Ctrl-C (identify writes its best result first; discover --identify keeps the discovery)."
)]
struct Cli {
    /// Machine-readable output: stdout holds only JSON objects, one per line (each command's
    /// summary; a scene written to stdout is embedded as "scene"; an error as {"error", ...}).
    #[arg(long, global = true)]
    json: bool,
    /// No human-readable report, progress bar or "wrote ..." line on stderr (warnings and
    /// errors still print).
    #[arg(long, short = 'q', global = true)]
    quiet: bool,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Simulate a scene from its initial state (the thesis' M2T).
    #[command(after_help = "Example:\n  cordis simulate rigid.json --frames 100 --out rigid.csv")]
    Simulate(commands::simulate::Args),
    /// Identify a scene's unknown parameters from an observed trajectory (the thesis' T2M).
    #[command(
        after_help = "Example:\n  cordis example rigid --out rigid.json\n  cordis simulate rigid.json --frames 100 --out rigid.csv\n  cordis example rigid --unknowns --out rigid-unknown.json\n  cordis identify rigid-unknown.json --trajectory rigid.csv --truth rigid.json --out identified.json"
    )]
    Identify(Box<commands::identify::Args>),
    /// Cost of a scene against an observed trajectory: total, rmse, per-particle local costs.
    #[command(
        after_help = "Example:\n  cordis cost rigid.json --trajectory rigid.csv --cost short"
    )]
    Cost(commands::cost::Args),
    /// Propose a spring network (links, masses, types) from positions alone.
    #[command(
        after_help = "Example:\n  cordis simulate net.json --frames 300 --out net.csv\n  cordis discover --trajectory net.csv --dt 0.005 --total-mass 20 --out found.json --scores scores.json"
    )]
    Discover(Box<commands::discover::Args>),
    /// Write a shipped example scene as JSON.
    #[command(after_help = "Example:\n  cordis example cloth --out cloth.json")]
    Example(commands::example::Args),
    /// Convert the thesis' files (NAME.mas, NAME.cat, NAME.ini, …) into a JSON scene, or a marker
    /// file (.c3d, .trc, .npz, .csv, .tsv) into a trajectory (NaN where a marker is missing).
    #[command(
        after_help = "Examples:\n  cordis import data/tri --dt 0.01 --out tri.json\n  cordis import walk.trc --out walk.npy\n  cordis import markers.csv --columns frame=Frame,particle=Marker,x=X,y=Y,z=Z --units mm --out markers.npy"
    )]
    Import(commands::import::Args),
    /// Export a scene to MuJoCo (MJCF) and a motion to glTF 2.0 (Blender, three.js) or a
    /// trajectory file.
    #[command(
        after_help = "Examples:\n  cordis export rigid.json --mjcf rigid.xml\n  cordis export cloth.json --frames 300 --gltf cloth.gltf --out cloth.npy\n  cordis export rigid.json --trajectory rigid.csv --gltf rigid.gltf"
    )]
    Export(commands::export::Args),
    /// Write a self-contained HTML page that plays a motion in 3-D (optionally against another).
    #[command(
        after_help = "Example:\n  cordis simulate rigid.json --frames 200 --out rigid.csv\n  cordis render rigid.json --trajectory rigid.csv --compare identified.csv --html rigid.html"
    )]
    Render(commands::render::Args),
    /// Identification report: one self-contained HTML page on a model and the motion it was
    /// fitted to (parameters with intervals, per-marker fits, residuals, convergence, 3-D replay).
    #[command(
        after_help = "Example:\n  cordis identify u.json -t obs.csv --log conv.csv --out fit.json --json > fit-summary.json\n  cordis report fit.json -t obs.csv --log conv.csv --summary fit-summary.json --html report.html"
    )]
    Report(commands::report::Args),
    /// Stability report: each particle's ratio to the bound 4m > K dt² + 2 Z dt, and a JSON line.
    #[command(after_help = "Example:\n  cordis check rigid.json")]
    Check(commands::check::Args),
    /// Scenes built from data: `from-markers` puts a spring network on tracked markers.
    Scene(commands::scene::Args),
    /// Benchmarks printing JSON lines and a readable table.
    #[command(after_help = "Example:\n  cordis bench cost")]
    Bench(commands::bench::Args),
}

/// Runs the command line; returns the process exit code.
pub fn run<I, T>(args: I) -> i32
where
    I: IntoIterator<Item = T>,
    T: Into<OsString> + Clone,
{
    let cli = match Cli::try_parse_from(args) {
        Ok(cli) => cli,
        Err(e)
            if !e.use_stderr()
                || e.kind() == clap::error::ErrorKind::DisplayHelpOnMissingArgumentOrSubcommand =>
        {
            let code = if e.use_stderr() { 2 } else { 0 };
            // --help and --version are not errors.
            let _ = e.print();
            return code;
        }
        Err(e) => {
            // One line, like every other error (clap adds the usage and tips on more lines),
            // with the option's value escaped.
            let text = e.render().to_string();
            eprintln!(
                "error: {} (see `cordis --help`)",
                cordis_core::error::printable(&first_clap_line(&text))
            );
            return 2;
        }
    };
    let output = commands::Output {
        json: cli.json,
        quiet: cli.quiet,
    };
    let result = match cli.command {
        Command::Simulate(a) => commands::simulate::run(a, output),
        Command::Identify(a) => commands::identify::run(*a, output),
        Command::Cost(a) => commands::cost::run(a, output),
        Command::Discover(a) => commands::discover::run(*a, output),
        Command::Example(a) => commands::example::run(a, output),
        Command::Import(a) => commands::import::run(a, output),
        Command::Export(a) => commands::export::run(a, output),
        Command::Render(a) => commands::render::run(a, output),
        Command::Report(a) => commands::report::run(a, output),
        Command::Check(a) => commands::check::run(a, output),
        Command::Bench(a) => commands::bench::run(a, output),
        Command::Scene(a) => commands::scene::run(a, output),
    };
    match result {
        Ok(()) => 0,
        Err(e) => {
            let code = exit_code(&e);
            let message = one_line(&e);
            eprintln!("error: {message}");
            if output.json {
                // Best effort: the error is already on stderr and in the exit code.
                let _ = output.json_line(&serde_json::json!({
                    "error": message,
                    "exit_code": code,
                }));
            }
            code
        }
    }
}

/// clap's error as one line: its first line, and when that ends in a colon (the missing
/// required arguments) the indented list under it, joined — else `identify guess.json` said
/// "the following required arguments were not provided:" and named none.
fn first_clap_line(text: &str) -> String {
    let mut lines = text.lines().skip_while(|l| l.trim().is_empty());
    let first = lines.next().unwrap_or("error");
    let first = first.strip_prefix("error: ").unwrap_or(first).trim_end();
    if !first.ends_with(':') {
        return first.to_string();
    }
    let listed: Vec<&str> = lines
        .take_while(|l| l.starts_with(' ') && !l.trim().is_empty())
        .map(str::trim)
        .collect();
    format!("{first} {}", listed.join(", "))
}

/// The error and its causes on one line, printable (input bytes escaped, long values cut:
/// `cordis_core::error::printable`).
fn one_line(e: &anyhow::Error) -> String {
    let mut s = e.to_string();
    for cause in e.chain().skip(1) {
        let c = cause.to_string();
        if !s.contains(&c) {
            s.push_str(": ");
            s.push_str(&c);
        }
    }
    cordis_core::error::printable(&s.replace('\n', " "))
}

/// 0 success, 1 a run that failed (divergence, a file that cannot be opened, read or written —
/// every input alike, `--resume` included), 2 bad input (a file that reads but is wrong) or
/// usage, 130 interrupted by Ctrl-C (after writing what was done so far). docs/cli.md holds
/// the table; `tests/exit_codes_cli.rs` checks it for every command.
fn exit_code(e: &anyhow::Error) -> i32 {
    use cordis_core::CordisError;
    use cordis_es::CostError;
    if e.is::<commands::Interrupted>() {
        return 130;
    }
    let core = e
        .downcast_ref::<CordisError>()
        .or(match e.downcast_ref::<CostError>() {
            Some(CostError::Core(c)) => Some(c),
            _ => None,
        });
    if matches!(e.downcast_ref::<CostError>(), Some(CostError::Run { .. })) {
        // A run that failed (no estimate, a failed evaluation, a checkpoint not written).
        return 1;
    }
    match core {
        Some(CordisError::Diverged { .. }) | Some(CordisError::Io { .. }) => 1,
        _ => 2,
    }
}
