//! How good a radiosity solution is: its error against the scene's reference solution, surface
//! by surface, and the error of the machine's form factors against the exact ones for the same
//! shooters.
//!
//! The reference exists only for an unoccluded scene ([`RadiosityScene::unoccluded`]: the inside
//! of a convex shell, such as `cornell-empty.ron`), where the exact point-to-polygon form
//! factors need no visibility: it is the direct solve of (I - rho F) B = E on the same mesh
//! with them ([`solver::direct`]), the solution progressive refinement converges to. A scene with
//! occluders has no reference here, and the figures that need one are absent, not estimated.
//!
//! A surface's error is that of its area-weighted mean radiosity, per colour band, relative to
//! the reference's; the solution's error is the worst over surfaces and bands (bands where the
//! reference is 0 are skipped). A shot's form-factor error is the relative L1 distance of the
//! machine's row F_i. from the exact one: sum |F_ij - F*_ij| / sum F*_ij.

use crate::mesh::Patch;
use crate::program::Batch;
use crate::scene::RadiosityScene;
use crate::solver;

/// The reference solution of a meshed, unoccluded scene.
#[derive(Clone, Debug)]
pub struct Reference {
    /// Per patch: its surface.
    surface_of: Vec<usize>,
    /// Per patch: its area.
    area: Vec<f64>,
    /// Surface names, for reports.
    names: Vec<String>,
    /// Per surface and band: the area-weighted mean radiosity of the direct solve.
    means: Vec<[f64; 3]>,
    /// The exact form factors, F[i][j] from the centre of patch i to patch j.
    form_factors: Vec<Vec<f64>>,
    /// The power the scene emits: sum of area x (E_R + E_G + E_B), as progressive refinement
    /// counts unshot power.
    emitted: f64,
}

/// A solution's worst surface error.
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceError {
    /// Relative error, e.g. 0.01 for 1 %.
    pub worst: f64,
    /// The surface and band (0 R, 1 G, 2 B) where it is.
    pub surface: String,
    pub band: usize,
}

impl Reference {
    /// The reference of `scene` meshed into `patches`, or `None` if the scene has occluders.
    /// Costs N^2 exact form factors and a direct solve.
    pub fn new(scene: &RadiosityScene, patches: &[Patch]) -> Option<Reference> {
        if !scene.unoccluded() {
            return None;
        }
        let form_factors = solver::exact_matrix(patches);
        let direct = solver::direct(patches, &form_factors);
        let mut r = Reference {
            surface_of: patches.iter().map(|p| p.surface).collect(),
            area: patches.iter().map(|p| p.area).collect(),
            names: scene.surfaces.iter().map(|s| s.name.clone()).collect(),
            means: Vec::new(),
            form_factors,
            emitted: patches
                .iter()
                .map(|p| p.area * p.emission.iter().sum::<f64>())
                .sum(),
        };
        r.means = r.surface_means(&direct);
        Some(r)
    }

    /// Per surface and band, the area-weighted mean of `radiosity` (one entry per patch).
    fn surface_means(&self, radiosity: &[[f64; 3]]) -> Vec<[f64; 3]> {
        let mut sum = vec![[0.0; 3]; self.names.len()];
        let mut area = vec![0.0; self.names.len()];
        for ((&s, &a), b) in self.surface_of.iter().zip(&self.area).zip(radiosity) {
            area[s] += a;
            for k in 0..3 {
                sum[s][k] += a * b[k];
            }
        }
        sum.iter()
            .zip(&area)
            .map(|(s, &a)| if a > 0.0 { s.map(|x| x / a) } else { [0.0; 3] })
            .collect()
    }

    /// The worst surface error of `radiosity` (one entry per patch).
    pub fn surface_error(&self, radiosity: &[[f64; 3]]) -> SurfaceError {
        let means = self.surface_means(radiosity);
        let mut worst = SurfaceError {
            worst: 0.0,
            surface: String::new(),
            band: 0,
        };
        for (s, (got, want)) in means.iter().zip(&self.means).enumerate() {
            for k in 0..3 {
                if want[k] <= 0.0 {
                    continue;
                }
                let e = (got[k] - want[k]).abs() / want[k];
                if e > worst.worst || worst.surface.is_empty() {
                    worst = SurfaceError {
                        worst: e,
                        surface: self.names[s].clone(),
                        band: k,
                    };
                }
            }
        }
        worst
    }

    /// The unshot power of `unshot` (one entry per patch) over the emitted power: the fraction
    /// `--threshold` compares the largest patch's with.
    pub fn unshot_fraction(&self, unshot: &[[f64; 3]]) -> f64 {
        let power: f64 = self
            .area
            .iter()
            .zip(unshot)
            .map(|(a, u)| a * u.iter().sum::<f64>())
            .sum();
        if self.emitted > 0.0 {
            power / self.emitted
        } else {
            0.0
        }
    }

    /// The relative L1 error of a machine-computed row of form factors from patch `shooter`.
    pub fn form_factor_error(&self, shooter: usize, row: &[f64]) -> f64 {
        let exact = &self.form_factors[shooter];
        let total: f64 = exact.iter().sum();
        let diff: f64 = exact.iter().zip(row).map(|(e, m)| (m - e).abs()).sum();
        if total > 0.0 { diff / total } else { 0.0 }
    }
}

/// One batch of a run, as its accuracy saw it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Point {
    /// Simulated seconds at the batch's end.
    pub seconds: f64,
    /// Shots so far.
    pub shots: usize,
    /// The worst surface error after the batch.
    pub error: f64,
    /// The unshot power left, over the emitted power ([`Reference::unshot_fraction`]): what a
    /// user without a reference can watch, beside the error it corresponds to.
    pub unshot: f64,
}

/// A run's accuracy over its batches, against a reference.
#[derive(Clone, Debug, PartialEq)]
pub struct Convergence {
    pub curve: Vec<Point>,
    /// The first batch within `target`: (simulated seconds, shots), if any.
    pub time_to_target: Option<(f64, usize)>,
    pub target: f64,
    /// The error after the last batch.
    pub last: Option<SurfaceError>,
    /// The mean over shots of the form-factor error ([`Reference::form_factor_error`]).
    pub form_factor_error: f64,
}

impl Convergence {
    /// The accuracy of the batches of one run against `reference`, with `target` the error a
    /// solution must reach (e.g. 0.01).
    pub fn new(reference: &Reference, batches: &[Batch], target: f64) -> Convergence {
        let mut curve = Vec::with_capacity(batches.len());
        let mut shots = 0;
        let (mut ff_sum, mut ff_n) = (0.0, 0usize);
        for b in batches {
            shots += b.shooters.len();
            curve.push(Point {
                seconds: b.end.as_secs_f64(),
                shots,
                error: reference.surface_error(&b.radiosity).worst,
                unshot: reference.unshot_fraction(&b.unshot),
            });
            for (&i, row) in b.shooters.iter().zip(&b.form_factors) {
                ff_sum += reference.form_factor_error(i, row);
                ff_n += 1;
            }
        }
        let time_to_target = curve
            .iter()
            .find(|p| p.error <= target)
            .map(|p| (p.seconds, p.shots));
        Convergence {
            time_to_target,
            target,
            last: batches
                .last()
                .map(|b| reference.surface_error(&b.radiosity)),
            form_factor_error: if ff_n > 0 { ff_sum / ff_n as f64 } else { 0.0 },
            curve,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::mesh;
    use crate::scenes;

    #[test]
    fn the_reference_is_its_own_solution_and_exact_rows_have_no_error() {
        let scene = scenes::cornell_empty();
        let patches = mesh(&scene, 150.0).unwrap();
        let r = Reference::new(&scene, &patches).expect("unoccluded");
        let direct = solver::direct(&patches, &r.form_factors);
        assert_eq!(r.surface_error(&direct).worst, 0.0);
        assert_eq!(r.form_factor_error(3, &r.form_factors[3]), 0.0);
        // Emission alone: every lit surface is 100 % low; the light itself is exact.
        let emitted: Vec<[f64; 3]> = patches.iter().map(|p| p.emission).collect();
        let e = r.surface_error(&emitted);
        assert_eq!(e.worst, 1.0, "{e:?}");
        // A row 10 % high everywhere is 10 % off.
        let high: Vec<f64> = r.form_factors[3].iter().map(|f| f * 1.1).collect();
        assert!((r.form_factor_error(3, &high) - 0.1).abs() < 1e-12);
        // The Cornell box with its blocks has no reference here.
        let full = scenes::cornell_box();
        assert!(Reference::new(&full, &mesh(&full, 150.0).unwrap()).is_none());
    }

    #[test]
    fn progressive_refinement_approaches_the_reference() {
        let scene = scenes::cornell_empty();
        let patches = mesh(&scene, 150.0).unwrap();
        let r = Reference::new(&scene, &patches).unwrap();
        let after = |shots| {
            let b = solver::progressive(&patches, &r.form_factors, 0.0, shots);
            r.surface_error(&b).worst
        };
        let (a, b, c) = (after(20), after(200), after(1000));
        assert!(a > b && b > c, "{a} {b} {c}");
        assert!(c < 0.01, "{c}");
    }
}
