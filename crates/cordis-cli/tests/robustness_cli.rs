//! Issue 17: bad input of any kind gives one printable line naming the place and exit 2 (or 1
//! for a failed run), never a panic: error text escaped and cut, every numeric option bounded.

use std::path::Path;
use std::process::{Command, Output};

fn cordis(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_cordis"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("cordis runs")
}

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// A failed run: `code`, one line on stderr holding every piece of `says`.
fn fails(dir: &Path, args: &[&str], code: i32, says: &[&str]) -> String {
    let out = cordis(dir, args);
    let err = stderr(&out);
    assert_eq!(out.status.code(), Some(code), "{args:?}: {err}");
    assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
    for s in says {
        assert!(err.contains(s), "{args:?}: `{s}` not in {err}");
    }
    err
}

fn rigid_dir() -> tempfile::TempDir {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for args in [
        &["example", "rigid", "--out", "r.json"][..],
        &["simulate", "r.json", "--frames", "30", "--out", "r.csv"],
    ] {
        let out = cordis(d, args);
        assert!(out.status.success(), "{args:?}: {}", stderr(&out));
    }
    dir
}

#[test]
fn error_messages_escape_input_bytes_and_cut_long_values() {
    let dir = rigid_dir();
    let d = dir.path();
    std::fs::write(
        d.join("esc.csv"),
        "frame,particle,x,y,z\n0,0,1,2,\x1b[31mred\x07\n",
    )
    .unwrap();
    let err = fails(
        d,
        &["render", "r.json", "-t", "esc.csv", "--html", "o.html"],
        2,
        &["esc.csv:2", "\\u{1b}[31mred\\u{7}"],
    );
    assert!(!err.contains('\x1b') && !err.contains('\x07'), "{err:?}");

    let long = "a".repeat(1_000_000);
    std::fs::write(
        d.join("long.csv"),
        format!("frame,particle,x,y,z\n0,0,1,2,{long}\n"),
    )
    .unwrap();
    let err = fails(
        d,
        &["render", "r.json", "-t", "long.csv", "--html", "o.html"],
        2,
        &["long.csv:2", "…(1000002 characters)"],
    );
    assert!(err.len() < 300, "{} bytes: {err}", err.len());
    assert!(!d.join("o.html").exists());
}
