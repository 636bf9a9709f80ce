//! Fuzz target of the Renderer's command validator (see `pxpl5_tests::fuzzing`): commands with
//! arbitrary operands (any offsets, widths, registers, coefficients, windows, rectangles,
//! multipliers, blocks, pixel values), on small boards of arbitrary valid configs, at both
//! fidelity levels. The board must never panic: a command it cannot execute is a
//! `CommandError` that says so, and one it accepts executes, with the same outcome, timing and
//! state at both levels.

use proptest::prelude::*;
use pxpl5_config::RendererConfig;
use pxpl5_renderer::{Bit, Board, Cmp, Command, Fidelity, Field, LogicOp, QeeExpr, Rect, Window};
use pxpl5_tests::fuzzing::{config, count, extreme_u64};

/// A u32 in `plausible` (where a valid operand lies) three times in four, else at the edges
/// (from [`extreme_u64`], cut to 32 bits).
fn u32_in(plausible: std::ops::Range<u32>) -> impl Strategy<Value = u32> {
    prop_oneof![
        3 => plausible,
        1 => extreme_u64().prop_map(|v| v as u32),
    ]
}

fn field() -> impl Strategy<Value = Field> {
    (u32_in(0..300), u32_in(1..65), any::<bool>()).prop_map(|(offset, bits, signed)| Field {
        offset,
        bits,
        signed,
    })
}

fn bit() -> impl Strategy<Value = Bit> {
    prop_oneof![Just(Bit::Enable), any::<u8>().prop_map(Bit::Flag)]
}

fn expr() -> impl Strategy<Value = QeeExpr> {
    let c = prop_oneof![
        2 => -5000i64..5000,
        1 => extreme_u64().prop_map(|v| v as i64),
    ];
    [c.clone(), c.clone(), c.clone(), c.clone(), c.clone(), c].prop_map(QeeExpr::from_raw)
}

fn window() -> impl Strategy<Value = Window> {
    (u32_in(0..24), u32_in(1..65)).prop_map(|(shift, bits)| Window { shift, bits })
}

fn rect() -> impl Strategy<Value = Rect> {
    let xy = (u32_in(0..64), u32_in(0..8));
    let size = (u32_in(1..65), u32_in(1..9));
    (xy, size).prop_map(|((x, y), (width, height))| Rect {
        x,
        y,
        width,
        height,
    })
}

fn cmp() -> impl Strategy<Value = Cmp> {
    prop::sample::select(Cmp::ALL.to_vec())
}

fn op() -> impl Strategy<Value = LogicOp> {
    any::<u8>().prop_map(LogicOp)
}

fn command() -> impl Strategy<Value = Command> {
    prop_oneof![
        (u32_in(0..300), u32_in(0..300)).prop_map(|(x, y)| Command::SetOrigin { x, y }),
        (bit(), bit(), bit(), op()).prop_map(|(dst, a, b, op)| Command::Logic { dst, a, b, op }),
        (expr(), window(), bit(), op()).prop_map(|(expr, window, dst, combine)| {
            Command::QeeSign {
                expr,
                window,
                dst,
                combine,
            }
        }),
        (expr(), window(), field()).prop_map(|(expr, window, dst)| Command::QeeStore {
            expr,
            window,
            dst
        }),
        (expr(), window(), field(), cmp(), bit(), op()).prop_map(
            |(expr, window, field, cmp, dst, combine)| Command::QeeCompare {
                expr,
                window,
                field,
                cmp,
                dst,
                combine
            }
        ),
        (expr(), window(), field()).prop_map(|(expr, window, dst)| Command::QeeAdd {
            expr,
            window,
            dst
        }),
        (field(), extreme_u64()).prop_map(|(dst, value)| Command::WriteConst { dst, value }),
        (field(), field()).prop_map(|(dst, src)| Command::Copy { dst, src }),
        (field(), field(), field()).prop_map(|(dst, a, b)| Command::Add { dst, a, b }),
        (field(), field(), field()).prop_map(|(dst, a, b)| Command::Sub { dst, a, b }),
        (field(), field(), cmp(), bit(), op()).prop_map(|(a, b, cmp, dst, combine)| {
            Command::Compare {
                a,
                b,
                cmp,
                dst,
                combine,
            }
        }),
        (field(), field(), extreme_u64(), u32_in(1..33)).prop_map(|(dst, src, k, k_bits)| {
            Command::MulConst {
                dst,
                src,
                k: k as i64,
                k_bits,
            }
        }),
        (field(), u32_in(0..300)).prop_map(|(field, block)| Command::Save { field, block }),
        (field(), u32_in(0..300)).prop_map(|(field, block)| Command::Load { field, block }),
        Just(Command::Fence),
        (field(), rect(), u32_in(0..300), u32_in(0..300)).prop_map(|(field, rect, dest, tag)| {
            Command::Readback {
                field,
                rect,
                dest,
                tag,
            }
        }),
        (
            field(),
            rect(),
            prop::collection::vec(extreme_u64(), 0..600)
        )
            .prop_map(|(dst, rect, values)| Command::WritePixels { dst, rect, values }),
    ]
}

/// A small board's config: 64 pixels wide (the simulator's unit), 1 to 8 rows, and arbitrary
/// memory, flags, backing store, QEE and cycle costs, all valid.
fn board_config() -> impl Strategy<Value = RendererConfig> {
    (
        1u32..9,
        1u32..=300,
        1u32..=64,
        0u32..=64,
        1u32..=64,
        (1u32..=20, 0u32..=26, 7u32..=12, 1u32..=64),
        (0u64..=20, 1u64..=5, 0u64..=4096),
    )
        .prop_map(|(height, memory, flags, blocks, block_bits, qee, cycles)| {
            let mut c = pxpl5_config::default_config().renderer;
            c.width = 64;
            c.height = height;
            c.pixel_memory_bits = memory;
            c.flag_registers = flags;
            c.backing_store.block_bits = block_bits;
            c.backing_store_bits = blocks * block_bits;
            let (int_bits, frac_bits, coordinate_bits, max_result_bits) = qee;
            c.qee.coefficient_format.int_bits = int_bits;
            // As many fractional bits as the validator allows with these integer and
            // coordinate bits (the QEE tree must fit 64 bits), at most the drawn number.
            let room = (60 - 2 * coordinate_bits).min(47) - int_bits;
            c.qee.coefficient_format.frac_bits = frac_bits.min(room);
            c.qee.coordinate_bits = coordinate_bits;
            c.qee.max_result_bits = max_result_bits;
            let (overhead, per_bit, block_cycles) = cycles;
            c.cycles.igc_overhead = overhead;
            c.cycles.per_bit = per_bit;
            c.backing_store.block_cycles = block_cycles.max(1);
            c
        })
}

proptest! {
    // About 1 ms a case (three boards, up to 24 commands) in the test profile.
    #![proptest_config(config(5_000))]

    #[test]
    fn fuzz_renderer_commands(
        cfg in board_config(),
        commands in prop::collection::vec(command(), 1..24),
    ) {
        let mut machine = pxpl5_config::default_config();
        machine.renderer = cfg.clone();
        // Only what the config validator accepts is a board a machine would build.
        prop_assert!(pxpl5_config::validate(&machine).is_ok(), "{:?}", pxpl5_config::validate(&machine));
        let mut bit = Board::new(&cfg, 32, Fidelity::Bit).stream_readbacks(64);
        let mut integer = Board::new(&cfg, 32, Fidelity::Integer).stream_readbacks(64);
        let mut sparse = Board::new(&cfg, 32, Fidelity::Sparse).stream_readbacks(64);
        for (i, c) in commands.iter().enumerate() {
            let (b, n) = (bit.execute(c), integer.execute(c));
            if let Err(e) = &b {
                prop_assert!(!e.to_string().is_empty());
            }
            prop_assert_eq!(&b, &n, "command {} {:?}: the levels differ", i, c);
            prop_assert_eq!(&n, &sparse.execute(c), "command {} {:?}: sparse differs", i, c);
        }
        prop_assert_eq!(bit.stats(), integer.stats());
        prop_assert_eq!(integer.stats(), sparse.stats());
        prop_assert!(bit.image() == integer.image(), "the levels' states differ");
        prop_assert!(integer.image() == sparse.image(), "the sparse level's state differs");
    }
}

/// Both paths are exercised: in a good share of cases some command executes, and in a good
/// share some command is refused.
#[test]
fn fuzz_renderer_commands_reach_both_paths() {
    let cases = (board_config(), prop::collection::vec(command(), 1..24));
    let outcomes = |(cfg, commands): &(RendererConfig, Vec<Command>)| {
        let mut board = Board::new(cfg, 32, Fidelity::Integer).stream_readbacks(64);
        commands
            .iter()
            .map(|c| board.execute(c).is_ok())
            .collect::<Vec<bool>>()
    };
    let some_ok = count(&cases, 300, |c| outcomes(c).contains(&true));
    let some_refused = count(&cases, 300, |c| outcomes(c).contains(&false));
    assert!(
        some_ok > 30 && some_refused > 30,
        "{some_ok} of 300 cases executed a command, {some_refused} refused one"
    );
}
