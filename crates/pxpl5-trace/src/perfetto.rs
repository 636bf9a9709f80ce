//! [`PerfettoTrace`]: a writer of Perfetto's native trace format (protobuf `TracePacket`s, the
//! `.pftrace` files Perfetto's UI opens) over simulated time, streamed as events are recorded.
//!
//! # Output format
//!
//! One packet sequence (`trusted_packet_sequence_id` 1) of [`crate::proto`] messages:
//!
//! * **Tracks.** A track group (the JSON's process, e.g. `GPs`, `Ring channel 0`) is a
//!   `TrackDescriptor` without events; its tracks (the JSON's threads) and its counters are
//!   `TrackDescriptor`s whose `parent_uuid` is the group's. Descriptors are written when the
//!   track is first used, before any event on it.
//! * **Events.** A slice is a `TYPE_SLICE_BEGIN` and a `TYPE_SLICE_END` event, a zero-length slice
//!   or an instant a `TYPE_INSTANT`, a counter sample a `TYPE_COUNTER`. Event names and argument
//!   names are interned: the packet that first uses one carries it in `interned_data` and says
//!   `SEQ_NEEDS_INCREMENTAL_STATE`; the first packet says `SEQ_INCREMENTAL_STATE_CLEARED`.
//!   Arguments are debug annotations.
//! * **Flows.** [`PerfettoTrace::flow`] puts the flow id on the begin event of the slice of its
//!   track that encloses its instant (as the JSON's `"bp":"e"` binds to it): in `flow_ids` for a
//!   start or a step, in `terminating_flow_ids` for the end. Perfetto links a flow's events in
//!   time order. A flow step whose slice was already written (see below) becomes an instant
//!   named as the flow, carrying the id, inside that slice.
//! * **Time.** Packet timestamps are nanoseconds (Perfetto's unit; it has none finer), the
//!   simulated picoseconds divided by 1,000 and rounded down. Rounding down keeps the order of
//!   events, so slices stay nested or disjoint as they were; a slice shorter than a nanosecond
//!   may become zero-length. The Chrome JSON keeps the exact picoseconds.
//! * **Window.** As [`crate::ChromeTrace`]: events outside the [`TraceWindow`] are dropped,
//!   slices crossing an edge clipped (arg `clipped`), a counter's last value before the window
//!   carried to its start.
//!
//! # Streaming
//!
//! Packets are written as events are recorded, through the writer given at creation, so memory
//! stays bounded whatever the run's length: per track the one slice (or run of grouped slices)
//! that later events may still join, per counter its value before the window, and the interned
//! names. The price is the file's order: it is the recording order, not time order. Perfetto's
//! trace processor sorts a trace's events by timestamp (keeping file order among equal
//! timestamps) before it builds slices; it holds a file's events until the file's end unless
//! the file has the tracing service's flush events, which this writer never writes (its
//! `TraceSorter`, `src/trace_processor/sorter/trace_sorter.h`). So what the writer must keep is
//! each track's own order:
//! a track's slices are to be recorded in start order, disjoint or enclosing what is recorded
//! after them, as the simulator's recorder does. Then at a shared timestamp a slice's end is
//! written before the next one's begin.
//!
//! Packets are gathered in chunks of about 256 KiB, each written compressed (deflate) as one
//! `compressed_packets` packet, as Perfetto's own tracing service writes them: the trace is
//! several times smaller, and the writer's memory is the chunk. [`read_packets`] reads them back.
//!
//! Write errors are kept (the first one) and returned by [`PerfettoTrace::finish`]; nothing more
//! is written after one.

use std::collections::HashMap;
use std::io::{self, Read, Write};

use flate2::Compression;
use flate2::read::ZlibDecoder;
use flate2::write::ZlibEncoder;
use prost::Message;
use pxpl5_sim::Tick;

use crate::chrome::{Args, FlowStep, TrackId};
use crate::json::JsonValue;
use crate::proto::{
    self, CounterDescriptor, DebugAnnotation, DebugAnnotationName, EventName, EventType,
    InternedData, TracePacket, TrackDescriptor,
};
use crate::window::TraceWindow;

/// The one packet sequence the writer uses.
const SEQUENCE: u32 = 1;

/// Packets are written in compressed chunks of about this many bytes: Perfetto wants a
/// `compressed_packets` packet under 512 KB, and this bounds the writer's buffer.
const CHUNK_BYTES: usize = 256 * 1024;

/// A slice of one track not yet written: later grouped slices may join it, later flows bind to it.
#[derive(Debug)]
struct Pending {
    name: u64,
    start: u64,
    end: u64,
    args: Args,
    /// `Some(min_gap)` for a run of grouped slices ([`PerfettoTrace::slice_grouped`]).
    group_gap: Option<u64>,
    count: u64,
    clipped: bool,
    flows: Vec<u64>,
    ends: Vec<u64>,
}

impl Pending {
    /// A slice of one recorded slice `(start, end, clipped)`.
    fn new(name: u64, span: (u64, u64, bool), args: Args, group_gap: Option<u64>) -> Pending {
        let (start, end, clipped) = span;
        Pending {
            name,
            start,
            end,
            args,
            group_gap,
            count: 1,
            clipped,
            flows: Vec::new(),
            ends: Vec::new(),
        }
    }
}

#[derive(Debug)]
struct Track {
    uuid: u64,
    pending: Option<Pending>,
}

#[derive(Debug)]
struct Counter {
    uuid: u64,
    /// The latest value before the window start, not yet written.
    carry: Option<i64>,
    /// Whether a sample inside the window was written.
    started: bool,
}

/// A streaming writer of a Perfetto protobuf trace over simulated time. See the module docs.
pub struct PerfettoTrace {
    window: TraceWindow,
    out: Box<dyn Write + Send>,
    error: Option<io::Error>,
    groups: HashMap<String, u64>,
    tracks: Vec<Track>,
    track_ids: HashMap<(u64, String), TrackId>,
    /// Counters in creation order, and their index per (group uuid, name).
    counters: Vec<Counter>,
    counter_ids: HashMap<(u64, String), usize>,
    names: HashMap<String, u64>,
    arg_names: HashMap<String, u64>,
    next_uuid: u64,
    /// Whether the first packet (the one clearing incremental state) is written.
    started: bool,
    /// Interned data the next packet must carry.
    new_names: InternedData,
    /// Encoded packets not yet compressed and written.
    chunk: Vec<u8>,
    bytes: u64,
}

impl std::fmt::Debug for PerfettoTrace {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PerfettoTrace")
            .field("window", &self.window)
            .field("tracks", &self.tracks.len())
            .field("bytes", &self.bytes)
            .finish_non_exhaustive()
    }
}

/// The interning id of `name` in `table` (numbered from 1 in order of first use), and whether it
/// is new: then the next packet must carry it.
fn number(table: &mut HashMap<String, u64>, name: &str) -> (u64, bool) {
    if let Some(&iid) = table.get(name) {
        return (iid, false);
    }
    let iid = table.len() as u64 + 1;
    table.insert(name.to_owned(), iid);
    (iid, true)
}

/// Simulated picoseconds as Perfetto's nanoseconds (rounded down; see the module docs).
fn ns(ps: u64) -> u64 {
    ps / 1_000
}

impl PerfettoTrace {
    /// A trace keeping what falls in `window`, written to `out` as it is recorded (wrap a file in
    /// a `BufWriter`: packets are small).
    pub fn new(window: TraceWindow, out: Box<dyn Write + Send>) -> PerfettoTrace {
        PerfettoTrace {
            window,
            out,
            error: None,
            groups: HashMap::new(),
            tracks: Vec::new(),
            track_ids: HashMap::new(),
            counters: Vec::new(),
            counter_ids: HashMap::new(),
            names: HashMap::new(),
            arg_names: HashMap::new(),
            next_uuid: 1,
            started: false,
            new_names: InternedData::default(),
            chunk: Vec::new(),
            bytes: 0,
        }
    }

    /// The window this trace keeps.
    pub fn window(&self) -> TraceWindow {
        self.window
    }

    /// Bytes written so far (compressed chunks; the last chunk is written by
    /// [`PerfettoTrace::finish`]).
    pub fn bytes_written(&self) -> u64 {
        self.bytes
    }

    /// The track `thread` of group `process` (names as [`crate::ChromeTrace::track`] takes
    /// them), created on first use.
    pub fn track(&mut self, process: &str, thread: &str) -> TrackId {
        let group = self.group(process);
        if let Some(&id) = self.track_ids.get(&(group, thread.to_owned())) {
            return id;
        }
        let uuid = self.describe(thread, Some(group), false);
        let id = TrackId(self.tracks.len());
        self.tracks.push(Track {
            uuid,
            pending: None,
        });
        self.track_ids.insert((group, thread.to_owned()), id);
        id
    }

    /// Records the slice `[start, end)` named `name` on `track`, with `args`.
    pub fn slice(&mut self, track: TrackId, name: &str, start: Tick, end: Tick, args: Args) {
        let Some((start, end, clipped)) = self.window.clip(start, end) else {
            return;
        };
        let mut args = args;
        if clipped {
            args.insert("clipped".to_owned(), JsonValue::Bool(true));
        }
        let name = self.intern(name);
        self.hold(track, Pending::new(name, (start, end, clipped), args, None));
    }

    /// Records a slice of a high-rate kind, merged with the previous slice of `track` when that
    /// one is of the same name, also grouped with the same `min_gap`, and `start` is less than
    /// `min_gap` after its end ([`crate::ChromeTrace::slice_grouped`]; here only the track's
    /// latest run can be joined, which on a track of sequential work is the same thing).
    pub fn slice_grouped(
        &mut self,
        track: TrackId,
        name: &str,
        start: Tick,
        end: Tick,
        min_gap: Tick,
    ) {
        let Some((start, end, clipped)) = self.window.clip(start, end) else {
            return;
        };
        let name = self.intern(name);
        let gap = min_gap.as_ps();
        if let Some(p) = self
            .tracks
            .get_mut(track.0)
            .and_then(|t| t.pending.as_mut())
            && p.name == name
            && p.group_gap == Some(gap)
            && start >= p.start
            && start < p.end.saturating_add(gap)
        {
            p.end = p.end.max(end);
            p.count += 1;
            p.clipped |= clipped;
            return;
        }
        let run = Pending::new(name, (start, end, clipped), Args::new(), Some(gap));
        self.hold(track, run);
    }

    /// Records an instant event at `at` on `track`, with `args`.
    pub fn instant(&mut self, track: TrackId, name: &str, at: Tick, args: Args) {
        if !self.window.contains(at) {
            return;
        }
        let Some(uuid) = self.tracks.get(track.0).map(|t| t.uuid) else {
            return;
        };
        let name = self.intern(name);
        let event = self.event(EventType::Instant, uuid, Some(name), &args);
        self.packet(at.as_ps(), event);
    }

    /// Records a step of flow `id` at `at` on `track` ([`crate::ChromeTrace::flow`]): bound to
    /// the slice of `track` enclosing `at`.
    pub fn flow(&mut self, track: TrackId, name: &str, id: u64, step: FlowStep, at: Tick) {
        if !self.window.contains(at) {
            return;
        }
        let at = at.as_ps();
        if let Some(p) = self
            .tracks
            .get_mut(track.0)
            .and_then(|t| t.pending.as_mut())
            && p.start <= at
            && (at < p.end || at == p.start)
        {
            match step {
                FlowStep::End => p.ends.push(id),
                FlowStep::Start | FlowStep::Step => p.flows.push(id),
            }
            return;
        }
        // The enclosing slice is written already (or there is none): an instant carries the id.
        let Some(uuid) = self.tracks.get(track.0).map(|t| t.uuid) else {
            return;
        };
        let name = self.intern(name);
        let mut event = self.event(EventType::Instant, uuid, Some(name), &Args::new());
        match step {
            FlowStep::End => event.terminating_flow_ids.push(id),
            FlowStep::Start | FlowStep::Step => event.flow_ids.push(id),
        }
        self.packet(at, event);
    }

    /// Records the value of counter `name` of group `process` at `at`.
    pub fn counter(&mut self, process: &str, name: &str, at: Tick, value: i64) {
        let group = self.group(process);
        let index = match self.counter_ids.get(&(group, name.to_owned())) {
            Some(&i) => i,
            None => {
                let uuid = self.describe(name, Some(group), true);
                self.counters.push(Counter {
                    uuid,
                    carry: None,
                    started: false,
                });
                self.counter_ids
                    .insert((group, name.to_owned()), self.counters.len() - 1);
                self.counters.len() - 1
            }
        };
        if at < self.window.start {
            self.counters[index].carry = Some(value);
            return;
        }
        if at >= self.window.end {
            return;
        }
        let c = &mut self.counters[index];
        let uuid = c.uuid;
        let carried = if c.started { None } else { c.carry.take() };
        c.started = true;
        if let Some(carried) = carried
            && at > self.window.start
        {
            self.sample(uuid, self.window.start.as_ps(), carried);
        }
        self.sample(uuid, at.as_ps(), value);
    }

    /// Writes what is still held (each track's last slice, counters' values carried to the
    /// window start) and flushes the writer. Returns the first write error, if any.
    pub fn finish(&mut self) -> io::Result<()> {
        for t in 0..self.tracks.len() {
            if let Some(p) = self.tracks[t].pending.take() {
                self.emit(self.tracks[t].uuid, p);
            }
        }
        for c in 0..self.counters.len() {
            if let Some(value) = self.counters[c].carry.take()
                && !self.counters[c].started
            {
                self.sample(self.counters[c].uuid, self.window.start.as_ps(), value);
            }
        }
        self.write_chunk();
        if self.error.is_none()
            && let Err(e) = self.out.flush()
        {
            self.error = Some(e);
        }
        match self.error.take() {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }

    /// Makes `slice` the track's held slice, writing the one it replaces.
    fn hold(&mut self, track: TrackId, slice: Pending) {
        let Some(t) = self.tracks.get_mut(track.0) else {
            return;
        };
        let uuid = t.uuid;
        if let Some(previous) = t.pending.replace(slice) {
            self.emit(uuid, previous);
        }
    }

    /// Writes a held slice: begin and end events, or an instant when it has no length.
    fn emit(&mut self, uuid: u64, mut p: Pending) {
        if p.group_gap.is_some() {
            p.args.insert("count".to_owned(), JsonValue::from(p.count));
            if p.clipped {
                p.args.insert("clipped".to_owned(), JsonValue::Bool(true));
            }
        }
        let kind = if p.start == p.end {
            EventType::Instant
        } else {
            EventType::SliceBegin
        };
        let mut begin = self.event(kind, uuid, Some(p.name), &p.args);
        // A flow listed twice on one slice (several commands of one message in a run) is one
        // step; one that ends here does not also pass.
        p.ends.sort_unstable();
        p.ends.dedup();
        p.flows.sort_unstable();
        p.flows.dedup();
        p.flows.retain(|id| p.ends.binary_search(id).is_err());
        begin.flow_ids = p.flows;
        begin.terminating_flow_ids = p.ends;
        self.packet(p.start, begin);
        if kind == EventType::SliceBegin {
            let end = self.event(EventType::SliceEnd, uuid, None, &Args::new());
            self.packet(p.end, end);
        }
    }

    fn sample(&mut self, uuid: u64, at: u64, value: i64) {
        let mut event = self.event(EventType::Counter, uuid, None, &Args::new());
        event.counter_value = Some(value);
        self.packet(at, event);
    }

    /// A track event of `kind` on track `uuid`, its arguments as debug annotations.
    fn event(
        &mut self,
        kind: EventType,
        uuid: u64,
        name: Option<u64>,
        args: &Args,
    ) -> proto::TrackEvent {
        let debug_annotations = args
            .iter()
            .map(|(key, value)| {
                let mut a = DebugAnnotation {
                    name_iid: Some(self.intern_arg(key)),
                    ..DebugAnnotation::default()
                };
                match value {
                    JsonValue::Bool(b) => a.bool_value = Some(*b),
                    JsonValue::Integer(n) => match (u64::try_from(*n), i64::try_from(*n)) {
                        (Ok(u), _) => a.uint_value = Some(u),
                        (_, Ok(i)) => a.int_value = Some(i),
                        _ => a.string_value = Some(n.to_string()),
                    },
                    JsonValue::String(s) => a.string_value = Some(s.clone()),
                    other => a.legacy_json_value = Some(other.to_string()),
                }
                a
            })
            .collect();
        proto::TrackEvent {
            debug_annotations,
            r#type: Some(kind as i32),
            name_iid: name,
            track_uuid: Some(uuid),
            ..proto::TrackEvent::default()
        }
    }

    /// The uuid of group `process`, described on first use.
    fn group(&mut self, process: &str) -> u64 {
        if let Some(&uuid) = self.groups.get(process) {
            return uuid;
        }
        let uuid = self.describe(process, None, false);
        self.groups.insert(process.to_owned(), uuid);
        uuid
    }

    /// Writes the descriptor of a new track and returns its uuid.
    fn describe(&mut self, name: &str, parent: Option<u64>, counter: bool) -> u64 {
        let uuid = self.next_uuid;
        self.next_uuid += 1;
        let descriptor = TrackDescriptor {
            uuid: Some(uuid),
            name: Some(name.to_owned()),
            parent_uuid: parent,
            counter: counter.then(CounterDescriptor::default),
        };
        self.write(TracePacket {
            track_descriptor: Some(descriptor),
            ..TracePacket::default()
        });
        uuid
    }

    fn intern(&mut self, name: &str) -> u64 {
        let (iid, new) = number(&mut self.names, name);
        if new {
            self.new_names.event_names.push(EventName {
                iid: Some(iid),
                name: Some(name.to_owned()),
            });
        }
        iid
    }

    fn intern_arg(&mut self, name: &str) -> u64 {
        let (iid, new) = number(&mut self.arg_names, name);
        if new {
            let interned = DebugAnnotationName {
                iid: Some(iid),
                name: Some(name.to_owned()),
            };
            self.new_names.debug_annotation_names.push(interned);
        }
        iid
    }

    /// Writes a track event at `at` picoseconds, with the names interned since the last packet.
    fn packet(&mut self, at: u64, event: proto::TrackEvent) {
        let new_names = std::mem::take(&mut self.new_names);
        let has_names =
            !new_names.event_names.is_empty() || !new_names.debug_annotation_names.is_empty();
        // Only events that name something interned need the sequence's state.
        let interned = event.name_iid.is_some() || !event.debug_annotations.is_empty();
        self.write(TracePacket {
            timestamp: Some(ns(at)),
            track_event: Some(event),
            interned_data: has_names.then_some(new_names),
            sequence_flags: interned.then_some(proto::SEQ_NEEDS_INCREMENTAL_STATE),
            ..TracePacket::default()
        });
    }

    /// Adds one packet to the current chunk as a `Trace` of one packet (concatenated, such
    /// encodings are a `Trace` of them all), on the writer's sequence; the first packet clears
    /// the sequence's state. A full chunk is written.
    fn write(&mut self, mut packet: TracePacket) {
        if self.error.is_some() {
            return;
        }
        packet.trusted_packet_sequence_id = Some(SEQUENCE);
        if !self.started {
            self.started = true;
            let flags = packet.sequence_flags.unwrap_or(0);
            packet.sequence_flags = Some(flags | proto::SEQ_INCREMENTAL_STATE_CLEARED);
        }
        let trace = proto::Trace {
            packet: vec![packet],
        };
        // Encoding into a Vec cannot fail (it grows as needed).
        let _ = trace.encode(&mut self.chunk);
        if self.chunk.len() >= CHUNK_BYTES {
            self.write_chunk();
        }
    }

    /// Writes the chunk of packets so far as one `compressed_packets` packet.
    fn write_chunk(&mut self) {
        if self.chunk.is_empty() || self.error.is_some() {
            return;
        }
        let mut z = ZlibEncoder::new(Vec::new(), Compression::default());
        let compressed = z.write_all(&self.chunk).and_then(|()| z.finish());
        self.chunk.clear();
        let result = compressed.and_then(|bytes| {
            let outer = proto::Trace {
                packet: vec![TracePacket {
                    compressed_packets: Some(bytes),
                    ..TracePacket::default()
                }],
            };
            let encoded = outer.encode_to_vec();
            self.out.write_all(&encoded)?;
            self.bytes += encoded.len() as u64;
            Ok(())
        });
        if let Err(e) = result {
            self.error = Some(e);
        }
    }
}

/// Every packet of a trace file's bytes, the compressed ones inflated in place (a reader's view:
/// for tests and `pxpl5 trace timeline`). Fails on bytes that are not a trace.
pub fn read_packets(bytes: &[u8]) -> io::Result<Vec<TracePacket>> {
    let invalid = |e: prost::DecodeError| io::Error::new(io::ErrorKind::InvalidData, e);
    let mut out = Vec::new();
    for packet in proto::Trace::decode(bytes).map_err(invalid)?.packet {
        match &packet.compressed_packets {
            Some(z) => {
                let mut inflated = Vec::new();
                ZlibDecoder::new(z.as_slice()).read_to_end(&mut inflated)?;
                out.extend(
                    proto::Trace::decode(inflated.as_slice())
                        .map_err(invalid)?
                        .packet,
                );
            }
            None => out.push(packet),
        }
    }
    Ok(out)
}
