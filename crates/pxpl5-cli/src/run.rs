//! `pxpl5 run`: run a program on a machine and write its outputs: the frame as PNG, simulated
//! stats as JSON (and a table on stdout), the effective config with its hash, and on request a
//! Chrome trace and a VCD of simulated time.
//!
//! Nothing is half-written: every output is checked before the run and written after it
//! (`output::write_all`). The run is watched (`watch`): its work is estimated first, it stops at
//! `--time-limit` (simulated) or `--host-time-limit` with exit code 1, and at Ctrl-C with exit
//! code 130, writing nothing either way.

use std::path::{Path, PathBuf};

use clap::Args;
use pxpl5_config::MachineConfig;
use pxpl5_machine::{FrameBufferImage, Machine, Program, Recorder, RunOptions, Stop};
use pxpl5_polygons::{Polygons, scenes};
use pxpl5_sim::Tick;
use pxpl5_trace::TraceWindow;

use crate::UserError;
use crate::choices::{FidelityArg, ProgramArg, RingLevelArg};
use crate::config_cmd;
use crate::failure::Failure;
use crate::output::{self, Dest, out, outln};
use crate::watch::{self, Estimate, HostLimit, Sim, Watch};

/// Most random triangles `--triangles` makes: one simulated second's worth at the paper's design
/// goal. On the reference host a run takes about 160 us and 1 KiB per triangle, so a million is
/// minutes and a gigabyte, and more would only be slower.
const MAX_TRIANGLES: u64 = 1_000_000;

/// Options of `pxpl5 run`.
#[derive(Args, Clone, Debug)]
pub struct RunArgs {
    /// Machine config (RON); default: the embedded seed machine.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Host threads for the Renderers' pixel work (1: all in one thread; never more than the
    /// machine's boards). Host work only: every output is byte-identical whatever the number.
    /// Default: the host's cores (the polygon program reads back only its frame, so the boards
    /// run ahead of the machine; see the README).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=256))]
    pub threads: Option<u32>,
    /// The program to run.
    #[arg(long, value_enum, default_value_t = ProgramArg::Polygons)]
    pub program: ProgramArg,
    /// Scene file (RON; see programs/polygons/scenes/); default: the built-in scene.
    #[arg(long, conflicts_with = "triangles")]
    pub scene: Option<PathBuf>,
    /// Instead of a scene file, N random triangles, 0 to 1,000,000 (the paper's design goal of
    /// a million triangles per second; a million take minutes of host time).
    #[arg(long, value_parser = clap::value_parser!(u64).range(0..=MAX_TRIANGLES))]
    pub triangles: Option<u64>,
    /// Seed of the random triangles.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output directory (created if needed).
    #[arg(long, default_value = "out/polygons")]
    pub out: PathBuf,
    #[command(flatten)]
    pub traces: TraceArgs,
    /// Renderer fidelity level: bit, integer or sparse (identical results and cycles). The approximate
    /// timing level draws no pixels, so it cannot make this program's picture: radiosity only.
    #[arg(long, value_enum, default_value_t = FidelityArg::Sparse)]
    pub fidelity: FidelityArg,
    /// Ring level: token (exact: tokens travel hop by hop) or message (approximate: no token
    /// travel, latency and bandwidth per message).
    #[arg(long, value_enum, default_value_t = RingLevelArg::Token)]
    pub ring_level: RingLevelArg,
    /// Stop with an error (exit code 1) if the run passes this much simulated time (e.g. 10s,
    /// 500ms): the polygon program's runs take milliseconds. Also --max-time.
    #[arg(long, alias = "max-time", value_name = "TIME", default_value = "10s",
          value_parser = watch::parse_time_limit)]
    pub time_limit: Tick,
    /// Stop with an error (exit code 1) once the command has taken this much host time (ms, s,
    /// min or h; `none`: no limit).
    #[arg(long, value_name = "TIME", default_value = watch::DEFAULT_HOST_LIMIT,
          value_parser = watch::parse_host_limit)]
    pub host_time_limit: HostLimit,
}

pub fn run(args: &RunArgs) -> Result<(), Failure> {
    if args.fidelity == FidelityArg::Timing {
        return Err(UserError(
            "--fidelity timing: the polygon program's result is its picture, and the timing \
             level draws no pixels; use bit or integer (or --ring-level message to approximate \
             the ring alone)"
                .into(),
        )
        .into());
    }
    let watch = Watch::new(args.host_time_limit.clone());
    let cfg = config_cmd::load(args.config.as_deref())?;
    let scene = match (&args.scene, args.triangles) {
        (Some(path), _) => {
            pxpl5_polygons::scene::load_triangle_scene(path).map_err(config_cmd::report)?
        }
        // `n` is at most MAX_TRIANGLES, so it fits a usize.
        (None, Some(n)) => scenes::random_scene(n as usize, args.seed, 3.0),
        (None, None) => scenes::builtin_scene(),
    };
    pxpl5_polygons::check_machine(
        &cfg.renderer,
        (cfg.frame_buffer.width, cfg.frame_buffer.height),
    )
    .map_err(UserError)?;

    // Check every destination before spending time on the run.
    output::check_dir("--out", &args.out)?;
    let dests = ["stats.json", "config.ron", "frame.png"]
        .iter()
        .map(|name| output::dest("--out", &args.out.join(name), false))
        .collect::<Result<Vec<_>, _>>()?;
    let mut traces = args.traces.dests(Path::to_path_buf, false)?;
    output::distinct(dests.iter().chain(traces.iter()))?;
    let recorder = args.traces.recorder(&mut traces)?;

    let program = Polygons::new(scene);
    let options = RunOptions {
        fidelity: args.fidelity.into(),
        ring_level: args.ring_level.into(),
        max_time: args.time_limit,
        monitor: None,
        threads: host_threads(args.threads, available_cores()),
    };
    watch::estimate(
        &Estimate {
            name: "run",
            units: machine_units(&cfg),
            work: program.scene().triangles.len() as u64,
            work_is: "triangles",
            large: watch::large::TRIANGLES,
        },
        watch.host_limit(),
    );
    let sim = Sim {
        name: "run",
        shots: None,
        interrupt: Stop::Now,
    };
    let (mut result, host_seconds) = watch.simulate(
        &sim,
        options,
        |options| Machine::new(&cfg, &program as &dyn Program, options, recorder)?.run(),
        |r| r.stats.end,
    )?;

    let stats = &result.stats;
    let mut json = serde_json::to_string_pretty(&stats.to_json()).map_err(UserError::from)?;
    json.push('\n');
    let contents = [
        json.into_bytes(),
        pxpl5_config::show(&cfg).into_bytes(),
        png_bytes(&result.frame, None)?,
    ];
    let files: Vec<_> = dests.into_iter().zip(contents).collect();
    let spools = traces.files(&mut result.recorder)?;
    output::write_all(&files, spools)?;

    out!("{}", stats.table())?;
    let triangles = program.scene().triangles.len();
    let seconds = stats.end.as_secs_f64();
    outln!(
        "\n{triangles} triangles in {:.3} ms simulated: {:.0} triangles per simulated second \
         (the paper's design goal: 1,000,000 Phong-shaded triangles/s for the whole machine; this \
         program shades Gouraud, three linear expressions per triangle, and its time includes \
         reading every region back to the frame buffer)",
        seconds * 1e3,
        triangles as f64 / seconds
    )?;
    let renderer_cycles: u64 = stats.renderers.iter().map(|r| r.busy.0 + r.idle.0).sum();
    outln!(
        "host: {host_seconds:.3} s, {:.2} M simulated Renderer cycles per host second (all boards)",
        renderer_cycles as f64 / host_seconds / 1e6
    )?;
    outln!(
        "wrote {}/frame.png, stats.json, config.ron",
        args.out.display()
    )?;
    Ok(())
}

/// GPs and Renderers of `cfg`, for work estimates.
pub fn machine_units(cfg: &MachineConfig) -> u64 {
    u64::from(cfg.gp.count) + u64::from(cfg.renderer.count)
}

/// `--threads`: the number asked for, or `default`. Measured on this 2-core machine (wall time,
/// 1 thread then 2): `run --triangles 10000` 2.09 -> 1.31 s on `pxpl5-1989.ron`, 1.59 -> 1.29 s
/// on the seed machine, so `run` takes the cores; a radiosity method 1.95 -> 1.92 s (hemisphere,
/// 200 shots) and 2.17 -> 2.71 s (hemicube), every readback a wait for the workers, so each
/// method takes 1 (and the methods run at once instead).
pub fn host_threads(asked: Option<u32>, default: usize) -> usize {
    asked.map_or(default, |n| n as usize)
}

/// The host's cores, as the standard library sees them (1 if it cannot tell).
pub fn available_cores() -> usize {
    std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// The trace options every simulating subcommand takes.
#[derive(Args, Clone, Debug)]
pub struct TraceArgs {
    /// Write an event trace of simulated time to FILE: Perfetto's native protobuf format when
    /// FILE ends in .pftrace (written as the run goes, compact), else a Chrome trace (JSON; both
    /// open in ui.perfetto.dev); `-` is stdout, as JSON (the report then goes to stderr). When a command runs several machines (radiosity
    /// --method both), each run's name goes before the extension: t.hemisphere.json,
    /// t.hemicube.json. A FIFO or device is written through, a symlink kept.
    #[arg(long, value_name = "FILE")]
    pub trace: Option<PathBuf>,
    /// Write a VCD (GTKWave, Surfer) of simulated time to FILE (named as for --trace; `-` is
    /// stdout).
    #[arg(long, value_name = "FILE")]
    pub vcd: Option<PathBuf>,
    /// Limit --trace and --vcd to a window of simulated time, e.g. 0..2ms or 1.5us..3us.
    #[arg(long, value_name = "START..END")]
    pub trace_window: Option<String>,
}

impl TraceArgs {
    /// The trace window, checked: fails before any simulation.
    pub fn window(&self) -> Result<TraceWindow, UserError> {
        match &self.trace_window {
            Some(w) => TraceWindow::parse(w).map_err(|e| UserError(format!("--trace-window: {e}"))),
            None => Ok(TraceWindow::all()),
        }
    }

    /// The recorder of one run whose traces go to `dests`. A Perfetto trace and a VCD are
    /// streamed during the run, and a Chrome trace spills its sorted runs beside its own: their
    /// spools (temporary files) are created now and kept in `dests`.
    pub fn recorder(&self, dests: &mut TraceDests) -> Result<Recorder, UserError> {
        let window = self.window()?;
        let vcd = self.vcd.as_ref().map(|_| window);
        let recorder = match &dests.trace {
            Some(dest) if dests.perfetto => {
                let (spool, file) = output::Spool::create(dest)?;
                dests.trace_spool = Some(spool);
                let out = Box::new(std::io::BufWriter::new(file));
                Recorder::perfetto(window, out, vcd)
            }
            Some(dest) => {
                // Created now, so that the JSON's sorted runs have a directory on the same
                // file system as the file (not the system's temporary directory, which may be
                // memory), and so that a destination that cannot be written fails before the run.
                let (spool, file) = output::Spool::create(dest)?;
                let dir = spool.dir();
                dests.json_spool = Some((spool, file));
                Recorder::new(Some(window), vcd).spill_chrome(dir, pxpl5_trace::SPILL_AT)
            }
            None => Recorder::new(None, vcd),
        };
        match &dests.vcd {
            Some(dest) => {
                let (spool, file) = output::Spool::create(dest)?;
                dests.vcd_spool = Some(spool);
                Ok(recorder.stream_vcd(Box::new(std::io::BufWriter::new(file))))
            }
            None => Ok(recorder),
        }
    }

    /// Where the traces of one run go, each at `name(path given)`, checked before the run
    /// (`output::dest`). `-` is stdout, unless `several` runs each write their own.
    pub fn dests(
        &self,
        name: impl Fn(&Path) -> PathBuf,
        several: bool,
    ) -> Result<TraceDests, UserError> {
        let one = |flag: &str, path: &Option<PathBuf>| {
            path.as_ref()
                .map(|p| {
                    if several && p.as_os_str() == "-" {
                        return Err(UserError(format!(
                            "{flag} -: each run writes its own trace, to FILE.RUN.EXT; name a \
                             file, not stdout"
                        )));
                    }
                    output::dest(flag, &name(p), true)
                })
                .transpose()
        };
        Ok(TraceDests {
            trace: one("--trace", &self.trace)?,
            vcd: one("--vcd", &self.vcd)?,
            perfetto: self.trace.as_deref().is_some_and(is_perfetto),
            trace_spool: None,
            json_spool: None,
            vcd_spool: None,
        })
    }
}

/// Whether `--trace FILE` asks for Perfetto's protobuf format: FILE ends in `.pftrace`.
/// Anything else, `-` included, is Chrome JSON.
pub fn is_perfetto(path: &Path) -> bool {
    path.extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("pftrace"))
}

/// Where one run's traces go (`Default`: nowhere, as for a sweep's points).
#[derive(Debug, Default)]
pub struct TraceDests {
    trace: Option<Dest>,
    vcd: Option<Dest>,
    /// Whether the trace is Perfetto's format, streamed to `trace_spool`.
    perfetto: bool,
    trace_spool: Option<output::Spool>,
    /// The Chrome trace's spool, open: the JSON is written to it when the run ends.
    json_spool: Option<(output::Spool, std::fs::File)>,
    /// The VCD's spool: it is always streamed.
    vcd_spool: Option<output::Spool>,
}

impl TraceDests {
    /// The destinations of the traces asked for.
    pub fn iter(&self) -> impl Iterator<Item = &Dest> {
        self.trace.iter().chain(&self.vcd)
    }

    /// A finished run's trace files, as spools: the streamed traces' ended now, the JSON written
    /// now (every trace goes to disk without its text held in memory).
    pub fn files(&mut self, recorder: &mut Recorder) -> Result<Vec<output::Spool>, UserError> {
        use std::io::Write as _;
        let mut spools = Vec::new();
        if let Some((spool, file)) = self.json_spool.take() {
            // Written to its spool, not gathered in memory first: the text is as large again as
            // the events it comes from (17 MB for a traced 10,000-triangle run).
            let mut out = std::io::BufWriter::new(file);
            recorder
                .write_chrome(&mut out)
                .and_then(|_| out.flush())
                .map_err(|e| cannot_stream(&self.trace, "--trace", e))?;
            spools.push(spool);
        }
        if let Some(spool) = self.trace_spool.take() {
            recorder
                .finish_trace()
                .map_err(|e| cannot_stream(&self.trace, "--trace", e))?;
            spools.push(spool);
        }
        if let Some(spool) = self.vcd_spool.take() {
            recorder
                .finish_vcd()
                .map_err(|e| cannot_stream(&self.vcd, "--vcd", e))?;
            spools.push(spool);
        }
        Ok(spools)
    }
}

/// The error of a streamed trace's write, naming where it goes.
fn cannot_stream(dest: &Option<Dest>, flag: &str, e: std::io::Error) -> UserError {
    let shown = dest.as_ref().map_or(flag.to_string(), |d| match d {
        Dest::Stdout => "stdout".to_string(),
        Dest::Replace(p) | Dest::Through(p) => p.display().to_string(),
    });
    UserError(format!("{shown}: cannot write: {e}"))
}

/// The frame as an 8-bit RGB PNG; with `comment`, in a tEXt chunk (keyword "Comment") beside
/// the simulator's name and version under "Software", so the picture says what produced it.
///
/// At the png crate's default compression, whose bytes every picture so far has had: its `Fast`
/// level (fdeflate) would save 1.4 G instructions on `run`'s 1280 x 1024 frame (11.97 G ->
/// 10.58 G for 10,000 triangles on pxpl5-1989.ron) with the same pixels, but a file 1.6x larger
/// and different bytes.
pub fn png_bytes(frame: &FrameBufferImage, comment: Option<&str>) -> Result<Vec<u8>, UserError> {
    let mut out = Vec::new();
    {
        let mut enc = png::Encoder::new(&mut out, frame.width, frame.height);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        if let Some(text) = comment {
            enc.add_text_chunk(
                "Software".to_string(),
                format!("pxpl5 {}", env!("CARGO_PKG_VERSION")),
            )
            .map_err(UserError::from)?;
            enc.add_text_chunk("Comment".to_string(), text.to_string())
                .map_err(UserError::from)?;
        }
        let mut w = enc.write_header().map_err(UserError::from)?;
        w.write_image_data(&frame.rgb).map_err(UserError::from)?;
    }
    Ok(out)
}
