//! Item buffers of a shot: one per view, each named uniquely (a hemisphere cut into 3 x 3 tiles
//! once gave tiles (2, 0) and (0, 1) the same name, so one overwrote the other), each filled.

use pxpl5_machine::{Machine, Recorder, RunOptions};
use pxpl5_radiosity::mesh::mesh;
use pxpl5_radiosity::program::RadiosityProgram;
use pxpl5_radiosity::scenes;
use pxpl5_radiosity::shot::{FfOptions, Method};

#[test]
fn a_hemisphere_of_nine_tiles_keeps_nine_item_buffers() {
    // The seed machine with nine Renderers: a disk of 300 pixels needs 3 x 3 boards of 128.
    let mut cfg = pxpl5_config::default_config();
    cfg.renderer.count = 9;
    let patches = mesh(&scenes::cornell_box(), 300.0).expect("meshes");
    let options = FfOptions {
        method: Method::Hemisphere,
        resolution: 300,
        ..FfOptions::default()
    };
    let mut program = RadiosityProgram::new(patches, options, 1, 0.0);
    program.item_shots = vec![0];
    let run = Machine::new(&cfg, &program, RunOptions::default(), Recorder::default())
        .expect("builds")
        .run()
        .expect("runs");
    let items = program.item_buffers.borrow();
    assert_eq!(items.len(), 1);
    let buffers = items[0].1.borrow();
    let mut names: Vec<&str> = buffers.iter().map(|b| b.view.as_str()).collect();
    names.sort_unstable();
    let want: Vec<String> = (0..9)
        .map(|t| format!("shooter0-hemisphere-tile{t}"))
        .collect();
    assert_eq!(names, want);
    // The centre tile looks straight down at the floor; the box's open front leaves at most a
    // few outer tiles seeing nothing.
    let drawn: Vec<bool> = want
        .iter()
        .map(|name| {
            let b = buffers.iter().find(|b| &b.view == name).expect("named");
            b.ids.iter().any(|&id| id != 0)
        })
        .collect();
    assert!(drawn[4], "the centre tile is empty");
    assert!(drawn.iter().filter(|&&d| d).count() >= 6, "{drawn:?}");
    // Bounded by simulated time: one shot on nine boards.
    assert!(run.stats.end.as_secs_f64() < 0.05, "{:?}", run.stats.end);
}
