//! Host-side reference solutions, for tests and for measuring the machine's error: progressive
//! refinement with exact point-to-patch form factors (docs/radiosity.md sections 1 and 4),
//! and a direct solve of (I - rho F) B = E on the same form-factor matrix.
//!
//! Both use the matrix the progressive method implies: F_ij from the centre of shooter i to
//! patch j (exact contour formula, unoccluded: meant for convex closed scenes such as the empty
//! box), and F_ji = F_ij A_i / A_j by reciprocity, so that the two solutions must agree.

use crate::exact::point_to_polygon;
use crate::mesh::Patch;

/// `F[i][j]`: from the centre of patch i to patch j (0 on the diagonal).
pub fn exact_matrix(patches: &[Patch]) -> Vec<Vec<f64>> {
    (0..patches.len()).map(|i| exact_row(patches, i)).collect()
}

/// F_ij from the centre of patch `i` to every patch j (0 for j = i): row `i` of [`exact_matrix`].
pub fn exact_row(patches: &[Patch], i: usize) -> Vec<f64> {
    let pi = &patches[i];
    patches
        .iter()
        .enumerate()
        .map(|(j, pj)| {
            if i == j {
                0.0
            } else {
                point_to_polygon(pi.centre, pi.normal, &pj.vertices)
            }
        })
        .collect()
}

/// Progressive refinement with the matrix `f` until the largest unshot power is below
/// `threshold` of the emitted power (or `max_shots`); radiosity per patch and band.
pub fn progressive(
    patches: &[Patch],
    f: &[Vec<f64>],
    threshold: f64,
    max_shots: usize,
) -> Vec<[f64; 3]> {
    progressive_by_rows(patches, |i| f[i].clone(), threshold, max_shots).0
}

/// [`progressive`] with the form-factor row of each shooter from `row(i)` (only the shooters'
/// rows are needed): the radiosity per patch and band, and the shooters in order. The shooter is
/// the patch of largest unshot power, ties to the lower index.
pub fn progressive_by_rows(
    patches: &[Patch],
    mut row: impl FnMut(usize) -> Vec<f64>,
    threshold: f64,
    max_shots: usize,
) -> (Vec<[f64; 3]>, Vec<usize>) {
    let mut b: Vec<[f64; 3]> = patches.iter().map(|p| p.emission).collect();
    let mut db = b.clone();
    let mut shooters = Vec::new();
    let power = |p: &Patch, u: [f64; 3]| (u[0] + u[1] + u[2]) * p.area;
    let emitted: f64 = patches.iter().map(|p| power(p, p.emission)).sum();
    for _ in 0..max_shots {
        let (best, i) = patches
            .iter()
            .enumerate()
            .map(|(i, p)| (power(p, db[i]), i))
            .fold((-1.0, 0), |a, x| if x.0 > a.0 { x } else { a });
        if emitted <= 0.0 || best / emitted < threshold {
            break;
        }
        shooters.push(i);
        let fi = row(i);
        let shot = db[i];
        for (j, pj) in patches.iter().enumerate() {
            if j == i {
                continue;
            }
            let fji = (fi[j] * patches[i].area / pj.area).min(1.0);
            for k in 0..3 {
                let d = pj.reflectance[k] * shot[k] * fji;
                b[j][k] += d;
                db[j][k] += d;
            }
        }
        db[i] = [0.0; 3];
    }
    (b, shooters)
}

/// The solution of (I - rho F^T') B = E with F_ji = F_ij A_i / A_j, by Gauss-Seidel iteration
/// to a relative change below 1e-13.
pub fn direct(patches: &[Patch], f: &[Vec<f64>]) -> Vec<[f64; 3]> {
    let n = patches.len();
    let mut b: Vec<[f64; 3]> = patches.iter().map(|p| p.emission).collect();
    for _ in 0..10_000 {
        let mut change: f64 = 0.0;
        for j in 0..n {
            let mut gathered = [0.0; 3];
            for (i, bi) in b.iter().enumerate().filter(|(i, _)| *i != j) {
                let fji = (f[i][j] * patches[i].area / patches[j].area).min(1.0);
                for (g, x) in gathered.iter_mut().zip(bi) {
                    *g += fji * x;
                }
            }
            let p = &patches[j];
            for (k, g) in gathered.iter().enumerate() {
                let new = p.emission[k] + p.reflectance[k] * g;
                change = change.max((new - b[j][k]).abs() / new.abs().max(1e-300));
                b[j][k] = new;
            }
        }
        if change < 1e-13 {
            break;
        }
    }
    b
}
