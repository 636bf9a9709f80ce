//! One Sutherland-Hodgman clipper for convex polygons. The walk (which vertices to keep, where to
//! insert a crossing) is shared; each caller says what "inside" is and how to make the crossing
//! vertex, so that the arithmetic of each stays its own (the polygon program interpolates colours
//! with its vertices, the exact form factor snaps crossings onto the horizon).

use glam::DVec3;

/// The part of convex polygon `poly` where `inside` holds: every kept vertex in order, and
/// between a vertex and the next one on the other side, `crossing(a, b)` (`a` is the one before).
pub fn clip<V: Clone>(
    poly: &[V],
    inside: impl Fn(&V) -> bool,
    crossing: impl Fn(&V, &V) -> V,
) -> Vec<V> {
    let mut out = Vec::with_capacity(poly.len() + 2);
    clip_into(poly, inside, crossing, &mut out);
    out
}

/// [`clip`] into `out` (cleared first), so that a caller clipping by plane after plane reuses two
/// buffers instead of allocating a polygon per plane.
pub fn clip_into<V: Clone>(
    poly: &[V],
    inside: impl Fn(&V) -> bool,
    crossing: impl Fn(&V, &V) -> V,
    out: &mut Vec<V>,
) {
    out.clear();
    for i in 0..poly.len() {
        let (a, b) = (&poly[i], &poly[(i + 1) % poly.len()]);
        let (ia, ib) = (inside(a), inside(b));
        if ia {
            out.push(a.clone());
        }
        if ia != ib {
            out.push(crossing(a, b));
        }
    }
}

/// The part of `poly` where `d(p) = n . p + w >= 0` (`plane` = (n, w)), into `out` (cleared
/// first); the crossing is `a + t (b - a)` with `t = d(a) / (d(a) - d(b))`.
pub fn clip_to_half_space_into(poly: &[DVec3], (n, w): (DVec3, f64), out: &mut Vec<DVec3>) {
    let d = |p: &DVec3| n.x * p.x + n.y * p.y + n.z * p.z + w;
    clip_into(
        poly,
        |p| d(p) >= 0.0,
        |a, b| {
            let (da, db) = (d(a), d(b));
            let t = da / (da - db);
            *a + t * (*b - *a)
        },
        out,
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    fn clip_to_half_space(poly: &[DVec3], plane: (DVec3, f64)) -> Vec<DVec3> {
        // A buffer that held something: the clip must clear it.
        let mut out = vec![DVec3::splat(9.0); 7];
        clip_to_half_space_into(poly, plane, &mut out);
        out
    }

    #[test]
    fn clips_a_square_to_a_half_plane() {
        let sq = [
            DVec3::new(-1.0, -1.0, 0.0),
            DVec3::new(1.0, -1.0, 0.0),
            DVec3::new(1.0, 1.0, 0.0),
            DVec3::new(-1.0, 1.0, 0.0),
        ];
        let half = clip_to_half_space(&sq, (DVec3::X, 0.0));
        assert_eq!(
            half,
            vec![
                DVec3::new(0.0, -1.0, 0.0),
                DVec3::new(1.0, -1.0, 0.0),
                DVec3::new(1.0, 1.0, 0.0),
                DVec3::new(0.0, 1.0, 0.0),
            ]
        );
        assert!(clip_to_half_space(&sq, (DVec3::X, -2.0)).is_empty());
        assert_eq!(clip_to_half_space(&sq, (DVec3::X, 2.0)), sq.to_vec());
    }
}
