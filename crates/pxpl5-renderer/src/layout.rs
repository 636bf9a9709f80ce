//! Allocation of pixel memory into named fields.
//!
//! A GP program decides where its per-pixel variables live in the 208 bits ([paper]) of every
//! pixel, as the real machine's programs did; commands then carry the resulting [`Field`]s. Asking
//! for more bits than are free is a [`LayoutError`] naming the field and what is allocated, never a
//! panic. First fit, so a freed field's bits are reused.

use thiserror::Error;

use crate::command::Field;

/// The fields of one program's pixel memory.
#[derive(Clone, Debug)]
pub struct PixelLayout {
    total_bits: u32,
    fields: Vec<(String, Field)>,
}

/// Why a field cannot be allocated.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
pub enum LayoutError {
    #[error(
        "pixel memory: field `{name}` needs {bits} contiguous bits but the largest free run is \
         {largest_free} of {total} bits (allocated: {allocated})"
    )]
    Full {
        name: String,
        bits: u32,
        largest_free: u32,
        total: u32,
        allocated: String,
    },
    #[error("pixel memory: field `{name}` must have 1 to 64 bits (asked for {bits})")]
    BadWidth { name: String, bits: u32 },
    #[error("pixel memory: a field named `{0}` is already allocated")]
    Duplicate(String),
}

impl PixelLayout {
    /// An empty layout of `total_bits` per pixel (the config's `renderer.pixel_memory_bits`).
    pub fn new(total_bits: u32) -> PixelLayout {
        PixelLayout {
            total_bits,
            fields: Vec::new(),
        }
    }

    /// Allocate `bits` contiguous bits (1 to 64: the widest value a command moves at once).
    pub fn alloc(&mut self, name: &str, bits: u32, signed: bool) -> Result<Field, LayoutError> {
        if !(1..=64).contains(&bits) {
            return Err(LayoutError::BadWidth {
                name: name.to_string(),
                bits,
            });
        }
        if self.get(name).is_some() {
            return Err(LayoutError::Duplicate(name.to_string()));
        }
        let mut used: Vec<Field> = self.fields.iter().map(|(_, f)| *f).collect();
        used.sort_by_key(|f| f.offset);
        let mut start = 0;
        let mut largest_free = 0;
        for f in used.iter().chain(std::iter::once(&Field {
            offset: self.total_bits,
            bits: 0,
            signed: false,
        })) {
            let free = f.offset - start;
            if free >= bits {
                let field = Field {
                    offset: start,
                    bits,
                    signed,
                };
                self.fields.push((name.to_string(), field));
                return Ok(field);
            }
            largest_free = largest_free.max(free);
            start = f.end();
        }
        Err(LayoutError::Full {
            name: name.to_string(),
            bits,
            largest_free,
            total: self.total_bits,
            allocated: self.describe(),
        })
    }

    /// Release a field's bits.
    pub fn free(&mut self, name: &str) -> Option<Field> {
        let i = self.fields.iter().position(|(n, _)| n == name)?;
        Some(self.fields.remove(i).1)
    }

    pub fn get(&self, name: &str) -> Option<Field> {
        self.fields.iter().find(|(n, _)| n == name).map(|(_, f)| *f)
    }

    /// Bits not allocated.
    pub fn free_bits(&self) -> u32 {
        self.total_bits - self.fields.iter().map(|(_, f)| f.bits).sum::<u32>()
    }

    /// `name bits@offset` for every field, in allocation order.
    pub fn describe(&self) -> String {
        if self.fields.is_empty() {
            return "nothing".to_string();
        }
        self.fields
            .iter()
            .map(|(n, f)| format!("{n} {}@{}", f.bits, f.offset))
            .collect::<Vec<_>>()
            .join(", ")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_fit_reuses_freed_bits_and_reports_overflow() {
        let mut l = PixelLayout::new(208);
        let id = l.alloc("id", 16, false).unwrap();
        let depth = l.alloc("depth", 32, true).unwrap();
        assert_eq!((id.offset, depth.offset), (0, 16));
        l.alloc("w", 64, false).unwrap();
        l.alloc("big", 64, false).unwrap();
        assert_eq!(l.free_bits(), 208 - 176);
        let err = l.alloc("more", 40, false).unwrap_err();
        let text = err.to_string();
        assert!(text.contains("`more` needs 40") && text.contains("largest free run is 32"));
        assert!(text.contains("depth 32@16"), "{text}");
        l.free("id");
        assert_eq!(l.alloc("flagsish", 8, false).unwrap().offset, 0);
        assert!(matches!(
            l.alloc("zero", 0, false),
            Err(LayoutError::BadWidth { .. })
        ));
        assert!(matches!(
            l.alloc("depth", 1, false),
            Err(LayoutError::Duplicate(_))
        ));
    }
}
