//! Whether a polygon is what the programs need, planar and convex with 3 or more distinct
//! corners, and what is wrong with it otherwise: the one check behind the radiosity scene files
//! and `pxpl5 formfactor`, with the tolerances both use. Every tolerance is relative to the
//! polygon's size ([`bounding_diagonal`]), so the verdict does not depend on the units.

use glam::DVec3;

use crate::convex::{self, Corner};
use crate::plane::{Plane, best_fit_plane, bounding_diagonal, worst_distance};

/// Largest distance of a vertex from the polygon's best-fit plane allowed, relative to its size.
pub const PLANARITY_TOLERANCE: f64 = 1e-6;

/// Below this area, relative to size squared, a polygon counts as having zero area: well above
/// f64 rounding of a collinear polygon's vector area (about 1e-16), well below any real sliver.
/// Times the size, it is also the edge length below which two vertices count as one.
pub const ZERO_AREA: f64 = 1e-12;

/// One thing wrong with a polygon that should be planar and convex.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Problem {
    /// Fewer than 3 vertices, or a coordinate that is not finite: nothing else is checked.
    NotAPolygon,
    /// Its vector area is below [`ZERO_AREA`] x size^2: coincident or collinear vertices, or
    /// edges that cross so that its parts cancel (a symmetric bow-tie). Nothing else is checked:
    /// without an area there is no plane to measure against.
    ZeroArea,
    /// Vertex `vertex` is `distance` from the best-fit plane, more than `limit`
    /// ([`PLANARITY_TOLERANCE`] x size).
    NotPlanar {
        vertex: usize,
        distance: f64,
        limit: f64,
    },
    /// A corner that is repeated, straight or reflex ([`convex::corners`]).
    Corner(Corner),
    /// Every corner turns the same way but the outline winds around `turns` times (a
    /// pentagram): its edges cross.
    Crossed { turns: f64 },
}

/// What is wrong with `v` as a planar convex polygon, in the order: [`Problem::NotAPolygon`] or
/// [`Problem::ZeroArea`] alone; else [`Problem::NotPlanar`] (the worst vertex), then each bad
/// corner, then [`Problem::Crossed`] when no corner is bad. Empty when the polygon is fine.
/// Either vertex order is fine: the corners are judged about the normal the order gives.
pub fn problems(v: &[DVec3]) -> Vec<Problem> {
    match plane_of(v) {
        Err(p) => vec![p],
        Ok((plane, size)) => shape_problems(v, &plane, size),
    }
}

/// The best-fit plane of `v` and its size, or why it has none.
fn plane_of(v: &[DVec3]) -> Result<(Plane, f64), Problem> {
    if v.len() < 3 || !v.iter().all(|p| p.is_finite()) {
        return Err(Problem::NotAPolygon);
    }
    let size = bounding_diagonal(v);
    best_fit_plane(v)
        .filter(|p| size > 0.0 && p.area > ZERO_AREA * size * size)
        .map(|p| (p, size))
        .ok_or(Problem::ZeroArea)
}

/// Planarity and convexity of `v` about its best-fit `plane`.
fn shape_problems(v: &[DVec3], plane: &Plane, size: f64) -> Vec<Problem> {
    let mut out = Vec::new();
    let (worst, distance) = worst_distance(v, plane);
    let limit = PLANARITY_TOLERANCE * size;
    if distance > limit {
        out.push(Problem::NotPlanar {
            vertex: worst,
            distance,
            limit,
        });
    }
    let (bad, total_turn) = convex::corners(v, plane.normal, ZERO_AREA * size);
    let crossed = bad.is_empty() && total_turn > 3.0 * std::f64::consts::PI;
    out.extend(bad.into_iter().map(Problem::Corner));
    if crossed {
        out.push(Problem::Crossed {
            turns: total_turn / std::f64::consts::TAU,
        });
    }
    out
}

/// Which corners of a zero-area polygon ([`Problem::ZeroArea`]) are at fault, to name them: the
/// corners of `v` judged about the normal of its largest corner triangle (a bow-tie's corners
/// then turn both ways), or about any normal when every corner is straight (collinear
/// vertices: straight or folded-back corners; all vertices equal: repeats). Empty for a polygon
/// with an area, or fewer than 3 finite vertices.
pub fn zero_area_corners(v: &[DVec3]) -> Vec<Corner> {
    if plane_of(v) != Err(Problem::ZeroArea) {
        return Vec::new();
    }
    let n = v.len();
    let size = bounding_diagonal(v);
    let mut normal = DVec3::ZERO;
    for k in 0..n {
        let (prev, here, next) = (v[(k + n - 1) % n], v[k], v[(k + 1) % n]);
        let c = (here - prev).cross(next - here);
        if c.length() > normal.length() {
            normal = c;
        }
    }
    let normal = if normal.length() > ZERO_AREA * size * size {
        normal.normalize()
    } else {
        // Collinear: any normal perpendicular to the line makes every turn 0 or pi.
        let dir = v.iter().map(|&p| p - v[0]).fold(DVec3::ZERO, |a, d| {
            if d.length() > a.length() { d } else { a }
        });
        if dir == DVec3::ZERO {
            // One point: every corner is a repeat, whatever the normal.
            DVec3::Z
        } else {
            dir.normalize().any_orthonormal_vector()
        }
    };
    convex::corners(v, normal, ZERO_AREA * size).0
}

/// A power of two by which to divide `v` so that its largest absolute coordinate lies in
/// [1, 2); 1 when every coordinate is 0, or one is not finite.
///
/// Dividing by a power of two is exact (unless a coordinate falls below 2^-1022 times the
/// largest, far below any tolerance here), and every check of this module is a ratio of sums of
/// products, so [`problems`] of the divided polygon gives the same verdict as of the polygon
/// itself, without the overflow of squares of coordinates beyond about 1e154 or the underflow
/// of those below about 1e-154. Distances it reports are then in units of the scale.
pub fn power_of_two_scale(v: &[DVec3]) -> f64 {
    let largest = v
        .iter()
        .flat_map(|p| p.to_array())
        .fold(0.0f64, |m, c| m.max(c.abs()));
    if !(largest > 0.0 && largest.is_finite()) {
        return 1.0;
    }
    let bits = largest.to_bits();
    let biased = (bits >> 52) as i32;
    if biased > 0 {
        // A normal number: 2^(exponent), the same biased exponent with a zero fraction.
        f64::from_bits((biased as u64) << 52)
    } else {
        // A subnormal: the power of two of its highest set bit.
        f64::from_bits(1u64 << (63 - bits.leading_zeros()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn xy(points: &[(f64, f64)]) -> Vec<DVec3> {
        points.iter().map(|&(x, y)| DVec3::new(x, y, 0.0)).collect()
    }

    #[test]
    fn power_of_two_scales() {
        let at = |c: f64| power_of_two_scale(&[DVec3::new(0.0, -c, 0.5 * c)]);
        assert_eq!(at(1.0), 1.0);
        assert_eq!(at(3.0), 2.0);
        assert_eq!(at(0.75), 0.5);
        assert_eq!(at(1e300), 2f64.powi(996));
        assert_eq!(at(f64::MAX), 2f64.powi(1023));
        assert_eq!(at(f64::MIN_POSITIVE), f64::MIN_POSITIVE);
        assert_eq!(at(3e-320), 2f64.powi(-1062));
        assert_eq!(at(5e-324), 5e-324);
        assert_eq!(at(0.0), 1.0);
        assert_eq!(at(f64::NAN), 1.0);
        assert_eq!(power_of_two_scale(&[]), 1.0);
        for c in [1.0, 3.0, 1e300, 1e-300, 3e-320, f64::MAX] {
            let m = c / at(c);
            assert!((1.0..2.0).contains(&m), "{c}: {m}");
        }
    }

    #[test]
    fn scaled_polygons_keep_their_verdict() {
        let dart = xy(&[(0.0, 0.0), (2.0, 0.0), (1.0, 0.5), (1.0, 2.0)]);
        let sq = xy(&[(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]);
        for c in [1e200, 1e-200] {
            // At these sizes the squares overflow or underflow: zero area, wrongly.
            let big: Vec<DVec3> = sq.iter().map(|&p| p * c).collect();
            assert_eq!(problems(&big), [Problem::ZeroArea]);
            let s = power_of_two_scale(&big);
            let scaled: Vec<DVec3> = big.iter().map(|&p| p / s).collect();
            assert!(problems(&scaled).is_empty());
            let big: Vec<DVec3> = dart.iter().map(|&p| p * c).collect();
            let s = power_of_two_scale(&big);
            let scaled: Vec<DVec3> = big.iter().map(|&p| p / s).collect();
            assert_eq!(problems(&scaled), [Problem::Corner(Corner::Reflex(2))]);
        }
    }

    #[test]
    fn a_square_either_way_round_is_fine() {
        let sq = xy(&[(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]);
        assert!(problems(&sq).is_empty());
        let mut back = sq.clone();
        back.reverse();
        assert!(problems(&back).is_empty());
        assert!(zero_area_corners(&sq).is_empty());
    }

    #[test]
    fn too_few_or_non_finite_vertices() {
        assert_eq!(
            problems(&xy(&[(0.0, 0.0), (1.0, 0.0)])),
            [Problem::NotAPolygon]
        );
        let nan = xy(&[(0.0, 0.0), (1.0, f64::NAN), (0.0, 1.0)]);
        assert_eq!(problems(&nan), [Problem::NotAPolygon]);
        assert!(zero_area_corners(&nan).is_empty());
    }

    #[test]
    fn a_bow_tie_has_zero_area_and_its_crossing_corners_are_named() {
        let bow = xy(&[(0.0, 0.0), (1.0, 1.0), (1.0, 0.0), (0.0, 1.0)]);
        assert_eq!(problems(&bow), [Problem::ZeroArea]);
        let corners = zero_area_corners(&bow);
        assert!(!corners.is_empty());
        assert!(
            corners.iter().all(|c| matches!(c, Corner::Reflex(_))),
            "{corners:?}"
        );
        // An asymmetric bow-tie has an area: its reflex corners are found directly.
        let bow = xy(&[(0.0, 0.0), (3.0, 1.0), (3.0, 0.0), (0.0, 2.0)]);
        let p = problems(&bow);
        assert!(
            p.iter()
                .any(|p| matches!(p, Problem::Corner(Corner::Reflex(_)))),
            "{p:?}"
        );
    }

    #[test]
    fn collinear_and_repeated_vertices() {
        let line = xy(&[(0.0, 0.0), (1.0, 0.0), (2.0, 0.0)]);
        assert_eq!(problems(&line), [Problem::ZeroArea]);
        let corners = zero_area_corners(&line);
        assert!(corners.contains(&Corner::Straight(1)), "{corners:?}");
        let same = xy(&[(1.0, 1.0), (1.0, 1.0), (1.0, 1.0)]);
        assert_eq!(problems(&same), [Problem::ZeroArea]);
        assert_eq!(
            zero_area_corners(&same),
            [Corner::Repeat(0), Corner::Repeat(1), Corner::Repeat(2)]
        );
        let repeat = xy(&[(0.0, 0.0), (1.0, 0.0), (1.0, 0.0), (0.0, 1.0)]);
        assert_eq!(problems(&repeat), [Problem::Corner(Corner::Repeat(1))]);
        let straight = xy(&[(0.0, 0.0), (1.0, 0.0), (2.0, 0.0), (0.0, 1.0)]);
        assert_eq!(problems(&straight), [Problem::Corner(Corner::Straight(1))]);
    }

    #[test]
    fn non_planar_names_the_worst_vertex_with_its_distance() {
        let mut sq = xy(&[(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]);
        sq[2].z = 0.004;
        let p = problems(&sq);
        let Some(Problem::NotPlanar {
            distance, limit, ..
        }) = p.first().copied()
        else {
            panic!("{p:?}")
        };
        // A quarter of the lift, as the best-fit plane splits it between the four corners.
        assert!((distance - 0.001).abs() < 1e-8, "{distance}");
        assert_eq!(limit, PLANARITY_TOLERANCE * bounding_diagonal(&sq));
        // Within the tolerance: fine.
        sq[2].z = 1e-7;
        assert!(problems(&sq).is_empty());
    }

    #[test]
    fn reflex_and_crossed() {
        let dart = xy(&[(0.0, 0.0), (2.0, 0.0), (1.0, 0.5), (1.0, 2.0)]);
        assert_eq!(problems(&dart), [Problem::Corner(Corner::Reflex(2))]);
        let star: Vec<DVec3> = (0..5)
            .map(|k| {
                let a = std::f64::consts::TAU * (2 * k) as f64 / 5.0;
                DVec3::new(a.cos(), a.sin(), 0.0)
            })
            .collect();
        let p = problems(&star);
        assert!(
            matches!(p[..], [Problem::Crossed { turns }] if (turns - 2.0).abs() < 1e-9),
            "{p:?}"
        );
    }
}
