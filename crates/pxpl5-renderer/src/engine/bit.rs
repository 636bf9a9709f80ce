//! The `bit` fidelity level, the reference: pixel memory as bit-planes (one u64 holds one bit of 64
//! pixels) and every multi-bit operation micro-cycle by micro-cycle through one-bit serial adders
//! with their carries, as the bit-serial pixel processors do.
//!
//! The QEE's three streams (x-tree, y-tree, cross stage; see [`crate::qee`]) arrive one bit-plane
//! per cycle, least significant bit first, and each pixel adds them with two serial adders before
//! its ALU consumes the sum. A group of 64 pixels is carried through all of a command's
//! micro-cycles before the next group (the groups are independent, so the order of the loops
//! changes nothing but the host's cache use).

use super::{Geometry, PixelEngine, QeeSink, Registers, gated, transpose64};
use crate::command::{Bit, Cmp, Field, LogicOp, Rect};
use crate::qee::{Streams, Window};

/// Bit-plane pixel memory and the shared one-bit registers.
pub struct BitEngine {
    geometry: Geometry,
    /// `memory_bits` planes of `geometry.groups` u64s (one per group), plane-major.
    planes: Vec<u64>,
    regs: Registers,
    scratch: Scratch,
}

/// Full-adder sum and carry on 64 pixels.
#[inline(always)]
fn full_add(a: u64, b: u64, c: u64) -> (u64, u64) {
    let t = a ^ b;
    (t ^ c, (a & b) | (c & t))
}

impl BitEngine {
    pub fn new(geometry: Geometry, memory_bits: u32, flag_count: usize) -> BitEngine {
        BitEngine {
            geometry,
            planes: vec![0; memory_bits as usize * geometry.groups],
            regs: Registers::new(geometry, flag_count),
            scratch: Scratch::default(),
        }
    }

    /// Bit `k` of field `f` for group `g`, extended past the field's top by its signedness.
    #[inline(always)]
    fn bit(&self, f: Field, k: u32, g: usize) -> u64 {
        if k < f.bits {
            self.planes[(f.offset + k) as usize * self.geometry.groups + g]
        } else if f.signed {
            self.planes[(f.offset + f.bits - 1) as usize * self.geometry.groups + g]
        } else {
            0
        }
    }

    /// Write bit `k` of field `f` for group `g` where `en` is set.
    #[inline(always)]
    fn write(&mut self, f: Field, k: u32, g: usize, v: u64, en: u64) {
        let p = &mut self.planes[(f.offset + k) as usize * self.geometry.groups + g];
        *p = gated(*p, en, v);
    }
}

impl PixelEngine for BitEngine {
    fn registers(&self) -> &Registers {
        &self.regs
    }

    fn registers_mut(&mut self) -> &mut Registers {
        &mut self.regs
    }

    fn qee(&mut self, s: &Streams, window: Window, sink: QeeSink, active: &[u32]) {
        // Blocks as wide as the row allows, up to four groups.
        match self.geometry.groups_per_row {
            n if n % 4 == 0 => self.qee_blocks::<4>(s, window, sink, active),
            n if n % 2 == 0 => self.qee_blocks::<2>(s, window, sink, active),
            _ => self.qee_blocks::<1>(s, window, sink, active),
        }
    }

    fn write_const(&mut self, dst: Field, value: u64, active: &[u32]) {
        for &g in active {
            let g = g as usize;
            let en = self.regs.enable[g];
            for k in 0..dst.bits {
                self.write(dst, k, g, ((value >> k) & 1).wrapping_neg(), en);
            }
        }
    }

    fn copy(&mut self, dst: Field, src: Field, active: &[u32]) {
        for &g in active {
            let g = g as usize;
            let en = self.regs.enable[g];
            for k in 0..dst.bits {
                let v = self.bit(src, k, g);
                self.write(dst, k, g, v, en);
            }
        }
    }

    fn add_sub(&mut self, dst: Field, a: Field, b: Field, subtract: bool, active: &[u32]) {
        let invert = if subtract { u64::MAX } else { 0 };
        for &g in active {
            let g = g as usize;
            let en = self.regs.enable[g];
            let mut carry = invert;
            for k in 0..dst.bits {
                let (s, c) = full_add(self.bit(a, k, g), self.bit(b, k, g) ^ invert, carry);
                carry = c;
                self.write(dst, k, g, s, en);
            }
        }
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
        // Both operands extended to max + 2 bits: their difference cannot overflow there.
        let width = a.bits.max(b.bits) + 2;
        for &g in active {
            let g = g as usize;
            let mut carry = u64::MAX;
            let mut differs = 0u64;
            let mut d = 0u64;
            for k in 0..width {
                let (x, y) = (self.bit(a, k, g), self.bit(b, k, g));
                differs |= x ^ y;
                let (s, c) = full_add(x, !y, carry);
                carry = c;
                d = s;
            }
            self.regs
                .combine(dst, g, cmp.from_lt_eq(d, !differs), combine);
        }
    }

    fn mul_const(&mut self, dst: Field, src: Field, k: i64, k_bits: u32, active: &[u32]) {
        // Shift and add: for each bit j of the two's-complement constant, add (or, for its sign
        // bit, subtract) src << j into an accumulator of dst's width, then store it where enabled.
        let n = dst.bits;
        let mut acc = [0u64; 64];
        for &g in active {
            let g = g as usize;
            acc[..n as usize].fill(0);
            for j in 0..k_bits.min(n) {
                if (k >> j) & 1 == 0 {
                    continue;
                }
                let negative = j == k_bits - 1;
                let invert = if negative { u64::MAX } else { 0 };
                let mut carry = invert;
                for t in j..n {
                    let (s, c) = full_add(acc[t as usize], self.bit(src, t - j, g) ^ invert, carry);
                    carry = c;
                    acc[t as usize] = s;
                }
            }
            let en = self.regs.enable[g];
            for t in 0..n {
                self.write(dst, t, g, acc[t as usize], en);
            }
        }
    }

    fn read_planes(&self, field: Field) -> Vec<u64> {
        let groups = self.geometry.groups;
        let start = field.offset as usize * groups;
        self.planes[start..start + field.bits as usize * groups].to_vec()
    }

    fn write_planes(&mut self, field: Field, planes: &[u64]) {
        let groups = self.geometry.groups;
        let start = field.offset as usize * groups;
        self.planes[start..start + field.bits as usize * groups].copy_from_slice(planes);
    }

    fn write_values(&mut self, field: Field, rect: Rect, values: &[u64]) {
        let per_row = self.geometry.groups_per_row;
        let mut it = values.iter();
        for py in rect.y as usize..(rect.y + rect.height) as usize {
            for px in rect.x as usize..(rect.x + rect.width) as usize {
                let g = py * per_row + px / 64;
                let v = *it.next().expect("validated length");
                for k in 0..field.bits {
                    let bit = ((v >> k) & 1).wrapping_neg();
                    self.write(field, k, g, bit, 1 << (px % 64));
                }
            }
        }
    }

    fn read_values(&self, field: Field, rect: Rect) -> Vec<u64> {
        let per_row = self.geometry.groups_per_row;
        let mut out = Vec::with_capacity((rect.width * rect.height) as usize);
        for py in rect.y as usize..(rect.y + rect.height) as usize {
            for px in rect.x as usize..(rect.x + rect.width) as usize {
                let g = py * per_row + px / 64;
                let mut v = 0u64;
                for k in 0..field.bits {
                    v |= ((self.bit(field, k, g) >> (px % 64)) & 1) << k;
                }
                out.push(v);
            }
        }
        out
    }
}

/// Rows per block: the rows of a block share the x-tree's planes and the step of the cross
/// stage, and each has its own row stream, so a block's rows fill a host vector register.
const ROWS: usize = 2;

/// One word of each row of a block (the same group column), side by side and aligned so that
/// the host keeps them in one vector register.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
#[repr(align(16))]
struct Rows([u64; ROWS]);

impl Rows {
    #[inline(always)]
    fn splat(v: u64) -> Rows {
        Rows([v; ROWS])
    }
}

macro_rules! rows_op {
    ($trait:ident, $method:ident, $op:tt) => {
        impl std::ops::$trait for Rows {
            type Output = Rows;
            #[inline(always)]
            fn $method(self, o: Rows) -> Rows {
                let mut r = self;
                for (a, b) in r.0.iter_mut().zip(o.0) {
                    *a $op b;
                }
                r
            }
        }
    };
}
rows_op!(BitAnd, bitand, &=);
rows_op!(BitOr, bitor, |=);
rows_op!(BitXor, bitxor, ^=);

impl std::ops::Not for Rows {
    type Output = Rows;
    #[inline(always)]
    fn not(self) -> Rows {
        Rows(self.0.map(|v| !v))
    }
}

/// A full adder on both rows of a block: `a + b + carry`, the carry updated in place.
#[inline(always)]
fn add_rows(a: Rows, b: Rows, carry: &mut Rows) -> Rows {
    let t = a ^ b;
    let s = t ^ *carry;
    *carry = (a & b) | (*carry & t);
    s
}

/// A block's words: `G` group columns of [`ROWS`] rows.
type Words<const G: usize> = [Rows; G];

/// Buffers a QEE command reuses, so that a command allocates nothing. Planes are kept per
/// *block column* (`G` consecutive group columns): plane `j` of block column `b` is entry
/// `b * 64 + j` of the slice's `G`-chunks. The x-tree's planes and the cross stage's steps are
/// the same for every row, so they are kept splatted across a block's rows, ready to use.
#[derive(Default)]
struct Scratch {
    /// The x-tree's planes, X(x) = A x + D x^2.
    col: Vec<Rows>,
    /// The cross stage's planes, Z(x, y) = (E y) x, for the rows of the block in `cross_row`.
    cross: Vec<Rows>,
    /// The cross stage's step from one block of rows to the next,
    /// Z(x, y + ROWS) - Z(x, y) = ROWS E x.
    step: Vec<Rows>,
    /// The first row whose Z `cross` holds, per block column (`usize::MAX`: none yet).
    cross_row: Vec<usize>,
    /// Which groups of the current block of rows the command may change (row-major).
    lanes: Vec<bool>,
}

/// How many blocks of rows a block column's cross planes may be stepped forward instead of being
/// built afresh (a step is one bit-sliced add per plane; a fresh build is [`ROWS`] x G 64 x 64
/// transposes, which cost about as much as this many steps).
const MAX_STEPS: usize = 4;

/// The 64 bit-planes of `values(i)` for the pixels i = 0..64 of a group, `out[j * stride]` for
/// plane j, each put in place by `set`.
fn planes_of(
    out: &mut [Rows],
    stride: usize,
    values: impl Fn(usize) -> i64,
    set: impl Fn(&mut Rows, u64),
) {
    let mut m = [0u64; 64];
    for (i, v) in m.iter_mut().enumerate() {
        *v = values(i) as u64;
    }
    transpose64(&mut m);
    for (j, &p) in m.iter().enumerate() {
        set(&mut out[j * stride], p);
    }
}

/// The tree's streams into one block, and the carries of its pixels' two stream adders.
struct BlockStream<'a, const G: usize, const CROSS: bool> {
    /// The x-tree's planes of the block's group columns.
    col: &'a [Words<G>],
    /// The cross stage's planes for the block's rows, advanced in place to the next block of
    /// rows as they are used.
    cross: &'a mut [Words<G>],
    step: &'a [Words<G>],
    /// Y(y) of each row: bit j goes to every pixel of the row at micro-cycle j.
    rows: [u64; ROWS],
    /// Carries of the x + y adder, the (x + y) + z adder, and the cross stage's row step.
    c1: Words<G>,
    c2: Words<G>,
    c_step: Words<G>,
}

impl<'a, const G: usize, const CROSS: bool> BlockStream<'a, G, CROSS> {
    fn new(
        col: &'a [Words<G>],
        cross: &'a mut [Words<G>],
        step: &'a [Words<G>],
        rows: [u64; ROWS],
    ) -> Self {
        let zero = [Rows::default(); G];
        BlockStream {
            col,
            cross,
            step,
            rows,
            c1: zero,
            c2: zero,
            c_step: zero,
        }
    }

    /// Micro-cycles `from .. to`, each one's bit of every pixel's V handed to `f` with its
    /// cycle number.
    #[inline(always)]
    fn run(&mut self, from: usize, to: usize, mut f: impl FnMut(usize, Words<G>)) {
        // The row streams bit-reversed, so that bit j is the top bit at micro-cycle j: an
        // arithmetic shift spreads it over the row's word.
        let mut rest = Rows(
            self.rows
                .map(|y| y.reverse_bits().checked_shl(from as u32).unwrap_or(0)),
        );
        let mut row_bits = || {
            let bits = Rows(rest.0.map(|v| ((v as i64) >> 63) as u64));
            rest = Rows(rest.0.map(|v| v << 1));
            bits
        };
        let col = &self.col[from..to];
        if CROSS {
            let planes = col
                .iter()
                .zip(&mut self.cross[from..to])
                .zip(&self.step[from..to]);
            for (j, ((x, z), d)) in (from..).zip(planes) {
                let y = row_bits();
                let mut v = [Rows::default(); G];
                for c in 0..G {
                    let s1 = add_rows(x[c], y, &mut self.c1[c]);
                    let zc = z[c];
                    // The cross stage moves on to the next rows while these are consumed:
                    // Z(x, y + ROWS) = Z(x, y) + ROWS E x, one plane per cycle with its carry.
                    z[c] = add_rows(zc, d[c], &mut self.c_step[c]);
                    v[c] = add_rows(s1, zc, &mut self.c2[c]);
                }
                f(j, v);
            }
        } else {
            for (j, x) in (from..).zip(col) {
                let y = row_bits();
                let mut v = [Rows::default(); G];
                for c in 0..G {
                    v[c] = add_rows(x[c], y, &mut self.c1[c]);
                }
                f(j, v);
            }
        }
    }
}

/// One block's place: its first row and group column, the words the command may change (bit
/// `c * ROWS + r` for column c, row r), their enables (0 where it may not).
#[derive(Clone, Copy)]
struct Block<const G: usize> {
    py: usize,
    cx: usize,
    lanes: u32,
    en: Words<G>,
}

impl<const G: usize> Block<G> {
    #[inline(always)]
    fn changes(&self, c: usize, r: usize) -> bool {
        self.lanes >> (c * ROWS + r) & 1 != 0
    }
}

impl BitEngine {
    /// The QEE command on blocks of [`ROWS`] rows by `G` groups: every block runs all its
    /// micro-cycles with its carries in registers before the next block.
    fn qee_blocks<const G: usize>(
        &mut self,
        s: &Streams,
        window: Window,
        sink: QeeSink,
        active: &[u32],
    ) {
        if s.cross {
            self.qee_run::<G, true>(s, window, sink, active)
        } else {
            self.qee_run::<G, false>(s, window, sink, active)
        }
    }

    fn qee_run<const G: usize, const CROSS: bool>(
        &mut self,
        s: &Streams,
        window: Window,
        sink: QeeSink,
        active: &[u32],
    ) {
        let (gpr, height) = (self.geometry.groups_per_row, self.geometry.height);
        let columns = gpr / G;
        let cycles = window.delivered_bits() as usize;
        let mut sc = std::mem::take(&mut self.scratch);
        // Group column c's plane j at entry (c / G * 64 + j) * G + c % G.
        let at = |c: usize| c / G * 64 * G + c % G;
        sc.col.resize(64 * gpr, Rows::default());
        for c in 0..gpr {
            let splat = |p: &mut Rows, v| *p = Rows::splat(v);
            planes_of(&mut sc.col[at(c)..], G, |i| s.col[c * 64 + i], splat);
        }
        if CROSS {
            sc.cross.resize(64 * gpr, Rows::default());
            sc.step.resize(64 * gpr, Rows::default());
            sc.cross_row.clear();
            sc.cross_row.resize(columns, usize::MAX);
            let step = ROWS as i64 * s.expr.e;
            for c in 0..gpr {
                let x = |i: usize| s.origin_x + (c * 64 + i) as i64;
                let splat = |p: &mut Rows, v| *p = Rows::splat(v);
                planes_of(&mut sc.step[at(c)..], G, |i| step * x(i), splat);
            }
        }
        sc.lanes.clear();
        sc.lanes.resize(ROWS * gpr, false);
        let mut i = 0;
        while i < active.len() {
            // The active groups of the next block of rows.
            let py = active[i] as usize / gpr / ROWS * ROWS;
            let first = i;
            while i < active.len() && (active[i] as usize) < (py + ROWS) * gpr {
                sc.lanes[active[i] as usize - py * gpr] = true;
                i += 1;
            }
            // A row past the array's last (an odd height) takes the last row's streams; it has
            // no active group, so nothing of it is written.
            let rows: [usize; ROWS] = std::array::from_fn(|r| (py + r).min(height - 1));
            let row_values = rows.map(|y| s.row[y] as u64);
            for b in 0..columns {
                let cx = b * G;
                let mut lanes = 0u32;
                let mut en = [Rows::default(); G];
                for (c, en) in en.iter_mut().enumerate() {
                    for r in 0..ROWS {
                        if sc.lanes[r * gpr + cx + c] {
                            lanes |= 1 << (c * ROWS + r);
                            en.0[r] = self.regs.enable[(py + r) * gpr + cx + c];
                        }
                    }
                }
                if lanes == 0 {
                    continue;
                }
                let block = Block { py, cx, lanes, en };
                let (col, _) = sc.col[b * 64 * G..][..cycles * G].as_chunks::<G>();
                if CROSS {
                    let (step, _) = sc.step[b * 64 * G..][..cycles * G].as_chunks::<G>();
                    let cross = &mut sc.cross[b * 64 * G..][..64 * G];
                    let from = sc.cross_row[b];
                    if from <= py && py - from <= MAX_STEPS * ROWS {
                        let (planes, _) = cross[..cycles * G].as_chunks_mut::<G>();
                        for _ in (from..py).step_by(ROWS) {
                            let mut carry = [Rows::default(); G];
                            for (p, d) in planes.iter_mut().zip(step) {
                                for c in 0..G {
                                    p[c] = add_rows(p[c], d[c], &mut carry[c]);
                                }
                            }
                        }
                    } else {
                        for c in 0..G {
                            let px = (cx + c) * 64;
                            for (r, &y) in rows.iter().enumerate() {
                                let z = |i| s.cross_at(px + i, y);
                                planes_of(&mut cross[c..], G, z, |p, v| p.0[r] = v);
                            }
                        }
                    }
                    sc.cross_row[b] = py + ROWS;
                    let (cross, _) = cross[..cycles * G].as_chunks_mut::<G>();
                    let st = BlockStream::<G, true>::new(col, cross, step, row_values);
                    self.run_block(st, window, sink, block);
                } else {
                    let st = BlockStream::<G, false>::new(col, &mut [], &[], row_values);
                    self.run_block(st, window, sink, block);
                }
            }
            for &g in &active[first..i] {
                sc.lanes[g as usize - py * gpr] = false;
            }
        }
        self.scratch = sc;
    }

    /// One block through the sink's micro-cycles.
    #[inline(always)]
    fn run_block<const G: usize, const CROSS: bool>(
        &mut self,
        mut st: BlockStream<'_, G, CROSS>,
        window: Window,
        sink: QeeSink,
        block: Block<G>,
    ) {
        let (shift, cycles) = (window.shift as usize, window.delivered_bits() as usize);
        match sink {
            QeeSink::Sign { dst, combine } => {
                // Only the window's top bit is used; the micro-cycles below it only carry.
                st.run(0, cycles - 1, |_, _| {});
                let mut last = [Rows::default(); G];
                st.run(cycles - 1, cycles, |_, v| last = v);
                self.combine_words(dst, combine, block, last.map(|v| !v));
            }
            QeeSink::Store { dst } => {
                st.run(0, shift, |_, _| {});
                st.run(shift, cycles, |j, v| {
                    self.for_words(dst, (j - shift) as u32, block, |c, r, p| {
                        *p = gated(*p, block.en[c].0[r], v[c].0[r])
                    });
                });
            }
            QeeSink::Add { dst } => {
                st.run(0, shift, |_, _| {});
                let mut carry = [Rows::default(); G];
                st.run(shift, cycles, |j, v| {
                    self.for_words(dst, (j - shift) as u32, block, |c, r, p| {
                        let (sum, n) = full_add(*p, v[c].0[r], carry[c].0[r]);
                        carry[c].0[r] = n;
                        *p = gated(*p, block.en[c].0[r], sum);
                    });
                });
            }
            QeeSink::Compare {
                field,
                cmp,
                dst,
                combine,
            } => {
                st.run(0, shift, |_, _| {});
                // V - field = V + !field + 1 through the ALU, on bits + 1 bits.
                let mut carry = [Rows::splat(u64::MAX); G];
                let mut differs = [Rows::default(); G];
                let mut last = [Rows::default(); G];
                st.run(shift, cycles, |j, v| {
                    let top = j == cycles - 1;
                    self.for_words(field, (j - shift) as u32, block, |c, r, p| {
                        let (x, y, carry) = (v[c].0[r], *p, &mut carry[c].0[r]);
                        differs[c].0[r] |= x ^ y;
                        let (d, n) = full_add(x, !y, *carry);
                        *carry = n;
                        last[c].0[r] = d;
                        if top {
                            // One more ALU cycle on the extension bits (covered by alu_setup):
                            // the difference needs bits + 1 bits to keep its sign.
                            let (ext, rext) = if field.signed { (x, y) } else { (0, 0) };
                            last[c].0[r] = full_add(ext, !rext, *carry).0;
                        }
                    });
                });
                let mut value = [Rows::default(); G];
                for c in 0..G {
                    for r in 0..ROWS {
                        value[c].0[r] = cmp.from_lt_eq(last[c].0[r], !differs[c].0[r]);
                    }
                }
                self.combine_words(dst, combine, block, value);
            }
        }
    }

    /// `f` on bit `k` of field `field` of each word of the block the command may change.
    #[inline(always)]
    fn for_words<const G: usize>(
        &mut self,
        field: Field,
        k: u32,
        block: Block<G>,
        mut f: impl FnMut(usize, usize, &mut u64),
    ) {
        let gpr = self.geometry.groups_per_row;
        let plane = (field.offset + k) as usize * self.geometry.groups;
        for c in 0..G {
            for r in 0..ROWS {
                if block.changes(c, r) {
                    f(
                        c,
                        r,
                        &mut self.planes[plane + (block.py + r) * gpr + block.cx + c],
                    );
                }
            }
        }
    }

    /// `dst := combine(dst, values)` on the block's rows. The words the command may not change
    /// are combined too: for them the combine is the identity (disabled for a gated write, or 0
    /// kept at 0), which is what leaves them out of the active list.
    fn combine_words<const G: usize>(
        &mut self,
        dst: Bit,
        combine: LogicOp,
        block: Block<G>,
        values: Words<G>,
    ) {
        let gpr = self.geometry.groups_per_row;
        for r in 0..ROWS.min(self.geometry.height - block.py) {
            let row: [u64; G] = std::array::from_fn(|c| values[c].0[r]);
            let start = (block.py + r) * gpr + block.cx;
            self.regs.combine_run(dst, start, &row, combine);
        }
    }
}
