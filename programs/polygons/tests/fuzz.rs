//! Fuzz target of the triangle-scene parser and checks (see `pxpl5_tests::fuzzing`): the shipped
//! scene, mutated, and scenes built from extreme numbers never make the loader panic; an error
//! is a proper report; an accepted scene projects to finite screen triangles whose expressions
//! quantise in every region, and draws on the machine exactly the reference picture.

use proptest::prelude::*;
use pxpl5_machine::{Machine, Recorder, RunOptions};
use pxpl5_polygons::Polygons;
use pxpl5_polygons::geometry::{View, triangle_exprs};
use pxpl5_polygons::reference::reference_frame;
use pxpl5_polygons::scene::{Camera, Triangle, TriangleScene, parse_triangle_scene};
use pxpl5_polygons::{Screen, scenes};
use pxpl5_tests::fuzzing::{config, count, extreme_f64, loaded, mutated, shipped, small_machine};

/// What must hold for any text: an error is a short report naming the file; an accepted scene
/// projects, quantises and draws the reference picture.
fn check(name: &str, text: &str) -> Result<(), TestCaseError> {
    match loaded(name, parse_triangle_scene(name, text))? {
        Some(scene) => draws(&scene),
        None => Ok(()),
    }
}

fn draws(scene: &TriangleScene) -> Result<(), TestCaseError> {
    let cfg = small_machine();
    let (fw, fh) = (cfg.frame_buffer.width, cfg.frame_buffer.height);
    let side = cfg.renderer.width.min(cfg.renderer.height);
    let screen = Screen::new(fw, fh, side);
    let view = View::new(&scene.camera, fw, fh);
    for i in 0..scene.triangles.len() {
        for t in view.project(scene, i) {
            prop_assert!(t.xyz.iter().flatten().all(|c| c.is_finite()), "{:?}", t);
            for k in 0..screen.regions() {
                let (x0, y0) = screen.origin(k);
                let exprs = triangle_exprs(&t, x0, y0, side, cfg.renderer.qee.coefficient_format);
                prop_assert!(exprs.is_ok(), "triangle {}: {:?}", i, exprs);
            }
        }
    }
    let program = Polygons::new(scene.clone());
    let run = Machine::new(&cfg, &program, RunOptions::default(), Recorder::default())
        .and_then(Machine::run);
    let frame = run
        .map_err(|e| TestCaseError::fail(format!("the run failed: {e}")))?
        .frame;
    prop_assert!(
        frame.rgb == reference_frame(scene, &cfg).rgb,
        "not the reference picture"
    );
    Ok(())
}

/// A point of ordinary coordinates, now and then an extreme one (one in sixteen coordinates, so
/// that a fair share of scenes pass the checks).
fn point() -> impl Strategy<Value = (f64, f64, f64)> {
    let c = prop_oneof![15 => -12.0f64..12.0, 1 => extreme_f64()];
    (c.clone(), c.clone(), c)
}

/// A scene of 1 to 4 triangles and a camera with extreme numbers in any field.
fn built() -> impl Strategy<Value = TriangleScene> {
    let camera = (
        point(),
        point(),
        point(),
        prop_oneof![6 => 1.0f64..179.0, 1 => extreme_f64()],
        prop_oneof![6 => 0.01f64..5.0, 1 => extreme_f64()],
        prop_oneof![6 => 5.0f64..100.0, 1 => extreme_f64()],
    )
        .prop_map(|(eye, target, up, fov_y_degrees, near, far)| {
            let d = scenes::default_camera();
            // Half the fields keep the default camera's values, so that many cameras can see.
            let pick = |a: (f64, f64, f64), b| if a.0 < 0.0 { b } else { a };
            Camera {
                eye: pick(eye, d.eye),
                target: pick(target, d.target),
                up: pick(up, d.up),
                fov_y_degrees,
                near,
                far,
            }
        });
    let colour = (0.0f64..=1.0, 0.0f64..=1.0, 0.0f64..=1.0);
    let triangle = (
        prop::collection::vec(point(), 3),
        prop::collection::vec(colour, 3),
    )
        .prop_map(|(vertices, colours)| Triangle { vertices, colours });
    (camera, prop::collection::vec(triangle, 1..5))
        .prop_map(|(camera, triangles)| TriangleScene { camera, triangles })
}

proptest! {
    // About 10 ms a case that draws (most of them), in the test profile.
    #![proptest_config(config(1_000))]

    #[test]
    fn fuzz_triangle_scene_files((name, text) in mutated(shipped("programs/polygons/scenes"))) {
        check(&name, &text)?;
    }

    /// Built scenes go through the checks as a file would.
    #[test]
    fn fuzz_triangle_scenes_built(scene in built()) {
        if pxpl5_polygons::scene::check_triangle_scene(&scene).is_ok() {
            draws(&scene)?;
        }
    }
}

/// Both targets reach both paths: some scenes are refused, some accepted and drawn.
#[test]
fn fuzz_triangle_scenes_reach_both_paths() {
    let files = mutated(shipped("programs/polygons/scenes"));
    let parsed = count(&files, 400, |(name, text)| {
        parse_triangle_scene(name, text).is_ok()
    });
    let checked = |s: &TriangleScene| pxpl5_polygons::scene::check_triangle_scene(s).is_ok();
    let built_ok = count(&built(), 400, checked);
    assert!(
        (40..360).contains(&parsed),
        "{parsed} of 400 files accepted"
    );
    assert!(
        (40..360).contains(&built_ok),
        "{built_ok} of 400 built scenes accepted"
    );
}
