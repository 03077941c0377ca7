//! Inputs saved by the fuzz targets (`fuzz/`), replayed as the target does. Each must give a
//! placed error (or a result), quickly, never a panic.

use std::time::{Duration, Instant};

/// `thesis_import`: the input split at 0xFF into the six thesis files, then imported.
fn thesis_import(data: &[u8]) -> cordis_core::Result<cordis_core::thesis::ThesisModel> {
    const FILES: [&str; 6] = ["m.mas", "m.cat", "m.ini", "m.tra", "m.lock", "Param.gene"];
    let dir = tempfile::tempdir().unwrap();
    for (part, name) in data.split(|&b| b == 0xFF).zip(FILES) {
        std::fs::write(dir.path().join(name), part).unwrap();
    }
    cordis_core::thesis::import(&dir.path().join("m"), 0.01)
}

/// Reported as a 10 s timeout while the machine was saturated; it takes milliseconds alone
/// (the `.mas` announces 5 unary links and lists none). Kept to prove it stays an error.
#[test]
fn thesis_import_timeout_c37e329e_is_a_prompt_placed_error() {
    let data = include_bytes!("fuzz-regressions/thesis_import-timeout-c37e329e");
    let start = Instant::now();
    let err = thesis_import(data).unwrap_err().to_string();
    assert!(err.contains("m.mas:7:"), "{err}");
    assert!(err.contains("liaisons unaires-position"), "{err}");
    assert!(start.elapsed() < Duration::from_secs(5));
}
