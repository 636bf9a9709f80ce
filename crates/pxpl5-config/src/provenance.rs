//! Where every config parameter comes from: one [`Provenance`] entry per leaf field of the
//! serialized config, with its tag and row in `docs/hardware.md` and a short source.
//!
//! The table describes each field's *default* value (the seed's machine). A config file that
//! changes a value says in its own comments where the new value comes from. A test walks the
//! serialized default config and checks that every leaf path has exactly one entry here, so no
//! parameter can be added to the schema undocumented.

use std::fmt;

use ron::ser::path_meta::{Field, Fields};

/// The kind of source of a parameter, as tagged in `docs/hardware.md`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Tag {
    /// Fuchs et al., "Pixel-Planes 5", SIGGRAPH '89.
    Paper,
    /// Goldfeather, "Progressive Radiosity Using Hemispheres", UNC TR89-002.
    Seed,
    /// Later descriptions of the running machine (Kesteloot 1995 and others).
    Secondary,
    /// Pixel-Planes 4, Goldfeather & Fuchs 1986.
    Lineage,
    /// No source found: a named, configurable assumption.
    Assumed,
    /// Not a hardware parameter (a label, free text).
    Choice,
}

impl Tag {
    /// The tag as written in `docs/hardware.md` and in config comments, e.g. `[paper]`.
    pub fn label(self) -> &'static str {
        match self {
            Tag::Paper => "[paper]",
            Tag::Seed => "[seed]",
            Tag::Secondary => "[secondary]",
            Tag::Lineage => "[lineage]",
            Tag::Assumed => "[assumed]",
            Tag::Choice => "[choice]",
        }
    }
}

impl fmt::Display for Tag {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.label())
    }
}

/// The provenance of one leaf field.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Provenance {
    /// Dotted path of the field in the RON file, e.g. `renderer.qee.latency_cycles`.
    pub path: &'static str,
    pub tag: Tag,
    /// Where the default comes from, most often ending with its row of `docs/hardware.md`.
    pub source: &'static str,
    /// For an `[assumed]` field, the values a 1989 machine plausibly had: `pxpl5 sensitivity`
    /// moves the field from one end to the other.
    pub range: Option<PlausibleRange>,
}

/// The plausible values of an assumed field: its low and high ends as a config file writes them
/// (a number, or an enum's variant), and why those.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct PlausibleRange {
    pub low: &'static str,
    pub high: &'static str,
    pub why: &'static str,
}

const fn p(path: &'static str, tag: Tag, source: &'static str) -> Provenance {
    Provenance {
        path,
        tag,
        source,
        range: None,
    }
}

impl Provenance {
    /// This entry with its plausible range.
    const fn range(self, low: &'static str, high: &'static str, why: &'static str) -> Provenance {
        Provenance {
            range: Some(PlausibleRange { low, high, why }),
            ..self
        }
    }
}

use Tag::{Assumed, Choice, Lineage, Paper, Secondary, Seed};

/// One entry per leaf field of the serialized [`crate::MachineConfig`], in file order.
pub const PROVENANCE: &[Provenance] = &[
    p(
        "name",
        Choice,
        "label of the machine, printed in stats and reports",
    ),
    p(
        "description",
        Choice,
        "free text: where the machine comes from",
    ),
    // Graphics Processors.
    p(
        "gp.count",
        Paper,
        "Fuchs et al. 1989: up to 32 GPs; the count is set per config file (the seed states none)",
    ),
    p(
        "gp.clock_hz",
        Secondary,
        "Intel i860 at 40 MHz (docs/hardware.md: Graphics Processors)",
    ),
    p(
        "gp.costs.vertex_transform",
        Assumed,
        "i860 cycles, 4x4 transform about 16-32 at 80 MFLOPS peak (docs/hardware.md: GP costs)",
    )
    .range("16", "48", "16 at the i860's dual-issue peak, 48 with pipeline stalls"),
    p(
        "gp.costs.clip_test",
        Assumed,
        "i860 cycles, six compares (docs/hardware.md: GP costs)",
    )
    .range("6", "16", "six compares at best, with branches at worst"),
    p(
        "gp.costs.polygon_setup",
        Assumed,
        "i860 cycles, plane equation, bounding box, binning (docs/hardware.md: GP costs)",
    )
    .range("50", "200", "half to twice the estimate"),
    p(
        "gp.costs.edge_setup",
        Assumed,
        "i860 cycles per linear or quadratic expression (docs/hardware.md: GP costs)",
    )
    .range("10", "40", "half to twice the estimate"),
    p(
        "gp.costs.command_encode",
        Assumed,
        "i860 cycles per Renderer command (docs/hardware.md: GP costs)",
    )
    .range("2", "8", "half to twice the estimate"),
    p(
        "gp.costs.message_send",
        Assumed,
        "i860 cycles of software per ring message sent (docs/hardware.md: GP costs)",
    )
    .range("20", "200", "a tight driver loop to an interrupt-driven one"),
    p(
        "gp.costs.message_receive",
        Assumed,
        "i860 cycles of software per ring message received (docs/hardware.md: GP costs)",
    )
    .range("20", "200", "a tight driver loop to an interrupt-driven one"),
    p(
        "gp.costs.ff_accumulate_per_pixel",
        Assumed,
        "i860 cycles per read-back pixel of form-factor accumulation (docs/hardware.md: GP costs)",
    )
    .range("2", "8", "half to twice the estimate"),
    p(
        "gp.costs.w_table_entry",
        Assumed,
        "i860 cycles per w-table pixel: two multiplies, two adds, a square root by the i860's \
         reciprocal-square-root estimate and Newton steps (the i860 has no square-root \
         instruction), a scale and a round (docs/hardware.md: GP costs)",
    )
    .range("20", "60", "fewer or more Newton steps"),
    p(
        "gp.costs.radiosity_update_per_patch",
        Assumed,
        "i860 cycles per patch and colour band (docs/hardware.md: GP costs)",
    )
    .range("10", "40", "half to twice the estimate"),
    // Ring.
    p(
        "ring.channels",
        Seed,
        "TR89-002: 80 million words/s \"4 channels on the ring\" (docs/hardware.md: Ring as the \
         seed costs it)",
    ),
    p(
        "ring.channel_clock_hz",
        Seed,
        "TR89-002: 80 Mwords/s over 4 channels = 20 MHz; [paper]'s 5 Gbit/s is 40 MHz with 32-bit \
         words (docs/hardware.md: Ring as the seed costs it, Interconnect)",
    ),
    p(
        "ring.word_bits",
        Assumed,
        "32: TR89-002 counts words, not bits; 32 bits makes [paper]'s 5 Gbit/s 160 Mwords/s \
         (docs/hardware.md: Interconnect)",
    )
    .range("16", "64", "half or twice the word of the seed's count"),
    p(
        "ring.hop_latency_cycles",
        Assumed,
        "1 channel clock per hop (docs/hardware.md: Ring hop latency, header size, ...)",
    )
    .range("1", "4", "a register per node up to a short pipeline"),
    p(
        "ring.header_words",
        Assumed,
        "1 header word per message (docs/hardware.md: Ring hop latency, header size, ...)",
    )
    .range("1", "4", "a routing word up to a header with length and type"),
    p(
        "ring.max_message_words",
        Assumed,
        "messages up to 1,024 words (docs/hardware.md: Ring hop latency, header size, ...)",
    )
    .range("256", "2000", "a quarter of the estimate up to what the queue holds"),
    p(
        "ring.token_policy",
        Assumed,
        "early token release (docs/hardware.md: Ring hop latency, header size, ...)",
    )
    .range("EarlyRelease", "LateRelease", "the two policies the ring knows"),
    p(
        "ring.node_order",
        Assumed,
        "GPs and Renderers interleaved around the ring (no source describes the order)",
    )
    .range("Interleaved", "GpsThenRenderers", "the two orders the ring knows"),
    p(
        "ring.queue_words",
        Assumed,
        "2,048 words per node and direction, shared by its channels: a whole message and its header fit (no source found)",
    )
    .range("1100", "8192", "one message and its header up to four times the estimate"),
    // Renderers.
    p(
        "renderer.count",
        Paper,
        "Fuchs et al. 1989: up to 16 Renderers; the count is set per config file (the seed states \
         none)",
    ),
    p(
        "renderer.width",
        Paper,
        "128 x 128 pixel processors per Renderer (docs/hardware.md: Renderers)",
    ),
    p(
        "renderer.height",
        Paper,
        "128 x 128 pixel processors per Renderer (docs/hardware.md: Renderers)",
    ),
    p(
        "renderer.pixel_memory_bits",
        Paper,
        "208 bits of on-chip memory per pixel (docs/hardware.md: On-chip memory)",
    ),
    p(
        "renderer.flag_registers",
        Assumed,
        "4 one-bit flags besides the [secondary] enable register (docs/hardware.md: Enable \
         register)",
    )
    .range("4", "8", "the 4 the radiosity program uses up to twice that"),
    p(
        "renderer.backing_store_bits",
        Paper,
        "4,096 bits of video RAM per pixel (docs/hardware.md: Backing store)",
    ),
    p(
        "renderer.clock_hz",
        Paper,
        "40 MHz design clock, 1.6 um CMOS (docs/hardware.md: Clock)",
    ),
    p(
        "renderer.qee.coefficient_format.int_bits",
        Assumed,
        "13 integer bits, room for values up to about N^2 (docs/hardware.md: QEE coefficient \
         precision; docs/radiosity.md section 6.3)",
    )
    .range("12", "16", "the fewest the programs need up to a 16-bit integer part"),
    p(
        "renderer.qee.coefficient_format.frac_bits",
        Assumed,
        "18 fractional bits place a hemisphere edge within 0.1 pixel at 128 across \
         (docs/hardware.md: QEE coefficient precision; docs/radiosity.md section 6.2)",
    )
    .range("14", "22", "an edge within a pixel up to what the 64-bit QEE tree holds"),
    p(
        "renderer.qee.coordinate_bits",
        Assumed,
        "12-bit pixel addresses, enough for the 1280 x 1024 frame buffer (no source found)",
    )
    .range("11", "14", "the frame buffer's 1280 up to what the 64-bit QEE tree holds"),
    p(
        "renderer.qee.max_result_bits",
        Assumed,
        "result windows up to 64 bits, chosen per command (docs/hardware.md: QEE coefficient \
         precision and result width)",
    )
    .range("48", "64", "a narrower tree up to the estimate"),
    p(
        "renderer.qee.latency_cycles",
        Assumed,
        "8 cycles of pipeline fill: 7 tree levels for 128 pixels plus one (docs/hardware.md: QEE \
         latency)",
    )
    .range("4", "16", "half to twice the estimate"),
    p(
        "renderer.qee.quadratic_extra_cycles",
        Lineage,
        "0: the quadratic tree runs at the linear one's clock, b + latency cycles \
         (docs/hardware.md: Cost of the quadratic tree; Cycles of a QEE command)",
    ),
    p(
        "renderer.cycles.igc_overhead",
        Assumed,
        "20 cycles of IGC decode per command (docs/hardware.md: IGC overhead per command)",
    )
    .range("10", "40", "half to twice the estimate"),
    p(
        "renderer.cycles.logic",
        Assumed,
        "1 cycle per enable or flag operation (docs/hardware.md: Bit-serial ALU costs)",
    )
    .range("1", "2", "one or two cycles per bit step"),
    p(
        "renderer.cycles.alu_setup",
        Assumed,
        "+1 cycle of set-up per add, subtract or compare (docs/hardware.md: Bit-serial ALU costs)",
    )
    .range("0", "4", "none up to a few cycles"),
    p(
        "renderer.cycles.per_bit",
        Assumed,
        "1 cycle per bit of a bit-serial operation (docs/hardware.md: Bit-serial ALU costs)",
    )
    .range("1", "2", "one or two cycles per bit"),
    p(
        "renderer.cycles.multiply_per_bit_pair",
        Assumed,
        "n x m cycles for an n-bit by m-bit multiply (docs/hardware.md: Bit-serial ALU costs)",
    )
    .range("1", "2", "one or two cycles per bit pair"),
    p(
        "renderer.cycles.backing_store_issue",
        Assumed,
        "1 foreground cycle to start a backing-store transfer (docs/hardware.md: Backing store \
         32-bit block transfer)",
    )
    .range("1", "4", "one to a few cycles"),
    p(
        "renderer.cycles.readback_per_bit",
        Assumed,
        "1 cycle per bit to move a field to the readback port (docs/hardware.md: Where readback \
         goes)",
    )
    .range("1", "4", "one to a few cycles per bit"),
    p(
        "renderer.cycles.set_origin",
        Assumed,
        "0 cycles beyond the IGC overhead to load a region origin (docs/hardware.md: IGC overhead \
         per command)",
    )
    .range("0", "20", "overhead only up to a second command's"),
    p(
        "renderer.backing_store.block_bits",
        Paper,
        "32-bit blocks, also [secondary] (docs/hardware.md: Backing store)",
    ),
    p(
        "renderer.backing_store.block_cycles",
        Assumed,
        "4,096 Renderer cycles per block in the background, VRAM serial ports of the period \
         (docs/hardware.md: Backing store 32-bit block transfer)",
    )
    .range("1024", "16384", "a quarter to four times the estimate"),
    // Frame buffer and host.
    p(
        "frame_buffer.width",
        Paper,
        "1280 x 1024 pixels (docs/hardware.md: Frame buffer)",
    ),
    p(
        "frame_buffer.height",
        Paper,
        "1280 x 1024 pixels (docs/hardware.md: Frame buffer)",
    ),
    p(
        "frame_buffer.bits_per_pixel",
        Assumed,
        "24 bits, 8 per colour (no source found)",
    )
    .range("24", "32", "8 per colour, with or without 8 more"),
    p(
        "host.present",
        Secondary,
        "a host workstation is attached to the ring (docs/hardware.md: Host)",
    ),
];

/// The provenance entry of a dotted field path, if there is one.
pub fn lookup(path: &str) -> Option<&'static Provenance> {
    PROVENANCE.iter().find(|e| e.path == path)
}

/// The table as ron path metadata: each leaf gets one doc line `[tag] source`, which ron's
/// pretty-printer writes as a `///` comment above the field.
pub(crate) fn path_meta() -> Field {
    let mut root = Field::empty();
    for entry in PROVENANCE {
        let parts: Vec<&str> = entry.path.split('.').collect();
        let mut doc = format!("{} {}", entry.tag.label(), entry.source);
        if let Some(r) = entry.range {
            doc += &format!("; plausible range {} to {} ({})", r.low, r.high, r.why);
        }
        attach(&mut root, &parts, &doc);
    }
    root
}

fn attach(field: &mut Field, parts: &[&str], doc: &str) {
    match parts.split_first() {
        None => {
            field.with_doc(doc);
        }
        Some((head, rest)) => {
            if field.fields().is_none() {
                field.with_fields(Some(Fields::new()));
            }
            if let Some(fields) = field.fields_mut() {
                attach(fields.field(*head), rest, doc);
            }
        }
    }
}
