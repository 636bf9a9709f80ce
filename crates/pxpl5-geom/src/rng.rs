//! The project's one seeded generator: a 64-bit linear congruential generator with Knuth's MMIX
//! constants. The seed is its only input and it uses integer arithmetic and one exact conversion,
//! so a stream is the same on every host (no `rand`, no time, no thread).
//!
//! The random triangle scenes of the polygon program (and hence its goldens) come from it, so its
//! constants and [`Lcg::unit`]'s mapping must not change.

/// A 64-bit LCG (MMIX: a = 6364136223846793005, c = 1442695040888963407).
#[derive(Clone, Debug)]
pub struct Lcg(u64);

impl Lcg {
    pub fn new(seed: u64) -> Lcg {
        Lcg(seed)
    }

    /// The next 64-bit state.
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        self.0
    }

    /// Uniform in [0, 1): the top 53 bits of the next state, exactly.
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Uniform in [lo, hi).
    pub fn range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }

    /// A rotation (cos a, sin a) with a uniform parameter t = tan(a / 2) in [-1, 1), so a covers
    /// [-90, 90) degrees: by the rational parametrisation ((1 - t^2) / (1 + t^2), 2 t / (1 + t^2)),
    /// exact to rounding and the same on every host (no sin or cos, whose last bits vary
    /// between libraries). Not uniform in angle; a view with 90-degree symmetry (a pixel grid, a
    /// hemicube) needs only that every orientation can occur.
    pub fn turn(&mut self) -> (f64, f64) {
        let t = self.range(-1.0, 1.0);
        let d = 1.0 + t * t;
        ((1.0 - t * t) / d, 2.0 * t / d)
    }

    /// An integer in 0..n (0 for n = 0) from the next state's high 31 bits (an LCG's low bits are
    /// poorly mixed), reduced mod n: for test inputs, not for statistics.
    pub fn below(&mut self, n: u64) -> u64 {
        (self.next_u64() >> 33) % n.max(1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stream_is_fixed() {
        let mut r = Lcg::new(1);
        assert_eq!(r.next_u64(), 7_806_831_264_735_756_412);
        let mut r = Lcg::new(1);
        let u = r.unit();
        assert_eq!(
            u,
            (7_806_831_264_735_756_412u64 >> 11) as f64 / 2f64.powi(53)
        );
        assert!((0.0..1.0).contains(&Lcg::new(u64::MAX).unit()));
        let x = Lcg::new(9).range(-2.0, 3.0);
        assert_eq!(Lcg::new(1).below(1 << 31), 7_806_831_264_735_756_412 >> 33);
        assert_eq!(Lcg::new(1).below(0), 0);
        let (c, s) = Lcg::new(3).turn();
        assert!((c * c + s * s - 1.0).abs() < 1e-15 && c >= 0.0);
        assert!((-2.0..3.0).contains(&x));
    }
}
