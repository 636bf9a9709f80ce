//! `pxpl5 radiosity` (progressive radiosity with hemisphere and/or hemicube form factors on the
//! machine, measured and set beside the seed's estimate) and `pxpl5 formfactor` (one point to
//! one polygon, exactly or on the machine).

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::rc::Rc;

use clap::Args;
use pxpl5_config::MachineConfig;
use pxpl5_geom::DVec3;
use pxpl5_machine::{Recorder, RunOptions, RunStats};
use pxpl5_polygons::scene::{Camera, Triangle, TriangleScene};
use pxpl5_radiosity::mesh::{Patch, mesh};
use pxpl5_radiosity::program::{FormFactorProgram, FormFactorResult, RadiosityProgram, Solution};
use pxpl5_radiosity::scene::RadiosityScene;
use pxpl5_radiosity::shot::{FfOptions, Method};
use pxpl5_radiosity::views::{EdgeRule, HemisphereDepth};
use pxpl5_renderer::Fidelity;

use crate::UserError;
use crate::config_cmd;
use crate::run::{TraceArgs, png_bytes, probe_writable, simulate, write_atomic};

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
    #[arg(long, default_value = "both", value_parser = ["hemisphere", "hemicube", "both"])]
    pub method: String,
    /// Shots (shooting patches, the seed's N).
    #[arg(long, default_value_t = 6)]
    pub shots: usize,
    /// Stop early when max unshot power / emitted power falls below this.
    #[arg(long, default_value_t = 0.001)]
    pub threshold: f64,
    /// Patch size in scene units (the Cornell box is in millimetres).
    #[arg(long, default_value_t = 90.0)]
    pub patch_size: f64,
    /// Pixels across the hemisphere's disk and the hemicube's top face.
    #[arg(long, default_value_t = 128)]
    pub resolution: u32,
    /// Hemisphere edge rule: sign-of-c (docs/radiosity.md section 3) or seed (TR89-002's
    /// CASE 1 / CASE 2).
    #[arg(long, default_value = "sign-of-c", value_parser = ["sign-of-c", "seed"])]
    pub edge_rule: String,
    /// Hemisphere delta form factors: exact (disk area) or seed (the seed's integral rule).
    #[arg(long, default_value = "exact", value_parser = ["exact", "seed"])]
    pub delta: String,
    /// Hemicube: transform and clip every receiver for every face (no cheap face test).
    #[arg(long)]
    pub all_faces: bool,
    /// Shoot this many patches at once, their views spread over the Renderers (1: classic
    /// progressive refinement).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    pub shooters_at_once: u32,
    /// Hemisphere depth: taylor (the seed's quadratic approximation) or stored-w (w per pixel,
    /// exact, slower).
    #[arg(long, default_value = "taylor", value_parser = ["taylor", "stored-w"])]
    pub depth: String,
    /// Output directory.
    #[arg(long, default_value = "out/radiosity")]
    pub out: PathBuf,
    /// Renderer fidelity level: bit or integer (identical results and cycles).
    #[arg(long, default_value = "integer", value_parser = crate::run::fidelity_values(false))]
    pub fidelity: String,
    #[command(flatten)]
    pub traces: TraceArgs,
    /// Write the item (ID) buffers of these shots (0-based, comma-separated) as PNGs:
    /// DIR/items-METHOD-shotK-VIEW.png, one colour per patch.
    #[arg(long, value_delimiter = ',')]
    pub item_buffers: Vec<usize>,
}

/// `path` with the method's name before its extension, when more than one method runs.
fn per_method(path: &std::path::Path, method: Method, several: bool) -> PathBuf {
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

    fn ff_options(&self, method: Method) -> FfOptions {
        FfOptions {
            method,
            resolution: self.resolution,
            edge_rule: if self.edge_rule == "seed" {
                EdgeRule::Seed
            } else {
                EdgeRule::SignOfC
            },
            exact_delta: self.delta == "exact",
            skip_faces: !self.all_faces,
            depth: if self.depth == "stored-w" {
                HemisphereDepth::StoredW
            } else {
                HemisphereDepth::Taylor
            },
        }
    }
}

/// One method's measured run.
struct Measured {
    method: Method,
    stats: RunStats,
    solution: Solution,
    host_seconds: f64,
}

fn run_method(
    cfg: &MachineConfig,
    patches: &[Patch],
    args: &RadiosityArgs,
    method: Method,
    fidelity: Fidelity,
    recorder: Recorder,
) -> Result<Measured, UserError> {
    let mut program = RadiosityProgram::new(
        patches.to_vec(),
        args.ff_options(method),
        args.shots,
        args.threshold,
    );
    program.item_shots = args.item_buffers.clone();
    program.shooters_at_once = args.shooters_at_once as usize;
    let options = RunOptions {
        fidelity,
        max_time: pxpl5_sim::Tick(1_000_000_000_000_000),
    };
    let (result, host_seconds) = simulate(cfg, &program, options, recorder)?;
    let solution = program.solution.borrow().clone();
    for (shot, buffers) in program.item_buffers.borrow().iter() {
        for b in buffers.borrow().iter() {
            let path = args
                .out
                .join(format!("items-{}-shot{shot}-{}.png", method.name(), b.view));
            write_atomic(&path, &item_png(b)?)?;
        }
    }
    let several = args.method == "both";
    args.traces
        .write(&result.recorder, |p| per_method(p, method, several))?;
    Ok(Measured {
        method,
        stats: result.stats,
        solution,
        host_seconds,
    })
}

/// The seed's estimate for M patches and N shots, in seconds: as written, and with its readback
/// term multiplied by N (it happens once per shot).
fn seed_estimate(m: usize, n: usize, method: Method) -> (f64, f64) {
    let faces = if method == Method::Hemicube { 5.0 } else { 1.0 };
    let broadcast = m as f64 * n as f64 / 1e6;
    let readback = 128.0 * 128.0 / 80e6;
    (
        faces * (broadcast + readback),
        faces * (broadcast + n as f64 * readback),
    )
}

/// Phase spans of a run: name -> simulated seconds (span from first start to last end).
fn phases(stats: &RunStats) -> BTreeMap<String, f64> {
    let mut out = BTreeMap::new();
    for p in &stats.phases {
        out.insert(
            p.name.clone(),
            (p.gp_time.as_secs_f64()) / stats.gps.len() as f64,
        );
    }
    out
}

pub fn radiosity(args: &RadiosityArgs) -> Result<(), UserError> {
    let cfg = config_cmd::load(args.config.as_deref())?;
    let scene: RadiosityScene = match &args.scene {
        Some(p) => pxpl5_radiosity::scene::load_radiosity_scene(p).map_err(config_cmd::report)?,
        None => pxpl5_radiosity::scenes::cornell_box(),
    };
    let fidelity: Fidelity = args.fidelity.parse()?;
    let patches = mesh(&scene, args.patch_size).map_err(|e| UserError(e.to_string()))?;
    std::fs::create_dir_all(&args.out)
        .map_err(|e| UserError(format!("--out {}: cannot create: {e}", args.out.display())))?;
    probe_writable(&args.out)?;
    let methods = match args.method.as_str() {
        "hemisphere" => vec![Method::Hemisphere],
        "hemicube" => vec![Method::Hemicube],
        _ => vec![Method::Hemisphere, Method::Hemicube],
    };
    let mut runs = Vec::new();
    for m in methods {
        tracing::info!(
            method = %m.name(),
            patches = patches.len(),
            max_shots = args.shots,
            "form-factor method starts"
        );
        let recorder = args.traces.recorder()?;
        runs.push(run_method(&cfg, &patches, args, m, fidelity, recorder)?);
    }

    // The comparison table.
    let mut table = String::new();
    let mut csv = String::from(
        "method,shots,patches,simulated_s,per_shot_s,bottleneck,seed_estimate_s,seed_estimate_readback_x_n_s,reciprocity_clamps\n",
    );
    let mut json_methods = Vec::new();
    table += &format!(
        "Progressive radiosity on {} ({}), scene {}, {} patches of <= {} units, resolution {}\n\n",
        cfg.name,
        pxpl5_config::config_hash(&cfg),
        scene.name,
        patches.len(),
        args.patch_size,
        args.resolution
    );
    for r in &runs {
        let shots = r.solution.shots.len().max(1);
        let total = r.stats.end.as_secs_f64();
        let ph = phases(&r.stats);
        let (bottleneck, _) = ph.iter().filter(|(k, _)| k.as_str() != "done").fold(
            ("none".to_string(), -1.0),
            |a, (k, v)| {
                if *v > a.1 { (k.clone(), *v) } else { a }
            },
        );
        let (seed, seed_n) = seed_estimate(patches.len(), shots, r.method);
        table += &format!(
            "{}: {} shots, {:.3} ms simulated ({:.3} ms per shot); seed's estimate {:.3} ms as written, {:.3} ms with readback x N\n",
            r.method.name(),
            r.solution.shots.len(),
            total * 1e3,
            total * 1e3 / shots as f64,
            seed * 1e3,
            seed_n * 1e3,
        );
        table += "  phase (mean GP time per shot, ms):";
        for (k, v) in &ph {
            table += &format!(" {k} {:.3};", v * 1e3 / shots as f64);
        }
        let renderer_busy: u64 = r.stats.renderers.iter().map(|x| x.busy.0).sum();
        table += &format!(
            "\n  Renderer busy {:.3} ms (all boards), ring {} payload words, bottleneck: {bottleneck}\n  reciprocity clamps {}, culled: {:?}\n  host {:.2} s\n\n",
            renderer_busy as f64 / cfg.renderer.clock_hz as f64 * 1e3,
            r.stats.ring.total.payload_words,
            r.solution.reciprocity_clamps,
            r.solution.culls,
            r.host_seconds,
        );
        csv += &format!(
            "{},{},{},{:.9},{:.9},{},{:.9},{:.9},{}\n",
            r.method.name(),
            r.solution.shots.len(),
            patches.len(),
            total,
            total / shots as f64,
            bottleneck,
            seed,
            seed_n,
            r.solution.reciprocity_clamps
        );
        json_methods.push(serde_json::json!({
            "method": r.method.name(),
            "shots": r.solution.shots.len(),
            "simulated_s": total,
            "per_shot_s": total / shots as f64,
            "phases_mean_gp_s": ph,
            "bottleneck": bottleneck,
            "seed_estimate_s": seed,
            "seed_estimate_readback_x_n_s": seed_n,
            "reciprocity_clamps": r.solution.reciprocity_clamps,
            "stats": r.stats.to_json(),
        }));
    }
    if let [a, b] = &runs[..] {
        let ratio = b.stats.end.as_secs_f64() / a.stats.end.as_secs_f64();
        table +=
            &format!("measured hemicube / hemisphere time: {ratio:.2} (the seed's claim: 5)\n");
    }
    print!("{table}");
    let json = serde_json::json!({ "config": cfg.name, "scene": scene.name, "patches": patches.len(), "methods": json_methods });
    write_atomic(&args.out.join("comparison.csv"), csv.as_bytes())?;
    write_atomic(
        &args.out.join("comparison.json"),
        (serde_json::to_string_pretty(&json).map_err(UserError::from)? + "\n").as_bytes(),
    )?;
    write_atomic(
        &args.out.join("config.ron"),
        pxpl5_config::show(&cfg).as_bytes(),
    )?;
    let last = runs.last().expect("at least one method");
    let mut pcsv = String::from("patch,surface,area,r,g,b\n");
    for (i, (p, b)) in patches.iter().zip(&last.solution.radiosity).enumerate() {
        pcsv += &format!(
            "{i},{},{:.6},{:.6},{:.6},{:.6}\n",
            p.surface, p.area, b[0], b[1], b[2]
        );
    }
    write_atomic(&args.out.join("patches.csv"), pcsv.as_bytes())?;
    if let Some(camera) = &scene.camera {
        let frame = render(&cfg, &patches, &last.solution, camera.clone())?;
        write_atomic(&args.out.join("radiosity.png"), &png_bytes(&frame)?)?;
    }
    println!(
        "wrote {}/comparison.csv, comparison.json, patches.csv, config.ron, radiosity.png",
        args.out.display()
    );
    Ok(())
}

/// An item buffer as a picture: one colour per ID (a hash), black where nothing was drawn, the
/// buffer's row 0 at the bottom.
fn item_png(b: &pxpl5_radiosity::shot::ItemBuffer) -> Result<Vec<u8>, UserError> {
    let mut rgb = Vec::with_capacity((b.width * b.rows * 3) as usize);
    for row in (0..b.rows).rev() {
        for col in 0..b.width {
            let id = b.ids[(row * b.width + col) as usize];
            if id == 0 {
                rgb.extend([0, 0, 0]);
            } else {
                let h = u32::from(id).wrapping_mul(0x9E37_79B9);
                rgb.extend([
                    (h >> 24) as u8 | 0x40,
                    (h >> 16) as u8 | 0x40,
                    (h >> 8) as u8 | 0x40,
                ]);
            }
        }
    }
    png_bytes(&pxpl5_machine::FrameBufferImage {
        width: b.width,
        height: b.rows,
        rgb,
        writes: 0,
    })
}

/// The solution seen from the scene's camera, drawn by the simulated machine's polygon
/// pipeline: patches as triangles, Gouraud-shaded from vertex radiosities (the mean of the
/// patches of one surface meeting at a vertex), with the ambient term for display, tone-mapped.
fn render(
    cfg: &MachineConfig,
    patches: &[Patch],
    s: &Solution,
    camera: Camera,
) -> Result<pxpl5_machine::FrameBufferImage, UserError> {
    let area: f64 = patches.iter().map(|p| p.area).sum();
    let mut rho = [0.0; 3];
    let mut unshot = [0.0; 3];
    for (p, u) in patches.iter().zip(&s.unshot) {
        for k in 0..3 {
            rho[k] += p.reflectance[k] * p.area / area;
            unshot[k] += u[k] * p.area / area;
        }
    }
    let display: Vec<[f64; 3]> = patches
        .iter()
        .zip(&s.radiosity)
        .map(|(p, b)| {
            let mut d = [0.0; 3];
            for k in 0..3 {
                let ambient = unshot[k] / (1.0 - rho[k]).max(1e-9);
                d[k] = b[k] + p.reflectance[k] * ambient;
            }
            d
        })
        .collect();
    // Vertex radiosity: mean over the patches of the same surface sharing the vertex.
    let key = |surface: usize, v: DVec3| {
        (
            surface,
            (v[0] * 1e3).round() as i64,
            (v[1] * 1e3).round() as i64,
            (v[2] * 1e3).round() as i64,
        )
    };
    // (surface, vertex position in thousandths) -> (summed radiosity, patch count).
    type VertexSums = BTreeMap<(usize, i64, i64, i64), ([f64; 3], f64)>;
    let mut sums = VertexSums::new();
    for (p, d) in patches.iter().zip(&display) {
        for v in &p.vertices {
            let e = sums.entry(key(p.surface, *v)).or_insert(([0.0; 3], 0.0));
            for (sum, x) in e.0.iter_mut().zip(d) {
                *sum += x;
            }
            e.1 += 1.0;
        }
    }
    // Tone map: scale so the 95th percentile of patch luminance maps to 0.9, then gamma 2.2.
    let mut lum: Vec<f64> = display.iter().map(|d| (d[0] + d[1] + d[2]) / 3.0).collect();
    lum.sort_by(f64::total_cmp);
    let white = lum
        .get(lum.len() * 95 / 100)
        .copied()
        .unwrap_or(1.0)
        .max(1e-12)
        / 0.9;
    let tone = |x: f64| (x / white).clamp(0.0, 1.0).powf(1.0 / 2.2);
    let mut triangles = Vec::new();
    for p in patches {
        let colours: Vec<(f64, f64, f64)> = p
            .vertices
            .iter()
            .map(|v| {
                let (c, n) = sums[&key(p.surface, *v)];
                (tone(c[0] / n), tone(c[1] / n), tone(c[2] / n))
            })
            .collect();
        for k in 1..p.vertices.len() - 1 {
            let idx = [0, k, k + 1];
            triangles.push(Triangle {
                vertices: idx
                    .iter()
                    .map(|&i| (p.vertices[i][0], p.vertices[i][1], p.vertices[i][2]))
                    .collect(),
                colours: idx.iter().map(|&i| colours[i]).collect(),
            });
        }
    }
    let tscene = TriangleScene { camera, triangles };
    let program = pxpl5_polygons::Polygons::new(tscene);
    let (result, _) = simulate(cfg, &program, RunOptions::default(), Recorder::default())?;
    Ok(result.frame)
}

/// Options of `pxpl5 formfactor`.
#[derive(Args, Clone, Debug)]
pub struct FormFactorArgs {
    /// The receiving point, X,Y,Z.
    #[arg(long, allow_hyphen_values = true)]
    pub point: String,
    /// Its normal, X,Y,Z (need not be unit length).
    #[arg(long, allow_hyphen_values = true)]
    pub normal: String,
    /// The polygon's vertices, "X,Y,Z;X,Y,Z;..." (planar, convex, 3 or more).
    #[arg(long, allow_hyphen_values = true)]
    pub polygon: String,
    /// exact (the contour formula), hemisphere or hemicube (on the simulated machine).
    #[arg(long, default_value = "exact", value_parser = ["exact", "hemisphere", "hemicube"])]
    pub method: String,
    /// Pixels across the disk or the hemicube's top face.
    #[arg(long, default_value_t = 128)]
    pub resolution: u32,
    /// Machine config (RON); default: the embedded seed machine.
    #[arg(long)]
    pub config: Option<PathBuf>,
}

fn parse_v3(what: &str, s: &str) -> Result<DVec3, UserError> {
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

pub fn formfactor(args: &FormFactorArgs) -> Result<(), UserError> {
    let point = parse_v3("--point", &args.point)?;
    let normal = parse_v3("--normal", &args.normal)?;
    if normal == DVec3::ZERO {
        return Err(UserError("--normal: must not be zero".into()));
    }
    let polygon: Vec<DVec3> = args
        .polygon
        .split(';')
        .filter(|s| !s.trim().is_empty())
        .enumerate()
        .map(|(i, s)| parse_v3(&format!("--polygon vertex {i}"), s))
        .collect::<Result<_, _>>()?;
    if polygon.len() < 3 {
        return Err(UserError(format!(
            "--polygon: needs at least 3 vertices (got {})",
            polygon.len()
        )));
    }
    let nn = normal.normalize();
    let exact = pxpl5_radiosity::exact::point_to_polygon(point, nn, &polygon);
    let method = match args.method.as_str() {
        "exact" => {
            println!("exact form factor: {exact:.9}");
            return Ok(());
        }
        "hemisphere" => Method::Hemisphere,
        _ => Method::Hemicube,
    };
    let cfg = config_cmd::load(args.config.as_deref())?;
    let result = Rc::new(RefCell::new(FormFactorResult::default()));
    let program = FormFactorProgram {
        point,
        normal: nn,
        polygons: vec![polygon],
        options: FfOptions {
            method,
            resolution: args.resolution,
            ..FfOptions::default()
        },
        result: result.clone(),
    };
    let (run, _) = simulate(&cfg, &program, RunOptions::default(), Recorder::default())?;
    let f = result.borrow().form_factors[0];
    let renderer: u64 = run.stats.renderers.iter().map(|r| r.busy.0).sum();
    println!(
        "{} form factor: {f:.9} (exact {exact:.9}, error {:+.3}%)",
        method.name(),
        if exact > 0.0 {
            (f - exact) / exact * 100.0
        } else {
            0.0
        }
    );
    println!(
        "simulated: {:.3} us on {}; Renderer busy {} cycles (all boards); GP 0 busy {} cycles; ring {} payload words",
        run.stats.end.as_secs_f64() * 1e6,
        cfg.name,
        renderer,
        run.stats.gps[0].busy.0,
        run.stats.ring.total.payload_words
    );
    Ok(())
}
