//! `cordis-bench stability` through the binary: JSON lines with the right verdicts.

use std::process::{Command, Output};

fn bench(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_cordis-bench"))
        .args(args)
        .output()
        .expect("run cordis-bench")
}

#[test]
fn bench_stability_quick_prints_json_lines_with_right_verdicts() {
    let out = bench(&[
        "stability",
        "--quick",
        "--frames",
        "800",
        "--long-steps",
        "2000",
        "--large-side",
        "10",
        "--identify-evals",
        "200",
        "--thesis",
        "/nonexistent/none",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let stdout = String::from_utf8(out.stdout).unwrap();
    let lines: Vec<serde_json::Value> = stdout
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert!(lines.iter().all(|v| v["bench"] == "stability"));
    let extremes = lines.iter().find(|v| v["case"] == "extremes").unwrap();
    assert_eq!(extremes["right"], extremes["runs"]);
    for v in lines.iter().filter(|v| v["case"] == "sweep") {
        let unstable_run = !v["diverged_frame"].is_null();
        // Beyond the bound the single mass diverges; inside it never does.
        if v["stable"] == true {
            assert!(!unstable_run, "{v}");
        }
    }
    for v in lines.iter().filter(|v| v["case"] == "limit") {
        let r = v["measured_over_bound"].as_f64().unwrap();
        assert!(r > 0.99, "the bound is safe: {v}");
    }
    // Long-cost identification over boxes 1e6 wide: rigid, horse, horse-gait × 2 strategies.
    let wide: Vec<_> = lines
        .iter()
        .filter(|v| v["case"] == "wide_identification")
        .collect();
    assert_eq!(wide.len(), 6);
    // An estimate is in its box and never NaN; a run with no finite cost (CMA-ES from the box
    // middle on the horses) says it has no estimate rather than hand back a point.
    for v in wide {
        assert_eq!(v["nan"], false, "{v}");
        match v["no_estimate"] == true {
            true => assert_eq!(v["finite"], false, "{v}"),
            false => assert_eq!(v["in_box"], true, "{v}"),
        }
    }
}
