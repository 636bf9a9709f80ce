//! The `pxpl5` command: the user's entry to the Pixel-Planes 5 simulator.
//!
//! Subcommands: `run` (a program on a machine, with stats, pictures and traces), `config
//! check|show` (machine configs), `bench renderer` (the Renderer's simulation speed at each
//! fidelity level). With no subcommand it runs `radiosity` with its defaults (the Cornell box, both
//! methods, on the embedded seed machine), which needs no file.
//!
//! Exit codes (`--help` ends with them, [`EXIT_CODES`]; [`failure`] says which failure gets
//! which): 0 success, also when the reader of stdout closes it early (see [`output`]); 1 a
//! simulation that failed (a deadlock, a limit reached, a program error on the machine), saying
//! where it was; 2 a user's mistake (bad config, bad flag, an output that cannot be written,
//! stdout included), naming the file, line, field or option at fault; 130 interrupted (Ctrl-C:
//! see [`watch`], which also holds the limits, work estimates and progress bars of every run).
//! The simulator never panics on user input; a panic is a simulator bug.
//!
//! Results go to stdout; the simulator's own logs (`-v`, `-q`, `RUST_LOG`: see [`logging`]) and
//! error messages go to stderr. Every print goes through [`output`].

mod bench;
mod choices;
mod config_cmd;
mod failure;
#[cfg(test)]
mod fuzz;
mod logging;
mod output;
mod plot;
mod radiosity;
mod run;
mod sensitivity;
mod stability;
mod stats_cmd;
mod sweep;
mod trace_cmd;
mod tradeoff;
mod watch;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

pub use crate::failure::UserError;
use crate::failure::{EXIT_CODES, Failure};
use crate::output::errln;

/// A cycle-level simulator of Pixel-Planes 5 (UNC, 1989): Graphics Processors on a token ring,
/// and 128 x 128 bit-serial SIMD Renderers with a quadratic expression evaluator.
///
/// With no subcommand, runs `pxpl5 radiosity`: the empty Cornell box with hemisphere and hemicube
/// form factors on the embedded seed machine (TR89-002), each until within 1 % of the exact
/// solution, beside the seed's estimate; writes out/radiosity/.
#[derive(Parser)]
#[command(name = "pxpl5", version, propagate_version = true, after_long_help = EXIT_CODES)]
struct Cli {
    /// Log more on stderr: -v info (each simulation's start and end), -vv debug, -vvv trace.
    /// Default: warnings and errors. RUST_LOG, when set, overrides -v and -q.
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    verbose: u8,
    /// Log only errors on stderr. Results on stdout are unchanged.
    #[arg(short, long, global = true, conflicts_with = "verbose")]
    quiet: bool,
    /// Host memory a machine may need, e.g. 16GiB or 512MiB (units B, KiB, MiB, GiB, TiB, all
    /// powers of 1,024). Every command estimates it from the machine config before building
    /// anything (Renderers' pixel memory and full backing store, GPs, ring, frame buffer; `config
    /// show` prints the estimate) and refuses a machine that needs more.
    #[arg(long, global = true, value_name = "SIZE", default_value = "4GiB",
          value_parser = pxpl5_machine::memory::parse_size)]
    memory_limit: u64,
    #[command(subcommand)]
    command: Option<Command>,
}

impl Command {
    /// The subcommand's name as the user types it.
    fn name(&self) -> &'static str {
        match self {
            Command::Config(ConfigCommand::Check { .. }) => "config check",
            Command::Config(ConfigCommand::Show { .. }) => "config show",
            Command::Radiosity(_) => "radiosity",
            Command::Formfactor(_) => "formfactor",
            Command::Run(_) => "run",
            Command::Bench(BenchCommand::Renderer(_)) => "bench renderer",
            Command::Bench(BenchCommand::Machine(_)) => "bench machine",
            Command::Stats(StatsCommand::Diff(_)) => "stats diff",
            Command::Trace(TraceCommand::Timeline(_)) => "trace timeline",
            Command::Trace(TraceCommand::Utilisation(_)) => "trace utilisation",
            Command::Plot(_) => "plot",
            Command::Sensitivity(_) => "sensitivity",
            Command::Stability(_) => "stability",
            Command::Tradeoff(_) => "tradeoff",
            Command::Sweep(c) if c.merge.is_some() => "sweep merge",
            Command::Sweep(_) => "sweep",
        }
    }
}

#[derive(Subcommand)]
enum Command {
    /// Validate and print machine configs (RON files in machine-configs/).
    #[command(subcommand)]
    Config(ConfigCommand),
    /// Progressive radiosity with hemisphere and/or hemicube form factors on the machine, both
    /// on the same resources: time per shot and to a target accuracy against the exact
    /// reference, form-factor error, work per shot, beside the seed's estimate; per method a
    /// picture, per-patch radiosity and the convergence curve.
    Radiosity(radiosity::RadiosityArgs),
    /// The form factor from a point to a polygon: exact, or measured on the machine with its
    /// cycles.
    Formfactor(radiosity::FormFactorArgs),
    /// Run a program on a machine: writes DIR/frame.png, DIR/stats.json and DIR/config.ron,
    /// prints the stats table; --trace and --vcd record simulated time.
    Run(run::RunArgs),
    /// Measure simulation speed on a fixed, documented workload: the radiosity program's own
    /// Renderer command stream.
    #[command(subcommand)]
    Bench(BenchCommand),
    /// Work with saved statistics (stats.json, comparison.json, formfactor --json).
    #[command(subcommand)]
    Stats(StatsCommand),
    /// Work with trace files (--trace's .json or .pftrace).
    #[command(subcommand)]
    Trace(TraceCommand),
    /// A study of the radiosity experiment over machine-config fields and radiosity options
    /// (--set PATH=V1,V2,... or --study FILE, their cross product): one row per point and
    /// method in OUT/sweep.csv and sweep.json, points run in parallel, a rerun resumes;
    /// `sweep merge` joins shards (--shard K/N).
    Sweep(sweep::SweepCommand),
    /// Draw saved results as SVG: a sweep's ratio and time per shot against a swept parameter,
    /// radiosity's convergence (error against shots, per method), a sensitivity tornado, a
    /// stability study.
    Plot(plot::PlotArgs),
    /// Move every `[assumed]` parameter of the machine config across its plausible range (low,
    /// high, the others at their defaults), run both methods, and rank the assumptions by how
    /// far they move the hemicube / hemisphere ratio: a table and a tornado chart (SVG).
    Sensitivity(sensitivity::SensitivityArgs),
    /// Numerical stability at the extremes: the machine's form factor against exact as the
    /// QEE's fractional bits (4 to 32), the geometry's scale (1e-9 to 1e9) and a polygon's
    /// elevation (pole to horizon) move: a table and a plot.
    Stability(stability::StabilityArgs),
    /// Speed against accuracy: the same workload (the main job, both methods) at every fidelity
    /// level (bit, integer, the approximate timing Renderer and message-level ring) and
    /// algorithm knob (resolution, QEE precision, depth, accuracy target): host seconds against
    /// the error in simulated time and in radiosity, Pareto-optimal knobs marked; a table and a
    /// plot (SVG).
    Tradeoff(tradeoff::TradeoffArgs),
}

#[derive(Subcommand)]
enum TraceCommand {
    /// Draw a trace's timeline as an SVG: one row per unit or ring lane, the critical-path track
    /// on top, slices coloured by category (what a Perfetto screenshot would show).
    Timeline(trace_cmd::TimelineArgs),
    /// Draw each resource's utilisation over simulated time as an SVG: per interval, the busy
    /// share of the GPs, of the Renderers and of the ring's channels.
    Utilisation(trace_cmd::UtilisationArgs),
}

#[derive(Subcommand)]
enum StatsCommand {
    /// Compare two runs' simulated figures: every figure that changed, was added or removed, with
    /// both values and the change. Exit code 0 if none differs (beyond --tolerance), 1 if some
    /// do, 2 if a file cannot be read or is not JSON: a CI job keeps one run's file and compares
    /// every build's with it.
    Diff(stats_cmd::DiffArgs),
}

#[derive(Subcommand)]
enum ConfigCommand {
    /// Parse and validate each FILE; report every problem with file, line and column (syntax) or
    /// the dotted field path (semantics). Exit code 2 if any file is bad.
    Check {
        /// Machine config files (RON).
        #[arg(required = true)]
        files: Vec<PathBuf>,
    },
    /// Print the effective config (every default resolved), each field annotated with its
    /// provenance: `[paper]`, `[seed]`, `[lineage]` or `[assumed]`. Without FILE, the embedded seed
    /// machine.
    Show {
        /// A machine config file (RON); default: the embedded seed-tr89-002.
        file: Option<PathBuf>,
    },
}

#[derive(Subcommand)]
enum BenchCommand {
    /// Run the radiosity program's own Renderer command stream (every receiver of the first
    /// Cornell-box shots, hemisphere and hemicube, with each view's set-up, completion probes and
    /// ID readbacks) on one full Renderer board and print its Renderer cycles, a digest of pixel
    /// memory, host seconds and simulated Renderer cycles per host second. Every fidelity level
    /// prints the same cycles and digest.
    Renderer(bench::RendererArgs),
    /// Run the main job's radiosity program (the empty Cornell box, 199 patches, on the whole
    /// machine: GPs, ring and Renderers) for a fixed number of shots per method and print the
    /// simulated time, host seconds and simulated seconds per host second. Every fidelity level
    /// gives the same time and solution.
    Machine(bench::MachineArgs),
}

/// Frees a 1 MiB block first thing, so that glibc's allocator keeps up to 2 MiB of freed heap
/// instead of handing it back to the kernel at once. Host work only.
///
/// glibc serves a block above its mmap threshold (128 KiB at start) by `mmap`; freeing one
/// raises the threshold to its size and the heap's trim threshold to twice that (`mallopt(3)`,
/// "dynamic mmap threshold"). Left at 128 KiB, the heap's top grew and shrank about 700 times in
/// the main job's hemisphere as GPs' command lists and readbacks came and went: 1,424 `brk`
/// calls and 29.6 K page faults, the kernel clearing pages for about 4 % of the run's CPU time
/// by `perf record`. With it: 64 `brk` calls and 3.4 K page faults (hemicube: 11.4 K to 5.0 K),
/// peak memory unchanged. Other allocators just free the block.
fn raise_heap_trim_threshold() {
    // `black_box`: the compiler may otherwise drop an allocation nothing reads.
    drop(std::hint::black_box(Vec::<u8>::with_capacity(1 << 20)));
}

fn main() -> ExitCode {
    raise_heap_trim_threshold();
    let result = match Cli::try_parse() {
        Ok(cli) => {
            config_cmd::set_memory_limit(cli.memory_limit);
            logging::init(cli.verbose, cli.quiet)
                .map_err(Failure::from)
                .and_then(|()| {
                    watch::enable_progress(cli.quiet);
                    run_command(cli.command)
                })
        }
        // A usage error, on stderr with exit code 2 (clap ignores a failing stderr).
        Err(e) if e.use_stderr() => e.exit(),
        // --help and --version, on stdout like any report.
        Err(e) => print_help(&e).map_err(Failure::from),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(failure) => {
            errln!("{}", failure.message());
            ExitCode::from(failure.exit_code())
        }
    }
}

/// Print clap's `--help` or `--version` text through the one stdout writer, styled as clap would
/// style it when stdout is a terminal.
fn print_help(e: &clap::Error) -> Result<(), UserError> {
    use std::io::IsTerminal;
    let styled = e.render();
    let colour = std::io::stdout().is_terminal()
        && std::env::var_os("NO_COLOR").is_none_or(|v| v.is_empty());
    if colour {
        output::print(format_args!("{}", styled.ansi()))
    } else {
        output::print(format_args!("{styled}"))
    }
}

/// Run one subcommand inside its span (`config` and `hash` are recorded when the command loads
/// its machine config: `config_cmd::load`). The commands that simulate catch Ctrl-C
/// ([`watch::catch_interrupts`]); the others end on it at once, as by default, having nothing to
/// keep.
fn run_command(command: Option<Command>) -> Result<(), Failure> {
    let name = command.as_ref().map_or("radiosity", Command::name);
    let span = tracing::info_span!(
        "pxpl5",
        command = %name,
        config = tracing::field::Empty,
        hash = tracing::field::Empty
    );
    let _entered = span.enter();
    if matches!(
        command,
        None | Some(
            Command::Run(_)
                | Command::Radiosity(_)
                | Command::Formfactor(_)
                | Command::Sweep(_)
                | Command::Sensitivity(_)
                | Command::Stability(_)
                | Command::Tradeoff(_)
        )
    ) {
        watch::catch_interrupts();
    }
    match command {
        None => radiosity::radiosity(&radiosity::RadiosityArgs::defaults()),
        Some(Command::Config(ConfigCommand::Check { files })) => Ok(config_cmd::check(&files)?),
        Some(Command::Config(ConfigCommand::Show { file })) => {
            Ok(config_cmd::show(file.as_deref())?)
        }
        Some(Command::Bench(BenchCommand::Renderer(args))) => Ok(bench::renderer(&args)?),
        Some(Command::Bench(BenchCommand::Machine(args))) => Ok(bench::machine(&args)?),
        Some(Command::Run(args)) => run::run(&args),
        Some(Command::Radiosity(args)) => radiosity::radiosity(&args),
        Some(Command::Formfactor(args)) => radiosity::formfactor(&args),
        Some(Command::Stats(StatsCommand::Diff(args))) => stats_cmd::diff(&args),
        Some(Command::Trace(TraceCommand::Timeline(args))) => trace_cmd::timeline(&args),
        Some(Command::Trace(TraceCommand::Utilisation(args))) => trace_cmd::utilisation(&args),
        Some(Command::Sweep(cmd)) => sweep::sweep(&cmd),
        Some(Command::Plot(args)) => Ok(plot::plot(&args)?),
        Some(Command::Sensitivity(args)) => sensitivity::sensitivity(&args),
        Some(Command::Stability(args)) => stability::stability(&args),
        Some(Command::Tradeoff(args)) => tradeoff::tradeoff(&args),
    }
}
