//! [`EventTrace`]: one of the two event-trace formats behind one recording interface, so that the
//! simulator records its tracks once whatever format `--trace FILE` asked for (the file's
//! extension chooses it).

use pxpl5_sim::Tick;

use crate::chrome::{Args, ChromeTrace, FlowStep, TrackId};
use crate::json::JsonValue;
use crate::perfetto::PerfettoTrace;
use crate::window::TraceWindow;

/// A trace of tracks, slices, instants, counters and flows in one of the supported formats.
#[derive(Debug)]
pub enum EventTrace {
    /// Chrome trace-event JSON, sorted in memory (or on disk past a budget,
    /// [`ChromeTrace::spill_to`]) and written at the end ([`ChromeTrace::write`]).
    Chrome(ChromeTrace),
    /// Perfetto's protobuf format, streamed to its writer ([`PerfettoTrace::finish`]).
    Perfetto(PerfettoTrace),
}

impl EventTrace {
    /// The window the trace keeps.
    pub fn window(&self) -> TraceWindow {
        match self {
            EventTrace::Chrome(c) => c.window(),
            EventTrace::Perfetto(p) => p.window(),
        }
    }

    /// [`ChromeTrace::track`].
    pub fn track(&mut self, process: &str, thread: &str) -> TrackId {
        match self {
            EventTrace::Chrome(c) => c.track(process, thread),
            EventTrace::Perfetto(p) => p.track(process, thread),
        }
    }

    /// [`ChromeTrace::slice`].
    pub fn slice<K: Into<String>>(
        &mut self,
        track: TrackId,
        name: &str,
        start: Tick,
        end: Tick,
        args: impl IntoIterator<Item = (K, JsonValue)>,
    ) {
        match self {
            EventTrace::Chrome(c) => c.slice(track, name, start, end, args),
            EventTrace::Perfetto(p) => {
                let args: Args = args.into_iter().map(|(k, v)| (k.into(), v)).collect();
                p.slice(track, name, start, end, args);
            }
        }
    }

    /// [`ChromeTrace::slice_grouped`].
    pub fn slice_grouped(
        &mut self,
        track: TrackId,
        name: &str,
        start: Tick,
        end: Tick,
        min_gap: Tick,
    ) {
        match self {
            EventTrace::Chrome(c) => c.slice_grouped(track, name, start, end, min_gap),
            EventTrace::Perfetto(p) => p.slice_grouped(track, name, start, end, min_gap),
        }
    }

    /// [`ChromeTrace::instant`].
    pub fn instant(&mut self, track: TrackId, name: &str, at: Tick) {
        match self {
            EventTrace::Chrome(c) => c.instant(track, name, at),
            EventTrace::Perfetto(p) => p.instant(track, name, at, Args::new()),
        }
    }

    /// [`ChromeTrace::counter`].
    pub fn counter(&mut self, process: &str, name: &str, at: Tick, value: i64) {
        match self {
            EventTrace::Chrome(c) => c.counter(process, name, at, value),
            EventTrace::Perfetto(p) => p.counter(process, name, at, value),
        }
    }

    /// [`ChromeTrace::flow`].
    pub fn flow(&mut self, track: TrackId, name: &str, id: u64, step: FlowStep, at: Tick) {
        match self {
            EventTrace::Chrome(c) => c.flow(track, name, id, step, at),
            EventTrace::Perfetto(p) => p.flow(track, name, id, step, at),
        }
    }

    /// [`ChromeTrace::metadata`]; Perfetto's format has no place for it and drops it.
    pub fn metadata(&mut self, key: &str, value: impl Into<JsonValue>) {
        if let EventTrace::Chrome(c) = self {
            c.metadata(key, value);
        }
    }
}
