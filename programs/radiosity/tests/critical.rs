//! The critical path names the bottleneck: on machines built so that one resource is slow, the
//! run's bottleneck is that resource, and the path accounts for every picosecond of the run.

use pxpl5_config::MachineConfig;
use pxpl5_machine::{Recorder, Resource};
use pxpl5_radiosity::experiment::{self, MethodRun, Settings, bottleneck};
use pxpl5_radiosity::mesh::mesh;
use pxpl5_radiosity::scenes;
use pxpl5_radiosity::shot::{FfOptions, Method};
use pxpl5_sim::Tick;

fn run(cfg: &MachineConfig, method: Method) -> MethodRun {
    let patches = mesh(&scenes::cornell_empty(), 200.0).expect("meshes");
    let settings = Settings {
        ff: FfOptions {
            method,
            ..FfOptions::default()
        },
        shots: 4,
        shooters_at_once: 4,
        ..Settings::default()
    };
    experiment::run(cfg, &patches, &settings, Recorder::default()).expect("runs")
}

#[test]
fn a_slow_resource_is_named_the_bottleneck() {
    let seed = pxpl5_config::default_config();
    let mut slow_ring = seed.clone();
    slow_ring.ring.channel_clock_hz /= 50;
    let mut slow_gp = seed.clone();
    slow_gp.gp.clock_hz /= 50;
    let mut slow_renderer = seed.clone();
    slow_renderer.renderer.clock_hz /= 50;
    let cases = [
        (&slow_ring, Resource::Ring),
        (&slow_gp, Resource::Gp),
        (&slow_renderer, Resource::Renderer),
    ];
    for method in [Method::Hemisphere, Method::Hemicube] {
        for (cfg, slow) in cases {
            let r = run(cfg, method);
            let path = r.stats.critical_resources();
            let total: u64 = r.stats.critical_path.iter().map(|p| p.time.0).sum();
            assert_eq!(Tick(total), r.stats.end, "the path covers the whole run");
            assert_eq!(path[0].0, slow, "{method:?}: {path:?}");
            // It holds most of the path, and the report says so.
            assert!(
                path[0].1.0 as f64 > 0.5 * r.stats.end.0 as f64,
                "{method:?}: {path:?}"
            );
            let b = bottleneck(&r.stats);
            assert!(b.starts_with(slow.name()), "{b}");
        }
    }
}
