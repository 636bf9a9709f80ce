//! A run's window to the host that watches it: how far the run has got (simulated time reached,
//! the program's own count of work done) and the host's request to stop it. Shared through an
//! `Arc` between the machine's thread and a watcher thread (a progress bar, a host-time limit, a
//! Ctrl-C handler); everything is an atomic, read and written with relaxed ordering, since no
//! other memory is published through it.
//!
//! **Out of the hot path.** The machine's loop publishes the simulated time and reads the stop
//! request once every [`CHECK_EVERY`] instants, not at each one: a relaxed atomic store and load
//! per 1,024 instants, against the thousands of instructions an instant takes.
//!
//! **Determinism.** A monitor never feeds a simulated result: the machine only writes to it, and
//! reads one thing, whether to stop. A run that is not asked to stop is the same run, byte for
//! byte, with or without a monitor. A run that is asked to stop either ends with an error
//! ([`Stop::Now`], `RunError::Stopped`) or, if its program honours [`Stop::Soon`], ends its
//! work early at a point of its own choosing (the radiosity program: between shots), and says so.

use std::sync::atomic::{AtomicU8, AtomicU64, Ordering};

use pxpl5_sim::Tick;

/// The machine's loop looks at its monitor once every this many instants (a power of two).
pub const CHECK_EVERY: u64 = 1024;

/// What the host asks of a run. Requests only escalate: `None` < `Soon` < `Now`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub enum Stop {
    /// Run to the end.
    None,
    /// End the work at the program's next convenient point (a program that has none runs on),
    /// keeping what was computed: a Ctrl-C of a radiosity run. A program honours `Soon` only,
    /// never `Now`, which must end the run with an error, not with results that end early.
    Soon,
    /// Stop the machine at once, within [`CHECK_EVERY`] instants, with `RunError::Stopped`: a
    /// host-time limit, or a Ctrl-C of a run that has no convenient point.
    Now,
}

/// The shared state of one run (see the module doc).
#[derive(Debug, Default)]
pub struct Monitor {
    /// Simulated picoseconds reached, as last published by the machine.
    reached: AtomicU64,
    /// Units of work done, counted by the program (the radiosity program: shots).
    done: AtomicU64,
    /// The [`Stop`] asked, as its discriminant.
    stop: AtomicU8,
}

impl Monitor {
    /// The simulated time the run had reached when it last published it.
    pub fn reached(&self) -> Tick {
        Tick(self.reached.load(Ordering::Relaxed))
    }

    /// The machine publishes how far it has got.
    pub(crate) fn set_reached(&self, t: Tick) {
        self.reached.store(t.0, Ordering::Relaxed);
    }

    /// The program's count of work done (radiosity: shots taken).
    pub fn done(&self) -> u64 {
        self.done.load(Ordering::Relaxed)
    }

    /// The program publishes its count of work done.
    pub fn set_done(&self, n: u64) {
        self.done.store(n, Ordering::Relaxed);
    }

    /// Ask the run to stop, `Soon` or `Now`; a weaker request than one already made is ignored.
    pub fn request(&self, stop: Stop) {
        self.stop.fetch_max(stop as u8, Ordering::Relaxed);
    }

    /// The strongest stop asked so far.
    pub fn requested(&self) -> Stop {
        match self.stop.load(Ordering::Relaxed) {
            0 => Stop::None,
            1 => Stop::Soon,
            _ => Stop::Now,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn requests_only_escalate() {
        let m = Monitor::default();
        assert_eq!(m.requested(), Stop::None);
        m.request(Stop::Soon);
        assert_eq!(m.requested(), Stop::Soon);
        m.request(Stop::Now);
        m.request(Stop::Soon);
        m.request(Stop::None);
        assert_eq!(m.requested(), Stop::Now);
    }

    #[test]
    fn counts_are_published() {
        let m = Monitor::default();
        m.set_reached(Tick(1234));
        m.set_done(7);
        assert_eq!((m.reached(), m.done()), (Tick(1234), 7));
    }
}
