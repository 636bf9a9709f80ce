//! In-order delivery per sender and receiver: the machine's promise that messages between two units
//! arrive in the order they were sent.
//!
//! The ring keeps no such order: a unit may send on several channels at once, and a short message
//! on a free channel overtakes a long one sent earlier. So every message carries a sequence number
//! per [`Route`] (sender, receiver), and an arrival that overtook an earlier message of its route
//! is held here until that message arrives. Order between *different* routes is not kept, as on
//! the real machine; programs that need it order their senders themselves (fences).

use pxpl5_ring::MessageId;

use pxpl5_sim::{SeqMap, Tick};

use crate::critical::Profile;
use crate::gp::{Message, Payload, Unit};
use crate::topology::Positions;

/// A sender and a receiver: the pair between which send order is kept.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) struct Route {
    pub from: Unit,
    pub to: Unit,
}

/// A message a unit wants to put on the ring (a GP's send, a Renderer's readback), kept until the
/// sender's output queue has room for it.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Outgoing {
    pub to: Unit,
    pub payload: Payload,
    /// Its size in ring words, computed once at the first offer (a waiting sender is offered
    /// again at every instant, and counting a command list's words is not free).
    pub words: Option<u32>,
    /// The sender's `Ring::output_freed` count when the ring last refused it for want of room:
    /// until that count moves, an offer would be refused again, so none is made.
    pub refused: Option<u64>,
}

impl Outgoing {
    pub fn new(to: Unit, payload: Payload) -> Outgoing {
        Outgoing::counted(to, payload, None)
    }

    /// A message whose `words` its sender counted, if it did (as [`crate::machine`]'s
    /// `ring_words` would, at least 1).
    pub fn counted(to: Unit, payload: Payload, words: Option<u32>) -> Outgoing {
        Outgoing {
            to,
            payload,
            words: words.map(|w| w.max(1)),
            refused: None,
        }
    }
}

/// A message on the ring: what the ring does not carry for us (it moves only word counts).
struct InFlight {
    route: Route,
    seq: u64,
    payload: Payload,
    sent: Sent,
}

/// When the ring took a message, and the critical path to then (see `critical`). The path is
/// boxed: a message and its arrival are moved about four times between send and hand-over, and
/// copying its 400 bytes each time was most of the machine's `memmove`s (2-3 % of the main job's
/// CPU time by `perf record -e cpu-clock`); a Renderer's message keeps the same box to its first
/// command.
#[derive(Clone, Debug)]
pub(crate) struct Sent {
    pub at: Tick,
    pub profile: Box<Profile>,
}

/// A message ready to be handed to its receiver, with the ring's id of it (the receiver frees the
/// message's input-queue space through it).
pub(crate) struct Arrival {
    pub id: MessageId,
    pub to: Unit,
    pub message: Message,
    pub sent: Sent,
}

/// The sequence numbers of one route.
#[derive(Default)]
struct RouteState {
    /// The number the next message sent on the route carries.
    next_send: u64,
    /// The number of the next message to hand to the receiver.
    next_deliver: u64,
    /// Arrivals that overtook an earlier message of the route, with their sequence numbers,
    /// latest first (the next one due is the last). A list kept across uses, not a `BTreeMap`:
    /// few are held at once, and the map allocated a node of eleven arrivals for each that was
    /// (30 K in the main job's hemicube).
    held: Vec<(u64, Arrival)>,
}

/// Every message between sending and handing over.
pub(crate) struct Delivery {
    /// By message id (the ring numbers messages in the order it accepts them).
    in_flight: SeqMap<InFlight>,
    /// Each route's state, by the sender's and the receiver's ring nodes: `routes[from][to]`, a
    /// sender's row made at its first send. (A `BTreeMap` by route took about 320 host
    /// instructions a look-up, two a message.)
    routes: Vec<Vec<RouteState>>,
    positions: Positions,
    nodes: usize,
}

impl Delivery {
    /// Delivery between the units at `positions`, `nodes` ring nodes in all.
    pub fn new(positions: Positions, nodes: usize) -> Delivery {
        Delivery {
            in_flight: SeqMap::new(),
            routes: Vec::new(),
            positions,
            nodes,
        }
    }

    /// The state of `route`, made at first use.
    ///
    /// # Panics
    /// If a unit of the route is not on the ring: the machine offers the ring only messages
    /// between its units.
    fn route(&mut self, route: Route) -> &mut RouteState {
        let node = |u: Unit| match self.positions.get(u) {
            Some(n) => n.0 as usize,
            None => panic!("message on route {route:?}: {u} is not on the ring"),
        };
        let (from, to) = (node(route.from), node(route.to));
        if self.routes.len() <= from {
            self.routes.resize_with(from + 1, Vec::new);
        }
        let row = &mut self.routes[from];
        if row.is_empty() {
            row.resize_with(self.nodes, RouteState::default);
        }
        &mut row[to]
    }

    /// The sequence number the next message on `route` will carry (the ring passes it through as
    /// the message's tag).
    pub fn next_seq(&mut self, route: Route) -> u64 {
        self.route(route).next_send
    }

    /// The ring accepted message `id` of `route`, numbered [`Delivery::next_seq`].
    pub fn sent(&mut self, id: MessageId, route: Route, payload: Payload, sent: Sent) {
        let state = self.route(route);
        let seq = state.next_send;
        state.next_send += 1;
        let fresh = self.in_flight.insert(
            id.0,
            InFlight {
                route,
                seq,
                payload,
                sent,
            },
        );
        if fresh.is_err() {
            panic!("ring accepted message {id} after a later one");
        }
    }

    /// The ring delivered message `id` at `at`: returns its route, and appends to `due` the
    /// messages now due to their receiver in send order (none if it overtook an earlier one;
    /// several if it was the one they waited for).
    ///
    /// # Panics
    /// If the ring delivers a message it was never given: a simulator bug.
    pub fn arrived(&mut self, id: MessageId, at: Tick, due: &mut Vec<Arrival>) -> Route {
        let InFlight {
            route,
            seq,
            payload,
            sent,
        } = self
            .in_flight
            .remove(id.0)
            .unwrap_or_else(|| panic!("ring delivered unknown message {id} at {at}"));
        let message = Message {
            from: route.from,
            payload,
            at,
        };
        let state = self.route(route);
        let arrival = Arrival {
            id,
            to: route.to,
            message,
            sent,
        };
        // In order (nearly always): handed over at once, not through `held` (an insert and a
        // remove of a 500-byte arrival, with its critical path, per message).
        if seq == state.next_deliver {
            state.next_deliver += 1;
            due.push(arrival);
        } else {
            let at = state.held.partition_point(|&(s, _)| s > seq);
            state.held.insert(at, (seq, arrival));
        }
        while state
            .held
            .last()
            .is_some_and(|&(s, _)| s == state.next_deliver)
        {
            let (_, a) = state.held.pop().expect("looked at a moment ago");
            state.next_deliver += 1;
            due.push(a);
        }
        route
    }

    /// Whether no message is on the ring.
    pub fn is_empty(&self) -> bool {
        self.in_flight.is_empty()
    }
}
