//! A GP node: one program future and what the machine knows of it (what it waits for, how long it
//! has been busy, its message counts).
//!
//! A GP is polled only when [`GpState::Runnable`]; each poll ends with the program finished, failed,
//! or waiting on a [`Request`] the machine turns into a state: `Busy` until a wake-up event (a
//! computation, or the software cost of a send or receive), `BlockedSend` while the ring's output
//! queue is full, `Receiving` until a message comes. The machine owns time, the ring and the
//! events; this module only keeps the GP's side consistent.

use std::cell::RefCell;
use std::rc::Rc;
use std::task::{Context, Poll, Waker};

use pxpl5_config::GpCostTable;
use pxpl5_sim::{ClockDomain, Cycles, Tick};

use crate::critical::Profile;
use crate::delivery::Outgoing;
use crate::gp::{Gp, GpFuture, Message, PhaseMark, Program, Request, Shared};
use crate::run::RunError;
use crate::stats::GpStats;

/// What running a GP led to.
pub(crate) enum GpStep {
    /// The program finished.
    Finished,
    /// Busy until this time (then a wake-up is due), doing this.
    Busy(Tick, Busy),
    /// Waiting for a message.
    Waiting,
}

/// What a busy GP does: the category its time goes to on a critical path.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Busy {
    Compute,
    Send,
    Receive,
}

/// What a GP is doing.
#[derive(Clone, Debug, PartialEq)]
pub(crate) enum GpState {
    Runnable,
    /// Busy until a wake-up event; then the send to perform, if the busy time was a send's cost.
    Busy(Option<Outgoing>),
    /// The ring's output queue was full; retried at every instant.
    BlockedSend(Outgoing),
    Receiving,
    Done,
}

pub(crate) struct GpNode {
    index: u32,
    future: Option<GpFuture>,
    shared: Rc<RefCell<Shared>>,
    pub state: GpState,
    clock: ClockDomain,
    /// Simulated time spent busy.
    busy: Tick,
    finished: Option<Tick>,
    messages_sent: u64,
    messages_received: u64,
    /// The critical path to this GP's present (see `critical`): when the GP is runnable, up to
    /// now; when busy, up to the end of its busy time.
    pub profile: Profile,
    /// Since when a blocked send has waited for output-queue space.
    pub blocked_since: Tick,
}

impl GpNode {
    /// GP `gp.index()` running `program`.
    pub fn new(gp: Gp, program: &dyn Program, clock: ClockDomain) -> GpNode {
        GpNode {
            index: gp.index,
            shared: gp.shared.clone(),
            future: Some(program.gp_main(gp)),
            state: GpState::Runnable,
            clock,
            busy: Tick::ZERO,
            finished: None,
            messages_sent: 0,
            messages_received: 0,
            profile: Profile::default(),
            blocked_since: Tick::ZERO,
        }
    }

    /// Run the program at `now` (the GP must be runnable) until it waits again, and take up what
    /// it asked for, priced by `costs`.
    pub fn run(&mut self, now: Tick, costs: &GpCostTable) -> Result<GpStep, RunError> {
        self.shared.borrow_mut().now = now;
        let mut fut = self.future.take().expect("a runnable GP has its future");
        match fut.as_mut().poll(&mut Context::from_waker(Waker::noop())) {
            Poll::Ready(Ok(())) => {
                self.state = GpState::Done;
                self.finished = Some(now);
                return Ok(GpStep::Finished);
            }
            Poll::Ready(Err(e)) => {
                return Err(RunError::Program {
                    gp: self.index,
                    message: e.0,
                });
            }
            Poll::Pending => self.future = Some(fut),
        }
        let request = self.shared.borrow_mut().request.take();
        Ok(match request {
            Some(Request::Compute(c)) => GpStep::Busy(self.busy(now, c, None), Busy::Compute),
            Some(Request::Send(to, payload)) => {
                let c = Cycles(costs.message_send);
                let until = self.busy(now, c, Some(Outgoing::new(to, payload)));
                GpStep::Busy(until, Busy::Send)
            }
            Some(Request::Recv) => {
                if self.receive() {
                    let until = self.busy(now, Cycles(costs.message_receive), None);
                    GpStep::Busy(until, Busy::Receive)
                } else {
                    self.state = GpState::Receiving;
                    GpStep::Waiting
                }
            }
            None => {
                // A future returned Pending without a request: it awaited something that is
                // not the machine's (a program bug the runtime cannot serve).
                return Err(RunError::Program {
                    gp: self.index,
                    message: "the program awaited a future that is not a GP request".into(),
                });
            }
        })
    }

    /// The phase marks the program made since the last call, into `marks` (empty), which
    /// takes the GP's buffer in exchange: neither side allocates once both have grown.
    pub fn take_phase_marks(&mut self, marks: &mut Vec<PhaseMark>) {
        std::mem::swap(&mut self.shared.borrow_mut().phase_marks, marks);
    }

    /// Hand the oldest message of the mailbox to the waiting receive; false if the mailbox is
    /// empty.
    fn receive(&mut self) -> bool {
        let mut shared = self.shared.borrow_mut();
        let Some(m) = shared.mailbox.pop_front() else {
            return false;
        };
        shared.received = Some(m);
        self.messages_received += 1;
        true
    }

    /// A message arrived at `now`. If a receive was waiting for it, the GP takes it and is busy
    /// for the receive's cost: returns until when.
    pub fn deliver(&mut self, now: Tick, m: Message, costs: &GpCostTable) -> Option<Tick> {
        self.shared.borrow_mut().mailbox.push_back(m);
        if self.state != GpState::Receiving || !self.receive() {
            return None;
        }
        Some(self.busy(now, Cycles(costs.message_receive), None))
    }

    /// Be busy from `now` for `c` GP cycles, then do `then`; returns when the busy time ends.
    fn busy(&mut self, now: Tick, c: Cycles, then: Option<Outgoing>) -> Tick {
        let until = now + self.clock.to_ticks(c);
        self.busy += until - now;
        self.state = GpState::Busy(then);
        until
    }

    /// The busy time ended: grant the request, or go on to the send it was the cost of.
    ///
    /// # Panics
    /// If the GP was not busy: the machine woke a GP it did not put to work.
    pub fn wake(&mut self, now: Tick) {
        let GpState::Busy(then) = std::mem::replace(&mut self.state, GpState::Runnable) else {
            panic!("GP {} woken at {now} while not busy", self.index);
        };
        match then {
            None => self.grant(),
            Some(out) => {
                self.state = GpState::BlockedSend(out);
                self.blocked_since = now;
            }
        }
    }

    /// The blocked send went onto the ring: the GP resumes.
    pub fn sent(&mut self) {
        self.state = GpState::Runnable;
        self.messages_sent += 1;
        self.grant();
    }

    /// Complete the program's pending request at its next poll.
    fn grant(&mut self) {
        self.shared.borrow_mut().granted = true;
    }

    /// A line for a report of the units still running (a deadlock, a limit), if the GP has not
    /// finished.
    pub fn waiting(&self) -> Option<String> {
        let what = match &self.state {
            GpState::Runnable => "runnable".to_string(),
            GpState::Busy(_) => "computing".to_string(),
            GpState::BlockedSend(out) => {
                format!("waits to send to {} (output queue full)", out.to)
            }
            GpState::Receiving => "waits for a message".to_string(),
            GpState::Done => return None,
        };
        Some(format!("  GP {}: {what}", self.index))
    }

    /// The GP's figures for a run that ended at `end`.
    pub fn stats(&self, end: Tick) -> GpStats {
        GpStats {
            gp: self.index,
            busy: self.clock.cycles_floor(self.busy),
            idle: self.clock.cycles_floor(end - self.busy),
            finished: self.finished.unwrap_or(end),
            messages_sent: self.messages_sent,
            messages_received: self.messages_received,
        }
    }
}
