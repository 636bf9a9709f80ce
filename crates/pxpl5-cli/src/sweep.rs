//! `pxpl5 sweep`: a study of the radiosity experiment over any machine-config field and any
//! option of `pxpl5 radiosity`, one row per point and method, and `pxpl5 sweep merge`, which joins
//! the outputs of shards (`--shard K/N`) into the bytes one run gives.
//!
//! **Points.** `--set PATH=V1,V2,...` (and a study file's `set`) span the cross product, the first
//! parameter varying slowest; a study file's `points` lists more. A PATH starting with `program.`
//! is an option of `pxpl5 radiosity` (`program.resolution` is `--resolution`): the point's
//! options are parsed by the radiosity command's own parser, so every value is checked as it is
//! there. Any other PATH is a field of the machine config, set on its serialized form and checked
//! by the config's own validation; a bad path or value is a user error naming it (exit code 2),
//! found before the first run.
//!
//! **Runs.** Each point runs as `pxpl5 radiosity` runs it (`radiosity::prepare`,
//! `radiosity::run_method`), with `--shots 24` and no accuracy target unless `--shots` or
//! `--until-error` say otherwise, so a default study takes minutes. Points run on a pool of
//! `--workers` threads (crossbeam-channel); each finished point is appended at once to
//! `OUT/rows.jsonl`, the journal. The outputs are written from the journal in point order, so
//! they are the same bytes whatever the number of workers or the order points finish in:
//! `sweep.csv`, `sweep.json` (every parameter and simulated result) and `study.json` (the points
//! and their keys). Host seconds (the CPU time of the thread that simulated the point), which
//! differ from run to run, go to `host.csv` alone.
//!
//! **Resume.** A point's key is a hash of the simulator's version, the point's machine config
//! (its hash) and its radiosity options: a rerun with the same `--out` skips every point whose
//! key is in the journal. Ctrl-C ends the points under way after their shot, discards them, and
//! writes the finished rows (exit code 130); `--limit N` runs at most N points and stops the same
//! way without the interrupt.

use std::collections::{BTreeMap, BTreeSet};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use clap::{Args, FromArgMatches, Subcommand};
use cpu_time::ThreadTime;
use pxpl5_config::{FileKind, MachineConfig};
use pxpl5_machine::Resource;
use pxpl5_radiosity::comparison::{Comparison, MethodSummary};
use pxpl5_radiosity::shot::check_resolution;
use serde_json::Value;
use sha2::{Digest, Sha256};

use crate::UserError;
use crate::choices::Methods;
use crate::config_cmd;
use crate::failure::Failure;
use crate::output::{self, outln};
use crate::radiosity::{self, Prepared, RadiosityArgs, number};
use crate::watch::{self, HostLimit, Watch};

/// `--shots` of a sweep without `--shots` or `--until-error`: enough shots to time them (the
/// time per shot settles after a few batches) and to measure the form factors, few enough that
/// the README's studies take minutes on 2 cores.
pub const DEFAULT_SHOTS: usize = 24;

/// `pxpl5 sweep`: run a study, or merge shards.
#[derive(clap::Args, Clone, Debug)]
#[command(args_conflicts_with_subcommands = true)]
pub struct SweepCommand {
    #[command(subcommand)]
    pub merge: Option<SweepSub>,
    #[command(flatten)]
    pub args: SweepArgs,
}

#[derive(Subcommand, Clone, Debug)]
pub enum SweepSub {
    /// Join the outputs of a study's shards (`--shard K/N`, each in its own directory) into OUT:
    /// the same bytes one run of the whole study writes. Every point must be in one shard.
    Merge {
        /// Output directory of the merged study.
        out: PathBuf,
        /// The shards' output directories.
        #[arg(required = true)]
        shards: Vec<PathBuf>,
    },
}

/// Options of `pxpl5 sweep`.
#[derive(Args, Clone, Debug)]
pub struct SweepArgs {
    /// A parameter and its values, PATH=V1,V2,...: a machine-config field (renderer.count,
    /// gp.costs.message_send, ring.token_policy, ...) or a radiosity option as program.NAME
    /// (program.resolution, program.patch_size, program.depth, program.all_faces, ...). Repeat
    /// for more parameters: the points are their cross product, the first varying slowest.
    #[arg(long = "set", value_name = "PATH=VALUES")]
    pub set: Vec<String>,
    /// A study file (RON): `(set: [("renderer.count", [1, 4])], points: [[("program.resolution",
    /// 64)]], config: "file.ron", method: "both", shots: 24, until_error: 0.01)`, every field
    /// optional; `--set` adds to its cross product, flags override the rest.
    #[arg(long, value_name = "FILE")]
    pub study: Option<PathBuf>,
    /// Machine config (RON) the config fields are set on; default: the embedded seed machine.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Form-factor methods run at every point (a row each).
    #[arg(long, value_enum)]
    pub method: Option<Methods>,
    /// Shots per run. Default: 24, or with --until-error the radiosity command's (10 per patch).
    #[arg(long)]
    pub shots: Option<usize>,
    /// Stop each run once every surface is within this fraction of the reference (the rows then
    /// have the time to target). Default: no target, a fixed number of shots.
    #[arg(long)]
    pub until_error: Option<f64>,
    /// Output directory; a rerun with the same one resumes (skips the points done).
    #[arg(long, default_value = "out/sweep")]
    pub out: PathBuf,
    /// Points run at once. Default: the cores available.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub workers: Option<u32>,
    /// Run only every N-th point from K (K from 0 to N-1), e.g. 0/4: one of N shards, to be joined
    /// by `pxpl5 sweep merge`.
    #[arg(long, value_name = "K/N", value_parser = parse_shard)]
    pub shard: Option<Shard>,
    /// Run at most this many points not yet done, then write the rows and stop (exit code 0; a
    /// rerun runs the rest).
    #[arg(long)]
    pub limit: Option<usize>,
    /// Stop a point's run with an error once it has taken this much host time (ms, s, min or h;
    /// `none`).
    #[arg(long, value_name = "TIME", default_value = watch::DEFAULT_HOST_LIMIT,
          value_parser = watch::parse_host_limit)]
    pub host_time_limit: HostLimit,
}

/// One of N shards: the points whose index is K modulo N.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    pub k: usize,
    pub n: usize,
}

/// Parse `--shard K/N`.
fn parse_shard(text: &str) -> Result<Shard, String> {
    let bad = || format!("`{text}`: give K/N with 0 <= K < N, e.g. 0/4");
    let (k, n) = text.split_once('/').ok_or_else(bad)?;
    let k: usize = k.trim().parse().map_err(|_| bad())?;
    let n: usize = n.trim().parse().map_err(|_| bad())?;
    if n == 0 || k >= n {
        return Err(bad());
    }
    Ok(Shard { k, n })
}

/// A study: the options every point shares and the points' parameter values.
#[derive(Clone, Debug)]
pub struct Study {
    pub config: Option<PathBuf>,
    pub method: Methods,
    pub shots: Option<usize>,
    pub until_error: Option<f64>,
    /// Parameter names in the order first given.
    pub params: Vec<String>,
    /// Per point, per parameter, its value (`None`: the default).
    pub points: Vec<Vec<Option<String>>>,
    pub host_time_limit: HostLimit,
}

/// One point, resolved: its machine config and the radiosity options it runs with.
#[derive(Clone, Debug)]
pub struct Point {
    pub index: usize,
    /// (parameter, value) as given, default values left out.
    pub values: Vec<(String, String)>,
    /// Every parameter of the study with this point's value, empty for its default: the rows'
    /// parameter columns.
    pub columns: Vec<(String, String)>,
    pub cfg: MachineConfig,
    pub args: RadiosityArgs,
    /// Hash of what the point's results depend on: version, config, options.
    pub key: String,
}

impl Point {
    /// The point as messages name it: `point 3 (renderer.count=4, program.resolution=64)`.
    pub fn label(&self) -> String {
        let values: Vec<String> = self
            .values
            .iter()
            .map(|(p, v)| format!("{p}={v}"))
            .collect();
        format!("point {} ({})", self.index, values.join(", "))
    }
}

/// A study from a file and flags: the file first, `--set` adding parameters to its cross product.
pub fn study_of(args: &SweepArgs) -> Result<Study, UserError> {
    let mut cross: Vec<(String, Vec<String>)> = Vec::new();
    let mut listed: Vec<Vec<(String, String)>> = Vec::new();
    let mut study = Study {
        config: args.config.clone(),
        method: args.method.unwrap_or(Methods::Both),
        shots: args.shots,
        until_error: args.until_error,
        params: Vec::new(),
        points: Vec::new(),
        host_time_limit: args.host_time_limit.clone(),
    };
    if let Some(file) = &args.study {
        let file_text = read_study_file(file)?;
        apply_study_file(&file_text, file, args, &mut study, &mut cross, &mut listed)?;
    }
    for set in &args.set {
        let (path, values) = set.split_once('=').ok_or_else(|| {
            UserError(format!(
                "--set {set}: give PATH=V1,V2,... (e.g. renderer.count=1,4)"
            ))
        })?;
        let values: Vec<String> = values
            .split(',')
            .map(|v| v.trim().to_string())
            .filter(|v| !v.is_empty())
            .collect();
        if values.is_empty() {
            return Err(UserError(format!("--set {set}: no values after `=`")));
        }
        cross.push((path.trim().to_string(), values));
    }
    for (name, _) in &cross {
        if cross.iter().filter(|(n, _)| n == name).count() > 1 {
            return Err(UserError(format!("--set {name}: given twice")));
        }
    }
    let mut params: Vec<String> = cross.iter().map(|(n, _)| n.clone()).collect();
    for point in &listed {
        for (name, _) in point {
            if !params.contains(name) {
                params.push(name.clone());
            }
        }
    }
    let mut points = Vec::new();
    if !cross.is_empty() || listed.is_empty() {
        let mut index = vec![0usize; cross.len()];
        'product: loop {
            let mut values: Vec<Option<String>> = vec![None; params.len()];
            for (k, (_, vs)) in cross.iter().enumerate() {
                values[k] = Some(vs[index[k]].clone());
            }
            points.push(values);
            // The last parameter varies fastest.
            for k in (0..cross.len()).rev() {
                index[k] += 1;
                if index[k] < cross[k].1.len() {
                    continue 'product;
                }
                index[k] = 0;
            }
            break;
        }
    }
    for point in listed {
        let mut values: Vec<Option<String>> = vec![None; params.len()];
        for (name, v) in point {
            if let Some(k) = params.iter().position(|p| *p == name) {
                values[k] = Some(v);
            }
        }
        points.push(values);
    }
    study.params = params;
    study.points = points;
    Ok(study)
}

/// The text of a study file.
fn read_study_file(file: &Path) -> Result<(String, String), UserError> {
    pxpl5_config::read_text(FileKind::Study, file).map_err(config_cmd::report)
}

/// A value of a study file as the text `--set` would give it.
fn value_text(file: &str, what: &str, v: &Value) -> Result<String, UserError> {
    match v {
        Value::String(s) => Ok(s.clone()),
        Value::Number(n) => Ok(n.to_string()),
        Value::Bool(b) => Ok(b.to_string()),
        _ => Err(UserError(format!(
            "{file}: {what}: a value must be a number, a string or a bool, not {v}"
        ))),
    }
}

/// A (name, value) list of a study file: `[("renderer.count", 4), ...]`.
fn pairs(file: &str, what: &str, v: &Value) -> Result<Vec<(String, Value)>, UserError> {
    let bad = || {
        UserError(format!(
            "{file}: {what}: must be a list of (\"path\", value) pairs"
        ))
    };
    let list = v.as_array().ok_or_else(bad)?;
    list.iter()
        .map(|pair| match pair.as_array().map(Vec::as_slice) {
            Some([Value::String(name), value]) => Ok((name.clone(), value.clone())),
            _ => Err(bad()),
        })
        .collect()
}

/// Read the study file's fields into `study` (flags given win) and its points into `cross` and
/// `listed`.
fn apply_study_file(
    (shown, text): &(String, String),
    path: &Path,
    args: &SweepArgs,
    study: &mut Study,
    cross: &mut Vec<(String, Vec<String>)>,
    listed: &mut Vec<Vec<(String, String)>>,
) -> Result<(), UserError> {
    let value: Value =
        pxpl5_config::parse_checked(FileKind::Study, shown, text, |_: &Value| Ok(()))
            .map_err(config_cmd::report)?;
    let file = shown.as_str();
    let Value::Object(fields) = value else {
        return Err(UserError(format!(
            "{file}: a study is a struct: (set: [...], points: [...], ...)"
        )));
    };
    for (name, v) in &fields {
        match name.as_str() {
            "set" => {
                for (param, values) in pairs(file, "set", v)? {
                    let values = match &values {
                        Value::Array(vs) => vs
                            .iter()
                            .map(|x| value_text(file, &format!("set {param}"), x))
                            .collect::<Result<Vec<_>, _>>()?,
                        x => vec![value_text(file, &format!("set {param}"), x)?],
                    };
                    if values.is_empty() {
                        return Err(UserError(format!("{file}: set {param}: no values")));
                    }
                    cross.push((param, values));
                }
            }
            "points" => {
                let bad = || UserError(format!("{file}: points: must be a list of lists of pairs"));
                for (k, p) in v.as_array().ok_or_else(bad)?.iter().enumerate() {
                    let what = format!("points[{k}]");
                    let point = pairs(file, &what, p)?
                        .into_iter()
                        .map(|(n, x)| Ok((n.clone(), value_text(file, &what, &x)?)))
                        .collect::<Result<Vec<_>, UserError>>()?;
                    listed.push(point);
                }
            }
            "config" if args.config.is_none() => {
                let c = v.as_str().ok_or_else(|| {
                    UserError(format!("{file}: config: must be a file name (a string)"))
                })?;
                // Relative to the study file, as a reader of the file expects.
                let dir = path.parent().unwrap_or(Path::new(""));
                study.config = Some(dir.join(c));
            }
            "method" if args.method.is_none() => {
                use clap::ValueEnum;
                let m = v.as_str().and_then(|m| Methods::from_str(m, true).ok());
                study.method = m.ok_or_else(|| {
                    UserError(format!(
                        "{file}: method: must be \"hemisphere\", \"hemicube\" or \"both\""
                    ))
                })?;
            }
            "shots" if args.shots.is_none() => {
                study.shots = Some(v.as_u64().filter(|&n| n > 0).ok_or_else(|| {
                    UserError(format!("{file}: shots: must be a whole number above 0"))
                })? as usize);
            }
            "until_error" if args.until_error.is_none() => {
                study.until_error =
                    Some(v.as_f64().ok_or_else(|| {
                        UserError(format!("{file}: until_error: must be a number"))
                    })?);
            }
            "config" | "method" | "shots" | "until_error" => {}
            other => {
                return Err(UserError(format!(
                    "{file}: unknown field `{other}` (a study has set, points, config, method, \
                     shots, until_error)"
                )));
            }
        }
    }
    Ok(())
}

/// Radiosity options a sweep sets itself, that write files a sweep does not keep, or that change
/// host work only (`threads`: a point's host seconds are its own thread's).
const NOT_SWEPT: &[&str] = &[
    "method",
    "out",
    "item-buffers",
    "trace",
    "vcd",
    "trace-window",
    "host-time-limit",
    "threads",
];

/// The radiosity command line of `study`'s point `values` (radiosity options only).
fn radiosity_argv(study: &Study, values: &[(String, String)]) -> Result<Vec<String>, UserError> {
    let cmd = RadiosityArgs::augment_args(clap::Command::new("radiosity"));
    use clap::ValueEnum;
    let method = study
        .method
        .to_possible_value()
        .map_or(String::new(), |v| v.get_name().to_string());
    let mut argv = vec!["radiosity".to_string(), "--method".into(), method];
    // A point's own shots or target replaces the study's.
    let sets = |name: &str| values.iter().any(|(p, _)| p == name);
    let shots = study
        .shots
        .or(study.until_error.is_none().then_some(DEFAULT_SHOTS));
    if let Some(n) = shots.filter(|_| !sets("program.shots")) {
        argv.extend(["--shots".to_string(), n.to_string()]);
    }
    if !sets("program.until_error") {
        argv.extend([
            "--until-error".to_string(),
            number(study.until_error.unwrap_or(0.0)),
        ]);
    }
    if let Some(c) = &study.config {
        argv.extend(["--config".to_string(), c.display().to_string()]);
    }
    for (path, value) in values {
        let Some(name) = path.strip_prefix("program.") else {
            continue;
        };
        let long = name.replace('_', "-");
        let arg = cmd
            .get_arguments()
            .find(|a| a.get_long() == Some(long.as_str()))
            .filter(|_| !NOT_SWEPT.contains(&long.as_str()));
        let Some(arg) = arg else {
            let known: Vec<String> = cmd
                .get_arguments()
                .filter_map(|a| a.get_long())
                .filter(|l| !NOT_SWEPT.contains(l) && *l != "help")
                .map(|l| format!("program.{}", l.replace('-', "_")))
                .collect();
            return Err(UserError(format!(
                "--set {path}: `{name}` is no option of the radiosity program a sweep can set \
                 (it can set: {})",
                known.join(", ")
            )));
        };
        if matches!(arg.get_action(), clap::ArgAction::SetTrue) {
            match value.as_str() {
                "true" => argv.push(format!("--{long}")),
                "false" => {}
                _ => {
                    return Err(UserError(format!(
                        "--set {path}={value}: a switch takes true or false"
                    )));
                }
            }
        } else {
            argv.extend([format!("--{long}"), value.clone()]);
        }
    }
    Ok(argv)
}

/// Parse a radiosity command line as `pxpl5 radiosity` would, naming `what` in its error.
fn parse_radiosity(argv: &[String], what: &str) -> Result<RadiosityArgs, UserError> {
    let cmd = RadiosityArgs::augment_args(clap::Command::new("radiosity"));
    let matches = cmd.try_get_matches_from(argv).map_err(|e| {
        let text = e.render().to_string();
        let first = text
            .lines()
            .next()
            .unwrap_or("")
            .trim_start_matches("error: ");
        UserError(format!("{what}: {first}"))
    })?;
    RadiosityArgs::from_arg_matches(&matches).map_err(|e| UserError(format!("{what}: {e}")))
}

/// `cfg` with each config field of `values` set (paths of its serialized form), checked as a
/// config file is.
fn set_config(
    cfg: &MachineConfig,
    values: &[(String, String)],
    label: &str,
) -> Result<MachineConfig, UserError> {
    let fields: Vec<&(String, String)> = values
        .iter()
        .filter(|(p, _)| !p.starts_with("program."))
        .collect();
    if fields.is_empty() {
        return Ok(cfg.clone());
    }
    let mut tree = serde_json::to_value(cfg).map_err(UserError::from)?;
    for (path, value) in &fields {
        let mut node = &mut tree;
        let mut walked = String::new();
        for part in path.split('.') {
            let Value::Object(map) = node else {
                return Err(UserError(format!(
                    "--set {path}: `{walked}` is a field, not a section: it has no `{part}`"
                )));
            };
            let names: Vec<String> = map.keys().cloned().collect();
            node = map.get_mut(part).ok_or_else(|| {
                let at = if walked.is_empty() {
                    "the machine config".to_string()
                } else {
                    format!("`{walked}`")
                };
                UserError(format!(
                    "--set {path}: {at} has no field `{part}` (its fields: {})",
                    names.join(", ")
                ))
            })?;
            walked = if walked.is_empty() {
                part.to_string()
            } else {
                format!("{walked}.{part}")
            };
        }
        *node =
            match node {
                Value::Object(map) => {
                    let names: Vec<&String> = map.keys().collect();
                    return Err(UserError(format!(
                        "--set {path}: is a section, not a field (set one of its fields: {})",
                        names
                            .iter()
                            .map(|n| format!("{path}.{n}"))
                            .collect::<Vec<_>>()
                            .join(", ")
                    )));
                }
                Value::Number(_) => {
                    let v = value.replace('_', "");
                    let n = v
                        .parse::<u64>()
                        .map(Value::from)
                        .or_else(|_| v.parse::<i64>().map(Value::from))
                        .ok()
                        .or_else(|| {
                            v.parse::<f64>()
                                .ok()
                                .and_then(|f| serde_json::Number::from_f64(f).map(Value::Number))
                        });
                    n.ok_or_else(|| UserError(format!("--set {path}={value}: not a number")))?
                }
                Value::Bool(_) => Value::Bool(value.parse().map_err(|_| {
                    UserError(format!("--set {path}={value}: must be true or false"))
                })?),
                _ => Value::String(value.clone()),
            };
    }
    let changed: MachineConfig = serde_json::from_value(tree).map_err(|e| {
        let names: Vec<String> = fields.iter().map(|(p, v)| format!("{p}={v}")).collect();
        UserError(format!("--set {}: {e}", names.join(" ")))
    })?;
    config_cmd::check_changed(&format!("the machine config of {label}"), &changed)?;
    Ok(changed)
}

/// Resolve every point of `study`: its config and options, checked; the first bad one is an
/// error naming the parameter.
pub fn resolve(study: &Study) -> Result<Vec<Point>, UserError> {
    let base = config_cmd::load(study.config.as_deref())?;
    let mut points = Vec::new();
    for (index, values) in study.points.iter().enumerate() {
        let values: Vec<(String, String)> = study
            .params
            .iter()
            .zip(values)
            .filter_map(|(p, v)| Some((p.clone(), v.clone()?)))
            .collect();
        let mut label = format!("point {index}");
        if !values.is_empty() {
            let shown: Vec<String> = values.iter().map(|(p, v)| format!("{p}={v}")).collect();
            label += &format!(" ({})", shown.join(", "));
        }
        let argv = radiosity_argv(study, &values)?;
        let mut args = parse_radiosity(&argv, &label)?;
        args.host_time_limit = study.host_time_limit.clone();
        let loaded;
        let start = match &args.config {
            Some(c) if Some(c) != study.config.as_ref() => {
                loaded = config_cmd::load(Some(c))?;
                &loaded
            }
            _ => &base,
        };
        let cfg = set_config(start, &values, &label)?;
        for method in args.method.methods() {
            check_resolution(method, args.resolution, &cfg.renderer).map_err(|e| {
                UserError(format!("{label}: --resolution {}: {e}", args.resolution))
            })?;
        }
        let key = key_of(&cfg, &argv);
        let columns = study
            .params
            .iter()
            .zip(&study.points[index])
            .map(|(p, v)| (p.clone(), v.clone().unwrap_or_default()))
            .collect();
        points.push(Point {
            index,
            values,
            columns,
            cfg,
            args,
            key,
        });
    }
    Ok(points)
}

/// The key of a point: the first 16 hex digits of the SHA-256 of the version, the config hash
/// and the radiosity command line.
fn key_of(cfg: &MachineConfig, argv: &[String]) -> String {
    let text = format!(
        "pxpl5 {}\n{}\n{}\n",
        env!("CARGO_PKG_VERSION"),
        pxpl5_config::config_hash(cfg),
        argv.join("\u{1f}")
    );
    let digest = Sha256::digest(text.as_bytes());
    digest.iter().take(8).map(|b| format!("{b:02x}")).collect()
}

/// One finished point: its rows (one per method, (column, value) in order) and the host seconds
/// of each method's run.
#[derive(Clone, Debug, PartialEq)]
pub struct Done {
    pub index: usize,
    pub key: String,
    pub rows: Vec<Vec<(String, String)>>,
    pub host_s: Vec<f64>,
}

impl Done {
    /// The journal line (JSON, no newline).
    fn line(&self) -> String {
        let rows: Vec<Value> = self
            .rows
            .iter()
            .map(|r| Value::Array(r.iter().map(|(c, v)| serde_json::json!([c, v])).collect()))
            .collect();
        serde_json::json!({
            "point": self.index,
            "key": self.key,
            "rows": rows,
            "host_s": self.host_s,
        })
        .to_string()
    }

    /// A journal line read back; `None` for a line cut short by a kill, or not one of ours.
    fn parse(line: &str) -> Option<Done> {
        let v: Value = serde_json::from_str(line).ok()?;
        let rows = v["rows"]
            .as_array()?
            .iter()
            .map(|r| {
                r.as_array()?
                    .iter()
                    .map(|p| Some((p[0].as_str()?.to_string(), p[1].as_str()?.to_string())))
                    .collect::<Option<Vec<_>>>()
            })
            .collect::<Option<Vec<_>>>()?;
        Some(Done {
            index: v["point"].as_u64()? as usize,
            key: v["key"].as_str()?.to_string(),
            rows,
            host_s: v["host_s"]
                .as_array()?
                .iter()
                .map(Value::as_f64)
                .collect::<Option<Vec<_>>>()?,
        })
    }
}

/// The rows of one point's comparison.
fn rows_of(point: &Point, c: &Comparison) -> Vec<Vec<(String, String)>> {
    let ratio = c.hemicube_over_hemisphere();
    let ratio_target = c.hemicube_over_hemisphere_to_target();
    let opt = |x: Option<f64>| x.map_or(String::new(), number);
    c.methods
        .iter()
        .map(|m: &MethodSummary| {
            let shots = m.shots.max(1) as f64;
            let mut row: Vec<(String, String)> = vec![
                ("point".into(), point.index.to_string()),
                ("method".into(), m.method.name().into()),
            ];
            row.extend(point.columns.iter().cloned());
            let critical = |r: Resource| number(radiosity::critical_share(&m.stats, r));
            let target = m.convergence.as_ref().and_then(|c| c.time_to_target);
            let bottleneck = m
                .stats
                .critical_resources()
                .first()
                .map_or("none", |(r, _)| r.name());
            row.extend([
                ("config".into(), c.config.clone()),
                ("config_hash".into(), c.config_hash.clone()),
                ("version".into(), env!("CARGO_PKG_VERSION").into()),
                ("scene".into(), c.scene.clone()),
                ("patches".into(), c.patches.to_string()),
                ("resolution".into(), c.resolution.to_string()),
                ("renderers".into(), m.boards.to_string()),
                ("gps".into(), m.gps.to_string()),
                ("shooters_at_once".into(), c.shooters_at_once.to_string()),
                ("shots".into(), m.shots.to_string()),
                ("simulated_ms".into(), number(m.simulated_s * 1e3)),
                ("per_shot_ms".into(), number(m.per_shot_s * 1e3)),
                ("to_target_ms".into(), opt(target.map(|t| t.0 * 1e3))),
                (
                    "shots_to_target".into(),
                    target.map_or(String::new(), |t| t.1.to_string()),
                ),
                ("ratio_per_shot".into(), opt(ratio)),
                ("ratio_to_target".into(), opt(ratio_target)),
                ("critical_gp".into(), critical(Resource::Gp)),
                ("critical_ring".into(), critical(Resource::Ring)),
                ("critical_renderer".into(), critical(Resource::Renderer)),
                ("bottleneck".into(), bottleneck.into()),
                (
                    "renderer_board_ms_per_shot".into(),
                    number(m.renderer_busy_s * 1e3 / shots),
                ),
                ("gp_ms_per_shot".into(), number(m.gp_busy_s * 1e3 / shots)),
                (
                    "ring_words_per_shot".into(),
                    number(m.ring_payload_words as f64 / shots),
                ),
                (
                    "renderer_utilisation".into(),
                    number(m.renderer_utilisation),
                ),
                (
                    "ff_error_l1".into(),
                    opt(m.convergence.as_ref().map(|c| c.form_factor_error)),
                ),
                (
                    "worst_surface_error".into(),
                    opt(m
                        .convergence
                        .as_ref()
                        .and_then(|c| c.last.as_ref())
                        .map(|e| e.worst)),
                ),
            ]);
            for (phase, s) in &m.phases {
                row.push((
                    format!("phase_{phase}_ms_per_shot"),
                    number(s * 1e3 / shots),
                ));
            }
            row.push(("key".into(), point.key.clone()));
            row
        })
        .collect()
}

/// Run one point: every method, as `pxpl5 radiosity` runs it. A run a Ctrl-C cut short is an
/// interrupt: its point is not done.
pub fn run_point(point: &Point) -> Result<Done, Failure> {
    let label = point.label();
    let failed = |f: Failure| match f {
        Failure::UserMistake(m) => Failure::UserMistake(format!("{label}: {m}")),
        Failure::SimulationFailed(m) => Failure::SimulationFailed(format!("{label}: {m}")),
        Failure::Interrupted(m) => Failure::Interrupted(format!("{label}: {m}")),
        Failure::Differs(m) => Failure::Differs(format!("{label}: {m}")),
    };
    let Prepared {
        scene,
        patches,
        plan,
    } = radiosity::prepare(&point.args, &point.cfg)
        .map_err(|e| Failure::UserMistake(format!("{label}: {}", e.0)))?;
    let watch = Watch::new(point.args.host_time_limit.clone());
    let mut runs = Vec::new();
    let mut host_s = Vec::new();
    for method in point.args.method.methods() {
        // Host seconds are this thread's CPU time: the run is simulated in it (a sweep runs
        // with one pixel thread), and other workers' points do not count, as wall time would.
        let cpu = ThreadTime::now();
        let (run, _wall) = radiosity::run_method(
            &watch,
            &point.cfg,
            &patches,
            &point.args,
            &plan,
            method,
            &mut crate::run::TraceDests::default(),
        )
        .map_err(failed)?;
        if run.partial() {
            return Err(Failure::Interrupted(format!("{label}: interrupted")));
        }
        runs.push(run);
        host_s.push(cpu.elapsed().as_secs_f64());
    }
    let comparison = Comparison::new(
        &point.cfg,
        &scene.name,
        (patches.len(), point.args.patch_size),
        (point.args.resolution, plan.shooters_at_once),
        &runs,
    );
    Ok(Done {
        index: point.index,
        key: point.key.clone(),
        rows: rows_of(point, &comparison),
        host_s,
    })
}

/// `study.json`: the study's points, their parameters and keys (no shard, no host figure), the
/// same for every shard of a study.
fn study_json(study: &Study, points: &[Point]) -> String {
    let pts: Vec<Value> = points
        .iter()
        .map(|p| {
            let params: serde_json::Map<String, Value> = p
                .values
                .iter()
                .map(|(k, v)| (k.clone(), Value::String(v.clone())))
                .collect();
            serde_json::json!({"point": p.index, "key": p.key, "params": params})
        })
        .collect();
    let json = serde_json::json!({
        "version": env!("CARGO_PKG_VERSION"),
        "params": study.params,
        "points": pts,
    });
    serde_json::to_string_pretty(&json).unwrap_or_default() + "\n"
}

/// A CSV field: quoted when it holds a comma, quote or line break.
fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// The outputs of a study from its finished points (any order): `sweep.csv`, `sweep.json`,
/// `host.csv`, and the journal compacted to `rows.jsonl`, in point order.
fn outputs(study_text: &str, done: &BTreeMap<usize, Done>, total: usize) -> Vec<(String, Vec<u8>)> {
    let rows: Vec<&Vec<(String, String)>> = done.values().flat_map(|d| &d.rows).collect();
    // Columns in the order first met; phases differ by method, so a row may lack some.
    let mut columns: Vec<String> = Vec::new();
    let mut seen = BTreeSet::new();
    for r in &rows {
        for (c, _) in r.iter() {
            if seen.insert(c.clone()) {
                columns.push(c.clone());
            }
        }
    }
    let cell = |r: &Vec<(String, String)>, c: &str| {
        r.iter()
            .find(|(k, _)| k == c)
            .map_or(String::new(), |(_, v)| v.clone())
    };
    let mut csv = format!(
        "# pxpl5 {} sweep: {} of {total} points\n",
        env!("CARGO_PKG_VERSION"),
        done.len()
    );
    csv += &columns
        .iter()
        .map(|c| csv_field(c))
        .collect::<Vec<_>>()
        .join(",");
    csv += "\n";
    for r in &rows {
        let cells: Vec<String> = columns.iter().map(|c| csv_field(&cell(r, c))).collect();
        csv += &cells.join(",");
        csv += "\n";
    }
    // JSON: a row per object, columns in order, numbers as numbers.
    let mut json = format!(
        "{{\n  \"version\": \"{}\",\n  \"points\": {total},\n  \"points_done\": {},\n  \"rows\": [",
        env!("CARGO_PKG_VERSION"),
        done.len()
    );
    for (k, r) in rows.iter().enumerate() {
        json += if k == 0 { "\n    {" } else { ",\n    {" };
        let fields: Vec<String> = r
            .iter()
            .map(|(c, v)| {
                let value = if v.parse::<f64>().is_ok_and(f64::is_finite)
                    && serde_json::from_str::<serde_json::Number>(v).is_ok()
                {
                    v.clone()
                } else {
                    Value::String(v.clone()).to_string()
                };
                format!("{}: {value}", Value::String(c.clone()))
            })
            .collect();
        json += &fields.join(", ");
        json += "}";
    }
    json += if rows.is_empty() {
        "]\n}\n"
    } else {
        "\n  ]\n}\n"
    };
    let mut host = String::from("point,method,key,host_s\n");
    let mut journal = String::new();
    for d in done.values() {
        for (r, h) in d.rows.iter().zip(&d.host_s) {
            host += &format!("{},{},{},{h:.3}\n", d.index, cell(r, "method"), d.key);
        }
        journal += &d.line();
        journal += "\n";
    }
    vec![
        ("sweep.csv".into(), csv.into_bytes()),
        ("sweep.json".into(), json.into_bytes()),
        ("host.csv".into(), host.into_bytes()),
        ("study.json".into(), study_text.as_bytes().to_vec()),
        ("rows.jsonl".into(), journal.into_bytes()),
    ]
}

/// The finished points of the journal in `dir` that belong to `points` (same index and key).
fn journal(dir: &Path, points: &[Point]) -> BTreeMap<usize, Done> {
    let text = std::fs::read_to_string(dir.join("rows.jsonl")).unwrap_or_default();
    let mut done = BTreeMap::new();
    for d in text.lines().filter_map(Done::parse) {
        if points.get(d.index).is_some_and(|p| p.key == d.key) {
            done.insert(d.index, d);
        }
    }
    done
}

/// Write `files` (name, bytes) into `dir`, all or nothing.
pub(crate) fn write_files(dir: &Path, files: Vec<(String, Vec<u8>)>) -> Result<(), UserError> {
    let writes = files
        .into_iter()
        .map(|(name, bytes)| Ok((output::dest("--out", &dir.join(name), false)?, bytes)))
        .collect::<Result<Vec<_>, UserError>>()?;
    output::write_all(&writes, Vec::new())
}

/// `pxpl5 sweep` and `pxpl5 sweep merge`.
pub fn sweep(cmd: &SweepCommand) -> Result<(), Failure> {
    if let Some(SweepSub::Merge { out, shards }) = &cmd.merge {
        return Ok(merge(out, shards)?);
    }
    let args = &cmd.args;
    let study = study_of(args)?;
    let points = resolve(&study)?;
    let (done, total, stopped) = run_study(&study, &points, args, workers(args.workers))?;
    let ran = done.len();
    let mine = points
        .iter()
        .filter(|p| args.shard.is_none_or(|s| p.index % s.n == s.k))
        .count();
    let shard = args.shard.map_or(String::new(), |s| {
        format!(" (shard {}/{}: {mine} points)", s.k, s.n)
    });
    match stopped {
        Stopped::No => outln!(
            "sweep: {ran} of {total} points done{shard}; wrote {}/sweep.csv, sweep.json, host.csv",
            args.out.display()
        )?,
        Stopped::Limit => outln!(
            "sweep: --limit reached, {ran} of {total} points done{shard}; wrote {}/sweep.csv, \
             sweep.json; rerun the same command to run the rest",
            args.out.display()
        )?,
        Stopped::Failed(f) => return Err(f),
        Stopped::Interrupted => {
            return Err(Failure::Interrupted(format!(
                "sweep: interrupted, {ran} of {total} points done{shard}; the finished rows are \
                 in {}; rerun the same command to resume",
                args.out.display()
            )));
        }
    }
    Ok(())
}

/// `--workers`, or the cores available.
pub fn workers(given: Option<u32>) -> usize {
    given.map_or_else(crate::run::available_cores, |n| n as usize)
}

/// Why a study's run stopped before its points were done, if it did.
#[derive(Debug)]
pub enum Stopped {
    No,
    Limit,
    Interrupted,
    Failed(Failure),
}

/// Run the points of `study` not yet in `args.out`'s journal (of the shard, up to the limit) on
/// `workers` threads, appending each to the journal as it finishes; then write the outputs.
/// Returns the finished points (every one of the journal), the study's size and why it stopped.
pub fn run_study(
    study: &Study,
    points: &[Point],
    args: &SweepArgs,
    workers: usize,
) -> Result<(BTreeMap<usize, Done>, usize, Stopped), Failure> {
    output::check_dir("--out", &args.out)?;
    let study_text = study_json(study, points);
    let mut done = journal(&args.out, points);
    let todo: Vec<&Point> = points
        .iter()
        .filter(|p| !done.contains_key(&p.index))
        .filter(|p| args.shard.is_none_or(|s| p.index % s.n == s.k))
        .collect();
    let limited = args.limit.is_some_and(|l| l < todo.len());
    let todo: Vec<&Point> = todo
        .into_iter()
        .take(args.limit.unwrap_or(usize::MAX))
        .collect();
    // Write the study first, so that even a killed run leaves a directory `merge` can name.
    write_files(
        &args.out,
        vec![("study.json".into(), study_text.clone().into_bytes())],
    )?;
    let journal_path = args.out.join("rows.jsonl");
    let mut file = std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(&journal_path)
        .map_err(|e| {
            UserError(format!(
                "--out: cannot write {}: {e}",
                journal_path.display()
            ))
        })?;
    watch::hide_run_bars();
    let in_shard = points
        .iter()
        .filter(|p| args.shard.is_none_or(|s| p.index % s.n == s.k))
        .count() as u64;
    let bar = watch::command_bar(
        in_shard,
        "sweep",
        "{prefix}: {pos}/{len} points [{bar:20}] {elapsed} elapsed, {eta} left",
    );
    if let Some(bar) = &bar {
        bar.set_position(in_shard - todo.len() as u64);
        bar.reset_eta();
    }
    let stop = AtomicBool::new(false);
    let mut failure: Option<Failure> = None;
    let (job_tx, job_rx) = crossbeam_channel::unbounded::<&Point>();
    let (done_tx, done_rx) = crossbeam_channel::unbounded::<Result<Done, Failure>>();
    for p in &todo {
        // The receiver lives until the scope below ends: a send cannot fail.
        let _ = job_tx.send(p);
    }
    drop(job_tx);
    let mut journal_error = None;
    std::thread::scope(|scope| {
        for _ in 0..workers.min(todo.len()) {
            let (jobs, results, stop) = (job_rx.clone(), done_tx.clone(), &stop);
            scope.spawn(move || {
                for point in jobs.iter() {
                    if stop.load(Ordering::SeqCst) || watch::interrupts() > 0 {
                        break;
                    }
                    if results.send(run_point(point)).is_err() {
                        break;
                    }
                }
            });
        }
        drop(done_tx);
        for result in done_rx.iter() {
            match result {
                Ok(d) => {
                    if journal_error.is_none()
                        && let Err(e) = writeln!(file, "{}", d.line()).and_then(|()| file.flush())
                    {
                        journal_error = Some(e);
                        stop.store(true, Ordering::SeqCst);
                    }
                    done.insert(d.index, d);
                    if let Some(bar) = &bar {
                        bar.inc(1);
                    }
                }
                // A point cut short by Ctrl-C is not done, and says nothing.
                Err(Failure::Interrupted(_)) => {}
                Err(f) => {
                    stop.store(true, Ordering::SeqCst);
                    failure.get_or_insert(f);
                }
            }
        }
    });
    watch::finish_bar(bar);
    if let Some(e) = journal_error {
        return Err(UserError(format!(
            "--out: cannot write {}: {e}",
            journal_path.display()
        ))
        .into());
    }
    write_files(&args.out, outputs(&study_text, &done, points.len()))?;
    let stopped = if let Some(f) = failure {
        let message = format!(
            "{}\n(sweep: the {} points finished are in {}; rerun to resume)",
            f.message(),
            done.len(),
            args.out.display()
        );
        Stopped::Failed(match f {
            Failure::UserMistake(_) => Failure::UserMistake(message),
            _ => Failure::SimulationFailed(message),
        })
    } else if watch::interrupts() > 0 {
        Stopped::Interrupted
    } else if limited {
        Stopped::Limit
    } else {
        Stopped::No
    };
    Ok((done, points.len(), stopped))
}

/// `pxpl5 sweep merge OUT SHARDS...`: the shards' journals joined and written as one run writes
/// them. The shards must be of one study (equal `study.json`) and together hold every point.
pub fn merge(out: &Path, shards: &[PathBuf]) -> Result<(), UserError> {
    let mut study_text: Option<(String, &PathBuf)> = None;
    let mut done: BTreeMap<usize, Done> = BTreeMap::new();
    for dir in shards {
        let path = dir.join("study.json");
        let text = std::fs::read_to_string(&path).map_err(|e| {
            UserError(format!(
                "sweep merge: cannot read {}: {e} (is it a sweep's output directory?)",
                path.display()
            ))
        })?;
        match &study_text {
            Some((first, from)) if *first != text => {
                return Err(UserError(format!(
                    "sweep merge: {} is of another study than {} (their study.json differ)",
                    dir.display(),
                    from.display()
                )));
            }
            Some(_) => {}
            None => study_text = Some((text.clone(), dir)),
        }
        let journal = std::fs::read_to_string(dir.join("rows.jsonl")).unwrap_or_default();
        for d in journal.lines().filter_map(Done::parse) {
            done.insert(d.index, d);
        }
    }
    let Some((study_text, _)) = study_text else {
        return Err(UserError("sweep merge: no shard directories given".into()));
    };
    let study: Value = serde_json::from_str(&study_text)
        .map_err(|e| UserError(format!("sweep merge: study.json: {e}")))?;
    let keys: Vec<(usize, String)> = study["points"]
        .as_array()
        .map(|ps| {
            ps.iter()
                .filter_map(|p| {
                    Some((
                        p["point"].as_u64()? as usize,
                        p["key"].as_str()?.to_string(),
                    ))
                })
                .collect()
        })
        .unwrap_or_default();
    done.retain(|i, d| keys.iter().any(|(k, key)| k == i && *key == d.key));
    let missing: Vec<String> = keys
        .iter()
        .filter(|(i, _)| !done.contains_key(i))
        .map(|(i, _)| i.to_string())
        .collect();
    if !missing.is_empty() {
        return Err(UserError(format!(
            "sweep merge: {} of {} points are in no shard: {} (rerun their shards: they resume)",
            missing.len(),
            keys.len(),
            missing.join(", ")
        )));
    }
    output::check_dir("sweep merge OUT", out)?;
    write_files(out, outputs(&study_text, &done, keys.len()))?;
    outln!(
        "sweep merge: {} points from {} shards; wrote {}/sweep.csv, sweep.json, host.csv",
        done.len(),
        shards.len(),
        out.display()
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(set: &[&str]) -> SweepArgs {
        let cmd = SweepArgs::augment_args(clap::Command::new("sweep"));
        let mut argv = vec!["sweep".to_string()];
        for s in set {
            argv.extend(["--set".to_string(), s.to_string()]);
        }
        SweepArgs::from_arg_matches(&cmd.get_matches_from(argv)).expect("parses")
    }

    #[test]
    fn the_cross_product_varies_the_last_parameter_fastest() {
        let s = study_of(&args(&[
            "renderer.count=1,2",
            "program.resolution=16,32,64",
        ]))
        .map_err(|e| e.0)
        .unwrap();
        assert_eq!(s.params, ["renderer.count", "program.resolution"]);
        let shown: Vec<String> = s
            .points
            .iter()
            .map(|p| {
                p.iter()
                    .map(|v| v.clone().unwrap())
                    .collect::<Vec<_>>()
                    .join("/")
            })
            .collect();
        assert_eq!(shown, ["1/16", "1/32", "1/64", "2/16", "2/32", "2/64"]);
        let points = resolve(&s).map_err(|e| e.0).unwrap();
        assert_eq!(points[4].cfg.renderer.count, 2);
        assert_eq!(points[4].args.resolution, 32);
        assert_eq!(points[4].args.shots, Some(DEFAULT_SHOTS));
        // Keys differ wherever the point differs.
        let keys: BTreeSet<&String> = points.iter().map(|p| &p.key).collect();
        assert_eq!(keys.len(), 6);
    }

    #[test]
    fn bad_paths_and_values_name_the_parameter() {
        let err = |set: &str| {
            resolve(&study_of(&args(&[set])).map_err(|e| e.0).unwrap())
                .unwrap_err()
                .0
        };
        let e = err("renderer.cont=1");
        assert!(
            e.contains("--set renderer.cont") && e.contains("no field `cont`"),
            "{e}"
        );
        let e = err("renderer=1");
        assert!(e.contains("is a section"), "{e}");
        let e = err("renderer.count=four");
        assert!(e.contains("renderer.count=four: not a number"), "{e}");
        let e = err("renderer.count=0");
        assert!(e.contains("renderer.count"), "{e}");
        let e = err("program.resolutoin=4");
        assert!(
            e.contains("program.resolutoin") && e.contains("program.resolution"),
            "{e}"
        );
        let e = err("program.resolution=0");
        assert!(
            e.contains("program.resolution=0") && e.contains("--resolution"),
            "{e}"
        );
        let e = err("program.out=x");
        assert!(e.contains("program.out"), "{e}");
        let e = err("ring.token_policy=Sometimes");
        assert!(e.contains("ring.token_policy=Sometimes"), "{e}");
    }

    #[test]
    fn shards_parse() {
        assert_eq!(parse_shard("1/4"), Ok(Shard { k: 1, n: 4 }));
        for bad in ["4/4", "1", "a/2", "0/0", "-1/2"] {
            assert!(parse_shard(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn journal_lines_read_back() {
        let d = Done {
            index: 3,
            key: "abc".into(),
            rows: vec![vec![
                ("a".into(), "1".into()),
                ("b".into(), "x, \"y\"".into()),
            ]],
            host_s: vec![0.5],
        };
        assert_eq!(Done::parse(&d.line()), Some(d.clone()));
        assert_eq!(Done::parse(&d.line()[..20]), None);
    }
}
