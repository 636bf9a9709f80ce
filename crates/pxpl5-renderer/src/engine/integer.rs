//! The `integer` fidelity level: pixel memory as per-pixel integers, operations as integer
//! arithmetic with exactly the semantics of the bit-serial level (proven equal by property tests).
//!
//! A pixel's memory is one integer of `memory_bits` bits, stored as 64-bit limbs: limb k holds
//! bits 64k .. 64k + 63 of every pixel (structure of arrays, so a field's loop walks one or two
//! contiguous vectors).

use super::{Geometry, PixelEngine, QeeSink, Registers, extend, value_of};
use crate::command::{Bit, Cmp, Field, LogicOp, Rect};
use crate::qee::{Streams, Window, mask};

/// Per-pixel integer pixel memory and the shared one-bit registers.
pub struct IntegerEngine {
    geometry: Geometry,
    limbs: Vec<Vec<u64>>,
    regs: Registers,
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
        }
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

    /// The window of the QEE's value at the 64 pixels of group `g`: V = X(x) + Y(y) + (E y) x.
    #[inline]
    fn window_values(&self, s: &Streams, window: Window, g: usize, out: &mut [u64; 64]) {
        let (py, px0) = self.geometry.group_origin(g);
        let col = &s.col[px0..px0 + 64];
        let row = s.row[py];
        let (shift, m) = (window.shift, mask(window.bits));
        if s.cross {
            let (ey, x0) = (s.e_row[py], s.origin_x + px0 as i64);
            for (i, (o, &c)) in out.iter_mut().zip(col).enumerate() {
                *o = (((c + row + ey * (x0 + i as i64)) >> shift) as u64) & m;
            }
        } else {
            for (o, &c) in out.iter_mut().zip(col) {
                *o = (((c + row) >> shift) as u64) & m;
            }
        }
    }
}

/// Sign tests solved per row span: along a row, V is a quadratic in x, so it is monotone on at most
/// two pieces, and on a monotone piece whose window cannot wrap the pixels with W >= 0 form one
/// prefix or suffix, found by binary search on exact values. A piece whose window might wrap falls
/// back to evaluating every pixel. Exact: the property tests compare it with the bit level.
impl IntegerEngine {
    fn sign_test(
        &mut self,
        s: &Streams,
        window: Window,
        dst: Bit,
        combine: LogicOp,
        active: &[u32],
    ) {
        let gpr = self.geometry.groups_per_row;
        let mut row_bits = vec![0u64; gpr];
        let mut i = 0;
        while i < active.len() {
            let py = active[i] as usize / gpr;
            sign_row(s, window, py, self.geometry.width, &mut row_bits);
            while i < active.len() && active[i] as usize / gpr == py {
                let g = active[i] as usize;
                self.regs.combine(dst, g, row_bits[g % gpr], combine);
                i += 1;
            }
        }
    }
}

/// Whether floor(v / 2^shift) fits the window's bits as a signed number (no wrap).
#[inline]
fn fits(v: i64, window: Window) -> bool {
    let q = i128::from(v >> window.shift);
    let half = 1i128 << (window.bits - 1);
    -half <= q && q < half
}

/// Set bits `lo ..= hi` of a row (one u64 per group), a group at a time.
fn set_span(out: &mut [u64], lo: usize, hi: usize) {
    for (g, group) in out.iter_mut().enumerate().take(hi / 64 + 1).skip(lo / 64) {
        let first = lo.max(g * 64) - g * 64;
        let last = hi.min(g * 64 + 63) - g * 64;
        *group |= mask(last as u32 + 1) & !mask(first as u32);
    }
}

/// The W >= 0 bits of row `py` into `out` (one u64 per 64 columns).
fn sign_row(s: &Streams, window: Window, py: usize, width: usize, out: &mut [u64]) {
    out.fill(0);
    let f = |px: usize| s.value(px, py);
    // f(px + 1) - f(px): linear in px (its slope is 2D), so monotone.
    let g = |px: usize| s.col[px + 1] - s.col[px] + s.e_row[py];
    let last = width - 1;
    // Split where the forward difference changes sign: f is monotone on [0, k] and on [k, last].
    let k = if last == 0 || (g(0) >= 0) == (g(last - 1) >= 0) {
        last
    } else {
        let rising = g(0) < 0; // g goes from negative to non-negative
        let (mut lo, mut hi) = (0usize, last - 1);
        // First px in [0, last - 1] where g's sign class flips.
        while lo < hi {
            let mid = (lo + hi) / 2;
            if (g(mid) >= 0) == rising {
                hi = mid;
            } else {
                lo = mid + 1;
            }
        }
        lo
    };
    let mut piece = |lo: usize, hi: usize| {
        let (a, b) = (f(lo), f(hi));
        if !(fits(a, window) && fits(b, window)) {
            let top = window.bits - 1;
            for px in lo..=hi {
                if (window.cut(f(px)) >> top) & 1 == 0 {
                    out[px / 64] |= 1 << (px % 64);
                }
            }
            return;
        }
        match (a >= 0, b >= 0) {
            (true, true) => set_span(out, lo, hi),
            (false, false) => {}
            (false, true) => {
                // Non-decreasing: the first px with f >= 0.
                let (mut l, mut h) = (lo, hi);
                while l < h {
                    let m = (l + h) / 2;
                    if f(m) >= 0 { h = m } else { l = m + 1 }
                }
                set_span(out, l, hi);
            }
            (true, false) => {
                // Non-increasing: the last px with f >= 0.
                let (mut l, mut h) = (lo, hi);
                while l < h {
                    let m = (l + h).div_ceil(2);
                    if f(m) >= 0 { l = m } else { h = m - 1 }
                }
                set_span(out, lo, l);
            }
        }
    };
    piece(0, k);
    if k < last {
        piece(k, last);
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
        let mut cut = [0u64; 64];
        for &g in active {
            let g = g as usize;
            self.window_values(s, window, g, &mut cut);
            let base = g * 64;
            let en = self.regs.enable[g];
            match sink {
                QeeSink::Sign { .. } => unreachable!("sign tests take the span path"),
                QeeSink::Store { dst } => {
                    let a = Access::of(dst);
                    for (i, &c) in cut.iter().enumerate() {
                        if (en >> i) & 1 != 0 {
                            self.set(a, base + i, c);
                        }
                    }
                }
                QeeSink::Compare {
                    field,
                    cmp,
                    dst,
                    combine,
                } => {
                    let a = Access::of(field);
                    let mut result = 0u64;
                    for (i, &c) in cut.iter().enumerate() {
                        let lhs = value_of(c, field.bits, field.signed);
                        let rhs = value_of(self.get(a, base + i), field.bits, field.signed);
                        result |= (cmp.holds(lhs, rhs) as u64) << i;
                    }
                    self.regs.combine(dst, g, result, combine);
                }
                QeeSink::Add { dst } => {
                    let a = Access::of(dst);
                    for (i, &c) in cut.iter().enumerate() {
                        if (en >> i) & 1 != 0 {
                            let v = self.get(a, base + i).wrapping_add(c);
                            self.set(a, base + i, v);
                        }
                    }
                }
            }
        }
    }

    fn write_const(&mut self, dst: Field, value: u64, active: &[u32]) {
        self.update(dst, active, |_, _| value)
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

    fn read_values(&self, field: Field, rect: Rect) -> Vec<u64> {
        let a = Access::of(field);
        let per_row = self.geometry.groups_per_row;
        let mut out = Vec::with_capacity((rect.width * rect.height) as usize);
        for py in rect.y as usize..(rect.y + rect.height) as usize {
            for px in rect.x as usize..(rect.x + rect.width) as usize {
                let p = (py * per_row + px / 64) * 64 + px % 64;
                out.push(self.get(a, p));
            }
        }
        out
    }
}
