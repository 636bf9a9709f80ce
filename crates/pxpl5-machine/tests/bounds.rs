//! The machine at the edges of what a valid config allows (issue 9): the largest costs at the
//! slowest clocks end a run at its time limit, never in an overflow panic or a wrapped time; the
//! host-memory estimate that commands check before building a machine; and the fuzz target of
//! machines built from arbitrary config fields.

use proptest::prelude::*;
use pxpl5_config::{MAX_COST_CYCLES, MAX_UNITS, MachineConfig};
use pxpl5_machine::memory::{DEFAULT_LIMIT, check, estimate, format_size};
use pxpl5_machine::{
    Gp, GpFuture, Machine, Op, Payload, Program, Recorder, RunError, RunOptions, Unit,
};
use pxpl5_renderer::{Command, Fidelity, Field, Rect};
use pxpl5_sim::Tick;
use pxpl5_tests::fuzzing::{CONFIG_FIELDS, is_cost};

fn shipped(name: &str) -> MachineConfig {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../machine-configs")
        .join(name);
    pxpl5_config::load_file(&path).expect("shipped config")
}

const VALUE: Field = Field {
    offset: 0,
    bits: 32,
    signed: false,
};

/// Every GP charges every operation, GP 0 drives Renderer 0 through every kind of cost (a
/// write, a backing-store transfer, a fence, a readback to itself) and the others send it data.
struct EveryCost;

impl Program for EveryCost {
    fn name(&self) -> &str {
        "every-cost"
    }

    fn gp_main(&self, gp: Gp) -> GpFuture {
        Box::pin(async move {
            for op in Op::ALL {
                gp.compute(op, 1 << 20).await;
            }
            if gp.index() != 0 {
                gp.send(
                    Unit::Gp(0),
                    Payload::Data {
                        tag: 1,
                        values: vec![1.0],
                        words: 2,
                    },
                )
                .await;
                return Ok(());
            }
            let rect = Rect {
                x: 0,
                y: 0,
                width: 4,
                height: 2,
            };
            gp.send_commands(
                0,
                vec![
                    Command::enable_all(),
                    Command::WriteConst {
                        dst: VALUE,
                        value: 7,
                    },
                    Command::Save {
                        field: VALUE,
                        block: 0,
                    },
                    Command::Fence,
                    Command::Readback {
                        field: VALUE,
                        rect,
                        dest: Unit::Gp(0).encode(),
                        tag: 0,
                    },
                ],
            )
            .await;
            for _ in 0..gp.gp_count() {
                gp.recv().await;
            }
            Ok(())
        })
    }
}

/// `cfg` with every cost at its largest and every clock at 1 Hz, still valid.
fn slowest(mut cfg: MachineConfig) -> MachineConfig {
    for (_, set) in CONFIG_FIELDS.iter().filter(|(path, _)| is_cost(path)) {
        set(&mut cfg, MAX_COST_CYCLES);
    }
    cfg.gp.clock_hz = 1;
    cfg.renderer.clock_hz = 1;
    cfg.ring.channel_clock_hz = 1;
    pxpl5_config::check("slowest", &cfg).expect("valid");
    cfg
}

#[test]
fn the_largest_costs_at_the_slowest_clocks_stop_at_the_time_limit() {
    for name in ["minimal.ron", "seed-tr89-002.ron"] {
        let cfg = slowest(shipped(name));
        for max_time in [
            RunOptions::default().max_time,
            Tick(u64::MAX / 2),
            Tick::MAX,
        ] {
            let options = RunOptions {
                fidelity: Fidelity::Integer,
                max_time,
                ..RunOptions::default()
            };
            let err = Machine::new(&cfg, &EveryCost, options, Recorder::new(None, None))
                .expect("builds")
                .run()
                .err()
                .unwrap_or_else(|| panic!("{name}: a run of 2^52 s finished by {max_time}"));
            // The ring refuses a message sent past its horizon (half of u64::MAX): what a
            // saturated time reaches when the time limit is the end of time.
            assert!(
                matches!(err, RunError::TimeLimit { limit, .. } if limit == max_time)
                    || (max_time > Tick(u64::MAX / 2) && matches!(err, RunError::Ring { .. })),
                "{name}, limit {max_time}: {err}"
            );
        }
    }
}

#[test]
fn the_program_runs_at_default_costs() {
    let cfg = shipped("seed-tr89-002.ron");
    let r = Machine::new(
        &cfg,
        &EveryCost,
        RunOptions::default(),
        Recorder::new(None, None),
    )
    .expect("builds")
    .run()
    .expect("runs");
    assert!(r.stats.end > Tick::ZERO);
}

#[test]
fn the_memory_estimate_admits_the_shipped_and_the_largest_default_machines() {
    for name in ["minimal.ron", "seed-tr89-002.ron", "pxpl5-1989.ron"] {
        let cfg = shipped(name);
        let e = check(&cfg, DEFAULT_LIMIT).expect("fits");
        assert!(e.total() < 200 << 20, "{name}: {e}");
    }
    let mut big = shipped("pxpl5-1989.ron");
    big.gp.count = MAX_UNITS;
    big.renderer.count = MAX_UNITS;
    pxpl5_config::check("big", &big).expect("valid");
    let e = check(&big, DEFAULT_LIMIT).expect("fits");
    // A Renderer of 128 x 128 pixels: 208-bit pixel memory as four 64-bit limbs, five one-bit
    // registers, a 4,096-bit backing store, 32 bytes of working memory per pixel, and 16 KiB.
    let px = 128 * 128;
    let renderer = px * 32 + px * 5 / 8 + px * 4096 / 8 + px * 32 + 16 * 1024;
    assert_eq!(e.parts[0].each, renderer);
    assert_eq!(e.parts[0].count, 256);
    assert!(e.total() > 256 * renderer, "{e}");
}

#[test]
fn the_memory_estimate_refuses_what_no_host_holds_and_never_overflows() {
    let mut fb = shipped("minimal.ron");
    fb.frame_buffer.width = 65_536;
    fb.frame_buffer.height = 65_536;
    pxpl5_config::check("fb", &fb).expect("valid");
    let err = check(&fb, DEFAULT_LIMIT).unwrap_err();
    let text = err.to_string();
    assert!(
        text.starts_with("machine `minimal` needs an estimated 24.0 GiB:"),
        "{text}"
    );
    assert!(
        text.contains("1 frame buffer x 24 GiB (65536 x 65536 pixels"),
        "{text}"
    );
    assert!(
        text.ends_with("more than the host memory limit of 4 GiB"),
        "{text}"
    );
    assert_eq!(err.suggested_limit().as_deref(), Some("25GiB"));
    check(&fb, 25 << 30).expect("within a raised limit");

    // Unchecked counts (a library user's config): the estimate saturates, no overflow.
    let mut absurd = shipped("minimal.ron");
    absurd.gp.count = u32::MAX;
    absurd.renderer.count = u32::MAX;
    absurd.ring.channels = u32::MAX;
    absurd.renderer.width = u32::MAX;
    absurd.renderer.height = u32::MAX;
    absurd.renderer.backing_store_bits = u32::MAX;
    let e = estimate(&absurd);
    assert_eq!(e.total(), u64::MAX);
    assert_eq!(format_size(e.total()), "16777216 TiB");
    let err = check(&absurd, u64::MAX - 1).unwrap_err();
    assert_eq!(err.suggested_limit(), None);
}

// ---------------------------------------------------------------------------------------------
// Fuzz target (see `pxpl5_tests::fuzzing`): machines built from arbitrary field values.

/// Host memory a fuzzed machine may take: enough for hundreds of default Renderers' arrays
/// (without their backing store, which the program barely touches), little enough for a quick
/// case.
const FUZZ_MEMORY: u64 = 256 << 20;

/// The minimal machine with 1 to 5 fields set to extreme values; a clock is set to a divisor of
/// 10^12 Hz half the time, so that many configs pass validation and run.
fn fuzzed_config() -> impl Strategy<Value = MachineConfig> {
    use pxpl5_tests::fuzzing::extreme_u64;
    let value = prop_oneof![
        3 => extreme_u64(),
        1 => (0u32..13).prop_map(|k| 10u64.pow(k)),
    ];
    prop::collection::vec((0..CONFIG_FIELDS.len(), value), 1..6).prop_map(|edits| {
        let mut cfg = shipped("minimal.ron");
        for (field, v) in edits {
            (CONFIG_FIELDS[field].1)(&mut cfg, v);
        }
        cfg
    })
}

proptest::proptest! {
    // Most cases are refused by the validator in microseconds; an accepted one runs the machine
    // (milliseconds, up to about a second for 256 GPs at a 1 Hz clock).
    #![proptest_config(pxpl5_tests::fuzzing::config(3000))]

    /// A config the validator accepts and the memory estimate admits builds and runs: to the end,
    /// or to an error (a time limit, the ring's horizon, a program's own error), never a panic.
    #[test]
    fn fuzz_machine_configs(cfg in fuzzed_config()) {
        if pxpl5_config::validate(&cfg).is_err() || check(&cfg, FUZZ_MEMORY).is_err() {
            return Ok(());
        }
        let options = RunOptions {
            fidelity: Fidelity::Integer,
            max_time: Tick(1_000_000_000_000),
                        ..RunOptions::default()
        };
        let machine = Machine::new(&cfg, &EveryCost, options, Recorder::new(None, None));
        if let Ok(machine) = machine {
            let _ = machine.run();
        }
    }
}

/// The fuzzed configs reach the machine: a share of them are valid, a share refused.
#[test]
fn fuzz_machine_configs_reach_the_machine() {
    let valid = pxpl5_tests::fuzzing::count(&fuzzed_config(), 400, |cfg| {
        pxpl5_config::validate(cfg).is_ok() && check(cfg, FUZZ_MEMORY).is_ok()
    });
    assert!((40..360).contains(&valid), "{valid} of 400 valid");
}
