//! Semantic checks of a parsed [`MachineConfig`]: the limits that serde's types cannot express.
//!
//! Every check names its field by dotted path, gives the offending value and says what is allowed;
//! all problems are collected, not just the first, so one edit-and-run fixes a file.
//!
//! The paper's machine sizes (up to 32 GPs, up to 16 Renderers) are deliberately *not* limits:
//! larger machines are legitimate what-if studies. The limits here are the ones beyond which the
//! simulator's model would be meaningless or inexact (a clock that is not a whole number of
//! picoseconds, a QEE wider than 64-bit arithmetic holds, a cost of zero that makes work free).

use crate::{MachineConfig, PS_PER_SECOND};

use crate::error::SemanticError;

/// Widest coefficient the QEE model accepts, sign included.
const MAX_COEFFICIENT_BITS: u64 = 48;
/// Most fractional coefficient bits the QEE model accepts.
const MAX_FRAC_BITS: u32 = 40;
/// Widest pixel memory the Renderer model accepts (the backing store's size, [paper] 4,096).
const MAX_PIXEL_MEMORY_BITS: u32 = 4096;

/// Checks every semantic limit of `cfg`; on failure returns all the problems found, in field
/// order.
pub fn validate(cfg: &MachineConfig) -> Result<(), Vec<SemanticError>> {
    let mut c = Checker::default();

    if cfg.name.trim().is_empty() {
        c.fail(
            "name",
            format!("{:?}", cfg.name),
            "must not be empty (it names the machine in stats and reports)",
        );
    }

    // Graphics Processors.
    c.at_least("gp.count", cfg.gp.count.into(), 1);
    c.clock("gp.clock_hz", cfg.gp.clock_hz);

    // Ring.
    let ring = &cfg.ring;
    c.at_least("ring.channels", ring.channels.into(), 1);
    c.clock("ring.channel_clock_hz", ring.channel_clock_hz);
    c.within("ring.word_bits", ring.word_bits.into(), 1, 64);
    c.at_least("ring.max_message_words", ring.max_message_words.into(), 1);
    // A word or a token needs at least one channel clock per hop: at 0 a token would circle
    // the ring in no time.
    c.at_least("ring.hop_latency_cycles", ring.hop_latency_cycles.into(), 1);
    let needed = u64::from(ring.max_message_words) + u64::from(ring.header_words);
    if u64::from(ring.queue_words) < needed {
        c.fail(
            "ring.queue_words",
            ring.queue_words.to_string(),
            format!(
                "must hold one whole message: at least ring.max_message_words + \
                 ring.header_words = {} + {} = {needed}",
                ring.max_message_words, ring.header_words
            ),
        );
    }

    // Renderer array and memory.
    let r = &cfg.renderer;
    c.at_least("renderer.count", r.count.into(), 1);
    if r.width == 0 || !r.width.is_multiple_of(64) {
        c.fail(
            "renderer.width",
            r.width.to_string(),
            "must be a positive multiple of 64 (the simulator works on whole 64-pixel groups)",
        );
    }
    c.at_least("renderer.height", r.height.into(), 1);
    c.within(
        "renderer.pixel_memory_bits",
        r.pixel_memory_bits.into(),
        1,
        MAX_PIXEL_MEMORY_BITS.into(),
    );
    c.within("renderer.flag_registers", r.flag_registers.into(), 1, 64);
    c.clock("renderer.clock_hz", r.clock_hz);

    // Backing store: whole blocks only; 0 bits (no backing store) is a valid what-if.
    let bs = &r.backing_store;
    let block_ok = c.within(
        "renderer.backing_store.block_bits",
        bs.block_bits.into(),
        1,
        64,
    );
    c.at_least("renderer.backing_store.block_cycles", bs.block_cycles, 1);
    if block_ok && !r.backing_store_bits.is_multiple_of(bs.block_bits) {
        c.fail(
            "renderer.backing_store_bits",
            r.backing_store_bits.to_string(),
            format!(
                "must be a multiple of renderer.backing_store.block_bits ({}): the backing store \
                 moves whole blocks",
                bs.block_bits
            ),
        );
    }

    // Quadratic expression evaluator.
    let q = &r.qee;
    let coord_ok = c.within(
        "renderer.qee.coordinate_bits",
        q.coordinate_bits.into(),
        1,
        16,
    );
    if coord_ok {
        // The region's pixel addresses must fit the tree's coordinate inputs.
        let limit = 1u64 << q.coordinate_bits;
        for (path, value) in [("renderer.width", r.width), ("renderer.height", r.height)] {
            if u64::from(value) > limit {
                c.fail(
                    path,
                    value.to_string(),
                    format!(
                        "must be at most 2^renderer.qee.coordinate_bits = 2^{} = {limit}",
                        q.coordinate_bits
                    ),
                );
            }
        }
    }
    c.within(
        "renderer.qee.coefficient_format.frac_bits",
        q.coefficient_format.frac_bits.into(),
        0,
        MAX_FRAC_BITS.into(),
    );
    // Computed in u64: `FixedFormat::total_bits` would overflow on absurd inputs.
    let coeff_bits =
        1 + u64::from(q.coefficient_format.int_bits) + u64::from(q.coefficient_format.frac_bits);
    if coeff_bits > MAX_COEFFICIENT_BITS {
        c.fail(
            "renderer.qee.coefficient_format",
            format!(
                "1 + int_bits {} + frac_bits {} = {coeff_bits} bits",
                q.coefficient_format.int_bits, q.coefficient_format.frac_bits
            ),
            format!("must total at most {MAX_COEFFICIENT_BITS} bits, sign included"),
        );
    }
    if coord_ok {
        // A quadratic term is coefficient x coordinate x coordinate, plus carries of the tree's
        // additions; the simulator evaluates it exactly in i64.
        let tree_bits = coeff_bits + 2 * u64::from(q.coordinate_bits) + 3;
        if tree_bits > 64 {
            c.fail(
                "renderer.qee.coefficient_format",
                format!(
                    "{coeff_bits} + 2 * {} + 3 = {tree_bits} bits",
                    q.coordinate_bits
                ),
                "renderer.qee.coefficient_format total bits + 2 * renderer.qee.coordinate_bits + 3 \
                 must be at most 64, so the QEE tree is simulated exactly in 64-bit arithmetic \
                 (narrow the coefficients or the coordinates)",
            );
        }
    }
    c.within(
        "renderer.qee.max_result_bits",
        q.max_result_bits.into(),
        1,
        64,
    );

    // Cycle costs that multiply work: a zero would make that work free.
    let cy = &r.cycles;
    for (path, value) in [
        ("renderer.cycles.per_bit", cy.per_bit),
        ("renderer.cycles.logic", cy.logic),
        (
            "renderer.cycles.multiply_per_bit_pair",
            cy.multiply_per_bit_pair,
        ),
        ("renderer.cycles.readback_per_bit", cy.readback_per_bit),
    ] {
        if value == 0 {
            c.fail(
                path,
                "0".to_string(),
                "must be at least 1: it is multiplied by the work done, so 0 would make that \
                 work free",
            );
        }
    }

    // Frame buffer.
    let fb = &cfg.frame_buffer;
    c.at_least("frame_buffer.width", fb.width.into(), 1);
    c.at_least("frame_buffer.height", fb.height.into(), 1);
    c.within(
        "frame_buffer.bits_per_pixel",
        fb.bits_per_pixel.into(),
        1,
        32,
    );

    c.finish()
}

/// Collects failures; the helpers return whether the check passed, so dependent checks can skip.
#[derive(Default)]
struct Checker {
    errors: Vec<SemanticError>,
}

impl Checker {
    fn fail(&mut self, path: &str, value: String, rule: impl Into<String>) {
        self.errors.push(SemanticError {
            path: path.to_string(),
            value,
            rule: rule.into(),
        });
    }

    fn at_least(&mut self, path: &str, value: u64, min: u64) -> bool {
        let ok = value >= min;
        if !ok {
            self.fail(path, value.to_string(), format!("must be at least {min}"));
        }
        ok
    }

    fn within(&mut self, path: &str, value: u64, min: u64, max: u64) -> bool {
        let ok = (min..=max).contains(&value);
        if !ok {
            self.fail(path, value.to_string(), format!("must be in {min}..={max}"));
        }
        ok
    }

    /// A clock must be positive and a whole number of picoseconds per cycle (time is kept in
    /// integer picoseconds, so any other clock would drift).
    fn clock(&mut self, path: &str, hz: u64) -> bool {
        let ok = hz > 0 && PS_PER_SECOND.is_multiple_of(hz);
        if !ok {
            self.fail(
                path,
                hz.to_string(),
                "must be a positive divisor of 10^12 Hz, so one cycle is a whole number of \
                 picoseconds (e.g. 40_000_000 = 25,000 ps, 33_333_333 is not allowed)",
            );
        }
        ok
    }

    fn finish(self) -> Result<(), Vec<SemanticError>> {
        if self.errors.is_empty() {
            Ok(())
        } else {
            Err(self.errors)
        }
    }
}
