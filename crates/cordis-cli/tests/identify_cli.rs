//! `cordis identify` end to end: example → simulate → identify, the JSON summary, `--lock`.

use std::process::{Command, Output};

fn cordis(dir: &std::path::Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_cordis"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("cordis runs")
}

fn summary(out: &Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    serde_json::from_str(text.lines().last().expect("a summary line")).expect("JSON")
}

#[test]
fn identify_recovers_rigid_and_honours_lock() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    assert!(cordis(d, &["example", "rigid", "--out", "truth.json"])
        .status
        .success());
    assert!(cordis(
        d,
        &[
            "simulate",
            "truth.json",
            "--frames",
            "100",
            "--out",
            "t.csv"
        ]
    )
    .status
    .success());
    assert!(
        cordis(d, &["example", "rigid", "--unknowns", "--out", "u.json"])
            .status
            .success()
    );
    let base = [
        "identify",
        "u.json",
        "--trajectory",
        "t.csv",
        "--truth",
        "truth.json",
        "-q",
    ];
    let s = summary(&cordis(d, &base));
    assert_eq!(s["strategy"], "least-squares");
    assert!(s["param_error_pct"].as_f64().unwrap() < 1e-6, "{s}");

    // A locked unknown keeps its starting value (its box's geometric middle).
    let mut args = base.to_vec();
    args.extend(["--lock", "types.brace.stiffness", "--out", "locked.json"]);
    let s = summary(&cordis(d, &args));
    assert!(s["param_error_pct"].as_f64().unwrap() > 1e-3, "{s}");
    let unknown: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("u.json")).unwrap()).unwrap();
    let b = &unknown["types"]["brace"]["stiffness"];
    let middle = (b["min"].as_f64().unwrap() * b["max"].as_f64().unwrap()).sqrt();
    let locked: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("locked.json")).unwrap()).unwrap();
    let got = locked["types"]["brace"]["stiffness"].as_f64().unwrap();
    assert!((got - middle).abs() <= 1e-12 * middle, "{got} vs {middle}");

    let mut bad = base.to_vec();
    bad.extend(["--lock", "types.nope.stiffness"]);
    let out = cordis(d, &bad);
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("types.nope.stiffness"));
}

#[test]
fn stable_horizon_is_reported_and_checked() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let ok = |args: &[&str]| assert!(cordis(d, args).status.success(), "{args:?}");
    ok(&["example", "horse-gait", "--out", "truth.json"]);
    ok(&["simulate", "truth.json", "--frames", "53", "--out", "t.csv"]);
    // The passive model of the four leg muscles only (12 unknowns).
    ok(&[
        "example",
        "horse-gait",
        "--passive",
        "--unknowns",
        "--width",
        "10",
        "--unknown-types",
        "front_left_1-girth,front_right_1-girth,hind_left_1-belly,hind_right_1-belly",
        "--out",
        "p.json",
    ]);
    let run = |extra: &[&str]| {
        let mut args = vec![
            "identify",
            "p.json",
            "-t",
            "t.csv",
            "--strategy",
            "cmaes",
            "--max-evals",
            "400",
            "-q",
        ];
        args.extend_from_slice(extra);
        cordis(d, &args)
    };
    let s = summary(&run(&["--stable-horizon", "530"]));
    assert_eq!(s["stable_horizon"], 530);
    assert!(s["cost"].as_f64().is_some_and(f64::is_finite), "{s}");
    assert!(summary(&run(&[]))["stable_horizon"].is_null());
    for (bad, place) in [
        (["--stable-horizon", "2"], "--stable-horizon"),
        (["--stable-spread", "0.5"], "--stable-spread"),
    ] {
        let mut extra = bad.to_vec();
        if place == "--stable-spread" {
            extra.extend(["--stable-horizon", "100"]);
        }
        let out = run(&extra);
        assert!(!out.status.success());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(place), "{err}");
    }
    let out = cordis(
        d,
        &["example", "horse", "--unknowns", "--unknown-types", "nope"],
    );
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("`nope`"));
}

#[test]
fn levenberg_marquardt_identifies_the_muscle_and_refuses_other_costs() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    for args in [
        &["example", "muscle", "--out", "truth.json"][..],
        &["example", "muscle", "--unknowns", "--out", "unknown.json"],
        &[
            "simulate",
            "truth.json",
            "--frames",
            "300",
            "--out",
            "t.npy",
        ],
    ] {
        let out = cordis(d, args);
        assert!(
            out.status.success(),
            "{args:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let run = |extra: &[&str]| {
        let mut args = vec![
            "identify",
            "unknown.json",
            "-t",
            "t.npy",
            "--truth",
            "truth.json",
            "--strategy",
            "levenberg-marquardt",
        ];
        args.extend_from_slice(extra);
        cordis(d, &args)
    };
    let s = summary(&run(&[]));
    assert_eq!(s["strategy"], "levenberg-marquardt");
    assert_eq!(s["stopped_by"], "converged");
    assert!(s["param_error_pct"].as_f64().unwrap() < 0.01, "{s}");
    assert!(s["evals"].as_u64().unwrap() < 1000, "{s}");

    let out = run(&["--cost", "horizon:3"]);
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("short cost"), "{err}");
}

/// A chain of 5 beads between fixed ends `span` m apart, under gravity, damped (springs and
/// air) so that it settles; `unknown`: K and l0 of the links in boxes.
fn chain_json(span: f64, unknown: &str) -> String {
    let mut particles = vec![r#"{"mass": 1.0, "pos": [0, 0, 0], "fixed": true}"#.to_string()];
    for k in 1..6 {
        let x = span * k as f64 / 6.0;
        particles.push(format!(r#"{{"mass": 0.1, "pos": [{x}, 0, 0]}}"#));
    }
    particles.push(format!(
        r#"{{"mass": 1.0, "pos": [{span}, 0, 0], "fixed": true}}"#
    ));
    let links: Vec<String> = (0..6)
        .map(|i| format!(r#"{{"type": "link", "particles": [{i}, {}]}}"#, i + 1))
        .chain((1..6).map(|i| format!(r#"{{"type": "air", "particles": [{i}]}}"#)))
        .collect();
    format!(
        r#"{{"dt": 0.01, "gravity": [0, 0, -9.81], "particles": [{}],
 "types": {{"link": {{"kind": "spring", {unknown}}},
           "air": {{"kind": "drag", "damping": 0.3}}}},
 "links": [{}]}}"#,
        particles.join(", "),
        links.join(", ")
    )
}

/// The last frame of a CSV trajectory, renumbered as frame `as_frame`.
fn last_frame(csv: &str, as_frame: usize) -> Vec<String> {
    let rows: Vec<&str> = csv.lines().skip(1).filter(|l| !l.is_empty()).collect();
    let frame = |l: &str| {
        l.split(',')
            .next()
            .unwrap()
            .trim()
            .parse::<usize>()
            .unwrap()
    };
    let last = rows.iter().map(|l| frame(l)).max().unwrap();
    rows.iter()
        .filter(|l| frame(l) == last)
        .map(|l| format!("{as_frame}{}", &l[l.find(',').unwrap()..]))
        .collect()
}

#[test]
fn the_static_cost_identifies_a_chain_from_two_equilibrium_frames() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let known = r#""stiffness": 40.0, "rest_length": 0.2, "damping": 0.3"#;
    let free = r#""stiffness": {"min": 2, "max": 500}, "rest_length": {"min": 0.05, "max": 0.5},
                  "damping": 0.3"#;
    // Two poses at rest of one chain: its ends 1.2 m and 1.0 m apart (the fixed particles are
    // read from each frame).
    let mut rows = vec!["frame,particle,x,y,z".to_string()];
    for (f, span) in [1.2, 1.0].into_iter().enumerate() {
        std::fs::write(d.join(format!("c{f}.json")), chain_json(span, known)).unwrap();
        let out = cordis(
            d,
            &[
                "simulate",
                &format!("c{f}.json"),
                "--frames",
                "6000",
                "--out",
                &format!("c{f}.csv"),
            ],
        );
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let csv = std::fs::read_to_string(d.join(format!("c{f}.csv"))).unwrap();
        rows.extend(last_frame(&csv, f));
    }
    std::fs::write(d.join("rest.csv"), rows.join("\n") + "\n").unwrap();
    std::fs::write(d.join("u.json"), chain_json(1.2, free)).unwrap();
    let args = [
        "identify", "u.json", "-t", "rest.csv", "--truth", "c0.json", "--cost", "static", "-q",
    ];
    let s = summary(&cordis(d, &args));
    assert_eq!(s["strategy"], "levenberg-marquardt", "{s}");
    assert_eq!(s["stopped_by"], "converged", "{s}");
    assert!(s["param_error_pct"].as_f64().unwrap() < 1e-6, "{s}");
    // The short cost cannot read two poses.
    let out = cordis(d, &["identify", "u.json", "-t", "rest.csv", "-q"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("at least 3"));
    // A damping is refused by name: it acts on nothing at rest.
    let damped = r#""stiffness": 40.0, "rest_length": 0.2, "damping": {"min": 0.01, "max": 1}"#;
    std::fs::write(d.join("z.json"), chain_json(1.2, damped)).unwrap();
    let out = cordis(
        d,
        &[
            "identify", "z.json", "-t", "rest.csv", "--cost", "static", "-q",
        ],
    );
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(err.lines().count(), 1, "{err}");
    assert!(
        err.contains("types.link.damping") && err.contains("zero velocity"),
        "{err}"
    );
}

#[test]
fn self_adaptive_takes_plus_and_correlated_and_other_strategies_refuse_them() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // The falling chain: two unknowns a 15-generation run of 14 improves on (the rigid
    // example's 20 keep the initial population's best that long, whatever the options).
    let truth = chain_json(
        1.0,
        r#""stiffness": 50, "rest_length": 0.15, "damping": 0.5"#,
    );
    std::fs::write(d.join("truth.json"), truth).unwrap();
    let boxes = r#""stiffness": {"min": 5, "max": 500}, "rest_length": {"min": 0.05, "max": 0.5},
        "damping": 0.5"#;
    std::fs::write(d.join("u.json"), chain_json(1.0, boxes)).unwrap();
    let sim = ["simulate", "truth.json", "--frames", "60", "--out", "t.csv"];
    assert!(cordis(d, &sim).status.success());
    let run = |extra: &[&str]| {
        let mut args = vec![
            "identify",
            "u.json",
            "--trajectory",
            "t.csv",
            "--strategy",
            "self-adaptive",
            "--generations",
            "15",
            "--population",
            "14",
            "--seed",
            "3",
            "-q",
        ];
        args.extend_from_slice(extra);
        let s = summary(&cordis(d, &args));
        assert_eq!(s["strategy"], "self-adaptive", "{s}");
        let cost = s["cost"].as_f64().unwrap();
        assert!(cost.is_finite(), "{s}");
        cost
    };
    let comma = run(&[]);
    let plus = run(&["--plus"]);
    let correlated = run(&["--correlated"]);
    let both = run(&["--plus", "--correlated"]);
    // Each option changes the search (it is read, not ignored); a seed fixes each run.
    assert_ne!(comma, plus);
    assert_ne!(comma, correlated);
    assert_ne!(plus, both);
    assert_eq!(correlated, run(&["--correlated"]));

    for (option, strategy) in [("--correlated", "cmaes"), ("--plus", "thesis")] {
        let args = [
            "identify",
            "u.json",
            "--trajectory",
            "t.csv",
            "--strategy",
            strategy,
            option,
        ];
        let out = cordis(d, &args);
        assert_eq!(out.status.code(), Some(2), "{option} {strategy}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains(option) && err.contains("self-adaptive") && err.lines().count() == 1,
            "{err}"
        );
    }
}

/// Issue 19: `--crossover`, `--descent-start`, `--descent-every` and a `Param.gene`'s `pcross`,
/// `pmut`, `reducer` configure the thesis ES (thesis, t2m). They were silently ignored by the
/// other strategies; now refused by name in one line, and still read where they apply.
#[test]
fn thesis_options_are_read_by_the_thesis_es_and_refused_by_other_strategies() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let truth = chain_json(
        1.0,
        r#""stiffness": 50, "rest_length": 0.15, "damping": 0.5"#,
    );
    std::fs::write(d.join("truth.json"), truth).unwrap();
    let boxes = r#""stiffness": {"min": 5, "max": 500}, "rest_length": {"min": 0.05, "max": 0.5},
        "damping": 0.5"#;
    std::fs::write(d.join("u.json"), chain_json(1.0, boxes)).unwrap();
    let sim = ["simulate", "truth.json", "--frames", "60", "--out", "t.csv"];
    assert!(cordis(d, &sim).status.success());
    std::fs::write(d.join("es.gene"), "pcross=30\npmut=2\n").unwrap();
    std::fs::write(d.join("size.gene"), "population=8\ngeneration=3\n").unwrap();
    let base = [
        "identify",
        "u.json",
        "--trajectory",
        "t.csv",
        "-q",
        "--seed",
        "3",
    ];
    let run = |strategy: &str, extra: &[&str]| {
        let mut args = base.to_vec();
        args.extend_from_slice(&["--strategy", strategy, "-g", "15", "-p", "14"]);
        args.extend_from_slice(extra);
        let s = summary(&cordis(d, &args));
        assert_eq!(s["strategy"], strategy, "{s}");
        s["cost"].as_f64().unwrap()
    };
    // Read: each changes the t2m search (a seed fixes each run).
    let plain = run("t2m", &[]);
    let n_parent = run("t2m", &["--crossover", "n-parent"]);
    let descents = run("t2m", &["--descent-start", "5", "--descent-every", "5"]);
    let gene = run("t2m", &["--param-gene", "es.gene"]);
    let eq33 = run("t2m", &["--local-cost", "distances"]);
    assert_ne!(plain, eq33);
    assert_ne!(plain, n_parent);
    assert_ne!(plain, descents);
    assert_ne!(plain, gene);
    assert_eq!(n_parent, run("t2m", &["--crossover", "n-parent"]));
    // The default given by hand is the default.
    assert_eq!(plain, run("t2m", &["--crossover", "mean"]));
    assert_eq!(plain, run("t2m", &["--local-cost", "positions"]));
    // A Param.gene of population and generations only is read by every strategy.
    let mut args = base.to_vec();
    args.extend_from_slice(&["--strategy", "cmaes", "--param-gene", "size.gene"]);
    let s = summary(&cordis(d, &args));
    assert_eq!(s["generations"], 3, "{s}");

    for (extra, strategy, says) in [
        (&["--crossover", "mean"][..], "cmaes", "--crossover"),
        (
            &["--descent-start", "5"][..],
            "self-adaptive",
            "--descent-start",
        ),
        (&["--descent-every", "0"][..], "hybrid", "--descent-every"),
        // `auto` picks least-squares on this linear scene: the option would be ignored.
        (
            &["--crossover", "n-parent"][..],
            "auto",
            "least-squares (what auto picked",
        ),
        (
            &["--param-gene", "es.gene"][..],
            "annealing",
            "pcross, pmut configure",
        ),
        (
            &["--local-cost", "distances"][..],
            "parisian",
            "--local-cost",
        ),
    ] {
        let mut args = base.to_vec();
        args.extend_from_slice(&["--strategy", strategy]);
        args.extend_from_slice(extra);
        let out = cordis(d, &args);
        assert_eq!(out.status.code(), Some(2), "{extra:?} {strategy}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.contains(extra[0])
                && err.contains(says)
                && err.contains("thesis ES only (thesis, t2m)")
                && err.lines().count() == 1,
            "{err}"
        );
    }
    // Eq 3.3 is defined on the short cost's one-step predictions.
    let mut args = base.to_vec();
    args.extend_from_slice(&[
        "--strategy",
        "t2m",
        "--cost",
        "long",
        "--local-cost",
        "distances",
    ]);
    let out = cordis(d, &args);
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.starts_with("error: --local-cost: distances (eq 3.3)")
            && err.contains("not the `long` cost")
            && err.lines().count() == 1,
        "{err}"
    );
}

/// Issue 19 item 8: `--first-frame K` puts the scene's signals on a cropped take's clock. The
/// tadpole's motion from frame 150 (200 frames, noiseless), Table 6.1's unknowns plus the
/// tendon's start as boxes: on the scene's clock no parameter set fits (cost 1.5e-5 m²); on
/// the take's clock `hybrid` fits to rounding (1.3e-21).
#[test]
fn first_frame_puts_the_signals_on_a_cropped_takes_clock() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let ok = |args: &[&str]| assert!(cordis(d, args).status.success(), "{args:?}");
    ok(&["example", "tadpole", "--out", "truth.json"]);
    ok(&[
        "simulate",
        "truth.json",
        "--frames",
        "350",
        "--out",
        "t.csv",
    ]);
    ok(&["example", "tadpole", "--unknowns", "--out", "u.json"]);
    // Frames 150… renumbered from 0.
    let text = std::fs::read_to_string(d.join("t.csv")).unwrap();
    let mut lines = text.lines();
    let mut cropped = vec![lines.next().unwrap().to_string()];
    for line in lines {
        let (frame, rest) = line.split_once(',').unwrap();
        let frame: usize = frame.parse().unwrap();
        if frame >= 150 {
            cropped.push(format!("{},{rest}", frame - 150));
        }
    }
    std::fs::write(d.join("c.csv"), cropped.join("\n") + "\n").unwrap();
    let mut u: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("u.json")).unwrap()).unwrap();
    u["types"]["muscle"]["tendon_position"] = serde_json::json!({"min": -0.5, "max": 0.5});
    u["types"]["muscle"]["tendon_velocity"] = serde_json::json!({"min": -5.0, "max": 5.0});
    std::fs::write(d.join("u2.json"), u.to_string()).unwrap();
    let base = ["identify", "u2.json", "--trajectory", "c.csv", "-q"];
    let scene_clock = summary(&cordis(d, &base));
    let mut with = base.to_vec();
    with.extend(["--first-frame", "150"]);
    let take_clock = summary(&cordis(d, &with));
    let (a, b) = (
        scene_clock["cost"].as_f64().unwrap(),
        take_clock["cost"].as_f64().unwrap(),
    );
    assert_eq!(take_clock["strategy"], "hybrid");
    assert!(a > 1e-6 && b < 1e-18, "scene clock {a}, take clock {b}");
}

/// `--restarts bipop` (Hansen 2009) reaches cmaes: once a run ends, BIPOP's next run is a
/// small-population one (λ_def, where IPOP doubles λ), so the same generations cost other
/// evaluations; a seed fixes the run; another strategy refuses the option by name.
#[test]
fn cmaes_takes_bipop_restarts_and_other_strategies_refuse_them() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let truth = chain_json(
        1.0,
        r#""stiffness": 50, "rest_length": 0.15, "damping": 0.5"#,
    );
    std::fs::write(d.join("truth.json"), truth).unwrap();
    let boxes = r#""stiffness": {"min": 5, "max": 500}, "rest_length": {"min": 0.05, "max": 0.5},
        "damping": 0.5"#;
    std::fs::write(d.join("u.json"), chain_json(1.0, boxes)).unwrap();
    let sim = ["simulate", "truth.json", "--frames", "60", "--out", "t.csv"];
    assert!(cordis(d, &sim).status.success());
    let base = [
        "identify",
        "u.json",
        "--trajectory",
        "t.csv",
        "-q",
        "--seed",
        "3",
    ];
    let run = |extra: &[&str]| {
        let mut args = base.to_vec();
        args.extend_from_slice(&["--strategy", "cmaes", "-g", "300", "-p", "6"]);
        args.extend_from_slice(extra);
        let s = summary(&cordis(d, &args));
        assert_eq!(s["strategy"], "cmaes", "{s}");
        (s["evals"].as_u64().unwrap(), s["cost"].as_f64().unwrap())
    };
    let ipop = run(&[]);
    let bipop = run(&["--restarts", "bipop"]);
    eprintln!("ipop {ipop:?}, bipop {bipop:?}");
    assert_ne!(ipop.0, bipop.0, "no restart, or bipop ignored");
    assert_eq!(ipop, run(&["--restarts", "ipop"]));
    assert_eq!(bipop, run(&["--restarts", "bipop"]));
    for strategy in ["thesis", "self-adaptive"] {
        let mut args = base.to_vec();
        args.extend_from_slice(&["--strategy", strategy, "--restarts", "bipop"]);
        let out = cordis(d, &args);
        assert_eq!(out.status.code(), Some(2), "{strategy}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            err.starts_with("error: --restarts: configures the cmaes strategy only")
                && err.contains(strategy)
                && err.lines().count() == 1,
            "{err}"
        );
    }
    let mut args = base.to_vec();
    args.extend_from_slice(&["--strategy", "cmaes", "--restarts", "nbipop"]);
    let err = String::from_utf8_lossy(&cordis(d, &args).stderr).to_string();
    assert!(
        err.contains("--restarts: unknown restarts `nbipop`"),
        "{err}"
    );
}
