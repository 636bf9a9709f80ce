//! The quadratic expression evaluator (QEE): exact integer semantics of quantised coefficients,
//! the result window, and the tree's three bit streams.
//!
//! Every pixel at address (x, y) (its position in the array plus the region origin) receives
//!
//! ```text
//!     V(x, y) = A x + B y + C + D x^2 + E x y + F y^2
//! ```
//!
//! where A..F are the *raw* integers of the coefficients in the configured [`FixedFormat`]
//! (value = raw / 2^frac_bits), so V is an exact integer in units of 2^-frac_bits. Linear
//! expressions are the case D = E = F = 0.
//!
//! **The result window (the documented cut rule).** A command asks for `bits` result bits starting
//! at bit `shift` of V. The tree delivers V bit-serially, least significant bit first, one bit per
//! Renderer cycle after its pipeline fill; the pixel ignores the first `shift` bits and uses the
//! next `bits`. The window is therefore `W = (V >> shift) mod 2^bits` (arithmetic shift, i.e.
//! floor division, then two's-complement wrap): a bit-serial LSB-first machine cannot saturate,
//! because it has written the low bits before it sees the high ones. Read as signed, W equals
//! floor(V / 2^shift) whenever that fits in `bits` bits; choosing a window wide enough is the
//! program's job (its GP knows the coefficients and the region).
//!
//! **The tree, as the bit-level model builds it** (\[assumed\]: the hardware's internal structure
//! is not published; what is fixed is that each pixel receives its exact value bit-serially,
//! \[lineage\]). The QEE is three serial-parallel trees whose outputs each pixel adds with its
//! own serial adders:
//! - the x-tree puts `X(x) = A x + D x^2` on every column line;
//! - the y-tree puts `Y(y) = C + B y + F y^2` on every row line;
//! - the cross stage puts `Z(x, y) = (E y) x` on every pixel (a per-row x-tree fed with E y);
//!   only expressions with E != 0 use it.
//!
//! So `V = X(x) + Y(y) + Z(x, y)`, which [`Streams`] computes once per command and both fidelity
//! levels consume: the `integer` level adds the three as integers, the `bit` level feeds them
//! through the pixels' serial adders one bit-plane per cycle.

use pxpl5_config::FixedFormat;
use thiserror::Error;

/// The six coefficients of a quadratic expression, as raw integers of the QEE's coefficient format
/// (value = raw / 2^frac_bits of the board's configured format).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct QeeExpr {
    pub a: i64,
    pub b: i64,
    pub c: i64,
    pub d: i64,
    pub e: i64,
    pub f: i64,
}

/// Names of the coefficients, in the order of [`QeeExpr::raw`], for error messages.
pub const COEFFICIENT_NAMES: [&str; 6] = ["A", "B", "C", "D", "E", "F"];

/// A coefficient that cannot be represented in the configured format.
#[derive(Clone, Debug, PartialEq, Error)]
pub enum QuantiseError {
    #[error("coefficient {name} is {value}: not a finite number")]
    NotFinite { name: &'static str, value: f64 },
    #[error(
        "coefficient {name} = {value} does not fit the QEE format of {int_bits} integer and \
         {frac_bits} fractional bits (range {min} .. {max})"
    )]
    OutOfRange {
        name: &'static str,
        value: f64,
        int_bits: u32,
        frac_bits: u32,
        min: f64,
        max: f64,
    },
}

/// The bits of a result that a command uses: `bits` bits starting at bit `shift` of V.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Window {
    pub shift: u32,
    pub bits: u32,
}

impl Window {
    /// Cycles the tree needs to deliver this window: every bit up to the window's top.
    pub fn delivered_bits(self) -> u32 {
        self.shift + self.bits
    }

    /// The window of `v`, as raw bits (the low `bits` bits of floor(v / 2^shift)).
    pub fn cut(self, v: i64) -> u64 {
        ((v >> self.shift) as u64) & mask(self.bits)
    }
}

/// The low `bits` bits set.
pub fn mask(bits: u32) -> u64 {
    if bits >= 64 {
        u64::MAX
    } else {
        (1u64 << bits) - 1
    }
}

/// 2^e, exactly: the same value as `(e as f64).exp2()` (glibc's exp2 is exact at integers),
/// without a library call. Quantising a GP's coefficients takes several per receiver.
#[inline]
pub fn pow2(e: i32) -> f64 {
    if (-1022..=1023).contains(&e) {
        f64::from_bits(((e + 1023) as u64) << 52)
    } else {
        f64::from(e).exp2()
    }
}

/// `x.round()` (to nearest, halves away from zero), bit for bit, without the library call that
/// it is on x86-64's baseline, and in floating point alone. Exact: below 2^52, adding and then
/// subtracting 2^52 gives the integer nearest to |x| (the sum lies where the floats are the
/// integers), a half rounding to the even one; a half that went down is taken up. At and above
/// 2^52 every float is an integer.
///
/// The truncation through i64 this replaced cost two saturating conversions (their NaN and
/// overflow fix-ups included) per coefficient `QeeExpr::quantise` rounds. The choice is a
/// select, not a branch: the fractions of a GP's coefficients are as likely above a half as
/// below, and a branch there was mispredicted (`perf record -e cpu-clock`).
#[inline]
pub fn round(x: f64) -> f64 {
    const TWO_52: f64 = 4_503_599_627_370_496.0;
    let a = x.abs();
    // Integers, infinities and NaN (not below anything): round changes none of them.
    if a.partial_cmp(&TWO_52) != Some(std::cmp::Ordering::Less) {
        return x;
    }
    let nearest = (a + TWO_52) - TWO_52;
    // Only a half rounded down to the even integer leaves exactly 0.5.
    let away = if a - nearest >= 0.5 {
        nearest + 1.0
    } else {
        nearest
    };
    // -0.3 rounds to -0.
    away.copysign(x)
}

/// `x.log2().floor()` as an integer, for a positive finite x: the float's exponent, without the
/// two library calls, where its mantissa is far enough from 1 and from 2 that glibc's log2
/// (within an ulp) floors to it too; at other values, that computation itself.
#[inline]
pub fn floor_log2(x: f64) -> i32 {
    let bits = x.to_bits();
    let exponent = ((bits >> 52) & 0x7ff) as i32;
    let mantissa = bits & ((1 << 52) - 1);
    // Guard bands of 2^-30 of the mantissa: log2 there is at least 2^-31 from an integer,
    // thousands of ulps.
    let guard = 1u64 << 22;
    let normal = exponent != 0 && exponent != 0x7ff && (bits >> 63) == 0;
    if normal && mantissa >= guard && mantissa < (1 << 52) - guard {
        exponent - 1023
    } else {
        x.log2().floor() as i32
    }
}

impl QeeExpr {
    /// `r2 - (kx (x - cx)^2 + e (x - cx) (y - cy) + ky (y - cy)^2)` in raw units: at least 0
    /// inside an ellipse about (cx, cy) when kx, ky > 0 and 4 kx ky > e^2 (a conic for tests
    /// and for programs that draw one).
    pub fn ellipse((cx, cy): (i64, i64), (kx, e, ky): (i64, i64, i64), r2: i64) -> QeeExpr {
        QeeExpr::from_raw([
            2 * kx * cx + e * cy,
            2 * ky * cy + e * cx,
            r2 - kx * cx * cx - e * cx * cy - ky * cy * cy,
            -kx,
            -e,
            -ky,
        ])
    }

    /// The linear expression A x + B y + C, already in raw units.
    pub fn linear(a: i64, b: i64, c: i64) -> QeeExpr {
        QeeExpr {
            a,
            b,
            c,
            ..QeeExpr::default()
        }
    }

    /// Quantise real coefficients `[A, B, C, D, E, F]` to `format`, rounding to nearest (halves
    /// away from zero). An error names the coefficient that is not finite or does not fit.
    /// Inlined: returned, the result was written a field at a time and copied whole by 16-byte
    /// loads that cannot take 8-byte stores' values forwarded (`perf annotate`, a GP's
    /// `quantise_for_sign`).
    #[inline(always)]
    pub fn quantise(coefficients: [f64; 6], format: FixedFormat) -> Result<QeeExpr, QuantiseError> {
        let scale = pow2(format.frac_bits as i32);
        let max_raw = (1i64 << (format.int_bits + format.frac_bits)) - 1;
        let mut raw = [0i64; 6];
        for (i, &value) in coefficients.iter().enumerate() {
            let name = COEFFICIENT_NAMES[i];
            if !value.is_finite() {
                return Err(QuantiseError::NotFinite { name, value });
            }
            let r = round(value * scale);
            if r > max_raw as f64 || r < -(max_raw as f64) - 1.0 {
                return Err(QuantiseError::OutOfRange {
                    name,
                    value,
                    int_bits: format.int_bits,
                    frac_bits: format.frac_bits,
                    min: -((max_raw + 1) as f64) / scale,
                    max: max_raw as f64 / scale,
                });
            }
            raw[i] = r as i64;
        }
        Ok(QeeExpr::from_raw(raw))
    }

    pub fn from_raw(r: [i64; 6]) -> QeeExpr {
        QeeExpr {
            a: r[0],
            b: r[1],
            c: r[2],
            d: r[3],
            e: r[4],
            f: r[5],
        }
    }

    pub fn raw(&self) -> [i64; 6] {
        [self.a, self.b, self.c, self.d, self.e, self.f]
    }

    /// Whether any second-order coefficient is non-zero (costs the quadratic extra cycles).
    pub fn is_quadratic(&self) -> bool {
        self.d != 0 || self.e != 0 || self.f != 0
    }

    /// A bound on |V| over the pixel addresses `origin .. origin + (width, height)`: the sum of
    /// each coefficient's magnitude times its monomial's largest magnitude there.
    pub fn bound(&self, origin: (u32, u32), width: u32, height: u32) -> u128 {
        let xm = u128::from(origin.0 + width.saturating_sub(1));
        let ym = u128::from(origin.1 + height.saturating_sub(1));
        let m = |c: i64| u128::from(c.unsigned_abs());
        m(self.a) * xm
            + m(self.b) * ym
            + m(self.c)
            + m(self.d) * xm * xm
            + m(self.e) * xm * ym
            + m(self.f) * ym * ym
    }

    /// The narrowest window from bit 0 whose signed value holds V everywhere in the region, so a
    /// sign test there is exact: what a GP program computes before it sends a sign test.
    pub fn sign_window(&self, origin: (u32, u32), width: u32, height: u32) -> Window {
        let bound = self.bound(origin, width, height);
        // Magnitude bits plus the sign bit.
        let bits = (128 - bound.leading_zeros()) + 1;
        Window { shift: 0, bits }
    }

    /// The exact value at pixel address (x, y), in raw units. The board's validation bounds the
    /// coefficients and addresses so that this cannot overflow (see `pxpl5_config` checks on
    /// `coefficient_format` and `coordinate_bits`).
    pub fn eval(&self, x: i64, y: i64) -> i64 {
        self.a * x + self.b * y + self.c + self.d * x * x + self.e * x * y + self.f * y * y
    }
}

/// Real coefficients `[A, B, C, D, E, F]` of `A u + B v + C + D u^2 + E uv + F v^2` rewritten for
/// pixel addresses by substituting u = k s + m and v = k t + m: how a GP program maps its own
/// coordinates (a disk from -1 to 1, say) onto the QEE's addresses before quantising.
pub fn substitute_affine(q: [f64; 6], k: f64, m: f64) -> [f64; 6] {
    let [a, b, c, d, e, f] = q;
    [
        a * k + 2.0 * d * k * m + e * k * m,
        b * k + 2.0 * f * k * m + e * k * m,
        c + (a + b) * m + (d + e + f) * m * m,
        d * k * k,
        e * k * k,
        f * k * k,
    ]
}

/// The three streams of the tree for one command on one board (see the module doc):
/// `V(px, py) = col[px] + row[py] + e_row[py] * x`, with x = origin_x + px.
#[derive(Clone, Debug)]
pub struct Streams {
    /// X(x) = A x + D x^2 per column of the array.
    pub col: Vec<i64>,
    /// Y(y) = C + B y + F y^2 per row of the array.
    pub row: Vec<i64>,
    /// E y per row: the cross stage's per-row multiplier; all zero when E = 0.
    pub e_row: Vec<i64>,
    /// Pixel address of column 0 (the region origin's x).
    pub origin_x: i64,
    /// Whether the cross stage is in use (E != 0).
    pub cross: bool,
    /// The expression and the region origin's y, for [`Streams::row_fn`]: along row py,
    /// V = D x^2 + (A + E y) x + Y(y), which the `integer` level solves per row.
    pub expr: QeeExpr,
    pub origin_y: i64,
}

impl Streams {
    /// The streams of `expr` on a `width` x `height` array whose pixel (0, 0) has address
    /// `origin`.
    pub fn new(expr: &QeeExpr, origin: (u32, u32), width: usize, height: usize) -> Streams {
        let mut s = Streams {
            col: Vec::with_capacity(width),
            row: Vec::with_capacity(height),
            e_row: Vec::with_capacity(height),
            origin_x: 0,
            cross: false,
            expr: QeeExpr::default(),
            origin_y: 0,
        };
        s.fill(expr, origin, width, height);
        s
    }

    /// Overwrite these streams with those of `expr` (as [`Streams::new`]), reusing the vectors:
    /// a board keeps one `Streams` and refills it for every QEE command.
    pub fn fill(&mut self, expr: &QeeExpr, origin: (u32, u32), width: usize, height: usize) {
        self.set_expr(expr, origin);
        let (ox, oy) = (origin.0 as i64, origin.1 as i64);
        self.col.clear();
        self.col.extend((0..width as i64).map(|px| {
            let x = ox + px;
            expr.a * x + expr.d * x * x
        }));
        self.row.clear();
        self.row.extend((0..height as i64).map(|py| {
            let y = oy + py;
            expr.c + expr.b * y + expr.f * y * y
        }));
        self.e_row.clear();
        self.e_row
            .extend((0..height as i64).map(|py| expr.e * (oy + py)));
    }

    /// Streams that answer only [`Streams::row_fn`] (as after [`Streams::set_expr`]), allocating
    /// nothing. (The `sparse` level keeps a deferred sign test's expression and origin alone, and
    /// its rows by [`RowFn::of`]: kept as streams, their three empty lists cost 0.8 % of `bench
    /// renderer`'s hemisphere stream.)
    pub fn for_rows(expr: &QeeExpr, origin: (u32, u32)) -> Streams {
        Streams {
            col: Vec::new(),
            row: Vec::new(),
            e_row: Vec::new(),
            origin_x: i64::from(origin.0),
            cross: expr.e != 0,
            expr: *expr,
            origin_y: i64::from(origin.1),
        }
    }

    /// Only what [`Streams::row_fn`] reads, the expression and the origin, with the three
    /// streams left empty: the `integer` level evaluates rows as quadratics and never reads the
    /// streams, so it does not pay for them.
    pub fn set_expr(&mut self, expr: &QeeExpr, origin: (u32, u32)) {
        self.col.clear();
        self.row.clear();
        self.e_row.clear();
        self.expr = *expr;
        self.origin_x = i64::from(origin.0);
        self.origin_y = i64::from(origin.1);
        self.cross = expr.e != 0;
    }

    /// V along row `py` as a function of the column: `D x^2 + (A + E y) x + Y(y)` with
    /// x = origin_x + px, evaluated as `(D x + b) x + Y(y)`. Equal to [`Streams::value`]: the
    /// config's bound on coefficient and coordinate bits keeps every partial sum inside i64.
    #[inline]
    pub fn row_fn(&self, py: usize) -> RowFn {
        RowFn::of(&self.expr, (self.origin_x, self.origin_y), py)
    }

    /// The cross term Z at (px, py).
    #[inline]
    pub fn cross_at(&self, px: usize, py: usize) -> i64 {
        self.e_row[py] * (self.origin_x + px as i64)
    }

    /// V at (px, py): the sum of the three streams.
    #[inline]
    pub fn value(&self, px: usize, py: usize) -> i64 {
        self.col[px] + self.row[py] + self.cross_at(px, py)
    }
}

/// V along one row: `(d x + b) x + r` at x = x0 + px (see [`Streams::row_fn`]).
#[derive(Clone, Copy, Debug)]
pub struct RowFn {
    pub d: i64,
    pub b: i64,
    pub r: i64,
    pub x0: i64,
}

impl RowFn {
    /// Row `py` of `expr` drawn at board origin (ox, oy), as [`Streams::row_fn`] gives it.
    #[inline]
    pub fn of(e: &QeeExpr, (ox, oy): (i64, i64), py: usize) -> RowFn {
        let y = oy + py as i64;
        RowFn {
            d: e.d,
            b: e.a + e.e * y,
            r: e.c + e.b * y + e.f * y * y,
            x0: ox,
        }
    }

    #[inline]
    pub fn at(self, px: usize) -> i64 {
        let x = self.x0 + px as i64;
        (self.d * x + self.b) * x + self.r
    }

    /// V's first difference along the row, `at(px + 1) - at(px) = D (2x + 1) + b`, linear in
    /// the column: where a row's V turns, and its step from pixel to pixel. In wrapping
    /// arithmetic, so equal to the exact difference modulo 2^64 (exactly it where, as the
    /// config's bounds keep it, that fits i64).
    #[inline]
    pub fn diff(self, px: usize) -> i64 {
        let x = self.x0.wrapping_add(px as i64);
        self.d
            .wrapping_mul(x.wrapping_mul(2).wrapping_add(1))
            .wrapping_add(self.b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn substitution_matches_direct_evaluation() {
        let q = [0.3, -0.7, 0.11, 0.5, -0.25, 0.9];
        let (k, m) = (1.0 / 64.0, (0.5 - 64.0) / 64.0);
        let p = substitute_affine(q, k, m);
        for (s, t) in [(0.0, 0.0), (10.0, 100.0), (127.0, 63.0)] {
            let (u, v) = (k * s + m, k * t + m);
            let direct = q[0] * u + q[1] * v + q[2] + q[3] * u * u + q[4] * u * v + q[5] * v * v;
            let pix = p[0] * s + p[1] * t + p[2] + p[3] * s * s + p[4] * s * t + p[5] * t * t;
            assert!((direct - pix).abs() < 1e-12, "{direct} vs {pix}");
        }
    }

    const FMT: FixedFormat = FixedFormat {
        int_bits: 13,
        frac_bits: 18,
    };

    #[test]
    fn quantise_rounds_to_nearest_and_checks_range() {
        let e = QeeExpr::quantise([1.0, -0.5, 1.0 / 3.0, 0.0, 0.0, 0.0], FMT).unwrap();
        assert_eq!(e.a, 1 << 18);
        assert_eq!(e.b, -(1 << 17));
        assert_eq!(e.c, ((1u64 << 18) as f64 / 3.0).round() as i64);
        assert!(!e.is_quadratic());
        let err = QeeExpr::quantise([0.0, 0.0, 0.0, 9000.0, 0.0, 0.0], FMT).unwrap_err();
        assert!(err.to_string().contains("coefficient D"), "{err}");
        let err = QeeExpr::quantise([0.0, f64::NAN, 0.0, 0.0, 0.0, 0.0], FMT).unwrap_err();
        assert!(err.to_string().contains("coefficient B"), "{err}");
        // The extremes of the format are representable.
        let max = 8192.0 - 1.0 / 262144.0;
        assert!(QeeExpr::quantise([max, -8192.0, 0.0, 0.0, 0.0, 0.0], FMT).is_ok());
    }

    /// The library-free `pow2`, `round` and `floor_log2` give the library's results bit for
    /// bit: every exponent, halves and near-halves, zeros, extremes, values just off powers of
    /// two, and a sweep of magnitudes.
    #[test]
    fn fixed_point_helpers_match_the_library() {
        for e in -1100..1100 {
            assert_eq!(pow2(e).to_bits(), f64::from(e).exp2().to_bits(), "2^{e}");
        }
        let mut values = vec![
            0.0,
            -0.0,
            0.5,
            -0.5,
            1.5,
            2.5,
            -2.5,
            0.49999999999999994,
            -0.49999999999999994,
            4503599627370495.5,
            4503599627370496.0,
            9007199254740993.0,
            f64::MAX,
            f64::MIN_POSITIVE,
            5e-324,
            f64::INFINITY,
            f64::NEG_INFINITY,
        ];
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        for _ in 0..20_000 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let m = (x >> 11) as f64 / (1u64 << 53) as f64;
            let v = m * pow2((x % 160) as i32 - 60);
            values.extend([v, -v, v.floor() + 0.5, f64::from_bits(v.to_bits() + 1)]);
        }
        for e in -1074..1024 {
            let p = f64::from(e).exp2();
            values.extend([
                p,
                f64::from_bits(p.to_bits() + 1),
                f64::from_bits(p.to_bits() - 1),
            ]);
        }
        for &v in &values {
            assert_eq!(round(v).to_bits(), v.round().to_bits(), "round({v:e})");
            if v > 0.0 && v.is_finite() {
                assert_eq!(floor_log2(v), v.log2().floor() as i32, "floor_log2({v:e})");
            }
        }
        assert!(round(f64::NAN).is_nan());
    }

    /// `QeeExpr::ellipse` is r2 at its centre, and falls by the form's value away from it.
    #[test]
    fn ellipse_is_r2_less_the_form() {
        let q = QeeExpr::ellipse((40, -7), (3, -2, 5), 1000);
        assert_eq!(q.eval(40, -7), 1000);
        assert_eq!(q.eval(41, -7), 1000 - 3);
        assert_eq!(q.eval(40, -5), 1000 - 5 * 4);
        assert_eq!(q.eval(42, -6), 1000 - (3 * 4 - 2 * 2 + 5));
    }

    #[test]
    fn window_is_floor_then_wrap() {
        let w = Window { shift: 4, bits: 8 };
        assert_eq!(w.cut(0x1234), 0x23);
        // floor(-17 / 16) = -2, as 8 bits 0xFE.
        assert_eq!(w.cut(-17), 0xFE);
        // Too wide for the window: wraps, never saturates.
        assert_eq!(w.cut(0x1_0000 + 0x50), 0x05);
        assert_eq!(Window { shift: 0, bits: 64 }.cut(-1), u64::MAX);
    }

    #[test]
    fn streams_sum_to_the_exact_value() {
        let e = QeeExpr::from_raw([3, -7, 11, 5, -13, 2]);
        let s = Streams::new(&e, (100, 37), 128, 128);
        for (px, py) in [(0, 0), (127, 0), (0, 127), (64, 90), (127, 127)] {
            assert_eq!(
                s.value(px, py),
                e.eval(100 + px as i64, 37 + py as i64),
                "at ({px}, {py})"
            );
            assert_eq!(
                s.row_fn(py).at(px),
                s.value(px, py),
                "row form at ({px}, {py})"
            );
        }
        assert!(s.cross);
    }

    #[test]
    fn sign_window_holds_every_value() {
        let e = QeeExpr::from_raw([3, -7, 11, 5, -13, 2]);
        let w = e.sign_window((0, 0), 128, 128);
        let half = 1i64 << (w.bits - 1);
        for (x, y) in [(0, 0), (127, 0), (0, 127), (127, 127)] {
            let v = e.eval(x, y);
            assert!(-half <= v && v < half, "{v} outside {} bits", w.bits);
        }
        assert_eq!(QeeExpr::default().sign_window((0, 0), 128, 128).bits, 1);
    }
}
