//! Integration tests of the machine: small programs on small machines, with exact simulated
//! values derived by hand from the timing rules (GP cost table, the ring's idle-latency formula
//! and token rules from `pxpl5_ring`'s crate doc, the Renderer cycle table), plus the run errors
//! (deadlock, time limit, a stop asked by the host, program error), determinism of stats and traces, fidelity independence
//! and per-pair message ordering.

use std::cell::RefCell;
use std::collections::BTreeSet;
use std::rc::Rc;
use std::sync::Arc;

use pxpl5_config::MachineConfig;
use pxpl5_machine::{
    CHECK_EVERY, Gp, GpFuture, Machine, Message, Monitor, Op, Payload, Program, ProgramError,
    Recorder, RunError, RunOptions, RunResult, Stop, Unit, node_order,
};
use pxpl5_renderer::{Bit, Command, Fidelity, Field, QeeExpr, Rect, Window, cycle_cost};
use pxpl5_ring::{idle_delivery, idle_latency};
use pxpl5_sim::{ClockDomain, Cycles, Tick};
use pxpl5_trace::TraceWindow;
use serde_json::Value;

// ---------------------------------------------------------------------------------------------
// Helpers
// ---------------------------------------------------------------------------------------------

/// A program made of one closure: GP `gp.index()` runs `f(gp)`.
struct FnProgram<F> {
    name: &'static str,
    f: F,
}

impl<F: Fn(Gp) -> GpFuture> Program for FnProgram<F> {
    fn name(&self) -> &str {
        self.name
    }
    fn gp_main(&self, gp: Gp) -> GpFuture {
        (self.f)(gp)
    }
}

fn program<F: Fn(Gp) -> GpFuture>(name: &'static str, f: F) -> FnProgram<F> {
    FnProgram { name, f }
}

/// `machine-configs/minimal.ron`: 1 GP, 1 Renderer, 1 ring channel, seed timings.
fn minimal() -> MachineConfig {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../../machine-configs/minimal.ron"
    );
    pxpl5_config::load_file(std::path::Path::new(path)).expect("minimal.ron loads")
}

/// `minimal` with some counts changed, checked by the config validator.
fn machine(gps: u32, renderers: u32, channels: u32) -> MachineConfig {
    let mut cfg = minimal();
    cfg.gp.count = gps;
    cfg.renderer.count = renderers;
    cfg.ring.channels = channels;
    pxpl5_config::check("test machine", &cfg).expect("test machine is valid");
    cfg
}

fn run_with(
    cfg: &MachineConfig,
    p: &dyn Program,
    fidelity: Fidelity,
    max_time: Tick,
    recorder: Recorder,
) -> Result<RunResult, RunError> {
    let options = RunOptions {
        fidelity,
        max_time,
        threads: 1,
        ..RunOptions::default()
    };
    Machine::new(cfg, p, options, recorder)?.run()
}

fn run(cfg: &MachineConfig, p: &dyn Program) -> Result<RunResult, RunError> {
    run_with(
        cfg,
        p,
        RunOptions::default().fidelity,
        RunOptions::default().max_time,
        Recorder::new(None, None),
    )
}

fn gp_clock(cfg: &MachineConfig) -> ClockDomain {
    ClockDomain::from_hz(cfg.gp.clock_hz).unwrap()
}

fn ring_clock(cfg: &MachineConfig) -> ClockDomain {
    ClockDomain::from_hz(cfg.ring.channel_clock_hz).unwrap()
}

/// Ring position of a unit.
fn pos(cfg: &MachineConfig, u: Unit) -> u32 {
    node_order(cfg).iter().position(|x| *x == u).unwrap() as u32
}

/// Hops from `a` to `b` in the direction of data flow.
fn hops(cfg: &MachineConfig, a: Unit, b: Unit) -> u32 {
    let n = node_order(cfg).len() as u32;
    (pos(cfg, b) + n - pos(cfg, a)) % n
}

/// The token wait of the ring doc ("idle latency") on a ring where no token has been captured
/// yet: the token of channel `c` stands at node `floor(c * n / C)` at clock 0 and visits node
/// `q` at clocks `hops(start, q) * h + m * n * h`; `w` is the clocks from `eligible` to the first
/// visit of any channel's token to `node` at or after it.
fn fresh_token_wait(cfg: &MachineConfig, node: u32, eligible: u64) -> u64 {
    let n = node_order(cfg).len() as u64;
    let channels = u64::from(cfg.ring.channels);
    let h = u64::from(cfg.ring.hop_latency_cycles);
    let lap = n * h;
    (0..channels)
        .map(|c| {
            let start = c * n / channels;
            let first = (u64::from(node) + n - start) % n * h;
            let visit = if first >= eligible {
                first
            } else {
                first + (eligible - first).div_ceil(lap) * lap
            };
            visit - eligible
        })
        .min()
        .unwrap()
}

fn field(offset: u32, bits: u32) -> Field {
    Field {
        offset,
        bits,
        signed: false,
    }
}

/// The `width x height` pixels at `(x, y)`.
fn rect(x: u32, y: u32, width: u32, height: u32) -> Rect {
    Rect {
        x,
        y,
        width,
        height,
    }
}

/// A readback of `field` over `rect` to GP 0, tagged `tag`.
fn readback_to_gp0(field: Field, rect: Rect, tag: u32) -> Command {
    Command::Readback {
        field,
        rect,
        dest: Unit::Gp(0).encode(),
        tag,
    }
}

fn data(tag: u64, words: u32) -> Payload {
    Payload::Data {
        tag,
        values: vec![tag as f64],
        words,
    }
}

fn chrome_bytes(r: &RunResult) -> Vec<u8> {
    let mut out = Vec::new();
    assert!(r.recorder.write_chrome(&mut out).unwrap());
    out
}

fn vcd_bytes(r: &RunResult) -> Vec<u8> {
    let mut out = Vec::new();
    assert!(r.recorder.write_vcd(&mut out).unwrap());
    out
}

// ---------------------------------------------------------------------------------------------
// 1. Compute only
// ---------------------------------------------------------------------------------------------

#[test]
fn compute_only_takes_exactly_the_cycles_charged() {
    // The seed machine (16 GPs) and the minimal one (1 GP).
    for cfg in [pxpl5_config::default_config(), minimal()] {
        let p = program("compute", |gp| {
            Box::pin(async move {
                gp.compute_cycles(Cycles(1000)).await;
                Ok(())
            })
        });
        let r = run(&cfg, &p).unwrap();
        // 1000 i860 cycles at 40 MHz (25,000 ps each).
        assert_eq!(gp_clock(&cfg).period(), Tick(25_000));
        assert_eq!(r.stats.end, Tick(25_000_000));
        assert_eq!(r.stats.gps.len(), cfg.gp.count as usize);
        for g in &r.stats.gps {
            assert_eq!(g.busy, Cycles(1000), "GP {}", g.gp);
            assert_eq!(g.idle, Cycles(0), "GP {}", g.gp);
            assert_eq!(g.finished, Tick(25_000_000));
            assert_eq!((g.messages_sent, g.messages_received), (0, 0));
        }
        for rs in &r.stats.renderers {
            // The Renderers (also 40 MHz) idled the whole run.
            assert_eq!(
                (rs.busy, rs.idle, rs.commands),
                (Cycles(0), Cycles(1000), 0)
            );
        }
        let j = r.stats.to_json();
        assert_eq!(j["simulated_ps"], 25_000_000);
        assert_eq!(j["gps"][0]["busy_percent"], 100.0);
        // 25 us of a 20 MHz channel clock; no traffic.
        assert_eq!(j["ring"]["elapsed_clocks"], 500);
        assert_eq!(j["ring"]["messages"], 0);
        assert_eq!(j["ring"]["token_wait_clocks"], 0);
        assert_eq!(j["frame_buffer_pixel_writes"], 0);
    }
}

#[test]
fn compute_op_is_priced_by_the_cost_table() {
    let cfg = machine(2, 1, 1);
    let p = program("ops", |gp| {
        Box::pin(async move {
            if gp.index() == 0 {
                gp.compute(Op::VertexTransform, 10).await; // 10 * 24
            } else {
                gp.compute(Op::PolygonSetup, 3).await; // 3 * 100
                gp.compute(Op::ClipTest, 0).await; // free, no wait
            }
            Ok(())
        })
    });
    let r = run(&cfg, &p).unwrap();
    assert_eq!(r.stats.gps[0].busy, Cycles(240));
    assert_eq!(r.stats.gps[0].finished, Tick(240 * 25_000));
    assert_eq!(r.stats.gps[1].busy, Cycles(300));
    assert_eq!(r.stats.gps[0].idle, Cycles(60));
    assert_eq!(r.stats.end, Tick(300 * 25_000));
}

// ---------------------------------------------------------------------------------------------
// 2. One message GP -> GP on an idle ring
// ---------------------------------------------------------------------------------------------

/// GP `from` sends one Data message of `words` words at time 0; GP `to` waits for it from time
/// 0. Returns the message, the receiver's time after `recv`, and the run.
fn one_message(cfg: &MachineConfig, from: u32, to: u32, words: u32) -> (Message, Tick, RunResult) {
    let got: Rc<RefCell<Option<(Message, Tick)>>> = Rc::default();
    let g2 = got.clone();
    let p = program("one-message", move |gp| {
        let got = g2.clone();
        Box::pin(async move {
            if gp.index() == from {
                gp.send(Unit::Gp(to), data(42, words)).await;
            } else if gp.index() == to {
                let m = gp.recv().await;
                *got.borrow_mut() = Some((m, gp.now()));
            }
            Ok(())
        })
    });
    let r = run(cfg, &p).unwrap();
    let (m, t) = got.borrow_mut().take().expect("received");
    (m, t, r)
}

#[test]
fn one_message_arrives_at_send_cost_plus_idle_ring_latency_plus_receive_cost() {
    let mut checked = 0;
    for channels in [1, 4] {
        for hop in [1, 3] {
            let mut cfg = machine(2, 1, channels);
            cfg.ring.hop_latency_cycles = hop;
            // Interleaved: GP 0, Renderer 0, GP 1, frame buffer, host.
            assert_eq!(
                node_order(&cfg),
                vec![
                    Unit::Gp(0),
                    Unit::Renderer(0),
                    Unit::Gp(1),
                    Unit::FrameBuffer,
                    Unit::Host
                ]
            );
            for (from, to) in [(0, 1), (1, 0)] {
                for words in [1, 100, 1024] {
                    let (m, received, r) = one_message(&cfg, from, to, words);
                    let (gc, rc) = (gp_clock(&cfg), ring_clock(&cfg));
                    let costs = &cfg.gp.costs;
                    // The sender is busy for message_send, then the ring takes the message.
                    let sent = gc.to_ticks(Cycles(costs.message_send));
                    assert_eq!(sent, Tick(1_250_000));
                    let eligible = rc.cycles_ceil(sent).0;
                    assert_eq!(eligible, 25);
                    let k = hops(&cfg, Unit::Gp(from), Unit::Gp(to));
                    let w = fresh_token_wait(&cfg, pos(&cfg, Unit::Gp(from)), eligible);
                    let delivered = idle_delivery(&cfg.ring, rc, sent, words, k, Cycles(w));
                    // Spelled out: next edge + (w + header + payload + k*h) clocks.
                    assert_eq!(
                        delivered,
                        rc.to_ticks(
                            Cycles(eligible) + idle_latency(&cfg.ring, words, k, Cycles(w))
                        )
                    );
                    assert_eq!(
                        delivered.0,
                        (eligible + w + 1 + u64::from(words) + u64::from(k * hop)) * 50_000
                    );
                    let ctx = format!("{channels} ch, hop {hop}, GP {from} -> GP {to}, {words} w");
                    assert_eq!(m.at, delivered, "{ctx}");
                    assert_eq!(m.from, Unit::Gp(from), "{ctx}");
                    assert_eq!(m.payload, data(42, words), "{ctx}");
                    let expect_rx = delivered + gc.to_ticks(Cycles(costs.message_receive));
                    assert_eq!(received, expect_rx, "{ctx}");
                    // The receiver finishing is the end of the run.
                    assert_eq!(r.stats.end, expect_rx, "{ctx}");
                    let s = &r.stats;
                    assert_eq!(s.gps[from as usize].busy, Cycles(costs.message_send));
                    assert_eq!(s.gps[from as usize].finished, sent);
                    assert_eq!(s.gps[from as usize].messages_sent, 1);
                    assert_eq!(s.gps[to as usize].busy, Cycles(costs.message_receive));
                    assert_eq!(s.gps[to as usize].messages_received, 1);
                    let j = s.to_json();
                    assert_eq!(j["ring"]["token_wait_clocks"], w, "{ctx}");
                    assert_eq!(j["ring"]["payload_words"], words);
                    assert_eq!(j["ring"]["header_words"], 1);
                    assert_eq!(j["ring"]["messages"], 1);
                    checked += 1;
                }
            }
        }
    }
    assert_eq!(checked, 24);

    // Golden values of one case, decomposed: 1 channel, hop 1, GP 1 (node 2) -> GP 0 (node 0),
    // 100 words. Sent at 50 i860 cycles = 1.25 us = ring edge 25. The token starts at node 0 at
    // clock 0 and visits node 2 at 2, 7, ..., 27: w = 2. Hops 2 -> 0 on 5 nodes: 3. Delivered
    // at edge 25 + 2 + 1 + 100 + 3 = 131 = 6.55 us; received after 50 more i860 cycles: 7.8 us.
    let cfg = machine(2, 1, 1);
    let (m, received, r) = one_message(&cfg, 1, 0, 100);
    assert_eq!(m.at, Tick(6_550_000));
    assert_eq!(received, Tick(7_800_000));
    assert_eq!(r.stats.to_json()["ring"]["token_wait_clocks"], 2);
}

// ---------------------------------------------------------------------------------------------
// 3. Renderer commands and a readback
// ---------------------------------------------------------------------------------------------

#[test]
fn renderer_busy_is_the_sum_of_cycle_costs_and_readback_returns_the_values_written() {
    let cfg = minimal();
    let writes = vec![
        Command::WriteConst {
            dst: field(0, 8),
            value: 0xFF,
        },
        // Overwrites the first: commands run in order.
        Command::WriteConst {
            dst: field(0, 8),
            value: 0x11,
        },
        Command::WriteConst {
            dst: field(8, 8),
            value: 0x22,
        },
        Command::WriteConst {
            dst: field(16, 8),
            value: 0x33,
        },
        Command::WriteConst {
            dst: field(24, 8),
            value: 0x44,
        },
        Command::WriteConst {
            dst: field(40, 16),
            value: 0xBEEF,
        },
    ];
    let rect = rect(3, 5, 4, 2);
    let readback_cmd = readback_to_gp0(field(0, 32), rect, 7);
    let got: Rc<RefCell<Option<(Message, Tick)>>> = Rc::default();
    let (w2, rb2, got2) = (writes.clone(), readback_cmd.clone(), got.clone());
    let p = program("readback", move |gp| {
        let (writes, rb, got) = (w2.clone(), rb2.clone(), got2.clone());
        Box::pin(async move {
            gp.send_commands(0, writes).await;
            gp.send_commands(0, vec![rb]).await;
            let m = gp.recv().await;
            *got.borrow_mut() = Some((m, gp.now()));
            Ok(())
        })
    });
    let r = run(&cfg, &p).unwrap();

    // Busy cycles: the cycle table, command by command.
    let all: Vec<Command> = writes.iter().cloned().chain([readback_cmd]).collect();
    let sum: u64 = all.iter().map(|c| cycle_cost(c, &cfg.renderer).0).sum();
    // igc_overhead 20 + bits * per_bit: five 8-bit writes (28), one 16-bit write (36), and the
    // readback of 32 bits (20 + 32 * readback_per_bit = 52).
    assert_eq!(sum, 5 * 28 + 36 + 52);
    let rs = &r.stats.renderers[0];
    assert_eq!(rs.busy, Cycles(sum));
    assert_eq!(rs.commands, 7);
    assert_eq!(rs.board.busy, Cycles(sum));
    assert_eq!(rs.board.by_kind["write_const"].count, 6);
    assert_eq!(rs.board.by_kind["write_const"].cycles, 176);
    assert_eq!(rs.board.by_kind["readback"].cycles, 52);
    let j = r.stats.to_json();
    assert_eq!(j["renderers"][0]["busy_cycles"], 228);
    assert_eq!(j["renderers"][0]["by_kind"]["readback"]["count"], 1);

    // The values: every pixel's bits 0..32 are 0x44_33_22_11.
    let (m, received) = got.borrow_mut().take().unwrap();
    assert_eq!(m.from, Unit::Renderer(0));
    let Payload::Pixels {
        tag,
        rect: got_rect,
        bits,
        values,
    } = m.payload
    else {
        panic!("expected pixels, got {:?}", m.payload);
    };
    assert_eq!((tag, got_rect, bits), (7, rect, 32));
    // 32-bit values, a ring word each: the timing below carries 8 words and a header.
    assert_eq!(values, vec![0x4433_2211; 8]);

    // Golden timing (minimal: nodes GP 0, Renderer 0, frame buffer, host, so a lap is 4 clocks
    // of 50 ns; one channel whose token starts at node 0; i860 and Renderer clocks 25 ns):
    // - GP 0 encodes 6 commands (6 x 4 cycles) and pays message_send (50): 74 cycles = 1.85 us
    //   = ring edge 37. The token visits node 0 at 36, 40: w = 3; 6 x 2 words + 1 header, 1 hop:
    //   delivered at 40 + 13 + 1 = 54 (2.7 us = Renderer cycle 108). The writes run 108..284.
    // - The token, released at 53, passes node 0 at 57, 61, 65. The readback (encode 4 + send
    //   50 cycles, ready at 3.2 us = edge 64) starts at 65 (w = 1), 3 words, arrives at 69
    //   (3.45 us) but waits for the writes: it runs 284..336 (8.4 us = edge 168).
    // - Renderer 0 (node 1) sends the 8 pixel words back: the token, released at 68, passes
    //   node 1 at 69 + 4m, so 169 (w = 1); 9 words, 3 hops: delivered at 181 = 9.05 us. GP 0
    //   has waited since 3.2 us; receiving costs 50 cycles: it is done at 10.3 us.
    assert_eq!(m.at, Tick(9_050_000));
    assert_eq!(received, m.at + Tick(50 * 25_000));
    assert_eq!(received, Tick(10_300_000));
    assert_eq!(r.stats.end, received);
    assert_eq!(j["ring"]["token_wait_clocks"], 3 + 1 + 1);
    assert_eq!(r.stats.gps[0].busy, Cycles(24 + 50 + 4 + 50 + 50));
    // 10.3 us = 412 Renderer cycles, 228 of them busy.
    assert_eq!(rs.idle, Cycles(412 - 228));
    assert_eq!(r.stats.frame_writes, 0);
}

// ---------------------------------------------------------------------------------------------
// 4. Ring contention
// ---------------------------------------------------------------------------------------------

/// GP 0 and GP 1 each send a 1,000-word message to GP 2 at time 0; GP 2 records the arrivals.
fn two_senders(channels: u32) -> (Vec<Message>, RunResult, MachineConfig) {
    let cfg = machine(3, 1, channels);
    let got: Rc<RefCell<Vec<Message>>> = Rc::default();
    let g2 = got.clone();
    let p = program("contention", move |gp| {
        let got = g2.clone();
        Box::pin(async move {
            match gp.index() {
                0 | 1 => {
                    gp.send(Unit::Gp(2), data(u64::from(gp.index()), 1000))
                        .await
                }
                _ => {
                    for _ in 0..2 {
                        let m = gp.recv().await;
                        got.borrow_mut().push(m);
                    }
                }
            }
            Ok(())
        })
    });
    let r = run(&cfg, &p).unwrap();
    let got = got.borrow().clone();
    (got, r, cfg)
}

#[test]
fn one_channel_serialises_two_long_messages_and_four_channels_overlap_them() {
    let ps = |clocks: u64| Tick(clocks * 50_000);
    // Both messages: 1 header + 1,000 payload words = 1,001 clocks on a channel.
    let transmission = ps(1001);

    // One channel. Nodes: GP 0, Renderer 0, GP 1, GP 2, frame buffer, host (6, lap 6 clocks).
    // Both sends are eligible at edge 25 (1.25 us). The token (from node 0 at clock 0) reaches
    // node 2 (GP 1) first, at 26: GP 1 starts at 26 (w 1), its last word is sent at 1027 and
    // arrives one hop on at 1028. The token, released at 1027, reaches node 0 at 1031: GP 0
    // starts there (w 1031 - 25 = 1006) and its message arrives 3 hops on at 2032 + 3 = 2035.
    let (got, r, cfg) = two_senders(1);
    assert_eq!(
        node_order(&cfg)[..4],
        [Unit::Gp(0), Unit::Renderer(0), Unit::Gp(1), Unit::Gp(2)]
    );
    assert_eq!(got[0].from, Unit::Gp(1));
    assert_eq!(got[1].from, Unit::Gp(0));
    assert!(got[1].at >= got[0].at + transmission);
    assert_eq!((got[0].at, got[1].at), (ps(1028), ps(2035)));
    let j = r.stats.to_json();
    let ring = &j["ring"];
    assert_eq!(ring["token_wait_clocks"], 1007);
    assert_eq!(ring["nodes"][0]["token_wait_clocks"], 1006);
    assert_eq!(ring["nodes"][2]["token_wait_clocks"], 1);
    assert!(ring["token_wait_clocks"].as_u64().unwrap() > 0);
    // GP 2 receives the second at 2035 clocks = 101.75 us and is done 1.25 us later: 103 us =
    // 2,060 clocks, of which the one channel was busy 2,002.
    assert_eq!(r.stats.end, Tick(103_000_000));
    assert_eq!(ring["elapsed_clocks"], 2060);
    assert_eq!(ring["channels"][0]["busy_clocks"], 2002);
    assert_eq!(ring["channels"][0]["utilisation_percent"], 97.18);

    // Four channels: tokens start at nodes 0, 1, 3, 4. At 25 channel 1's token stands at node 2
    // (1 + 4 * 6): GP 1 starts at once (w 0), arrives at 25 + 1001 + 1 = 1027; at 26 channel 3's
    // stands at node 0 (4 + 22): GP 0 starts (w 1), arrives at 26 + 1001 + 3 = 1030.
    let (got, r, _) = two_senders(4);
    assert_eq!(got[0].from, Unit::Gp(1));
    assert_eq!(got[1].from, Unit::Gp(0));
    assert!(
        got[1].at < got[0].at + transmission,
        "the transmissions overlap"
    );
    assert!(
        got[1].at - got[0].at <= ps(6),
        "within one lap of each other"
    );
    assert_eq!((got[0].at, got[1].at), (ps(1027), ps(1030)));
    let j = r.stats.to_json();
    let ring = &j["ring"];
    assert_eq!(ring["token_wait_clocks"], 1);
    // GP 2: first received at 51.35 + 1.25 = 52.6 us, second (already there) at 53.85 us.
    assert_eq!(r.stats.end, Tick(53_850_000));
    assert_eq!(ring["elapsed_clocks"], 1077);
    let busy: Vec<u64> = (0..4)
        .map(|c| ring["channels"][c]["busy_clocks"].as_u64().unwrap())
        .collect();
    assert_eq!(busy, vec![0, 1001, 0, 1001]);
    assert_eq!(ring["channels"][1]["utilisation_percent"], 92.94);
    assert_eq!(ring["channels"][3]["utilisation_percent"], 92.94);
}

// ---------------------------------------------------------------------------------------------
// 5-7. Run errors
// ---------------------------------------------------------------------------------------------

#[test]
fn waiting_for_a_message_nobody_sends_is_a_deadlock() {
    let p = program("deadlock", |gp| {
        Box::pin(async move {
            gp.compute_cycles(Cycles(100)).await;
            gp.recv().await;
            Ok(())
        })
    });
    let err = run(&minimal(), &p).err().expect("deadlock");
    let text = err.to_string();
    let RunError::Deadlock { at, waiting } = err else {
        panic!("expected a deadlock, got {text}");
    };
    // 100 i860 cycles, then the wait.
    assert_eq!(at, Tick(2_500_000));
    assert!(waiting.contains("GP 0"), "{waiting}");
    assert!(waiting.contains("waits for a message"), "{waiting}");
    assert!(text.starts_with("deadlock at 2500000 ps"), "{text}");
}

#[test]
fn computing_forever_hits_the_time_limit() {
    let one_ms = Tick(1_000_000_000);
    // Steps of 25 ms: the first wake-up already lies beyond 1 ms.
    let p = program("forever", |gp| {
        Box::pin(async move {
            loop {
                gp.compute_cycles(Cycles(1_000_000)).await;
            }
        })
    });
    let r = run_with(
        &minimal(),
        &p,
        Fidelity::Integer,
        one_ms,
        Recorder::new(None, None),
    );
    let Err(RunError::TimeLimit { limit, running }) = r else {
        panic!("expected a time limit");
    };
    assert_eq!(limit, one_ms);
    assert!(running.contains("GP 0: computing"), "{running}");

    // Steps of 25 us: 40 complete by 1 ms exactly (an event at the limit still runs), the 41st
    // would end beyond it.
    let steps: Rc<RefCell<u64>> = Rc::default();
    let s2 = steps.clone();
    let p = program("forever-small", move |gp| {
        let steps = s2.clone();
        Box::pin(async move {
            loop {
                gp.compute_cycles(Cycles(1000)).await;
                *steps.borrow_mut() += 1;
            }
        })
    });
    let r = run_with(
        &minimal(),
        &p,
        Fidelity::Integer,
        one_ms,
        Recorder::new(None, None),
    );
    assert!(matches!(r, Err(RunError::TimeLimit { limit, .. }) if limit == one_ms));
    assert_eq!(*steps.borrow(), 40);
}

/// A program computing forever in steps of 1,000 GP cycles (25 us on the minimal machine), one
/// instant each, counting its steps in `steps`.
fn forever_in_steps(steps: Rc<RefCell<u64>>) -> impl Program {
    program("forever-steps", move |gp| {
        let steps = steps.clone();
        Box::pin(async move {
            loop {
                gp.compute_cycles(Cycles(1000)).await;
                *steps.borrow_mut() += 1;
            }
        })
    })
}

/// A run of `forever_in_steps` with a stop asked before it starts, recorded (a VCD) or not: the
/// error's time and report, the steps taken, and the time the monitor was told.
fn stopped_now(recorded: bool) -> (Tick, String, u64, Tick) {
    let steps: Rc<RefCell<u64>> = Rc::default();
    let monitor = Arc::new(Monitor::default());
    monitor.request(Stop::Now);
    let options = RunOptions {
        monitor: Some(monitor.clone()),
        threads: 1,
        // 1,000 s: ahead of the loop, a GP covers more time an instant than the default 10 s
        // allow in CHECK_EVERY instants.
        max_time: Tick(1_000_000_000_000_000),
        ..RunOptions::default()
    };
    let p = forever_in_steps(steps.clone());
    let vcd = recorded.then(|| TraceWindow::parse("0..").unwrap());
    let r = Machine::new(&minimal(), &p, options, Recorder::new(None, vcd))
        .expect("builds")
        .run();
    let Err(RunError::Stopped { at, running }) = r else {
        panic!("expected a stop");
    };
    let taken = *steps.borrow();
    (at, running, taken, monitor.reached())
}

#[test]
fn a_stop_asked_now_ends_the_run_at_the_next_look_with_where_it_was() {
    // Recorded, the GP computes piece by piece, an instant each. The loop looks at its monitor
    // on its CHECK_EVERY-th instant, after the GPs acted: the instants were 0, 25 us, ...,
    // (CHECK_EVERY - 1) x 25 us, each but the first ending a step.
    let (at, running, steps, reached) = stopped_now(true);
    assert_eq!(at, Tick((CHECK_EVERY - 1) * 25_000_000));
    assert_eq!(steps, CHECK_EVERY - 1);
    assert_eq!(reached, at);
    assert!(running.contains("GP 0: computing"), "{running}");
    // Not recorded, the GP runs ahead through many pieces an instant (`gp_node`): the same look
    // comes later in simulated time, on a 25 us step, with every step up to it taken.
    let (quiet_at, running, steps, reached) = stopped_now(false);
    assert!(quiet_at > at, "{quiet_at}");
    assert_eq!(quiet_at.0 % 25_000_000, 0);
    assert!(
        steps >= quiet_at.0 / 25_000_000,
        "{steps} steps by {quiet_at}"
    );
    assert_eq!(reached, quiet_at);
    assert!(running.contains("GP 0: computing"), "{running}");
}

#[test]
fn a_monitor_changes_nothing_in_a_run_not_stopped_now() {
    let cfg = machine(2, 2, 2);
    let p = program("pingpong", |gp| {
        Box::pin(async move {
            for k in 0..3000u32 {
                gp.compute_cycles(Cycles(7 + u64::from(k % 5))).await;
                let other = 1 - gp.index();
                gp.send(Unit::Gp(other), data(u64::from(k), 2)).await;
                gp.recv().await;
            }
            Ok(())
        })
    });
    let plain = run(&cfg, &p).expect("runs");
    let monitor = Arc::new(Monitor::default());
    // A program that does not look at its monitor runs on when asked to stop soon.
    monitor.request(Stop::Soon);
    let options = RunOptions {
        monitor: Some(monitor.clone()),
        threads: 1,
        ..RunOptions::default()
    };
    let watched = Machine::new(&cfg, &p, options, Recorder::new(None, None))
        .expect("builds")
        .run()
        .expect("runs");
    assert_eq!(
        watched.stats.to_json().to_string(),
        plain.stats.to_json().to_string()
    );
    assert_eq!(monitor.reached(), plain.stats.end);
    assert!(plain.stats.end > Tick(0));
}

#[test]
fn a_program_error_names_its_gp() {
    let cfg = machine(2, 1, 1);
    let p = program("boom", |gp| {
        Box::pin(async move {
            gp.compute_cycles(Cycles(10)).await;
            if gp.index() == 1 {
                gp.compute_cycles(Cycles(10)).await;
                return Err(ProgramError("boom".into()));
            }
            Ok(())
        })
    });
    let err = run(&cfg, &p).err().expect("program error");
    assert_eq!(err.to_string(), "program error on GP 1: boom");
    assert!(matches!(err, RunError::Program { gp: 1, ref message } if message == "boom"));
}

// ---------------------------------------------------------------------------------------------
// A board's commands back to back
// ---------------------------------------------------------------------------------------------

/// A run of `p` with nothing recorded (a board then runs the commands of a message back to back,
/// without an instant of the loop each) and with a VCD recorded (every completion at its
/// instant of the loop): what each gave, as the text of its error or of its stats, and the
/// instants the loop stepped through.
fn quiet_and_recorded(cfg: &MachineConfig, p: &dyn Program, max_time: Tick) -> [(String, u64); 2] {
    [None, Some(TraceWindow::parse("0..").unwrap())].map(|vcd| {
        match run_with(
            cfg,
            p,
            Fidelity::Integer,
            max_time,
            Recorder::new(None, vcd),
        ) {
            Ok(r) => (r.stats.to_json().to_string(), r.host.instants),
            Err(e) => (e.to_string(), 0),
        }
    })
}

/// Eight messages of six commands each, to two boards, with a readback to GP 0 in the middle of
/// each board's stream.
fn back_to_back_program() -> impl Program {
    program("back-to-back", |gp| {
        Box::pin(async move {
            if gp.index() != 0 {
                return Ok(());
            }
            for m in 0..8u32 {
                let commands = (0..6u32)
                    .map(|k| Command::WriteConst {
                        dst: field(8 * (k % 4), 8 + 8 * (m % 2)),
                        value: u64::from(m * 6 + k),
                    })
                    .collect();
                gp.send_commands(m % 2, commands).await;
                if m == 3 || m == 4 {
                    let readback = readback_to_gp0(field(0, 16), rect(0, 0, 4, 1), m);
                    gp.send_commands(m % 2, vec![readback]).await;
                    gp.recv().await;
                }
            }
            Ok(())
        })
    })
}

/// [`quiet_and_recorded`] with the default time limit, for a run that must give the same stats
/// both ways: the stats, and the instants of the loop the quiet run did without.
fn quiet_as_recorded(cfg: &MachineConfig, p: &dyn Program) -> (String, u64) {
    let max_time = RunOptions::default().max_time;
    let [(quiet, quiet_instants), (recorded, recorded_instants)] =
        quiet_and_recorded(cfg, p, max_time);
    assert_eq!(quiet, recorded);
    (quiet, recorded_instants - quiet_instants)
}

#[test]
fn a_board_runs_a_messages_commands_back_to_back_with_the_same_stats() {
    let (quiet, saved) = quiet_as_recorded(&machine(1, 2, 2), &back_to_back_program());
    assert!(quiet.contains("\"commands\":25"), "{quiet}");
    // Each message's first five completions need no instant of the loop: up to 40 fewer (fewer
    // when another unit acts at the same instant; 38 here). Nor does the end of GP 0's
    // computing before each of its 10 sends (`GpNode::take_up_at`): 10 fewer.
    assert!((40..=50).contains(&saved), "{saved} instants saved");
}

/// GP 1 sends GP 0 six messages; GP 0 computes until they are all in its mailbox, then takes
/// them one by one, each after a piece of computing (half of them with a phase marked), and
/// answers GP 1 after computing.
fn receives_after_computing_program() -> impl Program {
    program("receives-after-computing", |gp| {
        Box::pin(async move {
            let data = |tag| Payload::Data {
                tag,
                values: vec![tag as f64],
                words: 2,
            };
            match gp.index() {
                0 => {
                    gp.phase("wait");
                    gp.compute_cycles(Cycles(20_000)).await;
                    for k in 0..6u64 {
                        gp.compute_cycles(Cycles(300 + 50 * k)).await;
                        if k % 2 == 1 {
                            gp.phase(if k == 3 { "odd" } else { "receive" });
                        }
                        let m = gp.recv().await;
                        assert!(matches!(m.payload, Payload::Data { tag, .. } if tag == k));
                    }
                    gp.compute_cycles(Cycles(700)).await;
                    gp.send(Unit::Gp(1), data(99)).await;
                }
                _ => {
                    for k in 0..6u64 {
                        gp.compute_cycles(Cycles(100)).await;
                        gp.send(Unit::Gp(0), data(k)).await;
                    }
                    gp.recv().await;
                }
            }
            Ok(())
        })
    })
}

#[test]
fn a_receive_or_send_after_computing_is_taken_up_at_once_with_the_same_stats() {
    // Not recorded, a GP's send after computing, and its receive after computing of a message
    // already in its mailbox, start their costs at the computing's end without an instant of
    // the loop there (`GpNode::take_up_at`); a receive after a phase mark keeps that instant.
    // The stats (phases and critical path included) are those of the recorded run, which
    // takes every step at its instant.
    let p = receives_after_computing_program();
    let (quiet, saved) = quiet_as_recorded(&machine(2, 1, 1), &p);
    assert!(quiet.contains("\"messages_received\":6"), "{quiet}");
    for phase in ["wait", "receive", "odd"] {
        assert!(quiet.contains(&format!("\"{phase}\"")), "{phase}: {quiet}");
    }
    // GP 0: three receives without a mark and the answer; GP 1: five of its six sends (its
    // first computing starts the run, the instant the program starts at) and its receive
    // waits for a message.
    assert!((8..=12).contains(&saved), "{saved} instants saved");
}

#[test]
fn a_time_limit_in_a_message_stops_the_run_where_the_loop_would() {
    let cfg = machine(1, 2, 2);
    let p = back_to_back_program();
    let end = run(&cfg, &p).unwrap().stats.end;
    // Limits every 100 ns up to the run's end: each falls somewhere in a board's stream.
    let (mut limited, mut step) = (0, Tick(100_000));
    while step < end {
        let [quiet, recorded] = quiet_and_recorded(&cfg, &p, step);
        assert_eq!(quiet.0, recorded.0, "limit {step}");
        limited += usize::from(quiet.0.contains("commands queued"));
        step += Tick(100_000);
    }
    assert!(limited > 10, "{limited} limits fell in a board's stream");
}

#[test]
fn a_refused_command_in_a_message_fails_the_run_when_the_loop_would() {
    // GP 0 sends a message whose third command names a field beyond pixel memory; GP 1 fails
    // after computing for a while. Whichever comes first in simulated time is the run's error,
    // however far ahead of the loop the board runs.
    let cfg = machine(2, 1, 1);
    let memory = cfg.renderer.pixel_memory_bits;
    let (mut gp_first, mut board_first) = (0, 0);
    for wait in (0..400).step_by(10) {
        let p = program("refused", move |gp| {
            Box::pin(async move {
                if gp.index() == 1 {
                    gp.compute_cycles(Cycles(wait)).await;
                    return Err(ProgramError("late".into()));
                }
                let mut commands = vec![
                    Command::WriteConst {
                        dst: field(0, 32),
                        value: 1,
                    };
                    4
                ];
                commands[2] = Command::WriteConst {
                    dst: field(memory, 8),
                    value: 1,
                };
                gp.send_commands(0, commands).await;
                Ok(())
            })
        });
        let [quiet, recorded] = quiet_and_recorded(&cfg, &p, RunOptions::default().max_time);
        assert_eq!(quiet.0, recorded.0, "GP 1 fails after {wait} cycles");
        if quiet.0.contains("late") {
            gp_first += 1;
        } else {
            assert!(
                quiet.0.contains("rejected command write_const"),
                "{}",
                quiet.0
            );
            board_first += 1;
        }
    }
    assert!(
        gp_first > 0 && board_first > 0,
        "{gp_first} / {board_first}"
    );
}

// ---------------------------------------------------------------------------------------------
// GPs ahead of the loop
// ---------------------------------------------------------------------------------------------

/// GP 1 sends GP 0 eight messages at uneven times; GP 0 computes in small uneven pieces, marks
/// phases now and then, and after every tenth piece looks at its mailbox, receiving what is
/// there. It
/// logs what it sees: the time after each piece and each message taken. With `fail_after`, GP 0
/// fails after that many pieces, and GP 1 after its fourth send.
fn ahead_program(log: Rc<RefCell<AheadLog>>, fail_after: Option<u64>) -> impl Program {
    program("ahead", move |gp| {
        let log = log.clone();
        Box::pin(async move {
            if gp.index() == 1 {
                for k in 0..8u64 {
                    if k == 4 && fail_after.is_some() {
                        return Err(ProgramError("early".into()));
                    }
                    gp.compute_cycles(Cycles(300 + 170 * (k % 3))).await;
                    gp.send(Unit::Gp(0), data(k, 4)).await;
                }
                return Ok(());
            }
            let (mut got, mut piece) = (0, 0u64);
            while got < 8 {
                piece += 1;
                if fail_after == Some(piece) {
                    return Err(ProgramError("late".into()));
                }
                if piece % 7 == 0 {
                    gp.phase(if piece % 2 == 0 { "even" } else { "odd" });
                }
                gp.compute_cycles(Cycles(13 + piece % 5)).await;
                log.borrow_mut().push((piece, gp.now()));
                if piece % 10 == 0 && gp.has_message(|_| true).await {
                    let m = gp.recv().await;
                    let Payload::Data { tag, .. } = m.payload else {
                        panic!("GP 1 sends data");
                    };
                    log.borrow_mut().push((1000 + tag, gp.now()));
                    got += 1;
                }
            }
            Ok(())
        })
    })
}

/// What GP 0 of `ahead_program` saw: each piece's number and the time after it, and each
/// message's tag (plus 1,000) and the time it was taken.
type AheadLog = Vec<(u64, Tick)>;

/// `ahead_program`'s run with nothing recorded (GPs run ahead of the loop) and with a VCD
/// recorded (piece by piece): what it gave (stats or error, as text), what GP 0 logged, and the
/// loop's instants.
fn ahead_runs(fail_after: Option<u64>) -> [(String, AheadLog, u64); 2] {
    [false, true].map(|recorded| {
        let log: Rc<RefCell<AheadLog>> = Rc::default();
        let p = ahead_program(log.clone(), fail_after);
        let vcd = recorded.then(|| TraceWindow::parse("0..").unwrap());
        let r = run_with(
            &machine(2, 1, 1),
            &p,
            Fidelity::Integer,
            RunOptions::default().max_time,
            Recorder::new(None, vcd),
        );
        let (text, instants) = match r {
            Ok(r) => (r.stats.to_json().to_string(), r.host.instants),
            Err(e) => (e.to_string(), 0),
        };
        let seen = log.borrow().clone();
        (text, seen, instants)
    })
}

#[test]
fn a_gp_ahead_of_the_loop_sees_and_does_what_it_would_piece_by_piece() {
    let [
        (quiet, quiet_log, quiet_instants),
        (recorded, recorded_log, recorded_instants),
    ] = ahead_runs(None);
    assert_eq!(quiet, recorded);
    assert_eq!(quiet_log, recorded_log);
    // Both phases were marked, every message taken.
    assert!(
        quiet.contains("\"even\"") && quiet.contains("\"odd\""),
        "{quiet}"
    );
    assert_eq!(quiet_log.iter().filter(|(k, _)| *k >= 1000).count(), 8);
    // Most pieces took no instant of their own.
    let pieces = quiet_log.iter().filter(|(k, _)| *k < 1000).count() as u64;
    assert!(pieces > 100, "{pieces}");
    assert!(
        recorded_instants - quiet_instants > pieces / 2,
        "{quiet_instants} instants of {recorded_instants}, {pieces} pieces"
    );
}

#[test]
fn a_program_error_ahead_of_the_loop_comes_when_it_would() {
    // GP 0 fails after its n-th piece, GP 1 after its fourth send: whichever comes first in
    // simulated time is the run's error, however far ahead of the loop GP 0 is.
    let (mut late, mut early) = (0, 0);
    for n in (1..200).step_by(3) {
        let [(quiet, ..), (recorded, ..)] = ahead_runs(Some(n));
        assert_eq!(quiet, recorded, "GP 0 failing after {n} pieces");
        if quiet.contains("late") {
            late += 1;
        } else {
            assert!(quiet.contains("early"), "{quiet}");
            early += 1;
        }
    }
    assert!(late > 0 && early > 0, "{late} / {early}");
}

// ---------------------------------------------------------------------------------------------
// 8-9. A mixed program: determinism, traces, fidelity
// ---------------------------------------------------------------------------------------------

/// Two GPs, two Renderers: messages both ways, Renderer commands (QEE, arithmetic, readbacks to a
/// GP and to the frame buffer) and phases. Every message received is logged.
struct Mixed {
    log: Rc<RefCell<Vec<(u32, Message, Tick)>>>,
}

const MIXED_A: Field = Field {
    offset: 0,
    bits: 16,
    signed: false,
};
const MIXED_B: Field = Field {
    offset: 16,
    bits: 16,
    signed: false,
};
const MIXED_SUM: Field = Field {
    offset: 32,
    bits: 16,
    signed: false,
};
const MIXED_RGB: Field = Field {
    offset: 48,
    bits: 24,
    signed: false,
};
const MIXED_RECT: Rect = Rect {
    x: 2,
    y: 3,
    width: 8,
    height: 4,
};

impl Program for Mixed {
    fn name(&self) -> &str {
        "mixed"
    }

    fn gp_main(&self, gp: Gp) -> GpFuture {
        let log = self.log.clone();
        Box::pin(async move {
            let me = gp.index();
            let record = |m: Message, now: Tick| log.borrow_mut().push((me, m, now));
            if me == 0 {
                gp.phase("setup");
                gp.compute(Op::VertexTransform, 10).await;
                gp.send(Unit::Gp(1), data(1, 64)).await;
                gp.phase("render");
                // QEE x + 2y (A = 1.0, B = 2.0 in 18 fractional bits), plus a constant.
                let expr = QeeExpr::linear(1 << 18, 2 << 18, 0);
                gp.send_commands(
                    0,
                    vec![
                        Command::SetOrigin { x: 0, y: 0 },
                        Command::enable_all(),
                        Command::WriteConst {
                            dst: MIXED_A,
                            value: 0x1234,
                        },
                        Command::QeeStore {
                            expr,
                            window: Window {
                                shift: 18,
                                bits: 16,
                            },
                            dst: MIXED_B,
                        },
                        Command::Add {
                            dst: MIXED_SUM,
                            a: MIXED_A,
                            b: MIXED_B,
                        },
                        Command::Readback {
                            field: MIXED_SUM,
                            rect: MIXED_RECT,
                            dest: Unit::Gp(0).encode(),
                            tag: 0,
                        },
                    ],
                )
                .await;
                let m = gp.recv().await;
                record(m, gp.now());
                gp.phase("reply");
                let m = gp.recv().await;
                record(m, gp.now());
            } else {
                gp.phase("work");
                let m = gp.recv().await;
                record(m, gp.now());
                gp.compute_cycles(Cycles(500)).await;
                gp.send_commands(
                    1,
                    vec![
                        Command::enable_all(),
                        Command::Logic {
                            dst: Bit::Flag(0),
                            a: Bit::Enable,
                            b: Bit::Enable,
                            op: pxpl5_renderer::LogicOp::A,
                        },
                        Command::WriteConst {
                            dst: MIXED_RGB,
                            value: 0x00FF_8040,
                        },
                        Command::Readback {
                            field: MIXED_RGB,
                            rect: Rect {
                                x: 0,
                                y: 0,
                                width: 16,
                                height: 16,
                            },
                            dest: Unit::FrameBuffer.encode(),
                            tag: 100 | (200 << 16),
                        },
                    ],
                )
                .await;
                gp.send(Unit::Gp(0), data(2, 300)).await;
                gp.phase("tail");
                gp.compute(Op::PolygonSetup, 3).await;
            }
            Ok(())
        })
    }
}

struct MixedRun {
    result: RunResult,
    log: Vec<(u32, Message, Tick)>,
}

fn mixed_cfg() -> MachineConfig {
    machine(2, 2, 2)
}

fn run_mixed(fidelity: Fidelity, chrome: Option<&str>, vcd: Option<&str>) -> MixedRun {
    let p = Mixed { log: Rc::default() };
    let window = |w: Option<&str>| w.map(|w| TraceWindow::parse(w).unwrap());
    let result = run_with(
        &mixed_cfg(),
        &p,
        fidelity,
        RunOptions::default().max_time,
        Recorder::new(window(chrome), window(vcd)),
    )
    .unwrap();
    let log = p.log.borrow().clone();
    MixedRun { result, log }
}

/// The mixed program's results that do not depend on timing details: the readback to GP 0 holds
/// 0x1234 + x + 2y, the frame buffer got 256 pixels of (0x40, 0x80, 0xFF).
fn check_mixed_values(m: &MixedRun) {
    assert_eq!(m.log.len(), 3);
    let (gp, ref msg, _) = m.log[0];
    assert_eq!((gp, msg.from), (1, Unit::Gp(0)));
    assert_eq!(msg.payload, data(1, 64));
    let (gp, ref msg, _) = m.log[1];
    assert_eq!((gp, msg.from), (0, Unit::Renderer(0)));
    let Payload::Pixels {
        rect, bits, values, ..
    } = &msg.payload
    else {
        panic!("expected pixels");
    };
    assert_eq!((*rect, *bits), (MIXED_RECT, 16));
    let r = MIXED_RECT;
    let expected: Vec<u64> = (r.y..r.y + r.height)
        .flat_map(|y| (r.x..r.x + r.width).map(move |x| u64::from(0x1234 + x + 2 * y)))
        .collect();
    assert_eq!(*values, expected);
    let (gp, ref msg, _) = m.log[2];
    assert_eq!((gp, msg.from), (0, Unit::Gp(1)));
    assert_eq!(msg.payload, data(2, 300));

    let f = &m.result.frame;
    assert_eq!(f.writes, 256);
    // Screen (100, 200) is array pixel (0, 0); frame rows count from the top.
    let i = ((f.height - 1 - 200) * f.width + 100) as usize * 3;
    assert_eq!(&f.rgb[i..i + 3], &[0x40, 0x80, 0xFF]);
    assert_eq!(f.rgb.iter().filter(|&&b| b != 0).count(), 256 * 3);
}

/// Minimal structural VCD check: header, declared ids, increasing timestamps, known value ids.
fn check_vcd(text: &str, end: Tick) {
    assert!(text.contains("$timescale 1 ps $end"), "{text}");
    let (head, body) = text
        .split_once("$enddefinitions $end")
        .expect("definitions");
    let mut ids = BTreeSet::new();
    let mut names = Vec::new();
    for line in head.lines().filter(|l| l.trim_start().starts_with("$var")) {
        let t: Vec<&str> = line.split_whitespace().collect();
        // $var wire WIDTH ID NAME [range] $end, or a string variable (the token's position)
        assert!(t[1] == "wire" || t[1] == "string", "{line}");
        ids.insert(t[3].to_string());
        names.push(t[4].to_string());
    }
    for want in ["gp0_busy", "gp1_busy", "renderer0_busy", "renderer1_busy"] {
        assert!(names.iter().any(|n| n == want), "no {want} in {names:?}");
    }
    assert!(names.iter().any(|n| n == "ch1_token_at"));
    // The token's position reads as node names, listed in the header.
    assert!(
        head.contains("ring order (node: unit), the values of chN_token_at: 0 GP 0, "),
        "{head}"
    );
    assert!(
        body.contains("sGP_0 ") || body.contains("sRenderer_0 "),
        "token at a named node"
    );
    let mut last: Option<u64> = None;
    let mut changes = 0;
    for line in body.lines().map(str::trim).filter(|l| !l.is_empty()) {
        if let Some(t) = line.strip_prefix('#') {
            let t: u64 = t.parse().expect("timestamp");
            assert!(last.is_none_or(|l| t > l), "timestamps increase: {line}");
            last = Some(t);
        } else if let Some(rest) = line.strip_prefix('s') {
            let (text, id) = rest.split_once(' ').expect("string change");
            assert!(
                text == "-" || text.contains('_') || text == "host",
                "{line}"
            );
            assert!(ids.contains(id), "{line}");
            changes += 1;
        } else if line.starts_with('$') {
            assert!(["$dumpvars", "$end"].contains(&line), "{line}");
        } else if let Some(rest) = line.strip_prefix('b') {
            let (bits, id) = rest.split_once(' ').expect("vector change");
            assert!(bits.bytes().all(|b| b == b'0' || b == b'1'), "{line}");
            assert!(ids.contains(id), "{line}");
            changes += 1;
        } else {
            let (v, id) = line.split_at(1);
            assert!(v == "0" || v == "1", "{line}");
            assert!(ids.contains(id), "{line}");
            changes += 1;
        }
    }
    assert!(changes > ids.len(), "some changes after the initial values");
    assert_eq!(last, Some(end.0), "the dump ends at the run's end");
}

fn trace_events(bytes: &[u8]) -> Vec<Value> {
    let v: Value = serde_json::from_slice(bytes).expect("Chrome trace is JSON");
    v["traceEvents"]
        .as_array()
        .expect("traceEvents array")
        .clone()
}

/// On every (pid, tid) track, slices are disjoint or nested (what Perfetto needs to draw them).
/// Times are compared in whole picoseconds (exact: a few hundred microseconds of six-decimal
/// timestamps are far inside an f64's 53 bits).
fn check_slices_nest(events: &[Value]) {
    let ps = |v: &Value| -> u64 { (v.as_f64().unwrap() * 1e6).round() as u64 };
    let mut tracks: std::collections::BTreeMap<(u64, u64), Vec<(u64, u64)>> = Default::default();
    for e in events.iter().filter(|e| e["ph"] == "X") {
        let key = (e["pid"].as_u64().unwrap(), e["tid"].as_u64().unwrap());
        let start = ps(&e["ts"]);
        tracks
            .entry(key)
            .or_default()
            .push((start, start + ps(&e["dur"])));
    }
    for (track, mut slices) in tracks {
        slices.sort_by_key(|&(s, e)| (s, std::cmp::Reverse(e)));
        let mut open: Vec<u64> = Vec::new();
        for (s, e) in slices {
            while open.last().is_some_and(|&end| end <= s) {
                open.pop();
            }
            if let Some(&end) = open.last() {
                assert!(
                    e <= end,
                    "track {track:?}: [{s}, {e}) overlaps a slice ending {end}"
                );
            }
            open.push(e);
        }
    }
}

#[test]
fn mixed_program_is_deterministic_with_traces_and_traces_are_well_formed() {
    let a = run_mixed(Fidelity::Integer, Some("0.."), Some("0.."));
    let b = run_mixed(Fidelity::Integer, Some("0.."), Some("0.."));
    check_mixed_values(&a);
    assert_eq!(
        a.result.stats.to_json().to_string(),
        b.result.stats.to_json().to_string()
    );
    assert_eq!(a.log, b.log);
    let (ca, cb) = (chrome_bytes(&a.result), chrome_bytes(&b.result));
    assert_eq!(ca, cb);
    let (va, vb) = (vcd_bytes(&a.result), vcd_bytes(&b.result));
    assert_eq!(va, vb);
    // Recording changes nothing simulated.
    let quiet = run_mixed(Fidelity::Integer, None, None);
    assert_eq!(
        a.result.stats.to_json().to_string(),
        quiet.result.stats.to_json().to_string()
    );
    let end = a.result.stats.end;
    assert!(end > Tick(10_000_000), "the run outlasts the 10 us window");

    // Chrome: slices for every GP phase and every Renderer command kind.
    let events = trace_events(&ca);
    let slices: BTreeSet<&str> = events
        .iter()
        .filter(|e| e["ph"] == "X")
        .map(|e| e["name"].as_str().unwrap())
        .collect();
    for name in [
        "setup",
        "render",
        "reply",
        "work",
        "tail",
        "compute",
        "message send",
        "message receive",
        "set_origin",
        "qee_store",
        "add",
        "logic",
        "write_const",
        "readback",
        "GP 0 -> GP 1",
        "Renderer 1 -> frame buffer",
    ] {
        assert!(slices.contains(name), "no slice {name:?} in {slices:?}");
    }
    check_slices_nest(&events);
    // Phase spans in the stats agree with the trace's phase slices.
    let phases: Vec<&str> = a
        .result
        .stats
        .phases
        .iter()
        .map(|p| p.name.as_str())
        .collect();
    assert_eq!(phases, ["setup", "render", "reply", "work", "tail"]);

    // A window keeps only what starts in it: a smaller trace whose events lie before 10 us.
    let w = run_mixed(Fidelity::Integer, Some("0..10us"), Some("0..10us"));
    assert_eq!(
        w.result.stats.to_json().to_string(),
        a.result.stats.to_json().to_string()
    );
    let cw = chrome_bytes(&w.result);
    assert!(cw.len() < ca.len());
    let wevents = trace_events(&cw);
    assert!(wevents.len() < events.len());
    let mut timed = 0;
    for e in &wevents {
        if let Some(ts) = e.get("ts") {
            let ts = ts.as_f64().unwrap();
            assert!(ts < 10.0, "event at {ts} us outside the window: {e}");
            if let Some(d) = e.get("dur") {
                assert!(ts + d.as_f64().unwrap() <= 10.0 + 1e-9, "{e}");
            }
            timed += 1;
        }
    }
    assert!(timed > 0);
    check_slices_nest(&wevents);

    // VCD: well formed, whole run and windowed.
    check_vcd(std::str::from_utf8(&va).unwrap(), end);
    let vw = vcd_bytes(&w.result);
    let vw = std::str::from_utf8(&vw).unwrap();
    assert!(vw.contains("$enddefinitions"));
    assert!(vw.len() < va.len());
    for line in vw.lines() {
        if let Some(t) = line.strip_prefix('#') {
            assert!(t.parse::<u64>().unwrap() <= 10_000_000, "{line}");
        }
    }
}

/// A track of a Chrome trace: (pid, tid).
type TrackKey = (u64, u64);
/// A slice read back: start and end in ps, name, args.
type ReadSlice = (u64, u64, String, Value);
/// A flow event read back: phase, track, ps.
type FlowEvent = (String, TrackKey, u64);

/// A Chrome trace read back: track names, slices per track, flow events per flow id.
struct TraceIndex {
    /// (pid, tid) -> (process name, thread name).
    tracks: std::collections::BTreeMap<(u64, u64), (String, String)>,
    /// (pid, tid) -> slices as (start ps, end ps, name, args), instants included (length 0).
    slices: std::collections::BTreeMap<TrackKey, Vec<ReadSlice>>,
    /// Flow id -> (phase, (pid, tid), ps), in file order (which is time order).
    flows: std::collections::BTreeMap<u64, Vec<FlowEvent>>,
}

impl TraceIndex {
    fn new(events: &[Value]) -> TraceIndex {
        let ps = |v: &Value| -> u64 { (v.as_f64().unwrap() * 1e6).round() as u64 };
        let key = |e: &Value| (e["pid"].as_u64().unwrap(), e["tid"].as_u64().unwrap_or(0));
        let mut process = std::collections::BTreeMap::new();
        let mut tracks = std::collections::BTreeMap::new();
        let mut slices: std::collections::BTreeMap<_, Vec<_>> = Default::default();
        let mut flows: std::collections::BTreeMap<_, Vec<_>> = Default::default();
        for e in events {
            let name = e["name"].as_str().unwrap_or_default().to_owned();
            match e["ph"].as_str().unwrap() {
                "M" if name == "process_name" => {
                    process.insert(e["pid"].as_u64().unwrap(), e["args"]["name"].clone());
                }
                "M" if name == "thread_name" => {
                    let p = process[&e["pid"].as_u64().unwrap()].as_str().unwrap();
                    let t = e["args"]["name"].as_str().unwrap();
                    tracks.insert(key(e), (p.to_owned(), t.to_owned()));
                }
                "X" | "i" => {
                    let start = ps(&e["ts"]);
                    let end = start + e.get("dur").map_or(0, ps);
                    slices
                        .entry(key(e))
                        .or_default()
                        .push((start, end, name, e["args"].clone()));
                }
                ph @ ("s" | "t" | "f") => {
                    assert_eq!(e["bp"], "e", "flows bind to the enclosing slice: {e}");
                    flows.entry(e["id"].as_u64().unwrap()).or_default().push((
                        ph.to_owned(),
                        key(e),
                        ps(&e["ts"]),
                    ));
                }
                _ => {}
            }
        }
        TraceIndex {
            tracks,
            slices,
            flows,
        }
    }

    /// The slice a flow event at `at` on `track` binds to: the innermost one enclosing it.
    fn bound(&self, track: TrackKey, at: u64) -> Option<&ReadSlice> {
        self.slices
            .get(&track)?
            .iter()
            .filter(|(s, e, ..)| *s <= at && at < *e)
            .min_by_key(|(s, e, ..)| e - s)
    }

    /// Flow `id`'s path: per event, (phase, "process/thread", bound slice's name).
    fn path(&self, id: u64) -> Vec<(String, String, String)> {
        self.flows[&id]
            .iter()
            .map(|(ph, track, at)| {
                let (p, t) = &self.tracks[track];
                let slice = self
                    .bound(*track, *at)
                    .unwrap_or_else(|| panic!("flow {id} {ph} at {at} ps on {p}/{t}: no slice"));
                (ph.clone(), format!("{p}/{t}"), slice.2.clone())
            })
            .collect()
    }
}

#[test]
fn every_message_is_a_flow_from_its_sender_through_the_ring_to_its_receiver() {
    let run = run_mixed(Fidelity::Integer, Some("0.."), None);
    let index = TraceIndex::new(&trace_events(&chrome_bytes(&run.result)));
    // One flow per message the ring carried, each a chain s, t..., f bound to slices.
    let messages: Vec<(u64, &String, &Value)> = index
        .slices
        .iter()
        .filter(|(track, _)| index.tracks[track].0.starts_with("Ring channel"))
        .flat_map(|(_, slices)| {
            slices
                .iter()
                .map(|(_, _, name, args)| (args["id"].as_u64().unwrap(), name, args))
        })
        .collect();
    assert!(messages.len() >= 5, "{}", messages.len());
    assert_eq!(index.flows.len(), messages.len());
    for (id, name, _) in &messages {
        let path = index.path(*id);
        let phases: Vec<&str> = path.iter().map(|(ph, ..)| ph.as_str()).collect();
        assert_eq!(phases.first(), Some(&"s"), "{name}: {path:?}");
        assert_eq!(phases.last(), Some(&"f"), "{name}: {path:?}");
        assert!(
            phases[1..phases.len() - 1].iter().all(|&p| p == "t"),
            "{path:?}"
        );
        // The ring step is the message's own slice.
        assert!(
            path.iter().any(|(_, _, slice)| slice == *name),
            "{name}: {path:?}"
        );
    }

    // The readback: GP 0's command message runs on Renderer 0, whose readback command sends
    // the reply that GP 0 receives.
    let (reply, _, args) = messages
        .iter()
        .find(|(_, name, _)| name.as_str() == "Renderer 0 -> GP 0")
        .expect("the readback reply");
    let asked = args["answers"]
        .as_u64()
        .expect("the reply names its request");
    let request = index.path(asked);
    assert_eq!(request[0].1, "GPs/GP 0");
    assert_eq!(request[0].2, "message send");
    assert!(
        request[1].1.starts_with("Ring channel 0/lane "),
        "{request:?}"
    );
    assert_eq!(request[1].2, "GP 0 -> Renderer 0");
    assert!(
        request[2..]
            .iter()
            .all(|(_, track, _)| track == "Renderers/Renderer 0")
    );
    assert!(
        request.iter().any(|(_, _, slice)| slice == "readback"),
        "{request:?}"
    );
    let answer = index.path(*reply);
    assert_eq!(
        answer
            .iter()
            .map(|(ph, track, slice)| (ph.as_str(), track.as_str(), slice.as_str()))
            .collect::<Vec<_>>(),
        [
            ("s", "Renderers/Renderer 0", "readback"),
            ("t", answer[1].1.as_str(), "Renderer 0 -> GP 0"),
            ("f", "GPs/GP 0", "message receive"),
        ]
    );
    // The reply leaves from the very point the request's flow passes on the readback command.
    let start = index.flows[reply][0].clone();
    assert!(
        index.flows[&asked]
            .iter()
            .any(|(_, track, at)| (*track, *at) == (start.1, start.2))
    );
}

#[test]
fn ring_lanes_are_named_by_channel_and_counters_by_what_they_count() {
    // Two channels: each message sits on the lanes of the channels that carried it.
    let run = run_mixed(Fidelity::Integer, Some("0.."), None);
    let events = trace_events(&chrome_bytes(&run.result));
    let index = TraceIndex::new(&events);
    let mut used = BTreeSet::new();
    for (track, slices) in &index.slices {
        let (process, thread) = &index.tracks[track];
        let Some(ch) = process.strip_prefix("Ring channel ") else {
            continue;
        };
        assert!(thread.starts_with("lane "), "{thread}");
        for (start, end, name, args) in slices {
            assert!(name.contains(" -> "), "{name}");
            assert_eq!(args["channels"].as_str(), Some(ch), "{name} on {process}");
            assert!(end >= start);
            assert!(args["hops"].as_u64().unwrap() >= 1);
            assert!(args["token_wait_ps"].as_u64().unwrap() <= end - start);
            used.insert(ch.to_owned());
        }
    }
    assert!(!used.is_empty());
    // No zero-length slice: those are instants.
    assert!(
        events
            .iter()
            .filter(|e| e["ph"] == "X")
            .all(|e| e["dur"].as_f64().unwrap() > 0.0)
    );
    // Counters: per channel whether its token is held, per node its queues.
    let pids: std::collections::BTreeMap<u64, &str> = events
        .iter()
        .filter(|e| e["ph"] == "M" && e["name"] == "process_name")
        .map(|e| {
            (
                e["pid"].as_u64().unwrap(),
                e["args"]["name"].as_str().unwrap(),
            )
        })
        .collect();
    let counters: BTreeSet<(&str, &str)> = events
        .iter()
        .filter(|e| e["ph"] == "C")
        .map(|e| {
            (
                pids[&e["pid"].as_u64().unwrap()],
                e["name"].as_str().unwrap(),
            )
        })
        .collect();
    for want in [
        ("Ring channel 0", "token held"),
        ("Ring channel 1", "token held"),
        ("Ring queues", "GP 0 output words"),
        ("Ring queues", "GP 1 input words"),
        ("Ring queues", "Renderer 0 input words"),
    ] {
        assert!(
            counters.contains(&want),
            "no counter {want:?} in {counters:?}"
        );
    }
}

#[test]
fn mixed_program_gives_the_same_stats_at_bit_and_integer_fidelity() {
    let bit = run_mixed(Fidelity::Bit, None, None);
    let integer = run_mixed(Fidelity::Integer, None, None);
    check_mixed_values(&bit);
    check_mixed_values(&integer);
    let (mut jb, mut ji) = (bit.result.stats.to_json(), integer.result.stats.to_json());
    assert_eq!(jb["fidelity"], "bit");
    assert_eq!(ji["fidelity"], "integer");
    jb.as_object_mut().unwrap().remove("fidelity");
    ji.as_object_mut().unwrap().remove("fidelity");
    assert_eq!(jb.to_string(), ji.to_string());
    assert_eq!(bit.log, integer.log);
    assert_eq!(bit.result.frame, integer.result.frame);
}

// ---------------------------------------------------------------------------------------------
// 10. Message ordering
// ---------------------------------------------------------------------------------------------

#[test]
fn messages_between_two_gps_arrive_in_send_order_on_four_channels() {
    let sizes: [u32; 20] = [
        1, 1500, 2, 1024, 1025, 7, 300, 1499, 3, 800, 1, 64, 1200, 5, 1023, 999, 2, 1500, 17, 512,
    ];
    let cfg = machine(2, 1, 4);
    let got: Rc<RefCell<Vec<Message>>> = Rc::default();
    let g2 = got.clone();
    let p = program("order", move |gp| {
        let got = g2.clone();
        Box::pin(async move {
            if gp.index() == 0 {
                for (i, &w) in sizes.iter().enumerate() {
                    gp.send(Unit::Gp(1), data(i as u64, w)).await;
                }
            } else {
                for _ in 0..sizes.len() {
                    let m = gp.recv().await;
                    got.borrow_mut().push(m);
                }
            }
            Ok(())
        })
    });
    let r = run(&cfg, &p).unwrap();
    let got = got.borrow();
    assert_eq!(got.len(), 20);
    for (i, m) in got.iter().enumerate() {
        assert_eq!(m.from, Unit::Gp(0));
        assert_eq!(m.payload, data(i as u64, sizes[i]), "message {i}");
    }
    let j = r.stats.to_json();
    let total: u64 = sizes.iter().map(|&w| u64::from(w)).sum();
    assert_eq!(j["ring"]["payload_words"], total);
    assert_eq!(j["ring"]["messages"], 20);
    // Messages over 1,024 words (1500, 1025, 1499, 1200, 1500) travel as two packets.
    assert_eq!(j["ring"]["header_words"], 20 + 5);
    assert_eq!(r.stats.gps[1].messages_received, 20);
    // On four channels a short message overtakes a long one on the ring; the machine holds it
    // back so that the program still sees send order (Message::at keeps the ring's arrival).
    let overtaken = got.windows(2).filter(|w| w[1].at < w[0].at).count();
    assert!(overtaken > 0, "the ring reordered some messages");
}

// ---------------------------------------------------------------------------------------------
// Regressions
// ---------------------------------------------------------------------------------------------

/// Zero-cycle costs are valid config values: an event due at the current instant runs then
/// (this used to stop the run with "machine made no progress").
#[test]
fn zero_cycle_costs_run() {
    let mut cfg = machine(2, 1, 1);
    cfg.gp.costs.message_send = 0;
    cfg.gp.costs.message_receive = 0;
    cfg.renderer.cycles.igc_overhead = 0;
    let p = program("zero", |gp| {
        Box::pin(async move {
            if gp.index() == 0 {
                gp.compute_cycles(Cycles(10)).await;
                gp.send(Unit::Gp(1), data(1, 4)).await;
                gp.send_commands(0, vec![pxpl5_renderer::Command::Fence])
                    .await;
            } else {
                gp.compute_cycles(Cycles(1000)).await;
                let m = gp.recv().await;
                assert_eq!(m.from, Unit::Gp(0));
            }
            Ok(())
        })
    });
    let r = run(&cfg, &p).expect("runs");
    assert_eq!(r.stats.end, Tick(1000 * 25_000));
}

/// A message to a unit the machine does not have names the sender and the destination.
#[test]
fn a_message_to_a_missing_unit_names_both_ends() {
    let cfg = machine(2, 1, 1);
    let p = program("nowhere", |gp| {
        Box::pin(async move {
            if gp.index() == 1 {
                gp.send(Unit::Gp(7), data(0, 1)).await;
            }
            Ok(())
        })
    });
    let err = run(&cfg, &p).err().expect("an error");
    assert_eq!(
        err.to_string(),
        "GP 1 sent a message to GP 7, which this machine does not have"
    );
}

/// A config that skipped validation with a zero clock is refused when the machine is built, naming
/// the field: no clock of 0 Hz is ever taken for another frequency.
#[test]
fn a_zero_clock_is_refused_not_hidden() {
    let p = program("idle", |_gp| Box::pin(async move { Ok(()) }));
    for (field, set) in [
        (
            "gp.clock_hz",
            (|c: &mut MachineConfig| c.gp.clock_hz = 0) as fn(&mut MachineConfig),
        ),
        ("renderer.clock_hz", |c| c.renderer.clock_hz = 0),
        ("ring.channel_clock_hz", |c| c.ring.channel_clock_hz = 0),
    ] {
        let mut cfg = minimal();
        set(&mut cfg);
        let err = run(&cfg, &p).err().expect("a zero clock is an error");
        assert!(
            matches!(err, RunError::Config(ref m) if m.contains(field)),
            "{field}: {err}"
        );
    }
}
