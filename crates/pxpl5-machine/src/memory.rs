//! The host memory a machine needs, estimated from its config before anything is built, so that
//! a config the host cannot hold (65,536 x 65,536 Renderers, a frame buffer of 2^32 pixels) is
//! refused with the estimate and the limit instead of aborting in the allocator.
//!
//! The estimate is of the machine's own state: per Renderer its pixel memory (the larger of the
//! two fidelity levels' layouts), its one-bit registers, its backing store as if every block
//! were written (it is allocated as programs write it), and the working memory of one command;
//! per GP its runtime; per ring node and channel the ring's state; the frame buffer's image and
//! its PNG. A program's own data (a scene, a solution) and traces, which grow with the run, are
//! not in it. Every figure is computed in saturating u64 arithmetic, so an absurd config gives a
//! huge estimate, never an overflow.
//!
//! [`DEFAULT_LIMIT`] is the limit the `pxpl5` command applies unless the user raises it
//! (`--memory-limit SIZE`); sizes are read and written by [`parse_size`] and [`format_size`].

use std::fmt;

use pxpl5_config::MachineConfig;

/// The limit a command applies by default: 4 GiB. Every machine of default-sized Renderers
/// within the config's limits (256 of them, 8.6 MiB each with a full backing store) fits in it,
/// and so does any laptop of the last decade; a larger what-if raises it.
pub const DEFAULT_LIMIT: u64 = 4 << 30;

/// Bytes of one GP's runtime (its handle, the state it shares with the machine, its program's
/// future without the program's own data), rounded up from the structures' sizes.
const GP_BYTES: u64 = 4096;
/// Bytes of the ring's state per node (queues' bookkeeping, statistics) and of the machine's per
/// unit (position, delivery routes), rounded up.
const NODE_BYTES: u64 = 1024;
/// Bytes of the ring's state per channel (its token, holder and statistics), rounded up.
const CHANNEL_BYTES: u64 = 256;
/// Bytes of a Renderer node besides its arrays (config, statistics, queues), rounded up.
const RENDERER_FIXED_BYTES: u64 = 16 * 1024;
/// Working memory of one Renderer command per pixel: a per-pixel value of the QEE's cross stage,
/// a field's planes unpacked for a multi-bit operation, a readback's values and ring words, each
/// at most 8 bytes per pixel.
const WORKING_BYTES_PER_PIXEL: u64 = 32;
/// Bytes per frame-buffer pixel: the RGB image (3) and, at the end of a run, its PNG (at most
/// about as large again).
const FRAME_BUFFER_BYTES_PER_PIXEL: u64 = 6;

/// One line of an estimate: `count` things of `each` bytes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Part {
    /// What is counted, e.g. "Renderer".
    pub what: &'static str,
    /// How many there are.
    pub count: u64,
    /// Bytes of one.
    pub each: u64,
    /// What one holds, for the report.
    pub detail: String,
}

impl Part {
    /// Bytes of all of them (saturating).
    pub fn bytes(&self) -> u64 {
        self.count.saturating_mul(self.each)
    }
}

/// The host memory a machine needs, by part.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MemoryEstimate {
    pub parts: Vec<Part>,
}

impl MemoryEstimate {
    /// Bytes in all (saturating).
    pub fn total(&self) -> u64 {
        self.parts
            .iter()
            .fold(0u64, |sum, p| sum.saturating_add(p.bytes()))
    }
}

impl fmt::Display for MemoryEstimate {
    /// `1.2 GiB: 4 Renderers x 8.6 MiB (...), 16 GPs x 4 KiB (...), ...`
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: ", format_size(self.total()))?;
        for (i, p) in self.parts.iter().enumerate() {
            let sep = if i == 0 { "" } else { ", " };
            let plural = if p.count == 1 { "" } else { "s" };
            write!(
                f,
                "{sep}{} {}{plural} x {} ({})",
                p.count,
                p.what,
                format_size(p.each),
                p.detail
            )?;
        }
        Ok(())
    }
}

/// The host memory of the machine of `cfg` (see the module doc for what is counted).
pub fn estimate(cfg: &MachineConfig) -> MemoryEstimate {
    let r = &cfg.renderer;
    let pixels = u64::from(r.width).saturating_mul(u64::from(r.height));
    let bits = u64::from(r.pixel_memory_bits);
    // The bit level keeps one u64 per bit per 64 pixels; the integer level whole u64 limbs per
    // pixel: the larger is what a run at either level may need.
    let pixel_memory =
        (pixels.saturating_mul(bits) / 8).max(pixels.saturating_mul(bits.div_ceil(64) * 8));
    let registers = pixels.saturating_mul(1 + u64::from(r.flag_registers)) / 8;
    let backing_store = pixels.saturating_mul(u64::from(r.backing_store_bits)) / 8;
    let working = pixels.saturating_mul(WORKING_BYTES_PER_PIXEL);
    let renderer = [pixel_memory, registers, backing_store, working]
        .into_iter()
        .fold(RENDERER_FIXED_BYTES, u64::saturating_add);
    let fb = &cfg.frame_buffer;
    let fb_pixels = u64::from(fb.width).saturating_mul(u64::from(fb.height));
    let nodes = u64::from(cfg.gp.count)
        .saturating_add(u64::from(r.count))
        .saturating_add(2);
    MemoryEstimate {
        parts: vec![
            Part {
                what: "Renderer",
                count: r.count.into(),
                each: renderer,
                detail: format!(
                    "{} x {} pixels: pixel memory {}, flags {}, backing store {} when full, \
                     working memory {}",
                    r.width,
                    r.height,
                    format_size(pixel_memory),
                    format_size(registers),
                    format_size(backing_store),
                    format_size(working)
                ),
            },
            Part {
                what: "GP",
                count: cfg.gp.count.into(),
                each: GP_BYTES,
                detail: "runtime, without the program's data".into(),
            },
            Part {
                what: "ring node",
                count: nodes,
                each: NODE_BYTES,
                detail: "queues and statistics".into(),
            },
            Part {
                what: "ring channel",
                count: cfg.ring.channels.into(),
                each: CHANNEL_BYTES,
                detail: "token and statistics".into(),
            },
            Part {
                what: "frame buffer",
                count: 1,
                each: fb_pixels.saturating_mul(FRAME_BUFFER_BYTES_PER_PIXEL),
                detail: format!("{} x {} pixels: RGB image and its PNG", fb.width, fb.height),
            },
        ],
    }
}

/// A machine that needs more host memory than the limit allows.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error(
    "machine `{name}` needs an estimated {estimate}; that is more than the host memory limit of \
     {limit}",
    limit = format_size(*.limit)
)]
pub struct MemoryError {
    pub name: String,
    pub estimate: MemoryEstimate,
    pub limit: u64,
}

impl MemoryError {
    /// A limit that would admit the machine, as [`parse_size`] reads it (the next whole GiB),
    /// or `None` for an estimate beyond a pebibyte, which no host has.
    pub fn suggested_limit(&self) -> Option<String> {
        let gib = self.estimate.total().div_ceil(1 << 30).max(1);
        (gib <= 1 << 20).then(|| format!("{gib}GiB"))
    }
}

/// The estimate of `cfg`, or an error if it is more than `limit` bytes.
pub fn check(cfg: &MachineConfig, limit: u64) -> Result<MemoryEstimate, MemoryError> {
    let estimate = estimate(cfg);
    if estimate.total() > limit {
        return Err(MemoryError {
            name: cfg.name.clone(),
            estimate,
            limit,
        });
    }
    Ok(estimate)
}

/// Units of [`parse_size`] and [`format_size`]: powers of 1,024 (a GiB is 2^30 bytes; `G` and
/// `GB` mean the same, as memory is sized in powers of two).
const UNITS: [(&str, u32); 5] = [("B", 0), ("KiB", 10), ("MiB", 20), ("GiB", 30), ("TiB", 40)];

/// A size in bytes from text: a whole number with an optional unit, `B`, `K`, `KiB`, `KB`, `M`,
/// `MiB`, `MB`, `G`, `GiB`, `GB`, `T`, `TiB` or `TB` (case-insensitive, all powers of 1,024),
/// e.g. `512MiB`, `16GiB`, `4096`. Errors say what was wrong; sizes beyond u64 are refused.
pub fn parse_size(text: &str) -> Result<u64, String> {
    let t = text.trim();
    let split = t.find(|c: char| !c.is_ascii_digit()).unwrap_or(t.len());
    let (digits, unit) = (&t[..split], t[split..].trim());
    if digits.is_empty() {
        return Err(format!(
            "`{text}` is not a size: expected a whole number of bytes with an optional unit \
             (B, KiB, MiB, GiB, TiB), e.g. 8GiB"
        ));
    }
    let shift = match unit.to_ascii_lowercase().as_str() {
        "" | "b" => 0,
        "k" | "kb" | "kib" => 10,
        "m" | "mb" | "mib" => 20,
        "g" | "gb" | "gib" => 30,
        "t" | "tb" | "tib" => 40,
        _ => {
            return Err(format!(
                "`{text}` has unknown unit `{unit}`: expected B, KiB, MiB, GiB or TiB"
            ));
        }
    };
    let too_large = || format!("`{text}` is too large: at most 2^64 - 1 bytes");
    let n: u64 = digits.parse().map_err(|_| too_large())?;
    n.checked_mul(1u64 << shift).ok_or_else(too_large)
}

/// `bytes` in the largest unit of `UNITS` it reaches, with one decimal below 100 of it
/// (`8.6 MiB`, `4 GiB`, `512 B`).
pub fn format_size(bytes: u64) -> String {
    let (name, shift) = UNITS
        .iter()
        .rev()
        .find(|&&(_, s)| bytes >= 1u64 << s)
        .copied()
        .unwrap_or(UNITS[0]);
    if shift == 0 {
        return format!("{bytes} B");
    }
    let value = bytes as f64 / (1u64 << shift) as f64;
    if value < 100.0 && !bytes.is_multiple_of(1u64 << shift) {
        format!("{value:.1} {name}")
    } else {
        format!("{value:.0} {name}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_and_print() {
        assert_eq!(parse_size("4096"), Ok(4096));
        assert_eq!(parse_size("512MiB"), Ok(512 << 20));
        assert_eq!(parse_size(" 16 GiB "), Ok(16 << 30));
        assert_eq!(parse_size("2g"), Ok(2 << 30));
        assert_eq!(parse_size("1TB"), Ok(1 << 40));
        assert!(parse_size("").unwrap_err().contains("not a size"));
        assert!(parse_size("GiB").unwrap_err().contains("not a size"));
        assert!(parse_size("-1").unwrap_err().contains("not a size"));
        assert!(parse_size("1.5GiB").unwrap_err().contains("unknown unit"));
        assert!(
            parse_size("3 parsecs")
                .unwrap_err()
                .contains("unknown unit")
        );
        assert!(parse_size("16777216TiB").unwrap_err().contains("too large"));
        assert!(
            parse_size("99999999999999999999")
                .unwrap_err()
                .contains("too large")
        );
        assert_eq!(format_size(0), "0 B");
        assert_eq!(format_size(1023), "1023 B");
        assert_eq!(format_size(4 << 30), "4 GiB");
        assert_eq!(format_size(9_000_000), "8.6 MiB");
        assert_eq!(format_size(u64::MAX), "16777216 TiB");
    }
}
