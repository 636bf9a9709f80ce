//! Tests of `PerfettoTrace`: what it writes decodes (with the crate's own message structs) to the
//! tracks, slices, grouped runs, counters, flows and window it was given; a write error is
//! reported, not lost.

use std::io::{self, Write};
use std::sync::{Arc, Mutex};

use pxpl5_trace::proto::{EventType, TracePacket};
use pxpl5_trace::{Args, FlowStep, JsonValue, PerfettoTrace, Tick, TraceWindow, read_packets};

#[derive(Clone, Default)]
struct Shared(Arc<Mutex<Vec<u8>>>);

impl Write for Shared {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

/// A writer that fails after `left` bytes.
struct Failing {
    left: usize,
}

impl Write for Failing {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        if buf.len() > self.left {
            return Err(io::Error::other("disk full"));
        }
        self.left -= buf.len();
        Ok(buf.len())
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

fn finish(mut t: PerfettoTrace, out: &Shared) -> Vec<TracePacket> {
    t.finish().unwrap();
    read_packets(&out.0.lock().unwrap()).unwrap()
}

/// Each track event as (ts ns, type, track name, event name, flows, terminating flows, value).
type Event = (
    u64,
    EventType,
    String,
    String,
    Vec<u64>,
    Vec<u64>,
    Option<i64>,
);

fn events(packets: &[TracePacket]) -> Vec<Event> {
    let mut tracks = std::collections::BTreeMap::new();
    let mut names = std::collections::BTreeMap::new();
    let mut out = Vec::new();
    for p in packets {
        if let Some(d) = &p.track_descriptor {
            tracks.insert(d.uuid.unwrap(), d.name.clone().unwrap());
        }
        if let Some(i) = &p.interned_data {
            for n in &i.event_names {
                names.insert(n.iid.unwrap(), n.name.clone().unwrap());
            }
        }
        if let Some(e) = &p.track_event {
            out.push((
                p.timestamp.unwrap(),
                EventType::try_from(e.r#type.unwrap()).unwrap(),
                tracks[&e.track_uuid.unwrap()].clone(),
                e.name_iid.map(|i| names[&i].clone()).unwrap_or_default(),
                e.flow_ids.clone(),
                e.terminating_flow_ids.clone(),
                e.counter_value,
            ));
        }
    }
    out
}

#[test]
fn slices_runs_flows_and_counters_decode_as_recorded() {
    let out = Shared::default();
    let mut t = PerfettoTrace::new(TraceWindow::all(), Box::new(out.clone()));
    let gp = t.track("GPs", "GP 0");
    let r = t.track("Renderers", "Renderer 0");
    assert_eq!(
        t.track("GPs", "GP 0"),
        gp,
        "the same names give the same track"
    );
    let args: Args = [("id".to_owned(), JsonValue::from(7))].into();
    t.slice(gp, "message send", Tick(1_000), Tick(3_000), args);
    t.flow(gp, "message", 7, FlowStep::Start, Tick(2_000));
    // Three commands a cycle apart or less merge; the fourth, further, starts a run.
    for (s, e) in [
        (10_000, 20_000),
        (20_000, 30_000),
        (30_500, 40_000),
        (90_000, 95_000),
    ] {
        t.slice_grouped(r, "qee", Tick(s), Tick(e), Tick(1_000));
        t.flow(r, "message", 7, FlowStep::Step, Tick(s + 1));
    }
    t.flow(r, "message", 7, FlowStep::End, Tick(94_000));
    // A flow whose slice is written already: an instant carries it.
    t.flow(r, "message", 8, FlowStep::Start, Tick(15_000));
    t.counter("Ring queues", "GP 0 output words", Tick(500), 4);
    t.counter("Ring queues", "GP 0 output words", Tick(2_500), 0);
    t.instant(gp, "mark", Tick(5_000), Args::new());
    let ev = events(&finish(t, &out));
    let find = |kind, track: &str, name: &str| {
        ev.iter()
            .filter(|e| e.1 == kind && e.2 == track && e.3 == name)
            .cloned()
            .collect::<Vec<_>>()
    };
    let send = find(EventType::SliceBegin, "GP 0", "message send");
    assert_eq!(send.len(), 1);
    assert_eq!((send[0].0, send[0].4.clone()), (1, vec![7]));
    let runs = find(EventType::SliceBegin, "Renderer 0", "qee");
    assert_eq!(runs.iter().map(|e| e.0).collect::<Vec<_>>(), [10, 90]);
    // The first run has the message twice, once: a step; the second ends it.
    assert_eq!((runs[0].4.clone(), runs[0].5.clone()), (vec![7], vec![]));
    assert_eq!((runs[1].4.clone(), runs[1].5.clone()), (vec![], vec![7]));
    let ends: Vec<u64> = ev
        .iter()
        .filter(|e| e.1 == EventType::SliceEnd && e.2 == "Renderer 0")
        .map(|e| e.0)
        .collect();
    assert_eq!(ends, [40, 95]);
    let late = find(EventType::Instant, "Renderer 0", "message");
    assert_eq!((late[0].0, late[0].4.clone()), (15, vec![8]));
    let counter: Vec<(u64, Option<i64>)> = ev
        .iter()
        .filter(|e| e.1 == EventType::Counter)
        .map(|e| (e.0, e.6))
        .collect();
    assert_eq!(counter, [(0, Some(4)), (2, Some(0))]);
    assert_eq!(find(EventType::Instant, "GP 0", "mark").len(), 1);
}

#[test]
fn the_window_clips_slices_and_carries_counters_to_its_start() {
    let out = Shared::default();
    let mut t = PerfettoTrace::new("10ns..100ns".parse().unwrap(), Box::new(out.clone()));
    let gp = t.track("GPs", "GP 0");
    t.slice(gp, "before", Tick(0), Tick(5_000), Args::new());
    t.slice(gp, "across", Tick(5_000), Tick(20_000), Args::new());
    t.slice(gp, "after", Tick(100_000), Tick(120_000), Args::new());
    t.counter("Ring queues", "words", Tick(1_000), 3);
    t.counter("Ring queues", "words", Tick(2_000), 5);
    t.counter("Ring queues", "words", Tick(50_000), 1);
    t.counter("Ring queues", "held", Tick(3_000), 1);
    let packets = finish(t, &out);
    let ev = events(&packets);
    let slices: Vec<(u64, EventType, String)> = ev
        .iter()
        .filter(|e| e.2 == "GP 0")
        .map(|e| (e.0, e.1, e.3.clone()))
        .collect();
    assert_eq!(
        slices,
        [
            (10, EventType::SliceBegin, "across".to_owned()),
            (20, EventType::SliceEnd, String::new())
        ]
    );
    let clipped = packets
        .iter()
        .filter_map(|p| p.track_event.as_ref())
        .any(|e| {
            e.debug_annotations
                .iter()
                .any(|a| a.bool_value == Some(true))
        });
    assert!(clipped, "the clipped slice says so");
    let mut counters: Vec<(String, u64, Option<i64>)> = ev
        .iter()
        .filter(|e| e.1 == EventType::Counter)
        .map(|e| (e.2.clone(), e.0, e.6))
        .collect();
    counters.sort();
    assert_eq!(
        counters,
        [
            ("held".to_owned(), 10, Some(1)),
            ("words".to_owned(), 10, Some(5)),
            ("words".to_owned(), 50, Some(1)),
        ]
    );
}

#[test]
fn a_write_error_is_returned_by_finish() {
    let mut t = PerfettoTrace::new(TraceWindow::all(), Box::new(Failing { left: 10 }));
    let gp = t.track("GPs", "GP 0");
    for i in 0..10_000u64 {
        t.slice(
            gp,
            "compute",
            Tick(i * 10_000),
            Tick(i * 10_000 + 5_000),
            Args::new(),
        );
    }
    let err = t.finish().unwrap_err();
    assert_eq!(err.to_string(), "disk full");
}

#[test]
fn bytes_that_are_not_a_trace_are_an_error_not_a_panic() {
    assert!(read_packets(b"\x0a\xff\xff\xff\xff\x0f").is_err());
    // A compressed packet whose bytes do not inflate.
    assert!(read_packets(&[0x0a, 0x05, 0x92, 0x03, 0x02, 0x00, 0x01]).is_err());
    assert_eq!(read_packets(b"").unwrap(), Vec::new());
}
