//! Helpers shared by the CLI tests (`output_safety_cli`, `robustness_cli`, `identify_tracked`).
#![allow(dead_code)] // each test crate uses its own part

use std::path::Path;
use std::process::{Command, Output};

pub fn cordis(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_cordis"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("cordis runs")
}

pub fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A failed run: `code`, one line on stderr holding every piece of `says`, nothing on stdout.
pub fn fails(dir: &Path, args: &[&str], code: i32, says: &[&str]) -> String {
    let out = cordis(dir, args);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(code), "{args:?}: {err}");
    assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
    for s in says {
        assert!(err.contains(s), "{args:?}: `{s}` not in {err}");
    }
    assert!(out.stdout.is_empty(), "{args:?} wrote on stdout");
    err
}

/// A directory with a rigid scene `r.json`, its unknown version `u.json` and motion `r.csv`.
pub fn rigid_dir() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for args in [
        &["example", "rigid", "--out", "r.json"][..],
        &["example", "rigid", "--unknowns", "--out", "u.json"],
        &["simulate", "r.json", "--frames", "30", "--out", "r.csv"],
    ] {
        let out = cordis(d, args);
        assert!(out.status.success(), "{args:?}: {}", stderr(&out));
    }
    dir
}

/// The temporary an output `name` in `dir` is streamed to until its run ends
/// (`.NAME.PID.N.tmp`, renamed over `name` then): where a running identification's log rows
/// are.
pub fn streamed(dir: &Path, name: &str) -> Option<std::path::PathBuf> {
    let prefix = format!(".{name}.");
    std::fs::read_dir(dir).ok()?.find_map(|e| {
        let p = e.ok()?.path();
        let file = p.file_name()?.to_str()?;
        (file.starts_with(&prefix) && file.ends_with(".tmp")).then_some(p)
    })
}
