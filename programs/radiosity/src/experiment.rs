//! One radiosity experiment on a machine config, as `pxpl5 radiosity` runs it and any other Rust
//! program can: progressive refinement of a meshed scene with one form-factor method
//! ([`run`]), the run's measured results ([`MethodRun`]), and the per-phase analysis that names
//! its bottleneck from the critical path ([`phase_times`], [`bottleneck`]). Also one point-to-polygon form factor on the
//! machine ([`form_factor`], `pxpl5 formfactor`).
//!
//! Nothing here reads a host clock or writes a file: callers time the runs and write what they
//! want, so every result of this module is simulated and reproducible.

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::rc::Rc;
use std::sync::Arc;

use pxpl5_config::MachineConfig;
use pxpl5_geom::DVec3;
use pxpl5_machine::{Machine, Recorder, RunError, RunOptions, RunStats};
use pxpl5_renderer::Fidelity;
use pxpl5_sim::Tick;

use crate::accuracy::{Convergence, Reference};
use crate::mesh::Patch;
use crate::program::{FormFactorProgram, FormFactorResult, Observer, RadiosityProgram, Solution};
use crate::shot::{FfOptions, ItemBuffer, Method};

/// How one method runs: the form-factor options (with the method), the refinement's limits, and
/// the machine run's options. The defaults are `pxpl5 radiosity`'s.
#[derive(Clone, Debug)]
pub struct Settings {
    pub ff: FfOptions,
    /// Most shots to take (the seed's N).
    pub shots: usize,
    /// Stop early when max unshot power / emitted power falls below this.
    pub threshold: f64,
    /// Shooters per batch, their views spread over the Renderers (1: classic progressive
    /// refinement).
    pub shooters_at_once: usize,
    /// Shots (0-based) whose item buffers to keep.
    pub item_shots: Vec<usize>,
    pub run: RunOptions,
    /// The scene's reference solution: with it, the run's accuracy is measured batch by batch
    /// ([`MethodRun::convergence`]).
    pub reference: Option<Arc<Reference>>,
    /// Stop once every surface is within this relative error of the reference (needs one).
    pub target_error: Option<f64>,
}

impl Default for Settings {
    fn default() -> Settings {
        Settings {
            ff: FfOptions::default(),
            shots: 6,
            threshold: 0.0,
            shooters_at_once: 1,
            item_shots: Vec::new(),
            reference: None,
            target_error: None,
            run: RunOptions {
                fidelity: Fidelity::Sparse,
                // 1,000 simulated seconds, far beyond the machine's default of 10: a fine mesh
                // with many shots may need it, and a runaway program still stops.
                max_time: Tick(1_000_000_000_000_000),
                ..RunOptions::default()
            },
        }
    }
}

/// The main job's patch size (`pxpl5 radiosity`'s default): the empty Cornell box at 120 mm
/// makes 199 patches.
pub const MAIN_JOB_PATCH_SIZE: f64 = 120.0;

impl Settings {
    /// The main job's settings for `method` on `cfg`, but a fixed number of shots with no target
    /// accuracy: a workload whose work does not depend on how fast it converges (the benchmarks').
    pub fn fixed_shots(method: Method, shots: usize, cfg: &MachineConfig) -> Settings {
        Settings {
            ff: FfOptions {
                method,
                ..FfOptions::default()
            },
            shots,
            shooters_at_once: cfg.renderer.count as usize,
            ..Settings::default()
        }
    }
}

/// One method's measured run.
pub struct MethodRun {
    pub method: Method,
    /// Simulated statistics of the whole run.
    pub stats: RunStats,
    /// The solution at the end of the run.
    pub solution: Solution,
    /// The kept item buffers: (shot, its views), in the order the shots were taken.
    pub item_buffers: Vec<(usize, Vec<ItemBuffer>)>,
    /// The run's traces, as recorded by the recorder given to [`run`].
    pub recorder: Recorder,
    /// Its accuracy batch by batch, when the settings had a reference.
    pub convergence: Option<Convergence>,
}

impl MethodRun {
    /// Shots taken (the run may stop early at its threshold, or when the host asks it to stop
    /// soon).
    pub fn shots_taken(&self) -> usize {
        self.solution.shots.len()
    }

    /// Whether the host's request to stop soon (`pxpl5_machine::Stop::Soon`, a Ctrl-C) ended the
    /// run before its shots: its solution holds the shots taken, each complete.
    pub fn partial(&self) -> bool {
        self.solution.stopped
    }
}

/// Progressive refinement of `patches` on the machine of `cfg` with `settings`, recording traces
/// with `recorder`. The monitor of `settings.run`, if any, is the program's too: GP 0 publishes
/// the shots taken there, and ends the run between shots if asked to stop soon.
pub fn run(
    cfg: &MachineConfig,
    patches: &[Patch],
    settings: &Settings,
    recorder: Recorder,
) -> Result<MethodRun, RunError> {
    let mut program = RadiosityProgram::new(
        patches.to_vec(),
        settings.ff,
        settings.shots,
        settings.threshold,
    );
    program.item_shots = settings.item_shots.clone();
    program.shooters_at_once = settings.shooters_at_once;
    program.monitor = settings.run.monitor.clone();
    if let Some(reference) = &settings.reference {
        let mut observer = Observer::default();
        if let Some(target) = settings.target_error {
            let reference = reference.clone();
            observer.target = Some(Box::new(move |radiosity: &[[f64; 3]]| {
                reference.surface_error(radiosity).worst <= target
            }));
        }
        program.observer = Some(Rc::new(RefCell::new(observer)));
    }
    let result = Machine::new(cfg, &program, settings.run.clone(), recorder)?.run()?;
    // The machine is gone, so the program's shared state has no other reader: move it out.
    let solution = std::mem::take(&mut *program.solution.borrow_mut());
    let item_buffers = std::mem::take(&mut *program.item_buffers.borrow_mut())
        .into_iter()
        .map(|(shot, views)| (shot, std::mem::take(&mut *views.borrow_mut())))
        .collect();
    let convergence = program
        .observer
        .zip(settings.reference.as_ref())
        .map(|(o, r)| {
            let batches = std::mem::take(&mut o.borrow_mut().batches);
            Convergence::new(r, &batches, settings.target_error.unwrap_or(0.0))
        });
    Ok(MethodRun {
        method: settings.ff.method,
        stats: result.stats,
        solution,
        item_buffers,
        recorder: result.recorder,
        convergence,
    })
}

/// The simulated seconds of each phase the GPs marked, over the whole run: the time every GP
/// spent in it, divided by the number of GPs (so phases add up to about the run's time).
pub fn phase_times(stats: &RunStats) -> BTreeMap<String, f64> {
    stats
        .phases
        .iter()
        .map(|p| {
            (
                p.name.clone(),
                p.gp_time.as_secs_f64() / stats.gps.len() as f64,
            )
        })
        .collect()
}

/// The run's bottleneck: the resource (GP, ring or Renderer) that held its critical path longest
/// (`RunStats::critical_resources`), with its share of the run and the path's largest activity,
/// e.g. "Renderer (72 % of the critical path; largest: Renderer qee_sign, 43 %)"; "none" for a
/// run with no path.
pub fn bottleneck(stats: &RunStats) -> String {
    let end = stats.end.0.max(1) as f64;
    let Some(&(resource, time)) = stats.critical_resources().first() else {
        return "none".to_string();
    };
    let share = |t: Tick| 100.0 * t.0 as f64 / end;
    let top = stats
        .critical_path
        .iter()
        .find(|p| p.resource == resource)
        .map_or(String::new(), |p| {
            format!("; largest: {}, {:.0} %", p.activity, share(p.time))
        });
    format!(
        "{} ({:.0} % of the critical path{top})",
        resource.name(),
        share(time)
    )
}

/// One form factor computed on the machine, with the run that computed it.
pub struct MachineFormFactor {
    pub form_factor: f64,
    pub stats: RunStats,
}

/// The form factor from `point` with unit `normal` to the planar convex `polygon`, computed on
/// the machine of `cfg` with `options` (the polygon is seen from whichever side faces the
/// point), the machine run with `run`. The exact value is [`crate::exact::point_to_polygon`].
///
/// The machine is given the polygon in the point's frame, [`point_frame`]: F does not change,
/// and the machine's arithmetic then never sees coordinates whose squares overflow or underflow.
pub fn form_factor(
    cfg: &MachineConfig,
    point: DVec3,
    normal: DVec3,
    polygon: Vec<DVec3>,
    options: FfOptions,
    run: RunOptions,
) -> Result<MachineFormFactor, RunError> {
    let result = Rc::new(RefCell::new(FormFactorResult::default()));
    let program = FormFactorProgram {
        point: DVec3::ZERO,
        normal,
        polygons: vec![point_frame(point, &polygon)],
        options,
        result: result.clone(),
    };
    let run = Machine::new(cfg, &program, run, Recorder::default())?.run()?;
    let form_factor = result.borrow().form_factors[0];
    Ok(MachineFormFactor {
        form_factor,
        stats: run.stats,
    })
}

/// `polygon` relative to `point`, divided by a power of two that brings its largest coordinate
/// into [1, 2) ([`pxpl5_geom::polygon::power_of_two_scale`]): a form factor depends only on the
/// vertices relative to the point, up to scale. The machine's shooter frame subtracts the point
/// too and divides by the polygon's reach, and division by a power of two is exact, so the run's
/// numbers are the same as with the polygon as given wherever those did not overflow or
/// underflow. A difference that overflows is taken of the halved coordinates.
pub fn point_frame(point: DVec3, polygon: &[DVec3]) -> Vec<DVec3> {
    let mut r: Vec<DVec3> = polygon.iter().map(|&v| v - point).collect();
    if !r.iter().all(|v| v.is_finite()) {
        r = polygon.iter().map(|&v| v * 0.5 - point * 0.5).collect();
    }
    let s = pxpl5_geom::polygon::power_of_two_scale(&r);
    r.iter().map(|&v| v / s).collect()
}
