//! Exact form factors, the ground truth the machine's hemisphere and hemicube are measured
//! against: from a differential area to an unoccluded polygon, by Lambert's (Hottel's) contour
//! formula (radiosity-formulas.md section 4).
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

use crate::mesh::{cross, dot, norm, scale, sub};

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
pub fn point_to_polygon(p: [f64; 3], n: [f64; 3], polygon: &[[f64; 3]]) -> f64 {
    let all_finite = p.iter().chain(&n).all(|c| c.is_finite())
        && polygon.iter().flatten().all(|c| c.is_finite());
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
    let n = scale(n, 1.0 / norm(n));
    // Work relative to p: the formula only needs r_i, and translating first keeps the digits of a
    // small polygon far from the origin.
    let mut r: Vec<[f64; 3]> = polygon.iter().map(|&v| sub(v, p)).collect();
    let reach = r.iter().flatten().fold(0.0f64, |m, c| m.max(c.abs()));
    if reach == 0.0 {
        return 0.0;
    }
    if !reach.is_finite() {
        // v - p overflowed (coordinates near f64::MAX of opposite signs): redo it halved.
        r = polygon
            .iter()
            .map(|&v| sub(scale(v, 0.5), scale(p, 0.5)))
            .collect();
    }
    let reach = r.iter().flatten().fold(0.0f64, |m, c| m.max(c.abs()));
    for v in &mut r {
        *v = v.map(|c| c / reach);
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
        let c = cross(a, sub(b, a));
        let c_len = norm(c);
        if c_len == 0.0 {
            // The edge is degenerate or points straight at p: it subtends no solid angle.
            continue;
        }
        let gamma = c_len.atan2(dot(a, b));
        sum += gamma * dot(n, c) / c_len;
    }
    sum.abs() / TAU
}

/// `v` divided by its largest absolute component; `None` for the zero vector.
fn unit_scaled(v: [f64; 3]) -> Option<[f64; 3]> {
    let largest = v.iter().fold(0.0f64, |m, c| m.max(c.abs()));
    (largest > 0.0).then(|| v.map(|c| c / largest))
}

/// Whether the origin (the point `p`, after translation) lies in the plane of the polygon `r`,
/// within [`IN_PLANE`] of the polygon's distance. A polygon with no defined plane (zero area)
/// counts as in plane: its form factor is 0.
fn in_plane(r: &[[f64; 3]]) -> bool {
    // Newell's vector area relative to vertex 0.
    let mut area = [0.0; 3];
    for k in 1..r.len() - 1 {
        let c = cross(sub(r[k], r[0]), sub(r[k + 1], r[0]));
        area = [area[0] + c[0], area[1] + c[1], area[2] + c[2]];
    }
    let area_len = norm(area);
    if area_len == 0.0 {
        return true;
    }
    let unit = scale(area, 1.0 / area_len);
    let count = r.len() as f64;
    let mean = r
        .iter()
        .fold([0.0; 3], |s, v| [s[0] + v[0], s[1] + v[1], s[2] + v[2]]);
    let distance = dot(unit, scale(mean, 1.0 / count)).abs();
    let reach = r.iter().map(|&v| norm(v)).fold(0.0, f64::max);
    distance <= IN_PLANE * reach
}

/// The part of polygon `r` (relative to p) in the half-space `n . x >= 0` (Sutherland-Hodgman
/// against one plane). Points on the horizon are kept: the clipped polygon's edges along the
/// horizon are part of its contour and contribute to the sum.
fn clip_to_front(r: &[[f64; 3]], n: [f64; 3]) -> Vec<[f64; 3]> {
    let m = r.len();
    let height: Vec<f64> = r.iter().map(|&v| dot(n, v)).collect();
    if height.iter().all(|&h| h >= 0.0) {
        return r.to_vec();
    }
    let mut out = Vec::with_capacity(m + 2);
    for i in 0..m {
        let j = (i + 1) % m;
        let (a, ha, hb) = (r[i], height[i], height[j]);
        if ha >= 0.0 {
            out.push(a);
        }
        if (ha >= 0.0) != (hb >= 0.0) {
            // ha and hb have strictly opposite signs here (one is < 0, the other >= 0, and they
            // differ), so ha - hb is not zero and t is in [0, 1].
            let t = ha / (ha - hb);
            let edge = sub(r[j], a);
            let mut x = [a[0] + t * edge[0], a[1] + t * edge[1], a[2] + t * edge[2]];
            // Put the crossing exactly on the horizon (rounding may leave it a hair below).
            let h = dot(n, x);
            x = [x[0] - h * n[0], x[1] - h * n[1], x[2] - h * n[2]];
            out.push(x);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unit_square_overhead() {
        // Parallel unit square at distance 1, normal through its corner: X = Y = 1.
        let f = point_to_polygon(
            [0.0; 3],
            [0.0, 0.0, 1.0],
            &[
                [0.0, 0.0, 1.0],
                [1.0, 0.0, 1.0],
                [1.0, 1.0, 1.0],
                [0.0, 1.0, 1.0],
            ],
        );
        let x = 1.0 / 2f64.sqrt();
        let exact = 2.0 * x * x.atan() / TAU;
        assert!((f - exact).abs() < 1e-15, "{f} {exact}");
    }

    #[test]
    fn degenerate_inputs() {
        let sq = [
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 1.0],
            [1.0, 1.0, 1.0],
            [0.0, 1.0, 1.0],
        ];
        assert_eq!(point_to_polygon([0.0; 3], [0.0; 3], &sq), 0.0);
        assert_eq!(point_to_polygon([0.0; 3], [0.0, 0.0, 1.0], &sq[..2]), 0.0);
        assert_eq!(point_to_polygon([0.0; 3], [0.0, 0.0, 1.0], &[]), 0.0);
        assert!(point_to_polygon([f64::NAN, 0.0, 0.0], [0.0, 0.0, 1.0], &sq).is_nan());
        let line = [[0.0, 0.0, 1.0], [1.0, 0.0, 1.0], [2.0, 0.0, 1.0]];
        assert_eq!(point_to_polygon([0.0; 3], [0.0, 0.0, 1.0], &line), 0.0);
        // p inside a coplanar polygon, with the polygon's normal.
        assert_eq!(point_to_polygon([0.5, 0.5, 1.0], [0.0, 0.0, 1.0], &sq), 0.0);
        // Unnormalised normal.
        let a = point_to_polygon([0.0; 3], [0.0, 0.0, 5.0], &sq);
        let b = point_to_polygon([0.0; 3], [0.0, 0.0, 1.0], &sq);
        assert_eq!(a, b);
    }
}
