//! `cordis import FILE --out traj.npy` converts the field's marker formats, and the commands
//! that take a trajectory read them by extension through the same reader.

mod common;

use std::fmt::Write;
use std::path::Path;

use common::{cordis, fails, rigid_dir, stderr};

/// A TRC file (mm, rate `1 / dt`) of a trajectory, with marker 0 dropped at `gap` frames.
fn write_trc(path: &Path, traj: &cordis_core::Trajectory, dt: f64, gap: &[usize]) {
    let (t, n) = (traj.frames(), traj.particles());
    let mut s = String::new();
    writeln!(s, "PathFileType\t4\t(X/Y/Z)\t{}", path.display()).unwrap();
    writeln!(s, "DataRate\tCameraRate\tNumFrames\tNumMarkers\tUnits\tOrigDataRate\tOrigDataStartFrame\tOrigNumFrames").unwrap();
    writeln!(
        s,
        "{}\t{}\t{t}\t{n}\tmm\t{}\t1\t{t}",
        1.0 / dt,
        1.0 / dt,
        1.0 / dt
    )
    .unwrap();
    let names: Vec<String> = (0..n).map(|i| format!("P{i}\t\t")).collect();
    writeln!(s, "Frame#\tTime\t{}", names.join("\t")).unwrap();
    let axes: Vec<String> = (1..=n).map(|i| format!("X{i}\tY{i}\tZ{i}")).collect();
    writeln!(s, "\t\t{}\n", axes.join("\t")).unwrap();
    for f in 0..t {
        write!(s, "{}\t{}", f + 1, f as f64 * dt).unwrap();
        for i in 0..n {
            let p = traj.pos(f, i);
            if i == 0 && gap.contains(&f) {
                s.push_str("\t\t\t");
            } else {
                write!(s, "\t{:?}\t{:?}\t{:?}", p.x * 1e3, p.y * 1e3, p.z * 1e3).unwrap();
            }
        }
        s.push('\n');
    }
    std::fs::write(path, s).unwrap();
}

#[test]
fn a_trc_converts_to_npy_with_nan_where_a_marker_is_missing() {
    let dir = rigid_dir();
    let d = dir.path();
    let traj = cordis_core::io::read_trajectory(&d.join("r.csv")).unwrap();
    write_trc(&d.join("r.trc"), &traj, 0.01, &[3, 4]);
    let out = cordis(d, &["import", "r.trc", "--out", "t.npy"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let err = stderr(&out);
    assert!(err.contains("read OpenSim TRC r.trc"), "{err}");
    assert!(err.contains("Units mm → m"), "{err}");
    let summary: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(summary["format"], "OpenSim TRC");
    assert_eq!(summary["missing"], 6);
    assert!((summary["dt"].as_f64().unwrap() - 0.01).abs() < 1e-12);
    let back = cordis_core::io::read_observations(&d.join("t.npy")).unwrap();
    assert_eq!(
        (back.frames(), back.particles()),
        (traj.frames(), traj.particles())
    );
    let n = traj.particles();
    for (k, (&v, &w)) in back.as_flat().iter().zip(traj.as_flat()).enumerate() {
        let (f, i) = (k / (3 * n), (k / 3) % n);
        if i == 0 && (f == 3 || f == 4) {
            assert!(v.is_nan(), "frame {f}: a missing marker is NaN, not {v}");
        } else {
            assert!((v - w).abs() < 1e-12, "frame {f} particle {i}: {v} vs {w}");
        }
    }
}

#[test]
fn cost_reads_a_trc_and_a_mapped_csv_by_extension() {
    let dir = rigid_dir();
    let d = dir.path();
    let traj = cordis_core::io::read_trajectory(&d.join("r.csv")).unwrap();
    write_trc(&d.join("r.trc"), &traj, 0.01, &[]);
    let cost = |args: &[&str]| -> f64 {
        let out = cordis(d, args);
        assert!(out.status.success(), "{args:?}: {}", stderr(&out));
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        v["total"].as_f64().unwrap()
    };
    let reference = cost(&["cost", "r.json", "-t", "r.csv"]);
    let from_trc = cost(&["cost", "r.json", "-t", "r.trc"]);
    assert!(
        (from_trc - reference).abs() <= 1e-9 * reference.abs().max(1e-12),
        "{from_trc} vs {reference}"
    );
    // The same motion as a wide table in cm with a time column, named by --columns.
    let mut s = String::from("Time");
    for i in 0..traj.particles() {
        write!(s, "\tp{i}:X\tp{i}:Y\tp{i}:Z").unwrap();
    }
    s.push('\n');
    for f in 0..traj.frames() {
        write!(s, "{}", f as f64 * 0.01).unwrap();
        for i in 0..traj.particles() {
            let p = traj.pos(f, i);
            write!(
                s,
                "\t{:?}\t{:?}\t{:?}",
                p.x * 100.0,
                p.y * 100.0,
                p.z * 100.0
            )
            .unwrap();
        }
        s.push('\n');
    }
    std::fs::write(d.join("w.tsv"), s).unwrap();
    let from_table = cost(&[
        "cost",
        "r.json",
        "-t",
        "w.tsv",
        "--columns",
        "time=Time,x=*:X",
        "--units",
        "cm",
    ]);
    assert!(
        (from_table - reference).abs() <= 1e-6 * reference.abs().max(1e-9),
        "{from_table} vs {reference}"
    );
}

#[test]
fn bad_input_is_one_line_naming_the_place_and_nothing_is_written() {
    let dir = rigid_dir();
    let d = dir.path();
    std::fs::write(d.join("m.csv"), "Frame,Marker,X,Y,Z\n0,A,1,2,3\n").unwrap();
    fails(
        d,
        &[
            "import",
            "m.csv",
            "--columns",
            "particle=Label",
            "--out",
            "o.npy",
        ],
        2,
        &[
            "m.csv:1: --columns names particle=Label",
            "(columns: Frame, Marker, X, Y, Z)",
        ],
    );
    std::fs::write(
        d.join("u.csv"),
        "frame,marker,x [mm],y [cm],z [mm]\n0,A,1,2,3\n",
    )
    .unwrap();
    fails(
        d,
        &["import", "u.csv", "--out", "o.npy"],
        2,
        &["u.csv:1: mixed units"],
    );
    let traj = cordis_core::io::read_trajectory(&d.join("r.csv")).unwrap();
    write_trc(&d.join("r.trc"), &traj, 0.01, &[]);
    let text = std::fs::read_to_string(d.join("r.trc")).unwrap();
    let wrong = text.replacen("\t30\t", "\t31\t", 1);
    std::fs::write(d.join("bad.trc"), wrong).unwrap();
    fails(
        d,
        &["import", "bad.trc", "--out", "o.npy"],
        2,
        &["bad.trc: wrong header count: NumFrames is 31 but the file has 30 rows"],
    );
    fails(
        d,
        &["import", "r.trc", "--units", "furlong", "--out", "o.npy"],
        2,
        &["--units: `furlong` is not a length unit"],
    );
    fails(d, &["import", "r.trc"], 2, &["--out: required"]);
    assert!(!d.join("o.npy").exists(), "a failed import writes nothing");
}

#[test]
fn the_thesis_import_is_unchanged_and_refuses_reader_options() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    fails(
        d,
        &["import", "tri", "--units", "mm"],
        2,
        &["--units: only for a trajectory file"],
    );
}

/// A float32 `.npy` (what trackers and `np.float32` arrays save) is read widened to f64, as
/// Python's `identify` takes the same array: the CLI refused it as "not float64".
#[test]
fn a_float32_npy_is_read_widened_to_f64() {
    let dir = rigid_dir();
    let d = dir.path();
    let traj = cordis_core::io::read_trajectory(&d.join("r.csv")).unwrap();
    let (t, n) = (traj.frames(), traj.particles());
    let header = format!("{{'descr': '<f4', 'fortran_order': False, 'shape': ({t}, {n}, 3), }}\n");
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend_from_slice(&(header.len() as u16).to_le_bytes());
    bytes.extend_from_slice(header.as_bytes());
    for v in traj.as_flat() {
        bytes.extend_from_slice(&(*v as f32).to_le_bytes());
    }
    std::fs::write(d.join("r32.npy"), bytes).unwrap();
    let out = cordis(d, &["import", "r32.npy", "--out", "r64.npy"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let back = cordis_core::io::read_trajectory(&d.join("r64.npy")).unwrap();
    let widened: Vec<f64> = traj.as_flat().iter().map(|v| *v as f32 as f64).collect();
    assert_eq!(back.as_flat(), &widened[..]);
    // And a command that fits reads it too.
    let out = cordis(d, &["cost", "r.json", "-t", "r32.npy"]);
    assert!(out.status.success(), "{}", stderr(&out));
}
