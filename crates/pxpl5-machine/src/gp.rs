//! The Graphics Processor runtime: what a program's code sees of the machine.
//!
//! A program is ordinary sequential Rust, one `async` function per GP, that waits on the machine
//! through a [`Gp`] handle: [`Gp::compute`] charges i860 cycles from the config's cost table,
//! [`Gp::send`] puts a message on the ring, [`Gp::recv`] waits for one, [`Gp::phase`] marks a
//! program phase. Nothing else of the simulator is visible.
//!
//! **Why futures.** Each GP's code is a future the machine polls on its own deterministic
//! schedule (GPs in index order at each simulated instant, with a no-op waker): a future that
//! must wait posts a [`Request`] to its GP's mailbox cell and returns `Pending`; the machine
//! grants the request at the right simulated time and polls again. No host thread, no wall clock,
//! so runs are byte-identical whatever the host does.

use std::cell::RefCell;
use std::collections::VecDeque;
use std::future::Future;
use std::pin::Pin;
use std::rc::Rc;
use std::task::{Context, Poll};

use pxpl5_config::GpCostTable;
use pxpl5_renderer::Command;
use pxpl5_sim::{Cycles, Tick};

/// A unit of the machine that messages can be addressed to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Unit {
    Gp(u32),
    Renderer(u32),
    FrameBuffer,
    Host,
}

impl std::fmt::Display for Unit {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Unit::Gp(i) => write!(f, "GP {i}"),
            Unit::Renderer(i) => write!(f, "Renderer {i}"),
            Unit::FrameBuffer => write!(f, "frame buffer"),
            Unit::Host => write!(f, "host"),
        }
    }
}

/// What a message carries. Its size on the ring is counted by the machine: each command's
/// encoding, the readback's packed words, or the program's declared word count.
#[derive(Clone, Debug, PartialEq)]
pub enum Payload {
    /// IGC commands for a Renderer, executed in order.
    Commands(Vec<Command>),
    /// A Renderer's readback: a field of `bits` bits of a rectangle of its array, packed into
    /// ring words as `pxpl5_renderer::readback` documents, with the readback command's tag (the
    /// frame buffer reads the tag as the screen position of array pixel (0, 0): x in the low 16
    /// bits, y in the high 16).
    Pixels {
        tag: u32,
        rect: pxpl5_renderer::Rect,
        bits: u32,
        words: Vec<u64>,
    },
    /// Program data between GPs: `words` ring words, with a program-defined value list.
    Data {
        tag: u64,
        values: Vec<f64>,
        words: u32,
    },
}

/// A delivered message.
#[derive(Clone, Debug, PartialEq)]
pub struct Message {
    pub from: Unit,
    pub payload: Payload,
    /// When the ring delivered it. A message held back to keep send order keeps its own arrival
    /// time, so successive receives can see `at` go backwards.
    pub at: Tick,
}

/// i860 operations a program charges, priced by the config's [`GpCostTable`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Op {
    VertexTransform,
    ClipTest,
    PolygonSetup,
    EdgeSetup,
    CommandEncode,
    FfAccumulatePerPixel,
    RadiosityUpdatePerPatch,
}

impl Op {
    /// i860 cycles of one operation.
    pub fn cycles(self, t: &GpCostTable) -> u64 {
        match self {
            Op::VertexTransform => t.vertex_transform,
            Op::ClipTest => t.clip_test,
            Op::PolygonSetup => t.polygon_setup,
            Op::EdgeSetup => t.edge_setup,
            Op::CommandEncode => t.command_encode,
            Op::FfAccumulatePerPixel => t.ff_accumulate_per_pixel,
            Op::RadiosityUpdatePerPatch => t.radiosity_update_per_patch,
        }
    }
}

/// The i860 operations a piece of GP work performed, priced by the cost table when
/// [`Gp::work`] charges them. Work that can run outside a GP (to record a command stream, say)
/// takes a `&mut Cost` and notes each operation where it does it, so what is charged and what is
/// computed cannot drift apart.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Cost {
    ops: Vec<(Op, u64)>,
}

impl Cost {
    /// Note `count` operations of kind `op`.
    pub fn add(&mut self, op: Op, count: u64) {
        if count > 0 {
            self.ops.push((op, count));
        }
    }

    /// The operations noted, in order.
    pub fn ops(&self) -> &[(Op, u64)] {
        &self.ops
    }

    /// i860 cycles of everything noted.
    pub fn cycles(&self, t: &GpCostTable) -> u64 {
        self.ops.iter().map(|&(op, n)| op.cycles(t) * n).sum()
    }
}

/// What a waiting GP asked the machine for.
#[derive(Clone, Debug, PartialEq)]
pub enum Request {
    /// Busy for this many i860 cycles.
    Compute(Cycles),
    /// Put a message on the ring (after the `message_send` software cost).
    Send(Unit, Payload),
    /// Wait for the next message.
    Recv,
}

/// The cell a GP's futures and the machine share.
#[derive(Debug, Default)]
pub(crate) struct Shared {
    pub request: Option<Request>,
    pub granted: bool,
    pub mailbox: VecDeque<Message>,
    pub received: Option<Message>,
    pub now: Tick,
    pub phase_marks: Vec<PhaseMark>,
}

/// The start of a program phase on one GP ([`Gp::phase`]).
#[derive(Debug)]
pub(crate) struct PhaseMark {
    pub name: String,
    pub at: Tick,
}

/// A GP's handle on the machine: everything its program may do.
#[derive(Clone)]
pub struct Gp {
    pub(crate) index: u32,
    pub(crate) gps: u32,
    pub(crate) renderers: u32,
    pub(crate) costs: GpCostTable,
    pub(crate) renderer_cfg: pxpl5_config::RendererConfig,
    pub(crate) ring_word_bits: u32,
    pub(crate) frame_buffer: (u32, u32),
    pub(crate) shared: Rc<RefCell<Shared>>,
}

/// A future that posts one request and completes when the machine grants it.
struct Wait {
    shared: Rc<RefCell<Shared>>,
    request: Option<Request>,
}

impl Future for Wait {
    type Output = ();
    fn poll(mut self: Pin<&mut Self>, _: &mut Context<'_>) -> Poll<()> {
        let this = &mut *self;
        let mut s = this.shared.borrow_mut();
        if let Some(r) = this.request.take() {
            s.request = Some(r);
            s.granted = false;
            return Poll::Pending;
        }
        if s.granted {
            s.granted = false;
            Poll::Ready(())
        } else {
            Poll::Pending
        }
    }
}

impl Gp {
    /// This GP's number, 0-based.
    pub fn index(&self) -> u32 {
        self.index
    }

    /// GPs in the machine.
    pub fn gp_count(&self) -> u32 {
        self.gps
    }

    /// Renderers in the machine.
    pub fn renderer_count(&self) -> u32 {
        self.renderers
    }

    /// The Renderers' configuration (size, pixel memory, QEE format): what a GP program must
    /// know to generate commands.
    pub fn renderer_config(&self) -> &pxpl5_config::RendererConfig {
        &self.renderer_cfg
    }

    /// Bits per ring word.
    pub fn ring_word_bits(&self) -> u32 {
        self.ring_word_bits
    }

    /// The frame buffer's width and height in pixels.
    pub fn frame_buffer_size(&self) -> (u32, u32) {
        self.frame_buffer
    }

    /// The current simulated time.
    pub fn now(&self) -> Tick {
        self.shared.borrow().now
    }

    /// Mark the start of a program phase (it lasts until the next mark or the program's end).
    pub fn phase(&self, name: &str) {
        let mut s = self.shared.borrow_mut();
        let now = s.now;
        s.phase_marks.push(PhaseMark {
            name: name.to_string(),
            at: now,
        });
    }

    /// Be busy for `count` operations of kind `op`, priced by the cost table.
    pub async fn compute(&self, op: Op, count: u64) {
        self.compute_cycles(Cycles(op.cycles(&self.costs) * count))
            .await
    }

    /// Do a piece of GP work and charge what it noted in its [`Cost`], as one call: `f` runs on
    /// the host (instantly), then the GP is busy for the cycles of the operations it noted.
    pub async fn work<T>(&self, f: impl FnOnce(&mut Cost) -> T) -> T {
        let mut cost = Cost::default();
        let out = f(&mut cost);
        self.compute_cycles(Cycles(cost.cycles(&self.costs))).await;
        out
    }

    /// Be busy for a number of i860 cycles.
    pub async fn compute_cycles(&self, cycles: Cycles) {
        if cycles.0 == 0 {
            return;
        }
        self.wait(Request::Compute(cycles)).await
    }

    /// Send a message; returns once the ring has accepted it (after the `message_send` cost and
    /// any wait for output-queue space).
    pub async fn send(&self, to: Unit, payload: Payload) {
        self.wait(Request::Send(to, payload)).await
    }

    /// Send Renderer commands, charging `command_encode` per command first.
    pub async fn send_commands(&self, renderer: u32, commands: Vec<Command>) {
        self.compute(Op::CommandEncode, commands.len() as u64).await;
        self.send(Unit::Renderer(renderer), Payload::Commands(commands))
            .await
    }

    /// Wait for the next message (in arrival order; messages between two units arrive in send
    /// order).
    pub async fn recv(&self) -> Message {
        self.wait(Request::Recv).await;
        self.shared
            .borrow_mut()
            .received
            .take()
            .expect("the machine grants a receive with a message")
    }

    async fn wait(&self, request: Request) {
        Wait {
            shared: self.shared.clone(),
            request: Some(request),
        }
        .await
    }
}

/// Why a program failed: its own mistake (a bad scene, too little pixel memory ...).
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{0}")]
pub struct ProgramError(pub String);

/// The future of one GP's program.
pub type GpFuture = Pin<Box<dyn Future<Output = Result<(), ProgramError>>>>;

/// A program: one future per GP.
pub trait Program {
    /// The program's name, for stats and traces.
    fn name(&self) -> &str;
    /// The code GP `gp.index()` runs.
    fn gp_main(&self, gp: Gp) -> GpFuture;
}
