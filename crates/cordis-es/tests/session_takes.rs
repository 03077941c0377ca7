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

/// The same take given twice (a file twice, its copy, or a crop of it) is refused by name:
/// its noise would count twice and every standard error shrink by √2 unseen (a tester's
/// finding), with the request's `noise` added too (the data's own noise still counts twice).
#[test]
fn a_take_given_twice_or_cropped_is_refused() {
    let mut req = rigid_takes(&[40, 30, 40]);
    req.take_places = vec!["a.csv".into(), "b.csv".into(), "c.csv".into()];
    let e = refusal(req);
    assert_eq!(
        e.to_string(),
        "b.csv: is the start of a.csv (take 0), bit for bit: a take given twice counts its \
         noise twice and shrinks every standard error by √2"
    );
    assert!(
        matches!(e, CostError::Core(CordisError::Trajectory { .. })),
        "{e:?}"
    );
    let mut noisy = rigid_takes(&[40, 40]);
    noisy.noise = 1e-3;
    assert!(refusal(noisy)
        .to_string()
        .starts_with("--trajectory[1]: is the same motion as --trajectory[0] (take 0)"));
    // Another motion of the same object is a take of its own.
    let truth = examples::rigid();
    let first = truth.simulate(40).unwrap();
    let mut pushed = truth.clone();
    pushed.particles[0].vel[0] += 0.1;
    let takes = vec![
        Observations::from_trajectory(&first),
        Observations::from_trajectory(&pushed.simulate(40).unwrap()),
    ];
    let guess = with_unknown_boxes(&truth, 10.0, 3);
    assert!(Session::new(IdentifyRequest::with_takes(guess, takes)).is_ok());
}

/// A take of the fixed particles only, and a free particle no observation reaches, are bad
/// input named by the take's file before any run (they were the estimator's "take 1: …",
/// a run's failure with exit 1: a tester's finding).
#[test]
fn a_take_no_state_can_be_estimated_from_is_bad_input_named_by_its_file() {
    let mut truth = examples::random_network(0, 6, 2);
    let n0 = truth.num_particles();
    let fixed: Vec<usize> = (0..n0).filter(|&i| truth.particles[i].fixed).collect();
    let lone = truth.add_particle(cordis_core::Particle::new(1.0, [9.0, 9.0, 9.0]));
    let ty = truth.types[truth.links[0].type_index].name.clone();
    truth.add_link(&ty, &[fixed[0], lone]);
    let n = truth.num_particles();
    let traj = truth.simulate(30).unwrap();
    let take_hiding = |hidden: &dyn Fn(usize) -> bool| {
        let mut data = traj.as_flat().to_vec();
        for t in 0..30 {
            for i in (0..n).filter(|&i| hidden(i)) {
                data[(t * n + i) * 3..(t * n + i) * 3 + 3].fill(f64::NAN);
            }
        }
        Observations::from_flat(30, n, data).unwrap()
    };
    let complete = Observations::from_trajectory(&traj);
    for (hidden, said) in [
        (
            take_hiding(&|i| !fixed.contains(&i)),
            "b.csv: observes none of the scene's free particles".to_string(),
        ),
        (
            take_hiding(&|i| i == lone),
            format!("b.csv, particle {lone}: has no visible frame"),
        ),
    ] {
        let guess = with_unknown_boxes(&truth, 25.0, 0);
        let mut req = IdentifyRequest::with_takes(guess, vec![complete.clone(), hidden]);
        req.take_places = vec!["a.csv".into(), "b.csv".into()];
        let e = refusal(req);
        assert!(e.to_string().starts_with(&said), "{e}");
        assert!(
            matches!(e, CostError::Core(CordisError::Trajectory { .. })),
            "{e:?}"
        );
    }
}
