//! The `integer` fidelity level: pixel memory as per-pixel integers, operations as integer
//! arithmetic with exactly the semantics of the bit-serial level (proven equal by property tests).
//!
//! A pixel's memory is one integer of `memory_bits` bits, stored as 64-bit limbs: limb k holds
//! bits 64k .. 64k + 63 of every pixel (structure of arrays, so a field's loop walks one or two
//! contiguous vectors).
//!
//! The per-group loops of QEE stores, adds and compares and of constant writes are compiled
//! twice, for x86-64-v3 (AVX2, BMI1/2) and portably, and [`pulp`] picks the build the CPU can run
//! when the engine is made, as the `bit` level's QEE loops are; a test holds both to the same
//! values.

use super::{
    DepthTest, Geometry, PixelEngine, QeeSink, Registers, depth_test_one_by_one, extend, gated,
    value_of,
};
use crate::command::{Bit, Cmp, Field, LogicOp, Rect};
use crate::qee::{QeeExpr, RowFn, Streams, Window, mask};

/// Per-pixel integer pixel memory and the shared one-bit registers.
pub struct IntegerEngine {
    geometry: Geometry,
    limbs: Vec<Vec<u64>>,
    regs: Registers,
    /// Scratch: one row's sign bits (host work only).
    row_bits: Vec<u64>,
    /// The host instructions the per-pixel loops of QEE stores, compares and adds and of
    /// constant writes run with: x86-64-v3 (AVX2, and BMI1/2's one-instruction bit scans) where
    /// the CPU has it, found once, else the portable build. Both give the same values.
    arch: pulp::Arch,
}

/// Where a field's bits sit in the limbs.
#[derive(Clone, Copy)]
struct Access {
    limb: usize,
    shift: u32,
    bits: u32,
    mask: u64,
}

impl Access {
    fn of(f: Field) -> Access {
        Access {
            limb: (f.offset / 64) as usize,
            shift: f.offset % 64,
            bits: f.bits,
            mask: mask(f.bits),
        }
    }

    #[inline]
    fn straddles(self) -> bool {
        self.shift + self.bits > 64
    }
}

impl IntegerEngine {
    pub fn new(geometry: Geometry, memory_bits: u32, flag_count: usize) -> IntegerEngine {
        let limbs = memory_bits.div_ceil(64) as usize;
        IntegerEngine {
            geometry,
            limbs: vec![vec![0; geometry.groups * 64]; limbs],
            regs: Registers::new(geometry, flag_count),
            row_bits: vec![0; geometry.groups_per_row],
            arch: pulp::Arch::new(),
        }
    }

    /// This engine with its loops in the portable build whatever the host has: what the tests
    /// compare the dispatched build with.
    #[cfg(test)]
    pub(crate) fn portable(mut self) -> IntegerEngine {
        self.arch = pulp::Arch::Scalar;
        self
    }

    #[inline]
    fn get(&self, a: Access, p: usize) -> u64 {
        let lo = self.limbs[a.limb][p] >> a.shift;
        if a.straddles() {
            (lo | (self.limbs[a.limb + 1][p] << (64 - a.shift))) & a.mask
        } else {
            lo & a.mask
        }
    }

    #[inline]
    fn set(&mut self, a: Access, p: usize, v: u64) {
        let v = v & a.mask;
        let limb = &mut self.limbs[a.limb][p];
        *limb = (*limb & !(a.mask << a.shift)) | (v << a.shift);
        if a.straddles() {
            let hi_bits = a.shift + a.bits - 64;
            let hi_mask = mask(hi_bits);
            let limb = &mut self.limbs[a.limb + 1][p];
            *limb = (*limb & !hi_mask) | (v >> (64 - a.shift));
        }
    }

    /// Apply `f(pixel) -> new raw value` to a field at the enabled pixels of the active groups.
    #[inline]
    fn update(&mut self, dst: Field, active: &[u32], mut f: impl FnMut(&Self, usize) -> u64) {
        let a = Access::of(dst);
        for &g in active {
            let g = g as usize;
            let en = self.regs.enable[g];
            for i in 0..64 {
                if (en >> i) & 1 != 0 {
                    let p = g * 64 + i;
                    let v = f(self, p);
                    self.set(a, p, v);
                }
            }
        }
    }

    /// Compute one result bit per pixel of the active groups and combine it into `dst`.
    #[inline]
    fn combine_bits(
        &mut self,
        dst: Bit,
        combine: LogicOp,
        active: &[u32],
        mut f: impl FnMut(&Self, usize) -> bool,
    ) {
        for &g in active {
            let g = g as usize;
            let mut result = 0u64;
            for i in 0..64 {
                result |= (f(self, g * 64 + i) as u64) << i;
            }
            self.regs.combine(dst, g, result, combine);
        }
    }
}

/// Sign tests solved per row span: along a row, V is a quadratic in x, so it is monotone on at most
/// two pieces, and on a monotone piece whose window cannot wrap the pixels with W >= 0 form one
/// prefix or suffix. The split between the pieces is one exact division (`split`); a piece's end
/// is found by a galloping search on exact integer values that starts where the previous row's
/// ended (two evaluations when it has not moved). A piece whose window might wrap falls back to evaluating every pixel. Exact: the
/// property tests compare it with the bit level.
impl IntegerEngine {
    fn sign_test(
        &mut self,
        s: &Streams,
        window: Window,
        dst: Bit,
        combine: LogicOp,
        active: &[u32],
    ) {
        // The seed's 128-pixel row is two groups: a row buffer whose length the compiler knows is
        // cleared by two stores and a group's row found by a shift. Through the board's buffer,
        // each row's clearing was a `memset` call, 8 % of the main job's instructions.
        // A window that holds every value the expression takes on the board (as programs choose
        // them, `QeeExpr::sign_window`) needs no check, row by row, that it does not wrap.
        let g = self.geometry;
        let checks = may_wrap(s, window, g);
        let cmd = (dst, combine);
        match (g.groups_per_row, checks) {
            (2, false) => self.sign_rows::<false>(s, window, cmd, active, &mut [0u64; 2]),
            (2, true) => self.sign_rows::<true>(s, window, cmd, active, &mut [0u64; 2]),
            _ => {
                let mut row = std::mem::take(&mut self.row_bits);
                self.sign_rows::<true>(s, window, cmd, active, &mut row);
                self.row_bits = row;
            }
        }
    }

    /// [`IntegerEngine::sign_test`] with a row buffer of one u64 per group of a row; `CHECKS`:
    /// whether a row's values may lie outside the window's unwrapped range.
    #[inline(always)]
    fn sign_rows<const CHECKS: bool>(
        &mut self,
        s: &Streams,
        window: Window,
        (dst, combine): (Bit, LogicOp),
        active: &[u32],
        row_bits: &mut impl AsMut<[u64]>,
    ) {
        let row_bits = row_bits.as_mut();
        let gpr = row_bits.len();
        let range = Unwrapped::of(window);
        // The destination plane, chosen once: a flag's writes are gated by enable.
        let Registers { enable, flags } = &mut self.regs;
        let mut flag = match dst {
            Bit::Flag(i) => Some(&mut flags[i as usize]),
            Bit::Enable => None,
        };
        let width = self.geometry.width;
        let mut hints = Hints::new(width);
        // The groups of the row solved last, `row_start .. row_end`: the active list ascends, so
        // a row is solved once, at its first active group, and only then divided for.
        let (mut row_start, mut row_end) = (0, 0);
        for &g in active {
            let g = g as usize;
            if g >= row_end {
                let py = g / gpr;
                (row_start, row_end) = (py * gpr, py * gpr + gpr);
                let span = (0, width - 1);
                sign_row::<CHECKS>(s.row_fn(py), (window, range), span, row_bits, &mut hints);
            }
            let v = row_bits[g - row_start];
            match &mut flag {
                Some(f) => f[g] = gated(f[g], enable[g], combine.apply(f[g], v)),
                None => enable[g] = combine.apply(enable[g], v),
            }
        }
    }
}

/// The values of V whose window does not wrap: floor(V / 2^shift) fits `bits` bits as a signed
/// number exactly when `min <= V <= max`. Computed once per command.
#[derive(Clone, Copy)]
pub(super) struct Unwrapped {
    min: i64,
    max: i64,
}

impl Unwrapped {
    pub(super) fn of(window: Window) -> Unwrapped {
        // -2^(bits-1) * 2^shift ..= 2^(bits-1) * 2^shift - 1, clamped to i64 (shift + bits <= 64
        // by validation, so the clamp only ever removes nothing).
        let e = window.bits - 1 + window.shift;
        let half = 1i128 << e.min(100);
        Unwrapped {
            min: (-half).max(i128::from(i64::MIN)) as i64,
            max: (half - 1).min(i128::from(i64::MAX)) as i64,
        }
    }

    #[inline]
    fn holds(self, v: i64) -> bool {
        self.min <= v && v <= self.max
    }
}

/// Whether a sign test of `s` through `window` may meet, somewhere on a board of `geometry`, a
/// value the window cannot hold unwrapped: then its rows are checked one by one (`CHECKS`).
pub(super) fn may_wrap(s: &Streams, window: Window, geometry: Geometry) -> bool {
    let origin = (s.origin_x as u32, s.origin_y as u32);
    may_wrap_within(&s.expr, origin, window, (geometry.width, geometry.height))
}

/// [`may_wrap`] for `expr` at board origin `origin`, on the board's first `width` columns of
/// its first `height` rows only.
pub(super) fn may_wrap_within(
    expr: &QeeExpr,
    origin: (u32, u32),
    window: Window,
    (width, height): (usize, usize),
) -> bool {
    let bound = expr.bound(origin, width as u32, height as u32);
    bound > Unwrapped::of(window).max as u128
}

/// Set bits `lo ..= hi` of a row (one u64 per group).
#[inline]
fn set_span(out: &mut [u64], lo: usize, hi: usize) {
    let (g0, g1) = (lo / 64, hi / 64);
    let (from, to) = (u64::MAX << (lo % 64), mask((hi % 64) as u32 + 1));
    if g0 == g1 {
        out[g0] |= from & to;
    } else {
        out[g0] |= from;
        // Only a row wider than two groups has groups between; a `fill` of none still costs a
        // `memset` call.
        if g1 > g0 + 1 {
            out[g0 + 1..g1].fill(u64::MAX);
        }
        out[g1] |= to;
    }
}

/// The W >= 0 bits of pixels `lo ..= hi` of a row one by one, for a piece whose window may wrap
/// (rare: programs choose windows that hold their values).
#[cold]
fn sign_pixels(v: RowFn, window: Window, lo: usize, hi: usize, out: &mut [u64]) {
    let top = window.bits - 1;
    for px in lo..=hi {
        if (window.cut(v.at(px)) >> top) & 1 == 0 {
            out[px / 64] |= 1 << (px % 64);
        }
    }
}

/// The first px in `lo ..= hi` where `pred` holds, `hi + 1` if none, for a `pred` that is false
/// and then true on the range. Gallops from `guess` (any estimate; clamped), so a guess off by
/// `d` costs about 2 log2(d) + 2 evaluations (2.9 on average on the hemisphere stream). Always
/// inlined: as a call per monotone piece (1.2 M on that stream) it cost 14 % more instructions.
#[inline(always)]
pub(super) fn first_true(
    lo: usize,
    hi: usize,
    guess: usize,
    pred: impl Fn(usize) -> bool,
) -> usize {
    let g = guess.clamp(lo, hi);
    // First true in (f, t], knowing pred(t).
    let bisect = |mut f: usize, mut t: usize| {
        while t - f > 1 {
            let m = f + (t - f) / 2;
            if pred(m) { t = m } else { f = m }
        }
        t
    };
    let mut step = 1;
    if pred(g) {
        let mut t = g;
        loop {
            if t == lo {
                return lo;
            }
            let probe = t.saturating_sub(step).max(lo);
            if pred(probe) {
                t = probe;
                step *= 2;
            } else {
                return bisect(probe, t);
            }
        }
    } else {
        let mut f = g;
        loop {
            if f == hi {
                return hi + 1;
            }
            let probe = (f + step).min(hi);
            if pred(probe) {
                return bisect(f, probe);
            }
            f = probe;
            step *= 2;
        }
    }
}

/// Where a sign test's previous row found its answers: the next row's searches start there,
/// since a boundary moves little from one row to the next (exactness does not depend on it).
#[derive(Clone, Copy)]
pub(super) struct Hints {
    /// The end of the span in each piece (the split between the pieces is found by division,
    /// `split`).
    first: [usize; 2],
}

impl Hints {
    pub(super) fn new(width: usize) -> Hints {
        Hints {
            first: [width / 2; 2],
        }
    }
}

/// The W >= 0 bits of pixels `lo ..= hi` of one row into `out` (one u64 per 64 columns); the
/// row's other bits are left 0. The `integer` level solves whole rows; the `sparse` level
/// (`super::sparse`) only the span whose results can still matter.
#[inline(always)]
pub(super) fn sign_row<const CHECKS: bool>(
    v: RowFn,
    (window, range): (Window, Unwrapped),
    (lo, hi): (usize, usize),
    out: &mut [u64],
    hints: &mut Hints,
) {
    out.fill(0);
    if v.d == 0 {
        return linear_sign_row::<CHECKS>(v, window, range, (lo, hi), out);
    }
    // V at the span's ends, each evaluated once: they end the pieces below too.
    let (fa, fb) = (v.at(lo), v.at(hi));
    // A row concave along it (d < 0) is least at an end of the span, a convex one greatest:
    // ends that agree on the sign then decide every pixel between them (a hemisphere edge's
    // ellipse inside, on the rows a receiver lies within, is >= 0 at both ends). Values
    // between the ends could wrap only where the row checks.
    if !CHECKS {
        if v.d < 0 && fa >= 0 && fb >= 0 {
            return set_span(out, lo, hi);
        }
        if v.d > 0 && fa < 0 && fb < 0 {
            return;
        }
    }
    // f(px + 1) - f(px) = D (2x + 1) + b: linear in px, so f is monotone on [lo, k] and [k, hi]
    // where k is the first px at which the difference changes sign class.
    let diff = |px: usize| v.diff(px);
    let k = if lo == hi || (diff(lo) >= 0) == (diff(hi - 1) >= 0) {
        hi
    } else {
        let rising = diff(lo) < 0;
        let flips = |px: usize| (diff(px) >= 0) == rising;
        match split(diff(lo), v.d, hi - lo) {
            Some(k) => lo + k,
            None => first_true(lo, hi - 1, lo + (hi - lo) / 2, flips),
        }
    };
    // V at the split, which ends both pieces.
    let fk = if k < hi { v.at(k) } else { fb };
    // A monotone piece holds its values between those at its ends, so the row's window cannot
    // wrap when it holds these three; otherwise every pixel is evaluated.
    if CHECKS && !(range.holds(fa) && range.holds(fk) && range.holds(fb)) {
        return sign_pixels(v, window, lo, hi, out);
    }
    let [first, second] = &mut hints.first;
    piece(v, (lo, fa), (k, fk), first, out);
    if k < hi {
        piece(v, (k, fk), (hi, fb), second, out);
    }
}

/// The W >= 0 pixels of the monotone piece `lo ..= hi` of a row, whose ends have the values
/// `fa` and `fb` inside the unwrapped range: one prefix or suffix, its end searched from `hint`.
/// Always inlined: called as a function (the compiler's choice) it cost 5 % more instructions
/// on the hemisphere stream, by `bench renderer --instructions`.
#[inline(always)]
fn piece(
    v: RowFn,
    (lo, fa): (usize, i64),
    (hi, fb): (usize, i64),
    hint: &mut usize,
    out: &mut [u64],
) {
    match (fa >= 0, fb >= 0) {
        (true, true) => set_span(out, lo, hi),
        (false, false) => {}
        // Non-decreasing: from the first px with f >= 0.
        (false, true) => {
            *hint = first_true(lo, hi, *hint, |px| v.at(px) >= 0);
            set_span(out, *hint, hi);
        }
        // Non-increasing: up to the last px with f >= 0.
        (true, false) => {
            *hint = first_true(lo, hi, *hint, |px| v.at(px) < 0);
            set_span(out, lo, *hint - 1);
        }
    }
}

/// Where a row's difference `diff(px) = diff0 + 2 d px` (d != 0) first changes sign class, for
/// a row on which it does within `0 ..= last - 1`: the first px with `diff(px) >= 0` when it
/// rises (d > 0), the first with `diff(px) < 0` when it falls, by one exact division instead of
/// a search. `None` if `2 d` overflows (the caller then searches).
#[inline]
fn split(diff0: i64, d: i64, last: usize) -> Option<usize> {
    let slope = d.checked_mul(2)?;
    let px = if slope > 0 {
        // diff0 + slope px >= 0  <=>  px >= ceil(-diff0 / slope)
        let n = diff0.checked_neg()?;
        n.div_euclid(slope) + i64::from(n.rem_euclid(slope) != 0)
    } else {
        // diff0 + slope px < 0  <=>  px > diff0 / -slope  <=>  px >= floor(diff0 / -slope) + 1
        diff0.div_euclid(slope.checked_neg()?) + 1
    };
    Some((px.max(0) as usize).min(last - 1))
}

/// [`sign_row`] for a row along which V is linear, `f(px) = f(lo) + b (px - lo)`: the end of
/// the span by one exact integer division. The `sparse` level's two-group rows take a linear,
/// unwrapped test's bits the same way, as one u128 (`sparse::half_plane_bits`).
#[inline(always)]
fn linear_sign_row<const CHECKS: bool>(
    v: RowFn,
    window: Window,
    range: Unwrapped,
    (lo, hi): (usize, usize),
    out: &mut [u64],
) {
    let (fa, fb) = (v.at(lo), v.at(hi));
    if CHECKS && !(range.holds(fa) && range.holds(fb)) {
        return sign_pixels(v, window, lo, hi, out);
    }
    match (fa >= 0, fb >= 0) {
        (true, true) => set_span(out, lo, hi),
        (false, false) => {}
        // Rising (b > 0, fa < 0): f(px) >= 0 from px = lo + ceil(-fa / b). Both operands are
        // positive and inside the unwrapped range, so nothing overflows.
        (false, true) => set_span(out, lo + ((-fa + v.b - 1) / v.b) as usize, hi),
        // Falling (b < 0, fa >= 0): f(px) >= 0 up to px = lo + floor(fa / -b).
        (true, false) => set_span(out, lo, lo + (fa / -v.b) as usize),
    }
}

/// Call `f(lo, hi)` for every run of set bits of `m` (bits `lo .. hi`), lowest first.
#[inline]
fn for_each_run(mut m: u64, mut f: impl FnMut(usize, usize)) {
    while m != 0 {
        let lo = m.trailing_zeros();
        // The run's length: the zeros of the complement above lo (64 - lo if it reaches bit 63).
        let len = (!(m >> lo)).trailing_zeros().min(64 - lo);
        f(lo as usize, (lo + len) as usize);
        m &= if lo + len == 64 {
            0
        } else {
            u64::MAX << (lo + len)
        };
    }
}

impl IntegerEngine {
    /// A QEE store, add or compare on the active groups (`PixelEngine::qee` less sign tests),
    /// inlined into each build `Groups` dispatches.
    #[inline(always)]
    fn qee_groups(&mut self, s: &Streams, window: Window, sink: QeeSink, active: &[u32]) {
        let gpr = self.geometry.groups_per_row;
        for &g in active {
            let g = g as usize;
            let (py, px0) = (g / gpr, (g % gpr) * 64);
            let v = s.row_fn(py);
            let cut = |i: u32| window.cut(v.at(px0 + i as usize));
            let base = g * 64;
            let en = self.regs.enable[g];
            match sink {
                QeeSink::Sign { .. } => unreachable!("sign tests take the span path"),
                // Gated writes: only enabled pixels change, so only they are evaluated.
                QeeSink::Store { dst } => {
                    let a = Access::of(dst);
                    if a.straddles() {
                        for_each_bit(en, |i| self.set(a, base + i as usize, cut(i)));
                        continue;
                    }
                    // A field inside one limb (a depth): the group's 64 words as one slice, indexed
                    // below 64, so no pixel pays for bounds checks or the straddle test (they
                    // were about a third of a hemicube's depth stores and compares). Where V is
                    // linear along the row (a hemicube's depth), a group's enabled pixels in one run
                    // are one loop that the x86-64-v3 build vectorises: 40 shots of the main job's
                    // hemicube took 1.565 G instructions against 1.623 G visiting each set bit.
                    // A quadratic V (a hemisphere's Taylor depth) keeps the visit per bit: a
                    // branch-free loop over the span, with V by forward differences, took more
                    // instructions before the builds were split (4.127 G against 4.112 G for
                    // 150 hemicube shots), and its two multiplications are two instructions.
                    let words = &mut self.limbs[a.limb][base..base + 64];
                    match linear_in_group(v, px0) {
                        Some(at) => store_group::<true>(words, en, (a, window), at),
                        None => {
                            store_group::<false>(words, en, (a, window), |i| v.at(px0 + i as usize))
                        }
                    }
                }
                QeeSink::Add { dst } => {
                    let a = Access::of(dst);
                    for_each_bit(en, |i| {
                        let p = base + i as usize;
                        let v = self.get(a, p).wrapping_add(cut(i));
                        self.set(a, p, v);
                    });
                }
                QeeSink::Compare {
                    field,
                    cmp,
                    dst,
                    combine,
                } => {
                    let a = Access::of(field);
                    let need = needed(dst, combine, en);
                    let result = if field.bits < 64 && window.bits < 64 {
                        // Both sides fit i64 (`value_of` of fewer than 64 bits): the pixel's
                        // two facts, lhs < rhs and lhs == rhs, and the comparison once per
                        // group, as the serial subtract gives them (a match per pixel was half
                        // a depth test's instructions).
                        let (mut lt, mut eq) = (0u64, 0u64);
                        let value = |raw: u64| extend(raw, field.bits, field.signed) as i64;
                        if a.straddles() {
                            for_each_bit(need, |i| {
                                let lhs = value(cut(i));
                                let rhs = value(self.get(a, base + i as usize));
                                lt |= u64::from(lhs < rhs) << i;
                                eq |= u64::from(lhs == rhs) << i;
                            });
                        } else {
                            // Inside one limb, as a store. Each side as a key whose order is
                            // its value's: a signed field's bits at the top of an i64 (the
                            // sign extension's arithmetic shift back down keeps order and
                            // equality, so it is left out), an unsigned side as it is (below
                            // 2^63). Extending both sides per pixel was 1.36 M of the hemicube
                            // stream's 32.6 M instructions.
                            let s = if field.signed { 64 - field.bits } else { 0 };
                            let words = &self.limbs[a.limb][base..base + 64];
                            (lt, eq) = match linear_in_group(v, px0) {
                                Some(at) => compare_group::<true>(words, need, (a, window, s), at),
                                None => compare_group::<false>(words, need, (a, window, s), |i| {
                                    v.at(px0 + i as usize)
                                }),
                            };
                        }
                        cmp.from_lt_eq(lt, eq) & need
                    } else {
                        let mut result = 0u64;
                        for_each_bit(need, |i| {
                            let lhs = value_of(cut(i), field.bits, field.signed);
                            let rhs =
                                value_of(self.get(a, base + i as usize), field.bits, field.signed);
                            result |= (cmp.holds(lhs, rhs) as u64) << i;
                        });
                        result
                    };
                    self.regs.combine(dst, g, result, combine);
                }
            }
        }
    }

    /// `PixelEngine::write_const`, inlined into each build `Groups` dispatches.
    #[inline(always)]
    fn write_const_groups(&mut self, dst: Field, value: u64, active: &[u32]) {
        let a = Access::of(dst);
        if a.straddles() {
            return self.update(dst, active, |_, _| value);
        }
        // A field inside one limb: `const_group`.
        let limb = &mut self.limbs[a.limb];
        for &g in active {
            let g = g as usize;
            const_group(
                &mut limb[g * 64..g * 64 + 64],
                self.regs.enable[g],
                (a, value),
            );
        }
    }

    /// `PixelEngine::depth_test`, inlined into each build `Groups` dispatches: a group's
    /// compare, store and constant write one after the other, so each group is visited once
    /// (its row's V, its enable word and its words found once) where three commands visit it
    /// three times and list the enabled groups again between them. Only for a test
    /// [`one_pass`] accepts.
    #[inline(always)]
    fn depth_test_groups(&mut self, s: &Streams, window: Window, test: DepthTest, active: &[u32]) {
        let (field, cmp, store) = (test.field, test.cmp, test.store);
        let a = Access::of(field);
        let id = test.id.map(|(dst, value)| (Access::of(dst), value));
        // As `qee_groups`' compare: each side as a key whose order is its value's.
        let key = if field.signed { 64 - field.bits } else { 0 };
        let gpr = self.geometry.groups_per_row;
        for &g in active {
            let g = g as usize;
            let en = self.regs.enable[g];
            if en == 0 {
                continue;
            }
            let (py, px0) = (g / gpr, (g % gpr) * 64);
            let v = s.row_fn(py);
            let base = g * 64;
            // One run of enabled pixels (a receiver meets most groups so): compare and store in
            // one loop, V stepped along the run by its differences.
            let run = one_run(en).filter(|_| store && window.shift + window.bits <= 64);
            if let Some(run) = run {
                let words = &mut self.limbs[a.limb][base..base + 64];
                let field = (a, window, key);
                let passed = match linear_in_group(v, px0) {
                    Some(at) => compare_store_run(words, run, field, cmp, linear_steps(at, run.0)),
                    // A quadratic V (a hemisphere's Taylor depth): one loop for every comparison,
                    // which tests it a pixel. A loop per comparison here too made the build
                    // larger, and the hemicube's linear loops slower (1.2 M more instructions
                    // of `bench machine`'s hemicube).
                    None => {
                        let steps = quadratic_steps(v, px0, run.0);
                        let passes = |l: i64, r: i64| cmp.holds(l.into(), r.into());
                        compare_store_run_by(words, run, field, steps, passes)
                    }
                };
                self.regs.enable[g] = passed;
                if let Some((i, value)) = id {
                    const_group(&mut self.limbs[i.limb][base..base + 64], passed, (i, value));
                }
                continue;
            }
            let words = &self.limbs[a.limb][base..base + 64];
            let (lt, eq) = match linear_in_group(v, px0) {
                Some(at) => compare_group::<true>(words, en, (a, window, key), at),
                None => {
                    compare_group::<false>(words, en, (a, window, key), |i| v.at(px0 + i as usize))
                }
            };
            // enable AND the comparison: a disabled pixel stays disabled.
            let en = en & cmp.from_lt_eq(lt, eq);
            self.regs.enable[g] = en;
            if store {
                let words = &mut self.limbs[a.limb][base..base + 64];
                match linear_in_group(v, px0) {
                    Some(at) => store_group::<true>(words, en, (a, window), at),
                    None => {
                        store_group::<false>(words, en, (a, window), |i| v.at(px0 + i as usize))
                    }
                }
            }
            if let Some((i, value)) = id {
                const_group(&mut self.limbs[i.limb][base..base + 64], en, (i, value));
            }
        }
    }
}

/// A depth test's compare and store over the one run `lo..hi` of a group's enabled pixels, in
/// one loop, V at each pixel of the run in turn from `next` (a [`linear_steps`] or
/// [`quadratic_steps`]), a window that ends at bit 64 at most; the field inside one limb, `key`
/// as for [`compare_group`]. Returns the pixels that passed: enable afterwards. Each pixel's
/// comparison selects, without a branch, whether its word takes the stored window, so the
/// compiler vectorises a linear V's loop as it does the compare's and the store's alone (the
/// window cut by a logical shift, as [`store_group`]'s).
///
/// One loop per comparison, each testing its own relation: through the two facts a serial
/// subtract yields (lhs < rhs, lhs == rhs) and the comparison's choice among them, as
/// [`Cmp::from_lt_eq`] takes them, every pixel paid two tests and six masks.
#[inline(always)]
fn compare_store_run(
    words: &mut [u64],
    run: (u32, u32),
    field: (Access, Window, u32),
    cmp: Cmp,
    next: impl FnMut() -> i64,
) -> u64 {
    match cmp {
        Cmp::Lt => compare_store_run_by(words, run, field, next, |l, r| l < r),
        Cmp::Le => compare_store_run_by(words, run, field, next, |l, r| l <= r),
        Cmp::Gt => compare_store_run_by(words, run, field, next, |l, r| l > r),
        Cmp::Ge => compare_store_run_by(words, run, field, next, |l, r| l >= r),
        Cmp::Eq => compare_store_run_by(words, run, field, next, |l, r| l == r),
        Cmp::Ne => compare_store_run_by(words, run, field, next, |l, r| l != r),
    }
}

/// [`compare_store_run`] for the comparison `passes(lhs, rhs)`.
#[inline(always)]
fn compare_store_run_by(
    words: &mut [u64],
    (lo, hi): (u32, u32),
    (a, w, key): (Access, Window, u32),
    mut next: impl FnMut() -> i64,
    passes: impl Fn(i64, i64) -> bool,
) -> u64 {
    let (clear, keep) = (!(a.mask << a.shift), mask(w.bits) & a.mask);
    let mut passed = 0u64;
    for (i, word) in (lo..hi).zip(&mut words[lo as usize..hi as usize]) {
        let value = ((next() as u64) >> w.shift) & keep;
        let lhs = (value << key) as i64;
        let rhs = (((*word >> a.shift) & a.mask) << key) as i64;
        let pass = 0u64.wrapping_sub(u64::from(passes(lhs, rhs)));
        passed |= (pass & 1) << i;
        let stored = (*word & clear) | (value << a.shift);
        *word = (stored & pass) | (*word & !pass);
    }
    passed
}

/// V linear along the row (`at(i)` at pixel i), from pixel `lo` on, a pixel a call: stepped by
/// one wrapping add, which vectorises as four lanes stepped together, where `at(i)`'s 64-bit
/// multiply has no AVX2 instruction.
#[inline(always)]
fn linear_steps(at: impl Fn(u32) -> i64, lo: u32) -> impl FnMut() -> i64 {
    let mut v = at(lo);
    let step = at(lo + 1).wrapping_sub(v);
    move || {
        let here = v;
        v = v.wrapping_add(step);
        here
    }
}

/// V of row function `v` at the group's pixel `lo` (of the group at column `px0`) and on, a
/// pixel a call, by forward differences: V(x + 1) - V(x) = D (2x + 1) + b, which grows by 2D a
/// pixel. In wrapping arithmetic, so equal to [`RowFn::at`] modulo 2^64 and the same in every
/// bit a window cuts; two adds a pixel where `at` takes two multiplies (a hemisphere's Taylor
/// depth was compared and then stored, V found twice, at each enabled pixel one by one).
#[inline(always)]
fn quadratic_steps(v: RowFn, px0: usize, lo: u32) -> impl FnMut() -> i64 {
    let mut value = v.at(px0 + lo as usize);
    let mut diff = v.diff(px0 + lo as usize);
    let twice_d = v.d.wrapping_mul(2);
    move || {
        let here = value;
        value = value.wrapping_add(diff);
        diff = diff.wrapping_add(twice_d);
        here
    }
}

/// Whether [`IntegerEngine::depth_test_groups`] takes `test`: its fields inside one limb each
/// and both sides of its compare below 64 bits (as a depth and an ID always are); the rest take
/// the commands one by one.
fn one_pass(test: DepthTest, window: Window) -> bool {
    !Access::of(test.field).straddles()
        && test.field.bits < 64
        && window.bits < 64
        && !test.id.is_some_and(|(dst, _)| Access::of(dst).straddles())
}

/// A constant written at the enabled pixels `en` of one group's 64 words, into a field inside
/// one limb: each run of enabled pixels in one branch-free pass that the compiler vectorises. A
/// polygon's ID is written at every pixel it covers, and a convex polygon meets a group's 64
/// pixels in one run: a loop per pixel (a mask per pixel, or a visit per set bit) cost 1.18 G
/// instructions of a hemicube run, 6.4 % of it.
#[inline(always)]
fn const_group(pixels: &mut [u64], en: u64, (a, value): (Access, u64)) {
    let (clear, set) = (!(a.mask << a.shift), (value & a.mask) << a.shift);
    // A whole group (a view's set-up clears its face): a loop of a length the compiler knows,
    // without finding the run: 4.2 M of the 263.98 M instructions of `bench machine`'s hemicube.
    if let (u64::MAX, Ok(all)) = (en, <&mut [u64; 64]>::try_from(&mut *pixels)) {
        for w in all {
            *w = (*w & clear) | set;
        }
        return;
    }
    for_each_run(en, |lo, hi| {
        for w in &mut pixels[lo..hi] {
            *w = (*w & clear) | set;
        }
    });
}

/// Per-group work whose loops are compiled once per instruction set [`pulp::Arch::dispatch`]
/// can choose: everything the loops call is inlined into each build.
struct Groups<'a> {
    engine: &'a mut IntegerEngine,
    active: &'a [u32],
    work: Work<'a>,
}

enum Work<'a> {
    Qee {
        s: &'a Streams,
        window: Window,
        sink: QeeSink,
    },
    Const {
        dst: Field,
        value: u64,
    },
    DepthTest {
        s: &'a Streams,
        window: Window,
        test: DepthTest,
    },
}

impl pulp::WithSimd for Groups<'_> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) {
        let Groups {
            engine,
            active,
            work,
        } = self;
        match work {
            Work::Qee { s, window, sink } => engine.qee_groups(s, window, sink, active),
            Work::Const { dst, value } => engine.write_const_groups(dst, value, active),
            Work::DepthTest { s, window, test } => {
                engine.depth_test_groups(s, window, test, active)
            }
        }
    }
}

/// V at pixel i of the group starting at pixel `px0` of a row where V is linear (d = 0: a
/// hemicube's depth, 1/z across a plane), as the group's first value plus i steps: one
/// multiply-add a pixel where `RowFn::at` takes two. In wrapping arithmetic, so equal to
/// `at`'s value modulo 2^64 and the same in every bit a window cuts.
#[inline(always)]
fn linear_in_group(v: RowFn, px0: usize) -> Option<impl Fn(u32) -> i64> {
    (v.d == 0).then(|| {
        let first =
            v.b.wrapping_mul(v.x0.wrapping_add(px0 as i64))
                .wrapping_add(v.r);
        move |i: u32| first.wrapping_add(v.b.wrapping_mul(i64::from(i)))
    })
}

/// A QEE store of window `w` of V (`at(i)` at pixel i) into a field inside one limb, at the
/// enabled pixels of one group's 64 words: the group as one slice indexed below 64, so no pixel
/// pays for bounds checks or the straddle test (they were about a third of a hemicube's depth
/// stores and compares), and the window's bits that the field keeps under one mask. `RUNS`:
/// enabled pixels in one run (`one_run`) as one loop, for a V linear along the row, which the
/// compiler vectorises (a visit per set bit otherwise).
#[inline(always)]
fn store_group<const RUNS: bool>(
    words: &mut [u64],
    en: u64,
    (a, w): (Access, Window),
    at: impl Fn(u32) -> i64,
) {
    let (clear, keep) = (!(a.mask << a.shift), mask(w.bits) & a.mask);
    // A window ends at bit 64 at most, so the bits the field keeps lie below the sign's copies
    // and a logical shift gives the arithmetic one's bits: a run's loop has no per-pixel
    // arithmetic shift of an i64 (AVX2 has none) to keep it from vectorising. `Board::validate`
    // refuses a longer window; the test is kept all the same, since the builds with it took
    // 0.23 M fewer instructions of the hemicube stream's 27.8 M.
    let store = |word: &mut u64, i: u32| {
        let value = ((at(i) as u64) >> w.shift) & keep;
        *word = (*word & clear) | (value << a.shift);
    };
    match one_run(en).filter(|_| RUNS && w.shift + w.bits <= 64) {
        Some((lo, hi)) => {
            // V linear (`RUNS`): stepped as in `compare_store_run`.
            let (mut v, step) = (at(lo), at(lo + 1).wrapping_sub(at(lo)));
            for word in &mut words[lo as usize..hi as usize] {
                let value = ((v as u64) >> w.shift) & keep;
                *word = (*word & clear) | (value << a.shift);
                v = v.wrapping_add(step);
            }
        }
        None => for_each_bit(en, |i| store(&mut words[i as usize & 63], i)),
    }
}

/// A QEE compare of window `w` of V (`at(i)` at pixel i) with a field inside one limb, at the
/// `need` pixels of one group: lhs < rhs and lhs == rhs per pixel, each side as a key whose
/// order is its value's (`s`: 64 less a signed field's bits, 0 for an unsigned one). `RUNS` as
/// for [`store_group`].
#[inline(always)]
fn compare_group<const RUNS: bool>(
    words: &[u64],
    need: u64,
    (a, w, s): (Access, Window, u32),
    at: impl Fn(u32) -> i64,
) -> (u64, u64) {
    let (mut lt, mut eq) = (0u64, 0u64);
    let mut pixel = |i: u32, word: u64| {
        let lhs = (w.cut(at(i)) << s) as i64;
        let rhs = (((word >> a.shift) & a.mask) << s) as i64;
        lt |= u64::from(lhs < rhs) << i;
        eq |= u64::from(lhs == rhs) << i;
    };
    match one_run(need).filter(|_| RUNS) {
        Some((lo, hi)) => {
            for (i, &word) in (lo..hi).zip(&words[lo as usize..hi as usize]) {
                pixel(i, word);
            }
        }
        None => for_each_bit(need, |i| pixel(i, words[i as usize & 63])),
    }
    (lt, eq)
}

/// The bits `lo..hi` of `m` when they are its only set bits, one run; `None` for an empty `m`
/// or one of several runs (those are visited bit by bit: a loop per run was 4.0 M more
/// instructions on the hemicube stream of `bench renderer`, 31.8 M).
#[inline(always)]
fn one_run(m: u64) -> Option<(u32, u32)> {
    let lo = m.trailing_zeros();
    let run = m.checked_shr(lo)?;
    (run & run.wrapping_add(1) == 0).then(|| (lo, lo + run.trailing_ones()))
}

/// Call `f` with the index of every set bit of `m`, lowest first.
#[inline]
fn for_each_bit(mut m: u64, mut f: impl FnMut(u32)) {
    while m != 0 {
        f(m.trailing_zeros());
        m &= m - 1;
    }
}

/// The pixels of a group whose result bit can matter when it is combined into `dst` with
/// `combine`: the enabled ones for a flag (its writes are gated) or for enable combined by an op
/// that keeps 0 at 0; all of them otherwise. Result bits elsewhere are left 0.
#[inline]
fn needed(dst: Bit, combine: LogicOp, en: u64) -> u64 {
    match dst {
        Bit::Enable if !combine.keeps_zero() => u64::MAX,
        _ => en,
    }
}

impl PixelEngine for IntegerEngine {
    fn registers(&self) -> &Registers {
        &self.regs
    }

    fn registers_mut(&mut self) -> &mut Registers {
        &mut self.regs
    }

    fn qee(&mut self, s: &Streams, window: Window, sink: QeeSink, active: &[u32]) {
        if let QeeSink::Sign { dst, combine } = sink {
            return self.sign_test(s, window, dst, combine, active);
        }
        let arch = self.arch;
        arch.dispatch(Groups {
            engine: self,
            active,
            work: Work::Qee { s, window, sink },
        })
    }

    fn write_const(&mut self, dst: Field, value: u64, active: &[u32]) {
        let arch = self.arch;
        arch.dispatch(Groups {
            engine: self,
            active,
            work: Work::Const { dst, value },
        })
    }

    fn depth_test(&mut self, s: &Streams, window: Window, test: DepthTest, active: &[u32]) {
        if !one_pass(test, window) {
            return depth_test_one_by_one(self, s, window, test, active);
        }
        let arch = self.arch;
        arch.dispatch(Groups {
            engine: self,
            active,
            work: Work::DepthTest { s, window, test },
        })
    }

    fn copy(&mut self, dst: Field, src: Field, active: &[u32]) {
        let s = Access::of(src);
        self.update(dst, active, |e, p| {
            extend(e.get(s, p), src.bits, src.signed)
        })
    }

    fn add_sub(&mut self, dst: Field, a: Field, b: Field, subtract: bool, active: &[u32]) {
        let (aa, ba) = (Access::of(a), Access::of(b));
        self.update(dst, active, |e, p| {
            let x = extend(e.get(aa, p), a.bits, a.signed);
            let y = extend(e.get(ba, p), b.bits, b.signed);
            if subtract {
                x.wrapping_sub(y)
            } else {
                x.wrapping_add(y)
            }
        })
    }

    fn compare(
        &mut self,
        a: Field,
        b: Field,
        cmp: Cmp,
        dst: Bit,
        combine: LogicOp,
        active: &[u32],
    ) {
        let (aa, ba) = (Access::of(a), Access::of(b));
        self.combine_bits(dst, combine, active, |e, p| {
            cmp.holds(
                value_of(e.get(aa, p), a.bits, a.signed),
                value_of(e.get(ba, p), b.bits, b.signed),
            )
        })
    }

    fn mul_const(&mut self, dst: Field, src: Field, k: i64, _k_bits: u32, active: &[u32]) {
        let s = Access::of(src);
        self.update(dst, active, |e, p| {
            extend(e.get(s, p), src.bits, src.signed).wrapping_mul(k as u64)
        })
    }

    fn read_planes(&self, field: Field) -> Vec<u64> {
        let a = Access::of(field);
        let groups = self.geometry.groups;
        let mut planes = vec![0u64; field.bits as usize * groups];
        for g in 0..groups {
            for i in 0..64 {
                let v = self.get(a, g * 64 + i);
                for k in 0..field.bits as usize {
                    planes[k * groups + g] |= ((v >> k) & 1) << i;
                }
            }
        }
        planes
    }

    fn write_planes(&mut self, field: Field, planes: &[u64]) {
        let a = Access::of(field);
        let groups = self.geometry.groups;
        for g in 0..groups {
            for i in 0..64 {
                let mut v = 0u64;
                for k in 0..field.bits as usize {
                    v |= ((planes[k * groups + g] >> i) & 1) << k;
                }
                self.set(a, g * 64 + i, v);
            }
        }
    }

    fn write_values(&mut self, field: Field, rect: Rect, values: &[u64]) {
        let a = Access::of(field);
        let per_row = self.geometry.groups_per_row;
        let mut it = values.iter();
        for py in rect.y as usize..(rect.y + rect.height) as usize {
            for px in rect.x as usize..(rect.x + rect.width) as usize {
                let p = (py * per_row + px / 64) * 64 + px % 64;
                self.set(a, p, *it.next().expect("validated length"));
            }
        }
    }

    fn read_values(&self, field: Field, rect: Rect, out: &mut Vec<u64>) {
        let a = Access::of(field);
        let (x0, x1) = (rect.x as usize, (rect.x + rect.width) as usize);
        out.clear();
        out.reserve((rect.width * rect.height) as usize);
        // A row's pixels are consecutive in a limb (pixel px of array row py is at
        // `py * width + px`): a row at a time, without an address per pixel (one cost 17
        // instructions a pixel of a hemicube's ID readback).
        for py in rect.y as usize..(rect.y + rect.height) as usize {
            let at = py * self.geometry.width;
            let lo = &self.limbs[a.limb][at + x0..at + x1];
            if a.straddles() {
                let hi = &self.limbs[a.limb + 1][at + x0..at + x1];
                out.extend(
                    lo.iter()
                        .zip(hi)
                        .map(|(&l, &h)| ((l >> a.shift) | (h << (64 - a.shift))) & a.mask),
                );
            } else {
                out.extend(lo.iter().map(|&l| (l >> a.shift) & a.mask));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::{for_each_run, split};

    /// The x86-64-v3 build (where this host has it) and the portable build of the per-group
    /// loops leave the same pixel memory and registers after QEE stores, adds and compares and
    /// constant writes: linear rows and quadratic ones, fields inside one limb and across two,
    /// signed and unsigned, on rows of one, two and four groups, with some groups disabled. On a
    /// host without it both engines run the portable build (the bit-against-integer properties
    /// then cover it).
    #[test]
    fn the_v3_build_matches_the_portable_one() {
        use super::{Geometry, IntegerEngine, PixelEngine, QeeSink};
        use crate::QeeExpr;
        use crate::command::{Bit, Cmp, Field, LogicOp};
        use crate::qee::{Streams, Window};
        let mut rng = pxpl5_geom::rng::Lcg::new(0x1A7E_6E2B_0B11);
        let field = |offset, bits, signed| Field {
            offset,
            bits,
            signed,
        };
        for (width, height) in [(64, 7), (128, 9), (256, 6)] {
            let geometry = Geometry::new(width, height);
            for trial in 0..40 {
                let mut v3 = IntegerEngine::new(geometry, 208, 2);
                for limb in v3.limbs.iter_mut() {
                    limb.iter_mut().for_each(|w| *w = rng.next_u64());
                }
                for (g, en) in v3.regs.enable.iter_mut().enumerate() {
                    *en = if (g + trial) % 3 == 0 {
                        0
                    } else {
                        rng.next_u64()
                    };
                }
                #[cfg(target_arch = "x86_64")]
                assert_eq!(
                    matches!(v3.arch, pulp::Arch::V3(_)),
                    pulp::x86::V3::try_new().is_some(),
                    "the v3 build is not the one the host can run"
                );
                let mut portable = IntegerEngine::new(geometry, 208, 2).portable();
                portable.limbs = v3.limbs.clone();
                portable.regs = v3.regs.clone();
                let mut c = || rng.below(2001) as i64 - 1000;
                let raw = [c(), c(), c(), c(), c(), c()];
                // Each kind of work (trial % 5) with a linear row and a quadratic one.
                let raw = if trial / 5 % 2 == 0 {
                    [raw[0], raw[1], raw[2], 0, 0, 0]
                } else {
                    raw
                };
                let expr = QeeExpr::from_raw(raw);
                let origin = (trial as u32 * 3, trial as u32 * 5);
                let streams = Streams::for_rows(&expr, origin);
                // Inside one limb, or across limbs 0 and 1 (trial / 10 odd).
                let (offset, signed) = (if trial / 10 % 2 == 0 { 20 } else { 58 }, trial % 4 == 1);
                let window = Window {
                    shift: trial as u32 % 4,
                    bits: 12,
                };
                let mut active = Vec::new();
                v3.regs.enabled_groups(&mut active);
                let sink = match trial % 5 {
                    0 => None,
                    1 => Some(QeeSink::Store {
                        dst: field(offset, 12, signed),
                    }),
                    2 => Some(QeeSink::Add {
                        dst: field(offset, 12, signed),
                    }),
                    3 => Some(QeeSink::Compare {
                        field: field(offset, 12, signed),
                        cmp: Cmp::Le,
                        dst: Bit::Enable,
                        combine: LogicOp::AND,
                    }),
                    _ => Some(QeeSink::Compare {
                        field: field(offset, 12, signed),
                        cmp: Cmp::Eq,
                        dst: Bit::Flag(1),
                        combine: LogicOp::OR,
                    }),
                };
                match sink {
                    Some(sink) => {
                        v3.qee(&streams, window, sink, &active);
                        portable.qee(&streams, window, sink, &active);
                    }
                    None => {
                        let dst = field(offset, 12, signed);
                        v3.write_const(dst, 0xABC, &active);
                        portable.write_const(dst, 0xABC, &active);
                    }
                }
                assert!(
                    v3.limbs == portable.limbs && v3.regs == portable.regs,
                    "{width} x {height}, trial {trial}: {sink:?} differs"
                );
            }
        }
    }

    /// `depth_test`'s one pass over the groups leaves what its three commands leave one after
    /// the other, in the v3 build and the portable one: depths inside one limb and across two,
    /// signed and unsigned, 64 bits wide (the commands one by one), every comparison, ties
    /// included, with and without the store, linear and quadratic V, enable in one run or
    /// scattered, and IDs beside the depth, across limbs or over the depth's own bits.
    #[test]
    fn a_depth_test_is_its_three_commands() {
        use super::{
            DepthTest, Geometry, IntegerEngine, PixelEngine, QeeSink, depth_test_one_by_one,
        };
        use crate::QeeExpr;
        use crate::command::{Cmp, Field};
        use crate::qee::{Streams, Window};
        let mut rng = pxpl5_geom::rng::Lcg::new(0xDE97_4E57);
        let field = |offset, bits, signed| Field {
            offset,
            bits,
            signed,
        };
        let depths = [
            field(20, 12, false),
            field(20, 12, true),
            field(58, 12, true),
            field(64, 32, false),
            field(100, 64, true),
        ];
        let ids = [
            None,
            Some(field(40, 16, false)),
            Some(field(120, 16, false)),
            Some(field(56, 16, false)),
            Some(field(24, 4, false)),
        ];
        for (width, height) in [(64, 7), (128, 9)] {
            let geometry = Geometry::new(width, height);
            for trial in 0..150usize {
                let depth = depths[trial % depths.len()];
                let id = ids[trial / 5 % ids.len()].map(|f| (f, rng.next_u64() & 0xF));
                let test = DepthTest {
                    field: depth,
                    cmp: Cmp::ALL[trial / 25 % Cmp::ALL.len()],
                    store: trial % 2 == 0,
                    id,
                };
                let mut c = || rng.below(2001) as i64 - 1000;
                let raw = [c(), c(), c(), c(), c(), c()];
                let raw = if trial % 3 == 0 {
                    raw
                } else {
                    [raw[0], raw[1], raw[2], 0, 0, 0]
                };
                let expr = QeeExpr::from_raw(raw);
                let streams = Streams::for_rows(&expr, (trial as u32 * 3, trial as u32));
                let window = Window {
                    shift: if depth.bits == 64 {
                        0
                    } else {
                        trial as u32 % 4
                    },
                    bits: depth.bits,
                };
                let mut start = IntegerEngine::new(geometry, 208, 2);
                for limb in start.limbs.iter_mut() {
                    limb.iter_mut()
                        .for_each(|w| *w = rng.next_u64() & rng.next_u64());
                }
                if trial % 3 != 1 {
                    // Depths equal to V where enable lets a store write: ties for `cmp`.
                    let tie = rng.next_u64();
                    start.regs.enable.iter_mut().for_each(|en| *en = tie);
                    let all: Vec<u32> = (0..geometry.groups as u32).collect();
                    start.qee(&streams, window, QeeSink::Store { dst: depth }, &all);
                }
                for (g, en) in start.regs.enable.iter_mut().enumerate() {
                    *en = match (g + trial) % 4 {
                        0 => 0,
                        1 => u64::MAX,
                        _ => rng.next_u64(),
                    };
                }
                let mut active = Vec::new();
                start.regs.enabled_groups(&mut active);
                let portable = |e: &IntegerEngine| {
                    let mut p = IntegerEngine::new(geometry, 208, 2).portable();
                    p.limbs = e.limbs.clone();
                    p.regs = e.regs.clone();
                    p
                };
                let mut one_by_one = portable(&start);
                depth_test_one_by_one(&mut one_by_one, &streams, window, test, &active);
                let mut fused = portable(&start);
                fused.depth_test(&streams, window, test, &active);
                start.depth_test(&streams, window, test, &active);
                for (build, e) in [("portable", &fused), ("dispatched", &start)] {
                    assert!(
                        e.limbs == one_by_one.limbs && e.regs == one_by_one.regs,
                        "{width} x {height}, trial {trial}, {build} build: {test:?} differs"
                    );
                }
            }
        }
    }

    /// `for_each_run` lists exactly the set bits of a mask, as disjoint ascending runs with a
    /// clear bit between neighbours: masks with runs at both ends, single bits, all and none.
    #[test]
    fn runs_cover_exactly_the_set_bits() {
        let mut masks = vec![
            0,
            u64::MAX,
            1,
            1 << 63,
            0x8000_0000_0000_0001,
            0x0ff0_00ff_f000_000f,
        ];
        let mut x = 0x9e37_79b9_7f4a_7c15u64;
        for _ in 0..200 {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            masks.push(x & (x >> 3));
        }
        for m in masks {
            let (mut seen, mut last) = (0u64, None);
            for_each_run(m, |lo, hi| {
                assert!(lo < hi && hi <= 64, "{m:#x}: run {lo}..{hi}");
                if let Some(end) = last {
                    assert!(lo > end, "{m:#x}: runs touch or overlap at {lo}");
                }
                last = Some(hi);
                for i in lo..hi {
                    seen |= 1 << i;
                }
            });
            assert_eq!(seen, m, "{m:#x}");
        }
    }

    /// `split` against its definition, the first px whose difference is in the other sign class,
    /// for rising and falling rows, flips anywhere in the row, exact multiples and remainders.
    #[test]
    fn split_is_the_first_flip() {
        for last in [1usize, 2, 63, 64, 127] {
            for d in [-1_000_003i64, -7, -2, -1, 1, 2, 7, 1_000_003] {
                for diff0 in (-300i64..=300).chain([-2 * d * 127, 2 * d * 127 - 1]) {
                    let diff = |px: usize| diff0 + 2 * d * px as i64;
                    let rising = diff(0) < 0;
                    if (diff(0) >= 0) == (diff(last - 1) >= 0) {
                        continue;
                    }
                    let want = (0..last)
                        .find(|&px| (diff(px) >= 0) == rising)
                        .expect("the class changes in the row");
                    assert_eq!(split(diff0, d, last), Some(want), "d {d}, diff0 {diff0}");
                }
            }
        }
        assert_eq!(split(0, i64::MAX, 10), None, "2 d overflows");
    }
}
