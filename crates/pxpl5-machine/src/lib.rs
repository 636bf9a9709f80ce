//! The machine: builds Pixel-Planes 5 from a config (GPs, Renderers, the frame buffer and the
//! host on the token ring) and runs a program on it in simulated time.
//!
//! This is the only crate that knows the topology. Programs see only the GP runtime ([`gp`]:
//! [`Gp`], [`Program`], [`Unit`], [`Payload`]) and the Renderer command set; stats are simulated
//! quantities only ([`RunStats`]); traces are recorded by [`Recorder`] in simulated time. A host
//! watches a run, and may stop it, through its [`Monitor`].

mod critical;
mod delivery;
mod frame_buffer;
pub mod gp;
mod gp_node;
mod machine;
pub mod memory;
mod monitor;
mod ready;
mod record;
mod renderer_node;
mod run;
mod stats;
mod topology;

pub use frame_buffer::FrameBufferImage;
pub use gp::{
    CommandBatch, Cost, DATA_HEADER_WORDS, Gp, GpFuture, Message, Op, Payload, Program,
    ProgramError, Record, Tag, Unit,
};
pub use machine::Machine;
pub use memory::{MemoryError, MemoryEstimate};
pub use monitor::{CHECK_EVERY, Monitor, Stop};
pub use record::Recorder;
pub use run::{HostWork, RunError, RunOptions, RunResult};
pub use stats::{GpStats, PathPart, PhaseSpan, RendererNodeStats, Resource, RunStats};
pub use topology::node_order;
