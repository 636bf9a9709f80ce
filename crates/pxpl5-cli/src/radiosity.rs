//! `pxpl5 radiosity` (progressive radiosity with hemisphere and/or hemicube form factors on the
//! machine, measured and set beside the seed's estimate) and `pxpl5 formfactor` (one point to
//! one polygon, exactly or on the machine).
//!
//! Only parsing, printing and files live here: the experiment itself (runs, phase analysis, the
//! seed's estimate, the comparison, pictures) is `pxpl5_radiosity`'s, so that another Rust
//! program can run it. The command times each run on the host and prints those figures apart;
//! they never reach a file.
//!
//! Every run is watched (`watch`): its work is estimated first; `--time-limit` (simulated) and
//! `--host-time-limit` stop it with exit code 1, writing nothing. Ctrl-C ends a radiosity run
//! after the shot under way; the methods not started are skipped, the pictures are drawn from the
//! shots taken, and everything is written marked partial (`partial` in comparison.json and
//! comparison.csv, "interrupted after N of M shots" in the report), exit code 130.

use std::path::{Path, PathBuf};

use clap::Args;
use pxpl5_geom::DVec3;
use pxpl5_geom::convex::Corner;
use pxpl5_geom::polygon::{self, Problem};
use pxpl5_machine::{Resource, RunOptions, RunStats, Stop};
use std::sync::Arc;

use pxpl5_radiosity::accuracy::Reference;
use pxpl5_radiosity::comparison::{Comparison, SEED_RATIO};
use pxpl5_radiosity::experiment::{self, MethodRun, Settings};
use pxpl5_radiosity::mesh::{Patch, mesh};
use pxpl5_radiosity::picture;
use pxpl5_radiosity::program::MAX_MACHINE_PATCHES;
use pxpl5_radiosity::scene::RadiosityScene;
use pxpl5_radiosity::shot::{FfOptions, Method, check_resolution};
use pxpl5_sim::Tick;

use crate::UserError;
use crate::choices::{
    Delta, DepthArg, EdgeRuleArg, FidelityArg, FormFactorMethod, Methods, RingLevelArg,
};
use crate::config_cmd;
use crate::failure::Failure;
use crate::output::{self, out, outln};
use crate::run::{TraceArgs, TraceDests, machine_units, png_bytes};
use crate::watch::{self, Estimate, HostLimit, Sim, Watch};

/// Options of `pxpl5 radiosity`.
#[derive(Args, Clone, Debug)]
pub struct RadiosityArgs {
    /// Machine config (RON); default: the embedded seed machine.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Radiosity scene (RON); default: the Cornell box without its blocks (cornell-empty.ron),
    /// which has an exact reference solution, so the run's accuracy is measured.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Form-factor method.
    #[arg(long, value_enum, default_value_t = Methods::Both)]
    pub method: Methods,
    /// Most shots to take (shooting patches, the seed's N). Default: for a scene with a
    /// reference, 10 per patch (a cap: 1 % takes about 3 per patch); otherwise 6.
    #[arg(long)]
    pub shots: Option<usize>,
    /// Stop once every surface's mean radiosity is within this fraction of the reference solution
    /// (0.01: 1 %; 0: never). Needs a scene without occluders (the reference is the direct solve
    /// with exact form factors); default 0.01 for such a scene.
    #[arg(long)]
    pub until_error: Option<f64>,
    /// Stop early when max unshot power / emitted power falls below this (0: never; a finite
    /// number >= 0).
    #[arg(long, default_value_t = 0.0, value_parser = non_negative_finite)]
    pub threshold: f64,
    /// Patch size in scene units (the Cornell box is in millimetres); the mesh may have at most
    /// 65,534 patches (the machine's 16-bit patch IDs).
    #[arg(long, default_value_t = experiment::MAIN_JOB_PATCH_SIZE, value_parser = positive_finite)]
    pub patch_size: f64,
    /// Host threads for the Renderers' pixel work (1: all in one thread). Host work only: every
    /// output is byte-identical whatever the number. Default 1: each readback waits for the
    /// workers, and today that costs more than the second core gains (see the README).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=256))]
    pub threads: Option<u32>,
    /// Run the methods one after the other. By default they run at once, a host thread each,
    /// when the host has a core for each and the memory limit holds all their machines. Host
    /// work only: every output is byte-identical either way. In turn, each method's host seconds
    /// has the host to itself, and a first Ctrl-C ends the method under way and starts no other.
    #[arg(long)]
    pub in_turn: bool,
    /// Pixels across the hemisphere's disk and the hemicube's top face, 1 to 4096; the machine
    /// limits it further (a disk larger than a Renderer is cut into tiles of 128 x 128, drawn in
    /// turn, each within the QEE's pixel addresses; a hemicube face must fit one Renderer, and N
    /// must be even).
    #[arg(long, default_value_t = 128,
          value_parser = clap::value_parser!(u32).range(1..=MAX_RESOLUTION))]
    pub resolution: u32,
    /// Hemisphere edge rule: sign-of-c (docs/radiosity.md section 3) or seed (TR89-002's
    /// CASE 1 / CASE 2).
    #[arg(long, value_enum, default_value_t = EdgeRuleArg::SignOfC)]
    pub edge_rule: EdgeRuleArg,
    /// Hemisphere delta form factors: exact (disk area) or seed (the seed's integral rule).
    #[arg(long, value_enum, default_value_t = Delta::Exact)]
    pub delta: Delta,
    /// Hemicube: transform and clip every receiver for every face (no cheap face test).
    #[arg(long)]
    pub all_faces: bool,
    /// Do not turn each shot's view about the shooter's normal (by default a seeded random turn
    /// per shot keeps a hemicube's aliasing from being the same, a bias, at every shot).
    #[arg(long)]
    pub no_rotation: bool,
    /// Seed of the per-shot turns (the same seed gives the same run).
    #[arg(long, default_value_t = 1)]
    pub rotation_seed: u64,
    /// Shoot this many patches at once, their views scheduled together on the Renderers (1:
    /// classic progressive refinement). Default: the number of Renderers, for both methods, so
    /// each can keep every board busy.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..))]
    pub shooters_at_once: Option<u32>,
    /// Hemisphere depth: taylor (the seed's quadratic approximation) or stored-w (w per pixel,
    /// exact, slower).
    #[arg(long, value_enum, default_value_t = DepthArg::Taylor)]
    pub depth: DepthArg,
    /// Output directory.
    #[arg(long, default_value = "out/radiosity")]
    pub out: PathBuf,
    /// Renderer fidelity level: bit, integer or sparse (exact, identical results and cycles), or timing
    /// (approximate: no pixel work, form factors from the exact formula on the host; only for a
    /// scene where no surface hides another).
    #[arg(long, value_enum, default_value_t = FidelityArg::Sparse)]
    pub fidelity: FidelityArg,
    /// Ring level: token (exact: tokens travel hop by hop) or message (approximate: no token
    /// travel, latency and bandwidth per message).
    #[arg(long, value_enum, default_value_t = RingLevelArg::Token)]
    pub ring_level: RingLevelArg,
    #[command(flatten)]
    pub traces: TraceArgs,
    /// Write the item (ID) buffers of these shots (0-based, comma-separated) as PNGs:
    /// DIR/items-METHOD-shotK-VIEW.png, one colour per patch.
    #[arg(long, value_delimiter = ',')]
    pub item_buffers: Vec<usize>,
    /// Stop with an error (exit code 1) if a run passes this much simulated time (e.g. 1000s,
    /// 500ms): far beyond the default run's 0.7 s, for fine meshes with many shots.
    #[arg(long, value_name = "TIME", default_value = "1000s",
          value_parser = watch::parse_time_limit)]
    pub time_limit: Tick,
    /// Stop with an error (exit code 1) once the command has taken this much host time (ms, s,
    /// min or h; `none`: no limit). Ctrl-C instead ends the run after the shot under way and
    /// writes what was computed, marked partial (exit code 130).
    #[arg(long, value_name = "TIME", default_value = watch::DEFAULT_HOST_LIMIT,
          value_parser = watch::parse_host_limit)]
    pub host_time_limit: HostLimit,
}

/// `path` with the method's name before its extension, when more than one method runs.
fn per_method(path: &Path, method: Method, several: bool) -> PathBuf {
    if !several {
        return path.to_path_buf();
    }
    let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("trace");
    let name = match path.extension().and_then(|e| e.to_str()) {
        Some(ext) => format!("{stem}.{}.{ext}", method.name()),
        None => format!("{stem}.{}", method.name()),
    };
    path.with_file_name(name)
}

impl RadiosityArgs {
    pub fn defaults() -> RadiosityArgs {
        use clap::{Args as _, FromArgMatches as _};
        let cmd = RadiosityArgs::augment_args(clap::Command::new("radiosity"));
        RadiosityArgs::from_arg_matches(&cmd.get_matches_from(["radiosity"]))
            .expect("the defaults parse")
    }

    /// The library's settings for one method's run on `plan`.
    pub(crate) fn settings(&self, method: Method, plan: &Plan) -> Settings {
        Settings {
            ff: FfOptions {
                method,
                resolution: self.resolution,
                edge_rule: self.edge_rule.into(),
                exact_delta: self.delta.exact(),
                skip_faces: !self.all_faces,
                depth: self.depth.into(),
                rotation: (!self.no_rotation).then_some(self.rotation_seed),
            },
            shots: plan.shots,
            threshold: self.threshold,
            shooters_at_once: plan.shooters_at_once,
            item_shots: self.item_buffers.clone(),
            reference: plan.reference.clone(),
            target_error: plan.until_error,
            run: RunOptions {
                fidelity: self.fidelity.into(),
                ring_level: self.ring_level.into(),
                max_time: self.time_limit,
                monitor: None,
                threads: crate::run::host_threads(self.threads, 1),
            },
        }
    }
}

/// What a run's defaults resolve to on its machine and scene.
pub(crate) struct Plan {
    pub shots: usize,
    pub shooters_at_once: usize,
    pub reference: Option<Arc<Reference>>,
    pub until_error: Option<f64>,
}

impl Plan {
    /// The plan of `args` for `patches` of `scene` on `cfg`; a `--until-error` the scene cannot
    /// honour (it has occluders, so no reference) is an error.
    fn new(
        args: &RadiosityArgs,
        cfg: &pxpl5_config::MachineConfig,
        scene: &RadiosityScene,
        patches: &[Patch],
    ) -> Result<Plan, UserError> {
        let until_error = match args.until_error {
            Some(e) if !(0.0..1.0).contains(&e) => {
                return Err(UserError(format!(
                    "--until-error {e}: must be a fraction from 0 (never) to below 1 (0.01 is 1 %)"
                )));
            }
            Some(e) => (e > 0.0).then_some(e),
            None => Some(DEFAULT_UNTIL_ERROR),
        };
        let reference = Reference::new(scene, patches).map(Arc::new);
        let until_error = match (until_error, &reference) {
            (Some(_), None) if args.until_error.is_some() => {
                return Err(UserError(format!(
                    "--until-error: scene {} has surfaces that can hide others (it is not the \
                     inside of a convex shell), so it has no exact reference solution to \
                     measure the error against",
                    scene.name
                )));
            }
            (_, None) => None,
            (e, Some(_)) => e,
        };
        let shots = args.shots.unwrap_or(match &reference {
            Some(_) => SHOTS_PER_PATCH * patches.len(),
            None => SHOTS_WITHOUT_REFERENCE,
        });
        Ok(Plan {
            shots,
            shooters_at_once: args
                .shooters_at_once
                .map_or(cfg.renderer.count as usize, |k| k as usize),
            reference,
            until_error,
        })
    }
}

/// `--until-error`'s default for a scene with a reference: 1 %.
const DEFAULT_UNTIL_ERROR: f64 = 0.01;
/// `--shots`' default cap per patch for a scene with a reference: progressive refinement of the
/// Cornell box reaches 1 % in about 3 shots per patch (with exact form factors: 450 shots for
/// 141 patches, 1,140 for 367), so 10 leaves room for a machine method's slower convergence.
const SHOTS_PER_PATCH: usize = 10;
/// `--shots`' default for a scene without a reference: a few shots, enough to time them.
const SHOTS_WITHOUT_REFERENCE: usize = 6;

/// Run `method` under `watch`; returns the run and its host seconds. Writes nothing.
pub(crate) fn run_method(
    watch: &Watch,
    cfg: &pxpl5_config::MachineConfig,
    patches: &[Patch],
    args: &RadiosityArgs,
    plan: &Plan,
    method: Method,
    traces: &mut TraceDests,
) -> Result<(MethodRun, f64), Failure> {
    tracing::info!(
        method = %method.name(),
        patches = patches.len(),
        max_shots = plan.shots,
        "form-factor method starts"
    );
    let recorder = args.traces.recorder(traces)?;
    let mut settings = args.settings(method, plan);
    let name = format!("radiosity ({})", method.name());
    let sim = Sim {
        name: &name,
        shots: Some(plan.shots as u64),
        interrupt: Stop::Soon,
    };
    watch.simulate(
        &sim,
        settings.run.clone(),
        |options| {
            settings.run = options;
            experiment::run(cfg, patches, &settings, recorder)
        },
        |r| r.stats.end,
    )
}

/// Receiver draws of a radiosity run at most, for its work estimate: patches x shots (each shot
/// draws every receiver) x methods x the Renderer tiles of a hemisphere view (ceil(resolution /
/// 128)^2 at 128 x 128 pixels a board).
fn receiver_draws(patches: usize, shots: usize, args: &RadiosityArgs, methods: usize) -> u64 {
    let tiles = u64::from(args.resolution.div_ceil(128)).pow(2);
    (patches as u64)
        .saturating_mul(shots as u64)
        .saturating_mul(methods as u64)
        .saturating_mul(tiles)
}

/// The files of the output directory written once per run.
const FILES: [&str; 3] = ["comparison.csv", "comparison.json", "config.ron"];

/// The files written per method: `patches-METHOD.csv` (per-patch radiosity), with a reference
/// `convergence-METHOD.csv` (error batch by batch), and with a camera `radiosity-METHOD.png`.
fn method_files(method: Method, reference: bool, camera: bool) -> Vec<String> {
    let m = method.name();
    let mut names = vec![format!("patches-{m}.csv")];
    if reference {
        names.push(format!("convergence-{m}.csv"));
    }
    if camera {
        names.push(format!("radiosity-{m}.png"));
    }
    names
}

/// A radiosity job ready to run on its machine: the scene, its mesh and the resolved plan.
pub(crate) struct Prepared {
    pub scene: RadiosityScene,
    pub patches: Vec<Patch>,
    pub plan: Plan,
}

/// Load the scene of `args`, mesh it and resolve the plan on the machine of `cfg`, checking
/// every option against them (patch count, resolution per method): what `radiosity` and each
/// point of `sweep` do before their first run.
pub(crate) fn prepare(
    args: &RadiosityArgs,
    cfg: &pxpl5_config::MachineConfig,
) -> Result<Prepared, UserError> {
    let scene: RadiosityScene = match &args.scene {
        Some(p) => pxpl5_radiosity::scene::load_radiosity_scene(p).map_err(config_cmd::report)?,
        None => pxpl5_radiosity::scenes::cornell_empty(),
    };
    let patches = mesh(&scene, args.patch_size)
        .map_err(|e| UserError(format!("--patch-size {:?}: {e}", args.patch_size)))?;
    if patches.len() > MAX_MACHINE_PATCHES {
        return Err(UserError(format!(
            "--patch-size {:?}: makes {} patches, more than the {MAX_MACHINE_PATCHES} the \
             machine's 16-bit patch IDs can name; use a larger patch size",
            args.patch_size,
            patches.len()
        )));
    }
    if args.fidelity == FidelityArg::Timing && !scene.unoccluded() {
        return Err(UserError(format!(
            "--fidelity timing: scene {} has surfaces that can hide others, and the timing \
             level's form factors come from the exact formula without occlusion; use bit or \
             integer",
            scene.name
        )));
    }
    for method in args.method.methods() {
        check_resolution(method, args.resolution, &cfg.renderer)
            .map_err(|e| UserError(format!("--resolution {}: {e}", args.resolution)))?;
    }
    let plan = Plan::new(args, cfg, &scene, &patches)?;
    Ok(Prepared {
        scene,
        patches,
        plan,
    })
}

/// What one method computed: its run, the host seconds it took, and the PNG of its solution's
/// picture when the scene has a camera.
struct Computed {
    run: MethodRun,
    host: f64,
    picture: Option<Vec<u8>>,
}

/// Whether `methods` runs go at once, a host thread each: unless `--in-turn`, when there are
/// several, the host has a core for each, and the memory limit holds all their machines at
/// once (it is checked for one machine when the config is loaded).
fn at_once(args: &RadiosityArgs, cfg: &pxpl5_config::MachineConfig, methods: usize) -> bool {
    if args.in_turn || methods < 2 {
        return false;
    }
    let cores = crate::run::available_cores();
    let machines = pxpl5_machine::memory::estimate(cfg)
        .total()
        .saturating_mul(methods as u64);
    let fits = machines <= config_cmd::memory_limit();
    if cores < methods || !fits {
        tracing::info!(cores, machines_bytes = machines, "the methods run in turn");
    }
    cores >= methods && fits
}

/// Runs every method (at once, a host thread each, or in turn: `at_once`), renders the
/// pictures, and only then writes every output, all or nothing (`output::write_all`), and prints
/// the report: a failure anywhere leaves the output directory as it was. Every output whose
/// name is known is checked before the first run.
pub fn radiosity(args: &RadiosityArgs) -> Result<(), Failure> {
    let watch = Watch::new(args.host_time_limit.clone());
    let cfg = config_cmd::load(args.config.as_deref())?;
    let Prepared {
        scene,
        patches,
        plan,
    } = prepare(args, &cfg)?;
    if scene.camera.is_some() {
        // The pictures are drawn by the polygon program: refuse a machine it cannot draw on now,
        // not after the radiosity runs.
        pxpl5_polygons::check_machine(
            &cfg.renderer,
            (cfg.frame_buffer.width, cfg.frame_buffer.height),
        )
        .map_err(|e| UserError(format!("the picture of the solution: {e}")))?;
    }
    let methods = args.method.methods();

    // Check every destination before the first run.
    output::check_dir("--out", &args.out)?;
    let mut names: Vec<String> = FILES.iter().map(|f| f.to_string()).collect();
    for &m in &methods {
        names.extend(method_files(
            m,
            plan.reference.is_some(),
            scene.camera.is_some(),
        ));
    }
    let files = names
        .iter()
        .map(|name| output::dest("--out", &args.out.join(name), false))
        .collect::<Result<Vec<_>, _>>()?;
    args.traces.window()?;
    let several = methods.len() > 1;
    let mut traces = methods
        .iter()
        .map(|&m| args.traces.dests(|p| per_method(p, m, several), several))
        .collect::<Result<Vec<_>, _>>()?;
    output::distinct(files.iter().chain(traces.iter().flat_map(|t| t.iter())))?;

    watch::estimate(
        &Estimate {
            name: "radiosity",
            units: machine_units(&cfg),
            work: receiver_draws(patches.len(), plan.shots, args, methods.len()),
            work_is: "receiver draws at most (patches x shots x methods x tiles per view)",
            large: watch::large::RECEIVER_DRAWS,
        },
        watch.host_limit(),
    );

    let options = options_json(args, &plan, &scene, &cfg);
    let stamp = format!(
        "pxpl5 {} radiosity; options {}",
        env!("CARGO_PKG_VERSION"),
        options
    );
    // One method's run and the picture of its solution.
    let compute = |method: Method, traces: &mut TraceDests| -> Result<Computed, Failure> {
        let (run, host) = run_method(&watch, &cfg, &patches, args, &plan, method, traces)?;
        let picture = match &scene.camera {
            // Drawn after a first Ctrl-C too, from the shots taken: the polygon program has no
            // point to stop at early, so only a second Ctrl-C stops it.
            Some(camera) => {
                let name = format!("radiosity (picture, {})", method.name());
                let sim = Sim {
                    name: &name,
                    shots: None,
                    interrupt: Stop::Soon,
                };
                let options = RunOptions {
                    max_time: args.time_limit,
                    ..RunOptions::default()
                };
                let (picture, _) = watch.simulate(
                    &sim,
                    options,
                    |options| {
                        picture::render(&cfg, &patches, &run.solution, camera.clone(), options)
                    },
                    |r| r.stats.end,
                )?;
                Some(png_bytes(&picture.frame, Some(&stamp))?)
            }
            None => None,
        };
        Ok(Computed { run, host, picture })
    };
    let computed = if at_once(args, &cfg, methods.len()) {
        // Each method on a host thread of its own: the runs share nothing, so the results are
        // those of runs in turn. The first failure in method order is the one reported.
        let span = tracing::Span::current();
        std::thread::scope(|scope| {
            let runs: Vec<_> = methods
                .iter()
                .zip(&mut traces)
                .map(|(&method, traces)| {
                    let (span, compute) = (span.clone(), &compute);
                    scope.spawn(move || span.in_scope(|| compute(method, traces)))
                })
                .collect();
            runs.into_iter()
                .map(|run| {
                    run.join()
                        .unwrap_or_else(|panic| std::panic::resume_unwind(panic))
                })
                .collect::<Result<Vec<_>, _>>()
        })?
    } else {
        // In turn; after a Ctrl-C, no other method starts.
        let mut computed = Vec::new();
        for (&method, traces) in methods.iter().zip(&mut traces) {
            if watch::interrupts() > 0 {
                break;
            }
            computed.push(compute(method, traces)?);
        }
        computed
    };
    if computed.is_empty() {
        return Err(Failure::Interrupted(
            "radiosity: interrupted before the first shot; nothing written".into(),
        ));
    }
    let (mut runs, mut host_seconds, mut pictures) = (Vec::new(), Vec::new(), Vec::new());
    for c in computed {
        runs.push(c.run);
        host_seconds.push(c.host);
        pictures.push(c.picture);
    }
    // Whether the results fall short of those asked: a run stopped between shots, or a method
    // not run. An interrupt after the last shot leaves them complete.
    let partial = runs.iter().any(MethodRun::partial) || runs.len() < methods.len();
    let comparison = Comparison::new(
        &cfg,
        &scene.name,
        (patches.len(), args.patch_size),
        (args.resolution, plan.shooters_at_once),
        &runs,
    );
    let mut contents = vec![
        format!("# {stamp}\n{}", comparison_csv(&comparison)).into_bytes(),
        (serde_json::to_string_pretty(&comparison_json(&comparison, &options, partial))
            .map_err(UserError::from)?
            + "\n")
            .into_bytes(),
        pxpl5_config::show(&cfg).into_bytes(),
    ];
    for (run, picture) in runs.iter().zip(pictures) {
        let mut pcsv = format!("# {stamp}\npatch,surface,area,r,g,b\n");
        for (i, (p, b)) in patches.iter().zip(&run.solution.radiosity).enumerate() {
            pcsv += &format!(
                "{i},{},{:.6},{:.6},{:.6},{:.6}\n",
                p.surface, p.area, b[0], b[1], b[2]
            );
        }
        contents.push(pcsv.into_bytes());
        if let Some(c) = &run.convergence {
            let mut ccsv =
                format!("# {stamp}\nbatch,shots,simulated_s,worst_surface_error,unshot_fraction\n");
            for (k, p) in c.curve.iter().enumerate() {
                ccsv += &format!(
                    "{k},{},{:.9},{:.6},{:.6e}\n",
                    p.shots, p.seconds, p.error, p.unshot
                );
            }
            contents.push(ccsv.into_bytes());
        }
        contents.extend(picture);
    }

    // Then write it all (the files of methods a Ctrl-C skipped are not among them).
    let written = names[..contents.len()].join(", ");
    let mut writes: Vec<_> = files.into_iter().zip(contents).collect();
    let mut spools = Vec::new();
    for (run, traces) in runs.iter_mut().zip(&mut traces) {
        for (shot, views) in &run.item_buffers {
            for b in views {
                let name = format!("items-{}-shot{shot}-{}.png", run.method.name(), b.view);
                let dest = output::dest("--out", &args.out.join(name), false)?;
                writes.push((dest, png_bytes(&picture::item_buffer_picture(b), None)?));
            }
        }
        spools.extend(traces.files(&mut run.recorder)?);
    }
    output::write_all(&writes, spools)?;

    out!("{}", table(&comparison, &host_seconds, plan.shots))?;
    outln!("wrote {}/{written}", args.out.display())?;
    if watch::interrupts() == 0 {
        return Ok(());
    }
    let done: Vec<String> = comparison
        .methods
        .iter()
        .map(|m| format!("{} {} of {} shots", m.method.name(), m.shots, plan.shots))
        .collect();
    let skipped: Vec<&str> = methods[runs.len()..].iter().map(|m| m.name()).collect();
    let mut message = format!("radiosity: interrupted after {}", done.join(", "));
    if !skipped.is_empty() {
        message += &format!(" ({} not run)", skipped.join(", "));
    }
    message += &if partial {
        format!(
            "; wrote what was computed to {}, marked partial",
            args.out.display()
        )
    } else {
        format!(
            "; the results were complete, written to {}",
            args.out.display()
        )
    };
    Err(Failure::Interrupted(message))
}

/// The options a run resolved to, with the scene, the machine config's name and hash and the
/// simulator's version: what every output records.
fn options_json(
    args: &RadiosityArgs,
    plan: &Plan,
    scene: &RadiosityScene,
    cfg: &pxpl5_config::MachineConfig,
) -> serde_json::Value {
    use clap::ValueEnum;
    let name = |v: Option<clap::builder::PossibleValue>| {
        v.map_or(String::new(), |v| v.get_name().to_string())
    };
    serde_json::json!({
        "version": env!("CARGO_PKG_VERSION"),
        "config": cfg.name,
        "config_hash": pxpl5_config::config_hash(cfg),
        "scene": scene.name,
        "scene_file": args.scene.as_ref().map(|p| p.display().to_string()),
        "method": name(args.method.to_possible_value()),
        "patch_size": args.patch_size,
        "resolution": args.resolution,
        "shots": plan.shots,
        "until_error": plan.until_error,
        "threshold": args.threshold,
        "shooters_at_once": plan.shooters_at_once,
        "edge_rule": name(args.edge_rule.to_possible_value()),
        "delta": name(args.delta.to_possible_value()),
        "all_faces": args.all_faces,
        "rotation_seed": (!args.no_rotation).then_some(args.rotation_seed),
        "depth": name(args.depth.to_possible_value()),
        "fidelity": name(args.fidelity.to_possible_value()),
        "ring_level": name(args.ring_level.to_possible_value()),
    })
}

/// The share of the run's time that `resource` held the critical path.
pub(crate) fn critical_share(stats: &RunStats, resource: Resource) -> f64 {
    let held = stats
        .critical_resources()
        .iter()
        .find(|(r, _)| *r == resource)
        .map_or(0, |(_, t)| t.0);
    held as f64 / stats.end.0.max(1) as f64
}

/// A percentage with enough digits to compare two methods.
fn pct(x: f64) -> String {
    format!("{:.2} %", 100.0 * x)
}

/// The comparison as the table printed on stdout, with each run's host seconds; a run that a
/// Ctrl-C ended early says after how many of the `asked` shots.
fn table(c: &Comparison, host_seconds: &[f64], asked: usize) -> String {
    let m0 = &c.methods[0];
    let mut t = format!(
        "Progressive radiosity on {} ({}): {} GPs, {} Renderers, {} ring channels\n\
         scene {}: {} patches of <= {} units; resolution {}; {} shooter{} per batch; every method \
         on the same machine with the same view scheduler\n",
        c.config,
        c.config_hash,
        m0.gps,
        m0.boards,
        m0.ring_channels,
        c.scene,
        c.patches,
        c.patch_size,
        c.resolution,
        c.shooters_at_once,
        if c.shooters_at_once == 1 { "" } else { "s" },
    );
    match m0.convergence.as_ref() {
        Some(conv) if conv.target > 0.0 => {
            t += &format!(
                "accuracy: against the direct solve with exact form factors on the same mesh; \
                 the run stops once every surface is within {}\n",
                pct(conv.target)
            )
        }
        Some(_) => {
            t += "accuracy: against the direct solve with exact form factors on the same mesh\n"
        }
        None => {
            t += "accuracy: not measured (the scene can hide surfaces from others, so there is \
                  no exact reference)\n"
        }
    }
    if m0.stats.approximate() {
        t += &format!(
            "simulated at fidelity {}: the time error of these levels is measured by `pxpl5 \
             tradeoff`\n",
            m0.stats.levels()
        );
    }
    for m in c.methods.iter().filter(|m| m.partial) {
        t += &format!(
            "{}: interrupted after {} of {asked} shots: partial results\n",
            m.method.name(),
            m.shots
        );
    }
    t += "\n";
    let w = 14;
    let row = |label: &str, cells: Vec<String>| -> String {
        let mut line = format!("  {label:<34}");
        for cell in cells {
            line += &format!("{cell:>w$}");
        }
        line + "\n"
    };
    let each = |f: &dyn Fn(&pxpl5_radiosity::comparison::MethodSummary) -> String| {
        c.methods.iter().map(f).collect::<Vec<_>>()
    };
    t += &row("", each(&|m| m.method.name().to_string()));
    t += &row("shots taken", each(&|m| m.shots.to_string()));
    t += &row(
        "time per shot (ms)",
        each(&|m| format!("{:.3}", m.per_shot_s * 1e3)),
    );
    if m0.convergence.as_ref().is_some_and(|c| c.target > 0.0) {
        t += &row(
            "time to target (ms)",
            each(
                &|m| match m.convergence.as_ref().and_then(|c| c.time_to_target) {
                    Some((s, _)) => format!("{:.1}", s * 1e3),
                    None => "not reached".to_string(),
                },
            ),
        );
        t += &row(
            "shots to target",
            each(
                &|m| match m.convergence.as_ref().and_then(|c| c.time_to_target) {
                    Some((_, n)) => n.to_string(),
                    None => "-".to_string(),
                },
            ),
        );
        // What a user without a reference can watch: the unshot power left when the error
        // reached the target (`--threshold` compares the largest patch's with it).
        t += &row(
            "unshot power left at target",
            each(&|m| {
                let reached = m.convergence.as_ref().and_then(|c| {
                    let (_, n) = c.time_to_target?;
                    c.curve.iter().find(|p| p.shots == n)
                });
                reached.map_or("-".to_string(), |p| pct(p.unshot))
            }),
        );
    }
    if m0.convergence.is_some() {
        t += &row(
            "worst surface error at end",
            each(&|m| {
                m.convergence
                    .as_ref()
                    .and_then(|c| c.last.as_ref())
                    .map_or("-".to_string(), |e| pct(e.worst))
            }),
        );
        t += &row(
            "form-factor error (mean L1 / shot)",
            each(&|m| {
                m.convergence
                    .as_ref()
                    .map_or("-".to_string(), |c| pct(c.form_factor_error))
            }),
        );
    }
    t += &row(
        "Renderer board-ms per shot",
        each(&|m| format!("{:.3}", m.renderer_busy_s * 1e3 / m.shots.max(1) as f64)),
    );
    t += &row(
        "GP-ms per shot (all GPs)",
        each(&|m| format!("{:.3}", m.gp_busy_s * 1e3 / m.shots.max(1) as f64)),
    );
    t += &row(
        "ring words per shot",
        each(&|m| format!("{}", m.ring_payload_words / m.shots.max(1) as u64)),
    );
    t += &row(
        "Renderer utilisation",
        each(&|m| pct(m.renderer_utilisation)),
    );
    for resource in [Resource::Gp, Resource::Ring, Resource::Renderer] {
        t += &row(
            &format!("critical path: {}", resource.name()),
            each(&|m| pct(critical_share(&m.stats, resource))),
        );
    }
    t += &row(
        "seed's estimate per shot (ms)",
        each(&|m| format!("{:.3}", m.seed.as_written * 1e3 / m.shots.max(1) as f64)),
    );
    t += &row(
        "host seconds",
        host_seconds.iter().map(|h| format!("{h:.2}")).collect(),
    );
    t += "\n";
    for m in &c.methods {
        t += &format!("{}: phases (mean GP time per shot, ms):", m.method.name());
        for (k, v) in &m.phases {
            t += &format!(" {k} {:.3};", v * 1e3 / m.shots.max(1) as f64);
        }
        t += &format!(
            "\n  reciprocity clamps {}, culled: {:?}\n",
            m.reciprocity_clamps, m.culls
        );
    }
    if let Some(ratio) = c.hemicube_over_hemisphere() {
        t += &format!(
            "\nhemicube / hemisphere, time per shot: {ratio:.2} (the seed's claim: {SEED_RATIO})"
        );
        if let Some(r) = c.hemicube_over_hemisphere_to_target() {
            t += &format!("; time to target: {r:.2}");
        }
        t += "\n";
    }
    t += "\n";
    for m in &c.methods {
        t += &format!("{} bottleneck: {}\n", m.method.name(), m.bottleneck);
    }
    if let Some(k) = &c.seed_check {
        t += &format!(
            "\nthe seed's assumptions, against what the machine did:\n\
             - 5 broadcasts of every patch for the hemicube, 1 for the hemisphere: the hemicube drew \
             {:.2} x the hemisphere's receivers per shot (a receiver goes only to the faces it may \
             touch)\n\
             - one 128 x 128 readback per run: every shot reads back its views, {} pixels per \
             hemisphere shot and {} per hemicube shot\n\
             - 1 us of Renderer time per polygon (10^6 per second), a hemisphere edge as cheap as a \
             hemicube edge: {:.1} us per hemisphere receiver, {:.1} us per hemicube receiver\n",
            k.drawn_ratio,
            k.readback_pixels_per_shot.0,
            k.readback_pixels_per_shot.1,
            k.renderer_us_per_receiver.0,
            k.renderer_us_per_receiver.1,
        );
    }
    t
}

/// The comparison as `comparison.csv`: a row per method.
fn comparison_csv(c: &Comparison) -> String {
    let mut csv = String::from(
        "method,shots,patches,shooters_at_once,simulated_s,per_shot_s,time_to_target_s,\
         shots_to_target,target_error,final_error,form_factor_error,renderer_busy_s,gp_busy_s,\
         ring_payload_words,renderer_utilisation,bottleneck,seed_estimate_s,\
         seed_estimate_readback_x_n_s,reciprocity_clamps,partial\n",
    );
    let opt = |x: Option<f64>| x.map_or(String::new(), |x| format!("{x:.9}"));
    for m in &c.methods {
        let conv = m.convergence.as_ref();
        let to = conv.and_then(|c| c.time_to_target);
        csv += &format!(
            "{},{},{},{},{:.9},{:.9},{},{},{},{},{},{:.9},{:.9},{},{:.4},\"{}\",{:.9},{:.9},{},{}\n",
            m.method.name(),
            m.shots,
            c.patches,
            c.shooters_at_once,
            m.simulated_s,
            m.per_shot_s,
            opt(to.map(|t| t.0)),
            to.map_or(String::new(), |t| t.1.to_string()),
            opt(conv.map(|c| c.target)),
            opt(conv.and_then(|c| c.last.as_ref()).map(|e| e.worst)),
            opt(conv.map(|c| c.form_factor_error)),
            m.renderer_busy_s,
            m.gp_busy_s,
            m.ring_payload_words,
            m.renderer_utilisation,
            // Quoted: the bottleneck's text holds commas (RFC 4180; it holds no quote).
            m.bottleneck,
            m.seed.as_written,
            m.seed.readback_x_n,
            m.reciprocity_clamps,
            m.partial
        );
    }
    csv
}

/// The comparison as `comparison.json`, with the options and each run's full simulated stats.
/// `partial` when the results fall short of those asked (a Ctrl-C: a run ended between shots,
/// each such run marked `partial` too, or a method not run).
fn comparison_json(
    c: &Comparison,
    options: &serde_json::Value,
    partial: bool,
) -> serde_json::Value {
    let methods: Vec<_> = c
        .methods
        .iter()
        .map(|m| {
            let conv = m.convergence.as_ref().map(|c| {
                serde_json::json!({
                    "target_error": c.target,
                    "time_to_target_s": c.time_to_target.map(|t| t.0),
                    "shots_to_target": c.time_to_target.map(|t| t.1),
                    "final_error": c.last.as_ref().map(|e| e.worst),
                    "final_error_surface": c.last.as_ref().map(|e| e.surface.clone()),
                    "form_factor_error": c.form_factor_error,
                })
            });
            serde_json::json!({
                "method": m.method.name(),
                "shots": m.shots,
                "partial": m.partial,
                "simulated_s": m.simulated_s,
                "per_shot_s": m.per_shot_s,
                "accuracy": conv,
                "renderer_busy_s": m.renderer_busy_s,
                "gp_busy_s": m.gp_busy_s,
                "ring_payload_words": m.ring_payload_words,
                "renderer_utilisation": m.renderer_utilisation,
                "phases_mean_gp_s": m.phases,
                "bottleneck": m.bottleneck,
                "seed_estimate_s": m.seed.as_written,
                "seed_estimate_readback_x_n_s": m.seed.readback_x_n,
                "reciprocity_clamps": m.reciprocity_clamps,
                "stats": m.stats.to_json(),
            })
        })
        .collect();
    let seed_check = c.seed_check.as_ref().map(|k| {
        serde_json::json!({
            "drawn_receivers_hemicube_over_hemisphere": k.drawn_ratio,
            "readback_pixels_per_shot": {
                "hemisphere": k.readback_pixels_per_shot.0,
                "hemicube": k.readback_pixels_per_shot.1,
            },
            "renderer_us_per_receiver": {
                "hemisphere": k.renderer_us_per_receiver.0,
                "hemicube": k.renderer_us_per_receiver.1,
            },
        })
    });
    serde_json::json!({
        "options": options,
        "partial": partial,
        "seed_assumptions": seed_check,
        "config": c.config,
        "config_hash": c.config_hash,
        "scene": c.scene,
        "patches": c.patches,
        "methods": methods,
    })
}

/// The largest `formfactor --resolution`: 2^12, the pixel addresses of the default QEE
/// (`renderer.qee.coordinate_bits`). It also bounds the host's table of a view's delta form
/// factors, N x N f64 values, at 128 MiB.
const MAX_RESOLUTION: i64 = 4096;

/// Options of `pxpl5 formfactor`.
///
/// Numbers are printed as the shortest decimal that reads back as the same f64 ([`number`]).
/// The absolute error is (method - exact), the relative error (method - exact) / exact, undefined
/// when the exact value is 0.
#[derive(Args, Clone, Debug)]
#[command(
    after_help = "Numbers are printed as the shortest decimal that reads back as the same \
    f64: positional from 1e-4 to 1e6 (0.5541264239795721), scientific outside (-9.4e-6). The \
    absolute error is (method - exact); the relative error is (method - exact) / exact, \
    undefined when the exact value is 0. Exit code 2 names the option (and the vertex) at fault."
)]
pub struct FormFactorArgs {
    /// The receiving point, X,Y,Z.
    #[arg(long, allow_hyphen_values = true)]
    pub point: String,
    /// Its normal, X,Y,Z: only its direction is used, so any length from f64::MIN_POSITIVE
    /// (about 2.2e-308) up will do; zero and shorter (subnormal) vectors are refused.
    #[arg(long, allow_hyphen_values = true)]
    pub normal: String,
    /// The polygon's vertices, "X,Y,Z;X,Y,Z;..." (3 or more, planar and convex, in either
    /// order; messages number them from 0). Checked as the radiosity scene files are: within
    /// 1e-6 x its size of a plane, no repeated, collinear or reflex corner, edges not crossing.
    #[arg(long, allow_hyphen_values = true)]
    pub polygon: String,
    /// exact (the contour formula), hemisphere or hemicube (on the simulated machine).
    #[arg(long, value_enum, default_value_t = FormFactorMethod::Exact)]
    pub method: FormFactorMethod,
    /// Pixels across the disk or the hemicube's top face, 1 to 4096; the machine limits it
    /// further (a disk larger than a Renderer is cut into tiles of 128 x 128, drawn in turn, each
    /// within the QEE's pixel addresses; a hemicube face must fit one Renderer, and N must be
    /// even).
    #[arg(long, default_value_t = 128,
          value_parser = clap::value_parser!(u32).range(1..=MAX_RESOLUTION))]
    pub resolution: u32,
    /// Machine config (RON); default: the embedded seed machine.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Print one JSON object instead of text: method, form_factor, exact, absolute_error,
    /// relative_error (both null for the exact method; relative_error null when the exact value
    /// is 0), simulated (the machine's figures: config, time, cycles, ring words, full stats;
    /// null for the exact method) and options (as given, with the unit normal used).
    #[arg(long)]
    pub json: bool,
    /// Stop with an error (exit code 1) if the machine's run passes this much simulated time.
    #[arg(long, value_name = "TIME", default_value = "10s",
          value_parser = watch::parse_time_limit)]
    pub time_limit: Tick,
    /// Stop with an error (exit code 1) once the command has taken this much host time (ms, s,
    /// min or h; `none`: no limit).
    #[arg(long, value_name = "TIME", default_value = watch::DEFAULT_HOST_LIMIT,
          value_parser = watch::parse_host_limit)]
    pub host_time_limit: HostLimit,
}

/// `x` as the shortest decimal that reads back as the same f64 (Rust's `{}` and `{:e}` both
/// give those digits): in positional notation for 0 and for 1e-4 <= |x| < 1e6, where it is at
/// most a few zeros long (0.5541264, 0.00012), and in scientific notation otherwise (1.25e-7,
/// 3.5e6), where positional notation would make the reader count zeros (1e-300 has 300).
pub fn number(x: f64) -> String {
    if x == 0.0 || !x.is_finite() || (1e-4..1e6).contains(&x.abs()) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

/// A finite number > 0, for clap.
pub fn positive_finite(s: &str) -> Result<f64, String> {
    let x = finite(s)?;
    if x > 0.0 {
        Ok(x)
    } else {
        Err(format!("`{s}` must be > 0"))
    }
}

/// A finite number >= 0, for clap.
pub fn non_negative_finite(s: &str) -> Result<f64, String> {
    let x = finite(s)?;
    if x >= 0.0 {
        Ok(x)
    } else {
        Err(format!("`{s}` must be >= 0"))
    }
}

fn finite(s: &str) -> Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(x) if x.is_finite() => Ok(x),
        _ => Err(format!("`{s}` is not a finite number")),
    }
}

pub(crate) fn parse_v3(what: &str, s: &str) -> Result<DVec3, UserError> {
    let parts: Vec<&str> = s.split(',').map(str::trim).collect();
    let bad = || UserError(format!("{what}: `{s}` is not three finite numbers X,Y,Z"));
    if parts.len() != 3 {
        return Err(bad());
    }
    let mut v = [0.0; 3];
    for (k, p) in parts.iter().enumerate() {
        v[k] = p.parse::<f64>().map_err(|_| bad())?;
        if !v[k].is_finite() {
            return Err(bad());
        }
    }
    Ok(DVec3::from_array(v))
}

/// The unit normal of `--normal` (`text` as given), or why it has no usable direction.
fn unit_normal(text: &str, normal: DVec3) -> Result<DVec3, UserError> {
    if normal == DVec3::ZERO {
        return Err(UserError(
            "--normal: must not be zero (only its direction is used, and zero has none)".into(),
        ));
    }
    pxpl5_radiosity::exact::unit_normal(normal).ok_or_else(|| {
        UserError(format!(
            "--normal: `{text}` is too short: its length must be at least f64::MIN_POSITIVE \
             ({:e}); a shorter vector is made of subnormal numbers, whose direction is not known \
             to f64 precision (only the direction is used: scale it up)",
            f64::MIN_POSITIVE
        ))
    })
}

/// Every problem of `--polygon` as a planar convex polygon, a line each naming the vertex (as
/// the user wrote it, `texts[k]`) where there is one; empty when it is fine.
///
/// The check runs on the polygon divided by a power of two ([`polygon::power_of_two_scale`]),
/// which gives the same verdict without overflowing for huge or tiny coordinates; distances are
/// reported in the user's units.
fn polygon_problems(texts: &[&str], v: &[DVec3]) -> Vec<String> {
    let s = polygon::power_of_two_scale(v);
    let scaled: Vec<DVec3> = v.iter().map(|&p| p / s).collect();
    let n = v.len();
    let at = |k: usize| format!("--polygon vertex {k} `{}`", texts[k].trim());
    let corner = |c: Corner| match c {
        Corner::Repeat(k) => format!(
            "{}: repeats vertex {k} (consecutive vertices must be more than {:e} x the \
             polygon's size apart)",
            at((k + 1) % n),
            polygon::ZERO_AREA
        ),
        Corner::Straight(k) => format!(
            "{}: is collinear with vertices {} and {}: remove it (a straight corner has no \
             defined turn)",
            at(k),
            (k + n - 1) % n,
            (k + 1) % n
        ),
        Corner::Reflex(k) => format!(
            "{}: makes the polygon non-convex (its corner turns against the others, or folds \
             back)",
            at(k)
        ),
    };
    let mut out = Vec::new();
    for problem in polygon::problems(&scaled) {
        match problem {
            // Excluded by the parser: 3 or more finite vertices.
            Problem::NotAPolygon => out.push("--polygon: needs 3 or more finite vertices".into()),
            Problem::ZeroArea => {
                out.push(
                    "--polygon: has zero area (coincident or collinear vertices, or edges that \
                     cross so that its parts cancel, as a bow-tie's do)"
                        .into(),
                );
                out.extend(polygon::zero_area_corners(&scaled).into_iter().map(corner));
            }
            Problem::NotPlanar {
                vertex,
                distance,
                limit,
            } => out.push(format!(
                "{}: is {} from the polygon's best-fit plane, more than {:e} x its size ({}): \
                 the polygon must be planar",
                at(vertex),
                number(distance * s),
                polygon::PLANARITY_TOLERANCE,
                number(limit * s)
            )),
            Problem::Corner(c) => out.push(corner(c)),
            Problem::Crossed { turns } => out.push(format!(
                "--polygon: is not convex: its edges cross (the outline winds around {turns:.1} \
                 times, not once)"
            )),
        }
    }
    out
}

/// What `pxpl5 formfactor` found: the exact value and, for a method on the machine, its value
/// and run.
struct FormFactorReport<'a> {
    exact: f64,
    machine: Option<Measured<'a>>,
}

/// A form factor measured on the machine.
struct Measured<'a> {
    method: Method,
    value: f64,
    stats: &'a RunStats,
    config: &'a str,
}

impl Measured<'_> {
    /// (value - exact, that over exact), the ratio `None` when exact is 0.
    fn errors(&self, exact: f64) -> (f64, Option<f64>) {
        let absolute = self.value - exact;
        (absolute, (exact != 0.0).then(|| absolute / exact))
    }

    fn renderer_busy(&self) -> u64 {
        self.stats.renderers.iter().map(|r| r.busy.0).sum()
    }
}

impl FormFactorReport<'_> {
    fn text(&self) -> String {
        let Some(m) = &self.machine else {
            return format!("exact form factor: {}\n", number(self.exact));
        };
        let name = m.method.name();
        let (absolute, relative) = m.errors(self.exact);
        let relative = relative.map_or("undefined (exact value 0)".to_string(), |r| {
            format!("{} (absolute error / exact)", number(r))
        });
        format!(
            "{name} form factor: {}\nexact form factor: {}\nabsolute error: {} ({name} - exact)\n\
             relative error: {relative}\n\
             simulated: {} us on {} ({}); Renderer busy {} cycles (all boards); GP 0 busy {} \
             cycles; ring {} payload words\n",
            number(m.value),
            number(self.exact),
            number(absolute),
            number(m.stats.end.0 as f64 / 1e6),
            m.config,
            m.stats.config_hash,
            m.renderer_busy(),
            m.stats.gps[0].busy.0,
            m.stats.ring.total.payload_words
        )
    }

    fn json(&self, args: &FormFactorArgs, given: &Given) -> serde_json::Value {
        let v3 = |v: DVec3| serde_json::json!(v.to_array());
        let errors = self.machine.as_ref().map(|m| m.errors(self.exact));
        let simulated = self.machine.as_ref().map(|m| {
            serde_json::json!({
                "config": m.config,
                "config_hash": m.stats.config_hash,
                "time_ps": m.stats.end.0,
                "time_s": m.stats.end.as_secs_f64(),
                "renderer_busy_cycles": m.renderer_busy(),
                "gp0_busy_cycles": m.stats.gps[0].busy.0,
                "ring_payload_words": m.stats.ring.total.payload_words,
                "stats": m.stats.to_json(),
            })
        });
        serde_json::json!({
            "method": method_name(args.method),
            "form_factor": self.machine.as_ref().map_or(self.exact, |m| m.value),
            "exact": self.exact,
            "absolute_error": errors.map(|e| e.0),
            "relative_error": errors.and_then(|e| e.1),
            "simulated": simulated,
            "options": {
                "point": v3(given.point),
                "normal": v3(given.normal),
                "unit_normal": v3(given.unit_normal),
                "polygon": given.polygon.iter().map(|&v| v3(v)).collect::<Vec<_>>(),
                "method": method_name(args.method),
                "resolution": args.resolution,
                "config": args.config.as_ref().map(|p| p.display().to_string()),
            },
        })
    }
}

/// `--method`'s name as the user types it.
fn method_name(m: FormFactorMethod) -> &'static str {
    m.on_machine().map_or("exact", Method::name)
}

/// The inputs of `pxpl5 formfactor`, parsed and checked.
pub(crate) struct Given {
    pub(crate) point: DVec3,
    pub(crate) normal: DVec3,
    pub(crate) unit_normal: DVec3,
    pub(crate) polygon: Vec<DVec3>,
}

/// Parse and check `--point`, `--normal` and `--polygon`.
pub(crate) fn given(args: &FormFactorArgs) -> Result<Given, UserError> {
    let point = parse_v3("--point", &args.point)?;
    let normal = parse_v3("--normal", &args.normal)?;
    let unit_normal = unit_normal(&args.normal, normal)?;
    let texts: Vec<&str> = args
        .polygon
        .split(';')
        .filter(|s| !s.trim().is_empty())
        .collect();
    let polygon: Vec<DVec3> = texts
        .iter()
        .enumerate()
        .map(|(i, s)| parse_v3(&format!("--polygon vertex {i}"), s))
        .collect::<Result<_, _>>()?;
    if polygon.len() < 3 {
        return Err(UserError(format!(
            "--polygon: needs at least 3 vertices (got {})",
            polygon.len()
        )));
    }
    let problems = polygon_problems(&texts, &polygon);
    if !problems.is_empty() {
        return Err(UserError(problems.join("\n")));
    }
    Ok(Given {
        point,
        normal,
        unit_normal,
        polygon,
    })
}

pub fn formfactor(args: &FormFactorArgs) -> Result<(), Failure> {
    let watch = Watch::new(args.host_time_limit.clone());
    let given = given(args)?;
    let exact = pxpl5_radiosity::exact::point_to_polygon(given.point, given.normal, &given.polygon);
    let measured = match args.method.on_machine() {
        None => None,
        Some(method) => {
            let cfg = config_cmd::load(args.config.as_deref())?;
            check_resolution(method, args.resolution, &cfg.renderer)
                .map_err(|e| UserError(format!("--resolution {}: {e}", args.resolution)))?;
            let options = FfOptions {
                method,
                resolution: args.resolution,
                ..FfOptions::default()
            };
            let name = format!("formfactor ({})", method.name());
            watch::estimate(
                &Estimate {
                    name: &name,
                    units: machine_units(&cfg),
                    work: 1,
                    work_is: "polygon",
                    large: 1,
                },
                watch.host_limit(),
            );
            let sim = Sim {
                name: &name,
                shots: None,
                interrupt: Stop::Now,
            };
            let run = RunOptions {
                max_time: args.time_limit,
                ..RunOptions::default()
            };
            let (measured, _) = watch.simulate(
                &sim,
                run,
                |run| {
                    experiment::form_factor(
                        &cfg,
                        given.point,
                        given.unit_normal,
                        given.polygon.clone(),
                        options,
                        run,
                    )
                },
                |r| r.stats.end,
            )?;
            Some((measured, method, cfg))
        }
    };
    let report = FormFactorReport {
        exact,
        machine: measured.as_ref().map(|(m, method, cfg)| Measured {
            method: *method,
            value: m.form_factor,
            stats: &m.stats,
            config: &cfg.name,
        }),
    };
    if args.json {
        let json =
            serde_json::to_string_pretty(&report.json(args, &given)).map_err(UserError::from)?;
        outln!("{json}")?;
    } else {
        out!("{}", report.text())?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Numbers read back as the same f64, in positional notation from 1e-4 to 1e6.
    #[test]
    fn numbers_are_shortest_round_trips() {
        assert_eq!(number(0.0), "0");
        assert_eq!(number(-0.0), "-0");
        assert_eq!(number(0.5541264239795721), "0.5541264239795721");
        assert_eq!(number(0.5), "0.5");
        assert_eq!(number(1e-4), "0.0001");
        assert_eq!(number(9.99e-5), "9.99e-5");
        assert_eq!(number(-1.25e-7), "-1.25e-7");
        assert_eq!(number(123456.5), "123456.5");
        assert_eq!(number(1e6), "1e6");
        assert_eq!(number(1e-300), "1e-300");
        assert_eq!(number(f64::NAN), "NaN");
        let mut rng = pxpl5_geom::rng::Lcg::new(8);
        let mut values = vec![
            f64::MIN_POSITIVE,
            5e-324,
            f64::MAX,
            0.1 + 0.2,
            1.0 / 3.0,
            -2.0f64.sqrt() * 1e-9,
        ];
        for _ in 0..1000 {
            values.push(rng.range(-1.0, 1.0) * 10f64.powf(rng.range(-320.0, 308.0)));
        }
        for x in values {
            let shown = number(x);
            assert_eq!(shown.parse::<f64>().unwrap(), x, "{shown}");
            // Not one digit more than Rust's shortest form.
            let digits = |s: &str| {
                let mantissa = s.split('e').next().unwrap_or("");
                mantissa
                    .chars()
                    .filter(char::is_ascii_digit)
                    .collect::<String>()
                    .trim_matches('0')
                    .len()
            };
            assert_eq!(digits(&shown), digits(&format!("{x:e}")), "{shown}");
        }
    }

    /// `pxpl5 radiosity` with no flags runs the library's default form-factor options and
    /// machine-run options; its shots, target and batching are the command's experiment policy,
    /// resolved from the machine and the scene (`Plan`).
    #[test]
    fn the_defaults_are_the_librarys() {
        let args = RadiosityArgs::defaults();
        let cfg = pxpl5_config::default_config();
        let scene = pxpl5_radiosity::scenes::cornell_empty();
        let patches = mesh(&scene, args.patch_size).unwrap();
        let Ok(plan) = Plan::new(&args, &cfg, &scene, &patches) else {
            panic!("the defaults plan")
        };
        let (ours, lib) = (
            args.settings(Method::Hemisphere, &plan),
            Settings::default(),
        );
        assert_eq!(ours.ff.method, lib.ff.method);
        assert_eq!(ours.ff.resolution, lib.ff.resolution);
        assert_eq!(ours.ff.edge_rule, lib.ff.edge_rule);
        assert_eq!(ours.ff.depth, lib.ff.depth);
        assert_eq!(ours.ff.exact_delta, lib.ff.exact_delta);
        assert_eq!(ours.ff.skip_faces, lib.ff.skip_faces);
        assert_eq!(ours.ff.rotation, lib.ff.rotation);
        assert_eq!(ours.threshold, lib.threshold);
        assert_eq!(ours.item_shots, lib.item_shots);
        assert_eq!(ours.run.fidelity, lib.run.fidelity);
        assert_eq!(ours.run.max_time, lib.run.max_time);
        // The policy: every Renderer gets a shooter; stop at 1 %, capped at 10 shots per patch.
        assert_eq!(ours.shooters_at_once, cfg.renderer.count as usize);
        assert_eq!(ours.target_error, Some(0.01));
        assert_eq!(ours.shots, 10 * patches.len());
        assert!(ours.reference.is_some());
        // A scene with occluders has no reference: 6 shots, no target; asking for one is refused.
        let full = pxpl5_radiosity::scenes::cornell_box();
        let full_patches = mesh(&full, args.patch_size).unwrap();
        let Ok(plan) = Plan::new(&args, &cfg, &full, &full_patches) else {
            panic!("the defaults plan for the Cornell box")
        };
        assert_eq!((plan.shots, plan.until_error), (6, None));
        let asked = RadiosityArgs {
            until_error: Some(0.05),
            ..RadiosityArgs::defaults()
        };
        let e = Plan::new(&asked, &cfg, &full, &full_patches).err().unwrap();
        assert!(e.0.contains("no exact reference"), "{}", e.0);
    }
}
