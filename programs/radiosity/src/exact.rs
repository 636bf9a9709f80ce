//! Exact form factors, the ground truth the machine's hemisphere and hemicube are measured
//! against: from a differential area to an unoccluded polygon, by Lambert's (Hottel's) contour
//! formula (docs/radiosity.md section 4).
//!
//! For a point `p` with unit normal `n` and a polygon `v_0 .. v_{m-1}`:
//!
//! ```text
//! r_i = v_i - p ;  c_i = r_i x r_{i+1} ;  gamma_i = atan2(|c_i|, r_i . r_{i+1})
//! F = | sum_i gamma_i (n . c_i) / |c_i| | / (2 pi)
//! ```
//!
//! after clipping the polygon to the half-space in front of `p` (without it the parts below the
//! horizon count negatively).

use std::f64::consts::TAU;

use pxpl5_geom::DVec3;

/// Below this distance from a polygon's plane, relative to the polygon's distance from `p`, `p`
/// counts as lying in that plane (form factor 0). Rounding of the plane test is about 1e-16; a
/// polygon seen this edge-on has a form factor of order 1e-12 at most.
const IN_PLANE: f64 = 1e-12;

/// The form factor from a differential area at `p` with normal `n` to the unoccluded `polygon`.
///
/// `n` need not be unit length (it is normalised); the polygon may have either orientation (the
/// result is the same: this is the geometric factor, not a test of which side faces `p`), may be
/// non-convex or slightly non-planar, and may straddle `p`'s horizon (it is clipped to the
/// half-space `n . (x - p) >= 0` first, Sutherland-Hodgman).
///
/// Defined results at the extremes: 0 for fewer than 3 vertices, a zero normal, a zero-area
/// polygon, a polygon wholly behind `p`, and a polygon whose plane contains `p`. Never NaN for
/// finite input; NaN if any input coordinate is NaN or infinite, so garbage is not mistaken for a
/// dark patch.
pub fn point_to_polygon(p: DVec3, n: DVec3, polygon: &[DVec3]) -> f64 {
    let all_finite = p.is_finite() && n.is_finite() && polygon.iter().all(|v| v.is_finite());
    if !all_finite {
        return f64::NAN;
    }
    if polygon.len() < 3 {
        return 0.0;
    }
    // F is scale invariant: bring the normal and the vertices (relative to p) to a largest
    // component of 1 (by division, which cannot overflow), so that the squares and cross
    // products below neither overflow nor underflow for coordinates anywhere in f64's range.
    let Some(n) = unit_scaled(n) else {
        return 0.0;
    };
    let n = n * (1.0 / n.length());
    // Work relative to p: the formula only needs r_i, and translating first keeps the digits of a
    // small polygon far from the origin.
    let mut r: Vec<DVec3> = polygon.iter().map(|&v| v - p).collect();
    let reach = largest_component(&r);
    if reach == 0.0 {
        return 0.0;
    }
    if !reach.is_finite() {
        // v - p overflowed (coordinates near f64::MAX of opposite signs): redo it halved.
        r = polygon.iter().map(|&v| v * 0.5 - p * 0.5).collect();
    }
    let reach = largest_component(&r);
    for v in &mut r {
        *v /= reach;
    }
    if in_plane(&r) {
        return 0.0;
    }
    let clipped = clip_to_front(&r, n);
    if clipped.len() < 3 {
        return 0.0;
    }
    let m = clipped.len();
    let mut sum = 0.0;
    for i in 0..m {
        let (a, b) = (clipped[i], clipped[(i + 1) % m]);
        // r_i x r_{i+1} = r_i x (r_{i+1} - r_i): with the edge vector the cross product keeps its
        // relative precision for an edge that is short compared to its distance (a sliver, a far
        // polygon), where r_i and r_{i+1} are nearly parallel and their cross product cancels.
        let c = a.cross(b - a);
        let c_len = c.length();
        if c_len == 0.0 {
            // The edge is degenerate or points straight at p: it subtends no solid angle.
            continue;
        }
        let gamma = c_len.atan2(a.dot(b));
        sum += gamma * n.dot(c) / c_len;
    }
    sum.abs() / TAU
}

/// The unit vector along a normal `n`, computed without overflow or underflow (`n` is divided by
/// its largest absolute component first, then by its length, as [`point_to_polygon`] does).
///
/// `None` unless every component is finite and the length of `n` is at least
/// `f64::MIN_POSITIVE` (about 2.2e-308, the smallest normal f64): a zero vector has no direction,
/// and a shorter one is made of subnormal components, which have lost significant bits, so its
/// direction is not known to f64 precision. At that bound the largest component still has at
/// least 52 of f64's 53 significant bits. Any finite vector at least that long is accepted,
/// however long (`(1e308, 1e308, 0)` gives `(1, 1, 0) / sqrt(2)`).
pub fn unit_normal(n: DVec3) -> Option<DVec3> {
    if !n.is_finite() {
        return None;
    }
    let scaled = unit_scaled(n)?;
    // |scaled| is in [1, sqrt(3)]; |n| = largest x |scaled| may round to infinity, which passes.
    let length = scaled.length();
    if largest_component(&[n]) * length < f64::MIN_POSITIVE {
        return None;
    }
    Some(scaled * (1.0 / length))
}

/// `v` divided by its largest absolute component; `None` for the zero vector.
fn unit_scaled(v: DVec3) -> Option<DVec3> {
    let largest = largest_component(&[v]);
    (largest > 0.0).then(|| v / largest)
}

/// The largest absolute coordinate of any of `vs` (0 for none).
fn largest_component(vs: &[DVec3]) -> f64 {
    vs.iter()
        .flat_map(|v| v.to_array())
        .fold(0.0f64, |m, c| m.max(c.abs()))
}

/// Whether the origin (the point `p`, after translation) lies in the plane of the polygon `r`,
/// within [`IN_PLANE`] of the polygon's distance. A polygon with no defined plane (zero area)
/// counts as in plane: its form factor is 0.
fn in_plane(r: &[DVec3]) -> bool {
    // Newell's vector area relative to vertex 0.
    let mut area = DVec3::ZERO;
    for k in 1..r.len() - 1 {
        area += (r[k] - r[0]).cross(r[k + 1] - r[0]);
    }
    let area_len = area.length();
    if area_len == 0.0 {
        return true;
    }
    let unit = area * (1.0 / area_len);
    let count = r.len() as f64;
    let mean = r.iter().fold(DVec3::ZERO, |s, &v| s + v);
    let distance = unit.dot(mean * (1.0 / count)).abs();
    let reach = r.iter().map(|v| v.length()).fold(0.0, f64::max);
    distance <= IN_PLANE * reach
}

/// The part of polygon `r` (relative to p) in the half-space `n . x >= 0` (Sutherland-Hodgman
/// against one plane). Points on the horizon are kept: the clipped polygon's edges along the
/// horizon are part of its contour and contribute to the sum.
fn clip_to_front(r: &[DVec3], n: DVec3) -> Vec<DVec3> {
    pxpl5_geom::clip::clip(
        r,
        |&v| n.dot(v) >= 0.0,
        |&a, &b| {
            // The heights have strictly opposite signs here (one is < 0, the other >= 0, and
            // they differ), so ha - hb is not zero and t is in [0, 1].
            let (ha, hb) = (n.dot(a), n.dot(b));
            let t = ha / (ha - hb);
            let x = a + t * (b - a);
            // Put the crossing exactly on the horizon (rounding may leave it a hair below).
            x - n.dot(x) * n
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_square_overhead() {
        // Parallel unit square at distance 1, normal through its corner: X = Y = 1.
        let f = point_to_polygon(
            DVec3::ZERO,
            DVec3::new(0.0, 0.0, 1.0),
            &[
                DVec3::new(0.0, 0.0, 1.0),
                DVec3::new(1.0, 0.0, 1.0),
                DVec3::new(1.0, 1.0, 1.0),
                DVec3::new(0.0, 1.0, 1.0),
            ],
        );
        let x = 1.0 / 2f64.sqrt();
        let exact = 2.0 * x * x.atan() / TAU;
        assert!((f - exact).abs() < 1e-15, "{f} {exact}");
    }

    #[test]
    fn unit_normals_from_any_scale() {
        assert_eq!(unit_normal(DVec3::new(0.0, 0.0, 2.0)), Some(DVec3::Z));
        // Squaring 1e-300 underflows; dividing by the largest component first does not.
        assert_eq!(unit_normal(DVec3::new(0.0, 0.0, 1e-300)), Some(DVec3::Z));
        assert_eq!(unit_normal(DVec3::new(0.0, -3e-308, 0.0)), Some(-DVec3::Y));
        let big = unit_normal(DVec3::new(1e308, 1e308, 0.0)).unwrap();
        assert!((big - DVec3::new(1.0, 1.0, 0.0) / 2f64.sqrt()).length() < 1e-15);
        // A subnormal component beside a normal one is fine: the length is what counts.
        assert_eq!(unit_normal(DVec3::new(1e-310, 0.0, 1.0)).unwrap().z, 1.0);
        // Zero, subnormal lengths and non-finite components have no direction to use.
        assert_eq!(unit_normal(DVec3::ZERO), None);
        assert_eq!(unit_normal(DVec3::new(0.0, 0.0, 1e-310)), None);
        assert_eq!(unit_normal(DVec3::new(1e-308, 1e-308, 1e-308)), None);
        assert_eq!(
            unit_normal(DVec3::new(0.0, 0.0, f64::MIN_POSITIVE)),
            Some(DVec3::Z)
        );
        assert_eq!(unit_normal(DVec3::new(f64::NAN, 0.0, 1.0)), None);
        assert_eq!(unit_normal(DVec3::new(f64::INFINITY, 0.0, 1.0)), None);
    }

    #[test]
    fn degenerate_inputs() {
        let sq = [
            DVec3::new(0.0, 0.0, 1.0),
            DVec3::new(1.0, 0.0, 1.0),
            DVec3::new(1.0, 1.0, 1.0),
            DVec3::new(0.0, 1.0, 1.0),
        ];
        assert_eq!(point_to_polygon(DVec3::ZERO, DVec3::ZERO, &sq), 0.0);
        assert_eq!(
            point_to_polygon(DVec3::ZERO, DVec3::new(0.0, 0.0, 1.0), &sq[..2]),
            0.0
        );
        assert_eq!(
            point_to_polygon(DVec3::ZERO, DVec3::new(0.0, 0.0, 1.0), &[]),
            0.0
        );
        assert!(
            point_to_polygon(
                DVec3::new(f64::NAN, 0.0, 0.0),
                DVec3::new(0.0, 0.0, 1.0),
                &sq
            )
            .is_nan()
        );
        let line = [
            DVec3::new(0.0, 0.0, 1.0),
            DVec3::new(1.0, 0.0, 1.0),
            DVec3::new(2.0, 0.0, 1.0),
        ];
        assert_eq!(
            point_to_polygon(DVec3::ZERO, DVec3::new(0.0, 0.0, 1.0), &line),
            0.0
        );
        // p inside a coplanar polygon, with the polygon's normal.
        assert_eq!(
            point_to_polygon(DVec3::new(0.5, 0.5, 1.0), DVec3::new(0.0, 0.0, 1.0), &sq),
            0.0
        );
        // Unnormalised normal.
        let a = point_to_polygon(DVec3::ZERO, DVec3::new(0.0, 0.0, 5.0), &sq);
        let b = point_to_polygon(DVec3::ZERO, DVec3::new(0.0, 0.0, 1.0), &sq);
        assert_eq!(a, b);
    }
}
