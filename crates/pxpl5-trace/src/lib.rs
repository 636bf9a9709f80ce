//! Trace writers over simulated time: the simulator's `--trace FILE.json` (Chrome trace-event
//! JSON, for Perfetto or chrome://tracing), `--trace FILE.pftrace` (Perfetto's native protobuf
//! format, streamed: [`PerfettoTrace`]) and `--vcd FILE` (Value Change Dump, for GTKWave or
//! Surfer).
//!
//! The crate knows nothing of Pixel-Planes: it offers tracks, slices, instants, counters and flows
//! ([`ChromeTrace`]) and scoped wires and string variables ([`VcdTrace`]), all stamped with [`Tick`]s of simulated time,
//! never host time. Both builders take a [`TraceWindow`] (parsed from user input such as `0..2ms`)
//! and drop or clip what lies outside it as it is recorded. Both write byte-identical output for
//! identical input, whatever the platform and whatever order events at different times were
//! recorded in, so traces can be compared and committed as golden files.
//!
//! The crate takes plain data and writes its own JSON ([`JsonValue`] for event args and file
//! metadata): like the rest of the simulator core, it has no serde dependency.
//!
//! ```
//! use pxpl5_sim::Tick;
//! use pxpl5_trace::{Args, ChromeTrace, TraceWindow, VcdTrace};
//!
//! let mut trace = ChromeTrace::new("0..2ms".parse::<TraceWindow>().unwrap());
//! let gp0 = trace.track("GPs", "GP 0");
//! trace.slice(gp0, "transform", Tick(25_000), Tick(75_000), Args::new());
//! assert!(trace.to_string().contains(r#""ts":0.025000,"dur":0.050000"#));
//!
//! let mut vcd = VcdTrace::default();
//! let ring = vcd.scope("ring");
//! let busy = vcd.wire(ring, "busy", 1);
//! vcd.change(busy, Tick(50_000), 1);
//! assert!(vcd.to_string().contains("#50000\n1!"));
//! ```

#![forbid(unsafe_code)]
#![warn(missing_docs)]

mod chrome;
mod event_trace;
mod json;
mod perfetto;
pub mod proto;
mod spill;
mod vcd_trace;
mod window;

pub use chrome::{
    Args, ChromeTrace, FlowStep, Micros, NestingError, RESERVED_METADATA_KEYS, SPILL_AT, SliceSpan,
    TIME_UNIT_NOTE, TrackId,
};
pub use event_trace::EventTrace;
pub use json::JsonValue;
pub use perfetto::{PerfettoTrace, read_packets};
pub use pxpl5_sim::Tick;
pub use vcd_trace::{MAX_WIDTH, Sample, ScopeId, SignalId, TextValue, VcdTrace, WidthError};
pub use window::{
    TimeErrorKind, TimeParseError, TraceWindow, WindowParseError, format_time, parse_time,
};
