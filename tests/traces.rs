//! The two event-trace formats of one run agree: the polygon program on
//! `programs/polygons/scenes/small.ron` on the seed machine, traced once as Chrome JSON and once
//! as Perfetto's protobuf format (decoded here with the writer's own message structs). The
//! Perfetto file must hold the JSON's tracks (grouped as the JSON's processes), its slices (to
//! the nanosecond), its counters and its flows, balanced begin/end pairs, and be at least 5x
//! smaller.

use std::collections::{BTreeMap, BTreeSet};
use std::io::{self, Write};
use std::sync::{Arc, Mutex};

use pxpl5_machine::{Machine, Recorder, RunOptions, RunResult};
use pxpl5_tests::workspace_root;
use pxpl5_trace::proto::{EventType, TracePacket};
use pxpl5_trace::{TraceWindow, read_packets};
use serde_json::Value;

/// A writer into a buffer shared with the test.
#[derive(Clone, Default)]
struct Shared(Arc<Mutex<Vec<u8>>>);

impl Write for Shared {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.0
            .lock()
            .map_err(|_| io::Error::other("poisoned"))?
            .extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

fn run(recorder: Recorder) -> RunResult {
    let cfg = pxpl5_config::default_config();
    let scene = pxpl5_polygons::scene::load_triangle_scene(
        &workspace_root().join("programs/polygons/scenes/small.ron"),
    )
    .expect("the small scene is valid");
    let program = pxpl5_polygons::Polygons::new(scene);
    Machine::new(&cfg, &program, RunOptions::default(), recorder)
        .expect("builds")
        .run()
        .expect("runs")
}

/// What both formats are reduced to: per track (`group/track`), its slices as (start ns, end ns,
/// name), its instants; per counter its samples; per flow id the tracks it visits.
#[derive(Debug, Default, PartialEq)]
struct Reduced {
    tracks: BTreeSet<String>,
    slices: BTreeMap<String, Vec<(u64, u64, String)>>,
    instants: BTreeMap<String, Vec<(u64, String)>>,
    counters: BTreeMap<String, Vec<(u64, i64)>>,
    flows: BTreeMap<u64, Vec<String>>,
}

/// The JSON's microseconds (six decimals: exact picoseconds) as picoseconds.
fn json_ps(v: &Value) -> u64 {
    let text = v.to_string();
    let (int, frac) = text.split_once('.').unwrap_or((&text, "0"));
    int.parse::<u64>().unwrap() * 1_000_000 + format!("{frac:0<6}").parse::<u64>().unwrap()
}

/// As nanoseconds, rounded down (the Perfetto file's unit).
fn json_ns(v: &Value) -> u64 {
    json_ps(v) / 1_000
}

fn reduce_json(bytes: &[u8]) -> Reduced {
    let doc: Value = serde_json::from_slice(bytes).expect("valid JSON");
    let events = doc["traceEvents"].as_array().unwrap();
    let mut processes = BTreeMap::new();
    let mut threads = BTreeMap::new();
    for e in events.iter().filter(|e| e["ph"] == "M") {
        let name = e["args"]["name"].as_str().map(str::to_owned);
        match (e["name"].as_str(), name) {
            (Some("process_name"), Some(n)) => {
                processes.insert(e["pid"].as_u64().unwrap(), n);
            }
            (Some("thread_name"), Some(n)) => {
                threads.insert((e["pid"].as_u64().unwrap(), e["tid"].as_u64().unwrap()), n);
            }
            _ => {}
        }
    }
    let track = |e: &Value| {
        let pid = e["pid"].as_u64().unwrap();
        let tid = e["tid"].as_u64().unwrap();
        format!("{}/{}", processes[&pid], threads[&(pid, tid)])
    };
    let mut r = Reduced::default();
    for (&(pid, _), name) in &threads {
        r.tracks.insert(format!("{}/{name}", processes[&pid]));
    }
    // Flow steps bind to the slice enclosing them: collect them, then find it.
    let mut flow_steps = Vec::new();
    for e in events {
        let name = e["name"].as_str().unwrap_or_default().to_owned();
        match e["ph"].as_str().unwrap() {
            "X" => {
                let start = json_ns(&e["ts"]);
                let end = (json_ps(&e["ts"]) + json_ps(&e["dur"])) / 1_000;
                r.slices
                    .entry(track(e))
                    .or_default()
                    .push((start, end, name));
            }
            "i" => r
                .instants
                .entry(track(e))
                .or_default()
                .push((json_ns(&e["ts"]), name)),
            "C" => {
                let pid = e["pid"].as_u64().unwrap();
                r.counters
                    .entry(format!("{}/{name}", processes[&pid]))
                    .or_default()
                    .push((json_ns(&e["ts"]), e["args"]["value"].as_i64().unwrap()));
            }
            "s" | "t" | "f" => flow_steps.push((e["id"].as_u64().unwrap(), track(e))),
            _ => {}
        }
    }
    for (id, track) in flow_steps {
        r.flows.entry(id).or_default().push(track);
    }
    r
}

/// Reduces a Perfetto trace, checking on the way what the format asks: interned names defined
/// before use, the first packet clearing the sequence's state, begin/end pairs balanced per
/// track in time order, every flow ending exactly once.
fn reduce_perfetto(packets: &[TracePacket]) -> Reduced {
    let mut descriptors: BTreeMap<u64, (String, Option<u64>, bool)> = BTreeMap::new();
    let mut names: BTreeMap<u64, String> = BTreeMap::new();
    // (ts, file order, track uuid, type, name, flows, terminating flows, counter value)
    type Ev = (
        u64,
        usize,
        u64,
        i32,
        Option<String>,
        Vec<u64>,
        Vec<u64>,
        Option<i64>,
    );
    let mut events: Vec<Ev> = Vec::new();
    let first = &packets[0];
    assert_eq!(
        first.sequence_flags.unwrap_or(0) & 1,
        1,
        "first packet clears"
    );
    for (i, p) in packets.iter().enumerate() {
        assert_eq!(p.trusted_packet_sequence_id, Some(1));
        if let Some(interned) = &p.interned_data {
            for n in &interned.event_names {
                names.insert(n.iid.unwrap(), n.name.clone().unwrap());
            }
        }
        if let Some(d) = &p.track_descriptor {
            descriptors.insert(
                d.uuid.unwrap(),
                (d.name.clone().unwrap(), d.parent_uuid, d.counter.is_some()),
            );
        }
        if let Some(e) = &p.track_event {
            let uuid = e.track_uuid.unwrap();
            assert!(descriptors.contains_key(&uuid), "track described first");
            let name = e.name_iid.map(|iid| {
                assert_eq!(p.sequence_flags, Some(2), "interned use says so");
                names.get(&iid).expect("name interned before use").clone()
            });
            events.push((
                p.timestamp.unwrap(),
                i,
                uuid,
                e.r#type.unwrap(),
                name,
                e.flow_ids.clone(),
                e.terminating_flow_ids.clone(),
                e.counter_value,
            ));
        }
    }
    let full = |uuid: u64| {
        let (name, parent, _) = &descriptors[&uuid];
        let group = &descriptors[&parent.expect("every track is in a group")].0;
        format!("{group}/{name}")
    };
    let mut r = Reduced::default();
    for (&uuid, (_, parent, counter)) in &descriptors {
        if parent.is_some() && !counter {
            r.tracks.insert(full(uuid));
        }
    }
    // As Perfetto's trace processor: events sorted by time, file order among equals.
    events.sort_by_key(|e| (e.0, e.1));
    let mut open: BTreeMap<u64, Vec<(u64, String)>> = BTreeMap::new();
    let mut ends: BTreeMap<u64, usize> = BTreeMap::new();
    for (ts, _, uuid, kind, name, flows, terminating, value) in events {
        let track = full(uuid);
        for &id in flows.iter().chain(&terminating) {
            r.flows.entry(id).or_default().push(track.clone());
        }
        for id in terminating {
            *ends.entry(id).or_default() += 1;
        }
        match EventType::try_from(kind).unwrap() {
            EventType::SliceBegin => open
                .entry(uuid)
                .or_default()
                .push((ts, name.expect("a begin is named"))),
            EventType::SliceEnd => {
                let (start, name) = open
                    .get_mut(&uuid)
                    .and_then(Vec::pop)
                    .unwrap_or_else(|| panic!("end without begin on {track} at {ts}"));
                r.slices.entry(track).or_default().push((start, ts, name));
            }
            EventType::Instant => r
                .instants
                .entry(track)
                .or_default()
                .push((ts, name.expect("an instant is named"))),
            EventType::Counter => r
                .counters
                .entry(track)
                .or_default()
                .push((ts, value.expect("a counter has a value"))),
            EventType::Unspecified => panic!("event without a type"),
        }
    }
    assert!(open.values().all(Vec::is_empty), "unbalanced: {open:?}");
    for (id, tracks) in &r.flows {
        assert!(tracks.len() >= 2, "flow {id} has one event: {tracks:?}");
        assert_eq!(ends.get(id), Some(&1), "flow {id} ends once");
    }
    r
}

#[test]
fn perfetto_trace_holds_the_json_trace_and_is_five_times_smaller() {
    let json_run = run(Recorder::new(Some(TraceWindow::all()), None));
    let mut json = Vec::new();
    assert!(json_run.recorder.write_chrome(&mut json).unwrap());

    let shared = Shared::default();
    let mut pf_run = run(Recorder::perfetto(
        TraceWindow::all(),
        Box::new(shared.clone()),
        None,
    ));
    assert!(pf_run.recorder.finish_trace().unwrap());
    let bytes = shared.0.lock().unwrap().clone();
    assert_eq!(
        pf_run.stats.end, json_run.stats.end,
        "tracing changes no timing"
    );

    let packets = read_packets(&bytes).expect("decodes");
    let pf = reduce_perfetto(&packets);
    let js = reduce_json(&json);
    // The run is big enough for the comparison to mean something.
    assert!(js.slices.values().map(Vec::len).sum::<usize>() > 1_000);
    assert!(js.flows.len() > 100 && js.counters.len() > 10);

    // Tracks: GPs, Renderers and ring lanes grouped per channel, named as in the JSON.
    assert_eq!(pf.tracks, js.tracks);
    for want in [
        "GPs/GP 0",
        "GPs/GP 0 phases",
        "Renderers/Renderer 0",
        "Ring channel 0/lane 0",
    ] {
        assert!(pf.tracks.contains(want), "no track {want}: {:?}", pf.tracks);
    }
    assert_eq!(
        pf.slices.keys().collect::<Vec<_>>(),
        js.slices.keys().collect::<Vec<_>>()
    );
    for (track, slices) in &js.slices {
        let mut a = slices.clone();
        let mut b = pf.slices[track].clone();
        a.sort();
        b.sort();
        assert_eq!(a.len(), b.len(), "{track}");
        assert_eq!(a, b, "{track}");
    }
    assert_eq!(pf.instants, js.instants);
    // Counters: the same samples (the queue counters and the tokens).
    assert!(pf.counters.contains_key("Ring queues/GP 0 output words"));
    assert!(pf.counters.contains_key("Ring channel 0/token held"));
    assert_eq!(pf.counters, js.counters);
    // Flows: the same ids through the same tracks.
    assert!(!pf.flows.is_empty());
    let tracks_of = |flows: &BTreeMap<u64, Vec<String>>| -> BTreeMap<u64, BTreeSet<String>> {
        flows
            .iter()
            .map(|(id, t)| (*id, t.iter().cloned().collect()))
            .collect()
    };
    assert_eq!(tracks_of(&pf.flows), tracks_of(&js.flows));

    assert!(
        bytes.len() * 5 <= json.len(),
        "pftrace {} bytes, JSON {} bytes",
        bytes.len(),
        json.len()
    );
}

#[test]
fn the_critical_path_track_sums_to_the_stats_critical_path() {
    let run = run(Recorder::new(Some(TraceWindow::all()), None));
    let mut json = Vec::new();
    assert!(run.recorder.write_chrome(&mut json).unwrap());
    let doc: Value = serde_json::from_slice(&json).unwrap();
    let events = doc["traceEvents"].as_array().unwrap();
    let pid = events
        .iter()
        .find(|e| e["name"] == "process_name" && e["args"]["name"] == "Critical path")
        .expect("a critical-path process")["pid"]
        .clone();
    let mut segments: Vec<(u64, u64, String, String)> = events
        .iter()
        .filter(|e| e["pid"] == pid && e["ph"] == "X")
        .map(|e| {
            let start = json_ps(&e["ts"]);
            (
                start,
                start + json_ps(&e["dur"]),
                e["name"].as_str().unwrap().to_owned(),
                e["args"]["category"].as_str().unwrap().to_owned(),
            )
        })
        .collect();
    segments.sort();
    assert!(segments.len() > 10, "{segments:?}");
    // End to end from 0: at every instant one unit holds the path.
    assert_eq!(segments[0].0, 0);
    for w in segments.windows(2) {
        assert_eq!(
            w[0].1, w[1].0,
            "a gap or overlap at {:?} / {:?}",
            w[0], w[1]
        );
    }
    // It ends when the last unit to finish did (the run's end may come later: a last message
    // to the frame buffer or the host).
    let path_end: u64 = run.stats.critical_path.iter().map(|p| p.time.0).sum();
    assert_eq!(segments.last().unwrap().1, path_end);
    assert!(path_end <= run.stats.end.0);
    // Per category, exactly the stats' figures.
    let mut sums: BTreeMap<String, u64> = BTreeMap::new();
    for (start, end, _, category) in &segments {
        *sums.entry(category.clone()).or_default() += end - start;
    }
    let stats: BTreeMap<String, u64> = run
        .stats
        .critical_path
        .iter()
        .map(|p| (p.activity.clone(), p.time.0))
        .collect();
    assert_eq!(sums, stats);
    // Names say which unit: GP and Renderer work is named by its unit.
    assert!(
        segments
            .iter()
            .any(|s| s.2.starts_with("GP ") && s.2.contains(": ")),
        "{segments:?}"
    );
}
