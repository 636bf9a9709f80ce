//! The radiosity program's built-in scenes: the Cornell box, the Cornell box without its blocks
//! and a closed unit box, embedded from
//! `programs/radiosity/scenes/*.ron` so the program runs without files, and closed boxes of any
//! size built in code for tests at other scales.
//!
//! The scene format (and its checks) lives in [`crate::scene`].

pub use crate::scene::{RadiosityScene, Surface};

use crate::scene::parse_radiosity_scene;

/// The text of `scenes/cornell-box.ron`: the Cornell box in millimetres, open at z = 0.
pub const CORNELL_BOX: &str = include_str!("../scenes/cornell-box.ron");

/// The text of `scenes/cornell-empty.ron`: the Cornell box's shell, materials, light and open
/// front, without the two blocks.
pub const CORNELL_EMPTY: &str = include_str!("../scenes/cornell-empty.ron");

/// The text of `scenes/empty-box.ron`: a closed unit box whose top face emits.
pub const EMPTY_BOX: &str = include_str!("../scenes/empty-box.ron");

/// The Cornell box, parsed from [`CORNELL_BOX`].
///
/// # Panics
/// Never in a released build: the embedded file is parsed and checked by this crate's tests.
pub fn cornell_box() -> RadiosityScene {
    parse_radiosity_scene("cornell-box.ron", CORNELL_BOX)
        .expect("the embedded cornell-box.ron is tested to parse and check")
}

/// The Cornell box without its blocks, parsed from [`CORNELL_EMPTY`]: [`cornell_box`]'s
/// surfaces of the shell and the light, in the same order, nothing else changed.
///
/// # Panics
/// Never in a released build: the embedded file is parsed and checked by this crate's tests.
pub fn cornell_empty() -> RadiosityScene {
    parse_radiosity_scene("cornell-empty.ron", CORNELL_EMPTY)
        .expect("the embedded cornell-empty.ron is tested to parse and check")
}

/// The closed unit box, parsed from [`EMPTY_BOX`]; its surfaces equal `closed_box(1.0, 0.5)`'s.
///
/// # Panics
/// Never in a released build: the embedded file is parsed and checked by this crate's tests.
pub fn empty_box() -> RadiosityScene {
    parse_radiosity_scene("empty-box.ron", EMPTY_BOX)
        .expect("the embedded empty-box.ron is tested to parse and check")
}

/// A closed axis-aligned cube `[0, size]^3` (y up): six inward-facing squares of grey
/// `reflectance`, the top one (the ceiling) also emitting 1 in every band. No camera.
///
/// Same surfaces, names and vertex order as `scenes/empty-box.ron`, scaled; the result is not
/// checked here (a `size` that is zero or not finite, or a reflectance outside [0, 1), gives a
/// scene that [`crate::scene::check_radiosity_scene`] rejects).
pub fn closed_box(size: f64, reflectance: f64) -> RadiosityScene {
    let s = size;
    // Corner patterns with normals into the box (right-hand rule), as in empty-box.ron.
    let faces = [
        (
            "floor",
            [(s, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, s), (s, 0.0, s)],
        ),
        (
            "ceiling",
            [(s, s, 0.0), (s, s, s), (0.0, s, s), (0.0, s, 0.0)],
        ),
        (
            "wall -x",
            [(0.0, 0.0, s), (0.0, 0.0, 0.0), (0.0, s, 0.0), (0.0, s, s)],
        ),
        (
            "wall +x",
            [(s, 0.0, 0.0), (s, 0.0, s), (s, s, s), (s, s, 0.0)],
        ),
        (
            "wall -z",
            [(0.0, 0.0, 0.0), (s, 0.0, 0.0), (s, s, 0.0), (0.0, s, 0.0)],
        ),
        (
            "wall +z",
            [(s, 0.0, s), (0.0, 0.0, s), (0.0, s, s), (s, s, s)],
        ),
    ];
    let surfaces = faces
        .iter()
        .map(|(name, vertices)| Surface {
            name: (*name).to_string(),
            object: Some("box".to_string()),
            vertices: vertices.to_vec(),
            reflectance: (reflectance, reflectance, reflectance),
            emission: if *name == "ceiling" {
                (1.0, 1.0, 1.0)
            } else {
                (0.0, 0.0, 0.0)
            },
        })
        .collect();
    RadiosityScene {
        name: format!("closed box of side {size}"),
        provenance: "built in code (scenes::closed_box): closed cube, top face emitting; form \
                     factors from any point inside sum to 1"
            .to_string(),
        camera: None,
        surfaces,
    }
}
