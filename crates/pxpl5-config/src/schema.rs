//! The machine-config schema: one serde type per section of a `machine-configs/*.ron` file.
//!
//! Every field documents its unit and its provenance tag, as in
//! `docs/hardware.md`: **[paper]** (Fuchs et al., SIGGRAPH '89),
//! **[seed]** (Goldfeather, TR89-002), **[secondary]**, **[lineage]** (Pixel-Planes 4, Goldfeather
//! & Fuchs 1986) or **[assumed]** (no source found; a named, configurable assumption).
//! The same tags are listed per field in [`crate::provenance::PROVENANCE`], which `pxpl5 config
//! show` prints beside the effective config.
//!
//! Structural fields (the counts of GPs, Renderers and ring channels, and the config's name) are
//! required in every file; all timing and format parameters default to the documented values, so a
//! file states only what differs from the seed's machine.

use serde::{Deserialize, Serialize};

/// A whole machine: GPs, ring, Renderers, frame buffer, host.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MachineConfig {
    /// Short name, printed in stats and reports.
    pub name: String,
    /// Free text: where the machine comes from.
    #[serde(default)]
    pub description: String,
    pub gp: GpConfig,
    pub ring: RingConfig,
    pub renderer: RendererConfig,
    #[serde(default)]
    pub frame_buffer: FrameBufferConfig,
    #[serde(default)]
    pub host: HostConfig,
}

/// The Graphics Processors (Intel i860s).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GpConfig {
    /// Number of GPs. [paper]: up to 32.
    pub count: u32,
    /// i860 clock in Hz. [secondary]: 40 MHz.
    #[serde(default = "defaults::gp_clock_hz")]
    pub clock_hz: u64,
    /// i860 cycles per operation of a GP program.
    #[serde(default)]
    pub costs: GpCostTable,
}

/// i860 cycles charged per operation of a GP program. All [assumed]: estimates from the i860's
/// peak of 80 MFLOPS at 40 MHz (two floating-point results per cycle at best).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GpCostTable {
    /// 4x4 matrix times a point with the homogeneous divide: 16 multiply-adds plus a divide.
    pub vertex_transform: u64,
    /// Clip test of one vertex against the view volume (six compares).
    pub clip_test: u64,
    /// Per-polygon set-up (plane equation, bounding box, binning).
    pub polygon_setup: u64,
    /// Per-edge set-up of one linear or quadratic expression (coefficients, quantisation).
    pub edge_setup: u64,
    /// Composing one Renderer command into the outgoing message buffer.
    pub command_encode: u64,
    /// Fixed software cost of sending one ring message.
    pub message_send: u64,
    /// Fixed software cost of receiving one ring message.
    pub message_receive: u64,
    /// Accumulating one read-back pixel's delta form factor into its patch's sum.
    pub ff_accumulate_per_pixel: u64,
    /// Computing one entry of the hemisphere's w table (stored-w depth): round(sqrt(1 - u^2 -
    /// v^2) 2^16) for one pixel.
    pub w_table_entry: u64,
    /// Updating one patch's radiosity and unshot radiosity for one colour band.
    pub radiosity_update_per_patch: u64,
}

/// The token ring connecting GPs, Renderers, the frame buffer and the host.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RingConfig {
    /// Number of independent channels. [seed]: 4.
    pub channels: u32,
    /// Words per second per channel, one word per channel clock. [seed]: 80 Mwords/s over 4
    /// channels, so 20 MHz.
    #[serde(default = "defaults::ring_channel_clock_hz")]
    pub channel_clock_hz: u64,
    /// Bits per ring word. [assumed]: 32. The seed counts words (80 Mwords/s), not bits; with
    /// 32-bit words the paper's 5 Gbit/s is 160 M words/s.
    #[serde(default = "defaults::ring_word_bits")]
    pub word_bits: u32,
    /// Channel clocks for a word to move one node along the ring. [assumed]: 1.
    #[serde(default = "defaults::one_u32")]
    pub hop_latency_cycles: u32,
    /// Header words in front of every message (destination, length, tag). [assumed]: 1.
    #[serde(default = "defaults::one_u32")]
    pub header_words: u32,
    /// Longest message in words, header excluded; longer ones are split. [assumed]: 1,024.
    #[serde(default = "defaults::ring_max_message_words")]
    pub max_message_words: u32,
    /// When a sender gives the token back. [assumed]: early release.
    #[serde(default)]
    pub token_policy: TokenPolicy,
    /// Order of the nodes around the ring. [assumed]: GPs and Renderers interleaved.
    #[serde(default)]
    pub node_order: NodeOrder,
    /// Words of buffering per node (shared by its channels), input and output each. [assumed]: 2,048, the
    /// longest message with its header rounded up to a power of two (must be at least
    /// `max_message_words + header_words`, so a whole message always fits).
    #[serde(default = "defaults::ring_queue_words")]
    pub queue_words: u32,
}

/// When a sender releases the token of a channel.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum TokenPolicy {
    /// The token follows the last word of the message (the next sender may start at once).
    #[default]
    EarlyRelease,
    /// The token is released only when the last word has reached its destination.
    LateRelease,
}

/// The order of the nodes around the ring.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
pub enum NodeOrder {
    /// GPs and Renderers alternate (as evenly as the counts allow), then frame buffer, then host.
    #[default]
    Interleaved,
    /// All GPs, then all Renderers, then frame buffer, then host.
    GpsThenRenderers,
}

/// The Renderer boards: 128 x 128 bit-serial SIMD pixel processors with a QEE.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RendererConfig {
    /// Number of Renderer boards. [paper]: up to 16.
    pub count: u32,
    /// Pixel processors per row. [paper]: 128. Must be a multiple of 64: the simulator works on
    /// whole 64-pixel groups.
    #[serde(default = "defaults::renderer_side")]
    pub width: u32,
    /// Pixel processor rows. [paper]: 128.
    #[serde(default = "defaults::renderer_side")]
    pub height: u32,
    /// On-chip memory bits per pixel. [paper]: 208.
    #[serde(default = "defaults::pixel_memory_bits")]
    pub pixel_memory_bits: u32,
    /// One-bit flag registers per pixel besides the enable register. [assumed]: 4.
    #[serde(default = "defaults::flag_registers")]
    pub flag_registers: u32,
    /// Backing-store bits per pixel. [paper]: 4,096 (video RAM).
    #[serde(default = "defaults::backing_store_bits")]
    pub backing_store_bits: u32,
    /// Renderer clock in Hz. [paper]: 40 MHz design clock.
    #[serde(default = "defaults::renderer_clock_hz")]
    pub clock_hz: u64,
    #[serde(default)]
    pub qee: QeeConfig,
    #[serde(default)]
    pub cycles: RendererCycleTable,
    #[serde(default)]
    pub backing_store: BackingStoreTiming,
}

/// A signed two's-complement fixed-point format: one sign bit, `int_bits` integer bits and
/// `frac_bits` fractional bits, so `1 + int_bits + frac_bits` bits in all. A value `v` is held as
/// the integer `round(v * 2^frac_bits)`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FixedFormat {
    pub int_bits: u32,
    pub frac_bits: u32,
}

impl FixedFormat {
    /// Total bits, sign included.
    pub fn total_bits(self) -> u32 {
        1 + self.int_bits + self.frac_bits
    }
}

/// The quadratic expression evaluator (QEE).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct QeeConfig {
    /// Format of the coefficients A..F fed to the tree. [assumed]: 1 + 13 + 18 = 32 bits; at least
    /// 18 fractional bits place a hemisphere edge within 0.1 pixel at 128 across
    /// (docs/radiosity.md section 6.2).
    pub coefficient_format: FixedFormat,
    /// Bits of a pixel address (x and y) the tree accepts, region origin included: pixel addresses
    /// lie in 0 .. 2^coordinate_bits. [assumed]: 12, enough for a 1280 x 1024 frame buffer.
    pub coordinate_bits: u32,
    /// Widest result window (shift + bits) a command may ask for. [assumed]: 64.
    pub max_result_bits: u32,
    /// Pipeline fill before the first result bit reaches the pixels, in Renderer cycles.
    /// [assumed]: 8, tree depth for 128 pixels (7 levels) plus one.
    pub latency_cycles: u32,
    /// Extra cycles of a quadratic over a linear expression (same clock). [lineage]: 0.
    pub quadratic_extra_cycles: u32,
}

/// Renderer cycles of every IGC command, as the terms of one cost function
/// (`pxpl5_renderer::cycle_cost`). All [assumed] unless noted; see docs/hardware.md.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct RendererCycleTable {
    /// Cycles the IGC spends decoding any command before the array starts. [assumed]: 20.
    pub igc_overhead: u64,
    /// One enable or flag logic operation. [assumed]: 1 (one one-bit ALU step).
    pub logic: u64,
    /// Extra set-up of a bit-serial add, subtract or compare (on top of one cycle per bit).
    /// [assumed]: 1.
    pub alu_setup: u64,
    /// Cycles per bit of a bit-serial write, copy, add, subtract or compare. [assumed]: 1.
    pub per_bit: u64,
    /// Cycles per (field bit x constant bit) of a multiply by a constant. [assumed]: 1 (shift-add).
    pub multiply_per_bit_pair: u64,
    /// Foreground cycles to start a backing-store transfer. [assumed]: 1.
    pub backing_store_issue: u64,
    /// Cycles per field bit to move a field into the readback port. [assumed]: 1.
    pub readback_per_bit: u64,
    /// Loading a new region origin into the QEE. [assumed]: 0 (overhead only).
    pub set_origin: u64,
}

/// Timing of the backing store (video RAM behind the pixel memory).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BackingStoreTiming {
    /// Bits per pixel moved by one block transfer. [paper]: 32.
    pub block_bits: u32,
    /// Renderer cycles per block, in the background. [assumed]: 4,096 (VRAM serial ports of the
    /// period).
    pub block_cycles: u64,
}

/// The frame buffer node.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FrameBufferConfig {
    /// Pixels per row. [paper]: 1280.
    pub width: u32,
    /// Rows. [paper]: 1024.
    pub height: u32,
    /// Bits stored per pixel. [assumed]: 24 (8 per colour).
    pub bits_per_pixel: u32,
}

/// The host workstation on the ring.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct HostConfig {
    /// Whether the host is a node of the ring. [secondary]: yes.
    pub present: bool,
}

/// Default values, one function per serde default, each citing its source in the field's doc.
pub mod defaults {
    pub fn gp_clock_hz() -> u64 {
        40_000_000
    }
    pub fn ring_channel_clock_hz() -> u64 {
        20_000_000
    }
    pub fn ring_word_bits() -> u32 {
        32
    }
    pub fn one_u32() -> u32 {
        1
    }
    pub fn ring_max_message_words() -> u32 {
        1024
    }
    pub fn ring_queue_words() -> u32 {
        // Not 1,024: a whole 1,024-word message plus its header must fit (see `validate`).
        2048
    }
    pub fn renderer_side() -> u32 {
        128
    }
    pub fn pixel_memory_bits() -> u32 {
        208
    }
    pub fn flag_registers() -> u32 {
        4
    }
    pub fn backing_store_bits() -> u32 {
        4096
    }
    pub fn renderer_clock_hz() -> u64 {
        40_000_000
    }
}

impl Default for GpCostTable {
    fn default() -> Self {
        Self {
            vertex_transform: 24,
            clip_test: 8,
            polygon_setup: 100,
            edge_setup: 20,
            command_encode: 4,
            message_send: 50,
            message_receive: 50,
            ff_accumulate_per_pixel: 4,
            w_table_entry: 30,
            radiosity_update_per_patch: 20,
        }
    }
}

impl Default for QeeConfig {
    fn default() -> Self {
        Self {
            coefficient_format: FixedFormat {
                int_bits: 13,
                frac_bits: 18,
            },
            coordinate_bits: 12,
            max_result_bits: 64,
            latency_cycles: 8,
            quadratic_extra_cycles: 0,
        }
    }
}

impl Default for RendererCycleTable {
    fn default() -> Self {
        Self {
            igc_overhead: 20,
            logic: 1,
            alu_setup: 1,
            per_bit: 1,
            multiply_per_bit_pair: 1,
            backing_store_issue: 1,
            readback_per_bit: 1,
            set_origin: 0,
        }
    }
}

impl Default for BackingStoreTiming {
    fn default() -> Self {
        Self {
            block_bits: 32,
            block_cycles: 4096,
        }
    }
}

impl Default for FrameBufferConfig {
    fn default() -> Self {
        Self {
            width: 1280,
            height: 1024,
            bits_per_pixel: 24,
        }
    }
}

impl Default for HostConfig {
    fn default() -> Self {
        Self { present: true }
    }
}
