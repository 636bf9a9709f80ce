//! `pxpl5 stats diff A B`: what changed between two runs' simulated figures, for regression work
//! on cycle counts (a CI job keeps a stats file and compares every build's with it).
//!
//! Both files are JSON as the simulator writes it: `stats.json` of `pxpl5 run`,
//! `comparison.json` of `pxpl5 radiosity`, or `formfactor --json`. They are flattened into
//! figures named by their path (`gps[gp=3].busy_cycles`, `methods[method=hemicube].per_shot_s`):
//! an array of objects is keyed by the object's identifying field (`gp`, `renderer`, `channel`,
//! `node`, `phase`, `activity`, `method`), so that a unit added or removed shows as that unit,
//! not as every later one shifted; other arrays by index. Numbers are compared with a relative
//! tolerance (`--tolerance`, default 0: exact), everything else exactly.
//!
//! The report lists every figure that changed, was added or was removed, with both values and,
//! for numbers, the change and the relative change. Exit code 0 when nothing differs beyond the
//! tolerance, 1 when something does (as `diff` does), 2 for a file that cannot be read or is not
//! JSON.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use clap::Args;
use serde_json::Value;

use crate::failure::{Failure, UserError};
use crate::output::{out, outln};

/// Options of `pxpl5 stats diff`.
#[derive(Args, Clone, Debug)]
pub struct DiffArgs {
    /// The reference file (JSON: stats.json, comparison.json, formfactor --json).
    pub a: PathBuf,
    /// The file compared with it.
    pub b: PathBuf,
    /// Relative tolerance for numbers: |b - a| <= tolerance x max(|a|, |b|) counts as equal
    /// (default 0: any change differs).
    #[arg(long, default_value_t = 0.0)]
    pub tolerance: f64,
    /// Compare only figures whose path starts with this (e.g. `methods[method=hemicube]`, `ring`);
    /// may be repeated.
    #[arg(long)]
    pub only: Vec<String>,
}

/// The fields that identify an object among its array's, in the order they are looked for.
const KEYS: [&str; 7] = [
    "method", "gp", "renderer", "channel", "node", "phase", "activity",
];

/// `pxpl5 stats diff`.
pub fn diff(args: &DiffArgs) -> Result<(), Failure> {
    if !(args.tolerance >= 0.0 && args.tolerance.is_finite()) {
        return Err(UserError(format!(
            "--tolerance {}: must be a finite number >= 0 (0.01 is 1 %)",
            args.tolerance
        ))
        .into());
    }
    let (a, b) = (figures(&args.a)?, figures(&args.b)?);
    let wanted = |path: &str| args.only.is_empty() || args.only.iter().any(|p| path.starts_with(p));
    let mut lines = Vec::new();
    let mut paths: Vec<&String> = a.keys().chain(b.keys()).filter(|p| wanted(p)).collect();
    paths.sort();
    paths.dedup();
    for path in paths {
        match (a.get(path), b.get(path)) {
            (Some(x), Some(y)) => {
                if let Some(line) = changed(path, x, y, args.tolerance) {
                    lines.push(line);
                }
            }
            (Some(x), None) => lines.push(format!("- {path}: {x} (only in A)")),
            (None, Some(y)) => lines.push(format!("+ {path}: {y} (only in B)")),
            (None, None) => {}
        }
    }
    let compared = a.keys().chain(b.keys()).filter(|p| wanted(p)).count();
    if lines.is_empty() {
        outln!(
            "{} and {}: no figure differs ({} compared{})",
            args.a.display(),
            args.b.display(),
            compared,
            tolerance_note(args.tolerance)
        )?;
        return Ok(());
    }
    outln!("A: {}\nB: {}", args.a.display(), args.b.display())?;
    for line in &lines {
        outln!("{line}")?;
    }
    out!("")?;
    Err(Failure::Differs(format!(
        "stats diff: {} of the figures differ{}",
        lines.len(),
        tolerance_note(args.tolerance)
    )))
}

fn tolerance_note(t: f64) -> String {
    if t > 0.0 {
        format!(", tolerance {}", t)
    } else {
        String::new()
    }
}

/// The report line of a figure that differs beyond `tolerance`, or `None`.
fn changed(path: &str, x: &Value, y: &Value, tolerance: f64) -> Option<String> {
    match (x.as_f64(), y.as_f64()) {
        (Some(p), Some(q)) => {
            let scale = p.abs().max(q.abs());
            if (q - p).abs() <= tolerance * scale || p == q {
                return None;
            }
            let relative = if p != 0.0 {
                format!(" ({:+.4} %)", 100.0 * (q - p) / p.abs())
            } else {
                String::new()
            };
            Some(format!("~ {path}: {x} -> {y}, {:+}{relative}", q - p))
        }
        _ => (x != y).then(|| format!("~ {path}: {x} -> {y}")),
    }
}

/// The figures of the JSON file at `path`, by path.
fn figures(path: &Path) -> Result<BTreeMap<String, Value>, UserError> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| UserError(format!("{}: cannot read: {e}", path.display())))?;
    let json: Value = serde_json::from_str(&text).map_err(|e| {
        UserError(format!(
            "{}: not JSON (line {}, column {}): {e}",
            path.display(),
            e.line(),
            e.column()
        ))
    })?;
    let mut out = BTreeMap::new();
    flatten(&json, String::new(), &mut out);
    Ok(out)
}

/// Add every leaf of `v` under `prefix` to `out`.
fn flatten(v: &Value, prefix: String, out: &mut BTreeMap<String, Value>) {
    let join = |p: &str, k: &str| {
        if p.is_empty() {
            k.to_string()
        } else {
            format!("{p}.{k}")
        }
    };
    match v {
        Value::Object(m) => {
            for (k, x) in m {
                flatten(x, join(&prefix, k), out);
            }
        }
        Value::Array(items) => {
            for (i, x) in items.iter().enumerate() {
                flatten(x, format!("{prefix}[{}]", item_key(x, i, items)), out);
            }
        }
        leaf => {
            out.insert(prefix, leaf.clone());
        }
    }
}

/// How an array item is named: by its identifying field if every item of the array has that field
/// with distinct values, else by its index.
fn item_key(x: &Value, i: usize, items: &[Value]) -> String {
    for k in KEYS {
        let values: Vec<&Value> = items.iter().filter_map(|it| it.get(k)).collect();
        if values.len() != items.len() {
            continue;
        }
        let mut distinct: Vec<String> = values.iter().map(|v| v.to_string()).collect();
        distinct.sort();
        distinct.dedup();
        if distinct.len() == items.len()
            && let Some(v) = x.get(k)
        {
            let shown = v.as_str().map_or_else(|| v.to_string(), str::to_string);
            return format!("{k}={shown}");
        }
    }
    i.to_string()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn flat(v: Value) -> BTreeMap<String, Value> {
        let mut out = BTreeMap::new();
        flatten(&v, String::new(), &mut out);
        out
    }

    #[test]
    fn arrays_of_units_are_keyed_by_the_unit() {
        let f = flat(serde_json::json!({
            "gps": [{"gp": 0, "busy": 5}, {"gp": 1, "busy": 7}],
            "plain": [3, 4],
            "methods": [{"method": "hemicube", "s": 1.5}],
        }));
        assert_eq!(f["gps[gp=1].busy"], 7);
        assert_eq!(f["plain[1]"], 4);
        assert_eq!(f["methods[method=hemicube].s"], 1.5);
        assert_eq!(f["methods[method=hemicube].method"], "hemicube");
    }

    #[test]
    fn numbers_within_the_tolerance_are_equal() {
        let (a, b) = (serde_json::json!(100), serde_json::json!(101));
        assert!(changed("x", &a, &b, 0.0).is_some());
        assert!(changed("x", &a, &b, 0.01).is_none());
        let line = changed("x", &a, &b, 0.001).unwrap();
        assert_eq!(line, "~ x: 100 -> 101, +1 (+1.0000 %)");
        let (s, t) = (serde_json::json!("a"), serde_json::json!("b"));
        assert_eq!(changed("k", &s, &t, 1.0).unwrap(), "~ k: \"a\" -> \"b\"");
        assert!(changed("k", &s, &s, 0.0).is_none());
    }
}
