//! Cycle-count goldens, one file per case in `tests/snapshots/`:
//! - the Renderer: the benchmark's stream (the radiosity program's commands for the first
//!   Cornell-box shot, hemisphere and hemicube, `pxpl5_radiosity::stream`) on every shipped
//!   machine config, at every exact fidelity level; each golden records the Renderer cycles, the
//!   per-kind command counts and cycles, and the digest of the board's final state;
//! - the machine (`machine_goldens!`, every program on every shipped config): the polygon program
//!   on `programs/polygons/scenes/small.ron`, and three shots of the Cornell box (patches of
//!   150 mm) with each form-factor method. Each golden is a functional block (what was computed:
//!   the frame's digest; the shooters, culls and the solution's digest) and a timing table with
//!   the same numbers as the run's stats.json, a line per total, phase, GP, Renderer, ring
//!   channel and ring node (`machine_golden.rs`).
//!
//! A golden changes only on purpose, in a commit whose message says why the timing changed
//! (`INSTA_UPDATE=always cargo test -p pxpl5-tests --test goldens` rewrites them).

use std::fmt::Write;

use pxpl5_radiosity::shot::{FfOptions, Method};
use pxpl5_radiosity::stream::cornell_stream;
use pxpl5_renderer::{Board, Fidelity};
use pxpl5_tests::workspace_root;

mod machine_golden;

fn golden(config_file: &str) -> String {
    let path = workspace_root().join("machine-configs").join(config_file);
    let cfg = pxpl5_config::load_file(&path).expect("shipped configs are valid");
    let mut out = String::new();
    writeln!(out, "config: {} ({})", cfg.name, config_file).unwrap();
    for method in [Method::Hemisphere, Method::Hemicube] {
        let opts = FfOptions {
            method,
            ..FfOptions::default()
        };
        let stream = cornell_stream(&cfg, &opts, 1).expect("the stream fits every config");
        let mut first: Option<(u64, String)> = None;
        for fidelity in [Fidelity::Bit, Fidelity::Integer, Fidelity::Sparse] {
            let mut board = Board::new(&cfg.renderer, cfg.ring.word_bits, fidelity);
            let cycles = stream.run(&mut board).expect("the stream runs").0;
            let digest = board.image().digest();
            match &first {
                None => {
                    writeln!(out, "\nstream: {}", stream.description).unwrap();
                    writeln!(out, "renderer cycles: {cycles}").unwrap();
                    let s = board.stats();
                    writeln!(
                        out,
                        "commands: {}, busy {}, stall {}",
                        s.commands, s.busy.0, s.stall.0
                    )
                    .unwrap();
                    for (kind, k) in &s.by_kind {
                        writeln!(
                            out,
                            "  {kind:<12} {:>6} commands {:>9} cycles",
                            k.count, k.cycles
                        )
                        .unwrap();
                    }
                    writeln!(out, "digest: {digest}").unwrap();
                    first = Some((cycles, digest));
                }
                Some((c, d)) => {
                    assert_eq!(
                        (*c, d.as_str()),
                        (cycles, digest.as_str()),
                        "{fidelity:?} differs"
                    )
                }
            }
        }
    }
    out
}

#[test]
fn renderer_stream_seed_tr89_002() {
    insta::assert_snapshot!(golden("seed-tr89-002.ron"));
}

#[test]
fn renderer_stream_pxpl5_1989() {
    insta::assert_snapshot!(golden("pxpl5-1989.ron"));
}

#[test]
fn renderer_stream_minimal() {
    insta::assert_snapshot!(golden("minimal.ron"));
}

/// A machine run's golden: the header, the functional block (the program's `functional` lines)
/// and the timing table of `machine_golden::text`, checked to hold every figure of the run's
/// stats.json.
fn machine_golden(
    result: &pxpl5_machine::RunResult,
    units: &[pxpl5_machine::Unit],
    functional: &[String],
    program_timing: &[String],
) -> String {
    let text = machine_golden::text(&result.stats, units, functional, program_timing);
    machine_golden::assert_holds_stats_json(&text, &result.stats.to_json());
    text
}

/// Runs `program` on the shipped config `config_file`: the result and the ring position of each
/// unit.
fn run_machine(
    config_file: &str,
    program: &dyn pxpl5_machine::Program,
) -> (pxpl5_machine::RunResult, Vec<pxpl5_machine::Unit>) {
    use pxpl5_machine::{Machine, Recorder, RunOptions};
    let path = workspace_root().join("machine-configs").join(config_file);
    let cfg = pxpl5_config::load_file(&path).expect("shipped configs are valid");
    let machine =
        Machine::new(&cfg, program, RunOptions::default(), Recorder::default()).expect("builds");
    (
        machine.run().expect("runs"),
        pxpl5_machine::node_order(&cfg),
    )
}

/// FNV-1a, 64 bits.
fn fnv1a64(words: impl IntoIterator<Item = u64>) -> u64 {
    words.into_iter().fold(0xcbf29ce484222325, |h, w| {
        (h ^ w).wrapping_mul(0x100000001b3)
    })
}

/// The polygon program on `programs/polygons/scenes/small.ron`.
fn polygons_small() -> pxpl5_polygons::Polygons {
    let scene = pxpl5_polygons::scene::load_triangle_scene(
        &workspace_root().join("programs/polygons/scenes/small.ron"),
    )
    .expect("the small scene is valid");
    pxpl5_polygons::Polygons::new(scene)
}

/// The polygon program's golden; functional: the frame's digest.
fn polygons_golden(config_file: &str) -> String {
    let (result, units) = run_machine(config_file, &polygons_small());
    let frame = fnv1a64(result.frame.rgb.iter().map(|&b| u64::from(b)));
    machine_golden(
        &result,
        &units,
        &[format!("frame fnv1a64: {frame:016x}")],
        &[],
    )
}

/// Three shots of the Cornell box (patches of 150 mm) with `method`; functional: the shooters,
/// reciprocity clamps, culls and the solution's digest; timing: when each shot ended.
fn radiosity_golden(config_file: &str, method: Method) -> String {
    use pxpl5_radiosity::shot::{CullCounts, FfOptions};
    use pxpl5_radiosity::{mesh::mesh, program::RadiosityProgram, scenes};
    let patches = mesh(&scenes::cornell_box(), 150.0).expect("meshes");
    let options = FfOptions {
        method,
        ..FfOptions::default()
    };
    let program = RadiosityProgram::new(patches, options, 3, 0.0);
    let (result, units) = run_machine(config_file, &program);
    let s = program.solution.borrow();
    let digest = fnv1a64(s.radiosity.iter().flatten().map(|x| x.to_bits()));
    let CullCounts {
        back_facing,
        below_horizon,
        coplanar,
        outside_face,
        unrepresentable,
        depth_range,
        drawn: _,
    } = s.culls;
    let shooters: Vec<String> = s.shots.iter().map(|(i, _)| i.to_string()).collect();
    let functional = [
        format!("method: {}", method.name()),
        format!("shooters: {}", shooters.join(", ")),
        format!("reciprocity clamps: {}", s.reciprocity_clamps),
        format!(
            "culls: back-facing {back_facing}, below horizon {below_horizon}, coplanar \
             {coplanar}, outside face {outside_face}, unrepresentable {unrepresentable}, \
             depth range {depth_range}"
        ),
        format!("solution fnv1a64: {digest:016x}"),
    ];
    let timing: Vec<String> = s
        .shots
        .iter()
        .enumerate()
        .map(|(k, (i, end))| {
            format!(
                "{:<26} {:>14} ps",
                format!("shot {k} (patch {i}) ended"),
                end.0
            )
        })
        .collect();
    machine_golden(&result, &units, &functional, &timing)
}

/// One golden per (program, shipped config): `machine_goldens! { name: golden_fn, ... }` makes a
/// module `name` with a test per config of `machine-configs/` (`name::minimal`, ...), whose
/// snapshot is `snapshots/goldens__{name}_{config}.snap`; `golden_fn` maps a config file to the
/// golden text.
macro_rules! machine_goldens {
    ($($program:ident: $golden:expr),* $(,)?) => {
        machine_goldens!(@cross [
            minimal: "minimal.ron",
            pxpl5_1989: "pxpl5-1989.ron",
            seed_tr89_002: "seed-tr89-002.ron"
        ] $($program: $golden),*);
    };
    (@cross $configs:tt $($program:ident: $golden:expr),*) => {
        machine_goldens!(@list $configs);
        $(machine_goldens!(@program $program, $golden, $configs);)*
    };
    (@list [$($config:ident: $file:literal),*]) => {
        /// The config files the machine goldens run on.
        const MACHINE_CONFIGS: &[&str] = &[$($file),*];
    };
    (@program $program:ident, $golden:expr, [$($config:ident: $file:literal),*]) => {
        mod $program {
            use super::*;
            $(
                #[test]
                fn $config() {
                    let golden: fn(&str) -> String = $golden;
                    assert_machine_golden(
                        concat!(stringify!($program), "_", stringify!($config)),
                        &golden($file),
                    );
                }
            )*
        }
    };
}

/// Compares `text` with `snapshots/goldens__{name}.snap`.
fn assert_machine_golden(name: &str, text: &str) {
    insta::assert_snapshot!(name, text);
}

machine_goldens! {
    polygons_small: polygons_golden,
    radiosity_cornell_hemisphere: |cfg| radiosity_golden(cfg, Method::Hemisphere),
    radiosity_cornell_hemicube: |cfg| radiosity_golden(cfg, Method::Hemicube),
}

/// The machine goldens cover every shipped config.
#[test]
fn machine_goldens_run_on_every_shipped_config() {
    let mut shipped: Vec<String> = std::fs::read_dir(workspace_root().join("machine-configs"))
        .expect("machine-configs/ exists")
        .map(|e| {
            e.expect("readable")
                .file_name()
                .to_string_lossy()
                .into_owned()
        })
        .filter(|n| n.ends_with(".ron"))
        .collect();
    shipped.sort();
    assert_eq!(shipped, MACHINE_CONFIGS);
}

/// The check of a machine golden is not vacuous: a text that holds one figure of stats.json
/// once fewer than the JSON does fails it.
#[test]
fn machine_golden_check_notices_a_dropped_figure() {
    let (result, units) = run_machine("minimal.ron", &polygons_small());
    let text = machine_golden::text(&result.stats, &units, &[], &[]);
    let json = result.stats.to_json();
    assert_eq!(machine_golden::holds_stats_json(&text, &json), Ok(()));
    let end = result.stats.end.0.to_string();
    let err = machine_golden::holds_stats_json(&text.replacen(&end, "", 1), &json).unwrap_err();
    assert!(
        err.contains("lacks these numbers of stats.json") && err.contains(&end),
        "{err}"
    );
}

/// The same radiosity run twice, and at both fidelity levels: identical stats and solution.
#[test]
fn radiosity_is_deterministic_across_runs_and_fidelity_levels() {
    use pxpl5_machine::{Machine, Recorder, RunOptions};
    use pxpl5_radiosity::{mesh::mesh, program::RadiosityProgram, scenes, shot::FfOptions};
    let cfg = pxpl5_config::default_config();
    let patches = mesh(&scenes::cornell_box(), 200.0).expect("meshes");
    let run = |fidelity| {
        let program = RadiosityProgram::new(patches.clone(), FfOptions::default(), 2, 0.0);
        let options = RunOptions {
            fidelity,
            ..RunOptions::default()
        };
        let r = Machine::new(
            &cfg,
            &program,
            options,
            Recorder::new(Some(Default::default()), None),
        )
        .expect("builds")
        .run()
        .expect("runs");
        let mut json = r.stats.to_json();
        json["fidelity"] = serde_json::Value::Null;
        let mut trace = Vec::new();
        r.recorder.write_chrome(&mut trace).expect("writes");
        let b = program.solution.borrow().radiosity.clone();
        (json.to_string(), trace, b)
    };
    let a = run(pxpl5_renderer::Fidelity::Integer);
    let b = run(pxpl5_renderer::Fidelity::Integer);
    let c = run(pxpl5_renderer::Fidelity::Bit);
    assert!(a == b, "two identical runs differ");
    assert!(a.0 == c.0 && a.2 == c.2, "bit and word levels differ");
}
