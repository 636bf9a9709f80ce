//! What the machine records as it runs: program phase marks (always, for the stats) and, on
//! request, Chrome trace and VCD events in simulated time.
//!
//! Tracks (Chrome trace, or Perfetto's format): first, process `Critical path`, whose track
//! `unit and activity` shows over simulated time which unit, doing what, held the run's critical
//! path (the stats' `critical_path` attribution, segment by segment: its slices' lengths per
//! category sum to the stats' figures; see `critical`); per GP its phases (named as in the stats' `phases`) and its busy time,
//! as `compute`, `message send` and `message receive` slices (the stats' critical-path
//! categories); per Renderer its commands, grouped into runs of back-to-back commands of one kind
//! (there are too many to show one by one); per ring channel a process `Ring channel C` whose
//! `lane N` tracks hold the messages that channel carried (a message goes on the first lane free
//! at its send time, so slices on a lane never overlap; a message whose packets took several
//! channels goes to `Ring channels A+B`), with a counter of whether the channel's token is held;
//! process `Ring queues`: per node the words in its output and input queues.
//!
//! Flows: every message is one flow, id = its ring message id, from the sender's slice (the GP's
//! `message send`, or the Renderer's readback command) through its ring slice to the receiver's
//! work on it (the GP's `message receive`; a Renderer's first, readback and last commands of it).
//! A readback's reply starts at the readback command, where the flow of the command message
//! that asked for it passes, and its ring slice names that message in the arg `answers`.
//!
//! VCD: per GP and per Renderer a busy wire; per ring channel the token's position as the name of
//! the node it is at (a string variable; a `$comment` lists the ring order) and whether it is
//! held. Ring signals are sampled at every instant the machine acts (the ring's own edges in
//! between are not visible).

use std::collections::{BTreeMap, VecDeque};

use pxpl5_ring::{Delivery, MessageId, NodeId, Ring};
use pxpl5_sim::Tick;
use pxpl5_trace::{
    Args, ChromeTrace, EventTrace, FlowStep, JsonValue, PerfettoTrace, SignalId, TextValue,
    TraceWindow, TrackId, VcdTrace,
};

use crate::critical::PathSegment;
use crate::gp::Unit;
use crate::gp_node::Busy;
use crate::renderer_node::Started;
use crate::stats::PhaseSpan;

/// The name every message flow carries (Perfetto links a flow's events by name and id).
const FLOW: &str = "message";

struct Tracks {
    critical: TrackId,
    gp: Vec<TrackId>,
    gp_phase: Vec<TrackId>,
    renderer: Vec<TrackId>,
    /// Per set of channels a message used (bit mask): its lanes.
    lanes: BTreeMap<u64, Vec<Lane>>,
}

/// A track ring messages are drawn on, and when its last message ends (a message goes on the
/// first lane free at its send time, so slices on a lane never overlap).
struct Lane {
    track: TrackId,
    free_from: Tick,
}

/// A phase mark of one GP.
struct Mark {
    gp: u32,
    name: &'static str,
    at: Tick,
}

/// One phase of one GP: from its mark to the GP's next mark or its program's end.
struct GpPhase {
    gp: u32,
    name: &'static str,
    start: Tick,
    end: Tick,
}

/// Each phase name's figures, summed as the marks come: the stats' phase spans.
///
/// Summed at the mark, not from a list of marks at the run's end: the main job's hemicube
/// marks hundreds of thousands of phases, and a list of them (kept only for a trace, which
/// draws every GP's phases) took page faults as it grew and a pass at the end (together about
/// 1.5 % of its CPU time by `perf record -e cpu-clock`). The figures are the same: a phase's
/// time is added, and its ends compared, whatever the order.
#[derive(Default)]
struct PhaseSums {
    /// Per name, in order of its first mark.
    sums: Vec<PhaseSum>,
    /// Per GP: its open phase (name, start) and how many marks it has made.
    open: Vec<(Option<(&'static str, Tick)>, usize)>,
}

/// One phase name's figures so far, and where it first appears in GP-major order.
#[derive(Clone, Copy)]
struct PhaseSum {
    name: &'static str,
    first_start: Tick,
    last_end: Tick,
    gp_time: Tick,
    first_seen: (u32, usize),
}

impl PhaseSum {
    /// A phase of this name lasted from `start` to `stop`.
    fn close(&mut self, start: Tick, stop: Tick) {
        self.first_start = self.first_start.min(start);
        self.last_end = self.last_end.max(stop);
        self.gp_time += stop - start;
    }
}

impl PhaseSums {
    /// The figures of phase `name`. Names are `'static` and nearly always the same literal:
    /// compared by address first.
    fn find<'a>(sums: &'a mut [PhaseSum], name: &'static str) -> Option<&'a mut PhaseSum> {
        sums.iter_mut()
            .find(|a| std::ptr::eq(a.name, name) || a.name == name)
    }

    /// GP `gp` marked phase `name` at `at`: its open phase ends there.
    fn mark(&mut self, gp: u32, name: &'static str, at: Tick) {
        let g = gp as usize;
        if self.open.len() <= g {
            self.open.resize(g + 1, (None, 0));
        }
        let (current, count) = &mut self.open[g];
        if let Some((was, start)) = current.take() {
            Self::find(&mut self.sums, was)
                .expect("a phase's name was seen at its mark")
                .close(start, at);
        }
        let seen = (gp, *count);
        *count += 1;
        *current = Some((name, at));
        match Self::find(&mut self.sums, name) {
            Some(a) => a.first_seen = a.first_seen.min(seen),
            None => self.sums.push(PhaseSum {
                name,
                first_start: at,
                last_end: at,
                gp_time: Tick::ZERO,
                first_seen: seen,
            }),
        }
    }

    /// The spans, each GP's open phase ended at its program's end (`gp_end`) or the run's.
    fn spans(&self, gp_end: &BTreeMap<u32, Tick>, end: Tick) -> Vec<PhaseSpan> {
        let mut sums = self.sums.clone();
        for (g, (current, _)) in self.open.iter().enumerate() {
            if let Some((name, start)) = *current {
                let stop = gp_end.get(&(g as u32)).copied().unwrap_or(end);
                Self::find(&mut sums, name)
                    .expect("a phase's name was seen at its mark")
                    .close(start, stop);
            }
        }
        sums.sort_by_key(|a| a.first_seen);
        sums.into_iter()
            .map(|a| PhaseSpan {
                name: a.name.to_string(),
                first_start: a.first_start,
                last_end: a.last_end,
                gp_time: a.gp_time,
            })
            .collect()
    }
}

struct Signals {
    gp: Vec<SignalId>,
    renderer: Vec<SignalId>,
    token_at: Vec<SignalId>,
    token_held: Vec<SignalId>,
    /// The values of `token_at`: each node's unit, named once (the token moves at every hop).
    node_text: Vec<TextValue>,
    /// The value of `token_at` for a channel whose token is nowhere.
    no_node: TextValue,
}

/// Names of the event trace's counters, made once (a counter changes at many instants).
#[derive(Default)]
struct CounterNames {
    /// Per node: its output and input queue counters.
    queues: Vec<(String, String)>,
    /// Per channel: the process its `token held` counter belongs to.
    channels: Vec<String>,
}

/// What the flows need to remember between a message's events; all of it is bounded by the
/// messages in flight.
#[derive(Default)]
struct Flows {
    /// Per GP, its latest busy slice: a send's flow starts in the `message send` slice before it.
    gp_last_busy: Vec<(Tick, Tick)>,
    /// Per GP, the messages handed to it and not yet received, in mailbox order.
    gp_inbox: Vec<VecDeque<MessageId>>,
    /// Per Renderer, its latest readback command's slice and the message it came in.
    readback: Vec<Option<(Tick, Tick, MessageId)>>,
    /// Readback replies on the ring, with the command message they answer.
    answers: BTreeMap<MessageId, MessageId>,
}

/// The machine's recorder.
#[derive(Default)]
pub struct Recorder {
    /// The event trace (`--trace`): Chrome JSON or Perfetto's format.
    trace: Option<EventTrace>,
    vcd: Option<VcdTrace>,
    tracks: Option<Tracks>,
    signals: Option<Signals>,
    flows: Flows,
    units: Vec<Unit>,
    /// Phase marks in mark order, for an event trace's phase slices.
    marks: Vec<Mark>,
    /// The phases' figures, for the stats.
    phase_sums: PhaseSums,
    /// GP end times, for the last phase's end.
    gp_end: BTreeMap<u32, Tick>,
    /// Last sampled output- and input-queue occupancy per node.
    queue_words: Vec<(u64, u64)>,
    /// Last sampled token state per channel: held, and (VCD) the node it is at.
    token: Vec<(bool, u32)>,
    counter_names: CounterNames,
    /// Renderer command slices shorter apart than this merge (one Renderer cycle).
    renderer_gap: Tick,
    /// Words of a node's ring output queue.
    queue_capacity: u64,
}

/// The middle of `[start, end)`: inside the slice (for a slice of two picoseconds or more), where
/// a flow binds to it whatever order a viewer reads equal timestamps in.
fn mid(start: Tick, end: Tick) -> Tick {
    Tick(start.0 + end.0.saturating_sub(start.0) / 2)
}

/// Channel numbers in a mask, joined by `sep`.
fn channel_list(mask: u64, sep: &str) -> String {
    (0..64)
        .filter(|c| mask & (1 << c) != 0)
        .map(|c: u32| c.to_string())
        .collect::<Vec<_>>()
        .join(sep)
}

impl Recorder {
    /// A recorder that writes a Chrome trace and/or a VCD limited to their windows.
    pub fn new(chrome: Option<TraceWindow>, vcd: Option<TraceWindow>) -> Recorder {
        Recorder::with_trace(chrome.map(|w| EventTrace::Chrome(ChromeTrace::new(w))), vcd)
    }

    /// A recorder that writes a Perfetto trace of `window` to `out` as the run goes (see
    /// [`PerfettoTrace`]), and a VCD if `vcd` says so; [`Recorder::finish_trace`] ends it.
    pub fn perfetto(
        window: TraceWindow,
        out: Box<dyn std::io::Write + Send>,
        vcd: Option<TraceWindow>,
    ) -> Recorder {
        Recorder::with_trace(
            Some(EventTrace::Perfetto(PerfettoTrace::new(window, out))),
            vcd,
        )
    }

    /// This recorder with its VCD written to `out` as the run goes (see [`VcdTrace::streamed`]),
    /// in the window it was asked for; [`Recorder::finish_vcd`] ends it. Without a VCD, the
    /// recorder is unchanged.
    pub fn stream_vcd(mut self, out: Box<dyn std::io::Write + Send>) -> Recorder {
        if let Some(v) = &self.vcd {
            self.vcd = Some(VcdTrace::streamed(v.window(), out));
        }
        self
    }

    /// This recorder with its Chrome trace's memory bounded: past `budget` bytes of events
    /// ([`pxpl5_trace::SPILL_AT`] is the CLI's), sorted runs go to anonymous files in `dir`
    /// (see [`ChromeTrace::spill_at`]); the output is the same. Without a Chrome trace, the
    /// recorder is unchanged.
    pub fn spill_chrome(mut self, dir: std::path::PathBuf, budget: usize) -> Recorder {
        self.trace = match self.trace.take() {
            Some(EventTrace::Chrome(c)) => Some(EventTrace::Chrome(c.spill_at(dir, budget))),
            other => other,
        };
        self
    }

    /// How many sorted runs the Chrome trace wrote to disk so far (0 without one).
    pub fn chrome_spilled_runs(&self) -> usize {
        match &self.trace {
            Some(EventTrace::Chrome(c)) => c.spilled_runs(),
            _ => 0,
        }
    }

    fn with_trace(trace: Option<EventTrace>, vcd: Option<TraceWindow>) -> Recorder {
        Recorder {
            trace,
            vcd: vcd.map(VcdTrace::new),
            ..Recorder::default()
        }
    }

    pub(crate) fn declare(
        &mut self,
        units: &[Unit],
        channels: u32,
        renderer_cycle: Tick,
        queue_capacity: u64,
    ) {
        self.units = units.to_vec();
        self.queue_capacity = queue_capacity;
        self.queue_words = vec![(0, 0); units.len()];
        self.token = vec![(false, u32::MAX); channels as usize];
        self.counter_names = CounterNames {
            queues: units
                .iter()
                .map(|u| (format!("{u} output words"), format!("{u} input words")))
                .collect(),
            channels: (0..channels.min(64))
                .map(|ch| format!("Ring channel {ch}"))
                .collect(),
        };
        self.renderer_gap = renderer_cycle;
        let gps = units.iter().filter(|u| matches!(u, Unit::Gp(_))).count();
        let renderers = units
            .iter()
            .filter(|u| matches!(u, Unit::Renderer(_)))
            .count();
        self.flows = Flows {
            gp_last_busy: vec![(Tick::ZERO, Tick::ZERO); gps],
            gp_inbox: vec![VecDeque::new(); gps],
            readback: vec![None; renderers],
            answers: BTreeMap::new(),
        };
        if let Some(c) = &mut self.trace {
            let critical = c.track("Critical path", "unit and activity");
            let mut gp_tracks = Vec::new();
            let mut phase_tracks = Vec::new();
            for g in 0..gps {
                phase_tracks.push(c.track("GPs", &format!("GP {g} phases")));
                gp_tracks.push(c.track("GPs", &format!("GP {g}")));
            }
            let renderer = (0..renderers)
                .map(|r| c.track("Renderers", &format!("Renderer {r}")))
                .collect();
            // Each channel's first lane now, so channels appear in order whatever carries first.
            let mut lanes = BTreeMap::new();
            for ch in 0..channels.min(64) {
                let track = c.track(&format!("Ring channel {ch}"), "lane 0");
                let lane = Lane {
                    track,
                    free_from: Tick::ZERO,
                };
                lanes.insert(1u64 << ch, vec![lane]);
            }
            c.metadata(
                "ring_order",
                units.iter().map(|u| u.to_string()).collect::<Vec<_>>(),
            );
            self.tracks = Some(Tracks {
                critical,
                gp: gp_tracks,
                gp_phase: phase_tracks,
                renderer,
                lanes,
            });
        }
        if let Some(v) = &mut self.vcd {
            let order: Vec<String> = units
                .iter()
                .enumerate()
                .map(|(i, u)| format!("{i} {u}"))
                .collect();
            v.comment(&format!(
                "ring order (node: unit), the values of chN_token_at: {}",
                order.join(", ")
            ));
            let gp_scope = v.scope("gps");
            let gp = (0..gps)
                .map(|g| v.wire(gp_scope, &format!("gp{g}_busy"), 1))
                .collect();
            let r_scope = v.scope("renderers");
            let renderer = (0..renderers)
                .map(|r| v.wire(r_scope, &format!("renderer{r}_busy"), 1))
                .collect();
            let ring_scope = v.scope("ring");
            let mut token_at = Vec::new();
            let mut token_held = Vec::new();
            for ch in 0..channels {
                token_at.push(v.text(ring_scope, &format!("ch{ch}_token_at"), "-"));
                token_held.push(v.wire(ring_scope, &format!("ch{ch}_busy"), 1));
            }
            let node_text = units.iter().map(|u| v.text_value(&u.to_string())).collect();
            let no_node = v.text_value("-");
            self.signals = Some(Signals {
                gp,
                renderer,
                token_at,
                token_held,
                node_text,
                no_node,
            });
        }
    }

    pub(crate) fn phase(&mut self, gp: u32, name: &'static str, at: Tick) {
        self.phase_sums.mark(gp, name, at);
        if self.trace.is_some() {
            self.marks.push(Mark { gp, name, at });
        }
    }

    pub(crate) fn gp_busy(&mut self, gp: u32, start: Tick, end: Tick, busy: Busy) {
        let g = gp as usize;
        if let (Some(c), Some(t)) = (&mut self.trace, &self.tracks) {
            let name = match busy {
                Busy::Compute => "compute",
                Busy::Send => "message send",
                Busy::Receive => "message receive",
            };
            c.slice_grouped(t.gp[g], name, start, end, Tick(1));
            if let Some(last) = self.flows.gp_last_busy.get_mut(g) {
                *last = (start, end);
            }
            if busy == Busy::Receive
                && let Some(id) = self.flows.gp_inbox.get_mut(g).and_then(VecDeque::pop_front)
            {
                c.flow(t.gp[g], FLOW, id.0, FlowStep::End, mid(start, end));
            }
        }
        if let (Some(v), Some(s)) = (&mut self.vcd, &self.signals) {
            // A GP does one thing at a time: its spans never overlap.
            v.span(s.gp[g], start, end);
        }
    }

    pub(crate) fn gp_done(&mut self, gp: u32, at: Tick) {
        self.gp_end.insert(gp, at);
    }

    pub(crate) fn renderer_command(&mut self, r: u32, started: &Started) {
        let &Started { start, end, .. } = started;
        let kind = started.kind();
        if let (Some(c), Some(t)) = (&mut self.trace, &self.tracks) {
            let track = t.renderer[r as usize];
            c.slice_grouped(track, kind, start, end, self.renderer_gap);
            // The message's flow passes its first, readback and last commands: enough to see
            // where its work begins, what it asked back, and where it ends.
            if started.first_in_message || started.last_in_message || started.readback {
                let step = if started.last_in_message {
                    FlowStep::End
                } else {
                    FlowStep::Step
                };
                c.flow(track, FLOW, started.message.0, step, mid(start, end));
            }
            if started.readback
                && let Some(last) = self.flows.readback.get_mut(r as usize)
            {
                *last = Some((start, end, started.message));
            }
        }
        if let (Some(v), Some(s)) = (&mut self.vcd, &self.signals) {
            // A board runs its commands one after another: its spans never overlap.
            v.span(s.renderer[r as usize], start, end);
        }
    }

    /// Message `id` left `from` (the ring took it) at `at`: its flow starts in the sender's slice.
    pub(crate) fn message_sent(&mut self, id: MessageId, from: Unit, at: Tick) {
        let (Some(c), Some(t)) = (&mut self.trace, &self.tracks) else {
            return;
        };
        match from {
            Unit::Gp(g) => {
                let (start, end) = self
                    .flows
                    .gp_last_busy
                    .get(g as usize)
                    .copied()
                    .unwrap_or((at, at));
                c.flow(
                    t.gp[g as usize],
                    FLOW,
                    id.0,
                    FlowStep::Start,
                    mid(start, end),
                );
            }
            Unit::Renderer(r) => {
                if let Some(Some((start, end, asked))) = self.flows.readback.get(r as usize) {
                    c.flow(
                        t.renderer[r as usize],
                        FLOW,
                        id.0,
                        FlowStep::Start,
                        mid(*start, *end),
                    );
                    self.flows.answers.insert(id, *asked);
                }
            }
            Unit::FrameBuffer | Unit::Host => {}
        }
    }

    /// Message `id` was handed to GP `gp`'s mailbox: its next receive takes it.
    pub(crate) fn handed_to_gp(&mut self, gp: u32, id: MessageId) {
        if self.trace.is_some()
            && let Some(inbox) = self.flows.gp_inbox.get_mut(gp as usize)
        {
            inbox.push_back(id);
        }
    }

    pub(crate) fn message_delivered(&mut self, d: &Delivery, from: Unit, to: Unit) {
        let (Some(c), Some(t)) = (&mut self.trace, &mut self.tracks) else {
            return;
        };
        let (sent, delivered) = (d.sent, d.delivered);
        let channels = d.channels;
        let lanes = t.lanes.entry(channels).or_default();
        let lane = match lanes.iter().position(|l| l.free_from <= sent) {
            Some(i) => i,
            None => {
                let process = if channels.count_ones() == 1 {
                    format!("Ring channel {}", channel_list(channels, ""))
                } else {
                    format!("Ring channels {}", channel_list(channels, "+"))
                };
                let track = c.track(&process, &format!("lane {}", lanes.len()));
                lanes.push(Lane {
                    track,
                    free_from: Tick::ZERO,
                });
                lanes.len() - 1
            }
        };
        lanes[lane].free_from = delivered;
        let track = lanes[lane].track;
        let n = self.units.len() as u32;
        let hops = (d.dst.0 + n - d.src.0) % n.max(1);
        let mut args: Vec<(&str, JsonValue)> = vec![
            ("id", JsonValue::from(d.id.0)),
            ("words", JsonValue::from(d.words)),
            ("packets", JsonValue::from(d.packets)),
            ("channels", JsonValue::from(channel_list(channels, ","))),
            ("hops", JsonValue::from(hops)),
            ("token_wait_ps", JsonValue::from((d.started - sent).0)),
        ];
        if let Some(asked) = self.flows.answers.remove(&d.id) {
            args.push(("answers", JsonValue::from(asked.0)));
        }
        c.slice(track, &format!("{from} -> {to}"), sent, delivered, args);
        // The frame buffer and the host have no track: a message to them ends on the ring.
        let step = match to {
            Unit::FrameBuffer | Unit::Host => FlowStep::End,
            Unit::Gp(_) | Unit::Renderer(_) => FlowStep::Step,
        };
        c.flow(track, FLOW, d.id.0, step, mid(sent, delivered));
    }

    pub(crate) fn ring_sample(&mut self, now: Tick, ring: &Ring) {
        if !self.records() {
            return;
        }
        if let Some(c) = &mut self.trace {
            let cap = self.queue_capacity;
            for (i, (out_name, in_name)) in self.counter_names.queues.iter().enumerate() {
                let node = NodeId(i as u32);
                let out = cap.saturating_sub(ring.output_free_words(node).unwrap_or(cap));
                let inp = cap.saturating_sub(ring.input_free_words(node).unwrap_or(cap));
                let (last_out, last_in) = self.queue_words[i];
                if out != last_out {
                    c.counter("Ring queues", out_name, now, out as i64);
                }
                if inp != last_in {
                    c.counter("Ring queues", in_name, now, inp as i64);
                }
                self.queue_words[i] = (out, inp);
            }
        }
        // Every change is recorded at the machine's current instant or later (a unit's busy
        // span, a Renderer command, a ring sample start now), and time never moves back.
        let mut sample = self.vcd.as_mut().map(|v| {
            v.settle(now);
            v.sample(now)
        });
        let channels = self.token.iter_mut().zip(ring.token_nodes()).enumerate();
        for (ch, (last, (node, held))) in channels {
            let node = node.0;
            let (was_held, was_at) = *last;
            if (held, node) == (was_held, was_at) {
                // Nothing for either trace to record.
                continue;
            }
            *last = (held, node);
            if held != was_held
                && let Some(c) = &mut self.trace
                && ch < 64
            {
                let process = &self.counter_names.channels[ch];
                c.counter(process, "token held", now, i64::from(held));
            }
            if let (Some(v), Some(s)) = (&mut sample, &self.signals) {
                if node != was_at {
                    let text = s.node_text.get(node as usize).copied();
                    v.change_to(s.token_at[ch], text.unwrap_or(s.no_node));
                }
                // Only a change: the VCD writes a wire only when its value changes, so a sample
                // equal to the last one would be dropped there anyway.
                if held != was_held {
                    v.change(s.token_held[ch], u64::from(held));
                }
            }
        }
    }

    /// Every GP's phases, GP by GP: a phase lasts until the GP's next mark or its program's end.
    fn gp_phases(&self, end: Tick) -> Vec<GpPhase> {
        let mut by_gp: BTreeMap<u32, Vec<&Mark>> = BTreeMap::new();
        for m in &self.marks {
            by_gp.entry(m.gp).or_default().push(m);
        }
        let mut out = Vec::new();
        for (gp, marks) in by_gp {
            let gp_end = self.gp_end.get(&gp).copied().unwrap_or(end);
            for (i, m) in marks.iter().enumerate() {
                out.push(GpPhase {
                    gp,
                    name: m.name,
                    start: m.at,
                    end: marks.get(i + 1).map_or(gp_end, |next| next.at),
                });
            }
        }
        out
    }

    /// Per-phase spans: for each phase name in order of first appearance (GP 0's marks first),
    /// its first start, last end and the GP time spent in it summed over GPs (see
    /// [`PhaseSums`]).
    pub(crate) fn phase_spans(&self, end: Tick) -> Vec<PhaseSpan> {
        self.phase_sums.spans(&self.gp_end, end)
    }

    /// Whether anything is recorded: an event trace or a VCD, which sample the ring at every
    /// instant of the machine's loop.
    pub(crate) fn records(&self) -> bool {
        self.trace.is_some() || self.vcd.is_some()
    }

    /// Whether an event trace is recorded (then the machine keeps its critical paths' segments).
    pub(crate) fn traces_events(&self) -> bool {
        self.trace.is_some()
    }

    /// Draws the run's critical path, `segments` in time order, on its track: each slice is named
    /// by its unit and activity (`GP 0: transform`, `ring transfer`, `Renderer 3: qee`, `GP 2:
    /// waits for ring queue space`), with
    /// args `category` (the stats' name), `resource` and `unit`.
    pub(crate) fn critical_path(&mut self, segments: &[PathSegment]) {
        let (Some(c), Some(t)) = (&mut self.trace, &self.tracks) else {
            return;
        };
        for s in segments {
            // Categories start with the kind of unit they are of: `GP transform` done by GP 0
            // is `GP 0: transform`.
            let kind = match s.unit {
                Some(Unit::Gp(_)) => "GP ",
                Some(Unit::Renderer(_)) => "Renderer ",
                _ => "",
            };
            let name = match (s.unit, s.activity.strip_prefix(kind)) {
                (Some(unit), Some(rest)) if !kind.is_empty() => format!("{unit}: {rest}"),
                _ => s.activity.clone(),
            };
            let mut args = vec![
                ("category", JsonValue::from(s.activity.as_str())),
                ("resource", JsonValue::from(s.resource.name())),
            ];
            if let Some(unit) = s.unit {
                args.push(("unit", JsonValue::from(unit.to_string())));
            }
            c.slice(t.critical, &name, s.start, s.end, args);
        }
    }

    pub(crate) fn close(&mut self, end: Tick) {
        // The phases are listed for the trace only: a run without one takes its phases' figures
        // from `phase_spans`.
        let spans = match (&self.trace, &self.tracks) {
            (Some(_), Some(_)) => self.gp_phases(end),
            _ => Vec::new(),
        };
        if let (Some(c), Some(t)) = (&mut self.trace, &self.tracks) {
            for p in spans {
                c.slice(
                    t.gp_phase[p.gp as usize],
                    p.name,
                    p.start,
                    p.end,
                    Args::new(),
                );
            }
            c.metadata("simulated_end_ps", end.0);
        }
        if let Some(v) = &mut self.vcd {
            v.set_end(end);
        }
    }

    /// Write the Chrome trace, if one was asked for.
    pub fn write_chrome(&self, w: impl std::io::Write) -> std::io::Result<bool> {
        match &self.trace {
            Some(EventTrace::Chrome(c)) => c.write(w).map(|_| true),
            _ => Ok(false),
        }
    }

    /// End the Perfetto trace, if one was asked for: write what it still holds and flush its
    /// writer. Returns whether there was one, or its first write error.
    pub fn finish_trace(&mut self) -> std::io::Result<bool> {
        match &mut self.trace {
            Some(EventTrace::Perfetto(p)) => p.finish().map(|()| true),
            _ => Ok(false),
        }
    }

    /// Write the VCD, if one was asked for and held in memory (a streamed one is ended by
    /// [`Recorder::finish_vcd`]).
    pub fn write_vcd(&self, w: impl std::io::Write) -> std::io::Result<bool> {
        match &self.vcd {
            Some(v) if !v.is_streamed() => v.write(w).map(|_| true),
            _ => Ok(false),
        }
    }

    /// End the streamed VCD, if there is one: write what it still holds and flush its writer.
    /// Returns whether there was one, or its first write error.
    pub fn finish_vcd(&mut self) -> std::io::Result<bool> {
        match &mut self.vcd {
            Some(v) if v.is_streamed() => v.finish().map(|()| true),
            _ => Ok(false),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// `phase_spans` as it was first written: every GP's phases listed (`gp_phases`), then each
    /// added to its name's span, names in order of first appearance in that list.
    fn spans_from_phases(r: &Recorder, end: Tick) -> Vec<PhaseSpan> {
        let mut spans: Vec<PhaseSpan> = Vec::new();
        for p in r.gp_phases(end) {
            match spans.iter_mut().find(|s| s.name == p.name) {
                Some(s) => {
                    s.first_start = s.first_start.min(p.start);
                    s.last_end = s.last_end.max(p.end);
                    s.gp_time += p.end - p.start;
                }
                None => spans.push(PhaseSpan {
                    name: p.name.to_string(),
                    first_start: p.start,
                    last_end: p.end,
                    gp_time: p.end - p.start,
                }),
            }
        }
        spans
    }

    const NAMES: [&str; 4] = ["select", "draw", "accumulate", "wait"];

    proptest! {
        /// Marks of up to four GPs, interleaved in time as the loop records them, some GPs
        /// finished before the run's end: the one-pass spans are the listed phases' spans,
        /// figures and order.
        #[test]
        fn phase_spans_are_the_listed_phases_spans(
            steps in prop::collection::vec((0u32..4, 0usize..4, 0u64..50), 0..60),
            finished in prop::collection::vec(any::<bool>(), 4),
        ) {
            // Traced: only a trace keeps the marks the listed phases are drawn from.
            let mut r = Recorder::new(Some(TraceWindow::all()), None);
            let mut at = Tick::ZERO;
            for &(gp, name, dt) in &steps {
                at += Tick(dt);
                r.phase(gp, NAMES[name], at);
            }
            let end = at + Tick(100);
            for (gp, &done) in finished.iter().enumerate() {
                if done {
                    r.gp_done(gp as u32, at + Tick(7 * gp as u64));
                }
            }
            let got = r.phase_spans(end);
            let want = spans_from_phases(&r, end);
            prop_assert_eq!(got.len(), want.len());
            for (g, w) in got.iter().zip(&want) {
                prop_assert_eq!(
                    (&g.name, g.first_start, g.last_end, g.gp_time),
                    (&w.name, w.first_start, w.last_end, w.gp_time)
                );
            }
        }
    }
}
