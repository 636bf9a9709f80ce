//! The polygon program's geometry, shared by the GP code and the reference rasteriser: camera
//! transform, near/far clipping, projection to the frame buffer's pixel grid, and the QEE
//! expressions (edges, depth, colours) of a screen triangle in a region's local coordinates.
//!
//! Projected coordinates are finite for every scene the checks accept (`scene::MAX_COORDINATE`,
//! `scene::MIN_FOV_DEGREES`: at most about 1e25 pixels, whose areas and planes stay far inside
//! an f64); a screen triangle whose area is not finite (a camera the checks refuse) is dropped,
//! and one whose expressions still cannot be quantised is an error, never a panic.
//!
//! Screen coordinates: x to the right, y up, pixel (x, y) sampled at its integer address (the
//! projection puts pixel centres on integers). A region's Renderer works in local addresses
//! (origin (0, 0)), so coefficients stay small: a global address up to 1280 would multiply every
//! rounding error of a coefficient by 1280 and push constant terms past the QEE's 13 integer bits.

use pxpl5_config::FixedFormat;
use pxpl5_geom::{DVec3, vec3};
use pxpl5_renderer::{QeeExpr, QuantiseError, Window};

use crate::scene::{Camera, TriangleScene};

/// A screen-space triple: (x, y, depth) of a vertex, or its (r, g, b).
pub type V3 = [f64; 3];

/// `a` divided by its length (divided, not multiplied by the reciprocal as glam's `normalize`:
/// the rounding the polygon goldens were made with).
fn unit(a: DVec3) -> DVec3 {
    a / a.length()
}

/// The camera as an orthonormal frame and a projection onto a `width` x `height` screen.
#[derive(Clone, Debug)]
pub struct View {
    eye: DVec3,
    right: DVec3,
    up: DVec3,
    back: DVec3,
    /// Pixels per unit of (x / depth) on screen.
    focal: f64,
    near: f64,
    far: f64,
    width: f64,
    height: f64,
}

/// A triangle on the screen: pixel coordinates, depth in 0..1 (near to far, linear in screen
/// space: a + b / depth), colours 0..255.
#[derive(Clone, Debug, PartialEq)]
pub struct ScreenTriangle {
    /// Index of the scene triangle it came from (clipping may make two).
    pub source: usize,
    pub xyz: [V3; 3],
    pub rgb: [V3; 3],
}

impl View {
    pub fn new(c: &Camera, width: u32, height: u32) -> View {
        let forward = unit(vec3(c.target) - vec3(c.eye));
        let right = unit(forward.cross(vec3(c.up)));
        let up = right.cross(forward);
        let half = (c.fov_y_degrees.to_radians() / 2.0).tan();
        View {
            eye: vec3(c.eye),
            right,
            up,
            back: -forward,
            focal: f64::from(height) / 2.0 / half,
            near: c.near,
            far: c.far,
            width: f64::from(width),
            height: f64::from(height),
        }
    }

    /// Camera-space position: (right, up, distance in front).
    fn camera(&self, p: DVec3) -> V3 {
        let d = p - self.eye;
        [d.dot(self.right), d.dot(self.up), -d.dot(self.back)]
    }

    /// Transform, clip against the near and far planes, and project one scene triangle; 0, 1 or 2
    /// screen triangles (a clipped triangle is a quad, split in two).
    pub fn project(&self, scene: &TriangleScene, index: usize) -> Vec<ScreenTriangle> {
        let tri = &scene.triangles[index];
        let mut poly: Vec<(V3, V3)> = (0..3)
            .map(|k| {
                let v = tri.vertices[k];
                let c = tri.colours[k];
                (
                    self.camera(vec3(v)),
                    [c.0 * 255.0, c.1 * 255.0, c.2 * 255.0],
                )
            })
            .collect();
        // Against depth >= near and depth <= far.
        for (limit, keep_above) in [(self.near, true), (self.far, false)] {
            poly = pxpl5_geom::clip::clip(
                &poly,
                |(p, _)| {
                    if keep_above {
                        p[2] >= limit
                    } else {
                        p[2] <= limit
                    }
                },
                |&(a, ca), &(b, cb)| {
                    let t = (limit - a[2]) / (b[2] - a[2]);
                    let lerp = |x: V3, y: V3| {
                        [
                            x[0] + t * (y[0] - x[0]),
                            x[1] + t * (y[1] - x[1]),
                            x[2] + t * (y[2] - x[2]),
                        ]
                    };
                    (lerp(a, b), lerp(ca, cb))
                },
            );
        }
        if poly.len() < 3 {
            return Vec::new();
        }
        let screen: Vec<(V3, V3)> = poly
            .iter()
            .map(|(p, c)| {
                let x = self.width / 2.0 + self.focal * p[0] / p[2] - 0.5;
                let y = self.height / 2.0 + self.focal * p[1] / p[2] - 0.5;
                // Depth mapped like a perspective z-buffer: 0 at near, 1 at far, affine in
                // screen space.
                let z = (1.0 / self.near - 1.0 / p[2]) / (1.0 / self.near - 1.0 / self.far);
                ([x, y, z], *c)
            })
            .collect();
        (1..screen.len() - 1)
            .map(|k| ScreenTriangle {
                source: index,
                xyz: [screen[0].0, screen[k].0, screen[k + 1].0],
                rgb: [screen[0].1, screen[k].1, screen[k + 1].1],
            })
            // Not finite only for a camera the scene checks refuse (see the module doc).
            .filter(|t| {
                let area = signed_area(t);
                area != 0.0 && area.is_finite()
            })
            .collect()
    }
}

/// Twice the signed screen area.
pub fn signed_area(t: &ScreenTriangle) -> f64 {
    let [a, b, c] = t.xyz;
    (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])
}

/// The regions (column, row of the `side`-pixel grid) a triangle's bounding box touches.
pub fn regions(t: &ScreenTriangle, side: u32, columns: u32, rows: u32) -> Vec<(u32, u32)> {
    let (mut lo, mut hi) = ([f64::MAX; 2], [f64::MIN; 2]);
    for v in t.xyz {
        for k in 0..2 {
            lo[k] = lo[k].min(v[k]);
            hi[k] = hi[k].max(v[k]);
        }
    }
    let s = f64::from(side);
    let range = |lo: f64, hi: f64, n: u32| {
        let a = (lo / s).floor().max(0.0);
        let b = (hi / s).floor().min(f64::from(n) - 1.0);
        if a > b {
            None
        } else {
            Some((a as u32, b as u32))
        }
    };
    let (Some((c0, c1)), Some((r0, r1))) =
        (range(lo[0], hi[0], columns), range(lo[1], hi[1], rows))
    else {
        return Vec::new();
    };
    let mut out = Vec::new();
    for r in r0..=r1 {
        for c in c0..=c1 {
            out.push((c, r));
        }
    }
    out
}

/// What the Renderer evaluates for one triangle in one region.
#[derive(Clone, Debug, PartialEq)]
pub struct TriangleExprs {
    /// Edge tests that can change something in the region (W >= 0 inside), each with its window.
    pub edges: Vec<(QeeExpr, Window)>,
    pub depth: QeeExpr,
    pub colours: [QeeExpr; 3],
}

/// Depth is stored as `floor(z * 2^DEPTH_BITS_FRAC)`: the expression carries z scaled by
/// 2^DEPTH_SCALE_LOG2, and the window drops the bits below DEPTH_BITS_FRAC.
pub const DEPTH_SCALE_LOG2: i32 = 10;
/// Width of the depth field: z in 0..1 at `frac_bits + DEPTH_SCALE_LOG2 - DEPTH_SHIFT` fractional
/// bits plus a sign bit and headroom for slight overshoot at clipped edges.
pub const DEPTH_FIELD_BITS: u32 = 24;
/// Bits the depth window drops.
pub const DEPTH_SHIFT: u32 = 6;

/// The plane through three (x, y, value) points as [A, B, C] of A x + B y + C, in local
/// coordinates, with A and B clamped to `max_slope` (a sliver's plane can be arbitrarily steep;
/// clamping keeps it representable and changes at most that sliver's pixels) and C chosen to keep
/// the value at the centroid.
fn plane(p: [[f64; 3]; 3], max_slope: f64) -> [f64; 3] {
    let [a, b, c] = p;
    let (e1, e2) = (
        DVec3::from_array(b) - DVec3::from_array(a),
        DVec3::from_array(c) - DVec3::from_array(a),
    );
    let n = e1.cross(e2);
    let (mut ga, mut gb) = (-n.x / n.z, -n.y / n.z);
    ga = ga.clamp(-max_slope, max_slope);
    gb = gb.clamp(-max_slope, max_slope);
    let cx = (a[0] + b[0] + c[0]) / 3.0;
    let cy = (a[1] + b[1] + c[1]) / 3.0;
    let cv = (a[2] + b[2] + c[2]) / 3.0;
    [ga, gb, cv - ga * cx - gb * cy]
}

fn fits(v: f64, f: FixedFormat) -> f64 {
    // The largest magnitude the format holds, a little inside it.
    let max = (f.int_bits as f64).exp2() - 1.0;
    v.clamp(-max, max)
}

/// The expressions of `t` for the region whose lower-left pixel is (x0, y0), or None when the
/// triangle cannot touch the region. `side` is the Renderer's width (= height).
///
/// Coefficients are clamped to `format` (a format of at least one integer bit, as configs
/// are checked to have), so the error is for input no checked scene and camera produce: a
/// coordinate that is not finite.
pub fn triangle_exprs(
    t: &ScreenTriangle,
    x0: u32,
    y0: u32,
    side: u32,
    format: FixedFormat,
) -> Result<Option<TriangleExprs>, QuantiseError> {
    let local: [V3; 3] = t
        .xyz
        .map(|v| [v[0] - f64::from(x0), v[1] - f64::from(y0), v[2]]);
    // Counter-clockwise: the interior is on the left of every edge.
    let ccw = signed_area(t) > 0.0;
    let max = f64::from(side);
    let q = |c: [f64; 6]| QeeExpr::quantise(c, format);
    let mut edges = Vec::new();
    for k in 0..3 {
        let (p, r) = if ccw {
            (local[k], local[(k + 1) % 3])
        } else {
            (local[(k + 1) % 3], local[k])
        };
        // Inside: (r - p) x (s - p) >= 0, i.e. a x + b y + c >= 0.
        let (a, b) = (-(r[1] - p[1]), r[0] - p[0]);
        let c = -(a * p[0] + b * p[1]);
        let scale = a.abs().max(b.abs());
        let (a, b, c) = (a / scale, b / scale, c / scale);
        // The edge line's values at the region's corners (-1 .. side): if all are inside the
        // test changes nothing; if all are outside the triangle misses the region.
        let corners = [(-1.0, -1.0), (max, -1.0), (-1.0, max), (max, max)];
        let vals: Vec<f64> = corners.iter().map(|(x, y)| a * x + b * y + c).collect();
        if vals.iter().all(|v| *v >= 0.5) {
            continue;
        }
        if vals.iter().all(|v| *v < -0.5) {
            return Ok(None);
        }
        let e = q([a, b, fits(c, format), 0.0, 0.0, 0.0])?;
        edges.push((e, e.sign_window((0, 0), side, side)));
    }
    let scale = f64::from(DEPTH_SCALE_LOG2).exp2();
    let max_slope = (format.int_bits as f64).exp2() / (4.0 * max);
    let [za, zb, zc] = plane(local.map(|v| [v[0], v[1], v[2] * scale]), max_slope);
    let depth = q([za, zb, fits(zc, format), 0.0, 0.0, 0.0])?;
    let colour = |k: usize| {
        let [a, b, c] = plane(
            [0, 1, 2].map(|i| [local[i][0], local[i][1], t.rgb[i][k] + 0.5]),
            max_slope,
        );
        q([a, b, fits(c, format), 0.0, 0.0, 0.0])
    };
    Ok(Some(TriangleExprs {
        edges,
        depth,
        colours: [colour(0)?, colour(1)?, colour(2)?],
    }))
}
