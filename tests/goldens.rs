//! Cycle-count goldens, one file per case in `tests/snapshots/`:
//! - the Renderer: the benchmark's hemisphere mix on every shipped machine config, at both
//!   fidelity levels; each golden records the Renderer cycles, the per-kind command counts and
//!   cycles, and the digest of the board's final state;
//! - the machine: the polygon program on `programs/polygons/scenes/small.ron` on every shipped
//!   config; each golden is the run's stats.json (simulated figures only), plus a digest of the
//!   frame;
//! - radiosity: three shots of the Cornell box (patches of 150 mm) with each form-factor method
//!   on every shipped config; each golden is the run's stats.json, the shooters, and a digest of
//!   the solution.
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
    let scene = pxpl5_polygons::scene::load_triangle_scene(
        &root.join("programs/polygons/scenes/small.ron"),
    )
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

fn radiosity_golden(config_file: &str, method: pxpl5_radiosity::shot::Method) -> String {
    use pxpl5_machine::{Machine, Recorder, RunOptions};
    use pxpl5_radiosity::{mesh::mesh, program::RadiosityProgram, scenes, shot::FfOptions};
    let root = workspace_root();
    let cfg = pxpl5_config::load_file(&root.join("machine-configs").join(config_file))
        .expect("shipped configs are valid");
    let patches = mesh(&scenes::cornell_box(), 150.0).expect("meshes");
    let options = FfOptions {
        method,
        ..FfOptions::default()
    };
    let program = RadiosityProgram::new(patches, options, 3, 0.0);
    let result = Machine::new(&cfg, &program, RunOptions::default(), Recorder::default())
        .expect("builds")
        .run()
        .expect("runs");
    let s = program.solution.borrow();
    let digest = s
        .radiosity
        .iter()
        .flat_map(|b| b.iter())
        .fold(0xcbf29ce484222325u64, |h, x| {
            (h ^ x.to_bits()).wrapping_mul(0x100000001b3)
        });
    format!(
        "shooters: {:?}\nreciprocity clamps: {}\nculls: {:?}\nsolution fnv1a64: {digest:016x}\n{}",
        s.shots.iter().map(|(i, t)| (*i, t.0)).collect::<Vec<_>>(),
        s.reciprocity_clamps,
        s.culls,
        serde_json::to_string_pretty(&result.stats.to_json()).expect("json")
    )
}

#[test]
fn radiosity_cornell_hemisphere_seed_tr89_002() {
    insta::assert_snapshot!(radiosity_golden(
        "seed-tr89-002.ron",
        pxpl5_radiosity::shot::Method::Hemisphere
    ));
}

#[test]
fn radiosity_cornell_hemicube_seed_tr89_002() {
    insta::assert_snapshot!(radiosity_golden(
        "seed-tr89-002.ron",
        pxpl5_radiosity::shot::Method::Hemicube
    ));
}

#[test]
fn radiosity_cornell_hemisphere_pxpl5_1989() {
    insta::assert_snapshot!(radiosity_golden(
        "pxpl5-1989.ron",
        pxpl5_radiosity::shot::Method::Hemisphere
    ));
}

#[test]
fn radiosity_cornell_hemicube_pxpl5_1989() {
    insta::assert_snapshot!(radiosity_golden(
        "pxpl5-1989.ron",
        pxpl5_radiosity::shot::Method::Hemicube
    ));
}

#[test]
fn radiosity_cornell_hemisphere_minimal() {
    insta::assert_snapshot!(radiosity_golden(
        "minimal.ron",
        pxpl5_radiosity::shot::Method::Hemisphere
    ));
}

#[test]
fn radiosity_cornell_hemicube_minimal() {
    insta::assert_snapshot!(radiosity_golden(
        "minimal.ron",
        pxpl5_radiosity::shot::Method::Hemicube
    ));
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
    let a = run(pxpl5_renderer::Fidelity::Word);
    let b = run(pxpl5_renderer::Fidelity::Word);
    let c = run(pxpl5_renderer::Fidelity::Bit);
    assert!(a == b, "two identical runs differ");
    assert!(a.0 == c.0 && a.2 == c.2, "bit and word levels differ");
}
