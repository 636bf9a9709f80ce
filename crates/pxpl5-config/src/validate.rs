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

/// Largest cost of one operation or command term, in cycles: 2^32 - 1. Simulated time is a u64
/// of picoseconds, and a program charges a cost times a count (pixels, bits, patches) that is
/// itself below 2^32, so a charge in cycles always fits a u64; converted to picoseconds it may
/// not (at a slow clock), and then it saturates to the end of time and the run stops at its time
/// limit (`pxpl5_sim`). The bound is a million times the largest default cost (4,096), so it
/// leaves every what-if open and rules out only values that are typos or overflow probes.
pub const MAX_COST_CYCLES: u64 = u32::MAX as u64;

/// Most GPs, and most Renderers, a machine may have: 256, 8 and 16 times the paper's largest
/// machine (32 GPs, 16 Renderers). The simulator scans its units at every simulated instant and
/// the programs' messages grow with GPs x Renderers, so a machine of thousands runs for minutes
/// (measured on this project's reference host: 256 GPs and 256 Renderers draw the 402 triangles
/// in 2 s and shoot one radiosity shot in 5 s; 1,024 GPs need 51 s for that shot and, with 1,024
/// Renderers, 90 s for the triangles). The host memory a machine needs is checked apart, before
/// it is built (`pxpl5_machine::memory`).
pub const MAX_UNITS: u32 = 256;

/// Most ring channels: 64, 16 times the seed's 4; a ring's tokens are all simulated, every
/// channel clock, and more channels than the machine has nodes carry nothing.
pub const MAX_CHANNELS: u32 = 64;

/// Largest frame-buffer side: a readback's tag carries the screen position of its region in two
/// 16-bit halves, so positions must be below 2^16.
pub const MAX_FRAME_BUFFER_SIDE: u32 = 1 << 16;

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
    c.within("gp.count", cfg.gp.count.into(), 1, MAX_UNITS.into());
    c.clock("gp.clock_hz", cfg.gp.clock_hz);
    let g = &cfg.gp.costs;
    for (path, value) in [
        ("gp.costs.vertex_transform", g.vertex_transform),
        ("gp.costs.clip_test", g.clip_test),
        ("gp.costs.polygon_setup", g.polygon_setup),
        ("gp.costs.edge_setup", g.edge_setup),
        ("gp.costs.command_encode", g.command_encode),
        ("gp.costs.message_send", g.message_send),
        ("gp.costs.message_receive", g.message_receive),
        (
            "gp.costs.ff_accumulate_per_pixel",
            g.ff_accumulate_per_pixel,
        ),
        ("gp.costs.w_table_entry", g.w_table_entry),
        (
            "gp.costs.radiosity_update_per_patch",
            g.radiosity_update_per_patch,
        ),
    ] {
        c.cost(path, value);
    }

    // Ring.
    let ring = &cfg.ring;
    c.within(
        "ring.channels",
        ring.channels.into(),
        1,
        MAX_CHANNELS.into(),
    );
    c.clock("ring.channel_clock_hz", ring.channel_clock_hz);
    c.within("ring.word_bits", ring.word_bits.into(), 1, 64);
    c.at_least("ring.max_message_words", ring.max_message_words.into(), 1);
    // A word or a token needs at least one channel clock per hop: at 0 a token would circle
    // the ring in no time.
    c.within(
        "ring.hop_latency_cycles",
        ring.hop_latency_cycles.into(),
        1,
        MAX_COST_CYCLES,
    );
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
    c.within("renderer.count", r.count.into(), 1, MAX_UNITS.into());
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
    c.within(
        "renderer.backing_store.block_cycles",
        bs.block_cycles,
        1,
        MAX_COST_CYCLES,
    );
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
    // A coefficient of magnitude 1 (a unit edge slope, which every edge test has) needs one
    // integer bit; with none the QEE cannot hold it.
    c.at_least(
        "renderer.qee.coefficient_format.int_bits",
        q.coefficient_format.int_bits.into(),
        1,
    );
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
    c.cost("renderer.qee.latency_cycles", q.latency_cycles.into());
    c.cost(
        "renderer.qee.quadratic_extra_cycles",
        q.quadratic_extra_cycles.into(),
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
    for (path, value) in [
        ("renderer.cycles.igc_overhead", cy.igc_overhead),
        ("renderer.cycles.logic", cy.logic),
        ("renderer.cycles.alu_setup", cy.alu_setup),
        ("renderer.cycles.per_bit", cy.per_bit),
        (
            "renderer.cycles.multiply_per_bit_pair",
            cy.multiply_per_bit_pair,
        ),
        (
            "renderer.cycles.backing_store_issue",
            cy.backing_store_issue,
        ),
        ("renderer.cycles.readback_per_bit", cy.readback_per_bit),
        ("renderer.cycles.set_origin", cy.set_origin),
    ] {
        c.cost(path, value);
    }

    // Frame buffer.
    let fb = &cfg.frame_buffer;
    let side = MAX_FRAME_BUFFER_SIDE.into();
    c.within("frame_buffer.width", fb.width.into(), 1, side);
    c.within("frame_buffer.height", fb.height.into(), 1, side);
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

    /// A cost in cycles must be at most [`MAX_COST_CYCLES`].
    fn cost(&mut self, path: &str, cycles: u64) -> bool {
        let ok = cycles <= MAX_COST_CYCLES;
        if !ok {
            self.fail(
                path,
                cycles.to_string(),
                format!(
                    "must be at most {MAX_COST_CYCLES} cycles (2^32 - 1): a cost times the \
                     counts a program charges it for must fit simulated time"
                ),
            );
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
