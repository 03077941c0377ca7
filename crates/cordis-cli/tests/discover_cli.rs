//! `cordis discover` end to end: a generated network's trajectory file in, its scene out.

use std::collections::HashSet;

use cordis_core::examples::random_network;
use cordis_core::Scene;

fn pairs(scene: &Scene) -> HashSet<[usize; 2]> {
    scene
        .links
        .iter()
        .map(|l| {
            let (a, b) = (l.particles[0], l.particles[1]);
            [a.min(b), a.max(b)]
        })
        .collect()
}

#[test]
fn discover_writes_the_generating_network_and_its_scores() {
    let dir = tempfile::tempdir().unwrap();
    let truth = random_network(4, 12, 3);
    let traj = truth.simulate(300).unwrap();
    let csv = dir.path().join("net.csv");
    cordis_core::io::write_trajectory(&csv, &traj).unwrap();
    let total: f64 = truth
        .particles
        .iter()
        .filter(|p| !p.fixed)
        .map(|p| p.mass.value())
        .sum();
    let (out, scores) = (
        dir.path().join("found.json"),
        dir.path().join("scores.json"),
    );
    let s = |p: &std::path::Path| p.to_str().unwrap().to_string();
    let code = cordis_cli::run([
        "cordis".to_string(),
        "discover".into(),
        "--trajectory".into(),
        s(&csv),
        "--dt".into(),
        truth.dt.to_string(),
        "--total-mass".into(),
        total.to_string(),
        "--out".into(),
        s(&out),
        "--scores".into(),
        s(&scores),
        "-q".into(),
    ]);
    assert_eq!(code, 0);
    let found = Scene::from_json_path(&out).unwrap();
    assert_eq!(pairs(&found), pairs(&truth));
    assert_eq!(found.types.len(), 3);
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&scores).unwrap()).unwrap();
    assert_eq!(v["links"].as_array().unwrap().len(), truth.links.len());

    // No mass scale: a usage error (exit 2), no panic.
    let code = cordis_cli::run([
        "cordis",
        "discover",
        "--trajectory",
        &s(&csv),
        "--dt",
        "0.005",
    ]);
    assert_ne!(code, 0);
}

/// `--gravity` as documented (`X,Y,Z`) and as three values, taken as known (the scene carries
/// it exactly); two values are refused with a non-zero exit; the scores say the noise level
/// was estimated (noiseless data: 0).
#[test]
fn discover_takes_gravity_as_given_and_reports_the_estimated_noise() {
    let dir = tempfile::tempdir().unwrap();
    let truth = random_network(4, 12, 3);
    let traj = truth.simulate(300).unwrap();
    let csv = dir.path().join("net.csv");
    cordis_core::io::write_trajectory(&csv, &traj).unwrap();
    let total: f64 = truth
        .particles
        .iter()
        .filter(|p| !p.fixed)
        .map(|p| p.mass.value())
        .sum();
    let s = |p: &std::path::Path| p.to_str().unwrap().to_string();
    let g = truth.gravity;
    let given = [
        vec![format!("--gravity={},{},{}", g[0], g[1], g[2])],
        vec![
            "--gravity".to_string(),
            g[0].to_string(),
            g[1].to_string(),
            g[2].to_string(),
        ],
    ];
    for (k, gravity) in given.iter().enumerate() {
        let (out, scores) = (
            dir.path().join(format!("found{k}.json")),
            dir.path().join(format!("scores{k}.json")),
        );
        let mut args = vec![
            "cordis".to_string(),
            "discover".into(),
            "--trajectory".into(),
            s(&csv),
            "--dt".into(),
            truth.dt.to_string(),
            "--total-mass".into(),
            total.to_string(),
            "--out".into(),
            s(&out),
            "--scores".into(),
            s(&scores),
            "-q".into(),
        ];
        args.extend(gravity.iter().cloned());
        assert_eq!(cordis_cli::run(args), 0, "{gravity:?}");
        let found = Scene::from_json_path(&out).unwrap();
        assert_eq!(found.gravity, g, "{gravity:?}");
        assert_eq!(pairs(&found), pairs(&truth));
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&scores).unwrap()).unwrap();
        assert_eq!(v["noise_estimated"], true);
        assert_eq!(v["noise_level"], 0.0);
    }
    let code = cordis_cli::run([
        "cordis",
        "discover",
        "--trajectory",
        &s(&csv),
        "--dt",
        "0.005",
        "--total-mass",
        "3",
        "--gravity=1,2",
    ]);
    assert_eq!(code, 2);
}

/// `--kinds`: a network with a damper and a link to a fixed particle is found with each link's
/// kind in the scores and a damper type in the scene; `--kinds spring,anchor` leaves the damper
/// out (its force then falls on other links); an unknown kind is refused (exit 2).
#[test]
fn discover_reports_each_links_kind_and_takes_the_kinds_to_look_for() {
    use cordis_core::examples::{varied_network, VariedKinds};
    let dir = tempfile::tempdir().unwrap();
    // Seed 2 of the varied generator: two dampers, two fixed particles.
    let (truth, case) = varied_network(2, VariedKinds::ALL);
    assert!(case.dampers > 0 && case.fixed > 0, "{case:?}");
    let traj = truth.simulate(300).unwrap();
    let csv = dir.path().join("net.csv");
    cordis_core::io::write_trajectory(&csv, &traj).unwrap();
    let total: f64 = truth
        .particles
        .iter()
        .filter(|p| !p.fixed)
        .map(|p| p.mass.value())
        .sum();
    let s = |p: &std::path::Path| p.to_str().unwrap().to_string();
    let run = |extra: &[&str], out: &std::path::Path, scores: &std::path::Path| {
        let mut args: Vec<String> = [
            "cordis",
            "discover",
            "-t",
            &s(&csv),
            "--dt",
            &truth.dt.to_string(),
            "--total-mass",
            &total.to_string(),
            "--out",
            &s(out),
            "--scores",
            &s(scores),
            "-q",
        ]
        .iter()
        .map(|a| a.to_string())
        .collect();
        args.extend(extra.iter().map(|a| a.to_string()));
        cordis_cli::run(args)
    };
    let (out, scores) = (dir.path().join("f.json"), dir.path().join("s.json"));
    assert_eq!(run(&[], &out, &scores), 0);
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&scores).unwrap()).unwrap();
    let kinds: Vec<&str> = v["links"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| l["kind"].as_str().unwrap())
        .collect();
    let count = |k: &str| kinds.iter().filter(|x| **x == k).count();
    let dampers = truth
        .links
        .iter()
        .filter(|l| truth.types[l.type_index].kind == cordis_core::LinkKind::Damper)
        .count();
    assert_eq!(count("damper"), dampers, "{kinds:?}");
    assert!(count("anchor") > 0 && count("spring") > 0, "{kinds:?}");
    let found = Scene::from_json_path(&out).unwrap();
    assert!(found
        .types
        .iter()
        .any(|t| t.kind == cordis_core::LinkKind::Damper));

    assert_eq!(run(&["--kinds", "spring,anchor"], &out, &scores), 0);
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&scores).unwrap()).unwrap();
    assert!(v["links"]
        .as_array()
        .unwrap()
        .iter()
        .all(|l| l["kind"] != "damper"));

    assert_eq!(run(&["--kinds", "spring,dumper"], &out, &scores), 2);
}
