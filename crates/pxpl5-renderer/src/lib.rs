//! The Pixel-Planes 5 Renderer board: 128 x 128 bit-serial SIMD pixel processors with 208 bits of
//! pixel memory each, an enable register and flags, a quadratic expression evaluator (QEE), a
//! backing store, and the IGC command set that drives them.
//!
//! - [`Command`] is the command set; [`cycle_cost`] is the one cycle table every level uses.
//! - [`Board`] runs commands at a [`Fidelity`]: `bit` (every micro-cycle on bit-planes, the
//!   reference) or `integer` (per-pixel integers); pixel memory, flags and cycle counts are
//!   identical, which the property tests in `tests/equivalence.rs` check on random command
//!   streams.
//! - [`qee`] fixes the QEE's exact semantics and its documented result-cut rule.
//! - [`PixelLayout`] allocates named fields in pixel memory; [`readback`] splits a readback into messages and counts their ring words.
//! - [`Workers`] runs boards' pixel work on host threads ([`Board::on_workers`]), with identical
//!   results.
//!
//! This crate knows nothing of the ring, GPs or programs: a readback names its destination node
//! only as an opaque number, and time is the board's own count of Renderer cycles.

mod board;
mod command;
mod cycles;
pub mod engine;
mod layout;
pub mod qee;
pub mod readback;
mod workers;

pub use board::{
    Board, BoardImage, BoardStats, CommandError, Executed, Fidelity, KindStats, ReadbackStream,
};
pub use command::{Bit, Cmp, Command, Field, Fields, LogicOp, Rect};
pub use cycles::{backing_store_blocks, backing_store_cycles, cycle_cost};
pub use layout::{LayoutError, PixelLayout};
pub use qee::{QeeExpr, QuantiseError, Window};
pub use workers::Workers;
