//! Meshing: cuts every surface of a [`RadiosityScene`] into small convex patches, the unit the
//! radiosity solution shoots from and gathers into.
//!
//! Quadrilaterals become a bilinear grid of quads, triangles k x k similar sub-triangles, other
//! convex polygons a fan of triangles from vertex 0 each subdivided the same way. Patches come out
//! in surface order, and within a surface in a fixed grid order, so a mesh is reproducible and
//! patch indices can be compared between runs.

use pxpl5_config::SemanticError;
use pxpl5_geom::DVec3;

use crate::scene::{RadiosityScene, Surface, check_radiosity_scene};

/// Most patches [`mesh`] makes for a whole scene: the solver keeps per-patch state and a form
/// factor row per shot, so a typo in the patch size (millimetres for metres) must be an error, not
/// an out-of-memory crash.
pub const MAX_PATCHES: usize = 100_000;

/// One patch: a small planar convex polygon of one surface, with that surface's material.
#[derive(Clone, Debug, PartialEq)]
pub struct Patch {
    /// Index of the surface in [`RadiosityScene::surfaces`] it was cut from.
    pub surface: usize,
    /// Vertices, in the surface's orientation (counter-clockwise seen from the front).
    pub vertices: Vec<DVec3>,
    /// Area centroid.
    pub centre: DVec3,
    /// Unit normal of the surface's (best-fit) plane, on the front side.
    pub normal: DVec3,
    /// Area (projected onto the surface's plane, which is the exact area for planar input).
    pub area: f64,
    /// The surface's reflectance per band (R, G, B).
    pub reflectance: [f64; 3],
    /// The surface's emission per band (R, G, B).
    pub emission: [f64; 3],
}

/// Why a scene could not be meshed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MeshError {
    /// The patch size is not a finite positive number.
    #[error("patch size must be a finite number > 0 (got {0:?})")]
    BadPatchSize(f64),
    /// The scene breaks the rules of `check_radiosity_scene` (the mesher relies on them).
    #[error("the scene is invalid:\n{}", list(.0))]
    InvalidScene(Vec<SemanticError>),
    /// Meshing would make more than [`MAX_PATCHES`] patches; `count` is the running total reached
    /// with this surface (possibly infinite for an absurdly small patch size).
    #[error(
        "surfaces[{surface}] ({name}): patch size {patch_size:?} would make more than \
         {MAX_PATCHES} patches (about {} in all up to this surface); use a larger patch size",
        about(*.count)
    )]
    TooManyPatches {
        surface: usize,
        name: String,
        patch_size: f64,
        count: f64,
    },
}

/// A patch count for a report: whole below 10^12, else in scientific notation (it may overflow
/// an f64 for an absurdly small patch size).
fn about(count: f64) -> String {
    if !count.is_finite() {
        "more than 1e308".to_string()
    } else if count < 1e12 {
        format!("{count:.0}")
    } else {
        format!("{count:.1e}")
    }
}

fn list(errors: &[SemanticError]) -> String {
    errors
        .iter()
        .map(ToString::to_string)
        .collect::<Vec<_>>()
        .join("\n")
}

/// Number of pieces an edge of `length` is cut into so that each is at most `size`.
fn pieces(length: f64, size: f64) -> f64 {
    // Shave a relative 1e-12 so that an edge that is a whole multiple of the size (1.0 / 0.25,
    // 0.3 / 0.1 = 3.0000000000000004) is not cut once more by rounding.
    (length / size * (1.0 - 1e-12)).ceil().max(1.0)
}

/// How a surface is cut: the grid dimensions, decided before any patch is made so the count can
/// be checked first.
enum Plan {
    /// A bilinear grid of `n` x `m` quads (n along edge 0-1).
    Quad { n: usize, m: usize },
    /// Triangles (the surface itself, or a fan from vertex 0), each cut into `k` x `k`.
    Triangles(Vec<SubdividedTriangle>),
}

/// A triangle `a, b, c` (in the surface's orientation) to be cut into `k` x `k` similar ones.
struct SubdividedTriangle {
    a: DVec3,
    b: DVec3,
    c: DVec3,
    k: usize,
}

/// The plan for one surface and its patch count (as f64: it may be astronomically large).
fn plan(v: &[DVec3], size: f64) -> (Plan, f64) {
    let len = |a: usize, b: usize| (v[b] - v[a]).length();
    if v.len() == 4 {
        let n = pieces(len(0, 1).max(len(3, 2)), size);
        let m = pieces(len(1, 2).max(len(0, 3)), size);
        // Casts saturate; they are only used once the count is known to be small.
        let plan = Plan::Quad {
            n: n as usize,
            m: m as usize,
        };
        return (plan, n * m);
    }
    let mut triangles = Vec::new();
    let mut count = 0.0;
    for j in 1..v.len() - 1 {
        let (a, b, c) = (v[0], v[j], v[j + 1]);
        let longest = (b - a).length().max((c - b).length()).max((a - c).length());
        let k = pieces(longest, size);
        count += k * k;
        triangles.push(SubdividedTriangle {
            a,
            b,
            c,
            k: k as usize,
        });
    }
    (Plan::Triangles(triangles), count)
}

/// Cuts every surface into convex patches at most about `patch_size` across (edges at most
/// `patch_size`; a quad patch's diagonal may be up to about 1.4 times that).
///
/// The scene is checked first ([`check_radiosity_scene`]): the mesher relies on convex, planar,
/// finite polygons. Errors: a patch size that is not finite and positive, an invalid scene, and
/// more than [`MAX_PATCHES`] patches (naming the surface where the total passes the limit).
pub fn mesh(scene: &RadiosityScene, patch_size: f64) -> Result<Vec<Patch>, MeshError> {
    if !(patch_size.is_finite() && patch_size > 0.0) {
        return Err(MeshError::BadPatchSize(patch_size));
    }
    check_radiosity_scene(scene).map_err(MeshError::InvalidScene)?;
    let mut plans = Vec::with_capacity(scene.surfaces.len());
    let mut total = 0.0;
    for (i, surface) in scene.surfaces.iter().enumerate() {
        let vertices = surface.points();
        let (plan, count) = plan(&vertices, patch_size);
        total += count;
        // `total` may be infinite (a patch size of 1e-300), never NaN: `pieces` is at least 1.
        if total > MAX_PATCHES as f64 {
            return Err(MeshError::TooManyPatches {
                surface: i,
                name: surface.name.clone(),
                patch_size,
                count: total,
            });
        }
        plans.push((vertices, plan));
    }
    let mut patches = Vec::with_capacity(total as usize);
    for (i, (surface, (vertices, plan))) in scene.surfaces.iter().zip(plans).enumerate() {
        cut_surface(i, surface, &vertices, plan, &mut patches);
    }
    Ok(patches)
}

/// Appends the patches of surface `index` following `plan`.
fn cut_surface(index: usize, surface: &Surface, v: &[DVec3], plan: Plan, out: &mut Vec<Patch>) {
    // The scene was checked, so the plane exists; the fallback only keeps this panic-free.
    let normal = surface.plane().map_or(DVec3::Z, |p| p.normal);
    let mut push = |vertices: Vec<DVec3>| {
        let (area, centre) = area_centroid(&vertices, normal);
        out.push(Patch {
            surface: index,
            vertices,
            centre,
            normal,
            area,
            reflectance: surface.reflectance.into(),
            emission: surface.emission.into(),
        });
    };
    match plan {
        Plan::Quad { n, m } => {
            // Bilinear: P(s, t) = (1-s)(1-t) v0 + s(1-t) v1 + s t v2 + (1-s) t v3. Its iso-lines
            // are straight, so for a planar convex quad every cell is a planar convex quad, and
            // the cells tile the quad exactly.
            let at = |i: usize, j: usize| {
                let (s, t) = (i as f64 / n as f64, j as f64 / m as f64);
                let bottom = v[0] * (1.0 - s) + v[1] * s;
                let top = v[3] * (1.0 - s) + v[2] * s;
                bottom * (1.0 - t) + top * t
            };
            for j in 0..m {
                for i in 0..n {
                    push(vec![at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]);
                }
            }
        }
        Plan::Triangles(triangles) => {
            for SubdividedTriangle { a, b, c, k } in triangles {
                // Lattice points a + (i/k)(b - a) + (j/k)(c - a), i + j <= k; "upright" cells keep
                // the orientation of (a, b, c), and so do the "inverted" ones as listed.
                let (e1, e2) = (b - a, c - a);
                let kf = k as f64;
                let at = |i: usize, j: usize| a + (e1 * (i as f64 / kf) + e2 * (j as f64 / kf));
                for j in 0..k {
                    for i in 0..k - j {
                        push(vec![at(i, j), at(i + 1, j), at(i, j + 1)]);
                        if i + j + 2 <= k {
                            push(vec![at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]);
                        }
                    }
                }
            }
        }
    }
}

/// Area (projected onto the plane of unit normal `normal`) and area centroid of a convex polygon,
/// from a fan of triangles at vertex 0.
pub fn area_centroid(vertices: &[DVec3], normal: DVec3) -> (f64, DVec3) {
    let Some(&first) = vertices.first() else {
        return (0.0, DVec3::ZERO);
    };
    let mut area = 0.0;
    let mut moment = DVec3::ZERO;
    for k in 1..vertices.len().saturating_sub(1) {
        let (b, c) = (vertices[k], vertices[k + 1]);
        let a2 = normal.dot((b - first).cross(c - first));
        area += a2;
        let centre = (first + (b + c)) * (1.0 / 3.0);
        moment += centre * a2;
    }
    if area > 0.0 {
        (area / 2.0, moment * (1.0 / area))
    } else {
        // Degenerate: fall back to the vertex mean so the centre is still a point of the polygon.
        let mean = vertices.iter().fold(DVec3::ZERO, |s, &v| s + v);
        (0.0, mean * (1.0 / vertices.len() as f64))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenes::{closed_box, empty_box};

    fn one(vertices: &[(f64, f64, f64)]) -> RadiosityScene {
        RadiosityScene::one_surface(vertices, (0.25, 0.5, 0.75), (1.0, 2.0, 3.0))
    }

    fn total_area(patches: &[Patch]) -> f64 {
        patches.iter().map(|p| p.area).sum()
    }

    fn close(a: f64, b: f64, rel: f64) -> bool {
        (a - b).abs() <= rel * a.abs().max(b.abs())
    }

    #[test]
    fn quad_grid_counts_areas_and_centres() {
        // A 3 x 1 rectangle in the plane z = 2, normal +z.
        let s = one(&[
            (0.0, 0.0, 2.0),
            (3.0, 0.0, 2.0),
            (3.0, 1.0, 2.0),
            (0.0, 1.0, 2.0),
        ]);
        let p = mesh(&s, 0.5).unwrap();
        assert_eq!(p.len(), 6 * 2);
        assert!(close(total_area(&p), 3.0, 1e-12));
        assert!(p.iter().all(|p| p.normal == DVec3::new(0.0, 0.0, 1.0)));
        assert!(p.iter().all(|p| close(p.area, 0.25, 1e-12)));
        assert_eq!(p[0].centre, DVec3::new(0.25, 0.25, 2.0));
        assert_eq!(p[0].reflectance, [0.25, 0.5, 0.75]);
        assert_eq!(p[0].emission, [1.0, 2.0, 3.0]);
        // A patch size larger than the surface leaves it whole.
        assert_eq!(mesh(&s, 10.0).unwrap().len(), 1);
        // A trapezoid: n from the longer of edges 0-1 and 3-2 (4 and 2 long), m from the
        // longer leg (both sqrt 2).
        let t = one(&[
            (0.0, 0.0, 0.0),
            (4.0, 0.0, 0.0),
            (3.0, 1.0, 0.0),
            (1.0, 1.0, 0.0),
        ]);
        let p = mesh(&t, 1.0).unwrap();
        assert_eq!(p.len(), 4 * 2);
        assert!(close(total_area(&p), 3.0, 1e-12));
    }

    #[test]
    fn triangle_and_pentagon_areas() {
        let t = one(&[(0.0, 0.0, 0.0), (0.0, 2.0, 0.0), (0.0, 0.0, 1.0)]);
        let p = mesh(&t, 0.5).unwrap();
        // Longest edge sqrt(5) = 2.24: k = 5.
        assert_eq!(p.len(), 25);
        assert!(close(total_area(&p), 1.0, 1e-12));
        assert!(p.iter().all(|p| close(p.area, 1.0 / 25.0, 1e-9)));
        assert!(p.iter().all(|p| p.normal == DVec3::X));
        // A regular pentagon of circumradius 1 around (1, 2, 3), tilted.
        let pentagon: Vec<(f64, f64, f64)> = (0..5)
            .map(|k| {
                let a = std::f64::consts::TAU * k as f64 / 5.0;
                (1.0 + a.cos(), 2.0 + a.sin() * 0.6, 3.0 + a.sin() * 0.8)
            })
            .collect();
        let p = mesh(&one(&pentagon), 0.1).unwrap();
        let exact = 2.5 * (std::f64::consts::TAU / 5.0).sin();
        assert!(close(total_area(&p), exact, 1e-12), "{}", total_area(&p));
        let n = DVec3::new(0.0, -0.8, 0.6);
        assert!(p.iter().all(|p| (p.normal - n).length() < 1e-12));
        // Every patch centre lies in the pentagon's plane.
        assert!(
            p.iter()
                .all(|p| (p.centre - DVec3::new(1.0, 2.0, 3.0)).dot(n).abs() < 1e-12)
        );
    }

    #[test]
    fn empty_box_at_a_quarter() {
        let p = mesh(&empty_box(), 0.25).unwrap();
        assert_eq!(p.len(), 6 * 16);
        assert!(close(total_area(&p), 6.0, 1e-12));
        for (k, patch) in p.iter().enumerate() {
            assert_eq!(patch.surface, k / 16);
            // Inward: the box's centre is in front of every patch.
            assert!((DVec3::splat(0.5) - patch.centre).dot(patch.normal) > 0.0);
        }
        let lit: f64 = p
            .iter()
            .filter(|p| p.emission[0] > 0.0)
            .map(|p| p.area)
            .sum();
        assert!(close(lit, 1.0, 1e-12));
        assert_eq!(mesh(&closed_box(1.0, 0.5), 0.25).unwrap(), p);
    }

    #[test]
    fn deterministic() {
        let s = closed_box(7.0, 0.3);
        assert_eq!(mesh(&s, 0.9).unwrap(), mesh(&s, 0.9).unwrap());
    }

    #[test]
    fn errors() {
        let s = empty_box();
        for bad in [0.0, -1.0, f64::NAN, f64::INFINITY] {
            assert!(matches!(mesh(&s, bad), Err(MeshError::BadPatchSize(_))));
        }
        let e = mesh(&s, 1e-3).unwrap_err();
        assert!(
            matches!(e, MeshError::TooManyPatches { surface: 0, .. }),
            "{e}"
        );
        assert!(e.to_string().contains("surfaces[0] (floor)"), "{e}");
        let e = mesh(&s, 1e-300).unwrap_err();
        assert!(matches!(e, MeshError::TooManyPatches { .. }), "{e}");
        let mut bad = s.clone();
        bad.surfaces[2].vertices[1].0 = f64::NAN;
        let e = mesh(&bad, 0.5).unwrap_err().to_string();
        assert!(e.contains("surfaces[2] (wall -x).vertices[1]"), "{e}");
    }
}
