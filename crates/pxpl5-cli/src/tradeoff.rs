//! `pxpl5 tradeoff`: what simulation speed costs in accuracy. One workload (by default the main
//! job: the empty Cornell box on the seed's machine, both methods, each until every surface is
//! within 1 % of the exact solution) runs at every fidelity level and algorithm knob in
//! [`KNOBS`]: the Renderer's exact levels (`sparse`, the default and the reference, `integer`
//! and `bit`) and its approximate `timing` level, the ring's approximate `message` level, lower
//! view resolutions, fewer QEE fraction bits, the hemisphere's exact depth, looser accuracy
//! targets. Each row gives the host seconds it took (the simulating thread's CPU time) and its
//! errors:
//!
//! - **time error**: the relative error of the simulated time to the target (and, beside it, of
//!   the time per shot) against the reference knob's, same method: what a user who took this
//!   knob's answer for the exact machine's would be off by;
//! - **radiosity error**: the worst surface error at the end against the exact solution (the
//!   direct solve with exact form factors), as `pxpl5 radiosity` reports it;
//! - the form-factor error and the methods' ratio (and its error), for the seed's question.
//!
//! A knob is **Pareto-optimal** (per method) when no other knob takes less host time without a
//! larger time error or radiosity error. The points are a sweep (`sweep::run_study`, resumable;
//! the rows in OUT/sweep.csv); the frontier is OUT/tradeoff.csv and OUT/tradeoff.svg, redrawn by
//! `pxpl5 plot OUT/tradeoff.csv`. Host seconds differ from run to run, so tradeoff.csv does too;
//! its simulated columns do not. Points run one at a time by default, so that the host seconds
//! they are ranked by are not inflated by each other.

use std::path::PathBuf;

use clap::Args;

use crate::UserError;
use crate::choices::Methods;
use crate::failure::Failure;
use crate::output::{out, outln};
use crate::plot::{self, Table};
use crate::radiosity::number;
use crate::sweep::{self, Done, Stopped, Study, SweepArgs};
use crate::watch::{self, HostLimit};

/// One knob of the study: its name, the (sweep parameter, value) pairs it sets, and the method it
/// applies to (`None`: both; a knob that changes nothing for a method has no row for it).
pub struct Knob {
    pub name: &'static str,
    pub sets: &'static [(&'static str, &'static str)],
    pub only: Option<&'static str>,
}

const fn knob(name: &'static str, sets: &'static [(&'static str, &'static str)]) -> Knob {
    Knob {
        name,
        sets,
        only: None,
    }
}

/// Every knob of the study; the first is the reference every error is measured against.
pub const KNOBS: &[Knob] = &[
    knob("sparse (reference)", &[]),
    knob("integer", &[("program.fidelity", "integer")]),
    knob("bit", &[("program.fidelity", "bit")]),
    knob("timing", &[("program.fidelity", "timing")]),
    knob("message ring", &[("program.ring_level", "message")]),
    knob(
        "timing + message ring",
        &[
            ("program.fidelity", "timing"),
            ("program.ring_level", "message"),
        ],
    ),
    knob("resolution 64", &[("program.resolution", "64")]),
    knob("resolution 32", &[("program.resolution", "32")]),
    knob(
        "QEE 12 fraction bits",
        &[("renderer.qee.coefficient_format.frac_bits", "12")],
    ),
    // The depth option is the hemisphere's: the hemicube's run is the reference's.
    Knob {
        name: "depth stored-w",
        sets: &[("program.depth", "stored-w")],
        only: Some("hemisphere"),
    },
    knob("target 2 %", &[("program.until_error", "0.02")]),
    knob("target 5 %", &[("program.until_error", "0.05")]),
];

/// Options of `pxpl5 tradeoff`.
#[derive(Args, Clone, Debug)]
pub struct TradeoffArgs {
    /// Machine config (RON); default: the embedded seed machine.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// A value every knob shares, PATH=VALUE: a config field or program.NAME (a radiosity
    /// option), as for `pxpl5 sweep --set` (e.g. program.patch_size=200 for a quicker study).
    #[arg(long = "set", value_name = "PATH=VALUE")]
    pub set: Vec<String>,
    /// Only the knobs whose name contains one of these (comma-separated), e.g. timing,ring; the
    /// reference always runs.
    #[arg(long, value_delimiter = ',')]
    pub only: Vec<String>,
    /// The accuracy every run stops at (the main job's 1 %); the knobs `target 2 %` and
    /// `target 5 %` loosen it.
    #[arg(long, default_value_t = 0.01)]
    pub until_error: f64,
    /// Output directory; a rerun with the same one resumes.
    #[arg(long, default_value = "out/tradeoff")]
    pub out: PathBuf,
    /// Points run at once. Default 1: host seconds are what is traded, and points running side
    /// by side on shared cores slow each other.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub workers: u32,
    /// Stop a point's run with an error once it has taken this much host time.
    #[arg(long, value_name = "TIME", default_value = watch::DEFAULT_HOST_LIMIT,
          value_parser = watch::parse_host_limit)]
    pub host_time_limit: HostLimit,
}

/// One knob's figures for one method.
#[derive(Clone, Debug, Default)]
struct Figures {
    host_s: Option<f64>,
    per_shot_ms: Option<f64>,
    to_target_ms: Option<f64>,
    shots_to_target: Option<f64>,
    radiosity_error: Option<f64>,
    ff_error: Option<f64>,
    ratio: Option<f64>,
}

impl Figures {
    /// The figures of `method`'s row of a finished point.
    fn of(done: &Done, method: &str) -> Option<Figures> {
        let k = done.rows.iter().position(|row| {
            row.iter()
                .any(|(c, v)| c.as_str() == "method" && v.as_str() == method)
        })?;
        let row = &done.rows[k];
        let cell = |c: &str| {
            row.iter()
                .find(|(k, _)| k.as_str() == c)
                .and_then(|(_, v)| v.parse::<f64>().ok())
        };
        Some(Figures {
            host_s: done.host_s.get(k).copied(),
            per_shot_ms: cell("per_shot_ms"),
            to_target_ms: cell("to_target_ms"),
            shots_to_target: cell("shots_to_target"),
            radiosity_error: cell("worst_surface_error"),
            ff_error: cell("ff_error_l1"),
            ratio: cell("ratio_to_target"),
        })
    }
}

/// A row of the frontier: a knob, a method, its figures and their errors against the reference.
struct Row {
    knob: &'static str,
    method: &'static str,
    f: Figures,
    time_error: Option<f64>,
    per_shot_error: Option<f64>,
    ratio_error: Option<f64>,
    pareto: bool,
}

/// |x - reference| / reference, when both exist and the reference is not zero.
fn relative_error(x: Option<f64>, reference: Option<f64>) -> Option<f64> {
    match (x, reference) {
        (Some(x), Some(r)) if r != 0.0 => Some((x - r).abs() / r.abs()),
        _ => None,
    }
}

/// Marks the rows of each method that no other row of the method dominates: at most its host
/// seconds, time error and radiosity error, and less in one. A row missing any of the three is
/// not on the frontier (its target was not reached, so its errors are not comparable).
fn mark_pareto(rows: &mut [Row]) {
    let key =
        |r: &Row| -> Option<[f64; 3]> { Some([r.f.host_s?, r.time_error?, r.f.radiosity_error?]) };
    let keys: Vec<Option<[f64; 3]>> = rows.iter().map(key).collect();
    for i in 0..rows.len() {
        let Some(a) = keys[i] else { continue };
        let dominated = (0..rows.len()).any(|j| {
            let Some(b) = keys[j].filter(|_| j != i && rows[j].method == rows[i].method) else {
                return false;
            };
            b.iter().zip(&a).all(|(b, a)| b <= a) && b.iter().zip(&a).any(|(b, a)| b < a)
        });
        rows[i].pareto = !dominated;
    }
}

/// `pxpl5 tradeoff`.
pub fn tradeoff(args: &TradeoffArgs) -> Result<(), Failure> {
    if !(0.0..1.0).contains(&args.until_error) || args.until_error == 0.0 {
        return Err(UserError(format!(
            "--until-error {}: must be a fraction above 0 and below 1 (0.01 is 1 %): the \
             frontier compares the time to reach it",
            args.until_error
        ))
        .into());
    }
    let knobs: Vec<usize> = (0..KNOBS.len())
        .filter(|&k| {
            k == 0
                || args.only.is_empty()
                || args.only.iter().any(|o| KNOBS[k].name.contains(o.as_str()))
        })
        .collect();
    if knobs.len() == 1 && !args.only.is_empty() {
        let names: Vec<&str> = KNOBS[1..].iter().map(|k| k.name).collect();
        return Err(UserError(format!(
            "--only {}: names no knob (the knobs: {})",
            args.only.join(","),
            names.join(", ")
        ))
        .into());
    }
    let mut fixed: Vec<(String, String)> = Vec::new();
    for set in &args.set {
        let (p, v) = set.split_once('=').ok_or_else(|| {
            UserError(format!(
                "--set {set}: give PATH=VALUE (e.g. program.patch_size=200)"
            ))
        })?;
        fixed.push((p.trim().to_string(), v.trim().to_string()));
    }
    // The study's parameters: the shared values, then every parameter a knob sets.
    let mut params: Vec<String> = fixed.iter().map(|(p, _)| p.clone()).collect();
    for &k in &knobs {
        for (p, _) in KNOBS[k].sets {
            if fixed.iter().any(|(f, _)| f == p) {
                return Err(UserError(format!(
                    "--set {p}: is a knob of this study ({}); use --only to leave it out",
                    KNOBS[k].name
                ))
                .into());
            }
            if !params.iter().any(|q| q == p) {
                params.push(p.to_string());
            }
        }
    }
    let points: Vec<Vec<Option<String>>> = knobs
        .iter()
        .map(|&k| {
            params
                .iter()
                .map(|p| {
                    let own = KNOBS[k].sets.iter().find(|(q, _)| q == p).map(|(_, v)| *v);
                    own.map(str::to_string)
                        .or_else(|| fixed.iter().find(|(f, _)| f == p).map(|(_, v)| v.clone()))
                })
                .collect()
        })
        .collect();
    let study = Study {
        config: args.config.clone(),
        method: Methods::Both,
        shots: None,
        until_error: Some(args.until_error),
        params,
        points,
        host_time_limit: args.host_time_limit.clone(),
    };
    let resolved = sweep::resolve(&study)?;
    let sweep_args = SweepArgs {
        set: Vec::new(),
        study: None,
        config: args.config.clone(),
        method: Some(Methods::Both),
        shots: None,
        until_error: Some(args.until_error),
        out: args.out.clone(),
        workers: Some(args.workers),
        shard: None,
        limit: None,
        host_time_limit: args.host_time_limit.clone(),
    };
    let (done, total, stopped) =
        sweep::run_study(&study, &resolved, &sweep_args, args.workers as usize)?;
    match stopped {
        Stopped::No | Stopped::Limit => {}
        Stopped::Failed(f) => return Err(f),
        Stopped::Interrupted => {
            return Err(Failure::Interrupted(format!(
                "tradeoff: interrupted, {} of {total} points done; rerun the same command to \
                 resume",
                done.len()
            )));
        }
    }
    let mut rows = Vec::new();
    for method in ["hemisphere", "hemicube"] {
        let reference = done.get(&0).and_then(|d| Figures::of(d, method));
        for (i, &k) in knobs.iter().enumerate() {
            if KNOBS[k].only.is_some_and(|m| m != method) {
                continue;
            }
            let Some(f) = done.get(&i).and_then(|d| Figures::of(d, method)) else {
                continue;
            };
            let r = reference.clone().unwrap_or_default();
            rows.push(Row {
                knob: KNOBS[k].name,
                method,
                time_error: relative_error(f.to_target_ms, r.to_target_ms),
                per_shot_error: relative_error(f.per_shot_ms, r.per_shot_ms),
                ratio_error: relative_error(f.ratio, r.ratio),
                f,
                pareto: false,
            });
        }
    }
    mark_pareto(&mut rows);
    let config = resolved
        .first()
        .map_or(String::new(), |p| p.cfg.name.clone());
    let csv = table_csv(&rows, &config, args.until_error);
    let table = Table::parse(&args.out.join("tradeoff.csv"), &csv)?;
    let svg = plot::svg(&plot::tradeoff_charts(&table)?, (560, 440))?;
    sweep::write_files(
        &args.out,
        vec![
            ("tradeoff.csv".into(), csv.into_bytes()),
            ("tradeoff.svg".into(), svg.into_bytes()),
        ],
    )?;
    out!("{}", table_text(&rows, &config, args.until_error))?;
    outln!(
        "wrote {}/tradeoff.csv, tradeoff.svg (the study's rows: sweep.csv)",
        args.out.display()
    )?;
    Ok(())
}

/// `tradeoff.csv`: a row per knob and method, in the study's order.
fn table_csv(rows: &[Row], config: &str, target: f64) -> String {
    let opt = |x: Option<f64>| x.map_or(String::new(), number);
    let mut csv = format!(
        "# pxpl5 {} tradeoff on {config}: every knob until {} or its own target; errors against \
         the reference knob (time) and the exact solution (radiosity); host_s is CPU seconds\n\
         knob,method,host_s,to_target_ms,time_error,per_shot_ms,per_shot_error,shots_to_target,\
         radiosity_error,ff_error_l1,ratio_to_target,ratio_error,pareto\n",
        env!("CARGO_PKG_VERSION"),
        number(target)
    );
    for r in rows {
        csv += &[
            r.knob.to_string(),
            r.method.to_string(),
            opt(r.f.host_s),
            opt(r.f.to_target_ms),
            opt(r.time_error),
            opt(r.f.per_shot_ms),
            opt(r.per_shot_error),
            opt(r.f.shots_to_target),
            opt(r.f.radiosity_error),
            opt(r.f.ff_error),
            opt(r.f.ratio),
            opt(r.ratio_error),
            r.pareto.to_string(),
        ]
        .join(",");
        csv += "\n";
    }
    csv
}

/// The frontier as printed.
fn table_text(rows: &[Row], config: &str, target: f64) -> String {
    let pct = |x: Option<f64>| x.map_or("-".to_string(), |v| format!("{:.2} %", 100.0 * v));
    let f = |x: Option<f64>, d: usize| x.map_or("-".to_string(), |v| format!("{v:.d$}"));
    let mut t = format!(
        "Speed against accuracy on {config}: every knob on the same workload (both methods, each \
         until every surface is within {}, unless the knob sets its own target)\ntime error: \
         simulated time to the target against the reference knob's (sparse, token ring); \
         radiosity error: worst surface against the exact solution; host s: CPU seconds; \
         * = Pareto-optimal for its method\n\n",
        pct(Some(target))
    );
    t += &format!(
        "  {:<24} {:<11} {:>8} {:>12} {:>11} {:>11} {:>10} {:>10} {:>8}\n",
        "knob",
        "method",
        "host s",
        "to target ms",
        "time error",
        "per shot",
        "radiosity",
        "FF error",
        "ratio"
    );
    for r in rows {
        t += &format!(
            "{} {:<24} {:<11} {:>8} {:>12} {:>11} {:>11} {:>10} {:>10} {:>8}\n",
            if r.pareto { "*" } else { " " },
            r.knob,
            r.method,
            f(r.f.host_s, 2),
            f(r.f.to_target_ms, 3),
            pct(r.time_error),
            pct(r.per_shot_error),
            pct(r.f.radiosity_error),
            pct(r.f.ff_error),
            f(r.f.ratio, 3),
        );
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(method: &'static str, host: f64, time: f64, radiosity: f64) -> Row {
        Row {
            knob: "k",
            method,
            f: Figures {
                host_s: Some(host),
                radiosity_error: Some(radiosity),
                ..Figures::default()
            },
            time_error: Some(time),
            per_shot_error: None,
            ratio_error: None,
            pareto: false,
        }
    }

    #[test]
    fn the_frontier_keeps_what_nothing_beats_per_method() {
        let mut rows = vec![
            row("hemisphere", 1.0, 0.0, 0.01),  // the reference: exact time
            row("hemisphere", 0.5, 0.01, 0.01), // faster, a little off: on the frontier
            row("hemisphere", 0.6, 0.02, 0.02), // slower and worse than the one above
            row("hemisphere", 2.0, 0.0, 0.01),  // as exact as the reference, slower
            row("hemicube", 3.0, 0.5, 0.5),     // alone in its method: on its frontier
        ];
        rows.push(Row {
            time_error: None,
            ..row("hemisphere", 0.1, 0.0, 0.0)
        });
        mark_pareto(&mut rows);
        let marks: Vec<bool> = rows.iter().map(|r| r.pareto).collect();
        assert_eq!(marks, [true, true, false, false, true, false]);
    }

    #[test]
    fn relative_errors_need_both_sides() {
        assert_eq!(
            relative_error(Some(1.1), Some(1.0)).map(|e| (e * 1e9).round()),
            Some(1e8)
        );
        assert_eq!(relative_error(None, Some(1.0)), None);
        assert_eq!(relative_error(Some(1.0), Some(0.0)), None);
    }

    /// Every knob makes a valid point of the seed's machine (its config fields and options
    /// parse), so the default study runs.
    #[test]
    fn every_knob_is_a_valid_point() {
        let args = TradeoffArgs {
            config: None,
            set: Vec::new(),
            only: Vec::new(),
            until_error: 0.01,
            out: PathBuf::from("unused"),
            workers: 1,
            host_time_limit: watch::parse_host_limit("none").unwrap_or_else(|e| panic!("{e}")),
        };
        let mut params: Vec<&str> = Vec::new();
        for k in KNOBS {
            for (p, _) in k.sets {
                if !params.contains(p) {
                    params.push(p);
                }
            }
        }
        let study = Study {
            config: args.config.clone(),
            method: Methods::Both,
            shots: None,
            until_error: Some(args.until_error),
            params: params.iter().map(|p| p.to_string()).collect(),
            points: KNOBS
                .iter()
                .map(|k| {
                    params
                        .iter()
                        .map(|p| {
                            k.sets
                                .iter()
                                .find(|(q, _)| q == p)
                                .map(|(_, v)| v.to_string())
                        })
                        .collect()
                })
                .collect(),
            host_time_limit: args.host_time_limit.clone(),
        };
        let points = sweep::resolve(&study).map_err(|e| e.0).unwrap();
        assert_eq!(points.len(), KNOBS.len());
    }
}
