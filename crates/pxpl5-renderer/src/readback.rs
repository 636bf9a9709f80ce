//! The packing of read-back pixels into ring words.
//!
//! A readback sends a field of a rectangle of pixels, row by row (array row `rect.y` first, then
//! upward; each row left to right),
//! as ring words of `word_bits` bits (\[seed\]: 32):
//!
//! - a field of `bits <= word_bits` packs `k = floor(word_bits / bits)` pixels per word, pixel i of
//!   the stream in bits `(i mod k) * bits ..` of word `i / k`, least significant first; the last
//!   word is padded with zeros. A 16-bit patch ID thus costs half a word per pixel;
//! - a wider field takes `ceil(bits / word_bits)` words per pixel, least significant word first.
//!
//! \[assumed\]: the real IGC's readback format is not published; this is the densest packing that
//! keeps every pixel inside whole words for narrow fields.

use crate::qee::mask;

/// Ring words carrying `values` (raw `bits`-bit field values) at `word_bits` bits per word.
pub fn pack(values: &[u64], bits: u32, word_bits: u32) -> Vec<u64> {
    if bits <= word_bits {
        let k = (word_bits / bits) as usize;
        values
            .chunks(k)
            .map(|chunk| {
                chunk.iter().enumerate().fold(0u64, |w, (i, &v)| {
                    w | ((v & mask(bits)) << (i as u32 * bits))
                })
            })
            .collect()
    } else {
        let per = bits.div_ceil(word_bits);
        values
            .iter()
            .flat_map(|&v| (0..per).map(move |j| (v >> (j * word_bits)) & mask(word_bits)))
            .collect()
    }
}

/// The inverse of [`pack`] for `count` pixels.
pub fn unpack(words: &[u64], bits: u32, word_bits: u32, count: usize) -> Vec<u64> {
    if bits <= word_bits {
        let k = (word_bits / bits) as usize;
        (0..count)
            .map(|i| (words[i / k] >> ((i % k) as u32 * bits)) & mask(bits))
            .collect()
    } else {
        let per = bits.div_ceil(word_bits) as usize;
        (0..count)
            .map(|i| {
                (0..per).fold(0u64, |v, j| {
                    v | (words[i * per + j] << (j as u32 * word_bits))
                })
            })
            .collect()
    }
}

/// Ring words a readback of `pixels` pixels of a `bits`-bit field needs.
pub fn words_needed(pixels: usize, bits: u32, word_bits: u32) -> usize {
    if bits <= word_bits {
        pixels.div_ceil((word_bits / bits) as usize)
    } else {
        pixels * bits.div_ceil(word_bits) as usize
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn narrow_fields_share_words() {
        let w = pack(&[0x1234, 0xABCD, 0x0F0F], 16, 32);
        assert_eq!(w, vec![0xABCD_1234, 0x0F0F]);
        assert_eq!(unpack(&w, 16, 32, 3), vec![0x1234, 0xABCD, 0x0F0F]);
        // 10-bit fields: three per 32-bit word, two bits of padding.
        let v: Vec<u64> = (0..7).map(|i| 1000 - i).collect();
        let w = pack(&v, 10, 32);
        assert_eq!(w.len(), 3);
        assert_eq!(words_needed(7, 10, 32), 3);
        assert_eq!(unpack(&w, 10, 32, 7), v);
    }

    #[test]
    fn wide_fields_span_words() {
        let w = pack(&[0x1_2345_6789], 40, 32);
        assert_eq!(w, vec![0x2345_6789, 0x1]);
        assert_eq!(unpack(&w, 40, 32, 1), vec![0x1_2345_6789]);
        assert_eq!(words_needed(5, 40, 32), 10);
    }
}
