//! Cycle-count goldens, one file per case in `tests/snapshots/`:
//! - the Renderer: the benchmark's hemisphere mix on every shipped machine config, at both
//!   fidelity levels; each golden records the Renderer cycles, the per-kind command counts and
//!   cycles, and the digest of the board's final state;
//! - the machine: the polygon program on `programs/polygons/scenes/small.ron` on every shipped
//!   config; each golden is the run's stats.json (simulated figures only), plus a digest of the
//!   frame.
//!
//! A golden changes only on purpose, in a commit whose message says why the timing changed
//! (`INSTA_UPDATE=always cargo test -p pxpl5-tests --test goldens` rewrites them).

use std::fmt::Write;

use pxpl5_renderer::{Board, Fidelity, workload};
use pxpl5_tests::workspace_root;

fn golden(config_file: &str) -> String {
    let path = workspace_root().join("machine-configs").join(config_file);
    let cfg = pxpl5_config::load_file(&path).expect("shipped configs are valid");
    let mix = workload::hemisphere_mix(&cfg.renderer, 40, 7).expect("the mix fits every config");
    let mut out = String::new();
    let mut first: Option<(u64, String)> = None;
    for fidelity in [Fidelity::Bit, Fidelity::Word] {
        let mut board = Board::new(&cfg.renderer, cfg.ring.word_bits, fidelity);
        let cycles = mix.run(&mut board).expect("the mix runs").0;
        let digest = board.image().digest();
        match &first {
            None => {
                writeln!(out, "config: {} ({})", cfg.name, config_file).unwrap();
                writeln!(out, "workload: {}", mix.description).unwrap();
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
    out
}

#[test]
fn renderer_mix_seed_tr89_002() {
    insta::assert_snapshot!(golden("seed-tr89-002.ron"));
}

#[test]
fn renderer_mix_pxpl5_1989() {
    insta::assert_snapshot!(golden("pxpl5-1989.ron"));
}

#[test]
fn renderer_mix_minimal() {
    insta::assert_snapshot!(golden("minimal.ron"));
}

fn polygons_golden(config_file: &str) -> String {
    use pxpl5_machine::{Machine, Recorder, RunOptions};
    let root = workspace_root();
    let cfg = pxpl5_config::load_file(&root.join("machine-configs").join(config_file))
        .expect("shipped configs are valid");
    let scene =
        pxpl5_config::scene::load_triangle_scene(&root.join("programs/polygons/scenes/small.ron"))
            .expect("the small scene is valid");
    let program = pxpl5_polygons::Polygons::new(scene);
    let result = Machine::new(&cfg, &program, RunOptions::default(), Recorder::default())
        .expect("builds")
        .run()
        .expect("runs");
    let frame: u64 = result.frame.rgb.iter().fold(0xcbf29ce484222325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x100000001b3)
    });
    format!(
        "frame fnv1a64: {frame:016x}\n{}",
        serde_json::to_string_pretty(&result.stats.to_json()).expect("json")
    )
}

#[test]
fn polygons_small_seed_tr89_002() {
    insta::assert_snapshot!(polygons_golden("seed-tr89-002.ron"));
}

#[test]
fn polygons_small_pxpl5_1989() {
    insta::assert_snapshot!(polygons_golden("pxpl5-1989.ron"));
}

#[test]
fn polygons_small_minimal() {
    insta::assert_snapshot!(polygons_golden("minimal.ron"));
}
