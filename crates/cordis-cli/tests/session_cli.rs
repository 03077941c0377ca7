//! `cordis identify` through the one session: honest failures (exit 1, no `--out`), refused
//! options and resumes, threads capped — each as the user meets it.

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

/// `truth.json`, `u.json` (rigid with unknowns) and `t.csv` (60 frames) in `d`.
fn rigid(d: &Path) {
    for args in [
        &["example", "rigid", "--out", "truth.json"][..],
        &["example", "rigid", "--unknowns", "--out", "u.json"],
        &["simulate", "truth.json", "--frames", "60", "--out", "t.csv"],
    ] {
        assert!(cordis(d, args).status.success(), "{args:?}");
    }
}

#[test]
fn a_failed_exact_solve_exits_1_and_writes_no_scene() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    rigid(d);
    // The same motion at 1e300 m: the normal equations overflow, the solve cannot succeed.
    let text = std::fs::read_to_string(d.join("t.csv")).unwrap();
    let mut big = String::new();
    for (k, line) in text.lines().enumerate() {
        if k == 0 {
            big.push_str(line);
        } else {
            let f: Vec<&str> = line.split(',').collect();
            let scaled: Vec<String> = f[2..]
                .iter()
                .map(|x| format!("{:e}", x.parse::<f64>().unwrap() * 1e300))
                .collect();
            big.push_str(&format!("{},{},{}", f[0], f[1], scaled.join(",")));
        }
        big.push('\n');
    }
    std::fs::write(d.join("big.csv"), big).unwrap();
    let out = cordis(
        d,
        &[
            "identify",
            "u.json",
            "-t",
            "big.csv",
            "--strategy",
            "least-squares",
            "--out",
            "out.json",
        ],
    );
    assert_eq!(out.status.code(), Some(1), "{}", stderr(&out));
    assert!(stderr(&out).contains("least-squares"), "{}", stderr(&out));
    assert!(!d.join("out.json").exists(), "a failed solve wrote a scene");
}

#[test]
fn a_resume_of_another_request_is_refused_naming_what_differs() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    rigid(d);
    let base = [
        "identify",
        "u.json",
        "-t",
        "t.csv",
        "--strategy",
        "thesis",
        "-p",
        "10",
    ];
    let mut first = base.to_vec();
    first.extend(["--checkpoint", "cp.json", "-g", "3"]);
    assert!(cordis(d, &first).status.success());
    // The same checkpoint resumes the same request …
    let mut same = base.to_vec();
    same.extend(["--resume", "cp.json", "-g", "5"]);
    let out = cordis(d, &same);
    assert!(out.status.success(), "{}", stderr(&out));
    // … not one on noisier data or another cost.
    for (extra, named) in [
        (&["--noise", "1e-4"][..], "noise"),
        (&["--cost", "horizon:3"], "cost"),
    ] {
        let mut other = same.clone();
        other.extend(extra);
        let out = cordis(d, &other);
        assert_eq!(out.status.code(), Some(2), "{extra:?}: {}", stderr(&out));
        let err = stderr(&out);
        assert!(
            err.contains("cp.json") && err.contains(named),
            "{extra:?}: {err}"
        );
    }
}

#[test]
fn threads_beyond_the_machine_are_capped_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    rigid(d);
    let out = cordis(
        d,
        &[
            "identify",
            "u.json",
            "-t",
            "t.csv",
            "--threads",
            "100000",
            "-q",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let err = stderr(&out);
    assert!(err.contains("warning: --threads 100000: capped"), "{err}");
}

#[test]
fn out_of_range_options_are_one_line_naming_them_not_a_panic() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    rigid(d);
    std::fs::write(d.join("huge.gene"), "population=100000000000\n").unwrap();
    for (args, named) in [
        (&["--time-limit", "inf"][..], "--time-limit"),
        (&["--time-limit", "NaN"], "--time-limit"),
        (&["--time-limit", "1e308"], "--time-limit"),
        (&["--noise", "inf"], "--noise"),
        (&["--noise", "1e308"], "--noise"),
        // Noise ten times the scene's size is a wrong unit: at 1e300 the solver met
        // overflowing numbers ("the least-squares system is not finite").
        (
            &["--noise", "1e300"],
            "--noise: 1e300 m is more than 10 times the size of the scene and its motion (",
        ),
        // Squared, 1e150 overflowed and changed the estimate: refused by index.
        (
            &["--weights", "1,1,1e150"],
            "--weights[2]: 1e150 is outside [1e-30, 1e30]: weights are relative (1/σ)",
        ),
        (
            &["--time-limit=-1"],
            "--time-limit: must be seconds in [0, ",
        ),
        (
            &["--target-cost", "inf"],
            "--target-cost: must be a finite number, got inf",
        ),
        (
            &["--population", "100000000000", "--strategy", "thesis"],
            "--population",
        ),
        (&["--total-mass=-1"], "--total-mass"),
        // Issue 17's low cases: NaN noise added nothing, NaN dt was accepted, a NaN target
        // ignored, a population of 0 ran.
        (&["--noise", "NaN"], "--noise: must be a standard deviation"),
        (&["--dt", "NaN"], "--dt: must be a finite number above 0"),
        (
            &["--target-cost", "NaN"],
            "--target-cost: must be a finite number",
        ),
        (
            &["--population", "0"],
            "--population: must be 2 or more, got 0",
        ),
        // Issue 17: more migrants than an island holds was accepted (and silently cut);
        // 10^7 islands were refused under --population with the population's own count.
        (
            &["--islands", "2", "--migrants", "7", "--population", "6"],
            "--migrants: 7 is more than an island's population of 6",
        ),
        (
            &["--islands", "10000000"],
            "--islands: 10000000 islands of 100 individuals need about",
        ),
        (&["--islands", "1"], "--islands: must be 2 or more islands"),
        (
            &["--islands", "2", "--migrate-every", "0"],
            "--migrate-every: must be 1 or more",
        ),
        // A Param.gene population beyond memory: the same check, with the estimate.
        (
            &["--param-gene", "huge.gene"],
            "--population: 100000000000 individuals need about",
        ),
    ] {
        let mut all = vec!["identify", "u.json", "-t", "t.csv"];
        all.extend(args);
        let out = cordis(d, &all);
        let err = stderr(&out);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(
            err.starts_with("error: ") && err.contains(named),
            "{args:?}: {err}"
        );
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert_eq!(err.lines().count(), 1, "{args:?}: {err}");
    }
}

#[test]
fn unknown_masses_without_a_total_are_refused_saying_to_pass_it() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    rigid(d);
    let mut scene: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("u.json")).unwrap()).unwrap();
    for p in scene["particles"].as_array_mut().unwrap() {
        if p["fixed"] != true {
            p["mass"] = serde_json::json!({"min": 0.3, "max": 3.0});
        }
    }
    std::fs::write(d.join("m.json"), scene.to_string()).unwrap();
    for strategy in ["auto", "thesis"] {
        let out = cordis(
            d,
            &[
                "identify",
                "m.json",
                "-t",
                "t.csv",
                "--strategy",
                strategy,
                "-g",
                "2",
            ],
        );
        assert_eq!(out.status.code(), Some(2), "{strategy}: {}", stderr(&out));
        assert!(
            stderr(&out).contains("--total-mass"),
            "{strategy}: {}",
            stderr(&out)
        );
    }
}

#[test]
fn cmaes_counts_its_evaluation_time_and_help_names_no_issue() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    rigid(d);
    let out = cordis(
        d,
        &[
            "identify",
            "u.json",
            "-t",
            "t.csv",
            "--strategy",
            "cmaes",
            "-g",
            "20",
            "-q",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let text = String::from_utf8_lossy(&out.stdout);
    let s: serde_json::Value = serde_json::from_str(text.lines().last().unwrap()).unwrap();
    let (eval, total) = (
        s["eval_seconds"].as_f64().unwrap(),
        s["seconds"].as_f64().unwrap(),
    );
    assert!(eval > 0.0 && eval <= total, "{s}");
    for args in [&["--help"][..], &["identify", "--help"]] {
        let help = String::from_utf8_lossy(&cordis(d, args).stdout).into_owned();
        assert!(!help.contains("(issue"), "{help}");
    }
}
