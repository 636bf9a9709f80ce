//! The IGC command set: what a GP sends a Renderer, and the operands commands name.
//!
//! The Image Generation Controller (IGC, [assumed] name and role) turns each command into SIMD
//! micro-instructions for the 128 x 128 pixel processors and coefficient bit streams for the QEE.
//! Commands name pixel memory by [`Field`] (a bit offset and a width, as the real machine's
//! instructions carry addresses) and one-bit registers by [`Bit`].
//!
//! **Enable.** Every write to pixel memory or to a flag register happens only at pixels whose
//! enable register is 1. Writes to the enable register itself are not gated (otherwise a disabled
//! pixel could never be enabled again). Backing-store transfers and readback move every pixel.

use crate::qee::{QeeExpr, Window};

/// An n-bit field of pixel memory: bits `offset .. offset + bits` of every pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Field {
    pub offset: u32,
    pub bits: u32,
    /// Whether arithmetic reads the field as two's complement (sign-extends it) or unsigned.
    pub signed: bool,
}

/// The fields one command names ([`Command::fields`]): at most three, in order, as a slice.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Fields {
    len: usize,
    fields: [Field; 3],
}

impl Fields {
    /// `N` fields, known when compiled, so that listing them is a few moves and no copy of a
    /// slice of run-time length (a call to `memcpy`: 40 instructions a command).
    fn of<const N: usize>(named: [Field; N]) -> Fields {
        let none = Field {
            offset: 0,
            bits: 0,
            signed: false,
        };
        let mut fields = [none; 3];
        fields[..N].copy_from_slice(&named);
        Fields { len: N, fields }
    }
}

impl std::ops::Deref for Fields {
    type Target = [Field];

    fn deref(&self) -> &[Field] {
        &self.fields[..self.len]
    }
}

impl IntoIterator for Fields {
    type Item = Field;
    type IntoIter = std::iter::Take<std::array::IntoIter<Field, 3>>;

    fn into_iter(self) -> Self::IntoIter {
        self.fields.into_iter().take(self.len)
    }
}

impl Field {
    pub fn end(self) -> u32 {
        // Saturating: a command may carry any offset, and a field ending past u32::MAX lies
        // outside pixel memory all the same (the board's validation says so).
        self.offset.saturating_add(self.bits)
    }

    /// Whether the two fields share any bit.
    pub fn overlaps(self, other: Field) -> bool {
        self.offset < other.end() && other.offset < self.end()
    }

    /// Whether the fields share bits without being the same bits: a bit-serial operation would
    /// read bits it has already written, so the command set forbids it.
    pub fn overlaps_partially(self, other: Field) -> bool {
        self.overlaps(other) && (self.offset != other.offset || self.bits != other.bits)
    }
}

/// A one-bit register of every pixel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Bit {
    /// The enable register.
    Enable,
    /// One of the configured flag registers.
    Flag(u8),
}

/// Any boolean function of two bits, as its truth table: bit `(a << 1) | b` of the table is the
/// result for inputs a, b. One ALU step (\[assumed\] 1 cycle, `cycles.logic`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct LogicOp(pub u8);

impl LogicOp {
    pub const ZERO: LogicOp = LogicOp(0b0000);
    pub const ONE: LogicOp = LogicOp(0b1111);
    pub const AND: LogicOp = LogicOp(0b1000);
    pub const OR: LogicOp = LogicOp(0b1110);
    pub const XOR: LogicOp = LogicOp(0b0110);
    /// a (copy the first input).
    pub const A: LogicOp = LogicOp(0b1100);
    /// b (copy the second input).
    pub const B: LogicOp = LogicOp(0b1010);
    pub const NOT_B: LogicOp = LogicOp(0b0101);
    /// a AND NOT b.
    pub const AND_NOT: LogicOp = LogicOp(0b0100);
    /// a OR NOT b.
    pub const OR_NOT: LogicOp = LogicOp(0b1101);

    /// The function applied to 64 pixels at once.
    #[inline]
    pub fn apply(self, a: u64, b: u64) -> u64 {
        self.anf().apply(a, b)
    }

    /// The truth table in algebraic normal form, f = c0 ^ c1 b ^ c2 a ^ c3 a b over GF(2)
    /// (c0 = t0, c1 = t0 ^ t1, c2 = t0 ^ t2, c3 = t0 ^ t1 ^ t2 ^ t3), each coefficient an
    /// all-ones or all-zeros mask: no branch, and seven operations where the sum of minterms
    /// took thirteen, so a loop over groups with a fixed op runs straight through.
    #[inline]
    pub fn anf(self) -> Anf {
        let t = |k: u8| u64::from((self.0 >> k) & 1);
        let m = |bit: u64| 0u64.wrapping_sub(bit);
        let (t0, t1, t2, t3) = (t(0), t(1), t(2), t(3));
        Anf([m(t0), m(t0 ^ t1), m(t0 ^ t2), m(t0 ^ t1 ^ t2 ^ t3)])
    }

    /// Whether the result is 0 whenever a is 0: a combine op with this property leaves a pixel
    /// whose old value is 0 at 0, which lets the engines skip such pixels.
    pub fn keeps_zero(self) -> bool {
        self.0 & 0b0011 == 0
    }
}

/// A [`LogicOp`] in algebraic normal form ([`LogicOp::anf`]): for a caller that applies one op
/// to many words across calls, so the form is found once.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Anf([u64; 4]);

impl Anf {
    #[inline]
    pub fn apply(self, a: u64, b: u64) -> u64 {
        anf(self.0, a, b)
    }

    /// [`Anf::apply`] on two words at once, each u128 holding two.
    #[inline]
    pub fn apply_wide(self, a: u128, b: u128) -> u128 {
        anf(self.0.map(|c| u128::from(c) | (u128::from(c) << 64)), a, b)
    }
}

/// The algebraic normal form `c0 ^ c1 b ^ c2 a ^ c3 a b` on words of any width: the one home of
/// the formula [`Anf::apply`] and [`Anf::apply_wide`] share.
#[inline(always)]
fn anf<T>([c0, c1, c2, c3]: [T; 4], a: T, b: T) -> T
where
    T: Copy + std::ops::BitAnd<Output = T> + std::ops::BitXor<Output = T>,
{
    c0 ^ (c1 & b) ^ (c2 & a) ^ (c3 & a & b)
}

/// A comparison of two values, `lhs cmp rhs`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Cmp {
    Lt,
    Le,
    Gt,
    Ge,
    Eq,
    Ne,
}

impl Cmp {
    pub const ALL: [Cmp; 6] = [Cmp::Lt, Cmp::Le, Cmp::Gt, Cmp::Ge, Cmp::Eq, Cmp::Ne];

    /// The result from the two facts a serial subtract yields: lhs < rhs and lhs == rhs.
    #[inline]
    pub fn from_lt_eq(self, lt: u64, eq: u64) -> u64 {
        match self {
            Cmp::Lt => lt,
            Cmp::Le => lt | eq,
            Cmp::Gt => !(lt | eq),
            Cmp::Ge => !lt,
            Cmp::Eq => eq,
            Cmp::Ne => !eq,
        }
    }

    pub fn holds(self, lhs: i128, rhs: i128) -> bool {
        match self {
            Cmp::Lt => lhs < rhs,
            Cmp::Le => lhs <= rhs,
            Cmp::Gt => lhs > rhs,
            Cmp::Ge => lhs >= rhs,
            Cmp::Eq => lhs == rhs,
            Cmp::Ne => lhs != rhs,
        }
    }
}

/// A rectangle of the array: columns `x .. x + width`, rows `y .. y + height`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Rect {
    pub x: u32,
    pub y: u32,
    pub width: u32,
    pub height: u32,
}

/// One IGC command. Cycle costs are given by [`crate::cycle_cost`]; effects by the variant docs.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub enum Command {
    /// Load the region origin: pixel (px, py) of the array has QEE address (x + px, y + py).
    SetOrigin { x: u32, y: u32 },
    /// `dst := op(a, b)`.
    Logic {
        dst: Bit,
        a: Bit,
        b: Bit,
        op: LogicOp,
    },
    /// `dst := combine(dst, W >= 0)`, W the window of the expression read as signed.
    QeeSign {
        expr: QeeExpr,
        window: Window,
        dst: Bit,
        combine: LogicOp,
    },
    /// `dst := W` (window width equals the field's).
    QeeStore {
        expr: QeeExpr,
        window: Window,
        dst: Field,
    },
    /// `dst := combine(dst, W cmp field)`, W read with the field's signedness (same width).
    QeeCompare {
        expr: QeeExpr,
        window: Window,
        field: Field,
        cmp: Cmp,
        dst: Bit,
        combine: LogicOp,
    },
    /// `dst := dst + W` modulo 2^bits (same width).
    QeeAdd {
        expr: QeeExpr,
        window: Window,
        dst: Field,
    },
    /// `dst := value` (value must fit the field's bits, as raw bits).
    WriteConst { dst: Field, value: u64 },
    /// `dst := src`, extended by src's signedness or cut to dst's width.
    Copy { dst: Field, src: Field },
    /// `dst := a + b` modulo 2^dst.bits, operands extended by their signedness.
    Add { dst: Field, a: Field, b: Field },
    /// `dst := a - b` modulo 2^dst.bits, operands extended by their signedness.
    Sub { dst: Field, a: Field, b: Field },
    /// `dst := combine(dst, a cmp b)`, exact whatever the widths and signedness.
    Compare {
        a: Field,
        b: Field,
        cmp: Cmp,
        dst: Bit,
        combine: LogicOp,
    },
    /// `dst := src * k` modulo 2^dst.bits; k is a `k_bits`-bit two's-complement constant
    /// (e.g. the polygon's C'/D' times a per-pixel stored w). dst must not overlap src.
    MulConst {
        dst: Field,
        src: Field,
        k: i64,
        k_bits: u32,
    },
    /// Copy a field to the backing store, starting at block `block`, in the background.
    Save { field: Field, block: u32 },
    /// Copy blocks of the backing store into a field, in the background.
    Load { field: Field, block: u32 },
    /// Backing-store fence: starts only once the background transfers of every `Save` and `Load`
    /// executed before it on this board have finished (the wait counts as stall, not busy), then
    /// costs `igc_overhead` cycles and changes no pixel state. It waits for nothing else: not the
    /// ring, other boards or GPs, nor the delivery of a readback's messages (earlier commands
    /// have ended anyway: a board runs one command at a time). It sends nothing, so no one outside
    /// the board can see it complete; a program that must know a batch has executed waits for a
    /// readback instead.
    Fence,
    /// Send a field of a rectangle of pixels to ring node `dest` as packed ring words
    /// (see [`crate::readback`] for the packing), with an opaque `tag` for the receiver (the
    /// frame buffer reads it as the screen position of the array's pixel (0, 0)).
    Readback {
        field: Field,
        rect: Rect,
        dest: u32,
        tag: u32,
    },
    /// Write ring data into a field of a rectangle of pixels, row by row (the inverse of a
    /// readback; not gated by enable): e.g. a per-pixel table such as the hemisphere's w.
    WritePixels {
        dst: Field,
        rect: Rect,
        values: Vec<u64>,
    },
}

impl Command {
    /// A short stable name of the command kind, for stats and traces.
    pub fn kind(&self) -> &'static str {
        Command::KINDS[self.kind_index()]
    }

    /// Every command kind's name, indexed by [`Command::kind_index`].
    pub const KINDS: [&'static str; 17] = [
        "set_origin",
        "logic",
        "qee_sign",
        "qee_store",
        "qee_compare",
        "qee_add",
        "write_const",
        "copy",
        "add",
        "sub",
        "compare",
        "mul_const",
        "save",
        "load",
        "fence",
        "readback",
        "write_pixels",
    ];

    /// The kind as a small number, for per-kind tables (host bookkeeping: cheaper than a map
    /// keyed by name).
    pub fn kind_index(&self) -> usize {
        match self {
            Command::SetOrigin { .. } => 0,
            Command::Logic { .. } => 1,
            Command::QeeSign { .. } => 2,
            Command::QeeStore { .. } => 3,
            Command::QeeCompare { .. } => 4,
            Command::QeeAdd { .. } => 5,
            Command::WriteConst { .. } => 6,
            Command::Copy { .. } => 7,
            Command::Add { .. } => 8,
            Command::Sub { .. } => 9,
            Command::Compare { .. } => 10,
            Command::MulConst { .. } => 11,
            Command::Save { .. } => 12,
            Command::Load { .. } => 13,
            Command::Fence => 14,
            Command::Readback { .. } => 15,
            Command::WritePixels { .. } => 16,
        }
    }

    /// Ring words of this command's encoding (\[assumed\]: the IGC's format is not published). One
    /// opcode word carries the kind and every small operand (field offsets and widths, flags,
    /// window, comparison, combine op); then the QEE coefficients (3 for a linear expression, 6
    /// for a quadratic), each `ceil(coefficient_bits / word_bits)` words; a constant's
    /// `ceil(bits / word_bits)` words; one more word for an origin, a multiplier, or a readback's
    /// rectangle and destination.
    pub fn words(&self, coefficient_bits: u32, word_bits: u32) -> u32 {
        self.words_of(coefficient_bits.div_ceil(word_bits), word_bits)
    }

    /// The ring words of a list of commands ([`Command::words`] each): the words a coefficient
    /// takes found once for the list, not by a division per command.
    pub fn list_words(commands: &[Command], coefficient_bits: u32, word_bits: u32) -> u32 {
        let per_coefficient = coefficient_bits.div_ceil(word_bits);
        commands
            .iter()
            .map(|c| c.words_of(per_coefficient, word_bits))
            .sum()
    }

    /// [`Command::words`] with a coefficient's words given.
    fn words_of(&self, per_coefficient: u32, word_bits: u32) -> u32 {
        1 + match self {
            Command::QeeSign { expr, .. }
            | Command::QeeStore { expr, .. }
            | Command::QeeCompare { expr, .. }
            | Command::QeeAdd { expr, .. } => {
                per_coefficient * if expr.is_quadratic() { 6 } else { 3 }
            }
            Command::WriteConst { dst, .. } => dst.bits.div_ceil(word_bits),
            Command::SetOrigin { .. } | Command::MulConst { .. } | Command::Readback { .. } => 1,
            // The rectangle, then the values packed as a readback packs them.
            Command::WritePixels { dst, values, .. } => {
                1 + crate::readback::words_needed(values.len(), dst.bits, word_bits) as u32
            }
            Command::Logic { .. }
            | Command::Copy { .. }
            | Command::Add { .. }
            | Command::Sub { .. }
            | Command::Compare { .. }
            | Command::Save { .. }
            | Command::Load { .. }
            | Command::Fence => 0,
        }
    }

    /// Whether the command can change the enable register: it is the command's destination bit.
    pub fn writes_enable(&self) -> bool {
        matches!(
            *self,
            Command::Logic {
                dst: Bit::Enable,
                ..
            } | Command::QeeSign {
                dst: Bit::Enable,
                ..
            } | Command::QeeCompare {
                dst: Bit::Enable,
                ..
            } | Command::Compare {
                dst: Bit::Enable,
                ..
            }
        )
    }

    /// Enable every pixel.
    pub fn enable_all() -> Command {
        Command::Logic {
            dst: Bit::Enable,
            a: Bit::Enable,
            b: Bit::Enable,
            op: LogicOp::ONE,
        }
    }

    /// The fields of pixel memory the command reads or writes (for backing-store interlocks),
    /// without an allocation (a `Vec` per command was a million allocations a hemicube run).
    pub fn fields(&self) -> Fields {
        match *self {
            Command::WritePixels { dst, .. } => Fields::of([dst]),
            Command::QeeStore { dst, .. } | Command::QeeAdd { dst, .. } => Fields::of([dst]),
            Command::QeeCompare { field, .. } => Fields::of([field]),
            Command::WriteConst { dst, .. } => Fields::of([dst]),
            Command::Copy { dst, src } | Command::MulConst { dst, src, .. } => {
                Fields::of([dst, src])
            }
            Command::Add { dst, a, b } | Command::Sub { dst, a, b } => Fields::of([dst, a, b]),
            Command::Compare { a, b, .. } => Fields::of([a, b]),
            Command::Save { field, .. }
            | Command::Load { field, .. }
            | Command::Readback { field, .. } => Fields::of([field]),
            Command::SetOrigin { .. }
            | Command::Logic { .. }
            | Command::QeeSign { .. }
            | Command::Fence => Fields::of([]),
        }
    }

    /// The expression and window of a QEE command.
    pub fn qee(&self) -> Option<(&QeeExpr, Window)> {
        match self {
            Command::QeeSign { expr, window, .. }
            | Command::QeeStore { expr, window, .. }
            | Command::QeeCompare { expr, window, .. }
            | Command::QeeAdd { expr, window, .. } => Some((expr, *window)),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn logic_tables() {
        let (a, b) = (0b1100u64, 0b1010u64);
        assert_eq!(LogicOp::AND.apply(a, b) & 0xF, 0b1000);
        assert_eq!(LogicOp::OR.apply(a, b) & 0xF, 0b1110);
        assert_eq!(LogicOp::XOR.apply(a, b) & 0xF, 0b0110);
        assert_eq!(LogicOp::A.apply(a, b) & 0xF, a);
        assert_eq!(LogicOp::B.apply(a, b) & 0xF, b);
        assert_eq!(LogicOp::AND_NOT.apply(a, b) & 0xF, 0b0100);
        assert_eq!(LogicOp::OR_NOT.apply(a, b) & 0xF, 0b1101);
        assert_eq!(LogicOp::ONE.apply(a, b), u64::MAX);
        assert!(LogicOp::AND.keeps_zero() && LogicOp::AND_NOT.keeps_zero());
        assert!(!LogicOp::OR.keeps_zero() && !LogicOp::B.keeps_zero());
    }

    #[test]
    fn every_op_is_its_truth_table_at_every_bit() {
        // All four input pairs in each nibble, at every bit position, for all 16 tables.
        let (a, b) = (0xCCCC_CCCC_CCCC_CCCCu64, 0xAAAA_AAAA_AAAA_AAAAu64);
        for table in 0..16u8 {
            let op = LogicOp(table);
            let want = (0..64).fold(0u64, |w, i| {
                let k = (((a >> i) & 1) << 1) | ((b >> i) & 1);
                w | (u64::from((table >> k) & 1) << i)
            });
            assert_eq!(op.apply(a, b), want, "table {table:04b}");
        }
    }

    #[test]
    fn overlap() {
        let f = |offset, bits| Field {
            offset,
            bits,
            signed: false,
        };
        assert!(f(0, 8).overlaps(f(7, 2)));
        assert!(!f(0, 8).overlaps(f(8, 2)));
        assert!(!f(0, 8).overlaps_partially(f(0, 8)));
        assert!(f(0, 8).overlaps_partially(f(0, 9)));
    }

    /// A list's words are its commands' words, with coefficients of 24, 32 and 40 bits in ring
    /// words of 16 and 32 bits: linear and quadratic expressions, a constant, a command of none.
    #[test]
    fn a_list_takes_its_commands_words() {
        let depth = Field {
            offset: 0,
            bits: 40,
            signed: true,
        };
        let window = Window { shift: 0, bits: 40 };
        let list = [
            Command::QeeStore {
                expr: QeeExpr::from_raw([1, 2, 3, 0, 0, 0]),
                window,
                dst: depth,
            },
            Command::QeeSign {
                expr: QeeExpr::from_raw([1, 2, 3, 0, 5, 0]),
                window,
                dst: Bit::Enable,
                combine: LogicOp::AND,
            },
            Command::WriteConst {
                dst: depth,
                value: 7,
            },
            Command::enable_all(),
        ];
        for (coefficient_bits, word_bits) in [(24, 16), (32, 32), (40, 32), (32, 16)] {
            let each: u32 = list
                .iter()
                .map(|c| c.words(coefficient_bits, word_bits))
                .sum();
            let per = coefficient_bits.div_ceil(word_bits);
            assert_eq!(each, 4 + 3 * per + 6 * per + 40u32.div_ceil(word_bits));
            assert_eq!(
                Command::list_words(&list, coefficient_bits, word_bits),
                each
            );
        }
    }
}
