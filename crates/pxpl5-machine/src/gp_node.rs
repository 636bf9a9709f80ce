//! A GP node: one program future and what the machine knows of it (what it waits for, how long it
//! has been busy, its message counts).
//!
//! A GP is polled only when [`GpState::Runnable`]; each poll ends with the program finished, failed,
//! or waiting on a [`Request`] the machine turns into a state: `Busy` until a wake-up event (a
//! computation, or the software cost of a send or receive), `BlockedSend` while the ring's output
//! queue is full, `Receiving` until a message comes. The machine owns time, the ring and the
//! events; this module only keeps the GP's side consistent.
//!
//! **Running ahead.** A program that asks only to compute, piece after piece, changes nothing
//! another unit can see until it asks for something else. So, unless the run is recorded, a
//! GP that asks to compute is polled again at once, at the end of that computing (its `now`
//! then, `Shared::ahead` set), and again while it asks only to compute and marks no phase: the
//! machine sees one busy time, their sum, and one wake-up instead of one a piece. What the
//! program asks next (a send, a receive, a phase mark with its computing, its end) is kept and
//! taken up at that wake-up, as if it had been asked then. Exact because each piece's time is
//! `cycles x period` (they add), the critical path charges the sum to the same phase, and a
//! program ahead of the machine sees nothing it could not see then: its `now` is that time,
//! and a look at its mailbox ([`crate::Gp::has_message`]) first waits for the machine to get
//! there. In the main job's hemicube, a GP's receivers are each a piece of work. A send asked
//! next, or a receive of a message already in the mailbox, starts its cost at the end of the
//! computing without that wake-up ([`GpNode::take_up_at`] says why that is exact).

use std::cell::RefCell;
use std::rc::Rc;
use std::task::{Context, Poll, Waker};

use pxpl5_config::GpCostTable;
use pxpl5_sim::{ClockDomain, Cycles, Tick};

use crate::critical::Profile;
use crate::delivery::Outgoing;
use crate::gp::{Gp, GpFuture, Message, PhaseMark, Program, ProgramError, Request, Shared};
use crate::run::RunError;
use crate::stats::GpStats;

/// What running a GP led to.
pub(crate) enum GpStep {
    /// The program finished.
    Finished,
    /// Busy until this time (then a wake-up is due), doing this.
    Busy(Tick, Busy),
    /// Computing until `computed`, then busy until `until` doing `then` (a send's or a receive's
    /// cost), with one wake-up, at `until` (see [`GpNode::take_up_at`]).
    ComputeThen {
        computed: Tick,
        until: Tick,
        then: Busy,
    },
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

/// What a poll of the program led to.
enum Outcome {
    /// It finished, or failed.
    Ended(Result<(), ProgramError>),
    /// It waits on this request (`None`: on something that is not a GP request).
    Asked(Option<Request>),
}

/// Most polls of a program ahead of the machine's time in one run-ahead: the loop looks at the
/// host's stop requests between instants, and a program computing in many small pieces would
/// otherwise keep it in one.
const MAX_AHEAD: usize = 1024;

/// What a program did ahead of the machine's time, taken up at the wake-up that reaches it:
/// the phases it marked and what its poll led to.
struct Parked {
    marks: Vec<PhaseMark>,
    outcome: Outcome,
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
    /// Whether the program may run ahead of the machine's time (see the module doc): not in a
    /// recorded run, whose trace shows each piece of computing.
    runs_ahead: bool,
    /// What the program did ahead of the machine, for the wake-up that reaches it.
    parked: Option<Parked>,
    /// The buffer of the marks parked next, kept from one parking to the next (a list split
    /// off per parking was 52 K allocations of the main job's hemicube).
    spare_marks: Vec<PhaseMark>,
}

impl GpNode {
    /// GP `gp.index()` running `program`.
    pub fn new(gp: Gp, program: &dyn Program, clock: ClockDomain, runs_ahead: bool) -> GpNode {
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
            runs_ahead,
            parked: None,
            spare_marks: Vec::new(),
        }
    }

    /// Poll the program at `at` and take what it asked for.
    fn poll(&mut self, at: Tick) -> Outcome {
        self.shared.borrow_mut().now = at;
        let mut fut = self.future.take().expect("a runnable GP has its future");
        match fut.as_mut().poll(&mut Context::from_waker(Waker::noop())) {
            Poll::Ready(result) => Outcome::Ended(result),
            Poll::Pending => {
                self.future = Some(fut);
                Outcome::Asked(self.shared.borrow_mut().request.take())
            }
        }
    }

    /// The program asked to compute `computing` GP cycles from `now`: while it asks only to
    /// compute more and marks no phase, poll it again at the end of what it asked for so far
    /// (see the module doc). Returns all it asked to compute; what its last poll led to, and the
    /// phases marked in it, are parked for the wake-up at the end.
    ///
    /// It stops short of polling past the run's time `limit` (the loop stops at the first
    /// wake-up past it, so a program computing forever ends there as it would piece by piece)
    /// and after [`MAX_AHEAD`] polls (so the loop still looks at the host's stop requests); the
    /// program then waits on its last piece, granted at the wake-up as usual, and nothing is
    /// parked.
    fn run_ahead(&mut self, now: Tick, mut computing: Cycles, limit: Tick) -> Cycles {
        for _ in 0..MAX_AHEAD {
            let at = now + self.clock.to_ticks(computing);
            if at > limit {
                return computing;
            }
            let marked = {
                let mut s = self.shared.borrow_mut();
                s.granted = true;
                s.ahead = true;
                s.phase_marks.len()
            };
            let outcome = self.poll(at);
            let mut s = self.shared.borrow_mut();
            s.ahead = false;
            match outcome {
                Outcome::Asked(Some(Request::Compute(c))) if s.phase_marks.len() == marked => {
                    computing = Cycles(computing.0.saturating_add(c.0));
                }
                outcome => {
                    let mut marks = std::mem::take(&mut self.spare_marks);
                    marks.extend(s.phase_marks.drain(marked..));
                    self.parked = Some(Parked { marks, outcome });
                    return computing;
                }
            }
        }
        // Stopped short of polling again: the program waits on its last piece, granted at the
        // wake-up as usual.
        computing
    }

    /// Run the program at `now` (the GP must be runnable) until it waits again, and take up what
    /// it asked for, priced by `costs`; or take up what it asked for ahead of the machine, parked
    /// for now. `limit` is the run's time limit.
    pub fn run(&mut self, now: Tick, costs: &GpCostTable, limit: Tick) -> Result<GpStep, RunError> {
        let mut outcome = match self.parked.take() {
            Some(Parked { mut marks, outcome }) => {
                self.shared.borrow_mut().phase_marks.append(&mut marks);
                self.spare_marks = marks;
                outcome
            }
            None => self.poll(now),
        };
        // A look at the present costs nothing: the program goes on at once.
        while let Outcome::Asked(Some(Request::Sync)) = outcome {
            self.grant();
            outcome = self.poll(now);
        }
        let request = match outcome {
            Outcome::Ended(Ok(())) => {
                self.state = GpState::Done;
                self.finished = Some(now);
                return Ok(GpStep::Finished);
            }
            Outcome::Ended(Err(e)) => {
                return Err(RunError::Program {
                    gp: self.index,
                    message: e.0,
                });
            }
            Outcome::Asked(request) => request,
        };
        Ok(match request {
            Some(Request::Compute(c)) => {
                let c = if self.runs_ahead {
                    self.run_ahead(now, c, limit)
                } else {
                    c
                };
                let computed = self.busy(now, c, None);
                match self.take_up_at(computed, costs) {
                    Some((until, then)) => GpStep::ComputeThen {
                        computed,
                        until,
                        then,
                    },
                    None => GpStep::Busy(computed, Busy::Compute),
                }
            }
            Some(Request::Send { to, payload, words }) => {
                let c = Cycles(costs.message_send);
                let out = Outgoing::counted(to, payload, words);
                let until = self.busy(now, c, Some(out));
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
            Some(Request::Sync) => unreachable!("a look at the present was granted above"),
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

    /// Take up now what the program asked for ahead of the machine, at `at`, the end of its
    /// computing, when what the GP does then depends on nothing the machine could change
    /// before: a send's cost (the send itself is offered at its end), or a receive's cost when
    /// a message waits in the mailbox already (it is the one the receive takes at `at`: others
    /// only join the mailbox behind it). Not when the program marked a phase with it (the
    /// marks go to the machine at `at`, in their order among every GP's). Returns when that
    /// busy time ends and what it is; the GP is then busy until then. This spares the loop the
    /// instant at `at`, where nothing but this GP would act: a fifth of the main job's GP
    /// wake-ups in the hemicube.
    fn take_up_at(&mut self, at: Tick, costs: &GpCostTable) -> Option<(Tick, Busy)> {
        let parked = self.parked.as_ref()?;
        if !parked.marks.is_empty() {
            return None;
        }
        match &parked.outcome {
            Outcome::Asked(Some(Request::Send { .. })) => {}
            Outcome::Asked(Some(Request::Recv)) if !self.shared.borrow().mailbox.is_empty() => {}
            _ => return None,
        }
        let Parked { marks, outcome } = self.parked.take()?;
        self.spare_marks = marks;
        match outcome {
            Outcome::Asked(Some(Request::Send { to, payload, words })) => {
                let out = Outgoing::counted(to, payload, words);
                let until = self.busy(at, Cycles(costs.message_send), Some(out));
                Some((until, Busy::Send))
            }
            Outcome::Asked(Some(Request::Recv)) => {
                let taken = self.receive();
                debug_assert!(taken, "GP {}: the mailbox held a message", self.index);
                let until = self.busy(at, Cycles(costs.message_receive), None);
                Some((until, Busy::Receive))
            }
            _ => unreachable!("matched above"),
        }
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
