//! Simulated statistics of a run, as JSON (what goldens compare) and as a readable table.
//!
//! Only simulated quantities appear here; host seconds and simulated cycles per host second are
//! the caller's to print, apart, and never enter the JSON.

use pxpl5_renderer::{BoardStats, Fidelity};
use pxpl5_ring::{RingLevel, RingStats};
use pxpl5_sim::{Cycles, Tick};
use serde_json::{Value, json};

pub use crate::critical::{PathPart, Resource};

/// One GP's figures.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GpStats {
    pub gp: u32,
    /// i860 cycles computing (operations, message software costs).
    pub busy: Cycles,
    /// i860 cycles waiting (for a message, for ring space) or finished.
    pub idle: Cycles,
    pub finished: Tick,
    pub messages_sent: u64,
    pub messages_received: u64,
}

/// One Renderer's figures.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RendererNodeStats {
    pub renderer: u32,
    pub busy: Cycles,
    pub idle: Cycles,
    pub commands: u64,
    pub board: BoardStats,
}

/// A program phase over all GPs.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct PhaseSpan {
    pub name: String,
    pub first_start: Tick,
    pub last_end: Tick,
    /// GP time in the phase, summed over GPs.
    pub gp_time: Tick,
}

/// Everything simulated a run measured.
#[derive(Clone, Debug)]
pub struct RunStats {
    pub program: String,
    pub config: String,
    pub config_hash: String,
    pub fidelity: Fidelity,
    pub ring_level: RingLevel,
    /// Simulated time at which the last unit finished.
    pub end: Tick,
    pub gps: Vec<GpStats>,
    pub renderers: Vec<RendererNodeStats>,
    pub ring: RingStats,
    pub phases: Vec<PhaseSpan>,
    pub frame_writes: u64,
    /// The run's critical path, by what it spent its time on, largest first (see the machine's
    /// `critical` module): GP phases and message costs, ring transfer, Renderer command kinds,
    /// waits. It sums to the time the last unit finished.
    pub critical_path: Vec<PathPart>,
}

fn pct(part: u64, whole: u64) -> f64 {
    if whole == 0 {
        0.0
    } else {
        // Rounded to 0.01 % so that the JSON stays short and stable.
        (part as f64 * 10000.0 / whole as f64).round() / 100.0
    }
}

impl RunStats {
    /// The critical path's time per resource, largest first (ties in [`Resource`] order): the
    /// first is the run's bottleneck, the resource that held the critical path longest.
    pub fn critical_resources(&self) -> Vec<(Resource, Tick)> {
        let mut by: std::collections::BTreeMap<Resource, Tick> = Default::default();
        for p in &self.critical_path {
            let t = by.entry(p.resource).or_insert(Tick::ZERO);
            *t += p.time;
        }
        let mut out: Vec<(Resource, Tick)> = by.into_iter().collect();
        out.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(&b.0)));
        out
    }

    /// The stats as JSON (keys in a fixed order; simulated figures only).
    pub fn to_json(&self) -> Value {
        let gps: Vec<Value> = self
            .gps
            .iter()
            .map(|g| {
                json!({
                    "gp": g.gp,
                    "busy_cycles": g.busy.0,
                    "idle_cycles": g.idle.0,
                    "busy_percent": pct(g.busy.0, g.busy.0 + g.idle.0),
                    "finished_ps": g.finished.0,
                    "messages_sent": g.messages_sent,
                    "messages_received": g.messages_received,
                })
            })
            .collect();
        let renderers: Vec<Value> = self
            .renderers
            .iter()
            .map(|r| {
                let kinds: serde_json::Map<String, Value> = r
                    .board
                    .by_kind
                    .iter()
                    .map(|(k, s)| (k.to_string(), json!({"count": s.count, "cycles": s.cycles})))
                    .collect();
                json!({
                    "renderer": r.renderer,
                    "busy_cycles": r.busy.0,
                    "idle_cycles": r.idle.0,
                    "busy_percent": pct(r.busy.0, r.busy.0 + r.idle.0),
                    "commands": r.commands,
                    "backing_store_stall_cycles": r.board.stall.0,
                    "by_kind": kinds,
                })
            })
            .collect();
        let channels: Vec<Value> = self
            .ring
            .channels
            .iter()
            .enumerate()
            .map(|(i, c)| {
                json!({
                    "channel": i,
                    "payload_words": c.payload_words,
                    "header_words": c.header_words,
                    "packets": c.packets,
                    "messages": c.messages,
                    "busy_clocks": c.busy.0,
                    "utilisation_percent": pct(c.busy.0, self.ring.elapsed.0),
                })
            })
            .collect();
        let nodes: Vec<Value> = self
            .ring
            .nodes
            .iter()
            .enumerate()
            .map(|(i, n)| {
                json!({
                    "node": i,
                    "messages_sent": n.messages_sent,
                    "messages_received": n.messages_received,
                    "payload_words_sent": n.payload_words_sent,
                    "payload_words_received": n.payload_words_received,
                    "max_output_queue_words": n.max_output_words,
                    "max_input_queue_words": n.max_input_words,
                    "token_wait_clocks": n.token_wait.0,
                })
            })
            .collect();
        let phases: Vec<Value> = self
            .phases
            .iter()
            .map(|p| {
                json!({
                    "phase": p.name,
                    "start_ps": p.first_start.0,
                    "end_ps": p.last_end.0,
                    "span_ps": (p.last_end - p.first_start).0,
                    "gp_time_ps": p.gp_time.0,
                })
            })
            .collect();
        let critical: Vec<Value> = self
            .critical_path
            .iter()
            .map(|p| json!({ "resource": p.resource.name(), "activity": p.activity, "ps": p.time.0 }))
            .collect();
        json!({
            "program": self.program,
            "config": self.config,
            "config_hash": self.config_hash,
            "fidelity": self.fidelity.name(),
            "ring_level": self.ring_level.name(),
            "simulated_ps": self.end.0,
            "critical_path": critical,
            "phases": phases,
            "gps": gps,
            "renderers": renderers,
            "ring": {
                "elapsed_clocks": self.ring.elapsed.0,
                "payload_words": self.ring.total.payload_words,
                "header_words": self.ring.total.header_words,
                "messages": self.ring.total.messages_delivered,
                "token_wait_clocks": self.ring.total.token_wait.0,
                "channels": channels,
                "nodes": nodes,
            },
            "frame_buffer_pixel_writes": self.frame_writes,
        })
    }

    /// Whether the run was simulated at an approximate level (Renderer or ring), so that its
    /// results may differ from an exact run's.
    pub fn approximate(&self) -> bool {
        !self.fidelity.has_pixels() || self.ring_level.is_approximate()
    }

    /// The levels the run was simulated at, as its reports name them: the Renderer's fidelity
    /// level alone for an exact run (the ring at its token level), else both, marked approximate.
    pub fn levels(&self) -> String {
        if self.approximate() {
            format!(
                "{}, ring level {} (APPROXIMATE: results may differ from an exact run's)",
                self.fidelity.name(),
                self.ring_level.name()
            )
        } else {
            self.fidelity.name().to_string()
        }
    }

    /// A readable summary table.
    pub fn table(&self) -> String {
        let mut out = String::new();
        let ms = |t: Tick| t.0 as f64 / 1e9;
        out += &format!(
            "{} on {} ({}): {:.3} ms simulated, fidelity {}\n",
            self.program,
            self.config,
            self.config_hash,
            ms(self.end),
            self.levels(),
        );
        out += "\ncritical path                          ms   share %\n";
        for p in &self.critical_path {
            out += &format!(
                "{:<34} {:>7.3} {:>9.2}\n",
                p.activity,
                ms(p.time),
                pct(p.time.0, self.end.0)
            );
        }
        out += "\nphase                     start ms      end ms     span ms   GP-time ms\n";
        for p in &self.phases {
            out += &format!(
                "{:<22} {:>11.3} {:>11.3} {:>11.3} {:>12.3}\n",
                p.name,
                ms(p.first_start),
                ms(p.last_end),
                ms(p.last_end - p.first_start),
                ms(p.gp_time)
            );
        }
        out += "\nunit          busy cycles   idle cycles   busy %   commands/messages\n";
        for g in &self.gps {
            out += &format!(
                "GP {:<9} {:>12} {:>13} {:>8.2} {:>10} sent\n",
                g.gp,
                g.busy.0,
                g.idle.0,
                pct(g.busy.0, g.busy.0 + g.idle.0),
                g.messages_sent
            );
        }
        for r in &self.renderers {
            out += &format!(
                "Renderer {:<3} {:>12} {:>13} {:>8.2} {:>10} commands\n",
                r.renderer,
                r.busy.0,
                r.idle.0,
                pct(r.busy.0, r.busy.0 + r.idle.0),
                r.commands
            );
        }
        out += "\nring channel   payload words   header words   packets   utilisation %\n";
        for (i, c) in self.ring.channels.iter().enumerate() {
            out += &format!(
                "{:<14} {:>13} {:>14} {:>9} {:>15.2}\n",
                i,
                c.payload_words,
                c.header_words,
                c.packets,
                pct(c.busy.0, self.ring.elapsed.0)
            );
        }
        out += &format!(
            "ring total: {} messages, {} payload words, {} clocks waiting for tokens\n",
            self.ring.total.messages_delivered,
            self.ring.total.payload_words,
            self.ring.total.token_wait.0
        );
        out
    }
}
