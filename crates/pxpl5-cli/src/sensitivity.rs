//! `pxpl5 sensitivity`: which of the machine's assumptions decides the seed's question. Every
//! `[assumed]` field of the machine config has a plausible range in its provenance
//! (`pxpl5_config::PROVENANCE`, shown by `config show`); this study moves each to the low and
//! then the high end of its range, every other field at its default, runs both methods at each
//! point, and ranks the assumptions by how far they move the hemicube / hemisphere ratio of the
//! time per shot. Also reported: each method's time per shot and the bottleneck at both ends.
//!
//! The points are a sweep (`sweep::run_study`): they run on the worker pool, resume after an
//! interrupt, and the study's rows are in OUT/sweep.csv. The ranking is OUT/sensitivity.csv,
//! its tornado chart OUT/sensitivity.svg (redrawn by `pxpl5 plot OUT/sensitivity.csv`).

use std::path::PathBuf;

use clap::Args;
use pxpl5_config::{PROVENANCE, Tag};

use crate::UserError;
use crate::choices::Methods;
use crate::failure::Failure;
use crate::output::{out, outln};
use crate::plot::{self, Table};
use crate::radiosity::number;
use crate::sweep::{self, Done, Stopped, Study, SweepArgs};
use crate::watch::{self, HostLimit};

/// Options of `pxpl5 sensitivity`.
#[derive(Args, Clone, Debug)]
pub struct SensitivityArgs {
    /// Machine config (RON) whose assumptions are moved; default: the embedded seed machine.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// A value every point shares, PATH=VALUE: a config field or program.NAME (a radiosity
    /// option), as for `pxpl5 sweep --set`.
    #[arg(long = "set", value_name = "PATH=VALUE")]
    pub set: Vec<String>,
    /// Only the assumptions whose path contains one of these (comma-separated), e.g.
    /// ring.,gp.costs.message; default: every one.
    #[arg(long, value_delimiter = ',')]
    pub only: Vec<String>,
    /// Shots per run.
    #[arg(long, default_value_t = sweep::DEFAULT_SHOTS)]
    pub shots: usize,
    /// Output directory; a rerun with the same one resumes.
    #[arg(long, default_value = "out/sensitivity")]
    pub out: PathBuf,
    /// Points run at once. Default: the cores available.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub workers: Option<u32>,
    /// Stop a point's run with an error once it has taken this much host time.
    #[arg(long, value_name = "TIME", default_value = watch::DEFAULT_HOST_LIMIT,
          value_parser = watch::parse_host_limit)]
    pub host_time_limit: HostLimit,
}

/// One assumption's effect: at the default, at the low end and at the high end.
struct Effect {
    path: &'static str,
    low: &'static str,
    high: &'static str,
    source: &'static str,
    /// (ratio, hemisphere ms per shot, hemicube ms per shot, bottlenecks) at the low and high ends.
    at_low: Figures,
    at_high: Figures,
}

#[derive(Clone, Debug, Default)]
struct Figures {
    ratio: Option<f64>,
    hemisphere_ms: Option<f64>,
    hemicube_ms: Option<f64>,
    bottleneck: String,
}

impl Figures {
    /// The figures of a finished point.
    fn of(done: &Done) -> Figures {
        let cell = |row: &[(String, String)], c: &str| {
            row.iter()
                .find(|(k, _)| k == c)
                .map(|(_, v)| v.clone())
                .unwrap_or_default()
        };
        let mut f = Figures::default();
        let mut bottlenecks = Vec::new();
        for row in &done.rows {
            let ms = cell(row, "per_shot_ms").parse().ok();
            match cell(row, "method").as_str() {
                "hemisphere" => f.hemisphere_ms = ms,
                _ => f.hemicube_ms = ms,
            }
            f.ratio = f.ratio.or(cell(row, "ratio_per_shot").parse().ok());
            bottlenecks.push(cell(row, "bottleneck"));
        }
        f.bottleneck = bottlenecks.join("/");
        f
    }
}

impl Effect {
    /// How far the assumption moves the ratio from `base`: the larger of its two ends' moves.
    fn swing(&self, base: f64) -> f64 {
        [self.at_low.ratio, self.at_high.ratio]
            .into_iter()
            .flatten()
            .map(|r| (r - base).abs())
            .fold(0.0, f64::max)
    }
}

/// `pxpl5 sensitivity`.
pub fn sensitivity(args: &SensitivityArgs) -> Result<(), Failure> {
    let assumptions: Vec<_> = PROVENANCE
        .iter()
        .filter(|e| e.tag == Tag::Assumed)
        .filter(|e| args.only.is_empty() || args.only.iter().any(|o| e.path.contains(o.as_str())))
        .filter_map(|e| Some((e, e.range?)))
        .collect();
    if assumptions.is_empty() {
        return Err(UserError(format!(
            "--only {}: names no assumed field (`pxpl5 config show` lists them, tagged [assumed])",
            args.only.join(",")
        ))
        .into());
    }
    // The study: the shared values, then per assumption its low and its high end.
    let mut fixed: Vec<(String, String)> = Vec::new();
    for set in &args.set {
        let (p, v) = set.split_once('=').ok_or_else(|| {
            UserError(format!(
                "--set {set}: give PATH=VALUE (e.g. program.resolution=64)"
            ))
        })?;
        fixed.push((p.trim().to_string(), v.trim().to_string()));
    }
    let mut params: Vec<String> = fixed.iter().map(|(p, _)| p.clone()).collect();
    for (e, _) in &assumptions {
        if params.iter().any(|p| p == e.path) {
            return Err(UserError(format!(
                "--set {}: is an assumption this study moves; use --only to leave it out",
                e.path
            ))
            .into());
        }
        params.push(e.path.to_string());
    }
    let base: Vec<Option<String>> = params
        .iter()
        .map(|p| fixed.iter().find(|(f, _)| f == p).map(|(_, v)| v.clone()))
        .collect();
    let mut points = vec![base.clone()];
    for (k, (_, range)) in assumptions.iter().enumerate() {
        for end in [range.low, range.high] {
            let mut point = base.clone();
            point[fixed.len() + k] = Some(end.to_string());
            points.push(point);
        }
    }
    let study = Study {
        config: args.config.clone(),
        method: Methods::Both,
        shots: Some(args.shots),
        until_error: None,
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
        shots: Some(args.shots),
        until_error: None,
        out: args.out.clone(),
        workers: args.workers,
        shard: None,
        limit: None,
        host_time_limit: args.host_time_limit.clone(),
    };
    let workers = sweep::workers(args.workers);
    let (done, total, stopped) = sweep::run_study(&study, &resolved, &sweep_args, workers)?;
    match stopped {
        Stopped::No | Stopped::Limit => {}
        Stopped::Failed(f) => return Err(f),
        Stopped::Interrupted => {
            return Err(Failure::Interrupted(format!(
                "sensitivity: interrupted, {} of {total} points done; rerun the same command to \
                 resume",
                done.len()
            )));
        }
    }
    let figures = |i: usize| done.get(&i).map(Figures::of).unwrap_or_default();
    let default = figures(0);
    let base_ratio = default.ratio.unwrap_or(f64::NAN);
    let mut effects: Vec<Effect> = assumptions
        .iter()
        .enumerate()
        .map(|(k, (e, r))| Effect {
            path: e.path,
            low: r.low,
            high: r.high,
            source: e.source,
            at_low: figures(1 + 2 * k),
            at_high: figures(2 + 2 * k),
        })
        .collect();
    // Largest swing first; ties in the study's order (the config's field order).
    effects.sort_by(|a, b| b.swing(base_ratio).total_cmp(&a.swing(base_ratio)));
    let csv = table_csv(&effects, &default, base_ratio);
    let table = Table::parse(&args.out.join("sensitivity.csv"), &csv)?;
    let svg = plot::sensitivity_chart(&table)?;
    sweep::write_files(
        &args.out,
        vec![
            ("sensitivity.csv".into(), csv.into_bytes()),
            ("sensitivity.svg".into(), svg.into_bytes()),
        ],
    )?;
    out!("{}", table_text(&effects, &default, base_ratio))?;
    outln!(
        "wrote {}/sensitivity.csv, sensitivity.svg (the study's rows: sweep.csv)",
        args.out.display()
    )?;
    Ok(())
}

/// `sensitivity.csv`: a row per assumption, largest swing first.
fn table_csv(effects: &[Effect], default: &Figures, base: f64) -> String {
    let opt = |x: Option<f64>| x.map_or(String::new(), number);
    let mut csv = format!(
        "# pxpl5 {} sensitivity: each assumption at the ends of its plausible range, the others \
         at their defaults\nrank,parameter,low,high,ratio_default,ratio_low,ratio_high,swing,\
         hemisphere_ms_default,hemisphere_ms_low,hemisphere_ms_high,hemicube_ms_default,\
         hemicube_ms_low,hemicube_ms_high,bottleneck_default,bottleneck_low,bottleneck_high,\
         source\n",
        env!("CARGO_PKG_VERSION")
    );
    let quote = |s: &str| format!("\"{}\"", s.replace('"', "\"\""));
    for (k, e) in effects.iter().enumerate() {
        csv += &[
            (k + 1).to_string(),
            e.path.to_string(),
            e.low.to_string(),
            e.high.to_string(),
            opt(default.ratio),
            opt(e.at_low.ratio),
            opt(e.at_high.ratio),
            number(e.swing(base)),
            opt(default.hemisphere_ms),
            opt(e.at_low.hemisphere_ms),
            opt(e.at_high.hemisphere_ms),
            opt(default.hemicube_ms),
            opt(e.at_low.hemicube_ms),
            opt(e.at_high.hemicube_ms),
            default.bottleneck.clone(),
            e.at_low.bottleneck.clone(),
            e.at_high.bottleneck.clone(),
            quote(e.source),
        ]
        .join(",");
        csv += "\n";
    }
    csv
}

/// The ranking as printed.
fn table_text(effects: &[Effect], default: &Figures, base: f64) -> String {
    let f = |x: Option<f64>, d: usize| x.map_or("-".to_string(), |v| format!("{v:.d$}"));
    let mut t = format!(
        "Sensitivity of the hemicube / hemisphere ratio (time per shot) to each assumption, moved \
         to the ends of its plausible range\nat the defaults: ratio {}, hemisphere {} ms, \
         hemicube {} ms per shot; bottleneck {}\n\n",
        f(default.ratio, 3),
        f(default.hemisphere_ms, 3),
        f(default.hemicube_ms, 3),
        default.bottleneck
    );
    t += &format!(
        "{:>4}  {:<42} {:>32} {:>16} {:>7} {:>16} {:>16}  {}\n",
        "rank",
        "assumption",
        "low .. high",
        "ratio",
        "swing",
        "hemisphere ms",
        "hemicube ms",
        "bottleneck (hemisphere/hemicube)"
    );
    for (k, e) in effects.iter().enumerate() {
        let ends = |a: Option<f64>, b: Option<f64>, d| format!("{} .. {}", f(a, d), f(b, d));
        let moved = if e.at_low.bottleneck == e.at_high.bottleneck {
            e.at_low.bottleneck.clone()
        } else {
            format!("{} .. {}", e.at_low.bottleneck, e.at_high.bottleneck)
        };
        t += &format!(
            "{:>4}  {:<42} {:>32} {:>16} {:>7.3} {:>16} {:>16}  {moved}\n",
            k + 1,
            e.path,
            format!("{} .. {}", e.low, e.high),
            ends(e.at_low.ratio, e.at_high.ratio, 3),
            e.swing(base),
            ends(e.at_low.hemisphere_ms, e.at_high.hemisphere_ms, 3),
            ends(e.at_low.hemicube_ms, e.at_high.hemicube_ms, 3),
        );
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Both ends of every plausible range make a valid seed machine, so the default study runs.
    #[test]
    fn every_range_end_is_a_valid_machine() {
        let mut study = Study {
            config: None,
            method: Methods::Both,
            shots: Some(1),
            until_error: None,
            params: Vec::new(),
            points: Vec::new(),
            host_time_limit: watch::parse_host_limit("none").unwrap_or_else(|e| panic!("{e}")),
        };
        let assumed: Vec<_> = PROVENANCE
            .iter()
            .filter_map(|e| Some((e.path, e.range?)))
            .collect();
        for (k, (path, range)) in assumed.iter().enumerate() {
            study.params.push(path.to_string());
            for end in [range.low, range.high] {
                let mut point = vec![None; assumed.len()];
                point[k] = Some(end.to_string());
                study.points.push(point);
            }
        }
        for p in &mut study.points {
            p.resize(assumed.len(), None);
        }
        let points = sweep::resolve(&study).map_err(|e| e.0).unwrap();
        assert_eq!(points.len(), 2 * assumed.len());
        // Each end changed the config (the hash), except where an end is the default.
        let seed = pxpl5_config::config_hash(&pxpl5_config::default_config());
        let changed = points
            .iter()
            .filter(|p| pxpl5_config::config_hash(&p.cfg) != seed)
            .count();
        assert!(changed >= assumed.len(), "{changed}");
    }
}
