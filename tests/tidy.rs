//! Tidy rules, run by the normal test command (after rust-analyzer's tidy test):
//!
//! - every `.rs` file of the project starts with a `//!` doc saying what it is for;
//! - no test expects a panic with `#[should_panic]`: a user's mistake is an error, so tests assert
//!   the error (`Result`), and a bug check that must be testable gets a `try_` form that returns
//!   one;
//! - crate dependencies follow the table in ARCHITECTURE.md (section "Dependency rules"): each
//!   crate of `crates/` and `programs/` may depend only on the project crates its row lists, and
//!   every such crate has a row;
//! - only the crates ARCHITECTURE.md names may depend on a file-format crate (`serde`,
//!   `serde_json`, `ron`, `toml`): each has a row in its `tidy:format-crates` table. Only
//!   `[dependencies]` count (a test may parse output with a dev-dependency), and a test checks
//!   that a violation fails;
//! - every crate's manifest takes the workspace's lints (`[lints] workspace = true`);
//! - `crates/pxpl5-sim/src` names no unit of Pixel-Planes 5 (GP, Renderer, ring, QEE, IGC, frame
//!   buffer), in code, comments or docs alike;
//! - the CLI (`crates/pxpl5-cli/src`) prints only through its writer (`output.rs`): no `println!`,
//!   `print!`, `eprintln!` or `eprint!`, which panic when their stream is closed or full; a test
//!   checks that the scan catches each.
//!
//! Each check also asserts that it found what it checks (files, crates, manifests, table rows),
//! so that a moved directory or a renamed table fails instead of passing on nothing.

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Path, PathBuf};

use pxpl5_tests::workspace_root;

/// The crates of `crates/` and `programs/` (7 + 2): fewer found means the scan is broken.
const MIN_CRATES: usize = 9;
/// Rust files of `crates/`, `programs/` and `tests/` (70 when this was written; a floor with room
/// for files merged by a refactor, far above what a broken scan finds).
const MIN_RUST_FILES: usize = 50;
/// The file-format crates: each must have a row in ARCHITECTURE.md's `tidy:format-crates` table.
const FORMAT_CRATES: [&str; 4] = ["serde", "serde_json", "ron", "toml"];

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = fs::read_dir(dir) else {
        return;
    };
    let mut entries: Vec<_> = entries.flatten().map(|e| e.path()).collect();
    entries.sort();
    for p in entries {
        let name = p.file_name().and_then(|n| n.to_str()).unwrap_or("");
        if p.is_dir() {
            if name != "target" && !name.starts_with('.') {
                rust_files(&p, out);
            }
        } else if name.ends_with(".rs") {
            out.push(p);
        }
    }
}

/// Every `.rs` file of `crates/`, `programs/` and `tests/`, at least [`MIN_RUST_FILES`].
fn project_rust_files() -> Vec<PathBuf> {
    let root = workspace_root();
    let mut files = Vec::new();
    for dir in ["crates", "programs", "tests"] {
        let before = files.len();
        rust_files(&root.join(dir), &mut files);
        assert!(files.len() > before, "found no .rs file under {dir}/");
    }
    assert!(
        files.len() >= MIN_RUST_FILES,
        "found only {} .rs files (expected at least {MIN_RUST_FILES})",
        files.len()
    );
    files
}

#[test]
fn every_rust_file_starts_with_a_module_doc() {
    let root = workspace_root();
    let files = project_rust_files();
    let missing: Vec<String> = files
        .iter()
        .filter(|f| {
            let text = fs::read_to_string(f).unwrap_or_default();
            let first = text.lines().find(|l| !l.trim().is_empty()).unwrap_or("");
            !first.starts_with("//!")
        })
        .map(|f| f.strip_prefix(&root).unwrap_or(f).display().to_string())
        .collect();
    assert!(
        missing.is_empty(),
        "these files do not start with a `//!` doc saying what they are for:\n  {}",
        missing.join("\n  ")
    );
}

#[test]
fn no_test_expects_a_panic() {
    let root = workspace_root();
    // Spelt in two pieces so that this file does not match itself.
    let attribute = format!("#[{}_panic", "should");
    let mut found = Vec::new();
    for f in project_rust_files() {
        let text = fs::read_to_string(&f).unwrap_or_default();
        for (i, line) in text.lines().enumerate() {
            if line.trim_start().starts_with(&attribute) {
                let path = f.strip_prefix(&root).unwrap_or(&f).display().to_string();
                found.push(format!("{path}:{}", i + 1));
            }
        }
    }
    assert!(
        found.is_empty(),
        "tests must assert the error (a Result), not expect a panic with {attribute}]:\n  {}",
        found.join("\n  ")
    );
}

/// The rows of the markdown table between `<!-- tidy:NAME -->` and `<!-- /tidy:NAME -->` in
/// ARCHITECTURE.md: first cell -> the comma-separated names of the second.
fn architecture_table(name: &str) -> BTreeMap<String, BTreeSet<String>> {
    let text = fs::read_to_string(workspace_root().join("ARCHITECTURE.md"))
        .expect("ARCHITECTURE.md exists at the workspace root");
    let start = format!("<!-- tidy:{name} -->");
    let end = format!("<!-- /tidy:{name} -->");
    let body = text
        .split_once(&start)
        .and_then(|(_, rest)| rest.split_once(&end))
        .map(|(body, _)| body)
        .unwrap_or_else(|| panic!("ARCHITECTURE.md has no {start} ... {end} table"));
    let rows: BTreeMap<String, BTreeSet<String>> = body
        .lines()
        .filter(|l| l.trim_start().starts_with('|') && !l.contains("---"))
        .skip(1) // the header row
        .map(|l| {
            let cells: Vec<&str> = l.trim().trim_matches('|').split('|').collect();
            let clean = |s: &str| s.trim().trim_matches('`').to_string();
            let allowed = cells
                .get(1)
                .map(|c| {
                    c.split(',')
                        .map(clean)
                        .filter(|s| !s.is_empty() && s != "nothing")
                        .collect()
                })
                .unwrap_or_default();
            (clean(cells[0]), allowed)
        })
        .collect();
    assert!(
        !rows.is_empty(),
        "ARCHITECTURE.md's {start} table has no rows"
    );
    rows
}

/// The package a dependency entry names: its key, or `package = "..."` when renamed.
fn package_name(key: &str, entry: &toml::Value) -> String {
    entry
        .get("package")
        .and_then(|p| p.as_str())
        .unwrap_or(key)
        .to_string()
}

/// The manifests of every crate: `crates/*`, `programs/*` and `tests/`.
fn crate_manifests() -> Vec<PathBuf> {
    let root = workspace_root();
    let mut out = Vec::new();
    for dir in ["crates", "programs"] {
        let Ok(entries) = fs::read_dir(root.join(dir)) else {
            continue;
        };
        let mut found: Vec<PathBuf> = entries
            .flatten()
            .map(|e| e.path().join("Cargo.toml"))
            .filter(|m| m.is_file())
            .collect();
        found.sort();
        out.extend(found);
    }
    out.push(root.join("tests/Cargo.toml"));
    assert!(
        out.len() > MIN_CRATES,
        "found only {} crate manifests (expected at least {})",
        out.len(),
        MIN_CRATES + 1
    );
    out
}

fn parse_manifest(manifest: &Path) -> toml::Table {
    let text =
        fs::read_to_string(manifest).unwrap_or_else(|err| panic!("{}: {err}", manifest.display()));
    text.parse()
        .unwrap_or_else(|err| panic!("{}: {err}", manifest.display()))
}

/// Every crate of crates/ and programs/: name -> the packages of its normal dependencies.
fn crates() -> BTreeMap<String, BTreeSet<String>> {
    let root = workspace_root();
    let mut out = BTreeMap::new();
    for manifest in crate_manifests() {
        if manifest.parent() == Some(root.join("tests").as_path()) {
            continue;
        }
        let doc = parse_manifest(&manifest);
        let name = doc["package"]["name"].as_str().unwrap().to_string();
        let deps = doc
            .get("dependencies")
            .and_then(|d| d.as_table())
            .map(|t| t.iter().map(|(k, v)| package_name(k, v)).collect())
            .unwrap_or_default();
        out.insert(name, deps);
    }
    assert!(
        out.len() >= MIN_CRATES,
        "found only {} crates in crates/ and programs/ (expected at least {MIN_CRATES})",
        out.len()
    );
    out
}

#[test]
fn crate_dependencies_follow_architecture_md() {
    let rules = architecture_table("dependencies");
    let crates = crates();
    let mut problems: Vec<String> = rules
        .keys()
        .filter(|name| !crates.contains_key(*name))
        .map(|name| format!("ARCHITECTURE.md's dependency table names {name}, which is no crate"))
        .collect();
    for (name, deps) in crates {
        let Some(allowed) = rules.get(&name) else {
            problems.push(format!(
                "{name} has no row in ARCHITECTURE.md's dependency table"
            ));
            continue;
        };
        for d in deps.iter().filter(|d| d.starts_with("pxpl5-")) {
            if !allowed.contains(d) {
                problems.push(format!(
                    "{name} depends on {d}, which ARCHITECTURE.md does not allow"
                ));
            }
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// What breaks the format-crates rule: `rules` (format crate -> crates allowed to depend on it)
/// against `crates` (crate -> its normal dependencies), one line per problem.
fn format_crate_problems(
    rules: &BTreeMap<String, BTreeSet<String>>,
    crates: &BTreeMap<String, BTreeSet<String>>,
) -> Vec<String> {
    let mut problems = Vec::new();
    for format_crate in FORMAT_CRATES {
        if !rules.contains_key(format_crate) {
            problems.push(format!(
                "ARCHITECTURE.md's format-crates table has no row for {format_crate}"
            ));
        }
    }
    // Every row is enforced, including format crates added to the table later.
    for (format_crate, allowed) in rules {
        for name in allowed.iter().filter(|n| !crates.contains_key(*n)) {
            problems.push(format!(
                "ARCHITECTURE.md allows {format_crate} in {name}, which is no crate"
            ));
        }
        for (name, deps) in crates {
            if deps.contains(format_crate) && !allowed.contains(name) {
                problems.push(format!(
                    "{name} depends on {format_crate}, which ARCHITECTURE.md does not allow"
                ));
            }
        }
    }
    problems
}

#[test]
fn only_the_crates_architecture_md_names_use_a_file_format_crate() {
    let problems = format_crate_problems(&architecture_table("format-crates"), &crates());
    assert!(problems.is_empty(), "{}", problems.join("\n"));
}

/// The rule reads `[dependencies]` only, and fails when broken: `pxpl5-trace` has `serde_json` as
/// a dev-dependency (its tests parse traces), which the rule ignores; as a dependency it is
/// refused ("no serde or serde_json below pxpl5-machine").
#[test]
fn the_format_crate_rule_ignores_dev_dependencies_and_catches_a_violation() {
    let manifest = parse_manifest(&workspace_root().join("crates/pxpl5-trace/Cargo.toml"));
    assert!(
        manifest["dev-dependencies"].get("serde_json").is_some(),
        "pxpl5-trace's tests no longer use serde_json: pick another dev-dependency to check"
    );
    let rules = architecture_table("format-crates");
    let mut crates = crates();
    assert!(
        !crates["pxpl5-trace"].contains("serde_json"),
        "dev-dependencies counted"
    );
    assert!(format_crate_problems(&rules, &crates).is_empty());
    crates
        .get_mut("pxpl5-trace")
        .expect("pxpl5-trace is a crate")
        .insert("serde_json".to_string());
    assert_eq!(
        format_crate_problems(&rules, &crates),
        ["pxpl5-trace depends on serde_json, which ARCHITECTURE.md does not allow"]
    );
    for core in ["pxpl5-sim", "pxpl5-renderer", "pxpl5-ring", "pxpl5-trace"] {
        for format_crate in ["serde", "serde_json"] {
            assert!(
                !rules[format_crate].contains(core),
                "ARCHITECTURE.md allows {format_crate} in {core}, below pxpl5-machine"
            );
        }
    }
}

#[test]
fn every_crate_takes_the_workspace_lints() {
    let root = workspace_root();
    let workspace = parse_manifest(&root.join("Cargo.toml"));
    let lints = workspace
        .get("workspace")
        .and_then(|w| w.get("lints"))
        .expect("the workspace Cargo.toml has [workspace.lints]");
    assert_eq!(
        lints
            .get("rust")
            .and_then(|r| r.get("unsafe_code"))
            .and_then(|v| v.as_str()),
        Some("forbid"),
        "[workspace.lints.rust] must forbid unsafe_code"
    );
    let mut problems = Vec::new();
    for manifest in crate_manifests() {
        let doc = parse_manifest(&manifest);
        let takes_workspace = doc
            .get("lints")
            .and_then(|l| l.get("workspace"))
            .and_then(|w| w.as_bool())
            == Some(true);
        if !takes_workspace {
            problems.push(
                manifest
                    .strip_prefix(&root)
                    .unwrap_or(&manifest)
                    .display()
                    .to_string(),
            );
        }
    }
    assert!(
        problems.is_empty(),
        "these manifests lack `[lints] workspace = true`:\n  {}",
        problems.join("\n  ")
    );
}

/// The words of `text` as they are read, split at every character that is not a letter or digit,
/// and within identifiers at `_` and case changes (`RingDelivery` is "Ring", "Delivery";
/// `QEEStream` is "QEE", "Stream"; `GPs` stays whole), in order.
fn word_parts(text: &str) -> Vec<String> {
    let mut parts = Vec::new();
    for token in text.split(|c: char| !c.is_ascii_alphanumeric()) {
        let chars: Vec<char> = token.chars().collect();
        let mut start = 0;
        for i in 1..chars.len() {
            let (prev, c) = (chars[i - 1], chars[i]);
            // In ABc the B starts a word (an acronym ends), but not in a plural acronym ("GPs").
            let plural = i + 2 == chars.len() && chars[i + 1] == 's';
            let next_lower = !plural && chars.get(i + 1).is_some_and(|n| n.is_ascii_lowercase());
            // aB starts a word, and so does the B of ABc.
            if c.is_ascii_uppercase()
                && (prev.is_ascii_lowercase() || (prev.is_ascii_uppercase() && next_lower))
            {
                parts.push(chars[start..i].iter().collect());
                start = i;
            }
        }
        if start < chars.len() {
            parts.push(chars[start..].iter().collect());
        }
    }
    parts
}

/// Where `text` names a unit of Pixel-Planes 5: each hit as the word found.
///
/// Whole words only, so "string" or "during" are not "ring"; compared without case, because an
/// identifier writes an acronym as `Gp` or `gp` (a case-sensitive `GP` would miss `GpResume`).
fn machine_words(text: &str) -> Vec<String> {
    const UNITS: [&str; 8] = [
        "gp",
        "gps",
        "renderer",
        "renderers",
        "ring",
        "rings",
        "qee",
        "igc",
    ];
    let parts: Vec<String> = word_parts(text)
        .iter()
        .map(|p| p.to_ascii_lowercase())
        .collect();
    let mut hits: Vec<String> = parts
        .iter()
        .filter(|p| UNITS.contains(&p.as_str()) || p.as_str() == "framebuffer")
        .cloned()
        .collect();
    hits.extend(
        parts
            .windows(2)
            .filter(|w| w[0] == "frame" && w[1] == "buffer")
            .map(|w| w.join(" ")),
    );
    hits
}

#[test]
fn machine_words_finds_identifiers_and_prose() {
    assert_eq!(
        machine_words("Priority::RingDelivery, GpResume, gp_wake, GPs; QEEStream IGC"),
        ["ring", "gp", "gp", "gps", "qee", "igc"]
    );
    assert_eq!(
        machine_words("FrameBuffer frame_buffer the frame buffer, Framebuffer"),
        [
            "framebuffer",
            "frame buffer",
            "frame buffer",
            "frame buffer"
        ]
    );
    assert_eq!(machine_words("a RendererComplete event"), ["renderer"]);
    assert!(machine_words("a string during gpu ringing; frame rate, buffer").is_empty());
}

/// ARCHITECTURE.md: "`pxpl5-sim` knows nothing of Pixel-Planes". Its doc comments are checked with
/// its code: they describe the kernel to every user, and a unit named there is a meaning the
/// kernel would be claiming to know.
#[test]
fn the_simulation_kernel_names_no_machine_unit() {
    let root = workspace_root();
    let mut files = Vec::new();
    rust_files(&root.join("crates/pxpl5-sim/src"), &mut files);
    assert!(!files.is_empty(), "crates/pxpl5-sim/src has no .rs files");
    let mut problems = Vec::new();
    for f in &files {
        let text = fs::read_to_string(f).unwrap_or_default();
        for (n, line) in text.lines().enumerate() {
            let hits = machine_words(line);
            if !hits.is_empty() {
                problems.push(format!(
                    "{}:{}: {} ({})",
                    f.strip_prefix(&root).unwrap_or(f).display(),
                    n + 1,
                    hits.join(", "),
                    line.trim()
                ));
            }
        }
    }
    assert!(
        problems.is_empty(),
        "pxpl5-sim must name no unit of the machine it simulates:\n  {}",
        problems.join("\n  ")
    );
}

/// ARCHITECTURE.md: "GP work and its cost are one call". Programs charge i860 time only through
/// `Gp::work`, which runs the work and charges what it noted, never by a separate `compute`.
#[test]
fn programs_charge_gp_work_where_they_do_it() {
    let root = workspace_root();
    let mut files = Vec::new();
    rust_files(&root.join("programs"), &mut files);
    files.retain(|f| f.components().any(|c| c.as_os_str() == "src"));
    assert!(
        files.len() >= 10,
        "found only {} program sources",
        files.len()
    );
    let mut problems = Vec::new();
    for f in &files {
        let text = fs::read_to_string(f).unwrap_or_default();
        for (n, line) in text.lines().enumerate() {
            if line.contains(".compute(") || line.contains(".compute_cycles(") {
                problems.push(format!(
                    "{}:{}: {}",
                    f.strip_prefix(&root).unwrap_or(f).display(),
                    n + 1,
                    line.trim()
                ));
            }
        }
    }
    assert!(
        problems.is_empty(),
        "programs must charge GP time with Gp::work (the work and its cost in one call):\n  {}",
        problems.join("\n  ")
    );
}

/// ARCHITECTURE.md: one home for geometry. Vector math is glam's, and what glam lacks lives in
/// `pxpl5-geom`: no other crate writes its own `cross` or `dot`; and programs own their file
/// formats: no scene type lives in `pxpl5-config`.
#[test]
fn geometry_and_scene_formats_have_one_home() {
    let root = workspace_root();
    let files = project_rust_files();
    let mut problems = Vec::new();
    for f in &files {
        let rel = f.strip_prefix(&root).unwrap_or(f);
        let text = fs::read_to_string(f).unwrap_or_default();
        for (n, line) in text.lines().enumerate() {
            let t = line.trim_start();
            let vector_math = ["cross", "dot"]
                .iter()
                .any(|name| t.contains(&format!("fn {name}(")));
            if vector_math && !rel.starts_with("crates/pxpl5-geom") {
                problems.push(format!("{}:{}: {}", rel.display(), n + 1, t));
            }
            let scene_type =
                (t.starts_with("pub struct") || t.starts_with("struct")) && t.contains("Scene");
            if scene_type && rel.starts_with("crates/pxpl5-config") {
                problems.push(format!("{}:{}: {}", rel.display(), n + 1, t));
            }
        }
    }
    assert!(
        problems.is_empty(),
        "vector math belongs to pxpl5-geom (glam) and scene formats to their programs:\n  {}",
        problems.join("\n  ")
    );
}

/// The std print macros: each panics when its stream fails (a closed pipe, a full device).
const PRINT_MACROS: [&str; 4] = ["println!", "print!", "eprintln!", "eprint!"];

/// The 1-based numbers of the lines of `text` that call a std print macro, outside `//`
/// comments.
fn print_macro_lines(text: &str) -> Vec<usize> {
    let mut lines = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let code = line.split("//").next().unwrap_or("");
        let calls = PRINT_MACROS.iter().any(|m| {
            code.match_indices(m).any(|(at, _)| {
                // A whole name: not the end of `outln!`, `my_print!` or `eprint!` inside `print!`.
                let before = code[..at].chars().next_back();
                !before.is_some_and(|c| c.is_alphanumeric() || c == '_')
            })
        });
        if calls {
            lines.push(n + 1);
        }
    }
    lines
}

#[test]
fn the_print_macro_scan_catches_each_macro() {
    for m in PRINT_MACROS {
        let text = format!("fn f() {{\n    {m}(\"x\");\n}}\n");
        assert_eq!(print_macro_lines(&text), vec![2], "{m} not caught");
    }
    let clean = "outln!(\"x\")?;\nerrln!(\"y\");\n// println!(\"in a comment\")\nlet s = \"a\"; // print!\n";
    assert_eq!(print_macro_lines(clean), Vec::<usize>::new());
}

/// The CLI prints through `output.rs`, which turns a closed or full stdout into an exit code
/// instead of a panic (exit 101).
#[test]
fn the_cli_prints_only_through_its_writer() {
    let root = workspace_root();
    let mut files = Vec::new();
    rust_files(&root.join("crates/pxpl5-cli/src"), &mut files);
    assert!(
        files.iter().any(|f| f.ends_with("output.rs")) && files.len() >= 5,
        "found {} files in crates/pxpl5-cli/src, without its writer output.rs",
        files.len()
    );
    let mut found = Vec::new();
    for f in &files {
        let text = fs::read_to_string(f).unwrap_or_default();
        let rel = f.strip_prefix(&root).unwrap_or(f).display().to_string();
        found.extend(
            print_macro_lines(&text)
                .into_iter()
                .map(|n| format!("{rel}:{n}")),
        );
    }
    assert!(
        found.is_empty(),
        "the CLI prints through output.rs (out!, outln!, errln!), not std's print macros:\n  {}",
        found.join("\n  ")
    );
}
