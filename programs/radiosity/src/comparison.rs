//! The comparison `pxpl5 radiosity` reports: per method, the measured simulated time, its phases
//! and bottleneck, beside the seed's estimate ([`crate::seed`]); and the measured hemicube /
//! hemisphere ratio beside the seed's claim of 5.
//!
//! Plain data, every figure simulated: how it is printed or written (table, CSV, JSON) is the
//! caller's choice.

use std::collections::BTreeMap;

use pxpl5_config::MachineConfig;
use pxpl5_machine::RunStats;

use crate::accuracy::Convergence;
use crate::experiment::{MethodRun, bottleneck, phase_times};
use crate::seed::{SeedEstimate, seed_estimate};
use crate::shot::{CullCounts, FfOptions, Method, View, views};

/// The seed report's claim for the hemicube / hemisphere time ratio.
pub const SEED_RATIO: f64 = 5.0;

/// The methods run on one scene and machine, side by side.
#[derive(Clone, Debug)]
pub struct Comparison {
    /// The machine config's name and hash.
    pub config: String,
    pub config_hash: String,
    /// The scene's name.
    pub scene: String,
    /// Patches (the seed's M) and the largest patch size that meshed them.
    pub patches: usize,
    pub patch_size: f64,
    /// Pixels across the hemisphere's disk and the hemicube's top face.
    pub resolution: u32,
    /// Shooters per batch, the same for every method.
    pub shooters_at_once: usize,
    /// One summary per method, in the order run.
    pub methods: Vec<MethodSummary>,
    /// The seed's assumptions against what the machine did, when both methods ran.
    pub seed_check: Option<SeedCheck>,
}

/// The assumptions behind the seed's estimate ([`crate::seed`]), each set against what the
/// simulated machine did in this comparison.
#[derive(Clone, Debug, PartialEq)]
pub struct SeedCheck {
    /// Receivers drawn per shot, hemicube over hemisphere. The seed: 5 (five broadcasts of every
    /// patch against one); the program sends a receiver only to the faces it may touch.
    pub drawn_ratio: f64,
    /// ID pixels read back per shot, (hemisphere, hemicube). The seed as written: one 128 x 128
    /// readback per run, whatever the number of shots.
    pub readback_pixels_per_shot: (u64, u64),
    /// Renderer microseconds per drawn receiver, (hemisphere, hemicube). The seed: 1 us for
    /// both (10^6 polygons per second), a hemisphere edge as cheap as a hemicube edge.
    pub renderer_us_per_receiver: (f64, f64),
}

impl SeedCheck {
    fn new(
        cfg: &MachineConfig,
        resolution: u32,
        sphere: &MethodSummary,
        cube: &MethodSummary,
    ) -> Option<SeedCheck> {
        let per_shot = |m: &MethodSummary| m.culls.drawn as f64 / m.shots.max(1) as f64;
        let pixels = |method| -> Option<u64> {
            let opts = FfOptions {
                method,
                resolution,
                ..FfOptions::default()
            };
            let views = views(&opts, &cfg.renderer).ok()?;
            Some(views.iter().map(View::pixels).sum())
        };
        let us = |m: &MethodSummary| 1e6 * m.renderer_busy_s / (m.culls.drawn.max(1) as f64);
        Some(SeedCheck {
            drawn_ratio: per_shot(cube) / per_shot(sphere),
            readback_pixels_per_shot: (pixels(Method::Hemisphere)?, pixels(Method::Hemicube)?),
            renderer_us_per_receiver: (us(sphere), us(cube)),
        })
    }
}

/// One method's measured figures beside the seed's estimate.
#[derive(Clone, Debug)]
pub struct MethodSummary {
    pub method: Method,
    /// Shots taken (the seed's N; fewer than asked when the threshold stopped the run, or a
    /// stop asked by the host).
    pub shots: usize,
    /// Whether the host's stop (a Ctrl-C) ended the run before its shots: its figures are those
    /// of the shots taken ([`MethodRun::partial`]).
    pub partial: bool,
    /// Simulated seconds of the whole run, and per shot (per one shot when none was taken).
    pub simulated_s: f64,
    pub per_shot_s: f64,
    /// Simulated seconds per phase over the run, GP time divided by the number of GPs
    /// ([`phase_times`]).
    pub phases: BTreeMap<String, f64>,
    /// The resource that held the critical path longest ([`bottleneck`]).
    pub bottleneck: String,
    /// The seed's estimate for this run's M and N (N at least 1).
    pub seed: SeedEstimate,
    /// Renderer busy time summed over every board, in simulated seconds.
    pub renderer_busy_s: f64,
    /// GP busy time summed over every GP, in simulated seconds.
    pub gp_busy_s: f64,
    /// Renderer busy time over boards x the run's time: how well the schedule used the boards.
    pub renderer_utilisation: f64,
    /// The machine: GPs, Renderer boards and ring channels.
    pub gps: usize,
    pub boards: usize,
    pub ring_channels: u32,
    /// Accuracy against the scene's reference, when it has one.
    pub convergence: Option<Convergence>,
    /// Payload words the ring carried.
    pub ring_payload_words: u64,
    /// Times reciprocity gave a form factor above 1, clamped.
    pub reciprocity_clamps: u64,
    pub culls: CullCounts,
    /// The run's full simulated statistics.
    pub stats: RunStats,
}

impl MethodSummary {
    /// The summary of `run`, made on the machine of `cfg` over `patches` patches.
    pub fn new(cfg: &MachineConfig, patches: usize, run: &MethodRun) -> MethodSummary {
        let shots = run.shots_taken();
        let simulated_s = run.stats.end.as_secs_f64();
        let phases = phase_times(&run.stats);
        let renderer_busy: u64 = run.stats.renderers.iter().map(|r| r.busy.0).sum();
        let gp_busy: u64 = run.stats.gps.iter().map(|g| g.busy.0).sum();
        let renderer_busy_s = renderer_busy as f64 / cfg.renderer.clock_hz as f64;
        let boards = run.stats.renderers.len();
        MethodSummary {
            method: run.method,
            shots,
            partial: run.partial(),
            simulated_s,
            per_shot_s: simulated_s / shots.max(1) as f64,
            bottleneck: bottleneck(&run.stats),
            phases,
            seed: seed_estimate(patches, shots.max(1), run.method),
            renderer_busy_s,
            gp_busy_s: gp_busy as f64 / cfg.gp.clock_hz as f64,
            renderer_utilisation: if simulated_s > 0.0 && boards > 0 {
                renderer_busy_s / (boards as f64 * simulated_s)
            } else {
                0.0
            },
            gps: run.stats.gps.len(),
            boards,
            ring_channels: cfg.ring.channels,
            convergence: run.convergence.clone(),
            ring_payload_words: run.stats.ring.total.payload_words,
            reciprocity_clamps: run.solution.reciprocity_clamps,
            culls: run.solution.culls.clone(),
            stats: run.stats.clone(),
        }
    }
}

impl Comparison {
    /// The comparison of `runs` of one scene (`scene`, meshed into `patches` patches of at most
    /// `patch_size`) on the machine of `cfg` at `resolution` with `shooters_at_once` shooters
    /// per batch.
    pub fn new(
        cfg: &MachineConfig,
        scene: &str,
        (patches, patch_size): (usize, f64),
        (resolution, shooters_at_once): (u32, usize),
        runs: &[MethodRun],
    ) -> Comparison {
        let methods: Vec<MethodSummary> = runs
            .iter()
            .map(|r| MethodSummary::new(cfg, patches, r))
            .collect();
        let find = |m: Method| methods.iter().find(|s| s.method == m);
        let seed_check = find(Method::Hemisphere)
            .zip(find(Method::Hemicube))
            .and_then(|(s, c)| SeedCheck::new(cfg, resolution, s, c));
        Comparison {
            config: cfg.name.clone(),
            config_hash: pxpl5_config::config_hash(cfg),
            scene: scene.to_string(),
            patches,
            patch_size,
            resolution,
            shooters_at_once,
            methods,
            seed_check,
        }
    }

    /// The measured hemicube / hemisphere ratio of the times per shot, when both ran (the seed claims
    /// [`SEED_RATIO`]).
    pub fn hemicube_over_hemisphere(&self) -> Option<f64> {
        let time = |m: Method| {
            self.methods
                .iter()
                .find(|s| s.method == m)
                .map(|s| s.per_shot_s)
        };
        Some(time(Method::Hemicube)? / time(Method::Hemisphere)?)
    }

    /// The measured hemicube / hemisphere ratio of the times to the target accuracy, when both
    /// reached it.
    pub fn hemicube_over_hemisphere_to_target(&self) -> Option<f64> {
        let time = |m: Method| {
            let s = self.methods.iter().find(|s| s.method == m)?;
            Some(s.convergence.as_ref()?.time_to_target?.0)
        };
        Some(time(Method::Hemicube)? / time(Method::Hemisphere)?)
    }
}
