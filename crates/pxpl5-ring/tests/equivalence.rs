//! Property tests: on random configs and random streams of sends, advances and consumes, the fast
//! ring (`advance`, which skips clocks arithmetically) and the clock-by-clock reference
//! (`advance_clock_by_clock`) agree exactly on every answer; `next_event_tick` is exact; and no
//! delivery beats the idle-ring formula; at both ring levels.

use proptest::prelude::*;
use pxpl5_config::{NodeOrder, RingConfig, TokenPolicy};
use pxpl5_ring::{MessageId, NodeId, Ring, RingLevel};
use pxpl5_sim::{Cycles, Tick};

/// 20 MHz: 50,000 ps per channel clock.
const P: u64 = 50_000;

#[derive(Clone, Debug)]
enum Op {
    /// Send after `gap` ps from now.
    Send {
        gap: u64,
        src: u32,
        dst_offset: u32,
        words: u32,
        tag: u64,
    },
    /// Advance by `ps`.
    Advance { ps: u64 },
    /// Advance to the next event, if any.
    ToNextEvent,
    /// Consume every delivered message.
    ConsumeAll,
}

fn config() -> impl Strategy<Value = (RingConfig, u32)> {
    (
        1u32..=4,
        1u32..=3,
        0u32..=2,
        1u32..=40,
        0u32..=100,
        any::<bool>(),
        2u32..=7,
    )
        .prop_map(|(channels, hop, header, max, extra, late, nodes)| {
            (
                RingConfig {
                    channels,
                    channel_clock_hz: 20_000_000,
                    word_bits: 32,
                    hop_latency_cycles: hop,
                    header_words: header,
                    max_message_words: max,
                    token_policy: if late {
                        TokenPolicy::LateRelease
                    } else {
                        TokenPolicy::EarlyRelease
                    },
                    node_order: NodeOrder::Interleaved,
                    queue_words: max + header + extra,
                },
                nodes,
            )
        })
}

fn op() -> impl Strategy<Value = Op> {
    prop_oneof![
        4 => (0u64..40 * P, 0u32..7, 0u32..6, 1u32..120, any::<u64>()).prop_map(
            |(gap, src, dst_offset, words, tag)| Op::Send { gap, src, dst_offset, words, tag }
        ),
        2 => (0u64..200 * P).prop_map(|ps| Op::Advance { ps }),
        2 => Just(Op::ToNextEvent),
        1 => Just(Op::ConsumeAll),
    ]
}

/// Everything a caller can observe, for comparing two rings.
fn observe(ring: &Ring) -> String {
    let n = ring.nodes();
    let free: Vec<_> = (0..n)
        .map(|q| {
            (
                ring.output_free_words(NodeId(q)),
                ring.input_free_words(NodeId(q)),
            )
        })
        .collect();
    let tokens: Vec<_> = (0..ring.channels()).map(|c| ring.token_at(c)).collect();
    format!(
        "now {:?} next {:?} idle {} free {free:?} tokens {tokens:?} stats {:?}",
        ring.now(),
        ring.next_event_tick(),
        ring.is_idle(),
        ring.stats()
    )
}

/// The part of the state `next_event_tick` promises to be about.
fn visible(ring: &Ring) -> (Vec<u64>, Vec<u64>, u64) {
    let n = ring.nodes();
    let out = (0..n)
        .map(|q| ring.output_free_words(NodeId(q)).unwrap())
        .collect();
    let received = ring
        .stats()
        .nodes
        .iter()
        .map(|s| s.payload_words_received)
        .collect();
    (out, received, ring.stats().total.messages_delivered)
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(500))]

    #[test]
    fn fast_and_clock_by_clock_rings_agree(
        (cfg, nodes) in config(),
        level in prop_oneof![Just(RingLevel::Token), Just(RingLevel::Message)],
        ops in prop::collection::vec(op(), 1..60),
    ) {
        let mut fast = Ring::with_level(&cfg, nodes, level).unwrap();
        let mut slow = Ring::with_level(&cfg, nodes, level).unwrap();
        let mut delivered: Vec<MessageId> = Vec::new();
        let hop = u64::from(cfg.hop_latency_cycles);
        for op in ops {
            match op {
                Op::Send { gap, src, dst_offset, words, tag } => {
                    let now = fast.now() + Tick(gap);
                    let src = src % nodes;
                    // dst_offset 0 sometimes makes a message to oneself: an error on both.
                    let dst = (src + dst_offset % nodes) % nodes;
                    let a = fast.send(now, NodeId(src), NodeId(dst), words, tag);
                    let b = slow.send(now, NodeId(src), NodeId(dst), words, tag);
                    prop_assert_eq!(a, b);
                }
                Op::Advance { ps } => {
                    let until = fast.now() + Tick(ps);
                    fast.advance(until);
                    slow.advance_clock_by_clock(until);
                }
                Op::ToNextEvent => {
                    let next = fast.next_event_tick();
                    prop_assert_eq!(next, slow.next_event_tick());
                    if let Some(t) = next {
                        prop_assert!(t > fast.now());
                        // Exact: nothing visible changes just before it, something at it.
                        let before = visible(&fast);
                        let mut probe = fast.clone();
                        probe.advance(t - Tick(1));
                        prop_assert_eq!(visible(&probe), before.clone());
                        probe.advance(t);
                        prop_assert_ne!(visible(&probe), before);
                        fast.advance(t);
                        slow.advance_clock_by_clock(t);
                    }
                }
                Op::ConsumeAll => {
                    for id in delivered.drain(..) {
                        prop_assert_eq!(fast.consume(id), Ok(()));
                        prop_assert_eq!(slow.consume(id), Ok(()));
                    }
                }
            }
            let (da, db) = (fast.take_deliveries(), slow.take_deliveries());
            prop_assert_eq!(&da, &db);
            for d in &da {
                // No message beats its last packet's idle time with no token wait.
                let max = cfg.max_message_words;
                let last = d.words - (d.packets - 1) * max;
                let hops = u64::from((d.dst.0 + nodes - d.src.0) % nodes);
                let floor = u64::from(cfg.header_words + last) + hops * hop;
                let clock = fast.clock();
                prop_assert!(d.delivered >= clock.next_edge(d.sent) + clock.to_ticks(Cycles(floor)));
                prop_assert_eq!(d.packets, d.words.div_ceil(max));
                delivered.push(d.id);
            }
            prop_assert_eq!(observe(&fast), observe(&slow));
            let stats = fast.stats();
            for ch in &stats.channels {
                prop_assert!(ch.busy <= stats.elapsed);
                prop_assert!(ch.header_words + ch.payload_words >= ch.busy.get());
            }
        }
        // Finally both drain to the same end.
        while let Some(t) = fast.next_event_tick() {
            fast.advance(t);
            slow.advance_clock_by_clock(t);
        }
        prop_assert_eq!(fast.take_deliveries(), slow.take_deliveries());
        prop_assert_eq!(observe(&fast), observe(&slow));
    }
}
