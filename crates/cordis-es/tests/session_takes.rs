//! The session's refusals of a take that cannot be read: bad input (a core `Trajectory` or an
//! `Invalid` option, exit 2 in the CLI) named by the take's file, whatever the take's position.
//! A short second take used to reach the output-error estimator and fail as a run (exit 1,
//! `output-error: take 1: …`), and a marker count that did not fit was blamed on the
//! trajectory option without naming the file.

use cordis_core::{examples, CordisError, Observations};
use cordis_es::identify::with_unknown_boxes;
use cordis_es::session::{IdentifyRequest, Session};
use cordis_es::CostError;

fn rigid_takes(frames: &[usize]) -> IdentifyRequest {
    let truth = examples::rigid();
    let takes = frames
        .iter()
        .map(|&f| Observations::from_trajectory(&truth.simulate(f).expect("rigid simulates")))
        .collect();
    IdentifyRequest::with_takes(with_unknown_boxes(&truth, 10.0, 3), takes)
}

fn refusal(req: IdentifyRequest) -> CostError {
    match Session::new(req) {
        Ok(_) => panic!("the session accepted the request"),
        Err(e) => e,
    }
}

#[test]
fn a_take_too_short_is_bad_input_named_by_its_file_at_any_position() {
    for (frames, at) in [(&[2][..], 0), (&[40, 2], 1), (&[40, 1], 1)] {
        let mut req = rigid_takes(frames);
        req.take_places = ["a.csv", "b.csv"][..frames.len()]
            .iter()
            .map(|s| s.to_string())
            .collect();
        let e = refusal(req);
        let f = frames[at];
        let said = match f {
            1 => "has 1 frame, at least 3 are needed".to_string(),
            _ => format!("has {f} frames, at least 3 are needed"),
        };
        assert_eq!(e.to_string(), format!("{}: {said}", ["a.csv", "b.csv"][at]));
        assert!(
            matches!(e, CostError::Core(CordisError::Trajectory { .. })),
            "{frames:?}: not bad input: {e:?}"
        );
    }
    // Without file names, the option as the front end spells it, indexed among several.
    assert_eq!(
        refusal(rigid_takes(&[40, 2])).to_string(),
        "--trajectory[1]: has 2 frames, at least 3 are needed"
    );
}

#[test]
fn a_marker_count_that_does_not_fit_names_the_option_and_the_file() {
    let mut req = rigid_takes(&[40]);
    req.take_places = vec!["a.csv".into()];
    req.markers = Some(vec![0, 1, 2]);
    let e = refusal(req);
    assert_eq!(
        e.to_string(),
        "--markers: names 3 particles for the 15 markers of a.csv"
    );
    assert!(matches!(e, CostError::Invalid { .. }), "{e:?}");
    // The weights are counted against each take, the second one's file named.
    let mut req = rigid_takes(&[40, 40]);
    req.take_places = vec!["a.csv".into(), "b.csv".into()];
    // Take 1 without its last particle: 14 markers.
    let all = req.takes[1].as_flat().to_vec();
    let fewer: Vec<f64> = all
        .chunks(15 * 3)
        .flat_map(|f| f[..14 * 3].to_vec())
        .collect();
    req.takes[1] = Observations::from_flat(40, 14, fewer).unwrap();
    req.weights = Some(vec![1.0; 15]);
    let e = refusal(req);
    assert!(
        e.to_string()
            .starts_with("--weights: holds 15 values for the 14 markers of b.csv"),
        "{e}"
    );
}

#[test]
fn a_take_with_every_coordinate_missing_names_its_file() {
    let mut req = rigid_takes(&[40, 40]);
    req.take_places = vec!["a.csv".into(), "gone.csv".into()];
    req.takes[1] = Observations::from_flat(40, 15, vec![f64::NAN; 40 * 15 * 3]).unwrap();
    let e = refusal(req);
    assert_eq!(e.to_string(), "gone.csv: every coordinate is missing");
    assert!(
        matches!(e, CostError::Core(CordisError::Trajectory { .. })),
        "{e:?}"
    );
}
