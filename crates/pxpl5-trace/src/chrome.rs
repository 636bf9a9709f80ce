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
//! * **Memory.** An event is rendered to its line of JSON as it is recorded and kept with its
//!   place in the order. By default everything is held until [`ChromeTrace::write`]; a trace
//!   made with [`ChromeTrace::spill_to`] (the CLI's) holds at most [`SPILL_AT`] bytes of lines
//!   and as many of grouped runs, writing each batch beyond that, sorted, to an anonymous
//!   temporary file, and `write` merges the files (`spill.rs`). The bytes are the same either
//!   way; a long run's trace then costs disk, not memory.
//! * One event per line, so traces diff and grep well.

use std::cmp::Reverse;
use std::collections::btree_map::Entry;
use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::fmt;
use std::io::{self, Write};
use std::path::PathBuf;

use pxpl5_sim::Tick;

use crate::json::{JsonValue, write_object, write_string};
use crate::spill::{ExternalSort, SortKey, merge};
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

/// A run of grouped slices merged so far. Ordered by start, then recording order: the order
/// runs of one key merge in.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
struct Group {
    start: u64,
    /// The smallest recording sequence number of its members: its place among equal timestamps.
    seq: u64,
    end: u64,
    count: u64,
    clipped: bool,
}

impl Group {
    /// Takes in `other`, a run that continues this one.
    fn absorb(&mut self, other: Group) {
        self.end = self.end.max(other.end);
        self.count += other.count;
        self.clipped |= other.clipped;
        self.seq = self.seq.min(other.seq);
    }
}

/// Identifies the slices that may merge: same track, same name, same `min_gap`.
type GroupKey = (TrackId, u32, u64);

/// A run of grouped slices with its key, kept for the output's merge in key order, then the
/// run's own.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
struct GroupRun(GroupKey, Group);

impl SortKey for GroupRun {
    const BYTES: usize = 53;

    fn put(&self, b: &mut [u8]) {
        let GroupRun((TrackId(track), name, min_gap), g) = *self;
        b[0..8].copy_from_slice(&(track as u64).to_le_bytes());
        b[8..12].copy_from_slice(&name.to_le_bytes());
        for (i, v) in [min_gap, g.start, g.seq, g.end, g.count]
            .into_iter()
            .enumerate()
        {
            b[12 + 8 * i..20 + 8 * i].copy_from_slice(&v.to_le_bytes());
        }
        b[52] = u8::from(g.clipped);
    }

    fn get(b: &[u8]) -> GroupRun {
        let u = |i: usize| u64::from_le_bytes(b[i..i + 8].try_into().expect("8 bytes"));
        let name = u32::from_le_bytes(b[8..12].try_into().expect("4 bytes"));
        let g = Group {
            start: u(20),
            seq: u(28),
            end: u(36),
            count: u(44),
            clipped: b[52] != 0,
        };
        GroupRun((TrackId(u(0) as usize), name, u(12)), g)
    }
}

#[derive(Clone, Copy, Debug)]
struct CounterSample {
    at: u64,
    seq: u64,
    value: i64,
}

/// An event's place in the output (by timestamp, then `rank`, then longer slices first, then
/// recording order) beside its JSON text, which is made as it is recorded (its process and
/// thread ids and its name are known by then).
#[derive(Clone, Copy, Debug)]
struct LineKey {
    ts: u64,
    /// 0 for a counter's value carried to the window start, which later samples at the same
    /// instant must override; 1 for everything else.
    rank: u8,
    /// A slice's duration (0 for the other kinds).
    dur: u64,
    seq: u64,
    /// A slice's track and name, for [`ChromeTrace::check_nesting`]; `NOT_A_SLICE` otherwise.
    track: u32,
    name: u32,
}

/// [`LineKey::track`] of an event that is not a slice.
const NOT_A_SLICE: u32 = u32::MAX;

impl LineKey {
    fn order(&self) -> (u64, u8, Reverse<u64>, u64) {
        (self.ts, self.rank, Reverse(self.dur), self.seq)
    }
}

// `seq` is unique, so the order is total and equal orders mean the same event.
impl PartialEq for LineKey {
    fn eq(&self, other: &LineKey) -> bool {
        self.order() == other.order()
    }
}
impl Eq for LineKey {}
impl PartialOrd for LineKey {
    fn partial_cmp(&self, other: &LineKey) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for LineKey {
    fn cmp(&self, other: &LineKey) -> std::cmp::Ordering {
        self.order().cmp(&other.order())
    }
}

impl SortKey for LineKey {
    const BYTES: usize = 33;

    fn put(&self, b: &mut [u8]) {
        b[0..8].copy_from_slice(&self.ts.to_le_bytes());
        b[8] = self.rank;
        b[9..17].copy_from_slice(&self.dur.to_le_bytes());
        b[17..25].copy_from_slice(&self.seq.to_le_bytes());
        b[25..29].copy_from_slice(&self.track.to_le_bytes());
        b[29..33].copy_from_slice(&self.name.to_le_bytes());
    }

    fn get(b: &[u8]) -> LineKey {
        let u64_at = |i: usize| u64::from_le_bytes(b[i..i + 8].try_into().expect("8 bytes"));
        let u32_at = |i: usize| u32::from_le_bytes(b[i..i + 4].try_into().expect("4 bytes"));
        LineKey {
            ts: u64_at(0),
            rank: b[8],
            dur: u64_at(9),
            seq: u64_at(17),
            track: u32_at(25),
            name: u32_at(29),
        }
    }
}

/// How many bytes of events a trace that spills ([`ChromeTrace::spill_to`]) holds in memory
/// before it writes a sorted run to disk; the grouped runs have a budget of their own, as
/// large.
pub const SPILL_AT: usize = 4 << 20;

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
    /// The recorded events, rendered.
    lines: ExternalSort<LineKey>,
    // BTreeMaps, not HashMaps, where iteration feeds the output: the final sort makes the order
    // total anyway, but no output should ever hinge on hash order.
    /// Per key, its latest run, which the next slice of the key may continue.
    open: BTreeMap<GroupKey, Group>,
    /// The runs that are no longer the latest of their key.
    closed: ExternalSort<GroupRun>,
    /// Per (process, counter name): the latest sample before the window start.
    counter_carry: BTreeMap<(usize, u32), CounterSample>,
    /// The counters with a sample of their own at the window start: nothing is carried to them.
    sampled_at_start: BTreeSet<(usize, u32)>,
    seq: u64,
    /// Where an event is rendered before it is kept (host work only).
    scratch: Vec<u8>,
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
            lines: ExternalSort::default(),
            open: BTreeMap::new(),
            closed: ExternalSort::default(),
            counter_carry: BTreeMap::new(),
            sampled_at_start: BTreeSet::new(),
            seq: 0,
            scratch: Vec::new(),
        }
    }

    /// This trace with bounded memory: past [`SPILL_AT`] bytes of events, it sorts what it holds
    /// and writes it to an anonymous temporary file in `dir` (gone when the trace is), and
    /// [`ChromeTrace::write`] merges the files. The output is the same bytes as without. Call it
    /// before recording; a spill's error is returned by `write`.
    pub fn spill_to(self, dir: PathBuf) -> ChromeTrace {
        self.spill_at(dir, SPILL_AT)
    }

    /// [`ChromeTrace::spill_to`] with a budget of `bytes` (tests spill small traces with it).
    pub fn spill_at(mut self, dir: PathBuf, bytes: usize) -> ChromeTrace {
        self.lines = ExternalSort::spilling(dir.clone(), bytes);
        self.closed = ExternalSort::spilling(dir, bytes);
        self
    }

    /// How many sorted runs went to disk so far (0 unless [`ChromeTrace::spill_to`]).
    pub fn spilled_runs(&self) -> usize {
        self.lines.runs() + self.closed.runs()
    }

    /// The bytes of events held in memory now: for a trace that spills, at most about twice its
    /// budget, whatever the length of the run.
    pub fn held_bytes(&self) -> usize {
        self.lines.held()
            + self.closed.held()
            + self.open.len() * std::mem::size_of::<(GroupKey, Group)>()
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
        let (seq, name) = (self.next_seq(), self.intern(name));
        let dur = end - start;
        self.record(start, seq, name, Kind::Slice { track, dur }, &args);
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
        let run = Group {
            start,
            end,
            count: 1,
            clipped,
            seq,
        };
        // Merge into the latest run when this slice continues it; anything else (an early slice
        // recorded late) starts a run of its own, and `merged_groups` merges runs on output.
        let last = match self.open.entry(key) {
            Entry::Vacant(v) => {
                v.insert(run);
                return;
            }
            Entry::Occupied(o) => o.into_mut(),
        };
        if start >= last.start && start < last.end.saturating_add(min_gap.as_ps()) {
            last.absorb(run);
            return;
        }
        let done = std::mem::replace(last, run);
        self.closed.push(GroupRun(key, done), &[]);
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
        let (seq, name) = (self.next_seq(), self.intern(name));
        self.record(at.as_ps(), seq, name, kind, &args);
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
        if at == self.window.start.as_ps() {
            self.sampled_at_start.insert((process, name));
        }
        self.record(
            at,
            seq,
            name,
            Kind::Counter { process, value },
            &Args::new(),
        );
    }

    /// Checks that on every track the slices to be written (after clipping and grouping) are
    /// properly nested or disjoint, which Perfetto needs to draw them: `Some` names the first
    /// pair that overlaps without nesting (boxed: it is large and rare). Reads the spilled runs
    /// again, and fails with their error (or a spill's) if there is one.
    pub fn check_nesting(&self) -> io::Result<Option<Box<NestingError>>> {
        // Output order puts an enclosing slice before what it encloses, so a stack of open
        // slices per track suffices, over the merged output as it comes.
        let mut open: BTreeMap<u32, Vec<(u64, u64, u32)>> = BTreeMap::new();
        let mut found = None;
        self.output(|line, _| {
            if line.track == NOT_A_SLICE || found.is_some() {
                return Ok(());
            }
            let (start, end, name) = (line.ts, line.ts + line.dur, line.name);
            let stack = open.entry(line.track).or_default();
            while stack.last().is_some_and(|&(_, e, _)| e <= start) {
                stack.pop();
            }
            if let Some(&(o_start, o_end, o_name)) = stack.last()
                && end > o_end
            {
                let t = &self.tracks[line.track as usize];
                found = Some(Box::new(NestingError {
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
            stack.push((start, end, name));
            Ok(())
        })?;
        Ok(found)
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
        self.output(|_, text| {
            separator(&mut w)?;
            w.write_all(text)
        })?;
        w.write_all(b"\n]}\n")
    }

    /// The JSON text of an event.
    /// Records the event, rendered.
    fn record(&mut self, ts: u64, seq: u64, name: u32, kind: Kind, args: &Args) {
        let mut scratch = std::mem::take(&mut self.scratch);
        let key = self.line(&mut scratch, ts, seq, name, kind, args);
        self.lines.push(key, &scratch);
        self.scratch = scratch;
    }

    /// The event's key, its text rendered in `scratch` (cleared first).
    fn line(
        &self,
        scratch: &mut Vec<u8>,
        ts: u64,
        seq: u64,
        name: u32,
        kind: Kind,
        args: &Args,
    ) -> LineKey {
        scratch.clear();
        self.render(scratch, ts, name, kind, args)
            .expect("writing to a Vec cannot fail");
        let (track, dur) = match kind {
            Kind::Slice { track, dur } => (track.0 as u32, dur),
            _ => (NOT_A_SLICE, 0),
        };
        LineKey {
            ts,
            rank: 1,
            dur,
            seq,
            track,
            name,
        }
    }

    fn render(
        &self,
        w: &mut Vec<u8>,
        ts: u64,
        name: u32,
        kind: Kind,
        args: &Args,
    ) -> io::Result<()> {
        let name = &self.names[name as usize];
        // Numbers by itoa, not `write!`: the formatting machinery was a third of a traced run's
        // trace work (callgrind), for the same digits.
        let mut n = itoa::Buffer::new();
        // `,"pid":P,"tid":T,"ts":TS` of an event on a track.
        let on_track = |w: &mut Vec<u8>, n: &mut itoa::Buffer, track: TrackId| {
            let t = &self.tracks[track.0];
            w.extend_from_slice(b",\"pid\":");
            w.extend_from_slice(n.format(self.processes[t.process].pid).as_bytes());
            w.extend_from_slice(b",\"tid\":");
            w.extend_from_slice(n.format(t.tid).as_bytes());
            w.extend_from_slice(b",\"ts\":");
            Micros(ts).write_to(w);
        };
        match kind {
            Kind::Slice { track, dur } if dur > 0 => {
                w.extend_from_slice(b"{\"ph\":\"X\",\"name\":");
                write_string(w, name)?;
                on_track(w, &mut n, track);
                w.extend_from_slice(b",\"dur\":");
                Micros(dur).write_to(w);
            }
            // A zero-length slice is an instant: viewers draw a marker, not an invisible box.
            Kind::Instant { track } | Kind::Slice { track, .. } => {
                w.extend_from_slice(b"{\"ph\":\"i\",\"s\":\"t\",\"name\":");
                write_string(w, name)?;
                on_track(w, &mut n, track);
            }
            Kind::Counter { process, value } => {
                w.extend_from_slice(b"{\"ph\":\"C\",\"name\":");
                write_string(w, name)?;
                w.extend_from_slice(b",\"pid\":");
                w.extend_from_slice(n.format(self.processes[process].pid).as_bytes());
                w.extend_from_slice(b",\"ts\":");
                Micros(ts).write_to(w);
                w.extend_from_slice(b",\"args\":{\"value\":");
                w.extend_from_slice(n.format(value).as_bytes());
                w.extend_from_slice(b"}}");
                return Ok(());
            }
            Kind::Flow { track, id, step } => {
                w.extend_from_slice(b"{\"ph\":\"");
                w.extend_from_slice(step.phase().as_bytes());
                w.extend_from_slice(b"\",\"cat\":\"flow\",\"name\":");
                write_string(w, name)?;
                w.extend_from_slice(b",\"id\":");
                w.extend_from_slice(n.format(id).as_bytes());
                on_track(w, &mut n, track);
                w.extend_from_slice(b",\"bp\":\"e\"}");
                return Ok(());
            }
        }
        if !args.is_empty() {
            w.write_all(b",\"args\":")?;
            write_object(w, args)?;
        }
        w.write_all(b"}")
    }

    /// Calls `f` with every event to write, in order, and its text: the recorded ones, the
    /// merged grouped slices and the carried counters.
    fn output(&self, mut f: impl FnMut(LineKey, &[u8]) -> io::Result<()>) -> io::Result<()> {
        let mut scratch = Vec::new();
        let groups = self.merged_groups(&mut scratch)?;
        let mut carried = ExternalSort::default();
        self.carried_counters(&mut scratch, &mut carried);
        merge(&[&self.lines, &groups, &carried], |key, text| f(key, text))
    }

    /// The grouped slices' runs merged, each run one slice: runs of a key merge, in start and
    /// recording order, while each starts less than `min_gap` after the end so far.
    fn merged_groups(&self, scratch: &mut Vec<u8>) -> io::Result<ExternalSort<LineKey>> {
        let mut out = self.lines.like();
        let mut open = ExternalSort::default();
        for (&key, &g) in &self.open {
            open.push(GroupRun(key, g), &[]);
        }
        let mut current: Option<GroupRun> = None;
        merge(&[&self.closed, &open], |run, _| {
            let GroupRun(key, g) = run;
            match &mut current {
                Some(GroupRun(last_key, last))
                    if *last_key == key && g.start < last.end.saturating_add(key.2) =>
                {
                    last.absorb(g);
                }
                _ => {
                    if let Some(done) = current.replace(run) {
                        let key = self.group_line(scratch, done);
                        out.push(key, scratch);
                    }
                }
            }
            Ok(())
        })?;
        if let Some(done) = current {
            let key = self.group_line(scratch, done);
            out.push(key, scratch);
        }
        Ok(out)
    }

    /// A merged run as a slice, with the args `count` and, if a member was, `clipped`.
    fn group_line(&self, scratch: &mut Vec<u8>, GroupRun(key, g): GroupRun) -> LineKey {
        let (track, name, _) = key;
        let mut args = Args::new();
        args.insert("count".to_owned(), JsonValue::from(g.count));
        if g.clipped {
            args.insert("clipped".to_owned(), JsonValue::Bool(true));
        }
        let kind = Kind::Slice {
            track,
            dur: g.end - g.start,
        };
        self.line(scratch, g.start, g.seq, name, kind, &args)
    }

    /// Adds, at the window start, each counter's last value from before the window, unless the
    /// counter has a sample of its own exactly there.
    fn carried_counters(&self, scratch: &mut Vec<u8>, out: &mut ExternalSort<LineKey>) {
        let start = self.window.start.as_ps();
        for (&(process, name), sample) in &self.counter_carry {
            if self.sampled_at_start.contains(&(process, name)) {
                continue;
            }
            let kind = Kind::Counter {
                process,
                value: sample.value,
            };
            let mut key = self.line(scratch, start, sample.seq, name, kind, &Args::new());
            // Before anything else at the window start.
            key.rank = 0;
            out.push(key, scratch);
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

/// Picoseconds written as microseconds with exactly six fractional digits, by integer arithmetic.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Micros(pub u64);

impl Micros {
    /// Appends the text to `out`, as `Display` writes it.
    pub fn write_to(self, out: &mut Vec<u8>) {
        let mut n = itoa::Buffer::new();
        out.extend_from_slice(n.format(self.0 / 1_000_000).as_bytes());
        out.push(b'.');
        let frac = n.format(self.0 % 1_000_000).as_bytes();
        out.extend_from_slice(&b"000000"[frac.len()..]);
        out.extend_from_slice(frac);
    }
}

impl fmt::Display for Micros {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut text = Vec::with_capacity(24);
        self.write_to(&mut text);
        f.write_str(std::str::from_utf8(&text).map_err(|_| fmt::Error)?)
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
