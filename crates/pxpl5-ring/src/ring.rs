//! [`Ring`]: the simulated token ring. Accepts messages ([`Ring::send`]), runs channel clocks
//! ([`Ring::advance`], or [`Ring::advance_clock_by_clock`], the reference), reports deliveries,
//! queue space, token positions and statistics. The timing rules are in the crate doc.

use std::cell::{Cell, RefCell};
use std::cmp::{Ordering, Reverse};
use std::collections::BinaryHeap;

use pxpl5_config::RingConfig;
use pxpl5_sim::{ClockDomain, Cycles, SeqMap, Tick};

use crate::engine::{self, Capture, Flow, Packet, Params, Queues, Token};
use crate::stats::{ChannelStats, NodeStats, RingStats, TotalStats, ratio};
use crate::{Delivery, MessageId, NodeId, RingError, RingLevel, TokenLocation};

/// Something fixed when a packet starts and due at a later clock.
#[derive(Clone, Copy, Debug)]
enum Event {
    /// The packet's last word has been sent: its words leave the output queue.
    OutputFree { channel: u32, node: u32, words: u32 },
    /// The packet's last word has reached its destination.
    Arrival {
        channel: u32,
        msg: MessageId,
        dst: u32,
        payload: u32,
    },
}

/// An event due at a ring clock, numbered in the order it was scheduled. Ordered by (clock,
/// number) alone, which no two share, so the event itself needs no order.
#[derive(Clone, Debug)]
struct Due {
    clock: u64,
    seq: u64,
    event: Event,
}

impl Ord for Due {
    fn cmp(&self, other: &Due) -> Ordering {
        (self.clock, self.seq).cmp(&(other.clock, other.seq))
    }
}

impl PartialOrd for Due {
    fn partial_cmp(&self, other: &Due) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl PartialEq for Due {
    fn eq(&self, other: &Due) -> bool {
        (self.clock, self.seq) == (other.clock, other.seq)
    }
}

impl Eq for Due {}

/// A message sent and not yet consumed.
#[derive(Clone, Debug)]
struct Message {
    src: u32,
    dst: u32,
    tag: u64,
    words: u32,
    packets: u32,
    /// Words (headers included) it holds in the destination's input queue once started.
    total: u32,
    sent: Tick,
    packets_left: u32,
    delivered: bool,
    /// Bit `c` set when a packet of it went on channel `c` (reported in its [`Delivery`]).
    channels: u64,
    /// The clock its first packet started on, if one has.
    first_start: Option<u64>,
}

/// The latest packet a channel carried: enough to say whether the token is held and how many of
/// its clocks have elapsed.
#[derive(Clone, Copy, Debug)]
struct Holder {
    by: u32,
    start: u64,
    end_tx: u64,
    release: u64,
}

/// Per-channel counters; busy clocks are committed whole at the start of a packet and trimmed to
/// the elapsed part in [`Ring::stats`].
#[derive(Clone, Debug, Default)]
struct ChannelAcc {
    header_words: u64,
    payload_words: u64,
    packets: u64,
    messages: u64,
    busy_committed: u64,
}

/// The decisions a look-ahead took on its copy of the flow, for the ring to take them again
/// without searching or deciding: valid while nothing is sent or consumed, each step taking the
/// next one. Decisions are a function of the queues and the flow alone (events change neither),
/// so the ring, stepping from the state the look-ahead copied, meets the same decisions.
#[derive(Clone, Debug, Default)]
struct Plan {
    valid: bool,
    /// Each decision's clock and the end of its captures in `caps`.
    decisions: Vec<(u64, usize)>,
    caps: Vec<Capture>,
    /// The tokens after each decision, a channel's each.
    tokens: Vec<Token>,
    /// How many of `decisions` the ring has stepped.
    taken: usize,
    /// [`engine::next_decision`] after the last of `decisions`.
    then: Option<u64>,
}

impl Plan {
    /// The ring's next decision by the plan, `None` without one.
    fn next(&self) -> Option<Option<u64>> {
        self.valid.then(|| {
            self.decisions
                .get(self.taken)
                .map(|&(clock, _)| clock)
                .or(self.then)
        })
    }

    /// Start a plan from nothing decided.
    fn clear(&mut self) {
        self.decisions.clear();
        self.caps.clear();
        self.tokens.clear();
        self.taken = 0;
    }

    /// Record the decision `flow` took at clock `t`, its captures `caps`.
    fn record(&mut self, t: u64, flow: &Flow, caps: &[Capture]) {
        self.caps.extend_from_slice(caps);
        self.tokens.extend_from_slice(&flow.tokens);
        self.decisions.push((t, self.caps.len()));
    }

    /// Take clock `t`'s decisions on `flow` as [`engine::decide_at`] would, appending the
    /// captures to `caps`, if the plan's next decision is at `t`; else the plan no longer holds
    /// and `false`.
    fn replay(&mut self, t: u64, flow: &mut Flow, caps: &mut Vec<Capture>) -> bool {
        let i = self.taken;
        if !(self.valid && self.decisions.get(i).is_some_and(|&(clock, _)| clock == t)) {
            self.valid = false;
            return false;
        }
        let from = i.checked_sub(1).map_or(0, |j| self.decisions[j].1);
        let to = self.decisions[i].1;
        let n = flow.tokens.len();
        flow.tokens
            .copy_from_slice(&self.tokens[i * n..(i + 1) * n]);
        for cap in &self.caps[from..to] {
            engine::book(flow, &cap.packet);
        }
        caps.extend_from_slice(&self.caps[from..to]);
        flow.next_clock = t + 1;
        self.taken += 1;
        true
    }
}

/// The token ring. See the crate doc for the model.
#[derive(Clone, Debug)]
pub struct Ring {
    p: Params,
    clock: ClockDomain,
    now: Tick,
    /// Packets not yet started, per node, in FIFO order.
    out: Queues,
    /// Output-queue words per node: packets waiting or being transmitted.
    out_used: Vec<u64>,
    /// Per node, how many times its output queue has freed words ([`Ring::output_freed`]).
    freed: Vec<u64>,
    /// The nodes whose output queue freed words since [`Ring::take_freed_nodes`] last listed
    /// them, each once (`freed_listed` marks them): at most one entry a node.
    freed_nodes: Vec<u32>,
    freed_listed: Vec<bool>,
    flow: Flow,
    /// The last [`engine::next_decision`] of `out` and `flow`, while neither has changed but
    /// for `flow.next_clock` moving up to it (which leaves it the answer: a later `from` cannot
    /// make another token's visit earlier). The machine asks for it twice an instant, once for
    /// [`Ring::next_event_tick`] and once to [`Ring::advance`] (4-6 % of `bench machine`).
    decision: Cell<Option<Option<u64>>>,
    /// Buffers reused by every call, for the captures of a clock and [`Ring::next_event_tick`]'s
    /// copy of the flow: allocated per call they were an allocation an advance and four a
    /// look-ahead (1 M allocations in a hemicube run of the main job).
    caps: RefCell<Vec<Capture>>,
    lookahead: RefCell<Option<Flow>>,
    /// The decisions [`Ring::next_event_tick`]'s look-ahead took, which [`Ring::advance`] then
    /// replays on the ring itself, neither searching for their clocks again
    /// ([`engine::next_decision`], 5.7 % of the main job's hemicube instructions, more than half
    /// of it repeating the look-ahead's) nor deciding them again.
    plan: RefCell<Plan>,
    holders: Vec<Option<Holder>>,
    /// Clock of each node's latest packet start (for the token-wait statistic).
    last_start: Vec<u64>,
    /// Due events, earliest (clock, sequence number) first: deterministic order within a clock.
    /// A heap, not a `BTreeMap`: the ring only ever takes the earliest, and the heap's push and
    /// pop took 0.36 % fewer of the main job's hemicube instructions.
    events: BinaryHeap<Reverse<Due>>,
    next_seq: u64,
    /// Messages from acceptance to consumption, by id (`MessageId`s are handed out in order).
    messages: SeqMap<Message>,
    next_msg: u64,
    deliveries: Vec<Delivery>,
    chan: Vec<ChannelAcc>,
    node: Vec<NodeStats>,
}

fn bad(field: &'static str, value: impl ToString, rule: impl Into<String>) -> RingError {
    RingError::BadConfig {
        field,
        value: value.to_string(),
        rule: rule.into(),
    }
}

impl Ring {
    /// The latest time a message may be sent: half the range of [`Tick`] (about 106 days of
    /// simulated time), so that every clock the ring computes from a send converts to a tick
    /// without overflow.
    pub const HORIZON: Tick = Tick(u64::MAX / 2);

    /// A ring of `nodes` endpoints (positions `0..nodes`) with the channels, clock, header,
    /// packet and queue sizes and token policy of `cfg`, at time zero with every queue empty and
    /// the token of channel `c` at node `c * nodes / channels` (rounded down).
    pub fn new(cfg: &RingConfig, nodes: u32) -> Result<Ring, RingError> {
        Ring::with_level(cfg, nodes, RingLevel::Token)
    }

    /// [`Ring::new`], simulated at `level` (crate doc, "ring levels").
    pub fn with_level(cfg: &RingConfig, nodes: u32, level: RingLevel) -> Result<Ring, RingError> {
        if nodes < 2 {
            return Err(bad("nodes", nodes, "a ring needs at least 2 nodes"));
        }
        if cfg.channels == 0 {
            return Err(bad("ring.channels", cfg.channels, "must be at least 1"));
        }
        let clock = ClockDomain::from_hz(cfg.channel_clock_hz)
            .map_err(|e| bad("ring.channel_clock_hz", cfg.channel_clock_hz, e.to_string()))?;
        if !(1..=64).contains(&cfg.word_bits) {
            return Err(bad("ring.word_bits", cfg.word_bits, "must be in 1..=64"));
        }
        if cfg.hop_latency_cycles == 0 {
            return Err(bad(
                "ring.hop_latency_cycles",
                0,
                "must be at least 1 (a token must take time to move)",
            ));
        }
        if cfg.max_message_words == 0 {
            return Err(bad("ring.max_message_words", 0, "must be at least 1"));
        }
        let needed = u64::from(cfg.max_message_words) + u64::from(cfg.header_words);
        if u64::from(cfg.queue_words) < needed {
            return Err(bad(
                "ring.queue_words",
                cfg.queue_words,
                format!(
                    "must hold one whole packet: at least ring.max_message_words + \
                     ring.header_words = {needed}"
                ),
            ));
        }
        let p = Params {
            nodes,
            channels: cfg.channels,
            hop: u64::from(cfg.hop_latency_cycles),
            header_words: cfg.header_words,
            max_payload: cfg.max_message_words,
            queue_words: cfg.queue_words,
            policy: cfg.token_policy,
            level,
        };
        let n = nodes as usize;
        // [assumed] tokens spread evenly at time zero (crate doc, "tokens").
        let tokens = (0..u64::from(cfg.channels))
            .map(|c| Token {
                pos: (c * u64::from(nodes) / u64::from(cfg.channels)) as u32,
                at: 0,
            })
            .collect();
        Ok(Ring {
            p,
            clock,
            now: Tick::ZERO,
            out: Queues::new(n),
            out_used: vec![0; n],
            freed: vec![0; n],
            freed_nodes: Vec::with_capacity(n),
            freed_listed: vec![false; n],
            flow: Flow {
                tokens,
                offsets: vec![0; n],
                in_used: vec![0; n],
                next_clock: 0,
            },
            decision: Cell::new(None),
            caps: RefCell::new(Vec::new()),
            lookahead: RefCell::new(None),
            plan: RefCell::new(Plan::default()),
            holders: vec![None; cfg.channels as usize],
            last_start: vec![0; n],
            events: BinaryHeap::new(),
            next_seq: 0,
            messages: SeqMap::new(),
            next_msg: 0,
            deliveries: Vec::new(),
            chan: vec![ChannelAcc::default(); cfg.channels as usize],
            node: vec![NodeStats::default(); n],
        })
    }

    /// The ring's current time: every event at or before it has happened.
    pub fn now(&self) -> Tick {
        self.now
    }

    /// The channel clock, shared by all channels.
    pub fn clock(&self) -> ClockDomain {
        self.clock
    }

    /// Number of nodes.
    pub fn nodes(&self) -> u32 {
        self.p.nodes
    }

    /// Number of channels.
    pub fn channels(&self) -> u32 {
        self.p.channels
    }

    /// The level the ring is simulated at.
    pub fn level(&self) -> RingLevel {
        self.p.level
    }

    fn check_node(&self, node: NodeId) -> Result<u32, RingError> {
        if node.0 < self.p.nodes {
            Ok(node.0)
        } else {
            Err(RingError::UnknownNode {
                node,
                nodes: self.p.nodes,
            })
        }
    }

    /// Words a message of `words` payload words occupies in a queue: its payload plus one header
    /// per packet.
    pub fn queue_words_of(&self, words: u32) -> u64 {
        let packets = u64::from(words.div_ceil(self.p.max_payload));
        u64::from(words) + packets * u64::from(self.p.header_words)
    }

    /// Queues a message of `words` payload words from `src` to `dst`, split into packets of at
    /// most `max_message_words` payload words each with its own header; it may start at the first
    /// channel-clock edge at or after `now`. Its packets go behind everything already in `src`'s
    /// output queue (FIFO, in call order).
    ///
    /// Errors: an unknown node, `src == dst`, zero words, `now` before [`Ring::now`], a message
    /// that can never fit a queue ([`RingError::MessageTooLarge`]), or not enough output-queue
    /// space now ([`RingError::OutputFull`]: retry after space frees, see
    /// [`Ring::next_event_tick`] and [`Ring::output_free_words`]).
    pub fn send(
        &mut self,
        now: Tick,
        src: NodeId,
        dst: NodeId,
        words: u32,
        tag: u64,
    ) -> Result<MessageId, RingError> {
        let s = self.check_node(src)?;
        let d = self.check_node(dst)?;
        if s == d {
            return Err(RingError::MessageToSelf { node: src });
        }
        if words == 0 {
            return Err(RingError::ZeroWords { src, dst });
        }
        if now < self.now {
            return Err(RingError::TimeWentBackwards {
                now,
                ring_now: self.now,
            });
        }
        if now > Self::HORIZON {
            return Err(RingError::BeyondHorizon {
                now,
                horizon: Self::HORIZON,
            });
        }
        let needed = self.queue_words_of(words);
        if needed > u64::from(self.p.queue_words) {
            return Err(RingError::MessageTooLarge {
                words,
                needed,
                queue_words: self.p.queue_words,
            });
        }
        let free = u64::from(self.p.queue_words) - self.out_used[s as usize];
        if needed > free {
            return Err(RingError::OutputFull {
                node: src,
                needed,
                free,
            });
        }
        // `needed` <= queue_words, a u32.
        let total = needed as u32;
        let id = MessageId(self.next_msg);
        self.next_msg += 1;
        let eligible = self.clock.cycles_ceil(now).get();
        let packets = words.div_ceil(self.p.max_payload);
        self.decision.set(None);
        self.plan.get_mut().valid = false;
        for i in 0..packets {
            let payload = (words - i * self.p.max_payload).min(self.p.max_payload);
            self.out.push(
                s as usize,
                Packet {
                    msg: id,
                    src: s,
                    dst: d,
                    payload,
                    words: payload + self.p.header_words,
                    reserve: if i == 0 { total } else { 0 },
                    last: i + 1 == packets,
                    eligible,
                },
            );
        }
        self.out_used[s as usize] += needed;
        let st = &mut self.node[s as usize];
        st.max_output_words = st.max_output_words.max(self.out_used[s as usize]);
        st.messages_sent += 1;
        let numbered = self.messages.insert(
            id.0,
            Message {
                src: s,
                dst: d,
                tag,
                words,
                packets,
                total,
                sent: now,
                packets_left: packets,
                delivered: false,
                channels: 0,
                first_start: None,
            },
        );
        if numbered.is_err() {
            panic!("pxpl5-ring model bug: message {id} numbered below one accepted before it");
        }
        Ok(id)
    }

    /// Frees the input-queue words of a delivered message at `dst`; the space counts for capture
    /// decisions from the first clock edge at or after [`Ring::now`] (advance first to consume at
    /// a later time).
    pub fn consume(&mut self, id: MessageId) -> Result<(), RingError> {
        if id.0 >= self.next_msg {
            return Err(RingError::UnknownMessage { id });
        }
        let Some(msg) = self.messages.get(id.0) else {
            return Err(RingError::AlreadyConsumed { id });
        };
        if !msg.delivered {
            return Err(RingError::NotDelivered { id });
        }
        let (dst, total) = (msg.dst as usize, u64::from(msg.total));
        self.decision.set(None);
        self.plan.get_mut().valid = false;
        let used = &mut self.flow.in_used[dst];
        let clock = self.flow.next_clock;
        *used = used.checked_sub(total).unwrap_or_else(|| {
            panic!(
                "pxpl5-ring model bug on channel (any), clock {clock}: node {dst}'s input queue \
                 holds fewer words than message {id}"
            )
        });
        self.messages.remove(id.0);
        Ok(())
    }

    /// Simulates every channel clock up to and including `until`, then sets [`Ring::now`] to
    /// `until`; an `until` not after `now` does nothing. Clocks on which no token can be captured
    /// are skipped arithmetically, so an idle second costs as little as an idle clock.
    pub fn advance(&mut self, until: Tick) {
        if until <= self.now {
            return;
        }
        let mut caps = std::mem::take(self.caps.get_mut());
        // Edge `t` decides only if it lies before `until` (see the crate doc, "calls and time").
        let edges = self.clock.cycles_floor_ceil(until);
        let stop = edges.1.get();
        while let Some(t) = self.next_decision() {
            if t >= stop {
                break;
            }
            self.step(t, &mut caps);
            Self::check_progress(&caps, t);
        }
        *self.caps.get_mut() = caps;
        self.finish(until, edges);
    }

    /// The reference for [`Ring::advance`]: the same, but visiting every channel clock one by one
    /// and moving every token one hop at a time. Slow on long idle stretches; the tests check that
    /// both give identical deliveries, statistics and token positions.
    pub fn advance_clock_by_clock(&mut self, until: Tick) {
        if until <= self.now {
            return;
        }
        let mut caps = Vec::new();
        let edges = self.clock.cycles_floor_ceil(until);
        let stop = edges.1.get();
        let mut t = self.flow.next_clock;
        while t < stop {
            self.step(t, &mut caps);
            t += 1;
        }
        self.finish(until, edges);
    }

    /// The fast path only stops at clocks where [`engine::next_decision`] found a token standing
    /// at a node that can start a packet; if nothing started there, the arithmetic is wrong (and
    /// skipping on would loop forever or miss captures).
    fn check_progress(caps: &[Capture], t: u64) {
        assert!(
            !caps.is_empty(),
            "pxpl5-ring model bug on channel (any), clock {t}: a capture was computed for this \
             clock but no token was captured"
        );
    }

    /// Events due by clock `t`, then the capture decisions of clock `t` (the plan's, while it
    /// holds).
    fn step(&mut self, t: u64, caps: &mut Vec<Capture>) {
        self.decision.set(None);
        self.run_events(t);
        caps.clear();
        if !self.plan.get_mut().replay(t, &mut self.flow, caps) {
            engine::decide_at(&self.p, &self.out, &mut self.flow, t, caps);
        }
        for cap in caps.iter() {
            self.apply(cap);
        }
    }

    /// Events due by `until`, whose clock edges before and after it are `(floor, ceil)`
    /// ([`ClockDomain::cycles_floor_ceil`]).
    fn finish(&mut self, until: Tick, (floor, ceil): (Cycles, Cycles)) {
        self.run_events(floor.get());
        self.now = until;
        let next = ceil.get();
        assert!(
            self.flow.next_clock <= next,
            "pxpl5-ring model bug on channel (any), clock {}: decided past {until}",
            self.flow.next_clock
        );
        self.flow.next_clock = next;
    }

    fn schedule(&mut self, clock: u64, ev: Event) {
        self.events.push(Reverse(Due {
            clock,
            seq: self.next_seq,
            event: ev,
        }));
        self.next_seq += 1;
    }

    /// Books a packet that started: pops it from its queue, schedules its output free and its
    /// arrival, and counts it.
    fn apply(&mut self, cap: &Capture) {
        let pkt = cap.packet;
        let q = pkt.src as usize;
        let popped = self.out.pop(q);
        if popped != Some(pkt) {
            panic!(
                "pxpl5-ring model bug on channel {}, clock {}: node {q} started {pkt:?} but its \
                 queue head is {popped:?}",
                cap.channel, cap.start
            );
        }
        self.flow.offsets[q] -= 1;
        if let Some(m) = self.messages.get_mut(pkt.msg.0) {
            // Channels above 63 share bit 63: the mask is a trace aid, not a model input.
            m.channels |= 1 << cap.channel.min(63);
            m.first_start.get_or_insert(cap.start);
        }
        self.schedule(
            cap.end_tx,
            Event::OutputFree {
                channel: cap.channel,
                node: pkt.src,
                words: pkt.words,
            },
        );
        self.schedule(
            cap.arrival,
            Event::Arrival {
                channel: cap.channel,
                msg: pkt.msg,
                dst: pkt.dst,
                payload: pkt.payload,
            },
        );
        let ch = &mut self.chan[cap.channel as usize];
        ch.header_words += u64::from(self.p.header_words);
        ch.payload_words += u64::from(pkt.payload);
        ch.packets += 1;
        ch.busy_committed += u64::from(pkt.words);
        if pkt.last {
            ch.messages += 1;
        }
        self.holders[cap.channel as usize] = Some(Holder {
            by: pkt.src,
            start: cap.start,
            end_tx: cap.end_tx,
            release: cap.release,
        });
        // Waiting starts when the packet is both eligible and at the head of the queue, i.e.
        // after the previous packet of this node started.
        let since = pkt.eligible.max(self.last_start[q]);
        self.last_start[q] = cap.start;
        let st = &mut self.node[q];
        st.packets_sent += 1;
        st.payload_words_sent += u64::from(pkt.payload);
        st.token_wait += Cycles(cap.start - since);
        let d = pkt.dst as usize;
        let dst = &mut self.node[d];
        dst.max_input_words = dst.max_input_words.max(self.flow.in_used[d]);
    }

    /// Runs every event due at or before clock `t`.
    fn run_events(&mut self, t: u64) {
        while let Some(Reverse(due)) = self.events.peek() {
            let clock = due.clock;
            if clock > t {
                break;
            }
            let Some(Reverse(due)) = self.events.pop() else {
                unreachable!("peeked a moment ago")
            };
            match due.event {
                Event::OutputFree {
                    channel,
                    node,
                    words,
                } => {
                    self.freed[node as usize] += 1;
                    if !std::mem::replace(&mut self.freed_listed[node as usize], true) {
                        self.freed_nodes.push(node);
                    }
                    let used = &mut self.out_used[node as usize];
                    *used = used.checked_sub(u64::from(words)).unwrap_or_else(|| {
                        panic!(
                            "pxpl5-ring model bug on channel {channel}, clock {clock}: node \
                             {node} frees {words} output words it does not hold"
                        )
                    });
                }
                Event::Arrival {
                    channel,
                    msg,
                    dst,
                    payload,
                } => {
                    self.node[dst as usize].payload_words_received += u64::from(payload);
                    let Some(m) = self.messages.get_mut(msg.0) else {
                        panic!(
                            "pxpl5-ring model bug on channel {channel}, clock {clock}: a packet \
                             of message {msg} arrived after the message was consumed"
                        );
                    };
                    m.packets_left -= 1;
                    if m.packets_left == 0 {
                        m.delivered = true;
                        self.node[dst as usize].messages_received += 1;
                        self.deliveries.push(Delivery {
                            id: msg,
                            src: NodeId(m.src),
                            dst: NodeId(m.dst),
                            tag: m.tag,
                            words: m.words,
                            packets: m.packets,
                            sent: m.sent,
                            started: m
                                .first_start
                                .map_or(m.sent, |c| self.clock.to_ticks(Cycles(c)).max(m.sent)),
                            delivered: self.clock.to_ticks(Cycles(clock)),
                            channels: m.channels,
                        });
                    }
                }
            }
        }
    }

    /// The messages delivered since the last call, by delivery tick, then message id.
    pub fn take_deliveries(&mut self) -> Vec<Delivery> {
        let mut out = Vec::new();
        self.take_deliveries_into(&mut out);
        out
    }

    /// [`Ring::take_deliveries`] into `out` (empty), which the ring keeps in exchange as its
    /// buffer for the next ones: a caller that passes the same buffer every time allocates
    /// nothing once both have grown.
    pub fn take_deliveries_into(&mut self, out: &mut Vec<Delivery>) {
        debug_assert!(
            out.is_empty(),
            "deliveries taken into a buffer that holds some"
        );
        std::mem::swap(&mut self.deliveries, out);
        out.sort_by_key(|d| (d.delivered, d.id));
    }

    /// The earliest tick after [`Ring::now`] at which the ring's visible state changes if nothing
    /// more is sent or consumed: a packet's words leave an output queue, or a packet (and perhaps
    /// its message) reaches its destination. `None` when nothing will ever happen: the ring is
    /// idle, or every waiting packet is held by a full destination that only
    /// [`Ring::consume`] can free.
    ///
    /// Packets not yet started are looked ahead on a copy of the token state, so the answer is
    /// exact: advancing to it produces an event, and advancing to just before it produces none.
    pub fn next_event_tick(&self) -> Option<Tick> {
        let mut best = self.events.peek().map(|Reverse(due)| due.clock);
        // The common case, nothing to decide before the next event, needs no copy of the flow.
        let first = match self.next_decision() {
            None => return best.map(|clock| self.clock.to_ticks(Cycles(clock))),
            Some(t) if best.is_some_and(|b| t >= b) => {
                return best.map(|clock| self.clock.to_ticks(Cycles(clock)));
            }
            Some(t) => t,
        };
        let mut slot = self.lookahead.borrow_mut();
        let flow = match slot.as_mut() {
            Some(f) => {
                f.copy_from(&self.flow);
                f
            }
            None => slot.insert(self.flow.clone()),
        };
        let mut caps = self.caps.borrow_mut();
        let mut plan = self.plan.borrow_mut();
        plan.clear();
        // The first decision is the ring's own, known already.
        let mut next = Some(first);
        while let Some(t) = next {
            if best.is_some_and(|b| t >= b) {
                break;
            }
            caps.clear();
            engine::decide_at(&self.p, &self.out, flow, t, &mut caps);
            Self::check_progress(&caps, t);
            plan.record(t, flow, &caps);
            for cap in caps.iter() {
                // A packet frees its output words before it can arrive anywhere.
                best = Some(best.map_or(cap.end_tx, |b| b.min(cap.end_tx)));
            }
            next = engine::next_decision(&self.p, &self.out, flow);
        }
        plan.then = next;
        plan.valid = true;
        best.map(|clock| self.clock.to_ticks(Cycles(clock)))
    }

    /// [`engine::next_decision`] of the ring's own queues and flow, remembered until they change.
    fn next_decision(&self) -> Option<u64> {
        if let Some(d) = self.decision.get()
            && d.is_none_or(|t| t >= self.flow.next_clock)
        {
            return d;
        }
        let d = self
            .plan
            .borrow()
            .next()
            .unwrap_or_else(|| engine::next_decision(&self.p, &self.out, &self.flow));
        self.decision.set(Some(d));
        d
    }

    /// Whether nothing is queued or in flight (delivered messages not yet consumed do not count).
    pub fn is_idle(&self) -> bool {
        self.events.is_empty() && self.out.is_empty()
    }

    /// How many times `node`'s output queue has freed words so far. A send refused for want of
    /// room ([`RingError::OutputFull`]) is refused again, with nothing changed, until this
    /// count moves: a waiting sender need not be offered before then.
    pub fn output_freed(&self, node: NodeId) -> Result<u64, RingError> {
        let q = self.check_node(node)?;
        Ok(self.freed[q as usize])
    }

    /// Call `f` with each node whose output queue has freed words (its [`Ring::output_freed`]
    /// count moved) since the last call, in the order they first did, and forget them: a sender
    /// refused for want of room need not be looked at before its node is listed here.
    pub fn take_freed_nodes(&mut self, mut f: impl FnMut(NodeId)) {
        for node in self.freed_nodes.drain(..) {
            self.freed_listed[node as usize] = false;
            f(NodeId(node));
        }
    }

    /// Free words in `node`'s output queue now.
    pub fn output_free_words(&self, node: NodeId) -> Result<u64, RingError> {
        let q = self.check_node(node)?;
        Ok(u64::from(self.p.queue_words) - self.out_used[q as usize])
    }

    /// Free words in `node`'s input queue now (not reserved by a message in flight, not held by a
    /// delivered message awaiting [`Ring::consume`]).
    pub fn input_free_words(&self, node: NodeId) -> Result<u64, RingError> {
        let q = self.check_node(node)?;
        Ok(u64::from(self.p.queue_words).saturating_sub(self.flow.in_used[q as usize]))
    }

    /// Where the token of `channel` is at the first clock edge at or after [`Ring::now`], before
    /// that edge's capture decision; `None` for a channel the ring does not have.
    pub fn token_at(&self, channel: u32) -> Option<TokenLocation> {
        let tok = *self.flow.tokens.get(channel as usize)?;
        Some(self.locate(tok, self.holders[channel as usize]))
    }

    /// Every channel's token, in channel order, as [`Ring::token_at`] finds it, reduced to one
    /// node and whether it is held: the holder, or the node it stands at or last left. What a
    /// trace samples at every instant (a VCD shows each channel's token position), so the
    /// channels are walked in one pass.
    pub fn token_nodes(&self) -> impl Iterator<Item = (NodeId, bool)> + '_ {
        self.flow
            .tokens
            .iter()
            .zip(&self.holders)
            .map(|(&tok, &holder)| match self.locate(tok, holder) {
                TokenLocation::Held { by } => (by, true),
                TokenLocation::At(n) | TokenLocation::Between { from: n, .. } => (n, false),
            })
    }

    /// Where token `tok`, held as `holder` says, is at the first clock edge at or after
    /// [`Ring::now`] (see [`Ring::token_at`]).
    #[inline(always)]
    fn locate(&self, tok: Token, holder: Option<Holder>) -> TokenLocation {
        let t = self.flow.next_clock;
        if let Some(h) = holder
            && h.start < t
            && t < h.release
        {
            return TokenLocation::Held { by: NodeId(h.by) };
        }
        if self.p.level == RingLevel::Message {
            // A free channel has no position at this level: it stands wherever a packet waits.
            // It is reported at its last sender.
            return TokenLocation::At(NodeId(tok.pos));
        }
        let n = self.p.nodes;
        let prev = |q: u32| NodeId((q + n - 1) % n);
        if tok.at > t {
            TokenLocation::Between {
                from: prev(tok.pos),
                to: NodeId(tok.pos),
            }
        } else {
            let d = t - tok.at;
            // pos < n and hops % n < n, so one subtraction wraps the sum: a division fewer in
            // a call a VCD makes for every channel at every instant.
            let q = u64::from(tok.pos) + (d / self.p.hop) % u64::from(n);
            let q = q.checked_sub(u64::from(n)).unwrap_or(q) as u32;
            if d.is_multiple_of(self.p.hop) {
                TokenLocation::At(NodeId(q))
            } else {
                TokenLocation::Between {
                    from: NodeId(q),
                    to: NodeId((q + 1) % n),
                }
            }
        }
    }

    /// The statistics as of [`Ring::now`].
    pub fn stats(&self) -> RingStats {
        let elapsed = self.clock.cycles_floor(self.now).get();
        let channels: Vec<ChannelStats> = self
            .chan
            .iter()
            .zip(&self.holders)
            .map(|(acc, holder)| {
                // Only the latest packet of a channel can still be in transmission.
                let unelapsed = holder.map_or(0, |h| h.end_tx - elapsed.clamp(h.start, h.end_tx));
                let busy = acc.busy_committed - unelapsed;
                ChannelStats {
                    header_words: acc.header_words,
                    payload_words: acc.payload_words,
                    packets: acc.packets,
                    messages: acc.messages,
                    busy: Cycles(busy),
                    utilisation: ratio(busy, elapsed),
                }
            })
            .collect();
        let busy: u64 = channels.iter().map(|c| c.busy.get()).sum();
        let total = TotalStats {
            header_words: channels.iter().map(|c| c.header_words).sum(),
            payload_words: channels.iter().map(|c| c.payload_words).sum(),
            packets: channels.iter().map(|c| c.packets).sum(),
            messages_sent: self.node.iter().map(|n| n.messages_sent).sum(),
            messages_delivered: self.node.iter().map(|n| n.messages_received).sum(),
            payload_words_delivered: self.node.iter().map(|n| n.payload_words_received).sum(),
            busy: Cycles(busy),
            utilisation: ratio(busy, elapsed * u64::from(self.p.channels)),
            token_wait: self.node.iter().map(|n| n.token_wait).sum(),
        };
        RingStats {
            now: self.now,
            elapsed: Cycles(elapsed),
            channels,
            nodes: self.node.clone(),
            total,
        }
    }
}
