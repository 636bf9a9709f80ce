//! Cycle-count goldens of the Renderer: the benchmark's hemisphere mix on every shipped machine
//! config, run at both fidelity levels. Each golden records the Renderer cycles, the per-kind
//! command counts and cycles, and the digest of the board's final state.
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
