//! Tests of `ChromeTrace`: the JSON is valid and exact (timestamps to the picosecond, written
//! without floats), deterministic, windowed, grouped, and nests as Perfetto needs.

use pxpl5_sim::Tick;
use pxpl5_trace::{Args, ChromeTrace, FlowStep, JsonValue, TraceWindow};
use serde_json::{Value, json};

fn parse(trace: &ChromeTrace) -> Value {
    let text = trace.to_string();
    serde_json::from_str(&text).unwrap_or_else(|e| panic!("invalid JSON ({e}):\n{text}"))
}

/// The non-metadata events, as parsed JSON.
fn events(trace: &ChromeTrace) -> Vec<Value> {
    parse(trace)["traceEvents"]
        .as_array()
        .expect("traceEvents is an array")
        .iter()
        .filter(|e| e["ph"] != "M")
        .cloned()
        .collect()
}

/// The lines of the output that are non-metadata events, verbatim.
fn event_lines(trace: &ChromeTrace) -> Vec<String> {
    trace
        .to_string()
        .lines()
        .filter(|l| l.starts_with('{') && !l.contains("\"ph\":\"M\"") && !l.contains("otherData"))
        .map(|l| l.trim_end_matches(',').to_owned())
        .collect()
}

fn window(s: &str) -> TraceWindow {
    s.parse().unwrap()
}

#[test]
fn whole_output_of_a_small_trace() {
    let mut t = ChromeTrace::default();
    t.metadata("config", "seed.ron");
    let gp = t.track("GPs", "GP 0");
    t.slice(
        gp,
        "transform",
        Tick(25_000),
        Tick(75_000),
        [("prims", JsonValue::from(3))],
    );
    t.instant(gp, "sync", Tick(75_000));
    t.counter("Ring", "queue depth", Tick(50_000), -2);
    let expected = r#"{"displayTimeUnit":"ns","otherData":{"time_unit":"1 trace microsecond = 1 simulated microsecond (timestamps are simulated time, not host time)","trace_window":"0..","config":"seed.ron"},"traceEvents":[
{"ph":"M","name":"process_name","pid":1,"args":{"name":"GPs"}},
{"ph":"M","name":"process_sort_index","pid":1,"args":{"sort_index":0}},
{"ph":"M","name":"process_name","pid":3,"args":{"name":"Ring"}},
{"ph":"M","name":"process_sort_index","pid":3,"args":{"sort_index":1}},
{"ph":"M","name":"thread_name","pid":1,"tid":2,"args":{"name":"GP 0"}},
{"ph":"M","name":"thread_sort_index","pid":1,"tid":2,"args":{"sort_index":0}},
{"ph":"X","name":"transform","pid":1,"tid":2,"ts":0.025000,"dur":0.050000,"args":{"prims":3}},
{"ph":"C","name":"queue depth","pid":3,"ts":0.050000,"args":{"value":-2}},
{"ph":"i","s":"t","name":"sync","pid":1,"tid":2,"ts":0.075000}
]}
"#;
    assert_eq!(t.to_string(), expected);
    let mut bytes = Vec::new();
    t.write(&mut bytes).unwrap();
    assert_eq!(bytes, expected.as_bytes());
}

#[test]
fn parses_as_json_with_metadata() {
    let mut t = ChromeTrace::new(window("0..2ms"));
    t.metadata("frames", 3);
    t.metadata("config", JsonValue::object([("gps", 8)]));
    // Reserved keys stay the builder's.
    t.metadata("time_unit", "host seconds");
    t.metadata("trace_window", "everything");
    let gp0 = t.track("GPs", "GP 0");
    let gp1 = t.track("GPs", "GP 1");
    let ch2 = t.track("Ring", "channel 2");
    t.slice(gp1, "a", Tick(0), Tick(1), Args::new());
    t.slice(gp0, "b", Tick(0), Tick(1), Args::new());
    t.slice(ch2, "c", Tick(0), Tick(1), Args::new());

    let json = parse(&t);
    assert_eq!(json["displayTimeUnit"], "ns");
    let other = &json["otherData"];
    assert_eq!(
        other["time_unit"],
        "1 trace microsecond = 1 simulated microsecond (timestamps are simulated time, not host time)"
    );
    assert_eq!(other["trace_window"], "0..2ms");
    assert_eq!(other["frames"], 3);
    assert_eq!(other["config"], json!({"gps": 8}));
    // Caller keys come in key order after the builder's.
    let text = t.to_string();
    assert!(text.contains(r#""trace_window":"0..2ms","config":{"gps":8},"frames":3}"#));

    let meta: Vec<&Value> = json["traceEvents"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|e| e["ph"] == "M")
        .collect();
    let named = |kind: &str| -> Vec<(u64, u64, String)> {
        meta.iter()
            .filter(|e| e["name"] == kind)
            .map(|e| {
                (
                    e["pid"].as_u64().unwrap(),
                    e["tid"].as_u64().unwrap_or(0),
                    e["args"]["name"].as_str().unwrap().to_owned(),
                )
            })
            .collect()
    };
    // Processes and threads share one id sequence, in order of first use.
    assert_eq!(
        named("process_name"),
        vec![(1, 0, "GPs".to_owned()), (4, 0, "Ring".to_owned())]
    );
    assert_eq!(
        named("thread_name"),
        vec![
            (1, 2, "GP 0".to_owned()),
            (1, 3, "GP 1".to_owned()),
            (4, 5, "channel 2".to_owned())
        ]
    );
    let sort: Vec<(u64, u64)> = meta
        .iter()
        .filter(|e| e["name"] == "thread_sort_index")
        .map(|e| {
            (
                e["tid"].as_u64().unwrap(),
                e["args"]["sort_index"].as_u64().unwrap(),
            )
        })
        .collect();
    assert_eq!(sort, vec![(2, 0), (3, 1), (5, 2)]);
}

#[test]
fn tracks_are_reused_by_name() {
    let mut t = ChromeTrace::default();
    let a = t.track("GPs", "GP 0");
    let b = t.track("Ring", "GP 0");
    let c = t.track("GPs", "GP 0");
    assert_eq!(a, c);
    assert_ne!(a, b);
}

#[test]
fn timestamps_are_exact_microseconds() {
    let mut t = ChromeTrace::default();
    let tr = t.track("p", "t");
    t.slice(tr, "ps", Tick(1), Tick(3), Args::new());
    t.slice(
        tr,
        "big",
        Tick(123_456_789_012_345),
        Tick(123_456_789_012_346),
        Args::new(),
    );
    t.slice(tr, "round", Tick(2_000_000), Tick(5_000_000), Args::new());
    t.slice(tr, "zero", Tick(7_000_000), Tick(7_000_000), Args::new());
    let lines = event_lines(&t);
    assert!(
        lines[0].contains(r#""ts":0.000001,"dur":0.000002"#),
        "{}",
        lines[0]
    );
    assert!(
        lines[1].contains(r#""ts":2.000000,"dur":3.000000"#),
        "{}",
        lines[1]
    );
    assert!(
        // A zero-length slice is an instant.
        lines[2].contains(r#""ph":"i","s":"t","name":"zero","pid":1,"tid":2,"ts":7.000000}"#),
        "{}",
        lines[2]
    );
    assert!(
        lines[3].contains(r#""ts":123456789.012345,"dur":0.000001"#),
        "{}",
        lines[3]
    );
    // The values a JSON reader sees are the same microseconds.
    let e = events(&t);
    assert_eq!(e[1]["ts"].as_f64(), Some(2.0));
    assert_eq!(e[1]["dur"].as_f64(), Some(3.0));
}

#[test]
fn names_and_args_are_escaped() {
    let mut t = ChromeTrace::default();
    let tr = t.track("proc \"A\"", "thread\\n\u{1}é");
    t.slice(
        tr,
        "say \"hi\"\n",
        Tick(0),
        Tick(10),
        vec![("k\"ey".to_owned(), JsonValue::from("v\u{0}al"))],
    );
    let e = events(&t);
    assert_eq!(e[0]["name"], "say \"hi\"\n");
    assert_eq!(e[0]["args"]["k\"ey"], "v\u{0}al");
    let json = parse(&t);
    let names: Vec<&str> = json["traceEvents"]
        .as_array()
        .unwrap()
        .iter()
        .filter_map(|e| e["args"]["name"].as_str())
        .collect();
    assert_eq!(names, vec!["proc \"A\"", "thread\\n\u{1}é"]);
}

#[test]
fn args_from_a_map_a_vec_or_an_array() {
    let mut t = ChromeTrace::default();
    let tr = t.track("p", "t");
    let mut map = Args::new();
    map.insert("m".into(), JsonValue::from(1));
    t.slice(tr, "map", Tick(0), Tick(1), map);
    t.slice(
        tr,
        "vec",
        Tick(1),
        Tick(2),
        vec![("v".to_owned(), JsonValue::from(vec![1, 2]))],
    );
    t.slice(
        tr,
        "array",
        Tick(2),
        Tick(3),
        [("a", JsonValue::from(true)), ("a", JsonValue::from(false))],
    );
    t.instant_with_args(tr, "instant", Tick(3), [("i", JsonValue::Null)]);
    let e = events(&t);
    assert_eq!(e[0]["args"], json!({"m": 1}));
    assert_eq!(e[1]["args"], json!({"v": [1, 2]}));
    // A later duplicate key wins.
    assert_eq!(e[2]["args"], json!({"a": false}));
    assert_eq!(e[3]["args"], json!({"i": null}));
    assert_eq!(e[3]["ph"], "i");
    assert_eq!(e[3]["s"], "t");
    // No args, no "args" key.
    let mut t = ChromeTrace::default();
    let tr = t.track("p", "t");
    t.slice(tr, "bare", Tick(0), Tick(1), Args::new());
    assert!(!t.to_string().contains("\"args\":{}"));
}

/// Records one event into a trace.
type Recorder = Box<dyn Fn(&mut ChromeTrace)>;

/// Records the same events in the given order.
fn build(order: &[usize]) -> ChromeTrace {
    let mut t = ChromeTrace::new(window("10ns..1us"));
    t.metadata("run", "determinism");
    let gp = t.track("GPs", "GP 0");
    let ring = t.track("Ring", "channel 0");
    let recorders: Vec<Recorder> = vec![
        Box::new(move |t| t.slice(gp, "frame", Tick(0), Tick(900_000), Args::new())),
        Box::new(move |t| {
            t.slice(
                gp,
                "transform",
                Tick(20_000),
                Tick(60_000),
                [("n", JsonValue::from(1))],
            )
        }),
        Box::new(move |t| t.slice(gp, "clip", Tick(60_000), Tick(70_000), Args::new())),
        Box::new(move |t| t.instant(ring, "token", Tick(30_000))),
        Box::new(|t| t.counter("Ring", "queue", Tick(5_000), 1)),
        Box::new(|t| t.counter("Ring", "queue", Tick(40_000), 2)),
        Box::new(move |t| t.slice_grouped(ring, "cmd", Tick(100_000), Tick(110_000), Tick(5_000))),
        Box::new(move |t| t.slice_grouped(ring, "cmd", Tick(112_000), Tick(120_000), Tick(5_000))),
        Box::new(move |t| t.slice_grouped(ring, "cmd", Tick(200_000), Tick(210_000), Tick(5_000))),
        Box::new(move |t| t.slice(ring, "late", Tick(2_000_000), Tick(3_000_000), Args::new())),
    ];
    for &i in order {
        recorders[i](&mut t);
    }
    t
}

#[test]
fn output_is_deterministic_and_independent_of_recording_order() {
    let forward: Vec<usize> = (0..10).collect();
    let a = build(&forward).to_string();
    assert_eq!(a, build(&forward).to_string());
    let orders: [[usize; 10]; 3] = [
        [9, 8, 7, 6, 5, 4, 3, 2, 1, 0],
        [3, 0, 8, 5, 1, 9, 6, 2, 7, 4],
        [6, 8, 7, 2, 4, 5, 0, 9, 3, 1],
    ];
    for order in orders {
        assert_eq!(build(&order).to_string(), a, "order {order:?}");
    }
    // Sorted by time in the file, whatever the recording order.
    let ts: Vec<f64> = events(&build(&orders[1]))
        .iter()
        .map(|e| e["ts"].as_f64().unwrap())
        .collect();
    assert!(ts.windows(2).all(|w| w[0] <= w[1]), "{ts:?}");
}

#[test]
fn enclosing_slices_come_first_at_equal_timestamps() {
    for outer_first in [true, false] {
        let mut t = ChromeTrace::default();
        let tr = t.track("p", "t");
        let record_outer = |t: &mut ChromeTrace| {
            t.slice(tr, "outer", Tick(1_000), Tick(9_000), Args::new());
        };
        let record_inner = |t: &mut ChromeTrace| {
            t.slice(tr, "inner", Tick(1_000), Tick(2_000), Args::new());
        };
        if outer_first {
            record_outer(&mut t);
            record_inner(&mut t);
        } else {
            record_inner(&mut t);
            record_outer(&mut t);
        }
        let names: Vec<Value> = events(&t).iter().map(|e| e["name"].clone()).collect();
        assert_eq!(names, vec![json!("outer"), json!("inner")]);
        assert_eq!(t.check_nesting().unwrap(), None);
    }
}

#[test]
fn equal_events_keep_recording_order() {
    let mut t = ChromeTrace::default();
    let tr = t.track("p", "t");
    t.instant(tr, "first", Tick(5));
    t.instant(tr, "second", Tick(5));
    let names: Vec<Value> = events(&t).iter().map(|e| e["name"].clone()).collect();
    assert_eq!(names, vec![json!("first"), json!("second")]);
}

#[test]
fn window_drops_and_clips() {
    // [1 us, 2 us)
    let mut t = ChromeTrace::new(window("1us..2us"));
    let tr = t.track("p", "t");
    t.slice(tr, "before", Tick(0), Tick(1_000_000), Args::new());
    t.slice(tr, "after", Tick(2_000_000), Tick(3_000_000), Args::new());
    t.slice(
        tr,
        "inside",
        Tick(1_100_000),
        Tick(1_200_000),
        [("k", JsonValue::from(1))],
    );
    t.slice(
        tr,
        "crosses start",
        Tick(500_000),
        Tick(1_500_000),
        [("k", JsonValue::from(2))],
    );
    t.slice(
        tr,
        "crosses end",
        Tick(1_900_000),
        Tick(2_500_000),
        Args::new(),
    );
    t.slice(tr, "covers", Tick(0), Tick(5_000_000), Args::new());
    t.slice(
        tr,
        "zero at start",
        Tick(1_000_000),
        Tick(1_000_000),
        Args::new(),
    );
    t.slice(
        tr,
        "zero at end",
        Tick(2_000_000),
        Tick(2_000_000),
        Args::new(),
    );
    t.slice(
        tr,
        "backwards",
        Tick(1_300_000),
        Tick(1_250_000),
        Args::new(),
    );
    t.instant(tr, "instant before", Tick(999_999));
    t.instant(tr, "instant at start", Tick(1_000_000));
    t.instant(tr, "instant at end", Tick(2_000_000));
    assert_eq!(
        event_lines(&t),
        vec![
            r#"{"ph":"X","name":"covers","pid":1,"tid":2,"ts":1.000000,"dur":1.000000,"args":{"clipped":true}}"#,
            r#"{"ph":"X","name":"crosses start","pid":1,"tid":2,"ts":1.000000,"dur":0.500000,"args":{"clipped":true,"k":2}}"#,
            r#"{"ph":"i","s":"t","name":"zero at start","pid":1,"tid":2,"ts":1.000000}"#,
            r#"{"ph":"i","s":"t","name":"instant at start","pid":1,"tid":2,"ts":1.000000}"#,
            r#"{"ph":"X","name":"inside","pid":1,"tid":2,"ts":1.100000,"dur":0.100000,"args":{"k":1}}"#,
            r#"{"ph":"i","s":"t","name":"backwards","pid":1,"tid":2,"ts":1.300000}"#,
            r#"{"ph":"X","name":"crosses end","pid":1,"tid":2,"ts":1.900000,"dur":0.100000,"args":{"clipped":true}}"#,
        ]
    );
    assert_eq!(t.window(), window("1us..2us"));
}

#[test]
fn grouping_merges_close_slices_of_one_name_and_track() {
    let mut t = ChromeTrace::default();
    let r0 = t.track("Renderers", "Renderer 0");
    let r1 = t.track("Renderers", "Renderer 1");
    let gap = Tick(10_000);
    // A run of commands 5 ns apart, then a pause of exactly min_gap (not below it: a new group).
    for i in 0..4 {
        let start = 100_000 + i * 30_000;
        t.slice_grouped(r0, "cmd", Tick(start), Tick(start + 25_000), gap);
    }
    // Last run ended at 215_000; 225_000 - 215_000 = gap, so a new group starts.
    t.slice_grouped(r0, "cmd", Tick(225_000), Tick(230_000), gap);
    // Another name and another track never merge with these.
    t.slice_grouped(r0, "other", Tick(231_000), Tick(232_000), gap);
    t.slice_grouped(r1, "cmd", Tick(232_000), Tick(233_000), gap);
    // Overlapping slices merge even with min_gap 0; touching ones do not.
    t.slice_grouped(r1, "dma", Tick(0), Tick(10), Tick(0));
    t.slice_grouped(r1, "dma", Tick(5), Tick(20), Tick(0));
    t.slice_grouped(r1, "dma", Tick(20), Tick(30), Tick(0));
    assert_eq!(
        event_lines(&t),
        vec![
            r#"{"ph":"X","name":"dma","pid":1,"tid":3,"ts":0.000000,"dur":0.000020,"args":{"count":2}}"#,
            r#"{"ph":"X","name":"dma","pid":1,"tid":3,"ts":0.000020,"dur":0.000010,"args":{"count":1}}"#,
            r#"{"ph":"X","name":"cmd","pid":1,"tid":2,"ts":0.100000,"dur":0.115000,"args":{"count":4}}"#,
            r#"{"ph":"X","name":"cmd","pid":1,"tid":2,"ts":0.225000,"dur":0.005000,"args":{"count":1}}"#,
            r#"{"ph":"X","name":"other","pid":1,"tid":2,"ts":0.231000,"dur":0.001000,"args":{"count":1}}"#,
            r#"{"ph":"X","name":"cmd","pid":1,"tid":3,"ts":0.232000,"dur":0.001000,"args":{"count":1}}"#,
        ]
    );
}

#[test]
fn grouping_does_not_depend_on_recording_order() {
    let slices: Vec<(u64, u64)> = vec![
        (0, 10),
        (12, 20),
        (25, 30),
        (50, 60),
        (61, 70),
        (100, 200),
        (150, 160),
        (203, 205),
    ];
    let build = |order: &[usize]| {
        let mut t = ChromeTrace::default();
        let tr = t.track("p", "t");
        for &i in order {
            let (s, e) = slices[i];
            t.slice_grouped(tr, "g", Tick(s), Tick(e), Tick(5));
        }
        t.to_string()
    };
    let forward = build(&[0, 1, 2, 3, 4, 5, 6, 7]);
    assert_eq!(build(&[7, 6, 5, 4, 3, 2, 1, 0]), forward);
    assert_eq!(build(&[2, 0, 6, 1, 7, 3, 5, 4]), forward);
    assert_eq!(build(&[1, 3, 5, 7, 0, 2, 4, 6]), forward);
    let mut t = ChromeTrace::default();
    let tr = t.track("p", "t");
    for &(s, e) in &slices {
        t.slice_grouped(tr, "g", Tick(s), Tick(e), Tick(5));
    }
    let groups: Vec<(f64, f64, u64)> = events(&t)
        .iter()
        .map(|e| {
            (
                e["ts"].as_f64().unwrap() * 1e6,
                e["dur"].as_f64().unwrap() * 1e6,
                e["args"]["count"].as_u64().unwrap(),
            )
        })
        .map(|(ts, dur, n)| (ts.round(), dur.round(), n))
        .collect();
    assert_eq!(
        groups,
        // 25 - 20 is not below 5: a group of its own. 61 - 60 and 203 - 200 are.
        vec![
            (0.0, 20.0, 2),
            (25.0, 5.0, 1),
            (50.0, 20.0, 2),
            (100.0, 105.0, 3)
        ]
    );
}

#[test]
fn grouping_respects_the_window() {
    let mut t = ChromeTrace::new(window("100ps..200ps"));
    let tr = t.track("p", "t");
    for s in (0..300).step_by(20) {
        t.slice_grouped(tr, "g", Tick(s), Tick(s + 10), Tick(15));
    }
    // Slices [s, s + 10) every 20 ps, gaps of 10 < 15: all one run. Only the five starting at 100,
    // 120, ..., 180 are inside; [80, 90) is not and does not count.
    assert_eq!(
        event_lines(&t),
        vec![
            r#"{"ph":"X","name":"g","pid":1,"tid":2,"ts":0.000100,"dur":0.000090,"args":{"count":5}}"#
        ]
    );
    let mut t = ChromeTrace::new(window("105ps..200ps"));
    let tr = t.track("p", "t");
    for s in (0..300).step_by(20) {
        t.slice_grouped(tr, "g", Tick(s), Tick(s + 10), Tick(15));
    }
    assert_eq!(
        event_lines(&t),
        vec![
            r#"{"ph":"X","name":"g","pid":1,"tid":2,"ts":0.000105,"dur":0.000085,"args":{"clipped":true,"count":5}}"#
        ]
    );
}

#[test]
fn counters() {
    let mut t = ChromeTrace::default();
    t.counter("Ring", "queue", Tick(0), 0);
    t.counter("Ring", "queue", Tick(1_000_000), 12);
    t.counter("Ring", "queue", Tick(2_000_000), i64::MIN);
    t.counter("Ring", "bytes", Tick(1_000_000), i64::MAX);
    let e = events(&t);
    assert_eq!(e.len(), 4);
    assert!(
        e.iter()
            .all(|e| e["ph"] == "C" && e["pid"] == 1 && e.get("tid").is_none())
    );
    let lines = event_lines(&t);
    assert_eq!(
        lines[1],
        r#"{"ph":"C","name":"queue","pid":1,"ts":1.000000,"args":{"value":12}}"#
    );
    assert_eq!(
        lines[2],
        r#"{"ph":"C","name":"bytes","pid":1,"ts":1.000000,"args":{"value":9223372036854775807}}"#
    );
    assert_eq!(e[3]["args"]["value"], json!(i64::MIN));
    // A counter-only process is named like any other.
    assert!(
        t.to_string()
            .contains(r#"{"ph":"M","name":"process_name","pid":1,"args":{"name":"Ring"}}"#)
    );
}

#[test]
fn counters_carry_their_value_into_the_window() {
    let mut t = ChromeTrace::new(window("1us..2us"));
    // Recorded out of order: the latest sample before the window is the one carried.
    t.counter("Ring", "queue", Tick(900_000), 5);
    t.counter("Ring", "queue", Tick(100_000), 3);
    t.counter("Ring", "queue", Tick(1_500_000), 6);
    t.counter("Ring", "queue", Tick(2_000_000), 7);
    // A counter sampled exactly at the window start needs no carried value.
    t.counter("Ring", "depth", Tick(0), 1);
    t.counter("Ring", "depth", Tick(1_000_000), 2);
    // A counter whose samples are all before the window still shows its value.
    t.counter("GPs", "busy", Tick(10), 1);
    assert_eq!(
        event_lines(&t),
        vec![
            r#"{"ph":"C","name":"queue","pid":1,"ts":1.000000,"args":{"value":5}}"#,
            r#"{"ph":"C","name":"busy","pid":2,"ts":1.000000,"args":{"value":1}}"#,
            r#"{"ph":"C","name":"depth","pid":1,"ts":1.000000,"args":{"value":2}}"#,
            r#"{"ph":"C","name":"queue","pid":1,"ts":1.500000,"args":{"value":6}}"#,
        ]
    );
}

#[test]
fn nesting_check() {
    let mut t = ChromeTrace::default();
    let tr = t.track("GPs", "GP 0");
    t.slice(tr, "frame", Tick(0), Tick(100), Args::new());
    t.slice(tr, "a", Tick(10), Tick(20), Args::new());
    t.slice(tr, "b", Tick(20), Tick(100), Args::new());
    t.slice(tr, "c", Tick(100), Tick(150), Args::new());
    // Overlaps on another track do not matter.
    let other = t.track("GPs", "GP 1");
    t.slice(other, "x", Tick(0), Tick(50), Args::new());
    t.slice(other, "y", Tick(0), Tick(50), Args::new());
    assert_eq!(t.check_nesting().unwrap(), None);

    t.slice(tr, "straddles", Tick(15), Tick(30), Args::new());
    let err = t.check_nesting().unwrap().expect("the straddling slice");
    assert_eq!(err.process, "GPs");
    assert_eq!(err.thread, "GP 0");
    assert_eq!(err.outer.name, "a");
    assert_eq!(err.inner.name, "straddles");
    assert_eq!((err.inner.start, err.inner.end), (Tick(15), Tick(30)));
    assert_eq!(
        err.to_string(),
        "on track GPs/GP 0, slice `straddles` [15 ps, 30 ps) starts inside slice `a` \
         [10 ps, 20 ps) but ends after it"
    );
}

#[test]
fn empty_trace_is_valid_json() {
    let t = ChromeTrace::default();
    let json = parse(&t);
    assert_eq!(json["traceEvents"], json!([]));
}

/// The same value as serde_json builds it.
fn to_serde(v: &JsonValue) -> Value {
    match v {
        JsonValue::Null => Value::Null,
        JsonValue::Bool(b) => Value::Bool(*b),
        JsonValue::Integer(n) => match i64::try_from(*n) {
            Ok(n) => Value::from(n),
            Err(_) => Value::from(u64::try_from(*n).expect("a 64-bit integer")),
        },
        JsonValue::String(s) => Value::String(s.clone()),
        JsonValue::Array(items) => Value::Array(items.iter().map(to_serde).collect()),
        JsonValue::Object(map) => {
            Value::Object(map.iter().map(|(k, v)| (k.clone(), to_serde(v))).collect())
        }
    }
}

/// The crate's JSON writer replaced serde_json's: traces must stay byte-identical, so its output
/// is checked against serde_json's on every ASCII character, on non-ASCII text and on nesting.
#[test]
fn json_writer_matches_serde_json() {
    let mut strings: Vec<String> = (0u8..=0x7F).map(|b| char::from(b).to_string()).collect();
    strings.push((0u8..=0x7F).map(char::from).collect());
    strings.extend(
        [
            "",
            "é",
            "\u{2028}\u{2029}",
            "😀 GP 0 -> Renderer 3",
            "a\"b\\\u{0}\u{1f}\u{7f}z",
        ]
        .map(String::from),
    );
    let mut values: Vec<JsonValue> = strings.iter().map(JsonValue::from).collect();
    values.extend([
        JsonValue::Null,
        true.into(),
        false.into(),
        0.into(),
        i64::MIN.into(),
        i64::MAX.into(),
        u64::MAX.into(),
        Vec::<u8>::new().into(),
        JsonValue::object(Vec::<(String, JsonValue)>::new()),
    ]);
    let object = JsonValue::object(
        strings
            .iter()
            .enumerate()
            .map(|(i, s)| (s.clone(), JsonValue::from(vec![i as u64, 7]))),
    );
    values.push(JsonValue::from(vec![object.clone(), JsonValue::Null]));
    values.push(object);
    for v in &values {
        let ours = v.to_string();
        let theirs = serde_json::to_string(&to_serde(v)).unwrap();
        assert_eq!(ours, theirs, "{v:?}");
    }
    // And a whole trace's args, metadata and names go through the same writer.
    let mut t = ChromeTrace::default();
    t.metadata("units", vec!["GP 0", "\u{1}\""]);
    let tr = t.track("p\u{7}", "t\u{1b}");
    t.slice(
        tr,
        "s\r",
        Tick(0),
        Tick(1),
        [("k\u{0}", JsonValue::from(u64::MAX))],
    );
    let text = t.to_string();
    let reparsed: Value = serde_json::from_str(&text).unwrap();
    assert!(text.contains(r#""units":["GP 0","\u0001\""]"#), "{text}");
    assert!(text.contains(r#""name":"s\r""#) && text.contains(r#""k\u0000":18446744073709551615"#));
    assert_eq!(reparsed["otherData"]["units"][1], "\u{1}\"");
}

#[test]
fn zero_length_slices_are_written_as_instants_with_their_args() {
    let mut t = ChromeTrace::default();
    let lane = t.track("Ring channel 0", "lane 0");
    t.slice(
        lane,
        "GP 0 -> GP 1",
        Tick(5_000),
        Tick(5_000),
        [("id", JsonValue::from(7))],
    );
    t.slice(lane, "GP 1 -> GP 0", Tick(6_000), Tick(9_000), Args::new());
    let ev = events(&t);
    assert_eq!(ev.len(), 2);
    assert_eq!(ev[0]["ph"], "i");
    assert_eq!(ev[0]["s"], "t");
    assert_eq!(ev[0]["ts"].as_f64(), Some(0.005));
    assert_eq!(ev[0]["args"], json!({"id": 7}));
    assert!(ev[0].get("dur").is_none());
    assert_eq!(ev[1]["ph"], "X");
    assert_eq!(ev[1]["dur"].as_f64(), Some(0.003));
}

#[test]
fn flows_are_chains_of_bound_steps_in_time_order() {
    let mut t = ChromeTrace::new(window("0..100ns"));
    let gp = t.track("GPs", "GP 0");
    let ring = t.track("Ring channel 0", "lane 0");
    t.slice(gp, "message send", Tick(0), Tick(10_000), Args::new());
    t.slice(
        ring,
        "GP 0 -> GP 1",
        Tick(10_000),
        Tick(30_000),
        Args::new(),
    );
    // Recorded out of order: written in time order, after slices starting at the same time.
    t.flow(ring, "message", 4, FlowStep::End, Tick(20_000));
    t.flow(gp, "message", 4, FlowStep::Start, Tick(5_000));
    // Outside the window: dropped.
    t.flow(gp, "message", 5, FlowStep::Start, Tick(200_000));
    let lines = event_lines(&t);
    assert_eq!(
        lines,
        [
            r#"{"ph":"X","name":"message send","pid":1,"tid":2,"ts":0.000000,"dur":0.010000}"#,
            r#"{"ph":"s","cat":"flow","name":"message","id":4,"pid":1,"tid":2,"ts":0.005000,"bp":"e"}"#,
            r#"{"ph":"X","name":"GP 0 -> GP 1","pid":3,"tid":4,"ts":0.010000,"dur":0.020000}"#,
            r#"{"ph":"f","cat":"flow","name":"message","id":4,"pid":3,"tid":4,"ts":0.020000,"bp":"e"}"#,
        ]
    );
    // The same events recorded in another order give the same bytes.
    let mut u = ChromeTrace::new(window("0..100ns"));
    let gp = u.track("GPs", "GP 0");
    let ring = u.track("Ring channel 0", "lane 0");
    u.flow(gp, "message", 4, FlowStep::Start, Tick(5_000));
    u.slice(
        ring,
        "GP 0 -> GP 1",
        Tick(10_000),
        Tick(30_000),
        Args::new(),
    );
    u.flow(ring, "message", 4, FlowStep::End, Tick(20_000));
    u.slice(gp, "message send", Tick(0), Tick(10_000), Args::new());
    assert_eq!(t.to_string(), u.to_string());
}

/// A trace that spills to disk writes the bytes of one held in memory: random slices (some
/// nested, some recorded late), grouped slices (in order and out of it, some touching, some of
/// zero length), instants, flows and counters (some before the window), in four windows, with a
/// budget small enough for dozens of runs. Memory stays within the budget.
#[test]
fn a_spilling_trace_writes_the_bytes_of_one_held_in_memory() {
    let windows = ["1us..2us", "5ps..", "0..300ns"].map(window);
    for w in [TraceWindow::all()].into_iter().chain(windows) {
        let budget = 4096;
        let mut held = ChromeTrace::new(w);
        let mut spilled = ChromeTrace::new(w).spill_at(std::env::temp_dir(), budget);
        let mut next = pxpl5_tests::xorshift(0x0005_EED0_F0DD_0BB5_u64);
        let mut now = 0u64;
        let mut most = 0;
        for i in 0..20_000u64 {
            now += next() % 300;
            let r = next();
            let start = if r.is_multiple_of(7) { now / 2 } else { now };
            let len = (r >> 8) % 500;
            let name = ["a", "b", "c"][(r >> 20) as usize % 3];
            let track = format!("GP {}", (r >> 24) % 3);
            let gap = Tick((r >> 28) % 3);
            for t in [&mut held, &mut spilled] {
                let tr = t.track("GPs", &track);
                match (r >> 32) % 6 {
                    0 => t.slice(
                        tr,
                        name,
                        Tick(start),
                        Tick(start + len),
                        [("i", JsonValue::from(i))],
                    ),
                    1 | 2 => t.slice_grouped(tr, name, Tick(start), Tick(start + len % 3), gap),
                    3 => t.instant(tr, name, Tick(start)),
                    4 => t.flow(tr, "msg", i, FlowStep::Step, Tick(start)),
                    _ => t.counter("Ring", name, Tick(start), (r % 11) as i64 - 5),
                }
            }
            most = most.max(spilled.held_bytes());
        }
        held.metadata("simulated_end_ps", now);
        spilled.metadata("simulated_end_ps", now);
        assert_eq!(held.spilled_runs(), 0);
        assert!(
            spilled.spilled_runs() > 10,
            "{w}: {} runs",
            spilled.spilled_runs()
        );
        // Each sort holds up to its budget and one record more; the open runs are one per key.
        assert!(most < 3 * budget, "{w}: {most} bytes held");
        let (mut a, mut b) = (Vec::new(), Vec::new());
        held.write(&mut a).unwrap();
        spilled.write(&mut b).unwrap();
        assert!(a == b, "{w}: spilled output differs");
        // Written twice, the same bytes: the runs are read again from their start.
        let mut c = Vec::new();
        spilled.write(&mut c).unwrap();
        assert!(b == c, "{w}: a second write differs");
        assert_eq!(
            held.check_nesting().unwrap().map(|e| e.to_string()),
            spilled.check_nesting().unwrap().map(|e| e.to_string())
        );
    }
}

/// A trace whose spill directory cannot hold its runs says so when it is written.
#[test]
fn a_spill_error_is_returned_by_write() {
    let dir = std::env::temp_dir()
        .join("pxpl5-no-such-dir")
        .join("deeper");
    let mut t = ChromeTrace::default().spill_at(dir, 64);
    let gp = t.track("GPs", "GP 0");
    for i in 0..100 {
        t.slice(gp, "x", Tick(i), Tick(i + 1), Args::new());
    }
    let err = t.write(Vec::new()).expect_err("no directory to spill to");
    assert!(err.to_string().contains("cannot spill the trace"), "{err}");
}
