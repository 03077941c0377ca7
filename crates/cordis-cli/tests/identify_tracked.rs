//! `cordis identify` on tracked motion: gaps in the file, several takes, the uncertainty in
//! the report, the estimated initial state in the identified scene, refusals by name.

mod common;

use std::path::{Path, PathBuf};
use std::process::Output;

use common::{cordis, stderr};

fn summary(out: &Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8_lossy(&out.stdout);
    serde_json::from_str(text.lines().last().expect("a summary line")).expect("JSON")
}

fn soft_block() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/data/soft-block")
}

/// The soft block's markers with every 7th row absent and every 11th row's y cell empty.
fn gappy_markers(dir: &Path) -> PathBuf {
    let text = std::fs::read_to_string(soft_block().join("markers.csv")).unwrap();
    let mut out = String::new();
    for (k, line) in text.lines().enumerate() {
        if k > 0 && k % 7 == 0 {
            continue;
        }
        if k > 0 && k % 11 == 0 {
            let f: Vec<&str> = line.split(',').collect();
            out.push_str(&format!("{},{},{},,{}\n", f[0], f[1], f[2], f[4]));
            continue;
        }
        out.push_str(line);
        out.push('\n');
    }
    let path = dir.join("gappy.csv");
    std::fs::write(&path, out).unwrap();
    path
}

#[test]
fn gaps_in_a_csv_are_missing_observations_and_the_estimate_comes_with_intervals() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let gappy = gappy_markers(d);
    let sb = soft_block();
    let (guess, truth) = (sb.join("guess.json"), sb.join("truth.json"));
    let args = [
        "identify",
        guess.to_str().unwrap(),
        "--trajectory",
        gappy.to_str().unwrap(),
        "--truth",
        truth.to_str().unwrap(),
        "--out",
        "identified.json",
    ];
    let out = cordis(d, &args);
    let s = summary(&out);
    assert_eq!(s["strategy"], "output-error", "{s}");
    assert_eq!(s["stopped_by"], "converged", "{s}");
    assert!(s["param_error_pct"].as_f64().unwrap() < 5.0, "{s}");
    let why = s["solver"]["chosen_because"].as_str().unwrap();
    assert!(why.contains("missing"), "{why}");
    // cost and rmse are what the fit minimised, the replay's residuals: about the 1 mm noise
    // (the short cost's rmse on these markers is far above it).
    let (cost, rmse) = (s["cost"].as_f64().unwrap(), s["rmse"].as_f64().unwrap());
    assert_eq!(cost, s["solver"]["position_cost"].as_f64().unwrap(), "{s}");
    assert!((0.8e-3..1.2e-3).contains(&rmse), "{s}");
    let u = s["solver"]["uncertainty"].as_array().unwrap();
    assert_eq!(u.len(), 9);
    for p in u {
        let (lo, hi) = (
            p["interval"][0].as_f64().unwrap(),
            p["interval"][1].as_f64().unwrap(),
        );
        assert!(lo < hi && p["std_error"].as_f64().unwrap() > 0.0, "{p}");
    }
    let table = String::from_utf8_lossy(&out.stderr);
    assert!(table.contains(" ± "), "{table}");
    // The report says why auto chose the estimator, as the JSON line does.
    assert!(
        table.contains(&format!("  chosen by auto: {why}")),
        "{table}"
    );
    // The identified scene carries the estimated initial state: it replays the take.
    let scene: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("identified.json")).unwrap()).unwrap();
    // The JSON line carries the estimate itself, the values `--out` writes.
    let params = s["params"].as_object().unwrap();
    assert_eq!(params.len(), 9, "{s}");
    for (name, value) in params {
        let [_, ty, key] = name.split('.').collect::<Vec<_>>()[..] else {
            panic!("{name}")
        };
        assert_eq!(value, &scene["types"][ty][key], "{name}");
    }
    let v = &scene["particles"][13]["vel"];
    assert!(v.is_array() && v[0].as_f64().unwrap().abs() > 1e-3, "{v}");
}

#[test]
fn two_takes_share_one_parameter_set() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sb = soft_block();
    // A second take: the true block pushed the other way, simulated.
    let mut truth: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(sb.join("truth.json")).unwrap()).unwrap();
    for p in truth["particles"].as_array_mut().unwrap() {
        if p["fixed"].as_bool() != Some(true) {
            p["vel"] = serde_json::json!([-0.2, 0.0, 0.1]);
        }
    }
    std::fs::write(d.join("other.json"), truth.to_string()).unwrap();
    assert!(cordis(
        d,
        &[
            "simulate",
            "other.json",
            "--frames",
            "120",
            "--out",
            "b.csv"
        ]
    )
    .status
    .success());
    let (guess, markers) = (sb.join("guess.json"), sb.join("markers.csv"));
    let (guess, markers) = (guess.to_str().unwrap(), markers.to_str().unwrap());
    let both = ["identify", guess, "-t", markers, "-t", "b.csv"];
    let truth = sb.join("truth.json");
    let out = cordis(
        d,
        &[
            &both[..],
            &["--truth", truth.to_str().unwrap(), "--out", "model.json"],
        ]
        .concat(),
    );
    let s = summary(&out);
    assert_eq!(s["strategy"], "output-error", "{s}");
    assert_eq!(
        s["solver"]["chosen_because"],
        "2 takes share one parameter set"
    );
    assert!(s["param_error_pct"].as_f64().unwrap() < 5.0, "{s}");
    // Each take's scene carries its own estimated initial state: take 1 (b.csv, noiseless)
    // started every free particle at (-0.2, 0, 0.1) m/s, take 0 (the markers) elsewhere.
    let vel = |file: &str, i: usize| -> Vec<f64> {
        let text = std::fs::read_to_string(d.join(file)).expect(file);
        let scene: serde_json::Value = serde_json::from_str(&text).unwrap();
        let v = scene["particles"][i]["vel"]
            .as_array()
            .expect("a velocity")
            .clone();
        v.iter().map(|c| c.as_f64().unwrap()).collect()
    };
    let wrote = String::from_utf8_lossy(&out.stderr);
    assert!(wrote.contains("wrote take 1's identified scene"), "{wrote}");
    for i in [9, 13, 26] {
        let (take0, take1) = (vel("model.json", i), vel("model.take1.json", i));
        for (c, want) in [-0.2, 0.0, 0.1].into_iter().enumerate() {
            assert!((take1[c] - want).abs() < 1e-2, "particle {i}: {take1:?}");
        }
        assert!(
            (take0[0] + 0.2).abs() > 5e-2,
            "particle {i}: take 0 {take0:?}"
        );
    }
    // One initial state per take: 6 values for each of the 18 free particles, twice.
    assert_eq!(s["solver"]["variables"], 9 + 2 * 6 * 18);
    // Another strategy cannot combine takes, and says so before any work.
    let out = cordis(d, &[&both[..], &["--strategy", "least-squares"]].concat());
    assert_eq!(out.status.code(), Some(2));
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(e.contains("2 takes: `least-squares` reads one"), "{e}");
}

#[test]
fn gaps_are_refused_by_name_where_they_cannot_be_read() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let gappy = gappy_markers(d);
    let guess = soft_block().join("guess.json");
    let out = cordis(
        d,
        &[
            "identify",
            guess.to_str().unwrap(),
            "-t",
            gappy.to_str().unwrap(),
            "--strategy",
            "thesis",
        ],
    );
    assert_eq!(out.status.code(), Some(2));
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(
        e.contains("missing observations: `thesis` needs every coordinate"),
        "{e}"
    );
    assert_eq!(e.lines().count(), 1, "{e}");
    // A file naming a particle the scene does not have.
    let text = "frame,particle,x,y,z\n0,0,0,0,0\n0,40,1,1,1\n";
    std::fs::write(d.join("extra.csv"), text).unwrap();
    let out = cordis(d, &["identify", guess.to_str().unwrap(), "-t", "extra.csv"]);
    assert_eq!(out.status.code(), Some(2));
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(e.contains("41 particles but the scene has 27"), "{e}");
    // A misspelt z header (`q`): read as planar, it once went silently to a fit that diverged.
    let text = std::fs::read_to_string(soft_block().join("markers.csv")).unwrap();
    let typo = text.replacen("frame,particle,x,y,z", "frame,particle,x,y,q", 1);
    assert_ne!(typo, text, "the header the test changes");
    std::fs::write(d.join("typo.csv"), typo).unwrap();
    let out = cordis(d, &["identify", guess.to_str().unwrap(), "-t", "typo.csv"]);
    assert_eq!(out.status.code(), Some(2));
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(
        e.starts_with(
            "error: typo.csv:1: column `q` (field 5) is not read (read: frame, particle, x, y)"
        ),
        "{e}"
    );
    assert_eq!(e.lines().count(), 1, "{e}");
    // Mapped without its z, the table reads planar: refused for a scene with depth.
    let mapped = "frame=frame,particle=particle,x=x,y=y";
    let args = [
        guess.to_str().unwrap(),
        "-t",
        "typo.csv",
        "--columns",
        mapped,
    ];
    let out = cordis(d, &[&["identify"][..], &args].concat());
    assert_eq!(out.status.code(), Some(2));
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(
        e.starts_with("error: typo.csv: every z is 0") && e.contains("particles[3]"),
        "{e}"
    );
    assert_eq!(e.lines().count(), 1, "{e}");
}

#[test]
fn output_error_stopped_by_the_time_limit_prints_its_best_so_far_and_resumes_to_the_uninterrupted_model(
) {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sb = soft_block();
    let (guess, markers) = (sb.join("guess.json"), sb.join("markers.csv"));
    let (guess, markers) = (guess.to_str().unwrap(), markers.to_str().unwrap());
    let base = [
        "identify",
        guess,
        "--trajectory",
        markers,
        "--json",
        "--quiet",
    ];
    let whole = cordis(d, &[&base[..], &["--out", "whole.json"]].concat());
    let whole_line = summary(&whole);
    assert_eq!(whole_line["stopped_by"], "converged");

    // The whole fit takes ~1 s of CPU: 0.05 s stops it inside its first windows.
    let stopped = cordis(
        d,
        &[
            &base[..],
            &[
                "--time-limit",
                "0.05",
                "--checkpoint",
                "fit.ckpt",
                "--out",
                "stopped.json",
            ],
        ]
        .concat(),
    );
    let line = summary(&stopped);
    assert_eq!(line["stopped_by"], "time_limit");
    // Inside a window (or, on a machine slow enough, before the first one began): either
    // way the run stopped it (it said `running` between windows).
    assert_eq!(line["solver"]["end"], "stopped", "{line}");
    // A generation budget spent between windows said `running` of a run that had ended.
    let budget = summary(&cordis(d, &[&base[..], &["-g", "1"]].concat()));
    assert_eq!(budget["stopped_by"], "generations", "{budget}");
    assert_eq!(budget["solver"]["end"], "stopped", "{budget}");
    assert!(line["cost"].as_f64().unwrap().is_finite());
    assert!(
        line.get("uncertainty").is_none(),
        "no interval from a fit not finished"
    );
    let warned = String::from_utf8_lossy(&stopped.stderr);
    assert!(
        warned.contains("before reaching the whole take"),
        "{warned}"
    );
    assert!(
        d.join("stopped.json").exists(),
        "the best so far is written"
    );

    let resumed = cordis(
        d,
        &[
            &base[..],
            &["--resume", "fit.ckpt", "--out", "resumed.json"],
        ]
        .concat(),
    );
    let resumed_line = summary(&resumed);
    assert_eq!(resumed_line["stopped_by"], "converged");
    assert_eq!(resumed_line["cost"], whole_line["cost"]);
    assert_eq!(resumed_line["uncertainty"], whole_line["uncertainty"]);
    let read = |f: &str| std::fs::read_to_string(d.join(f)).unwrap();
    assert_eq!(
        read("resumed.json"),
        read("whole.json"),
        "the same identified scene"
    );
}

/// The soft block's markers in another order and without the clamped particles (0–8): file
/// particle j is scene particle `order[j]`.
fn reordered_markers(dir: &Path) -> (PathBuf, Vec<usize>) {
    let order: Vec<usize> = (9..27).rev().collect();
    let text = std::fs::read_to_string(soft_block().join("markers.csv")).unwrap();
    let mut lines = text.lines();
    let mut out = format!("{}\n", lines.next().unwrap());
    for line in lines {
        let f: Vec<&str> = line.split(',').collect();
        let p: usize = f[1].parse().unwrap();
        if let Some(j) = order.iter().position(|&q| q == p) {
            out.push_str(&format!("{},{j},{},{},{}\n", f[0], f[2], f[3], f[4]));
        }
    }
    let path = dir.join("reordered.csv");
    std::fs::write(&path, out).unwrap();
    (path, order)
}

#[test]
fn markers_map_a_file_in_its_own_order_without_the_fixed_particles() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (file, order) = reordered_markers(d);
    let sb = soft_block();
    let (guess, truth) = (sb.join("guess.json"), sb.join("truth.json"));
    let map = order
        .iter()
        .map(|p| p.to_string())
        .collect::<Vec<_>>()
        .join(",");
    let args = [
        "identify",
        guess.to_str().unwrap(),
        "-t",
        file.to_str().unwrap(),
        "--markers",
        &map,
        "--truth",
        truth.to_str().unwrap(),
        "--json",
        "--quiet",
    ];
    let s = summary(&cordis(d, &args));
    assert_eq!(s["strategy"], "output-error", "{s}");
    assert_eq!(s["stopped_by"], "converged", "{s}");
    assert!(s["param_error_pct"].as_f64().unwrap() < 5.0, "{s}");
    // 18 tracked markers × 200 frames × 3 coordinates: the clamped particles are not data,
    // nor missing (`auto` chose the estimator for the noise, not for gaps there are none of).
    assert_eq!(s["solver"]["observed"], 18 * 200 * 3);
    let why = s["solver"]["chosen_because"].as_str().unwrap_or_default();
    assert!(why.contains("noisy") && !why.contains("missing"), "{why}");
    // Spaces after the commas are read as the same map (` 0` was "invalid digit").
    let spaced = map.replace(',', ", ");
    let mut with_spaces = args;
    with_spaces[5] = &spaced;
    let sp = summary(&cordis(d, &with_spaces));
    assert_eq!(sp["cost"], s["cost"], "{sp}");

    // Down-weighting two markers (three weights each) changes the estimate, not its quality.
    let mut weights = vec!["1"; 3 * order.len()];
    weights[..6].fill("0.25");
    let weights = weights.join(",");
    let w = summary(&cordis(d, &[&args[..], &["--weights", &weights]].concat()));
    assert_eq!(w["stopped_by"], "converged", "{w}");
    assert_ne!(w["cost"], s["cost"]);
    assert!(w["param_error_pct"].as_f64().unwrap() < 5.0, "{w}");
}

#[test]
fn bad_markers_and_weights_are_refused_by_name() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sb = soft_block();
    let (guess, markers) = (sb.join("guess.json"), sb.join("markers.csv"));
    let base = [
        "identify",
        guess.to_str().unwrap(),
        "-t",
        markers.to_str().unwrap(),
    ];
    let all: Vec<String> = (0..27).map(|p| p.to_string()).collect();
    let mut twice = all.clone();
    twice[5] = "4".into();
    let (twice, all) = (twice.join(","), all.join(","));
    let cases: [(&[&str], &[&str]); 11] = [
        (
            &["--markers", "0, 1,-1"],
            &[
                "--markers",
                "entry 2: expected a particle index (an integer from 0), got `-1`",
            ],
        ),
        (
            &["--loss", "l1"],
            &["--loss", "not one of squared, huber, cauchy"],
        ),
        (
            &["--loss", "huber", "--strategy", "least-squares"],
            &["--loss", "read by output-error only"],
        ),
        (
            &["--intervals", "likelihood"],
            &["--intervals", "not one of wald, profile"],
        ),
        (
            &["--intervals", "profile", "--strategy", "least-squares"],
            &["--intervals", "read by output-error only"],
        ),
        (
            &["--markers", &twice],
            &["--markers[5]", "already tracked by marker 4"],
        ),
        (
            &["--markers", "0,1,99"],
            &["--markers[2]", "particle 99 does not exist"],
        ),
        (
            &["--markers", "0,1,2"],
            &[
                "--markers: names 3 particles for the 27 markers of",
                "markers.csv",
            ],
        ),
        (
            &["--weights", "1,2"],
            &[
                "--weights: holds 2 values for the 27 markers of",
                "markers.csv",
            ],
        ),
        (
            &[
                "--markers",
                &all,
                "--weights",
                &["1"; 26].join(",").replace("1,1,1", "1,nan,1"),
            ],
            &["--weights[1]", "positive finite"],
        ),
        (
            &[
                "--weights",
                &["2"; 27].join(","),
                "--strategy",
                "least-squares",
            ],
            &["per-marker weights", "least-squares"],
        ),
    ];
    for (extra, says) in cases {
        common::fails(d, &[&base[..], extra].concat(), 2, says);
    }
}

/// A take that cannot be read is bad input (exit 2) named by its file wherever it stands on
/// the line: a short second take used to fail as a run (exit 1, `output-error: take 1: …`),
/// and a marker count that did not fit was blamed on `--trajectory` without the file.
#[test]
fn a_bad_take_is_bad_input_named_by_its_file_at_any_position() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sb = soft_block();
    let guess = sb.join("guess.json");
    let text = std::fs::read_to_string(sb.join("markers.csv")).unwrap();
    let header = text.lines().next().unwrap();
    let rows = |keep: &dyn Fn(&[&str]) -> Option<String>| -> String {
        let mut out = format!("{header}\n");
        for line in text.lines().skip(1) {
            if let Some(row) = keep(&line.split(',').collect::<Vec<_>>()) {
                out.push_str(&row);
                out.push('\n');
            }
        }
        out
    };
    std::fs::copy(sb.join("markers.csv"), d.join("markers.csv")).unwrap();
    let two = rows(&|f| (f[0].parse::<usize>().unwrap() < 2).then(|| f.join(",")));
    std::fs::write(d.join("two.csv"), two).unwrap();
    let gone = rows(&|f| Some(format!("{},{},,,", f[0], f[1])));
    std::fs::write(d.join("gone.csv"), gone).unwrap();
    // The 18 free markers only, renumbered from 0.
    let free = rows(&|f| {
        let p: usize = f[1].parse().unwrap();
        (p >= 9).then(|| format!("{},{},{},{},{}", f[0], p - 9, f[2], f[3], f[4]))
    });
    std::fs::write(d.join("free.csv"), free).unwrap();
    let all: Vec<String> = (0..27).map(|p| p.to_string()).collect();
    let all = all.join(",");
    let g = guess.to_str().unwrap();
    let cases: [(&[&str], &str); 5] = [
        (
            &["-t", "two.csv"],
            "two.csv: has 2 frames, at least 3 are needed",
        ),
        (
            &["-t", "markers.csv", "-t", "two.csv"],
            "two.csv: has 2 frames, at least 3 are needed",
        ),
        (&["-t", "gone.csv"], "gone.csv: every coordinate is missing"),
        (
            &["-t", "markers.csv", "-t", "gone.csv"],
            "gone.csv: every coordinate is missing",
        ),
        (
            &["-t", "markers.csv", "-t", "free.csv", "--markers", &all],
            "--markers: names 27 particles for the 18 markers of free.csv",
        ),
    ];
    for (takes, says) in cases {
        let err = common::fails(d, &[&["identify", g][..], takes].concat(), 2, &[says]);
        assert_eq!(err.trim_end(), format!("error: {says}"));
    }
}

/// An unknown the data do not determine (a spring between two fixed particles) has an
/// infinite standard error, written `"inf"`, and its box as its interval: it was written
/// `[0.0, null]`, infinity two ways in one object and a lower end below the box's 1. The
/// report reads the summary back and shows the box.
#[test]
fn an_undetermined_unknown_s_interval_is_its_box_in_the_summary_and_the_report() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sb = soft_block();
    let mut guess: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(sb.join("guess.json")).unwrap()).unwrap();
    let fixed = guess["particles"].as_array().unwrap();
    assert!(fixed[0]["fixed"] == true && fixed[1]["fixed"] == true);
    guess["types"]["dummy"] = serde_json::json!({
        "kind": "spring", "stiffness": {"min": 1, "max": 100}, "rest_length": 0.1
    });
    let link = serde_json::json!({"type": "dummy", "particles": [0, 1]});
    guess["links"].as_array_mut().unwrap().push(link);
    std::fs::write(d.join("dummy.json"), guess.to_string()).unwrap();
    let markers = sb.join("markers.csv");
    let args = [
        "identify",
        "dummy.json",
        "-t",
        markers.to_str().unwrap(),
        "--out",
        "fit.json",
        "--json",
        "-q",
    ];
    let out = cordis(d, &args);
    let line = String::from_utf8_lossy(&out.stdout).to_string();
    assert!(!line.contains("null"), "{line}");
    let s = summary(&out);
    let u = s["solver"]["uncertainty"].as_array().unwrap();
    let dummy = u
        .iter()
        .find(|p| p["name"] == "types.dummy.stiffness")
        .expect("the undetermined unknown is reported");
    assert_eq!(dummy["std_error"], "inf", "{dummy}");
    assert_eq!(
        dummy["interval"],
        serde_json::json!([1.0, 100.0]),
        "{dummy}"
    );
    // The determined ones keep their Wald intervals, finite and around their values.
    assert_eq!(u.len(), 10);
    for p in u.iter().filter(|p| p["name"] != "types.dummy.stiffness") {
        let se = p["std_error"].as_f64().unwrap();
        let (lo, hi) = (
            p["interval"][0].as_f64().unwrap(),
            p["interval"][1].as_f64().unwrap(),
        );
        assert!(se > 0.0 && lo < hi && hi - lo < 10.0 * se, "{p}");
    }
    std::fs::write(d.join("summary.json"), &line).unwrap();
    let report = [
        "report",
        "fit.json",
        "-t",
        markers.to_str().unwrap(),
        "--summary",
        "summary.json",
        "--html",
        "r.html",
        "-q",
    ];
    let out = cordis(d, &report);
    assert!(out.status.success(), "{}", stderr(&out));
    let page = std::fs::read_to_string(d.join("r.html")).unwrap();
    assert!(
        page.contains("not determined <span class=\"muted\">[1, 100] (its box)</span>"),
        "the page shows the box"
    );
}

/// Issue 18: `cordis report` reads `--markers` and `--weights` as `identify` does. On the
/// reordered file the mapped page fits the truth as the scene-order file does; unmapped, the
/// file's particle j is drawn as the scene's particle j and the fit is far off.
#[test]
fn report_maps_markers_and_weights_as_identify_does() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let (file, order) = reordered_markers(d);
    let truth = soft_block().join("truth.json");
    let map = order
        .iter()
        .map(|p| p.to_string())
        .collect::<Vec<_>>()
        .join(",");
    let warned = std::cell::RefCell::new(String::new());
    let rms = |extra: &[&str]| -> f64 {
        let mut args = vec![
            "report",
            truth.to_str().unwrap(),
            "-t",
            file.to_str().unwrap(),
            "--html",
            "r.html",
            "-q",
        ];
        args.extend(extra);
        let out = cordis(d, &args);
        assert!(out.status.success(), "{extra:?}: {}", stderr(&out));
        *warned.borrow_mut() = stderr(&out);
        let page = std::fs::read_to_string(d.join("r.html")).unwrap();
        let at = page.find("position RMS error</th><td>").unwrap() + 27;
        page[at..].split(' ').next().unwrap().parse().unwrap()
    };
    let mapped = rms(&["--markers", &map]);
    assert!(warned.borrow().is_empty(), "{}", warned.borrow());
    let unmapped = rms(&[]);
    assert!(
        mapped < 1e-2 && unmapped > 10.0 * mapped,
        "{mapped} {unmapped}"
    );
    // Unmapped, the page's fit is far worse than the run's was: the report says why, as
    // identify does (it said nothing; a new user's finding).
    let said = warned.borrow().clone();
    assert!(
        said.starts_with("warning: ")
            && said.contains("fixed particles are observed far from where the scene holds them")
            && said.contains("check --markers"),
        "{said}"
    );
    let page = std::fs::read_to_string(d.join("r.html")).unwrap();
    assert!(!page.contains("weighted position RMS"));
    let weights = vec!["2"; order.len()].join(",");
    assert_eq!(rms(&["--markers", &map, "--weights", &weights]), mapped);
    let page = std::fs::read_to_string(d.join("r.html")).unwrap();
    // The 9 clamped particles the file does not track are where the scene puts them: not
    // hidden, not missing.
    assert!(
        page.contains("27 in the scene (9 fixed), 18 in the motion, 0 never observed"),
        "the clamped particles"
    );
    assert!(page.contains("<td>0 of 10800 coordinates (0.00 %)</td>"));
    assert!(page.contains("weighted position RMS error</th><td>"));
    let out = cordis(
        d,
        &[
            "report",
            truth.to_str().unwrap(),
            "-t",
            file.to_str().unwrap(),
            "--html",
            "bad.html",
            "--markers",
            "9,9",
        ],
    );
    assert_eq!(out.status.code(), Some(2));
    let e = stderr(&out);
    assert!(
        e.contains(&format!(
            "--markers: names 2 particles for the 18 markers of {}",
            file.display()
        )),
        "{e}"
    );
    assert!(!d.join("bad.html").exists());
}

/// `cordis bench noise` on a small grid: one JSON line per cell, the angle networks' rest
/// cosines among the unknowns (their own coverage column), noiseless fits exact, and a bad
/// `--masses` range refused by name.
#[test]
fn bench_noise_reports_each_cell_with_coverage_per_parameter_kind() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let args = [
        "bench",
        "noise",
        "--draws",
        "2",
        "--noise",
        "0,1e-3",
        "--patterns",
        "complete",
        "--masses",
        "12-14",
        "--frames",
        "60",
    ];
    let out = cordis(d, &args);
    assert!(out.status.success(), "{}", stderr(&out));
    let text = String::from_utf8_lossy(&out.stdout);
    let cells: Vec<serde_json::Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).expect("JSON line"))
        .collect();
    assert_eq!(cells.len(), 2);
    assert_eq!(cells[0]["masses"], "12-14");
    assert!(
        cells[0]["error_pct"].as_f64().unwrap() < 1e-6,
        "{}",
        cells[0]
    );
    let noisy = &cells[1];
    for kind in ["stiffness", "rest_length", "rest_cos", "damping"] {
        let c = noisy["coverage95"][kind].as_f64();
        assert!(
            c.is_some_and(|c| (0.0..=1.0).contains(&c)),
            "{kind}: {noisy}"
        );
    }
    assert!(noisy["crb_pct"].as_f64().unwrap() > 0.0);
    for bad in ["3", "20-12", "x"] {
        let out = cordis(d, &["bench", "noise", "--masses", bad]);
        assert_eq!(out.status.code(), Some(2), "{bad}");
        assert!(stderr(&out).contains("--masses"), "{bad}: {}", stderr(&out));
    }
}

/// A box that leaves the truth out (the rigid object's `h_bottom` stiffness, 1050, searched in
/// [262.5, 525]): the estimate ends on the box's edge, the report names it in `at_bound` with a
/// warning, and its interval is cut at the box (it reached past it, naming values the fit
/// could never return). Before, nothing said so, and the output was labelled as any other.
#[test]
fn an_estimate_on_its_boxs_edge_is_named_and_its_interval_cut_there() {
    let dir = common::rigid_dir();
    let d = dir.path();
    let out = cordis(
        d,
        &["simulate", "r.json", "--frames", "100", "--out", "r100.csv"],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let mut scene: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("u.json")).unwrap()).unwrap();
    scene["types"]["h_bottom"]["stiffness"] = serde_json::json!({"min": 262.5, "max": 525.0});
    std::fs::write(d.join("narrow.json"), scene.to_string()).unwrap();
    let out = cordis(
        d,
        &[
            "identify",
            "narrow.json",
            "-t",
            "r100.csv",
            "--strategy",
            "output-error",
            "--noise",
            "1e-3",
            "--json",
        ],
    );
    let v = summary(&out);
    let solver = &v["solver"];
    assert_eq!(
        solver["at_bound"],
        serde_json::json!(["types.h_bottom.stiffness"]),
        "{solver}"
    );
    let row = solver["uncertainty"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["name"] == "types.h_bottom.stiffness")
        .expect("its row");
    let (low, high) = (
        row["interval"][0].as_f64().unwrap(),
        row["interval"][1].as_f64().unwrap(),
    );
    assert!(262.5 <= low && low < high && high == 525.0, "{row}");
    assert!(
        stderr(&out).contains("on an edge of the box: types.h_bottom.stiffness"),
        "{}",
        stderr(&out)
    );
}

/// The soft block's markers shifted by 0.5 m along x (or in mm for a scene in m, or without the
/// `--markers` their file needs): its fixed particles are observed far from where the scene
/// holds them, and a warning says so before the fit, naming the take and the farthest. The
/// data as shipped give no such warning.
#[test]
fn fixed_particles_observed_far_from_the_scene_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let text = std::fs::read_to_string(soft_block().join("markers.csv")).unwrap();
    let mut shifted = String::new();
    for (k, line) in text.lines().enumerate() {
        let mut f: Vec<String> = line.split(',').map(str::to_string).collect();
        if k > 0 {
            f[2] = format!("{}", f[2].parse::<f64>().unwrap() + 0.5);
        }
        shifted.push_str(&f.join(","));
        shifted.push('\n');
    }
    std::fs::write(d.join("shift.csv"), shifted).unwrap();
    let guess = soft_block().join("guess.json");
    let run = |take: &Path| {
        let out = cordis(
            d,
            &[
                "identify",
                guess.to_str().unwrap(),
                "-t",
                take.to_str().unwrap(),
                "--generations",
                "1",
            ],
        );
        stderr(&out)
    };
    let err = run(&d.join("shift.csv"));
    assert!(
        err.contains(
            "shift.csv: 9 fixed particles are observed far from where the scene holds them"
        ),
        "{err}"
    );
    let err = run(&soft_block().join("markers.csv"));
    assert!(!err.contains("far from where the scene"), "{err}");
}

/// A take of 3 frames has no third difference to read its noise from: the fit's residuals are
/// not judged against a level, and the report says so (`solver.noise_unread`, a warning)
/// instead of calling them "above the data's noise level (0.000e0 m)". The whole take gives
/// no such warning.
#[test]
fn a_take_too_short_for_its_noise_level_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let text = std::fs::read_to_string(soft_block().join("markers.csv")).unwrap();
    let short: Vec<&str> = text
        .lines()
        .enumerate()
        .filter(|(k, l)| {
            *k == 0
                || l.split(',')
                    .next()
                    .is_some_and(|f| f.trim().parse::<u32>().is_ok_and(|f| f < 3))
        })
        .map(|(_, l)| l)
        .collect();
    std::fs::write(d.join("short.csv"), short.join("\n")).unwrap();
    let guess = soft_block().join("guess.json");
    let out = cordis(
        d,
        &[
            "identify",
            guess.to_str().unwrap(),
            "-t",
            "short.csv",
            "--json",
        ],
    );
    let v = summary(&out);
    assert_eq!(v["solver"]["noise_unread"], serde_json::json!([0]), "{v}");
    let err = stderr(&out);
    assert!(
        err.contains("the noise level of take 0 cannot be read"),
        "{err}"
    );
    assert!(!err.contains("above the data's noise level"), "{err}");
}
