//! What the machine records as it runs: program phase marks (always, for the stats) and, on
//! request, Chrome trace and VCD events in simulated time.
//!
//! Tracks: one per GP (compute bursts, grouped) and one per GP for its phases; one per Renderer
//! (commands, grouped into runs of back-to-back commands of one kind, since there are too many to
//! show one by one); ring messages on "lanes" (a message goes on the first lane free at its send
//! time, so slices on a lane never overlap); counters of each node's ring output-queue occupancy.
//! VCD: per GP and per Renderer a busy wire; per ring channel the token's position and whether it
//! is held. Ring signals are sampled at every instant the machine acts (the ring's own edges in
//! between are not visible).

use std::collections::BTreeMap;

use pxpl5_ring::{MessageId, NodeId, Ring, TokenLocation};
use pxpl5_sim::Tick;
use pxpl5_trace::{Args, ChromeTrace, JsonValue, SignalId, TraceWindow, TrackId, VcdTrace};

use crate::gp::Unit;
use crate::stats::PhaseSpan;

struct Tracks {
    gp: Vec<TrackId>,
    gp_phase: Vec<TrackId>,
    renderer: Vec<TrackId>,
    lanes: Vec<Lane>,
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
    name: String,
    at: Tick,
}

/// One phase of one GP: from its mark to the GP's next mark or its program's end.
struct GpPhase {
    gp: u32,
    name: String,
    start: Tick,
    end: Tick,
}

struct Signals {
    gp: Vec<SignalId>,
    renderer: Vec<SignalId>,
    token_at: Vec<SignalId>,
    token_held: Vec<SignalId>,
}

/// The machine's recorder.
#[derive(Default)]
pub struct Recorder {
    chrome: Option<ChromeTrace>,
    vcd: Option<VcdTrace>,
    tracks: Option<Tracks>,
    signals: Option<Signals>,
    units: Vec<Unit>,
    /// Phase marks in mark order.
    marks: Vec<Mark>,
    /// GP end times, for the last phase's end.
    gp_end: BTreeMap<u32, Tick>,
    /// Last sampled output-queue occupancy per node.
    queue_words: Vec<u64>,
    /// Renderer command slices shorter apart than this merge (one Renderer cycle).
    renderer_gap: Tick,
    /// Words of a node's ring output queue.
    queue_capacity: u64,
}

impl Recorder {
    /// A recorder that writes a Chrome trace and/or a VCD limited to their windows.
    pub fn new(chrome: Option<TraceWindow>, vcd: Option<TraceWindow>) -> Recorder {
        Recorder {
            chrome: chrome.map(ChromeTrace::new),
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
        self.queue_words = vec![0; units.len()];
        self.renderer_gap = renderer_cycle;
        let gps: Vec<u32> = units
            .iter()
            .filter_map(|u| if let Unit::Gp(g) = u { Some(*g) } else { None })
            .collect();
        let renderers: Vec<u32> = units
            .iter()
            .filter_map(|u| {
                if let Unit::Renderer(r) = u {
                    Some(*r)
                } else {
                    None
                }
            })
            .collect();
        if let Some(c) = &mut self.chrome {
            let mut gp_tracks = Vec::new();
            let mut phase_tracks = Vec::new();
            for g in 0..gps.len() {
                phase_tracks.push(c.track("GPs", &format!("GP {g} phases")));
                gp_tracks.push(c.track("GPs", &format!("GP {g}")));
            }
            let renderer = (0..renderers.len())
                .map(|r| c.track("Renderers", &format!("Renderer {r}")))
                .collect();
            c.metadata(
                "ring_order",
                units.iter().map(|u| u.to_string()).collect::<Vec<_>>(),
            );
            self.tracks = Some(Tracks {
                gp: gp_tracks,
                gp_phase: phase_tracks,
                renderer,
                lanes: Vec::new(),
            });
        }
        if let Some(v) = &mut self.vcd {
            let gp_scope = v.scope("gps");
            let gp = (0..gps.len())
                .map(|g| v.wire(gp_scope, &format!("gp{g}_busy"), 1))
                .collect();
            let r_scope = v.scope("renderers");
            let renderer = (0..renderers.len())
                .map(|r| v.wire(r_scope, &format!("renderer{r}_busy"), 1))
                .collect();
            let ring_scope = v.scope("ring");
            let mut token_at = Vec::new();
            let mut token_held = Vec::new();
            for ch in 0..channels {
                token_at.push(v.wire(ring_scope, &format!("ch{ch}_token_node"), 16));
                token_held.push(v.wire(ring_scope, &format!("ch{ch}_busy"), 1));
            }
            self.signals = Some(Signals {
                gp,
                renderer,
                token_at,
                token_held,
            });
        }
    }

    pub(crate) fn phase(&mut self, gp: u32, name: &str, at: Tick) {
        self.marks.push(Mark {
            gp,
            name: name.to_string(),
            at,
        });
    }

    pub(crate) fn gp_busy(&mut self, gp: u32, start: Tick, end: Tick) {
        if let (Some(c), Some(t)) = (&mut self.chrome, &self.tracks) {
            c.slice_grouped(t.gp[gp as usize], "busy", start, end, Tick(1));
        }
        if let (Some(v), Some(s)) = (&mut self.vcd, &self.signals) {
            v.change(s.gp[gp as usize], start, 1);
            v.change(s.gp[gp as usize], end, 0);
        }
    }

    pub(crate) fn gp_done(&mut self, gp: u32, at: Tick) {
        self.gp_end.insert(gp, at);
    }

    pub(crate) fn renderer_command(&mut self, r: u32, kind: &str, start: Tick, end: Tick) {
        if let (Some(c), Some(t)) = (&mut self.chrome, &self.tracks) {
            c.slice_grouped(t.renderer[r as usize], kind, start, end, self.renderer_gap);
        }
        if let (Some(v), Some(s)) = (&mut self.vcd, &self.signals) {
            v.change(s.renderer[r as usize], start, 1);
            v.change(s.renderer[r as usize], end, 0);
        }
    }

    pub(crate) fn message_delivered(
        &mut self,
        id: MessageId,
        from: Unit,
        to: Unit,
        sent: Tick,
        delivered: Tick,
        words: u32,
    ) {
        let (Some(c), Some(t)) = (&mut self.chrome, &mut self.tracks) else {
            return;
        };
        let lane = match t.lanes.iter().position(|l| l.free_from <= sent) {
            Some(i) => i,
            None => {
                let track = c.track("Ring", &format!("messages lane {}", t.lanes.len()));
                t.lanes.push(Lane {
                    track,
                    free_from: Tick::ZERO,
                });
                t.lanes.len() - 1
            }
        };
        t.lanes[lane].free_from = delivered;
        c.slice(
            t.lanes[lane].track,
            &format!("{from} -> {to}"),
            sent,
            delivered,
            [
                ("id", JsonValue::from(id.0)),
                ("words", JsonValue::from(words)),
            ],
        );
    }

    pub(crate) fn ring_sample(&mut self, now: Tick, ring: &Ring) {
        if self.chrome.is_none() && self.vcd.is_none() {
            return;
        }
        if let Some(c) = &mut self.chrome {
            let cap = self.queue_capacity;
            for (i, unit) in self.units.iter().enumerate() {
                let free = ring.output_free_words(NodeId(i as u32)).unwrap_or(0);
                let used = cap.saturating_sub(free);
                if used != self.queue_words[i] {
                    self.queue_words[i] = used;
                    c.counter("Ring", &format!("output queue {unit}"), now, used as i64);
                }
            }
        }
        if let (Some(v), Some(s)) = (&mut self.vcd, &self.signals) {
            for (ch, (&at, &held)) in s.token_at.iter().zip(&s.token_held).enumerate() {
                let (node, busy) = match ring.token_at(ch as u32) {
                    Some(TokenLocation::Held { by }) => (by.0, 1),
                    Some(TokenLocation::At(n)) => (n.0, 0),
                    Some(TokenLocation::Between { from, .. }) => (from.0, 0),
                    None => (0, 0),
                };
                v.change(at, now, u64::from(node));
                v.change(held, now, busy);
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
                    name: m.name.clone(),
                    start: m.at,
                    end: marks.get(i + 1).map_or(gp_end, |next| next.at),
                });
            }
        }
        out
    }

    /// Per-phase spans: for each phase name in order of first appearance (GP 0's marks first),
    /// its first start, last end and the GP time spent in it summed over GPs.
    pub(crate) fn phase_spans(&self, end: Tick) -> Vec<PhaseSpan> {
        let mut spans: Vec<PhaseSpan> = Vec::new();
        for GpPhase {
            name,
            start,
            end: stop,
            ..
        } in self.gp_phases(end)
        {
            match spans.iter_mut().find(|s| s.name == name) {
                Some(s) => {
                    s.first_start = s.first_start.min(start);
                    s.last_end = s.last_end.max(stop);
                    s.gp_time += stop - start;
                }
                None => spans.push(PhaseSpan {
                    name,
                    first_start: start,
                    last_end: stop,
                    gp_time: stop - start,
                }),
            }
        }
        spans
    }

    pub(crate) fn close(&mut self, end: Tick) {
        let spans = self.gp_phases(end);
        if let (Some(c), Some(t)) = (&mut self.chrome, &self.tracks) {
            for p in spans {
                c.slice(
                    t.gp_phase[p.gp as usize],
                    &p.name,
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
        match &self.chrome {
            Some(c) => c.write(w).map(|_| true),
            None => Ok(false),
        }
    }

    /// Write the VCD, if one was asked for.
    pub fn write_vcd(&self, w: impl std::io::Write) -> std::io::Result<bool> {
        match &self.vcd {
            Some(v) => v.write(w).map(|_| true),
            None => Ok(false),
        }
    }
}
