//! The radiosity run's Chrome trace as a timing analyst reads it: one readback followed end to
//! end along its flow arrows, from a GP's send through the ring and a Renderer's commands to the
//! reply the GP it names receives; ring lanes named by channel; no zero-length slices.

use std::collections::BTreeMap;
use std::process::Command;

use serde_json::Value;

/// Picoseconds from a trace timestamp in microseconds (six decimals: exact in an f64 here).
fn ps(v: &Value) -> u64 {
    (v.as_f64().expect("a number") * 1e6).round() as u64
}

/// A flow event: its phase, the "process/thread" it is on, and the slice it binds to.
#[derive(Debug, PartialEq)]
struct Bound {
    phase: String,
    track: String,
    slice: String,
}

/// The trace's events by kind: slices (instants included) per track name, flow events per id.
struct Trace {
    slices: BTreeMap<String, Vec<(u64, u64, String, Value)>>,
    flows: BTreeMap<u64, Vec<(String, String, u64)>>,
}

fn read(bytes: &[u8]) -> Trace {
    let json: Value = serde_json::from_slice(bytes).expect("the trace is JSON");
    let events = json["traceEvents"].as_array().expect("traceEvents");
    let mut process = BTreeMap::new();
    let mut thread = BTreeMap::new();
    for e in events.iter().filter(|e| e["ph"] == "M") {
        let name = e["args"]["name"].as_str().unwrap_or_default().to_owned();
        match e["name"].as_str() {
            Some("process_name") => {
                process.insert(e["pid"].as_u64().unwrap(), name);
            }
            Some("thread_name") => {
                thread.insert(e["tid"].as_u64().unwrap(), name);
            }
            _ => {}
        }
    }
    let track = |e: &Value| {
        let p = &process[&e["pid"].as_u64().unwrap()];
        format!("{p}/{}", thread[&e["tid"].as_u64().unwrap()])
    };
    let mut trace = Trace {
        slices: BTreeMap::new(),
        flows: BTreeMap::new(),
    };
    for e in events {
        let ph = e["ph"].as_str().unwrap();
        if ph == "X" {
            assert!(ps(&e["dur"]) > 0, "a zero-length slice: {e}");
        }
        if ph == "X" || ph == "i" {
            let start = ps(&e["ts"]);
            let end = start + e.get("dur").map_or(0, ps);
            let name = e["name"].as_str().unwrap().to_owned();
            trace
                .slices
                .entry(track(e))
                .or_default()
                .push((start, end, name, e["args"].clone()));
        } else if ["s", "t", "f"].contains(&ph) {
            trace
                .flows
                .entry(e["id"].as_u64().unwrap())
                .or_default()
                .push((ph.to_owned(), track(e), ps(&e["ts"])));
        }
    }
    trace
}

impl Trace {
    /// Flow `id`, each event with the innermost slice of its track enclosing it.
    fn follow(&self, id: u64) -> Vec<Bound> {
        self.flows[&id]
            .iter()
            .map(|(phase, track, at)| {
                let slice = self.slices[track]
                    .iter()
                    .filter(|(s, e, ..)| s <= at && at < e)
                    .min_by_key(|(s, e, ..)| e - s)
                    .unwrap_or_else(|| panic!("flow {id}: nothing on {track} at {at} ps"));
                Bound {
                    phase: phase.clone(),
                    track: track.clone(),
                    slice: slice.2.clone(),
                }
            })
            .collect()
    }
}

#[test]
fn a_readback_is_followed_from_the_gps_send_to_the_reply_it_receives() {
    // The default run, but 2 shots: both methods, each with its own trace.
    let dir = std::env::temp_dir().join(format!("pxpl5-trace-flows-{}", std::process::id()));
    let out = Command::new(env!("CARGO_BIN_EXE_pxpl5"))
        .args(["radiosity", "--shots", "2", "--trace"])
        .arg(dir.join("r.json"))
        .arg("--out")
        .arg(dir.join("out"))
        .output()
        .expect("pxpl5 runs");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    for method in ["hemisphere", "hemicube"] {
        let file = dir.join(format!("r.{method}.json"));
        check_readback(&read(&std::fs::read(file).expect("the trace is written")));
    }
    let _ = std::fs::remove_dir_all(&dir);
}

fn check_readback(trace: &Trace) {
    // Ring lanes are named by channel and hold messages of that channel.
    let lanes: Vec<&String> = trace
        .slices
        .keys()
        .filter(|t| t.starts_with("Ring channel"))
        .collect();
    assert!(lanes.len() >= 2, "{lanes:?}");
    for lane in &lanes {
        let channel = lane
            .strip_prefix("Ring channel ")
            .and_then(|t| t.split_once("/lane "))
            .map(|(c, _)| c);
        for (.., args) in &trace.slices[*lane] {
            if let Some(c) = channel {
                assert_eq!(args["channels"].as_str(), Some(c), "{lane}");
            }
        }
    }

    // A reply from a Renderer to a GP, and the command message it answers.
    let (reply, asked, to) = trace
        .slices
        .iter()
        .filter(|(t, _)| t.starts_with("Ring channel"))
        .flat_map(|(_, s)| s)
        .find_map(|(.., name, args)| {
            let (_, to) = name.split_once(" -> ")?;
            let asked = args.get("answers")?.as_u64()?;
            to.starts_with("GP ")
                .then(|| (args["id"].as_u64().unwrap(), asked, to.to_owned()))
        })
        .expect("a readback reply to a GP");
    let request = trace.follow(asked);
    let answer = trace.follow(reply);
    let renderer = answer[0].track.clone();
    assert!(renderer.starts_with("Renderers/Renderer "), "{answer:?}");
    let r = renderer.trim_start_matches("Renderers/");

    // A GP sends the commands ...
    assert_eq!(request[0].phase, "s");
    assert_eq!(request[0].slice, "message send");
    let sender = request[0]
        .track
        .strip_prefix("GPs/")
        .expect("a GP sends the commands");
    // ... the ring carries them ...
    assert!(request[1].track.starts_with("Ring channel"), "{request:?}");
    assert_eq!(request[1].slice, format!("{sender} -> {r}"));
    // ... the Renderer runs them, the readback among them, and the flow ends there.
    assert!(
        request[2..].iter().all(|b| b.track == renderer),
        "{request:?}"
    );
    assert!(request.iter().any(|b| b.slice == "readback"), "{request:?}");
    assert_eq!(request.last().unwrap().phase, "f");
    // The reply leaves from that readback command, crosses the ring, and the GP the readback
    // names receives it.
    assert_eq!(answer.len(), 3, "{answer:?}");
    assert_eq!(
        (answer[0].phase.as_str(), answer[0].slice.as_str()),
        ("s", "readback")
    );
    assert!(answer[1].track.starts_with("Ring channel"), "{answer:?}");
    assert_eq!(answer[1].slice, format!("{r} -> {to}"));
    assert_eq!(
        answer[2],
        Bound {
            phase: "f".into(),
            track: format!("GPs/{to}"),
            slice: "message receive".into(),
        }
    );
    let start = &trace.flows[&reply][0];
    assert!(
        trace.flows[&asked]
            .iter()
            .any(|(_, track, at)| (track, at) == (&start.1, &start.2)),
        "the reply starts where the request's flow passes its readback"
    );
}
