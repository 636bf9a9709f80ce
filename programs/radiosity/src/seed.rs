//! The seed report's (TR89-002's) estimate of form-factor time, set beside every measurement so
//! that the two can be compared (docs/tr89-002.md, "Section II: the estimate" and "What the
//! estimate leaves out").
//!
//! The estimate counts, per broadcast, the M patches sent at 10^6 polygons per second and one
//! 128 x 128 ID readback at 80 million ring words per second; the hemicube broadcasts five times
//! per shooter, the hemisphere once. It uses the report's constants whatever the machine config
//! and resolution, so that it stays the report's number.

use crate::shot::Method;

/// The report's rendering rate: polygons per second (Pixel-Planes 5's design goal).
const POLYGONS_PER_SECOND: f64 = 1e6;
/// Words of one readback: one per pixel of a 128 x 128 Renderer.
const READBACK_WORDS: f64 = 128.0 * 128.0;
/// The ring's rate in the report: 80 million words per second ("4 channels on the ring").
const RING_WORDS_PER_SECOND: f64 = 80e6;

/// The seed's estimate for one run, in seconds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SeedEstimate {
    /// The report's total as written: faces x (M N / 10^6 + 128^2 / (80 x 10^6)).
    pub as_written: f64,
    /// The same with the readback term multiplied by N, since a readback happens once per shot:
    /// faces x (M N / 10^6 + N x 128^2 / (80 x 10^6)).
    pub readback_x_n: f64,
}

/// The seed's estimate for `patches` (M) patches and `shots` (N) shots with `method`.
pub fn seed_estimate(patches: usize, shots: usize, method: Method) -> SeedEstimate {
    let faces = match method {
        Method::Hemicube => 5.0,
        Method::Hemisphere => 1.0,
    };
    let broadcast = patches as f64 * shots as f64 / POLYGONS_PER_SECOND;
    let readback = READBACK_WORDS / RING_WORDS_PER_SECOND;
    SeedEstimate {
        as_written: faces * (broadcast + readback),
        readback_x_n: faces * (broadcast + shots as f64 * readback),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// docs/tr89-002.md's example: M = 1,000, N = 10.
    #[test]
    fn the_documented_example() {
        let ms = |s: f64| (s * 1e4).round() / 10.0;
        let sphere = seed_estimate(1000, 10, Method::Hemisphere);
        let cube = seed_estimate(1000, 10, Method::Hemicube);
        assert_eq!((ms(sphere.as_written), ms(cube.as_written)), (10.2, 51.0));
        assert_eq!(
            (ms(sphere.readback_x_n), ms(cube.readback_x_n)),
            (12.0, 60.2)
        );
    }
}
