//! The machine: GPs, Renderers, the frame buffer and the host on the ring, built from a config,
//! running one program to completion in simulated time. The units are state machines of their own
//! modules (`gp_node`, `renderer_node`, `frame_buffer`; in-order delivery in `delivery`); this
//! module owns time, the ring and the event queue, and moves messages between them.
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
//! A Renderer's completion that only the board would notice (not its message's last command,
//! no readback) needs no instant: the board starts its next command at once, at the
//! completion's time (`Machine::back_to_back` says when, and why that is exact). Nor does a
//! GP's piece of computing followed by another: its program runs ahead of the loop through
//! them (`gp_node`). A recorded run keeps both instant by instant, as its trace shows them.
//!
//! If every GP waits and nothing is due, the run stops with a deadlock report naming who waits for
//! what; a limit on simulated time ends runaway runs with an error. Once every `CHECK_EVERY`
//! instants the loop tells the run's `Monitor`, if it has one, the simulated time reached, and
//! stops with `RunError::Stopped` if the host asked it to stop now (`crate::monitor`).

use std::cell::RefCell;
use std::rc::Rc;

use pxpl5_config::MachineConfig;
use pxpl5_renderer::Workers;
use pxpl5_ring::{MessageId, Ring, RingError};
use pxpl5_sim::{ClockDomain, ComponentId, EventQueue, Priority, Tick};

use crate::critical::{Cat, Categories, Fixed, PathPart, Profile, Resource, SpareProfiles};
use crate::delivery::{Arrival, Delivery, Route, Sent};
use crate::frame_buffer::FrameBufferImage;
use crate::gp::{Gp, Payload, PhaseMark, Program, Shared, Unit};
use crate::gp_node::{Busy, GpNode, GpState, GpStep};
use crate::monitor::{CHECK_EVERY, Stop};
use crate::ready::Ready;
use crate::record::Recorder;
use crate::renderer_node::{RendererNode, Started};
use crate::run::{HostWork, RunError, RunOptions, RunResult};
use crate::stats::{PhaseSpan, RunStats};
use crate::topology::{Positions, node_order};

/// Events of the machine's queue.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Event {
    GpWake(u32),
    RendererDone(u32),
}

impl Event {
    /// The event's class within an instant (`pxpl5_sim` pops lower classes first and gives them
    /// no meaning; this order is the machine's):
    /// - 0, a Renderer completed a command: it frees the Renderer (and its message's input-queue
    ///   space) before GPs act, so a GP acting at the same instant sees it idle instead of
    ///   waiting a cycle for nothing;
    /// - 1, a GP's busy time ended: after every completion of the instant, so programs' decisions
    ///   do not depend on the order in which other units happened to be processed.
    fn priority(self) -> Priority {
        match self {
            Event::RendererDone(_) => Priority(0),
            Event::GpWake(_) => Priority(1),
        }
    }

    fn component(self) -> ComponentId {
        match self {
            Event::RendererDone(i) | Event::GpWake(i) => ComponentId(i),
        }
    }
}

/// A machine built from a config.
pub struct Machine {
    cfg: MachineConfig,
    units: Vec<Unit>,
    positions: Positions,
    ring: Ring,
    gps: Vec<GpNode>,
    /// The GPs that can act in an instant: runnable, or blocked on a send the ring has not
    /// refused since its output queue last freed words. The others wait for what puts them
    /// back: a wake-up, a message, words freed at their node (`Ring::take_freed_nodes`).
    gp_ready: Ready,
    renderers: Vec<RendererNode>,
    /// The Renderers that may start a command or offer a readback message in an instant: those
    /// handed commands, whose command completed, or whose waiting readback's node freed
    /// output-queue words since the loop last looked at them. Nothing else changes what a
    /// Renderer can do, and none of these happens inside an instant's rounds (the ring
    /// delivers and frees words, and completions are due, only between them).
    renderer_ready: Ready,
    /// The boxes the messages' critical paths travel in, kept (host work only).
    spare_profiles: SpareProfiles,
    frame: FrameBufferImage,
    events: EventQueue<Event>,
    delivery: Delivery,
    /// Arrivals due to their receivers, a buffer kept across deliveries.
    due: Vec<Arrival>,
    /// The ring's deliveries of an instant, a buffer kept across instants.
    deliveries: Vec<pxpl5_ring::Delivery>,
    now: Tick,
    options: RunOptions,
    recorder: Recorder,
    program: String,
    /// The critical path's categories (see `critical`): the fixed ones, each GP's current phase,
    /// and each Renderer command kind's.
    categories: Categories,
    fixed: Fixed,
    gp_phase: Vec<Cat>,
    /// Each phase name's category, in order of first mark.
    phase_cats: Vec<(&'static str, Cat)>,
    /// Phase marks taken from a GP, a buffer kept across calls.
    marks: Vec<PhaseMark>,
    /// Each Renderer command kind's category, by `Command::kind_index`, made on first use.
    kinds: Vec<Option<Cat>>,
    host: HostWork,
    /// The host threads of the Renderers' pixel work, if any (kept as long as the boards).
    _workers: Option<Workers>,
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
        let positions = Positions::new(&units);
        let ring = Ring::with_level(&cfg.ring, units.len() as u32, options.ring_level)
            .map_err(|e| RunError::Config(e.to_string()))?;
        let gp_clock = clock(cfg.gp.clock_hz, "gp.clock_hz")?;
        let r_clock = clock(cfg.renderer.clock_hz, "renderer.clock_hz")?;
        let fb = (cfg.frame_buffer.width, cfg.frame_buffer.height);
        // GPs run ahead of the loop through pieces of computing (`gp_node`) unless the run is
        // recorded: its trace and VCD show each piece.
        let runs_ahead = !recorder.records();
        let gps: Vec<GpNode> = (0..cfg.gp.count)
            .map(|i| {
                let gp = Gp {
                    index: i,
                    gps: cfg.gp.count,
                    renderers: cfg.renderer.count,
                    costs: cfg.gp.costs.clone(),
                    renderer_cfg: cfg.renderer.clone(),
                    pixels: options.fidelity.has_pixels(),
                    ring_word_bits: cfg.ring.word_bits,
                    max_message_words: cfg.ring.max_message_words,
                    frame_buffer: fb,
                    shared: Rc::new(RefCell::new(Shared::default())),
                };
                GpNode::new(gp, program, gp_clock, runs_ahead)
            })
            .collect();
        // Pixel work on host threads only when asked for, and never more threads than boards.
        let workers = (options.threads > 1 && cfg.renderer.count > 1)
            .then(|| Workers::new(options.threads.min(cfg.renderer.count as usize)));
        let renderers: Vec<RendererNode> = (0..cfg.renderer.count)
            .map(|r| {
                RendererNode::new(
                    r,
                    &cfg.renderer,
                    cfg.ring.word_bits,
                    cfg.ring.max_message_words,
                    options.fidelity,
                    r_clock,
                    workers.as_ref(),
                )
            })
            .collect();
        let mut categories = Categories::new();
        let fixed = Fixed::new(&mut categories);
        let computing = categories.get("GP computing", Resource::Gp);
        let delivery = Delivery::new(positions.clone(), units.len());
        Ok(Machine {
            gp_phase: vec![computing; cfg.gp.count as usize],
            phase_cats: Vec::new(),
            marks: Vec::new(),
            categories,
            fixed,
            kinds: vec![None; pxpl5_renderer::Command::KINDS.len()],
            _workers: workers,
            host: HostWork::default(),
            spare_profiles: SpareProfiles::default(),
            cfg: cfg.clone(),
            units,
            positions,
            ring,
            gp_ready: Ready::full(gps.len()),
            renderer_ready: Ready::full(renderers.len()),
            gps,
            renderers,
            frame: FrameBufferImage::new(fb.0, fb.1),
            events: EventQueue::new(),
            delivery,
            due: Vec::new(),
            deliveries: Vec::new(),
            now: Tick::ZERO,
            options,
            recorder,
            program: program.name().to_string(),
        })
    }

    /// Run the program to completion. Never inlined: `pxpl5 bench machine --instructions`
    /// counts the instructions inside it by name, across link-time optimisation.
    #[inline(never)]
    pub fn run(mut self) -> Result<RunResult, RunError> {
        let _span =
            tracing::debug_span!("machine", program = %self.program, config = %self.cfg.name)
                .entered();
        let renderer_cycle = self
            .renderers
            .first()
            .map(|r| r.clock().period())
            .unwrap_or(Tick(1));
        self.recorder.declare(
            &self.units,
            self.cfg.ring.channels,
            renderer_cycle,
            u64::from(self.cfg.ring.queue_words),
        );
        // A traced run keeps its critical paths' segments, for the trace's critical-path track.
        if self.recorder.traces_events() {
            self.gps
                .iter_mut()
                .for_each(|g| g.profile = Profile::traced());
            self.renderers
                .iter_mut()
                .for_each(|r| r.profile = Profile::traced());
        }
        // Instants since the monitor was last looked at (see `crate::monitor`).
        let mut unwatched = 0u64;
        // Whether the instant delivered a message or ran an event (the first instant starts
        // every unit).
        let mut acted = true;
        loop {
            self.host.instants += 1;
            self.step_units(acted)?;
            if self.gps.iter().all(|g| g.state == GpState::Done) && self.quiescent() {
                break;
            }
            if let Some(m) = &self.options.monitor {
                unwatched += 1;
                if unwatched == CHECK_EVERY {
                    unwatched = 0;
                    m.set_reached(self.now);
                    if m.requested() == Stop::Now {
                        return Err(RunError::Stopped {
                            at: self.now,
                            running: self.waiting_report().replace('\n', "; "),
                        });
                    }
                }
            }
            // A match, not `min` over an array's iterator: that iterator, built on the stack
            // in pieces and read back whole, stalled the instant's loop (the loop's hottest
            // instruction by `perf record -e cpu-clock`, 2 % of the main job's CPU time).
            let next = match (self.events.peek_tick(), self.ring.next_event_tick()) {
                (Some(a), Some(b)) => Some(a.min(b)),
                (a, b) => a.or(b),
            };
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
            let mut deliveries = std::mem::take(&mut self.deliveries);
            self.ring.take_deliveries_into(&mut deliveries);
            acted = !deliveries.is_empty();
            for d in deliveries.drain(..) {
                progress = true;
                self.deliver(d)?;
            }
            self.deliveries = deliveries;
            while self.events.peek_tick() == Some(next) {
                progress = true;
                acted = true;
                let e = self.events.pop().expect("peeked");
                match e.payload {
                    Event::RendererDone(r) => self.renderer_done(r),
                    Event::GpWake(g) => {
                        self.gps[g as usize].wake(self.now);
                        self.gp_mark(g as usize);
                    }
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

    /// Steps 3 to 5 of the loop at the current instant, repeated until nothing changes (a GP
    /// whose blocked send the ring took runs on at the same instant). Only the units in the
    /// ready sets are looked at. `acted`: whether the instant delivered a message or ran an
    /// event.
    fn step_units(&mut self, acted: bool) -> Result<(), RunError> {
        // A refused send may go now if its node's output queue freed words (only the ring's
        // advance frees them, before this step).
        let (units, gps, renderers, ready, renderer_ready) = (
            &self.units,
            &self.gps,
            &self.renderers,
            &mut self.gp_ready,
            &mut self.renderer_ready,
        );
        let mut woke = false;
        self.ring
            .take_freed_nodes(|node| match units.get(node.0 as usize) {
                Some(&Unit::Gp(g)) if matches!(gps[g as usize].state, GpState::BlockedSend(_)) => {
                    ready.set(g as usize, true);
                    woke = true;
                }
                Some(&Unit::Renderer(r)) if renderers[r as usize].has_outgoing() => {
                    renderer_ready.set(r as usize, true);
                    woke = true;
                }
                _ => {}
            });
        // An instant of the ring alone (its output queues freed words no sender waits for):
        // every unit is as the last round left it, with nothing to do, since a Renderer's next
        // command waits only for a delivery or its completion's event, and a GP for an event, a
        // delivery or its queue's space. A fifth of the main job's instants are such, each a
        // round over every Renderer and the GPs.
        if !acted && !woke {
            return Ok(());
        }
        loop {
            let mut progress = false;
            let mut next = self.renderer_ready.next_from(0);
            while let Some(r) = next {
                // Looked at: it waits again for one of the changes that put it back.
                self.renderer_ready.set(r, false);
                progress |= self.renderer_try_start(r as u32)?;
                next = self.renderer_ready.next_from(r + 1);
            }
            let mut next = self.gp_ready.next_from(0);
            while let Some(g) = next {
                self.host.gp_checks += 1;
                progress |= self.gp_run(g as u32)?;
                next = self.gp_ready.next_from(g + 1);
            }
            let mut next = self.gp_ready.next_from(0);
            while let Some(g) = next {
                next = self.gp_ready.next_from(g + 1);
                self.host.gp_checks += 1;
                let GpState::BlockedSend(out) = &mut self.gps[g].state else {
                    continue;
                };
                let to = out.to;
                let words = *out
                    .words
                    .get_or_insert_with(|| ring_words(&self.cfg, &out.payload));
                debug_assert_eq!(words, ring_words(&self.cfg, &out.payload), "GP {g}'s count");
                let mut refused = out.refused;
                let offered = self.offer(Unit::Gp(g as u32), to, words, &mut refused)?;
                if let GpState::BlockedSend(out) = &mut self.gps[g].state {
                    out.refused = refused;
                }
                if offered.is_none() {
                    // Refused: the same answer until the node's output queue frees words.
                    self.gp_ready.set(g, false);
                }
                if let Some(taken) = offered {
                    let GpState::BlockedSend(out) =
                        std::mem::replace(&mut self.gps[g].state, GpState::Runnable)
                    else {
                        unreachable!("GP {g} was blocked on a send a moment ago")
                    };
                    let node = &mut self.gps[g];
                    node.profile.add_by(
                        self.fixed.blocked,
                        self.now - node.blocked_since,
                        Unit::Gp(g as u32),
                    );
                    let sent = Sent {
                        at: self.now,
                        profile: self.spare_profiles.copy(&node.profile),
                    };
                    self.recorder
                        .message_sent(taken.0, Unit::Gp(g as u32), self.now);
                    self.delivery.sent(taken.0, taken.1, out.payload, sent);
                    self.gps[g].sent();
                    self.gp_mark(g);
                    progress = true;
                }
            }
            if !progress {
                return Ok(());
            }
        }
    }

    /// GP `g`'s state changed: whether the loop must look at it now follows.
    fn gp_mark(&mut self, g: usize) {
        let ready = matches!(
            self.gps[g].state,
            GpState::Runnable | GpState::BlockedSend(_)
        );
        self.gp_ready.set(g, ready);
    }

    fn quiescent(&self) -> bool {
        self.ring.is_idle()
            && self.delivery.is_empty()
            && self.renderers.iter().all(|r| r.is_idle())
    }

    /// Run GP `g` if it is runnable; whether it did anything.
    fn gp_run(&mut self, g: u32) -> Result<bool, RunError> {
        let node = &mut self.gps[g as usize];
        if node.state != GpState::Runnable {
            return Ok(false);
        }
        let step = node.run(self.now, &self.cfg.gp.costs, self.options.max_time);
        self.gp_mark(g as usize);
        self.flush_phases(g);
        match step? {
            GpStep::Finished => self.recorder.gp_done(g, self.now),
            GpStep::Busy(until, busy) => self.gp_busy(g, until, busy),
            GpStep::ComputeThen {
                computed,
                until,
                then,
            } => {
                self.charge_busy(g, (self.now, computed), Busy::Compute);
                self.charge_busy(g, (computed, until), then);
                self.schedule(until, Event::GpWake(g));
            }
            GpStep::Waiting => {}
        }
        Ok(true)
    }

    /// GP `g` became busy until `until` doing `busy`: record it, extend its critical path, and
    /// schedule its wake-up.
    fn gp_busy(&mut self, g: u32, until: Tick, busy: Busy) {
        self.charge_busy(g, (self.now, until), busy);
        self.schedule(until, Event::GpWake(g));
    }

    /// GP `g` is busy from `from` to `until` doing `busy`: record it and extend its critical
    /// path.
    fn charge_busy(&mut self, g: u32, (from, until): (Tick, Tick), busy: Busy) {
        self.recorder.gp_busy(g, from, until, busy);
        let cat = match busy {
            Busy::Compute => self.gp_phase[g as usize],
            Busy::Send => self.fixed.send,
            Busy::Receive => self.fixed.receive,
        };
        self.gps[g as usize]
            .profile
            .add_by(cat, until - from, Unit::Gp(g));
    }

    fn schedule(&mut self, at: Tick, e: Event) {
        self.events.schedule(at, e.priority(), e.component(), e);
    }

    /// Offer the ring a message of `words` ring words from `from` to `to`: its id and route if
    /// the sender's output queue took it (the caller then hands the payload to delivery), `None`
    /// if the queue is full. O(1), and nothing is copied until the ring takes the message. A
    /// sender the ring refused (`refused` holds the sender's `Ring::output_freed` count then) is
    /// offered again only once its output queue has freed words: before that the answer could
    /// only be the same.
    fn offer(
        &mut self,
        from: Unit,
        to: Unit,
        words: u32,
        refused: &mut Option<u64>,
    ) -> Result<Option<(MessageId, Route)>, RunError> {
        let (Some(src), Some(dst)) = (self.positions.get(from), self.positions.get(to)) else {
            return Err(RunError::NoSuchUnit { from, to });
        };
        let freed = self
            .ring
            .output_freed(src)
            .map_err(|error| RunError::Ring { unit: from, error })?;
        if *refused == Some(freed) {
            return Ok(None);
        }
        self.host.offers += 1;
        let route = Route { from, to };
        let seq = self.delivery.next_seq(route);
        match self.ring.send(self.now, src, dst, words, seq) {
            Ok(id) => Ok(Some((id, route))),
            Err(RingError::OutputFull { .. }) => {
                *refused = Some(freed);
                self.host.refused_offers += 1;
                Ok(None)
            }
            Err(error) => Err(RunError::Ring { unit: from, error }),
        }
    }

    /// A message arrived: hand it (and any held successors) to the receiver in send order.
    fn deliver(&mut self, d: pxpl5_ring::Delivery) -> Result<(), RunError> {
        // The buffer of due arrivals is the machine's, kept across deliveries (a `Vec` a
        // delivery was an allocation a message).
        let mut due = std::mem::take(&mut self.due);
        let route = self.delivery.arrived(d.id, d.delivered, &mut due);
        self.recorder.message_delivered(&d, route.from, route.to);
        for a in due.drain(..) {
            self.hand_over(a);
        }
        self.due = due;
        Ok(())
    }

    /// Give a message to its receiver, and free its input-queue space unless a Renderer still
    /// has to execute it.
    fn hand_over(&mut self, a: Arrival) {
        let Arrival {
            id,
            to,
            message,
            sent: Sent {
                at,
                profile: mut arrived,
            },
        } = a;
        // The critical path to the handing over: the sender's, then the ring's.
        arrived.add(self.fixed.ring, self.now - at);
        match to {
            Unit::Gp(g) => {
                self.consume(id);
                self.recorder.handed_to_gp(g, id);
                let node = &mut self.gps[g as usize];
                if let Some(until) = node.deliver(self.now, message, &self.cfg.gp.costs) {
                    // The GP waited for this message: its path runs through it.
                    std::mem::swap(&mut node.profile, &mut arrived);
                    self.gp_busy(g, until, Busy::Receive);
                }
                self.spare_profiles.keep(arrived);
                self.gp_mark(g as usize);
            }
            Unit::Renderer(r) => match message.payload {
                Payload::Commands(cs) => {
                    let arrival = (self.now, arrived);
                    if self.renderers[r as usize].accept(message.from, id, cs, arrival) {
                        self.renderer_ready.set(r as usize, true);
                    } else {
                        self.consume(id);
                    }
                }
                _ => {
                    self.spare_profiles.keep(arrived);
                    self.consume(id);
                }
            },
            Unit::FrameBuffer => {
                self.spare_profiles.keep(arrived);
                self.consume(id);
                if let Payload::Pixels {
                    tag, rect, values, ..
                } = message.payload
                {
                    self.frame.write_pixels(tag, rect, &values);
                }
            }
            Unit::Host => {
                self.spare_profiles.keep(arrived);
                self.consume(id);
            }
        }
    }

    /// Free a delivered message's space in its receiver's input queue.
    fn consume(&mut self, id: MessageId) {
        self.ring
            .consume(id)
            .unwrap_or_else(|e| panic!("consuming delivered message {id} at {}: {e}", self.now));
    }

    /// Start Renderer `r`'s next command if it is idle; whether it started one.
    fn renderer_try_start(&mut self, r: u32) -> Result<bool, RunError> {
        if self.renderers[r as usize].is_running() {
            return Ok(false);
        }
        // Readbacks waiting for the ring hold the Renderer (its output port is busy).
        while let Some(out) = self.renderers[r as usize].next_outgoing() {
            let to = out.to;
            let words = *out
                .words
                .get_or_insert_with(|| ring_words(&self.cfg, &out.payload));
            let mut refused = out.refused;
            let offered = self.offer(Unit::Renderer(r), to, words, &mut refused)?;
            let Some((id, route)) = offered else {
                if let Some(out) = self.renderers[r as usize].next_outgoing() {
                    out.refused = refused;
                }
                return Ok(false);
            };
            let node = &mut self.renderers[r as usize];
            let out = node
                .outgoing_sent()
                .expect("the outgoing message offered a moment ago");
            let sent = Sent {
                at: self.now,
                profile: self.spare_profiles.boxed(node.profile.plus_by(
                    self.fixed.readback_waits,
                    self.now - node.last_end,
                    Unit::Renderer(r),
                )),
            };
            self.recorder.message_sent(id, Unit::Renderer(r), self.now);
            self.delivery.sent(id, route, out.payload, sent);
        }
        let Some(mut started) = self.renderers[r as usize].start_next(self.now)? else {
            return Ok(false);
        };
        // The board's commands back to back, while nothing but the board would act at their
        // completions (see `Machine::back_to_back`).
        loop {
            self.recorder.renderer_command(r, &started);
            let (end, last, readback) = (started.end, started.last_in_message, started.readback);
            self.renderer_path(r, started);
            if !self.back_to_back(r, end, last || readback) {
                self.schedule(end, Event::RendererDone(r));
                return Ok(true);
            }
            started = match self.renderers[r as usize].start_next(end) {
                Ok(Some(next)) => next,
                // A command the board refuses: its error is the loop's at the instant the board
                // would have started it, after everything before then. Refusing changes nothing
                // on the board, so the completion's instant starts it again and fails the same
                // way.
                Ok(None) | Err(_) => {
                    self.schedule(end, Event::RendererDone(r));
                    return Ok(true);
                }
            };
        }
    }

    /// Whether Renderer `r`, whose command just started ends at `end`, may start its next
    /// command now, at `end`, instead of at that completion's instant of the loop. It may when
    /// the completion would change nothing but the board:
    /// - `seen` is false: the command is not its message's last (whose completion frees
    ///   input-queue space the ring sees) and left no readback messages (which the board offers
    ///   the ring at its completion);
    /// - the completion is within the run's time limit (past it the loop stops first);
    /// - the next command's kind already has its critical-path category (categories are
    ///   numbered in the loop's order of first use);
    /// - nothing is recorded (traces and VCDs sample the ring at every instant of the loop).
    ///
    /// A board's commands then run without an instant of the loop each: in the main job's
    /// hemisphere, four in five of its instants were such completions.
    fn back_to_back(&self, r: u32, end: Tick, seen: bool) -> bool {
        !seen
            && end <= self.options.max_time
            && !self.recorder.records()
            && self.renderers[r as usize]
                .next_kind_index()
                .is_some_and(|k| self.kinds[k].is_some())
    }

    /// Extend Renderer `r`'s critical path by a command that started: from the later of the
    /// board's previous command and the command's message, through any wait (readback words the
    /// ring had no room for, or a stall), to the command's end.
    fn renderer_path(&mut self, r: u32, started: Started) {
        let kind = match self.kinds[started.kind_index] {
            Some(c) => c,
            None => {
                let name = format!("Renderer {}", started.kind());
                let c = self.categories.get(&name, Resource::Renderer);
                self.kinds[started.kind_index] = Some(c);
                c
            }
        };
        let node = &mut self.renderers[r as usize];
        let wait = if node.last_readback {
            self.fixed.readback_waits
        } else {
            self.fixed.stall
        };
        let unit = Unit::Renderer(r);
        let run = started.end - started.start;
        match started.arrival {
            Some((at, mut path)) if at > node.last_end => {
                path.add_by(self.fixed.stall, started.start - at, unit);
                path.add_by(kind, run, unit);
                std::mem::swap(&mut node.profile, &mut path);
                self.spare_profiles.keep(path);
            }
            // The board's own previous command is the cause: its path grows in place (a copy of
            // the 400-byte profile per command was 1.5 % of a radiosity run's instructions).
            arrival => {
                let idle = started.start - node.last_end;
                node.profile.add_by(wait, idle, unit);
                node.profile.add_by(kind, run, unit);
                if let Some((_, path)) = arrival {
                    self.spare_profiles.keep(path);
                }
            }
        }
        node.last_end = started.end;
        node.last_readback = started.readback;
    }

    fn renderer_done(&mut self, r: u32) {
        self.renderer_ready.set(r as usize, true);
        if let Some(id) = self.renderers[r as usize].complete() {
            self.consume(id);
        }
    }

    /// Move GP phase marks to the recorder; the last is the GP's phase from now on.
    fn flush_phases(&mut self, g: u32) {
        let mut marks = std::mem::take(&mut self.marks);
        self.gps[g as usize].take_phase_marks(&mut marks);
        for mark in marks.drain(..) {
            // A program has a few phase names and marks them every shot: their categories are
            // looked up by name here, not formatted and hashed per mark.
            let cat = match self.phase_cats.iter().find(|(name, _)| *name == mark.name) {
                Some(&(_, cat)) => cat,
                None => {
                    let cat = self
                        .categories
                        .get(&format!("GP {}", mark.name), Resource::Gp);
                    self.phase_cats.push((mark.name, cat));
                    cat
                }
            };
            self.gp_phase[g as usize] = cat;
            self.recorder.phase(g, mark.name, mark.at);
        }
        self.marks = marks;
    }

    /// The path of the unit that finished last (a GP on a tie), and when it finished.
    fn last_path(&self, end: Tick) -> Option<(Tick, &Profile)> {
        let gps = self.gps.iter().map(|g| (g.stats(end).finished, &g.profile));
        let renderers = self.renderers.iter().map(|r| (r.last_end, &r.profile));
        gps.chain(renderers)
            .fold(None, |best: Option<(Tick, &Profile)>, (t, p)| match best {
                Some((bt, _)) if bt >= t => best,
                _ => Some((t, p)),
            })
    }

    /// The run's critical path: the path of the unit that finished last.
    fn critical_path(&self, end: Tick) -> Vec<PathPart> {
        self.last_path(end).map_or_else(Vec::new, |(t, p)| {
            // Every step adds exactly the time it took: the path accounts for all of it.
            debug_assert_eq!(p.total(), t, "critical path total");
            self.categories.parts(p)
        })
    }

    fn waiting_report(&self) -> String {
        let lines: Vec<String> = (self.gps.iter().filter_map(GpNode::waiting))
            .chain(self.renderers.iter().filter_map(RendererNode::waiting))
            .collect();
        if lines.is_empty() {
            "  (no unit is waiting)".to_string()
        } else {
            lines.join("\n")
        }
    }

    fn finish(self) -> RunResult {
        let end = self.now;
        if let Some(m) = &self.options.monitor {
            m.set_reached(end);
        }
        let gps = self.gps.iter().map(|g| g.stats(end)).collect();
        let renderers = self.renderers.iter().map(|r| r.stats(end)).collect();
        let phases: Vec<PhaseSpan> = self.recorder.phase_spans(end);
        let critical_path = self.critical_path(end);
        let segments = self
            .last_path(end)
            .map_or_else(Vec::new, |(_, p)| self.categories.path_segments(p));
        let stats = RunStats {
            critical_path,
            program: self.program.clone(),
            config: self.cfg.name.clone(),
            config_hash: pxpl5_config::config_hash(&self.cfg),
            fidelity: self.options.fidelity,
            ring_level: self.options.ring_level,
            end,
            gps,
            renderers,
            ring: self.ring.stats(),
            phases,
            frame_writes: self.frame.writes,
        };
        let mut recorder = self.recorder;
        recorder.critical_path(&segments);
        recorder.close(end);
        RunResult {
            stats,
            frame: self.frame,
            recorder,
            host: self.host,
        }
    }
}

/// Ring words of a payload (headers are the ring's business), at least 1.
fn ring_words(cfg: &MachineConfig, p: &Payload) -> u32 {
    let coefficient_bits = cfg.renderer.qee.coefficient_format.total_bits();
    let word_bits = cfg.ring.word_bits;
    match p {
        Payload::Commands(cs) => {
            pxpl5_renderer::Command::list_words(cs, coefficient_bits, word_bits)
        }
        // The values packed as `pxpl5_renderer::readback` documents (a count beyond u32 is one
        // no ring takes).
        Payload::Pixels { bits, values, .. } => {
            let words = pxpl5_renderer::readback::words_needed(values.len(), *bits, word_bits);
            u32::try_from(words).unwrap_or(u32::MAX)
        }
        Payload::Data { words, .. } => *words,
    }
    .max(1)
}
