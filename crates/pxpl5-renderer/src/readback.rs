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
//!
//! A readback leaves the board as messages of whole rows, each packed on its own (its last word
//! padded), as many rows per message as fit in `max_message_words` words and at least one
//! (\[assumed\] streaming: the output port never needs to hold a whole field). The board packs them
//! once ([`pack_messages`]); whoever consumes a message unpacks it once ([`unpack`]).

use crate::command::Rect;
use crate::qee::mask;

/// One message of a readback: the rows of `rect` it carries, packed as [`pack`] does.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ReadbackMessage {
    pub rect: Rect,
    pub words: Vec<u64>,
}

/// The messages carrying `values` (the raw `bits`-bit values of `rect`'s pixels, row by row) at
/// `word_bits` bits per word and at most `max_message_words` words per message (a row longer than
/// that still travels whole, alone).
pub fn pack_messages(
    values: &[u64],
    rect: Rect,
    bits: u32,
    word_bits: u32,
    max_message_words: u32,
) -> Vec<ReadbackMessage> {
    let width = rect.width as usize;
    let row_words = words_needed(width, bits, word_bits);
    let rows_per = (max_message_words as usize / row_words.max(1)).max(1);
    values
        .chunks(rows_per * width)
        .enumerate()
        .map(|(i, rows)| ReadbackMessage {
            rect: Rect {
                x: rect.x,
                y: rect.y + (i * rows_per) as u32,
                width: rect.width,
                height: (rows.len() / width) as u32,
            },
            words: pack(rows, bits, word_bits),
        })
        .collect()
}

/// Ring words carrying `values` (raw `bits`-bit field values) at `word_bits` bits per word.
pub fn pack(values: &[u64], bits: u32, word_bits: u32) -> Vec<u64> {
    let mut out = Vec::with_capacity(words_needed(values.len(), bits, word_bits));
    if bits <= word_bits {
        // k known to the compiler for the usual ID fields, as in `unpack` (a general fold per
        // word cost 22 instructions a pixel of a hemicube readback).
        let m = mask(bits);
        match (word_bits / bits) as usize {
            1 => pack_words(1, values, bits, m, &mut out),
            2 => pack_words(2, values, bits, m, &mut out),
            4 => pack_words(4, values, bits, m, &mut out),
            k => pack_words(k, values, bits, m, &mut out),
        }
    } else {
        let per = bits.div_ceil(word_bits);
        out.extend(
            values
                .iter()
                .flat_map(|&v| (0..per).map(move |j| (v >> (j * word_bits)) & mask(word_bits))),
        );
    }
    out
}

/// [`pack`] of `k` pixels a word onto `out`, the last word holding the rest. Always inlined, so
/// that a literal `k` makes the inner loop one the compiler unrolls.
#[inline(always)]
fn pack_words(k: usize, values: &[u64], bits: u32, m: u64, out: &mut Vec<u64>) {
    let word = |pixels: &[u64]| {
        pixels
            .iter()
            .enumerate()
            .fold(0u64, |w, (i, &v)| w | ((v & m) << (i as u32 * bits)))
    };
    // Appended from exact chunks, whose length the `extend` knows (words zeroed by a `resize`
    // and then made were 88 M more of the main job's hemicube's 8.23 G instructions; an
    // `extend` from `chunks` was not inlined: 20 instructions a pixel).
    let chunks = values.chunks_exact(k);
    let rest = chunks.remainder();
    out.extend(chunks.map(word));
    if !rest.is_empty() {
        out.push(word(rest));
    }
}

/// The inverse of [`pack`] for `count` pixels.
pub fn unpack(words: &[u64], bits: u32, word_bits: u32, count: usize) -> Vec<u64> {
    let mut out = Vec::new();
    unpack_into(words, bits, word_bits, count, &mut out);
    out.truncate(count);
    out
}

/// [`unpack`] into the first `count` values of `out`, which are returned; `out` is grown to
/// `count` values if it is shorter and keeps any beyond them. A GP that reads back message
/// after message keeps one buffer (a fresh zeroed one per message was 2.5 % of a hemicube
/// run's instructions, most of them zeroing it), and a buffer cut to each message's length was
/// zeroed again as a longer message followed a shorter one (50 M of the main job's hemicube's
/// 8.26 G instructions).
pub fn unpack_into<'a>(
    words: &[u64],
    bits: u32,
    word_bits: u32,
    count: usize,
    out: &'a mut Vec<u64>,
) -> &'a [u64] {
    // Every pixel is written below: only a buffer that grows is filled first.
    if out.len() < count {
        out.resize(count, 0);
    }
    let out = &mut out[..count];
    if bits <= word_bits {
        // Word by word, k pixels each, then the last word's part: no division per pixel (a
        // GP unpacks every ID it reads back, 49,152 per hemicube shot).
        let k = (word_bits / bits) as usize;
        let m = mask(bits);
        // Filled in place, a word's k pixels at a time, k known to the compiler for the usual
        // ID fields (an `extend` per word cost 20 instructions a pixel on the hemicube).
        match k {
            1 => unpack_words(1, words, bits, m, out),
            2 => unpack_words(2, words, bits, m, out),
            4 => unpack_words(4, words, bits, m, out),
            k => unpack_words(k, words, bits, m, out),
        }
    } else {
        let per = bits.div_ceil(word_bits) as usize;
        for (i, o) in out.iter_mut().enumerate() {
            *o = (0..per).fold(0u64, |v, j| {
                v | (words[i * per + j] << (j as u32 * word_bits))
            });
        }
    }
    out
}

/// [`unpack`] of `k` pixels a word into `out`; the last word may hold fewer. Always inlined,
/// so that a literal `k` makes the inner loop one the compiler unrolls.
#[inline(always)]
fn unpack_words(k: usize, words: &[u64], bits: u32, m: u64, out: &mut [u64]) {
    let word = |w: u64, pixels: &mut [u64]| {
        for (j, o) in pixels.iter_mut().enumerate() {
            *o = (w >> (j as u32 * bits)) & m;
        }
    };
    // Whole words by exact chunks (the compiler unrolls those; `chunks_mut` cost 3 % more
    // instructions on the hemicube by `bench machine`), then the last word's part.
    let full = out.len() / k;
    let mut chunks = out.chunks_exact_mut(k);
    for (chunk, &w) in (&mut chunks).zip(words) {
        word(w, chunk);
    }
    let rest = chunks.into_remainder();
    if !rest.is_empty() {
        word(words[full], rest);
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

    /// `unpack_into` gives `unpack`'s pixels whatever its buffer held before, longer or shorter,
    /// and keeps what lies beyond them.
    #[test]
    fn unpack_into_replaces_the_buffer() {
        let px: Vec<u64> = (0..37).map(|i| (i * 2654435761u64) & 0x3ff).collect();
        for bits in [10, 16, 32, 40] {
            let w = pack(&px, bits, 32);
            for held in [vec![], vec![u64::MAX; 5], vec![7; 100]] {
                let mut out = held.clone();
                let got = unpack_into(&w, bits, 32, px.len(), &mut out).to_vec();
                assert_eq!(got, unpack(&w, bits, 32, px.len()), "{bits} bits");
                assert_eq!(got, px, "{bits} bits");
                assert_eq!(out.len(), held.len().max(px.len()), "{bits} bits");
                assert_eq!(out[px.len()..], held[px.len().min(held.len())..]);
            }
        }
    }

    #[test]
    fn messages_carry_whole_rows_packed_apart() {
        let rect = Rect {
            x: 3,
            y: 10,
            width: 3,
            height: 5,
        };
        let v: Vec<u64> = (0..15).collect();
        // 16-bit values: a row of 3 is 2 words, so 5 words hold 2 rows; the last message 1 row.
        let m = pack_messages(&v, rect, 16, 32, 5);
        let heights: Vec<u32> = m.iter().map(|m| m.rect.height).collect();
        assert_eq!(heights, [2, 2, 1]);
        assert_eq!(
            m[1].rect,
            Rect {
                y: 12,
                height: 2,
                ..rect
            }
        );
        // Rows of one message share words (6 values in 3 words); each message pads on its own.
        assert_eq!(m[0].words, pack(&v[..6], 16, 32));
        assert_eq!(m[2].words, pack(&v[12..], 16, 32));
        let back: Vec<u64> = m
            .iter()
            .flat_map(|m| unpack(&m.words, 16, 32, (m.rect.width * m.rect.height) as usize))
            .collect();
        assert_eq!(back, v);
        // A row longer than a message travels whole; an unlimited message takes everything.
        assert_eq!(pack_messages(&v, rect, 16, 32, 1).len(), 5);
        assert_eq!(pack_messages(&v, rect, 16, 32, u32::MAX).len(), 1);
    }
}
