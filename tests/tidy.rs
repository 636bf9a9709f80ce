//! Tidy rules, run by the normal test command (after rust-analyzer's tidy test):
//!
//! - every `.rs` file of the project starts with a `//!` doc saying what it is for;
//! - crate dependencies follow the table in ARCHITECTURE.md (section "Dependency rules"): each
//!   crate of `crates/` and `programs/` may depend only on the project crates its row lists, and
//!   every such crate has a row;
//! - only the crates ARCHITECTURE.md names may depend on `serde` or `ron` (the config schema is the
//!   one place that knows the file format);
//! - `crates/pxpl5-sim/src` names no unit of Pixel-Planes 5 (GP, Renderer, ring, QEE, IGC, frame
//!   buffer), in code, comments or docs alike.

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Path, PathBuf};

use pxpl5_tests::workspace_root;

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

#[test]
fn every_rust_file_starts_with_a_module_doc() {
    let root = workspace_root();
    let mut files = Vec::new();
    for dir in ["crates", "programs", "tests"] {
        rust_files(&root.join(dir), &mut files);
    }
    assert!(files.len() > 10, "found only {} files", files.len());
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
    body.lines()
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
        .collect()
}

/// Every crate of crates/ and programs/: name -> its normal dependencies.
fn crates() -> BTreeMap<String, BTreeSet<String>> {
    let root = workspace_root();
    let mut out = BTreeMap::new();
    for dir in ["crates", "programs"] {
        let Ok(entries) = fs::read_dir(root.join(dir)) else {
            continue;
        };
        for e in entries.flatten() {
            let manifest = e.path().join("Cargo.toml");
            let Ok(text) = fs::read_to_string(&manifest) else {
                continue;
            };
            let doc: toml::Table = text
                .parse()
                .unwrap_or_else(|err| panic!("{}: {err}", manifest.display()));
            let name = doc["package"]["name"].as_str().unwrap().to_string();
            let deps = doc
                .get("dependencies")
                .and_then(|d| d.as_table())
                .map(|t| t.keys().cloned().collect())
                .unwrap_or_default();
            out.insert(name, deps);
        }
    }
    out
}

#[test]
fn crate_dependencies_follow_architecture_md() {
    let rules = architecture_table("dependencies");
    let mut problems = Vec::new();
    for (name, deps) in crates() {
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

#[test]
fn only_the_config_crate_knows_the_file_format() {
    let rules = architecture_table("format-crates");
    let mut problems = Vec::new();
    for (name, deps) in crates() {
        for format_crate in ["serde", "ron", "toml"] {
            let allowed = rules.get(format_crate).cloned().unwrap_or_default();
            if deps.contains(format_crate) && !allowed.contains(&name) {
                problems.push(format!("{name} depends on {format_crate}"));
            }
        }
    }
    assert!(problems.is_empty(), "{}", problems.join("\n"));
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
