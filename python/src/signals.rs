//! Long Rust work run from Python without the GIL, Ctrl-C still heard.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc;
use std::time::Duration;

use pyo3::prelude::*;

/// How often the waiting thread checks for Ctrl-C.
const SIGNAL_POLL: Duration = Duration::from_millis(50);

/// Runs `work` on a worker thread without the GIL while this thread, the one Python delivers
/// signals to, checks for Ctrl-C every [`SIGNAL_POLL`]: on one, `interrupt` is raised (the
/// work's halt flag) and the signal's exception returned beside the work's result. `Err` when
/// the worker panicked.
pub(crate) fn with_signals<T: Send>(
    py: Python<'_>,
    interrupt: &AtomicBool,
    work: impl FnOnce() -> T + Send,
) -> (std::thread::Result<T>, Option<PyErr>) {
    py.detach(|| {
        let (done, finished) = mpsc::channel::<()>();
        std::thread::scope(|s| {
            let worker = s.spawn(move || {
                let r = work();
                let _ = done.send(());
                r
            });
            let mut signal = None;
            loop {
                match finished.recv_timeout(SIGNAL_POLL) {
                    Err(mpsc::RecvTimeoutError::Timeout) if signal.is_none() => {
                        if let Err(e) = Python::attach(|py| py.check_signals()) {
                            signal = Some(e);
                            interrupt.store(true, Ordering::Relaxed);
                        }
                    }
                    Err(mpsc::RecvTimeoutError::Timeout) => {}
                    // Finished, or the worker panicked and dropped its sender.
                    _ => break,
                }
            }
            (worker.join(), signal)
        })
    })
}
