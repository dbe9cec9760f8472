//! Ctrl-C during a long call: Python delivers SIGINT to its main thread as
//! a flag that only the interpreter reads, so a call that runs for seconds
//! with the interpreter released must look at it itself.
//!
//! Two ways, by the shape of the work:
//! - a batch ([`in_slices`]) runs in slices of [`SLICE`] rows and checks
//!   for signals between slices, so it stops within one slice;
//! - a long computation of the library (building tables, the results
//!   table, the sweep, a target search: [`cancellable`]) runs on a thread
//!   of its own while the calling thread waits for it, checking for
//!   signals every [`POLL`]. On Ctrl-C the call raises `KeyboardInterrupt`
//!   at once; the computation is told to stop through its [`Checkpoint`],
//!   which it passes at each step it reports (a report's samplers, a
//!   search's tolerances), and its result is dropped. A build of tables
//!   reports no steps: it runs to its end in the background.

use std::any::Any;
use std::panic::{catch_unwind, resume_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::sync::Arc;
use std::time::Duration;

use pyo3::prelude::*;

use crate::arrays::chunked_by;
use crate::errors::raise;

/// Rows per slice of a batch call: between two slices it checks for
/// Ctrl-C (a slice takes milliseconds).
pub const SLICE: usize = 1 << 16;

/// How often a call waiting for a [`cancellable`] computation checks for
/// Ctrl-C.
pub const POLL: Duration = Duration::from_millis(20);

/// Run `each(start_row, out_slice)` over `out` (`width` values per row) in
/// slices of [`SLICE`] rows, each with the interpreter released and in
/// parallel when large ([`chunked_by`]); between slices, pending signals
/// are handled, so Ctrl-C raises `KeyboardInterrupt` and leaves `out`
/// partly filled (the caller drops it).
pub fn in_slices<T: Send>(
    py: Python<'_>,
    out: &mut [T],
    width: usize,
    each: impl Fn(usize, &mut [T]) + Sync + Send,
) -> PyResult<()> {
    for (k, slice) in out.chunks_mut(SLICE * width).enumerate() {
        let each = &each;
        py.detach(move || chunked_by(slice, width, |start, c| each(k * SLICE + start, c)));
        py.check_signals()?;
    }
    Ok(())
}

/// The payload with which a cancelled computation unwinds.
struct Cancelled;

/// Passed to a [`cancellable`] computation: [`check`](Self::check) ends it
/// once the caller has been interrupted.
#[derive(Clone)]
pub struct Checkpoint(Arc<AtomicBool>);

impl Checkpoint {
    /// Return if the call goes on; unwind out of the computation (caught by
    /// [`cancellable`], no panic message) if it was interrupted. Call it
    /// only where unwinding leaves nothing half-written (a progress report
    /// of the library: between steps).
    pub fn check(&self) {
        if self.0.load(Ordering::Relaxed) {
            resume_unwind(Box::new(Cancelled));
        }
    }
}

/// The text of a panic's payload.
fn panic_text(payload: &(dyn Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| s.to_string())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "unknown panic".to_string())
}

/// Run `work` on a new thread and wait for it with the interpreter
/// released, handling signals every [`POLL`]: Ctrl-C raises
/// `KeyboardInterrupt` at once and sets the flag `work`'s [`Checkpoint`]
/// reads. A panic of `work` (a bug) becomes `acdf.Error`, never a crash.
pub fn cancellable<R: Send + 'static>(
    py: Python<'_>,
    work: impl FnOnce(&Checkpoint) -> R + Send + 'static,
) -> PyResult<R> {
    let flag = Arc::new(AtomicBool::new(false));
    let checkpoint = Checkpoint(flag.clone());
    let (tx, rx) = mpsc::channel();
    std::thread::Builder::new()
        .name("acdf-call".into())
        .spawn(move || {
            let out = catch_unwind(AssertUnwindSafe(|| work(&checkpoint)));
            // The caller is gone when it was interrupted.
            let _ = tx.send(out);
        })
        .map_err(|e| raise(py, "Error", format!("cannot start a thread: {e}")))?;
    let mut rx = rx;
    loop {
        let (back, received) = py.detach(move || {
            let r = rx.recv_timeout(POLL);
            (rx, r)
        });
        rx = back;
        match received {
            Ok(Ok(r)) => return Ok(r),
            Ok(Err(payload)) => {
                return Err(raise(
                    py,
                    "Error",
                    format!("internal error: {}", panic_text(payload.as_ref())),
                ))
            }
            Err(RecvTimeoutError::Timeout) => {
                if let Err(e) = py.check_signals() {
                    flag.store(true, Ordering::Relaxed);
                    return Err(e);
                }
            }
            Err(RecvTimeoutError::Disconnected) => {
                return Err(raise(
                    py,
                    "Error",
                    "internal error: the computation ended without a result",
                ))
            }
        }
    }
}
