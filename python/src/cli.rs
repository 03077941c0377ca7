//! The `cordis` console script: the Rust CLI itself, run in-process.

use std::io::Write;

use pyo3::prelude::*;

/// Runs the `cordis` command line with `argv` (`argv[0]` is the program name) and returns its
/// exit code. For the console script (`cordis …`, `python -m cordis …`): the `identify`
/// command installs its own Ctrl-C handler for the rest of the process.
#[pyfunction]
#[pyo3(signature = (argv, /))]
pub fn _cli_main(py: Python<'_>, argv: Vec<String>) -> i32 {
    py.detach(|| {
        let code = cordis_cli::run(argv);
        // A Rust runtime that does not own the process never flushes its stdout at exit.
        let _ = std::io::stdout().flush();
        let _ = std::io::stderr().flush();
        code
    })
}

pub fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_function(wrap_pyfunction!(_cli_main, m)?)?;
    Ok(())
}
