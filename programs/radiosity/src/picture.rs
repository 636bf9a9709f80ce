//! Pictures of a radiosity run, as RGB frames (encoding them is the caller's business):
//!
//! - the solution seen from the scene's camera ([`render`]), drawn by the simulated machine's own
//!   polygon pipeline (`pxpl5_polygons`): patches as triangles ([`triangle_scene`]),
//!   Gouraud-shaded from vertex radiosities ([`VertexRadiosity`]) of the displayed radiosity
//!   ([`display_radiosity`], with the ambient term of docs/radiosity.md section 1), tone-mapped
//!   ([`ToneMap`]);
//! - an item buffer, one colour per patch ID ([`item_buffer_picture`]).

use std::collections::BTreeMap;

use pxpl5_config::MachineConfig;
use pxpl5_geom::DVec3;
use pxpl5_machine::{FrameBufferImage, Machine, Recorder, RunError, RunOptions, RunResult};
use pxpl5_polygons::Polygons;
use pxpl5_polygons::scene::{Camera, Triangle, TriangleScene};

use crate::mesh::Patch;
use crate::program::Solution;
use crate::shot::ItemBuffer;

/// Per patch, the radiosity to show: the solution's plus its reflectance times the ambient term,
/// which stands for the light not shot yet (area-weighted mean unshot radiosity over one minus
/// the mean reflectance). For display only: it never enters the solution.
pub fn display_radiosity(patches: &[Patch], s: &Solution) -> Vec<[f64; 3]> {
    let area: f64 = patches.iter().map(|p| p.area).sum();
    let mut rho = [0.0; 3];
    let mut unshot = [0.0; 3];
    for (p, u) in patches.iter().zip(&s.unshot) {
        for k in 0..3 {
            rho[k] += p.reflectance[k] * p.area / area;
            unshot[k] += u[k] * p.area / area;
        }
    }
    patches
        .iter()
        .zip(&s.radiosity)
        .map(|(p, b)| {
            let mut d = [0.0; 3];
            for k in 0..3 {
                let ambient = unshot[k] / (1.0 - rho[k]).max(1e-9);
                d[k] = b[k] + p.reflectance[k] * ambient;
            }
            d
        })
        .collect()
}

/// (surface, vertex position in thousandths of a scene unit): patches of one surface share a
/// vertex when their rounded positions agree, so that float noise from meshing cannot split it.
type VertexKey = (usize, i64, i64, i64);

fn vertex_key(surface: usize, v: DVec3) -> VertexKey {
    (
        surface,
        (v[0] * 1e3).round() as i64,
        (v[1] * 1e3).round() as i64,
        (v[2] * 1e3).round() as i64,
    )
}

/// Radiosity at patch vertices: the mean over the patches of the same surface meeting at the
/// vertex (patches of different surfaces do not blend, so edges between walls stay sharp).
pub struct VertexRadiosity {
    /// Per vertex: summed radiosity and the number of patches summed.
    sums: BTreeMap<VertexKey, ([f64; 3], f64)>,
}

impl VertexRadiosity {
    /// The vertex radiosities of `patches`, whose radiosities are `per_patch`.
    pub fn new(patches: &[Patch], per_patch: &[[f64; 3]]) -> VertexRadiosity {
        let mut sums = BTreeMap::new();
        for (p, d) in patches.iter().zip(per_patch) {
            for v in &p.vertices {
                let e = sums
                    .entry(vertex_key(p.surface, *v))
                    .or_insert(([0.0; 3], 0.0));
                for (sum, x) in e.0.iter_mut().zip(d) {
                    *sum += x;
                }
                e.1 += 1.0;
            }
        }
        VertexRadiosity { sums }
    }

    /// The radiosity at vertex `v` of a patch of `surface`, if such a patch was given.
    pub fn at(&self, surface: usize, v: DVec3) -> Option<[f64; 3]> {
        let (c, n) = self.sums.get(&vertex_key(surface, v))?;
        Some([c[0] / n, c[1] / n, c[2] / n])
    }
}

/// Tone mapping: radiosity scaled so that the 95th percentile of patch luminance maps to 0.9 (a
/// few bright patches, the light above all, may saturate), clamped to [0, 1], then gamma 2.2.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ToneMap {
    /// The radiosity shown as full intensity.
    pub white: f64,
}

impl ToneMap {
    /// The tone map for patches whose displayed radiosities are `display`.
    pub fn new(display: &[[f64; 3]]) -> ToneMap {
        let mut lum: Vec<f64> = display.iter().map(|d| (d[0] + d[1] + d[2]) / 3.0).collect();
        lum.sort_by(f64::total_cmp);
        let white = lum
            .get(lum.len() * 95 / 100)
            .copied()
            .unwrap_or(1.0)
            .max(1e-12)
            / 0.9;
        ToneMap { white }
    }

    /// The displayed intensity, 0 to 1, of radiosity `x`.
    pub fn apply(&self, x: f64) -> f64 {
        (x / self.white).clamp(0.0, 1.0).powf(1.0 / 2.2)
    }
}

/// The solution `s` on `patches` as triangles seen by `camera`: each patch a fan of triangles,
/// each vertex coloured with its tone-mapped vertex radiosity.
///
/// # Panics
/// If `s` has fewer radiosities than there are patches (it is not their solution).
pub fn triangle_scene(patches: &[Patch], s: &Solution, camera: Camera) -> TriangleScene {
    let display = display_radiosity(patches, s);
    let vertices = VertexRadiosity::new(patches, &display);
    let tone = ToneMap::new(&display);
    let mut triangles = Vec::new();
    for p in patches {
        let colours: Vec<(f64, f64, f64)> = p
            .vertices
            .iter()
            .map(|v| {
                let c = vertices
                    .at(p.surface, *v)
                    .expect("every vertex of every patch was summed");
                (tone.apply(c[0]), tone.apply(c[1]), tone.apply(c[2]))
            })
            .collect();
        for k in 1..p.vertices.len() - 1 {
            let idx = [0, k, k + 1];
            triangles.push(Triangle {
                vertices: idx
                    .iter()
                    .map(|&i| (p.vertices[i][0], p.vertices[i][1], p.vertices[i][2]))
                    .collect(),
                colours: idx.iter().map(|&i| colours[i]).collect(),
            });
        }
    }
    TriangleScene { camera, triangles }
}

/// The solution `s` seen from `camera`, drawn by the polygon program on the machine of `cfg`
/// ([`triangle_scene`]) run with `options`; the picture is the result's `frame`.
pub fn render(
    cfg: &MachineConfig,
    patches: &[Patch],
    s: &Solution,
    camera: Camera,
    options: RunOptions,
) -> Result<RunResult, RunError> {
    let program = Polygons::new(triangle_scene(patches, s, camera));
    Machine::new(cfg, &program, options, Recorder::default())?.run()
}

/// An item buffer as a picture: one colour per ID (a multiplicative hash, lightened so that no
/// patch is black), black where nothing was drawn, the buffer's row 0 at the bottom.
pub fn item_buffer_picture(b: &ItemBuffer) -> FrameBufferImage {
    let mut rgb = Vec::with_capacity((b.width * b.rows * 3) as usize);
    for row in (0..b.rows).rev() {
        for col in 0..b.width {
            let id = b.ids[(row * b.width + col) as usize];
            if id == 0 {
                rgb.extend([0, 0, 0]);
            } else {
                let h = u32::from(id).wrapping_mul(0x9E37_79B9);
                rgb.extend([
                    (h >> 24) as u8 | 0x40,
                    (h >> 16) as u8 | 0x40,
                    (h >> 8) as u8 | 0x40,
                ]);
            }
        }
    }
    FrameBufferImage {
        width: b.width,
        height: b.rows,
        rgb,
        writes: 0,
    }
}
