//! `pxpl5 trace timeline FILE` and `pxpl5 trace utilisation FILE`.
//!
//! **utilisation**: per resource, its busy share in each of `--bins` equal intervals of simulated
//! time, as lines in an SVG: the GPs' and the Renderers' work slices (per unit, their union; a
//! unit with no slice in the trace is not counted), and the ring channels' `token held`
//! counters. The counter is sampled at the instants the machine steps, so a hold that begins and
//! ends between two is missed: over the main job's first shots it gives the channels 15.5 % busy
//! where the stats' exact busy clocks give 16.1 %; the GPs' and Renderers' shares are exact.
//!
//! **timeline**: the timeline of a trace file (`--trace`'s Chrome JSON or
//! Perfetto `.pftrace`) drawn as an SVG with plotters: one row per unit or ring lane that has
//! slices in the window, the critical-path track on top, slices coloured by category, a time
//! axis and a legend of the critical path's categories. The picture a Perfetto UI screenshot
//! would give, made where no browser runs (docs, CI artifacts, reports).
//!
//! A row's slices are drawn per pixel column: each column takes the colour of the category that
//! covers most of it, and runs of columns of one colour are one rectangle. So the SVG's size is
//! bounded by rows x width whatever the trace's length, and a busy stretch of tiny slices reads
//! as what dominated it.
//!
//! Categories: on the critical-path track the slice's `category` argument (the stats' names); on
//! a GP or Renderer track `GP <slice>` / `Renderer <slice>` (so a Renderer's `qee` has the colour
//! of the critical path's `Renderer qee`); on a ring lane `ring transfer`; on a GP's phases track
//! `phase <slice>`.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use clap::Args;
use plotters::prelude::*;
use pxpl5_trace::proto::EventType;
use pxpl5_trace::{Tick, TraceWindow, format_time, read_packets};
use serde_json::Value;

use crate::failure::{Failure, UserError};
use crate::output::{self, outln};

/// Options of `pxpl5 trace timeline`.
#[derive(Args, Clone, Debug)]
pub struct TimelineArgs {
    /// The trace: Chrome JSON (`--trace FILE.json`) or Perfetto's format (`--trace FILE.pftrace`).
    pub file: PathBuf,
    /// Where the SVG goes; default: FILE with the extension .svg.
    #[arg(long, value_name = "FILE.svg")]
    pub out: Option<PathBuf>,
    /// Draw only this window of simulated time, e.g. 0..2ms (as --trace-window).
    #[arg(long, value_name = "START..END")]
    pub window: Option<String>,
    /// Width of the picture in pixels.
    #[arg(long, default_value_t = 1600, value_parser = clap::value_parser!(u32).range(400..=20_000))]
    pub width: u32,
}

/// The group and name of the critical-path track (as the recorder names it).
const CRITICAL: (&str, &str) = ("Critical path", "unit and activity");

/// A track of the trace with its slices, in picoseconds.
#[derive(Debug, Default)]
pub struct Row {
    /// The track's group (the JSON's process) and name (its thread).
    pub group: String,
    pub name: String,
    /// `(start, end, category)`.
    pub slices: Vec<(u64, u64, String)>,
}

impl Row {
    fn label(&self) -> String {
        match self.group.as_str() {
            "GPs" | "Renderers" => self.name.clone(),
            g if (g, self.name.as_str()) == CRITICAL => "critical path".to_owned(),
            g => format!("{g} / {}", self.name),
        }
    }

    /// The colour key of a slice named `name` (see the module doc).
    fn category(&self, name: &str, args_category: Option<&str>) -> String {
        if let Some(c) = args_category {
            return c.to_owned();
        }
        match self.group.as_str() {
            "GPs" if self.name.ends_with(" phases") => format!("phase {name}"),
            "GPs" => format!("GP {name}"),
            "Renderers" => format!("Renderer {name}"),
            g if g.starts_with("Ring channel") => "ring transfer".to_owned(),
            _ => name.to_owned(),
        }
    }
}

/// `pxpl5 trace timeline`.
pub fn timeline(args: &TimelineArgs) -> Result<(), Failure> {
    let window = match &args.window {
        Some(w) => TraceWindow::parse(w).map_err(|e| UserError(format!("--window: {e}")))?,
        None => TraceWindow::all(),
    };
    let out_path = args
        .out
        .clone()
        .unwrap_or_else(|| args.file.with_extension("svg"));
    let dest = output::dest("--out", &out_path, false)?;
    let bytes = std::fs::read(&args.file)
        .map_err(|e| UserError(format!("{}: cannot read: {e}", args.file.display())))?;
    let rows = read_rows(&args.file, &bytes)?;
    let svg = draw(&rows, window, args.width)
        .map_err(|e| UserError(format!("{}: {e}", args.file.display())))?;
    output::write_all(&[(dest, svg.into_bytes())], Vec::new())?;
    outln!("wrote {}", out_path.display())?;
    Ok(())
}

/// The rows of a trace file, critical path first, then in the trace's track order. The format is
/// the extension's (`.pftrace`), else JSON; an error names the file.
pub fn read_rows(path: &Path, bytes: &[u8]) -> Result<Vec<Row>, UserError> {
    let perfetto = crate::run::is_perfetto(path);
    let rows = if perfetto {
        perfetto_rows(bytes)
    } else {
        json_rows(bytes)
    };
    let mut rows = rows.map_err(|e| {
        let what = if perfetto {
            "a Perfetto trace"
        } else {
            "a Chrome trace (JSON)"
        };
        UserError(format!("{}: not {what}: {e}", path.display()))
    })?;
    // The critical path on top; the others keep their order.
    rows.sort_by_key(|r| (r.group.as_str(), r.name.as_str()) != CRITICAL);
    Ok(rows)
}

/// A JSON timestamp or duration in microseconds as picoseconds: exact for the simulator's six
/// decimals, rounded for other writers' numbers; `None` if not a non-negative number.
fn json_ps(v: &Value) -> Option<u64> {
    let Value::Number(n) = v else {
        return None;
    };
    let text = n.to_string();
    if let Some((int, frac)) = text.split_once('.').or(Some((text.as_str(), "")))
        && frac.len() <= 6
        && !text.contains(['e', 'E', '-'])
    {
        let int: u64 = int.parse().ok()?;
        let frac: u64 = format!("{frac:0<6}").parse().ok()?;
        return int.checked_mul(1_000_000)?.checked_add(frac);
    }
    let us = n.as_f64()?;
    (0.0..1.8e13)
        .contains(&us)
        .then(|| (us * 1e6).round() as u64)
}

/// The rows of a Chrome trace: its threads, in their sort order, with their complete (`X`)
/// slices.
fn json_rows(bytes: &[u8]) -> Result<Vec<Row>, String> {
    let doc: Value = serde_json::from_slice(bytes).map_err(|e| e.to_string())?;
    let events = doc
        .get("traceEvents")
        .and_then(Value::as_array)
        .ok_or("no traceEvents array")?;
    let id = |e: &Value, key: &str| e.get(key).and_then(Value::as_u64);
    let text = |e: &Value, key: &str| e.get(key).and_then(Value::as_str).map(str::to_owned);
    let mut processes: BTreeMap<u64, (u64, String)> = BTreeMap::new();
    let mut threads: BTreeMap<(u64, u64), (u64, String)> = BTreeMap::new();
    for e in events.iter().filter(|e| e["ph"] == "M") {
        let (Some(pid), Some(what)) = (id(e, "pid"), text(e, "name")) else {
            continue;
        };
        let args = &e["args"];
        let tid = id(e, "tid");
        match (what.as_str(), tid) {
            ("process_name", _) => {
                processes.entry(pid).or_insert((pid, String::new())).1 =
                    text(args, "name").unwrap_or_default();
            }
            ("process_sort_index", _) => {
                processes.entry(pid).or_insert((pid, String::new())).0 =
                    id(args, "sort_index").unwrap_or(pid);
            }
            ("thread_name", Some(tid)) => {
                threads.entry((pid, tid)).or_insert((tid, String::new())).1 =
                    text(args, "name").unwrap_or_default();
            }
            ("thread_sort_index", Some(tid)) => {
                threads.entry((pid, tid)).or_insert((tid, String::new())).0 =
                    id(args, "sort_index").unwrap_or(tid);
            }
            _ => {}
        }
    }
    let mut order: Vec<((u64, u64), (u64, u64))> = threads
        .iter()
        .map(|(&key, &(sort, _))| {
            let p = processes.get(&key.0).map_or(key.0, |p| p.0);
            ((p, sort), key)
        })
        .collect();
    order.sort();
    let mut index = BTreeMap::new();
    let mut rows: Vec<Row> = Vec::new();
    for (_, key) in order {
        index.insert(key, rows.len());
        rows.push(Row {
            group: processes
                .get(&key.0)
                .map(|p| p.1.clone())
                .unwrap_or_default(),
            name: threads[&key].1.clone(),
            slices: Vec::new(),
        });
    }
    for e in events.iter().filter(|e| e["ph"] == "X") {
        let (Some(pid), Some(tid)) = (id(e, "pid"), id(e, "tid")) else {
            continue;
        };
        let Some(&row) = index.get(&(pid, tid)) else {
            continue;
        };
        let start = json_ps(&e["ts"]).ok_or("an X event without a valid ts")?;
        let dur = json_ps(&e["dur"]).ok_or("an X event without a valid dur")?;
        let name = text(e, "name").unwrap_or_default();
        let category = rows[row].category(&name, e["args"]["category"].as_str());
        rows[row]
            .slices
            .push((start, start.saturating_add(dur), category));
    }
    Ok(rows)
}

/// The rows of a Perfetto trace: its non-counter tracks that have a parent, in descriptor order,
/// with the slices their begin/end events make (in time order, as Perfetto pairs them).
fn perfetto_rows(bytes: &[u8]) -> Result<Vec<Row>, String> {
    let packets = read_packets(bytes).map_err(|e| e.to_string())?;
    let mut names: BTreeMap<u64, String> = BTreeMap::new();
    let mut arg_names: BTreeMap<u64, String> = BTreeMap::new();
    let mut groups: BTreeMap<u64, String> = BTreeMap::new();
    let mut index: BTreeMap<u64, usize> = BTreeMap::new();
    let mut rows: Vec<Row> = Vec::new();
    // (ts ns, file order, row, begin?, name, category arg)
    let mut events: Vec<(u64, usize, usize, bool, String, Option<String>)> = Vec::new();
    for (i, p) in packets.iter().enumerate() {
        if let Some(interned) = &p.interned_data {
            for n in &interned.event_names {
                names.insert(n.iid.unwrap_or(0), n.name.clone().unwrap_or_default());
            }
            for n in &interned.debug_annotation_names {
                arg_names.insert(n.iid.unwrap_or(0), n.name.clone().unwrap_or_default());
            }
        }
        if let Some(d) = &p.track_descriptor {
            let (uuid, name) = (d.uuid.unwrap_or(0), d.name.clone().unwrap_or_default());
            match d.parent_uuid {
                None => {
                    groups.insert(uuid, name);
                }
                Some(parent) if d.counter.is_none() => {
                    index.insert(uuid, rows.len());
                    rows.push(Row {
                        group: groups.get(&parent).cloned().unwrap_or_default(),
                        name,
                        slices: Vec::new(),
                    });
                }
                Some(_) => {}
            }
        }
        let Some(e) = &p.track_event else {
            continue;
        };
        let Some(&row) = e.track_uuid.and_then(|u| index.get(&u)) else {
            continue;
        };
        let ts = p.timestamp.unwrap_or(0);
        let name = e
            .name_iid
            .and_then(|iid| names.get(&iid).cloned())
            .unwrap_or_default();
        let category = e.debug_annotations.iter().find_map(|a| {
            let key = arg_names.get(&a.name_iid?)?;
            (key == "category").then(|| a.string_value.clone())?
        });
        match e.r#type.and_then(|t| EventType::try_from(t).ok()) {
            Some(EventType::SliceBegin) => events.push((ts, i, row, true, name, category)),
            Some(EventType::SliceEnd) => events.push((ts, i, row, false, name, category)),
            _ => {}
        }
    }
    events.sort_by_key(|e| (e.0, e.1));
    let mut open: BTreeMap<usize, Vec<(u64, String, Option<String>)>> = BTreeMap::new();
    for (ts, _, row, begin, name, category) in events {
        if begin {
            open.entry(row).or_default().push((ts, name, category));
        } else if let Some((start, name, category)) = open.get_mut(&row).and_then(Vec::pop) {
            let category = rows[row].category(&name, category.as_deref());
            rows[row].slices.push((start * 1_000, ts * 1_000, category));
        }
    }
    // Tracks are described as first used (a ring lane when a message first needs it): group them
    // as the JSON's processes do, groups in order of first appearance.
    let mut first: BTreeMap<String, usize> = BTreeMap::new();
    for (i, r) in rows.iter().enumerate() {
        first.entry(r.group.clone()).or_insert(i);
    }
    rows.sort_by_key(|r| first[&r.group]);
    Ok(rows)
}

/// The counter the recorder keeps per ring channel: 1 while a sender holds the channel's token
/// (transmitting, or under late release waiting for its last word), 0 when it is free.
const TOKEN_HELD: &str = "token held";

/// Per group (process) of a trace, the intervals in which its counter `name` was not zero, as
/// the slices of a row named `name`; an interval still open at the trace's end runs to
/// `u64::MAX` (a caller clamps it to its window).
pub fn counter_rows(path: &Path, bytes: &[u8], name: &str) -> Result<Vec<Row>, UserError> {
    let perfetto = crate::run::is_perfetto(path);
    let samples = if perfetto {
        perfetto_counter(bytes, name)
    } else {
        json_counter(bytes, name)
    };
    let samples = samples.map_err(|e| UserError(format!("{}: {e}", path.display())))?;
    Ok(samples
        .into_iter()
        .map(|(group, mut points)| {
            points.sort_by_key(|p| (p.0, p.1));
            let mut slices = Vec::new();
            let mut from: Option<u64> = None;
            for (ts, _, value) in points {
                match (from, value != 0) {
                    (None, true) => from = Some(ts),
                    (Some(s), false) => {
                        slices.push((s, ts, String::new()));
                        from = None;
                    }
                    _ => {}
                }
            }
            if let Some(s) = from {
                slices.push((s, u64::MAX, String::new()));
            }
            Row {
                group,
                name: name.to_owned(),
                slices,
            }
        })
        .collect())
}

/// Per process name, the samples `(ps, file order, value)` of a Chrome trace's counter `name`.
type Samples = BTreeMap<String, Vec<(u64, usize, i64)>>;

fn json_counter(bytes: &[u8], name: &str) -> Result<Samples, String> {
    let doc: Value = serde_json::from_slice(bytes).map_err(|e| e.to_string())?;
    let events = doc
        .get("traceEvents")
        .and_then(Value::as_array)
        .ok_or("not a Chrome trace (JSON): no traceEvents array")?;
    let processes: BTreeMap<u64, String> = events
        .iter()
        .filter(|e| e["ph"] == "M" && e["name"] == "process_name")
        .filter_map(|e| Some((e["pid"].as_u64()?, e["args"]["name"].as_str()?.to_owned())))
        .collect();
    let mut out = Samples::new();
    for (i, e) in events.iter().enumerate() {
        if e["ph"] != "C" || e["name"] != name {
            continue;
        }
        let (Some(group), Some(ts), Some(value)) = (
            e["pid"].as_u64().and_then(|p| processes.get(&p)),
            json_ps(&e["ts"]),
            e["args"]["value"].as_i64(),
        ) else {
            return Err(format!("a counter `{name}` without pid, ts or value"));
        };
        out.entry(group.clone()).or_default().push((ts, i, value));
    }
    Ok(out)
}

fn perfetto_counter(bytes: &[u8], name: &str) -> Result<Samples, String> {
    let packets = read_packets(bytes).map_err(|e| format!("not a Perfetto trace: {e}"))?;
    let mut groups: BTreeMap<u64, String> = BTreeMap::new();
    let mut tracks: BTreeMap<u64, String> = BTreeMap::new();
    let mut out = Samples::new();
    for (i, p) in packets.iter().enumerate() {
        if let Some(d) = &p.track_descriptor {
            let uuid = d.uuid.unwrap_or(0);
            match d.parent_uuid {
                None => {
                    groups.insert(uuid, d.name.clone().unwrap_or_default());
                }
                Some(parent) if d.counter.is_some() && d.name.as_deref() == Some(name) => {
                    tracks.insert(uuid, groups.get(&parent).cloned().unwrap_or_default());
                }
                Some(_) => {}
            }
        }
        let Some(e) = &p.track_event else {
            continue;
        };
        let Some(group) = e.track_uuid.and_then(|u| tracks.get(&u)) else {
            continue;
        };
        if e.r#type.and_then(|t| EventType::try_from(t).ok()) == Some(EventType::Counter) {
            let ts = p.timestamp.unwrap_or(0).saturating_mul(1_000);
            let value = e.counter_value.unwrap_or(0);
            out.entry(group.clone()).or_default().push((ts, i, value));
        }
    }
    Ok(out)
}

/// Pixels: the label column, a row, the axis band, the legend's lines.
const LABEL_W: i32 = 230;
const ROW_H: i32 = 16;
const AXIS_H: i32 = 28;
const LEGEND_LINE: i32 = 16;

/// Distinct colours, given to categories in order of first appearance (critical path first).
const PALETTE: [(u8, u8, u8); 20] = [
    (31, 119, 180),
    (255, 127, 14),
    (44, 160, 44),
    (214, 39, 40),
    (148, 103, 189),
    (140, 86, 75),
    (227, 119, 194),
    (127, 127, 127),
    (188, 189, 34),
    (23, 190, 207),
    (174, 199, 232),
    (255, 187, 120),
    (152, 223, 138),
    (255, 152, 150),
    (197, 176, 213),
    (196, 156, 148),
    (247, 182, 210),
    (199, 199, 199),
    (219, 219, 141),
    (158, 218, 229),
];

/// A time step of 1, 2 or 5 times a power of ten (picoseconds) giving at most `most` ticks.
fn tick_step(span: u64, most: u64) -> u64 {
    let mut step = 1u64;
    loop {
        for m in [1, 2, 5] {
            let s = step.saturating_mul(m);
            if span / s <= most {
                return s;
            }
        }
        step = step.saturating_mul(10);
    }
}

/// Picoseconds as ms or us with three decimals, for the legend.
fn readable(ps: u64) -> String {
    if ps >= 1_000_000_000 {
        format!("{:.3} ms", ps as f64 / 1e9)
    } else {
        format!("{:.3} us", ps as f64 / 1e6)
    }
}

/// The SVG of `rows` over `window` (an open end: the last slice's end), `width` pixels wide.
pub fn draw(rows: &[Row], window: TraceWindow, width: u32) -> Result<String, String> {
    let last = rows
        .iter()
        .flat_map(|r| r.slices.iter().map(|s| s.1))
        .filter(|&e| e != u64::MAX)
        .max()
        .unwrap_or(0);
    let start = window.start.as_ps();
    let end = if window.is_open_ended() {
        last.max(start + 1)
    } else {
        window.end.as_ps()
    };
    let visible: Vec<&Row> = rows
        .iter()
        .filter(|r| r.slices.iter().any(|s| s.0 < end && s.1 > start))
        .collect();
    // Colours: critical path's categories first, in order of appearance.
    let mut colours: BTreeMap<&str, usize> = BTreeMap::new();
    let mut legend: Vec<(&str, u64)> = Vec::new();
    for r in &visible {
        for (s, e, c) in &r.slices {
            let n = colours.len();
            colours.entry(c.as_str()).or_insert(n);
            if (r.group.as_str(), r.name.as_str()) == CRITICAL {
                let t = e.min(&end).saturating_sub(*s.max(&start));
                match legend.iter_mut().find(|(name, _)| name == c) {
                    Some(l) => l.1 += t,
                    None => legend.push((c, t)),
                }
            }
        }
    }
    legend.sort_by(|a, b| b.1.cmp(&a.1).then(a.0.cmp(b.0)));
    legend.truncate(16);
    let plot_w = width as i32 - LABEL_W - 10;
    let rows_h = visible.len() as i32 * ROW_H;
    let legend_h = if legend.is_empty() {
        0
    } else {
        LEGEND_LINE * (legend.len() as i32 + 2)
    };
    let height = (AXIS_H + rows_h + 10 + legend_h).max(60) as u32;
    let span = (end - start) as f64;
    let x_of =
        |ps: u64| LABEL_W as f64 + (ps.clamp(start, end) - start) as f64 * plot_w as f64 / span;
    let colour = |c: &str| {
        let (r, g, b) = PALETTE[colours.get(c).copied().unwrap_or(0) % PALETTE.len()];
        RGBColor(r, g, b)
    };
    let font = |size: i32| ("sans-serif", size).into_font();

    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (width, height)).into_drawing_area();
        let e = |e: DrawingAreaErrorKind<std::io::Error>| e.to_string();
        root.fill(&WHITE).map_err(e)?;
        // Time axis: ticks and grid lines.
        let step = tick_step(end - start, 10);
        let mut t = start.div_ceil(step) * step;
        while t <= end {
            let x = x_of(t) as i32;
            root.draw(&PathElement::new(
                vec![(x, AXIS_H - 6), (x, AXIS_H + rows_h)],
                RGBColor(220, 220, 220),
            ))
            .map_err(e)?;
            root.draw(&Text::new(format_time(Tick(t)), (x + 2, 6), font(13)))
                .map_err(e)?;
            t += step;
        }
        for (i, r) in visible.iter().enumerate() {
            let y = AXIS_H + i as i32 * ROW_H;
            root.draw(&Text::new(r.label(), (4, y + 2), font(13)))
                .map_err(e)?;
            // Per pixel column, the time each category covers; the largest colours the column.
            let mut columns: Vec<BTreeMap<&str, f64>> = vec![BTreeMap::new(); plot_w as usize];
            for (s, en, c) in &r.slices {
                if *en <= start || *s >= end {
                    continue;
                }
                let (x0, x1) = (x_of(*s) - LABEL_W as f64, x_of(*en) - LABEL_W as f64);
                let first = x0.floor().max(0.0) as usize;
                let last = (x1.ceil() as usize).min(plot_w as usize);
                for (col, cover) in columns.iter_mut().enumerate().take(last).skip(first) {
                    let (a, b) = (col as f64, col as f64 + 1.0);
                    let covered = (x1.min(b) - x0.max(a)).max(0.0);
                    // A slice narrower than its pixel still shows.
                    *cover.entry(c.as_str()).or_default() += covered.max(1e-3);
                }
            }
            let dominant: Vec<Option<&str>> = columns
                .iter()
                .map(|m| {
                    m.iter()
                        .max_by(|a, b| a.1.total_cmp(b.1).then(b.0.cmp(a.0)))
                        .map(|(c, _)| *c)
                })
                .collect();
            let mut col = 0;
            while col < dominant.len() {
                let Some(c) = dominant[col] else {
                    col += 1;
                    continue;
                };
                let run_end = (col..dominant.len())
                    .find(|&k| dominant[k] != Some(c))
                    .unwrap_or(dominant.len());
                let x = LABEL_W + col as i32;
                root.draw(&Rectangle::new(
                    [(x, y + 2), (LABEL_W + run_end as i32, y + ROW_H - 2)],
                    colour(c).filled(),
                ))
                .map_err(e)?;
                col = run_end;
            }
        }
        if !legend.is_empty() {
            let y0 = AXIS_H + rows_h + 10;
            let total: u64 = legend.iter().map(|l| l.1).sum::<u64>().max(1);
            root.draw(&Text::new(
                "critical path, by category (share of the window):",
                (4, y0),
                font(14),
            ))
            .map_err(e)?;
            for (i, (c, t)) in legend.iter().enumerate() {
                let y = y0 + LEGEND_LINE * (i as i32 + 1);
                root.draw(&Rectangle::new(
                    [(8, y + 2), (20, y + 12)],
                    colour(c).filled(),
                ))
                .map_err(e)?;
                let share = *t as f64 * 100.0 / total as f64;
                root.draw(&Text::new(
                    format!("{c}: {} ({share:.1} %)", readable(*t)),
                    (26, y),
                    font(13),
                ))
                .map_err(e)?;
            }
        }
        root.present().map_err(e)?;
    }
    Ok(svg)
}

/// Options of `pxpl5 trace utilisation`.
#[derive(Args, Clone, Debug)]
pub struct UtilisationArgs {
    /// The trace: Chrome JSON (`--trace FILE.json`) or Perfetto's format (`--trace FILE.pftrace`).
    pub file: PathBuf,
    /// Where the SVG goes; default: FILE with `-utilisation.svg` for its extension.
    #[arg(long, value_name = "FILE.svg")]
    pub out: Option<PathBuf>,
    /// Only this window of simulated time, e.g. 0..2ms (as --trace-window).
    #[arg(long, value_name = "START..END")]
    pub window: Option<String>,
    /// Intervals of simulated time the window is cut into; each point is one's busy share.
    #[arg(long, default_value_t = 200, value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub bins: u32,
}

/// A resource's tracks in a trace: the GPs' work tracks (not their phases), the Renderers, and
/// per ring channel its token-held counter as slices ([`counter_rows`]): the channel is busy
/// while a sender holds its token. Its message lanes are not used: a lane's slice runs from the
/// send to the last word's arrival, waits in the sender's queue included.
fn resource_of(row: &Row) -> Option<(&'static str, String)> {
    match row.group.as_str() {
        "GPs" if row.name.ends_with(" phases") => None,
        "GPs" => Some(("GPs", row.name.clone())),
        "Renderers" => Some(("Renderers", row.name.clone())),
        g if g.starts_with("Ring channel") && row.name == TOKEN_HELD => {
            Some(("ring channels", g.to_owned()))
        }
        _ => None,
    }
}

/// Busy intervals of a unit: the union of its slices, sorted.
fn union(mut slices: Vec<(u64, u64)>) -> Vec<(u64, u64)> {
    slices.sort_unstable();
    let mut out: Vec<(u64, u64)> = Vec::new();
    for (s, e) in slices {
        match out.last_mut() {
            Some(last) if s <= last.1 => last.1 = last.1.max(e),
            _ => out.push((s, e)),
        }
    }
    out
}

/// Per resource (GPs, Renderers, ring channels) and per bin of `[start, end)`, the share of its
/// units' time they were busy: the overlap of each unit's busy intervals with the bin, summed
/// over units, over units x bin width. A unit with no slice in the trace is not counted.
pub fn utilisation_series(
    rows: &[Row],
    (start, end): (u64, u64),
    bins: u32,
) -> Vec<(String, Vec<(f64, f64)>)> {
    let mut units: BTreeMap<(&str, String), Vec<(u64, u64)>> = BTreeMap::new();
    for row in rows {
        if let Some(key) = resource_of(row) {
            units
                .entry(key)
                .or_default()
                .extend(row.slices.iter().map(|&(s, e, _)| (s, e)));
        }
    }
    let span = end.saturating_sub(start).max(1);
    let bins = u64::from(bins);
    let edge = |k: u64| start + (u128::from(span) * u128::from(k) / u128::from(bins)) as u64;
    let mut series = Vec::new();
    for resource in ["GPs", "Renderers", "ring channels"] {
        let busy: Vec<Vec<(u64, u64)>> = units
            .iter()
            .filter(|((r, _), _)| *r == resource)
            .map(|(_, s)| union(s.clone()))
            .collect();
        if busy.is_empty() {
            continue;
        }
        let mut sums = vec![0u64; bins as usize];
        for intervals in &busy {
            for &(s, e) in intervals {
                let (s, e) = (s.max(start), e.min(end));
                if s >= e {
                    continue;
                }
                // The bins it overlaps: from the one holding s to the one holding e - 1.
                let first = (u128::from(s - start) * u128::from(bins) / u128::from(span)) as u64;
                let last = (u128::from(e - 1 - start) * u128::from(bins) / u128::from(span)) as u64;
                for k in first..=last.min(bins - 1) {
                    let (a, b) = (edge(k), edge(k + 1));
                    sums[k as usize] += e.min(b).saturating_sub(s.max(a));
                }
            }
        }
        let points = (0..bins)
            .map(|k| {
                let (a, b) = (edge(k), edge(k + 1));
                let width = (b - a).max(1) * busy.len() as u64;
                let mid_ms = (a + b) as f64 / 2.0 / 1e9;
                (mid_ms, sums[k as usize] as f64 / width as f64)
            })
            .collect();
        series.push((format!("{resource} ({})", busy.len()), points));
    }
    series
}

/// `pxpl5 trace utilisation`.
pub fn utilisation(args: &UtilisationArgs) -> Result<(), Failure> {
    let window = match &args.window {
        Some(w) => TraceWindow::parse(w).map_err(|e| UserError(format!("--window: {e}")))?,
        None => TraceWindow::all(),
    };
    let out_path = args.out.clone().unwrap_or_else(|| {
        let stem = args
            .file
            .file_stem()
            .map_or("trace".into(), |s| s.to_string_lossy().into_owned());
        args.file.with_file_name(format!("{stem}-utilisation.svg"))
    });
    let dest = output::dest("--out", &out_path, false)?;
    let bytes = std::fs::read(&args.file)
        .map_err(|e| UserError(format!("{}: cannot read: {e}", args.file.display())))?;
    let mut rows = read_rows(&args.file, &bytes)?;
    rows.extend(counter_rows(&args.file, &bytes, TOKEN_HELD)?);
    let last = rows
        .iter()
        .flat_map(|r| r.slices.iter().map(|s| s.1))
        .max()
        .unwrap_or(0);
    let start = window.start.0.min(last);
    let end = window.end.0.min(last);
    if end <= start {
        return Err(UserError(format!(
            "{}: no slice in the window {}..{}",
            args.file.display(),
            format_time(Tick(start)),
            format_time(Tick(end))
        ))
        .into());
    }
    let series = utilisation_series(&rows, (start, end), args.bins);
    if series.is_empty() {
        return Err(UserError(format!(
            "{}: has no GP, Renderer or ring track to measure",
            args.file.display()
        ))
        .into());
    }
    let mut summary = Vec::new();
    let chart = crate::plot::Chart {
        title: "busy share per resource over simulated time".into(),
        x_label: "simulated ms".into(),
        y_label: "busy share of the resource's units".into(),
        log_x: false,
        log_y: false,
        series: series
            .into_iter()
            .map(|(name, points)| {
                let mean = points.iter().map(|p| p.1).sum::<f64>() / points.len().max(1) as f64;
                summary.push(format!("{name}: {:.1} % busy", 100.0 * mean));
                crate::plot::Series {
                    name,
                    points,
                    line: true,
                }
            })
            .collect(),
        legend: SeriesLabelPosition::UpperRight,
    };
    let svg = crate::plot::svg(&[chart], (960, 420))?;
    output::write_all(&[(dest, svg.into_bytes())], Vec::new())?;
    outln!(
        "{} to {}: {}",
        format_time(Tick(start)),
        format_time(Tick(end)),
        summary.join(", ")
    )?;
    outln!("wrote {}", out_path.display())?;
    Ok(())
}

#[cfg(test)]
mod utilisation_tests {
    use super::*;

    fn row(group: &str, name: &str, slices: &[(u64, u64)]) -> Row {
        Row {
            group: group.into(),
            name: name.into(),
            slices: slices.iter().map(|&(s, e)| (s, e, String::new())).collect(),
        }
    }

    #[test]
    fn busy_shares_per_bin_per_resource() {
        let rows = [
            row("GPs", "GP 0", &[(0, 50), (40, 60)]), // overlapping slices count once
            row("GPs", "GP 0 phases", &[(0, 100)]),   // phases are not work
            row("GPs", "GP 1", &[(50, 100)]),
            row("Renderers", "Renderer 0", &[(25, 75)]),
            row("Ring channel 0", "lane 0", &[(0, 100)]), // a message's wait and flight
            row("Ring channel 0", TOKEN_HELD, &[(0, 10), (5, 20)]),
        ];
        let s = utilisation_series(&rows, (0, 100), 2);
        let names: Vec<&str> = s.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, ["GPs (2)", "Renderers (1)", "ring channels (1)"]);
        // GPs: bin [0, 50) GP 0 busy 50 of 2 x 50; bin [50, 100) GP 0 10 + GP 1 50.
        assert_eq!(s[0].1, [(2.5e-8, 0.5), (7.5e-8, 0.6)]);
        assert_eq!(s[1].1, [(2.5e-8, 0.5), (7.5e-8, 0.5)]);
        // The channel's token was held 0..20 (the intervals overlap); its lane does not count.
        assert_eq!(s[2].1, [(2.5e-8, 0.4), (7.5e-8, 0.0)]);
    }
}
