//! Convexity of a planar polygon, corner by corner: every corner must turn the same way as the
//! polygon's normal (left, seen from the front), and the turns must add up to one full turn, not
//! two or more (a pentagram turns left at every corner but is not convex).

use glam::DVec3;

/// Below this sine of the turn between consecutive edges, a corner counts as straight (three
/// collinear vertices): such a vertex gives the mesher and the hemisphere edge tests a
/// zero-length or undefined edge plane.
pub const STRAIGHT_CORNER: f64 = 1e-9;

/// What is wrong at one corner.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Corner {
    /// Vertex `k + 1` repeats vertex `k` (an edge shorter than `tiny`).
    Repeat(usize),
    /// Vertex `k` is collinear with its neighbours.
    Straight(usize),
    /// Vertex `k` turns clockwise seen from the front, or folds back.
    Reflex(usize),
}

/// The corners of `v` that break convexity about `normal` (a unit normal of its plane); `tiny` is
/// the edge length below which two vertices count as one. Also returns the total turn in radians
/// (2 pi for a convex polygon; 4 pi or more for one whose edges cross).
pub fn corners(v: &[DVec3], normal: DVec3, tiny: f64) -> (Vec<Corner>, f64) {
    let n = v.len();
    let mut bad = Vec::new();
    let mut total_turn = 0.0;
    for k in 0..n {
        let (prev, here, next) = (v[(k + n - 1) % n], v[k], v[(k + 1) % n]);
        let (e1, e2) = (here - prev, next - here);
        let (l1, l2) = (e1.length(), e2.length());
        if l2 <= tiny {
            bad.push(Corner::Repeat(k));
            continue;
        }
        if l1 <= tiny {
            // Reported as a repeat at the previous corner.
            continue;
        }
        let sine = normal.dot(e1.cross(e2)) / (l1 * l2);
        let cosine = e1.dot(e2) / (l1 * l2);
        total_turn += sine.atan2(cosine);
        if sine.abs() <= STRAIGHT_CORNER && cosine > 0.0 {
            bad.push(Corner::Straight(k));
        } else if sine <= STRAIGHT_CORNER {
            bad.push(Corner::Reflex(k));
        }
    }
    (bad, total_turn)
}

/// Whether `v` is convex about `normal`: no bad corner, and it winds around once.
pub fn is_convex(v: &[DVec3], normal: DVec3, tiny: f64) -> bool {
    let (bad, turn) = corners(v, normal, tiny);
    bad.is_empty() && turn <= 3.0 * std::f64::consts::PI
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn square_star_and_bow_tie() {
        let sq = [DVec3::ZERO, DVec3::X, DVec3::new(1.0, 1.0, 0.0), DVec3::Y];
        assert!(is_convex(&sq, DVec3::Z, 1e-12));
        assert!(!is_convex(&sq, -DVec3::Z, 1e-12));
        let bow = [DVec3::ZERO, DVec3::new(1.0, 1.0, 0.0), DVec3::X, DVec3::Y];
        assert!(!is_convex(&bow, DVec3::Z, 1e-12));
        let star: Vec<DVec3> = (0..5)
            .map(|k| {
                let a = std::f64::consts::TAU * (2 * k) as f64 / 5.0;
                DVec3::new(a.cos(), a.sin(), 0.0)
            })
            .collect();
        let (bad, turn) = corners(&star, DVec3::Z, 1e-12);
        assert!(bad.is_empty());
        assert!((turn - 2.0 * std::f64::consts::TAU).abs() < 1e-9);
        let rep = [DVec3::ZERO, DVec3::X, DVec3::X, DVec3::Y];
        assert_eq!(corners(&rep, DVec3::Z, 1e-12).0, vec![Corner::Repeat(1)]);
    }
}
