//! Tests of `VcdTrace`: the file parses back with the `vcd` crate's parser and holds the right
//! values at the right times; output is deterministic; the window folds and drops changes.

use pxpl5_sim::Tick;
use pxpl5_tests::SharedBytes;
use pxpl5_trace::{TraceWindow, VcdTrace, WidthError};
use vcd::{Command, IdCode, ScopeItem, TimescaleUnit, Value};

/// What a parsed VCD says: the header's (scope, wire, width, id) in order, and every value
/// written as (time, id, value as a number), `$dumpvars` included.
struct Parsed {
    timescale: Option<(u32, TimescaleUnit)>,
    wires: Vec<(String, String, u32, IdCode)>,
    values: Vec<(u64, IdCode, u64)>,
    /// Every timestamp, in file order.
    times: Vec<u64>,
}

fn parse(trace: &VcdTrace) -> Parsed {
    let text = trace.to_string();
    let mut parser = vcd::Parser::new(text.as_bytes());
    let header = parser
        .parse_header()
        .unwrap_or_else(|e| panic!("bad header ({e}):\n{text}"));
    let mut wires = Vec::new();
    for item in &header.items {
        let ScopeItem::Scope(scope) = item else {
            continue;
        };
        for item in &scope.items {
            if let ScopeItem::Var(var) = item {
                wires.push((
                    scope.identifier.clone(),
                    var.reference.clone(),
                    var.size,
                    var.code,
                ));
            }
        }
    }
    let bits = |v: &mut dyn Iterator<Item = Value>| {
        v.fold(0u64, |acc, b| {
            (acc << 1)
                | match b {
                    Value::V0 => 0,
                    Value::V1 => 1,
                    other => panic!("unexpected value {other:?}"),
                }
        })
    };
    let mut now = None;
    let mut values = Vec::new();
    let mut times = Vec::new();
    for command in parser {
        match command.unwrap_or_else(|e| panic!("bad body ({e}):\n{text}")) {
            Command::Timestamp(t) => {
                now = Some(t);
                times.push(t);
            }
            Command::ChangeScalar(id, v) => {
                values.push((now.expect("a time first"), id, bits(&mut [v].into_iter())))
            }
            Command::ChangeVector(id, v) => {
                values.push((now.expect("a time first"), id, bits(&mut v.iter())))
            }
            Command::Begin(_) | Command::End(_) => {}
            other => panic!("unexpected command {other:?}"),
        }
    }
    Parsed {
        timescale: header.timescale,
        wires,
        values,
        times,
    }
}

#[test]
fn whole_output_of_a_small_trace() {
    let mut t = VcdTrace::default();
    let gp = t.scope("GP 0");
    let busy = t.wire(gp, "busy", 1);
    let state = t.wire(gp, "state", 4);
    let ring = t.scope("ring");
    let token = t.wire(ring, "token holder", 8);
    t.change(busy, Tick(25_000), 1);
    t.change(state, Tick(25_000), 9);
    t.change(token, Tick(50_000), 0xa5);
    t.change(busy, Tick(75_000), 0);
    t.set_end(Tick(100_000));
    let expected = "\
$version
    pxpl5-trace
$end
$comment
    timestamps are simulated time in picoseconds, not host time
$end
$timescale 1 ps $end
$scope module GP_0 $end
$var wire 1 ! busy $end
$var wire 4 \" state [3:0] $end
$upscope $end
$scope module ring $end
$var wire 8 # token_holder [7:0] $end
$upscope $end
$enddefinitions $end
#0
$dumpvars
0!
b0000 \"
b00000000 #
$end
#25000
1!
b1001 \"
#50000
b10100101 #
#75000
0!
#100000
";
    assert_eq!(t.to_string(), expected);
    let mut bytes = Vec::new();
    t.write(&mut bytes).unwrap();
    assert_eq!(bytes, expected.as_bytes());
}

#[test]
fn parses_back_with_the_right_changes() {
    let mut t = VcdTrace::default();
    let gp = t.scope("GPs");
    let busy = t.wire(gp, "busy", 1);
    let count = t.wire(gp, "count", 64);
    let ring = t.scope("Ring");
    let ch = t.wire(ring, "channel 2", 3);
    t.change(busy, Tick(0), 1);
    t.change(busy, Tick(25_000), 0);
    t.change(count, Tick(25_000), u64::MAX);
    t.change(ch, Tick(50_000), 5);
    t.change(count, Tick(1_000_000_000_000), 42);
    // Wider than the wire: the high bits are dropped.
    t.change(ch, Tick(75_000), 0b1110);

    let p = parse(&t);
    assert_eq!(p.timescale, Some((1, TimescaleUnit::PS)));
    let ids: Vec<IdCode> = p.wires.iter().map(|w| w.3).collect();
    assert_eq!(
        p.wires
            .iter()
            .map(|(s, n, w, _)| (s.as_str(), n.as_str(), *w))
            .collect::<Vec<_>>(),
        vec![
            ("GPs", "busy", 1),
            ("GPs", "count", 64),
            ("Ring", "channel_2", 3)
        ]
    );
    let (b, c, r) = (ids[0], ids[1], ids[2]);
    assert_eq!(
        p.values,
        vec![
            // Initial values; the change at time 0 is folded in.
            (0, b, 1),
            (0, c, 0),
            (0, r, 0),
            (25_000, b, 0),
            (25_000, c, u64::MAX),
            (50_000, r, 5),
            (75_000, r, 0b110),
            (1_000_000_000_000, c, 42),
        ]
    );
}

#[test]
fn recording_order_does_not_matter() {
    let changes: Vec<(usize, u64, u64)> = vec![
        (0, 10, 1),
        (1, 10, 3),
        (0, 20, 0),
        (2, 15, 1),
        (1, 30, 2),
        (0, 30, 1),
        (2, 40, 0),
    ];
    let build = |order: &[usize]| {
        let mut t = VcdTrace::new("5ps..".parse().unwrap());
        let s = t.scope("top");
        let wires = [t.wire(s, "a", 1), t.wire(s, "b", 2), t.wire(s, "c", 1)];
        for &i in order {
            let (w, at, v) = changes[i];
            t.change(wires[w], Tick(at), v);
        }
        t.to_string()
    };
    let forward = build(&[0, 1, 2, 3, 4, 5, 6]);
    assert_eq!(build(&[0, 1, 2, 3, 4, 5, 6]), forward);
    assert_eq!(build(&[6, 5, 4, 3, 2, 1, 0]), forward);
    assert_eq!(build(&[3, 6, 0, 5, 2, 4, 1]), forward);
}

#[test]
fn one_instant_keeps_the_last_value_and_repeats_are_not_written() {
    let mut t = VcdTrace::default();
    let s = t.scope("top");
    let a = t.wire(s, "a", 4);
    let b = t.wire(s, "b", 1);
    t.change(a, Tick(10), 1);
    t.change(a, Tick(10), 7);
    t.change(a, Tick(20), 7); // no change
    t.change(a, Tick(30), 2);
    t.change(a, Tick(30), 7); // back to what it was: nothing to write
    t.change(b, Tick(30), 0); // already 0
    t.change(b, Tick(40), 1);
    let p = parse(&t);
    let (ia, ib) = (p.wires[0].3, p.wires[1].3);
    assert_eq!(
        p.values,
        vec![(0, ia, 0), (0, ib, 0), (10, ia, 7), (40, ib, 1)]
    );
    // No timestamp without a change under it.
    assert_eq!(p.times, vec![0, 10, 40]);
}

#[test]
fn window_folds_early_changes_and_drops_late_ones() {
    let mut t = VcdTrace::new("1us..2us".parse().unwrap());
    let s = t.scope("top");
    let a = t.wire(s, "a", 8);
    let b = t.wire(s, "b", 1);
    let c = t.wire(s, "c", 1);
    // Out of order: the latest change before the start is the initial value.
    t.change(a, Tick(900_000), 9);
    t.change(a, Tick(100_000), 3);
    t.change(b, Tick(500_000), 1);
    // A change exactly at the start is the initial value too.
    t.change(c, Tick(500_000), 1);
    t.change(c, Tick(1_000_000), 0);
    t.change(a, Tick(1_500_000), 4);
    t.change(b, Tick(2_000_000), 0); // at the end: outside
    t.change(a, Tick(5_000_000), 5);
    t.set_end(Tick(9_000_000));
    let p = parse(&t);
    let ids: Vec<IdCode> = p.wires.iter().map(|w| w.3).collect();
    assert_eq!(
        p.values,
        vec![
            (1_000_000, ids[0], 9),
            (1_000_000, ids[1], 1),
            (1_000_000, ids[2], 0),
            (1_500_000, ids[0], 4),
        ]
    );
    // The end of the run is clipped to the window end.
    assert_eq!(p.times, vec![1_000_000, 1_500_000, 2_000_000]);
    let text = t.to_string();
    assert!(
        text.contains("$comment\n    trace window 1us..2us\n$end"),
        "{text}"
    );
    assert_eq!(t.window(), "1us..2us".parse::<TraceWindow>().unwrap());
}

#[test]
fn equal_changes_at_one_instant_before_the_window_keep_the_last_recorded() {
    let mut t = VcdTrace::new("1ns..".parse().unwrap());
    let s = t.scope("top");
    let a = t.wire(s, "a", 4);
    t.change(a, Tick(10), 1);
    t.change(a, Tick(10), 2);
    let p = parse(&t);
    assert_eq!(p.values, vec![(1_000, p.wires[0].3, 2)]);
}

#[test]
fn end_before_the_last_change_adds_no_timestamp() {
    let mut t = VcdTrace::default();
    let s = t.scope("top");
    let a = t.wire(s, "a", 1);
    t.change(a, Tick(50), 1);
    t.set_end(Tick(50));
    assert_eq!(parse(&t).times, vec![0, 50]);
    t.set_end(Tick(10));
    assert_eq!(parse(&t).times, vec![0, 50]);
    t.set_end(Tick(60));
    assert_eq!(parse(&t).times, vec![0, 50, 60]);
}

#[test]
fn many_wires_get_distinct_valid_identifiers() {
    let mut t = VcdTrace::default();
    let scopes: Vec<_> = (0..10).map(|i| t.scope(&format!("node {i}"))).collect();
    let mut wires = Vec::new();
    for i in 0..500u64 {
        let w = t.wire(scopes[(i % 10) as usize], &format!("w{i}"), 16);
        t.change(w, Tick(i + 1), i);
        wires.push(w);
    }
    // Scopes are reused by name.
    assert_eq!(t.scope("node 3"), scopes[3]);
    let p = parse(&t);
    assert_eq!(p.wires.len(), 500);
    let mut ids: Vec<IdCode> = p.wires.iter().map(|w| w.3).collect();
    ids.sort();
    ids.dedup();
    assert_eq!(ids.len(), 500);
    // Wire i changed to i at time i + 1 (wire 0's change to 0 is no change).
    let by_name: std::collections::HashMap<IdCode, u64> = p
        .wires
        .iter()
        .map(|(_, name, _, id)| (*id, name[1..].parse::<u64>().unwrap()))
        .collect();
    let changes: Vec<(u64, u64)> = p
        .values
        .iter()
        .filter(|(time, _, _)| *time > 0)
        .map(|(time, id, v)| {
            assert_eq!(by_name[id], *v);
            (*time, *v)
        })
        .collect();
    assert_eq!(changes.len(), 499);
    assert!(changes.iter().all(|&(time, v)| time == v + 1));
}

#[test]
fn empty_trace_is_valid() {
    let t = VcdTrace::default();
    let p = parse(&t);
    assert!(p.wires.is_empty());
    assert_eq!(p.times, vec![0]);
}

#[test]
fn a_width_outside_1_to_64_is_an_error() {
    let mut t = VcdTrace::default();
    let s = t.scope("top");
    for width in [0, 65] {
        let e = t.try_wire(s, "nothing", width).unwrap_err();
        assert_eq!(
            e,
            WidthError {
                name: "nothing".to_string(),
                width,
            }
        );
        assert_eq!(
            e.to_string(),
            format!("VCD wire `nothing` has width {width}; expected 1 to 64 bits")
        );
    }
    // Nothing was added: the trace is still empty.
    assert!(parse(&t).wires.is_empty());
    assert!(t.try_wire(s, "one", 1).is_ok() && t.try_wire(s, "wide", 64).is_ok());
}

#[test]
fn text_variables_carry_names_and_comments_explain_them() {
    let mut t = VcdTrace::default();
    t.comment("ring order: 0 GP 0, 1 Renderer 0");
    let ring = t.scope("ring");
    let at = t.text(ring, "ch0_token_at", "-");
    let held = t.wire(ring, "ch0_busy", 1);
    t.change_text(at, Tick(10), "GP 0");
    t.change(held, Tick(10), 1);
    t.change_text(at, Tick(20), "Renderer 0");
    // The same text again is no change.
    t.change_text(at, Tick(30), "Renderer 0");
    t.change_text(at, Tick(40), "GP 0");
    let text = t.to_string();
    assert!(
        text.contains("$comment\n    ring order: 0 GP 0, 1 Renderer 0\n$end"),
        "{text}"
    );
    let mut parser = vcd::Parser::new(text.as_bytes());
    let header = parser.parse_header().unwrap();
    let Some(scope) = header.items.iter().find_map(|item| match item {
        ScopeItem::Scope(scope) => Some(scope),
        _ => None,
    }) else {
        panic!("no scope: {text}");
    };
    let ScopeItem::Var(var) = &scope.items[0] else {
        panic!("a variable: {text}");
    };
    assert_eq!(var.var_type, vcd::VarType::String);
    assert_eq!(var.reference, "ch0_token_at");
    let mut now = 0;
    let mut texts = Vec::new();
    for command in parser {
        match command.unwrap() {
            Command::Timestamp(t) => now = t,
            Command::ChangeString(id, v) if id == var.code => texts.push((now, v)),
            _ => {}
        }
    }
    let want = [(0, "-"), (10, "GP_0"), (20, "Renderer_0"), (40, "GP_0")];
    let want: Vec<(u64, String)> = want.iter().map(|&(t, v)| (t, v.to_owned())).collect();
    assert_eq!(texts, want);
}

/// A streamed trace writes the bytes an in-memory one does, for changes recorded out of order
/// (ahead of the settled instant, several to one wire at one instant, some repeating the value)
/// over several flushes, in each kind of window; and it holds no more than a batch and what was
/// recorded ahead.
#[test]
fn a_streamed_trace_writes_the_bytes_of_one_held_in_memory() {
    let windows = ["1us..2us", "5ps..", "0..300ns"].map(|w| w.parse().unwrap());
    for window in [TraceWindow::all()].into_iter().chain(windows) {
        let out = SharedBytes::default();
        let mut held = VcdTrace::new(window);
        let mut streamed = VcdTrace::streamed(window, Box::new(out.clone()));
        let mut wires = Vec::new();
        for t in [&mut held, &mut streamed] {
            t.comment("legend");
            let scope = t.scope("units");
            let mut w = vec![t.wire(scope, "busy", 1), t.wire(scope, "count", 8)];
            w.push(t.wire(scope, "wide", 64));
            w.push(t.text(scope, "at", "-"));
            wires = w;
        }
        let texts: Vec<_> = ["GP 0", "Renderer 1", "-"]
            .iter()
            .map(|x| (held.text_value(x), streamed.text_value(x)))
            .collect();
        let mut next = pxpl5_tests::xorshift(0x0005_EED0_F0DD_0BB5_u64);
        let (mut now, mut most) = (0u64, 0usize);
        for _ in 0..3 * VcdTrace::FLUSH_AT {
            now += next() % 3;
            streamed.settle(Tick(now));
            let r = next();
            // Half of them at the settled instant itself, the edge a flush must not cross.
            let at = Tick(now + if r & 1 == 0 { 0 } else { (r >> 8) % 40 });
            let k = (r % 4) as usize;
            // A quarter of them through a sample of the instant (the path of a recorder's
            // per-instant samples): the same changes. Values up to 299 are masked by the
            // narrow wires.
            let sampled = (r >> 40).is_multiple_of(4);
            if k == 3 {
                let (a, b) = texts[(r >> 20) as usize % texts.len()];
                if sampled {
                    held.sample(at).change_to(wires[k], a);
                    streamed.sample(at).change_to(wires[k], b);
                } else {
                    held.change_to(wires[k], at, a);
                    streamed.change_to(wires[k], at, b);
                }
            } else {
                let value = (r >> 32) % 300;
                if sampled {
                    held.sample(at).change(wires[k], value);
                    streamed.sample(at).change(wires[k], value);
                } else {
                    held.change(wires[k], at, value);
                    streamed.change(wires[k], at, value);
                }
            }
            most = most.max(streamed.held_changes());
        }
        held.set_end(Tick(now + 100));
        streamed.set_end(Tick(now + 100));
        streamed.finish().expect("writes to memory");
        assert!(
            most <= VcdTrace::FLUSH_AT + 100,
            "{most} changes held at once in {window}"
        );
        let bytes = out.bytes();
        streamed.finish().expect("a second finish writes nothing");
        assert_eq!(out.bytes(), bytes, "a second finish wrote more");
        assert_eq!(
            String::from_utf8(bytes).unwrap(),
            held.to_string(),
            "window {window}"
        );
    }
}

/// A change before the settled instant would be written out of order: a bug of the recorder,
/// which `finish` reports instead of writing a file out of order.
#[test]
fn a_streamed_change_before_the_settled_instant_is_an_error() {
    let out = SharedBytes::default();
    let mut t = VcdTrace::streamed(TraceWindow::all(), Box::new(out.clone()));
    let scope = t.scope("s");
    let w = t.wire(scope, "w", 1);
    t.settle(Tick(100));
    t.change(w, Tick(99), 1);
    let err = t.finish().expect_err("out of order");
    assert!(
        err.to_string().contains("recorded after time settled at"),
        "{err}"
    );
}

/// A streamed trace's write error comes back from `finish`.
#[test]
fn a_streamed_write_error_is_returned() {
    struct Full;
    impl std::io::Write for Full {
        fn write(&mut self, _: &[u8]) -> std::io::Result<usize> {
            Err(std::io::Error::other("disk full"))
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }
    let mut t = VcdTrace::streamed(TraceWindow::all(), Box::new(Full));
    let scope = t.scope("s");
    let w = t.wire(scope, "w", 1);
    t.change(w, Tick(5), 1);
    let err = t.finish().expect_err("nothing can be written");
    assert!(err.to_string().contains("disk full"), "{err}");
}

/// Spans give the VCD of a change to 1 at each start and to 0 at each end: joined by a streamed
/// trace where one starts as the last ends, plain in a trace held in memory. Spans back to back,
/// after gaps, of no length, at the settled instant and ahead of it, ending past the window,
/// among changes to other wires, over several flushes, in windows that fold changes in and drop
/// them.
#[test]
fn spans_write_the_changes_at_their_starts_and_ends() {
    let windows = ["0..", "300ps..900ps", "1ps..", "50ns.."].map(|w| w.parse().unwrap());
    for window in windows {
        let out = SharedBytes::default();
        let mut held = VcdTrace::new(window);
        let mut plain = VcdTrace::new(window);
        let mut streamed = VcdTrace::streamed(window, Box::new(out.clone()));
        let mut wires = Vec::new();
        for t in [&mut held, &mut plain, &mut streamed] {
            let scope = t.scope("units");
            wires = (0..3).map(|i| t.wire(scope, &format!("u{i}"), 1)).collect();
            wires.push(t.wire(scope, "count", 4));
        }
        let mut next = pxpl5_tests::xorshift(0x00B5_5EED_0000_0001);
        let mut free = [0u64; 3];
        let mut now = 0u64;
        for _ in 0..3 * VcdTrace::FLUSH_AT {
            let r = next();
            now += r % 3;
            streamed.settle(Tick(now));
            let w = (r >> 8) as usize % 4;
            if w == 3 {
                // Another wire, at the settled instant.
                for t in [&mut held, &mut plain, &mut streamed] {
                    t.change(wires[3], Tick(now), r >> 32);
                }
                continue;
            }
            // A unit's next span: at once after its last (most), or after a gap.
            let gap = if (r >> 16) & 3 == 0 { (r >> 20) & 7 } else { 0 };
            let start = free[w].max(now) + gap;
            if start > now + 4 {
                continue;
            }
            let end = start + (r >> 24) % 5;
            held.span(wires[w], Tick(start), Tick(end));
            streamed.span(wires[w], Tick(start), Tick(end));
            plain.change(wires[w], Tick(start), 1);
            plain.change(wires[w], Tick(end), 0);
            free[w] = end;
        }
        for t in [&mut held, &mut plain, &mut streamed] {
            t.set_end(Tick(now + 10));
        }
        streamed.finish().expect("writes to memory");
        let plain = plain.to_string();
        assert!(
            plain.lines().count() > 100,
            "a trace with changes in {window}"
        );
        assert_eq!(held.to_string(), plain, "held, {window}");
        assert_eq!(
            String::from_utf8(out.bytes()).unwrap(),
            plain,
            "streamed, {window}"
        );
    }
}
