//! Tests of the exact point-to-polygon form factor against the closed forms of Howell's catalog
//! (docs/radiosity.md section 4), its invariances, the horizon clipping, degenerate shapes,
//! and additivity: from inside a closed box the form factors to the six faces sum to 1.

use std::f64::consts::TAU;

use pxpl5_geom::DVec3;
use pxpl5_radiosity::exact::point_to_polygon;
use pxpl5_radiosity::scenes::{closed_box, empty_box};

const UP: DVec3 = DVec3::new(0.0, 0.0, 1.0);

fn rel_err(got: f64, want: f64) -> f64 {
    (got - want).abs() / want.abs()
}

/// dA to a parallel a x b rectangle at distance c, the normal through a corner.
fn parallel_corner(a: f64, b: f64, c: f64) -> f64 {
    let (x, y) = (a / c, b / c);
    let (sx, sy) = ((1.0 + x * x).sqrt(), (1.0 + y * y).sqrt());
    (x / sx * (y / sx).atan() + y / sy * (x / sy).atan()) / TAU
}

/// dA to a perpendicular a x b rectangle sharing the element's plane along its edge of length a,
/// the element at distance c from that edge on the normal through a corner.
fn perpendicular(a: f64, b: f64, c: f64) -> f64 {
    let d = (b * b + c * c).sqrt();
    ((a / c).atan() - c / d * (a / d).atan()) / TAU
}

/// The rectangle of `parallel_corner`, seen from the origin with normal +z.
fn parallel_rectangle(a: f64, b: f64, c: f64) -> Vec<DVec3> {
    vec![
        DVec3::new(0.0, 0.0, c),
        DVec3::new(a, 0.0, c),
        DVec3::new(a, b, c),
        DVec3::new(0.0, b, c),
    ]
}

/// The rectangle of `perpendicular`, seen from the origin with normal +z: in the plane y = c,
/// x from 0 to a along the shared edge, z from 0 to b.
fn perpendicular_rectangle(a: f64, b: f64, c: f64) -> Vec<DVec3> {
    vec![
        DVec3::new(0.0, c, 0.0),
        DVec3::new(a, c, 0.0),
        DVec3::new(a, c, b),
        DVec3::new(0.0, c, b),
    ]
}

/// Deterministic pseudo-random numbers in [0, 1): the project's seeded generator.
struct Rng(pxpl5_geom::rng::Lcg);

impl Rng {
    fn next(&mut self) -> f64 {
        self.0.unit()
    }

    /// A uniformly distributed unit vector (rejection from the cube).
    fn direction(&mut self) -> DVec3 {
        loop {
            let v = [
                2.0 * self.next() - 1.0,
                2.0 * self.next() - 1.0,
                2.0 * self.next() - 1.0,
            ];
            let len = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
            if len > 0.1 && len <= 1.0 {
                return DVec3::new(v[0] / len, v[1] / len, v[2] / len);
            }
        }
    }
}

/// Rotation by `angle` about the unit `axis` (Rodrigues).
fn rotate(v: DVec3, axis: DVec3, angle: f64) -> DVec3 {
    let (s, c) = angle.sin_cos();
    let k = axis;
    let kxv = [
        k[1] * v[2] - k[2] * v[1],
        k[2] * v[0] - k[0] * v[2],
        k[0] * v[1] - k[1] * v[0],
    ];
    let kv = k[0] * v[0] + k[1] * v[1] + k[2] * v[2];
    DVec3::new(
        v[0] * c + kxv[0] * s + k[0] * kv * (1.0 - c),
        v[1] * c + kxv[1] * s + k[1] * kv * (1.0 - c),
        v[2] * c + kxv[2] * s + k[2] * kv * (1.0 - c),
    )
}

#[test]
fn parallel_rectangle_through_a_corner() {
    for (a, b, c) in [
        (1.0, 1.0, 1.0),
        (2.0, 0.5, 1.0),
        (0.1, 3.0, 2.0),
        (10.0, 10.0, 0.1),
        (0.01, 0.02, 5.0),
        (100.0, 0.3, 7.0),
    ] {
        let got = point_to_polygon(DVec3::ZERO, UP, &parallel_rectangle(a, b, c));
        let want = parallel_corner(a, b, c);
        assert!(rel_err(got, want) < 1e-9, "{a} {b} {c}: {got} vs {want}");
    }
}

#[test]
fn coaxial_disk_as_a_720_gon() {
    const N: usize = 720;
    let gon = |r: f64, h: f64| -> Vec<DVec3> {
        (0..N)
            .map(|k| {
                let a = TAU * k as f64 / N as f64;
                DVec3::new(r * a.cos(), r * a.sin(), h)
            })
            .collect()
    };
    // Circumradius factor of the regular N-gon with the disk's area: its remaining difference
    // from the disk is of second order (measured under 1e-11), so the comparison tests the
    // formula rather than the polygon.
    let equal_area = (TAU / (N as f64 * (TAU / N as f64).sin())).sqrt();
    for (radius, h) in [(1.0, 1.0), (0.5, 2.0), (3.0, 0.2), (1.0, 10.0), (2.0, 0.01)] {
        let want = radius * radius / (radius * radius + h * h);
        // The inscribed 720-gon lacks 1.3e-5 of the disk's area: within 1e-5 absolute.
        let inscribed = point_to_polygon(DVec3::ZERO, UP, &gon(radius, h));
        assert!(
            (inscribed - want).abs() < 1e-5 && inscribed < want,
            "R {radius} h {h}: {inscribed} vs {want}"
        );
        let got = point_to_polygon(DVec3::ZERO, UP, &gon(radius * equal_area, h));
        assert!(
            rel_err(got, want) < 1e-9,
            "R {radius} h {h}: {got} vs {want}"
        );
    }
}

#[test]
fn perpendicular_rectangle_sharing_an_edge() {
    for (a, b, c) in [
        (1.0, 1.0, 1.0),
        (2.0, 0.5, 1.0),
        (0.1, 3.0, 2.0),
        (10.0, 10.0, 0.1),
        (0.5, 0.01, 3.0),
        (3.0, 40.0, 0.7),
    ] {
        let got = point_to_polygon(DVec3::ZERO, UP, &perpendicular_rectangle(a, b, c));
        let want = perpendicular(a, b, c);
        assert!(rel_err(got, want) < 1e-9, "{a} {b} {c}: {got} vs {want}");
    }
}

/// A generic configuration: a tilted quad seen from an off-origin point with a tilted normal.
fn generic() -> (DVec3, DVec3, Vec<DVec3>) {
    let p = DVec3::new(0.3, -0.2, 0.1);
    let n = {
        let v: DVec3 = DVec3::new(0.2, 0.1, 1.0);
        let l = (v[0] * v[0] + v[1] * v[1] + v[2] * v[2]).sqrt();
        DVec3::new(v[0] / l, v[1] / l, v[2] / l)
    };
    let quad = vec![
        DVec3::new(-0.5, -0.4, 1.2),
        DVec3::new(0.9, -0.3, 1.5),
        DVec3::new(1.1, 0.8, 1.0),
        DVec3::new(-0.2, 0.7, 0.9),
    ];
    (p, n, quad)
}

#[test]
fn scale_invariance() {
    let (p, n, quad) = generic();
    let base = point_to_polygon(p, n, &quad);
    assert!(base > 0.05, "{base}");
    // 1e-6 to 1e6 as asked, and beyond: the vertices are rescaled inside, so even 1e+-200 (whose
    // cross products would overflow or underflow) keeps every digit.
    for s in [1e-200, 1e-6, 1e-3, 0.1, 7.0, 1e3, 1e6, 1e200] {
        let scaled: Vec<DVec3> = quad.iter().map(|v| v.map(|c| c * s)).collect();
        let got = point_to_polygon(p.map(|c| c * s), n, &scaled);
        assert!(rel_err(got, base) < 1e-9, "scale {s}: {got} vs {base}");
    }
}

#[test]
fn rotation_invariance() {
    let (p, n, quad) = generic();
    let base = point_to_polygon(p, n, &quad);
    let mut rng = Rng(pxpl5_geom::rng::Lcg::new(7));
    for _ in 0..20 {
        let axis = rng.direction();
        let angle = TAU * rng.next();
        let r = |v: DVec3| rotate(v, axis, angle);
        let turned: Vec<DVec3> = quad.iter().map(|&v| r(v)).collect();
        let got = point_to_polygon(r(p), r(n), &turned);
        assert!(
            rel_err(got, base) < 1e-9,
            "{axis:?} {angle}: {got} vs {base}"
        );
    }
}

#[test]
fn polygon_partly_below_the_horizon() {
    // A square in the plane y = 1 spanning z from -1 to 1: only its upper half is visible, and
    // by symmetry that half is two perpendicular rectangles of the closed form (a = b = c = 1).
    let square = [
        DVec3::new(-1.0, 1.0, -1.0),
        DVec3::new(1.0, 1.0, -1.0),
        DVec3::new(1.0, 1.0, 1.0),
        DVec3::new(-1.0, 1.0, 1.0),
    ];
    let by_hand = [
        DVec3::new(-1.0, 1.0, 0.0),
        DVec3::new(1.0, 1.0, 0.0),
        DVec3::new(1.0, 1.0, 1.0),
        DVec3::new(-1.0, 1.0, 1.0),
    ];
    let got = point_to_polygon(DVec3::ZERO, UP, &square);
    let clipped = point_to_polygon(DVec3::ZERO, UP, &by_hand);
    assert!(rel_err(got, clipped) < 1e-12, "{got} vs {clipped}");
    let want = 2.0 * perpendicular(1.0, 1.0, 1.0);
    assert!(rel_err(got, want) < 1e-9, "{got} vs {want}");

    // A tilted triangle with one vertex below: clipped by hand at the two crossings.
    let tri = [
        DVec3::new(0.0, 1.0, -1.0),
        DVec3::new(1.0, 1.0, 1.0),
        DVec3::new(-1.0, 2.0, 1.0),
    ];
    // Edge 0-1 crosses z = 0 at its middle (0.5, 1, 0); edge 2-0 also at its middle
    // (-0.5, 1.5, 0).
    let tri_by_hand = [
        DVec3::new(0.5, 1.0, 0.0),
        DVec3::new(1.0, 1.0, 1.0),
        DVec3::new(-1.0, 2.0, 1.0),
        DVec3::new(-0.5, 1.5, 0.0),
    ];
    let got = point_to_polygon(DVec3::ZERO, UP, &tri);
    let want = point_to_polygon(DVec3::ZERO, UP, &tri_by_hand);
    assert!(rel_err(got, want) < 1e-12, "{got} vs {want}");
    // The contour sum of the unclipped triangle is far off (the part below counts negatively):
    // the case really exercises the clip.
    let unclipped = unclipped_contour(DVec3::ZERO, UP, &tri);
    assert!(rel_err(unclipped, want) > 0.1, "{unclipped} vs {want}");
    let unclipped = unclipped_contour(DVec3::ZERO, UP, &square);
    assert!(unclipped < 1e-12, "{unclipped}");
}

/// The contour formula without the horizon clip, to show what the clip fixes.
fn unclipped_contour(p: DVec3, n: DVec3, polygon: &[DVec3]) -> f64 {
    let m = polygon.len();
    let mut sum = 0.0;
    for i in 0..m {
        let r = |v: DVec3| [v[0] - p[0], v[1] - p[1], v[2] - p[2]];
        let (a, b) = (r(polygon[i]), r(polygon[(i + 1) % m]));
        let c = [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ];
        let c_len = (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt();
        if c_len > 0.0 {
            let gamma = c_len.atan2(a[0] * b[0] + a[1] * b[1] + a[2] * b[2]);
            sum += gamma * (n[0] * c[0] + n[1] * c[1] + n[2] * c[2]) / c_len;
        }
    }
    sum.abs() / TAU
}

#[test]
fn polygon_wholly_below_is_zero() {
    let below = parallel_rectangle(1.0, 2.0, -1.0);
    assert_eq!(point_to_polygon(DVec3::ZERO, UP, &below), 0.0);
    // Touching the horizon with one edge and otherwise below: still nothing visible.
    let touching = [
        DVec3::new(0.0, 1.0, 0.0),
        DVec3::new(1.0, 1.0, 0.0),
        DVec3::new(1.0, 1.0, -1.0),
        DVec3::new(0.0, 1.0, -1.0),
    ];
    assert_eq!(point_to_polygon(DVec3::ZERO, UP, &touching), 0.0);
}

#[test]
fn sliver_of_width_1e_minus_9() {
    for (w, b, c) in [(1e-9, 1.0, 1.0), (1e-9, 0.2, 3.0), (1e-12, 1.0, 1.0)] {
        let got = point_to_polygon(DVec3::ZERO, UP, &parallel_rectangle(w, b, c));
        let want = parallel_corner(w, b, c);
        assert!(got.is_finite());
        assert!(rel_err(got, want) < 1e-9, "{w} {b} {c}: {got} vs {want}");
        // The same sliver as a triangle along the other axis.
        let tri = [
            DVec3::new(0.0, 0.0, c),
            DVec3::new(b, 0.0, c),
            DVec3::new(b, w, c),
        ];
        let got = point_to_polygon(DVec3::ZERO, UP, &tri);
        assert!(got.is_finite() && got > 0.0 && got < want * 1.001, "{got}");
    }
}

#[test]
fn never_nan_for_finite_input() {
    // Points on vertices and edges, polygons through p, huge and tiny coordinates.
    let sq = [
        DVec3::new(0.0, 0.0, 1.0),
        DVec3::new(1.0, 0.0, 1.0),
        DVec3::new(1.0, 1.0, 1.0),
        DVec3::new(0.0, 1.0, 1.0),
    ];
    let mut rng = Rng(pxpl5_geom::rng::Lcg::new(99));
    let mut cases: Vec<(DVec3, DVec3)> = vec![
        (DVec3::new(0.0, 0.0, 1.0), UP),
        (DVec3::new(0.0, 0.0, 1.0), DVec3::new(0.0, 0.0, -1.0)),
        (DVec3::new(0.5, 0.0, 1.0), DVec3::new(0.0, 1.0, 0.0)),
        (DVec3::new(0.5, 0.0, 0.0), DVec3::new(1.0, 0.0, 0.0)),
        (DVec3::new(1e300, 0.0, 0.0), UP),
        (DVec3::new(1e-300, 1e-300, 0.0), UP),
        (DVec3::new(0.2, 0.3, 0.0), DVec3::new(1e-300, 0.0, 1e-310)),
        (DVec3::new(0.2, 0.3, 0.0), DVec3::new(1e300, 1e300, 1e300)),
        (DVec3::new(0.2, 0.3, 0.0), DVec3::new(0.0, 0.0, f64::MAX)),
    ];
    for _ in 0..200 {
        let p = DVec3::new(
            3.0 * rng.next() - 1.0,
            3.0 * rng.next() - 1.0,
            3.0 * rng.next() - 1.0,
        );
        cases.push((p, rng.direction()));
    }
    for (p, n) in cases {
        let f = point_to_polygon(p, n, &sq);
        assert!(
            f.is_finite() && (0.0..=1.0 + 1e-12).contains(&f),
            "{p:?} {n:?}: {f}"
        );
    }
    // Extreme coordinates: overflowing differences, subnormal polygons.
    let big = f64::MAX;
    let polygons = [
        vec![
            DVec3::new(-big, -big, big),
            DVec3::new(big, -big, big),
            DVec3::new(big, big, big),
            DVec3::new(-big, big, big),
        ],
        vec![
            DVec3::new(0.0, 0.0, 1e-310),
            DVec3::new(1e-310, 0.0, 1e-310),
            DVec3::new(0.0, 1e-310, 1e-310),
        ],
        vec![
            DVec3::new(0.0, 0.0, 1e200),
            DVec3::new(1e200, 0.0, 1e200),
            DVec3::new(0.0, 1e200, 1e200),
        ],
    ];
    for polygon in &polygons {
        for p in [
            DVec3::ZERO,
            DVec3::new(-big, 0.0, -big),
            DVec3::new(1e-320, 0.0, 0.0),
        ] {
            let f = point_to_polygon(p, UP, polygon);
            assert!(
                f.is_finite() && (0.0..=1.0 + 1e-12).contains(&f),
                "{p:?} {polygon:?}: {f}"
            );
        }
    }
    // Seen from the origin, the huge square overhead fills most of the hemisphere.
    let f = point_to_polygon(DVec3::ZERO, UP, &polygons[0]);
    assert!(
        (f - 4.0 * parallel_corner(1.0, 1.0, 1.0)).abs() < 1e-9,
        "{f}"
    );
}

#[test]
fn form_factors_inside_a_closed_box_sum_to_one() {
    let faces: Vec<Vec<DVec3>> = empty_box()
        .surfaces
        .iter()
        .map(|s| {
            s.vertices
                .iter()
                .map(|&(x, y, z)| DVec3::new(x, y, z))
                .collect()
        })
        .collect();
    let axes = [
        DVec3::new(1.0, 0.0, 0.0),
        DVec3::new(-1.0, 0.0, 0.0),
        DVec3::new(0.0, 1.0, 0.0),
        DVec3::new(0.0, -1.0, 0.0),
        DVec3::new(0.0, 0.0, 1.0),
        DVec3::new(0.0, 0.0, -1.0),
    ];
    let mut rng = Rng(pxpl5_geom::rng::Lcg::new(2024));
    for k in 0..50 {
        let p = DVec3::new(
            0.01 + 0.98 * rng.next(),
            0.01 + 0.98 * rng.next(),
            0.01 + 0.98 * rng.next(),
        );
        // Every fifth point looks along an axis (whole faces behind it, side faces clipped
        // exactly at their middle); the rest in random directions.
        let n = if k % 5 == 0 {
            axes[(k / 5) % 6]
        } else {
            rng.direction()
        };
        let sum: f64 = faces.iter().map(|f| point_to_polygon(p, n, f)).sum();
        assert!((sum - 1.0).abs() < 1e-9, "point {k} {p:?} {n:?}: sum {sum}");
    }
    // The centre, looking straight at a face: four corner rectangles of the closed form to it,
    // the rest split evenly among the four sides.
    let f: Vec<f64> = faces
        .iter()
        .map(|f| point_to_polygon(DVec3::splat(0.5), DVec3::new(0.0, 1.0, 0.0), f))
        .collect();
    let ceiling = 4.0 * parallel_corner(0.5, 0.5, 0.5);
    assert!(rel_err(f[1], ceiling) < 1e-12, "{f:?}");
    assert_eq!(f[0], 0.0);
    for side in &f[2..] {
        assert!(rel_err(*side, (1.0 - ceiling) / 4.0) < 1e-12, "{f:?}");
    }
}

#[test]
fn closed_boxes_at_other_scales_sum_to_one() {
    let mut rng = Rng(pxpl5_geom::rng::Lcg::new(5));
    for size in [1e-6, 1e-2, 1e3, 1e6] {
        let faces: Vec<Vec<DVec3>> = closed_box(size, 0.5)
            .surfaces
            .iter()
            .map(|s| {
                s.vertices
                    .iter()
                    .map(|&(x, y, z)| DVec3::new(x, y, z))
                    .collect()
            })
            .collect();
        for _ in 0..10 {
            let p = DVec3::new(
                size * (0.01 + 0.98 * rng.next()),
                size * (0.01 + 0.98 * rng.next()),
                size * (0.01 + 0.98 * rng.next()),
            );
            let n = rng.direction();
            let sum: f64 = faces.iter().map(|f| point_to_polygon(p, n, f)).sum();
            assert!((sum - 1.0).abs() < 1e-9, "size {size} {p:?}: {sum}");
        }
    }
}
