//! A Renderer node: one board on the ring, executing the commands it receives.
//!
//! - Commands run one at a time in arrival order, at the Renderer clock: the board has one
//!   command stream, fed from its ring input queue.
//! - A command message's input-queue space is freed when its *last* command completes, not when
//!   it arrives: the commands sit in the input queue until the board has executed them, which is
//!   what throttles GPs that send faster than the board renders (back-pressure).
//! - A readback streams its rows in messages of at most `max_message_words` words, packed by the
//!   board (`pxpl5_renderer::readback`), so a whole board's field never needs an output queue
//!   that large; while those messages wait for output-queue space the board starts nothing new
//!   (its port is busy).
//!
//! The node is a state machine; the machine moves messages on the ring and schedules the
//! completions.

use std::collections::VecDeque;

use pxpl5_config::RendererConfig;
use pxpl5_renderer::{Board, Command, Fidelity, Workers};
use pxpl5_ring::MessageId;
use pxpl5_sim::{ClockDomain, Tick};

use crate::critical::Profile;
use crate::delivery::Outgoing;
use crate::gp::{Payload, Unit};
use crate::run::RunError;
use crate::stats::RendererNodeStats;

/// A command message in the input queue, with the commands the board has not started. Its
/// commands stay in the message's own list, taken by reference when each starts: moving each
/// into a queue of commands and out again took about 2 % of the main job's hemicube in CPU
/// time by `perf record -e cpu-clock`'s samples (0.5 % now), though host seconds moved less
/// than their jitter.
struct QueuedMessage {
    commands: Vec<Command>,
    /// The next command to start.
    next: usize,
    from: Unit,
    /// The ring message they came in.
    message: MessageId,
    /// Until its first command starts: when the message was handed over, and the critical
    /// path to then (see `critical`).
    arrival: Option<(Tick, Box<Profile>)>,
}

/// The command executing now: only what its completion needs.
struct Running {
    message: MessageId,
    last_in_message: bool,
}

/// A command that started: what the machine records and when it completes.
pub(crate) struct Started {
    /// [`pxpl5_renderer::Command::kind_index`] of the command ([`Started::kind`] its name).
    pub kind_index: usize,
    pub start: Tick,
    pub end: Tick,
    /// Its message's arrival, for a message's first command.
    pub arrival: Option<(Tick, Box<Profile>)>,
    /// Whether it left readback messages for the ring.
    pub readback: bool,
    /// The ring message it came in, and whether it is that message's first and last command
    /// (for the trace's flows).
    pub message: MessageId,
    pub first_in_message: bool,
    pub last_in_message: bool,
}

pub(crate) struct RendererNode {
    index: u32,
    board: Board,
    clock: ClockDomain,
    queue: VecDeque<QueuedMessage>,
    running: Option<Running>,
    /// Readback messages waiting for output-queue space, in order.
    outbox: VecDeque<Outgoing>,
    /// Simulated time spent executing commands.
    busy: Tick,
    commands: u64,
    /// The critical path to the end of the last command (see `critical`), that end, and whether
    /// that command left readback messages.
    pub profile: Profile,
    pub last_end: Tick,
    pub last_readback: bool,
}

impl Started {
    /// The command's kind, as the board's statistics name it.
    pub fn kind(&self) -> &'static str {
        Command::KINDS[self.kind_index]
    }
}

impl RendererNode {
    /// Renderer `index` of a machine whose ring has `word_bits`-bit words and messages of at most
    /// `max_message_words` words.
    pub fn new(
        index: u32,
        cfg: &RendererConfig,
        word_bits: u32,
        max_message_words: u32,
        fidelity: Fidelity,
        clock: ClockDomain,
        workers: Option<&Workers>,
    ) -> RendererNode {
        let board = Board::new(cfg, word_bits, fidelity).stream_readbacks(max_message_words);
        let board = match workers {
            Some(w) => board.on_workers(w),
            None => board,
        };
        RendererNode {
            index,
            board,
            clock,
            queue: VecDeque::new(),
            running: None,
            outbox: VecDeque::new(),
            busy: Tick::ZERO,
            commands: 0,
            profile: Profile::default(),
            last_end: Tick::ZERO,
            last_readback: false,
        }
    }

    pub fn clock(&self) -> ClockDomain {
        self.clock
    }

    /// Queue the commands of message `message` from `from`, handed over at `arrival` (with the
    /// critical path to then). Returns false if there were none: then no completion will free the
    /// message, so the caller frees it now.
    pub fn accept(
        &mut self,
        from: Unit,
        message: MessageId,
        commands: Vec<Command>,
        arrival: (Tick, Box<Profile>),
    ) -> bool {
        if commands.is_empty() {
            return false;
        }
        self.queue.push_back(QueuedMessage {
            commands,
            next: 0,
            from,
            message,
            arrival: Some(arrival),
        });
        true
    }

    pub fn is_running(&self) -> bool {
        self.running.is_some()
    }

    /// Whether the node has nothing left to do or to send.
    pub fn is_idle(&self) -> bool {
        self.queue.is_empty() && self.running.is_none() && self.outbox.is_empty()
    }

    /// Whether readback messages wait for the ring.
    pub fn has_outgoing(&self) -> bool {
        !self.outbox.is_empty()
    }

    /// The oldest readback message waiting for the ring.
    pub fn next_outgoing(&mut self) -> Option<&mut Outgoing> {
        self.outbox.front_mut()
    }

    /// The ring took [`RendererNode::next_outgoing`]: hand it over.
    pub fn outgoing_sent(&mut self) -> Option<Outgoing> {
        self.outbox.pop_front()
    }

    /// [`Command::kind_index`] of the next queued command, if any.
    pub fn next_kind_index(&self) -> Option<usize> {
        let q = self.queue.front()?;
        Some(q.commands[q.next].kind_index())
    }

    /// Start the next queued command at `now` (at the next Renderer clock edge, or later if the
    /// board is still busy); `None` if nothing is queued.
    pub fn start_next(&mut self, now: Tick) -> Result<Option<Started>, RunError> {
        let Some(q) = self.queue.front_mut() else {
            return Ok(None);
        };
        let command = &q.commands[q.next];
        let start_cycle = self.clock.cycles_ceil(now);
        self.board.idle_until(start_cycle);
        let executed = self
            .board
            .execute(command)
            .map_err(|error| RunError::Command {
                renderer: self.index,
                kind: command.kind(),
                from: q.from,
                error,
            })?;
        let kind_index = command.kind_index();
        q.next += 1;
        let (message, last_in_message) = (q.message, q.next == q.commands.len());
        let arrival = q.arrival.take();
        if last_in_message {
            self.queue.pop_front();
        }
        let start = self.clock.to_ticks(executed.start);
        let end = self.clock.to_ticks(executed.end);
        self.busy += end - start;
        self.commands += 1;
        let readback = executed.readback.is_some();
        if let Some(rb) = executed.readback {
            // The board split the rows into messages; they travel as they are.
            let to = Unit::decode(rb.dest);
            self.outbox.extend(rb.messages.into_iter().map(|m| {
                let payload = Payload::Pixels {
                    tag: rb.tag,
                    rect: m.rect,
                    bits: rb.bits,
                    values: m.values,
                };
                Outgoing::new(to, payload)
            }));
        }
        self.running = Some(Running {
            message,
            last_in_message,
        });
        Ok(Some(Started {
            kind_index,
            start,
            end,
            first_in_message: arrival.is_some(),
            arrival,
            readback,
            message,
            last_in_message,
        }))
    }

    /// The running command completed: the message whose input-queue space it frees, if any.
    ///
    /// # Panics
    /// If no command is running: the machine scheduled a completion it did not start.
    pub fn complete(&mut self) -> Option<MessageId> {
        let done = self
            .running
            .take()
            .expect("a completion has a running command");
        done.last_in_message.then_some(done.message)
    }

    /// The node's figures for a run that ended at `end`.
    pub fn stats(&self, end: Tick) -> RendererNodeStats {
        RendererNodeStats {
            renderer: self.index,
            busy: self.clock.cycles_floor(self.busy),
            idle: self.clock.cycles_floor(end - self.busy),
            commands: self.commands,
            board: self.board.stats(),
        }
    }

    /// A line for a deadlock report, if the node has work left.
    pub fn waiting(&self) -> Option<String> {
        (!self.queue.is_empty() || !self.outbox.is_empty()).then(|| {
            format!(
                "  Renderer {}: {} commands queued, {} readbacks waiting for the ring",
                self.index,
                self.queue
                    .iter()
                    .map(|q| q.commands.len() - q.next)
                    .sum::<usize>(),
                self.outbox.len()
            )
        })
    }
}
