//! Issue 17: one exit-code table for every command (docs/cli.md): 0 success, 1 a file that
//! cannot be read or written (missing, a directory, beyond the size limit) or a run that
//! failed, 2 input that reads but is wrong, or usage. A missing `--resume` and `--masses` used
//! to exit 2 while a missing trajectory or `--truth` exited 1.

mod common;

use common::{cordis, fails, rigid_dir, stderr};

#[test]
fn a_missing_input_file_exits_1_naming_it_for_every_command() {
    let dir = rigid_dir();
    let d = dir.path();
    let id = |extra: &[&'static str]| {
        let mut a = vec![
            "identify", "u.json", "-t", "r.csv", "-g", "2", "-o", "o.json",
        ];
        a.extend_from_slice(extra);
        a
    };
    let cases: Vec<Vec<&str>> = vec![
        vec!["simulate", "nope.json", "--frames", "3", "-o", "x.csv"],
        vec!["check", "nope.json"],
        vec!["cost", "nope.json", "-t", "r.csv"],
        vec!["cost", "r.json", "-t", "nope.csv"],
        vec!["render", "nope.json", "-t", "r.csv", "--html", "x.html"],
        vec!["render", "r.json", "-t", "nope.csv", "--html", "x.html"],
        vec![
            "discover",
            "-t",
            "nope.csv",
            "--dt",
            "0.01",
            "--total-mass",
            "1",
        ],
        vec![
            "discover", "-t", "r.csv", "--dt", "0.01", "--masses", "nope.txt",
        ],
        vec!["import", "nope", "--dt", "0.01", "-o", "x.json"],
        vec!["export", "nope.json", "--mjcf", "o.json"],
        vec!["report", "nope.json", "-t", "r.csv", "--html", "o.json"],
        vec![
            "report", "r.json", "-t", "r.csv", "--log", "nope.csv", "--html", "o.json",
        ],
        vec!["export", "r.json", "-t", "nope.csv", "--gltf", "o.json"],
        vec!["identify", "nope.json", "-t", "r.csv", "-o", "o.json"],
        vec!["identify", "u.json", "-t", "nope.csv", "-o", "o.json"],
        id(&["--truth", "nope.json"]),
        id(&["--resume", "nope.json"]),
        id(&["--param-gene", "nope.gene"]),
        id(&["--lock", "nope.lock"]),
    ];
    for args in &cases {
        let missing = args.iter().find(|a| a.starts_with("nope")).unwrap();
        fails(d, args, 1, &[missing, "No such file or directory"]);
        assert!(!d.join("o.json").exists() && !d.join("x.csv").exists());
    }
}

#[test]
fn an_unbounded_input_exits_1_with_the_limit_and_bad_content_exits_2() {
    let dir = rigid_dir();
    let d = dir.path();
    std::os::unix::fs::symlink("/dev/zero", d.join("zero.csv")).unwrap();
    std::os::unix::fs::symlink("/dev/zero", d.join("zero.json")).unwrap();
    for args in [
        &[
            "discover",
            "-t",
            "zero.csv",
            "--dt",
            "0.01",
            "--total-mass",
            "1",
        ][..],
        &["check", "zero.json"],
        &["identify", "u.json", "-t", "zero.csv", "-o", "o.json"],
    ] {
        fails(d, args, 1, &["zero.", "256 MiB"]);
    }
    // Read, but wrong: 2, whichever input it is.
    std::fs::write(d.join("bad.json"), "{\"dt\": 0.01, \"dt\": 0.02}").unwrap();
    std::fs::write(d.join("bad.csv"), "frame,particle,x,y,z\n0,0,1,2\n").unwrap();
    // Reads, but holds two frames: too few for a motion cost, named by its file.
    std::fs::write(
        d.join("short.csv"),
        "frame,particle,x,y,z\n0,0,1,2,3\n1,0,1,2,3\n",
    )
    .unwrap();
    std::fs::write(d.join("cp.json"), "garbage").unwrap();
    std::fs::write(d.join("p.gene"), "population = -3\n").unwrap();
    // Param.gene's `damping` is read by no strategy: any value but the thesis' 0 is refused.
    std::fs::write(d.join("d.gene"), "pcross=15\ndamping = 0.2\n").unwrap();
    for (args, says) in [
        (&["check", "bad.json"][..], "duplicate key `dt`"),
        (&["cost", "r.json", "-t", "bad.csv"], "bad.csv"),
        (
            &["cost", "r.json", "-t", "short.csv"],
            "short.csv: has 2 frames, the short cost needs at least 3",
        ),
        (
            &["export", "r.json", "-t", "bad.csv", "--gltf", "o.json"],
            "bad.csv",
        ),
        (
            &["report", "r.json", "-t", "bad.csv", "--html", "o.json"],
            "bad.csv",
        ),
        (
            &[
                "report", "r.json", "-t", "r.csv", "--log", "bad.csv", "--html", "o.json",
            ],
            "bad.csv:1: the header has no `generation` column",
        ),
        (
            &["export", "bad.json", "--mjcf", "o.json"],
            "duplicate key `dt`",
        ),
        (
            &[
                "identify", "u.json", "-t", "r.csv", "--truth", "bad.json", "-o", "o.json",
            ],
            "bad.json",
        ),
        (
            &[
                "identify", "u.json", "-t", "r.csv", "--resume", "cp.json", "-o", "o.json",
            ],
            "cp.json: not a checkpoint",
        ),
        (
            &[
                "identify", "u.json", "-t", "r.csv", "--truth", "u.json", "-o", "o.json",
            ],
            "--truth: must be the scene with every parameter known",
        ),
        (
            &[
                "identify",
                "u.json",
                "-t",
                "r.csv",
                "--param-gene",
                "p.gene",
                "-o",
                "o.json",
            ],
            "p.gene",
        ),
        (
            &[
                "identify",
                "u.json",
                "-t",
                "r.csv",
                "--param-gene",
                "d.gene",
                "-o",
                "o.json",
            ],
            "d.gene:2: damping=0.2: not supported",
        ),
        (
            &[
                "identify",
                "u.json",
                "-t",
                "r.csv",
                "--crossover",
                "uniform",
                "-o",
                "o.json",
            ],
            "--crossover: unknown crossover `uniform` (expected one of: mean, n-parent, mn-parent)",
        ),
        (&["simulate", "r.json", "--frames", "x"], "--frames"),
    ] {
        fails(d, args, 2, &[says]);
    }
    let ok = cordis(d, &["check", "r.json"]);
    assert_eq!(ok.status.code(), Some(0), "{}", stderr(&ok));
}

/// A missing required argument is named on the one error line (clap lists them on the lines
/// under its first, which the one-line error used to drop: "…were not provided:" and nothing).
#[test]
fn a_missing_required_argument_is_named() {
    let dir = rigid_dir();
    let d = dir.path();
    fails(
        d,
        &["identify", "u.json"],
        2,
        &["not provided: --trajectory"],
    );
    fails(
        d,
        &["simulate"],
        2,
        &["not provided: --frames <FRAMES>, <SCENE>"],
    );
}

/// A scene given where a run's summary or log is expected was read as a summary without
/// intervals (exit 0): each names the kind it expected and the kind it got.
#[test]
fn report_refuses_a_scene_given_as_its_summary_or_log() {
    let dir = rigid_dir();
    let d = dir.path();
    let page = ["report", "r.json", "-t", "r.csv", "--html", "o.html"];
    fails(
        d,
        &[&page[..], &["--summary", "r.json"]].concat(),
        2,
        &[
            "r.json: expected a run's summary (the JSON line of `cordis identify --json`), got a scene",
        ],
    );
    fails(
        d,
        &[&page[..], &["--log", "u.json"]].concat(),
        2,
        &["u.json: expected a convergence log (`cordis identify --log`, .csv or .jsonl), got a scene"],
    );
    // A log's row given as the summary.
    std::fs::write(
        d.join("log.jsonl"),
        "{\"generation\": 0, \"best_cost\": 1.0}\n",
    )
    .unwrap();
    fails(
        d,
        &[&page[..], &["--summary", "log.jsonl"]].concat(),
        2,
        &[
            "log.jsonl: expected a run's summary",
            "got a row of a convergence log (--log)",
        ],
    );
    assert!(!d.join("o.html").exists());
}
