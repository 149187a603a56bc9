//! Stopping a long run on SIGINT (Ctrl-C) or SIGTERM, cleanly.
//!
//! While a [`Guard`] is alive, SIGINT and SIGTERM only set a flag (the
//! handler, through `signal-hook`, does nothing else); the long loops of the
//! core (MCAP chunks, backprojection, octree insertion, output writing) call
//! [`check`], which then returns [`Error::Interrupted`]. The error travels up
//! like any other: temporary output files are removed on the way
//! (`io::atomic`) and the previous outputs stay as they were. The
//! command line exits with `128 + signal` (130, 143), the Python bindings
//! raise `KeyboardInterrupt`.
//!
//! A handler that was there before (Python's own SIGINT handler) keeps being
//! called: the interpreter still sees its Ctrl-C. Without a live guard,
//! [`check`] never fails.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, OnceLock};

use crate::error::{Error, Result};

/// SIGINT (2).
pub const SIGINT: i32 = 2;
/// SIGTERM (15).
pub const SIGTERM: i32 = 15;

/// The signal received while a guard was alive (0: none).
fn pending() -> &'static Arc<AtomicUsize> {
    static PENDING: OnceLock<Arc<AtomicUsize>> = OnceLock::new();
    PENDING.get_or_init(|| Arc::new(AtomicUsize::new(0)))
}

/// Live guards (read by [`check`] without the lock).
static GUARDS: AtomicUsize = AtomicUsize::new(0);

/// Live guards and the handler registrations they share.
struct Registry {
    guards: usize,
    ids: Vec<signal_hook::SigId>,
}

static REGISTRY: Mutex<Registry> = Mutex::new(Registry {
    guards: 0,
    ids: Vec::new(),
});

/// Fails with [`Error::Interrupted`] when SIGINT or SIGTERM arrived since the
/// first of the live [`Guard`]s was made; `Ok` without a live guard. Cheap
/// (two atomic loads): call it once per chunk, keyframe or block of output.
pub fn check() -> Result<()> {
    match pending_signal() {
        None => Ok(()),
        Some(signal) => Err(Error::Interrupted { signal }),
    }
}

/// The signal [`check`] would report.
pub fn pending_signal() -> Option<i32> {
    if GUARDS.load(Ordering::SeqCst) == 0 {
        return None;
    }
    match pending().load(Ordering::SeqCst) {
        0 => None,
        s => Some(s as i32),
    }
}

/// The signal received while the guards were last alive, even once they are
/// gone (until a guard is made again): how a caller tells a run that ended
/// on a signal from one that saw none.
pub fn received() -> Option<i32> {
    match pending().load(Ordering::SeqCst) {
        0 => None,
        s => Some(s as i32),
    }
}

/// Marks `signal` as received, as the handler does (for callers that learn
/// of an interruption another way, such as Python's own signal check).
pub fn request(signal: i32) {
    pending().store(signal.max(1) as usize, Ordering::SeqCst);
}

/// How a second signal is treated while a guard is alive.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Second {
    /// A second SIGINT or SIGTERM ends the process at once (the signal's
    /// default action): for the command line, where a run that does not
    /// reach a check must still be stoppable.
    Terminates,
    /// Every signal only sets the flag (and calls the handler that was there
    /// before): for a library inside an interpreter.
    Flags,
}

/// SIGINT and SIGTERM set the flag that [`check`] reads while this is alive.
/// Guards nest (and may live on several threads); the flag is cleared when
/// the first one is made.
#[must_use = "signals are only caught while the guard lives"]
pub struct Guard {
    _private: (),
}

impl Guard {
    /// Installs the flag handlers (once for all live guards). Failing to
    /// install them is not an error: the run is then not interruptible, as
    /// before.
    pub fn new(second: Second) -> Guard {
        let mut reg = REGISTRY.lock().unwrap_or_else(|e| e.into_inner());
        if reg.guards == 0 {
            pending().store(0, Ordering::SeqCst);
            for sig in [SIGINT, SIGTERM] {
                if second == Second::Terminates {
                    // Registered first: runs before the flag is set by the action below,
                    // so it sees the flag of an earlier signal only.
                    if let Ok(id) =
                        signal_hook::flag::register_conditional_default(sig, flag_bool())
                    {
                        reg.ids.push(id);
                    }
                }
                if let Ok(id) =
                    signal_hook::flag::register_usize(sig, Arc::clone(pending()), sig as usize)
                {
                    reg.ids.push(id);
                }
                if let Ok(id) = signal_hook::flag::register(sig, flag_bool()) {
                    reg.ids.push(id);
                }
            }
        }
        reg.guards += 1;
        GUARDS.store(reg.guards, Ordering::SeqCst);
        Guard { _private: () }
    }
}

/// The boolean twin of [`pending`] that `register_conditional_default` reads.
fn flag_bool() -> Arc<std::sync::atomic::AtomicBool> {
    static FLAG: OnceLock<Arc<std::sync::atomic::AtomicBool>> = OnceLock::new();
    Arc::clone(FLAG.get_or_init(|| Arc::new(std::sync::atomic::AtomicBool::new(false))))
}

impl Drop for Guard {
    fn drop(&mut self) {
        let mut reg = REGISTRY.lock().unwrap_or_else(|e| e.into_inner());
        reg.guards -= 1;
        GUARDS.store(reg.guards, Ordering::SeqCst);
        if reg.guards == 0 {
            for id in reg.ids.drain(..) {
                signal_hook::low_level::unregister(id);
            }
            flag_bool().store(false, Ordering::SeqCst);
        }
    }
}

/// The exit status of a process ended by `signal` (`128 + signal`, as shells report it).
pub fn exit_code(signal: i32) -> i32 {
    128 + signal
}

/// `SIGINT`, `SIGTERM` or `signal N`.
pub fn name(signal: i32) -> String {
    crate::error::signal_name(signal)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_and_exit_codes() {
        assert_eq!(exit_code(SIGINT), 130);
        assert_eq!(exit_code(SIGTERM), 143);
        assert_eq!(name(SIGTERM), "SIGTERM");
        assert_eq!(name(9), "signal 9");
    }
}
