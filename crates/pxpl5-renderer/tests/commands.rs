//! Every IGC command: its effect on pixels and its cycle count, asserted together, at both
//! exact fidelity levels (each check runs the same commands on a `bit` and an `integer` board and
//! requires identical state), and its time at the `timing` level, which must not differ.

use pxpl5_config::RendererConfig;
use pxpl5_renderer::{
    Bit, Board, Cmp, Command, CommandError, Fidelity, Field, LogicOp, PixelLayout, QeeExpr, Rect,
    Window,
};

/// The seed machine's Renderer: 128 x 128, 208 bits, 4 flags, IGC overhead 20, QEE latency 8.
fn cfg() -> RendererConfig {
    pxpl5_config::default_config().renderer
}

/// Both boards, after running `setup`.
fn boards(setup: &[Command]) -> [Board; 2] {
    [Fidelity::Bit, Fidelity::Integer].map(|f| {
        let mut b = Board::new(&cfg(), 32, f);
        for c in setup {
            b.execute(c).unwrap();
        }
        b
    })
}

/// Run `cmd` on both levels; assert its cycles (end - start) and that the levels agree; return
/// the bit board. The timing level, which does no pixel work, must time it the same and send a
/// readback's messages with the same rows and sizes, all zeros.
fn check(setup: &[Command], cmd: Command, cycles: u64) -> Board {
    let [mut bit, mut integer] = boards(setup);
    let eb = bit.execute(&cmd).unwrap();
    let ei = integer.execute(&cmd).unwrap();
    assert_eq!(eb, ei, "{cmd:?}: bit and integer executions differ");
    let mut timing = Board::new(&cfg(), 32, Fidelity::Timing);
    for c in setup {
        timing.execute(c).unwrap();
    }
    let et = timing.execute(&cmd).unwrap();
    assert_eq!(
        (et.start, et.end, et.stall),
        (eb.start, eb.end, eb.stall),
        "{cmd:?}: the timing level's time"
    );
    assert_eq!(
        timing.stats(),
        bit.stats(),
        "{cmd:?}: the timing level's stats"
    );
    let shape = |r: &pxpl5_renderer::ReadbackStream| {
        let rows: Vec<_> = r
            .messages
            .iter()
            .map(|m| (m.rect, m.values.len()))
            .collect();
        (r.dest, r.tag, r.bits, rows)
    };
    assert_eq!(
        et.readback.as_ref().map(shape),
        eb.readback.as_ref().map(shape)
    );
    if let Some(r) = &et.readback {
        assert!(r.messages.iter().all(|m| m.values.iter().all(|&v| v == 0)));
    }
    assert_eq!((eb.end - eb.start).0, cycles, "{cmd:?}: cycles");
    assert_eq!(
        bit.image(),
        integer.image(),
        "{cmd:?}: bit and integer state differ"
    );
    bit
}

fn field(offset: u32, bits: u32, signed: bool) -> Field {
    Field {
        offset,
        bits,
        signed,
    }
}

/// Enable only the left half of the board (x < 64), by a linear sign test: 63.5 - x >= 0.
fn left_half() -> Command {
    Command::QeeSign {
        expr: QeeExpr::linear(-2, 0, 127),
        window: Window { shift: 0, bits: 12 },
        dst: Bit::Enable,
        combine: LogicOp::B,
    }
}

const W: usize = 128;

#[test]
fn logic_is_one_cycle_plus_overhead() {
    let setup = [left_half()];
    let mut b = check(
        &setup,
        Command::Logic {
            dst: Bit::Flag(2),
            a: Bit::Enable,
            b: Bit::Flag(2),
            op: LogicOp::OR,
        },
        21,
    );
    let f = b.bit_values(Bit::Flag(2));
    // Gated: written only where enabled, and there it is 1.
    assert!(f[5] && !f[100] && f[W * 77 + 63] && !f[W * 77 + 64]);
    // Writing enable itself is not gated.
    let mut b = check(&setup, Command::enable_all(), 21);
    assert!(b.bit_values(Bit::Enable).iter().all(|&e| e));
}

#[test]
fn qee_sign_costs_latency_plus_window() {
    // 12-bit window, linear: 20 + 8 + 12.
    let mut b = check(&[], left_half(), 40);
    let e = b.bit_values(Bit::Enable);
    assert!(e[0] && e[63] && !e[64] && !e[127] && e[W * 127 + 10]);
    // A quadratic costs the same with quadratic_extra_cycles = 0 [lineage].
    let circle = QeeExpr::from_raw([128, 128, -(64 * 64 * 2 - 40 * 40), -1, 0, -1]);
    let mut b = check(
        &[],
        Command::QeeSign {
            expr: circle,
            window: Window { shift: 3, bits: 16 },
            dst: Bit::Flag(0),
            combine: LogicOp::B,
        },
        20 + 8 + 19,
    );
    let f = b.bit_values(Bit::Flag(0));
    for (x, y) in [(64usize, 64usize), (30, 64), (64, 100), (0, 0), (127, 127)] {
        let v = circle.eval(x as i64, y as i64) >> 3;
        assert_eq!(f[y * W + x], v >= 0, "({x}, {y}) v = {v}");
    }
}

#[test]
fn qee_store_add_and_compare() {
    let mut l = PixelLayout::new(208);
    let z = l.alloc("z", 20, true).unwrap();
    let expr = QeeExpr::from_raw([3, -5, 1000, 0, 1, 0]);
    let win = Window { shift: 2, bits: 20 };
    let setup = [left_half(), Command::SetOrigin { x: 100, y: 200 }];
    let mut b = check(
        &setup,
        Command::QeeStore {
            expr,
            window: win,
            dst: z,
        },
        20 + 8 + 22,
    );
    let vals = b.field_values(z);
    let at = |x: usize, y: usize| win.cut(expr.eval(100 + x as i64, 200 + y as i64));
    assert_eq!(vals[W * 9 + 7], at(7, 9));
    assert_eq!(vals[W * 9 + 70], 0, "disabled pixels keep their value");

    let store = Command::QeeStore {
        expr,
        window: win,
        dst: z,
    };
    let mut s2 = setup.to_vec();
    s2.push(store.clone());
    let mut b = check(
        &s2,
        Command::QeeAdd {
            expr,
            window: win,
            dst: z,
        },
        20 + 8 + 22 + 1,
    );
    assert_eq!(b.field_values(z)[W * 3 + 1], (2 * at(1, 3)) & 0xF_FFFF);

    // Compare the stored value against an expression one larger: strictly greater everywhere.
    let bigger = QeeExpr { c: 1004, ..expr };
    let mut b = check(
        &s2,
        Command::QeeCompare {
            expr: bigger,
            window: win,
            field: z,
            cmp: Cmp::Gt,
            dst: Bit::Flag(1),
            combine: LogicOp::B,
        },
        20 + 8 + 22 + 1,
    );
    let f = b.bit_values(Bit::Flag(1));
    assert!(f[W * 50 + 3] && !f[W * 50 + 90]);
}

#[test]
fn field_arithmetic() {
    let (a, b, d) = (field(0, 8, true), field(8, 12, false), field(60, 10, true));
    let setup = [
        Command::WriteConst {
            dst: a,
            value: 0xF0, // -16
        },
        Command::WriteConst { dst: b, value: 700 },
    ];
    let mut board = check(&setup, Command::Add { dst: d, a, b }, 20 + 1 + 10);
    assert_eq!(board.field_values(d)[0], 684);
    let mut board = check(&setup, Command::Sub { dst: d, a, b }, 20 + 1 + 10);
    assert_eq!(board.field_values(d)[0], (-716i64 as u64) & 0x3FF);
    let mut board = check(&setup, Command::Copy { dst: d, src: a }, 20 + 10);
    assert_eq!(board.field_values(d)[0], 0x3F0, "sign-extended");
    let mut board = check(
        &setup,
        Command::MulConst {
            dst: d,
            src: a,
            k: -3,
            k_bits: 3,
        },
        20 + 8 * 3,
    );
    assert_eq!(board.field_values(d)[0], 48);
    let mut board = check(&setup, Command::WriteConst { dst: d, value: 513 }, 20 + 10);
    assert_eq!(board.field_values(d)[W * W - 1], 513);
}

#[test]
fn compare_is_exact_across_widths_and_signedness() {
    let (a, b) = (field(0, 8, true), field(8, 12, false));
    for (va, vb) in [(0xF0u64, 700u64), (0x7F, 100), (0x64, 100), (0x00, 0)] {
        let setup = [
            Command::WriteConst { dst: a, value: va },
            Command::WriteConst { dst: b, value: vb },
        ];
        let x = ((va as i64) << 56) >> 56;
        for cmp in Cmp::ALL {
            let mut board = check(
                &setup,
                Command::Compare {
                    a,
                    b,
                    cmp,
                    dst: Bit::Flag(3),
                    combine: LogicOp::B,
                },
                20 + 1 + 12,
            );
            let expect = cmp.holds(x as i128, vb as i128);
            assert_eq!(
                board.bit_values(Bit::Flag(3))[0],
                expect,
                "{x} {cmp:?} {vb}"
            );
        }
    }
}

#[test]
fn backing_store_runs_in_the_background_and_interlocks() {
    let f = field(10, 40, false);
    let setup = [Command::WriteConst {
        dst: f,
        value: 0x12_3456_789A,
    }];
    let [mut bit, mut integer] = boards(&setup);
    for b in [&mut bit, &mut integer] {
        let t0 = b.free_at().0;
        let save = b.execute(&Command::Save { field: f, block: 5 }).unwrap();
        // Foreground: overhead + issue.
        assert_eq!(save.end.0 - save.start.0, 21);
        // An unrelated command does not wait.
        let other = b
            .execute(&Command::WriteConst {
                dst: field(100, 4, false),
                value: 3,
            })
            .unwrap();
        assert_eq!(other.stall.0, 0);
        // Overwrite the field: waits for the 2-block transfer (2 x 4096 cycles).
        let over = b
            .execute(&Command::WriteConst { dst: f, value: 0 })
            .unwrap();
        assert_eq!(over.start.0, t0 + 21 + 2 * 4096);
        assert_eq!(over.stall.0, 2 * 4096 - 24);
        let load = b.execute(&Command::Load { field: f, block: 5 }).unwrap();
        assert_eq!(load.stall.0, 0);
        let fence = b.execute(&Command::Fence).unwrap();
        assert_eq!(fence.start.0, load.end.0 + 2 * 4096);
        assert_eq!(b.field_values(f)[777], 0x12_3456_789A);
        assert_eq!(b.stats().backing_store_busy.0, 4 * 4096);
    }
    assert_eq!(bit.image(), integer.image());
}

#[test]
fn readback_packs_ring_words() {
    let id = field(0, 16, false);
    let setup = [Command::QeeStore {
        expr: QeeExpr::linear(1, 1000, 0),
        window: Window { shift: 0, bits: 16 },
        dst: id,
    }];
    let rect = Rect {
        x: 10,
        y: 20,
        width: 5,
        height: 3,
    };
    let b = check(
        &setup,
        Command::Readback {
            field: id,
            rect,
            dest: 7,
            tag: 9,
        },
        20 + 16,
    );
    let [mut bit, _] = boards(&setup);
    let r = bit
        .execute(&Command::Readback {
            field: id,
            rect,
            dest: 7,
            tag: 9,
        })
        .unwrap()
        .readback
        .unwrap();
    assert_eq!((r.dest, r.tag, r.bits), (7, 9, 16));
    // Unlimited messages: one message carries the whole rectangle.
    assert_eq!(r.messages.len(), 1);
    assert_eq!(r.messages[0].rect, rect);
    let px = &r.messages[0].values;
    assert_eq!(px.len(), 15);
    assert_eq!(px[0], 10 + 20 * 1000);
    assert_eq!(px[14], 14 + 22 * 1000);
    drop(b);
}

#[test]
fn program_mistakes_are_errors_not_panics() {
    let [mut b, _] = boards(&[]);
    let err = |b: &mut Board, c: Command| b.execute(&c).unwrap_err();
    assert!(matches!(
        err(
            &mut b,
            Command::WriteConst {
                dst: field(200, 16, false),
                value: 0
            }
        ),
        CommandError::FieldOutside { .. }
    ));
    assert!(matches!(
        err(
            &mut b,
            Command::Add {
                dst: field(0, 8, false),
                a: field(4, 8, false),
                b: field(20, 8, false)
            }
        ),
        CommandError::Overlap { .. }
    ));
    assert!(matches!(
        err(
            &mut b,
            Command::Logic {
                dst: Bit::Flag(9),
                a: Bit::Enable,
                b: Bit::Enable,
                op: LogicOp::A
            }
        ),
        CommandError::NoSuchFlag { .. }
    ));
    // Each register of a Logic step, and a sign test's destination, is checked.
    assert!(matches!(
        err(
            &mut b,
            Command::Logic {
                dst: Bit::Enable,
                a: Bit::Enable,
                b: Bit::Flag(7),
                op: LogicOp::A
            }
        ),
        CommandError::NoSuchFlag { flag: 7, .. }
    ));
    assert!(matches!(
        err(
            &mut b,
            Command::QeeSign {
                expr: QeeExpr::default(),
                window: Window { shift: 0, bits: 8 },
                dst: Bit::Flag(8),
                combine: LogicOp::B
            }
        ),
        CommandError::NoSuchFlag { flag: 8, .. }
    ));
    assert!(matches!(
        err(
            &mut b,
            Command::QeeStore {
                expr: QeeExpr::linear(1 << 40, 0, 0),
                window: Window { shift: 0, bits: 8 },
                dst: field(0, 8, false)
            }
        ),
        CommandError::Coefficient { name: "A", .. }
    ));
    // The first coefficient out of range is named, below the range as above it.
    assert!(matches!(
        err(
            &mut b,
            Command::QeeSign {
                expr: QeeExpr::from_raw([1, 0, 0, 0, -(1 << 40), 1 << 40]),
                window: Window { shift: 0, bits: 8 },
                dst: Bit::Enable,
                combine: LogicOp::AND
            }
        ),
        CommandError::Coefficient { name: "E", raw, .. } if raw == -(1 << 40)
    ));
    assert!(matches!(
        err(
            &mut b,
            Command::QeeStore {
                expr: QeeExpr::default(),
                window: Window { shift: 0, bits: 9 },
                dst: field(0, 8, false)
            }
        ),
        CommandError::WidthMismatch { .. }
    ));
    assert!(matches!(
        err(
            &mut b,
            Command::QeeSign {
                expr: QeeExpr::default(),
                window: Window { shift: 60, bits: 9 },
                dst: Bit::Enable,
                combine: LogicOp::B
            }
        ),
        CommandError::Window { .. }
    ));
    assert!(matches!(
        err(&mut b, Command::SetOrigin { x: 4000, y: 0 }),
        CommandError::Origin { .. }
    ));
    assert!(matches!(
        err(
            &mut b,
            Command::Save {
                field: field(0, 64, false),
                block: 127
            }
        ),
        CommandError::BackingStore { .. }
    ));
    assert!(matches!(
        err(
            &mut b,
            Command::MulConst {
                dst: field(0, 8, false),
                src: field(8, 8, false),
                k: 9,
                k_bits: 4
            }
        ),
        CommandError::Multiplier { .. }
    ));
    assert!(matches!(
        err(
            &mut b,
            Command::WriteConst {
                dst: field(0, 4, false),
                value: 16
            }
        ),
        CommandError::Constant { .. }
    ));
    // Nothing ran: time did not move.
    assert_eq!(b.free_at().0, 0);
}

#[test]
fn write_pixels_fills_a_rectangle_ungated() {
    let f = field(30, 17, false);
    let rect = Rect {
        x: 60,
        y: 5,
        width: 8,
        height: 2,
    };
    let values: Vec<u64> = (0..16).map(|i| 1000 * i + 7).collect();
    // Enable covers only x < 64: the write is not gated, so x >= 64 is written too.
    let mut b = check(
        &[left_half()],
        Command::WritePixels {
            dst: f,
            rect,
            values: values.clone(),
        },
        20 + 17,
    );
    let all = b.field_values(f);
    assert_eq!(all[W * 5 + 60], 7);
    assert_eq!(all[W * 6 + 67], 15007);
    assert_eq!(all[W * 6 + 68], 0);
    let cmd = Command::WritePixels {
        dst: f,
        rect,
        values,
    };
    // The opcode word, the rectangle's word, and 16 values of 17 bits, one per 32-bit word.
    assert_eq!(cmd.words(32, 32), 18);
    let [mut bad, _] = boards(&[]);
    assert!(matches!(
        bad.execute(&Command::WritePixels {
            dst: f,
            rect,
            values: vec![1; 3]
        }),
        Err(CommandError::PixelCount { got: 3, want: 16 })
    ));
}

/// Operands near u32::MAX are errors, not overflows in the validator (found by the fuzz target
/// `tests/fuzz.rs`: `offset + bits` and `shift + bits` overflowed).
#[test]
fn operands_at_the_edge_of_u32_are_errors() {
    let [mut board, _] = boards(&[]);
    let far = Field {
        offset: u32::MAX,
        bits: 8,
        signed: false,
    };
    let e = board
        .execute(&Command::WriteConst { dst: far, value: 1 })
        .unwrap_err();
    assert!(
        matches!(
            e,
            CommandError::FieldOutside {
                offset: u32::MAX,
                bits: 8,
                memory: 208,
                ..
            }
        ),
        "{e:?}"
    );
    let window = Window {
        shift: u32::MAX,
        bits: 8,
    };
    let e = board
        .execute(&Command::QeeSign {
            expr: QeeExpr::linear(1, 0, 0),
            window,
            dst: Bit::Enable,
            combine: LogicOp::AND,
        })
        .unwrap_err();
    assert!(
        matches!(
            e,
            CommandError::Window {
                shift: u32::MAX,
                bits: 8,
                max: 64,
                ..
            }
        ),
        "{e:?}"
    );
}
