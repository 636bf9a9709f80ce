//! The machine: GPs, Renderers, the frame buffer and the host on the ring, built from a config,
//! running one program to completion in simulated time.
//!
//! **The loop.** Simulated time advances from one instant to the next at which something happens:
//! a GP finishes computing, a Renderer finishes a command, the ring delivers a message or frees
//! queue space. At each instant, in this order (each step's reason in brackets):
//! 1. the ring advances to the instant and its deliveries are handed to their units [arrivals are
//!    visible to everything that acts at the same instant];
//! 2. due events pop in (tick, priority, component, sequence) order: Renderer completions, then
//!    GP wake-ups [a Renderer that finishes frees its queue before GPs run];
//! 3. idle Renderers start their next command;
//! 4. GPs run in index order until each waits again [GPs see every arrival and completion of the
//!    instant];
//! 5. blocked sends are retried.
//!
//! If every GP waits and nothing is due, the run stops with a deadlock report naming who waits for
//! what; a limit on simulated time ends runaway runs with an error.

use std::cell::RefCell;
use std::collections::{BTreeMap, VecDeque};
use std::rc::Rc;
use std::task::{Context, Poll, Waker};

use pxpl5_config::{MachineConfig, NodeOrder};
use pxpl5_renderer::{Board, Command, Fidelity, readback};
use pxpl5_ring::{MessageId, NodeId, Ring, RingError};
use pxpl5_sim::{ClockDomain, ComponentId, Cycles, EventQueue, Priority, Tick};

use crate::gp::{Gp, GpFuture, Message, Payload, Program, Request, Shared, Unit};
use crate::record::Recorder;
use crate::stats::{GpStats, PhaseSpan, RendererNodeStats, RunStats};

/// Options of one run.
#[derive(Clone, Debug)]
pub struct RunOptions {
    pub fidelity: Fidelity,
    /// Simulated time after which the run is stopped with an error.
    pub max_time: Tick,
}

impl Default for RunOptions {
    fn default() -> RunOptions {
        RunOptions {
            fidelity: Fidelity::Word,
            // 10 simulated seconds: far beyond any shipped program's run.
            max_time: Tick(10_000_000_000_000),
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
    #[error("{unit} sent a message the ring cannot carry: {error}")]
    Ring { unit: Unit, error: RingError },
    #[error("{from} sent a message to {to}, which this machine does not have")]
    NoSuchUnit { from: Unit, to: Unit },
    #[error("bad machine: {0}")]
    Config(String),
}

/// What a GP is doing.
#[derive(Clone, Debug, PartialEq)]
enum GpState {
    Runnable,
    /// Busy until a wake-up event; the request to grant then (a send to perform, or none).
    Busy(Option<(Unit, Payload)>),
    /// The ring's output queue was full; retried at every instant.
    BlockedSend(Unit, Payload),
    Receiving,
    Done,
}

struct GpNode {
    future: Option<GpFuture>,
    shared: Rc<RefCell<Shared>>,
    state: GpState,
    clock: ClockDomain,
    busy: Tick,
    finished: Option<Tick>,
    messages_sent: u64,
    messages_received: u64,
}

struct RendererNode {
    board: Board,
    clock: ClockDomain,
    /// Commands in arrival order, with their sender and the ring message they came in.
    queue: VecDeque<(Command, Unit, MessageId, bool)>,
    running: Option<(Command, Unit, MessageId, bool, Tick)>,
    /// Readback messages waiting for output-queue space.
    outbox: VecDeque<(Unit, Payload)>,
    busy: Tick,
    commands: u64,
}

/// Events of the machine's queue.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Event {
    GpWake(u32),
    RendererDone(u32),
}

/// The frame buffer's memory: 8-bit RGB.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Frame {
    pub width: u32,
    pub height: u32,
    /// Row-major RGB bytes.
    pub rgb: Vec<u8>,
    /// Pixels written so far.
    pub writes: u64,
}

/// The result of a run: simulated statistics, the frame, and the trace recorder.
pub struct RunResult {
    pub stats: RunStats,
    pub frame: Frame,
    pub recorder: Recorder,
}

/// A machine built from a config.
pub struct Machine {
    cfg: MachineConfig,
    units: Vec<Unit>,
    positions: BTreeMap<Unit, NodeId>,
    ring: Ring,
    gps: Vec<GpNode>,
    renderers: Vec<RendererNode>,
    frame: Frame,
    events: EventQueue<Event>,
    /// Payloads of messages on the ring, by id.
    in_flight: BTreeMap<MessageId, (Unit, Unit, u64, Payload)>,
    /// Per (from, to): the next sequence number to send and to deliver, and arrivals waiting for
    /// an earlier message (the ring may deliver out of send order across channels).
    send_seq: BTreeMap<(Unit, Unit), u64>,
    deliver_seq: BTreeMap<(Unit, Unit), u64>,
    held: BTreeMap<(Unit, Unit, u64), (MessageId, Message)>,
    now: Tick,
    options: RunOptions,
    recorder: Recorder,
    program: String,
}

/// The ring position of every unit under the config's node order.
pub fn node_order(cfg: &MachineConfig) -> Vec<Unit> {
    let (g, r) = (cfg.gp.count, cfg.renderer.count);
    let mut units = Vec::new();
    match cfg.ring.node_order {
        NodeOrder::GpsThenRenderers => {
            units.extend((0..g).map(Unit::Gp));
            units.extend((0..r).map(Unit::Renderer));
        }
        NodeOrder::Interleaved => {
            // Spread the smaller group evenly among the larger (Bresenham-like, integer only).
            let (mut gi, mut ri) = (0, 0);
            while gi < g || ri < r {
                // Place a GP when GPs are behind their share of the positions so far.
                if ri >= r
                    || (gi < g && u64::from(gi) * u64::from(r) <= u64::from(ri) * u64::from(g))
                {
                    units.push(Unit::Gp(gi));
                    gi += 1;
                } else {
                    units.push(Unit::Renderer(ri));
                    ri += 1;
                }
            }
        }
    }
    units.push(Unit::FrameBuffer);
    if cfg.host.present {
        units.push(Unit::Host);
    }
    units
}

fn clock(hz: u64, what: &str) -> Result<ClockDomain, RunError> {
    ClockDomain::from_hz(hz).map_err(|e| RunError::Config(format!("{what}: {e}")))
}

impl Machine {
    /// Build the machine of `cfg` (validated by `pxpl5_config`) to run `program`.
    pub fn new(
        cfg: &MachineConfig,
        program: &dyn Program,
        options: RunOptions,
        recorder: Recorder,
    ) -> Result<Machine, RunError> {
        let units = node_order(cfg);
        let positions = units
            .iter()
            .enumerate()
            .map(|(i, u)| (*u, NodeId(i as u32)))
            .collect();
        let ring = Ring::new(&cfg.ring, units.len() as u32)
            .map_err(|e| RunError::Config(e.to_string()))?;
        let gp_clock = clock(cfg.gp.clock_hz, "gp.clock_hz")?;
        let r_clock = clock(cfg.renderer.clock_hz, "renderer.clock_hz")?;
        let fb = (cfg.frame_buffer.width, cfg.frame_buffer.height);
        let gps = (0..cfg.gp.count)
            .map(|i| {
                let shared = Rc::new(RefCell::new(Shared::default()));
                let gp = Gp {
                    index: i,
                    gps: cfg.gp.count,
                    renderers: cfg.renderer.count,
                    costs: cfg.gp.costs.clone(),
                    renderer_cfg: cfg.renderer.clone(),
                    ring_word_bits: cfg.ring.word_bits,
                    frame_buffer: fb,
                    shared: shared.clone(),
                };
                GpNode {
                    future: Some(program.gp_main(gp)),
                    shared,
                    state: GpState::Runnable,
                    clock: gp_clock,
                    busy: Tick::ZERO,
                    finished: None,
                    messages_sent: 0,
                    messages_received: 0,
                }
            })
            .collect();
        let renderers = (0..cfg.renderer.count)
            .map(|_| RendererNode {
                board: Board::new(&cfg.renderer, cfg.ring.word_bits, options.fidelity),
                clock: r_clock,
                queue: VecDeque::new(),
                running: None,
                outbox: VecDeque::new(),
                busy: Tick::ZERO,
                commands: 0,
            })
            .collect();
        Ok(Machine {
            cfg: cfg.clone(),
            units,
            positions,
            ring,
            gps,
            renderers,
            frame: Frame {
                width: fb.0,
                height: fb.1,
                rgb: vec![0; fb.0 as usize * fb.1 as usize * 3],
                writes: 0,
            },
            events: EventQueue::new(),
            in_flight: BTreeMap::new(),
            send_seq: BTreeMap::new(),
            deliver_seq: BTreeMap::new(),
            held: BTreeMap::new(),
            now: Tick::ZERO,
            options,
            recorder,
            program: program.name().to_string(),
        })
    }

    /// The ring positions of the units, in order.
    pub fn units(&self) -> &[Unit] {
        &self.units
    }

    /// Run the program to completion.
    pub fn run(mut self) -> Result<RunResult, RunError> {
        let _span =
            tracing::debug_span!("machine", program = %self.program, config = %self.cfg.name)
                .entered();
        let renderer_cycle = self
            .renderers
            .first()
            .map(|r| r.clock.period())
            .unwrap_or(Tick(1));
        self.recorder.declare(
            &self.units,
            self.cfg.ring.channels,
            renderer_cycle,
            u64::from(self.cfg.ring.queue_words),
        );
        loop {
            self.step_units()?;
            if self.gps.iter().all(|g| g.state == GpState::Done) && self.quiescent() {
                break;
            }
            let next = [self.events.peek_tick(), self.ring.next_event_tick()]
                .into_iter()
                .flatten()
                .min();
            let Some(next) = next else {
                return Err(RunError::Deadlock {
                    at: self.now,
                    waiting: self.waiting_report(),
                });
            };
            if next > self.options.max_time {
                return Err(RunError::TimeLimit {
                    limit: self.options.max_time,
                    running: self.waiting_report().replace('\n', "; "),
                });
            }
            // Events may be due at the current instant (a zero-cycle cost): they run now.
            let mut progress = next > self.now;
            self.now = next;
            self.ring.advance(next);
            for d in self.ring.take_deliveries() {
                progress = true;
                self.deliver(d)?;
            }
            while self.events.peek_tick() == Some(next) {
                progress = true;
                let e = self.events.pop().expect("peeked");
                match e.payload {
                    Event::RendererDone(r) => self.renderer_done(r)?,
                    Event::GpWake(g) => self.gp_wake(g),
                }
            }
            self.recorder.ring_sample(self.now, &self.ring);
            assert!(
                progress,
                "machine made no progress at {}: ring reports an event due now but delivers nothing",
                self.now
            );
        }
        Ok(self.finish())
    }

    /// Steps 3 to 5 of the loop at the current instant, repeated until nothing changes (a GP's
    /// send can make a Renderer runnable and so on, all at the same instant).
    fn step_units(&mut self) -> Result<(), RunError> {
        loop {
            let mut progress = false;
            for r in 0..self.renderers.len() {
                progress |= self.renderer_try_start(r as u32)?;
            }
            for g in 0..self.gps.len() {
                progress |= self.gp_run(g as u32)?;
            }
            for g in 0..self.gps.len() {
                if let GpState::BlockedSend(to, payload) = self.gps[g].state.clone()
                    && self.try_send(Unit::Gp(g as u32), to, payload)?
                {
                    self.gps[g].state = GpState::Runnable;
                    self.gps[g].shared.borrow_mut().granted = true;
                    progress = true;
                }
            }
            if !progress {
                return Ok(());
            }
        }
    }

    fn quiescent(&self) -> bool {
        self.ring.is_idle()
            && self.in_flight.is_empty()
            && self
                .renderers
                .iter()
                .all(|r| r.queue.is_empty() && r.running.is_none() && r.outbox.is_empty())
    }

    /// Run GP `g` if it is runnable; whether it did anything.
    fn gp_run(&mut self, g: u32) -> Result<bool, RunError> {
        let gi = g as usize;
        if self.gps[gi].state != GpState::Runnable {
            return Ok(false);
        }
        let now = self.now;
        self.gps[gi].shared.borrow_mut().now = now;
        let mut fut = self.gps[gi]
            .future
            .take()
            .expect("a runnable GP has its future");
        let poll = fut.as_mut().poll(&mut Context::from_waker(Waker::noop()));
        self.gps[gi].future = Some(fut);
        self.flush_phases(g);
        match poll {
            Poll::Ready(Ok(())) => {
                self.gps[gi].state = GpState::Done;
                self.gps[gi].finished = Some(now);
                self.gps[gi].future = None;
                self.recorder.gp_done(g, now);
                return Ok(true);
            }
            Poll::Ready(Err(e)) => {
                return Err(RunError::Program {
                    gp: g,
                    message: e.0,
                });
            }
            Poll::Pending => {}
        }
        let request = self.gps[gi].shared.borrow_mut().request.take();
        let costs = &self.cfg.gp.costs;
        match request {
            Some(Request::Compute(c)) => self.gp_busy(g, c, None),
            Some(Request::Send(to, payload)) => {
                let c = Cycles(costs.message_send);
                self.gp_busy(g, c, Some((to, payload)));
            }
            Some(Request::Recv) => {
                let next = self.gps[gi].shared.borrow_mut().mailbox.pop_front();
                match next {
                    Some(m) => {
                        self.gps[gi].shared.borrow_mut().received = Some(m);
                        self.gps[gi].messages_received += 1;
                        let c = Cycles(costs.message_receive);
                        self.gp_busy(g, c, None);
                    }
                    None => self.gps[gi].state = GpState::Receiving,
                }
            }
            None => {
                // A future returned Pending without a request: it awaited something that is
                // not the machine's (a program bug the runtime cannot serve).
                return Err(RunError::Program {
                    gp: g,
                    message: "the program awaited a future that is not a GP request".into(),
                });
            }
        }
        Ok(true)
    }

    /// GP `g` is busy for `c` of its cycles, then does `then` (a send) and resumes.
    fn gp_busy(&mut self, g: u32, c: Cycles, then: Option<(Unit, Payload)>) {
        let node = &mut self.gps[g as usize];
        let until = self.now + node.clock.to_ticks(c);
        node.busy += until - self.now;
        node.state = GpState::Busy(then);
        self.recorder.gp_busy(g, self.now, until);
        self.events
            .schedule(until, Priority::GpResume, ComponentId(g), Event::GpWake(g));
    }

    fn gp_wake(&mut self, g: u32) {
        let gi = g as usize;
        let GpState::Busy(then) = std::mem::replace(&mut self.gps[gi].state, GpState::Runnable)
        else {
            panic!("GP {g} woken at {} while not busy", self.now);
        };
        match then {
            None => self.gps[gi].shared.borrow_mut().granted = true,
            Some((to, payload)) => self.gps[gi].state = GpState::BlockedSend(to, payload),
        }
    }

    /// Put a message on the ring; false if the sender's output queue is full.
    fn try_send(&mut self, from: Unit, to: Unit, payload: Payload) -> Result<bool, RunError> {
        let (Some(src), Some(dst)) = (self.positions.get(&from), self.positions.get(&to)) else {
            return Err(RunError::NoSuchUnit { from, to });
        };
        let (src, dst) = (*src, *dst);
        let words = self.payload_words(&payload);
        let seq = *self.send_seq.get(&(from, to)).unwrap_or(&0);
        match self.ring.send(self.now, src, dst, words, seq) {
            Ok(id) => {
                self.send_seq.insert((from, to), seq + 1);
                self.in_flight.insert(id, (from, to, seq, payload));
                if let Unit::Gp(g) = from {
                    self.gps[g as usize].messages_sent += 1;
                }
                Ok(true)
            }
            Err(RingError::OutputFull { .. }) => Ok(false),
            Err(error) => Err(RunError::Ring { unit: from, error }),
        }
    }

    /// Ring words of a payload (headers are the ring's business).
    fn payload_words(&self, p: &Payload) -> u32 {
        let coefficient_bits = self.cfg.renderer.qee.coefficient_format.total_bits();
        let word_bits = self.cfg.ring.word_bits;
        match p {
            Payload::Commands(cs) => cs
                .iter()
                .map(|c| c.words(coefficient_bits, word_bits))
                .sum(),
            Payload::Pixels { words, .. } => words.len() as u32,
            Payload::Data { words, .. } => *words,
        }
        .max(1)
    }

    /// A message arrived: release it (and any held successors) in send order.
    fn deliver(&mut self, d: pxpl5_ring::Delivery) -> Result<(), RunError> {
        let (from, to, seq, payload) = self.in_flight.remove(&d.id).unwrap_or_else(|| {
            panic!("ring delivered unknown message {} at {}", d.id, d.delivered)
        });
        self.recorder
            .message_delivered(d.id, from, to, d.sent, d.delivered, d.words);
        let message = Message {
            from,
            payload,
            at: d.delivered,
        };
        self.held.insert((from, to, seq), (d.id, message));
        loop {
            let next = *self.deliver_seq.get(&(from, to)).unwrap_or(&0);
            let Some((id, m)) = self.held.remove(&(from, to, next)) else {
                return Ok(());
            };
            self.deliver_seq.insert((from, to), next + 1);
            self.hand_over(to, id, m)?;
        }
    }

    fn hand_over(&mut self, to: Unit, id: MessageId, m: Message) -> Result<(), RunError> {
        match to {
            Unit::Gp(g) => {
                self.consume(id);
                let node = &mut self.gps[g as usize];
                node.shared.borrow_mut().mailbox.push_back(m);
                if node.state == GpState::Receiving {
                    node.state = GpState::Runnable;
                    // Re-posting the receive takes the message and charges its cost.
                    node.shared.borrow_mut().request = None;
                    let msg = node
                        .shared
                        .borrow_mut()
                        .mailbox
                        .pop_front()
                        .expect("pushed");
                    node.shared.borrow_mut().received = Some(msg);
                    node.messages_received += 1;
                    let c = Cycles(self.cfg.gp.costs.message_receive);
                    self.gp_busy(g, c, None);
                }
            }
            Unit::Renderer(r) => match m.payload {
                Payload::Commands(cs) => {
                    let n = cs.len();
                    let node = &mut self.renderers[r as usize];
                    for (i, c) in cs.into_iter().enumerate() {
                        node.queue.push_back((c, m.from, id, i + 1 == n));
                    }
                    if n == 0 {
                        self.consume(id);
                    }
                }
                _ => self.consume(id),
            },
            Unit::FrameBuffer => {
                self.consume(id);
                if let Payload::Pixels {
                    tag,
                    rect,
                    bits,
                    words,
                } = m.payload
                {
                    let (x, y) = (rect.x + (tag & 0xFFFF), rect.y + (tag >> 16));
                    let (width, height) = (rect.width, rect.height);
                    let px = readback::unpack(
                        &words,
                        bits,
                        self.cfg.ring.word_bits,
                        (width * height) as usize,
                    );
                    for row in 0..height {
                        for col in 0..width {
                            let (fx, fy) = (x + col, y + row);
                            if fx >= self.frame.width || fy >= self.frame.height {
                                continue;
                            }
                            let v = px[(row * width + col) as usize];
                            // Frame-buffer rows count from the top of the screen; Renderer rows
                            // from the bottom (y up), so flip.
                            let i = ((self.frame.height - 1 - fy) * self.frame.width + fx) as usize;
                            self.frame.rgb[i * 3] = (v & 0xFF) as u8;
                            self.frame.rgb[i * 3 + 1] = ((v >> 8) & 0xFF) as u8;
                            self.frame.rgb[i * 3 + 2] = ((v >> 16) & 0xFF) as u8;
                            self.frame.writes += 1;
                        }
                    }
                }
            }
            Unit::Host => self.consume(id),
        }
        Ok(())
    }

    fn consume(&mut self, id: MessageId) {
        self.ring
            .consume(id)
            .unwrap_or_else(|e| panic!("consuming delivered message {id} at {}: {e}", self.now));
    }

    /// Start Renderer `r`'s next command if it is idle; whether it started one.
    fn renderer_try_start(&mut self, r: u32) -> Result<bool, RunError> {
        if self.renderers[r as usize].running.is_some() {
            return Ok(false);
        }
        // Readbacks waiting for the ring hold the Renderer (its output port is busy).
        while let Some((to, payload)) = self.renderers[r as usize].outbox.front().cloned() {
            if self.try_send(Unit::Renderer(r), to, payload)? {
                self.renderers[r as usize].outbox.pop_front();
            } else {
                return Ok(false);
            }
        }
        let node = &mut self.renderers[r as usize];
        let Some((cmd, from, id, last)) = node.queue.pop_front() else {
            return Ok(false);
        };
        let start_cycle = node.clock.cycles_ceil(self.now);
        node.board.idle_until(start_cycle);
        let executed = node
            .board
            .execute(&cmd)
            .map_err(|error| RunError::Command {
                renderer: r,
                kind: cmd.kind(),
                from,
                error,
            })?;
        let start = node.clock.to_ticks(executed.start);
        let end = node.clock.to_ticks(executed.end);
        node.busy += end - start;
        node.commands += 1;
        if let Some(rb) = executed.readback {
            let Command::Readback { field, rect, .. } = cmd else {
                unreachable!("only a readback reads back")
            };
            // The output port streams the rows in messages of at most max_message_words words,
            // so a whole board's field never needs a queue that large ([assumed] streaming).
            let to = Unit::decode(rb.dest);
            let word_bits = self.cfg.ring.word_bits;
            let values = readback::unpack(
                &rb.words,
                field.bits,
                word_bits,
                (rect.width * rect.height) as usize,
            );
            let row_words = readback::words_needed(rect.width as usize, field.bits, word_bits);
            let rows_per = (self.cfg.ring.max_message_words as usize / row_words.max(1)).max(1);
            for (i, rows) in values.chunks(rows_per * rect.width as usize).enumerate() {
                let height = (rows.len() / rect.width as usize) as u32;
                node.outbox.push_back((
                    to,
                    Payload::Pixels {
                        tag: rb.tag,
                        rect: pxpl5_renderer::Rect {
                            x: rect.x,
                            y: rect.y + (i * rows_per) as u32,
                            width: rect.width,
                            height,
                        },
                        bits: field.bits,
                        words: readback::pack(rows, field.bits, word_bits),
                    },
                ));
            }
        }
        self.recorder.renderer_command(r, cmd.kind(), start, end);
        node.running = Some((cmd, from, id, last, end));
        self.events.schedule(
            end,
            Priority::RendererComplete,
            ComponentId(r),
            Event::RendererDone(r),
        );
        Ok(true)
    }

    fn renderer_done(&mut self, r: u32) -> Result<(), RunError> {
        let node = &mut self.renderers[r as usize];
        let (_, _, id, last, _) = node
            .running
            .take()
            .expect("a completion has a running command");
        if last {
            self.consume(id);
        }
        Ok(())
    }

    /// Move GP phase marks to the recorder.
    fn flush_phases(&mut self, g: u32) {
        let marks: Vec<(String, Tick)> =
            std::mem::take(&mut self.gps[g as usize].shared.borrow_mut().phase_marks);
        for (name, at) in marks {
            self.recorder.phase(g, &name, at);
        }
    }

    fn waiting_report(&self) -> String {
        let mut lines = Vec::new();
        for (i, g) in self.gps.iter().enumerate() {
            let what = match &g.state {
                GpState::Runnable => "runnable".to_string(),
                GpState::Busy(_) => "computing".to_string(),
                GpState::BlockedSend(to, _) => format!("waits to send to {to} (output queue full)"),
                GpState::Receiving => "waits for a message that nobody sends".to_string(),
                GpState::Done => continue,
            };
            lines.push(format!("  GP {i}: {what}"));
        }
        for (i, r) in self.renderers.iter().enumerate() {
            if !r.queue.is_empty() || !r.outbox.is_empty() {
                lines.push(format!(
                    "  Renderer {i}: {} commands queued, {} readbacks waiting for the ring",
                    r.queue.len(),
                    r.outbox.len()
                ));
            }
        }
        if lines.is_empty() {
            "  (no unit is waiting)".to_string()
        } else {
            lines.join("\n")
        }
    }

    fn finish(self) -> RunResult {
        let end = self.now;
        let gps = self
            .gps
            .iter()
            .enumerate()
            .map(|(i, g)| GpStats {
                gp: i as u32,
                busy: g.clock.cycles_floor(g.busy),
                idle: g.clock.cycles_floor(end - g.busy),
                finished: g.finished.unwrap_or(end),
                messages_sent: g.messages_sent,
                messages_received: g.messages_received,
            })
            .collect();
        let renderers = self
            .renderers
            .iter()
            .enumerate()
            .map(|(i, r)| RendererNodeStats {
                renderer: i as u32,
                busy: r.clock.cycles_floor(r.busy),
                idle: r.clock.cycles_floor(end - r.busy),
                commands: r.commands,
                board: r.board.stats().clone(),
            })
            .collect();
        let phases: Vec<PhaseSpan> = self.recorder.phase_spans(end);
        let stats = RunStats {
            program: self.program.clone(),
            config: self.cfg.name.clone(),
            config_hash: pxpl5_config::config_hash(&self.cfg),
            fidelity: self.options.fidelity,
            ring_mode: "cycle",
            end,
            gps,
            renderers,
            ring: self.ring.stats(),
            phases,
            frame_writes: self.frame.writes,
        };
        let mut recorder = self.recorder;
        recorder.close(end);
        RunResult {
            stats,
            frame: self.frame,
            recorder,
        }
    }
}

impl Unit {
    /// The opaque node number a Renderer's readback carries (`Command::Readback::dest`).
    pub fn encode(self) -> u32 {
        match self {
            Unit::Gp(i) => i,
            Unit::Renderer(i) => 0x4000_0000 | i,
            Unit::FrameBuffer => 0x8000_0000,
            Unit::Host => 0x8000_0001,
        }
    }

    /// The inverse of [`Unit::encode`].
    pub fn decode(code: u32) -> Unit {
        match code {
            0x8000_0000 => Unit::FrameBuffer,
            0x8000_0001 => Unit::Host,
            c if c & 0x4000_0000 != 0 => Unit::Renderer(c & 0x3FFF_FFFF),
            c => Unit::Gp(c),
        }
    }
}
