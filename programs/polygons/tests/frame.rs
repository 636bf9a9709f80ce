//! The polygon program on the simulated machine: its frame equals the reference rasteriser's,
//! pixel for pixel, and its timing is deterministic.

use pxpl5_machine::{Machine, Recorder, RunOptions};
use pxpl5_polygons::{Polygons, reference::reference_frame, scenes};

fn config(name: &str) -> pxpl5_config::MachineConfig {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../machine-configs");
    pxpl5_config::load_file(&root.join(name)).expect("shipped config")
}

#[test]
fn frame_matches_the_reference_rasteriser() {
    let scene = scenes::random_scene(60, 5, 3.0);
    for cfg_name in ["minimal.ron", "seed-tr89-002.ron"] {
        let cfg = config(cfg_name);
        let program = Polygons::new(scene.clone());
        let machine = Machine::new(&cfg, &program, RunOptions::default(), Recorder::default())
            .expect("builds");
        let result = machine.run().expect("runs");
        let reference = reference_frame(&scene, &cfg);
        let differ = result
            .frame
            .rgb
            .chunks(3)
            .zip(reference.rgb.chunks(3))
            .filter(|(a, b)| a != b)
            .count();
        assert_eq!(
            differ, 0,
            "{cfg_name}: {differ} pixels differ from the reference"
        );
        let lit = reference.rgb.chunks(3).filter(|p| p != &[0, 0, 0]).count();
        assert!(lit > 10_000, "{cfg_name}: only {lit} pixels drawn");
        assert_eq!(result.frame.writes, 1280 * 1024);
        println!("{}", result.stats.table());
    }
}
