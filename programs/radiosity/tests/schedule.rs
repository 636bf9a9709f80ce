//! The list scheduler of a shot's views (`shot::shoot`): on a batched workload it keeps every
//! Renderer busy, and the solution it computes does not depend on the machine's timing.

use pxpl5_config::MachineConfig;
use pxpl5_machine::Recorder;
use pxpl5_radiosity::experiment::{self, MethodRun, Settings};
use pxpl5_radiosity::mesh::mesh;
use pxpl5_radiosity::scenes;
use pxpl5_radiosity::shot::{FfOptions, Method};

/// `shots` shots of the Cornell box at 150 mm patches with `at_once` shooters per batch.
fn run(cfg: &MachineConfig, method: Method, shots: usize, at_once: usize) -> MethodRun {
    let patches = mesh(&scenes::cornell_box(), 150.0).expect("meshes");
    let settings = Settings {
        ff: FfOptions {
            method,
            ..FfOptions::default()
        },
        shots,
        threshold: 0.0,
        shooters_at_once: at_once,
        ..Settings::default()
    };
    experiment::run(cfg, &patches, &settings, Recorder::default()).expect("runs")
}

/// Each Renderer's busy share of the run, in percent.
fn busy(run: &MethodRun) -> Vec<f64> {
    run.stats
        .renderers
        .iter()
        .map(|r| 100.0 * r.busy.0 as f64 / (r.busy.0 + r.idle.0) as f64)
        .collect()
}

#[test]
fn a_batch_of_views_keeps_every_board_busy() {
    let cfg = pxpl5_config::default_config();
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    for method in [Method::Hemisphere, Method::Hemicube] {
        // One shooter at a time: the hemisphere's one view leaves three of four boards idle, the
        // hemicube's fifth face runs alone.
        let single = run(&cfg, method, 8, 1);
        // Eight at a time: 8 (hemisphere) or 40 (hemicube) views on 4 boards. A board is not
        // busy while a readback waits for the ring to take its IDs (its port is busy), so even a
        // full list leaves each board idle part of the time; and views differ in cost (a shooter
        // that sees fewer receivers draws fewer), so with two hemisphere views per board the
        // boards' shares differ too (31-67 % measured).
        let batched = run(&cfg, method, 16, 8);
        let (one, eight) = (busy(&single), busy(&batched));
        assert_eq!(eight.len(), 4);
        for (r, &share) in eight.iter().enumerate() {
            assert!(
                share >= 25.0,
                "{method:?}: Renderer {r} busy {share:.1}% with 8 shooters at once: {eight:?}"
            );
        }
        assert!(
            mean(&eight) > mean(&one) + 15.0,
            "{method:?}: batching raises the boards' mean busy share: {one:?} -> {eight:?}"
        );
        let per_shot = |r: &MethodRun| r.stats.end.0 as f64 / r.shots_taken() as f64;
        assert!(
            per_shot(&batched) < 0.8 * per_shot(&single),
            "{method:?}: a shot takes less time batched"
        );
        assert_eq!(batched.shots_taken(), 16);
    }
}

#[test]
fn the_solution_does_not_depend_on_the_machine_s_timing() {
    let fast = pxpl5_config::default_config();
    let mut slow = fast.clone();
    // A slower ring and dearer GP messages change every time and the order bands and partial
    // sums arrive in, not what is computed.
    slow.ring.channel_clock_hz /= 4;
    slow.gp.costs.message_send *= 4;
    slow.gp.costs.message_receive *= 4;
    for method in [Method::Hemisphere, Method::Hemicube] {
        let a = run(&fast, method, 4, 2);
        let b = run(&slow, method, 4, 2);
        assert!(
            b.stats.end > a.stats.end,
            "{method:?}: the slow machine takes longer"
        );
        assert_eq!(a.solution.shots.len(), b.solution.shots.len());
        let bits = |r: &MethodRun| -> Vec<u64> {
            r.solution
                .radiosity
                .iter()
                .flatten()
                .map(|x| x.to_bits())
                .collect()
        };
        assert!(bits(&a) == bits(&b), "{method:?}: solutions differ");
    }
}
