//! What a run takes and gives: its options (with the limit of simulated time and the host's
//! [`Monitor`]), its result, and why it can fail.

use std::sync::Arc;

use pxpl5_renderer::Fidelity;
use pxpl5_ring::{RingError, RingLevel};
use pxpl5_sim::Tick;

use crate::frame_buffer::FrameBufferImage;
use crate::gp::Unit;
use crate::monitor::Monitor;
use crate::record::Recorder;
use crate::stats::RunStats;

/// Options of one run.
#[derive(Clone, Debug)]
pub struct RunOptions {
    /// How the Renderers' pixel work is simulated.
    pub fidelity: Fidelity,
    /// How the ring is simulated: by tokens (exact) or per message (approximate).
    pub ring_level: RingLevel,
    /// Simulated time after which the run is stopped with an error.
    pub max_time: Tick,
    /// Where the host watches the run and may ask it to stop; `None` runs it unwatched. It never
    /// changes a result of a run that is not asked to stop (see [`Monitor`]).
    pub monitor: Option<Arc<Monitor>>,
    /// Host threads for the Renderers' pixel work: 1 does it in the machine's own thread; more
    /// run the boards' pixel work on a pool of that many workers (`pxpl5_renderer::Workers`).
    /// Host work only: every result is identical whatever the number.
    pub threads: usize,
}

impl Default for RunOptions {
    fn default() -> RunOptions {
        RunOptions {
            fidelity: Fidelity::Sparse,
            ring_level: RingLevel::Token,
            // 10 simulated seconds: far beyond any shipped program's run.
            max_time: Tick(10_000_000_000_000),
            monitor: None,
            threads: 1,
        }
    }
}

/// Why a run failed.
#[derive(Debug, thiserror::Error)]
pub enum RunError {
    #[error("program error on GP {gp}: {message}")]
    Program { gp: u32, message: String },
    #[error("Renderer {renderer} rejected command {kind} sent by {from}: {error}")]
    Command {
        renderer: u32,
        kind: &'static str,
        from: Unit,
        error: pxpl5_renderer::CommandError,
    },
    #[error("deadlock at {at}: every unit waits and nothing is due:\n{waiting}")]
    Deadlock { at: Tick, waiting: String },
    #[error("simulated time limit of {limit} reached (still running: {running})")]
    TimeLimit { limit: Tick, running: String },
    /// The host asked the run to stop at once ([`crate::Stop::Now`]): a host-time limit or an
    /// interrupt, which the host knows and says.
    #[error("stopped at {at} of simulated time (still running: {running})")]
    Stopped { at: Tick, running: String },
    #[error("{unit} sent a message the ring cannot carry: {error}")]
    Ring { unit: Unit, error: RingError },
    #[error("{from} sent a message to {to}, which this machine does not have")]
    NoSuchUnit { from: Unit, to: Unit },
    #[error("bad machine: {0}")]
    Config(String),
}

/// The result of a run: simulated statistics, the frame buffer's image, and the trace recorder.
pub struct RunResult {
    pub stats: RunStats,
    /// The frame buffer's image at the end of the run.
    pub frame: FrameBufferImage,
    pub recorder: Recorder,
    /// What the simulator did on the host to get there.
    pub host: HostWork,
}

/// Counts of the simulator's own work in a run: host figures, deterministic like the simulated
/// ones (the same inputs give the same counts) but about the simulator, not the machine, so they
/// stay out of `RunStats` and its JSON. Tests bound them to keep host work following the
/// machine's work (a unit waiting for the ring must cost O(1) per instant, not a copy of its
/// message).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct HostWork {
    /// Instants the machine's loop stepped through.
    pub instants: u64,
    /// Messages offered to the ring, taken or not.
    pub offers: u64,
    /// Offers refused because the sender's output queue was full (each retried at a later
    /// instant).
    pub refused_offers: u64,
    /// GPs the loop looked at (to run one, or to retry its send): only those that could act,
    /// twice per round of an instant, not every GP at every instant.
    pub gp_checks: u64,
}
