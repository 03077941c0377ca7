//! Ctrl-C and a run's label: a fit that has met its own criterion is reported as converged
//! even if the interrupt arrives before the run loop looks again (the CLI said `interrupted`
//! and exited 130 after a converged fit whose uncertainty was computed: a new user's finding).

use std::sync::atomic::{AtomicBool, Ordering};

use cordis_core::examples;
use cordis_es::executor::{HistoryRow, Observer, StopReason};
use cordis_es::identify::{add_noise, with_unknown_boxes};
use cordis_es::session::{IdentifyRequest, Session};

/// Presses Ctrl-C after every generation.
struct CtrlC<'a>(&'a AtomicBool);

impl Observer for CtrlC<'_> {
    fn observe(&mut self, _: &HistoryRow) -> bool {
        self.0.store(true, Ordering::Relaxed);
        true
    }
}

fn run_pressing_ctrl_c(req: IdentifyRequest) -> StopReason {
    let flag = AtomicBool::new(false);
    let mut press = CtrlC(&flag);
    let out = Session::new(req)
        .expect("the session prepares")
        .run(&mut [&mut press], Some(&flag))
        .expect("the run ends");
    out.result.stopped_by
}

#[test]
fn ctrl_c_after_the_fit_met_its_criterion_keeps_its_end_and_before_it_interrupts() {
    let truth = examples::rigid();
    let guess = with_unknown_boxes(&truth, 10.0, 3);
    // Noiseless: the exact least-squares solve ends in its first generation, converged.
    let exact = IdentifyRequest::new(guess.clone(), truth.simulate(40).unwrap());
    assert_eq!(run_pressing_ctrl_c(exact), StopReason::Converged);
    // Noisy: output-error's first window is one generation of several; the press stops it.
    let noisy = truth.simulate(100).unwrap();
    let tracked = IdentifyRequest::new(guess, add_noise(&noisy, 1e-3 * noisy.scale(), 0));
    assert_eq!(run_pressing_ctrl_c(tracked), StopReason::Interrupted);
}
