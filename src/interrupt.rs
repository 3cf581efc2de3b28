//! Stopping a run cleanly from outside (Ctrl-C, `kill`, Python's `KeyboardInterrupt`).
//!
//! A run's driver asks [`requested`] after every accepted step; once it says yes the run ends as
//! if a stop criterion were met: the last state is written (series row, snapshot, `summary.json`
//! with `completed = false` and `stop_reason = "interrupted"`), and the run returns normally.
//! The caller then tells its user (the command line exits with 128 + the signal's number, Python
//! raises `KeyboardInterrupt`).
//!
//! Two ways a request arrives:
//! - a signal: [`install_handlers`] (the command line's `main`) turns SIGINT and SIGTERM into a
//!   request (signal-hook: the handler only stores to an atomic); a second signal of the same
//!   kind ends the process at once (exit code 128 + signal), for a run that does not reach its
//!   next step;
//! - a poll: an embedding (the Python package) registers a function with [`set_poll`] that
//!   [`requested`] calls at most every [`POLL_INTERVAL`] seconds on the thread that installed it
//!   (Python runs its signal handlers only on its main thread).

use std::cell::RefCell;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, AtomicI32, Ordering};
use std::time::{Duration, Instant};

/// Set by a signal or a poll; cleared by [`clear`].
static REQUESTED: std::sync::LazyLock<Arc<AtomicBool>> = std::sync::LazyLock::new(|| Arc::new(AtomicBool::new(false)));
/// The number of the signal that asked (0: none or a poll).
static SIGNAL: AtomicI32 = AtomicI32::new(0);
/// Whether a process-wide request was seen by [`requested`], i.e. some work stopped early on it.
static OBSERVED: AtomicBool = AtomicBool::new(false);

/// Shortest interval between two calls of a registered poll [s].
pub const POLL_INTERVAL: f64 = 0.05;

thread_local! {
    /// The poll registered on this thread and when it last ran.
    static POLL: RefCell<Option<(Box<dyn FnMut() -> bool>, Instant)>> = const { RefCell::new(None) };
    /// The stop flag of the call this thread computes for ([`Scope::enter`]), if any.
    static SCOPE: RefCell<Option<Arc<AtomicBool>>> = const { RefCell::new(None) };
}

/// Whether a stop was requested (a signal arrived, the [`Scope`] this thread works in was asked
/// to stop, or this thread's poll said so: the request then goes to that scope alone, or to the
/// whole process outside a scope).
pub fn requested() -> bool {
    if REQUESTED.load(Ordering::Relaxed) {
        OBSERVED.store(true, Ordering::Relaxed);
        return true;
    }
    let scope = SCOPE.with(|s| s.borrow().clone());
    if scope.as_ref().is_some_and(|f| f.load(Ordering::Relaxed)) {
        return true;
    }
    let polled = POLL.with(|p| {
        let mut p = p.borrow_mut();
        match p.as_mut() {
            Some((f, last)) if last.elapsed() >= Duration::from_secs_f64(POLL_INTERVAL) => {
                *last = Instant::now();
                f()
            }
            _ => false,
        }
    });
    if polled {
        scope.as_deref().unwrap_or(&**REQUESTED).store(true, Ordering::Relaxed);
    }
    polled
}

/// The stop request of one call (an embedding's run: the Python package runs calls in several
/// threads at once, and Ctrl-C must stop the call that received it, not every call of the
/// process). Threads that compute for the call [`Scope::enter`] it; a poll on such a thread
/// requests a stop of this scope only.
#[derive(Clone, Default)]
pub struct Scope(Arc<AtomicBool>);

impl Scope {
    /// A scope with no stop requested.
    pub fn new() -> Scope {
        Scope::default()
    }

    /// Makes this the scope of the calling thread until the guard is dropped.
    pub fn enter(&self) -> ScopeGuard {
        let previous = SCOPE.with(|s| s.borrow_mut().replace(self.0.clone()));
        ScopeGuard { previous, _not_send: std::marker::PhantomData }
    }

    /// Whether a stop of this scope was requested.
    pub fn requested(&self) -> bool {
        self.0.load(Ordering::Relaxed)
    }
}

/// Restores the thread's earlier scope when dropped.
pub struct ScopeGuard {
    previous: Option<Arc<AtomicBool>>,
    _not_send: std::marker::PhantomData<*const ()>,
}

impl Drop for ScopeGuard {
    fn drop(&mut self) {
        SCOPE.with(|s| *s.borrow_mut() = self.previous.take());
    }
}

/// Asks every run of this process to stop after its current step.
pub fn request() {
    REQUESTED.store(true, Ordering::Relaxed);
}

/// Forgets an earlier request (before a new run starts).
pub fn clear() {
    REQUESTED.store(false, Ordering::Relaxed);
    SIGNAL.store(0, Ordering::Relaxed);
    OBSERVED.store(false, Ordering::Relaxed);
}

/// Whether a process-wide stop request was acted on: [`requested`] said yes to some work (every
/// caller asks it only while work remains, and stops early on yes). A signal that arrives after
/// the last question finds the work complete: the command line then exits 0, not 128 + signal
/// with a summary that says `completed = true` (issue 38, found by the run-path fuzzer).
pub fn observed() -> bool {
    OBSERVED.load(Ordering::Relaxed)
}

/// The signal that requested the stop (2 = SIGINT, 15 = SIGTERM), if one did.
pub fn signal() -> Option<i32> {
    match SIGNAL.load(Ordering::Relaxed) {
        0 => None,
        s => Some(s),
    }
}

/// Registers `poll` on this thread (replacing an earlier one) until the guard is dropped:
/// [`requested`] calls it at most every [`POLL_INTERVAL`] s and treats `true` as a request.
pub fn set_poll(poll: Box<dyn FnMut() -> bool>) -> PollGuard {
    POLL.with(|p| *p.borrow_mut() = Some((poll, Instant::now())));
    PollGuard { _not_send: std::marker::PhantomData }
}

/// Removes this thread's poll when dropped.
pub struct PollGuard {
    _not_send: std::marker::PhantomData<*const ()>,
}

impl Drop for PollGuard {
    fn drop(&mut self) {
        POLL.with(|p| *p.borrow_mut() = None);
    }
}

/// Turns SIGINT and SIGTERM into a stop request (the command line's `main`). A second signal of
/// the same kind while the first is pending ends the process with exit code 128 + signal.
#[cfg(unix)]
pub fn install_handlers() -> std::io::Result<()> {
    use signal_hook::consts::{SIGINT, SIGTERM};
    for sig in [SIGINT, SIGTERM] {
        let armed = Arc::new(AtomicBool::new(false));
        // registered first, so that it sees `armed` as the previous signal left it
        signal_hook::flag::register_conditional_shutdown(sig, 128 + sig, armed.clone())?;
        // SAFETY: the action only stores to atomics (async-signal-safe).
        let requested = REQUESTED.clone();
        unsafe {
            signal_hook::low_level::register(sig, move || {
                SIGNAL.store(sig, Ordering::Relaxed);
                requested.store(true, Ordering::Relaxed);
                armed.store(true, Ordering::Relaxed);
            })?;
        }
    }
    Ok(())
}

/// Turns Ctrl-C and SIGTERM into a stop request (signal-hook's portable subset).
#[cfg(not(unix))]
pub fn install_handlers() -> std::io::Result<()> {
    use signal_hook::consts::{SIGINT, SIGTERM};
    for sig in [SIGINT, SIGTERM] {
        signal_hook::flag::register(sig, REQUESTED.clone())?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_poll_requests_a_stop_and_goes_with_its_guard() {
        clear();
        let g = set_poll(Box::new(|| true));
        std::thread::sleep(Duration::from_secs_f64(POLL_INTERVAL * 1.2));
        assert!(requested());
        drop(g);
        clear();
        assert!(!requested());
    }
}
