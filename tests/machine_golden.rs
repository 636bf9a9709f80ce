//! The text of a machine golden (a program run on the whole machine): a header naming the run, a
//! functional block (what was computed) and a timing table (what it cost), with one line per
//! total, phase, GP, Renderer, ring channel and ring node, so that a timing change reads as the
//! few lines it moved.
//!
//! The timing table holds the same simulated numbers as the run's stats.json
//! (`RunStats::to_json`), nothing more and nothing less: [`assert_holds_stats_json`] checks that
//! every number and name of that JSON appears in the text.

use std::collections::BTreeMap;
use std::fmt::Write;

use pxpl5_machine::{GpStats, PathPart, PhaseSpan, RendererNodeStats, RunStats, Unit};
use serde_json::Value;

/// Column widths (characters, right-aligned) wide enough for every shipped run, so that a changed
/// number moves only its own line.
const PS: usize = 14;
const CYCLES: usize = 12;
const PERCENT: usize = 7;
const COUNT: usize = 10;

/// `part / whole` in percent rounded to 0.01 %, as stats.json writes it (`stats.rs`'s `pct`).
fn pct(part: u64, whole: u64) -> f64 {
    if whole == 0 {
        0.0
    } else {
        (part as f64 * 10000.0 / whole as f64).round() / 100.0
    }
}

/// One table line: the first cell left-aligned in `first` characters, then each cell
/// right-aligned in its width, a space apart; no trailing spaces.
fn row(out: &mut String, first: usize, label: &str, cells: &[(usize, String)]) {
    let mut line = format!("{label:<first$}");
    for (w, c) in cells {
        write!(line, " {c:>w$}").unwrap();
    }
    writeln!(out, "{}", line.trim_end()).unwrap();
}

/// The golden text of a run: `stats` and the ring position of each unit (`Machine::units`),
/// with the program's own functional lines (digests, results) and timing lines (e.g. when each
/// shot ended) placed in their blocks.
pub fn text(
    stats: &RunStats,
    units: &[Unit],
    functional: &[String],
    program_timing: &[String],
) -> String {
    let RunStats {
        program,
        config,
        config_hash,
        fidelity,
        end,
        gps,
        renderers,
        ring,
        phases,
        frame_writes,
        critical_path,
        ring_level,
    } = stats;
    let mut out = String::new();
    writeln!(
        out,
        "{program} on {config} (config hash {config_hash}), fidelity {}, ring level {}",
        fidelity.name(),
        ring_level.name()
    )
    .unwrap();

    out += "\nfunctional\n";
    for l in functional {
        writeln!(out, "  {l}").unwrap();
    }
    writeln!(out, "  frame-buffer pixel writes: {frame_writes}").unwrap();

    out += "\ntiming\n";
    let total = |out: &mut String, name: &str, value: u64, unit: &str| {
        let line = format!("  {name:<26} {value:>PS$} {unit}");
        writeln!(out, "{}", line.trim_end()).unwrap();
    };
    total(&mut out, "simulated end", end.0, "ps");
    total(&mut out, "ring elapsed", ring.elapsed.0, "clocks");
    total(
        &mut out,
        "ring messages delivered",
        ring.total.messages_delivered,
        "",
    );
    total(&mut out, "ring payload words", ring.total.payload_words, "");
    total(&mut out, "ring header words", ring.total.header_words, "");
    total(
        &mut out,
        "ring token wait",
        ring.total.token_wait.0,
        "clocks",
    );
    for l in program_timing {
        writeln!(out, "  {l}").unwrap();
    }

    out += "\n";
    let h = |w: usize, s: &str| (w, s.to_string());
    row(
        &mut out,
        20,
        "phase",
        &[
            h(PS, "start ps"),
            h(PS, "end ps"),
            h(PS, "span ps"),
            h(PS, "GP time ps"),
        ],
    );
    for p in phases {
        let PhaseSpan {
            name,
            first_start,
            last_end,
            gp_time,
        } = p;
        row(
            &mut out,
            20,
            name,
            &[
                (PS, first_start.0.to_string()),
                (PS, last_end.0.to_string()),
                (PS, (*last_end - *first_start).0.to_string()),
                (PS, gp_time.0.to_string()),
            ],
        );
    }

    out += "\n";
    row(&mut out, 34, "critical path", &[h(PS, "ps")]);
    for p in critical_path {
        let PathPart {
            resource: _,
            activity,
            time,
        } = p;
        row(&mut out, 34, activity, &[(PS, time.0.to_string())]);
    }

    out += "\n";
    row(
        &mut out,
        6,
        "GP",
        &[
            h(CYCLES, "busy cycles"),
            h(CYCLES, "idle cycles"),
            h(PERCENT, "busy %"),
            h(PS, "finished ps"),
            h(COUNT, "msgs sent"),
            h(COUNT, "msgs recv"),
        ],
    );
    for g in gps {
        let GpStats {
            gp,
            busy,
            idle,
            finished,
            messages_sent,
            messages_received,
        } = g;
        row(
            &mut out,
            6,
            &gp.to_string(),
            &[
                (CYCLES, busy.0.to_string()),
                (CYCLES, idle.0.to_string()),
                (PERCENT, format!("{:.2}", pct(busy.0, busy.0 + idle.0))),
                (PS, finished.0.to_string()),
                (COUNT, messages_sent.to_string()),
                (COUNT, messages_received.to_string()),
            ],
        );
    }

    out += "\n";
    row(
        &mut out,
        8,
        "Renderer",
        &[
            h(CYCLES, "busy cycles"),
            h(CYCLES, "idle cycles"),
            h(PERCENT, "busy %"),
            h(COUNT, "commands"),
            h(20, "backing-store stall"),
        ],
    );
    for r in renderers {
        let RendererNodeStats {
            renderer,
            busy,
            idle,
            commands,
            board,
        } = r;
        row(
            &mut out,
            8,
            &renderer.to_string(),
            &[
                (CYCLES, busy.0.to_string()),
                (CYCLES, idle.0.to_string()),
                (PERCENT, format!("{:.2}", pct(busy.0, busy.0 + idle.0))),
                (COUNT, commands.to_string()),
                (20, board.stall.0.to_string()),
            ],
        );
    }

    // Commands by kind: one column per kind any Renderer ran, each cell `count/cycles`.
    let mut kinds: Vec<&str> = renderers
        .iter()
        .flat_map(|r| r.board.by_kind.keys().copied())
        .collect();
    kinds.sort_unstable();
    kinds.dedup();
    if !kinds.is_empty() {
        const KIND: usize = 12;
        out += "\nRenderer commands by kind: count/cycles\n";
        let head: Vec<(usize, String)> = kinds.iter().map(|k| h(KIND, k)).collect();
        row(&mut out, 8, "Renderer", &head);
        for r in renderers {
            let cells: Vec<(usize, String)> = kinds
                .iter()
                .map(|k| {
                    let c = r
                        .board
                        .by_kind
                        .get(k)
                        .map_or("-".to_string(), |s| format!("{}/{}", s.count, s.cycles));
                    (KIND, c)
                })
                .collect();
            row(&mut out, 8, &r.renderer.to_string(), &cells);
        }
    }

    out += "\n";
    row(
        &mut out,
        7,
        "channel",
        &[
            h(CYCLES, "payload wds"),
            h(CYCLES, "header wds"),
            h(COUNT, "packets"),
            h(COUNT, "messages"),
            h(CYCLES, "busy clocks"),
            h(PERCENT, "util %"),
        ],
    );
    for (i, c) in ring.channels.iter().enumerate() {
        row(
            &mut out,
            7,
            &i.to_string(),
            &[
                (CYCLES, c.payload_words.to_string()),
                (CYCLES, c.header_words.to_string()),
                (COUNT, c.packets.to_string()),
                (COUNT, c.messages.to_string()),
                (CYCLES, c.busy.0.to_string()),
                (PERCENT, format!("{:.2}", pct(c.busy.0, ring.elapsed.0))),
            ],
        );
    }

    out += "\n";
    assert_eq!(units.len(), ring.nodes.len(), "one ring node per unit");
    row(
        &mut out,
        17,
        "node unit",
        &[
            h(COUNT, "msgs sent"),
            h(COUNT, "msgs recv"),
            h(CYCLES, "payload sent"),
            h(CYCLES, "payload recv"),
            h(COUNT, "max outq"),
            h(COUNT, "max inq"),
            h(CYCLES, "token wait"),
        ],
    );
    for (i, (n, u)) in ring.nodes.iter().zip(units).enumerate() {
        row(
            &mut out,
            17,
            &format!("{i:<4} {u}"),
            &[
                (COUNT, n.messages_sent.to_string()),
                (COUNT, n.messages_received.to_string()),
                (CYCLES, n.payload_words_sent.to_string()),
                (CYCLES, n.payload_words_received.to_string()),
                (COUNT, n.max_output_words.to_string()),
                (COUNT, n.max_input_words.to_string()),
                (CYCLES, n.token_wait.0.to_string()),
            ],
        );
    }
    out
}

/// The leaves of a JSON value: its numbers and its string values (not its keys).
fn leaves(v: &Value, numbers: &mut Vec<f64>, strings: &mut Vec<String>) {
    match v {
        Value::Number(n) => numbers.push(n.as_f64().expect("finite")),
        Value::String(s) => strings.push(s.clone()),
        Value::Array(a) => a.iter().for_each(|x| leaves(x, numbers, strings)),
        Value::Object(o) => o.values().for_each(|x| leaves(x, numbers, strings)),
        Value::Bool(_) | Value::Null => {}
    }
}

/// Checks that `text` holds every figure of `json` (a run's stats.json): each number as often as
/// the JSON holds it (the text's numbers are the runs of digits and dots between other
/// characters), every string value (program, config, hash, phase names, ...) and every Renderer
/// command kind (a key of `by_kind`). The JSON's other keys are field names, which the text
/// spells as its own headings.
pub fn assert_holds_stats_json(text: &str, json: &Value) {
    if let Err(e) = holds_stats_json(text, json) {
        panic!("{e}");
    }
}

/// What [`assert_holds_stats_json`] checks: `Err` names what the text lacks.
pub fn holds_stats_json(text: &str, json: &Value) -> Result<(), String> {
    let mut numbers = Vec::new();
    let mut names = Vec::new();
    leaves(json, &mut numbers, &mut names);
    for r in json["renderers"].as_array().expect("renderers") {
        names.extend(r["by_kind"].as_object().expect("by_kind").keys().cloned());
    }

    let mut have: BTreeMap<u64, usize> = BTreeMap::new();
    for token in text.split(|c: char| !(c.is_ascii_digit() || c == '.')) {
        if let Ok(x) = token.parse::<f64>() {
            *have.entry(x.to_bits()).or_default() += 1;
        }
    }
    let mut missing = Vec::new();
    for x in numbers {
        // `+ 0.0` makes -0.0 into 0.0; the text writes no signs.
        match have.get_mut(&(x + 0.0).to_bits()) {
            Some(n) if *n > 0 => *n -= 1,
            _ => missing.push(x.to_string()),
        }
    }
    if !missing.is_empty() {
        return Err(format!(
            "the golden text lacks these numbers of stats.json (or holds them fewer times): {}",
            missing.join(", ")
        ));
    }
    names.retain(|s| !text.contains(s.as_str()));
    if !names.is_empty() {
        return Err(format!(
            "the golden text lacks these names of stats.json: {names:?}"
        ));
    }
    Ok(())
}
