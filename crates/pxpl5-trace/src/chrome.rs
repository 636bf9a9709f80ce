//! [`ChromeTrace`]: a builder of Chrome trace-event JSON (the format Perfetto and
//! chrome://tracing open) whose clock is simulated time.
//!
//! # Output format
//!
//! ```text
//! {"displayTimeUnit":"ns","otherData":{"time_unit":"...","trace_window":"0..",...},"traceEvents":[
//! {"ph":"M","name":"process_name","pid":1,"args":{"name":"GPs"}},
//! ...
//! {"ph":"X","name":"transform","pid":1,"tid":2,"ts":0.025000,"dur":0.050000,"args":{...}}
//! {"ph":"s","cat":"flow","name":"message","id":7,"pid":1,"tid":2,"ts":0.050000,"bp":"e"}
//! ]}
//! ```
//!
//! * **Instants.** A slice of zero length is written as a thread instant (`"ph":"i"`), which
//!   viewers draw as a marker; an invisible zero-width box helps no one.
//! * **Flows.** [`ChromeTrace::flow`] writes `s`/`t`/`f` events with `"bp":"e"`: each binds to
//!   the slice of its track that encloses its timestamp, and Perfetto draws an arrow from each to
//!   the next of the same name and id.
//! * **Time.** Chrome's timestamps are microseconds. `ts` and `dur` are written as decimals with
//!   exactly six fractional digits, computed from integer picoseconds by integer division
//!   (1 us = 1,000,000 ps), so they are exact (six digits of a microsecond are a picosecond) and
//!   byte-identical on every platform; no float is ever formatted. Times are absolute simulated
//!   time, also inside a window, so they match the simulator's other reports.
//! * **Tracks.** A track is a (process, thread) pair of names. Process ids and thread ids come
//!   from one shared sequence starting at 1, in order of first use: ids never collide, which
//!   matters because a viewer gives process-level events (counters, process names) the thread id
//!   equal to the pid. `process_name`/`thread_name` metadata name them and
//!   `process_sort_index`/`thread_sort_index` make them appear in creation order.
//! * **Order.** Events may be recorded in any order. On output they are sorted by timestamp, then
//!   longer slices first (so a slice precedes the slices it encloses when both start together:
//!   Perfetto nests slices in file order at equal timestamps), then by recording order. Identical
//!   inputs give identical bytes, and events recorded at different times in a different order
//!   give the same bytes.
//! * **Window.** Events entirely outside the [`TraceWindow`] are dropped as they are recorded (a
//!   long run's trace need not fit in memory); slices crossing an edge are clipped to it and get
//!   the arg `"clipped": true`. A counter's last value before the window is carried to the window
//!   start, since a counter holds its value until its next sample.
//! * One event per line, so traces diff and grep well.

use std::borrow::Cow;
use std::cmp::Reverse;
use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::fmt;
use std::io::{self, Write};

use pxpl5_sim::Tick;

use crate::json::{JsonValue, write_object, write_string};
use crate::window::TraceWindow;

/// Arguments attached to an event (shown in the viewer's details panel).
pub type Args = BTreeMap<String, JsonValue>;

/// The note placed in `otherData.time_unit`: a reader must not mistake simulated for host time.
pub const TIME_UNIT_NOTE: &str =
    "1 trace microsecond = 1 simulated microsecond (timestamps are simulated time, not host time)";

/// The `otherData` keys the builder writes itself; [`ChromeTrace::metadata`] cannot replace them.
pub const RESERVED_METADATA_KEYS: [&str; 2] = ["time_unit", "trace_window"];

/// A (process, thread) track of one [`ChromeTrace`]; meaningless to any other trace.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct TrackId(pub(crate) usize);

/// A named process: a group of tracks, and the owner of counters.
#[derive(Debug)]
struct Process {
    name: String,
    pid: u32,
    threads: HashMap<String, TrackId>,
}

#[derive(Debug)]
struct Track {
    process: usize,
    name: String,
    tid: u32,
}

#[derive(Clone, Copy, Debug)]
enum Kind {
    Slice {
        track: TrackId,
        dur: u64,
    },
    Instant {
        track: TrackId,
    },
    Counter {
        process: usize,
        value: i64,
    },
    Flow {
        track: TrackId,
        id: u64,
        step: FlowStep,
    },
}

/// Where an event of a flow (a chain of arrows between slices, [`ChromeTrace::flow`]) stands in
/// its chain.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum FlowStep {
    /// The first slice of the chain (`"ph":"s"`).
    Start,
    /// A slice in the middle (`"ph":"t"`).
    Step,
    /// The last slice (`"ph":"f"`).
    End,
}

impl FlowStep {
    fn phase(self) -> &'static str {
        match self {
            FlowStep::Start => "s",
            FlowStep::Step => "t",
            FlowStep::End => "f",
        }
    }
}

/// A recorded event; `name` indexes the interned names (high-rate events repeat few names).
#[derive(Debug)]
struct Event {
    ts: u64,
    seq: u64,
    name: u32,
    kind: Kind,
    args: Args,
}

/// A run of grouped slices merged so far.
#[derive(Clone, Copy, Debug)]
struct Group {
    start: u64,
    end: u64,
    count: u64,
    clipped: bool,
    /// The smallest recording sequence number of its members: its place among equal timestamps.
    seq: u64,
}

/// Identifies the slices that may merge: same track, same name, same `min_gap`.
type GroupKey = (TrackId, u32, u64);

#[derive(Clone, Copy, Debug)]
struct CounterSample {
    at: u64,
    seq: u64,
    value: i64,
}

/// A builder of a Chrome trace-event JSON file over simulated time. See the module docs for the
/// output format.
#[derive(Debug)]
pub struct ChromeTrace {
    window: TraceWindow,
    metadata: BTreeMap<String, JsonValue>,
    processes: Vec<Process>,
    process_ids: HashMap<String, usize>,
    tracks: Vec<Track>,
    /// The next pid or tid (one sequence for both).
    next_id: u32,
    names: Vec<String>,
    name_ids: HashMap<String, u32>,
    events: Vec<Event>,
    // BTreeMaps, not HashMaps, where iteration feeds the output: the final sort makes the order
    // total anyway, but no output should ever hinge on hash order.
    groups: BTreeMap<GroupKey, Vec<Group>>,
    /// Per (process, counter name): the latest sample before the window start.
    counter_carry: BTreeMap<(usize, u32), CounterSample>,
    seq: u64,
}

impl Default for ChromeTrace {
    fn default() -> ChromeTrace {
        ChromeTrace::new(TraceWindow::all())
    }
}

impl ChromeTrace {
    /// An empty trace keeping what falls in `window`.
    pub fn new(window: TraceWindow) -> ChromeTrace {
        ChromeTrace {
            window,
            metadata: BTreeMap::new(),
            processes: Vec::new(),
            process_ids: HashMap::new(),
            tracks: Vec::new(),
            next_id: 1,
            names: Vec::new(),
            name_ids: HashMap::new(),
            events: Vec::new(),
            groups: BTreeMap::new(),
            counter_carry: BTreeMap::new(),
            seq: 0,
        }
    }

    /// The window this trace keeps.
    pub fn window(&self) -> TraceWindow {
        self.window
    }

    /// Adds `key: value` to the file's `otherData` (e.g. the machine configuration's name), written
    /// in key order. Setting a key again replaces its value. The keys in
    /// [`RESERVED_METADATA_KEYS`] belong to the builder and are ignored here.
    pub fn metadata(&mut self, key: &str, value: impl Into<JsonValue>) {
        if !RESERVED_METADATA_KEYS.contains(&key) {
            self.metadata.insert(key.to_owned(), value.into());
        }
    }

    /// The track for `thread` within `process`, created on first use (the same names give the same
    /// track). Tracks are shown in creation order.
    pub fn track(&mut self, process: &str, thread: &str) -> TrackId {
        let p = self.process(process);
        if let Some(&id) = self.processes[p].threads.get(thread) {
            return id;
        }
        let id = TrackId(self.tracks.len());
        let tid = self.fresh_id();
        self.tracks.push(Track {
            process: p,
            name: thread.to_owned(),
            tid,
        });
        self.processes[p].threads.insert(thread.to_owned(), id);
        id
    }

    /// Records a complete slice `[start, end)` named `name` on `track`.
    ///
    /// `args` is anything yielding `(key, value)` pairs: an [`Args`] map, a
    /// `Vec<(String, JsonValue)>`, or an array such as `[("cmd", JsonValue::from(3))]`;
    /// `Args::new()` for none.
    /// A later duplicate key wins. `end < start` is taken as `end == start` (a zero-length slice).
    ///
    /// Slices on one track must be properly nested or disjoint for Perfetto to draw them (see
    /// [`ChromeTrace::check_nesting`]); they may be recorded in any order.
    pub fn slice<K: Into<String>>(
        &mut self,
        track: TrackId,
        name: &str,
        start: Tick,
        end: Tick,
        args: impl IntoIterator<Item = (K, JsonValue)>,
    ) {
        let Some((start, end, clipped)) = self.window.clip(start, end) else {
            return;
        };
        let mut args: Args = args.into_iter().map(|(k, v)| (k.into(), v)).collect();
        if clipped {
            args.insert("clipped".to_owned(), JsonValue::Bool(true));
        }
        let event = Event {
            ts: start,
            seq: self.next_seq(),
            name: self.intern(name),
            kind: Kind::Slice {
                track,
                dur: end - start,
            },
            args,
        };
        self.events.push(event);
    }

    /// Records a slice of a high-rate kind (e.g. Renderer commands), merged with the other slices
    /// of the same `name` on the same `track` (recorded with the same `min_gap`) whose gap to it is
    /// below `min_gap`: slices `[s1, e1)` and `[s2, e2)` with `s1 <= s2` merge when
    /// `s2 < e1 + min_gap`, so overlapping slices always merge and, with `min_gap` 0, only they do.
    ///
    /// Each merged run is one slice from its first start to its last end with the arg `"count"`
    /// (how many recorded slices it stands for, counting only those inside the window) and
    /// `"clipped": true` if a member was clipped to the window. The result does not depend on the
    /// order slices are recorded in; recording them in time order keeps memory to one entry per
    /// run.
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
        let seq = self.next_seq();
        let key = (track, self.intern(name), min_gap.as_ps());
        let runs = self.groups.entry(key).or_default();
        // Merge into the latest run when this slice continues it; anything else (an early slice
        // recorded late) starts a run of its own, and `grouped_events` merges runs on output.
        if let Some(last) = runs.last_mut()
            && start >= last.start
            && start < last.end.saturating_add(min_gap.as_ps())
        {
            last.end = last.end.max(end);
            last.count += 1;
            last.clipped |= clipped;
            return;
        }
        runs.push(Group {
            start,
            end,
            count: 1,
            clipped,
            seq,
        });
    }

    /// Records an instant event (a thread-scoped marker) at `at` on `track`.
    pub fn instant(&mut self, track: TrackId, name: &str, at: Tick) {
        self.instant_with_args(track, name, at, Args::new());
    }

    /// [`ChromeTrace::instant`] with arguments, taken as by [`ChromeTrace::slice`].
    pub fn instant_with_args<K: Into<String>>(
        &mut self,
        track: TrackId,
        name: &str,
        at: Tick,
        args: impl IntoIterator<Item = (K, JsonValue)>,
    ) {
        let args = args.into_iter().map(|(k, v)| (k.into(), v)).collect();
        self.point(Kind::Instant { track }, name, at, args);
    }

    /// Records an event of one instant, unless `at` lies outside the window.
    fn point(&mut self, kind: Kind, name: &str, at: Tick, args: Args) {
        if !self.window.contains(at) {
            return;
        }
        let event = Event {
            ts: at.as_ps(),
            seq: self.next_seq(),
            name: self.intern(name),
            kind,
            args,
        };
        self.events.push(event);
    }

    /// Records a step of flow `id` (named `name`: Perfetto links the events of one flow by name
    /// and id) at `at` on `track`. The step binds to the slice of `track` enclosing `at`
    /// (`"bp":"e"`), so `at` should lie strictly inside a slice: a slice's midpoint, say. Perfetto
    /// draws an arrow from each step to the next in time order.
    pub fn flow(&mut self, track: TrackId, name: &str, id: u64, step: FlowStep, at: Tick) {
        self.point(Kind::Flow { track, id, step }, name, at, Args::new());
    }

    /// Records that counter `name` of `process` (created on first use, like a track's process)
    /// takes `value` from `at` until its next sample. Written as `"args":{"value":V}`; Perfetto
    /// names the track `NAME value`.
    pub fn counter(&mut self, process: &str, name: &str, at: Tick, value: i64) {
        // The process exists whether or not this sample is kept, so pids do not depend on the window.
        let process = self.process(process);
        let at = at.as_ps();
        if at >= self.window.end.as_ps() {
            return;
        }
        let seq = self.next_seq();
        let name = self.intern(name);
        if at < self.window.start.as_ps() {
            let sample = CounterSample { at, seq, value };
            self.counter_carry
                .entry((process, name))
                .and_modify(|kept| {
                    if at >= kept.at {
                        *kept = sample;
                    }
                })
                .or_insert(sample);
            return;
        }
        self.events.push(Event {
            ts: at,
            seq,
            name,
            kind: Kind::Counter { process, value },
            args: Args::new(),
        });
    }

    /// Checks that on every track the slices to be written (after clipping and grouping) are
    /// properly nested or disjoint, which Perfetto needs to draw them; reports the first pair that
    /// overlaps without nesting (boxed: it is large and errors are rare).
    pub fn check_nesting(&self) -> Result<(), Box<NestingError>> {
        let mut per_track: BTreeMap<TrackId, Vec<(u64, u64, u32)>> = BTreeMap::new();
        for e in self.output_events() {
            if let Kind::Slice { track, dur } = e.kind {
                per_track
                    .entry(track)
                    .or_default()
                    .push((e.ts, e.ts + dur, e.name));
            }
        }
        for (track, slices) in per_track {
            // Output order puts an enclosing slice before what it encloses, so a stack of open
            // slices' ends suffices.
            let mut open: Vec<(u64, u64, u32)> = Vec::new();
            for (start, end, name) in slices {
                while open.last().is_some_and(|&(_, e, _)| e <= start) {
                    open.pop();
                }
                if let Some(&(o_start, o_end, o_name)) = open.last()
                    && end > o_end
                {
                    let t = &self.tracks[track.0];
                    return Err(Box::new(NestingError {
                        process: self.processes[t.process].name.clone(),
                        thread: t.name.clone(),
                        outer: SliceSpan {
                            name: self.names[o_name as usize].clone(),
                            start: Tick(o_start),
                            end: Tick(o_end),
                        },
                        inner: SliceSpan {
                            name: self.names[name as usize].clone(),
                            start: Tick(start),
                            end: Tick(end),
                        },
                    }));
                }
                open.push((start, end, name));
            }
        }
        Ok(())
    }

    /// Writes the trace as JSON to `w` (wrap a file in a `BufWriter`: this writes in small pieces).
    pub fn write<W: Write>(&self, mut w: W) -> io::Result<()> {
        w.write_all(b"{\"displayTimeUnit\":\"ns\",\"otherData\":{\"time_unit\":")?;
        write_string(&mut w, TIME_UNIT_NOTE)?;
        w.write_all(b",\"trace_window\":")?;
        write_string(&mut w, &self.window.to_string())?;
        for (key, value) in &self.metadata {
            w.write_all(b",")?;
            write_string(&mut w, key)?;
            w.write_all(b":")?;
            value.write_to(&mut w)?;
        }
        w.write_all(b"},\"traceEvents\":[")?;

        let mut first = true;
        let mut separator = |w: &mut W| -> io::Result<()> {
            w.write_all(if first { b"\n" } else { b",\n" })?;
            first = false;
            Ok(())
        };
        for (index, p) in self.processes.iter().enumerate() {
            separator(&mut w)?;
            write!(
                w,
                "{{\"ph\":\"M\",\"name\":\"process_name\",\"pid\":{},\"args\":{{\"name\":",
                p.pid
            )?;
            write_string(&mut w, &p.name)?;
            w.write_all(b"}}")?;
            separator(&mut w)?;
            write!(
                w,
                "{{\"ph\":\"M\",\"name\":\"process_sort_index\",\"pid\":{},\"args\":{{\"sort_index\":{index}}}}}",
                p.pid
            )?;
        }
        for (index, t) in self.tracks.iter().enumerate() {
            let pid = self.processes[t.process].pid;
            separator(&mut w)?;
            write!(
                w,
                "{{\"ph\":\"M\",\"name\":\"thread_name\",\"pid\":{pid},\"tid\":{},\"args\":{{\"name\":",
                t.tid
            )?;
            write_string(&mut w, &t.name)?;
            w.write_all(b"}}")?;
            separator(&mut w)?;
            write!(
                w,
                "{{\"ph\":\"M\",\"name\":\"thread_sort_index\",\"pid\":{pid},\"tid\":{},\"args\":{{\"sort_index\":{index}}}}}",
                t.tid
            )?;
        }
        for e in self.output_events() {
            separator(&mut w)?;
            self.write_event(&mut w, &e)?;
        }
        w.write_all(b"\n]}\n")
    }

    fn write_event<W: Write>(&self, w: &mut W, e: &OutEvent<'_>) -> io::Result<()> {
        let name = &self.names[e.name as usize];
        match e.kind {
            Kind::Slice { track, dur } if dur > 0 => {
                let t = &self.tracks[track.0];
                w.write_all(b"{\"ph\":\"X\",\"name\":")?;
                write_string(w, name)?;
                write!(
                    w,
                    ",\"pid\":{},\"tid\":{},\"ts\":{},\"dur\":{}",
                    self.processes[t.process].pid,
                    t.tid,
                    Micros(e.ts),
                    Micros(dur)
                )?;
            }
            // A zero-length slice is an instant: viewers draw a marker, not an invisible box.
            Kind::Instant { track } | Kind::Slice { track, .. } => {
                let t = &self.tracks[track.0];
                w.write_all(b"{\"ph\":\"i\",\"s\":\"t\",\"name\":")?;
                write_string(w, name)?;
                write!(
                    w,
                    ",\"pid\":{},\"tid\":{},\"ts\":{}",
                    self.processes[t.process].pid,
                    t.tid,
                    Micros(e.ts)
                )?;
            }
            Kind::Counter { process, value } => {
                w.write_all(b"{\"ph\":\"C\",\"name\":")?;
                write_string(w, name)?;
                write!(
                    w,
                    ",\"pid\":{},\"ts\":{},\"args\":{{\"value\":{value}}}}}",
                    self.processes[process].pid,
                    Micros(e.ts)
                )?;
                return Ok(());
            }
            Kind::Flow { track, id, step } => {
                let t = &self.tracks[track.0];
                write!(
                    w,
                    "{{\"ph\":\"{}\",\"cat\":\"flow\",\"name\":",
                    step.phase()
                )?;
                write_string(w, name)?;
                write!(
                    w,
                    ",\"id\":{id},\"pid\":{},\"tid\":{},\"ts\":{},\"bp\":\"e\"}}",
                    self.processes[t.process].pid,
                    t.tid,
                    Micros(e.ts)
                )?;
                return Ok(());
            }
        }
        let args = e.args.map();
        if !args.is_empty() {
            w.write_all(b",\"args\":")?;
            write_object(w, &args)?;
        }
        w.write_all(b"}")
    }

    /// Every event to write, sorted: recorded ones, merged grouped slices and carried counters.
    fn output_events(&self) -> Vec<OutEvent<'_>> {
        let mut out: Vec<OutEvent<'_>> = self
            .events
            .iter()
            .map(|e| OutEvent {
                ts: e.ts,
                rank: 1,
                seq: e.seq,
                name: e.name,
                kind: e.kind,
                args: OutArgs::Recorded(&e.args),
            })
            .collect();
        self.grouped_events(&mut out);
        self.carried_counters(&mut out);
        // `seq` is unique, so this is a total order and the sort's stability is irrelevant.
        out.sort_unstable_by_key(|e| {
            let dur = match e.kind {
                Kind::Slice { dur, .. } => dur,
                _ => 0,
            };
            (e.ts, e.rank, Reverse(dur), e.seq)
        });
        out
    }

    fn grouped_events<'a>(&'a self, out: &mut Vec<OutEvent<'a>>) {
        for (&(track, name, min_gap), runs) in &self.groups {
            let mut runs = runs.clone();
            runs.sort_unstable_by_key(|g| (g.start, g.seq));
            let mut merged: Vec<Group> = Vec::with_capacity(runs.len());
            for g in runs {
                match merged.last_mut() {
                    Some(last) if g.start < last.end.saturating_add(min_gap) => {
                        last.end = last.end.max(g.end);
                        last.count += g.count;
                        last.clipped |= g.clipped;
                        last.seq = last.seq.min(g.seq);
                    }
                    _ => merged.push(g),
                }
            }
            for g in merged {
                out.push(OutEvent {
                    ts: g.start,
                    rank: 1,
                    seq: g.seq,
                    name,
                    kind: Kind::Slice {
                        track,
                        dur: g.end - g.start,
                    },
                    args: OutArgs::Group {
                        count: g.count,
                        clipped: g.clipped,
                    },
                });
            }
        }
    }

    /// Adds, at the window start, each counter's last value from before the window, unless the
    /// counter has a sample of its own exactly there.
    fn carried_counters<'a>(&'a self, out: &mut Vec<OutEvent<'a>>) {
        let start = self.window.start.as_ps();
        let sampled_at_start: BTreeSet<(usize, u32)> = self
            .events
            .iter()
            .filter(|e| e.ts == start)
            .filter_map(|e| match e.kind {
                Kind::Counter { process, .. } => Some((process, e.name)),
                _ => None,
            })
            .collect();
        for (&(process, name), sample) in &self.counter_carry {
            if sampled_at_start.contains(&(process, name)) {
                continue;
            }
            out.push(OutEvent {
                ts: start,
                // Before anything else at the window start.
                rank: 0,
                seq: sample.seq,
                name,
                kind: Kind::Counter {
                    process,
                    value: sample.value,
                },
                args: OutArgs::None,
            });
        }
    }

    fn process(&mut self, name: &str) -> usize {
        if let Some(&p) = self.process_ids.get(name) {
            return p;
        }
        let pid = self.fresh_id();
        let p = self.processes.len();
        self.processes.push(Process {
            name: name.to_owned(),
            pid,
            threads: HashMap::new(),
        });
        self.process_ids.insert(name.to_owned(), p);
        p
    }

    fn fresh_id(&mut self) -> u32 {
        let id = self.next_id;
        self.next_id += 1;
        id
    }

    fn next_seq(&mut self) -> u64 {
        let seq = self.seq;
        self.seq += 1;
        seq
    }

    fn intern(&mut self, name: &str) -> u32 {
        if let Some(&id) = self.name_ids.get(name) {
            return id;
        }
        let id = self.names.len() as u32;
        self.names.push(name.to_owned());
        self.name_ids.insert(name.to_owned(), id);
        id
    }
}

/// The whole JSON text (what [`ChromeTrace::write`] writes).
impl fmt::Display for ChromeTrace {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut bytes = Vec::new();
        self.write(&mut bytes).map_err(|_| fmt::Error)?;
        f.write_str(std::str::from_utf8(&bytes).map_err(|_| fmt::Error)?)
    }
}

/// An event as written: borrowed from the recorded ones where possible.
struct OutEvent<'a> {
    ts: u64,
    /// Orders events at equal timestamps before duration and sequence: 0 for values carried to
    /// the window start, which later samples at the same instant must override.
    rank: u8,
    seq: u64,
    name: u32,
    kind: Kind,
    args: OutArgs<'a>,
}

/// An output event's args: a recorded event's own, or a merged run's `count` and `clipped`,
/// made only as the event is written (a run of Renderer commands is most of a trace's events,
/// and a map per run held them all at once: 80 MB of the 131 MB peak of a traced 10,000-triangle
/// run, by massif).
#[derive(Clone, Copy, Debug)]
enum OutArgs<'a> {
    Recorded(&'a Args),
    Group { count: u64, clipped: bool },
    None,
}

impl OutArgs<'_> {
    /// The args as a map, borrowed where they were recorded.
    fn map(&self) -> Cow<'_, Args> {
        match *self {
            OutArgs::Recorded(args) => Cow::Borrowed(args),
            OutArgs::Group { count, clipped } => {
                let mut args = Args::new();
                args.insert("count".to_owned(), JsonValue::from(count));
                if clipped {
                    args.insert("clipped".to_owned(), JsonValue::Bool(true));
                }
                Cow::Owned(args)
            }
            OutArgs::None => Cow::Owned(Args::new()),
        }
    }
}

/// Picoseconds written as microseconds with exactly six fractional digits, by integer arithmetic.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Micros(pub u64);

impl fmt::Display for Micros {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.{:06}", self.0 / 1_000_000, self.0 % 1_000_000)
    }
}

/// A slice named in a [`NestingError`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SliceSpan {
    /// The slice's name.
    pub name: String,
    /// Its start, after clipping to the window.
    pub start: Tick,
    /// Its end, after clipping to the window.
    pub end: Tick,
}

/// Two slices on one track that overlap without one enclosing the other.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NestingError {
    /// The track's process name.
    pub process: String,
    /// The track's thread name.
    pub thread: String,
    /// The slice that starts first (or is longer, when both start together).
    pub outer: SliceSpan,
    /// The slice that starts inside `outer` but ends after it.
    pub inner: SliceSpan,
}

impl fmt::Display for NestingError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "on track {}/{}, slice `{}` [{}, {}) starts inside slice `{}` [{}, {}) but ends after it",
            self.process,
            self.thread,
            self.inner.name,
            self.inner.start,
            self.inner.end,
            self.outer.name,
            self.outer.start,
            self.outer.end
        )
    }
}

impl std::error::Error for NestingError {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn micros_are_exact_to_the_picosecond() {
        assert_eq!(Micros(0).to_string(), "0.000000");
        assert_eq!(Micros(1).to_string(), "0.000001");
        assert_eq!(Micros(25_000).to_string(), "0.025000");
        assert_eq!(Micros(1_000_000).to_string(), "1.000000");
        assert_eq!(Micros(u64::MAX).to_string(), "18446744073709.551615");
    }
}
