//! The Renderer's cycle table: the one function that gives every IGC command's cost.
//!
//! The SIMD array's timing depends only on the command stream, never on pixel data, so a command
//! costs the same at every fidelity level; both levels call [`cycle_cost`]. The terms come from
//! `renderer.cycles` and `renderer.qee` of the machine config, whose docs tag each as [paper],
//! [lineage] or [assumed] (all of today's terms but the bit-serial structure are assumptions, from
//! `docs/hardware.md`, "Not found anywhere"):
//!
//! | command | cycles |
//! |---|---|
//! | every command | `igc_overhead` (IGC decode) plus: |
//! | `SetOrigin` | `set_origin` |
//! | `Logic` | `logic` (one one-bit ALU step) |
//! | `QeeSign`, `QeeStore` | `latency + (shift + bits) * per_bit` (+ `quadratic_extra` if D, E or F != 0): the tree delivers one bit per cycle, low bits first, so the window's top bit arrives after shift + bits cycles |
//! | `QeeCompare`, `QeeAdd` | as above + `alu_setup` |
//! | `WriteConst`, `Copy` | `dst.bits * per_bit` |
//! | `Add`, `Sub` | `alu_setup + dst.bits * per_bit` |
//! | `Compare` | `alu_setup + max(a.bits, b.bits) * per_bit` |
//! | `MulConst` | `src.bits * k_bits * multiply_per_bit_pair` (shift-and-add) |
//! | `Save`, `Load` | `backing_store_issue` in the foreground; [`backing_store_cycles`] in the background |
//! | `Fence` | nothing more (its wait is a stall, not work) |
//! | `Readback` | `field.bits * readback_per_bit` (moving the field into the output port; the ring's time is the ring's) |
//! | `WritePixels` | `dst.bits * readback_per_bit` (the same port, the other way) |

use pxpl5_config::RendererConfig;
use pxpl5_sim::Cycles;

use crate::command::{Command, Field};

/// Foreground Renderer cycles of `cmd` on a board configured by `cfg`. Inlined into a board's
/// `execute`, once a command.
#[inline]
pub fn cycle_cost(cmd: &Command, cfg: &RendererConfig) -> Cycles {
    let t = &cfg.cycles;
    let bits = |f: &Field| u64::from(f.bits);
    let qee = |expr: &crate::QeeExpr, w: crate::Window| {
        let extra = if expr.is_quadratic() {
            u64::from(cfg.qee.quadratic_extra_cycles)
        } else {
            0
        };
        u64::from(cfg.qee.latency_cycles) + extra + u64::from(w.delivered_bits()) * t.per_bit
    };
    let work = match cmd {
        Command::SetOrigin { .. } => t.set_origin,
        Command::Logic { .. } => t.logic,
        Command::QeeSign { expr, window, .. } | Command::QeeStore { expr, window, .. } => {
            qee(expr, *window)
        }
        Command::QeeCompare { expr, window, .. } | Command::QeeAdd { expr, window, .. } => {
            qee(expr, *window) + t.alu_setup
        }
        Command::WriteConst { dst, .. } | Command::Copy { dst, .. } => bits(dst) * t.per_bit,
        Command::Add { dst, .. } | Command::Sub { dst, .. } => t.alu_setup + bits(dst) * t.per_bit,
        Command::Compare { a, b, .. } => t.alu_setup + bits(a).max(bits(b)) * t.per_bit,
        Command::MulConst { src, k_bits, .. } => {
            bits(src) * u64::from(*k_bits) * t.multiply_per_bit_pair
        }
        Command::Save { .. } | Command::Load { .. } => t.backing_store_issue,
        Command::Fence => 0,
        Command::Readback { field, .. } | Command::WritePixels { dst: field, .. } => {
            bits(field) * t.readback_per_bit
        }
    };
    Cycles(t.igc_overhead + work)
}

/// Blocks of the backing store a field occupies.
pub fn backing_store_blocks(field: Field, cfg: &RendererConfig) -> u32 {
    field.bits.div_ceil(cfg.backing_store.block_bits)
}

/// Background Renderer cycles of one backing-store transfer of `field` (either direction).
pub fn backing_store_cycles(field: Field, cfg: &RendererConfig) -> Cycles {
    Cycles(u64::from(backing_store_blocks(field, cfg)) * cfg.backing_store.block_cycles)
}
