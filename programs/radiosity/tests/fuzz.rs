//! Fuzz target of the radiosity-scene parser and checks (see `pxpl5_tests::fuzzing`): the
//! shipped scenes, mutated, never make the loader panic; an error is a proper report; an
//! accepted scene meshes (or says the patch size is too small), solves to finite radiosities,
//! and its picture (triangles of checked coordinates and colours in 0..1) draws on the machine.

use proptest::prelude::*;
use pxpl5_machine::RunOptions;
use pxpl5_polygons::scene::in_range;
use pxpl5_radiosity::mesh::{MeshError, mesh};
use pxpl5_radiosity::picture::{render, triangle_scene};
use pxpl5_radiosity::program::Solution;
use pxpl5_radiosity::scene::{RadiosityScene, parse_radiosity_scene};
use pxpl5_radiosity::solver::{exact_matrix, progressive};
use pxpl5_tests::fuzzing::{config, count, loaded, mutated, shipped, small_machine};

/// Most patches a case solves exactly (the exact form factors are quadratic in them).
const MAX_SOLVED: usize = 120;

/// The scene's size: the longest side of its bounding box.
fn size(scene: &RadiosityScene) -> f64 {
    let points = scene.surfaces.iter().flat_map(|s| s.points());
    let (lo, hi) = points.fold(([f64::MAX; 3], [f64::MIN; 3]), |(lo, hi), p| {
        let p = p.to_array();
        (
            [0, 1, 2].map(|k| lo[k].min(p[k])),
            [0, 1, 2].map(|k| hi[k].max(p[k])),
        )
    });
    (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max)
}

fn check(name: &str, text: &str) -> Result<(), TestCaseError> {
    let Some(scene) = loaded(name, parse_radiosity_scene(name, text))? else {
        return Ok(());
    };
    // A few patches per side of the scene.
    let patches = match mesh(&scene, size(&scene) / 3.0) {
        Ok(patches) => patches,
        Err(MeshError::TooManyPatches { .. }) => return Ok(()),
        Err(e) => return Err(TestCaseError::fail(format!("a checked scene: {e}"))),
    };
    prop_assert!(
        patches
            .iter()
            .all(|p| p.area > 0.0 && p.area.is_finite() && p.centre.is_finite()),
        "degenerate patches"
    );
    if patches.len() > MAX_SOLVED {
        return Ok(());
    }
    let radiosity = progressive(&patches, &exact_matrix(&patches), 1e-3, 50);
    prop_assert!(
        radiosity
            .iter()
            .flatten()
            .all(|b| b.is_finite() && *b >= 0.0),
        "radiosity {:?}",
        radiosity
    );
    let Some(camera) = scene.camera.clone() else {
        return Ok(());
    };
    let solution = Solution {
        unshot: vec![[0.0; 3]; patches.len()],
        radiosity,
        ..Solution::default()
    };
    // The picture's triangles: vertices the scene checks accept and colours in 0..1 (slivers
    // of a long thin surface may be thinner than a triangle scene file allows; the program
    // draws them all the same).
    let picture = triangle_scene(&patches, &solution, camera.clone());
    for t in &picture.triangles {
        prop_assert!(t.vertices.iter().all(|&v| in_range(v)), "{:?}", t);
        let colours = t.colours.iter().flat_map(|c| [c.0, c.1, c.2]);
        prop_assert!(colours.clone().all(|c| (0.0..=1.0).contains(&c)), "{:?}", t);
    }
    let run = render(
        &small_machine(),
        &patches,
        &solution,
        camera,
        RunOptions::default(),
    );
    prop_assert!(
        run.is_ok(),
        "the picture: {}",
        run.err().map(|e| e.to_string()).unwrap_or_default()
    );
    Ok(())
}

proptest! {
    // Up to about 50 ms a case that solves and draws, in the test profile.
    #![proptest_config(config(500))]

    #[test]
    fn fuzz_radiosity_scene_files((name, text) in mutated(shipped("programs/radiosity/scenes"))) {
        check(&name, &text)?;
    }
}

/// The mutations reach both paths: some scenes are refused, some accepted.
#[test]
fn fuzz_radiosity_scenes_reach_both_paths() {
    let files = mutated(shipped("programs/radiosity/scenes"));
    let parsed = count(&files, 400, |(name, text)| {
        parse_radiosity_scene(name, text).is_ok()
    });
    assert!(
        (40..360).contains(&parsed),
        "{parsed} of 400 files accepted"
    );
}
