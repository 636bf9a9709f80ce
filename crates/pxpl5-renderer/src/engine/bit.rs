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

    /// The 64 planes of the x-tree stream for each group position `cg` along a row.
    fn column_planes(&self, s: &Streams) -> Vec<[u64; 64]> {
        (0..self.geometry.groups_per_row)
            .map(|cg| {
                let mut m = [0u64; 64];
                for (i, v) in m.iter_mut().enumerate() {
                    *v = s.col[cg * 64 + i] as u64;
                }
                transpose64(&mut m);
                m
            })
            .collect()
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
        let cols = self.column_planes(s);
        let cycles = window.delivered_bits();
        // The cross stage's stream (E y) x = (E y) x0 + (E y) i for column i of a 64-pixel group
        // starting at x0: its planes of (E y) i are the same for every group of a row, so they
        // are built once per row, and (E y) x0 enters with the row stream (the same integer sum,
        // so the same bits).
        let mut cross = [0u64; 64];
        let mut cross_row = usize::MAX;
        for &g in active {
            let g = g as usize;
            let (py, px0) = self.geometry.group_origin(g);
            let col = &cols[px0 / 64];
            let mut row = s.row[py] as u64;
            if s.cross {
                if cross_row != py {
                    for (i, v) in cross.iter_mut().enumerate() {
                        *v = (s.e_row[py] * i as i64) as u64;
                    }
                    transpose64(&mut cross);
                    cross_row = py;
                }
                row = row.wrapping_add((s.e_row[py] * (s.origin_x + px0 as i64)) as u64);
            }
            let en = self.regs.enable[g];
            // Carries of the pixels' two stream adders and of the ALU.
            let (mut c1, mut c2) = (0u64, 0u64);
            let mut alu_carry = match sink {
                // lhs - rhs = lhs + !rhs + 1.
                QeeSink::Compare { .. } => u64::MAX,
                _ => 0,
            };
            let mut differs = 0u64;
            let mut last = 0u64;
            for j in 0..cycles {
                let row_bit = ((row >> j) & 1).wrapping_neg();
                let (s1, n1) = full_add(col[j as usize], row_bit, c1);
                c1 = n1;
                let v = if s.cross {
                    let (s2, n2) = full_add(s1, cross[j as usize], c2);
                    c2 = n2;
                    s2
                } else {
                    s1
                };
                if j < window.shift {
                    continue;
                }
                let k = j - window.shift;
                match sink {
                    QeeSink::Sign { .. } => last = v,
                    QeeSink::Store { dst } => self.write(dst, k, g, v, en),
                    QeeSink::Add { dst } => {
                        let (sum, c) = full_add(self.bit(dst, k, g), v, alu_carry);
                        alu_carry = c;
                        self.write(dst, k, g, sum, en);
                    }
                    QeeSink::Compare { field, .. } => {
                        let r = self.bit(field, k, g);
                        let (d, c) = full_add(v, !r, alu_carry);
                        alu_carry = c;
                        differs |= v ^ r;
                        last = d;
                        if k == window.bits - 1 {
                            // One more ALU cycle on the extension bits (covered by alu_setup):
                            // the difference needs bits + 1 bits to keep its sign.
                            let ext = if field.signed { v } else { 0 };
                            let rext = if field.signed { r } else { 0 };
                            let (d, _) = full_add(ext, !rext, alu_carry);
                            last = d;
                        }
                    }
                }
            }
            match sink {
                QeeSink::Sign { dst, combine } => self.regs.combine(dst, g, !last, combine),
                QeeSink::Compare {
                    cmp, dst, combine, ..
                } => self
                    .regs
                    .combine(dst, g, cmp.from_lt_eq(last, !differs), combine),
                QeeSink::Store { .. } | QeeSink::Add { .. } => {}
            }
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
