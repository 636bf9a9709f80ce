//! The `pxpl5` command as a user runs it: exit codes, messages naming file, line and field, and
//! the benchmark's agreement between fidelity levels.

use std::collections::BTreeSet;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};

use pxpl5_tests::OutDir;

fn pxpl5(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pxpl5"))
        .args(args)
        .current_dir(root())
        .output()
        .expect("pxpl5 runs")
}

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// A file `name` holding `contents`, in a directory of its own removed when the test passes.
fn temp_file(name: &str, contents: &str) -> TempFile {
    let dir = OutDir::new("pxpl5-cli-test", name);
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, contents).unwrap();
    TempFile { _dir: dir, path }
}

/// What [`temp_file`] writes: its path, and the directory that goes with it.
struct TempFile {
    _dir: OutDir,
    path: PathBuf,
}

impl std::ops::Deref for TempFile {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.path
    }
}

impl AsRef<Path> for TempFile {
    fn as_ref(&self) -> &Path {
        &self.path
    }
}

#[test]
fn shipped_configs_check() {
    let out = pxpl5(&[
        "config",
        "check",
        "machine-configs/seed-tr89-002.ron",
        "machine-configs/pxpl5-1989.ron",
        "machine-configs/minimal.ron",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let stdout = text(&out.stdout);
    assert_eq!(stdout.matches(": ok").count(), 3, "{stdout}");
}

#[test]
fn a_typo_fails_with_line_and_column() {
    let f = temp_file(
        "typo.ron",
        "(\n    name: \"typo\",\n    gp: (count: 1),\n    ring: (chanels: 4),\n    renderer: (count: 1),\n)\n",
    );
    let out = pxpl5(&["config", "check", f.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    let err = text(&out.stderr);
    assert!(err.contains("typo.ron:4:12"), "{err}");
    assert!(err.contains("chanels") && err.contains("channels"), "{err}");
}

#[test]
fn a_semantic_error_names_the_field() {
    let f = temp_file(
        "zero.ron",
        "(name: \"zero\", gp: (count: 1), ring: (channels: 0), renderer: (count: 1))",
    );
    let out = pxpl5(&["bench", "renderer", "--config", f.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        text(&out.stderr).contains("ring.channels"),
        "{}",
        text(&out.stderr)
    );
}

#[test]
fn a_missing_file_is_a_user_error() {
    let out = pxpl5(&["config", "show", "no/such/file.ron"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(text(&out.stderr).contains("no/such/file.ron"));
}

#[test]
fn show_prints_provenance_and_parses_back() {
    let out = pxpl5(&["config", "show"]);
    assert!(out.status.success());
    let shown = text(&out.stdout);
    assert!(shown.contains("[assumed]") && shown.contains("[paper]"));
    let back = pxpl5_config_parse(&shown);
    assert!(back, "config show output does not parse back");
}

fn pxpl5_config_parse(text: &str) -> bool {
    let f = temp_file("shown.ron", text);
    pxpl5(&["config", "check", f.to_str().unwrap()])
        .status
        .success()
}

#[test]
fn bench_levels_print_the_same_cycles_and_digest() {
    let out = pxpl5(&[
        "bench",
        "renderer",
        "--shots",
        "1",
        "--resolution",
        "64",
        "--repeat",
        "1",
        "--json",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let streams = v["streams"].as_array().unwrap();
    assert_eq!(streams.len(), 2);
    assert_eq!(streams[0]["method"], "hemisphere");
    assert_eq!(streams[1]["method"], "hemicube");
    for s in streams {
        let levels = s["levels"].as_array().unwrap();
        assert_eq!(levels.len(), 3);
        assert_eq!(levels[0]["fidelity"], "bit");
        assert_eq!(levels[2]["fidelity"], "sparse");
        for other in &levels[1..] {
            assert_eq!(levels[0]["renderer_cycles"], other["renderer_cycles"]);
            assert_eq!(levels[0]["digest"], other["digest"]);
        }
        assert!(levels[0]["renderer_cycles"].as_u64().unwrap() > 50_000);
        assert_eq!(s["shooters"].as_array().unwrap().len(), 1);
    }
    assert_eq!(v["levels_agree"], true);
}

#[test]
fn machine_bench_levels_give_the_same_time_and_solution() {
    let out = pxpl5(&[
        "bench",
        "machine",
        "--shots",
        "2",
        "--fidelity",
        "all",
        "--json",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["levels_agree"], true);
    assert_eq!(v["patches"], 199, "the main job's mesh");
    let methods = v["methods"].as_array().unwrap();
    assert_eq!(methods.len(), 2);
    for m in methods {
        let levels = m["levels"].as_array().unwrap();
        assert_eq!(levels.len(), 3);
        for other in &levels[1..] {
            assert_eq!(levels[0]["simulated_seconds"], other["simulated_seconds"]);
        }
        // Two shots (one batch of the seed's 4 shooters cut to 2) take a few simulated ms.
        let t = levels[0]["simulated_seconds"].as_f64().unwrap();
        assert!((1e-3..20e-3).contains(&t), "{m}");
        assert!(levels[1]["host_seconds"].as_f64().unwrap() > 0.0);
        assert!(levels[1]["host_instructions"].is_null(), "not asked for");
    }
}

/// `bench machine --main-job` times each method as `pxpl5 radiosity` runs it: the same shots
/// to the 1 % target and the same simulated time as the main job's own report, and a host
/// figure for the simulation alone.
#[test]
fn machine_bench_runs_the_main_job_as_the_main_job_does() {
    let out = pxpl5(&[
        "bench",
        "machine",
        "--main-job",
        "--method",
        "hemicube",
        "--fidelity",
        "sparse",
        "--json",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["main_job"], true);
    assert!(v["shots"].is_null(), "no fixed number of shots");
    let level = &v["methods"][0]["levels"][0];
    let d = out_dir("bench-main-job");
    let job = pxpl5(&[
        "radiosity",
        "--method",
        "hemicube",
        "-q",
        "--out",
        d.to_str().unwrap(),
    ]);
    assert!(job.status.success(), "{}", text(&job.stderr));
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("comparison.json")).unwrap()).unwrap();
    let method = &json["methods"][0];
    assert_eq!(level["shots"], method["shots"]);
    assert_eq!(
        level["simulated_seconds"].as_f64().unwrap(),
        simulated_ps(&d) as f64 * 1e-12
    );
    // The main job takes hundreds of shots: more than a fixed run's default 24.
    assert!(level["shots"].as_u64().unwrap() > 24, "{level}");
    assert!(level["host_seconds"].as_f64().unwrap() > 0.0);
    // A fixed number of shots and the main job's plan are one or the other.
    let both = pxpl5(&["bench", "machine", "--main-job", "--shots", "3"]);
    assert_eq!(both.status.code(), Some(2));
}

#[test]
fn bench_counts_instructions_with_valgrind_or_says_it_needs_it() {
    let out = pxpl5(&[
        "bench",
        "renderer",
        "--instructions",
        "--shots",
        "1",
        "--resolution",
        "16",
        "--method",
        "hemicube",
        "--fidelity",
        "integer",
        "--repeat",
        "1",
        "--json",
    ]);
    let has_valgrind = std::process::Command::new("valgrind")
        .arg("--version")
        .output()
        .is_ok_and(|o| o.status.success());
    if !has_valgrind {
        assert_eq!(out.status.code(), Some(2));
        assert!(
            text(&out.stderr).contains("needs valgrind"),
            "{}",
            text(&out.stderr)
        );
        return;
    }
    assert!(out.status.success(), "{}", text(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let level = &v["streams"][0]["levels"][0];
    let (ir, cycles) = (
        level["host_instructions"].as_u64().unwrap(),
        level["renderer_cycles"].as_u64().unwrap(),
    );
    // Only the stream's execution is counted (not the process's set-up or the digest): tens to
    // a few thousand instructions per simulated Renderer cycle.
    let per = level["instructions_per_cycle"].as_f64().unwrap();
    assert!((10.0..5_000.0).contains(&per), "{per} per cycle");
    assert!((per - ir as f64 / cycles as f64).abs() < 1e-6);
}

#[test]
fn help_explains_each_subcommand() {
    let out = pxpl5(&["--help"]);
    let help = text(&out.stdout);
    assert!(help.contains("config") && help.contains("bench"), "{help}");
    let out = pxpl5(&["bench", "renderer", "--help"]);
    assert!(text(&out.stdout).contains("--fidelity"));
    let out = pxpl5(&["frobnicate"]);
    assert_eq!(out.status.code(), Some(2));
}

fn out_dir(name: &str) -> OutDir {
    OutDir::new("pxpl5-cli-run", name)
}

/// `pxpl5 run` on the small scene of the minimal machine: the arguments every such test starts
/// with.
const SMALL_RUN: [&str; 5] = [
    "run",
    "--config",
    "machine-configs/minimal.ron",
    "--scene",
    "programs/polygons/scenes/small.ron",
];

fn run_small(out: &std::path::Path) -> Output {
    let (trace, vcd) = (out.join("trace.json"), out.join("trace.vcd"));
    run_small_with(
        out,
        &[
            "--trace",
            trace.to_str().unwrap(),
            "--vcd",
            vcd.to_str().unwrap(),
        ],
    )
}

#[test]
fn run_writes_outputs_and_is_deterministic() {
    let (a, b) = (out_dir("a"), out_dir("b"));
    for d in [&a, &b] {
        let out = run_small(d);
        assert!(out.status.success(), "{}", text(&out.stderr));
        let stdout = text(&out.stdout);
        assert!(
            stdout.contains("triangles per simulated second"),
            "{stdout}"
        );
        assert!(stdout.contains("1,000,000 Phong-shaded"), "{stdout}");
    }
    for f in [
        "stats.json",
        "config.ron",
        "frame.png",
        "trace.json",
        "trace.vcd",
    ] {
        let x = std::fs::read(a.join(f)).unwrap();
        let y = std::fs::read(b.join(f)).unwrap();
        assert!(!x.is_empty(), "{f} is empty");
        assert!(x == y, "{f} differs between two identical runs");
    }
    let stats: serde_json::Value =
        serde_json::from_slice(&std::fs::read(a.join("stats.json")).unwrap()).unwrap();
    assert_eq!(stats["program"], "polygons");
    assert!(stats["simulated_ps"].as_u64().unwrap() > 0);
    let json = std::fs::read_to_string(a.join("stats.json")).unwrap();
    assert!(
        !json.contains("host"),
        "host figures leaked into stats.json"
    );
    let trace: serde_json::Value =
        serde_json::from_slice(&std::fs::read(a.join("trace.json")).unwrap()).unwrap();
    assert!(trace["traceEvents"].as_array().unwrap().len() > 50);
    let vcd = std::fs::read_to_string(a.join("trace.vcd")).unwrap();
    assert!(vcd.contains("$timescale 1 ps $end") && vcd.contains("$enddefinitions"));
    let png = std::fs::read(a.join("frame.png")).unwrap();
    assert_eq!(&png[1..4], b"PNG");
}

/// `run`'s Renderers on host threads (by default as many as the host has cores): the seed
/// machine's four boards on 1, 2 and 8 threads and by default give the same bytes, traces too.
#[test]
fn run_outputs_are_the_same_on_any_number_of_host_threads() {
    let files = ["stats.json", "frame.png", "t.json", "t.vcd"];
    let outputs = |threads: Option<&str>| -> Vec<Vec<u8>> {
        let d = out_dir(&format!("run-threads-{}", threads.unwrap_or("default")));
        let (trace, vcd) = (d.join("t.json"), d.join("t.vcd"));
        let mut args = vec!["run", "--triangles", "300", "--out", d.to_str().unwrap()];
        args.extend(["--trace", trace.to_str().unwrap()]);
        args.extend(["--vcd", vcd.to_str().unwrap()]);
        if let Some(n) = threads {
            args.extend(["--threads", n]);
        }
        let out = pxpl5(&args);
        assert!(out.status.success(), "{}", text(&out.stderr));
        files
            .iter()
            .map(|f| std::fs::read(d.join(f)).unwrap())
            .collect()
    };
    let one = outputs(Some("1"));
    for threads in [Some("2"), Some("8"), None] {
        let other = outputs(threads);
        for ((f, a), b) in files.iter().zip(&one).zip(&other) {
            assert!(a == b, "{f} differs on {threads:?} threads");
        }
    }
}

#[test]
fn the_sparse_level_gives_integer_results_on_boards_run_ahead_on_threads() {
    // The frame and every simulated figure on the seed machine's four Renderers, each on a
    // host worker; the stats differ only in naming the level.
    let run = |fidelity: &str, d: &std::path::Path| {
        let out = pxpl5(&[
            "run",
            "--scene",
            "programs/polygons/scenes/small.ron",
            "--out",
            d.to_str().unwrap(),
            "--fidelity",
            fidelity,
            "--threads",
            "2",
        ]);
        assert!(out.status.success(), "{}", text(&out.stderr));
        let mut stats: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(d.join("stats.json")).unwrap()).unwrap();
        assert_eq!(stats["fidelity"], fidelity);
        stats["fidelity"] = serde_json::Value::Null;
        (stats, std::fs::read(d.join("frame.png")).unwrap())
    };
    let (a, b) = (out_dir("sparse-level"), out_dir("sparse-integer"));
    let (sparse, integer) = (run("sparse", &a), run("integer", &b));
    assert!(sparse.0 == integer.0, "stats differ");
    assert!(sparse.1 == integer.1, "frames differ");
}

#[test]
fn fidelity_word_is_a_hidden_alias_of_integer() {
    let run = |fidelity: &str, d: &std::path::Path| {
        let out = run_small_with(d, &["--fidelity", fidelity]);
        assert!(out.status.success(), "{}", text(&out.stderr));
        std::fs::read_to_string(d.join("stats.json")).unwrap()
    };
    let (old, new) = (out_dir("fidelity-word"), out_dir("fidelity-integer"));
    let stats = run("word", &old);
    assert_eq!(stats, run("integer", &new), "word must run as integer");
    let json: serde_json::Value = serde_json::from_str(&stats).unwrap();
    assert_eq!(json["fidelity"], "integer");
    // Hidden: neither the help nor the list of values in an error names the old value.
    for command in ["run", "radiosity"] {
        let help = text(&pxpl5(&[command, "--help"]).stdout);
        // The option's entry: its line and, in the long help, the next.
        let entry = help.split("--fidelity <FIDELITY>").nth(1).unwrap();
        let entry = entry.split("\n      --").next().unwrap();
        assert!(
            entry.contains("[possible values: bit, integer, sparse, timing]"),
            "{entry}"
        );
        assert!(!entry.contains("word"), "{entry}");
        let out = pxpl5(&[command, "--fidelity", "words"]);
        assert_eq!(out.status.code(), Some(2));
        let err = text(&out.stderr);
        assert!(
            err.contains("bit, integer") && !err.contains("word,"),
            "{err}"
        );
    }
}

#[test]
fn run_rejects_bad_input_without_writing() {
    let good = std::fs::read_to_string(root().join("programs/polygons/scenes/small.ron")).unwrap();
    let nan = temp_file(
        "nan.ron",
        &good.replacen("(-9.0, -7.0, -6.0)", "(NaN, -7.0, -6.0)", 1),
    );
    let flat = temp_file(
        "flat.ron",
        &good.replacen("(0.0, 3.0, 0.0)", "(-3.0, -2.0, -1.0)", 1),
    );
    for (scene, needle) in [(&nan, "triangles[0].vertices[0]"), (&flat, "triangles[2]")] {
        let out_d = out_dir("bad");
        let out = pxpl5(&[
            "run",
            "--scene",
            scene.to_str().unwrap(),
            "--out",
            out_d.to_str().unwrap(),
        ]);
        assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
        assert!(text(&out.stderr).contains(needle), "{}", text(&out.stderr));
        assert!(!out_d.join("stats.json").exists(), "half-written output");
    }
    let out = pxpl5(&["run", "--program", "teapots"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(text(&out.stderr).contains("teapots"));
    // An output directory under a regular file cannot be created.
    let file = temp_file("not-a-dir", "x");
    let out = pxpl5(&[
        "run",
        "--triangles",
        "3",
        "--out",
        file.join("sub").to_str().unwrap(),
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        text(&out.stderr).contains("not-a-dir"),
        "{}",
        text(&out.stderr)
    );
    let out = pxpl5(&["run", "--triangles", "3", "--trace-window", "5ms..1ms"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(text(&out.stderr).contains("--trace-window"));
}

#[test]
fn radiosity_compares_both_methods_with_the_seed() {
    // 8 shots of 200 mm patches into `d`, with `extra` options.
    let radiosity = |d: &Path, extra: &[&str]| {
        let mut args = vec!["radiosity", "--shots", "8", "--patch-size", "200"];
        args.extend(["--out", d.to_str().unwrap()]);
        args.extend_from_slice(extra);
        pxpl5(&args)
    };
    let out_d = out_dir("radiosity");
    let out = radiosity(&out_d, &[]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let stdout = text(&out.stdout);
    for wanted in [
        "4 Renderers",
        "4 shooters per batch",
        "the same view scheduler",
        "against the direct solve with exact form factors",
        "time per shot (ms)",
        "time to target (ms)",
        "form-factor error",
        "Renderer board-ms per shot",
        "Renderer utilisation",
        "seed's estimate per shot",
        "hemicube / hemisphere, time per shot",
    ] {
        assert!(stdout.contains(wanted), "{wanted}: {stdout}");
    }
    // 8 shots of 76 patches are far from 1 %: said so, not a time.
    assert!(stdout.contains("not reached"), "{stdout}");
    let csv = std::fs::read_to_string(out_d.join("comparison.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert_eq!(lines.len(), 4, "{csv}");
    // The first line records the options, the config hash and the version.
    assert!(
        lines[0].starts_with("# pxpl5 ") && lines[0].contains("\"config_hash\""),
        "{}",
        lines[0]
    );
    assert!(
        csv.contains("\nhemisphere,8,76,4,") && csv.contains("\nhemicube,8,76,4,"),
        "{csv}"
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out_d.join("comparison.json")).unwrap())
            .unwrap();
    assert_eq!(json["options"]["patch_size"], 200.0);
    assert_eq!(json["options"]["shooters_at_once"], 4);
    assert_eq!(json["options"]["until_error"], 0.01);
    let accuracy = &json["methods"][0]["accuracy"];
    assert!(
        accuracy["final_error"].as_f64().unwrap() > 0.01,
        "{accuracy}"
    );
    assert!(accuracy["time_to_target_s"].is_null(), "{accuracy}");
    for method in ["hemisphere", "hemicube"] {
        let png = std::fs::read(out_d.join(format!("radiosity-{method}.png"))).unwrap();
        assert_eq!(&png[1..4], b"PNG");
        let decoder = png::Decoder::new(std::io::Cursor::new(&png));
        let reader = decoder.read_info().unwrap();
        let comment = reader
            .info()
            .uncompressed_latin1_text
            .iter()
            .find(|t| t.keyword == "Comment")
            .map(|t| t.text.clone())
            .unwrap_or_default();
        assert!(comment.contains("\"resolution\":128"), "{comment}");
        let patches = std::fs::read_to_string(out_d.join(format!("patches-{method}.csv"))).unwrap();
        assert!(patches.starts_with("# pxpl5 "));
        assert_eq!(patches.lines().count(), 2 + 76);
        let curve =
            std::fs::read_to_string(out_d.join(format!("convergence-{method}.csv"))).unwrap();
        // 8 shots in batches of up to 4 (the first is the light's one patch alone: nothing
        // else has power yet), the error falling.
        let rows: Vec<Vec<f64>> = curve
            .lines()
            .skip(2)
            .map(|l| l.split(',').map(|x| x.parse().unwrap()).collect())
            .collect();
        assert!(rows.len() >= 2, "{curve}");
        let (first, last) = (&rows[0], &rows[rows.len() - 1]);
        assert_eq!(last[1], 8.0, "{curve}");
        assert!(last[3] < first[3], "{curve}");
    }

    // The methods ran at once (the host has the cores; 2 on CI): in turn, every file and the
    // report are the same, byte for byte, but for the host seconds.
    let turn_d = out_dir("radiosity-in-turn");
    let turn = radiosity(&turn_d, &["--in-turn"]);
    assert!(turn.status.success(), "{}", text(&turn.stderr));
    let (at_once, in_turn) = (listing(&out_d), listing(&turn_d));
    let names = |l: &[(String, Vec<u8>)]| l.iter().map(|f| f.0.clone()).collect::<Vec<_>>();
    assert_eq!(names(&at_once), names(&in_turn));
    assert_eq!(at_once.len(), 9, "{:?}", names(&at_once));
    for (a, b) in at_once.iter().zip(&in_turn) {
        assert!(a.1 == b.1, "{} differs in turn", a.0);
    }
    let report = |out: &Output, d: &Path| -> String {
        text(&out.stdout)
            .lines()
            .filter(|l| !l.trim_start().starts_with("host seconds"))
            .map(|l| l.replace(d.to_str().unwrap(), "OUT") + "\n")
            .collect()
    };
    assert_eq!(report(&out, &out_d), report(&turn, &turn_d));
}

#[test]
fn formfactor_exact_and_on_the_machine() {
    let square = "-1,-1,1;1,-1,1;1,1,1;-1,1,1";
    let out = pxpl5(&[
        "formfactor",
        "--point",
        "0,0,0",
        "--normal",
        "0,0,1",
        "--polygon",
        square,
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    // Four corner rectangles of 1 x 1 at distance 1: 4 x 0.138532... (Howell's catalogue).
    assert!(
        text(&out.stdout).contains("0.5541264"),
        "{}",
        text(&out.stdout)
    );
    let out = pxpl5(&[
        "formfactor",
        "--point",
        "0,0,0",
        "--normal",
        "0,0,1",
        "--polygon",
        square,
        "--method",
        "hemicube",
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(
        text(&out.stdout).contains("Renderer busy"),
        "{}",
        text(&out.stdout)
    );
    let out = pxpl5(&[
        "formfactor",
        "--point",
        "0,0",
        "--normal",
        "0,0,1",
        "--polygon",
        square,
    ]);
    assert_eq!(out.status.code(), Some(2));
    assert!(text(&out.stderr).contains("--point"));
}

/// The square of side 2 at height 1 above the origin, as `--polygon` takes it.
const SQUARE: &str = "-1,-1,1;1,-1,1;1,1,1;-1,1,1";

/// `pxpl5 formfactor` from the origin, normal `normal`, to `polygon`, with `more` flags.
fn formfactor(normal: &str, polygon: &str, more: &[&str]) -> Output {
    let mut args = vec![
        "formfactor",
        "--point",
        "0,0,0",
        "--normal",
        normal,
        "--polygon",
        polygon,
    ];
    args.extend(more);
    pxpl5(&args)
}

/// The value after `label: ` on its line of `out`'s stdout, up to the next space.
fn value_of(out: &Output, label: &str) -> String {
    let stdout = text(&out.stdout);
    let line = stdout
        .lines()
        .find_map(|l| l.strip_prefix(&format!("{label}: ")))
        .unwrap_or_else(|| panic!("no {label:?} in {stdout}"));
    line.split(' ').next().unwrap_or("").to_string()
}

fn f64_of(out: &Output, label: &str) -> f64 {
    let v = value_of(out, label);
    v.parse()
        .unwrap_or_else(|_| panic!("{label}: {v:?} is not a number"))
}

/// The square's corners as vectors, scaled by `s`.
fn square_points(s: f64) -> Vec<pxpl5_geom::DVec3> {
    SQUARE
        .split(';')
        .map(|v| {
            let c: Vec<f64> = v
                .split(',')
                .map(|x| x.parse::<f64>().unwrap() * s)
                .collect();
            pxpl5_geom::DVec3::new(c[0], c[1], c[2])
        })
        .collect()
}

#[test]
fn formfactor_prints_round_trip_values_and_both_errors() {
    use pxpl5_radiosity::exact::point_to_polygon;
    let exact = point_to_polygon(
        pxpl5_geom::DVec3::ZERO,
        pxpl5_geom::DVec3::Z,
        &square_points(1.0),
    );
    let out = formfactor("0,0,1", SQUARE, &["--method", "hemicube"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    // Every printed number reads back as the very f64 computed.
    let f = f64_of(&out, "hemicube form factor");
    assert_eq!(f64_of(&out, "exact form factor"), exact);
    let absolute = f64_of(&out, "absolute error");
    assert_eq!(absolute, f - exact);
    assert_eq!(f64_of(&out, "relative error"), absolute / exact);
    // The hemicube's error here is below 1e-4 in magnitude (about -7e-5 with the default seeded
    // turn of the view): scientific notation, all its digits.
    assert!(absolute.abs() < 1e-4, "{absolute}");
    assert!(
        value_of(&out, "absolute error").contains("e-"),
        "{}",
        text(&out.stdout)
    );
    assert!(!text(&out.stdout).contains('%'));
    assert!(text(&out.stdout).contains("Renderer busy"));
    // --help states the rule.
    let help = text(&pxpl5(&["formfactor", "--help"]).stdout);
    assert!(
        help.contains("shortest decimal that reads back as the same f64"),
        "{help}"
    );

    // A tiny form factor keeps its digits (nine fixed decimals printed 0.000000000).
    let far = "1000,1000,1;1001,1000,1;1001,1001,1";
    let out = formfactor("0,0,1", far, &[]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let far_points = [
        pxpl5_geom::DVec3::new(1000.0, 1000.0, 1.0),
        pxpl5_geom::DVec3::new(1001.0, 1000.0, 1.0),
        pxpl5_geom::DVec3::new(1001.0, 1001.0, 1.0),
    ];
    let exact = point_to_polygon(pxpl5_geom::DVec3::ZERO, pxpl5_geom::DVec3::Z, &far_points);
    assert!(exact > 0.0 && exact < 1e-10, "{exact}");
    assert_eq!(f64_of(&out, "exact form factor"), exact);
    assert!(value_of(&out, "exact form factor").contains("e-14"));
}

#[test]
fn formfactor_relative_error_is_undefined_when_the_exact_value_is_0() {
    // The square lies wholly behind the point: F = 0 exactly, on the machine too.
    let out = formfactor("0,0,-1", SQUARE, &["--method", "hemisphere"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let stdout = text(&out.stdout);
    assert_eq!(f64_of(&out, "exact form factor"), 0.0);
    assert_eq!(f64_of(&out, "hemisphere form factor"), 0.0);
    assert!(
        stdout.contains("relative error: undefined (exact value 0)\n"),
        "{stdout}"
    );
    assert!(!stdout.contains('%'), "{stdout}");
}

#[test]
fn formfactor_json_has_the_values_the_run_and_the_options() {
    let out = formfactor("0,0,2", SQUARE, &["--method", "hemicube", "--json"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON on stdout");
    let text_run = formfactor("0,0,2", SQUARE, &["--method", "hemicube"]);
    // The same values as the text, to the bit.
    let f = json["form_factor"].as_f64().unwrap();
    let exact = json["exact"].as_f64().unwrap();
    assert_eq!(f, f64_of(&text_run, "hemicube form factor"));
    assert_eq!(exact, f64_of(&text_run, "exact form factor"));
    assert_eq!(json["absolute_error"].as_f64(), Some(f - exact));
    assert_eq!(json["relative_error"].as_f64(), Some((f - exact) / exact));
    assert_eq!(json["method"], "hemicube");
    // The machine's figures.
    let sim = &json["simulated"];
    assert_eq!(sim["config"], "seed-tr89-002");
    let ps = sim["time_ps"].as_u64().unwrap();
    assert!(ps > 0);
    assert_eq!(sim["time_s"].as_f64(), Some(ps as f64 * 1e-12));
    assert!(sim["renderer_busy_cycles"].as_u64().unwrap() > 0);
    assert!(sim["gp0_busy_cycles"].as_u64().unwrap() > 0);
    assert!(sim["ring_payload_words"].as_u64().unwrap() > 0);
    assert_eq!(sim["stats"]["config_hash"], sim["config_hash"]);
    // The options, as given and as used.
    let opts = &json["options"];
    assert_eq!(opts["normal"], serde_json::json!([0.0, 0.0, 2.0]));
    assert_eq!(opts["unit_normal"], serde_json::json!([0.0, 0.0, 1.0]));
    assert_eq!(opts["point"], serde_json::json!([0.0, 0.0, 0.0]));
    assert_eq!(opts["polygon"].as_array().unwrap().len(), 4);
    assert_eq!(opts["polygon"][0], serde_json::json!([-1.0, -1.0, 1.0]));
    assert_eq!(opts["method"], "hemicube");
    assert_eq!(opts["resolution"], 128);
    assert_eq!(opts["config"], serde_json::Value::Null);

    // The exact method: no machine, no errors.
    let out = formfactor("0,0,1", SQUARE, &["--json"]);
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON on stdout");
    assert_eq!(json["method"], "exact");
    assert_eq!(json["form_factor"], json["exact"]);
    assert!(json["simulated"].is_null() && json["absolute_error"].is_null());
    // Exact value 0: the relative error is null, not 0.
    let out = formfactor("0,0,-1", SQUARE, &["--method", "hemisphere", "--json"]);
    let json: serde_json::Value = serde_json::from_slice(&out.stdout).expect("JSON on stdout");
    assert_eq!(json["exact"].as_f64(), Some(0.0));
    assert_eq!(json["absolute_error"].as_f64(), Some(0.0));
    assert!(json["relative_error"].is_null(), "{json}");
}

#[test]
fn formfactor_refuses_polygons_that_are_not_planar_and_convex() {
    let cases: [(&str, &str, &[&str]); 8] = [
        // The bow-tie (it printed 0.1416 against an exact 0).
        (
            "bow-tie",
            "0,0,1;1,1,1;1,0,1;0,1,1",
            &["zero area", "bow-tie", "vertex 1 `1,1,1`", "non-convex"],
        ),
        (
            "asymmetric bow-tie",
            "0,0,1;3,1,1;3,0,1;0,2,1",
            &["vertex 1 `3,1,1`", "non-convex"],
        ),
        (
            "collinear triangle",
            "0,0,1;1,0,1;2,0,1",
            &["zero area", "vertex 1 `1,0,1`: is collinear"],
        ),
        (
            "collinear vertex",
            "0,0,1;1,0,1;2,0,1;0,1,1",
            &["vertex 1 `1,0,1`: is collinear with vertices 0 and 2"],
        ),
        (
            "repeated vertex",
            "0,0,1;1,0,1;1,0,1;0,1,1",
            &["vertex 2 `1,0,1`: repeats vertex 1"],
        ),
        (
            "non-planar",
            "0,0,1;1,0,1;1,1,1.004;0,1,1",
            &["best-fit plane", "1e-6 x its size", "must be planar"],
        ),
        (
            "reflex corner",
            "0,0,1;2,0,1;1,0.5,1;1,2,1",
            &["vertex 2 `1,0.5,1`: makes the polygon non-convex"],
        ),
        (
            "pentagram",
            "1,0,1;-0.809,0.588,1;0.309,-0.951,1;0.309,0.951,1;-0.809,-0.588,1",
            &["edges cross", "2.0 times"],
        ),
    ];
    for (name, polygon, wanted) in cases {
        for method in ["exact", "hemisphere"] {
            let out = formfactor("0,0,1", polygon, &["--method", method]);
            assert_eq!(out.status.code(), Some(2), "{name}: {}", text(&out.stdout));
            assert_eq!(text(&out.stdout), "", "{name}");
            let err = text(&out.stderr);
            assert!(err.starts_with("--polygon"), "{name}: {err}");
            for w in wanted {
                assert!(err.contains(w), "{name}: no {w:?} in {err}");
            }
        }
    }
    // Clockwise is as good as counter-clockwise, and within 1e-6 of planar is planar.
    for polygon in [
        "-1,1,1;1,1,1;1,-1,1;-1,-1,1",
        "-1,-1,1;1,-1,1;1,1,1.000001;-1,1,1",
    ] {
        let out = formfactor("0,0,1", polygon, &[]);
        assert!(out.status.success(), "{polygon}: {}", text(&out.stderr));
    }
}

#[test]
fn formfactor_normals_need_a_direction() {
    let refused = [
        ("0,0,0", "must not be zero"),
        ("0,0,1e-310", "too short"),
        ("1e-308,1e-308,1e-308", "f64::MIN_POSITIVE"),
        ("0,0,inf", "finite"),
        ("0,0,nan", "finite"),
    ];
    for (normal, wanted) in refused {
        let out = formfactor(normal, SQUARE, &["--method", "hemicube"]);
        assert_eq!(out.status.code(), Some(2), "{normal}");
        let err = text(&out.stderr);
        assert!(
            err.starts_with("--normal") && err.contains(wanted),
            "{normal}: {err}"
        );
    }
    // Only the direction counts: a tiny (not subnormal) or a huge normal is the unit one.
    let unit = formfactor("0,0,1", SQUARE, &["--method", "hemisphere"]);
    assert!(unit.status.success());
    for normal in ["0,0,1e-300", "0,0,1e308", "0,0,3e-308"] {
        let out = formfactor(normal, SQUARE, &["--method", "hemisphere"]);
        assert!(out.status.success(), "{normal}: {}", text(&out.stderr));
        assert_eq!(text(&out.stdout), text(&unit.stdout), "{normal}");
    }
}

#[test]
fn formfactor_resolution_is_bounded_by_the_option_and_the_machine() {
    for bad in ["0", "4097", "4294967295"] {
        let out = formfactor(
            "0,0,1",
            SQUARE,
            &["--method", "hemisphere", "--resolution", bad],
        );
        assert_eq!(out.status.code(), Some(2), "{bad}");
        let err = text(&out.stderr);
        assert!(
            err.contains("--resolution") && err.contains("1..=4096"),
            "{bad}: {err}"
        );
    }
    // A hemicube face must fit one Renderer of 128 x 128, and be even.
    let cases = [
        ("hemicube", "130", "from 2 to 128"),
        ("hemicube", "127", "even"),
    ];
    for (method, n, wanted) in cases {
        let out = formfactor("0,0,1", SQUARE, &["--method", method, "--resolution", n]);
        assert_eq!(out.status.code(), Some(2), "{method} {n}");
        let err = text(&out.stderr);
        assert!(
            err.starts_with(&format!("--resolution {n}: the {method}")) && err.contains(wanted),
            "{err}"
        );
    }
    // A disk larger than a board is cut into tiles, each a view the Renderers take in turn:
    // 3 x 3 tiles of 128 on the seed machine's 4 boards, as close to exact as 128 pixels.
    let tiled = formfactor(
        "0,0,1",
        SQUARE,
        &["--method", "hemisphere", "--resolution", "384"],
    );
    assert!(tiled.status.success(), "{}", text(&tiled.stderr));
    let relative: f64 = value_of(&tiled, "relative error").parse().unwrap();
    assert!(relative.abs() < 1e-3, "{relative}");
}

#[test]
fn formfactor_is_the_same_at_any_power_of_two_scale() {
    // Scaled by 2^600 the squares of the coordinates overflow f64, and by 2^-600 they
    // underflow: the check and both computations still give the unscaled run's every digit.
    let base = formfactor(
        "0,0,1",
        SQUARE,
        &["--method", "hemisphere", "--resolution", "64"],
    );
    assert!(base.status.success(), "{}", text(&base.stderr));
    for s in [2f64.powi(600), 2f64.powi(-600)] {
        let polygon: Vec<String> = square_points(s)
            .iter()
            .map(|v| format!("{:e},{:e},{:e}", v.x, v.y, v.z))
            .collect();
        let out = formfactor(
            "0,0,1",
            &polygon.join(";"),
            &["--method", "hemisphere", "--resolution", "64"],
        );
        assert!(out.status.success(), "{s:e}: {}", text(&out.stderr));
        assert_eq!(text(&out.stdout), text(&base.stdout), "{s:e}");
    }
}

/// `pxpl5 run` on the small scene with `flags`, writing to `out`, with `RUST_LOG` set to
/// `rust_log` (or unset).
fn run_small_logged(out: &std::path::Path, flags: &[&str], rust_log: Option<&str>) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_pxpl5"));
    cmd.args(flags)
        .args(SMALL_RUN)
        .args(["--out", out.to_str().unwrap()])
        .current_dir(root());
    match rust_log {
        Some(filter) => cmd.env("RUST_LOG", filter),
        None => cmd.env_remove("RUST_LOG"),
    };
    cmd.output().expect("pxpl5 runs")
}

/// Stdout without the line of host figures, which vary from run to run.
fn results(out: &Output) -> String {
    text(&out.stdout)
        .lines()
        .filter(|l| !l.starts_with("host: "))
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn logs_go_to_stderr_at_the_level_asked_and_leave_stdout_alone() {
    let d = out_dir("logs");
    let plain = run_small_logged(&d, &[], None);
    assert!(plain.status.success(), "{}", text(&plain.stderr));
    assert_eq!(text(&plain.stderr), "", "a default run logs only warnings");
    assert!(results(&plain).contains("triangles per simulated second"));

    // -v: info lines on stderr (the command's span with the config, each simulation's start and
    // end); stdout exactly as without it.
    let verbose = run_small_logged(&d, &["-v"], None);
    assert!(verbose.status.success(), "{}", text(&verbose.stderr));
    let err = text(&verbose.stderr);
    assert!(
        err.contains("INFO") && err.contains("simulation ends") && err.contains("config=minimal"),
        "{err}"
    );
    assert!(!err.contains("DEBUG"), "{err}");
    assert_eq!(results(&verbose), results(&plain));

    // -q: nothing on stderr for a successful run.
    let quiet = run_small_logged(&d, &["-q"], None);
    assert!(quiet.status.success());
    assert_eq!(text(&quiet.stderr), "");
    assert_eq!(results(&quiet), results(&plain));

    // RUST_LOG overrides the flags: info without -v, error silences -v.
    let info = run_small_logged(&d, &[], Some("info"));
    let err = text(&info.stderr);
    assert!(err.contains("simulation ends"), "{err}");
    assert_eq!(results(&info), results(&plain));
    // -vv (debug) shows the machine run's span when it closes.
    let debug = run_small_logged(&d, &["-vv"], None);
    let err = text(&debug.stderr);
    assert!(err.contains("DEBUG") && err.contains("machine{"), "{err}");
    assert_eq!(results(&debug), results(&plain));
    let silenced = run_small_logged(&d, &["-v"], Some("error"));
    assert_eq!(text(&silenced.stderr), "");

    // A bad filter is the user's mistake; -v with -q is a usage error.
    let bad = run_small_logged(&d, &[], Some("[[["));
    assert_eq!(bad.status.code(), Some(2));
    assert!(
        text(&bad.stderr).contains("RUST_LOG"),
        "{}",
        text(&bad.stderr)
    );
    let both = run_small_logged(&d, &["-v", "-q"], None);
    assert_eq!(both.status.code(), Some(2));
}

/// `pxpl5 ARGS` with stdout `stdout`.
fn pxpl5_to(args: &[&str], stdout: impl Into<Stdio>) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pxpl5"))
        .args(args)
        .current_dir(root())
        .stdout(stdout)
        .output()
        .expect("pxpl5 runs")
}

/// `pxpl5 ARGS` writing to a pipe whose reader is already closed: its first write to stdout
/// fails with EPIPE, whatever the timing.
fn pxpl5_closed_stdout(args: &[&str]) -> Output {
    let (reader, writer) = std::io::pipe().expect("a pipe");
    drop(reader);
    pxpl5_to(args, writer)
}

/// A small radiosity run (one hemisphere shot of the empty Cornell box in big patches) writing to
/// `out`.
fn radiosity_small(out: &Path) -> Vec<String> {
    [
        "radiosity",
        "--method",
        "hemisphere",
        "--shots",
        "1",
        "--patch-size",
        "400",
        "--resolution",
        "16",
        "--out",
        out.to_str().unwrap(),
    ]
    .map(String::from)
    .to_vec()
}

fn no_panic(out: &Output) {
    let err = text(&out.stderr);
    assert!(!err.contains("panicked"), "{err}");
    assert_ne!(out.status.code(), Some(101), "{err}");
}

#[test]
fn a_closed_stdout_ends_quietly_with_exit_code_0() {
    let out_d = out_dir("closed-stdout");
    let radiosity = radiosity_small(&out_d);
    let run_d = out_dir("closed-stdout-run");
    let run = [&SMALL_RUN[..], &["--out", run_d.to_str().unwrap()]].concat();
    let square = "-1,-1,1;1,-1,1;1,1,1;-1,1,1";
    let formfactor = [
        "formfactor",
        "--point",
        "0,0,0",
        "--normal",
        "0,0,1",
        "--polygon",
        square,
    ];
    let bench = [
        "bench",
        "renderer",
        "--method",
        "hemisphere",
        "--fidelity",
        "integer",
        "--shots",
        "1",
        "--resolution",
        "16",
        "--repeat",
        "1",
    ];
    let commands: Vec<Vec<&str>> = vec![
        vec!["config", "show"],
        vec!["config", "check", "machine-configs/minimal.ron"],
        vec!["--help"],
        vec!["--version"],
        formfactor.to_vec(),
        bench.to_vec(),
        run.to_vec(),
        radiosity.iter().map(String::as_str).collect(),
    ];
    for args in &commands {
        let out = pxpl5_closed_stdout(args);
        no_panic(&out);
        assert_eq!(
            out.status.code(),
            Some(0),
            "{args:?}: {}",
            text(&out.stderr)
        );
        assert_eq!(text(&out.stderr), "", "{args:?}: a closed pipe is quiet");
    }
    // Only the report is lost: the files are whole.
    assert!(run_d.join("frame.png").exists());
    assert!(out_d.join("radiosity-hemisphere.png").exists());

    // A closed stdout does not hide a failed check: the verdict is the exit code.
    let bad = temp_file("closed-bad.ron", "(name: \"bad\")");
    let out = pxpl5_closed_stdout(&[
        "config",
        "check",
        "machine-configs/minimal.ron",
        bad.to_str().unwrap(),
    ]);
    no_panic(&out);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
    assert!(text(&out.stderr).contains("closed-bad.ron"));

    // As `pxpl5 radiosity | head -1` does it: one line read, then the reader closed.
    let mut child = Command::new(env!("CARGO_BIN_EXE_pxpl5"))
        .args(&radiosity)
        .current_dir(root())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("pxpl5 runs");
    let mut first = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    assert!(first.starts_with("Progressive radiosity"), "{first}");
    let out = child.wait_with_output().unwrap();
    no_panic(&out);
    assert_eq!(out.status.code(), Some(0), "{}", text(&out.stderr));
}

#[test]
fn a_full_stdout_is_an_error_naming_stdout() {
    if !Path::new("/dev/full").exists() {
        return;
    }
    let full = || {
        std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/full")
            .unwrap()
    };
    let square = "-1,-1,1;1,-1,1;1,1,1;-1,1,1";
    let out_d = out_dir("full-stdout");
    let radiosity = radiosity_small(&out_d);
    let commands: Vec<Vec<&str>> = vec![
        vec!["config", "show"],
        vec!["config", "check", "machine-configs/minimal.ron"],
        vec!["--help"],
        vec![
            "formfactor",
            "--point",
            "0,0,0",
            "--normal",
            "0,0,1",
            "--polygon",
            square,
        ],
        radiosity.iter().map(String::as_str).collect(),
    ];
    for args in &commands {
        let out = pxpl5_to(args, full());
        no_panic(&out);
        assert_eq!(
            out.status.code(),
            Some(2),
            "{args:?}: {}",
            text(&out.stderr)
        );
        let err = text(&out.stderr);
        assert!(err.starts_with("stdout: cannot write: "), "{args:?}: {err}");
    }
}

/// `pxpl5 run` of the small scene on the minimal machine into `out`, with `extra` flags.
fn run_small_with(out: &Path, extra: &[&str]) -> Output {
    let mut args = SMALL_RUN.to_vec();
    args.extend(["--out", out.to_str().unwrap()]);
    args.extend_from_slice(extra);
    pxpl5(&args)
}

fn assert_chrome_trace(bytes: &[u8]) {
    let trace: serde_json::Value = serde_json::from_slice(bytes).expect("a Chrome trace");
    assert!(trace["traceEvents"].as_array().unwrap().len() > 50);
}

#[cfg(unix)]
#[test]
fn a_fifo_output_is_written_through_and_stays_a_fifo() {
    use std::os::unix::fs::FileTypeExt;
    let d = out_dir("fifo");
    std::fs::create_dir_all(&d).unwrap();
    let fifo = d.join("trace.fifo");
    let made = Command::new("mkfifo").arg(&fifo).status();
    if !made.is_ok_and(|s| s.success()) {
        return; // no mkfifo on this host
    }
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || std::fs::read(fifo).unwrap())
    };
    let out = run_small_with(&d.join("out"), &["--trace", fifo.to_str().unwrap()]);
    // Should pxpl5 not have opened the FIFO, open it as a writer (read-write does not block on
    // Linux) so that the reader sees its end instead of waiting forever.
    drop(
        std::fs::OpenOptions::new()
            .read(true)
            .write(true)
            .open(&fifo),
    );
    let bytes = reader.join().unwrap();
    assert!(out.status.success(), "{}", text(&out.stderr));
    let kind = std::fs::symlink_metadata(&fifo).unwrap().file_type();
    assert!(kind.is_fifo(), "the FIFO was replaced: {kind:?}");
    assert_chrome_trace(&bytes);
}

#[cfg(unix)]
#[test]
fn a_symlink_output_stays_a_symlink_and_a_device_a_device() {
    use std::os::unix::fs::FileTypeExt;
    let d = out_dir("symlink");
    std::fs::create_dir_all(&d).unwrap();
    let real = d.join("real.json");
    std::fs::write(&real, "old").unwrap();
    let link = d.join("link.json");
    // Relative to the link's directory, not to pxpl5's.
    std::os::unix::fs::symlink("real.json", &link).unwrap();
    let out = run_small_with(
        &d.join("out"),
        &["--trace", link.to_str().unwrap(), "--vcd", "/dev/null"],
    );
    assert!(out.status.success(), "{}", text(&out.stderr));
    let kind = std::fs::symlink_metadata(&link).unwrap().file_type();
    assert!(kind.is_symlink(), "the symlink was replaced: {kind:?}");
    assert_eq!(std::fs::read_link(&link).unwrap(), Path::new("real.json"));
    assert_chrome_trace(&std::fs::read(&real).unwrap());
    let null = std::fs::metadata("/dev/null").unwrap().file_type();
    assert!(null.is_char_device(), "{null:?}");
    // /dev/stdout links to /proc/self/fd/1, which names a pipe here, not a path to follow.
    if Path::new("/dev/stdout").exists() {
        let out = run_small_with(&d.join("out"), &["--trace", "/dev/stdout"]);
        assert!(out.status.success(), "{}", text(&out.stderr));
        assert!(text(&out.stdout).starts_with("{\"displayTimeUnit\""));
    }
}

#[test]
fn a_directory_given_for_a_file_fails_before_the_run() {
    let d = out_dir("trace-dir");
    let dir = d.join("some/dir");
    std::fs::create_dir_all(&dir).unwrap();
    let out_d = d.join("out");
    for flag in ["--trace", "--vcd"] {
        let out = run_small_with(&out_d, &[flag, dir.to_str().unwrap()]);
        assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
        let err = text(&out.stderr);
        assert!(
            err.contains(flag) && err.contains("is a directory"),
            "{err}"
        );
        assert!(!err.contains("simulation"), "{err}");
        assert!(!out_d.exists(), "{flag}: something was written");
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0);
    }
    // A directory where run writes one of its own files.
    std::fs::create_dir_all(out_d.join("stats.json")).unwrap();
    let out = run_small_with(&out_d, &[]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
    assert!(text(&out.stderr).contains("stats.json: is a directory"));
    assert_eq!(std::fs::read_dir(&out_d).unwrap().count(), 1);
}

#[test]
fn a_dash_sends_a_trace_to_stdout_and_the_report_to_stderr() {
    let d = out_dir("dash");
    let out = run_small_with(&d, &["--trace", "-"]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert_chrome_trace(&out.stdout);
    assert!(text(&out.stderr).contains("triangles per simulated second"));
    assert!(!d.join("-").exists());
    // Two runs cannot share stdout.
    let out = pxpl5(&["radiosity", "--trace", "-", "--out", d.to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
    assert!(text(&out.stderr).contains("--trace -"));
}

/// The seed machine with a 1 kHz Renderer clock: with `--time-limit 30s`, radiosity's form-factor
/// runs of one shot in big patches fit the limit (18 s and 14 s simulated), the picture's render
/// does not (44 s), so it fails after everything else was computed.
fn slow_renderer_config() -> TempFile {
    let seed = std::fs::read_to_string(root().join("machine-configs/seed-tr89-002.ron")).unwrap();
    let clock = "clock_hz: 40_000_000, // [paper]";
    assert_eq!(
        seed.matches(clock).count(),
        1,
        "the Renderer clock's line moved"
    );
    temp_file(
        "slow-renderer.ron",
        &seed.replace(clock, "clock_hz: 1_000, // [paper]"),
    )
}

/// The names and contents of the files of `dir`, sorted.
fn listing(dir: &Path) -> Vec<(String, Vec<u8>)> {
    let mut files: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| {
            let e = e.unwrap();
            (
                e.file_name().to_string_lossy().into_owned(),
                std::fs::read(e.path()).unwrap(),
            )
        })
        .collect();
    files.sort();
    files
}

#[test]
fn a_failed_run_leaves_the_output_directory_as_it_found_it() {
    let config = slow_renderer_config();
    // A directory that does not exist stays absent; one that exists keeps its files, unchanged.
    let absent = out_dir("failed-absent").join("out");
    let present = out_dir("failed-present");
    std::fs::create_dir_all(&present).unwrap();
    std::fs::write(present.join("keep.txt"), "mine").unwrap();
    std::fs::write(present.join("comparison.csv"), "old").unwrap();
    let before = listing(&present);
    // Every kind of trace: each run's JSON, Perfetto trace and VCD has a spool from the run's
    // start, several in one new directory (before, the one that made it went first and the
    // directory stayed behind, empty).
    for (out_d, trace) in [
        (absent.as_path(), "t.json"),
        (absent.as_path(), "t.pftrace"),
        (&*present, "t.json"),
        (&*present, "t.pftrace"),
    ] {
        // Both methods run, with item buffers and traces; the picture's render fails last.
        let out = pxpl5(&[
            "radiosity",
            "--config",
            config.to_str().unwrap(),
            "--shots",
            "1",
            "--patch-size",
            "400",
            "--resolution",
            "16",
            "--item-buffers",
            "0",
            "--time-limit",
            "30s",
            "--out",
            out_d.to_str().unwrap(),
            "--trace",
            out_d.join(trace).to_str().unwrap(),
            "--vcd",
            out_d.join("t.vcd").to_str().unwrap(),
        ]);
        no_panic(&out);
        let err = text(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert!(
            err.starts_with(
                "radiosity (picture, hemisphere): simulated time limit of 30.000 s reached \
                 (--time-limit)"
            ),
            "{err}"
        );
        assert_eq!(text(&out.stdout), "", "a failed run prints no report");
    }
    assert!(
        !absent.exists(),
        "a failed run created its output directory"
    );
    assert_eq!(listing(&present), before);

    // `run` past its --time-limit.
    let run_d = out_dir("failed-run");
    let out = run_small_with(
        &run_d,
        &[
            "--time-limit",
            "1us",
            "--trace",
            run_d.join("t.json").to_str().unwrap(),
        ],
    );
    no_panic(&out);
    assert_eq!(out.status.code(), Some(1), "{}", text(&out.stderr));
    assert!(!run_d.exists(), "a failed run wrote {:?}", listing(&run_d));
}

#[test]
fn a_failed_write_takes_back_the_files_written_before_it() {
    if !Path::new("/dev/full").exists() {
        return;
    }
    // The trace goes to stdout, which is full: stats.json, config.ron and frame.png were staged
    // before it and must not appear.
    let run_d = out_dir("failed-write");
    let full = std::fs::OpenOptions::new()
        .write(true)
        .open("/dev/full")
        .unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_pxpl5"))
        .args(SMALL_RUN)
        .args([
            "--out",
            run_d.join("new/dirs").to_str().unwrap(),
            "--trace",
            "-",
        ])
        .current_dir(root())
        .stdout(full)
        .output()
        .unwrap();
    no_panic(&out);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
    assert!(text(&out.stderr).contains("stdout: cannot write"));
    assert!(!run_d.exists(), "left behind: {:?}", listing(&run_d));
}

#[test]
fn two_outputs_to_one_file_fail_before_the_run() {
    let d = out_dir("twice");
    let out = run_small_with(&d, &["--trace", d.join("stats.json").to_str().unwrap()]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
    assert!(
        text(&out.stderr).contains("two outputs"),
        "{}",
        text(&out.stderr)
    );
    let out = run_small_with(&d, &["--trace", "-", "--vcd", "-"]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
    assert!(text(&out.stderr).contains("stdout: two outputs"));
    assert!(!d.exists());
}

// ---------------------------------------------------------------------------------------------
// Runs that cannot hang silently: limits, exit codes, Ctrl-C
// ---------------------------------------------------------------------------------------------

/// A radiosity run of the hemisphere only, in big patches at a low resolution, with `more`.
fn radiosity_hemisphere(out: &Path, shots: &str, more: &[&str]) -> Output {
    let mut args = vec![
        "radiosity",
        "--method",
        "hemisphere",
        "--shots",
        shots,
        "--threshold",
        "0",
        "--patch-size",
        "400",
        "--resolution",
        "16",
        // One shooter at a time and no accuracy target: shots end one by one, at the same
        // simulated times in a 2-shot and a 6-shot run.
        "--shooters-at-once",
        "1",
        "--until-error",
        "0",
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend(more);
    pxpl5(&args)
}

/// Simulated picoseconds of the one method of `dir/comparison.json`.
fn simulated_ps(dir: &Path) -> u64 {
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("comparison.json")).unwrap()).unwrap();
    json["methods"][0]["stats"]["simulated_ps"]
        .as_u64()
        .unwrap()
}

#[test]
fn a_failed_simulation_exits_1_saying_where_it_was() {
    // `run` past its simulated time limit (also spelled --max-time): the units still running, a
    // line per group, and nothing written.
    let d = out_dir("limit-run");
    for flag in ["--time-limit", "--max-time"] {
        let out = run_small_with(&d, &[flag, "20us"]);
        no_panic(&out);
        let err = text(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{err}");
        assert!(
            err.starts_with(
                "run: simulated time limit of 20.000 us reached (--time-limit); nothing written. \
                 Still running:\n  GP 0: "
            ),
            "{err}"
        );
        assert_eq!(text(&out.stdout), "");
        assert!(!d.exists(), "a failed run wrote {:?}", listing(&d));
    }

    // Radiosity: the limit set at the end of a 2-shot run stops a 6-shot run with 2 shots done
    // (the first shots of both are the same run).
    let two = out_dir("limit-two-shots");
    let out = radiosity_hemisphere(&two, "2", &[]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let limit = format!("{}ps", simulated_ps(&two));
    let d = out_dir("limit-radiosity");
    let out = radiosity_hemisphere(&d, "6", &["--time-limit", &limit]);
    no_panic(&out);
    let err = text(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.starts_with("radiosity (hemisphere): simulated time limit of ")
            && err.contains(
                " reached (--time-limit), 2 of 6 shots done; nothing written. Still running:\n"
            ),
        "{err}"
    );
    assert!(!d.exists(), "a failed run wrote {:?}", listing(&d));

    // A user's mistake is still 2.
    let out = radiosity_hemisphere(&d, "6", &["--time-limit", "10 parsecs"]);
    assert_eq!(out.status.code(), Some(2), "{}", text(&out.stderr));
    assert!(text(&out.stderr).contains("--time-limit"));
}

#[test]
fn a_host_time_limit_stops_a_long_run_saying_where_it_was() {
    // 100,000 shots would take many minutes; the host-time limit stops the run after 500 ms.
    let d = out_dir("host-limit");
    let t0 = std::time::Instant::now();
    // The default patches (199) and no accuracy target, so that 100,000 shots cannot end early.
    let out = pxpl5(&[
        "radiosity",
        "--method",
        "hemisphere",
        "--shots",
        "100000",
        "--threshold",
        "0",
        "--until-error",
        "0",
        "--resolution",
        "16",
        "--host-time-limit",
        "500ms",
        "--out",
        d.to_str().unwrap(),
    ]);
    let took = t0.elapsed();
    no_panic(&out);
    let err = text(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    // First the work estimate's warning (199 patches x 100,000 shots), then the report.
    let (warning, report) = err.split_once('\n').expect("two parts");
    assert!(
        warning.contains(
            "WARN pxpl5::watch: radiosity: a large run: 19,900,000 receiver draws at most \
             (patches x shots x methods x tiles per view), more than 5,000,000; it may take many \
             minutes (--host-time-limit 500ms stops it)"
        ),
        "{err}"
    );
    let prefix = "radiosity (hemisphere): host time limit of 500ms reached (--host-time-limit): \
                  stopped at ";
    assert!(report.starts_with(prefix), "{err}");
    let done: u64 = err
        .split(" of 100000 shots done")
        .next()
        .and_then(|s| s.rsplit(", ").next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no shot count: {err}"));
    assert!(done < 100_000, "{err}");
    assert!(err.contains("nothing written. Still running:\n  "), "{err}");
    assert!(!d.exists(), "a failed run wrote {:?}", listing(&d));
    assert!(took < std::time::Duration::from_secs(60), "{took:?}");

    for bad in ["0s", "10", "soon"] {
        let out = radiosity_hemisphere(&d, "1", &["--host-time-limit", bad]);
        assert_eq!(out.status.code(), Some(2), "{bad}: {}", text(&out.stderr));
        assert!(text(&out.stderr).contains("--host-time-limit"), "{bad}");
    }
}

#[test]
fn help_gives_the_exit_codes_and_the_limits_with_their_defaults() {
    let help = text(&pxpl5(&["--help"]).stdout);
    for code in [
        "  0    success",
        "  1    a simulation that failed",
        "  2    a user's mistake",
        "  130  interrupted",
    ] {
        assert!(help.contains(code), "{code}: {help}");
    }
    for (command, time_limit) in [
        ("run", "10s"),
        ("radiosity", "1000s"),
        ("formfactor", "10s"),
    ] {
        let help = text(&pxpl5(&[command, "--help"]).stdout);
        let flat = help.split_whitespace().collect::<Vec<_>>().join(" ");
        assert!(
            flat.contains(&format!("[default: {time_limit}]")),
            "{command}: {help}"
        );
        assert!(
            flat.contains("--host-time-limit <TIME>"),
            "{command}: {help}"
        );
        assert!(flat.contains("[default: 10min]"), "{command}: {help}");
    }
}

/// A child `pxpl5 -v ARGS` whose stderr lines arrive on the returned channel.
fn spawn_logged(args: &[&str]) -> (std::process::Child, std::sync::mpsc::Receiver<String>) {
    let mut child = Command::new(env!("CARGO_BIN_EXE_pxpl5"))
        .arg("-v")
        .args(args)
        .current_dir(root())
        .env_remove("RUST_LOG")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("pxpl5 starts");
    let stderr = child.stderr.take().expect("piped");
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    (child, rx)
}

/// Wait (at most a minute) for a line of `lines` containing `needle`; kill `child` and fail if
/// none comes.
fn wait_for_line(
    child: &mut std::process::Child,
    lines: &std::sync::mpsc::Receiver<String>,
    needle: &str,
) {
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    loop {
        let left = deadline.saturating_duration_since(std::time::Instant::now());
        match lines.recv_timeout(left) {
            Ok(line) if line.contains(needle) => return,
            Ok(_) => {}
            Err(_) => {
                let _ = child.kill();
                panic!("no line with `{needle}` on stderr within a minute");
            }
        }
    }
}

/// Send SIGINT to `child`, as Ctrl-C does, and wait (at most a minute) for it to end; its exit
/// code, stdout and the rest of its stderr.
fn interrupt(
    mut child: std::process::Child,
    lines: std::sync::mpsc::Receiver<String>,
) -> (Option<i32>, String, String) {
    let sent = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .expect("kill runs");
    assert!(sent.success());
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(60);
    let status = loop {
        if let Some(status) = child.try_wait().expect("waits") {
            break status;
        }
        if std::time::Instant::now() > deadline {
            let _ = child.kill();
            panic!("pxpl5 did not end within a minute of SIGINT");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    };
    let mut stdout = String::new();
    std::io::Read::read_to_string(&mut child.stdout.take().expect("piped"), &mut stdout).unwrap();
    let stderr: Vec<String> = lines.iter().collect();
    (status.code(), stdout, stderr.join("\n"))
}

/// `radiosity` with `extra` options and both methods, 100,000 shots each (many minutes), into
/// `d`, interrupted once a shot is done (the handler is in place and the run well under way):
/// its exit code, stdout and stderr.
fn interrupted_radiosity(d: &Path, extra: &[&str]) -> (Option<i32>, String, String) {
    let mut args = vec!["radiosity", "--shots", "100000", "--threshold", "0"];
    args.extend(["--until-error", "0", "--resolution", "16"]);
    args.extend(["--out", d.to_str().unwrap()]);
    args.extend_from_slice(extra);
    let (mut child, lines) = spawn_logged(&args);
    wait_for_line(&mut child, &lines, " of 100000 shots done");
    interrupt(child, lines)
}

#[test]
fn ctrl_c_ends_radiosity_between_shots_and_writes_what_it_computed_marked_partial() {
    let d = out_dir("interrupted-radiosity");
    // The methods in turn: the hemicube is never started.
    let (code, stdout, stderr) = interrupted_radiosity(&d, &["--in-turn"]);
    no_panic(&Output {
        status: std::process::ExitStatus::default(),
        stdout: Vec::new(),
        stderr: stderr.clone().into_bytes(),
    });
    assert_eq!(code, Some(130), "{stderr}");

    // comparison.json: complete (it parses), marked partial, the hemicube not run.
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("comparison.json")).unwrap()).unwrap();
    assert_eq!(json["partial"], true);
    let methods = json["methods"].as_array().unwrap();
    assert_eq!(methods.len(), 1, "the hemicube was not run");
    assert_eq!(methods[0]["method"], "hemisphere");
    assert_eq!(methods[0]["partial"], true);
    let shots = methods[0]["shots"].as_u64().unwrap();
    assert!((1..100_000).contains(&shots), "{shots}");

    // The report and the message say so.
    assert!(
        stdout.contains(&format!(
            "hemisphere: interrupted after {shots} of 100000 shots: partial results"
        )),
        "{stdout}"
    );
    assert!(
        stderr.ends_with(&format!(
            "radiosity: interrupted after hemisphere {shots} of 100000 shots (hemicube not run); \
             wrote what was computed to {}, marked partial",
            d.display()
        )),
        "{stderr}"
    );

    // Every other file complete: the CSVs to their last line, the picture to its last row.
    // (Each CSV's first line records the options: `# pxpl5 ...`.)
    let csv = std::fs::read_to_string(d.join("comparison.csv")).unwrap();
    let rows: Vec<&str> = csv.lines().skip(1).collect();
    assert_eq!(rows.len(), 2, "{csv}");
    assert!(rows[0].ends_with(",partial") && rows[1].starts_with(&format!("hemisphere,{shots},")));
    assert!(rows[1].ends_with(",true"), "{csv}");
    let patches = json["patches"].as_u64().unwrap() as usize;
    let pcsv = std::fs::read_to_string(d.join("patches-hemisphere.csv")).unwrap();
    assert!(pcsv.ends_with('\n'));
    assert_eq!(pcsv.lines().count(), patches + 2);
    assert!(
        pcsv.lines().skip(1).all(|l| l.split(',').count() == 6),
        "{pcsv}"
    );
    assert!(
        !d.join("patches-hemicube.csv").exists(),
        "the hemicube was not run"
    );
    let decoder = png::Decoder::new(std::io::Cursor::new(
        std::fs::read(d.join("radiosity-hemisphere.png")).unwrap(),
    ));
    let mut reader = decoder.read_info().expect("a PNG");
    let mut pixels = vec![0; reader.output_buffer_size().expect("sized")];
    reader.next_frame(&mut pixels).expect("every row");
    let check = pxpl5(&["config", "check", d.join("config.ron").to_str().unwrap()]);
    assert!(check.status.success(), "{}", text(&check.stderr));
}

/// Methods run at once (the default on a host with the cores): a first Ctrl-C ends each between
/// shots, and both are written, marked partial.
#[test]
fn ctrl_c_ends_methods_run_at_once_between_shots() {
    let d = out_dir("interrupted-radiosity-at-once");
    let (code, _, stderr) = interrupted_radiosity(&d, &[]);
    assert_eq!(code, Some(130), "{stderr}");
    let json: serde_json::Value =
        serde_json::from_slice(&std::fs::read(d.join("comparison.json")).unwrap()).unwrap();
    assert_eq!(json["partial"], true);
    let methods = json["methods"].as_array().unwrap();
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    if cores < 2 {
        // One core: in turn, and the first Ctrl-C starts no other method.
        assert_eq!(methods.len(), 1, "{json}");
        return;
    }
    let done: Vec<String> = methods
        .iter()
        .map(|m| {
            assert_eq!(m["partial"], true, "{m}");
            let shots = m["shots"].as_u64().unwrap();
            assert!(shots < 100_000, "{m}");
            format!("{} {shots} of 100000 shots", m["method"].as_str().unwrap())
        })
        .collect();
    assert_eq!(done.len(), 2, "{json}");
    assert!(done[0].starts_with("hemisphere ") && done[1].starts_with("hemicube "));
    assert!(
        stderr.ends_with(&format!(
            "radiosity: interrupted after {}; wrote what was computed to {}, marked partial",
            done.join(", "),
            d.display()
        )),
        "{stderr}"
    );
    for m in ["hemisphere", "hemicube"] {
        let pcsv = std::fs::read_to_string(d.join(format!("patches-{m}.csv"))).unwrap();
        assert!(pcsv.ends_with('\n'), "{m}");
    }
}

#[test]
fn ctrl_c_stops_run_at_once_and_writes_nothing() {
    let d = out_dir("interrupted-run");
    // 400,000 triangles: about a minute, unless interrupted.
    let (mut child, lines) =
        spawn_logged(&["run", "--triangles", "400000", "--out", d.to_str().unwrap()]);
    wait_for_line(&mut child, &lines, "simulation starts");
    let (code, stdout, stderr) = interrupt(child, lines);
    assert_eq!(code, Some(130), "{stderr}");
    assert!(
        stderr.contains("run: interrupted at ")
            && stderr.contains("; nothing written. Still running:"),
        "{stderr}"
    );
    assert_eq!(stdout, "");
    assert!(!d.exists(), "an interrupted run wrote {:?}", listing(&d));
}

/// `stats diff`: two runs of the same inputs have no figure apart (exit 0); a slower ring moves
/// the simulated time, named with both values (exit 1); a tolerance wider than the change hides
/// it; an unreadable file is a user's mistake (exit 2).
#[test]
fn stats_diff_names_what_changed_with_an_exit_code_ci_can_use() {
    let (a, b, c) = (out_dir("diff-a"), out_dir("diff-b"), out_dir("diff-c"));
    for d in [&a, &b] {
        let out = run_small(d);
        assert!(out.status.success(), "{}", text(&out.stderr));
    }
    let seed = std::fs::read_to_string(root().join("machine-configs/minimal.ron")).unwrap();
    let slow = seed.replace(
        "channel_clock_hz: 20_000_000",
        "channel_clock_hz: 10_000_000",
    );
    assert_ne!(slow, seed, "the minimal config names its ring clock");
    let config = temp_file("diff-slow-ring.ron", &slow);
    let mut args = SMALL_RUN.to_vec();
    assert_eq!(args[1], "--config");
    args[2] = config.to_str().unwrap();
    args.extend(["--out", c.to_str().unwrap()]);
    let out = pxpl5(&args);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let stats = |d: &Path| d.join("stats.json").to_str().unwrap().to_string();

    let same = pxpl5(&["stats", "diff", &stats(&a), &stats(&b)]);
    assert_eq!(same.status.code(), Some(0), "{}", text(&same.stderr));
    assert!(text(&same.stdout).contains("no figure differs"));

    let moved = pxpl5(&[
        "stats",
        "diff",
        &stats(&a),
        &stats(&c),
        "--only",
        "simulated_ps",
    ]);
    assert_eq!(moved.status.code(), Some(1), "{}", text(&moved.stderr));
    let report = text(&moved.stdout);
    let line = report
        .lines()
        .find(|l| l.starts_with("~ simulated_ps: "))
        .unwrap_or_else(|| panic!("{report}"));
    let values: Vec<u64> = line
        .trim_start_matches("~ simulated_ps: ")
        .split([' ', ','])
        .filter_map(|w| w.parse().ok())
        .collect();
    assert!(values.len() >= 2 && values[1] > values[0], "{line}");
    assert!(text(&moved.stderr).contains("1 of the figures differ"));
    // A tolerance wider than the change hides it.
    let wide = pxpl5(&[
        "stats",
        "diff",
        &stats(&a),
        &stats(&c),
        "--only",
        "simulated_ps",
        "--tolerance",
        "10",
    ]);
    assert_eq!(wide.status.code(), Some(0), "{}", text(&wide.stdout));

    let missing = pxpl5(&["stats", "diff", &stats(&a), "/no/such/file.json"]);
    assert_eq!(missing.status.code(), Some(2));
    assert!(text(&missing.stderr).contains("/no/such/file.json: cannot read"));
    let not_json = temp_file("diff-not.json", "{ nope");
    let bad = pxpl5(&["stats", "diff", &stats(&a), not_json.to_str().unwrap()]);
    assert_eq!(bad.status.code(), Some(2));
    assert!(
        text(&bad.stderr).contains("not JSON (line 1"),
        "{}",
        text(&bad.stderr)
    );
}

// Inputs bounded where they enter (issue 9): configs, scenes and flags the simulator cannot
// honour are refused before anything runs, with exit code 2, naming the field or flag, the value
// and the limit; error reports of huge files stay small.

/// `machine-configs/minimal.ron` with `from` replaced by `to` (which must occur once), as a
/// temporary file.
fn minimal_with(name: &str, from: &str, to: &str) -> TempFile {
    let text = std::fs::read_to_string(root().join("machine-configs/minimal.ron")).unwrap();
    assert_eq!(text.matches(from).count(), 1, "{from}");
    temp_file(name, &text.replacen(from, to, 1))
}

/// A miette report's text with its line wrapping undone (blanks folded, the frame's bars gone),
/// for matching a message that may have been wrapped.
fn unwrapped(report: &str) -> String {
    report
        .split_whitespace()
        .filter(|w| *w != "│")
        .collect::<Vec<_>>()
        .join(" ")
}

/// The exit code 2 and the stderr of `args`, which must not have created `out`.
fn refused(args: &[&str], out: &Path) -> String {
    let o = pxpl5(args);
    no_panic(&o);
    let err = text(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{args:?}: {err}");
    assert!(!out.exists(), "{args:?} wrote {}", out.display());
    err
}

#[test]
fn configs_the_simulator_cannot_run_are_refused_naming_the_field() {
    let d = out_dir("bad-configs");
    let dir = d.to_str().unwrap();
    let cases = [
        (
            "vertex_transform: 24,",
            "vertex_transform: 18446744073709551615,",
            "gp.costs.vertex_transform: must be at most 4294967295 cycles",
        ),
        (
            "igc_overhead: 20,",
            "igc_overhead: 18446744073709551615,",
            "renderer.cycles.igc_overhead: must be at most 4294967295 cycles",
        ),
        (
            "int_bits: 13,",
            "int_bits: 0,",
            "renderer.qee.coefficient_format.int_bits: must be at least 1 (got 0)",
        ),
        (
            "channels: 1,",
            "channels: 4294967295,",
            "ring.channels: must be in 1..=64 (got 4294967295)",
        ),
        (
            "count: 1, // [assumed] the smallest machine (docs/hardware.md: Graphics",
            "count: 4294967295, // (docs/hardware.md: Graphics",
            "gp.count: must be in 1..=256 (got 4294967295)",
        ),
        (
            "count: 1, // [assumed] the smallest machine (docs/hardware.md: Renderers",
            "count: 10000, // (docs/hardware.md: Renderers",
            "renderer.count: must be in 1..=256 (got 10000)",
        ),
    ];
    for (i, (from, to, message)) in cases.iter().enumerate() {
        let cfg = minimal_with(&format!("bad-{i}.ron"), from, to);
        let cfg = cfg.to_str().unwrap();
        for args in [
            vec!["config", "check", cfg],
            vec!["run", "--config", cfg, "--out", dir],
            vec!["radiosity", "--config", cfg, "--out", dir],
        ] {
            let err = refused(&args, &d);
            assert!(unwrapped(&err).contains(message), "{args:?}: {err}");
        }
    }
}

#[test]
fn a_machine_beyond_the_memory_limit_is_refused_until_the_limit_is_raised() {
    let cfg = minimal_with(
        "huge-frame-buffer.ron",
        "width: 1280, // [paper]",
        "width: 65536, // [paper]",
    );
    let text_cfg = std::fs::read_to_string(&cfg).unwrap();
    let cfg = temp_file(
        "huge-frame-buffer.ron",
        &text_cfg.replacen("height: 1024, // [paper]", "height: 65536, // [paper]", 1),
    );
    let cfg = cfg.to_str().unwrap();
    let d = out_dir("huge-frame-buffer");
    let err = refused(&["run", "--config", cfg, "--out", d.to_str().unwrap()], &d);
    assert!(
        err.contains("machine `minimal` needs an estimated 24.0 GiB")
            && err.contains("1 frame buffer x 24 GiB (65536 x 65536 pixels")
            && err.contains("more than the host memory limit of 4 GiB")
            && err.contains("raise the limit with --memory-limit 25GiB"),
        "{err}"
    );
    refused(&["config", "check", cfg], &d);
    // Raised, the check passes (without building the machine: config check only reads it).
    let ok = pxpl5(&["--memory-limit", "25GiB", "config", "check", cfg]);
    assert!(ok.status.success(), "{}", text(&ok.stderr));
    let ok = pxpl5(&["config", "check", cfg, "--memory-limit", "32G"]);
    assert!(ok.status.success(), "{}", text(&ok.stderr));
    // config show prints the estimate and the verdict, and still parses back.
    let show = pxpl5(&["config", "show", cfg]);
    assert!(show.status.success(), "{}", text(&show.stderr));
    let shown = text(&show.stdout);
    assert!(
        shown.starts_with("// Host memory: the simulator needs an estimated 24.0 GiB: ")
            && shown.contains("// The limit is 4 GiB (--memory-limit; default 4 GiB): more than"),
        "{shown}"
    );
    pxpl5_config::parse_str("shown.ron", &shown).expect("parses back");
    let seed = text(&pxpl5(&["config", "show"]).stdout);
    assert!(seed.contains("): within the limit."), "{seed}");
    // A bad size is a usage error naming the option.
    let bad = pxpl5(&["--memory-limit", "3 parsecs", "config", "show"]);
    assert_eq!(bad.status.code(), Some(2));
    assert!(
        text(&bad.stderr).contains("--memory-limit"),
        "{}",
        text(&bad.stderr)
    );
}

#[test]
fn the_default_memory_limit_is_the_documented_one() {
    let help = text(&pxpl5(&["--help"]).stdout);
    assert!(help.contains("--memory-limit <SIZE>"), "{help}");
    assert!(help.contains("[default: 4GiB]"), "{help}");
    assert_eq!(
        pxpl5_machine::memory::parse_size("4GiB"),
        Ok(pxpl5_machine::memory::DEFAULT_LIMIT)
    );
}

#[test]
fn flags_out_of_range_are_refused_before_anything_runs() {
    let d = out_dir("bad-flags");
    let dir = d.to_str().unwrap();
    let cases: &[(&[&str], &str)] = &[
        (
            &["run", "--triangles", "18446744073709551615"],
            "18446744073709551615 is not in 0..=1000000",
        ),
        (
            &["run", "--triangles", "1000000000"],
            "1000000000 is not in 0..=1000000",
        ),
        (
            &["radiosity", "--resolution", "4294967295"],
            "4294967295 is not in 1..=4096",
        ),
        (&["radiosity", "--resolution", "0"], "0 is not in 1..=4096"),
        (
            &["radiosity", "--resolution", "4096"],
            "--resolution 4096: the hemicube takes an even number of pixels from 2 to 128",
        ),
        (
            &["radiosity", "--method", "hemicube", "--resolution", "127"],
            "--resolution 127: the hemicube takes an even number of pixels",
        ),
        (
            &["radiosity", "--patch-size", "6"],
            "--patch-size 6.0: makes 69028 patches, more than the 65534",
        ),
        (
            &["radiosity", "--patch-size", "1e-300"],
            "--patch-size 1e-300: surfaces[0] (floor): patch size 1e-300 would make more than \
             100000 patches (about more than 1e308",
        ),
        (
            &["radiosity", "--patch-size", "NaN"],
            "`NaN` is not a finite number",
        ),
        (&["radiosity", "--patch-size", "0"], "`0` must be > 0"),
        (&["radiosity", "--threshold=-1"], "`-1` must be >= 0"),
        (
            &["radiosity", "--threshold", "inf"],
            "`inf` is not a finite number",
        ),
    ];
    for (args, message) in cases {
        let mut args = args.to_vec();
        args.extend(["--out", dir]);
        let err = refused(&args, &d);
        assert!(err.contains(message), "{args:?}: {err}");
    }
}

#[test]
fn a_format_the_polygon_program_cannot_draw_with_is_refused_up_front() {
    let cfg = minimal_with("int-bits-1.ron", "int_bits: 13,", "int_bits: 1,");
    let cfg = cfg.to_str().unwrap();
    let d = out_dir("int-bits-1");
    let dir = d.to_str().unwrap();
    for args in [
        vec!["run", "--config", cfg, "--out", dir],
        vec!["radiosity", "--config", cfg, "--out", dir],
    ] {
        let err = refused(&args, &d);
        assert!(
            err.contains(
                "renderer.qee.coefficient_format.int_bits: the polygon program needs at least 11"
            ),
            "{args:?}: {err}"
        );
    }
}

#[test]
fn scenes_whose_numbers_cannot_be_represented_name_the_field() {
    let d = out_dir("bad-scenes");
    let dir = d.to_str().unwrap();
    let cornell =
        std::fs::read_to_string(root().join("programs/radiosity/scenes/cornell-box.ron")).unwrap();
    let small = std::fs::read_to_string(root().join("programs/polygons/scenes/small.ron")).unwrap();
    let cases = [
        (
            "radiosity",
            cornell.replacen(
                "fov_y_degrees: 39.30764811610662",
                "fov_y_degrees: 1e-300",
                1,
            ),
            "camera.fov_y_degrees: must be in [1e-6, 180)",
        ),
        (
            "radiosity",
            cornell.replacen("emission: (17.0, 11.8, 4.0)", "emission: (1e308, 1, 1)", 1),
            "surfaces[9] (light).emission: components must be >= 0 and at",
        ),
        (
            "run",
            small.replacen("fov_y_degrees: 45.0", "fov_y_degrees: 1e-300", 1),
            "camera.fov_y_degrees: must be in [1e-6, 180)",
        ),
        (
            "run",
            small.replacen("(-9.0, -7.0, -6.0)", "(-9e300, -7.0, -6.0)", 1),
            "triangles[0].vertices[0]: must be finite numbers of magnitude at most 1e12",
        ),
    ];
    for (i, (command, scene, message)) in cases.iter().enumerate() {
        let f = temp_file(&format!("bad-scene-{i}.ron"), scene);
        let err = refused(&[command, "--scene", f.to_str().unwrap(), "--out", dir], &d);
        assert!(unwrapped(&err).contains(message), "{command} {i}: {err}");
    }
}

#[test]
fn a_ten_megabyte_line_gives_a_short_report() {
    let f = temp_file(
        "one-huge-line.ron",
        &format!("(name: \"x\", {}zzz)", " ".repeat(10_000_000)),
    );
    let long = temp_file(
        "one-long-line.ron",
        &format!(
            "(name: \"{}\", gp: (count: 1), ring: (channels: 1), renderer: (count: 1), oops: 1)",
            "é".repeat(1_000_000)
        ),
    );
    for f in [f, long] {
        let out = pxpl5(&["config", "check", f.to_str().unwrap()]);
        no_panic(&out);
        assert_eq!(out.status.code(), Some(2));
        assert!(out.stderr.len() < 5_000, "{} bytes", out.stderr.len());
        assert!(text(&out.stderr).contains("unknown field"));
    }
}

#[test]
fn a_pftrace_is_perfetto_protobuf_streamed_to_its_file_or_a_device_and_nothing_on_failure() {
    let d = out_dir("pftrace");
    let file = d.join("deep/t.pftrace");
    let out = run_small_with(&d.join("out"), &["--trace", file.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let bytes = std::fs::read(&file).unwrap();
    let packets = pxpl5_trace::read_packets(&bytes).expect("a Perfetto trace");
    let tracks: BTreeSet<String> = packets
        .iter()
        .filter_map(|p| p.track_descriptor.as_ref()?.name.clone())
        .collect();
    assert!(
        tracks.contains("GP 0") && tracks.contains("Ring channel 0"),
        "{tracks:?}"
    );
    assert!(packets.iter().filter(|p| p.track_event.is_some()).count() > 50);
    // No temporary file is left beside it.
    assert_eq!(std::fs::read_dir(d.join("deep")).unwrap().count(), 1);

    // Through a symlink to a device (stdout, a pipe here), named .pftrace: the same bytes (a run
    // is deterministic), written through, spooled meanwhile in the temporary directory. (`-` has
    // no extension: it is JSON.)
    #[cfg(unix)]
    if Path::new("/dev/stdout").exists() {
        let link = d.join("stdout.pftrace");
        std::os::unix::fs::symlink("/dev/stdout", &link).unwrap();
        let out = run_small_with(&d.join("out"), &["--trace", link.to_str().unwrap()]);
        assert!(out.status.success(), "{}", text(&out.stderr));
        assert!(out.stdout.starts_with(&bytes), "not the same trace");
        assert!(
            std::fs::symlink_metadata(&link)
                .unwrap()
                .file_type()
                .is_symlink()
        );
    }

    // A run that fails leaves no file, no temporary file and no directory it made.
    let failed = out_dir("pftrace-failed");
    let out = run_small_with(
        &failed,
        &[
            "--time-limit",
            "1us",
            "--trace",
            failed.join("new/t.pftrace").to_str().unwrap(),
        ],
    );
    no_panic(&out);
    assert_eq!(out.status.code(), Some(1), "{}", text(&out.stderr));
    assert!(!failed.exists(), "a failed run left {:?}", listing(&failed));
}

/// The row labels of a timeline SVG, top to bottom (the label column's texts).
fn timeline_rows(svg: &str) -> Vec<String> {
    let mut rows = Vec::new();
    let mut rest = svg;
    while let Some(at) = rest.find("<text x=\"4\"") {
        rest = &rest[at..];
        let body = &rest[rest.find('>').unwrap() + 1..rest.find("</text>").unwrap()];
        rows.push(body.trim().to_owned());
        rest = &rest[1..];
    }
    rows
}

#[test]
fn trace_timeline_draws_a_row_per_track_with_the_critical_path_on_top() {
    let d = out_dir("timeline");
    std::fs::create_dir_all(&d).unwrap();
    let (json, pf) = (d.join("t.json"), d.join("t.pftrace"));
    for trace in [&json, &pf] {
        let out = run_small_with(&d.join("out"), &["--trace", trace.to_str().unwrap()]);
        assert!(out.status.success(), "{}", text(&out.stderr));
    }
    for trace in [&json, &pf] {
        let out = pxpl5(&["trace", "timeline", trace.to_str().unwrap()]);
        assert!(out.status.success(), "{}", text(&out.stderr));
        let svg = std::fs::read_to_string(trace.with_extension("svg")).unwrap();
        assert!(svg.starts_with("<svg"), "{trace:?}");
        let rows = timeline_rows(&svg);
        assert_eq!(rows[0], "critical path", "{rows:?}");
        for want in [
            "GP 0",
            "GP 0 phases",
            "Renderer 0",
            "Ring channel 0 / lane 0",
        ] {
            assert!(rows.iter().any(|r| r == want), "no row {want}: {rows:?}");
        }
        assert!(svg.contains("critical path, by category"), "a legend");
        assert!(svg.matches("<rect").count() > 20);
    }
    // A window drops the rows with nothing in it, and the axis starts at its start.
    let narrow = d.join("narrow.svg");
    let out = pxpl5(&[
        "trace",
        "timeline",
        json.to_str().unwrap(),
        "--window",
        "1ms..1.2ms",
        "--out",
        narrow.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    let svg = std::fs::read_to_string(&narrow).unwrap();
    assert!(svg.contains(">\n1ms\n<"), "the axis starts at 1ms");
    let all = timeline_rows(&std::fs::read_to_string(json.with_extension("svg")).unwrap());
    assert!(timeline_rows(&svg).len() < all.len());

    // Mistakes: exit code 2 naming the file or option.
    let bad = d.join("bad.json");
    std::fs::write(&bad, "{\"not\": 1}").unwrap();
    let garbage = d.join("bad.pftrace");
    std::fs::write(&garbage, [0x0a, 0xff, 0xff, 0xff, 0xff, 0x0f]).unwrap();
    for (args, says) in [
        (
            vec![bad.to_str().unwrap()],
            "bad.json: not a Chrome trace (JSON)",
        ),
        (
            vec![garbage.to_str().unwrap()],
            "bad.pftrace: not a Perfetto trace",
        ),
        (vec!["no/such.json"], "no/such.json: cannot read"),
        (
            vec![json.to_str().unwrap(), "--window", "2ms..1ms"],
            "--window",
        ),
    ] {
        let mut all = vec!["trace", "timeline"];
        all.extend(args);
        let out = pxpl5(&all);
        no_panic(&out);
        assert_eq!(out.status.code(), Some(2), "{all:?}");
        assert!(
            text(&out.stderr).contains(says),
            "{all:?}: {}",
            text(&out.stderr)
        );
    }
}

/// The approximate levels: a report says it was simulated at them, and where a level cannot give
/// the program's result it is a user error naming the option.
#[test]
fn approximate_levels_are_named_and_refused_where_they_cannot_serve() {
    let dir = out_dir("approx");
    let d = dir.to_str().unwrap();
    let o = pxpl5(&[
        "radiosity",
        "--fidelity",
        "timing",
        "--ring-level",
        "message",
        "--shots",
        "2",
        "--patch-size",
        "400",
        "--resolution",
        "16",
        "--out",
        d,
    ]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let report = text(&o.stdout);
    assert!(
        report.contains("timing, ring level message (APPROXIMATE"),
        "{report}"
    );
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("comparison.json")).unwrap())
            .unwrap();
    assert_eq!(json["options"]["ring_level"], "message");
    assert_eq!(json["methods"][0]["stats"]["ring_level"], "message");
    assert_eq!(json["methods"][0]["stats"]["fidelity"], "timing");
    // The polygon program's result is its picture, which the timing level does not draw.
    let o = pxpl5(&["run", "--fidelity", "timing", "--out", d]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        text(&o.stderr).contains("--fidelity timing"),
        "{}",
        text(&o.stderr)
    );
    // Its form factors ignore occlusion: a scene with occluders is refused.
    let o = pxpl5(&[
        "radiosity",
        "--fidelity",
        "timing",
        "--scene",
        "programs/radiosity/scenes/cornell-box.ron",
        "--out",
        d,
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        text(&o.stderr).contains("hide others"),
        "{}",
        text(&o.stderr)
    );
    // The message ring draws the polygon program's picture exactly; only time may differ.
    let o = pxpl5(&["run", "--ring-level", "message", "--out", d]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(
        text(&o.stdout).contains("APPROXIMATE"),
        "{}",
        text(&o.stdout)
    );
}

/// `pxpl5 trace utilisation` of a traced run: the Renderers' mean busy share over the run is the
/// stats' (each bin's share weighed equally: the bins are of equal width), in both formats; a
/// window with nothing in it is a user error.
#[test]
fn trace_utilisation_agrees_with_the_stats() {
    let dir = out_dir("util");
    let d = dir.to_str().unwrap();
    for trace in ["t.json", "t.pftrace"] {
        let file = dir.join(trace);
        let o = pxpl5(&[
            "run",
            "--scene",
            "programs/polygons/scenes/small.ron",
            "--trace",
            file.to_str().unwrap(),
            "--out",
            d,
        ]);
        assert!(o.status.success(), "{}", text(&o.stderr));
        let stats: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("stats.json")).unwrap())
                .unwrap();
        let busy: Vec<f64> = stats["renderers"]
            .as_array()
            .unwrap()
            .iter()
            .map(|r| r["busy_percent"].as_f64().unwrap())
            .collect();
        let mean = busy.iter().sum::<f64>() / busy.len() as f64;
        let svg = dir.join("u.svg");
        let o = pxpl5(&[
            "trace",
            "utilisation",
            file.to_str().unwrap(),
            "--bins",
            "64",
            "--out",
            svg.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", text(&o.stderr));
        let report = text(&o.stdout);
        let at = report.find("Renderers (").expect("a Renderers figure");
        let figure: f64 = report[at..]
            .split_once("): ")
            .and_then(|(_, r)| r.split_once(" %"))
            .map(|(v, _)| v.parse().unwrap())
            .unwrap();
        assert!(
            (figure - mean).abs() < 0.11,
            "{trace}: {report} vs stats {mean}"
        );
        assert!(
            report.contains("GPs (") && report.contains("ring channels ("),
            "{report}"
        );
        assert!(
            std::fs::read_to_string(&svg)
                .unwrap()
                .contains("busy share")
        );
        let o = pxpl5(&[
            "trace",
            "utilisation",
            file.to_str().unwrap(),
            "--window",
            "1s..2s",
        ]);
        assert_eq!(o.status.code(), Some(2), "{}", text(&o.stderr));
    }
}
