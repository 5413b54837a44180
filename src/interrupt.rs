//! A request to stop, from SIGINT (Ctrl-C) or SIGTERM, that the long loops answer by saving
//! their state first.
//!
//! The binary calls [`install`] once. From then on a signal's effect depends on whether a
//! loop that can save its state is running, that is whether an [`Armed`] guard is alive:
//! - **armed** (the stepping of `slurry run` and `slurry reproduce`, the settling of a bed in
//!   the fluid): the first signal only records itself ([`requested`]); the loop stops at its
//!   next complete state (after an even number of steps: the AA pattern's state is complete only
//!   then), writes its checkpoint after a health check, and returns [`Interrupted`], naming the
//!   step and how to continue. A second signal ends the process at once (exit status 128 +
//!   the signal's number), for a user who will not wait for the checkpoint;
//! - **not armed** (set-up, the dry bed, statistics, figures): the process ends at once with
//!   the same status, as it would without the handler.
//!
//! A process ended at once leaves only files that were complete: every output is written
//! atomically, and the temporary files of an interrupted write are removed by the next run.
//!
//! The handler touches only atomics and `_exit`, both async-signal-safe
//! ([`signal_hook::low_level::register`]).

use std::sync::atomic::{AtomicBool, AtomicI32, AtomicUsize, Ordering};

/// How many loops that answer [`requested`] are running (their [`Armed`] guards).
static ARMED: AtomicUsize = AtomicUsize::new(0);
/// The first signal received while armed (0: none).
static REQUESTED: AtomicI32 = AtomicI32::new(0);
/// Whether [`install`] has registered the handler.
static INSTALLED: AtomicBool = AtomicBool::new(false);

/// The signals that ask a run to stop.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Signal {
    /// SIGINT: Ctrl-C in the terminal.
    Interrupt,
    /// SIGTERM: `kill PID`, or a batch system ending the job.
    Terminate,
}

impl Signal {
    /// The POSIX signal number.
    pub fn number(self) -> i32 {
        match self {
            Signal::Interrupt => signal_hook::consts::SIGINT,
            Signal::Terminate => signal_hook::consts::SIGTERM,
        }
    }

    /// The exit status of a process ended by this signal, by the shells' convention:
    /// 128 + the signal's number (130 for SIGINT, 143 for SIGTERM).
    pub fn exit_status(self) -> u8 {
        // 128 + 2 and 128 + 15 both fit in a byte.
        (128 + self.number()) as u8
    }

    fn from_number(n: i32) -> Option<Signal> {
        [Signal::Interrupt, Signal::Terminate].into_iter().find(|s| s.number() == n)
    }
}

impl std::fmt::Display for Signal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Signal::Interrupt => "SIGINT (Ctrl-C)",
            Signal::Terminate => "SIGTERM",
        })
    }
}

/// Registers the handler for SIGINT and SIGTERM (once; later calls do nothing). Until an
/// [`Armed`] guard is taken, a signal still ends the process at once.
pub fn install() -> std::io::Result<()> {
    if INSTALLED.swap(true, Ordering::SeqCst) {
        return Ok(());
    }
    for signal in [Signal::Interrupt, Signal::Terminate] {
        let n = signal.number();
        let status = i32::from(signal.exit_status());
        // SAFETY: the action touches only atomics and calls `_exit`, all async-signal-safe; it
        // allocates nothing, takes no lock and does not unwind.
        unsafe {
            signal_hook::low_level::register(n, move || {
                if ARMED.load(Ordering::SeqCst) == 0 || REQUESTED.swap(n, Ordering::SeqCst) != 0 {
                    signal_hook::low_level::exit(status);
                }
            })?;
        }
    }
    Ok(())
}

/// The signal that asked the running loop to stop, if one did.
pub fn requested() -> Option<Signal> {
    Signal::from_number(REQUESTED.load(Ordering::SeqCst))
}

/// While alive, a signal asks the loop to stop ([`requested`]) instead of ending the process.
/// Take it around a loop that polls [`requested`] and can save its state.
#[derive(Debug)]
#[must_use = "the loop is armed only while the guard lives"]
pub struct Armed(());

/// Arms the handler until the guard is dropped (guards count: nested or concurrent loops
/// keep it armed until the last one ends).
pub fn arm() -> Armed {
    ARMED.fetch_add(1, Ordering::SeqCst);
    Armed(())
}

impl Drop for Armed {
    fn drop(&mut self) {
        ARMED.fetch_sub(1, Ordering::SeqCst);
    }
}

/// A loop stopped at a signal's request, its state saved where it says.
#[derive(Clone, Debug, thiserror::Error)]
#[error("stopped by {signal} at step {step}: {saved}")]
pub struct Interrupted {
    /// The signal that asked for the stop.
    pub signal: Signal,
    /// The step at which the loop stopped.
    pub step: u64,
    /// What was saved and how to continue.
    pub saved: String,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn signals_map_to_their_numbers_and_exit_statuses() {
        assert_eq!(Signal::Interrupt.exit_status(), 130);
        assert_eq!(Signal::Terminate.exit_status(), 143);
        for s in [Signal::Interrupt, Signal::Terminate] {
            assert_eq!(Signal::from_number(s.number()), Some(s));
        }
        assert_eq!(Signal::from_number(0), None);
        assert_eq!(Signal::from_number(signal_hook::consts::SIGKILL), None);
    }
}
