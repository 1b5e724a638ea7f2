//! Long work with Ctrl-C: run in a worker thread with the GIL released while the calling
//! thread looks for signals.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::sync::Mutex;
use std::time::Duration;

use isomesh::Error;
use pyo3::prelude::*;

use crate::callable::PyFunction;
use crate::to_py;

/// How often the calling thread looks for Ctrl-C while work runs.
const POLL: Duration = Duration::from_millis(50);

/// Runs `work` in a worker thread; this thread waits with the GIL released, looking for
/// Ctrl-C every 50 ms. A KeyboardInterrupt sets `cancel` (which `work` polls), waits for
/// `work` to end, and is raised; else what the Python function `callable` raised is, else
/// `work`'s result (a panic in it as an error, not a crash).
pub(crate) fn interruptible<T: Send>(
    py: Python<'_>,
    cancel: &AtomicBool,
    callable: Option<&PyFunction>,
    work: impl FnOnce() -> isomesh::Result<T> + Send,
) -> PyResult<T> {
    let (tx, rx) = mpsc::channel();
    let rx = Mutex::new(rx);
    let mut interrupt: Option<PyErr> = None;
    let outcome = std::thread::scope(|s| {
        s.spawn(move || {
            let r = catch_unwind(AssertUnwindSafe(work));
            let _ = tx.send(r.unwrap_or_else(|p| Err(Error::Trace(panic_message(&p)))));
        });
        loop {
            match py.detach(|| {
                rx.lock()
                    .unwrap_or_else(|e| e.into_inner())
                    .recv_timeout(POLL)
            }) {
                Ok(r) => break r,
                Err(RecvTimeoutError::Timeout) => {
                    if interrupt.is_none() {
                        if let Err(e) = py.check_signals() {
                            cancel.store(true, Ordering::Relaxed);
                            interrupt = Some(e);
                        }
                    }
                }
                Err(RecvTimeoutError::Disconnected) => {
                    break Err(Error::Trace(
                        "the worker thread ended without a result".into(),
                    ))
                }
            }
        }
    });
    if let Some(e) = interrupt {
        return Err(e);
    }
    if let Some(e) = callable.and_then(|c| c.take_error()) {
        return Err(e);
    }
    outcome.map_err(to_py)
}

fn panic_message(p: &Box<dyn std::any::Any + Send>) -> String {
    let what = p
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| p.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown".into());
    format!("internal error (please report): {what}")
}
