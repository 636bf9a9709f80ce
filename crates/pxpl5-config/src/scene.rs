//! The triangle-scene file of the polygon program: a camera and triangles with per-vertex colours,
//! in RON, loaded and checked with the same error reports as machine configs (file, line, column
//! for syntax; the triangle's index and field for semantic problems).
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

use crate::{ConfigError, SemanticError};

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
    let (shown, text) = crate::read_text(path)?;
    parse_triangle_scene(&shown, &text)
}

/// Parse and check a triangle scene held in memory; `file_name` names it in errors.
pub fn parse_triangle_scene(file_name: &str, text: &str) -> Result<TriangleScene, ConfigError> {
    crate::parse_checked(file_name, text, check_triangle_scene)
}

fn finite(v: Vec3) -> bool {
    v.0.is_finite() && v.1.is_finite() && v.2.is_finite()
}

fn sub(a: Vec3, b: Vec3) -> Vec3 {
    (a.0 - b.0, a.1 - b.1, a.2 - b.2)
}

fn cross(a: Vec3, b: Vec3) -> Vec3 {
    (
        a.1 * b.2 - a.2 * b.1,
        a.2 * b.0 - a.0 * b.2,
        a.0 * b.1 - a.1 * b.0,
    )
}

fn norm(a: Vec3) -> f64 {
    (a.0 * a.0 + a.1 * a.1 + a.2 * a.2).sqrt()
}

/// Every problem of a scene: non-finite numbers, degenerate triangles (zero area: collinear or
/// repeated vertices), colours outside 0..1, a camera that cannot see.
pub fn check_triangle_scene(scene: &TriangleScene) -> Result<(), Vec<SemanticError>> {
    let mut errors = Vec::new();
    let mut err = |path: String, value: String, rule: &str| {
        errors.push(SemanticError {
            path,
            value,
            rule: rule.to_string(),
        })
    };
    let c = &scene.camera;
    for (name, v) in [("eye", c.eye), ("target", c.target), ("up", c.up)] {
        if !finite(v) {
            err(
                format!("camera.{name}"),
                format!("{v:?}"),
                "must be finite numbers",
            );
        }
    }
    if finite(c.eye) && finite(c.target) && finite(c.up) {
        let dir = sub(c.target, c.eye);
        if norm(dir) == 0.0 || norm(cross(dir, c.up)) <= 1e-12 * norm(dir) * norm(c.up) {
            err(
                "camera.up".into(),
                format!("{:?}", c.up),
                "must not be parallel to the view direction (eye to target), which must not be zero",
            );
        }
    }
    if !(c.fov_y_degrees > 0.0 && c.fov_y_degrees < 180.0) {
        err(
            "camera.fov_y_degrees".into(),
            c.fov_y_degrees.to_string(),
            "must be in (0, 180)",
        );
    }
    if !(c.near > 0.0 && c.far > c.near && c.far.is_finite()) {
        err(
            "camera.near".into(),
            format!("near {} far {}", c.near, c.far),
            "must satisfy 0 < near < far < infinity",
        );
    }
    for (i, t) in scene.triangles.iter().enumerate() {
        if t.vertices.len() != 3 || t.colours.len() != 3 {
            err(
                format!("triangles[{i}]"),
                format!("{} vertices, {} colours", t.vertices.len(), t.colours.len()),
                "must have exactly 3 vertices and 3 colours",
            );
            continue;
        }
        for (k, v) in t.vertices.iter().enumerate() {
            if !finite(*v) {
                err(
                    format!("triangles[{i}].vertices[{k}]"),
                    format!("{v:?}"),
                    "must be finite numbers",
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
        if t.vertices.iter().all(|v| finite(*v)) {
            let (a, b, c) = (t.vertices[0], t.vertices[1], t.vertices[2]);
            let (e1, e2) = (sub(b, a), sub(c, a));
            let area2 = norm(cross(e1, e2));
            let scale = norm(e1).max(norm(e2));
            if area2 <= 1e-12 * scale * scale {
                err(
                    format!("triangles[{i}]"),
                    format!("{:?}", t.vertices),
                    "is degenerate (zero area: repeated or collinear vertices)",
                );
            }
        }
    }
    if errors.is_empty() {
        Ok(())
    } else {
        Err(errors)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const GOOD: &str = "(camera: (eye: (0, 0, 5), target: (0, 0, 0), up: (0, 1, 0), \
        fov_y_degrees: 40, near: 0.5, far: 50), triangles: [(vertices: [(-1, -1, 0), (1, -1, 0), \
        (0, 1, 0)], colours: [(1, 0, 0), (0, 1, 0), (0, 0, 1)])])";

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
