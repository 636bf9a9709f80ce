//! The `pxpl5` command: the user's entry to the Pixel-Planes 5 simulator.
//!
//! Subcommands: `run` (a program on a machine, with stats, pictures and traces), `config
//! check|show` (machine configs), `bench renderer` (the Renderer's simulation speed at each
//! fidelity level). With no subcommand it runs `radiosity` with its defaults (the Cornell box, both
//! methods, on the embedded seed machine), which needs no file.
//!
//! Exit codes (`--help` ends with them, [`EXIT_CODES`]): 0 success, also when the reader of
//! stdout closes it early (see [`output`]); 2 a user's mistake (bad config, bad flag, an output
//! that cannot be written, stdout included) or a failed simulation, reported with the file, line
//! or field at fault. The simulator never panics on user input; a panic is a simulator bug.
//!
//! Results go to stdout; the simulator's own logs (`-v`, `-q`, `RUST_LOG`: see [`logging`]) and
//! error messages go to stderr. Every print goes through [`output`].

mod bench;
mod choices;
mod config_cmd;
#[cfg(test)]
mod fuzz;
mod logging;
mod output;
mod radiosity;
mod run;

use std::path::PathBuf;
use std::process::ExitCode;

use clap::{Parser, Subcommand};

use crate::output::errln;

/// A cycle-level simulator of Pixel-Planes 5 (UNC, 1989): Graphics Processors on a token ring,
/// and 128 x 128 bit-serial SIMD Renderers with a quadratic expression evaluator.
///
/// With no subcommand, runs `pxpl5 radiosity`: the Cornell box with hemisphere and hemicube form
/// factors on the embedded seed machine (TR89-002), beside the seed's estimate; writes
/// out/radiosity/.
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
        }
    }
}

#[derive(Subcommand)]
enum Command {
    /// Validate and print machine configs (RON files in machine-configs/).
    #[command(subcommand)]
    Config(ConfigCommand),
    /// Progressive radiosity with hemisphere and/or hemicube form factors on the machine: the
    /// measured time per method and phase beside the seed's estimate, radiosity.png, per-patch
    /// radiosity CSV.
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
}

/// The exit codes, as `--help` ends with them.
const EXIT_CODES: &str = "\
Exit codes:
  0  success; also when the reader of stdout closes it early (`pxpl5 radiosity | head -1`): the
     rest of the report is dropped quietly, as ripgrep does, since a reader that stops once it
     has what it wanted is no failure (files are written before the report, so none is lost)
  2  a user's mistake: a bad config, scene or flag, an output that cannot be written (a
     directory where a file is expected, a full disk or device, stdout included), or a
     simulation that failed (a deadlock, a time limit reached), with the file, line or field at
     fault";

/// A user's mistake: printed, exit code 2.
pub struct UserError(pub String);

impl<E: std::fmt::Display> From<E> for UserError {
    fn from(e: E) -> UserError {
        UserError(e.to_string())
    }
}

fn main() -> ExitCode {
    let result = match Cli::try_parse() {
        Ok(cli) => {
            config_cmd::set_memory_limit(cli.memory_limit);
            logging::init(cli.verbose, cli.quiet).and_then(|()| run_command(cli.command))
        }
        // A usage error, on stderr with exit code 2 (clap ignores a failing stderr).
        Err(e) if e.use_stderr() => e.exit(),
        // --help and --version, on stdout like any report.
        Err(e) => print_help(&e),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(UserError(message)) => {
            errln!("{message}");
            ExitCode::from(2)
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
/// its machine config: `config_cmd::load`).
fn run_command(command: Option<Command>) -> Result<(), UserError> {
    let name = command.as_ref().map_or("radiosity", Command::name);
    let span = tracing::info_span!(
        "pxpl5",
        command = %name,
        config = tracing::field::Empty,
        hash = tracing::field::Empty
    );
    let _entered = span.enter();
    match command {
        None => radiosity::radiosity(&radiosity::RadiosityArgs::defaults()),
        Some(Command::Config(ConfigCommand::Check { files })) => config_cmd::check(&files),
        Some(Command::Config(ConfigCommand::Show { file })) => config_cmd::show(file.as_deref()),
        Some(Command::Bench(BenchCommand::Renderer(args))) => bench::renderer(&args),
        Some(Command::Run(args)) => run::run(&args),
        Some(Command::Radiosity(args)) => radiosity::radiosity(&args),
        Some(Command::Formfactor(args)) => radiosity::formfactor(&args),
    }
}
