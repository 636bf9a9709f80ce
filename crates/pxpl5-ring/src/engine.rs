//! The token-passing core: what happens at one channel clock ([`decide_at`]), and the next clock
//! at which anything can be captured ([`next_decision`]).
//!
//! Both paths of [`crate::Ring`] use these two functions: the clock-by-clock reference calls
//! [`decide_at`] on every clock; the fast path calls it only on the clocks [`next_decision`]
//! computes arithmetically, since a clock on which no token is captured changes nothing but token
//! positions, which are a linear function of time. The state they work on ([`Flow`]) is small and
//! cloneable, so [`crate::Ring::next_event_tick`] can look ahead on a copy without touching the
//! ring.
//!
//! Clocks here are plain `u64` channel-clock numbers (edge `t` is at tick `t * period`); they
//! never leave the crate as bare numbers.

use std::collections::VecDeque;

use pxpl5_config::TokenPolicy;

use crate::{MessageId, RingLevel};

/// The ring's parameters, checked by [`crate::Ring::new`].
#[derive(Clone, Copy, Debug)]
pub(crate) struct Params {
    pub nodes: u32,
    pub channels: u32,
    /// Channel clocks per hop, at least 1 (a zero would let a free token circle forever in one
    /// clock).
    pub hop: u64,
    pub header_words: u32,
    pub max_payload: u32,
    pub queue_words: u32,
    pub policy: TokenPolicy,
    /// Tokens that travel ([`RingLevel::Token`]), or channels any node may take as soon as they
    /// are free ([`RingLevel::Message`]).
    pub level: RingLevel,
}

impl Params {
    /// Hops from `src` to `dst` in the direction of data flow (increasing position, wrapping).
    pub fn hops(&self, src: u32, dst: u32) -> u64 {
        debug_assert!(src < self.nodes && dst < self.nodes);
        // Below twice the nodes: one subtraction, not the division of a `%` (a ring decision
        // takes a hop count for every waiting node and token).
        let d = dst + self.nodes - src;
        u64::from(if d >= self.nodes { d - self.nodes } else { d })
    }

    /// Clocks for a free token to go once round the ring.
    fn lap(&self) -> u64 {
        u64::from(self.nodes) * self.hop
    }
}

/// One packet waiting in an output queue: a header plus up to `max_message_words` payload words.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Packet {
    pub msg: MessageId,
    pub src: u32,
    pub dst: u32,
    pub payload: u32,
    /// Header plus payload words: clocks of transmission.
    pub words: u32,
    /// Input-queue words to reserve at the destination when this packet starts: the whole
    /// message's words (headers included) on its first packet, zero on the others (their credit
    /// was reserved with the first; see the crate doc, "input queue").
    pub reserve: u32,
    /// The message's final packet.
    pub last: bool,
    /// First clock at which the packet may start (the first edge at or after its send time).
    pub eligible: u64,
}

/// The nodes' output queues of packets not yet started, FIFO, and which nodes have any: the
/// decisions look only at those (most nodes wait for nothing at a given clock, and scanning all
/// of them was most of [`next_decision`]'s work).
#[derive(Clone, Debug)]
pub(crate) struct Queues {
    queues: Vec<VecDeque<Packet>>,
    /// Bit q % 64 of word q / 64 is set when node q's queue is not empty.
    waiting: Vec<u64>,
}

impl Queues {
    /// Empty queues for `nodes` nodes.
    pub fn new(nodes: usize) -> Queues {
        Queues {
            queues: vec![VecDeque::new(); nodes],
            waiting: vec![0; nodes.div_ceil(64)],
        }
    }

    /// Appends `pkt` to node `q`'s queue.
    pub fn push(&mut self, q: usize, pkt: Packet) {
        self.queues[q].push_back(pkt);
        self.waiting[q / 64] |= 1 << (q % 64);
    }

    /// Takes the head of node `q`'s queue.
    pub fn pop(&mut self, q: usize) -> Option<Packet> {
        let pkt = self.queues[q].pop_front();
        if self.queues[q].is_empty() {
            self.waiting[q / 64] &= !(1 << (q % 64));
        }
        pkt
    }

    /// Packet `i` of node `q`'s queue (0: its head).
    #[inline]
    pub fn get(&self, q: usize, i: usize) -> Option<&Packet> {
        self.queues[q].get(i)
    }

    /// Whether no node has a packet waiting.
    pub fn is_empty(&self) -> bool {
        self.waiting.iter().all(|&w| w == 0)
    }

    /// The nodes whose queue is not empty, in increasing order.
    #[inline]
    pub fn waiting(&self) -> Waiting<'_> {
        Waiting {
            words: &self.waiting,
            word: 0,
            bits: self.waiting.first().copied().unwrap_or(0),
        }
    }
}

/// The iterator of [`Queues::waiting`]: the set bits of the words, lowest first.
pub(crate) struct Waiting<'a> {
    words: &'a [u64],
    /// Index of the word `bits` came from, and its bits not yet returned.
    word: usize,
    bits: u64,
}

impl Iterator for Waiting<'_> {
    type Item = u32;

    #[inline]
    fn next(&mut self) -> Option<u32> {
        while self.bits == 0 {
            self.word += 1;
            self.bits = *self.words.get(self.word)?;
        }
        let bit = self.bits.trailing_zeros();
        self.bits &= self.bits - 1;
        Some((self.word * 64) as u32 + bit)
    }
}

/// Where a channel's token goes next: it reaches node `pos` at clock `at` and is free there.
/// Between visits it is travelling (or held by the sender that captured it, see
/// [`crate::Ring::token_at`]); a token that is not captured at `pos` reaches `pos + 1` at
/// `at + hop`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Token {
    pub pos: u32,
    pub at: u64,
}

/// The state that capture decisions read and change: tokens, how many packets each node has
/// started in this look-ahead (so the queues themselves stay untouched), input-queue credit in use
/// per node, and the first clock not yet decided.
#[derive(Clone, Debug)]
pub(crate) struct Flow {
    pub tokens: Vec<Token>,
    /// Packets already started from the front of each node's output queue but not yet popped.
    pub offsets: Vec<usize>,
    /// Input-queue words per node: reserved for messages in flight plus delivered, not consumed.
    pub in_used: Vec<u64>,
    /// The first clock whose capture decisions have not been taken.
    pub next_clock: u64,
}

impl Flow {
    /// Become a copy of `other`, in this flow's own buffers (destructured, so that a new field
    /// cannot be forgotten here).
    pub fn copy_from(&mut self, other: &Flow) {
        let Flow {
            tokens,
            offsets,
            in_used,
            next_clock,
        } = other;
        self.tokens.clone_from(tokens);
        self.offsets.clone_from(offsets);
        self.in_used.clone_from(in_used);
        self.next_clock = *next_clock;
    }
}

/// A packet that started on a channel, with its timing fixed at that moment.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Capture {
    pub channel: u32,
    pub packet: Packet,
    /// Clock of the first (header) word.
    pub start: u64,
    /// The clock after the last word is sent: the packet's output-queue words free then.
    pub end_tx: u64,
    /// Clock at which the last word reaches the destination: the packet's delivery.
    pub arrival: u64,
    /// Clock at which the sender lets the token go (early: `end_tx`; late: `arrival`).
    pub release: u64,
}

/// The packet node `q` would start now, ignoring only its eligibility time: the first packet of
/// the output queue not yet started (FIFO, head-of-line blocking), provided the destination has
/// room for its whole message when it is the message's first packet.
fn startable<'a>(p: &Params, out: &'a Queues, flow: &Flow, q: u32) -> Option<&'a Packet> {
    let pkt = out.get(q as usize, flow.offsets[q as usize])?;
    let free = u64::from(p.queue_words).saturating_sub(flow.in_used[pkt.dst as usize]);
    (u64::from(pkt.reserve) <= free).then_some(pkt)
}

/// Moves a free token that was not captured on its way to its first visit at or after clock `t`.
fn normalise(p: &Params, tok: &mut Token, t: u64) {
    if tok.at < t {
        let steps = (t - tok.at).div_ceil(p.hop);
        // The token's new position, pos + steps round the ring, dividing only for a lap or
        // more (it is called for every channel at every decision).
        let nodes = u64::from(p.nodes);
        let within = if steps < nodes { steps } else { steps % nodes };
        let pos = u64::from(tok.pos) + within;
        tok.pos = (if pos >= nodes { pos - nodes } else { pos }) as u32;
        tok.at += steps * p.hop;
    }
}

/// Takes every capture decision of clock `t` (which must be `flow.next_clock` or later, with no
/// capture possible in between): channels in increasing number, so that when two tokens stand at
/// nodes at the same clock the lower channel chooses first (\[assumed\] tie rule). Appends the
/// packets started to `caps` and sets `flow.next_clock` to `t + 1`.
pub(crate) fn decide_at(
    p: &Params,
    out: &Queues,
    flow: &mut Flow,
    t: u64,
    caps: &mut Vec<Capture>,
) {
    assert!(
        t >= flow.next_clock,
        "pxpl5-ring model bug on channel (any), clock {t}: clock already decided (next is {})",
        flow.next_clock
    );
    if p.level == RingLevel::Message {
        decide_message_level(p, out, flow, t, caps);
        return;
    }
    for c in 0..p.channels {
        let mut tok = flow.tokens[c as usize];
        normalise(p, &mut tok, t);
        if tok.at == t {
            let q = tok.pos;
            let next = if q + 1 == p.nodes { 0 } else { q + 1 };
            let ready = startable(p, out, flow, q).filter(|pkt| pkt.eligible <= t);
            if let Some(&pkt) = ready {
                let cap = capture(p, flow, c, pkt, t);
                // The released token moves on from the sender: it reaches the next node one hop
                // after release (the sender cannot take it straight back, so tokens go round).
                tok = Token {
                    pos: next,
                    at: cap.release + p.hop,
                };
                caps.push(cap);
            } else {
                tok = Token {
                    pos: next,
                    at: t + p.hop,
                };
            }
        }
        flow.tokens[c as usize] = tok;
    }
    flow.next_clock = t + 1;
}

/// Starts `pkt` on channel `c` at clock `t`: its timing, and the flow's bookkeeping ([`book`]).
fn capture(p: &Params, flow: &mut Flow, c: u32, pkt: Packet, t: u64) -> Capture {
    let end_tx = t + u64::from(pkt.words);
    let arrival = end_tx + p.hops(pkt.src, pkt.dst) * p.hop;
    let release = match p.policy {
        TokenPolicy::EarlyRelease => end_tx,
        TokenPolicy::LateRelease => arrival,
    };
    book(flow, &pkt);
    Capture {
        channel: c,
        packet: pkt,
        start: t,
        end_tx,
        arrival,
        release,
    }
}

/// A capture's bookkeeping in the flow: the packet leaves its queue's unstarted part, and its
/// message's credit is reserved at the destination.
pub(crate) fn book(flow: &mut Flow, pkt: &Packet) {
    flow.offsets[pkt.src as usize] += 1;
    flow.in_used[pkt.dst as usize] += u64::from(pkt.reserve);
}

/// The message-level model's decisions at clock `t` (crate doc, "ring levels"): every channel
/// free at `t`, in increasing number, starts the startable, eligible packet that became eligible
/// first (ties: the lower message number), from whichever node holds it. A free channel has no
/// position: a node never waits for a token to travel to it, only for a channel to be free and
/// for credit. Its token's `at` is the clock from which the channel is free and its `pos` the
/// last sender.
fn decide_message_level(
    p: &Params,
    out: &Queues,
    flow: &mut Flow,
    t: u64,
    caps: &mut Vec<Capture>,
) {
    for c in 0..p.channels {
        if flow.tokens[c as usize].at > t {
            continue;
        }
        let first = out
            .waiting()
            .filter_map(|q| startable(p, out, flow, q))
            .filter(|pkt| pkt.eligible <= t)
            .min_by_key(|pkt| (pkt.eligible, pkt.msg))
            .copied();
        let Some(pkt) = first else {
            break;
        };
        let cap = capture(p, flow, c, pkt, t);
        flow.tokens[c as usize] = Token {
            pos: pkt.src,
            at: cap.release,
        };
        caps.push(cap);
    }
    flow.next_clock = t + 1;
}

/// The message-level model's [`next_decision`]: the first clock at which a channel is free and a
/// startable packet eligible.
fn next_message_level_decision(p: &Params, out: &Queues, flow: &Flow) -> Option<u64> {
    let eligible = out
        .waiting()
        .filter_map(|q| startable(p, out, flow, q))
        .map(|pkt| pkt.eligible)
        .min()?;
    let free = flow.tokens.iter().map(|tok| tok.at).min()?;
    Some(eligible.max(free).max(flow.next_clock))
}

/// The first clock at or after `flow.next_clock` at which some token stands at a node that can
/// start a packet, or `None` if no packet can ever start without a new send or consume.
///
/// Until the first capture nothing that gates a capture changes (heads, credit and eligibility
/// change only at captures, sends and consumes), so each free token's visits to node `q` are the
/// arithmetic sequence `at + j*hop + m*lap` and the first one at or after the packet's eligibility
/// is found by one division. This is what lets the ring skip idle stretches.
pub(crate) fn next_decision(p: &Params, out: &Queues, flow: &Flow) -> Option<u64> {
    if p.level == RingLevel::Message {
        return next_message_level_decision(p, out, flow);
    }
    let lap = p.lap();
    let mut best: Option<u64> = None;
    for q in out.waiting() {
        let Some(pkt) = startable(p, out, flow, q) else {
            continue;
        };
        let from = pkt.eligible.max(flow.next_clock);
        for tok in &flow.tokens {
            let first = tok.at + p.hops(tok.pos, q) * p.hop;
            let visit = if first >= from {
                first
            } else {
                first + (from - first).div_ceil(lap) * lap
            };
            best = Some(best.map_or(visit, |b| b.min(visit)));
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params(nodes: u32, channels: u32, hop: u64) -> Params {
        Params {
            nodes,
            channels,
            hop,
            header_words: 1,
            max_payload: 16,
            queue_words: 64,
            policy: TokenPolicy::EarlyRelease,
            level: RingLevel::Token,
        }
    }

    fn flow(p: &Params, tokens: Vec<Token>) -> Flow {
        Flow {
            tokens,
            offsets: vec![0; p.nodes as usize],
            in_used: vec![0; p.nodes as usize],
            next_clock: 0,
        }
    }

    fn packet(src: u32, dst: u32, payload: u32, eligible: u64) -> Packet {
        Packet {
            msg: MessageId(0),
            src,
            dst,
            payload,
            words: payload + 1,
            reserve: payload + 1,
            last: true,
            eligible,
        }
    }

    /// The waiting set follows pushes and pops, across words, lowest node first.
    #[test]
    fn queues_list_the_nodes_with_packets() {
        let mut q = Queues::new(130);
        assert!(q.is_empty() && q.waiting().next().is_none());
        for node in [129, 3, 64, 3] {
            q.push(node, packet(node as u32, 0, 1, 0));
        }
        assert_eq!(q.waiting().collect::<Vec<_>>(), [3, 64, 129]);
        assert!(q.pop(3).is_some());
        assert_eq!(
            q.waiting().collect::<Vec<_>>(),
            [3, 64, 129],
            "one left at 3"
        );
        assert!(q.pop(3).is_some() && q.pop(129).is_some());
        assert_eq!(q.waiting().collect::<Vec<_>>(), [64]);
        assert!(q.pop(64).is_some() && q.pop(64).is_none());
        assert!(q.is_empty() && q.waiting().next().is_none());
    }

    #[test]
    fn hops_wrap_in_the_direction_of_flow() {
        let p = params(5, 1, 1);
        assert_eq!(p.hops(1, 3), 2);
        assert_eq!(p.hops(3, 1), 3);
        assert_eq!(p.hops(4, 0), 1);
    }

    #[test]
    fn normalise_steps_whole_hops() {
        let p = params(5, 1, 3);
        let mut tok = Token { pos: 4, at: 10 };
        normalise(&p, &mut tok, 10);
        assert_eq!(tok, Token { pos: 4, at: 10 });
        // 11..=13 is one hop on: node 0 at clock 13.
        normalise(&p, &mut tok, 11);
        assert_eq!(tok, Token { pos: 0, at: 13 });
        // Seven laps and two hops later.
        normalise(&p, &mut tok, 13 + 7 * 15 + 5);
        assert_eq!(
            tok,
            Token {
                pos: 2,
                at: 13 + 7 * 15 + 6
            }
        );
    }

    #[test]
    fn next_decision_waits_for_eligibility_by_whole_laps() {
        // 4 nodes, hop 2: the token visits node 3 at 6, 14, 22, ...
        let p = params(4, 1, 2);
        let mut out = Queues::new(4);
        out.push(3, packet(3, 1, 4, 15));
        let f = flow(&p, vec![Token { pos: 0, at: 0 }]);
        assert_eq!(next_decision(&p, &out, &f), Some(22));
        // Nothing waiting: nothing to decide.
        let empty = Queues::new(4);
        assert_eq!(next_decision(&p, &empty, &f), None);
    }

    #[test]
    fn a_full_destination_blocks_the_head_and_the_packets_behind_it() {
        let p = params(4, 1, 1);
        let mut out = Queues::new(4);
        out.push(0, packet(0, 2, 10, 0));
        out.push(0, packet(0, 3, 1, 0));
        let mut f = flow(&p, vec![Token { pos: 0, at: 0 }]);
        f.in_used[2] = 60; // 4 words free, the head needs 11
        assert_eq!(next_decision(&p, &out, &f), None);
        let mut caps = Vec::new();
        decide_at(&p, &out, &mut f, 0, &mut caps);
        assert!(caps.is_empty());
        assert_eq!(f.tokens[0], Token { pos: 1, at: 1 });
    }

    #[test]
    fn decide_at_starts_a_packet_and_releases_the_token_by_policy() {
        for (policy, release) in [
            (TokenPolicy::EarlyRelease, 5 + 11),
            (TokenPolicy::LateRelease, 5 + 11 + 3 * 2),
        ] {
            let mut p = params(6, 1, 2);
            p.policy = policy;
            let mut out = Queues::new(6);
            out.push(1, packet(1, 4, 10, 0));
            let mut f = flow(&p, vec![Token { pos: 1, at: 5 }]);
            f.next_clock = 5;
            let mut caps = Vec::new();
            decide_at(&p, &out, &mut f, 5, &mut caps);
            assert_eq!(caps.len(), 1);
            let c = caps[0];
            assert_eq!((c.start, c.end_tx, c.arrival), (5, 16, 16 + 6));
            assert_eq!(c.release, release);
            assert_eq!(
                f.tokens[0],
                Token {
                    pos: 2,
                    at: release + 2
                }
            );
            assert_eq!(f.offsets[1], 1);
            assert_eq!(f.in_used[4], 11);
            assert_eq!(f.next_clock, 6);
        }
    }
}
