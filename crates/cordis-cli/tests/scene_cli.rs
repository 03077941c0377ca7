//! `cordis scene from-markers`: a network built on the soft block's tracked markers, which
//! `cordis identify` then fits as it is (no hand edits).

mod common;

use std::path::{Path, PathBuf};

use common::{cordis, fails, stderr};

fn soft_block() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/data/soft-block")
}

fn json(path: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

#[test]
fn from_markers_on_the_soft_block_gives_a_scene_identify_fits() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let sb = soft_block();
    let markers = sb.join("markers.csv");
    let markers = markers.to_str().unwrap();
    let out = cordis(
        d,
        &[
            "scene",
            "from-markers",
            markers,
            "--dt",
            "0.01",
            "--total-mass",
            "0.54",
            "--radius",
            "0.18",
            "--out",
            "block.json",
        ],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let scene = json(&d.join("block.json"));
    let truth = json(&sb.join("truth.json"));
    let fixed = |s: &serde_json::Value| -> Vec<bool> {
        s["particles"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| p["fixed"].as_bool() == Some(true))
            .collect()
    };
    assert_eq!(
        fixed(&scene),
        fixed(&truth),
        "the clamped markers are found fixed"
    );
    assert_eq!(scene["links"].as_array().unwrap().len(), 158);
    assert_eq!(
        scene["types"].as_object().unwrap().len(),
        3,
        "edge, face, body"
    );
    let out = cordis(
        d,
        &["identify", "block.json", "-t", markers, "--out", "fit.json"],
    );
    assert!(out.status.success(), "{}", stderr(&out));
    let line = String::from_utf8_lossy(&out.stdout);
    let summary: serde_json::Value = serde_json::from_str(line.lines().last().unwrap()).unwrap();
    assert_eq!(summary["strategy"], "output-error", "{summary}");
    // The fixed markers sit at their mean position (at their first, noisy frame the fit
    // ended above the noise in a wrong basin): the network on the markers is the truth's
    // (uniform masses, one type per length family) and the fit converges at the noise.
    assert_eq!(summary["solver"]["end"], "converged", "{summary}");
    assert_eq!(summary["stopped_by"], "converged", "{summary}");
    let rmse = summary["rmse"].as_f64().unwrap();
    assert!((0.95e-3..1.05e-3).contains(&rmse), "{summary}");
    assert!(
        !stderr(&out).contains("above the data's noise level"),
        "{}",
        stderr(&out)
    );
    // The families are the truth's types in increasing length: edge, face, body; each true
    // value within 3 of its standard errors.
    let fit = json(&d.join("fit.json"));
    let errors = summary["solver"]["uncertainty"].as_array().unwrap();
    let std_error = |name: &str| {
        let u = errors.iter().find(|u| u["name"] == name).unwrap();
        u["std_error"].as_f64().unwrap()
    };
    let mut worst = [0.0f64; 3];
    for (k, name) in ["edge", "face", "body"].iter().enumerate() {
        let (t, f) = (&truth["types"][name], &fit["types"][format!("family_{k}")]);
        for (p, key) in ["stiffness", "rest_length", "damping"].iter().enumerate() {
            let (want, got) = (t[key].as_f64().unwrap(), f[key].as_f64().unwrap());
            worst[p] = worst[p].max((got - want).abs() / want);
            let se = std_error(&format!("types.family_{k}.{key}"));
            assert!(
                (got - want).abs() < 3.0 * se,
                "{name}.{key}: {got} ± {se}, truth {want}"
            );
        }
    }
    // Measured: stiffness 1.2 %, rest length 0.43 %, damping 19.5 % at worst (the body
    // springs; 1 mm noise, the Cramér–Rao bound of the data set's README is 1 %, 0.35 %, 13 %).
    assert!(
        worst[0] < 0.03 && worst[1] < 0.01 && worst[2] < 0.3,
        "{worst:?}"
    );
}

#[test]
fn bad_options_are_one_line_naming_them() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let markers = soft_block().join("markers.csv");
    let markers = markers.to_str().unwrap();
    let base = ["scene", "from-markers", markers, "--total-mass", "0.54"];
    fails(d, &base, 2, &["the file records no rate: give --dt"]);
    let with = |extra: &[&'static str]| [&base[..], &["--dt", "0.01"], extra].concat();
    fails(d, &with(&["--radius", "0.001"]), 2, &["--radius: no pair"]);
    fails(d, &with(&["--neighbours", "40"]), 2, &["--neighbours: 40"]);
    fails(d, &with(&["--width", "1"]), 2, &["--width"]);
    fails(d, &with(&["--gravity", "0,1"]), 2, &["--gravity"]);
}
