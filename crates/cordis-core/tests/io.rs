//! Trajectory files (CSV, .npy, .tra) and the thesis' model files: round trips, every
//! malformed case with its placed message, and parsers that never panic.

use std::path::{Path, PathBuf};

use cordis_core::io::{self, csv, npy, tra, TrajectoryFormat};
use cordis_core::thesis::{self, Family};
use cordis_core::{CordisError, LinkKind, LinkType, Particle, Scene, Trajectory};
use proptest::prelude::*;

fn fixtures() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tests/fixtures/thesis")
}

fn traj(frames: usize, n: usize) -> Trajectory {
    let data = (0..frames * n * 3)
        .map(|k| (k as f64 * 0.37).sin() * 10f64.powi((k % 7) as i32 - 3))
        .collect();
    Trajectory::from_flat(frames, n, data).unwrap()
}

fn bits(t: &Trajectory) -> Vec<u64> {
    t.as_flat().iter().map(|v| v.to_bits()).collect()
}

/// The error's one-line message, after checking it names `place` and says `what`.
#[track_caller]
fn assert_err<T: std::fmt::Debug>(r: Result<T, CordisError>, place: &str, what: &str) {
    let msg = r.expect_err("expected an error").to_string();
    assert!(msg.contains(place), "`{msg}` does not name `{place}`");
    assert!(msg.contains(what), "`{msg}` does not say `{what}`");
    assert!(!msg.contains('\n'), "`{msg}` is not one line");
}

// ---------------------------------------------------------------- CSV

#[test]
fn csv_round_trip_is_bit_exact_for_awkward_values() {
    let data = vec![
        -0.0,
        5e-324,
        f64::MAX,
        f64::MIN_POSITIVE,
        0.1 + 0.2,
        -1e300,
        1.0 / 3.0,
        123456789.12345679,
        -7.0,
    ];
    let t = Trajectory::from_flat(1, 3, data).unwrap();
    let back = csv::parse_csv("t.csv", &csv::write_csv(&t)).unwrap();
    assert_eq!(bits(&back), bits(&t));
    assert_eq!((back.frames(), back.particles()), (1, 3));
}

#[test]
fn csv_malformed_cases_name_file_and_line() {
    let h = "frame,particle,x,y,z\n";
    let p = |s: &str| csv::parse_csv("run.csv", s);
    assert_err(p(""), "run.csv", "empty file");
    assert_err(p("\n  \n"), "run.csv", "empty file");
    assert_err(p(h), "run.csv", "no rows");
    assert_err(
        p("frame,particle,x,y\n0,0,1,2\n"),
        "run.csv:1",
        "wrong header",
    );
    assert_err(
        p("t,i,x,y,z\n"),
        "run.csv:1",
        "expected `frame,particle,x,y,z`",
    );
    assert_err(p(&format!("{h}0,0,1,2\n")), "run.csv:2", "short row");
    assert_err(p(&format!("{h}0,0,1,2,3,4\n")), "run.csv:2", "long row");
    assert_err(
        p(&format!("{h}0,0,1,2,3\n1,0,a,2,3\n")),
        "run.csv:3",
        "x `a` is not a number",
    );
    assert_err(
        p(&format!("{h}0,0,1,NaN,3\n")),
        "run.csv:2",
        "y is NaN (a gap): this command needs complete motion",
    );
    assert_err(
        p(&format!("{h}0,0,1,,3\n")),
        "run.csv:2",
        "y is empty (a gap): this command needs complete motion",
    );
    assert_err(
        p(&format!("{h}0,0,1,2,inf\n")),
        "run.csv:2",
        "must be finite",
    );
    assert_err(
        p(&format!("{h}-1,0,1,2,3\n")),
        "run.csv:2",
        "frame index -1 is negative",
    );
    assert_err(
        p(&format!("{h}0,1.5,1,2,3\n")),
        "run.csv:2",
        "not a whole number",
    );
    assert_err(
        p(&format!("{h}0,zz,1,2,3\n")),
        "run.csv:2",
        "particle index `zz` is not a number",
    );
    assert_err(
        p(&format!("{h}0,0,1,2,3\n0,1,1,2,3\n1,1,1,2,3\n")),
        "run.csv",
        "no row for frame 1, particle 0",
    );
    assert_err(
        p(&format!("{h}0,0,1,2,3\n0,2,1,2,3\n")),
        "run.csv",
        "no row for frame 0, particle 1",
    );
    assert_err(
        p(&format!("{h}0,0,1,2,3\n0,1,1,2,3\n0,0,4,5,6\n")),
        "run.csv:4",
        "duplicate row for frame 0, particle 0 (first given on line 2)",
    );
}

#[test]
fn csv_tolerates_crlf_bom_and_blank_lines() {
    let text = "\u{feff}frame , particle,x,y ,z\r\n\r\n0,0,1,2,3\r\n\r\n";
    let t = csv::parse_csv("a.csv", text).unwrap();
    assert_eq!(t.pos(0, 0).y, 2.0);
}

// ---------------------------------------------------------------- .npy

fn hex(s: &str) -> Vec<u8> {
    (0..s.len())
        .step_by(2)
        .map(|i| u8::from_str_radix(&s[i..i + 2], 16).unwrap())
        .collect()
}

/// Written by NumPy 2.4: `np.arange(12.).reshape(2, 2, 3) * 0.5 - 1.25`, saved in C order
/// (v1.0), Fortran order (v1.0), big-endian (v2.0) and v3.0.
const NP_HEAD: &str = "934e554d5059";
const NP_C_V1: &str = "010076007b276465736372273a20273c6638272c2027666f727472616e5f6f72646572273a2046616c73652c20277368617065273a2028322c20322c2033292c207d202020202020202020202020202020202020202020202020202020202020202020202020202020202020202020202020202020202020200a000000000000f4bf000000000000e8bf000000000000d0bf000000000000d03f000000000000e83f000000000000f43f000000000000fc3f000000000000024000000000000006400000000000000a400000000000000e400000000000001140";
const NP_F_V1: &str = "010076007b276465736372273a20273c6638272c2027666f727472616e5f6f72646572273a20547275652c20277368617065273a2028322c20322c2033292c207d20202020202020202020202020202020202020202020202020202020202020202020202020202020202020202020202020202020202020200a000000000000f4bf000000000000fc3f000000000000d03f0000000000000a40000000000000e8bf0000000000000240000000000000e83f0000000000000e40000000000000d0bf0000000000000640000000000000f43f0000000000001140";
const NP_BE_V2: &str = "0200740000007b276465736372273a20273e6638272c2027666f727472616e5f6f72646572273a2046616c73652c20277368617065273a2028322c20322c2033292c207d20202020202020202020202020202020202020202020202020202020202020202020202020202020202020202020202020202020200abff4000000000000bfe8000000000000bfd00000000000003fd00000000000003fe80000000000003ff40000000000003ffc00000000000040020000000000004006000000000000400a000000000000400e0000000000004011000000000000";
const NP_C_V3: &str = "0300740000007b276465736372273a20273c6638272c2027666f727472616e5f6f72646572273a2046616c73652c20277368617065273a2028322c20322c2033292c207d20202020202020202020202020202020202020202020202020202020202020202020202020202020202020202020202020202020200a000000000000f4bf000000000000e8bf000000000000d0bf000000000000d03f000000000000e83f000000000000f43f000000000000fc3f000000000000024000000000000006400000000000000a400000000000000e400000000000001140";

fn numpy_file(body: &str) -> Vec<u8> {
    hex(&format!("{NP_HEAD}{body}"))
}

#[test]
fn npy_reads_what_numpy_writes_in_every_layout() {
    let want: Vec<f64> = (0..12).map(|k| k as f64 * 0.5 - 1.25).collect();
    for body in [NP_C_V1, NP_F_V1, NP_BE_V2, NP_C_V3] {
        let t = npy::parse_npy("a.npy", &numpy_file(body)).unwrap();
        assert_eq!((t.frames(), t.particles()), (2, 2));
        assert_eq!(t.as_flat(), &want[..]);
    }
}

#[test]
fn npy_writes_what_numpy_writes() {
    let t = npy::parse_npy("a.npy", &numpy_file(NP_C_V1)).unwrap();
    assert_eq!(npy::write_npy(&t), numpy_file(NP_C_V1));
}

#[test]
fn npy_round_trip_is_bit_exact() {
    let mut data = traj(7, 5).into_flat();
    data[3] = -0.0;
    data[4] = 5e-324;
    let t = Trajectory::from_flat(7, 5, data).unwrap();
    let back = npy::parse_npy("t.npy", &npy::write_npy(&t)).unwrap();
    assert_eq!(bits(&back), bits(&t));
}

/// A v1.0 file with the given header dict and raw data.
fn npy_with(dict: &str, data: &[u8]) -> Vec<u8> {
    let mut out = b"\x93NUMPY\x01\x00".to_vec();
    let header = format!("{dict}\n");
    out.extend_from_slice(&(header.len() as u16).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    out.extend_from_slice(data);
    out
}

#[test]
fn npy_malformed_cases_say_what_is_wrong() {
    let d = |shape: &str, descr: &str| {
        format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}")
    };
    let eight: Vec<u8> = [1.0f64, 2.0, 3.0]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let p = |b: &[u8]| npy::parse_npy("m.npy", b);
    assert_err(p(b""), "m.npy", "not a .npy file");
    assert_err(
        p(b"PK\x03\x04 not numpy at all"),
        "m.npy",
        "not a .npy file",
    );
    assert_err(
        p(b"\x93NUMPY\x04\x00\x10\x00{}"),
        "m.npy",
        "version 4.0 is not supported",
    );
    assert_err(
        p(b"\x93NUMPY\x01\x00\xff\x00{'descr'"),
        "m.npy",
        "ends inside the header",
    );
    assert_err(
        p(b"\x93NUMPY\x02\x00\x01\x00"),
        "m.npy",
        "ends inside the header length",
    );
    assert_err(
        p(&npy_with(&d("(1, 1, 3)", "<i4"), &eight)),
        "m.npy",
        "dtype `<i4` is not read: expected float64",
    );
    assert_err(
        p(&npy_with(&d("(1, 3)", "<f8"), &eight)),
        "m.npy",
        "is not (frames, particles, 3)",
    );
    assert_err(
        p(&npy_with(&d("(1, 1, 4)", "<f8"), &eight)),
        "m.npy",
        "is not (frames, particles, 3)",
    );
    assert_err(
        p(&npy_with(&d("(0, 1, 3)", "<f8"), &[])),
        "m.npy",
        "is empty",
    );
    assert_err(
        p(&npy_with(&d("(2, 1, 3)", "<f8"), &eight)),
        "m.npy",
        "needs 48 bytes",
    );
    assert_err(
        p(&npy_with(
            &d("(1, 1, 3)", "<f8"),
            &[eight.clone(), vec![0]].concat(),
        )),
        "m.npy",
        "the file holds 25",
    );
    assert_err(
        p(&npy_with(&d("(4294967296, 4294967296, 3)", "<f8"), &eight)),
        "m.npy",
        "needs",
    );
    assert_err(
        p(&npy_with("{'descr': '<f8', 'shape': (1, 1, 3)}", &eight)),
        "m.npy",
        "no 'fortran_order' key",
    );
    assert_err(
        p(&npy_with(
            "{'descr': '<f8', 'fortran_order': Maybe, 'shape': (1, 1, 3)}",
            &eight,
        )),
        "m.npy",
        "expected True or False",
    );
    assert_err(
        p(&npy_with(
            "{'descr': '<f8', 'fortran_order': False, 'shape': (1, 1, 3), 'x': 1}",
            &eight,
        )),
        "m.npy",
        "unexpected key 'x'",
    );
    let nan: Vec<u8> = [1.0f64, f64::NAN, 3.0]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    assert_err(
        p(&npy_with(&d("(1, 1, 3)", "<f8"), &nan)),
        "m.npy: frame 0, particle 0, y",
        "not a finite number",
    );
}

// ---------------------------------------------------------------- .tra

#[test]
fn tra_round_trip_is_bit_exact() {
    let t = traj(4, 3);
    let text = tra::write_tra(&t);
    assert!(
        text.starts_with("Nombre de particules:3\nNombre de pas de temps:4\nPoints de l'image 1\n")
    );
    let back = tra::parse_tra("t.tra", &text).unwrap();
    assert_eq!(bits(&back), bits(&t));
}

#[test]
fn tra_reads_the_thesis_example_printed_on_one_line() {
    let text = std::fs::read_to_string(fixtures().join("exemple.tra")).unwrap();
    assert_eq!(text.lines().count(), 1);
    let t = tra::parse_tra("exemple.tra", &text).unwrap();
    assert_eq!((t.frames(), t.particles()), (2, 3));
    assert_eq!(t.pos(0, 2).z, -1.0727);
    assert_eq!(t.pos(1, 1).x, -1.146738);
}

#[test]
fn tra_accepts_frames_numbered_from_zero() {
    let text = "Nombre de particules : 1\nNombre de pas de temps:2\nPoints de l'image 0\n1 2 3\nPoints de l'image 1\n4 5 6\n";
    let t = tra::parse_tra("z.tra", text).unwrap();
    assert_eq!(t.pos(1, 0).x, 4.0);
}

#[test]
fn tra_malformed_cases_name_file_and_line() {
    let head = "Nombre de particules:2\nNombre de pas de temps:2\n";
    let p = |s: &str| tra::parse_tra("m.tra", s);
    assert_err(p(""), "m.tra", "empty file");
    assert_err(
        p("Nombre de masses:2\n"),
        "m.tra:1",
        "expected `Nombre de particules:N`",
    );
    assert_err(
        p("Nombre de particules:-2\n"),
        "m.tra:1",
        "not a non-negative integer",
    );
    assert_err(
        p("Nombre de particules:2\nNombre de pas de temps:0\n"),
        "m.tra:2",
        "at least one of each",
    );
    let f1 = "Points de l'image 1\n1 2 3\n4 5 6\n";
    assert_err(
        p(&format!("{head}{f1}")),
        "m.tra:5",
        "the file ends after 1 frames; the header says 2",
    );
    assert_err(
        p(&format!("{head}{f1}Points de l'image 2\n1 2 3\n")),
        "m.tra:7",
        "expected x of point 2 (of 2) in frame 2, found the end of the file",
    );
    assert_err(
        p(&format!(
            "{head}{f1}Points de l'image 2\n1 2 3\n4 5 6\n7 8 9\n"
        )),
        "m.tra:9",
        "unexpected `7` after the last frame",
    );
    assert_err(
        p(&format!("{head}{f1}Points de l'image 3\n1 2 3\n4 5 6\n")),
        "m.tra:6",
        "frame numbered 3, expected 2",
    );
    assert_err(
        p(&format!("{head}Points de l'image 1\n1 2 3\n4 five 6\n")),
        "m.tra:5",
        "expected y of point 2 (of 2) in frame 1, found `five`",
    );
    assert_err(
        p(&format!("{head}Points de l'image 1\n1 2 3\n4 nan 6\n")),
        "m.tra:5",
        "must be finite",
    );
    assert_err(
        p(&format!("{head}Points de l'image 1\n1 2 3\n4 1.2.3 6\n")),
        "m.tra:5",
        "`1.2.3` is not a number",
    );
}

// ---------------------------------------------------------------- files by extension

#[test]
fn files_round_trip_in_each_format_and_writes_are_atomic() {
    let dir = tempfile::tempdir().unwrap();
    let t = traj(3, 4);
    for ext in ["csv", "npy", "tra", "CSV"] {
        let path = dir.path().join(format!("run.{ext}"));
        std::fs::write(&path, "old content").unwrap();
        io::write_trajectory(&path, &t).unwrap();
        let back = io::read_trajectory(&path).unwrap();
        assert_eq!(bits(&back), bits(&t), "{ext}");
    }
    // Only the written files remain: no temporary left behind.
    let mut names: Vec<String> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    names.sort();
    assert_eq!(names, ["run.CSV", "run.csv", "run.npy", "run.tra"]);
}

#[test]
fn unknown_extension_lists_the_three_formats() {
    let t = traj(1, 1);
    for name in ["run.txt", "run", "dir/.csv.bak"] {
        assert_err(
            io::write_trajectory(Path::new(name), &t),
            name,
            ".csv, .npy or .tra",
        );
        assert_err(
            io::read_trajectory(Path::new(name)),
            name,
            ".csv, .npy or .tra",
        );
    }
    assert_eq!(
        TrajectoryFormat::from_path(Path::new("a.NpY")).unwrap(),
        TrajectoryFormat::Npy
    );
    let dir = tempfile::tempdir().unwrap();
    assert_err(
        io::write_trajectory(&dir.path().join("e.csv"), &Trajectory::zeros(0, 3)),
        "e.csv",
        "empty trajectory",
    );
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}

#[test]
fn io_errors_name_the_path() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("nope.csv");
    let e = io::read_trajectory(&missing).unwrap_err();
    assert!(matches!(e, CordisError::Io { .. }));
    assert!(e.to_string().contains("nope.csv"));
    let e = io::write_atomic(&dir.path().join("no_dir/x.json"), b"{}").unwrap_err();
    assert!(e.to_string().contains("no_dir"));
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
}

#[test]
fn parse_errors_from_files_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.csv");
    std::fs::write(&path, "frame,particle,x,y,z\n0,0,1,2\n").unwrap();
    assert_err(io::read_trajectory(&path), "bad.csv:2", "short row");
}

// ---------------------------------------------------------------- thesis files

#[test]
fn thesis_example_imports() {
    let m = thesis::import(&fixtures().join("exemple"), 0.01).unwrap();
    let s = &m.scene;
    assert_eq!(s.dt, 0.01);
    assert_eq!(s.particles.len(), 3);
    assert!(s
        .particles
        .iter()
        .all(|p| p.mass.value() == 1.0 && !p.fixed));
    assert_eq!(s.particles[2].pos, [1.0, 1.0, -1.0]);
    assert_eq!(s.particles[1].vel, [-0.1, -0.1, -0.1]);
    let names: Vec<&str> = s.types.iter().map(|t| t.name.as_str()).collect();
    assert_eq!(names, ["bp0", "bp1", "bp2"]);
    for (k, t) in s.types.iter().enumerate() {
        let v = 0.1 * (k + 1) as f64;
        assert_eq!(t.kind, LinkKind::Spring);
        assert_eq!(t.value("rest_length"), Some((k + 1) as f64));
        assert!((t.value("stiffness").unwrap() - v).abs() < 1e-15);
        assert!((t.value("damping").unwrap() - v).abs() < 1e-15);
    }
    let links: Vec<(usize, Vec<usize>)> = s
        .links
        .iter()
        .map(|l| (l.type_index, l.particles.clone()))
        .collect();
    assert_eq!(links, [(0, vec![0, 1]), (1, vec![1, 2]), (2, vec![2, 0])]);
    let tr = m.trajectory.as_ref().unwrap();
    assert_eq!((tr.frames(), tr.particles(), tr.dt), (2, 3, Some(0.01)));
    let g = m.gene.as_ref().unwrap();
    assert_eq!(
        (g.generation, g.population, g.pcross, g.reducer, g.damping),
        (Some(1000010), Some(2000), Some(15.0), Some(0.01), Some(0.0))
    );
    assert_eq!(m.lock.len(), 2);
    assert_eq!(m.lock[1].type_name(), "bp1");
    assert_eq!(m.lock[1].locked, [true, false, true]);
    // Accepted with the extension too.
    let again = thesis::import(&fixtures().join("exemple.mas"), 0.01).unwrap();
    assert_eq!(again, m);
}

#[test]
fn thesis_example_simulates_like_its_json() {
    let m = thesis::import(&fixtures().join("exemple"), 0.01).unwrap();
    let t = m.scene.simulate(500).unwrap();
    assert!(t.as_flat().iter().all(|v| v.is_finite()));
    // The triangle's springs pull: the particles move away from the initial positions.
    assert!((t.pos(499, 0) - t.pos(0, 0)).norm() > 1e-3);
    let back = Scene::from_json_str(&m.scene.to_json_string()).unwrap();
    assert_eq!(back, m.scene);
    assert_eq!(bits(&back.simulate(500).unwrap()), bits(&t));
}

#[test]
fn thesis_cat_to_json_to_cat_round_trips() {
    let m = thesis::import(&fixtures().join("exemple"), 0.01).unwrap();
    let cat = thesis::write_cat(&m.scene).unwrap();
    let via_json = Scene::from_json_str(&m.scene.to_json_string()).unwrap();
    assert_eq!(thesis::write_cat(&via_json).unwrap(), cat);
    let original = std::fs::read_to_string(fixtures().join("exemple.cat")).unwrap();
    assert_eq!(
        thesis::parse_cat("w.cat", &cat).unwrap(),
        thesis::parse_cat("exemple.cat", &original).unwrap()
    );
    // The written records have the width of the thesis' (l0 K Z and six mutabilities).
    assert!(cat.contains("\n1.0 0.1 0.1 0 0 0 0 0 0\n"), "{cat}");
}

#[test]
fn thesis_sav_reads_as_a_catalogue() {
    let text = std::fs::read_to_string(fixtures().join("exemple.sav")).unwrap();
    let types = thesis::parse_cat("exemple.sav", &text).unwrap();
    assert_eq!(
        thesis::read_catalogue(&fixtures().join("exemple.sav")).unwrap(),
        types
    );
    assert_eq!(types.len(), 3);
    assert_eq!(types[1].value("rest_length"), Some(10.688819));
    assert_eq!(types[1].value("stiffness"), Some(6.272265));
    assert_eq!(types[2].value("damping"), Some(0.468789));
}

#[test]
fn thesis_lock_example_reads() {
    let text = std::fs::read_to_string(fixtures().join("annexe.lock")).unwrap();
    let lock = thesis::parse_lock("annexe.lock", &text).unwrap();
    assert_eq!(lock.len(), 14);
    assert!(lock
        .iter()
        .all(|l| l.family == Family::BinaryVelocity && l.locked == [true; 3]));
    assert_eq!(lock[13].index, 13);
    assert_eq!(lock[13].extra.as_deref(), Some("0"));
    assert_eq!(
        thesis::parse_lock("w.lock", &thesis::write_lock(&lock)).unwrap(),
        lock
    );
}

/// A scene with one type of each family and non-trivial values everywhere.
fn five_family_scene() -> Scene {
    let mut s = Scene::new(0.005);
    for k in 0..4 {
        let x = k as f64;
        s.add_particle(Particle::new(0.5 + x, [x, 0.3 * x, -0.1]).with_vel([0.01 * x, -0.02, 0.0]));
    }
    s.add_type(
        LinkType::new("hold", LinkKind::Anchor)
            .with("stiffness", 3.0)
            .with("rest_length", 0.1)
            .with("damping", 0.2),
    );
    s.add_type(
        LinkType::new("rib", LinkKind::Spring)
            .with("stiffness", 20.0)
            .with("rest_length", 1.1)
            .with("damping", 0.05),
    );
    s.add_type(LinkType::new("air", LinkKind::Drag).with("damping", 0.3));
    s.add_type(
        LinkType::new("bend", LinkKind::Angle)
            .with("stiffness", 2.0)
            .with("rest_cos", -0.5),
    );
    s.add_type(LinkType::new("goo", LinkKind::Damper).with("damping", 0.7));
    s.add_type(
        LinkType::new("rib2", LinkKind::Spring)
            .with("stiffness", 10.0)
            .with("rest_length", 0.9),
    );
    s.add_link("rib", &[0, 1]);
    s.add_link("rib2", &[1, 2]);
    s.add_link("rib", &[2, 3]);
    s.add_link("hold", &[0]);
    s.add_link("air", &[3]);
    s.add_link("goo", &[0, 3]);
    s.add_link("bend", &[0, 1, 2]);
    s.validate().unwrap();
    s
}

#[test]
fn thesis_files_round_trip_every_family() {
    let dir = tempfile::tempdir().unwrap();
    let s = five_family_scene();
    let t = s.simulate(20).unwrap();
    let base = dir.path().join("five");
    thesis::export(&base, &s, Some(&t)).unwrap();
    let m = thesis::import(&base, s.dt).unwrap();
    assert_eq!(bits(m.trajectory.as_ref().unwrap()), bits(&t));
    // Types are renamed by family and regrouped in family order; the model is the same.
    let names: Vec<&str> = m.scene.types.iter().map(|t| t.name.as_str()).collect();
    assert_eq!(names, ["up0", "uv0", "bp0", "bp1", "bv0", "tp0"]);
    assert_eq!(m.scene.particles, s.particles);
    // Links are regrouped by family: compare them as sorted lists of what they are.
    let described = |sc: &Scene| {
        let mut v: Vec<String> = sc
            .links
            .iter()
            .map(|l| {
                let t = &sc.types[l.type_index];
                format!("{} {:?} {:?}", t.kind, t.params, l.particles)
            })
            .collect();
        v.sort();
        v
    };
    assert_eq!(described(&m.scene), described(&s));
    // Same model, but the force passes may sum in another order: equal to rounding.
    for (a, b) in m
        .scene
        .simulate(20)
        .unwrap()
        .as_flat()
        .iter()
        .zip(t.as_flat())
    {
        approx::assert_relative_eq!(a, b, max_relative = 1e-12, epsilon = 1e-15);
    }
    // Written again, the files are identical.
    assert_eq!(
        thesis::write_mas(&m.scene).unwrap(),
        thesis::write_mas(&s).unwrap()
    );
    assert_eq!(
        thesis::write_cat(&m.scene).unwrap(),
        thesis::write_cat(&s).unwrap()
    );
    assert_eq!(
        thesis::write_ini(&m.scene).unwrap(),
        thesis::write_ini(&s).unwrap()
    );
}

#[test]
fn thesis_initial_state_from_tra_without_ini() {
    let dir = tempfile::tempdir().unwrap();
    let src = fixtures();
    for f in ["exemple.mas", "exemple.cat", "exemple.tra"] {
        std::fs::copy(src.join(f), dir.path().join(f)).unwrap();
    }
    let m = thesis::import(&dir.path().join("exemple"), 0.5).unwrap();
    assert_eq!(m.scene.particles[2].pos, [1.1333, 1.1333, -1.0727]);
    let v = m.scene.particles[0].vel;
    assert_eq!(v[0], (1.234545 - 1.1111) / 0.5);
    assert!(m.gene.is_none() && m.lock.is_empty());

    std::fs::remove_file(dir.path().join("exemple.tra")).unwrap();
    assert_err(
        thesis::import(&dir.path().join("exemple"), 0.5),
        "exemple.ini",
        "no initial state",
    );
    assert_err(
        thesis::import(&dir.path().join("exemple"), 0.0),
        "dt",
        "positive",
    );
    assert_err(
        thesis::import(&dir.path().join("other"), 0.5),
        "other.mas",
        "",
    );
}

const MAS_HEAD: &str = "Nombre de particules:2\n1\n2\n";

fn mas(body: &str) -> String {
    format!("{MAS_HEAD}Nombre de liaisons unaires-position installees:0\nNombre de liaisons unaires-vitesse installees:0\n{body}")
}

#[test]
fn thesis_mas_malformed_cases() {
    let p = |s: &str| thesis::parse_mas("m.mas", s);
    let tail = "Nombre de liaisons binaires-vitesse installees:0\nNombre de liaisons ternaires-position installees:0\n";
    let ok = mas(&format!(
        "Nombre de liaisons binaires-position installees:1\n0 0 1\n{tail}"
    ));
    assert_eq!(p(&ok).unwrap().links.len(), 1);
    assert_err(p(""), "m.mas:1", "expected `Nombre de particules:N`");
    assert_err(
        p("Nombre de particules:2\n1\n"),
        "m.mas:2",
        "expected the mass of particle 1 (of 2)",
    );
    assert_err(
        p("Nombre de particules:2\n1\n0\n"),
        "m.mas:3",
        "must be positive",
    );
    assert_err(
        p("Nombre de particules:0\n"),
        "m.mas",
        "at least one particle",
    );
    assert_err(
        p(&mas(&format!(
            "Nombre de liaisons binaires-position installees:1\n0 0 2\n{tail}"
        ))),
        "m.mas:7",
        "particle 2 does not exist",
    );
    assert_err(
        p(&mas(&format!(
            "Nombre de liaisons binaires-position installees:1\n0 1 1\n{tail}"
        ))),
        "m.mas:7",
        "linked to itself",
    );
    assert_err(
        p(&mas(&format!(
            "Nombre de liaisons binaires-position installees:1\n0 0 1\n1 0 1\n{tail}"
        ))),
        "m.mas:8",
        "more records than the previous count (1)?",
    );
    assert_err(
        p(&mas(&format!(
            "Nombre de liaisons binaires-position installees:2\n0 0 1\n{tail}"
        ))),
        "m.mas:8",
        "expected the type of link 1 (of 2) of liaisons binaires-position, found `Nombre`",
    );
    assert_err(p(&mas(tail)), "m.mas:6", "expected the header `Nombre de liaisons binaires-position installees:COUNT`, found `Nombre de liaisons binaires-vitesse installees`");
    assert_err(
        p(&format!("{ok}5\n")),
        "m.mas:10",
        "unexpected `5` after the last family",
    );
    assert_err(
        p(&mas(&format!(
            "Nombre de liaisons binaires-position installees:1\n0 0 x\n{tail}"
        ))),
        "m.mas:7",
        "particle 2 of link 0",
    );
}

#[test]
fn thesis_mas_type_beyond_the_catalogue_names_the_mas_line() {
    let dir = tempfile::tempdir().unwrap();
    let src = fixtures();
    for f in ["exemple.cat", "exemple.ini"] {
        std::fs::copy(src.join(f), dir.path().join(f)).unwrap();
    }
    let text = std::fs::read_to_string(src.join("exemple.mas"))
        .unwrap()
        .replace("2 2 0", "3 2 0");
    std::fs::write(dir.path().join("exemple.mas"), text).unwrap();
    assert_err(
        thesis::import(&dir.path().join("exemple"), 0.01),
        "exemple.mas:15",
        "type 3 of liaisons binaires-position: the catalogue has 3 such types",
    );

    std::fs::copy(src.join("exemple.mas"), dir.path().join("exemple.mas")).unwrap();
    std::fs::write(
        dir.path().join("exemple.lock"),
        "liaisons binaires position\n0 x x x\n7 x 0 0\n",
    )
    .unwrap();
    assert_err(
        thesis::import(&dir.path().join("exemple"), 0.01),
        "exemple.lock:3",
        "type 7 of liaisons binaires-position is not in",
    );

    std::fs::remove_file(dir.path().join("exemple.lock")).unwrap();
    std::fs::write(dir.path().join("exemple.ini"), "1 1 1 0 0 0\n").unwrap();
    assert_err(
        thesis::import(&dir.path().join("exemple"), 0.01),
        "exemple.ini:1",
        "expected x of particle 1 (of 3)",
    );
    std::fs::copy(src.join("exemple.ini"), dir.path().join("exemple.ini")).unwrap();
    std::fs::write(
        dir.path().join("Param.gene"),
        "population=2000\npopulation=ten\n",
    )
    .unwrap();
    assert_err(
        thesis::import(&dir.path().join("exemple"), 0.01),
        "Param.gene:2",
        "`ten` is not a non-negative integer",
    );
}

#[test]
fn thesis_cat_malformed_cases() {
    let p = |s: &str| thesis::parse_cat("c.cat", s);
    let head = "Nombre de liaisons unaires-position:0\nNombre de liaisons unaires-vitesse:0\n";
    let tail = "Nombre de liaisons binaires-vitesse:0\nNombre de liaisons ternaires-position:0\n";
    let cat = |bp: &str| format!("{head}{bp}{tail}");
    assert_eq!(
        p(&cat(
            "Nombre de liaisons binaires-position:2\n1 2 3\n4 5 6\n"
        ))
        .unwrap()
        .len(),
        2
    );
    assert_err(
        p(&cat(
            "Nombre de liaisons binaires-position:2\n1 2 3\n4 5 6 7\n",
        )),
        "c.cat:3",
        "found 7 numbers",
    );
    assert_err(
        p(&cat("Nombre de liaisons binaires-position:2\n1 2\n4 5\n")),
        "c.cat:3",
        "at least 3 numbers",
    );
    assert_err(
        p(&cat("Nombre de liaisons binaires-position:0\n1 2 3\n")),
        "c.cat:3",
        "0 types of liaisons binaires-position",
    );
    assert_err(
        p(&cat("Nombre de liaisons binaires-position:1\n1 -2 3\n")),
        "c.cat:4",
        "type 0 (bp0) of liaisons binaires-position: stiffness K is -2",
    );
    assert_err(
        p(&cat("Nombre de liaisons binaires-position:1\n1 2 -3\n")),
        "c.cat:4",
        "damping Z is -3",
    );
    assert_err(
        p(&cat("Nombre de liaisons binaires-position:1\n1 2 inf\n")),
        "c.cat:4",
        "must be finite",
    );
    assert_err(p(&format!("{head}Nombre de liaisons binaires-position:0\n")), "c.cat:3", "expected the header `Nombre de liaisons binaires-vitesse:COUNT`, found the end of the file");
    assert_err(
        p(&format!("{head}Nombre de liaisons binaires-position:0\n{tail}Nombre de liaisons ternaires-position:0\n")),
        "c.cat:6",
        "unexpected `Nombre` after the last family",
    );
    let angle = format!("{head}Nombre de liaisons binaires-position:0\nNombre de liaisons binaires-vitesse:0\nNombre de liaisons ternaires-position:1\n1.5 1 0\n");
    assert_err(
        p(&angle),
        "c.cat:6",
        "rest cosine is 1.5, must be in [-1, 1]",
    );
}

#[test]
fn thesis_lock_and_gene_malformed_cases() {
    let l = |s: &str| thesis::parse_lock("l.lock", s);
    assert_err(l("0 x x x 0\n"), "l.lock:1", "before any family header");
    assert_err(
        l("liaisons binaires position\n0 x x\n"),
        "l.lock:2",
        "3 fields",
    );
    assert_err(
        l("liaisons binaires position\n0 x x x 0 0\n"),
        "l.lock:2",
        "6 fields",
    );
    assert_err(
        l("liaisons binaires position\n-1 x x x\n"),
        "l.lock:2",
        "`-1` is not a non-negative integer",
    );
    assert_err(
        l("liaisons binaires position\n0 x x x\n\n0 0 0 0\n"),
        "l.lock:4",
        "listed twice",
    );
    assert_err(
        l("liaisons quaternaires position\n"),
        "l.lock:1",
        "neither a family header",
    );
    assert_err(
        l("liaisons binaires position\nliaisons binaires-position\n"),
        "l.lock:2",
        "appear twice",
    );
    let g = |s: &str| thesis::parse_gene("Param.gene", s);
    assert_err(
        g("generation=10\nmutation=3\n"),
        "Param.gene:2",
        "unknown key `mutation`",
    );
    assert_err(
        g("population=ten\n"),
        "Param.gene:1",
        "population: `ten` is not a non-negative integer",
    );
    assert_err(g("pcross=NaN\n"), "Param.gene:1", "not a finite number");
    assert_err(g("pcross 3\n"), "Param.gene:1", "is not `key=value`");
    assert_err(g("noise=0\nnoise=1\n"), "Param.gene:2", "given twice");
    assert_eq!(g(" noise = 0.5 \n").unwrap().noise, Some(0.5));
}

#[test]
fn thesis_writers_refuse_what_the_files_cannot_hold() {
    let mut s = five_family_scene();
    s.particles[1].fixed = true;
    assert_err(thesis::write_mas(&s), "particles[1].fixed", "cannot say so");
    let mut s = five_family_scene();
    s.gravity = [0.0, 0.0, -9.81];
    assert_err(thesis::write_cat(&s), "gravity", "cannot say so");
    let mut s = five_family_scene();
    s.add_type(LinkType::new("swim", LinkKind::NonlinearDrag));
    assert_err(
        thesis::write_ini(&s),
        "types.swim.kind",
        "nonlinear_drag has no family",
    );
    let mut s = five_family_scene();
    s.links[3].point = Some([9.0, 9.0, 9.0]);
    assert_err(
        thesis::write_mas(&s),
        "links[3].point",
        "not its particle's initial position",
    );
}

// ---------------------------------------------------------------- parsers never panic

/// Text made of the files' own words, numbers and separators, so that random inputs reach
/// deep into the parsers rather than failing on the first token.
fn soup() -> impl Strategy<Value = String> {
    let tok = prop::sample::select(vec![
        "Nombre",
        "de",
        "particules",
        "pas",
        "temps",
        "Points",
        "l'image",
        "liaisons",
        "unaires-position",
        "binaires-position",
        "ternaires-position",
        "unaires-vitesse",
        "binaires-vitesse",
        "installees",
        ":",
        "0",
        "1",
        "2",
        "3",
        "-1",
        "1.5",
        "nan",
        "inf",
        "x",
        "×",
        "=",
        ",",
        "\n",
        " ",
        "frame,particle,x,y,z",
        "1e308",
        "99999999999999999999",
        "generation",
        "noise",
    ]);
    prop::collection::vec(tok, 0..60).prop_map(|v| v.join(" "))
}

fn parse_all_text(s: &str) {
    let _ = csv::parse_csv("p", s);
    let _ = tra::parse_tra("p", s);
    let _ = thesis::parse_mas("p", s);
    let _ = thesis::parse_cat("p", s);
    let _ = thesis::parse_ini("p", s, 2);
    let _ = thesis::parse_lock("p", s);
    let _ = thesis::parse_gene("p", s);
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 400, ..ProptestConfig::default() })]

    #[test]
    fn random_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..300)) {
        for format in [TrajectoryFormat::Csv, TrajectoryFormat::Npy, TrajectoryFormat::Tra] {
            let _ = io::parse_trajectory("p", format, &bytes);
        }
        parse_all_text(&String::from_utf8_lossy(&bytes));
    }

    #[test]
    fn token_soup_never_panics(s in soup()) {
        parse_all_text(&s);
    }

    #[test]
    fn npy_with_random_header_never_panics(dict in "\\{[ '\":,()a-z_<>f8TrueFals0-9]{0,80}\\}", data in prop::collection::vec(any::<u8>(), 0..64)) {
        let _ = npy::parse_npy("p", &npy_with(&dict, &data));
    }

    #[test]
    fn every_format_round_trips_bit_exact(
        frames in 1usize..4,
        n in 1usize..4,
        seed in prop::collection::vec(any::<f64>().prop_filter("finite", |v| v.is_finite()), 36),
    ) {
        let data = seed[..frames * n * 3].to_vec();
        let t = Trajectory::from_flat(frames, n, data).unwrap();
        let csv_back = csv::parse_csv("p", &csv::write_csv(&t)).unwrap();
        let npy_back = npy::parse_npy("p", &npy::write_npy(&t)).unwrap();
        let tra_back = tra::parse_tra("p", &tra::write_tra(&t)).unwrap();
        for back in [csv_back, npy_back, tra_back] {
            prop_assert_eq!(bits(&back), bits(&t));
        }
    }
}

#[test]
fn thesis_files_in_latin1_read() {
    let dir = tempfile::tempdir().unwrap();
    let src = fixtures();
    for f in ["exemple.cat", "exemple.ini"] {
        std::fs::copy(src.join(f), dir.path().join(f)).unwrap();
    }
    // `installées` with its accent in Latin-1 (0xE9), as a French editor of 2002 would save it.
    let text = std::fs::read_to_string(src.join("exemple.mas")).unwrap();
    let bytes: Vec<u8> = text
        .replace("installees", "install\u{e9}es")
        .chars()
        .map(|c| c as u8)
        .collect();
    assert!(std::str::from_utf8(&bytes).is_err());
    std::fs::write(dir.path().join("exemple.mas"), bytes).unwrap();
    let m = thesis::import(&dir.path().join("exemple"), 0.01).unwrap();
    assert_eq!(m.scene.links.len(), 3);
}

#[test]
fn write_atomic_writes_through_devices_instead_of_replacing_them() {
    // Renaming a temporary over /dev/null would replace the device with a regular file.
    let null = std::path::Path::new("/dev/null");
    if std::fs::metadata(null).is_ok_and(|m| !m.is_file()) {
        cordis_core::io::write_atomic(null, b"discarded").unwrap();
        let meta = std::fs::metadata(null).unwrap();
        assert!(!meta.is_file(), "/dev/null must still be a device");
        assert_eq!(std::fs::read(null).unwrap().len(), 0);
    }
}

/// Issue 17: a symlink to `/dev/zero` as the trajectory, the scene or a thesis file was read
/// until memory ran out (in Python: `CordisIOError [Errno None] None`). Now refused with the
/// limit, naming the file: a stream after 256 MiB, a regular file before any read by its size.
#[test]
fn inputs_of_unbounded_size_are_refused_with_the_limit() {
    let dir = tempfile::tempdir().unwrap();
    let zero = dir.path().join("zero.csv");
    std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
    let t0 = std::time::Instant::now();
    let e = io::read_trajectory(&zero).unwrap_err();
    let text = e.to_string();
    assert!(
        matches!(&e, CordisError::Io { path, source }
            if *path == zero && source.kind() == std::io::ErrorKind::FileTooLarge),
        "{e:?}"
    );
    assert!(
        text.contains("more than the 268435456 bytes (256 MiB) read from a stream"),
        "{text}"
    );
    assert!(t0.elapsed().as_secs_f64() < 30.0);
    let scene = dir.path().join("zero.json");
    std::os::unix::fs::symlink("/dev/zero", &scene).unwrap();
    assert!(Scene::from_json_path(&scene)
        .unwrap_err()
        .to_string()
        .contains("256 MiB"));
    // A sparse 3 GiB file: refused by its size, nothing read.
    let huge = dir.path().join("huge.npy");
    std::fs::File::create(&huge)
        .unwrap()
        .set_len(3 << 30)
        .unwrap();
    let t0 = std::time::Instant::now();
    let text = io::read_trajectory(&huge).unwrap_err().to_string();
    assert!(
        text.contains("3221225472 bytes, larger than the 2147483648 bytes (2 GiB)"),
        "{text}"
    );
    assert!(t0.elapsed().as_secs_f64() < 1.0);
    // A directory is an I/O error naming it, not a panic or an empty read.
    let sub = dir.path().join("d.csv");
    std::fs::create_dir(&sub).unwrap();
    let e = io::read_trajectory(&sub).unwrap_err();
    assert!(e.to_string().contains("is a directory"), "{e}");
}
