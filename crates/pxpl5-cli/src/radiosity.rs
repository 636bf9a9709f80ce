//! `pxpl5 radiosity` (progressive radiosity with hemisphere and/or hemicube form factors on the
//! machine, measured and set beside the seed's estimate) and `pxpl5 formfactor` (one point to
//! one polygon, exactly or on the machine).
//!
//! Only parsing, printing and files live here: the experiment itself (runs, phase analysis, the
//! seed's estimate, the comparison, pictures) is `pxpl5_radiosity`'s, so that another Rust
//! program can run it. The command times each run on the host and prints those figures apart;
//! they never reach a file.

use std::path::{Path, PathBuf};

use clap::Args;
use pxpl5_geom::DVec3;
use pxpl5_geom::convex::Corner;
use pxpl5_geom::polygon::{self, Problem};
use pxpl5_machine::{RunOptions, RunStats};
use pxpl5_radiosity::comparison::{Comparison, SEED_RATIO};
use pxpl5_radiosity::experiment::{self, MethodRun, Settings};
use pxpl5_radiosity::mesh::{Patch, mesh};
use pxpl5_radiosity::picture;
use pxpl5_radiosity::program::MAX_MACHINE_PATCHES;
use pxpl5_radiosity::scene::RadiosityScene;
use pxpl5_radiosity::shot::{FfOptions, Method, check_resolution};

use crate::UserError;
use crate::choices::{Delta, DepthArg, EdgeRuleArg, FidelityArg, FormFactorMethod, Methods};
use crate::config_cmd;
use crate::output::{self, out, outln};
use crate::run::{TraceArgs, png_bytes, timed};

/// Options of `pxpl5 radiosity`.
#[derive(Args, Clone, Debug)]
pub struct RadiosityArgs {
    /// Machine config (RON); default: the embedded seed machine.
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Radiosity scene (RON); default: the Cornell box.
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// Form-factor method.
    #[arg(long, value_enum, default_value_t = Methods::Both)]
    pub method: Methods,
    /// Shots (shooting patches, the seed's N).
    #[arg(long, default_value_t = 6)]
    pub shots: usize,
    /// Stop early when max unshot power / emitted power falls below this (a finite number >= 0).
    #[arg(long, default_value_t = 0.001, value_parser = non_negative_finite)]
    pub threshold: f64,
    /// Patch size in scene units (the Cornell box is in millimetres); the mesh may have at most
    /// 65,534 patches (the machine's 16-bit patch IDs).
    #[arg(long, default_value_t = 90.0, value_parser = positive_finite)]
    pub patch_size: f64,
    /// Pixels across the hemisphere's disk and the hemicube's top face, 1 to 4096; the machine
    /// limits it further (a disk of N pixels needs ceil(N / 128)^2 Renderers of 128 x 128; a
    /// hemicube face must fit one Renderer, and N must be even).
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
    /// Shoot this many patches at once, their views spread over the Renderers (1: classic
    /// progressive refinement).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    pub shooters_at_once: u32,
    /// Hemisphere depth: taylor (the seed's quadratic approximation) or stored-w (w per pixel,
    /// exact, slower).
    #[arg(long, value_enum, default_value_t = DepthArg::Taylor)]
    pub depth: DepthArg,
    /// Output directory.
    #[arg(long, default_value = "out/radiosity")]
    pub out: PathBuf,
    /// Renderer fidelity level.
    #[arg(long, value_enum, default_value_t = FidelityArg::Integer)]
    pub fidelity: FidelityArg,
    #[command(flatten)]
    pub traces: TraceArgs,
    /// Write the item (ID) buffers of these shots (0-based, comma-separated) as PNGs:
    /// DIR/items-METHOD-shotK-VIEW.png, one colour per patch.
    #[arg(long, value_delimiter = ',')]
    pub item_buffers: Vec<usize>,
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

    /// The library's settings for one method's run.
    fn settings(&self, method: Method) -> Settings {
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
            shots: self.shots,
            threshold: self.threshold,
            shooters_at_once: self.shooters_at_once as usize,
            item_shots: self.item_buffers.clone(),
            run: RunOptions {
                fidelity: self.fidelity.into(),
                ..Settings::default().run
            },
        }
    }
}

/// Run `method`; returns the run and its host seconds. Writes nothing.
fn run_method(
    cfg: &pxpl5_config::MachineConfig,
    patches: &[Patch],
    args: &RadiosityArgs,
    method: Method,
) -> Result<(MethodRun, f64), UserError> {
    tracing::info!(
        method = %method.name(),
        patches = patches.len(),
        max_shots = args.shots,
        "form-factor method starts"
    );
    let recorder = args.traces.recorder()?;
    let settings = args.settings(method);
    timed(
        "radiosity",
        settings.run.fidelity,
        || experiment::run(cfg, patches, &settings, recorder),
        |r| r.stats.end,
    )
}

/// The files of the output directory whose names are known before the run.
const FILES: [&str; 5] = [
    "comparison.csv",
    "comparison.json",
    "patches.csv",
    "config.ron",
    "radiosity.png",
];

/// Runs every method, renders the picture, and only then writes every output, all or nothing
/// (`output::write_all`), and prints the report: a failure anywhere leaves the output directory
/// as it was. Every output whose name is known is checked before the first run.
pub fn radiosity(args: &RadiosityArgs) -> Result<(), UserError> {
    let cfg = config_cmd::load(args.config.as_deref())?;
    let scene: RadiosityScene = match &args.scene {
        Some(p) => pxpl5_radiosity::scene::load_radiosity_scene(p).map_err(config_cmd::report)?,
        None => pxpl5_radiosity::scenes::cornell_box(),
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
    for method in args.method.methods() {
        check_resolution(method, args.resolution, cfg.renderer.count, &cfg.renderer)
            .map_err(|e| UserError(format!("--resolution {}: {e}", args.resolution)))?;
    }
    if scene.camera.is_some() {
        // The picture is drawn by the polygon program: refuse a machine it cannot draw on now,
        // not after the radiosity runs.
        pxpl5_polygons::check_machine(
            &cfg.renderer,
            (cfg.frame_buffer.width, cfg.frame_buffer.height),
        )
        .map_err(|e| UserError(format!("the picture of the solution: {e}")))?;
    }

    // Check every destination before the first run.
    output::check_dir("--out", &args.out)?;
    let names = match scene.camera {
        Some(_) => &FILES[..],
        None => &FILES[..4],
    };
    let files = names
        .iter()
        .map(|name| output::dest("--out", &args.out.join(name), false))
        .collect::<Result<Vec<_>, _>>()?;
    args.traces.recorder()?;
    let methods = args.method.methods();
    let several = methods.len() > 1;
    let traces = methods
        .iter()
        .map(|&m| args.traces.dests(|p| per_method(p, m, several), several))
        .collect::<Result<Vec<_>, _>>()?;
    output::distinct(files.iter().chain(traces.iter().flat_map(|t| t.iter())))?;

    // Compute everything.
    let mut runs = Vec::new();
    let mut host_seconds = Vec::new();
    for &method in &methods {
        let (run, host) = run_method(&cfg, &patches, args, method)?;
        runs.push(run);
        host_seconds.push(host);
    }
    let comparison = Comparison::new(
        &cfg,
        &scene.name,
        patches.len(),
        args.patch_size,
        args.resolution,
        &runs,
    );
    let last = runs.last().expect("at least one method");
    let picture = match &scene.camera {
        Some(camera) => {
            let (picture, _) = timed(
                "polygons",
                RunOptions::default().fidelity,
                || picture::render(&cfg, &patches, &last.solution, camera.clone()),
                |r| r.stats.end,
            )?;
            Some(png_bytes(&picture.frame)?)
        }
        None => None,
    };

    // Then write it all.
    let mut pcsv = String::from("patch,surface,area,r,g,b\n");
    for (i, (p, b)) in patches.iter().zip(&last.solution.radiosity).enumerate() {
        pcsv += &format!(
            "{i},{},{:.6},{:.6},{:.6},{:.6}\n",
            p.surface, p.area, b[0], b[1], b[2]
        );
    }
    let json =
        serde_json::to_string_pretty(&comparison_json(&comparison)).map_err(UserError::from)?;
    let mut contents = vec![
        comparison_csv(&comparison).into_bytes(),
        (json + "\n").into_bytes(),
        pcsv.into_bytes(),
        pxpl5_config::show(&cfg).into_bytes(),
    ];
    contents.extend(picture);
    let mut writes: Vec<_> = files.into_iter().zip(contents).collect();
    for (run, traces) in runs.iter().zip(&traces) {
        for (shot, views) in &run.item_buffers {
            for b in views {
                let name = format!("items-{}-shot{shot}-{}.png", run.method.name(), b.view);
                let dest = output::dest("--out", &args.out.join(name), false)?;
                writes.push((dest, png_bytes(&picture::item_buffer_picture(b))?));
            }
        }
        writes.extend(traces.files(&run.recorder)?);
    }
    output::write_all(&writes)?;

    out!("{}", table(&comparison, &host_seconds))?;
    outln!("wrote {}/{}", args.out.display(), names.join(", "))?;
    Ok(())
}

/// The comparison as the table printed on stdout, with each run's host seconds.
fn table(c: &Comparison, host_seconds: &[f64]) -> String {
    let mut table = format!(
        "Progressive radiosity on {} ({}), scene {}, {} patches of <= {} units, resolution {}\n\n",
        c.config, c.config_hash, c.scene, c.patches, c.patch_size, c.resolution
    );
    for (m, host) in c.methods.iter().zip(host_seconds) {
        let shots = m.shots.max(1);
        table += &format!(
            "{}: {} shots, {:.3} ms simulated ({:.3} ms per shot); seed's estimate {:.3} ms as written, {:.3} ms with readback x N\n",
            m.method.name(),
            m.shots,
            m.simulated_s * 1e3,
            m.simulated_s * 1e3 / shots as f64,
            m.seed.as_written * 1e3,
            m.seed.readback_x_n * 1e3,
        );
        table += "  phase (mean GP time per shot, ms):";
        for (k, v) in &m.phases {
            table += &format!(" {k} {:.3};", v * 1e3 / shots as f64);
        }
        table += &format!(
            "\n  Renderer busy {:.3} ms (all boards), ring {} payload words, bottleneck: {}\n  reciprocity clamps {}, culled: {:?}\n  host {host:.2} s\n\n",
            m.renderer_busy_s * 1e3,
            m.ring_payload_words,
            m.bottleneck,
            m.reciprocity_clamps,
            m.culls,
        );
    }
    if let Some(ratio) = c.hemicube_over_hemisphere() {
        table += &format!(
            "measured hemicube / hemisphere time: {ratio:.2} (the seed's claim: {SEED_RATIO})\n"
        );
    }
    table
}

/// The comparison as `comparison.csv`: a row per method.
fn comparison_csv(c: &Comparison) -> String {
    let mut csv = String::from(
        "method,shots,patches,simulated_s,per_shot_s,bottleneck,seed_estimate_s,seed_estimate_readback_x_n_s,reciprocity_clamps\n",
    );
    for m in &c.methods {
        csv += &format!(
            "{},{},{},{:.9},{:.9},{},{:.9},{:.9},{}\n",
            m.method.name(),
            m.shots,
            c.patches,
            m.simulated_s,
            m.per_shot_s,
            m.bottleneck,
            m.seed.as_written,
            m.seed.readback_x_n,
            m.reciprocity_clamps
        );
    }
    csv
}

/// The comparison as `comparison.json`, with each run's full simulated stats.
fn comparison_json(c: &Comparison) -> serde_json::Value {
    let methods: Vec<_> = c
        .methods
        .iter()
        .map(|m| {
            serde_json::json!({
                "method": m.method.name(),
                "shots": m.shots,
                "simulated_s": m.simulated_s,
                "per_shot_s": m.per_shot_s,
                "phases_mean_gp_s": m.phases,
                "bottleneck": m.bottleneck,
                "seed_estimate_s": m.seed.as_written,
                "seed_estimate_readback_x_n_s": m.seed.readback_x_n,
                "reciprocity_clamps": m.reciprocity_clamps,
                "stats": m.stats.to_json(),
            })
        })
        .collect();
    serde_json::json!({
        "config": c.config,
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
    /// further (a disk of N pixels needs ceil(N / 128)^2 Renderers of 128 x 128; a hemicube
    /// face must fit one Renderer, and N must be even).
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

pub fn formfactor(args: &FormFactorArgs) -> Result<(), UserError> {
    let given = given(args)?;
    let exact = pxpl5_radiosity::exact::point_to_polygon(given.point, given.normal, &given.polygon);
    let measured = match args.method.on_machine() {
        None => None,
        Some(method) => {
            let cfg = config_cmd::load(args.config.as_deref())?;
            check_resolution(method, args.resolution, cfg.renderer.count, &cfg.renderer)
                .map_err(|e| UserError(format!("--resolution {}: {e}", args.resolution)))?;
            let options = FfOptions {
                method,
                resolution: args.resolution,
                ..FfOptions::default()
            };
            let (measured, _) = timed(
                "formfactor",
                RunOptions::default().fidelity,
                || {
                    experiment::form_factor(
                        &cfg,
                        given.point,
                        given.unit_normal,
                        given.polygon.clone(),
                        options,
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

    /// `pxpl5 radiosity` with no flags runs the library's default experiment.
    #[test]
    fn the_defaults_are_the_librarys() {
        let args = RadiosityArgs::defaults();
        let (ours, lib) = (args.settings(Method::Hemisphere), Settings::default());
        assert_eq!(ours.ff.method, lib.ff.method);
        assert_eq!(ours.ff.resolution, lib.ff.resolution);
        assert_eq!(ours.ff.edge_rule, lib.ff.edge_rule);
        assert_eq!(ours.ff.depth, lib.ff.depth);
        assert_eq!(ours.ff.exact_delta, lib.ff.exact_delta);
        assert_eq!(ours.ff.skip_faces, lib.ff.skip_faces);
        assert_eq!(ours.shots, lib.shots);
        assert_eq!(ours.threshold, lib.threshold);
        assert_eq!(ours.shooters_at_once, lib.shooters_at_once);
        assert_eq!(ours.item_shots, lib.item_shots);
        assert_eq!(ours.run.fidelity, lib.run.fidelity);
        assert_eq!(ours.run.max_time, lib.run.max_time);
    }
}
