//! `cordis check` and the stability side of `cordis simulate`, through the binary.

use std::path::Path;
use std::process::{Command, Output};

fn cordis(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_cordis"))
        .args(args)
        .output()
        .expect("run cordis")
}

/// One 2 kg mass 1 m from an anchor with K dt²/m = `k`.
fn anchored(dir: &Path, k: f64) -> String {
    let path = dir.join(format!("anchor-{k}.json"));
    let stiffness = k * 2.0 / (0.01 * 0.01);
    std::fs::write(
        &path,
        format!(
            r#"{{"format": "cordis-scene/1", "dt": 0.01,
                "particles": [{{"mass": 2.0, "pos": [1, 0, 0]}}],
                "types": {{"a": {{"kind": "anchor", "stiffness": {stiffness}, "point": [0, 0, 0]}}}},
                "links": [{{"type": "a", "particles": [0]}}]}}"#
        ),
    )
    .unwrap();
    path.to_str().unwrap().to_owned()
}

fn json_line(out: &Output) -> serde_json::Value {
    let stdout = String::from_utf8(out.stdout.clone()).unwrap();
    assert_eq!(stdout.lines().count(), 1, "one JSON line: {stdout}");
    serde_json::from_str(stdout.trim()).unwrap()
}

#[test]
fn check_reports_the_acceptance_ratios() {
    let dir = tempfile::tempdir().unwrap();
    for (k, ratio, stable) in [(3.8, 0.95, true), (4.2, 1.05, false)] {
        let out = cordis(&["check", &anchored(dir.path(), k)]);
        assert!(out.status.success(), "check exits 0 either way");
        let v = json_line(&out);
        let q = v["max_stability_ratio"].as_f64().unwrap();
        assert!((q - ratio).abs() < 1e-12, "{q} vs {ratio}");
        assert_eq!(v["stable"], stable);
        assert_eq!(v["worst_particle"], 0);
        let dt_max = v["max_stable_dt"].as_f64().unwrap();
        assert!((dt_max - 0.01 / ratio.sqrt()).abs() < 1e-12);
        let stderr = String::from_utf8(out.stderr).unwrap();
        assert!(stderr.contains(if stable { "stable" } else { "UNSTABLE" }));
    }
}

#[test]
fn simulate_stops_an_unstable_scene_naming_the_frame_and_writes_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let out_path = dir.path().join("out.csv");
    let out = cordis(&[
        "simulate",
        &anchored(dir.path(), 4.2),
        "--frames",
        "5000",
        "--out",
        out_path.to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(1));
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(stderr.contains("warning: stability ratio 1.05"), "{stderr}");
    let error = stderr.lines().find(|l| l.starts_with("error:")).unwrap();
    assert!(
        error.contains("diverged at frame 39, particle 0"),
        "{error}"
    );
    assert!(!out_path.exists());
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        1,
        "no temporary left"
    );
}

#[test]
fn simulate_runs_a_stable_scene_bounded_without_warning() {
    let dir = tempfile::tempdir().unwrap();
    let out_path = dir.path().join("out.csv");
    let out = cordis(&[
        "simulate",
        &anchored(dir.path(), 3.8),
        "--frames",
        "5000",
        "--out",
        out_path.to_str().unwrap(),
    ]);
    assert!(out.status.success());
    assert!(!String::from_utf8(out.stderr).unwrap().contains("warning"));
    let text = std::fs::read_to_string(&out_path).unwrap();
    assert_eq!(text.lines().count(), 5001);
    let peak = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').nth(2).unwrap().parse::<f64>().unwrap().abs())
        .fold(0.0, f64::max);
    assert!(peak <= 1.0 / 0.05f64.sqrt() + 1e-9, "peak {peak}");
}

#[test]
fn simulate_refuses_frame_counts_that_cannot_be_held() {
    let dir = tempfile::tempdir().unwrap();
    let scene = anchored(dir.path(), 1.0);
    for frames in ["18446744073709551615", "100000000000000000"] {
        let out = cordis(&["simulate", &scene, "--frames", frames]);
        assert_eq!(out.status.code(), Some(2));
        let stderr = String::from_utf8(out.stderr).unwrap();
        assert!(stderr.starts_with("error: --frames"), "{stderr}");
        assert_eq!(stderr.lines().count(), 1);
    }
}

#[test]
fn check_of_a_malformed_scene_is_a_placed_one_line_error() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.json");
    std::fs::write(
        &path,
        r#"{"format": "cordis-scene/1", "dt": 0.01, "particles": [{"mass": -1, "pos": [0,0,0]}]}"#,
    )
    .unwrap();
    let out = cordis(&["check", path.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8(out.stderr).unwrap();
    assert!(stderr.contains("particles[0].mass"), "{stderr}");
    assert_eq!(stderr.lines().count(), 1);
}

/// Issue 17: a free particle on the vertex of an angle link (an arm of 0 m). `check` called it
/// stable (the angle was skipped) and `simulate` threw the particle 35 m in 49 frames without a
/// word; now `check` names the link and calls the scene unstable, and `simulate` warns.
#[test]
fn check_reports_a_degenerate_angle_and_simulate_warns() {
    let dir = tempfile::tempdir().unwrap();
    let scene = dir.path().join("degenerate.json");
    std::fs::write(
        &scene,
        r#"{"format": "cordis-scene/1", "dt": 0.01,
            "particles": [{"mass": 1, "pos": [0, 0, 0], "fixed": true},
                          {"mass": 1, "pos": [0, 0, 0], "vel": [0, 0.1, 0]},
                          {"mass": 1, "pos": [1, 0, 0]}],
            "types": {"bend": {"kind": "angle", "stiffness": 10, "rest_cos": -1},
                      "rib": {"kind": "spring", "stiffness": 10, "rest_length": 1}},
            "links": [{"type": "bend", "particles": [0, 1, 2]},
                      {"type": "rib", "particles": [1, 2]}]}"#,
    )
    .unwrap();
    let scene = scene.to_str().unwrap();
    let out = cordis(&["check", scene]);
    assert!(out.status.success());
    let v = json_line(&out);
    assert_eq!(v["stable"], false, "{v}");
    assert_eq!(v["degenerate_angles"], serde_json::json!([0]), "{v}");
    let report = String::from_utf8_lossy(&out.stderr);
    assert!(
        report.contains("1 degenerate angle link(s)") && report.contains("links[0] [0, 1, 2]"),
        "{report}"
    );
    let csv = dir.path().join("d.csv");
    let out = cordis(&[
        "simulate",
        scene,
        "-n",
        "50",
        "-o",
        csv.to_str().unwrap(),
        "-q",
    ]);
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).starts_with("warning: stability ratio"));
    let traj = cordis_core::io::read_trajectory(&csv).unwrap();
    assert!(traj.scale() < 1.5, "the motion reached {} m", traj.scale());
}

/// Issue 17: a ratio of 6.8e303 was printed as a 300-digit decimal (1e10 as 10000000000.0000);
/// now with four decimals in scientific notation from 1e6 on, in `check`'s report and
/// `simulate`'s warning.
#[test]
fn huge_ratios_are_printed_in_scientific_notation() {
    let dir = tempfile::tempdir().unwrap();
    let scene = anchored(dir.path(), 4e10);
    let out = cordis(&["check", &scene]);
    let report = String::from_utf8_lossy(&out.stderr);
    assert!(report.contains("max q = 1.0000e10"), "{report}");
    assert!(report.lines().all(|l| l.len() < 200), "{report}");
    let out = cordis(&["simulate", &scene, "-n", "3", "-q"]);
    let warning = String::from_utf8_lossy(&out.stderr);
    assert!(
        warning.starts_with("warning: stability ratio 1.0000e10 ≥ 1"),
        "{warning}"
    );
}
