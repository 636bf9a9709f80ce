//! The simulation kernel: simulated time and the deterministic event queue.
//!
//! This crate knows nothing of Pixel-Planes 5. It gives the rest of the simulator:
//! - [`Tick`], the global time in picoseconds, and [`Cycles`], a count of clocks of one
//!   [`ClockDomain`]; the two convert only through a clock domain, so a bare `u64` never means time;
//! - [`EventQueue`], ordered by (tick, priority, component, sequence), so that events at the same
//!   tick always pop in the same order whatever the host does;
//! - [`SeqMap`], the values of things numbered in order while they are alive.

mod queue;
mod seq_map;
mod time;

pub use queue::{ComponentId, Event, EventQueue, PastEvent, Priority};
pub use seq_map::SeqMap;
pub use time::{ClockDomain, ClockError, Cycles, Tick};
