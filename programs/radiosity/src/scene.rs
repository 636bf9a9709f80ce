//! The scene file of the radiosity program: named planar convex polygons ("surfaces") with a
//! reflectance and an emission, and an optional camera, in RON; loaded through `pxpl5-config`'s
//! RON loader and checked with the same error reports as machine configs (file, line, column for syntax; for semantic problems the
//! surface by index and name, e.g. `surfaces[3] (left wall).vertices[1]`).
//!
//! ```ron
//! (
//!     name: "one lit square",
//!     provenance: "made up for the docs",
//!     camera: Some((eye: (0.5, 0.5, 3), target: (0.5, 0.5, 0), up: (0, 1, 0),
//!                   fov_y_degrees: 40, near: 0.1, far: 10)),
//!     surfaces: [
//!         // Counter-clockwise seen from +z, so its normal (right-hand rule) is +z.
//!         (name: "floor", object: Some("room"), vertices: [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)],
//!          reflectance: (0.5, 0.5, 0.5)),
//!         (name: "lamp", vertices: [(0, 0, 1), (0, 1, 1), (1, 1, 1), (1, 0, 1)],
//!          reflectance: (0, 0, 0), emission: (1, 1, 1)),
//!     ],
//! )
//! ```
//!
//! A surface is a planar convex polygon of 3 or more vertices, listed counter-clockwise as seen
//! from the side its normal points to (the normal follows the right-hand rule); it reflects and
//! emits on that front side only. [`check_radiosity_scene`] enforces this (and finite numbers,
//! reflectance in [0, 1), non-negative emission) so that the mesher and the form-factor code can
//! rely on it instead of each guarding against degenerate input.

use std::path::Path;

use serde::{Deserialize, Serialize};

use pxpl5_config::{ConfigError, FileKind, SemanticError};
use pxpl5_geom::convex::Corner;
use pxpl5_geom::plane::best_fit_plane;
use pxpl5_geom::polygon::{self, Problem};
use pxpl5_geom::{DVec3, vec3};
use pxpl5_polygons::scene::in_range;
pub use pxpl5_polygons::scene::{Camera, MAX_COORDINATE, Vec3};

/// A scene for the radiosity program.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RadiosityScene {
    /// Short name, for reports.
    pub name: String,
    /// Where the data comes from and how it was adapted (free text).
    #[serde(default)]
    pub provenance: String,
    /// A viewpoint for pictures of the solution; the radiosity solution itself does not need one.
    #[serde(default)]
    pub camera: Option<Camera>,
    /// The polygons, in the order patches are generated.
    pub surfaces: Vec<Surface>,
}

/// One planar convex polygon with its material.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Surface {
    /// Names the surface in error reports and pictures.
    pub name: String,
    /// The object the surface belongs to (e.g. "tall block"), to group surfaces in reports.
    #[serde(default)]
    pub object: Option<String>,
    /// 3 or more vertices, counter-clockwise seen from the front (the normal's side).
    pub vertices: Vec<Vec3>,
    /// Diffuse reflectance per colour band (R, G, B), each in [0, 1).
    pub reflectance: Vec3,
    /// Emitted radiosity per band (R, G, B), each >= 0; zero for a surface that only reflects.
    #[serde(default)]
    pub emission: Vec3,
}

impl RadiosityScene {
    /// A scene of one surface named "poly" (for tests and examples), not checked.
    pub fn one_surface(vertices: &[Vec3], reflectance: Vec3, emission: Vec3) -> RadiosityScene {
        RadiosityScene {
            name: "one".into(),
            provenance: String::new(),
            camera: None,
            surfaces: vec![Surface {
                name: "poly".into(),
                object: None,
                vertices: vertices.to_vec(),
                reflectance,
                emission,
            }],
        }
    }
}

impl RadiosityScene {
    /// Whether no surface can hide part of another from a third: every vertex lies on or in front
    /// of every surface's plane (within [`PLANARITY_TOLERANCE`] of the scene's size), so the
    /// surfaces bound a convex region, as the inside of a box does. Then the exact, unoccluded
    /// form factors of [`crate::solver`] are the true ones and its direct solve is the scene's
    /// reference solution; a scene with anything inside (the Cornell box's blocks) has none.
    pub fn unoccluded(&self) -> bool {
        let all: Vec<DVec3> = self.surfaces.iter().flat_map(|s| s.points()).collect();
        let tolerance = PLANARITY_TOLERANCE * pxpl5_geom::plane::bounding_diagonal(&all);
        self.surfaces.iter().all(|s| {
            s.plane().is_some_and(|plane| {
                all.iter()
                    .all(|&v| plane.normal.dot(v - plane.point) >= -tolerance)
            })
        })
    }
}

impl Surface {
    /// The vertices as vectors.
    pub fn points(&self) -> Vec<DVec3> {
        self.vertices.iter().map(|&v| vec3(v)).collect()
    }

    /// The surface's best-fit plane (Newell's method); `None` where no normal is defined.
    pub fn plane(&self) -> Option<pxpl5_geom::plane::Plane> {
        best_fit_plane(&self.points())
    }
}

/// Largest distance of a vertex from the polygon's plane allowed, relative to its size: the
/// geometry crate's, shared with `pxpl5 formfactor`.
pub use pxpl5_geom::polygon::PLANARITY_TOLERANCE;

/// Read, parse and check a radiosity scene. The file's path (as given) names the source in errors.
pub fn load_radiosity_scene(path: &Path) -> Result<RadiosityScene, ConfigError> {
    let (shown, text) = pxpl5_config::read_text(FileKind::RadiosityScene, path)?;
    parse_radiosity_scene(&shown, &text)
}

/// Parse and check a radiosity scene held in memory; `file_name` names it in errors.
pub fn parse_radiosity_scene(file_name: &str, text: &str) -> Result<RadiosityScene, ConfigError> {
    pxpl5_config::parse_checked(
        FileKind::RadiosityScene,
        file_name,
        text,
        check_radiosity_scene,
    )
}

/// Every problem of a scene, each naming the surface by index and name: no surfaces; numbers that
/// are not finite or beyond [`MAX_COORDINATE`] (coordinates and emissions); fewer than 3 vertices; zero area; non-planar beyond [`PLANARITY_TOLERANCE`] (with the
/// distance); non-convex, including repeated and collinear consecutive vertices; reflectance
/// outside [0, 1); negative emission; a camera that cannot see.
pub fn check_radiosity_scene(scene: &RadiosityScene) -> Result<(), Vec<SemanticError>> {
    let mut errors = Vec::new();
    if scene.surfaces.is_empty() {
        errors.push(SemanticError {
            path: "surfaces".into(),
            value: "[]".into(),
            rule: "must list at least one surface".into(),
        });
    }
    if let Some(camera) = &scene.camera {
        // The triangle scenes' camera rules apply unchanged, with the same `camera.*` paths.
        errors.extend(pxpl5_polygons::scene::check_camera(camera));
    }
    for (i, surface) in scene.surfaces.iter().enumerate() {
        check_surface(
            &format!("surfaces[{i}] ({})", surface.name),
            surface,
            &mut errors,
        );
    }
    if errors.is_empty() {
        Ok(())
    } else {
        Err(errors)
    }
}

/// The checks of one surface; `at` is its path prefix `surfaces[i] (name)`.
fn check_surface(at: &str, s: &Surface, errors: &mut Vec<SemanticError>) {
    let mut err = |path: String, value: String, rule: String| {
        errors.push(SemanticError { path, value, rule })
    };
    let r = s.reflectance;
    if ![r.0, r.1, r.2].iter().all(|c| (0.0..1.0).contains(c)) {
        err(
            format!("{at}.reflectance"),
            format!("{r:?}"),
            "components must be in [0, 1): a reflectance of 1 or more never lets the light \
             converge"
                .into(),
        );
    }
    let e = s.emission;
    if ![e.0, e.1, e.2]
        .iter()
        .all(|c| (0.0..=MAX_COORDINATE).contains(c))
    {
        err(
            format!("{at}.emission"),
            format!("{e:?}"),
            format!(
                "components must be >= 0 and at most {MAX_COORDINATE:e}, so that powers \
                 (emission x area) stay finite"
            ),
        );
    }
    if s.vertices.len() < 3 {
        err(
            format!("{at}.vertices"),
            format!("{} vertices", s.vertices.len()),
            "a surface is a polygon and needs at least 3 vertices".into(),
        );
    }
    let mut all_finite = true;
    for (k, &v) in s.vertices.iter().enumerate() {
        if !in_range(v) {
            all_finite = false;
            err(
                format!("{at}.vertices[{k}]"),
                format!("{v:?}"),
                format!("must be finite numbers of magnitude at most {MAX_COORDINATE:e}"),
            );
        }
    }
    if s.vertices.len() < 3 || !all_finite {
        return;
    }
    let v = s.points();
    let n = v.len();
    for problem in polygon::problems(&v) {
        match problem {
            // Excluded above: 3 or more finite vertices.
            Problem::NotAPolygon => {}
            Problem::ZeroArea => err(
                format!("{at}.vertices"),
                format!("{:?}", s.vertices),
                "has zero area (coincident or collinear vertices)".into(),
            ),
            Problem::NotPlanar {
                vertex,
                distance,
                limit,
            } => err(
                format!("{at}.vertices[{vertex}]"),
                format!(
                    "{:?}, {distance:.6} from the best-fit plane",
                    s.vertices[vertex]
                ),
                format!(
                    "a surface must be planar: every vertex within {PLANARITY_TOLERANCE:e} x the \
                     polygon's size ({limit:.3e}) of its best-fit plane; split it into triangles"
                ),
            ),
            Problem::Corner(Corner::Repeat(k)) => err(
                format!("{at}.vertices[{}]", (k + 1) % n),
                format!("{:?}", s.vertices[(k + 1) % n]),
                format!("repeats vertex {k}: consecutive vertices must differ"),
            ),
            Problem::Corner(Corner::Straight(k)) => err(
                format!("{at}.vertices[{k}]"),
                format!("{:?}", s.vertices[k]),
                "is collinear with its neighbours: remove it (a straight corner has no \
                 defined turn)"
                    .into(),
            ),
            Problem::Corner(Corner::Reflex(k)) => err(
                format!("{at}.vertices[{k}]"),
                format!("{:?}", s.vertices[k]),
                "makes the polygon non-convex (the corner turns clockwise seen from the front, \
                 or folds back); split the surface into convex pieces"
                    .into(),
            ),
            Problem::Crossed { turns } => err(
                format!("{at}.vertices"),
                format!("turns {turns:.1} times around"),
                "is not convex: its edges cross (the outline must wind around once)".into(),
            ),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = r#"(
        name: "test",
        camera: Some((eye: (0.5, 0.5, 3), target: (0.5, 0.5, 0), up: (0, 1, 0),
                      fov_y_degrees: 40, near: 0.1, far: 10)),
        surfaces: [
            (name: "floor", object: Some("room"), vertices: [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)],
             reflectance: (0.5, 0.5, 0.5)),
            (name: "lamp", vertices: [(0, 0, 1), (0, 1, 1), (1, 0, 1)],
             reflectance: (0, 0, 0), emission: (1, 1, 1)),
        ],
    )"#;

    /// The error text of `GOOD` with `from` replaced by `to`.
    fn error_of(from: &str, to: &str) -> String {
        assert!(GOOD.contains(from), "{from}");
        let text = GOOD.replacen(from, to, 1);
        match parse_radiosity_scene("s.ron", &text) {
            Ok(_) => panic!("{to} was accepted"),
            Err(e) => e.to_string(),
        }
    }

    fn surface(vertices: &[Vec3]) -> RadiosityScene {
        RadiosityScene::one_surface(vertices, (0.5, 0.5, 0.5), (0.0, 0.0, 0.0))
    }

    fn errors_of(vertices: &[Vec3]) -> Vec<SemanticError> {
        check_radiosity_scene(&surface(vertices))
            .err()
            .unwrap_or_default()
    }

    #[test]
    fn parses_a_scene_and_the_docs_example() {
        let s = parse_radiosity_scene("s.ron", GOOD).unwrap();
        assert_eq!(s.surfaces.len(), 2);
        assert_eq!(s.surfaces[0].object.as_deref(), Some("room"));
        assert_eq!(s.surfaces[0].emission, (0.0, 0.0, 0.0));
        assert_eq!(s.provenance, "");
        let docs = "(name: \"one lit square\", provenance: \"made up for the docs\", \
            camera: Some((eye: (0.5, 0.5, 3), target: (0.5, 0.5, 0), up: (0, 1, 0), \
            fov_y_degrees: 40, near: 0.1, far: 10)), surfaces: [\
            (name: \"floor\", object: Some(\"room\"), vertices: [(0, 0, 0), (1, 0, 0), (1, 1, 0), \
            (0, 1, 0)], reflectance: (0.5, 0.5, 0.5)), (name: \"lamp\", vertices: [(0, 0, 1), \
            (0, 1, 1), (1, 1, 1), (1, 0, 1)], reflectance: (0, 0, 0), emission: (1, 1, 1))])";
        parse_radiosity_scene("docs.ron", docs).unwrap();
    }

    #[test]
    fn nan_and_infinite_vertices_name_the_surface_and_vertex() {
        let e = error_of("(1, 1, 0)", "(1, NaN, 0)");
        assert!(e.contains("surfaces[0] (floor).vertices[2]"), "{e}");
        assert!(e.contains("finite"), "{e}");
        let e = error_of("(0, 1, 1)", "(0, inf, 1)");
        assert!(e.contains("surfaces[1] (lamp).vertices[1]"), "{e}");
    }

    #[test]
    fn too_few_vertices() {
        let e = error_of("(0, 0, 1), (0, 1, 1), (1, 0, 1)", "(0, 0, 1), (0, 1, 1)");
        assert!(
            e.contains("surfaces[1] (lamp).vertices") && e.contains("2 vertices"),
            "{e}"
        );
        let e = error_of("(0, 0, 1), (0, 1, 1), (1, 0, 1)", "");
        assert!(e.contains("0 vertices"), "{e}");
    }

    #[test]
    fn zero_area() {
        let e = error_of(
            "(0, 0, 1), (0, 1, 1), (1, 0, 1)",
            "(0, 0, 1), (0, 1, 1), (0, 2, 1)",
        );
        assert!(
            e.contains("surfaces[1] (lamp).vertices") && e.contains("zero area"),
            "{e}"
        );
        let e = error_of(
            "(0, 0, 1), (0, 1, 1), (1, 0, 1)",
            "(2, 2, 2), (2, 2, 2), (2, 2, 2)",
        );
        assert!(e.contains("zero area"), "{e}");
    }

    #[test]
    fn non_planar_says_by_how_much() {
        let e = error_of("(1, 1, 0)", "(1, 1, 0.004)");
        assert!(e.contains("surfaces[0] (floor).vertices["), "{e}");
        assert!(
            e.contains("planar") && e.contains("0.001000 from the best-fit plane"),
            "{e}"
        );
        // Within the tolerance: accepted (1e-7 of a size of sqrt(2)).
        let text = GOOD.replacen("(1, 1, 0)", "(1, 1, 1e-7)", 1);
        parse_radiosity_scene("s.ron", &text).unwrap();
    }

    #[test]
    fn non_convex_repeated_collinear_and_crossed() {
        // A reflex corner at vertex 2.
        let e = errors_of(&[
            (0.0, 0.0, 0.0),
            (2.0, 0.0, 0.0),
            (1.0, 0.5, 0.0),
            (1.0, 2.0, 0.0),
        ]);
        assert_eq!(e.len(), 1, "{e:?}");
        assert_eq!(e[0].path, "surfaces[0] (poly).vertices[2]");
        assert!(e[0].rule.contains("non-convex"), "{e:?}");
        // A repeated vertex.
        let e = errors_of(&[
            (0.0, 0.0, 0.0),
            (1.0, 0.0, 0.0),
            (1.0, 0.0, 0.0),
            (0.0, 1.0, 0.0),
        ]);
        assert!(
            e.iter()
                .any(|e| e.path == "surfaces[0] (poly).vertices[2]" && e.rule.contains("repeats")),
            "{e:?}"
        );
        // A collinear middle vertex.
        let e = errors_of(&[
            (0.0, 0.0, 0.0),
            (1.0, 0.0, 0.0),
            (2.0, 0.0, 0.0),
            (0.0, 1.0, 0.0),
        ]);
        assert!(
            e.iter()
                .any(|e| e.path == "surfaces[0] (poly).vertices[1]" && e.rule.contains("collinear")),
            "{e:?}"
        );
        // A folded-back corner (the polygon doubles back along an edge).
        let e = errors_of(&[
            (0.0, 0.0, 0.0),
            (2.0, 0.0, 0.0),
            (1.0, 0.0, 0.0),
            (0.0, 1.0, 0.0),
        ]);
        assert!(!e.is_empty());
        // A pentagram: every corner turns left, but it winds twice.
        let star: Vec<Vec3> = (0..5)
            .map(|k| {
                let a = std::f64::consts::TAU * (2 * k) as f64 / 5.0;
                (a.cos(), a.sin(), 0.0)
            })
            .collect();
        let e = errors_of(&star);
        assert!(
            e.iter()
                .any(|e| e.value.contains("2.0 times") && e.rule.contains("cross")),
            "{e:?}"
        );
        // Clockwise is fine: it only flips the normal.
        assert!(errors_of(&[(0.0, 0.0, 0.0), (0.0, 1.0, 0.0), (1.0, 0.0, 0.0)]).is_empty());
    }

    #[test]
    fn reflectance_and_emission_limits() {
        let e = error_of(
            "reflectance: (0.5, 0.5, 0.5)",
            "reflectance: (0.5, 1.0, 0.5)",
        );
        assert!(
            e.contains("surfaces[0] (floor).reflectance") && e.contains("[0, 1)"),
            "{e}"
        );
        let e = error_of(
            "reflectance: (0.5, 0.5, 0.5)",
            "reflectance: (-0.1, 0.5, NaN)",
        );
        assert!(e.contains("surfaces[0] (floor).reflectance"), "{e}");
        let e = error_of("emission: (1, 1, 1)", "emission: (1, -1, 1)");
        assert!(
            e.contains("surfaces[1] (lamp).emission") && e.contains(">= 0"),
            "{e}"
        );
        let e = error_of("emission: (1, 1, 1)", "emission: (1, inf, 1)");
        assert!(e.contains("surfaces[1] (lamp).emission"), "{e}");
    }

    #[test]
    fn empty_scene_and_empty_file() {
        let e = parse_radiosity_scene("s.ron", "(name: \"x\", surfaces: [])")
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("surfaces: must list at least one surface"),
            "{e}"
        );
        let e = parse_radiosity_scene("s.ron", "").unwrap_err().to_string();
        assert!(e.starts_with("s.ron:1:"), "{e}");
        let e = parse_radiosity_scene("s.ron", "  \n ")
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("s.ron:"), "{e}");
    }

    #[test]
    fn camera_and_field_errors() {
        let e = error_of("fov_y_degrees: 40", "fov_y_degrees: 0");
        assert!(e.contains("camera.fov_y_degrees"), "{e}");
        let e = error_of("reflectance: (0.5", "reflectence: (0.5");
        assert!(e.contains("s.ron:") && e.contains("reflectence"), "{e}");
        // Several problems are all reported.
        let text = GOOD.replacen("(1, 1, 0)", "(1, NaN, 0)", 1).replacen(
            "emission: (1, 1, 1)",
            "emission: (-1, 1, 1)",
            1,
        );
        let err = parse_radiosity_scene("s.ron", &text).unwrap_err();
        assert_eq!(err.semantic_errors().len(), 2, "{err}");
    }

    #[test]
    fn load_reports_missing_and_non_utf8_files() {
        let dir =
            std::env::temp_dir().join(format!("pxpl5-radiosity-scene-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let missing = dir.join("missing.ron");
        let err = load_radiosity_scene(&missing).unwrap_err();
        assert!(matches!(err, ConfigError::Io { .. }));
        // The report names the kind of file: a scene, not a machine config.
        let text = err.to_string();
        assert!(
            text.contains("missing.ron: cannot read radiosity scene"),
            "{text}"
        );
        let bad = dir.join("bad.ron");
        std::fs::write(&bad, b"(name: \"\xff\")").unwrap();
        assert!(matches!(
            load_radiosity_scene(&bad),
            Err(ConfigError::NotUtf8 { .. })
        ));
        let good = dir.join("good.ron");
        std::fs::write(&good, GOOD).unwrap();
        assert_eq!(load_radiosity_scene(&good).unwrap().surfaces.len(), 2);
        let _ = std::fs::remove_dir_all(&dir);
    }
}
