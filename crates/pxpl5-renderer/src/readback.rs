//! Read-back pixels on the ring: their packing into ring words, which decides what a message
//! costs, and their messages.
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
//! (\[assumed\] streaming: the output port never needs to hold a whole field).
//!
//! The packing decides how many words each message takes on the ring ([`words_needed`] of its
//! pixels); the host carries the pixels' values instead of packing them into words and
//! unpacking them at the receiver, which gives the same values (each is a `bits`-bit field's,
//! below 2^`bits`). Host work only: packing and unpacking were 4 % of the main job's hemicube
//! instructions (346 M of 7.78 G, by callgrind).

use crate::command::Rect;

/// One message of a readback: the rows of `rect` it carries, as their pixels' raw field values,
/// row by row (on the ring, [`words_needed`] of them).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ReadbackMessage {
    pub rect: Rect,
    pub values: Vec<u64>,
}

/// The messages carrying `values` (the raw `bits`-bit values of `rect`'s pixels, row by row) at
/// `word_bits` bits per word and at most `max_message_words` words per message (a row longer than
/// that still travels whole, alone). Values that fit one message travel in their own buffer, not
/// a copy (the copy was most of the board's cost of a hemicube's ID bands).
pub fn messages(
    values: Vec<u64>,
    rect: Rect,
    bits: u32,
    word_bits: u32,
    max_message_words: u32,
) -> Vec<ReadbackMessage> {
    debug_assert!(
        bits >= 64 || values.iter().all(|&v| v >> bits == 0),
        "read-back values wider than their {bits}-bit field"
    );
    let width = rect.width as usize;
    let row_words = words_needed(width, bits, word_bits);
    let rows_per = (max_message_words as usize / row_words.max(1)).max(1);
    if values.is_empty() {
        return Vec::new();
    }
    if values.len() <= rows_per.saturating_mul(width) {
        return vec![ReadbackMessage { rect, values }];
    }
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
            values: rows.to_vec(),
        })
        .collect()
}

/// Ring words a readback of `pixels` pixels of a `bits`-bit field needs (none for a field of no
/// bits, which only a program's own payload can claim: a board's fields have 1 to 64).
pub fn words_needed(pixels: usize, bits: u32, word_bits: u32) -> usize {
    if bits == 0 || word_bits == 0 {
        0
    } else if bits <= word_bits {
        pixels.div_ceil((word_bits / bits) as usize)
    } else {
        pixels.saturating_mul(bits.div_ceil(word_bits) as usize)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn narrow_fields_share_words() {
        // 16-bit fields: two per 32-bit word, the last word padded.
        assert_eq!(words_needed(3, 16, 32), 2);
        // 10-bit fields: three per 32-bit word, two bits of padding.
        assert_eq!(words_needed(7, 10, 32), 3);
        assert_eq!(words_needed(6, 10, 32), 2);
        assert_eq!(words_needed(1, 32, 32), 1);
        // A payload a program made, of no bits, takes no words (and no division by zero).
        assert_eq!(words_needed(5, 0, 32), 0);
    }

    #[test]
    fn wide_fields_span_words() {
        assert_eq!(words_needed(1, 40, 32), 2);
        assert_eq!(words_needed(5, 40, 32), 10);
        assert_eq!(words_needed(3, 64, 32), 6);
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
        let m = messages(v.clone(), rect, 16, 32, 5);
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
        let words = |m: &[ReadbackMessage], bits| {
            m.iter()
                .map(|m| words_needed(m.values.len(), bits, 32))
                .collect::<Vec<_>>()
        };
        assert_eq!(words(&m, 16), [3, 3, 2]);
        assert_eq!(m[0].values, v[..6]);
        assert_eq!(m[2].values, v[12..]);
        let back: Vec<u64> = m.iter().flat_map(|m| m.values.iter().copied()).collect();
        assert_eq!(back, v);
        // A row longer than a message travels whole; an unlimited message takes everything.
        assert_eq!(messages(v.clone(), rect, 16, 32, 1).len(), 5);
        // Values that fit one message travel as they are, under the whole rectangle.
        assert_eq!(
            messages(v.clone(), rect, 16, 32, u32::MAX),
            [ReadbackMessage {
                rect,
                values: v.clone()
            }]
        );
        // Five rows of two words: ten words are one message, nine are two.
        assert_eq!(
            messages(v.clone(), rect, 16, 32, 10),
            messages(v.clone(), rect, 16, 32, u32::MAX)
        );
        assert_eq!(messages(v.clone(), rect, 16, 32, 9).len(), 2);
        assert!(messages(Vec::new(), Rect { height: 0, ..rect }, 16, 32, 5).is_empty());
        // 40-bit values: 2 words a pixel, 6 a row; 13 words hold 2 rows.
        assert_eq!(
            words(&messages(v.clone(), rect, 40, 32, 13), 40),
            [12, 12, 6]
        );
    }
}
