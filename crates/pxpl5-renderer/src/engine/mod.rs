//! The pixel work of the Renderer at two fidelity levels, behind one trait.
//!
//! [`PixelEngine`] is what a [`Board`](crate::Board) calls once it has validated a command and
//! charged its cycles: the engines only change pixel state, they never decide time. Both keep the
//! one-bit registers (enable and flags) the same way, as bit-planes in [`Registers`], because a
//! one-bit register has no integer form to differ in; they differ in pixel memory and arithmetic:
//!
//! - [`bit::BitEngine`] (`bit`): pixel memory as 208 bit-planes (one u64 holds one bit of a
//!   group's 64 pixels); every multi-bit operation runs micro-cycle by micro-cycle through serial
//!   adders with their carries, and QEE results arrive from the tree's streams one bit-plane per
//!   cycle.
//! - [`integer::IntegerEngine`] (`integer`): pixel memory as per-pixel integers; the same
//!   semantics by integer arithmetic.
//!
//! Both engines work a *group* at a time: 64 consecutive pixels of one array row (columns 64k to
//! 64k + 63), numbered row-major ([`Geometry`]); in a bit-plane, one u64 holds one bit of each
//! pixel of a group. A group is the host's unit of work, with no counterpart on the board. Both
//! engines skip the groups a command cannot change (every pixel disabled, for a gated write): a
//! shortcut with no effect on any result, shared by both levels through
//! [`Registers::enabled_groups`].

pub mod bit;
pub mod integer;
pub mod sparse;

use crate::command::{Anf, Bit, Cmp, Field, LogicOp, Rect};
use crate::qee::{Streams, Window};

/// The shape of the array in 64-pixel groups: pixel (px, py) is bit px % 64 of group
/// py * groups_per_row + px / 64.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Geometry {
    pub width: usize,
    pub height: usize,
    pub groups_per_row: usize,
    pub groups: usize,
}

impl Geometry {
    pub fn new(width: u32, height: u32) -> Geometry {
        let groups_per_row = (width as usize) / 64;
        Geometry {
            width: width as usize,
            height: height as usize,
            groups_per_row,
            groups: groups_per_row * height as usize,
        }
    }

    /// Row and first column of group `g`.
    #[inline]
    pub fn group_origin(&self, g: usize) -> (usize, usize) {
        (g / self.groups_per_row, (g % self.groups_per_row) * 64)
    }
}

/// The enable register and the flag registers of every pixel, as bit-planes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Registers {
    pub enable: Vec<u64>,
    pub flags: Vec<Vec<u64>>,
}

impl Registers {
    /// All pixels enabled (the state at power-up is undefined on the real board; the simulator
    /// defines it so that runs are reproducible), all flags 0.
    pub fn new(geometry: Geometry, flag_count: usize) -> Registers {
        Registers {
            enable: vec![u64::MAX; geometry.groups],
            flags: vec![vec![0; geometry.groups]; flag_count],
        }
    }

    #[inline]
    pub fn get(&self, b: Bit, g: usize) -> u64 {
        match b {
            Bit::Enable => self.enable[g],
            Bit::Flag(i) => self.flags[i as usize][g],
        }
    }

    /// `dst := combine(dst, value)` for the 64 pixels of group `g`, gated by enable unless `dst` is
    /// the enable register itself.
    #[inline]
    pub fn combine(&mut self, dst: Bit, g: usize, value: u64, combine: LogicOp) {
        match dst {
            Bit::Enable => self.enable[g] = combine.apply(self.enable[g], value),
            Bit::Flag(i) => {
                let old = self.flags[i as usize][g];
                self.flags[i as usize][g] = gated(old, self.enable[g], combine.apply(old, value));
            }
        }
    }

    /// `dst := op(a, b)`: one ALU step on every pixel.
    pub fn logic(&mut self, dst: Bit, a: Bit, b: Bit, op: LogicOp) {
        // The destination's plane is taken out so the inputs can be read beside it; an input that
        // is the destination itself is read from a copy of the chunk's old values (each group's
        // result depends only on that group's inputs). Every loop is a plain zip of slices with a
        // fixed, branch-free op: 2.7 K instructions per command on a 128 x 128 board, by
        // callgrind, where the per-case loops with the sum-of-minterms op took 4.4 K.
        const CHUNK: usize = 64;
        let mut out = std::mem::take(self.plane_mut(dst));
        let mut old = [0u64; CHUNK];
        let aliased = a == dst || b == dst;
        let n = out.len();
        for start in (0..n).step_by(CHUNK) {
            let end = (start + CHUNK).min(n);
            let old = &mut old[..end - start];
            if aliased {
                old.copy_from_slice(&out[start..end]);
            }
            let input = |i: Bit| -> &[u64] {
                if i == dst {
                    old
                } else {
                    &self.plane(i)[start..end]
                }
            };
            let (x, y) = (input(a), input(b));
            let o = &mut out[start..end];
            match dst {
                Bit::Enable => {
                    for ((o, &x), &y) in o.iter_mut().zip(x).zip(y) {
                        *o = op.apply(x, y);
                    }
                }
                Bit::Flag(_) => {
                    let en = &self.enable[start..end];
                    for (((o, &x), &y), &en) in o.iter_mut().zip(x).zip(y).zip(en) {
                        *o = gated(*o, en, op.apply(x, y));
                    }
                }
            }
        }
        *self.plane_mut(dst) = out;
    }

    fn plane_mut(&mut self, b: Bit) -> &mut Vec<u64> {
        match b {
            Bit::Enable => &mut self.enable,
            Bit::Flag(i) => &mut self.flags[i as usize],
        }
    }

    /// The bit-plane of a one-bit register.
    #[inline]
    pub fn plane(&self, b: Bit) -> &[u64] {
        match b {
            Bit::Enable => &self.enable,
            Bit::Flag(i) => &self.flags[i as usize],
        }
    }

    /// [`Registers::combine`] for the consecutive groups `start .. start + N`, the op in normal
    /// form (found once per block by the caller). Always inlined,
    /// with `N` known: the bit level calls it for every block of every QEE command, where as a
    /// call over a slice it took 82 instructions for two words; inlined, the bit level's
    /// hemisphere stream takes 1.8 % fewer instructions (`bench renderer --instructions`).
    #[inline(always)]
    pub fn combine_run<const N: usize>(
        &mut self,
        dst: Bit,
        start: usize,
        values: &[u64; N],
        combine: Anf,
    ) {
        let end = start + N;
        match dst {
            Bit::Enable => {
                for (e, &v) in self.enable[start..end].iter_mut().zip(values) {
                    *e = combine.apply(*e, v);
                }
            }
            Bit::Flag(i) => {
                let flag = &mut self.flags[i as usize][start..end];
                for ((f, &v), &en) in flag.iter_mut().zip(values).zip(&self.enable[start..end]) {
                    *f = gated(*f, en, combine.apply(*f, v));
                }
            }
        }
    }

    /// The groups with an enabled pixel: those a gated write (memory and flags) can change, and
    /// those a combine into enable by an op that keeps 0 at 0 can (any other op can change every
    /// group). They go into a buffer the caller reuses (a board keeps one, so a command allocates
    /// nothing).
    pub fn enabled_groups(&self, out: &mut Vec<u32>) {
        self.enabled_groups_in(0..self.enable.len(), out);
    }

    /// [`Registers::enabled_groups`] for an enable that has no pixel outside groups `within`.
    pub fn enabled_groups_in(&self, within: std::ops::Range<usize>, out: &mut Vec<u32>) {
        out.clear();
        out.resize(within.len(), 0);
        let mut k = 0;
        // Sixteen groups at a time: a view's enable is mostly zero once its first edges are
        // drawn (a receiver's, a few rows of the board), and an all-zero run costs one test;
        // elsewhere branch-free, writing every group and advancing past the enabled ones. The
        // hemicube stream took 20.86 M instructions with four groups a test, 20.75 M with
        // eight, 20.67 M with sixteen and 20.85 M with 32.
        let mut g = within.start as u32;
        let mut chunks = self.enable[within].chunks_exact(16);
        for c in &mut chunks {
            if c.iter().fold(0, |any, &en| any | en) != 0 {
                for (i, &en) in c.iter().enumerate() {
                    out[k] = g + i as u32;
                    k += usize::from(en != 0);
                }
            }
            g += 16;
        }
        for (i, &en) in chunks.remainder().iter().enumerate() {
            out[k] = g + i as u32;
            k += usize::from(en != 0);
        }
        out.truncate(k);
    }
}

/// A gated write of 64 pixels: `new` where enabled, `old` elsewhere.
#[inline]
pub fn gated(old: u64, enable: u64, new: u64) -> u64 {
    (old & !enable) | (new & enable)
}

/// Where a QEE result goes.
#[derive(Clone, Copy, Debug)]
pub enum QeeSink {
    Sign {
        dst: Bit,
        combine: LogicOp,
    },
    Store {
        dst: Field,
    },
    Compare {
        field: Field,
        cmp: Cmp,
        dst: Bit,
        combine: LogicOp,
    },
    Add {
        dst: Field,
    },
}

/// A receiver's depth test, three commands that a level may run as one pass over the groups:
/// a `QeeCompare` of the window with `field` by `cmp`, combined into enable by AND; then, at the
/// pixels still enabled, the same window's `QeeStore` into `field` if `store`, and `id`'s
/// `WriteConst` (field, value) if any. A group's pixels change only through that group's inputs,
/// so doing the three a group at a time gives what doing them one after the other gives.
#[derive(Clone, Copy, Debug)]
pub struct DepthTest {
    pub field: Field,
    pub cmp: Cmp,
    pub store: bool,
    pub id: Option<(Field, u64)>,
}

/// The pixel work of one fidelity level. Callers have validated every operand (fields inside
/// memory and not partially overlapping, widths matching, flags existing).
pub trait PixelEngine {
    fn registers(&self) -> &Registers;
    fn registers_mut(&mut self) -> &mut Registers;
    /// [`Registers::enabled_groups`]; a level that knows where enable has no pixel may look
    /// only at the rest.
    fn enabled_groups(&self, out: &mut Vec<u32>) {
        self.registers().enabled_groups(out)
    }
    /// A QEE command: the tree's streams, the window the pixels use, and where it goes.
    fn qee(&mut self, streams: &Streams, window: Window, sink: QeeSink, active: &[u32]);
    /// `test`'s commands on the groups `active` lists (a superset of those with an enabled
    /// pixel): by default one after the other, each over the same list (the groups the compare
    /// disables have nothing for the gated writes to change).
    fn depth_test(&mut self, streams: &Streams, window: Window, test: DepthTest, active: &[u32]) {
        depth_test_one_by_one(self, streams, window, test, active);
    }
    fn write_const(&mut self, dst: Field, value: u64, active: &[u32]);
    fn copy(&mut self, dst: Field, src: Field, active: &[u32]);
    fn add_sub(&mut self, dst: Field, a: Field, b: Field, subtract: bool, active: &[u32]);
    fn compare(&mut self, a: Field, b: Field, cmp: Cmp, dst: Bit, combine: LogicOp, active: &[u32]);
    fn mul_const(&mut self, dst: Field, src: Field, k: i64, k_bits: u32, active: &[u32]);
    /// The field of every pixel as bit-planes (plane-major, `field.bits * groups` u64s).
    fn read_planes(&self, field: Field) -> Vec<u64>;
    /// Overwrite the field of every pixel (not gated) from bit-planes.
    fn write_planes(&mut self, field: Field, planes: &[u64]);
    /// The field's raw bits for the pixels of `rect`, row by row, into `out` (its contents
    /// replaced: a board reads back into one buffer, rather than a fresh one a readback).
    fn read_values(&self, field: Field, rect: Rect, out: &mut Vec<u64>);
    /// Overwrite the field's raw bits for the pixels of `rect`, row by row (not gated).
    fn write_values(&mut self, field: Field, rect: Rect, values: &[u64]);
}

/// `test`'s commands one after the other, each over `active`: what a depth test must leave, and
/// how a level runs one it has no single pass for.
pub fn depth_test_one_by_one<E: PixelEngine + ?Sized>(
    engine: &mut E,
    streams: &Streams,
    window: Window,
    test: DepthTest,
    active: &[u32],
) {
    let DepthTest {
        field,
        cmp,
        store,
        id,
    } = test;
    let compare = QeeSink::Compare {
        field,
        cmp,
        dst: Bit::Enable,
        combine: LogicOp::AND,
    };
    engine.qee(streams, window, compare, active);
    if store {
        engine.qee(streams, window, QeeSink::Store { dst: field }, active);
    }
    if let Some((dst, value)) = id {
        engine.write_const(dst, value, active);
    }
}

/// Sign- or zero-extend the raw `bits`-bit value of a field to 64 bits.
#[inline]
pub fn extend(raw: u64, bits: u32, signed: bool) -> u64 {
    if signed && bits < 64 {
        let s = 64 - bits;
        (((raw << s) as i64) >> s) as u64
    } else {
        raw
    }
}

/// The value of a field's raw bits as an exact integer.
#[inline]
pub fn value_of(raw: u64, bits: u32, signed: bool) -> i128 {
    if signed {
        extend(raw, bits, true) as i64 as i128
    } else {
        raw as i128
    }
}

/// Transpose a 64 x 64 bit matrix in place: afterwards bit i of `m[j]` is what bit j of `m[i]`
/// was. Used to turn 64 stream values into 64 bit-planes (recursive block swaps, 6 rounds).
pub fn transpose64(m: &mut [u64; 64]) {
    let mut s = 32;
    let mut mask: u64 = 0x0000_0000_FFFF_FFFF;
    while s != 0 {
        let mut k = 0;
        while k < 64 {
            for i in k..k + s {
                let t = ((m[i] >> s) ^ m[i + s]) & mask;
                m[i] ^= t << s;
                m[i + s] ^= t;
            }
            k += 2 * s;
        }
        s >>= 1;
        mask ^= mask << s;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    #[allow(clippy::needless_range_loop)] // (i, j) index a matrix both ways
    fn transpose_matches_the_naive_one() {
        let mut rng = pxpl5_geom::rng::Lcg::new(0x9E37_79B9_7F4A_7C15);
        let mut m = [0u64; 64];
        for v in m.iter_mut() {
            *v = rng.next_u64();
        }
        let orig = m;
        transpose64(&mut m);
        for i in 0..64 {
            for j in 0..64 {
                assert_eq!((m[j] >> i) & 1, (orig[i] >> j) & 1, "bit ({i}, {j})");
            }
        }
    }

    #[test]
    fn extension() {
        assert_eq!(extend(0b101, 3, true), (-3i64) as u64);
        assert_eq!(extend(0b101, 3, false), 5);
        assert_eq!(value_of(u64::MAX, 64, false), u64::MAX as i128);
        assert_eq!(value_of(u64::MAX, 64, true), -1);
    }
}
