//! `pxpl5 plot`: SVG pictures of saved results, drawn with plotters from the CSV files the other
//! commands write, so a figure can be redrawn without rerunning anything.
//!
//! - A sweep's `sweep.csv`: the methods' ratio (hemicube / hemisphere time per shot) and each
//!   method's time per shot against a swept parameter (`--x`, default the first that varies),
//!   a series per method and per value of the other parameters; `--y COLUMN` draws that column
//!   instead.
//! - `pxpl5 radiosity`'s `convergence-METHOD.csv` files (one or more): the worst surface error
//!   against shots, a series per file (per method), the error on a log scale.
//! - `pxpl5 sensitivity`'s `sensitivity.csv`: its tornado chart.
//! - `pxpl5 tradeoff`'s `tradeoff.csv`: the speed-accuracy frontier, host seconds against the
//!   error in simulated time and in radiosity, every knob a point and the Pareto-optimal ones
//!   joined, per method.
//! - `pxpl5 stability`'s `stability.csv`: form-factor error against the swept quantity.
//!
//! Only the SVG backend is built (no font or bitmap crates): text is left to the SVG viewer's
//! fonts, and its width estimated for the layout. The SVG bytes depend only on the rows, so a
//! figure is as reproducible as the study it shows.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use clap::Args;
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::UserError;
use crate::output::{self, outln};

/// Options of `pxpl5 plot`.
#[derive(Args, Clone, Debug)]
pub struct PlotArgs {
    /// CSV files: a sweep's sweep.csv, radiosity's convergence-*.csv (several: one series
    /// each), sensitivity.csv, tradeoff.csv or stability.csv.
    #[arg(required = true)]
    pub files: Vec<PathBuf>,
    /// A sweep's column for the x axis (a swept parameter); default: the first that varies.
    #[arg(long)]
    pub x: Option<String>,
    /// A sweep's column for the y axis, a series per method; default: two charts, the ratio and
    /// the time per shot.
    #[arg(long)]
    pub y: Option<String>,
    /// The SVG to write; default: the first file with .svg for .csv.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

/// One line of a chart, or its points alone.
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
    /// Whether the points are joined (false: markers only, for points in no order).
    pub line: bool,
}

/// One chart of lines; a log axis plots log10 of its values, labelled with the values.
pub struct Chart {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub log_x: bool,
    pub log_y: bool,
    pub series: Vec<Series>,
    /// Where the legend goes: where the lines are not.
    pub legend: SeriesLabelPosition,
}

/// The colours of the series, in turn: distinct on white and in grey.
const COLOURS: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(23, 190, 207),
    RGBColor(127, 127, 127),
];

/// A drawing error as the user's: plotters fails only on the output it writes to.
fn drawing<E: std::error::Error + Send + Sync>(e: DrawingAreaErrorKind<E>) -> UserError {
    UserError(format!("plot: cannot draw: {e}"))
}

/// A value as an axis label: short, no trailing zeros.
fn tick(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if !(1e-3..1e5).contains(&a) {
        // Up to three significant digits, trailing zeros dropped: 8.06e-4, 1e-6.
        let s = format!("{v:.2e}");
        let (mantissa, exponent) = s.split_once('e').unwrap_or((&s, "0"));
        let mantissa = mantissa.trim_end_matches('0').trim_end_matches('.');
        return format!("{mantissa}e{exponent}");
    }
    let s = format!("{v:.3}");
    s.trim_end_matches('0').trim_end_matches('.').to_string()
}

/// A linear f64 axis labelled at the values given ([`ticks`]), not at plotters' own.
struct Keyed {
    inner: plotters::coord::types::RangedCoordf64,
    keys: Vec<f64>,
}

impl Keyed {
    fn new(range: std::ops::Range<f64>, keys: Vec<f64>) -> Keyed {
        Keyed {
            inner: range.into(),
            keys,
        }
    }
}

impl Ranged for Keyed {
    type FormatOption = plotters::coord::ranged1d::DefaultFormatting;
    type ValueType = f64;
    fn map(&self, value: &f64, limit: (i32, i32)) -> i32 {
        self.inner.map(value, limit)
    }
    fn key_points<Hint: plotters::coord::ranged1d::KeyPointHint>(&self, hint: Hint) -> Vec<f64> {
        // Light lines (the hint asks for many) are not drawn: only the labelled values.
        if hint.max_num_points() > self.keys.len() * 4 && hint.weight().allow_light_points() {
            return Vec::new();
        }
        self.keys.clone()
    }
    fn range(&self) -> std::ops::Range<f64> {
        self.inner.range()
    }
}

/// Round values to label an axis from `lo` to `hi`: about 6 steps of 1, 2 or 5 times a power
/// of ten; on a log axis (`lo`, `hi` are log10 of the values), 1, 2 and 5 times each power of
/// ten, as log10, thinned to at most 12.
fn ticks(lo: f64, hi: f64, log: bool) -> Vec<f64> {
    if !(lo.is_finite() && hi.is_finite() && hi > lo) {
        return vec![lo];
    }
    if log {
        let mut out = Vec::new();
        let mut decade = lo.floor() as i32;
        while f64::from(decade) <= hi && out.len() < 100 {
            for m in [1.0, 2.0, 5.0] {
                let v = (m * 10f64.powi(decade)).log10();
                if (lo..=hi).contains(&v) {
                    out.push(v);
                }
            }
            decade += 1;
        }
        if out.len() > 12 {
            out.retain(|v| (v - v.round()).abs() < 1e-9);
        }
        if out.len() >= 2 {
            return out;
        }
    }
    let raw = (hi - lo) / 6.0;
    let power = 10f64.powf(raw.log10().floor());
    let step = [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * power)
        .find(|s| *s >= raw)
        .unwrap_or(10.0 * power);
    let mut out = Vec::new();
    let mut v = (lo / step).ceil() * step;
    while v <= hi && out.len() < 50 {
        // Snap to the step's grid, so that 0.30000000000000004 prints as 0.3.
        out.push((v / step).round() * step);
        v += step;
    }
    out
}

/// The range of `values` with a margin, never empty.
fn range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), v| {
            (l.min(v), h.max(v))
        });
    if lo > hi {
        return (0.0, 1.0);
    }
    let pad = if hi > lo {
        (hi - lo) * 0.05
    } else {
        lo.abs().max(1.0) * 0.1
    };
    (lo - pad, hi + pad)
}

/// `charts` side by side, `width` x `height` pixels each, as SVG text.
pub fn svg(charts: &[Chart], (width, height): (u32, u32)) -> Result<String, UserError> {
    let mut text = String::new();
    {
        let n = charts.len().max(1) as u32;
        let root = SVGBackend::with_string(&mut text, (width * n, height)).into_drawing_area();
        root.fill(&WHITE).map_err(drawing)?;
        let areas = root.split_evenly((1, n as usize));
        for (area, chart) in areas.iter().zip(charts) {
            draw_chart(area, chart)?;
        }
        root.present().map_err(drawing)?;
    }
    Ok(text)
}

fn draw_chart(area: &DrawingArea<SVGBackend, Shift>, chart: &Chart) -> Result<(), UserError> {
    let fx = |v: f64| if chart.log_x { v.log10() } else { v };
    let fy = |v: f64| if chart.log_y { v.log10() } else { v };
    let points: Vec<Vec<(f64, f64)>> = chart
        .series
        .iter()
        .map(|s| {
            s.points
                .iter()
                .map(|&(x, y)| (fx(x), fy(y)))
                .filter(|(x, y)| x.is_finite() && y.is_finite())
                .collect()
        })
        .collect();
    let (x0, x1) = range(points.iter().flatten().map(|p| p.0));
    let (y0, y1) = range(points.iter().flatten().map(|p| p.1));
    // Labels at round values: on a log axis, the values plotted when they are few (a sweep's
    // parameter), else 1, 2 and 5 times powers of ten.
    let mut xs: Vec<f64> = points.iter().flatten().map(|p| p.0).collect();
    xs.sort_by(f64::total_cmp);
    xs.dedup();
    let x_keys = if chart.log_x && xs.len() <= 12 {
        xs
    } else {
        ticks(x0, x1, chart.log_x)
    };
    let mut c = ChartBuilder::on(area)
        .caption(&chart.title, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(42)
        .y_label_area_size(64)
        .build_cartesian_2d(
            Keyed::new(x0..x1, x_keys),
            Keyed::new(y0..y1, ticks(y0, y1, chart.log_y)),
        )
        .map_err(drawing)?;
    let (log_x, log_y) = (chart.log_x, chart.log_y);
    let x_fmt = move |v: &f64| tick(if log_x { 10f64.powf(*v) } else { *v });
    let y_fmt = move |v: &f64| tick(if log_y { 10f64.powf(*v) } else { *v });
    c.configure_mesh()
        .x_desc(chart.x_label.as_str())
        .y_desc(chart.y_label.as_str())
        .x_label_formatter(&x_fmt)
        .y_label_formatter(&y_fmt)
        .light_line_style(WHITE)
        .draw()
        .map_err(drawing)?;
    for (k, (s, pts)) in chart.series.iter().zip(&points).enumerate() {
        let colour = COLOURS[k % COLOURS.len()];
        if !s.line {
            c.draw_series(
                pts.iter()
                    .map(|&p| Circle::new(p, 4, colour.stroke_width(2))),
            )
            .map_err(drawing)?
            .label(s.name.as_str())
            .legend(move |(x, y)| Circle::new((x + 9, y), 4, colour.stroke_width(2)));
            continue;
        }
        c.draw_series(LineSeries::new(pts.iter().copied(), colour.stroke_width(2)))
            .map_err(drawing)?
            .label(s.name.as_str())
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(2))
            });
        // Markers only where they can be told apart.
        if pts.len() <= 40 {
            c.draw_series(pts.iter().map(|&p| Circle::new(p, 3, colour.filled())))
                .map_err(drawing)?;
        }
    }
    if chart.series.len() > 1 || chart.series.first().is_some_and(|s| !s.name.is_empty()) {
        c.configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(chart.legend.clone())
            .draw()
            .map_err(drawing)?;
    }
    Ok(())
}

/// One bar of a tornado chart: a name and the change (low end, high end) it causes.
pub struct Bar {
    pub name: String,
    pub low: f64,
    pub high: f64,
}

/// A tornado chart: a horizontal bar per entry of `bars` (largest first, at the top), from its
/// low end's change to its high end's, about 0, as SVG text.
pub fn tornado(title: &str, x_label: &str, bars: &[Bar]) -> Result<String, UserError> {
    let mut text = String::new();
    {
        let n = bars.len().max(1);
        let height = 120 + 28 * n as u32;
        let root = SVGBackend::with_string(&mut text, (900, height)).into_drawing_area();
        root.fill(&WHITE).map_err(drawing)?;
        let (x0, x1) = range(bars.iter().flat_map(|b| [b.low, b.high, 0.0]));
        let names: Vec<String> = bars.iter().map(|b| b.name.clone()).collect();
        let mut c = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 18))
            .margin(12)
            .x_label_area_size(42)
            .y_label_area_size(330)
            .build_cartesian_2d(
                Keyed::new(x0..x1, ticks(x0, x1, false)),
                // A label at the middle of each bar's row.
                Keyed::new(0.0..n as f64, (0..n).map(|i| i as f64 + 0.5).collect()),
            )
            .map_err(drawing)?;
        // Row i from the bottom holds bar n - 1 - i: the first bar (the largest) at the top.
        let label = |v: &f64| {
            let row = v.floor().max(0.0) as usize;
            names
                .get(n.saturating_sub(1).saturating_sub(row))
                .cloned()
                .unwrap_or_default()
        };
        c.configure_mesh()
            .x_desc(x_label)
            .x_label_formatter(&|v: &f64| tick(*v))
            .y_label_formatter(&label)
            .light_line_style(WHITE)
            .draw()
            .map_err(drawing)?;
        let low = RGBColor(31, 119, 180);
        let high = RGBColor(214, 39, 40);
        for (k, b) in bars.iter().enumerate() {
            let row = (n - 1 - k) as f64;
            // The longer bar first, so that the shorter one stays visible over it.
            let mut ends = [(b.low, low), (b.high, high)];
            ends.sort_by(|x, y| y.0.abs().total_cmp(&x.0.abs()));
            for (end, colour) in ends {
                let rect = Rectangle::new(
                    [(0.0, row + 0.15), (end, row + 0.85)],
                    colour.mix(0.8).filled(),
                );
                c.draw_series(std::iter::once(rect)).map_err(drawing)?;
            }
        }
        // The legend: which colour is which end.
        c.draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())
            .map_err(drawing)?
            .label("low end of the range")
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 14, y + 5)], low.filled()));
        c.draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())
            .map_err(drawing)?
            .label("high end of the range")
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 14, y + 5)], high.filled()));
        c.configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .position(SeriesLabelPosition::LowerRight)
            .draw()
            .map_err(drawing)?;
        root.present().map_err(drawing)?;
    }
    Ok(text)
}

/// A CSV file as written by the commands: its columns and rows (`#` lines skipped).
pub struct Table {
    pub path: PathBuf,
    pub columns: Vec<String>,
    pub rows: Vec<Vec<String>>,
}

impl Table {
    pub fn read(path: &Path) -> Result<Table, UserError> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| UserError(format!("{}: cannot read: {e}", path.display())))?;
        Table::parse(path, &text)
    }

    /// The table of CSV `text`, named `path` in errors.
    pub fn parse(path: &Path, text: &str) -> Result<Table, UserError> {
        let mut lines = text
            .lines()
            .filter(|l| !l.starts_with('#') && !l.is_empty());
        let header = lines
            .next()
            .ok_or_else(|| UserError(format!("{}: empty: no header line", path.display())))?;
        Ok(Table {
            path: path.to_path_buf(),
            columns: split_csv(header),
            rows: lines.map(split_csv).collect(),
        })
    }

    /// The index of `column`, or an error naming the file and the columns it has.
    pub fn column(&self, column: &str, what: &str) -> Result<usize, UserError> {
        self.columns
            .iter()
            .position(|c| c == column)
            .ok_or_else(|| {
                UserError(format!(
                    "{what} {column}: {} has no such column (it has: {})",
                    self.path.display(),
                    self.columns.join(", ")
                ))
            })
    }

    /// The number in `row`'s `col`, or an error naming the file, row and column.
    fn number(&self, row: usize, col: usize) -> Result<Option<f64>, UserError> {
        let cell = self.rows[row].get(col).map_or("", String::as_str);
        if cell.is_empty() {
            return Ok(None);
        }
        cell.parse::<f64>().map(Some).map_err(|_| {
            UserError(format!(
                "{}: row {}, column {}: `{cell}` is not a number",
                self.path.display(),
                row + 1,
                self.columns[col]
            ))
        })
    }
}

/// The fields of one CSV line (quoted fields may hold commas and doubled quotes).
pub fn split_csv(line: &str) -> Vec<String> {
    let mut out = Vec::new();
    let mut field = String::new();
    let mut quoted = false;
    let mut chars = line.chars().peekable();
    while let Some(c) = chars.next() {
        match (c, quoted) {
            ('"', true) if chars.peek() == Some(&'"') => {
                field.push('"');
                chars.next();
            }
            ('"', _) => quoted = !quoted,
            (',', false) => out.push(std::mem::take(&mut field)),
            (c, _) => field.push(c),
        }
    }
    out.push(field);
    out
}

/// `pxpl5 plot`.
pub fn plot(args: &PlotArgs) -> Result<(), UserError> {
    let tables = args
        .files
        .iter()
        .map(|f| Table::read(f))
        .collect::<Result<Vec<_>, _>>()?;
    let first = &tables[0];
    let has = |t: &Table, c: &str| t.columns.iter().any(|x| x == c);
    let picture = if has(first, "per_shot_ms") && has(first, "method") {
        if tables.len() > 1 {
            return Err(UserError("plot: give one sweep.csv at a time".into()));
        }
        svg(
            &sweep_charts(first, args.x.as_deref(), args.y.as_deref())?,
            (560, 420),
        )?
    } else if has(first, "worst_surface_error") && has(first, "shots") {
        svg(&[convergence_chart(&tables)?], (640, 440))?
    } else if has(first, "ratio_low") && has(first, "parameter") {
        sensitivity_chart(first)?
    } else if has(first, "time_error") && has(first, "pareto") {
        svg(&tradeoff_charts(first)?, (560, 440))?
    } else if has(first, "ff_error") && has(first, "study") {
        svg(&stability_charts(first)?, (560, 420))?
    } else {
        return Err(UserError(format!(
            "plot: {}: not a file pxpl5 plot knows (a sweep.csv, convergence-*.csv, \
             sensitivity.csv, tradeoff.csv or stability.csv); its columns: {}",
            first.path.display(),
            first.columns.join(", ")
        )));
    };
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| first.path.with_extension("svg"));
    let dest = output::dest("--out", &out, true)?;
    output::write_all(&[(dest, picture.into_bytes())], Vec::new())?;
    if out.as_os_str() != "-" {
        outln!("plot: wrote {}", out.display())?;
    }
    Ok(())
}

/// The parameter columns of a sweep: between `method` and `config`.
fn parameters(t: &Table) -> Vec<usize> {
    let start = t
        .columns
        .iter()
        .position(|c| c == "method")
        .map_or(0, |k| k + 1);
    let end = t
        .columns
        .iter()
        .position(|c| c == "config")
        .unwrap_or(start);
    (start..end).collect()
}

/// The charts of a sweep: `y` (or the ratio and the time per shot) against `x`.
fn sweep_charts(t: &Table, x: Option<&str>, y: Option<&str>) -> Result<Vec<Chart>, UserError> {
    let params = parameters(t);
    let varies = |c: usize| {
        let mut values: Vec<&String> = t.rows.iter().filter_map(|r| r.get(c)).collect();
        values.dedup();
        values.len() > 1
    };
    let x = match x {
        Some(name) => t.column(name, "--x")?,
        None => params.iter().copied().find(|&c| varies(c)).ok_or_else(|| {
            UserError(format!(
                "plot: {}: no swept parameter varies; give --x COLUMN",
                t.path.display()
            ))
        })?,
    };
    let method = t.column("method", "plot")?;
    let others: Vec<usize> = params
        .into_iter()
        .filter(|&c| c != x && varies(c))
        .collect();
    let name_of = |r: &[String], with_method: bool| {
        let mut parts: Vec<String> = Vec::new();
        if with_method {
            parts.push(r[method].clone());
        }
        parts.extend(others.iter().map(|&c| format!("{}={}", t.columns[c], r[c])));
        parts.join(", ")
    };
    // Series in the order first met (the study's order), points sorted by x.
    let collect =
        |ycol: usize, with_method: bool, only: Option<&str>| -> Result<Vec<Series>, UserError> {
            let mut order: Vec<String> = Vec::new();
            let mut by: BTreeMap<String, Vec<(f64, f64)>> = BTreeMap::new();
            for (k, r) in t.rows.iter().enumerate() {
                if only.is_some_and(|m| r[method] != m) {
                    continue;
                }
                let (Some(xv), Some(yv)) = (t.number(k, x)?, t.number(k, ycol)?) else {
                    continue;
                };
                let name = name_of(r, with_method);
                if !by.contains_key(&name) {
                    order.push(name.clone());
                }
                by.entry(name).or_default().push((xv, yv));
            }
            Ok(order
                .into_iter()
                .map(|name| {
                    let mut points = by.remove(&name).unwrap_or_default();
                    points.sort_by(|a, b| a.0.total_cmp(&b.0));
                    Series {
                        name,
                        points,
                        line: true,
                    }
                })
                .collect())
        };
    let x_label = t.columns[x].clone();
    // A quantity that spans more than a factor of 8 reads best on a log axis.
    let spread = |c: usize| {
        let vs: Vec<f64> = (0..t.rows.len())
            .filter_map(|k| t.number(k, c).ok().flatten())
            .collect();
        let (lo, hi) = vs
            .iter()
            .fold((f64::INFINITY, 0f64), |(l, h), &v| (l.min(v), h.max(v)));
        lo > 0.0 && hi / lo > 8.0
    };
    let log_x = spread(x);
    if let Some(y) = y {
        let ycol = t.column(y, "--y")?;
        return Ok(vec![Chart {
            title: format!("{y} against {x_label}"),
            x_label,
            y_label: y.to_string(),
            log_x,
            log_y: spread(ycol),
            series: collect(ycol, true, None)?,
            legend: SeriesLabelPosition::UpperRight,
        }]);
    }
    let ratio = t.column("ratio_per_shot", "plot")?;
    let per_shot = t.column("per_shot_ms", "plot")?;
    let first_method = t
        .rows
        .first()
        .map(|r| r[method].clone())
        .unwrap_or_default();
    Ok(vec![
        Chart {
            title: format!("hemicube / hemisphere time per shot against {x_label}"),
            x_label: x_label.clone(),
            y_label: "ratio (the seed claims 5)".into(),
            log_x,
            log_y: false,
            series: collect(ratio, false, Some(&first_method))?,
            legend: SeriesLabelPosition::UpperLeft,
        },
        Chart {
            title: format!("simulated time per shot against {x_label}"),
            x_label,
            y_label: "ms per shot".into(),
            log_x,
            log_y: spread(per_shot),
            series: collect(per_shot, true, None)?,
            legend: SeriesLabelPosition::UpperRight,
        },
    ])
}

/// Error against shots, a series per convergence file.
fn convergence_chart(tables: &[Table]) -> Result<Chart, UserError> {
    let mut series = Vec::new();
    for t in tables {
        let shots = t.column("shots", "plot")?;
        let error = t.column("worst_surface_error", "plot")?;
        let points = (0..t.rows.len())
            .map(|k| Ok(t.number(k, shots)?.zip(t.number(k, error)?)))
            .collect::<Result<Vec<_>, UserError>>()?
            .into_iter()
            .flatten()
            .filter(|&(_, e)| e > 0.0)
            .collect();
        let stem = t.path.file_stem().and_then(|s| s.to_str()).unwrap_or("");
        let name = stem
            .strip_prefix("convergence-")
            .unwrap_or(stem)
            .to_string();
        series.push(Series {
            name,
            points,
            line: true,
        });
    }
    Ok(Chart {
        title: "convergence: worst surface error against shots".into(),
        x_label: "shots".into(),
        y_label: "worst surface error (relative)".into(),
        log_x: false,
        log_y: true,
        series,
        legend: SeriesLabelPosition::UpperRight,
    })
}

/// The tornado chart of a `sensitivity.csv`.
pub fn sensitivity_chart(t: &Table) -> Result<String, UserError> {
    let name = t.column("parameter", "plot")?;
    let low = t.column("ratio_low", "plot")?;
    let high = t.column("ratio_high", "plot")?;
    let base = t.column("ratio_default", "plot")?;
    let mut bars = Vec::new();
    for k in 0..t.rows.len() {
        let b = t.number(k, base)?.unwrap_or(0.0);
        bars.push(Bar {
            name: t.rows[k][name].clone(),
            low: t.number(k, low)?.map_or(0.0, |v| v - b),
            high: t.number(k, high)?.map_or(0.0, |v| v - b),
        });
    }
    let b = if t.rows.is_empty() {
        0.0
    } else {
        t.number(0, base)?.unwrap_or(0.0)
    };
    tornado(
        &format!(
            "sensitivity of the hemicube / hemisphere ratio ({} at the defaults)",
            tick(b)
        ),
        "change of the ratio per shot",
        &bars,
    )
}

/// Errors below this are drawn at it on the frontier's log axes: an exact level's time error is
/// exactly 0, which a log axis cannot show (0.001 %, far below any error the study reports).
const ERROR_FLOOR: f64 = 1e-5;

/// The charts of a `tradeoff.csv`: host seconds against the time error, then against the
/// radiosity error; per method its knobs as points and its Pareto-optimal knobs joined by a line
/// in order of host seconds.
pub fn tradeoff_charts(t: &Table) -> Result<Vec<Chart>, UserError> {
    let method = t.column("method", "plot")?;
    let host = t.column("host_s", "plot")?;
    let pareto = t.column("pareto", "plot")?;
    let mut charts = Vec::new();
    for (column, what) in [
        ("time_error", "simulated time to target"),
        ("radiosity_error", "radiosity (worst surface)"),
    ] {
        let y = t.column(column, "plot")?;
        let mut methods: Vec<String> = Vec::new();
        for r in &t.rows {
            if !methods.contains(&r[method]) {
                methods.push(r[method].clone());
            }
        }
        let mut series = Vec::new();
        for m in &methods {
            let mut all = Vec::new();
            let mut front = Vec::new();
            for (k, r) in t.rows.iter().enumerate().filter(|(_, r)| &r[method] == m) {
                let (Some(h), Some(e)) = (t.number(k, host)?, t.number(k, y)?) else {
                    continue;
                };
                let point = (h, e.max(ERROR_FLOOR));
                all.push(point);
                if r[pareto] == "true" {
                    front.push(point);
                }
            }
            front.sort_by(|a, b| a.0.total_cmp(&b.0));
            series.push(Series {
                name: format!("{m}: every knob"),
                points: all,
                line: false,
            });
            series.push(Series {
                name: format!("{m}: Pareto frontier"),
                points: front,
                line: true,
            });
        }
        charts.push(Chart {
            title: format!("error in {what} against host time"),
            x_label: "host CPU seconds".into(),
            y_label: format!("relative error (floor {})", tick(ERROR_FLOOR)),
            log_x: true,
            log_y: true,
            series,
            legend: SeriesLabelPosition::UpperRight,
        });
    }
    Ok(charts)
}

/// The charts of a `stability.csv`: per study, the form-factor error against its quantity.
pub fn stability_charts(t: &Table) -> Result<Vec<Chart>, UserError> {
    let study = t.column("study", "plot")?;
    let x = t.column("x", "plot")?;
    let method = t.column("method", "plot")?;
    let error = t.column("ff_error", "plot")?;
    let mut studies: Vec<String> = Vec::new();
    for r in &t.rows {
        if !studies.contains(&r[study]) {
            studies.push(r[study].clone());
        }
    }
    let mut charts = Vec::new();
    for s in studies {
        let mut by: Vec<Series> = Vec::new();
        for (k, r) in t.rows.iter().enumerate().filter(|(_, r)| r[study] == s) {
            let (Some(xv), Some(e)) = (t.number(k, x)?, t.number(k, error)?) else {
                continue;
            };
            // Exact zeros cannot go on a log axis: floored at 1e-17, below f64's precision.
            let point = (xv, e.abs().max(1e-17));
            match by.iter_mut().find(|b| b.name == r[method]) {
                Some(b) => b.points.push(point),
                None => by.push(Series {
                    name: r[method].clone(),
                    points: vec![point],
                    line: true,
                }),
            }
        }
        let log_x = by.iter().flat_map(|b| &b.points).all(|p| p.0 > 0.0) && s != "qee_frac_bits";
        charts.push(Chart {
            title: format!("form-factor error against {s}"),
            x_label: s.clone(),
            y_label: "|machine - exact| / exact".into(),
            log_x,
            log_y: true,
            series: by,
            legend: SeriesLabelPosition::UpperRight,
        });
    }
    Ok(charts)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn csv_fields_split_with_quotes() {
        assert_eq!(
            split_csv("1,\"a, \"\"b\"\"\",,x"),
            ["1", "a, \"b\"", "", "x"]
        );
    }

    #[test]
    fn ticks_are_short() {
        assert_eq!(tick(0.0), "0");
        assert_eq!(tick(2.5), "2.5");
        assert_eq!(tick(128.0), "128");
        assert_eq!(tick(1e-6), "1e-6");
        assert_eq!(tick(8.0555e-4), "8.06e-4");
        assert_eq!(tick(0.125), "0.125");
        assert_eq!(
            ticks(0.0, 1.0, false),
            [0.0, 0.2, 0.4, 0.6000000000000001, 0.8, 1.0]
        );
        let log: Vec<String> = ticks(0.0, 2.0, true)
            .iter()
            .map(|v| tick(10f64.powf(*v)))
            .collect();
        assert_eq!(log, ["1", "2", "5", "10", "20", "50", "100"]);
    }

    /// The same series draw the same bytes, and every series is in the picture.
    #[test]
    fn svgs_are_reproducible_and_hold_every_series() {
        let chart = || Chart {
            title: "t".into(),
            x_label: "x".into(),
            y_label: "y".into(),
            log_x: true,
            log_y: false,
            series: vec![
                Series {
                    name: "hemisphere".into(),
                    points: vec![(1.0, 2.0), (4.0, 3.0)],
                    line: true,
                },
                Series {
                    name: "hemicube".into(),
                    points: vec![(1.0, 5.0), (4.0, 1.0)],
                    line: true,
                },
            ],
            legend: SeriesLabelPosition::UpperRight,
        };
        let a = svg(&[chart()], (400, 300)).unwrap_or_default();
        assert_eq!(a, svg(&[chart()], (400, 300)).unwrap_or_default());
        assert!(a.starts_with("<svg") && a.contains("hemisphere") && a.contains("hemicube"));
        let t = tornado(
            "ranked",
            "change",
            &[Bar {
                name: "ring.hop_latency_cycles".into(),
                low: -0.5,
                high: 1.0,
            }],
        )
        .unwrap_or_default();
        assert!(t.contains("ring.hop_latency_cycles"), "{t}");
    }
}
