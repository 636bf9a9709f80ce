//! The pixel grid of a form-factor view: `n` pixels across the square [-1, 1] (the hemisphere's
//! unit disk seen from above, or a hemicube face in units of its half-width). Pixel `s` covers
//! [s h - 1, (s + 1) h - 1] with h = 2 / n and is sampled at its centre.
//!
//! The same map has two forms, each kept in the order of operations its users were written with:
//! [`Grid::centre`] for host tables (delta form factors, the w table), and [`Grid::affine`], the
//! coefficients (k, m) of u = k s + m that turn an expression in u into one in pixel addresses
//! for the QEE (`pxpl5_renderer::qee::substitute_affine`). They agree to within an ulp.

/// `n` pixels across [-1, 1].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Grid {
    pub n: u32,
}

impl Grid {
    pub fn new(n: u32) -> Grid {
        Grid { n }
    }

    /// The width of one pixel, 2 / n.
    pub fn pixel(self) -> f64 {
        2.0 / f64::from(self.n)
    }

    /// The centre of pixel `s`: (s + 0.5) h - 1.
    pub fn centre(self, s: u32) -> f64 {
        (f64::from(s) + 0.5) * self.pixel() - 1.0
    }

    /// The low edge of pixel `s`: s h - 1.
    pub fn edge(self, s: u32) -> f64 {
        f64::from(s) * self.pixel() - 1.0
    }

    /// (k, m) with u = k s + m the centre of pixel s: k = 2 / n, m = (1 - n) / n.
    pub fn affine(self) -> (f64, f64) {
        let n = f64::from(self.n);
        (2.0 / n, (1.0 - n) / n)
    }

    /// The pixel coordinate (fractional) of u: the inverse of [`Grid::centre`],
    /// s = (u + 1) n / 2 - 0.5.
    pub fn pixel_of(self, u: f64) -> f64 {
        (u + 1.0) * (f64::from(self.n) / 2.0) - 0.5
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn forms_agree() {
        for n in [1, 2, 7, 64, 96, 128, 1000] {
            let g = Grid::new(n);
            let (k, m) = g.affine();
            for s in [0, n / 2, n - 1] {
                let c = g.centre(s);
                assert!((k * f64::from(s) + m - c).abs() <= 4.0 * f64::EPSILON);
                assert!((g.pixel_of(c) - f64::from(s)).abs() < 1e-9);
                assert!(g.edge(s) < c && c < g.edge(s + 1));
            }
        }
        assert_eq!(Grid::new(128).affine(), (1.0 / 64.0, -127.0 / 128.0));
    }
}
