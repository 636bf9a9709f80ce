//! The plane of a polygon: Newell's best-fit plane, and the polygon's size that tolerances are
//! relative to (so that they do not depend on the scene's units).

use glam::DVec3;

/// The plane that best fits a polygon, see [`best_fit_plane`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    /// Unit normal, by the right-hand rule over the vertex order.
    pub normal: DVec3,
    /// A point of the plane: the mean of the vertices.
    pub point: DVec3,
    /// Area of the polygon projected onto the plane (the exact area for a planar polygon).
    pub area: f64,
}

/// The best-fit plane of a polygon by Newell's method: the normal is the polygon's vector area
/// (exact for planar polygons, the standard least-sensitive estimate for slightly non-planar ones)
/// and the plane passes through the vertex mean.
///
/// `None` for fewer than 3 vertices, non-finite coordinates or zero vector area (collinear or
/// coincident vertices), where no normal is defined.
pub fn best_fit_plane(vertices: &[DVec3]) -> Option<Plane> {
    if vertices.len() < 3 || !vertices.iter().all(|v| v.is_finite()) {
        return None;
    }
    // Relative to vertex 0, so the cross products of large, far-off coordinates do not cancel.
    let origin = vertices[0];
    let mut n = DVec3::ZERO;
    for k in 1..vertices.len() - 1 {
        n += (vertices[k] - origin).cross(vertices[k + 1] - origin);
    }
    let len = n.length();
    if !(len > 0.0 && len.is_finite()) {
        return None;
    }
    let count = vertices.len() as f64;
    let sum = vertices.iter().fold(DVec3::ZERO, |s, &v| s + v);
    Some(Plane {
        // Divided (not multiplied by 1 / len): the rounding the scene checks were written with.
        normal: n / len,
        point: sum / count,
        area: len / 2.0,
    })
}

/// Length of the diagonal of the axis-aligned bounding box of `vertices`: a polygon's "size" that
/// planarity and degeneracy tolerances are relative to, or a scene's. 0 for no vertices.
pub fn bounding_diagonal(vertices: &[DVec3]) -> f64 {
    let Some(&first) = vertices.first() else {
        return 0.0;
    };
    let (lo, hi) = vertices
        .iter()
        .fold((first, first), |(lo, hi), &v| (lo.min(v), hi.max(v)));
    (hi - lo).length()
}

/// The worst vertex's distance from `plane`: (its index, the distance).
pub fn worst_distance(vertices: &[DVec3], plane: &Plane) -> (usize, f64) {
    vertices
        .iter()
        .map(|&p| plane.normal.dot(p - plane.point).abs())
        .enumerate()
        .fold(
            (0, 0.0),
            |best, (k, d)| if d > best.1 { (k, d) } else { best },
        )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn square_plane_and_size() {
        let sq = [
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(2.0, 2.0, 0.0),
            DVec3::new(0.0, 2.0, 0.0),
        ];
        let p = best_fit_plane(&sq).unwrap();
        assert_eq!(p.normal, DVec3::Z);
        assert_eq!(p.point, DVec3::new(1.0, 1.0, 0.0));
        assert_eq!(p.area, 4.0);
        assert_eq!(bounding_diagonal(&sq), 8f64.sqrt());
        assert_eq!(worst_distance(&sq, &p), (0, 0.0));
        let line = [DVec3::ZERO, DVec3::X, 2.0 * DVec3::X];
        assert!(best_fit_plane(&line).is_none());
        assert!(best_fit_plane(&sq[..2]).is_none());
        let nan = [DVec3::new(f64::NAN, 0.0, 0.0), DVec3::X, DVec3::Y];
        assert!(best_fit_plane(&nan).is_none());
        let tri = [
            DVec3::ZERO,
            DVec3::new(2.0, 0.0, 0.0),
            DVec3::new(2.0, 3.0, 0.0),
        ];
        assert_eq!(best_fit_plane(&tri).unwrap().area, 3.0);
        assert_eq!(bounding_diagonal(&[]), 0.0);
    }
}
