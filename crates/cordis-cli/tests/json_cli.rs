//! `--json` and `--quiet` on every subcommand, and the exit codes (docs/cli.md): with `--json`
//! stdout holds only JSON objects, one per line; `--quiet` leaves stderr empty on success; an
//! error is one stderr line, a `{"error", "exit_code"}` object with `--json`, and exit code
//! 1 (run failed: I/O, divergence) or 2 (bad input or usage).

mod common;

use std::path::Path;
use std::process::{Command, Output};

use common::cordis;
use cordis_core::examples::random_network;
use cordis_core::Scene;
use serde_json::Value;

/// Every stdout line of a `--json` run, each parsed as a JSON object (fails otherwise).
fn json_lines(out: &Output) -> Vec<Value> {
    let text = String::from_utf8(out.stdout.clone()).expect("UTF-8 stdout");
    text.lines()
        .map(|l| {
            let v: Value = serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}: {l}"));
            assert!(v.is_object(), "not an object: {l}");
            v
        })
        .collect()
}

/// A successful `--json --quiet` run: one JSON object on stdout, nothing on stderr.
fn one_object(dir: &Path, args: &[&str]) -> Value {
    let mut all = args.to_vec();
    all.extend(["--json", "--quiet"]);
    let out = cordis(dir, &all);
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        out.stderr.is_empty(),
        "{args:?} --quiet wrote on stderr: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let mut lines = json_lines(&out);
    assert_eq!(lines.len(), 1, "{args:?}: {lines:?}");
    lines.pop().unwrap()
}

#[test]
fn every_subcommand_prints_one_json_object_per_line() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();

    // example: to a file (summary), or embedded in the summary without --out.
    let v = one_object(d, &["example", "rigid", "--out", "rigid.json"]);
    assert_eq!(v["out"], "rigid.json");
    assert_eq!(v["particles"], 15);
    let truth = Scene::from_json_path(d.join("rigid.json")).unwrap();
    let v = one_object(d, &["example", "rigid"]);
    assert_eq!(Scene::from_json_value(&v["scene"]).unwrap(), truth);
    assert_eq!(v["out"], Value::Null);
    let v = one_object(d, &["example", "rigid", "--unknowns", "--out", "u.json"]);
    assert_eq!(v["unknowns"], true);

    let v = one_object(
        d,
        &["simulate", "rigid.json", "--frames", "60", "--out", "r.csv"],
    );
    assert_eq!(
        (v["frames"].as_u64(), v["particles"].as_u64()),
        (Some(60), Some(15))
    );
    let v = one_object(d, &["cost", "rigid.json", "--trajectory", "r.csv"]);
    assert!(v["total"].as_f64().unwrap() < 1e-20, "{v}");
    assert_eq!(v["per_particle"].as_array().unwrap().len(), 15);
    let v = one_object(d, &["check", "rigid.json"]);
    assert_eq!(v["stable"], true);
    let v = one_object(
        d,
        &[
            "identify",
            "u.json",
            "--trajectory",
            "r.csv",
            "--truth",
            "rigid.json",
        ],
    );
    assert!(v["param_error_pct"].as_f64().unwrap() < 1e-6, "{v}");
    assert_eq!(v["stopped_by"], "converged");
    let v = one_object(
        d,
        &[
            "render",
            "rigid.json",
            "--trajectory",
            "r.csv",
            "--html",
            "v.html",
        ],
    );
    assert_eq!(
        (v["frames"].as_u64(), v["motions"].as_u64()),
        (Some(60), Some(1))
    );
    assert!(v["bytes"].as_u64().unwrap() > 1000);
    let v = one_object(
        d,
        &[
            "report",
            "rigid.json",
            "-t",
            "r.csv",
            "--html",
            "report.html",
        ],
    );
    assert_eq!(
        (v["frames"].as_u64(), v["particles"].as_u64()),
        (Some(60), Some(15))
    );
    let v = one_object(
        d,
        &[
            "export",
            "rigid.json",
            "--mjcf",
            "r.xml",
            "--frames",
            "5",
            "--out",
            "x.npy",
        ],
    );
    assert_eq!(
        (v["mjcf"].as_str(), v["frames"].as_u64()),
        (Some("r.xml"), Some(5))
    );

    // import: the thesis' Annexe 1 files.
    let thesis = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/fixtures/thesis/exemple");
    let v = one_object(
        d,
        &[
            "import",
            thesis.to_str().unwrap(),
            "--out",
            "tri.json",
            "--trajectory",
            "tri.csv",
        ],
    );
    let imported = Scene::from_json_path(d.join("tri.json")).unwrap();
    assert_eq!(v["particles"], imported.num_particles());
    assert!(d.join("tri.csv").exists());

    // discover: a generated network's motion; the scene embedded without --out.
    let net = random_network(4, 8, 2);
    let traj = net.simulate(200).unwrap();
    cordis_core::io::write_trajectory(&d.join("net.csv"), &traj).unwrap();
    let total: f64 = net
        .particles
        .iter()
        .filter(|p| !p.fixed)
        .map(|p| p.mass.value())
        .sum();
    let (dt, total) = (net.dt.to_string(), total.to_string());
    let v = one_object(
        d,
        &[
            "discover",
            "--trajectory",
            "net.csv",
            "--dt",
            &dt,
            "--total-mass",
            &total,
        ],
    );
    let found = Scene::from_json_value(&v["scene"]).unwrap();
    assert_eq!(found.links.len(), net.links.len());
    assert_eq!(v["num_links"], net.links.len());
}

#[test]
fn without_json_the_report_is_human_text_and_quiet_silences_it() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A scene to stdout stays the pretty JSON file it always was.
    let out = cordis(d, &["example", "rigid"]);
    assert!(out.status.success());
    let text = String::from_utf8(out.stdout).unwrap();
    assert!(text.lines().count() > 10, "pretty-printed");
    std::fs::write(d.join("rigid.json"), &text).unwrap();

    let out = cordis(
        d,
        &["simulate", "rigid.json", "--frames", "20", "--out", "r.csv"],
    );
    let err = String::from_utf8(out.stderr).unwrap();
    assert!(err.starts_with("simulated 20 frames"), "{err}");
    let out = cordis(d, &["simulate", "rigid.json", "--frames", "20", "-q"]);
    assert!(out.stderr.is_empty());
    assert_eq!(json_lines(&out).len(), 1);
    // --quiet is global: accepted before the subcommand too.
    let out = cordis(d, &["-q", "example", "rigid", "--out", "again.json"]);
    assert!(out.status.success() && out.stderr.is_empty() && out.stdout.is_empty());
}

#[test]
fn errors_are_one_line_a_json_object_and_a_shell_exit_code() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    assert!(cordis(d, &["example", "rigid", "--out", "rigid.json"])
        .status
        .success());
    let mut bad: Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("rigid.json")).unwrap()).unwrap();
    bad["links"][3]["particles"][1] = 40.into();
    std::fs::write(d.join("bad.json"), bad.to_string()).unwrap();

    for (args, code, words) in [
        (
            &["simulate", "missing.json", "--frames", "3"][..],
            1,
            "missing.json",
        ),
        (
            &["simulate", "bad.json", "--frames", "3"][..],
            2,
            "links[3].particles[1]",
        ),
        (&["example", "nope"][..], 2, "example `nope` does not exist"),
        (
            &["cost", "rigid.json", "--trajectory", "rigid.json"][..],
            2,
            "rigid.json",
        ),
    ] {
        let mut all = args.to_vec();
        all.push("--json");
        let out = cordis(d, &all);
        assert_eq!(out.status.code(), Some(code), "{args:?}");
        let err = String::from_utf8(out.stderr.clone()).unwrap();
        assert_eq!(err.lines().count(), 1, "{err}");
        assert!(err.starts_with("error: ") && err.contains(words), "{err}");
        let lines = json_lines(&out);
        assert_eq!(lines.len(), 1, "{args:?}");
        assert_eq!(lines[0]["exit_code"], code);
        assert!(lines[0]["error"].as_str().unwrap().contains(words));
    }
    // Usage errors come from the argument parser: exit 2.
    assert_eq!(
        cordis(d, &["simulate", "rigid.json"]).status.code(),
        Some(2)
    );
    assert_eq!(cordis(d, &["no-such-command"]).status.code(), Some(2));
    assert_eq!(cordis(d, &["--help"]).status.code(), Some(0));
}

/// Ctrl-C stops `identify` after it writes its best result: the summary says so and the exit
/// code is 130 (128 + SIGINT), so `cordis identify … && next` does not go on.
#[cfg(unix)]
#[test]
fn an_interrupted_identification_exits_130_after_writing_its_result() {
    use std::process::Stdio;
    use std::time::{Duration, Instant};

    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for args in [
        &["example", "rigid", "--out", "rigid.json"][..],
        &[
            "simulate",
            "rigid.json",
            "--frames",
            "100",
            "--out",
            "r.csv",
        ][..],
        &["example", "rigid", "--unknowns", "--out", "u.json"][..],
    ] {
        assert!(cordis(d, args).status.success());
    }
    // The evolution strategy with a long time limit: only the interrupt ends it early.
    let child = Command::new(env!("CARGO_BIN_EXE_cordis"))
        .current_dir(d)
        .args([
            "identify",
            "u.json",
            "--trajectory",
            "r.csv",
            "--strategy",
            "thesis",
        ])
        .args([
            "--generations",
            "100000000",
            "--time-limit",
            "120",
            "--out",
            "best.json",
        ])
        .args(["--log", "log.csv", "--json", "-q"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // Wait until it has run a few generations (the log has rows), then send SIGINT.
    let start = Instant::now();
    let rows = || {
        common::streamed(d, "log.csv")
            .and_then(|p| std::fs::read_to_string(p).ok())
            .map_or(0, |t| t.lines().count())
    };
    while rows() < 3 {
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "identify never started"
        );
        std::thread::sleep(Duration::from_millis(50));
    }
    let kill = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let out = child.wait_with_output().unwrap();
    assert_eq!(
        out.status.code(),
        Some(130),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let lines = json_lines(&out);
    assert_eq!(lines[0]["stopped_by"], "interrupted", "{lines:?}");
    assert_eq!(lines.last().unwrap()["exit_code"], 130);
    Scene::from_json_path(d.join("best.json")).unwrap();
    // The interrupted run's log is put in place.
    let log = std::fs::read_to_string(d.join("log.csv")).unwrap();
    assert!(log.lines().count() >= 3, "{log}");
}
