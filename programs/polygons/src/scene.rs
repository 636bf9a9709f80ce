//! The triangle-scene file of the polygon program: a camera and triangles with per-vertex colours,
//! in RON, loaded through `pxpl5-config`'s RON loader, so errors read as machine configs' do (file,
//! line, column for syntax; the triangle's index and field for semantic problems).
//!
//! ```ron
//! (
//!     camera: (eye: (0, 0, 5), target: (0, 0, 0), up: (0, 1, 0), fov_y_degrees: 40, near: 0.5, far: 50),
//!     triangles: [
//!         (vertices: [(-1, -1, 0), (1, -1, 0), (0, 1, 0)], colours: [(1, 0, 0), (0, 1, 0), (0, 0, 1)]),
//!     ],
//! )
//! ```

use std::path::Path;

use serde::{Deserialize, Serialize};

use pxpl5_config::{ConfigError, FileKind, SemanticError};
use pxpl5_geom::vec3;

/// A point or a colour.
pub type Vec3 = (f64, f64, f64);

/// A pinhole camera.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Camera {
    pub eye: Vec3,
    pub target: Vec3,
    pub up: Vec3,
    /// Vertical field of view.
    pub fov_y_degrees: f64,
    /// Near and far clipping distances along the view direction.
    pub near: f64,
    pub far: f64,
}

/// One triangle: three vertices and their colours (each component 0 to 1).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Triangle {
    /// Exactly three vertices.
    pub vertices: Vec<Vec3>,
    /// Exactly three colours, one per vertex.
    pub colours: Vec<Vec3>,
}

/// A scene of triangles seen by a camera.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TriangleScene {
    pub camera: Camera,
    pub triangles: Vec<Triangle>,
}

/// Read, parse and check a triangle scene.
pub fn load_triangle_scene(path: &Path) -> Result<TriangleScene, ConfigError> {
    let (shown, text) = pxpl5_config::read_text(FileKind::TriangleScene, path)?;
    parse_triangle_scene(&shown, &text)
}

/// Parse and check a triangle scene held in memory; `file_name` names it in errors.
pub fn parse_triangle_scene(file_name: &str, text: &str) -> Result<TriangleScene, ConfigError> {
    pxpl5_config::parse_checked(
        FileKind::TriangleScene,
        file_name,
        text,
        check_triangle_scene,
    )
}

/// Largest magnitude of a coordinate in a scene (vertices, the camera's points and up vector;
/// the radiosity scenes' too, and their emissions): 10^12, a billion times the Cornell box's
/// largest coordinate (556 mm) and its lamp's emission (17). Below it, differences, areas (up to
/// 4e24), powers (emission x area) and their sums over a mesh stay far inside an f64 (1.8e308);
/// at 1e308 they overflow to infinity, which no picture or QEE expression can hold.
pub const MAX_COORDINATE: f64 = 1e12;

/// Narrowest field of view, in degrees: the projection multiplies camera coordinates by 1 /
/// tan(fov / 2), about 1.1e8 at 1e-6 degrees, which keeps projected coordinates of a scene within
/// [`MAX_COORDINATE`] finite.
pub const MIN_FOV_DEGREES: f64 = 1e-6;

/// Largest far / near ratio of a camera: a depth buffer separates nothing beyond it (the polygon
/// program's is 24 bits), and it keeps 1 / near finite.
pub const MAX_FAR_OVER_NEAR: f64 = 1e12;

/// Smallest far / near ratio: depth from near to far is scaled by 1 / (1 / near - 1 / far), which
/// must be finite.
pub const MIN_FAR_OVER_NEAR: f64 = 1.0 + 1e-6;

/// Whether every component of `v` is finite and at most [`MAX_COORDINATE`] in magnitude.
pub fn in_range(v: Vec3) -> bool {
    [v.0, v.1, v.2]
        .iter()
        .all(|c| c.is_finite() && c.abs() <= MAX_COORDINATE)
}

/// Every problem of a scene: non-finite numbers, degenerate triangles (zero area: collinear or
/// repeated vertices), colours outside 0..1, a camera that cannot see.
pub fn check_triangle_scene(scene: &TriangleScene) -> Result<(), Vec<SemanticError>> {
    let mut errors = check_camera(&scene.camera);
    let mut err = |path: String, value: String, rule: &str| {
        errors.push(SemanticError {
            path,
            value,
            rule: rule.to_string(),
        })
    };
    for (i, t) in scene.triangles.iter().enumerate() {
        check_triangle(i, t, &mut err);
    }
    if errors.is_empty() {
        Ok(())
    } else {
        Err(errors)
    }
}

/// The problems of a camera (with `camera.*` paths): numbers that are not finite or beyond
/// [`MAX_COORDINATE`], an up vector parallel to the view direction, a field of view outside
/// [[`MIN_FOV_DEGREES`], 180), near and far out of order or too close or too far apart (see
/// [`MAX_FAR_OVER_NEAR`]). The radiosity scenes' cameras follow the same rules.
pub fn check_camera(c: &Camera) -> Vec<SemanticError> {
    let mut errors = Vec::new();
    let mut err = |path: String, value: String, rule: &str| {
        errors.push(SemanticError {
            path,
            value,
            rule: rule.to_string(),
        })
    };
    for (name, v) in [("eye", c.eye), ("target", c.target), ("up", c.up)] {
        if !in_range(v) {
            err(
                format!("camera.{name}"),
                format!("{v:?}"),
                &format!("must be finite numbers of magnitude at most {MAX_COORDINATE:e}"),
            );
        }
    }
    if in_range(c.eye) && in_range(c.target) && in_range(c.up) {
        let (dir, up) = (vec3(c.target) - vec3(c.eye), vec3(c.up));
        if dir.length() == 0.0 || dir.cross(up).length() <= 1e-12 * dir.length() * up.length() {
            err(
                "camera.up".into(),
                format!("{:?}", c.up),
                "must not be parallel to the view direction (eye to target), which must not be zero",
            );
        }
    }
    if !(c.fov_y_degrees >= MIN_FOV_DEGREES && c.fov_y_degrees < 180.0) {
        err(
            "camera.fov_y_degrees".into(),
            format!("{:?}", c.fov_y_degrees),
            &format!(
                "must be in [{MIN_FOV_DEGREES:e}, 180): a narrower view overflows the projection"
            ),
        );
    }
    if !(c.near > 0.0 && c.far > c.near && c.far.is_finite()) {
        err(
            "camera.near".into(),
            format!("near {:?} far {:?}", c.near, c.far),
            "must satisfy 0 < near < far < infinity",
        );
    } else if !(MIN_FAR_OVER_NEAR..=MAX_FAR_OVER_NEAR).contains(&(c.far / c.near)) {
        err(
            "camera.far".into(),
            format!("near {:?} far {:?}", c.near, c.far),
            &format!(
                "far / near must be in [1 + 1e-6, {MAX_FAR_OVER_NEAR:e}]: depth is scaled by 1 / \
                 (1 / near - 1 / far), which must be finite, and a depth buffer separates \
                 nothing over a wider range"
            ),
        );
    }
    errors
}

/// The problems of triangle `i`, each passed to `err(path, value, rule)`.
fn check_triangle(i: usize, t: &Triangle, err: &mut impl FnMut(String, String, &str)) {
    if t.vertices.len() != 3 || t.colours.len() != 3 {
        err(
            format!("triangles[{i}]"),
            format!("{} vertices, {} colours", t.vertices.len(), t.colours.len()),
            "must have exactly 3 vertices and 3 colours",
        );
        return;
    }
    for (k, v) in t.vertices.iter().enumerate() {
        if !in_range(*v) {
            err(
                format!("triangles[{i}].vertices[{k}]"),
                format!("{v:?}"),
                &format!("must be finite numbers of magnitude at most {MAX_COORDINATE:e}"),
            );
        }
    }
    for (k, v) in t.colours.iter().enumerate() {
        let ok = [v.0, v.1, v.2].iter().all(|c| (0.0..=1.0).contains(c));
        if !ok {
            err(
                format!("triangles[{i}].colours[{k}]"),
                format!("{v:?}"),
                "components must be in 0..1",
            );
        }
    }
    if t.vertices.iter().all(|v| in_range(*v)) {
        let [a, b, c] = [0, 1, 2].map(|k| vec3(t.vertices[k]));
        let (e1, e2) = (b - a, c - a);
        let area2 = e1.cross(e2).length();
        let scale = e1.length().max(e2.length());
        if area2 <= 1e-12 * scale * scale {
            err(
                format!("triangles[{i}]"),
                format!("{:?}", t.vertices),
                "is degenerate (zero area: repeated or collinear vertices)",
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = "(camera: (eye: (0, 0, 5), target: (0, 0, 0), up: (0, 1, 0), \
        fov_y_degrees: 40, near: 0.5, far: 50), triangles: [(vertices: [(-1, -1, 0), (1, -1, 0), \
        (0, 1, 0)], colours: [(1, 0, 0), (0, 1, 0), (0, 0, 1)])])";

    #[test]
    fn a_missing_file_is_named_a_triangle_scene() {
        let missing = std::env::temp_dir().join("pxpl5-no-such-triangle-scene.ron");
        let text = load_triangle_scene(&missing).unwrap_err().to_string();
        assert!(text.contains("cannot read triangle scene"), "{text}");
        assert!(!text.contains("machine config"), "{text}");
    }

    #[test]
    fn parses_a_scene() {
        let s = parse_triangle_scene("s.ron", GOOD).unwrap();
        assert_eq!(s.triangles.len(), 1);
    }

    #[test]
    fn names_the_bad_triangle() {
        let nan = GOOD.replace("(0, 1, 0)], colours", "(0, NaN, 0)], colours");
        let e = parse_triangle_scene("s.ron", &nan).unwrap_err().to_string();
        assert!(e.contains("triangles[0].vertices[2]"), "{e}");
        let flat = GOOD.replace("(0, 1, 0)], colours", "(3, -1, 0)], colours");
        let e = parse_triangle_scene("s.ron", &flat)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("triangles[0]") && e.contains("degenerate"),
            "{e}"
        );
        let typo = GOOD.replace("vertices", "vertexes");
        let e = parse_triangle_scene("s.ron", &typo)
            .unwrap_err()
            .to_string();
        assert!(e.contains("s.ron:1:"), "{e}");
    }
}
