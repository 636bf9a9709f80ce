//! The Pixel-Planes 5 token ring, simulated channel clock by channel clock: channels, tokens,
//! hops, packets, bounded queues with back-pressure.
//!
//! The ring knows only endpoints: [`NodeId`]s at positions `0..n` around the ring. Which node is
//! a GP, a Renderer, the frame buffer or the host is the machine crate's business. Everything is
//! deterministic: ordered maps only, no wall clock, no randomness.
//!
//! Tags follow `docs/hardware.md` ("facts" below): **\[seed\]** is
//! Goldfeather TR89-002, **\[assumed\]** means no source was found and the rule is this model's
//! choice (the facts' row "Ring hop latency, header size, max message, token rules, broadcast"
//! unless said otherwise); every \[assumed\] number is a field of [`pxpl5_config::RingConfig`].
//!
//! # The model
//!
//! **Time.** All `C` channels share one channel clock ([`ClockDomain`] from `channel_clock_hz`;
//! \[seed\]: 20 MHz, one word per channel clock per channel, 4 channels = 80 Mwords/s). Everything
//! happens on clock edges; edge `t` is at tick `t * period`. On each edge, first what is due then
//! happens (a packet's output words are freed, packets reach their destinations, messages are
//! delivered), then the *capture decisions* of that edge are taken, channel by channel in
//! increasing channel number (\[assumed\] tie rule).
//!
//! **Nodes and hops.** Data flows in increasing position order, wrapping. A message from `src`
//! to `dst` travels `k = (dst - src) mod n` hops; `src == dst` is an error. A word, or a free
//! token, needs `h = hop_latency_cycles` clocks per hop (\[assumed\] 1; at least 1).
//!
//! **Tokens.** Each channel has one token. At time zero the token of channel `c` stands at node
//! `floor(c * n / C)` (\[assumed\]: spread evenly, so with the seed's 4 channels on 16 nodes at
//! nodes 0, 4, 8, 12). A free token standing at node `p` at clock `t` that is not captured reaches
//! `p + 1` at clock `t + h`.
//!
//! **Capture.** A free token standing at node `p` at clock `t` is captured, and a packet starts,
//! when `p`'s output queue has a waiting packet at its head that
//! - is eligible: its message was sent at or before edge `t` (a message sent at tick `now` is
//!   eligible from the first edge at or after `now`), and
//! - has credit: if it is its message's first packet, the destination's input queue has room for
//!   the *whole message* (see "input queue").
//!
//! Otherwise the token moves on. Output queues are FIFO with head-of-line blocking (\[assumed\]: a
//! simple interface): a head packet whose destination is full holds back every packet behind it,
//! even to other destinations. A node may transmit different packets on different channels at the
//! same time, one per channel: each packet leaves on the first channel whose token reaches the
//! node (ties: the lowest channel number).
//!
//! **Transmission.** A packet is `W = header_words + payload` words (\[assumed\] 1 header word).
//! Started at clock `s`, its words are sent in clocks `s, s+1, ..., s+W-1`, one per clock; word
//! `i` reaches the destination at edge `s + i + 1 + k*h` (one clock to send it, `h` per hop). The
//! packet is delivered at edge `s + W + k*h`, when its last word arrives.
//!
//! **Token release** (\[assumed\] policy, `token_policy`):
//! - `EarlyRelease` (default): the token follows the last word: it is free at the sender at edge
//!   `s + W` and reaches the next node at `s + W + h`, together with the last word.
//! - `LateRelease`: the sender holds the token until the last word has reached the destination,
//!   edge `s + W + k*h`; the token reaches the next node `h` clocks later.
//!
//! Either way the released token moves on: the sender cannot take it straight back, so a node with
//! more to send waits for the token to come round (or for another channel's token).
//!
//! **Messages and packets.** A message longer than `max_message_words` payload words (\[assumed\]
//! 1,024) is split into packets of that size and a shorter last one, each with its own header. A
//! message is delivered when all its packets have arrived (they may travel on different channels
//! and arrive out of order). Two messages between the same pair of nodes may likewise be
//! delivered out of send order when they travel on different channels; a receiver that needs send
//! order sorts by [`MessageId`], which increases in send order.
//!
//! **Output queue.** One per node, shared by all channels, `queue_words` words (\[assumed\] 2,048).
//! [`Ring::send`] puts all of a message's packets, headers included, in the sender's output queue,
//! or fails with [`RingError::OutputFull`] (retry later) when they do not fit now, or with
//! [`RingError::MessageTooLarge`] when they could never fit. A packet's words leave the output
//! queue at edge `s + W`, when its last word has been sent.
//!
//! **Input queue.** One per node, shared by all channels, `queue_words` words. The whole
//! message's words (headers included) are reserved at the destination when its first packet
//! starts, so no word ever waits on the ring, and held until the receiver calls
//! [`Ring::consume`] with the delivered message's id. Credit is reserved per message, not per
//! packet, because per-packet credit deadlocks: two long messages to one node could each get
//! some packets in and leave no room for the rest of either, and neither could be consumed. Both
//! queues are per node, shared by its channels, as the config's `queue_words` says.
//!
//! **Calls and time.** [`Ring::advance`]`(until)` runs every edge up to and including `until`:
//! what is due at `until` happens, but the capture decisions of the edge at `until` are left to
//! the next call, so a message sent (or consumed) at exactly `until` still takes part in them.
//! `send` and `consume` take effect from the first edge at or after [`Ring::now`]; `send` may be
//! dated later than `now` (it is then eligible later) but never earlier, nor after
//! [`Ring::HORIZON`].
//!
//! **Idle skipping.** Between captures nothing that gates a capture changes, so each free token's
//! visits to a node form an arithmetic sequence: [`Ring::advance`] computes the next clock at
//! which a capture can happen and jumps there, so an idle second costs no more than an idle clock.
//! [`Ring::advance_clock_by_clock`] is the reference that visits every clock and moves tokens hop
//! by hop; the tests check that both agree exactly. [`Ring::next_event_tick`] takes the decisions
//! before the next event on a copy of the ring's state to find when it is; the ring keeps them
//! (their clocks, captures and tokens) and [`Ring::advance`] replays them, neither searching nor
//! deciding again, while nothing is sent or consumed.
//!
//! **Idle latency.** On an otherwise idle ring a one-packet message (payload
//! `<= max_message_words`) sent at tick `sent` over `k` hops is delivered at
//! `next_edge(sent) + (w + header_words + payload + k*h)` clocks, where `w` is its *token wait*:
//! the clocks from its eligible edge to the first edge at which a free token of any channel stands
//! at the sender (`w = 0` when one already stands there). [`idle_latency`] is that formula.
//!
//! **Ring levels.** The model above is the [`RingLevel::Token`] level, the reference. The
//! [`RingLevel::Message`] level is an approximation for studies that trade accuracy for host
//! time: a channel has no travelling token, so a node never waits for one to come round. Each
//! channel is free from the clock its previous packet released it (by the same `token_policy`);
//! at each clock every free channel, in increasing number, starts the waiting packet that became
//! eligible first (ties: the lower [`MessageId`]) from whichever node's queue head holds it, under
//! the same queues, credit, packet sizes, transmission and hop latency. What it leaves out is
//! token-by-token contention: the token's travel and which node it reaches first. Its error
//! against the token level is measured, never assumed (`pxpl5 tradeoff`).
//!
//! **Statistics** ([`RingStats`]): per channel, header and payload words, packets, messages and
//! busy clocks (clocks in which a sender was putting a word on the channel) and utilisation; per
//! node, queue high-water marks, traffic, and token wait: the clocks from when a packet was both
//! eligible and at the head of its queue to its start (which includes time its destination was
//! full).
//!
//! A model bug (an impossible state) panics with a message naming the channel and clock; every
//! caller mistake is a [`RingError`].

mod engine;
mod error;
mod ring;
mod stats;

use std::fmt;

use pxpl5_config::RingConfig;
use pxpl5_sim::{ClockDomain, Cycles, Tick};

pub use error::RingError;
pub use ring::Ring;
pub use stats::{ChannelStats, NodeStats, RingStats, TotalStats};

/// An endpoint of the ring: its position, `0..n`, in the direction data flows.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct NodeId(pub u32);

/// A message, numbered from 0 in the order [`Ring::send`] accepted them.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct MessageId(pub u64);

impl fmt::Display for NodeId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.0)
    }
}

impl fmt::Display for MessageId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "#{}", self.0)
    }
}

/// A message that has fully arrived. Its words stay in `dst`'s input queue until
/// [`Ring::consume`]`(id)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Delivery {
    pub id: MessageId,
    pub src: NodeId,
    pub dst: NodeId,
    /// The caller's tag, passed through.
    pub tag: u64,
    /// Payload words (headers excluded).
    pub words: u32,
    /// Packets it was split into.
    pub packets: u32,
    /// The `now` it was sent with.
    pub sent: Tick,
    /// When its first packet started on a channel (the sender held the token): the time from
    /// `sent` to it is queueing and token wait.
    pub started: Tick,
    /// When its last word arrived.
    pub delivered: Tick,
    /// The channels its packets went on: bit `c` for channel `c` (channels above 63 share bit 63).
    pub channels: u64,
}

/// How the ring is simulated (crate doc, "ring levels"): the host's choice, never the machine's.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum RingLevel {
    /// Tokens travel hop by hop and are captured where they stand: the reference.
    #[default]
    Token,
    /// Latency and bandwidth per message: a free channel goes to the packet eligible first,
    /// wherever it waits. Approximate.
    Message,
}

impl RingLevel {
    /// The level's name in options, statistics and reports.
    pub fn name(self) -> &'static str {
        match self {
            RingLevel::Token => "token",
            RingLevel::Message => "message",
        }
    }

    /// Whether results at this level may differ from the reference's.
    pub fn is_approximate(self) -> bool {
        self != RingLevel::Token
    }
}

/// Where a channel's token is (see [`Ring::token_at`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TokenLocation {
    /// Held by a sender: transmitting, or (late release) waiting for its last word to arrive.
    Held { by: NodeId },
    /// Free and standing at a node, which may capture it on this edge.
    At(NodeId),
    /// Free and travelling from one node to the next.
    Between { from: NodeId, to: NodeId },
}

/// Channel clocks from a one-packet message's eligible edge to its delivery on an otherwise idle
/// ring: `token_wait + header_words + payload_words + hops * hop_latency_cycles` (see the crate
/// doc, "idle latency"). `payload_words` must be at most `max_message_words` for the message to be
/// one packet; the formula does not check it.
pub fn idle_latency(cfg: &RingConfig, payload_words: u32, hops: u32, token_wait: Cycles) -> Cycles {
    token_wait
        + Cycles(u64::from(cfg.header_words) + u64::from(payload_words))
        + Cycles(u64::from(hops) * u64::from(cfg.hop_latency_cycles))
}

/// The tick of a one-packet message's delivery on an otherwise idle ring: the first edge of
/// `clock` at or after `sent`, plus [`idle_latency`].
pub fn idle_delivery(
    cfg: &RingConfig,
    clock: ClockDomain,
    sent: Tick,
    payload_words: u32,
    hops: u32,
    token_wait: Cycles,
) -> Tick {
    clock.next_edge(sent) + clock.to_ticks(idle_latency(cfg, payload_words, hops, token_wait))
}
