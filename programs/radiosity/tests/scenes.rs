//! Tests of the built-in scenes (the Cornell box, with and without its blocks, and the closed
//! box): they are valid, they mesh,
//! their normals face the right way, the Cornell box's quirks are handled as its header says;
//! and bad scene files give errors that name the surface, never a panic.

use pxpl5_geom::DVec3;
use pxpl5_radiosity::exact::point_to_polygon;
use pxpl5_radiosity::mesh::{MeshError, mesh};
use pxpl5_radiosity::scene::{RadiosityScene, check_radiosity_scene, parse_radiosity_scene};
use pxpl5_radiosity::scenes::{
    CORNELL_BOX, CORNELL_EMPTY, EMPTY_BOX, closed_box, cornell_box, cornell_empty, empty_box,
};

fn close(a: f64, b: f64, rel: f64) -> bool {
    (a - b).abs() <= rel * a.abs().max(b.abs())
}

fn object(scene: &RadiosityScene, k: usize) -> &str {
    scene.surfaces[k].object.as_deref().unwrap_or("")
}

#[test]
fn built_in_scenes_are_valid_and_mesh() {
    let cornell = cornell_box();
    check_radiosity_scene(&cornell).unwrap();
    assert_eq!(cornell.surfaces.len(), 20);
    let patches = mesh(&cornell, 50.0).unwrap();
    assert!(patches.len() > 20, "{}", patches.len());
    assert!(patches.iter().all(|p| p.area > 0.0 && p.centre.is_finite()));
    let area: f64 = cornell
        .surfaces
        .iter()
        .map(|s| s.plane().unwrap().area)
        .sum();
    let meshed: f64 = patches.iter().map(|p| p.area).sum();
    assert!(close(area, meshed, 1e-12), "{area} {meshed}");

    let empty = empty_box();
    check_radiosity_scene(&empty).unwrap();
    assert_eq!(mesh(&empty, 0.25).unwrap().len(), 6 * 16);
    // The file and the code build the same box.
    assert_eq!(empty.surfaces, closed_box(1.0, 0.5).surfaces);
    assert!(EMPTY_BOX.contains("sum to 1"));
}

#[test]
fn cornell_empty_is_the_cornell_box_without_its_blocks() {
    let empty = cornell_empty();
    check_radiosity_scene(&empty).unwrap();
    let full = cornell_box();
    // The same surfaces, in the same order, minus the blocks': names, objects, vertices,
    // materials alike.
    let shell: Vec<_> = full
        .surfaces
        .iter()
        .enumerate()
        .filter(|&(k, _)| !object(&full, k).ends_with("block"))
        .map(|(_, s)| s.clone())
        .collect();
    assert_eq!(shell.len(), 10);
    assert_eq!(empty.surfaces, shell);
    assert_eq!(
        full.surfaces.len() - shell.len(),
        10,
        "two blocks of five faces"
    );
    // Same camera and opening; it meshes into the Cornell box's patches minus the blocks'.
    assert_eq!(empty.camera, full.camera);
    let patches = mesh(&empty, 90.0).unwrap();
    let full_patches = mesh(&full, 90.0).unwrap();
    let blocks = full_patches
        .iter()
        .filter(|p| object(&full, p.surface).ends_with("block"))
        .count();
    assert_eq!(patches.len(), full_patches.len() - blocks);
    assert!(patches.iter().all(|p| p.area > 0.0 && p.centre.is_finite()));
    let area: f64 = patches.iter().map(|p| p.area).sum();
    let shell_area: f64 = shell.iter().map(|s| s.plane().unwrap().area).sum();
    assert!(close(area, shell_area, 1e-12), "{area} {shell_area}");
    // Nothing inside hides anything: every vertex lies on or in front of every surface's plane
    // (the shell is convex), as the header says; the blocks hide parts of the floor.
    assert!(empty.unoccluded());
    assert!(!full.unoccluded());
    assert!(pxpl5_radiosity::scenes::empty_box().unoccluded());
    // Open at the front, closed behind, as the Cornell box's shell.
    let p = DVec3::new(278.0, 274.0, 280.0);
    let faces: Vec<Vec<DVec3>> = empty.surfaces.iter().map(|s| s.points()).collect();
    let sum = |n: DVec3| -> f64 { faces.iter().map(|f| point_to_polygon(p, n, f)).sum() };
    assert!((sum(DVec3::Z) - 1.0).abs() < 1e-9);
    assert!(sum(DVec3::NEG_Z) < 0.7);
    for word in ["without its two blocks", "cornell-box.ron", "sum to 1"] {
        assert!(CORNELL_EMPTY.contains(word), "{word}");
    }
    assert_eq!(empty.name, "Cornell box, empty");
    assert!(empty.provenance.contains("without the two blocks"));
}

#[test]
fn cornell_light_and_ceiling_areas() {
    let cornell = cornell_box();
    let patches = mesh(&cornell, 20.0).unwrap();
    let light: f64 = patches
        .iter()
        .filter(|p| object(&cornell, p.surface) == "light")
        .map(|p| p.area)
        .sum();
    assert!(close(light, 130.0 * 105.0, 1e-12), "{light}");
    // Only the light emits, with the page's emission.
    let emitting: f64 = patches
        .iter()
        .filter(|p| p.emission != [0.0; 3])
        .map(|p| p.area)
        .sum();
    assert_eq!(emitting, light);
    assert!(
        patches
            .iter()
            .filter(|p| p.emission != [0.0; 3])
            .all(|p| p.emission == [17.0, 11.8, 4.0] && p.reflectance == [0.0; 3])
    );
    // The four ceiling pieces and the light tile the page's ceiling exactly.
    let ceiling: f64 = cornell
        .surfaces
        .iter()
        .filter(|s| s.name.starts_with("ceiling") || s.name == "light")
        .map(|s| s.plane().unwrap().area)
        .sum();
    assert!(close(ceiling, 556.0 * 559.2, 1e-12), "{ceiling}");
}

#[test]
fn cornell_normals_point_into_the_box_and_out_of_the_blocks() {
    let cornell = cornell_box();
    let centre = DVec3::new(278.0, 274.0, 280.0);
    let mut counts = [0; 3];
    for (k, s) in cornell.surfaces.iter().enumerate() {
        let plane = s.plane().unwrap();
        match object(&cornell, k) {
            "shell" | "light" => {
                counts[0] += 1;
                let side = plane.normal.dot(centre - plane.point);
                assert!(side > 0.0, "{} faces away from the box's centre", s.name);
            }
            block @ ("short block" | "tall block") => {
                counts[if block == "short block" { 1 } else { 2 }] += 1;
                // The block's centre: the mean of all its vertices (it is convex).
                let vertices: Vec<_> = cornell
                    .surfaces
                    .iter()
                    .enumerate()
                    .filter(|&(j, _)| object(&cornell, j) == block)
                    .flat_map(|(_, s)| s.points())
                    .collect();
                let n = vertices.len() as f64;
                let block_centre = vertices.iter().sum::<DVec3>() / n;
                let side = plane.normal.dot(block_centre - plane.point);
                assert!(side < 0.0, "{} faces into its block", s.name);
            }
            other => panic!("unexpected object {other:?} of {}", s.name),
        }
    }
    // 9 shell pieces and the light; five faces per block (no bottoms).
    assert_eq!(counts, [10, 5, 5]);
    // Spot checks of the main directions.
    let normal_of = |name: &str| {
        let s = cornell.surfaces.iter().find(|s| s.name == name).unwrap();
        s.plane().unwrap().normal
    };
    assert_eq!(normal_of("floor"), DVec3::Y);
    assert_eq!(normal_of("light"), DVec3::NEG_Y);
    assert_eq!(normal_of("ceiling, front of light"), DVec3::NEG_Y);
    assert_eq!(normal_of("back wall"), DVec3::NEG_Z);
    assert_eq!(normal_of("right wall"), DVec3::X);
    assert!(normal_of("left wall, floor side").x < -0.99);
    assert!(normal_of("left wall, ceiling side").x < -0.99);
    // The empty box's faces point into it too.
    for s in empty_box().surfaces {
        let plane = s.plane().unwrap();
        assert!(
            plane.normal.dot(DVec3::splat(0.5) - plane.point) > 0.0,
            "{}",
            s.name
        );
    }
}

#[test]
fn cornell_shell_is_closed_except_the_opening() {
    // Looking from the centre away from the opening, the shell (walls, floor, ceiling pieces and
    // light, which do not overlap) fills the whole hemisphere: the quirk fixes left no gaps.
    let cornell = cornell_box();
    let shell: Vec<Vec<DVec3>> = cornell
        .surfaces
        .iter()
        .enumerate()
        .filter(|&(k, _)| matches!(object(&cornell, k), "shell" | "light"))
        .map(|(_, s)| s.points())
        .collect();
    let p = DVec3::new(278.0, 274.0, 280.0);
    let sum = |n: DVec3| -> f64 { shell.iter().map(|f| point_to_polygon(p, n, f)).sum() };
    let back = sum(DVec3::Z);
    assert!((back - 1.0).abs() < 1e-9, "{back}");
    // Facing the opening, much of the light escapes: the form factors do not sum to 1.
    let front = sum(DVec3::NEG_Z);
    assert!(front < 0.7, "{front}");
}

#[test]
fn cornell_header_and_camera() {
    let cornell = cornell_box();
    let camera = cornell.camera.as_ref().unwrap();
    assert_eq!(camera.eye, (278.0, 273.0, -800.0));
    assert_eq!(camera.target, (278.0, 273.0, 0.0));
    assert_eq!(camera.up, (0.0, 1.0, 0.0));
    let fov = 2.0 * (12.5f64 / 35.0).atan().to_degrees();
    assert!((camera.fov_y_degrees - fov).abs() < 1e-12, "{fov}");
    assert_eq!((camera.near, camera.far), (10.0, 3000.0));
    for word in [
        "Cornell Box Data",
        "not planar",
        "hole",
        "receive nothing",
        "sum to 1",
    ] {
        assert!(CORNELL_BOX.contains(word), "{word}");
    }
    assert!(cornell.provenance.contains("Cornell"));
}

#[test]
fn the_pages_red_wall_is_rejected_as_non_planar() {
    let mut cornell = cornell_box();
    let k = cornell
        .surfaces
        .iter()
        .position(|s| s.name == "left wall, floor side")
        .unwrap();
    cornell.surfaces[k].name = "left wall".into();
    cornell.surfaces[k].vertices = vec![
        (552.8, 0.0, 0.0),
        (549.6, 0.0, 559.2),
        (556.0, 548.8, 559.2),
        (556.0, 548.8, 0.0),
    ];
    let errors = check_radiosity_scene(&cornell).unwrap_err();
    assert_eq!(errors.len(), 1, "{errors:?}");
    let e = errors[0].to_string();
    assert!(
        e.starts_with(&format!("surfaces[{k}] (left wall).vertices[")),
        "{e}"
    );
    assert!(
        e.contains("0.799966 from the best-fit plane") && e.contains("planar"),
        "{e}"
    );
}

/// The error text of the Cornell box file with the first `from` replaced by `to`.
fn cornell_error(from: &str, to: &str) -> String {
    assert!(CORNELL_BOX.contains(from), "{from}");
    let text = CORNELL_BOX.replacen(from, to, 1);
    match parse_radiosity_scene("cornell-box.ron", &text) {
        Ok(_) => panic!("{to} was accepted"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn bad_scenes_name_the_surface() {
    let e = cornell_error("(552.8, 0, 0), (0, 0, 0)", "(NaN, 0, 0), (0, 0, 0)");
    assert!(
        e.contains("surfaces[0] (floor).vertices[0]: must be finite"),
        "{e}"
    );
    let e = cornell_error(
        "(0, 548.8, 0), (0, 548.8, 559.2)]",
        "(0, inf, 0), (0, 548.8, 559.2)]",
    );
    assert!(e.contains("surfaces[6] (right wall).vertices[2]"), "{e}");
    // Zero area: the light squashed onto a line.
    let e = cornell_error(
        "(213, 548.8, 332), (213, 548.8, 227)]",
        "(343, 548.8, 332), (343, 548.8, 227)]",
    );
    assert!(
        e.contains("surfaces[9] (light).vertices") && e.contains("zero area"),
        "{e}"
    );
    // Non-convex: the back wall's corner pushed inward.
    let e = cornell_error(
        "(0, 0, 559.2), (0, 548.8, 559.2), (556",
        "(300, 400, 559.2), (0, 548.8, 559.2), (556",
    );
    assert!(
        e.contains("surfaces[5] (back wall).vertices[1]") && e.contains("non-convex"),
        "{e}"
    );
    // Non-planar: the floor's corner lifted by 1 mm.
    let e = cornell_error("(549.6, 0, 559.2)]", "(549.6, 1, 559.2)]");
    assert!(
        e.contains("surfaces[0] (floor).vertices[") && e.contains("planar"),
        "{e}"
    );
    // Reflectance and emission.
    let e = cornell_error("reflectance: (0.1319", "reflectance: (1.1319");
    assert!(e.contains("surfaces[6] (right wall).reflectance"), "{e}");
    let e = cornell_error("emission: (17.0", "emission: (-17.0");
    assert!(e.contains("surfaces[9] (light).emission"), "{e}");
    // Empty file, empty surface list, a misspelt field.
    let e = parse_radiosity_scene("x.ron", "").unwrap_err().to_string();
    assert!(e.starts_with("x.ron:1:"), "{e}");
    let e = parse_radiosity_scene("x.ron", "(name: \"x\", surfaces: [])")
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("surfaces: must list at least one surface"),
        "{e}"
    );
    let e = cornell_error("reflectance: (0.1319", "reflectence: (0.1319");
    assert!(
        e.contains("cornell-box.ron:") && e.contains("reflectence"),
        "{e}"
    );
    // The mesher refuses invalid scenes built in code, naming the surface too.
    let mut bad = closed_box(1.0, 0.5);
    bad.surfaces[3].vertices[2].1 = f64::INFINITY;
    let e = mesh(&bad, 0.5).unwrap_err();
    assert!(matches!(e, MeshError::InvalidScene(_)));
    assert!(
        e.to_string().contains("surfaces[3] (wall +x).vertices[2]"),
        "{e}"
    );
    let mut bad = closed_box(1.0, 0.5);
    bad.surfaces.clear();
    assert!(mesh(&bad, 0.5).is_err());
    assert!(check_radiosity_scene(&closed_box(0.0, 0.5)).is_err());
    assert!(check_radiosity_scene(&closed_box(f64::NAN, 0.5)).is_err());
    assert!(check_radiosity_scene(&closed_box(1.0, 1.0)).is_err());
}

/// Deterministic pseudo-random test inputs: the project's seeded generator.
struct Rng(pxpl5_geom::rng::Lcg);

impl Rng {
    fn below(&mut self, n: usize) -> usize {
        self.0.below(n as u64) as usize
    }
}

#[test]
fn garbage_never_panics() {
    const ALPHABET: &[&str] = &[
        "(", ")", "[", "]", ",", ":", ".", "-", "0", "1", "9", "e", "e999", "NaN", "inf", " ",
        "\"", "\n", "Some(", "None", "vertices", "surfaces", "1e-300", "é", "//", "/*",
    ];
    let mut rng = Rng(pxpl5_geom::rng::Lcg::new(1989));
    let chars: Vec<char> = CORNELL_BOX.chars().collect();
    let mut accepted = 0;
    for round in 0..400 {
        let mut text = chars.clone();
        for _ in 0..1 + rng.below(4) {
            let at = rng.below(text.len() + 1);
            match rng.below(4) {
                0 => {
                    let end = (at + rng.below(40)).min(text.len());
                    text.drain(at..end);
                }
                1 => {
                    let piece = ALPHABET[rng.below(ALPHABET.len())];
                    text.splice(at..at, piece.chars());
                }
                2 => text.truncate(at),
                _ => {
                    // Swap a digit for another, the commonest harmless-looking corruption.
                    let digit = char::from(b'0' + rng.below(10) as u8);
                    if let Some(c) = text.get_mut(at).filter(|c| c.is_ascii_digit()) {
                        *c = digit;
                    }
                }
            }
        }
        let text: String = text.into_iter().collect();
        match parse_radiosity_scene("garbage.ron", &text) {
            Ok(scene) => {
                accepted += 1;
                // Whatever was accepted is checked, so it meshes (or says it would be too fine,
                // if an edit made the box huge).
                match mesh(&scene, 100.0) {
                    Ok(patches) => {
                        assert!(patches.iter().all(|p| p.area.is_finite()), "round {round}")
                    }
                    Err(MeshError::TooManyPatches { .. }) => {}
                    Err(e) => panic!("round {round}: {e}"),
                }
            }
            Err(e) => assert!(!e.to_string().is_empty(), "round {round}"),
        }
    }
    // Some edits (a digit changed in a harmless place) leave a valid scene: both paths run.
    assert!(accepted > 0);
    // Pure noise.
    for _ in 0..200 {
        let len = rng.below(60);
        let text: String = (0..len)
            .map(|_| ALPHABET[rng.below(ALPHABET.len())])
            .collect();
        let _ = parse_radiosity_scene("noise.ron", &text);
    }
}

/// Emissions and coordinates whose powers or projections cannot be represented are refused at
/// load, naming the field (issue 9: an emission of 1e308 panicked in the picture's quantisation).
#[test]
fn emissions_and_coordinates_are_bounded() {
    use pxpl5_radiosity::scene::MAX_COORDINATE;
    let e = cornell_error(
        "emission: (17.0, 11.8, 4.0)",
        "emission: (1e308, 1e308, 1e308)",
    );
    assert!(e.contains("(light).emission") && e.contains("1e12"), "{e}");
    let e = cornell_error("fov_y_degrees: 39.30764811610662", "fov_y_degrees: 1e-300");
    assert!(e.contains("camera.fov_y_degrees"), "{e}");
    let e = cornell_error("(556, 548.8, 227)", "(5.56e300, 548.8, 227)");
    assert!(e.contains(".vertices[") && e.contains("magnitude"), "{e}");
    // The bounds themselves are accepted, and such a scene solves to finite radiosities, which
    // the picture's tone map can show.
    let mut big = closed_box(MAX_COORDINATE, 0.5);
    big.surfaces[0].emission = (MAX_COORDINATE, MAX_COORDINATE, MAX_COORDINATE);
    check_radiosity_scene(&big).unwrap();
    let patches = mesh(&big, MAX_COORDINATE / 2.0).unwrap();
    let f = pxpl5_radiosity::solver::exact_matrix(&patches);
    let radiosity = pxpl5_radiosity::solver::progressive(&patches, &f, 1e-6, 1000);
    assert!(
        radiosity
            .iter()
            .flatten()
            .all(|b| b.is_finite() && *b >= 0.0),
        "{radiosity:?}"
    );
    assert!(radiosity.iter().flatten().any(|b| *b > 1e11));
}
