//! The `bit` fidelity level, the reference: pixel memory as bit-planes (one u64 holds one bit of 64
//! pixels) and every multi-bit operation micro-cycle by micro-cycle through one-bit serial adders
//! with their carries, as the bit-serial pixel processors do.
//!
//! The QEE's three streams (x-tree, y-tree, cross stage; see [`crate::qee`]) arrive one bit-plane
//! per cycle, least significant bit first, and each pixel adds them with two serial adders before
//! its ALU consumes the sum. The host runs a QEE command on *blocks* of words, four rows by one or
//! more groups, each block through all of the command's micro-cycles before the next, with the
//! carries of its adders in registers and one loop per kind of result (the blocks are
//! independent, so their order changes nothing but the host's work). The x-tree's planes are
//! built once per command; the cross stage's planes Z(x, y) = (E y) x move from row to row by the
//! tree's own recurrence, Z(x, y + 4) = Z(x, y) + 4 E x, one bit-sliced add per plane. A block's
//! four rows are the lanes of one host vector value (`Rows`): the QEE loops are compiled twice,
//! once with AVX2 (one 256-bit instruction per operation on 256 pixels) and once portable, and
//! [`pulp`] picks the build the CPU can run when the engine is made. Both give the same bits,
//! as a test checks, and our code holds no `unsafe`.

use super::{Geometry, PixelEngine, QeeSink, Registers, gated};
use crate::command::{Anf, Bit, Cmp, Field, LogicOp, Rect};
use crate::qee::{Streams, Window};
use wide::u64x2;

/// Bit-plane pixel memory and the shared one-bit registers.
pub struct BitEngine {
    geometry: Geometry,
    /// `memory_bits` planes of `geometry.groups` u64s (one per group), plane-major.
    planes: Vec<u64>,
    regs: Registers,
    scratch: Scratch,
    /// The host's vector instructions the QEE loops run with: AVX2 where the CPU has it (found
    /// once, at construction), else the portable build. Both give the same bits.
    arch: pulp::Arch,
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
            arch: pulp::Arch::new(),
        }
    }

    /// This engine with its QEE loops in the portable build whatever the host has: what the
    /// tests compare the vector build with.
    #[cfg(test)]
    fn portable(mut self) -> BitEngine {
        self.arch = pulp::Arch::Scalar;
        self
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

    fn read_values(&self, field: Field, rect: Rect, out: &mut Vec<u64>) {
        let per_row = self.geometry.groups_per_row;
        out.clear();
        out.reserve((rect.width * rect.height) as usize);
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
    }
}

/// Rows per block: the rows of a block share the x-tree's planes and the step of the cross
/// stage, and each has its own row stream. Four u64s fill one 256-bit host vector register where
/// the host has AVX2 (see [`BitEngine::qee`]), two 128-bit ones elsewhere.
const ROWS: usize = 4;

/// One word of each row of a block (the same group column), side by side: every operation is
/// the same on each lane, so the compiler makes it one vector instruction for all the rows.
#[derive(Clone, Copy, Default, PartialEq, Eq)]
#[repr(align(32))]
struct Rows([u64; ROWS]);

impl Rows {
    #[inline(always)]
    fn splat(v: u64) -> Rows {
        Rows([v; ROWS])
    }

    #[inline(always)]
    fn lanes(self) -> [u64; ROWS] {
        self.0
    }

    /// `op` on each lane of `self` and `o`.
    #[inline(always)]
    fn zip(self, o: Rows, op: impl Fn(u64, u64) -> u64) -> Rows {
        let mut v = self.0;
        for (a, b) in v.iter_mut().zip(o.0) {
            *a = op(*a, b);
        }
        Rows(v)
    }
}

impl std::ops::BitAnd for Rows {
    type Output = Rows;
    #[inline(always)]
    fn bitand(self, o: Rows) -> Rows {
        self.zip(o, |a, b| a & b)
    }
}

impl std::ops::BitOr for Rows {
    type Output = Rows;
    #[inline(always)]
    fn bitor(self, o: Rows) -> Rows {
        self.zip(o, |a, b| a | b)
    }
}

impl std::ops::BitXor for Rows {
    type Output = Rows;
    #[inline(always)]
    fn bitxor(self, o: Rows) -> Rows {
        self.zip(o, |a, b| a ^ b)
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
    /// The cross stage's planes, Z(x, y) = (E y) x, for the rows from `cross_row`.
    cross: Vec<Rows>,
    /// The planes of E x, group column c's plane j at `c * 64 + j`: Z's step from a row to the next.
    ex: Vec<u64>,
    /// Z's step from one block of rows to the next, Z(x, y + ROWS) - Z(x, y) = ROWS E x.
    step: Vec<Rows>,
    /// The first row whose Z `cross` holds, per group column (`usize::MAX`: none yet).
    cross_row: Vec<usize>,
    /// Which groups of the current block of rows the command may change (row-major).
    lanes: Vec<bool>,
}

/// How many blocks of rows a group column's cross planes may be stepped forward instead of being
/// built afresh (a step is one bit-sliced add per plane; a fresh build a 64 x 64 transpose and an
/// add, which cost about as much as this many steps).
const MAX_STEPS: usize = 4;

/// The 64 bit-planes of `values(i)` for the pixels i = 0..64 of a group, plane j into
/// `set(j, plane)`. Inlined, so that its loops take the QEE build's vector instructions.
#[inline(always)]
fn planes_of(values: impl Fn(usize) -> i64, mut set: impl FnMut(usize, u64)) {
    let mut m = [0u64; 64];
    for (i, v) in m.iter_mut().enumerate() {
        *v = values(i) as u64;
    }
    transpose64_pairs(&mut m);
    for (j, &p) in m.iter().enumerate() {
        set(j, p);
    }
}

/// [`super::transpose64`] two rows at a time, one host vector register per pair: the same block swaps,
/// the last round (neighbouring rows) done across two registers' lanes.
fn transpose64_pairs(m: &mut [u64; 64]) {
    let mut v: [u64x2; 32] = std::array::from_fn(|k| u64x2::new([m[2 * k], m[2 * k + 1]]));
    let mut s = 32u32;
    let mut mask: u64 = 0x0000_0000_FFFF_FFFF;
    while s >= 2 {
        let (vs, mv) = (s as usize / 2, u64x2::splat(mask));
        for k in (0..32).step_by(2 * vs) {
            for i in k..k + vs {
                let t = ((v[i] >> s) ^ v[i + vs]) & mv;
                v[i] ^= t << s;
                v[i + vs] ^= t;
            }
        }
        s >>= 1;
        mask ^= mask << s;
    }
    let mv = u64x2::splat(mask);
    for k in (0..32).step_by(2) {
        // Even rows in one register, odd rows in the other.
        let (even, odd) = (v[k].unpack_lo(v[k + 1]), v[k].unpack_hi(v[k + 1]));
        let t = ((even >> 1u32) ^ odd) & mv;
        let (even, odd) = (even ^ (t << 1u32), odd ^ t);
        v[k] = even.unpack_lo(odd);
        v[k + 1] = even.unpack_hi(odd);
    }
    for (k, p) in v.iter().enumerate() {
        [m[2 * k], m[2 * k + 1]] = p.to_array();
    }
}

/// The tree's streams into `N` of the `G` group columns of a block column, from column `c0`,
/// and the carries of the pixels' two stream adders.
struct BlockStream<'a, const G: usize, const N: usize, const CROSS: bool> {
    /// The x-tree's planes of the block's group columns.
    col: &'a [Words<G>],
    /// The cross stage's planes for the block's rows, advanced in place to the next block of
    /// rows as they are used.
    cross: &'a mut [Words<G>],
    step: &'a [Words<G>],
    c0: usize,
    /// Y(y) of each row: bit j goes to every pixel of the row at micro-cycle j.
    rows: [u64; ROWS],
    /// Carries of the x + y adder, the (x + y) + z adder, and the cross stage's row step.
    c1: Words<N>,
    c2: Words<N>,
    c_step: Words<N>,
}

impl<'a, const G: usize, const N: usize, const CROSS: bool> BlockStream<'a, G, N, CROSS> {
    /// Micro-cycles `from .. to`, each one's bit of every pixel's V handed to `f` with its
    /// cycle number.
    #[inline(always)]
    fn run(&mut self, from: usize, to: usize, mut f: impl FnMut(usize, Words<N>)) {
        // Bit j of each row's stream, spread over the row's word: 0 - ((y >> j) & 1).
        let mut rest = Rows(self.rows.map(|y| y.checked_shr(from as u32).unwrap_or(0)));
        let mut row_bits = || {
            let bits = Rows(rest.0.map(|y| (y & 1).wrapping_neg()));
            rest = Rows(rest.0.map(|y| y >> 1));
            bits
        };
        let c0 = self.c0;
        let col = &self.col[from..to];
        if CROSS {
            let planes = col
                .iter()
                .zip(&mut self.cross[from..to])
                .zip(&self.step[from..to]);
            for (j, ((x, z), d)) in (from..).zip(planes) {
                let y = row_bits();
                let mut v = [Rows::default(); N];
                for c in 0..N {
                    let s1 = add_rows(x[c0 + c], y, &mut self.c1[c]);
                    let zc = z[c0 + c];
                    // The cross stage moves on to the next rows while these are consumed:
                    // Z(x, y + ROWS) = Z(x, y) + ROWS E x, one plane per cycle with its carry.
                    z[c0 + c] = add_rows(zc, d[c0 + c], &mut self.c_step[c]);
                    v[c] = add_rows(s1, zc, &mut self.c2[c]);
                }
                f(j, v);
            }
        } else {
            for (j, x) in (from..).zip(col) {
                let y = row_bits();
                let mut v = [Rows::default(); N];
                for c in 0..N {
                    v[c] = add_rows(x[c0 + c], y, &mut self.c1[c]);
                }
                f(j, v);
            }
        }
    }
}

/// One block's place: its first row and group column, the words the command may change (bit
/// `c * ROWS + r` for column c, row r), their enables (0 where it may not).
#[derive(Clone, Copy)]
struct Block<const N: usize> {
    py: usize,
    cx: usize,
    lanes: u32,
    en: [[u64; ROWS]; N],
}

impl<const N: usize> Block<N> {
    #[inline(always)]
    fn changes(&self, c: usize, r: usize) -> bool {
        self.lanes >> (c * ROWS + r) & 1 != 0
    }
}

/// One QEE command's streams as bit-planes, and what it does, for [`BitEngine::qee_block`].
struct QeeCommand<'a> {
    s: &'a Streams,
    window: Window,
    sink: QeeSink,
}

/// One QEE command's run, for [`pulp::Arch::dispatch`]: its body is compiled once per instruction
/// set the dispatch can choose (everything it calls in the block loops is `#[inline(always)]`, so
/// the lanes of [`Rows`] become AVX2 instructions in the AVX2 build).
struct QeeRun<'a, const G: usize, const CROSS: bool> {
    engine: &'a mut BitEngine,
    s: &'a Streams,
    window: Window,
    sink: QeeSink,
    active: &'a [u32],
}

impl<const G: usize, const CROSS: bool> pulp::WithSimd for QeeRun<'_, G, CROSS> {
    type Output = ();

    #[inline(always)]
    fn with_simd<S: pulp::Simd>(self, _: S) {
        let QeeRun {
            engine,
            s,
            window,
            sink,
            active,
        } = self;
        engine.qee_run::<G, CROSS>(s, window, sink, active)
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
        let arch = self.arch;
        let engine = self;
        if s.cross {
            arch.dispatch(QeeRun::<G, true> {
                engine,
                s,
                window,
                sink,
                active,
            })
        } else {
            arch.dispatch(QeeRun::<G, false> {
                engine,
                s,
                window,
                sink,
                active,
            })
        }
    }

    #[inline(always)]
    fn qee_run<const G: usize, const CROSS: bool>(
        &mut self,
        s: &Streams,
        window: Window,
        sink: QeeSink,
        active: &[u32],
    ) {
        let gpr = self.geometry.groups_per_row;
        let mut sc = std::mem::take(&mut self.scratch);
        // Group column c's plane j at entry (c / G * 64 + j) * G + c % G.
        let at = |c: usize, j: usize| (c / G * 64 + j) * G + c % G;
        sc.col.resize(64 * gpr, Rows::default());
        for c in 0..gpr {
            planes_of(
                |i| s.col[c * 64 + i],
                |j, p| sc.col[at(c, j)] = Rows::splat(p),
            );
        }
        if CROSS {
            sc.cross.resize(64 * gpr, Rows::default());
            sc.ex.resize(64 * gpr, 0);
            sc.step.resize(64 * gpr, Rows::default());
            sc.cross_row.clear();
            sc.cross_row.resize(gpr, usize::MAX);
            for c in 0..gpr {
                let x = |i: usize| s.origin_x + (c * 64 + i) as i64;
                planes_of(|i| s.expr.e * x(i), |j, p| sc.ex[c * 64 + j] = p);
                // ROWS E x = (E x) << log2(ROWS): plane j is E x's plane j - log2(ROWS).
                const { assert!(ROWS.is_power_of_two()) };
                let shift = ROWS.trailing_zeros() as usize;
                for j in 0..64 {
                    sc.step[at(c, j)] = match j.checked_sub(shift) {
                        Some(k) => Rows::splat(sc.ex[c * 64 + k]),
                        None => Rows::default(),
                    };
                }
            }
        }
        sc.lanes.clear();
        sc.lanes.resize(ROWS * gpr, false);
        let cmd = QeeCommand { s, window, sink };
        let mut i = 0;
        while i < active.len() {
            // The active groups of the next block of rows.
            let py = active[i] as usize / gpr / ROWS * ROWS;
            let first = i;
            while i < active.len() && (active[i] as usize) < (py + ROWS) * gpr {
                sc.lanes[active[i] as usize - py * gpr] = true;
                i += 1;
            }
            for b in 0..gpr / G {
                // Which of the block column's group columns have a word to change.
                let mut used = 0u32;
                for c in 0..G {
                    for r in 0..ROWS {
                        if sc.lanes[r * gpr + b * G + c] {
                            used |= 1 << c;
                        }
                    }
                }
                // Every column when most are used; else each used column alone.
                if used.count_ones() as usize * 2 > G {
                    self.qee_block::<G, G, CROSS>(&cmd, &mut sc, py, b, 0);
                } else {
                    for c0 in 0..G {
                        if used >> c0 & 1 != 0 {
                            self.qee_block::<G, 1, CROSS>(&cmd, &mut sc, py, b, c0);
                        }
                    }
                }
            }
            for &g in &active[first..i] {
                sc.lanes[g as usize - py * gpr] = false;
            }
        }
        self.scratch = sc;
    }

    /// The `N` group columns from `c0` of block column `b`, rows `py ..`.
    #[inline(always)]
    #[allow(clippy::needless_range_loop)] // (c, r) index a block's words both ways
    fn qee_block<const G: usize, const N: usize, const CROSS: bool>(
        &mut self,
        cmd: &QeeCommand,
        sc: &mut Scratch,
        py: usize,
        b: usize,
        c0: usize,
    ) {
        let (gpr, height) = (self.geometry.groups_per_row, self.geometry.height);
        let cycles = cmd.window.delivered_bits() as usize;
        let cx = b * G + c0;
        let mut lanes = 0u32;
        let mut en = [[0u64; ROWS]; N];
        for c in 0..N {
            for r in 0..ROWS {
                if sc.lanes[r * gpr + cx + c] {
                    lanes |= 1 << (c * ROWS + r);
                    en[c][r] = self.regs.enable[(py + r) * gpr + cx + c];
                }
            }
        }
        let block = Block { py, cx, lanes, en };
        // A row past the array's last (an odd height) takes the last row's stream; it has no
        // active group, so nothing of it is written.
        let rows = std::array::from_fn(|r| cmd.s.row[(py + r).min(height - 1)] as u64);
        let (col, _) = sc.col[b * 64 * G..][..cycles * G].as_chunks::<G>();
        let mut st = BlockStream::<G, N, CROSS> {
            col,
            cross: &mut [],
            step: &[],
            c0,
            rows,
            c1: [Rows::default(); N],
            c2: [Rows::default(); N],
            c_step: [Rows::default(); N],
        };
        if CROSS {
            let (step, _) = sc.step[b * 64 * G..][..cycles * G].as_chunks::<G>();
            let (cross, _) = sc.cross[b * 64 * G..][..cycles * G].as_chunks_mut::<G>();
            for c in c0..c0 + N {
                let from = sc.cross_row[b * G + c];
                if from <= py && py - from <= MAX_STEPS * ROWS {
                    // Catch up from the rows these planes hold.
                    for _ in (from..py).step_by(ROWS) {
                        let mut carry = Rows::default();
                        for (p, d) in cross.iter_mut().zip(step) {
                            p[c] = add_rows(p[c], d[c], &mut carry);
                        }
                    }
                } else {
                    // Afresh: Z of the first row, then of each next one by adding E x.
                    let px = (b * G + c) * 64;
                    let mut first = [0u64; 64];
                    planes_of(|i| cmd.s.cross_at(px + i, py), |j, p| first[j] = p);
                    let ex = &sc.ex[(b * G + c) * 64..][..cycles];
                    let mut carry = [0u64; ROWS];
                    for ((p, &z), &d) in cross.iter_mut().zip(&first).zip(ex) {
                        let mut lanes = [z; ROWS];
                        for r in 1..ROWS {
                            let (next, n) = full_add(lanes[r - 1], d, carry[r]);
                            carry[r] = n;
                            lanes[r] = next;
                        }
                        p[c] = Rows(lanes);
                    }
                }
                sc.cross_row[b * G + c] = py + ROWS;
            }
            st.cross = cross;
            st.step = step;
            self.run_block(st, cmd.window, cmd.sink, block);
        } else {
            self.run_block(st, cmd.window, cmd.sink, block);
        }
    }

    /// One block through the sink's micro-cycles.
    #[inline(always)]
    fn run_block<const G: usize, const N: usize, const CROSS: bool>(
        &mut self,
        mut st: BlockStream<'_, G, N, CROSS>,
        window: Window,
        sink: QeeSink,
        block: Block<N>,
    ) {
        let (shift, cycles) = (window.shift as usize, window.delivered_bits() as usize);
        match sink {
            QeeSink::Sign { dst, combine } => {
                // Only the window's top bit is used; the micro-cycles below it only carry.
                st.run(0, cycles - 1, |_, _| {});
                let mut last = [[0u64; ROWS]; N];
                st.run(cycles - 1, cycles, |_, v| last = v.map(Rows::lanes));
                self.combine_words(dst, combine.anf(), block, last.map(|w| w.map(|v| !v)));
            }
            QeeSink::Store { dst } => {
                st.run(0, shift, |_, _| {});
                st.run(shift, cycles, |j, v| {
                    let v = v.map(Rows::lanes);
                    self.for_words(dst, (j - shift) as u32, block, |c, r, p| {
                        *p = gated(*p, block.en[c][r], v[c][r])
                    });
                });
            }
            QeeSink::Add { dst } => {
                st.run(0, shift, |_, _| {});
                let mut carry = [[0u64; ROWS]; N];
                st.run(shift, cycles, |j, v| {
                    let v = v.map(Rows::lanes);
                    self.for_words(dst, (j - shift) as u32, block, |c, r, p| {
                        let (sum, n) = full_add(*p, v[c][r], carry[c][r]);
                        carry[c][r] = n;
                        *p = gated(*p, block.en[c][r], sum);
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
                let mut carry = [[u64::MAX; ROWS]; N];
                let mut differs = [[0u64; ROWS]; N];
                let mut last = [[0u64; ROWS]; N];
                st.run(shift, cycles, |j, v| {
                    let v = v.map(Rows::lanes);
                    let top = j == cycles - 1;
                    self.for_words(field, (j - shift) as u32, block, |c, r, p| {
                        let (x, y, carry) = (v[c][r], *p, &mut carry[c][r]);
                        differs[c][r] |= x ^ y;
                        let (d, n) = full_add(x, !y, *carry);
                        *carry = n;
                        last[c][r] = d;
                        if top {
                            // One more ALU cycle on the extension bits (covered by alu_setup):
                            // the difference needs bits + 1 bits to keep its sign.
                            let (ext, rext) = if field.signed { (x, y) } else { (0, 0) };
                            last[c][r] = full_add(ext, !rext, *carry).0;
                        }
                    });
                });
                let mut value = [[0u64; ROWS]; N];
                for c in 0..N {
                    for r in 0..ROWS {
                        value[c][r] = cmp.from_lt_eq(last[c][r], !differs[c][r]);
                    }
                }
                self.combine_words(dst, combine.anf(), block, value);
            }
        }
    }

    /// `f` on bit `k` of field `field` of each word of the block the command may change.
    #[inline(always)]
    fn for_words<const N: usize>(
        &mut self,
        field: Field,
        k: u32,
        block: Block<N>,
        mut f: impl FnMut(usize, usize, &mut u64),
    ) {
        let gpr = self.geometry.groups_per_row;
        let plane = (field.offset + k) as usize * self.geometry.groups;
        for c in 0..N {
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
    #[inline(always)]
    #[allow(clippy::needless_range_loop)] // (c, r) index a block's words both ways
    fn combine_words<const N: usize>(
        &mut self,
        dst: Bit,
        combine: Anf,
        block: Block<N>,
        values: [[u64; ROWS]; N],
    ) {
        let gpr = self.geometry.groups_per_row;
        for r in 0..ROWS.min(self.geometry.height - block.py) {
            let row: [u64; N] = std::array::from_fn(|c| values[c][r]);
            let start = (block.py + r) * gpr + block.cx;
            self.regs.combine_run(dst, start, &row, combine);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::engine::transpose64;

    /// The vector build (AVX2, where this host has it) and the portable build of the QEE loops
    /// leave the same pixel memory and registers after every kind of QEE command: linear and
    /// quadratic, with and without the cross stage, on rows of one, two and four groups and on
    /// heights that leave a partial block of rows. On a host without AVX2 both engines run the
    /// portable build (the bit-against-integer properties then cover it).
    #[test]
    fn the_vector_build_matches_the_portable_one() {
        use crate::qee::QeeExpr;
        let mut rng = pxpl5_geom::rng::Lcg::new(0x005E_ED0F_B175);
        let field = |offset, bits, signed| Field {
            offset,
            bits,
            signed,
        };
        for (width, height) in [(64, 7), (128, 9), (256, 6)] {
            let geometry = Geometry::new(width, height);
            for trial in 0..24 {
                let mut vector = BitEngine::new(geometry, 208, 2);
                for p in vector.planes.iter_mut() {
                    *p = rng.next_u64();
                }
                for (g, en) in vector.regs.enable.iter_mut().enumerate() {
                    // Some groups wholly disabled, so that blocks have partial lanes.
                    *en = if (g + trial) % 3 == 0 {
                        0
                    } else {
                        rng.next_u64()
                    };
                }
                // Where the host has AVX2 and the rest of x86-64-v3, the engine must have
                // chosen that build, or this test would compare the portable build with itself.
                #[cfg(target_arch = "x86_64")]
                assert_eq!(
                    matches!(vector.arch, pulp::Arch::V3(_)),
                    pulp::x86::V3::try_new().is_some(),
                    "the vector build is not the one the host can run"
                );
                let mut portable = BitEngine::new(geometry, 208, 2).portable();
                portable.planes = vector.planes.clone();
                portable.regs = vector.regs.clone();
                let mut c = || rng.below(2001) as i64 - 1000;
                let raw = [c(), c(), c(), c(), c(), c()];
                // Each sink (trial % 4) in turn linear and quadratic (the cross stage where
                // E != 0), as trial / 4 alternates.
                let raw = if trial / 4 % 2 == 0 {
                    [raw[0], raw[1], raw[2], 0, 0, 0]
                } else {
                    raw
                };
                let expr = QeeExpr::from_raw(raw);
                let origin = (trial as u32 * 3, trial as u32 * 5);
                let streams = Streams::new(&expr, origin, width as usize, height as usize);
                let sign = expr.sign_window(origin, width, height);
                let window = Window {
                    shift: trial as u32 % 4,
                    bits: 12,
                };
                let (sink, window) = match trial % 4 {
                    0 => (
                        QeeSink::Sign {
                            dst: Bit::Flag(0),
                            combine: LogicOp::AND,
                        },
                        sign,
                    ),
                    1 => (
                        QeeSink::Store {
                            dst: field(20, 12, true),
                        },
                        window,
                    ),
                    2 => (
                        QeeSink::Add {
                            dst: field(40, 12, false),
                        },
                        window,
                    ),
                    _ => (
                        QeeSink::Compare {
                            field: field(60, 12, trial % 8 == 3),
                            cmp: Cmp::Le,
                            dst: Bit::Enable,
                            combine: LogicOp::OR,
                        },
                        window,
                    ),
                };
                let mut active = Vec::new();
                vector.regs.enabled_groups(&mut active);
                vector.qee(&streams, window, sink, &active);
                portable.qee(&streams, window, sink, &active);
                assert!(
                    vector.planes == portable.planes && vector.regs == portable.regs,
                    "{width} x {height}, trial {trial}: {sink:?} differs"
                );
            }
        }
    }

    #[test]
    fn pairwise_transpose_matches_the_shared_one() {
        let mut rng = pxpl5_geom::rng::Lcg::new(0x0123_4567_89AB_CDEF);
        for _ in 0..8 {
            let mut m = [0u64; 64];
            for v in m.iter_mut() {
                *v = rng.next_u64();
            }
            let mut expected = m;
            transpose64(&mut expected);
            transpose64_pairs(&mut m);
            assert_eq!(m, expected);
        }
    }
}
