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
    /// A Renderer's readback: the values of a field of `bits` bits of a rectangle of its array,
    /// row by row (on the ring, the words they take packed as `pxpl5_renderer::readback`
    /// documents; the host carries the values themselves), with the readback command's tag (the
    /// frame buffer reads the tag as the screen position of array pixel (0, 0): x in the low 16
    /// bits, y in the high 16).
    Pixels {
        tag: u32,
        rect: pxpl5_renderer::Rect,
        bits: u32,
        values: Vec<u64>,
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
    WTableEntry,
    RadiosityUpdatePerPatch,
}

impl Op {
    /// Every operation, in declaration order (`op as usize` is its place).
    pub const ALL: [Op; 8] = [
        Op::VertexTransform,
        Op::ClipTest,
        Op::PolygonSetup,
        Op::EdgeSetup,
        Op::CommandEncode,
        Op::FfAccumulatePerPixel,
        Op::WTableEntry,
        Op::RadiosityUpdatePerPatch,
    ];

    /// i860 cycles of one operation.
    pub fn cycles(self, t: &GpCostTable) -> u64 {
        match self {
            Op::VertexTransform => t.vertex_transform,
            Op::ClipTest => t.clip_test,
            Op::PolygonSetup => t.polygon_setup,
            Op::EdgeSetup => t.edge_setup,
            Op::CommandEncode => t.command_encode,
            Op::FfAccumulatePerPixel => t.ff_accumulate_per_pixel,
            Op::WTableEntry => t.w_table_entry,
            Op::RadiosityUpdatePerPatch => t.radiosity_update_per_patch,
        }
    }
}

/// The i860 operations a piece of GP work performed, priced by the cost table when
/// [`Gp::work`] charges them. Work that can run outside a GP (to record a command stream, say)
/// takes a `&mut Cost` and notes each operation where it does it, so what is charged and what is
/// computed cannot drift apart. A count per kind of operation, not a list: a list was an
/// allocation per piece of work (a receiver's commands, 24 K in 24 hemicube shots).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Cost {
    counts: [u64; Op::ALL.len()],
}

impl Cost {
    /// Note `count` operations of kind `op`.
    pub fn add(&mut self, op: Op, count: u64) {
        let c = &mut self.counts[op as usize];
        *c = c.saturating_add(count);
    }

    /// The operations of kind `op` noted so far.
    pub fn count(&self, op: Op) -> u64 {
        self.counts[op as usize]
    }

    /// i860 cycles of everything noted, saturating at `u64::MAX` (costs are user input; a
    /// saturated charge ends the run at its time limit, see `pxpl5_sim`'s time module).
    pub fn cycles(&self, t: &GpCostTable) -> u64 {
        // min(sum of cycles x count, u64::MAX): the same in any grouping of the counts.
        Op::ALL.iter().fold(0u64, |sum, &op| {
            sum.saturating_add(op.cycles(t).saturating_mul(self.count(op)))
        })
    }
}

/// What a waiting GP asked the machine for.
#[derive(Clone, Debug, PartialEq)]
pub enum Request {
    /// Busy for this many i860 cycles.
    Compute(Cycles),
    /// Put a message on the ring (after the `message_send` software cost).
    Send {
        to: Unit,
        payload: Payload,
        /// Its ring words, if the sender counted them (a [`CommandBatch`] has, as it filled
        /// the message); else the machine counts them.
        words: Option<u32>,
    },
    /// Wait for the next message.
    Recv,
    /// Nothing but the present: a program that looks at its mailbox while its GP runs ahead of
    /// the machine's time (`Shared::ahead`) waits for the machine to reach it first.
    Sync,
}

/// The cell a GP's futures and the machine share.
#[derive(Debug, Default)]
pub(crate) struct Shared {
    pub request: Option<Request>,
    pub granted: bool,
    pub mailbox: VecDeque<Message>,
    pub received: Option<Message>,
    pub now: Tick,
    /// Whether the program is polled ahead of the machine's time: at the end of computing it
    /// asked for, before the machine reaches that instant (see `gp_node`). `now` is then that
    /// end; what arrives meanwhile is not in the mailbox yet.
    pub ahead: bool,
    pub phase_marks: Vec<PhaseMark>,
    /// Messages received (and charged) that the program did not want yet, in arrival order: the
    /// selective receive of [`Gp::recv_where`] takes from here first.
    pub stash: VecDeque<Message>,
}

/// The start of a program phase on one GP ([`Gp::phase`]).
#[derive(Debug)]
pub(crate) struct PhaseMark {
    pub name: &'static str,
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
    /// Whether the Renderers simulate pixel values (`RunOptions::fidelity`).
    pub(crate) pixels: bool,
    pub(crate) ring_word_bits: u32,
    pub(crate) max_message_words: u32,
    pub(crate) frame_buffer: (u32, u32),
    pub(crate) shared: Rc<RefCell<Shared>>,
}

/// Ring words of a Data message besides its values: one word for the tag and the record count
/// (\[choice\] of the GP runtime's message format; the ring adds its own packet headers).
pub const DATA_HEADER_WORDS: u32 = 1;

/// Marks the last message of a record stream ([`Gp::send_records`]) in its tag.
const LAST_OF_STREAM: u64 = 1 << 63;

/// A program's tag of a Data message: what the message carries. Programs name their tags with an
/// enum and give each a distinct code below 2^63 (the runtime keeps the top bit).
pub trait Tag: Copy {
    fn code(self) -> u64;
}

/// A fixed-size record of program data sent between GPs, and what it costs on the ring.
pub trait Record: Sized {
    /// Values per record.
    const VALUES: usize;
    /// Ring words per record: the program's statement of how its values travel (each record type
    /// documents it, e.g. one 32-bit word per value).
    const WORDS: u32;
    /// Append the record's `VALUES` values.
    fn encode(&self, out: &mut Vec<f64>);
    /// The record from exactly `VALUES` values.
    fn decode(values: &[f64]) -> Self;
}

/// Most commands a [`CommandBatch`] makes room for at once (a bound on what a guess from the
/// first group of a message may take).
const MAX_RESERVED_COMMANDS: usize = 4096;

/// Commands for one Renderer gathered into messages of at most the ring's `max_message_words`:
/// [`CommandBatch::push`] sends what it holds when the next group of commands would not fit.
pub struct CommandBatch {
    renderer: u32,
    commands: Vec<Command>,
    words: u32,
    sent: bool,
}

impl CommandBatch {
    /// An empty batch for Renderer `renderer`.
    pub fn new(renderer: u32) -> CommandBatch {
        CommandBatch {
            renderer,
            commands: Vec::new(),
            words: 0,
            sent: false,
        }
    }

    /// The Renderer the batch is for.
    pub fn renderer(&self) -> u32 {
        self.renderer
    }

    /// Add a group of commands that must travel in one message (one receiver's, one triangle's);
    /// first send what the batch holds if the group would not fit beside it. Whether it sent a
    /// message (a program drawing into several boards can then turn to another). The group is
    /// left empty, its buffer the caller's for the next group.
    pub async fn push(&mut self, gp: &Gp, group: &mut Vec<Command>) -> bool {
        let w = gp.command_words(group);
        let full = self.words + w > gp.max_message_words && !self.commands.is_empty();
        if full {
            self.send(gp).await;
        }
        if self.commands.is_empty() {
            // Room for a message of groups like this one, made once: grown group by group, a
            // message's list was reallocated several times (each time copied whole).
            let groups = (gp.max_message_words / w.max(1)).max(1) as usize;
            self.commands.reserve(
                group
                    .len()
                    .saturating_mul(groups)
                    .min(MAX_RESERVED_COMMANDS),
            );
        }
        self.commands.append(group);
        self.words += w;
        full
    }

    /// Send what the batch holds; whether the batch sent anything at all, now or before.
    pub async fn finish(mut self, gp: &Gp) -> bool {
        if !self.commands.is_empty() {
            self.send(gp).await;
        }
        self.sent
    }

    /// The message's words go with it: counting its commands again at the machine was 0.7 % of
    /// the main job's hemisphere CPU time.
    async fn send(&mut self, gp: &Gp) {
        let words = std::mem::take(&mut self.words);
        self.sent = true;
        let commands = std::mem::take(&mut self.commands);
        gp.send_commands_counted(self.renderer, commands, Some(words))
            .await;
    }
}

/// A future that completes when the machine grants the request [`Gp::wait`] posted: pending
/// at its first poll, which follows the posting at once.
struct Wait {
    shared: Rc<RefCell<Shared>>,
}

impl Future for Wait {
    type Output = ();
    fn poll(self: Pin<&mut Self>, _: &mut Context<'_>) -> Poll<()> {
        let mut s = self.shared.borrow_mut();
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

    /// Whether the Renderers' readbacks carry pixel values. At the approximate `timing` fidelity
    /// level they carry zeros (in messages of the right size, at the right time), so a program
    /// whose results come from pixel values must compute them some other way, outside
    /// simulated time, and say so. Host knowledge, not the machine's: a program's simulated
    /// work and charges must not depend on it.
    pub fn renderers_have_pixels(&self) -> bool {
        self.pixels
    }

    /// Bits per ring word.
    pub fn ring_word_bits(&self) -> u32 {
        self.ring_word_bits
    }

    /// The most payload words one ring message carries (`ring.max_message_words`).
    pub fn max_message_words(&self) -> u32 {
        self.max_message_words
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
    /// A program has a few phases and marks them over and over, so a phase is named by a
    /// `'static` string, kept without a copy.
    pub fn phase(&self, name: &'static str) {
        let mut s = self.shared.borrow_mut();
        let now = s.now;
        s.phase_marks.push(PhaseMark { name, at: now });
    }

    /// Be busy for `count` operations of kind `op`, priced by the cost table. Programs charge
    /// their work with [`Gp::work`] instead, so that what is charged is what is done (tidy checks
    /// `programs/`); this is for tests of the machine.
    pub async fn compute(&self, op: Op, count: u64) {
        self.compute_cycles(Cycles(op.cycles(&self.costs).saturating_mul(count)))
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
        self.send_counted(to, payload, None).await
    }

    /// [`Gp::send`] of a payload of `words` ring words, if known.
    async fn send_counted(&self, to: Unit, payload: Payload, words: Option<u32>) {
        self.wait(Request::Send { to, payload, words }).await
    }

    /// Send Renderer commands, charging `command_encode` per command first.
    pub async fn send_commands(&self, renderer: u32, commands: Vec<Command>) {
        self.send_commands_counted(renderer, commands, None).await
    }

    /// [`Gp::send_commands`] of `words` ring words, if known.
    async fn send_commands_counted(
        &self,
        renderer: u32,
        commands: Vec<Command>,
        words: Option<u32>,
    ) {
        self.compute(Op::CommandEncode, commands.len() as u64).await;
        let to = Unit::Renderer(renderer);
        self.send_counted(to, Payload::Commands(commands), words)
            .await
    }

    /// Ring words of a list of commands (with this machine's QEE format and ring word).
    pub fn command_words(&self, commands: &[Command]) -> u32 {
        let coefficient_bits = self.renderer_cfg.qee.coefficient_format.total_bits();
        Command::list_words(commands, coefficient_bits, self.ring_word_bits)
    }

    /// The first message `want` accepts: from the stash of messages received earlier that were
    /// not wanted then, else the next ones received (each charged `message_receive` as it
    /// arrives; those not wanted go to the stash in arrival order).
    pub async fn recv_where(&self, want: impl Fn(&Message) -> bool) -> Message {
        let stashed = {
            let mut s = self.shared.borrow_mut();
            let i = s.stash.iter().position(&want);
            i.and_then(|i| s.stash.remove(i))
        };
        if let Some(m) = stashed {
            return m;
        }
        loop {
            let m = self.recv().await;
            if want(&m) {
                return m;
            }
            self.shared.borrow_mut().stash.push_back(m);
        }
    }

    /// Whether a message `want` accepts has arrived by now (received earlier and stashed, or
    /// delivered and not yet received): a look at the ring interface's status, not a receive, so
    /// nothing is charged (\[choice\]: an i860 load of a status register, a few cycles, where a
    /// receive costs `message_receive`). A program with work in hand uses it to receive only what
    /// is there.
    pub async fn has_message(&self, want: impl Fn(&Message) -> bool) -> bool {
        // Ahead of the machine's time, the mailbox lacks what arrives until now: wait for the
        // machine to reach now, which costs nothing.
        if self.shared.borrow().ahead {
            self.wait(Request::Sync).await;
        }
        let s = self.shared.borrow();
        s.stash.iter().any(&want) || s.mailbox.iter().any(&want)
    }

    /// The next Data message with `tag`.
    pub async fn recv_data(&self, tag: impl Tag) -> Message {
        let code = tag.code();
        self.recv_where(|m| matches!(m.payload, Payload::Data { tag: t, .. } if t == code))
            .await
    }

    /// The next Pixels message (a readback) from Renderer `r`.
    pub async fn recv_pixels(&self, r: u32) -> Message {
        self.recv_where(|m| {
            m.from == Unit::Renderer(r) && matches!(m.payload, Payload::Pixels { .. })
        })
        .await
    }

    /// Send GP `to` a Data message with `tag` and no values: a signal.
    pub async fn signal(&self, to: u32, tag: impl Tag) {
        let payload = Payload::Data {
            tag: tag.code(),
            values: Vec::new(),
            words: DATA_HEADER_WORDS,
        };
        self.send(Unit::Gp(to), payload).await
    }

    /// Send GP `to` a stream of records with `tag`, in messages of as many whole records as fit
    /// in the ring's `max_message_words` (at least one; an empty stream is one empty message); the
    /// last message is marked, so the receiver knows the stream is complete.
    pub async fn send_records<R: Record>(&self, to: u32, tag: impl Tag, records: &[R]) {
        let room = self.max_message_words.saturating_sub(DATA_HEADER_WORDS);
        let per = (room / R::WORDS.max(1)).max(1) as usize;
        let chunks: Vec<&[R]> = if records.is_empty() {
            vec![&[]]
        } else {
            records.chunks(per).collect()
        };
        let n = chunks.len();
        for (i, chunk) in chunks.into_iter().enumerate() {
            let mut values = Vec::with_capacity(chunk.len() * R::VALUES);
            for r in chunk {
                r.encode(&mut values);
            }
            let last = if i + 1 == n { LAST_OF_STREAM } else { 0 };
            let payload = Payload::Data {
                tag: tag.code() | last,
                values,
                words: DATA_HEADER_WORDS + R::WORDS * chunk.len() as u32,
            };
            self.send(Unit::Gp(to), payload).await;
        }
    }

    /// One complete [`Gp::send_records`] stream with `tag` from each of `senders` GPs: their
    /// records, in arrival order.
    pub async fn recv_records<R: Record>(&self, tag: impl Tag, senders: u32) -> Vec<R> {
        let code = tag.code();
        let mut out = Vec::new();
        let mut done = 0;
        while done < senders {
            let m = self
                .recv_where(|m| {
                    matches!(m.payload, Payload::Data { tag: t, .. } if t & !LAST_OF_STREAM == code)
                })
                .await;
            if let Payload::Data { tag: t, values, .. } = m.payload {
                out.extend(values.chunks_exact(R::VALUES).map(R::decode));
                if t & LAST_OF_STREAM != 0 {
                    done += 1;
                }
            }
        }
        out
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

    /// Post `request` for the machine; the future completes when the machine grants it. A
    /// plain function its async callers await at once, so the request is posted in the same
    /// poll as before, and written where the machine reads it: carried in the future and moved
    /// at its first poll, it was copied by 16-byte loads from the 8-byte stores that had just
    /// made it, which cannot take their values forwarded (`perf annotate`: the two hottest
    /// instructions of the GPs' waits, about 1 % of the main job's hemicube CPU time).
    #[inline(always)]
    fn wait(&self, request: Request) -> Wait {
        let mut s = self.shared.borrow_mut();
        s.request = Some(request);
        s.granted = false;
        Wait {
            shared: self.shared.clone(),
        }
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

#[cfg(test)]
mod tests {
    use super::{Cost, Op};
    use pxpl5_config::GpCostTable;

    /// `op as usize` is the op's place in `Op::ALL`: a count noted under one op is charged at
    /// that op's price.
    #[test]
    fn every_op_is_counted_at_its_own_price() {
        let t = GpCostTable::default();
        for (i, &op) in Op::ALL.iter().enumerate() {
            assert_eq!(op as usize, i, "{op:?}");
            let mut c = Cost::default();
            c.add(op, 3);
            c.add(op, 4);
            assert_eq!(c.count(op), 7, "{op:?}");
            assert_eq!(c.cycles(&t), op.cycles(&t) * 7, "{op:?}");
        }
    }

    /// A charge that overflows saturates, as a list of (op, count) summed with saturation did.
    #[test]
    fn an_overflowing_charge_saturates() {
        let t = GpCostTable::default();
        let mut c = Cost::default();
        c.add(Op::VertexTransform, u64::MAX / 2);
        c.add(Op::VertexTransform, u64::MAX / 2);
        c.add(Op::ClipTest, 5);
        assert!(Op::VertexTransform.cycles(&t) > 1);
        assert_eq!(c.cycles(&t), u64::MAX);
    }
}
