//! `pxpl5 bench`: simulation speed on fixed, documented workloads.
//!
//! - `bench renderer`: the Renderer at each fidelity level, on the command stream the radiosity
//!   program sends for its first Cornell-box shots (`pxpl5_radiosity::stream`), hemisphere and
//!   hemicube, on one board.
//! - `bench machine`: the whole machine (GPs, ring, Renderers) running the main job's radiosity
//!   program for a fixed number of shots: simulated seconds per host second.
//!
//! Simulated figures (cycles, digests, solutions) must be identical across levels, and the command
//! fails if they are not. Host seconds are the CPU time of the simulating thread (wall time on a
//! shared machine counts other processes' work too), the fastest of `--repeat` runs; `--instructions` also counts the instructions the host executes in the
//! simulation itself, with valgrind's callgrind (exact and repeatable where host time jitters: the
//! way to compare levels and builds on a shared machine).

use std::path::PathBuf;

use clap::Args;
use cpu_time::ThreadTime;
use pxpl5_machine::Recorder;
use pxpl5_radiosity::experiment::{self, MAIN_JOB_PATCH_SIZE, Settings};
use pxpl5_radiosity::mesh::mesh;
use pxpl5_radiosity::shot::{FfOptions, Method};
use pxpl5_radiosity::stream::{Stream, cornell_stream};
use pxpl5_renderer::{Board, Fidelity};

use crate::UserError;
use crate::choices::{BenchFidelity, Methods};
use crate::config_cmd;
use crate::output::outln;
use crate::radiosity::{self, RadiosityArgs};

/// Options of `pxpl5 bench renderer`.
#[derive(Args, Clone, Debug)]
pub struct RendererArgs {
    /// Fidelity level: bit (every micro-cycle on bit-planes), integer (per-pixel integers), sparse
    /// (integer with the one-bit registers deferred), or all.
    #[arg(long, value_enum, default_value_t = BenchFidelity::All)]
    pub fidelity: BenchFidelity,
    /// Machine config (RON); default: the embedded seed machine.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Form-factor method whose stream is timed: hemisphere, hemicube, or both.
    #[arg(long, value_enum, default_value_t = Methods::Both)]
    pub method: Methods,
    /// Shots of the Cornell box in the stream (the first of progressive refinement).
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..=64))]
    pub shots: u32,
    /// Pixels across the hemisphere's disk and the hemicube's top face.
    #[arg(long, default_value_t = 128, value_parser = clap::value_parser!(u32).range(1..=128))]
    pub resolution: u32,
    /// Runs per level; host figures are those of the fastest.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(1..))]
    pub repeat: u32,
    /// Also count the host instructions each level executes running the stream (valgrind's
    /// callgrind, run on this binary once per method and level: slow, about 50x, but exact),
    /// and print instructions per simulated Renderer cycle.
    #[arg(long)]
    pub instructions: bool,
}

impl Default for RendererArgs {
    fn default() -> RendererArgs {
        RendererArgs {
            fidelity: BenchFidelity::All,
            config: None,
            json: false,
            method: Methods::Both,
            shots: 3,
            resolution: 128,
            repeat: 3,
            instructions: false,
        }
    }
}

/// One level's result on one stream.
struct Measured {
    fidelity: Fidelity,
    cycles: u64,
    digest: String,
    host_seconds: f64,
    /// Sign tests and their Renderer cycles.
    signs: (u64, u64),
    /// Host instructions running the stream, when counted.
    instructions: Option<u64>,
}

pub fn renderer(args: &RendererArgs) -> Result<(), UserError> {
    let cfg = config_cmd::load(args.config.as_deref())?;
    let levels = args.fidelity.levels();
    let mut report = Vec::new();
    for method in args.method.methods() {
        let opts = FfOptions {
            method,
            resolution: args.resolution,
            ..FfOptions::default()
        };
        let stream = cornell_stream(&cfg, &opts, args.shots as usize).map_err(|e| {
            UserError(format!(
                "the {} stream does not fit this config: {e}",
                method.name()
            ))
        })?;
        let mut results = measure(&stream, &cfg, &levels, args.repeat)?;
        if args.instructions {
            for m in &mut results {
                let extra = [
                    format!("--shots={}", args.shots),
                    format!("--resolution={}", args.resolution),
                    "--repeat=1".to_string(),
                ];
                let child = child_args(
                    "renderer",
                    (method, m.fidelity),
                    args.config.as_deref(),
                    &extra,
                );
                m.instructions = Some(count_instructions(&child, "*Stream::run*")?);
            }
        }
        report.push((stream, results));
    }
    let agree = report.iter().all(|(_, results)| {
        results
            .windows(2)
            .all(|w| w[0].cycles == w[1].cycles && w[0].digest == w[1].digest)
    });
    if args.json {
        print_json(&cfg, &report, agree)?;
    } else {
        print_table(&cfg, args, &report, agree)?;
    }
    if agree {
        Ok(())
    } else {
        // Not a user error: the levels are proven equal by tests, so this is a bug.
        panic!("fidelity levels disagree on the benchmark stream: simulator bug");
    }
}

/// Run `stream` at each level, `repeat` times on fresh boards; keep the fastest run per level.
fn measure(
    stream: &Stream,
    cfg: &pxpl5_config::MachineConfig,
    levels: &[Fidelity],
    repeat: u32,
) -> Result<Vec<Measured>, UserError> {
    let mut results = Vec::new();
    for &fidelity in levels {
        let mut best: Option<Measured> = None;
        for _ in 0..repeat {
            let mut board = Board::new(&cfg.renderer, cfg.ring.word_bits, fidelity);
            let t0 = ThreadTime::now();
            let cycles = stream.run(&mut board).map_err(|e| {
                UserError(format!("the benchmark stream failed on this config: {e}"))
            })?;
            let host_seconds = t0.elapsed().as_secs_f64();
            let signs = board
                .stats()
                .by_kind
                .get("qee_sign")
                .map_or((0, 0), |k| (k.count, k.cycles));
            let m = Measured {
                fidelity,
                cycles: cycles.0,
                digest: board.image().digest(),
                host_seconds,
                signs,
                instructions: None,
            };
            if best
                .as_ref()
                .is_none_or(|b| m.host_seconds < b.host_seconds)
            {
                best = Some(m);
            }
        }
        results.extend(best);
    }
    Ok(results)
}

fn print_json(
    cfg: &pxpl5_config::MachineConfig,
    report: &[(Stream, Vec<Measured>)],
    agree: bool,
) -> Result<(), UserError> {
    let streams: Vec<_> = report
        .iter()
        .map(|(stream, results)| {
            let levels: Vec<_> = results
                .iter()
                .map(|m| {
                    serde_json::json!({
                        "fidelity": m.fidelity.name(),
                        "renderer_cycles": m.cycles,
                        "digest": m.digest,
                        "host_seconds": m.host_seconds,
                        "cycles_per_host_second": m.cycles as f64 / m.host_seconds,
                        "host_instructions": m.instructions,
                        "instructions_per_cycle": m.instructions.map(|i| i as f64 / m.cycles as f64),
                    })
                })
                .collect();
            let (signs, sign_cycles) = results.first().map_or((0, 0), |m| m.signs);
            serde_json::json!({
                "method": stream.method.name(),
                "stream": stream.description,
                "shooters": stream.shooters,
                "commands": stream.commands.len(),
                "sign_tests": signs,
                "sign_test_cycles": sign_cycles,
                "levels": levels,
            })
        })
        .collect();
    let out = serde_json::json!({
        "config": cfg.name,
        "config_hash": pxpl5_config::config_hash(cfg),
        "renderer_clock_hz": cfg.renderer.clock_hz,
        "streams": streams,
        "levels_agree": agree,
    });
    outln!(
        "{}",
        serde_json::to_string_pretty(&out).map_err(UserError::from)?
    )?;
    Ok(())
}

fn print_table(
    cfg: &pxpl5_config::MachineConfig,
    args: &RendererArgs,
    report: &[(Stream, Vec<Measured>)],
    agree: bool,
) -> Result<(), UserError> {
    let r = &cfg.renderer;
    outln!(
        "pxpl5 bench renderer: the radiosity program's own command stream, one board\n\
         machine {} (hash {}): one {} x {} board, {} bits per pixel, {} MHz; host figures: \
         fastest of {} runs",
        cfg.name,
        pxpl5_config::config_hash(cfg),
        r.width,
        r.height,
        r.pixel_memory_bits,
        r.clock_hz / 1_000_000,
        args.repeat
    )?;
    for (stream, results) in report {
        let (signs, sign_cycles) = results.first().map_or((0, 0), |m| m.signs);
        outln!(
            "\n{}\n{} commands; {} sign tests, {:.1} cycles each on average\n",
            stream.description,
            stream.commands.len(),
            signs,
            sign_cycles as f64 / signs.max(1) as f64
        )?;
        outln!(
            "{:<9} {:>16} {:>14}  {:<16} {:>12} {:>22}{}",
            "fidelity",
            "Renderer cycles",
            "simulated ms",
            "digest",
            "host CPU s",
            "cycles per host s",
            if args.instructions {
                "  host instructions  per cycle"
            } else {
                ""
            }
        )?;
        for m in results {
            let counted = m.instructions.map_or(String::new(), |i| {
                format!("  {i:>17}  {:>9.1}", i as f64 / m.cycles as f64)
            });
            outln!(
                "{:<9} {:>16} {:>14.3}  {:<16} {:>12.4} {:>19.2} M{counted}",
                m.fidelity.name(),
                m.cycles,
                m.cycles as f64 / r.clock_hz as f64 * 1e3,
                &m.digest[..16],
                m.host_seconds,
                m.cycles as f64 / m.host_seconds / 1e6
            )?;
        }
    }
    if report.iter().any(|(_, r)| r.len() > 1) {
        outln!(
            "\nlevels agree on cycles and digest: {}",
            if agree { "yes" } else { "NO (a simulator bug)" }
        )?;
    }
    Ok(())
}

/// The arguments that make this binary run `bench SUBCOMMAND` once for one method at one level
/// (with `extra` options and `config`): what [`count_instructions`] runs under callgrind.
fn child_args(
    subcommand: &str,
    (method, fidelity): (Method, Fidelity),
    config: Option<&std::path::Path>,
    extra: &[String],
) -> Vec<String> {
    let mut child = vec![
        "bench".to_string(),
        subcommand.to_string(),
        "--json".to_string(),
        format!("--method={}", method.name()),
        format!("--fidelity={}", fidelity.name()),
    ];
    child.extend_from_slice(extra);
    if let Some(c) = config {
        child.push(format!("--config={}", c.display()));
    }
    child
}

/// The host instructions executed inside functions matching `function` (a callgrind
/// `--toggle-collect` pattern) when this binary runs with `args`: exact, and the same on every
/// run of the same build, unlike host time.
fn count_instructions(args: &[String], function: &str) -> Result<u64, UserError> {
    let exe = std::env::current_exe()
        .map_err(|e| UserError(format!("--instructions: cannot find this program: {e}")))?;
    let dir = std::env::temp_dir().join(format!("pxpl5-instructions-{}", std::process::id()));
    std::fs::create_dir_all(&dir)
        .map_err(|e| UserError(format!("--instructions: {}: {e}", dir.display())))?;
    let out = dir.join("callgrind.out");
    let status = std::process::Command::new("valgrind")
        .arg("--tool=callgrind")
        .arg(format!("--toggle-collect={function}"))
        .arg(format!("--callgrind-out-file={}", out.display()))
        .arg(&exe)
        .args(args)
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .status();
    let text = std::fs::read_to_string(&out);
    // Best effort: a temporary directory left behind is no error.
    let _ = std::fs::remove_dir_all(&dir);
    match status {
        Err(e) => Err(UserError(format!(
            "--instructions needs valgrind (apt-get install valgrind): {e}"
        ))),
        Ok(s) if !s.success() => Err(UserError(format!(
            "--instructions: the counted run `{} {}` failed under valgrind ({s})",
            exe.display(),
            args.join(" ")
        ))),
        Ok(_) => text
            .ok()
            .and_then(|t| {
                t.lines()
                    .find_map(|l| l.strip_prefix("summary:"))
                    .and_then(|n| n.trim().parse().ok())
            })
            .ok_or_else(|| UserError("--instructions: valgrind wrote no instruction count".into()))
            .and_then(|n: u64| {
                // Nothing counted: no function matched (inlined away), not a free simulation.
                if n == 0 {
                    Err(UserError(format!(
                        "--instructions: no instructions ran inside `{function}`: the build \
                         inlined it away"
                    )))
                } else {
                    Ok(n)
                }
            }),
    }
}

/// Options of `pxpl5 bench machine`.
#[derive(Args, Clone, Debug)]
pub struct MachineArgs {
    /// Fidelity level of the Renderers: bit, integer, sparse, or all.
    #[arg(long, value_enum, default_value_t = BenchFidelity::Integer)]
    pub fidelity: BenchFidelity,
    /// Machine config (RON); default: the embedded seed machine.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Print JSON instead of a table.
    #[arg(long)]
    pub json: bool,
    /// Form-factor method: hemisphere, hemicube, or both.
    #[arg(long, value_enum, default_value_t = Methods::Both)]
    pub method: Methods,
    /// Shots of progressive refinement per run (fixed, so the work is: no target accuracy).
    #[arg(long, default_value_t = 24, value_parser = clap::value_parser!(u32).range(1..=10_000))]
    pub shots: u32,
    /// Run each method as the main job (`pxpl5 radiosity` without flags) does instead of a fixed
    /// number of shots: until every surface is within 1 % of the exact reference, so the shots
    /// differ by method. Simulated seconds per host CPU second then say whether the main job
    /// simulates as fast as real time (the reference's solve is not timed, nor the picture).
    #[arg(long, conflicts_with = "shots")]
    pub main_job: bool,
    /// Runs per level; host figures are those of the fastest.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    pub repeat: u32,
    /// Also count the host instructions of each simulation (valgrind's callgrind, once per
    /// method and level: slow but exact), and print them per simulated microsecond.
    #[arg(long)]
    pub instructions: bool,
}

/// One level's run of the machine workload.
struct MachineRun {
    fidelity: Fidelity,
    simulated_seconds: f64,
    host_seconds: f64,
    /// Shots taken: the fixed number, or as many as the main job's target took.
    shots: usize,
    /// The solution's bits, which every level must reproduce.
    solution: Vec<u64>,
    instructions: Option<u64>,
}

/// `pxpl5 bench machine`: the main job's radiosity program, a fixed number of shots per method
/// or as the main job runs it (`--main-job`), on the whole machine.
pub fn machine(args: &MachineArgs) -> Result<(), UserError> {
    let cfg = config_cmd::load(args.config.as_deref())?;
    // The main job's plan (its reference and target) when asked for: the reference is solved
    // here, before any timing.
    let main_job = args
        .main_job
        .then(|| {
            let job = RadiosityArgs::defaults();
            radiosity::prepare(&job, &cfg).map(|p| (job, p))
        })
        .transpose()?;
    let patches = match &main_job {
        Some((_, p)) => p.patches.clone(),
        None => mesh(
            &pxpl5_radiosity::scenes::cornell_empty(),
            MAIN_JOB_PATCH_SIZE,
        )
        .map_err(|e| UserError(format!("the main job's mesh: {e}")))?,
    };
    let mut report = Vec::new();
    for method in args.method.methods() {
        let mut runs = Vec::new();
        for fidelity in args.fidelity.levels() {
            let mut settings = match &main_job {
                Some((job, p)) => job.settings(method, &p.plan),
                None => Settings::fixed_shots(method, args.shots as usize, &cfg),
            };
            settings.run.fidelity = fidelity;
            let mut best: Option<MachineRun> = None;
            for _ in 0..args.repeat {
                let t0 = ThreadTime::now();
                let run = experiment::run(&cfg, &patches, &settings, Recorder::default())
                    .map_err(|e| UserError(format!("the machine workload failed: {e}")))?;
                let host_seconds = t0.elapsed().as_secs_f64();
                let m = MachineRun {
                    fidelity,
                    simulated_seconds: run.stats.end.as_secs_f64(),
                    host_seconds,
                    shots: run.shots_taken(),
                    solution: run
                        .solution
                        .radiosity
                        .iter()
                        .flatten()
                        .map(|x| x.to_bits())
                        .collect(),
                    instructions: None,
                };
                if best.as_ref().is_none_or(|b| host_seconds < b.host_seconds) {
                    best = Some(m);
                }
            }
            let mut m = best.expect("at least one run");
            if args.instructions {
                let plan = if args.main_job {
                    "--main-job".to_string()
                } else {
                    format!("--shots={}", args.shots)
                };
                let child = child_args(
                    "machine",
                    (method, fidelity),
                    args.config.as_deref(),
                    &[plan],
                );
                m.instructions = Some(count_instructions(&child, "*Machine::run*")?);
            }
            runs.push(m);
        }
        report.push((method, runs));
    }
    let agree = report.iter().all(|(_, runs)| {
        runs.windows(2).all(|w| {
            w[0].simulated_seconds == w[1].simulated_seconds
                && w[0].shots == w[1].shots
                && w[0].solution == w[1].solution
        })
    });
    if args.json {
        let methods: Vec<_> = report
            .iter()
            .map(|(method, runs)| {
                let levels: Vec<_> = runs
                    .iter()
                    .map(|m| {
                        serde_json::json!({
                            "fidelity": m.fidelity.name(),
                            "shots": m.shots,
                            "simulated_seconds": m.simulated_seconds,
                            "host_seconds": m.host_seconds,
                            "simulated_per_host_second": m.simulated_seconds / m.host_seconds,
                            "host_instructions": m.instructions,
                            "instructions_per_simulated_us": m
                                .instructions
                                .map(|i| i as f64 / (m.simulated_seconds * 1e6)),
                        })
                    })
                    .collect();
                serde_json::json!({ "method": method.name(), "levels": levels })
            })
            .collect();
        let out = serde_json::json!({
            "config": cfg.name,
            "config_hash": pxpl5_config::config_hash(&cfg),
            "patches": patches.len(),
            "main_job": args.main_job,
            "shots": (!args.main_job).then_some(args.shots),
            "methods": methods,
            "levels_agree": agree,
        });
        outln!(
            "{}",
            serde_json::to_string_pretty(&out).map_err(UserError::from)?
        )?;
    } else {
        let plan = if args.main_job {
            "run as the main job runs it (until every surface is within 1 % of the reference; \
             the reference's solve and the picture are not timed)"
                .to_string()
        } else {
            format!("for {} shots per method", args.shots)
        };
        outln!(
            "pxpl5 bench machine: the main job's radiosity program {plan}\n\
             machine {} (hash {}): {} GPs, {} Renderers, {} ring channels; the empty Cornell box, \
             {} patches; host figures: fastest of {} runs",
            cfg.name,
            pxpl5_config::config_hash(&cfg),
            cfg.gp.count,
            cfg.renderer.count,
            cfg.ring.channels,
            patches.len(),
            args.repeat
        )?;
        outln!(
            "\n{:<11} {:<9} {:>6} {:>13} {:>10} {:>22}{}",
            "method",
            "fidelity",
            "shots",
            "simulated ms",
            "host CPU s",
            "simulated s per host s",
            if args.instructions {
                "  host instructions  per simulated us"
            } else {
                ""
            }
        )?;
        for (method, runs) in &report {
            for m in runs {
                let counted = m.instructions.map_or(String::new(), |i| {
                    format!(
                        "  {i:>17}  {:>16.0}",
                        i as f64 / (m.simulated_seconds * 1e6)
                    )
                });
                outln!(
                    "{:<11} {:<9} {:>6} {:>13.3} {:>10.3} {:>22.3}{counted}",
                    method.name(),
                    m.fidelity.name(),
                    m.shots,
                    m.simulated_seconds * 1e3,
                    m.host_seconds,
                    m.simulated_seconds / m.host_seconds
                )?;
            }
        }
        if report.iter().any(|(_, r)| r.len() > 1) {
            outln!(
                "\nlevels agree on time and solution: {}",
                if agree { "yes" } else { "NO (a simulator bug)" }
            )?;
        }
    }
    if agree {
        Ok(())
    } else {
        panic!("fidelity levels disagree on the machine benchmark: simulator bug");
    }
}
