//! Issue 17, outputs: every output path is checked before any work — not an input (by
//! canonical path, symlinks and hard links included), not another output, writable — and a
//! write that fails at the end names the file and exits 1. No temporary is left behind.

mod common;

use std::path::Path;

use common::{cordis, fails, rigid_dir, stderr, streamed};

/// No file of `dir` is a temporary (`.NAME.PID.N.tmp` or a writability probe).
fn no_temporaries(dir: &Path) {
    let left: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".tmp"))
        .collect();
    assert!(left.is_empty(), "temporaries left: {left:?}");
}

#[test]
fn render_html_onto_the_trajectory_is_refused_and_the_trajectory_kept() {
    let dir = rigid_dir();
    let d = dir.path();
    let before = std::fs::read(d.join("r.csv")).unwrap();
    fails(
        d,
        &["render", "r.json", "-t", "r.csv", "--html", "r.csv"],
        2,
        &["--html", "--trajectory", "r.csv", "same file"],
    );
    // Through another spelling, a symlink, a hard link: the same file, refused.
    std::fs::create_dir(d.join("sub")).unwrap();
    std::os::unix::fs::symlink("../r.csv", d.join("sub/link.csv")).unwrap();
    std::fs::hard_link(d.join("r.csv"), d.join("hard.csv")).unwrap();
    for html in ["./sub/../r.csv", "sub/link.csv", "hard.csv"] {
        fails(
            d,
            &["render", "r.json", "-t", "r.csv", "--html", html],
            2,
            &["--html", "same file"],
        );
    }
    // The scene and --compare are inputs too.
    fails(
        d,
        &["render", "r.json", "-t", "r.csv", "--html", "r.json"],
        2,
        &["--html", "scene"],
    );
    fails(
        d,
        &[
            "render",
            "r.json",
            "-t",
            "r.csv",
            "-c",
            "hard.csv",
            "--html",
            "sub/link.csv",
        ],
        2,
        &["--html", "same file"],
    );
    assert_eq!(std::fs::read(d.join("r.csv")).unwrap(), before);
    no_temporaries(d);
}

#[test]
fn simulate_out_onto_its_scene_is_refused() {
    let dir = rigid_dir();
    let d = dir.path();
    let before = std::fs::read(d.join("r.json")).unwrap();
    std::os::unix::fs::symlink("r.json", d.join("r-link.csv")).unwrap();
    fails(
        d,
        &["simulate", "r.json", "-n", "5", "--out", "r-link.csv"],
        2,
        &["--out", "r-link.csv", "scene r.json"],
    );
    assert_eq!(std::fs::read(d.join("r.json")).unwrap(), before);
}

#[test]
fn two_outputs_on_one_file_are_refused() {
    let dir = rigid_dir();
    let d = dir.path();
    fails(
        d,
        &[
            "discover",
            "-t",
            "r.csv",
            "--dt",
            "0.01",
            "--total-mass",
            "1",
            "--out",
            "f.json",
            "--scores",
            "./f.json",
        ],
        2,
        &["--scores", "--out", "one would overwrite the other"],
    );
    let thesis = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/fixtures/thesis/exemple");
    let thesis = thesis.to_str().unwrap();
    fails(
        d,
        &["import", thesis, "--out", "t.tra", "--trajectory", "t.tra"],
        2,
        &["--trajectory", "--out"],
    );
    assert!(!d.join("f.json").exists() && !d.join("t.tra").exists());
}

#[test]
fn import_never_writes_onto_the_thesis_files() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/fixtures/thesis");
    for e in std::fs::read_dir(&fixtures).unwrap() {
        let e = e.unwrap();
        if e.file_type().unwrap().is_file() {
            std::fs::copy(e.path(), d.join(e.file_name())).unwrap();
        }
    }
    let tra = std::fs::read(d.join("exemple.tra")).unwrap();
    fails(
        d,
        &["import", "exemple", "--trajectory", "exemple.tra"],
        2,
        &["--trajectory", "exemple.tra", "same file"],
    );
    fails(
        d,
        &["import", "exemple.mas", "--out", "exemple.cat"],
        2,
        &["--out", "exemple.cat"],
    );
    assert_eq!(std::fs::read(d.join("exemple.tra")).unwrap(), tra);
}

#[test]
fn identify_outputs_off_its_inputs_and_each_other() {
    let dir = rigid_dir();
    let d = dir.path();
    let before = std::fs::read(d.join("r.csv")).unwrap();
    fn run<'a>(extra: &[&'a str]) -> Vec<&'a str> {
        let mut args = vec!["identify", "u.json", "-t", "r.csv", "-g", "3"];
        args.extend(extra);
        args
    }
    for (extra, says) in [
        (&["--out", "r.csv"][..], &["--out", "--trajectory"][..]),
        (&["--log", "u.json"], &["--log", "scene"]),
        (
            &["--checkpoint", "r.csv"],
            &["--checkpoint", "--trajectory"],
        ),
        (
            &["--truth", "r.json", "--out", "r.json"],
            &["--out", "--truth"],
        ),
        (
            &["--checkpoint", "c.json", "--out", "c.json"],
            &["--out", "--checkpoint"],
        ),
        (&["--log", "l.csv", "--out", "l.csv"], &["--log", "--out"]),
        // The checkpoint's history file beside it is an output too.
        (
            &["--checkpoint", "c.json", "--log", "c.json.history"],
            &["--log", "--checkpoint's history"],
        ),
        (
            &["--checkpoint", "c.json", "--out", "c.json.history"],
            &["--out", "--checkpoint's history"],
        ),
        (
            &["--resume", "c.json", "--out", "c.json"],
            &["--out", "--resume"],
        ),
    ] {
        fails(d, &run(extra), 2, says);
    }
    assert_eq!(std::fs::read(d.join("r.csv")).unwrap(), before);
    // Resuming from the checkpoint it goes on writing is the documented use: allowed.
    let args = run(&["--strategy", "cmaes", "--checkpoint", "c.json", "-q"]);
    assert!(cordis(d, &args).status.success());
    let args = run(&[
        "--strategy",
        "cmaes",
        "--resume",
        "c.json",
        "--checkpoint",
        "c.json",
        "-q",
    ]);
    let out = cordis(d, &args);
    assert!(out.status.success(), "{}", stderr(&out));
}

#[test]
fn an_unwritable_output_fails_before_the_run() {
    let dir = rigid_dir();
    let d = dir.path();
    // A directory that does not exist, a file in the place of a directory, a directory in the
    // place of the file: exit 1 (a file that cannot be written), naming the option and path.
    std::fs::create_dir(d.join("adir")).unwrap();
    for (args, says) in [
        (
            &["example", "rigid", "--out", "nodir/x.json"][..],
            &["nodir/x.json", "--out"][..],
        ),
        (
            &["simulate", "r.json", "-n", "5", "--out", "r.json/x.csv"],
            &["r.json/x.csv", "--out"],
        ),
        (
            &["render", "r.json", "-t", "r.csv", "--html", "adir"],
            &["adir", "--html", "directory"],
        ),
        // identify finds it before generation 0, not after the whole run.
        (
            &["identify", "u.json", "-t", "r.csv", "--out", "nodir/i.json"],
            &["nodir/i.json", "--out"],
        ),
    ] {
        fails(d, args, 1, says);
    }
    no_temporaries(d);
}

#[test]
fn a_failed_final_write_names_the_file_and_exits_1() {
    if !Path::new("/dev/full").exists() {
        return; // Linux only: a device on which every write fails (ENOSPC)
    }
    let dir = rigid_dir();
    let d = dir.path();
    std::os::unix::fs::symlink("/dev/full", d.join("full.csv")).unwrap();
    std::os::unix::fs::symlink("/dev/full", d.join("full.json")).unwrap();
    fails(
        d,
        &["simulate", "r.json", "-n", "5", "--out", "full.csv"],
        1,
        &["full.csv", "No space left"],
    );
    fails(
        d,
        &["example", "rigid", "--out", "full.json"],
        1,
        &["full.json", "No space left"],
    );
    no_temporaries(d);
}

#[test]
fn stale_temporaries_of_a_killed_writer_are_removed_by_the_next_write() {
    let dir = rigid_dir();
    let d = dir.path();
    // No process has a pid above pid_max: the writer of these temporaries is gone.
    let pid_max: u64 = std::fs::read_to_string("/proc/sys/kernel/pid_max")
        .map(|s| s.trim().parse().unwrap())
        .unwrap_or(4_194_304);
    let dead = pid_max + 1;
    let stale = [
        format!(".r.csv.{dead}.0.tmp"),
        format!(".r.csv.{dead}.probe.tmp"),
    ];
    // A live writer's temporary (this test's own pid) and unrelated files stay.
    let live = format!(".r.csv.{}.3.tmp", std::process::id());
    let other = [
        format!(".q.csv.{dead}.0.tmp"),
        format!(".r.csv.{dead}.x.tmp"),
    ];
    for n in stale.iter().chain([&live]).chain(&other) {
        std::fs::write(d.join(n), "partial").unwrap();
    }
    let out = cordis(d, &["simulate", "r.json", "-n", "5", "--out", "r.csv"]);
    assert!(out.status.success(), "{}", stderr(&out));
    for n in &stale {
        assert!(!d.join(n).exists(), "{n} left");
    }
    for n in [&live].into_iter().chain(&other) {
        assert!(d.join(n).exists(), "{n} removed");
    }
}

/// Issue 17: an identification whose `--log`, `--out` or `--checkpoint` write failed (a full disk)
/// lost its result — no table, no summary line — and a failing `--log` exited 2 naming no
/// file. Now the summary line is printed first, then the error names the file, exit 1.
#[test]
fn identify_prints_its_result_before_a_failed_log_or_out_write() {
    if !Path::new("/dev/full").exists() {
        return; // Linux only
    }
    let dir = rigid_dir();
    let d = dir.path();
    std::os::unix::fs::symlink("/dev/full", d.join("full.csv")).unwrap();
    std::os::unix::fs::symlink("/dev/full", d.join("full.json")).unwrap();
    let run = [
        "identify",
        "u.json",
        "-t",
        "r.csv",
        "--strategy",
        "thesis",
        "-g",
        "5",
    ];
    for extra in [
        &["--log", "full.csv"][..],
        &["--out", "full.json"],
        // A checkpoint that cannot be written lost the result too (exit 1, nothing printed).
        &["--checkpoint", "full.json"],
    ] {
        let mut args = run.to_vec();
        args.extend_from_slice(extra);
        args.extend(["--json", "-q"]);
        let out = cordis(d, &args);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(1), "{extra:?}: {err}");
        let stdout = String::from_utf8_lossy(&out.stdout);
        let lines: Vec<&str> = stdout.lines().collect();
        assert_eq!(lines.len(), 2, "{stdout}");
        let summary: serde_json::Value = serde_json::from_str(lines[0]).unwrap();
        assert_eq!(summary["generations"], 5, "{stdout}");
        assert!(summary["cost"].is_number());
        assert!(lines[1].contains(extra[1]) && lines[1].contains("No space left"));
        assert!(
            err.contains(extra[1]) && err.contains("No space left"),
            "{err}"
        );
    }
}

/// Issue 17: the log went through an 8 KB buffer, so a killed run left a torn last row. Each
/// row is now one write of the whole line: after kill -9 every line is complete. The rows
/// stream to a temporary beside the log, so the kill leaves the previous log as it was (it was
/// truncated when the run started).
#[test]
fn a_killed_identification_leaves_only_whole_log_rows_and_the_old_log() {
    let dir = rigid_dir();
    let d = dir.path();
    std::fs::write(d.join("l.csv"), "the last good run's log\n").unwrap();
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_cordis"))
        .current_dir(d)
        .args([
            "identify",
            "u.json",
            "-t",
            "r.csv",
            "--strategy",
            "thesis",
            "-g",
            "100000000",
        ])
        .args([
            "-p",
            "4",
            "--threads",
            "1",
            "--log",
            "l.csv",
            "-q",
            "-o",
            "o.json",
        ])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    // Until the log holds a few thousand rows (several buffers' worth), then kill -9.
    let t0 = std::time::Instant::now();
    while streamed(d, "l.csv")
        .and_then(|p| std::fs::metadata(p).ok())
        .map_or(0, |m| m.len())
        < 200_000
        && t0.elapsed().as_secs() < 60
    {
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    child.kill().unwrap();
    child.wait().unwrap();
    assert_eq!(
        std::fs::read_to_string(d.join("l.csv")).unwrap(),
        "the last good run's log\n"
    );
    let text = std::fs::read_to_string(streamed(d, "l.csv").expect("the streamed rows")).unwrap();
    assert!(text.len() >= 200_000, "{} bytes", text.len());
    assert!(
        text.ends_with('\n'),
        "a torn last row: {:?}",
        &text[text.len() - 80..]
    );
    let fields = |l: &str| l.split(',').count();
    let mut lines = text.lines();
    let header = fields(lines.next().unwrap());
    assert!(lines.all(|l| fields(l) == header));
}

/// A run that fails after its log was opened (a checkpoint that cannot resume) truncated an
/// existing `--log`: the old log is kept, and a run with a result replaces it whole, leaving
/// no temporary behind.
#[test]
fn a_failed_identification_keeps_the_old_log() {
    let dir = rigid_dir();
    let d = dir.path();
    std::fs::write(d.join("l.csv"), "the last good run's log\n").unwrap();
    std::fs::write(d.join("cp.json"), "{}").unwrap();
    let run = [
        "identify", "u.json", "-t", "r.csv", "-g", "3", "--log", "l.csv", "-q",
    ];
    let out = cordis(d, &[&run[..], &["--resume", "cp.json"]].concat());
    assert_ne!(out.status.code(), Some(0), "{}", stderr(&out));
    assert_eq!(
        std::fs::read_to_string(d.join("l.csv")).unwrap(),
        "the last good run's log\n"
    );
    let out = cordis(d, &run);
    assert!(out.status.success(), "{}", stderr(&out));
    let log = std::fs::read_to_string(d.join("l.csv")).unwrap();
    assert!(log.starts_with("generation,"), "{log}");
    let names: Vec<String> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".tmp"))
        .collect();
    assert!(names.is_empty(), "{names:?}");
}

/// Issue 17: `--checkpoint`'s help said "every 50 generations", but periodic checkpoints are
/// also at least a second apart and the history goes to FILE.history.
#[test]
fn checkpoint_help_says_when_it_writes() {
    let out = cordis(Path::new("."), &["identify", "--help"]);
    let help = String::from_utf8_lossy(&out.stdout).replace('\n', " ");
    let help = help.split_whitespace().collect::<Vec<_>>().join(" ");
    assert!(
        help.contains(
            "every 50 generations but at most once a second, and at the end however the run stops"
        ),
        "{help}"
    );
    assert!(help.contains("FILE.history"), "{help}");
}
