//! Exact timing tests of the token ring: idle latency against the formula, parallel channels,
//! throughput bounds, contention, packet splitting, back-pressure, determinism and idle skipping.
//! Every expected tick is worked out by hand from the rules in the crate doc.

use pxpl5_config::{NodeOrder, RingConfig, TokenPolicy};
use pxpl5_ring::{
    Delivery, MessageId, NodeId, Ring, RingError, RingLevel, TokenLocation, idle_delivery,
    idle_latency,
};
use pxpl5_sim::{Cycles, Tick};

/// The seed's channel clock: 20 MHz, 50,000 ps per clock.
const P: u64 = 50_000;

fn cfg(channels: u32) -> RingConfig {
    // The seed's ring (machine-configs/seed-tr89-002.ron) with a chosen channel count.
    RingConfig {
        channels,
        channel_clock_hz: 20_000_000,
        word_bits: 32,
        hop_latency_cycles: 1,
        header_words: 1,
        max_message_words: 1024,
        token_policy: TokenPolicy::EarlyRelease,
        node_order: NodeOrder::Interleaved,
        queue_words: 2048,
    }
}

fn at(clock: u64) -> Tick {
    Tick(clock * P)
}

fn send(ring: &mut Ring, now: Tick, src: u32, dst: u32, words: u32) -> MessageId {
    ring.send(
        now,
        NodeId(src),
        NodeId(dst),
        words,
        u64::from(src) << 32 | u64::from(dst),
    )
    .expect("the test's send fits")
}

/// Advances until nothing more can happen and returns every delivery.
fn drain(ring: &mut Ring) -> Vec<Delivery> {
    while let Some(t) = ring.next_event_tick() {
        ring.advance(t);
    }
    ring.take_deliveries()
}

#[test]
fn idle_messages_take_exactly_the_formula() {
    for policy in [TokenPolicy::EarlyRelease, TokenPolicy::LateRelease] {
        for hop in [1, 3] {
            for header in [0, 1, 4] {
                for words in [1, 7, 100, 1024] {
                    for hops in [1, 3, 7] {
                        let mut c = cfg(1);
                        c.token_policy = policy;
                        c.hop_latency_cycles = hop;
                        c.header_words = header;
                        let nodes = 8;
                        // Channel 0's token stands at node 0 at time zero: the sender holds it.
                        let mut ring = Ring::new(&c, nodes).unwrap();
                        let id = send(&mut ring, Tick::ZERO, 0, hops, words);
                        let d = drain(&mut ring);
                        assert_eq!(d.len(), 1);
                        let expect = u64::from(header + words + hops * hop);
                        assert_eq!(idle_latency(&c, words, hops, Cycles::ZERO), Cycles(expect));
                        assert_eq!(
                            d[0].delivered,
                            at(expect),
                            "{c:?} words {words} hops {hops}"
                        );
                        assert_eq!(
                            (d[0].id, d[0].words, d[0].packets, d[0].sent),
                            (id, words, 1, Tick::ZERO)
                        );

                        // The same from node 3, sent between edges after an idle gap: the token
                        // visits node 3 at clocks 3h + 8h*m; the wait is to the first visit at or
                        // after the first edge at or after the send.
                        let mut ring = Ring::new(&c, nodes).unwrap();
                        let sent = Tick(1_234 * P + 17);
                        ring.advance(Tick(1_000 * P + 5));
                        let src = 3;
                        let dst = (src + hops) % nodes;
                        ring.send(sent, NodeId(src), NodeId(dst), words, 9).unwrap();
                        let eligible = 1_235;
                        let lap = u64::from(nodes * hop);
                        let mut visit = u64::from(src * hop);
                        while visit < eligible {
                            visit += lap;
                        }
                        let wait = Cycles(visit - eligible);
                        let d = drain(&mut ring);
                        assert_eq!(
                            d[0].delivered,
                            idle_delivery(&c, ring.clock(), sent, words, hops, wait),
                            "{c:?} words {words} hops {hops}"
                        );
                        assert_eq!(ring.stats().nodes[src as usize].token_wait, wait);
                    }
                }
            }
        }
    }
}

#[test]
fn four_channels_carry_four_messages_in_parallel() {
    // 8 nodes, 4 channels: tokens at nodes 0, 2, 4, 6 at time zero.
    let c = cfg(4);
    let mut ring = Ring::new(&c, 8).unwrap();
    for src in [0, 2, 4, 6] {
        send(&mut ring, Tick::ZERO, src, (src + 3) % 8, 100);
    }
    let d = drain(&mut ring);
    assert_eq!(d.len(), 4);
    for del in &d {
        // Each as if alone, with no token wait: 1 + 100 words, 3 hops.
        assert_eq!(del.delivered, at(104));
        assert_eq!(
            del.delivered,
            idle_delivery(&c, ring.clock(), Tick::ZERO, 100, 3, Cycles(0))
        );
    }
    // Each went on the channel whose token stood at its sender (node 2c for channel c), at once.
    for del in &d {
        assert_eq!(del.channels, 1 << (del.src.0 / 2), "{del:?}");
        assert_eq!(del.started, Tick::ZERO);
    }
    let stats = ring.stats();
    for ch in &stats.channels {
        assert_eq!((ch.packets, ch.payload_words, ch.header_words), (1, 100, 1));
        assert_eq!(ch.busy, Cycles(101));
    }

    // From the odd nodes each waits one hop for the token behind it, still in parallel.
    let mut ring = Ring::new(&c, 8).unwrap();
    for src in [1, 3, 5, 7] {
        send(&mut ring, Tick::ZERO, src, (src + 2) % 8, 50);
    }
    for del in drain(&mut ring) {
        assert_eq!(del.delivered, at(1 + 51 + 2));
        // The token wait: one clock before the first packet started.
        assert_eq!(del.started, at(1));
        assert_eq!(del.channels.count_ones(), 1);
    }
    assert_eq!(ring.stats().total.token_wait, Cycles(4));
}

/// Keeps `senders` sending `words`-word messages to `(src + 5) % nodes` until `end`, consuming
/// every delivery at once; returns (payload words, payload + header words) delivered by `end`.
fn stream(c: &RingConfig, nodes: u32, senders: &[u32], words: u32, end: Tick) -> (u64, u64) {
    let mut ring = Ring::new(c, nodes).unwrap();
    let (mut payload, mut all) = (0, 0);
    loop {
        let now = ring.now();
        for &src in senders {
            while ring
                .send(now, NodeId(src), NodeId((src + 5) % nodes), words, 0)
                .is_ok()
            {}
        }
        for d in ring.take_deliveries() {
            payload += u64::from(d.words);
            all += u64::from(d.words) + u64::from(d.packets * c.header_words);
            ring.consume(d.id).unwrap();
        }
        match ring.next_event_tick() {
            Some(t) if t <= end => ring.advance(t),
            _ => break,
        }
    }
    ring.advance(end);
    for d in ring.take_deliveries() {
        payload += u64::from(d.words);
        all += u64::from(d.words) + u64::from(d.packets * c.header_words);
    }
    let stats = ring.stats();
    for ch in &stats.channels {
        assert!(ch.busy <= stats.elapsed && ch.utilisation <= 1.0);
    }
    (payload, all)
}

#[test]
fn throughput_is_bounded_by_one_word_per_channel_clock_and_approaches_it() {
    let clocks = 200_000; // 10 ms of simulated time
    let end = at(clocks);
    let senders = [0, 2, 4, 6, 8, 10, 12, 14];
    for channels in [4, 1] {
        let c = cfg(channels);
        let (payload, all) = stream(&c, 16, &senders, 256, end);
        let bound = u64::from(channels) * clocks;
        assert!(
            all <= bound,
            "{all} words in {clocks} clocks on {channels} channels"
        );
        // 80 Mwords/s for the seed's 4 channels, 20 Mwords/s for one.
        let per_second = all as f64 / end.as_secs_f64();
        assert!(per_second <= channels as f64 * 20e6 + 1.0);
        // Overheads: one header per 256 words, two hops to the next sender, the ring's fill.
        assert!(
            payload as f64 >= 0.97 * bound as f64,
            "{payload} payload words in {clocks} clocks on {channels} channels"
        );
    }
}

#[test]
fn contention_on_one_channel_delays_the_second_sender_exactly() {
    for policy in [TokenPolicy::EarlyRelease, TokenPolicy::LateRelease] {
        for hop in [1u64, 2] {
            let mut c = cfg(1);
            c.token_policy = policy;
            c.hop_latency_cycles = hop as u32;
            let mut ring = Ring::new(&c, 8).unwrap();
            let a = send(&mut ring, Tick::ZERO, 2, 7, 50); // 5 hops, W = 51
            let b = send(&mut ring, Tick::ZERO, 5, 1, 30); // 4 hops, W = 31
            let d = drain(&mut ring);
            // The token leaves node 0 at clock 0 and reaches node 2 at 2h: A starts.
            let start_a = 2 * hop;
            let release_a = match policy {
                TokenPolicy::EarlyRelease => start_a + 51,
                TokenPolicy::LateRelease => start_a + 51 + 5 * hop,
            };
            // Then three hops from node 2 to node 5: B starts.
            let start_b = release_a + 3 * hop;
            assert_eq!(d[0].id, a);
            assert_eq!(d[0].delivered, at(start_a + 51 + 5 * hop));
            assert_eq!(d[1].id, b);
            assert_eq!(d[1].delivered, at(start_b + 31 + 4 * hop));
            // Alone, B would have started at 5h: it lost A's transmission (and, with late
            // release, A's flight) to the one token.
            let delay = start_b - 5 * hop;
            assert_eq!(
                delay,
                match policy {
                    TokenPolicy::EarlyRelease => 51,
                    TokenPolicy::LateRelease => 51 + 5 * hop,
                }
            );
            let stats = ring.stats();
            assert_eq!(stats.nodes[5].token_wait, Cycles(start_b));
            assert_eq!(stats.nodes[2].token_wait, Cycles(start_a));

            // Watch the token: held by node 2 from A's start to its release, then on its way to
            // node 3, which it reaches one hop later; busy clocks count only elapsed clocks.
            let mut ring = Ring::new(&c, 8).unwrap();
            send(&mut ring, Tick::ZERO, 2, 7, 50);
            send(&mut ring, Tick::ZERO, 5, 1, 30);
            assert_eq!(ring.token_at(0), Some(TokenLocation::At(NodeId(0))));
            ring.advance(at(start_a));
            assert_eq!(ring.token_at(0), Some(TokenLocation::At(NodeId(2))));
            ring.advance(at(start_a) + Tick(1));
            let held = Some(TokenLocation::Held { by: NodeId(2) });
            assert_eq!(ring.token_at(0), held);
            ring.advance(at(start_a + 10));
            assert_eq!(ring.stats().channels[0].busy, Cycles(10));
            ring.advance(at(release_a - 1));
            assert_eq!(ring.token_at(0), held);
            ring.advance(at(release_a));
            let leaving = TokenLocation::Between {
                from: NodeId(2),
                to: NodeId(3),
            };
            assert_eq!(ring.token_at(0), Some(leaving));
            assert_eq!(ring.stats().channels[0].busy, Cycles(51));
            ring.advance(at(release_a + hop));
            assert_eq!(ring.token_at(0), Some(TokenLocation::At(NodeId(3))));
        }
    }
}

/// The message-level ring: the same two messages as above, with no token to wait for. A starts
/// at once; B, sent at the same clock, gets the one channel when A releases it (it became
/// eligible at the same clock, and A's message number is lower), with no hops of token travel.
#[test]
fn the_message_level_has_no_token_travel_but_keeps_the_channel_busy() {
    for policy in [TokenPolicy::EarlyRelease, TokenPolicy::LateRelease] {
        for hop in [1u64, 2] {
            let mut c = cfg(1);
            c.token_policy = policy;
            c.hop_latency_cycles = hop as u32;
            let mut ring = Ring::with_level(&c, 8, RingLevel::Message).unwrap();
            assert_eq!(ring.level(), RingLevel::Message);
            let a = send(&mut ring, Tick::ZERO, 2, 7, 50); // 5 hops, W = 51
            let b = send(&mut ring, Tick::ZERO, 5, 1, 30); // 4 hops, W = 31
            let d = drain(&mut ring);
            let release_a = match policy {
                TokenPolicy::EarlyRelease => 51,
                TokenPolicy::LateRelease => 51 + 5 * hop,
            };
            assert_eq!((d[0].id, d[0].started), (a, at(0)));
            assert_eq!(d[0].delivered, at(51 + 5 * hop));
            assert_eq!((d[1].id, d[1].started), (b, at(release_a)));
            assert_eq!(d[1].delivered, at(release_a + 31 + 4 * hop));
            let stats = ring.stats();
            assert_eq!(stats.nodes[5].token_wait, Cycles(release_a));
            assert_eq!(stats.nodes[2].token_wait, Cycles(0));
            // The token level makes B wait for the token's travel as well: the message level
            // is never slower here, and the difference is exactly that travel.
            let mut token = Ring::new(&c, 8).unwrap();
            send(&mut token, Tick::ZERO, 2, 7, 50);
            send(&mut token, Tick::ZERO, 5, 1, 30);
            let t = drain(&mut token);
            assert_eq!(t[1].started, at(2 * hop + release_a + 3 * hop));
        }
    }
    // Four channels carry four waiting messages at once, whatever nodes they wait at, where the
    // token level makes each wait for a token to reach it.
    let mut ring = Ring::with_level(&cfg(4), 16, RingLevel::Message).unwrap();
    for src in [1, 2, 3, 9] {
        send(&mut ring, Tick::ZERO, src, 0, 10);
    }
    let d = drain(&mut ring);
    assert_eq!(d.len(), 4);
    assert!(d.iter().all(|d| d.started == at(0)), "{d:?}");
    assert_eq!(ring.stats().total.token_wait, Cycles(0));
}

#[test]
fn long_messages_are_split_into_packets_with_their_own_headers() {
    let mut c = cfg(1);
    c.max_message_words = 100;
    c.header_words = 2;
    c.queue_words = 400;
    let mut ring = Ring::new(&c, 4).unwrap();
    assert_eq!(ring.queue_words_of(250), 256);
    send(&mut ring, Tick::ZERO, 0, 2, 250);
    assert_eq!(ring.output_free_words(NodeId(0)), Ok(400 - 256));
    let d = drain(&mut ring);
    // Packets of 100, 100, 50 (W = 102, 102, 52); between them the token goes round 4 nodes.
    let (s1, s2, s3) = (0, 102 + 4, 106 + 102 + 4);
    assert_eq!((s2, s3), (106, 212));
    assert_eq!(d.len(), 1);
    assert_eq!((d[0].words, d[0].packets), (250, 3));
    assert_eq!(d[0].delivered, at(s3 + 52 + 2));
    let stats = ring.stats();
    let ch = &stats.channels[0];
    assert_eq!(
        (ch.packets, ch.header_words, ch.payload_words, ch.messages),
        (3, 6, 250, 1)
    );
    assert_eq!(ch.busy, Cycles(256));
    assert_eq!(stats.nodes[0].packets_sent, 3);
    assert_eq!(stats.nodes[0].max_output_words, 256);
    assert_eq!(stats.nodes[2].max_input_words, 256);
    assert_eq!(stats.nodes[2].payload_words_received, 250);
    // Each later packet waits from its predecessor's start for the token.
    assert_eq!(stats.nodes[0].token_wait, Cycles((s2 - s1) + (s3 - s2)));

    // With 4 channels (tokens at nodes 0, 1, 2, 3) the packets leave on channels 0, 3 and 2 at
    // clocks 0, 1 and 2, and arrive out of order; the message is delivered with the last.
    let mut c4 = c.clone();
    c4.channels = 4;
    let mut ring = Ring::new(&c4, 4).unwrap();
    send(&mut ring, Tick::ZERO, 0, 2, 250);
    let d = drain(&mut ring);
    assert_eq!(d[0].delivered, at(1 + 102 + 2));
    let packets: Vec<u64> = ring
        .stats()
        .channels
        .iter()
        .map(|c| c.payload_words)
        .collect();
    assert_eq!(packets, [100, 0, 50, 100]);
}

#[test]
fn a_full_output_queue_refuses_and_frees_as_packets_leave() {
    let mut c = cfg(1);
    c.max_message_words = 100;
    c.queue_words = 300;
    let mut ring = Ring::new(&c, 4).unwrap();
    send(&mut ring, Tick::ZERO, 0, 2, 150); // 101 + 51 = 152 words
    assert_eq!(
        ring.send(Tick::ZERO, NodeId(0), NodeId(2), 150, 0),
        Err(RingError::OutputFull {
            node: NodeId(0),
            needed: 152,
            free: 148
        })
    );
    assert_eq!(
        ring.send(Tick::ZERO, NodeId(1), NodeId(2), 299, 0),
        Err(RingError::MessageTooLarge {
            words: 299,
            needed: 302,
            queue_words: 300
        })
    );
    // The token stands at node 0: the first packet's 101 words leave when it has been sent.
    assert_eq!(ring.next_event_tick(), Some(at(101)));
    ring.advance(at(101) - Tick(1));
    assert_eq!(ring.output_free_words(NodeId(0)), Ok(148));
    ring.advance(at(101));
    assert_eq!(ring.output_free_words(NodeId(0)), Ok(249));
    send(&mut ring, at(101), 0, 2, 150);
    assert_eq!(ring.output_free_words(NodeId(0)), Ok(97));
}

#[test]
fn a_full_destination_holds_packets_until_consume() {
    let mut c = cfg(1);
    c.max_message_words = 100;
    c.queue_words = 300;
    let mut ring = Ring::new(&c, 4).unwrap();
    let big = send(&mut ring, Tick::ZERO, 1, 3, 250); // 253 words reserved at node 3
    let small = send(&mut ring, Tick::ZERO, 2, 3, 50); // needs 51, only 47 left
    assert_eq!(ring.consume(big), Err(RingError::NotDelivered { id: big }));
    assert_eq!(
        ring.consume(MessageId(99)),
        Err(RingError::UnknownMessage { id: MessageId(99) })
    );
    // Packets of `big` start at 1, 106, 211 (the token goes round 4 nodes between them, passing
    // node 2, which is blocked); the last (W = 51) arrives 2 hops later at 264.
    let d = drain(&mut ring);
    assert_eq!(d.len(), 1);
    assert_eq!((d[0].id, d[0].delivered), (big, at(211 + 51 + 2)));
    assert_eq!(ring.next_event_tick(), None);
    assert!(!ring.is_idle());
    assert_eq!(ring.input_free_words(NodeId(3)), Ok(47));
    assert_eq!(ring.token_at(0), Some(TokenLocation::At(NodeId(3))));

    // Consume between edges at 1,000: from edge 1,001 the token's visits to node 2
    // (263 + 4m) may start `small`: at 1,003; 51 words, 1 hop.
    let consume_at = Tick(1_000 * P + 1);
    ring.advance(consume_at);
    ring.consume(big).unwrap();
    assert_eq!(
        ring.consume(big),
        Err(RingError::AlreadyConsumed { id: big })
    );
    assert_eq!(ring.input_free_words(NodeId(3)), Ok(300));
    let d = drain(&mut ring);
    assert_eq!((d[0].id, d[0].delivered), (small, at(1_003 + 51 + 1)));
    let stats = ring.stats();
    assert_eq!(stats.nodes[3].max_input_words, 253);
    assert_eq!(stats.nodes[2].token_wait, Cycles(1_003));
    assert_eq!(ring.input_free_words(NodeId(3)), Ok(249));
    assert!(ring.is_idle());
}

/// `token_nodes`, a trace's sample of every channel at once, is `token_at` reduced to a node.
fn assert_tokens_sampled(ring: &Ring) {
    let want: Vec<(NodeId, bool)> = (0..ring.channels())
        .map(|ch| match ring.token_at(ch).unwrap() {
            TokenLocation::Held { by } => (by, true),
            TokenLocation::At(n) | TokenLocation::Between { from: n, .. } => (n, false),
        })
        .collect();
    assert_eq!(ring.token_nodes().collect::<Vec<_>>(), want);
}

/// A fixed pseudo-random workload (the project's seeded generator; no randomness source).
fn workload(ring: &mut Ring, seed: u64) -> (Vec<Delivery>, pxpl5_ring::RingStats) {
    let mut rng = pxpl5_geom::rng::Lcg::new(seed);
    let mut next = move |m: u64| rng.below(m);
    let n = u64::from(ring.nodes());
    let mut all = Vec::new();
    for _ in 0..400 {
        let now = ring.now() + Tick(next(40) * 397_919);
        let src = next(n) as u32;
        let dst = ((u64::from(src) + 1 + next(n - 1)) % n) as u32;
        let _ = ring.send(
            now,
            NodeId(src),
            NodeId(dst),
            1 + next(1_500) as u32,
            next(1 << 20),
        );
        ring.advance(now + Tick(next(3) * 40_000));
        assert_tokens_sampled(ring);
        for d in ring.take_deliveries() {
            ring.consume(d.id).unwrap();
            all.push(d);
        }
    }
    all.extend(drain(ring));
    (all, ring.stats())
}

#[test]
fn the_same_sends_give_the_same_deliveries_and_stats() {
    let mut c = cfg(4);
    c.queue_words = 4_096;
    let first = workload(&mut Ring::new(&c, 12).unwrap(), 7);
    let second = workload(&mut Ring::new(&c, 12).unwrap(), 7);
    assert!(first.0.len() > 300);
    assert_eq!(first, second);
}

#[test]
fn an_idle_second_is_skipped_and_tokens_are_where_stepping_puts_them() {
    let mut c = cfg(4);
    c.hop_latency_cycles = 3;
    let nodes = 10;
    // Clock by clock against the arithmetic skip, at edges and between them.
    let mut fast = Ring::new(&c, nodes).unwrap();
    let mut slow = Ring::new(&c, nodes).unwrap();
    let mut t = Tick::ZERO;
    for step in 1..200u64 {
        t += Tick(step * 13_001 % 170_000);
        fast.advance(t);
        slow.advance_clock_by_clock(t);
        for ch in 0..4 {
            assert_eq!(fast.token_at(ch), slow.token_at(ch), "channel {ch} at {t}");
        }
    }
    assert_eq!(fast.token_at(4), None);

    // One idle second (20,000,000 clocks) in one call: tokens start at nodes 0, 2, 5, 7
    // (floor(c * 10 / 4)) and move one node per 3 clocks, 40 clocks a lap: after 20,000,000
    // clocks, 6,666,666 hops and 2 clocks more, so between node (s + 6) mod 10 and the next.
    let mut ring = Ring::new(&c, nodes).unwrap();
    ring.advance(Tick(1_000_000_000_000));
    for (ch, s) in [0u32, 2, 5, 7].into_iter().enumerate() {
        assert_eq!(
            ring.token_at(ch as u32),
            Some(TokenLocation::Between {
                from: NodeId((s + 6) % 10),
                to: NodeId((s + 7) % 10)
            })
        );
    }
    // A message from node 9 now, at edge 20,000,000: channel 1's token (between 8 and 9, one
    // clock to go) is the nearest, so the wait is 1 clock; from node 6 it is channel 0's (between
    // 6 and 7): 2 clocks to node 7, then 9 hops of 3 clocks.
    let sent = ring.now();
    send(&mut ring, sent, 9, 0, 10);
    let d = drain(&mut ring);
    assert_eq!(
        d[0].delivered,
        idle_delivery(&c, ring.clock(), sent, 10, 1, Cycles(1))
    );
    assert_eq!(ring.stats().channels[1].packets, 1);
}

#[test]
fn bad_configs_and_calls_are_errors() {
    let mut c = cfg(0);
    assert!(matches!(
        Ring::new(&c, 4),
        Err(RingError::BadConfig {
            field: "ring.channels",
            ..
        })
    ));
    c.channels = 1;
    assert!(matches!(
        Ring::new(&c, 1),
        Err(RingError::BadConfig { field: "nodes", .. })
    ));
    c.channel_clock_hz = 3;
    let err = Ring::new(&c, 4).unwrap_err();
    assert!(matches!(
        err,
        RingError::BadConfig {
            field: "ring.channel_clock_hz",
            ..
        }
    ));
    assert!(
        err.to_string().contains("whole number of picoseconds"),
        "{err}"
    );
    c.channel_clock_hz = 20_000_000;
    c.hop_latency_cycles = 0;
    assert!(Ring::new(&c, 4).is_err());
    c.hop_latency_cycles = 1;
    c.queue_words = 1_024;
    assert!(matches!(
        Ring::new(&c, 4),
        Err(RingError::BadConfig {
            field: "ring.queue_words",
            ..
        })
    ));
    c.queue_words = 2_048;
    let mut ring = Ring::new(&c, 4).unwrap();
    let t = Tick::ZERO;
    assert_eq!(
        ring.send(t, NodeId(4), NodeId(0), 1, 0),
        Err(RingError::UnknownNode {
            node: NodeId(4),
            nodes: 4
        })
    );
    assert_eq!(
        ring.send(t, NodeId(2), NodeId(2), 1, 0),
        Err(RingError::MessageToSelf { node: NodeId(2) })
    );
    assert_eq!(
        ring.send(t, NodeId(1), NodeId(2), 0, 0),
        Err(RingError::ZeroWords {
            src: NodeId(1),
            dst: NodeId(2)
        })
    );
    ring.advance(at(10));
    assert_eq!(
        ring.send(at(9), NodeId(1), NodeId(2), 1, 0),
        Err(RingError::TimeWentBackwards {
            now: at(9),
            ring_now: at(10)
        })
    );
    let late = Ring::HORIZON + Tick(1);
    assert_eq!(
        ring.send(late, NodeId(1), NodeId(2), 1, 0),
        Err(RingError::BeyondHorizon {
            now: late,
            horizon: Ring::HORIZON
        })
    );
    assert!(ring.output_free_words(NodeId(9)).is_err());
    assert!(ring.input_free_words(NodeId(9)).is_err());
    // Nothing queued: nothing will happen.
    assert_eq!(ring.next_event_tick(), None);
    assert!(ring.is_idle());
}

#[test]
fn a_message_sent_on_an_edge_already_advanced_to_still_uses_that_edge() {
    // The token of the only channel stands at node 0 at clocks 0, 4, 8, ...: a message sent at
    // exactly edge 8 after advancing to it starts at 8, as one sent before advancing does.
    let c = cfg(1);
    let mut a = Ring::new(&c, 4).unwrap();
    a.advance(at(8));
    send(&mut a, at(8), 0, 1, 5);
    let mut b = Ring::new(&c, 4).unwrap();
    send(&mut b, at(8), 0, 1, 5);
    let (da, db) = (drain(&mut a), drain(&mut b));
    assert_eq!(da[0].delivered, at(8 + 6 + 1));
    assert_eq!(da, db);
}
