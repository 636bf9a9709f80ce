//! `pxpl5 sweep` as a user runs it: the same bytes for 1 and 4 workers, for shards merged and for
//! a run resumed after it stopped; a bad parameter is a user error naming it. Every study here is
//! tiny (27 patches, 4 shots, resolutions 16 and 32), a fraction of a second a point.

use std::path::Path;
use std::process::{Command, Output};

use pxpl5_tests::OutDir;

fn pxpl5(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_pxpl5"))
        .args(args)
        .output()
        .expect("pxpl5 runs")
}

fn text(b: &[u8]) -> String {
    String::from_utf8_lossy(b).into_owned()
}

/// The rows of a CSV the commands write (no `#` lines, no header), split at commas.
fn csv_rows(csv: &str) -> Vec<Vec<&str>> {
    csv.lines()
        .filter(|l| !l.starts_with('#'))
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect()
}

/// A fresh directory for `name`'s outputs.
fn dir(name: &str) -> OutDir {
    OutDir::new("pxpl5-sweep-test", name)
}

/// The tiny study: 2 Renderer counts x 2 resolutions, both methods.
const STUDY: &[&str] = &[
    "sweep",
    "--set",
    "renderer.count=1,2",
    "--set",
    "program.resolution=16,32",
    "--set",
    "program.patch_size=400",
    "--shots",
    "4",
];

fn sweep(out: &Path, more: &[&str]) -> Output {
    let mut args: Vec<&str> = STUDY.to_vec();
    let out = out.to_str().unwrap();
    args.extend(["--out", out]);
    args.extend(more);
    let o = pxpl5(&args);
    assert!(o.status.success(), "{:?}: {}", more, text(&o.stderr));
    o
}

/// The files whose bytes must not depend on workers, shards or resumes.
const SAME: [&str; 3] = ["sweep.csv", "sweep.json", "study.json"];

fn assert_same(a: &Path, b: &Path) {
    for f in SAME {
        let (x, y) = (
            std::fs::read(a.join(f)).unwrap(),
            std::fs::read(b.join(f)).unwrap(),
        );
        assert!(
            x == y,
            "{f} differs between {} and {}",
            a.display(),
            b.display()
        );
    }
}

#[test]
fn workers_shards_and_resumes_give_the_same_bytes() {
    let one = dir("one");
    sweep(&one, &["--workers", "1"]);
    let csv = std::fs::read_to_string(one.join("sweep.csv")).unwrap();
    // 4 points x 2 methods, after the stamp and the header.
    assert_eq!(csv.lines().count(), 2 + 8, "{csv}");
    let header: Vec<&str> = csv.lines().nth(1).unwrap().split(',').collect();
    for column in [
        "renderer.count",
        "program.resolution",
        "per_shot_ms",
        "ratio_per_shot",
        "ff_error_l1",
        "worst_surface_error",
        "critical_renderer",
        "config_hash",
    ] {
        assert!(header.contains(&column), "{column} missing from {header:?}");
    }
    // Host seconds are kept apart from the deterministic rows.
    assert!(!header.iter().any(|c| c.contains("host")));
    let host = std::fs::read_to_string(one.join("host.csv")).unwrap();
    assert_eq!(host.lines().count(), 1 + 8, "{host}");
    // More Renderers: each shot takes less simulated time (point 2 is 2 Renderers at 16 pixels,
    // point 0 one Renderer).
    let per_shot = |point: &str| -> f64 {
        let col = header.iter().position(|c| *c == "per_shot_ms").unwrap();
        let row = csv
            .lines()
            .find(|l| l.starts_with(&format!("{point},hemisphere")))
            .unwrap();
        row.split(',').nth(col).unwrap().parse().unwrap()
    };
    assert!(
        per_shot("2") < per_shot("0"),
        "{} {}",
        per_shot("2"),
        per_shot("0")
    );

    let four = dir("four");
    sweep(&four, &["--workers", "4"]);
    assert_same(&one, &four);

    // Shards, merged.
    let shards: Vec<OutDir> = (0..3).map(|k| dir(&format!("shard{k}"))).collect();
    for (k, s) in shards.iter().enumerate() {
        sweep(s, &["--shard", &format!("{k}/3")]);
    }
    let merged = dir("merged");
    let mut args = vec!["sweep", "merge", merged.to_str().unwrap()];
    args.extend(shards.iter().map(|s| s.to_str().unwrap()));
    let o = pxpl5(&args);
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert_same(&one, &merged);
    // A shard missing is named, exit code 2.
    let o = pxpl5(&[
        "sweep",
        "merge",
        dir("part").to_str().unwrap(),
        shards[0].to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        text(&o.stderr).contains("2 of 4 points are in no shard: 1, 2"),
        "{}",
        text(&o.stderr)
    );

    // Stopped after one point (as a Ctrl-C or a kill would leave it), then resumed.
    let resumed = dir("resumed");
    let o = sweep(&resumed, &["--limit", "1"]);
    assert!(
        text(&o.stdout).contains("1 of 4 points done"),
        "{}",
        text(&o.stdout)
    );
    let partial = std::fs::read_to_string(resumed.join("sweep.csv")).unwrap();
    assert_eq!(partial.lines().count(), 2 + 2);
    // A kill can cut the journal's last line short: it is ignored, and that point run again.
    let journal = resumed.join("rows.jsonl");
    let mut j = std::fs::read_to_string(&journal).unwrap();
    j += "{\"point\": 3, \"key\": \"cut sh";
    std::fs::write(&journal, j).unwrap();
    let o = sweep(&resumed, &[]);
    assert!(
        text(&o.stdout).contains("4 of 4 points done"),
        "{}",
        text(&o.stdout)
    );
    assert_same(&one, &resumed);
    let host = std::fs::read_to_string(resumed.join("host.csv")).unwrap();
    assert_eq!(host.lines().count(), 1 + 8, "{host}");
}

#[test]
fn a_bad_parameter_is_a_user_error_naming_it() {
    let out = dir("bad");
    for (set, says) in [
        (
            "renderer.cont=1,2",
            "--set renderer.cont: `renderer` has no field `cont`",
        ),
        (
            "gp.costs.message_send=fast",
            "--set gp.costs.message_send=fast: not a number",
        ),
        ("renderer.count=0", "renderer.count"),
        ("program.reslution=32", "--set program.reslution"),
        ("program.resolution=5000", "program.resolution=5000"),
    ] {
        let o = pxpl5(&["sweep", "--set", set, "--out", out.to_str().unwrap()]);
        assert_eq!(o.status.code(), Some(2), "{set}");
        assert!(text(&o.stderr).contains(says), "{set}: {}", text(&o.stderr));
        // Found before any run: nothing written.
        assert!(!out.exists(), "{set}");
    }
}

#[test]
fn a_study_file_lists_points_beside_its_cross_product() {
    let out = dir("file");
    std::fs::create_dir_all(&out).unwrap();
    let study = out.join("study.ron");
    std::fs::write(
        &study,
        "(\n    set: [(\"renderer.count\", [1, 2])],\n    points: [[(\"program.resolution\", 16), \
         (\"gp.count\", 4)]],\n    shots: 2,\n)\n",
    )
    .unwrap();
    let o = pxpl5(&[
        "sweep",
        "--study",
        study.to_str().unwrap(),
        "--set",
        "program.patch_size=400",
        "--method",
        "hemisphere",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let csv = std::fs::read_to_string(out.join("sweep.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert!(
        lines[1].starts_with(
            "point,method,renderer.count,program.patch_size,program.resolution,gp.count,"
        ),
        "{}",
        lines[1]
    );
    assert!(
        lines[2].starts_with("0,hemisphere,1,400,,,"),
        "{}",
        lines[2]
    );
    assert!(lines[4].starts_with("2,hemisphere,,,16,4,"), "{}", lines[4]);
    assert_eq!(lines.len(), 5);
    // A field the study does not know is named with the file.
    std::fs::write(&study, "(sets: [])").unwrap();
    let o = pxpl5(&[
        "sweep",
        "--study",
        study.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        text(&o.stderr).contains("unknown field `sets`"),
        "{}",
        text(&o.stderr)
    );
}

/// `pxpl5 sensitivity` on two assumptions of a tiny job: a row each, ranked by how far they move
/// the ratio, and the tornado chart; an `--only` that names nothing is a user error.
#[test]
fn sensitivity_ranks_the_assumptions_it_moves() {
    let out = dir("sensitivity");
    let o = pxpl5(&[
        "sensitivity",
        "--only",
        "ring.hop_latency,gp.costs.message_send",
        "--set",
        "program.patch_size=400",
        "--set",
        "program.resolution=16",
        "--shots",
        "4",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let csv = std::fs::read_to_string(out.join("sensitivity.csv")).unwrap();
    let rows = csv_rows(&csv);
    assert_eq!(rows.len(), 2, "{csv}");
    let mut names: Vec<&str> = rows.iter().map(|r| r[1]).collect();
    names.sort_unstable();
    assert_eq!(names, ["gp.costs.message_send", "ring.hop_latency_cycles"]);
    // Ranked by swing, largest first; the swing is the larger move of the ratio at either end.
    let swing = |r: &Vec<&str>| r[7].parse::<f64>().unwrap();
    assert!(swing(&rows[0]) >= swing(&rows[1]), "{csv}");
    for r in &rows {
        let (d, lo, hi) = (
            r[4].parse::<f64>().unwrap(),
            r[5].parse::<f64>().unwrap(),
            r[6].parse::<f64>().unwrap(),
        );
        assert_eq!(swing(r), (lo - d).abs().max((hi - d).abs()), "{csv}");
    }
    // 200 cycles a message cost the GPs more than 20: the hemisphere's time per shot grows.
    let send = rows
        .iter()
        .find(|r| r[1] == "gp.costs.message_send")
        .unwrap();
    assert!(
        send[10].parse::<f64>().unwrap() > send[9].parse::<f64>().unwrap(),
        "{csv}"
    );
    let svg = std::fs::read_to_string(out.join("sensitivity.svg")).unwrap();
    assert!(svg.contains("ring.hop_latency_cycles") && svg.contains("gp.costs.message_send"));
    // The study's rows: the default and both ends of each, two methods each.
    let study = std::fs::read_to_string(out.join("sweep.csv")).unwrap();
    assert_eq!(study.lines().count(), 2 + 5 * 2, "{study}");

    let o = pxpl5(&[
        "sensitivity",
        "--only",
        "no.such",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        text(&o.stderr).contains("--only no.such"),
        "{}",
        text(&o.stderr)
    );
}

/// `pxpl5 stability`: a row per study value; scaling the whole geometry changes neither the
/// exact form factor nor the machine's (it works in the point's frame), so the error is the same
/// at every scale; the same bytes on a second run.
#[test]
fn stability_rows_and_scale_invariance() {
    let out = dir("stability");
    let run = || {
        let o = pxpl5(&[
            "stability",
            "--method",
            "hemisphere",
            "--out",
            out.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", text(&o.stderr));
        std::fs::read(out.join("stability.csv")).unwrap()
    };
    let first = run();
    assert_eq!(first, run());
    let csv = String::from_utf8(first).unwrap();
    let rows = csv_rows(&csv);
    assert_eq!(rows.len(), 8 + 7 + 9, "{csv}");
    let scale: Vec<f64> = rows
        .iter()
        .filter(|r| r[0] == "scale")
        .map(|r| r[5].parse().unwrap())
        .collect();
    assert_eq!(scale.len(), 7);
    // The machine's value is the same bits at every scale; the exact one is rounded a little
    // differently, far below the error itself.
    assert!(
        scale
            .iter()
            .all(|e| (e - scale[0]).abs() < 1e-9 * scale[0] && *e < 0.05),
        "{scale:?}"
    );
    let values: Vec<&str> = rows
        .iter()
        .filter(|r| r[0] == "scale")
        .map(|r| r[3])
        .collect();
    assert!(values.iter().all(|v| *v == values[0]), "{values:?}");
    // At 128 pixels across, 4 fractional bits place the hemisphere's edges worse than 16.
    let frac = |bits: &str| -> f64 {
        rows.iter()
            .find(|r| r[0] == "qee_frac_bits" && r[1] == bits)
            .map(|r| r[5].parse().unwrap())
            .unwrap()
    };
    assert!(frac("4") > frac("16"), "{csv}");
    assert!(
        std::fs::read_to_string(out.join("stability.svg"))
            .unwrap()
            .contains("elevation_deg")
    );
}

/// `pxpl5 tradeoff` on a tiny job: the reference, the timing Renderer, the message-level ring and
/// both. Each approximate level's reported errors are those of a direct comparison: `pxpl5
/// radiosity` run at that level and at the reference, its time to the target and final error
/// read from comparison.json.
#[test]
fn tradeoff_errors_match_a_direct_comparison() {
    let job = [
        "--set",
        "program.patch_size=400",
        "--set",
        "program.resolution=16",
        "--until-error",
        "0.2",
    ];
    let out = dir("tradeoff");
    let mut args = vec!["tradeoff", "--only", "timing,message"];
    args.extend(job);
    args.extend(["--out", out.to_str().unwrap()]);
    let o = pxpl5(&args);
    assert!(o.status.success(), "{}", text(&o.stderr));
    let csv = std::fs::read_to_string(out.join("tradeoff.csv")).unwrap();
    let rows = csv_rows(&csv);
    // 4 knobs x 2 methods.
    assert_eq!(rows.len(), 8, "{csv}");
    let direct = |level: &[&str], name: &str| -> serde_json::Value {
        let d = dir(&format!("tradeoff-direct-{name}"));
        let mut a = vec![
            "radiosity",
            "--patch-size",
            "400",
            "--resolution",
            "16",
            "--until-error",
            "0.2",
            "--out",
            d.to_str().unwrap(),
        ];
        a.extend(level);
        let o = pxpl5(&a);
        assert!(o.status.success(), "{name}: {}", text(&o.stderr));
        let json = std::fs::read_to_string(d.join("comparison.json")).unwrap();
        serde_json::from_str(&json).unwrap()
    };
    let reference = direct(&[], "reference");
    let levels: [(&str, &[&str]); 4] = [
        ("sparse (reference)", &[]),
        ("timing", &["--fidelity", "timing"]),
        ("message ring", &["--ring-level", "message"]),
        (
            "timing + message ring",
            &["--fidelity", "timing", "--ring-level", "message"],
        ),
    ];
    for (knob, level) in levels {
        let run = direct(level, &knob.replace([' ', '(', ')', '+'], ""));
        for (m, method) in ["hemisphere", "hemicube"].into_iter().enumerate() {
            let row = rows
                .iter()
                .find(|r| r[0] == knob && r[1] == method)
                .unwrap_or_else(|| panic!("{knob} {method}: {csv}"));
            let acc = |v: &serde_json::Value, what: &str| {
                v["methods"][m]["accuracy"][what].as_f64().unwrap()
            };
            let (t, t_ref) = (
                acc(&run, "time_to_target_s"),
                acc(&reference, "time_to_target_s"),
            );
            let reported: f64 = row[4].parse().unwrap();
            let expected = (t - t_ref).abs() / t_ref;
            assert!(
                (reported - expected).abs() <= 1e-12 * expected.max(1.0),
                "{knob} {method}: time error {reported}, directly {expected}"
            );
            let radiosity: f64 = row[8].parse().unwrap();
            assert_eq!(radiosity, acc(&run, "final_error"), "{knob} {method}");
            if knob.starts_with("timing") {
                // Its form factors are the exact formula's.
                assert_eq!(row[9], "0", "{knob} {method}: {csv}");
            }
        }
    }
    let svg = std::fs::read_to_string(out.join("tradeoff.svg")).unwrap();
    assert!(svg.contains("Pareto frontier"), "{svg}");
    // A knob filter that names nothing is a user error.
    let o = pxpl5(&["tradeoff", "--only", "nothing-like-this"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        text(&o.stderr).contains("names no knob"),
        "{}",
        text(&o.stderr)
    );
}
