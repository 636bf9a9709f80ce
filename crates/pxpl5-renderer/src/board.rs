//! One Renderer board: validates each IGC command, charges its cycles from the cycle table,
//! interlocks with the backing store, and hands the pixel work to the engine of the chosen
//! fidelity level.
//!
//! Time on a board is a count of Renderer cycles since it was built; the board keeps no clock of
//! its own, only the cycle at which it is next free ([`Board::free_at`]). A command starts when the
//! board is free and every backing-store transfer touching its fields has finished (the wait is a
//! *stall*, counted apart from work), and ends [`cycle_cost`] cycles later. A backing-store
//! transfer runs in the background on the board's one transfer engine: transfers queue behind each
//! other, and the foreground goes on.

use std::collections::BTreeMap;

use pxpl5_config::RendererConfig;
use pxpl5_sim::Cycles;
use sha2::{Digest, Sha256};
use thiserror::Error;

use crate::command::{Bit, Command, Field, LogicOp, Rect};
use crate::cycles::{backing_store_blocks, backing_store_cycles, cycle_cost};
use crate::engine::bit::BitEngine;
use crate::engine::integer::IntegerEngine;
use crate::engine::sparse::SparseEngine;
use crate::engine::{DepthTest, Geometry, PixelEngine, QeeSink, Registers};
use crate::qee::{COEFFICIENT_NAMES, QeeExpr, Streams, Window};
use crate::readback::{self, ReadbackMessage};
use crate::workers::{Remote, Workers};

/// How the pixel work is simulated. Cycle counts are identical at every level, since they come
/// from the cycle table alone; results are identical at every exact level.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Fidelity {
    /// Every micro-cycle on bit-planes: the reference.
    Bit,
    /// Per-pixel integer arithmetic with the same semantics.
    Integer,
    /// The integer level with the one-bit registers kept symbolically until something reads
    /// them (`engine::sparse`): what a scene does not require is not simulated. Same results.
    Sparse,
    /// No pixel work at all: every command costs its cycles and changes nothing, and a readback
    /// carries zeros in messages of the right size. Approximate: a program whose control flow
    /// depends on pixel values (item buffers) must get them elsewhere, and its timing may then
    /// differ from an exact level's; the error is measured (`pxpl5 tradeoff`), never assumed.
    Timing,
}

impl Fidelity {
    pub fn name(self) -> &'static str {
        match self {
            Fidelity::Bit => "bit",
            Fidelity::Integer => "integer",
            Fidelity::Sparse => "sparse",
            Fidelity::Timing => "timing",
        }
    }

    /// Whether the level simulates pixel values (every level but [`Fidelity::Timing`]).
    pub fn has_pixels(self) -> bool {
        self != Fidelity::Timing
    }
}

impl std::str::FromStr for Fidelity {
    type Err = String;
    fn from_str(s: &str) -> Result<Fidelity, String> {
        match s {
            "bit" => Ok(Fidelity::Bit),
            "integer" => Ok(Fidelity::Integer),
            "sparse" => Ok(Fidelity::Sparse),
            "timing" => Ok(Fidelity::Timing),
            _ => Err(format!(
                "unknown fidelity `{s}` (expected bit, integer, sparse or timing)"
            )),
        }
    }
}

/// A command the board cannot execute: a program's mistake, never a panic.
#[derive(Clone, Debug, PartialEq, Eq, Error)]
pub enum CommandError {
    #[error("{kind}: field {offset}+{bits} lies outside the {memory} bits of pixel memory")]
    FieldOutside {
        kind: &'static str,
        offset: u32,
        bits: u32,
        memory: u32,
    },
    #[error("{kind}: a field must have 1 to 64 bits (got {bits})")]
    FieldWidth { kind: &'static str, bits: u32 },
    #[error("{kind}: flag {flag} does not exist (the board has {flags} flag registers)")]
    NoSuchFlag {
        kind: &'static str,
        flag: u8,
        flags: u32,
    },
    #[error("{kind}: fields {a:?} and {b:?} overlap without being the same bits")]
    Overlap {
        kind: &'static str,
        a: Field,
        b: Field,
    },
    #[error("{kind}: raw coefficient {name} = {raw} does not fit {bits}-bit QEE coefficients")]
    Coefficient {
        kind: &'static str,
        name: &'static str,
        raw: i64,
        bits: u32,
    },
    #[error(
        "{kind}: result window shift {shift} + bits {bits} must be 1 to {max} bits \
         (renderer.qee.max_result_bits)"
    )]
    Window {
        kind: &'static str,
        shift: u32,
        bits: u32,
        max: u32,
    },
    #[error("{kind}: window of {window} bits does not match field of {field} bits")]
    WidthMismatch {
        kind: &'static str,
        window: u32,
        field: u32,
    },
    #[error("{kind}: value {value:#x} does not fit a {bits}-bit field")]
    Constant {
        kind: &'static str,
        value: u64,
        bits: u32,
    },
    #[error("mul_const: k = {k} does not fit {k_bits}-bit two's complement (k_bits 1 to 32)")]
    Multiplier { k: i64, k_bits: u32 },
    #[error(
        "set_origin: origin ({x}, {y}) puts pixel addresses beyond 2^{coordinate_bits} \
         (renderer.qee.coordinate_bits)"
    )]
    Origin {
        x: u32,
        y: u32,
        coordinate_bits: u32,
    },
    #[error("{kind}: blocks {first}..{end} lie outside the {blocks} blocks of the backing store")]
    BackingStore {
        kind: &'static str,
        first: u32,
        end: u32,
        blocks: u32,
    },
    #[error("write_pixels: {got} values for a rectangle of {want} pixels")]
    PixelCount { got: usize, want: usize },
    #[error("rectangle {rect:?} is empty or outside the {width} x {height} array")]
    Rect { rect: Rect, width: u32, height: u32 },
}

/// What executing one command did.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Executed {
    /// Cycle the command started (after any stall).
    pub start: Cycles,
    /// Cycle the board is free again.
    pub end: Cycles,
    /// Cycles waited for the backing store before starting.
    pub stall: Cycles,
    /// The messages a readback sends.
    pub readback: Option<ReadbackStream>,
}

/// The messages a readback sends, and to whom.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ReadbackStream {
    /// The ring node the messages are for (opaque to the board).
    pub dest: u32,
    /// The command's tag, passed through.
    pub tag: u32,
    /// Bits per pixel value: the field's width.
    pub bits: u32,
    /// The field's rows in order, in messages whose ring words are counted as [`crate::readback`]
    /// documents.
    pub messages: Vec<ReadbackMessage>,
}

/// Per command kind: how many ran and the cycles they took.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct KindStats {
    pub count: u64,
    pub cycles: u64,
}

/// Simulated statistics of a board (never host figures).
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct BoardStats {
    pub commands: u64,
    /// Cycles spent executing commands.
    pub busy: Cycles,
    /// Cycles commands waited for the backing store.
    pub stall: Cycles,
    /// Cycles the backing-store engine moved blocks.
    pub backing_store_busy: Cycles,
    pub by_kind: BTreeMap<&'static str, KindStats>,
}

/// A transfer in flight: which bits of pixel memory, and when it is done.
#[derive(Clone, Copy, Debug)]
struct Transfer {
    field: Field,
    done: Cycles,
}

/// The board's pixel engine, at its fidelity level. One per board, in its boxed [`Pixels`],
/// which a worker adopts at most once: the levels' different sizes cost nothing, where boxing
/// the largest would add an indirection to every command.
#[allow(clippy::large_enum_variant)]
enum Engine {
    Bit(BitEngine),
    Integer(IntegerEngine),
    Sparse(SparseEngine),
}

impl Engine {
    fn get(&self) -> &dyn PixelEngine {
        match self {
            Engine::Bit(e) => e,
            Engine::Integer(e) => e,
            Engine::Sparse(e) => e,
        }
    }
    fn get_mut(&mut self) -> &mut dyn PixelEngine {
        match self {
            Engine::Bit(e) => e,
            Engine::Integer(e) => e,
            Engine::Sparse(e) => e,
        }
    }
}

/// One Renderer board.
pub struct Board {
    cfg: RendererConfig,
    /// The cycle at which the last command ends (or the board stops idling).
    free_at: Cycles,
    backing_store_free: Cycles,
    in_flight: Vec<Transfer>,
    stats: BoardStats,
    /// Per command kind, by [`Command::kind_index`] (`stats` puts them into `by_kind`).
    kinds: [KindStats; Command::KINDS.len()],
    /// The pixel state, here or on a host worker thread ([`Board::on_workers`]).
    pixels: Side,
}

/// Where a board's pixel work runs.
enum Side {
    Here(Box<Pixels>),
    Away(Remote),
    /// Nowhere: [`Fidelity::Timing`].
    Blank(Blank),
}

/// What a board without pixel state ([`Fidelity::Timing`]) needs to answer a readback: the sizes
/// of its messages. It reads as a board that never ran a command: memory zero, every pixel
/// enabled, flags clear.
struct Blank {
    cfg: RendererConfig,
    ring_word_bits: u32,
    max_message_words: u32,
}

impl Blank {
    fn apply(&self, cmd: &Command) -> Option<ReadbackStream> {
        let Command::Readback {
            field,
            rect,
            dest,
            tag,
        } = *cmd
        else {
            return None;
        };
        let zeros = vec![0; rect.width as usize * rect.height as usize];
        Some(ReadbackStream {
            dest,
            tag,
            bits: field.bits,
            messages: readback::messages(
                zeros,
                rect,
                field.bits,
                self.ring_word_bits,
                self.max_message_words,
            ),
        })
    }

    fn pixels(&self) -> usize {
        self.cfg.width as usize * self.cfg.height as usize
    }

    fn image(&self) -> BoardImage {
        let geometry = Geometry::new(self.cfg.width, self.cfg.height);
        let registers = Registers::new(geometry, self.cfg.flag_registers as usize);
        BoardImage {
            enable: registers.enable,
            flags: registers.flags,
            memory: vec![0; geometry.groups * self.cfg.pixel_memory_bits as usize],
            backing_store: BTreeMap::new(),
        }
    }

    fn bit_values(&self, b: Bit) -> Vec<bool> {
        vec![b == Bit::Enable; self.pixels()]
    }
}

/// A board's pixel state and the work that changes it: everything but time. A board's pixels
/// depend only on its commands in order, so this part can run on another host thread, ahead of
/// the machine, as long as a readback waits for it ([`crate::workers`]).
pub(crate) struct Pixels {
    cfg: RendererConfig,
    geometry: Geometry,
    ring_word_bits: u32,
    /// Most ring words per readback message (see [`Board::stream_readbacks`]).
    max_message_words: u32,
    engine: Engine,
    origin: (u32, u32),
    /// Backing store, allocated a block at a time on first save: block -> block_bits planes.
    backing_store: BTreeMap<u32, Vec<u64>>,
    /// Host work only: the groups with an enabled pixel, listed when a command first needs them
    /// after enable last changed (`enabled_valid`), so the commands between two writes to enable
    /// share one list; every group, for a command that can change disabled ones; and the QEE's
    /// streams, reused by every command.
    enabled: Vec<u32>,
    enabled_valid: bool,
    /// Set when a command combined into enable by an op that keeps 0 at 0 over a valid list
    /// (a receiver's depth test): enable only lost pixels, so the list holds every enabled
    /// group and is filtered, not made anew from the whole board, when next needed.
    enabled_superset: bool,
    all_groups: Vec<u32>,
    streams: Streams,
    /// A depth test [`Pixels::apply`] holds back to run as one pass.
    held: Option<Held>,
}

/// The start of a receiver's depth test, held back: its `QeeCompare` into enable by AND, and
/// whether the same expression's `QeeStore` into the compared field followed it.
struct Held {
    compare: Command,
    store: bool,
}

impl Held {
    /// Whether a `QeeStore` of `expr`'s `window` into `dst` stores what the compare compared.
    fn stored_by(&self, expr: &QeeExpr, window: Window, dst: Field) -> bool {
        matches!(
            self.compare,
            Command::QeeCompare { expr: e, window: w, field, .. }
                if e == *expr && w == window && field == dst
        )
    }
}

impl Board {
    /// A board of `cfg` (already validated by `pxpl5_config`) whose readback packs ring words of
    /// `ring_word_bits` bits, all in one message unless [`Board::stream_readbacks`] limits them.
    pub fn new(cfg: &RendererConfig, ring_word_bits: u32, fidelity: Fidelity) -> Board {
        let geometry = Geometry::new(cfg.width, cfg.height);
        let flags = cfg.flag_registers as usize;
        let engine = match fidelity {
            Fidelity::Bit => Engine::Bit(BitEngine::new(geometry, cfg.pixel_memory_bits, flags)),
            Fidelity::Integer => {
                Engine::Integer(IntegerEngine::new(geometry, cfg.pixel_memory_bits, flags))
            }
            Fidelity::Sparse => {
                Engine::Sparse(SparseEngine::new(geometry, cfg.pixel_memory_bits, flags))
            }
            Fidelity::Timing => {
                let blank = Blank {
                    cfg: cfg.clone(),
                    ring_word_bits,
                    max_message_words: u32::MAX,
                };
                return Board::keeping_time(cfg, Side::Blank(blank));
            }
        };
        let pixels = Pixels {
            cfg: cfg.clone(),
            geometry,
            ring_word_bits,
            max_message_words: u32::MAX,
            engine,
            origin: (0, 0),
            backing_store: BTreeMap::new(),
            enabled: Vec::new(),
            enabled_valid: false,
            enabled_superset: false,
            all_groups: (0..geometry.groups as u32).collect(),
            streams: Streams::new(&QeeExpr::default(), (0, 0), 0, 0),
            held: None,
        };
        Board::keeping_time(cfg, Side::Here(Box::new(pixels)))
    }

    /// A board at cycle zero whose pixel work is `pixels`.
    fn keeping_time(cfg: &RendererConfig, pixels: Side) -> Board {
        Board {
            cfg: cfg.clone(),
            free_at: Cycles::ZERO,
            backing_store_free: Cycles::ZERO,
            in_flight: Vec::new(),
            stats: BoardStats::default(),
            kinds: Default::default(),
            pixels,
        }
    }

    /// Do this board's pixel work on a host thread of `workers` from now on. Results are
    /// identical: the thread applies the board's commands in order, and a readback (or any look
    /// at the pixels) waits until it has caught up.
    pub fn on_workers(mut self, workers: &Workers) -> Board {
        if let Side::Here(pixels) = self.pixels {
            self.pixels = Side::Away(workers.adopt(pixels));
        }
        self
    }

    /// Send readbacks in messages of at most `max_message_words` ring words (whole rows, at least
    /// one per message), as the ring's longest message requires.
    pub fn stream_readbacks(mut self, max_message_words: u32) -> Board {
        match &mut self.pixels {
            Side::Here(p) => p.max_message_words = max_message_words,
            Side::Blank(b) => b.max_message_words = max_message_words,
            Side::Away(_) => panic!("stream_readbacks after on_workers: set it first"),
        }
        self
    }

    /// The cycle at which the board is free for its next command: when its last command ended,
    /// or later if it was told to idle. The next command starts there, or later if it
    /// stalls for the backing store.
    pub fn free_at(&self) -> Cycles {
        self.free_at
    }

    /// Let the board sit idle until `t` (the machine's scheduler does this when no command is
    /// waiting): afterwards it is free at the later of `t` and [`Board::free_at`].
    pub fn idle_until(&mut self, t: Cycles) {
        self.free_at = self.free_at.max(t);
    }

    /// The board's statistics so far.
    pub fn stats(&self) -> BoardStats {
        let mut stats = self.stats.clone();
        for (name, k) in Command::KINDS.iter().zip(&self.kinds) {
            if k.count > 0 {
                stats.by_kind.insert(name, k.clone());
            }
        }
        stats
    }

    /// Execute one command: validate it, wait for interlocks, do the pixel work, advance time.
    /// Inlined into its caller: returned, the result was written a field at a time and copied
    /// whole by 16-byte loads that cannot take 8-byte stores' values forwarded (`perf
    /// annotate`: 29 % of the machine's `start_next`).
    #[inline(always)]
    pub fn execute(&mut self, cmd: &Command) -> Result<Executed, CommandError> {
        self.validate(cmd)?;
        let cost = cycle_cost(cmd, &self.cfg);

        // Backing-store interlock: wait for transfers touching this command's fields (a fence
        // waits for every transfer in flight). Most commands find none in flight, and skip
        // listing their fields.
        let ready = if self.in_flight.is_empty() {
            Cycles::ZERO
        } else {
            self.in_flight
                .iter()
                .filter(|t| {
                    matches!(cmd, Command::Fence)
                        || cmd.fields().iter().any(|f| f.overlaps(t.field))
                })
                .map(|t| t.done)
                .max()
                .unwrap_or(Cycles::ZERO)
        };
        let start = self.free_at.max(ready);
        let stall = start - self.free_at;
        let end = start + cost;
        if !self.in_flight.is_empty() {
            self.in_flight.retain(|t| t.done > start);
        }

        if let Command::Save { field, .. } | Command::Load { field, .. } = *cmd {
            self.start_transfer(field, end);
        }
        let readback = match &mut self.pixels {
            Side::Here(p) => p.apply(cmd),
            Side::Away(r) => r.apply(cmd),
            Side::Blank(b) => b.apply(cmd),
        };

        self.free_at = end;
        self.stats.commands += 1;
        self.stats.busy += cost;
        self.stats.stall += stall;
        let k = &mut self.kinds[cmd.kind_index()];
        k.count += 1;
        k.cycles += cost.0;
        Ok(Executed {
            start,
            end,
            stall,
            readback,
        })
    }

    /// Queue a background transfer of `field` on the backing-store engine, issued at `issued`.
    fn start_transfer(&mut self, field: Field, issued: Cycles) {
        let start = issued.max(self.backing_store_free);
        let busy = backing_store_cycles(field, &self.cfg);
        let done = start + busy;
        self.backing_store_free = done;
        self.stats.backing_store_busy += busy;
        self.in_flight.push(Transfer { field, done });
    }

    /// Whether `cmd` can run on this board: its fields, registers, coefficients and window,
    /// constants and rectangles; else the error that names what is wrong.
    #[inline]
    fn validate(&self, cmd: &Command) -> Result<(), CommandError> {
        let kind = cmd.kind();
        // The two kinds without fields that make up most of a receiver's commands (17 of a
        // hemisphere receiver's 20) checked here, in the order `validate_other` checks the
        // rest, without listing their (no) fields: 0.9 M of `bench renderer`'s hemisphere
        // stream's 33.4 M instructions.
        match *cmd {
            Command::Logic { dst, a, b, .. } => {
                self.check_bit(kind, dst)?;
                self.check_bit(kind, a)?;
                self.check_bit(kind, b)
            }
            Command::QeeSign {
                ref expr,
                window,
                dst,
                ..
            } => {
                self.check_qee(kind, expr, window)?;
                self.check_bit(kind, dst)
            }
            _ => self.validate_other(cmd),
        }
    }

    /// [`Board::validate`] for every kind of command but Logic and QeeSign, which it checks
    /// itself.
    fn validate_other(&self, cmd: &Command) -> Result<(), CommandError> {
        let kind = cmd.kind();
        let memory = self.cfg.pixel_memory_bits;
        // The command's fields, listed once for both checks.
        let fields = cmd.fields();
        for &f in fields.iter() {
            if !(1..=64).contains(&f.bits) {
                return Err(CommandError::FieldWidth { kind, bits: f.bits });
            }
            if f.end() > memory {
                return Err(CommandError::FieldOutside {
                    kind,
                    offset: f.offset,
                    bits: f.bits,
                    memory,
                });
            }
        }
        for (i, a) in fields.iter().enumerate() {
            for b in &fields[i + 1..] {
                let forbidden = match cmd {
                    // A shift-and-add multiply reads its source after writing the accumulator.
                    Command::MulConst { .. } => a.overlaps(*b),
                    _ => a.overlaps_partially(*b),
                };
                if forbidden {
                    return Err(CommandError::Overlap { kind, a: *a, b: *b });
                }
            }
        }
        let check_bit = |b: Bit| self.check_bit(kind, b);
        if let Some((expr, window)) = cmd.qee() {
            self.check_qee(kind, expr, window)?;
        }
        match *cmd {
            Command::SetOrigin { x, y } => {
                let limit = 1u64 << self.cfg.qee.coordinate_bits;
                if u64::from(x) + u64::from(self.cfg.width) > limit
                    || u64::from(y) + u64::from(self.cfg.height) > limit
                {
                    return Err(CommandError::Origin {
                        x,
                        y,
                        coordinate_bits: self.cfg.qee.coordinate_bits,
                    });
                }
            }
            // Checked by `validate`.
            Command::Logic { .. } | Command::QeeSign { .. } => {}
            Command::QeeStore { window, dst, .. } | Command::QeeAdd { window, dst, .. } => {
                if window.bits != dst.bits {
                    return Err(CommandError::WidthMismatch {
                        kind,
                        window: window.bits,
                        field: dst.bits,
                    });
                }
            }
            Command::QeeCompare {
                window, field, dst, ..
            } => {
                check_bit(dst)?;
                if window.bits != field.bits {
                    return Err(CommandError::WidthMismatch {
                        kind,
                        window: window.bits,
                        field: field.bits,
                    });
                }
            }
            Command::WriteConst { dst, value } => {
                if value & !crate::qee::mask(dst.bits) != 0 {
                    return Err(CommandError::Constant {
                        kind,
                        value,
                        bits: dst.bits,
                    });
                }
            }
            Command::Compare { dst, .. } => check_bit(dst)?,
            Command::MulConst { k, k_bits, .. } => {
                let fits = (1..=32).contains(&k_bits)
                    && k >= -(1i64 << (k_bits - 1))
                    && k < (1i64 << (k_bits - 1));
                if !fits {
                    return Err(CommandError::Multiplier { k, k_bits });
                }
            }
            Command::Save { field, block } | Command::Load { field, block } => {
                let blocks = self.cfg.backing_store_bits / self.cfg.backing_store.block_bits;
                let end = block.saturating_add(backing_store_blocks(field, &self.cfg));
                if end > blocks {
                    return Err(CommandError::BackingStore {
                        kind,
                        first: block,
                        end,
                        blocks,
                    });
                }
            }
            Command::WritePixels {
                dst,
                rect,
                ref values,
            } => {
                self.check_rect(rect)?;
                // In u64: a rectangle of the largest array (2^16 x 2^16) has 2^32 pixels.
                let want = u64::from(rect.width) * u64::from(rect.height);
                if values.len() as u64 != want {
                    return Err(CommandError::PixelCount {
                        got: values.len(),
                        want: want as usize,
                    });
                }
                if let Some(&v) = values
                    .iter()
                    .find(|&&v| v & !crate::qee::mask(dst.bits) != 0)
                {
                    return Err(CommandError::Constant {
                        kind,
                        value: v,
                        bits: dst.bits,
                    });
                }
            }
            Command::Readback { rect, .. } => self.check_rect(rect)?,
            Command::Copy { .. } | Command::Add { .. } | Command::Sub { .. } | Command::Fence => {}
        }
        Ok(())
    }

    /// A QEE command's coefficients and window, for command kind `kind`.
    #[inline]
    fn check_qee(
        &self,
        kind: &'static str,
        expr: &QeeExpr,
        window: Window,
    ) -> Result<(), CommandError> {
        let bits = self.cfg.qee.coefficient_format.total_bits();
        let (lo, hi) = (-(1i64 << (bits - 1)), (1i64 << (bits - 1)) - 1);
        // Every coefficient in range, the usual case, in one test without a branch per
        // coefficient (half the validation of a QEE command); else find the one that is not.
        let raw = expr.raw();
        let fits = |r: i64| r.wrapping_sub(lo) as u64 <= hi.wrapping_sub(lo) as u64;
        if !raw.iter().fold(true, |all, &r| all & fits(r)) {
            let i = raw.iter().position(|&r| !fits(r)).unwrap_or_default();
            return Err(CommandError::Coefficient {
                kind,
                name: COEFFICIENT_NAMES[i],
                raw: raw[i],
                bits,
            });
        }
        let max = self.cfg.qee.max_result_bits.min(64);
        if window.bits == 0 || u64::from(window.shift) + u64::from(window.bits) > max.into() {
            return Err(CommandError::Window {
                kind,
                shift: window.shift,
                bits: window.bits,
                max,
            });
        }
        Ok(())
    }

    /// A one-bit register that exists.
    fn check_bit(&self, kind: &'static str, b: Bit) -> Result<(), CommandError> {
        let flags = self.cfg.flag_registers;
        match b {
            Bit::Flag(i) if u32::from(i) >= flags => Err(CommandError::NoSuchFlag {
                kind,
                flag: i,
                flags,
            }),
            _ => Ok(()),
        }
    }

    /// A rectangle must be non-empty and inside the array.
    fn check_rect(&self, rect: Rect) -> Result<(), CommandError> {
        let (w, h) = (self.cfg.width, self.cfg.height);
        if rect.width == 0
            || rect.height == 0
            || u64::from(rect.x) + u64::from(rect.width) > u64::from(w)
            || u64::from(rect.y) + u64::from(rect.height) > u64::from(h)
        {
            return Err(CommandError::Rect {
                rect,
                width: w,
                height: h,
            });
        }
        Ok(())
    }

    /// The board's state in the canonical form both fidelity levels share. `&mut`: the pixel
    /// work a level holds back (a receiver's depth test) runs first.
    pub fn image(&mut self) -> BoardImage {
        match &mut self.pixels {
            Side::Here(p) => p.image(),
            Side::Away(r) => r.image(),
            Side::Blank(b) => b.image(),
        }
    }

    /// Raw values of a field over the whole array, row by row (for tests and pictures).
    pub fn field_values(&mut self, field: Field) -> Vec<u64> {
        match &mut self.pixels {
            Side::Here(p) => p.field_values(field),
            Side::Away(r) => r.field_values(field),
            Side::Blank(b) => vec![0; b.pixels()],
        }
    }

    /// One one-bit register of every pixel, row by row.
    pub fn bit_values(&mut self, b: Bit) -> Vec<bool> {
        match &mut self.pixels {
            Side::Here(p) => p.bit_values(b),
            Side::Away(r) => r.bit_values(b),
            Side::Blank(blank) => blank.bit_values(b),
        }
    }
}

impl Pixels {
    /// The pixel (or board-state) effect of a validated command, and the messages of a readback.
    ///
    /// At the `integer` and `sparse` levels a receiver's depth test (a `QeeCompare` into enable
    /// by AND, then the same expression's `QeeStore` into the compared field, then a
    /// `WriteConst`) is held back until its last command arrives or another does, and then runs
    /// as one [`PixelEngine::depth_test`]: host work only, since a board's time never depends on
    /// its pixels and every look at them ([`Pixels::settle`]) runs what is held first.
    pub(crate) fn apply(&mut self, cmd: &Command) -> Option<ReadbackStream> {
        // A command the sparse level defers (17 of a hemisphere receiver's 20) returns here,
        // before the set-up the others need; not while a depth test is held, which must run
        // on the registers as they were before it.
        let tried = self.held.is_none() && matches!(self.engine, Engine::Sparse(_));
        if tried && self.defer(cmd) {
            return None;
        }
        self.apply_after_deferral(cmd, tried)
    }

    /// The sparse level's deferral of `cmd`, if it takes it; whether it did.
    fn defer(&mut self, cmd: &Command) -> bool {
        let Engine::Sparse(e) = &mut self.engine else {
            return false;
        };
        let deferred = e.defer(cmd, self.origin);
        // A changed enable makes the list of enabled groups stale.
        if e.take_enable_materialised() || (deferred && cmd.writes_enable()) {
            self.enabled_valid = false;
        }
        deferred
    }

    /// [`Pixels::apply`] for a command the sparse level did not defer (`tried`) or has not
    /// been offered yet.
    #[inline(never)]
    fn apply_after_deferral(&mut self, cmd: &Command, tried: bool) -> Option<ReadbackStream> {
        if let Some(mut held) = self.held.take() {
            match *cmd {
                Command::QeeStore {
                    ref expr,
                    window,
                    dst,
                } if !held.store && held.stored_by(expr, window, dst) => {
                    held.store = true;
                    self.held = Some(held);
                    return None;
                }
                Command::WriteConst { dst, value } => {
                    self.depth_test(&held, Some((dst, value)));
                    return None;
                }
                _ => self.depth_test(&held, None),
            }
        }
        let holds = matches!(self.engine, Engine::Integer(_) | Engine::Sparse(_))
            && matches!(
                *cmd,
                Command::QeeCompare {
                    dst: Bit::Enable,
                    combine: LogicOp::AND,
                    ..
                }
            );
        if holds {
            self.held = Some(Held {
                compare: cmd.clone(),
                store: false,
            });
            return None;
        }
        self.apply_now(cmd, tried)
    }

    /// Run what [`Pixels::apply`] holds back, if anything: before any look at the pixels.
    pub(crate) fn settle(&mut self) {
        if let Some(held) = self.held.take() {
            self.depth_test(&held, None);
        }
    }

    /// The held depth test, its compare's `WriteConst` `id` included if any.
    fn depth_test(&mut self, held: &Held, id: Option<(Field, u64)>) {
        let Command::QeeCompare {
            window, field, cmp, ..
        } = held.compare
        else {
            unreachable!("only a QeeCompare is held");
        };
        // The compare's preparation, as if it ran alone; no level defers a compare.
        let every_group = self.prepare(&held.compare, false);
        debug_assert_eq!(
            every_group,
            Some(false),
            "a compare by AND lists its groups"
        );
        let test = DepthTest {
            field,
            cmp,
            store: held.store,
            id,
        };
        let engine = self.engine.get_mut();
        engine.depth_test(&self.streams, window, test, &self.enabled);
    }

    /// What every command needs before its pixel work: the sparse level's deferral (`None`: the
    /// command is deferred, nothing more to do) and materialisation, the list of enabled groups
    /// brought up to date if the command needs it, and the QEE's streams set to its expression.
    /// `Some(every_group)`: whether the command works on every group rather than the listed ones.
    /// `tried`: the sparse level was offered the command already and did not defer it.
    fn prepare(&mut self, cmd: &Command, tried: bool) -> Option<bool> {
        // The sparse level defers what it can and materialises what the rest reads.
        if !tried && self.defer(cmd) {
            return None;
        }
        if let Engine::Sparse(e) = &mut self.engine {
            e.prepare(cmd);
            if e.take_enable_materialised() {
                self.enabled_valid = false;
            }
        }
        // The groups the command can change, listed only for the commands that need them (a Logic
        // or SetOrigin command, half a hemisphere stream, needs none): `None` for a gated write
        // (any enabled pixel), else how it combines into a one-bit register.
        let writes = match *cmd {
            Command::QeeSign { dst, combine, .. }
            | Command::QeeCompare { dst, combine, .. }
            | Command::Compare { dst, combine, .. } => Some(enable_write(dst, combine)),
            Command::QeeStore { .. }
            | Command::QeeAdd { .. }
            | Command::WriteConst { .. }
            | Command::Copy { .. }
            | Command::Add { .. }
            | Command::Sub { .. }
            | Command::MulConst { .. } => Some(None),
            _ => None,
        };
        let every_group = matches!(writes, Some(Some(op)) if !op.keeps_zero());
        if writes.is_some() && !every_group {
            let engine = self.engine.get();
            let regs = engine.registers();
            if !self.enabled_valid {
                engine.enabled_groups(&mut self.enabled);
                self.enabled_valid = true;
            } else if self.enabled_superset {
                self.enabled.retain(|&g| regs.enable[g as usize] != 0);
            }
            self.enabled_superset = false;
        }
        // Enable changes only through a command whose destination it is; the list is made anew
        // when a later command needs it, or filtered if the command could only clear pixels of
        // the groups it listed.
        if cmd.writes_enable() {
            match writes {
                Some(Some(op)) if op.keeps_zero() && self.enabled_valid => {
                    self.enabled_superset = true;
                }
                _ => self.enabled_valid = false,
            }
        }
        if let Some((expr, _)) = cmd.qee() {
            let g = self.geometry;
            match self.engine {
                Engine::Bit(_) => self.streams.fill(expr, self.origin, g.width, g.height),
                Engine::Integer(_) | Engine::Sparse(_) => self.streams.set_expr(expr, self.origin),
            }
        }
        Some(every_group)
    }

    /// A command applied at once.
    fn apply_now(&mut self, cmd: &Command, tried: bool) -> Option<ReadbackStream> {
        let every_group = self.prepare(cmd, tried)?;
        let active = if every_group {
            &self.all_groups[..]
        } else {
            &self.enabled[..]
        };
        let s = &self.streams;
        let engine = self.engine.get_mut();
        match *cmd {
            Command::SetOrigin { x, y } => self.origin = (x, y),
            Command::Logic { dst, a, b, op } => engine.registers_mut().logic(dst, a, b, op),
            Command::QeeSign {
                window,
                dst,
                combine,
                ..
            } => engine.qee(s, window, QeeSink::Sign { dst, combine }, active),
            Command::QeeStore { window, dst, .. } => {
                engine.qee(s, window, QeeSink::Store { dst }, active)
            }
            Command::QeeCompare {
                window,
                field,
                cmp,
                dst,
                combine,
                ..
            } => {
                let sink = QeeSink::Compare {
                    field,
                    cmp,
                    dst,
                    combine,
                };
                engine.qee(s, window, sink, active);
            }
            Command::QeeAdd { window, dst, .. } => {
                engine.qee(s, window, QeeSink::Add { dst }, active)
            }
            Command::WriteConst { dst, value } => engine.write_const(dst, value, active),
            Command::Copy { dst, src } => engine.copy(dst, src, active),
            Command::Add { dst, a, b } => engine.add_sub(dst, a, b, false, active),
            Command::Sub { dst, a, b } => engine.add_sub(dst, a, b, true, active),
            Command::Compare {
                a,
                b,
                cmp,
                dst,
                combine,
            } => engine.compare(a, b, cmp, dst, combine, active),
            Command::MulConst {
                dst,
                src,
                k,
                k_bits,
            } => engine.mul_const(dst, src, k, k_bits, active),
            Command::Save { field, block } => {
                // The data are copied at issue: the interlock keeps every later access to the
                // field behind the transfer's end, so no command can see the difference.
                let planes = self.engine.get().read_planes(field);
                let groups = self.geometry.groups;
                let block_bits = self.cfg.backing_store.block_bits as usize;
                for (i, chunk) in planes.chunks(block_bits * groups).enumerate() {
                    let stored = self
                        .backing_store
                        .entry(block + i as u32)
                        .or_insert_with(|| vec![0; block_bits * groups]);
                    stored[..chunk.len()].copy_from_slice(chunk);
                }
            }
            Command::Load { field, block } => {
                let groups = self.geometry.groups;
                let block_bits = self.cfg.backing_store.block_bits as usize;
                let mut planes = vec![0u64; field.bits as usize * groups];
                for (i, chunk) in planes.chunks_mut(block_bits * groups).enumerate() {
                    // A block never saved reads as zeros (the simulator's definition of VRAM
                    // never written).
                    if let Some(stored) = self.backing_store.get(&(block + i as u32)) {
                        chunk.copy_from_slice(&stored[..chunk.len()]);
                    }
                }
                self.engine.get_mut().write_planes(field, &planes);
            }
            Command::Fence => {}
            Command::WritePixels {
                dst,
                rect,
                ref values,
            } => self.engine.get_mut().write_values(dst, rect, values),
            Command::Readback {
                field,
                rect,
                dest,
                tag,
            } => {
                // A buffer of the readback's own, which its messages take (one message, as a
                // band of a view's IDs is, takes it whole).
                let mut values = Vec::new();
                self.engine.get().read_values(field, rect, &mut values);
                return Some(ReadbackStream {
                    dest,
                    tag,
                    bits: field.bits,
                    messages: readback::messages(
                        values,
                        rect,
                        field.bits,
                        self.ring_word_bits,
                        self.max_message_words,
                    ),
                });
            }
        }
        None
    }

    /// The one-bit registers as the commands so far left them (the sparse level computes what
    /// it has deferred, leaving it deferred).
    fn registers(&self) -> std::borrow::Cow<'_, Registers> {
        match &self.engine {
            Engine::Sparse(e) => std::borrow::Cow::Owned(e.materialised()),
            e => std::borrow::Cow::Borrowed(e.get().registers()),
        }
    }

    /// The board's state in the canonical form both fidelity levels share.
    pub(crate) fn image(&mut self) -> BoardImage {
        self.settle();
        let e = self.engine.get();
        let memory = e.read_planes(Field {
            offset: 0,
            bits: self.cfg.pixel_memory_bits.min(64),
            signed: false,
        });
        let mut planes = memory;
        // read_planes moves at most 64 bits at a time.
        let mut offset = 64;
        while offset < self.cfg.pixel_memory_bits {
            let bits = (self.cfg.pixel_memory_bits - offset).min(64);
            planes.extend(e.read_planes(Field {
                offset,
                bits,
                signed: false,
            }));
            offset += bits;
        }
        let Registers { enable, flags } = self.registers().into_owned();
        BoardImage {
            enable,
            flags,
            memory: planes,
            backing_store: self.backing_store.clone(),
        }
    }

    /// Raw values of a field over the whole array, row by row (for tests and pictures).
    pub(crate) fn field_values(&mut self, field: Field) -> Vec<u64> {
        self.settle();
        let rect = Rect {
            x: 0,
            y: 0,
            width: self.cfg.width,
            height: self.cfg.height,
        };
        let mut values = Vec::new();
        self.engine.get().read_values(field, rect, &mut values);
        values
    }

    /// One one-bit register of every pixel, row by row.
    pub(crate) fn bit_values(&mut self, b: Bit) -> Vec<bool> {
        self.settle();
        let regs = self.registers();
        (0..self.geometry.groups * 64)
            .map(|p| (regs.get(b, p / 64) >> (p % 64)) & 1 != 0)
            .collect()
    }
}

/// Which writes to enable a command makes: `Some(op)` when it combines into enable by `op`.
fn enable_write(dst: Bit, combine: LogicOp) -> Option<LogicOp> {
    match dst {
        Bit::Enable => Some(combine),
        Bit::Flag(_) => None,
    }
}

/// A board's complete state in canonical bit-plane form: what the fidelity levels must agree on.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct BoardImage {
    pub enable: Vec<u64>,
    pub flags: Vec<Vec<u64>>,
    /// Every bit-plane of pixel memory, plane-major.
    pub memory: Vec<u64>,
    /// The backing-store blocks ever written.
    pub backing_store: BTreeMap<u32, Vec<u64>>,
}

impl BoardImage {
    /// SHA-256 of the state, hex: enable, flags, memory planes, then each written backing-store
    /// block with its number, each u64 little-endian.
    pub fn digest(&self) -> String {
        let mut h = Sha256::new();
        let mut put = |values: &[u64]| {
            for v in values {
                h.update(v.to_le_bytes());
            }
        };
        put(&self.enable);
        for f in &self.flags {
            put(f);
        }
        put(&self.memory);
        for (block, planes) in &self.backing_store {
            put(&[u64::from(*block)]);
            put(planes);
        }
        h.finalize().iter().map(|b| format!("{b:02x}")).collect()
    }
}
