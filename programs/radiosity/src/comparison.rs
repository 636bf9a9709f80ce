//! The comparison `pxpl5 radiosity` reports: per method, the measured simulated time, its phases
//! and bottleneck, beside the seed's estimate ([`crate::seed`]); and the measured hemicube /
//! hemisphere ratio beside the seed's claim of 5.
//!
//! Plain data, every figure simulated: how it is printed or written (table, CSV, JSON) is the
//! caller's choice.

use std::collections::BTreeMap;

use pxpl5_config::MachineConfig;
use pxpl5_machine::RunStats;

use crate::experiment::{MethodRun, bottleneck, phase_times};
use crate::seed::{SeedEstimate, seed_estimate};
use crate::shot::{CullCounts, Method};

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
    /// One summary per method, in the order run.
    pub methods: Vec<MethodSummary>,
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
    /// The phase that took the most time ([`bottleneck`]).
    pub bottleneck: String,
    /// The seed's estimate for this run's M and N (N at least 1).
    pub seed: SeedEstimate,
    /// Renderer busy time summed over every board, in simulated seconds.
    pub renderer_busy_s: f64,
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
        MethodSummary {
            method: run.method,
            shots,
            partial: run.partial(),
            simulated_s,
            per_shot_s: simulated_s / shots.max(1) as f64,
            bottleneck: bottleneck(&phases),
            phases,
            seed: seed_estimate(patches, shots.max(1), run.method),
            renderer_busy_s: renderer_busy as f64 / cfg.renderer.clock_hz as f64,
            ring_payload_words: run.stats.ring.total.payload_words,
            reciprocity_clamps: run.solution.reciprocity_clamps,
            culls: run.solution.culls.clone(),
            stats: run.stats.clone(),
        }
    }
}

impl Comparison {
    /// The comparison of `runs` of one scene (`scene`, meshed into `patches` patches of at most
    /// `patch_size`) on the machine of `cfg` at `resolution`.
    pub fn new(
        cfg: &MachineConfig,
        scene: &str,
        patches: usize,
        patch_size: f64,
        resolution: u32,
        runs: &[MethodRun],
    ) -> Comparison {
        Comparison {
            config: cfg.name.clone(),
            config_hash: pxpl5_config::config_hash(cfg),
            scene: scene.to_string(),
            patches,
            patch_size,
            resolution,
            methods: runs
                .iter()
                .map(|r| MethodSummary::new(cfg, patches, r))
                .collect(),
        }
    }

    /// The measured hemicube / hemisphere time ratio, when both ran (the seed claims
    /// [`SEED_RATIO`]).
    pub fn hemicube_over_hemisphere(&self) -> Option<f64> {
        let time = |m: Method| {
            self.methods
                .iter()
                .find(|s| s.method == m)
                .map(|s| s.simulated_s)
        };
        Some(time(Method::Hemicube)? / time(Method::Hemisphere)?)
    }
}
