//! Tests of `pxpl5-config` through its public API: the shipped machine configs, round trips,
//! error reports (positions, texts, no panics on any input), every semantic check, and the
//! completeness of the provenance table and of the config files' comments.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use pxpl5_config::{
    ConfigError, EMBEDDED_TEXT, MachineConfig, PROVENANCE, Tag, config_hash, default_config,
    load_file, parse_str, provenance, show, to_ron, validate,
};

fn configs_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../machine-configs")
}

fn config_files() -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(configs_dir())
        .expect("machine-configs/ exists")
        .map(|entry| entry.expect("readable directory entry").path())
        .filter(|path| path.extension().is_some_and(|ext| ext == "ron"))
        .collect();
    files.sort();
    files
}

fn load(name: &str) -> MachineConfig {
    load_file(&configs_dir().join(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
}

// ---------------------------------------------------------------------------------------------
// The shipped configs.

#[test]
fn every_shipped_config_parses_and_validates() {
    let files = config_files();
    let names: Vec<String> = files
        .iter()
        .map(|p| {
            p.file_name()
                .unwrap_or_default()
                .to_string_lossy()
                .into_owned()
        })
        .collect();
    for expected in ["minimal.ron", "pxpl5-1989.ron", "seed-tr89-002.ron"] {
        assert!(
            names.iter().any(|n| n == expected),
            "{expected} missing: {names:?}"
        );
    }
    for path in &files {
        let cfg = load_file(path).unwrap_or_else(|e| panic!("{e}"));
        // A config's name is its file's stem, so reports can be traced back to the file.
        let stem = path.file_stem().unwrap_or_default().to_string_lossy();
        assert_eq!(cfg.name, stem, "{}", path.display());
        assert!(!cfg.description.is_empty(), "{}", path.display());
    }
}

#[test]
fn the_shipped_machines_are_what_they_say() {
    let seed = load("seed-tr89-002.ron");
    assert_eq!((seed.gp.count, seed.renderer.count), (16, 4));
    assert_eq!(seed.ring.channels, 4);
    // The seed's 80 Mwords/s over 4 channels.
    assert_eq!(
        u64::from(seed.ring.channels) * seed.ring.channel_clock_hz,
        80_000_000
    );

    let paper = load("pxpl5-1989.ron");
    assert_eq!((paper.gp.count, paper.renderer.count), (32, 16));
    // The paper's "5 gigabit" ring: 4 x 40 MHz x 32 bits.
    let bits_per_s = u64::from(paper.ring.channels)
        * paper.ring.channel_clock_hz
        * u64::from(paper.ring.word_bits);
    assert_eq!(bits_per_s, 5_120_000_000);

    let minimal = load("minimal.ron");
    assert_eq!(
        (
            minimal.gp.count,
            minimal.renderer.count,
            minimal.ring.channels
        ),
        (1, 1, 1)
    );
}

#[test]
fn default_config_is_the_seed_file() {
    assert_eq!(default_config(), load("seed-tr89-002.ron"));
    let on_disk = std::fs::read_to_string(configs_dir().join("seed-tr89-002.ron"))
        .expect("seed file readable");
    assert_eq!(on_disk, EMBEDDED_TEXT);
}

/// The files write every field out; apart from the required fields, the seed's values must be
/// exactly the schema's defaults, and the other files differ from it only where they say so.
#[test]
fn the_seed_file_writes_out_the_schema_defaults() {
    let seed = default_config();
    let text = format!(
        "(name: {:?}, description: {:?}, gp: (count: {}), ring: (channels: {}), renderer: (count: {}))",
        seed.name, seed.description, seed.gp.count, seed.ring.channels, seed.renderer.count
    );
    let from_defaults = parse_str("defaults.ron", &text).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(from_defaults, seed);

    let mut minimal = load("minimal.ron");
    minimal.name = seed.name.clone();
    minimal.description = seed.description.clone();
    minimal.gp.count = seed.gp.count;
    minimal.ring.channels = seed.ring.channels;
    minimal.renderer.count = seed.renderer.count;
    assert_eq!(minimal, seed);

    let mut paper = load("pxpl5-1989.ron");
    paper.name = seed.name.clone();
    paper.description = seed.description.clone();
    paper.gp.count = seed.gp.count;
    paper.renderer.count = seed.renderer.count;
    paper.ring.channel_clock_hz = seed.ring.channel_clock_hz;
    assert_eq!(paper, seed);
}

// ---------------------------------------------------------------------------------------------
// Round trips and the printed forms.

#[test]
fn to_ron_round_trips_every_config() {
    let mut configs: Vec<MachineConfig> = config_files()
        .iter()
        .map(|p| load_file(p).unwrap_or_else(|e| panic!("{e}")))
        .collect();
    // Awkward text and non-default enum values must survive too.
    let mut odd = default_config();
    odd.description =
        "quotes \" backslash \\ newline \n tab \t unicode é ∑ // not a comment".into();
    odd.ring.token_policy = pxpl5_config::TokenPolicy::LateRelease;
    odd.ring.node_order = pxpl5_config::NodeOrder::GpsThenRenderers;
    odd.host.present = false;
    configs.push(odd);
    for cfg in configs {
        let text = to_ron(&cfg);
        let back = parse_str("round-trip.ron", &text).unwrap_or_else(|e| panic!("{e}\n{text}"));
        assert_eq!(back, cfg);
        assert_eq!(to_ron(&back), text, "to_ron is a fixed point");
        // show's comments must not change what the text means.
        let shown = show(&cfg);
        let back = parse_str("show.ron", &shown).unwrap_or_else(|e| panic!("{e}\n{shown}"));
        assert_eq!(back, cfg);
    }
}

#[test]
fn show_puts_each_fields_provenance_above_it() {
    let shown = show(&default_config());
    let lines: Vec<&str> = shown.lines().collect();
    let latency = lines
        .iter()
        .position(|l| l.trim_start().starts_with("latency_cycles: 8,"))
        .expect("latency_cycles is shown");
    let entry = provenance::lookup("renderer.qee.latency_cycles").expect("has provenance");
    // An assumed field's plausible range follows its source.
    assert_eq!(
        lines[latency - 1].trim(),
        format!(
            "/// [assumed] {}; plausible range 4 to 16 (half to twice the estimate)",
            entry.source
        )
    );
    let channels = lines
        .iter()
        .position(|l| l.trim_start().starts_with("channels: 4,"))
        .expect("channels is shown");
    assert!(
        lines[channels - 1].contains("/// [seed] TR89-002"),
        "{shown}"
    );
    for tag in [
        "[paper]",
        "[seed]",
        "[secondary]",
        "[lineage]",
        "[assumed]",
        "[choice]",
    ] {
        assert!(shown.contains(tag), "{tag} missing from show output");
    }
    assert!(shown.contains(&config_hash(&default_config())));
}

#[test]
fn config_hash_is_16_hex_digits_and_tracks_the_effective_config() {
    let seed = default_config();
    let h = config_hash(&seed);
    assert_eq!(h.len(), 16);
    assert!(
        h.chars()
            .all(|c| c.is_ascii_hexdigit() && !c.is_ascii_uppercase())
    );
    assert_eq!(h, config_hash(&seed.clone()));
    let mut other = seed.clone();
    other.renderer.qee.latency_cycles += 1;
    assert_ne!(config_hash(&other), h);
    assert_ne!(config_hash(&load("pxpl5-1989.ron")), h);
}

// ---------------------------------------------------------------------------------------------
// Syntax and type errors.

const SMALL: &str = "(
    name: \"bad\",
    gp: (count: 1),
    ring: (
        channels: 4,
    ),
    renderer: (count: 1),
)
";

fn syntax_error(text: &str) -> (String, usize, usize, String) {
    match parse_str("machine-configs/bad.ron", text) {
        Err(ConfigError::Syntax(e)) => (e.to_string(), e.line, e.col, e.message.clone()),
        Err(e) => panic!("expected a syntax error, got: {e}"),
        Ok(_) => panic!("expected a syntax error, parsed:\n{text}"),
    }
}

#[test]
fn the_small_example_is_valid() {
    parse_str("small.ron", SMALL).unwrap_or_else(|e| panic!("{e}"));
}

#[test]
fn a_misspelled_key_names_file_line_column_line_text_and_the_right_key() {
    let text = SMALL.replace("channels: 4", "chanels: 4");
    let (shown, line, col, message) = syntax_error(&text);
    assert_eq!((line, col), (5, 9), "{shown}");
    assert!(
        shown.starts_with("machine-configs/bad.ron:5:9: "),
        "{shown}"
    );
    assert!(
        shown.contains("        chanels: 4,"),
        "line text missing: {shown}"
    );
    assert!(message.contains("chanels"), "{message}");
    assert!(
        message.contains("`channels`"),
        "expectation missing: {message}"
    );
    // The caret line sits under the key.
    assert!(shown.ends_with("\n  |         ^"), "{shown:?}");
}

#[test]
fn a_misspelled_key_gets_a_suggestion_and_a_label() {
    let text = SMALL.replace("channels: 4", "chanels: 4");
    let err = parse_str("bad.ron", &text).expect_err("typo");
    let rendered = render(&err);
    assert!(rendered.contains("did you mean `channels`?"), "{rendered}");
    assert!(rendered.contains("unknown field `chanels`"), "{rendered}");
}

#[test]
fn a_wrong_type_gives_line_and_column() {
    let text = SMALL.replace("gp: (count: 1)", "gp: (count: \"four\")");
    let (shown, line, col, message) = syntax_error(&text);
    assert_eq!((line, col), (3, 17), "{shown}");
    assert!(
        shown.starts_with("machine-configs/bad.ron:3:17: "),
        "{shown}"
    );
    assert!(message.to_lowercase().contains("integer"), "{message}");
    assert!(shown.contains("gp: (count: \"four\"),"), "{shown}");
}

#[test]
fn a_missing_required_field_gives_line_and_column() {
    let text = SMALL.replace("renderer: (count: 1)", "renderer: (width: 128)");
    let (shown, line, col, message) = syntax_error(&text);
    assert_eq!(line, 7, "{shown}");
    assert!(col > 1, "{shown}");
    assert!(
        shown.starts_with(&format!("machine-configs/bad.ron:7:{col}: ")),
        "{shown}"
    );
    assert!(message.contains("count"), "{message}");
    assert!(shown.contains("renderer: (width: 128),"), "{shown}");
}

#[test]
fn a_missing_section_and_an_unknown_variant_are_reported() {
    let no_ring = SMALL.replace("    ring: (\n        channels: 4,\n    ),\n", "");
    let (_, _, _, message) = syntax_error(&no_ring);
    assert!(message.contains("ring"), "{message}");

    let text = SMALL.replace("channels: 4,", "channels: 4, token_policy: Early,");
    let (shown, line, _, message) = syntax_error(&text);
    assert_eq!(line, 5, "{shown}");
    assert!(message.contains("EarlyRelease"), "{message}");
}

#[test]
fn an_empty_file_is_an_error_at_1_1() {
    let (shown, line, col, _) = syntax_error("");
    assert_eq!((line, col), (1, 1));
    assert!(
        shown.starts_with("machine-configs/bad.ron:1:1: "),
        "{shown}"
    );
    let (_, _, _, _) = syntax_error("   \n\n// only a comment\n");
}

fn render(err: &ConfigError) -> String {
    let mut out = String::new();
    miette::GraphicalReportHandler::new_themed(miette::GraphicalTheme::unicode_nocolor())
        .render_report(&mut out, err)
        .expect("miette renders every error");
    out
}

/// Checks the invariants of any error of `text`: a non-empty Display that starts with the file
/// name, and a label span inside the source on char boundaries.
fn check_error(text: &str, render_it: bool) {
    let Err(err) = parse_str("garbage.ron", text) else {
        return;
    };
    let shown = err.to_string();
    assert!(shown.starts_with("garbage.ron"), "{shown}");
    if let ConfigError::Syntax(e) = &err {
        assert!(e.line >= 1 && e.col >= 1);
        let (start, end) = (e.span.offset(), e.span.offset() + e.span.len());
        assert!(
            end <= text.len(),
            "span {start}..{end} outside {} bytes",
            text.len()
        );
        assert!(text.is_char_boundary(start) && text.is_char_boundary(end));
    }
    if render_it {
        let _ = render(&err);
    }
}

#[test]
fn garbage_never_panics() {
    const PIECES: &[&str] = &[
        "(",
        ")",
        "(",
        ")",
        ":",
        ",",
        ",",
        " ",
        "\n",
        "\r\n",
        "\t",
        "name",
        "gp",
        "ring",
        "renderer",
        "count",
        "channels",
        "chanels",
        "qee",
        "coefficient_format",
        "int_bits",
        "token_policy",
        "EarlyRelease",
        "Some(",
        "\"str\"",
        "\"",
        "'c'",
        "4",
        "-1",
        "0x",
        "1e99",
        "1.5",
        "_1",
        "18446744073709551616",
        "true",
        "[",
        "]",
        "{",
        "}",
        "/*",
        "*/",
        "//",
        "#![enable(implicit_some)]",
        "#!",
        "r#",
        "r\"",
        "b\"",
        "\\",
        "é",
        "∑",
        "\u{0}",
        "\u{feff}",
        "..",
        "MachineConfig",
        "=",
    ];
    let mut rng = pxpl5_geom::rng::Lcg::new(0x2545_f491_4f6c_dd1d);
    let mut next = move || rng.below(1 << 31) as usize;
    for i in 0..600 {
        let len = next() % 40;
        let text: String = (0..len).map(|_| PIECES[next() % PIECES.len()]).collect();
        check_error(&text, i % 10 == 0);
    }
    // Garbage after a valid prefix reaches the deeper parts of the parser.
    for i in 0..300 {
        let cut = next() % EMBEDDED_TEXT.len();
        let cut = (0..=cut)
            .rev()
            .find(|&c| EMBEDDED_TEXT.is_char_boundary(c))
            .unwrap_or(0);
        let tail: String = (0..next() % 8)
            .map(|_| PIECES[next() % PIECES.len()])
            .collect();
        check_error(&format!("{}{tail}", &EMBEDDED_TEXT[..cut]), i % 10 == 0);
    }
}

#[test]
fn every_truncation_of_the_seed_file_is_a_clean_error() {
    for (i, (cut, _)) in EMBEDDED_TEXT.char_indices().enumerate() {
        check_error(&EMBEDDED_TEXT[..cut], i % 97 == 0);
    }
}

#[test]
fn deep_nesting_is_an_error_not_a_stack_overflow() {
    let text = format!("{}{}", "(".repeat(100_000), ")".repeat(100_000));
    check_error(&text, false);
}

// ---------------------------------------------------------------------------------------------
// File errors.

fn scratch_file(name: &str, bytes: &[u8]) -> PathBuf {
    let path = Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    std::fs::write(&path, bytes).expect("write scratch file");
    path
}

#[test]
fn a_missing_file_is_an_io_error_naming_the_path() {
    let path = configs_dir().join("no-such-machine.ron");
    let err = load_file(&path).expect_err("missing file");
    assert!(matches!(err, ConfigError::Io { .. }), "{err:?}");
    assert!(err.to_string().contains("no-such-machine.ron"), "{err}");
}

#[test]
fn a_non_utf8_file_is_an_error_with_its_position() {
    let mut bytes = SMALL.as_bytes().to_vec();
    // Line 2 is `    name: "bad",`; put an invalid byte inside the string.
    let at = SMALL.find("bad").expect("name present");
    bytes[at] = 0xff;
    let path = scratch_file("not-utf8.ron", &bytes);
    let err = load_file(&path).expect_err("invalid UTF-8");
    let shown = err.to_string();
    assert!(matches!(err, ConfigError::NotUtf8 { .. }), "{err:?}");
    assert!(shown.contains("not-utf8.ron:2:12: "), "{shown}");
    assert!(shown.contains("0xff"), "{shown}");
}

#[test]
fn load_file_reports_syntax_errors_under_the_given_path() {
    let path = scratch_file("typo.ron", SMALL.replace("channels", "chanels").as_bytes());
    let err = load_file(&path).expect_err("typo");
    assert!(
        err.to_string()
            .starts_with(&format!("{}:5:9: ", path.display())),
        "{err}"
    );
}

// ---------------------------------------------------------------------------------------------
// Semantic checks: each names its field.

/// The semantic error text of the seed machine changed by `change`.
fn semantic(change: impl FnOnce(&mut MachineConfig)) -> String {
    let mut cfg = default_config();
    change(&mut cfg);
    match validate(&cfg) {
        Ok(()) => panic!("expected a semantic error"),
        Err(errors) => errors
            .iter()
            .map(ToString::to_string)
            .collect::<Vec<_>>()
            .join("\n"),
    }
}

fn assert_names(change: impl FnOnce(&mut MachineConfig), path: &str) {
    let text = semantic(change);
    assert!(
        text.lines().any(|l| l.starts_with(&format!("{path}: "))),
        "{path} not named in:\n{text}"
    );
    assert!(text.contains("(got "), "value missing in:\n{text}");
}

#[test]
fn semantic_error_display_names_file_field_rule_and_value() {
    let text = SMALL.replace("renderer: (count: 1)", "renderer: (count: 0)");
    let err = parse_str("bad.ron", &text).expect_err("zero renderers");
    assert_eq!(
        err.to_string(),
        "bad.ron: renderer.count: must be in 1..=256 (got 0)"
    );
    assert_eq!(err.semantic_errors().len(), 1);
}

#[test]
fn all_semantic_errors_are_reported_one_per_line() {
    let text = SMALL
        .replace("gp: (count: 1)", "gp: (count: 0)")
        .replace("channels: 4", "channels: 0")
        .replace("renderer: (count: 1)", "renderer: (count: 0, width: 100)");
    let err = parse_str("bad.ron", &text).expect_err("several problems");
    let shown = err.to_string();
    let lines: Vec<&str> = shown.lines().collect();
    assert_eq!(lines.len(), 4, "{shown}");
    for path in [
        "gp.count",
        "ring.channels",
        "renderer.count",
        "renderer.width",
    ] {
        assert!(
            lines
                .iter()
                .any(|l| l.starts_with(&format!("bad.ron: {path}: "))),
            "{path} missing:\n{shown}"
        );
    }
    let _ = render(&err);
}

#[test]
fn counts_must_be_at_least_one_and_a_bigger_machine_is_allowed() {
    assert_names(|c| c.gp.count = 0, "gp.count");
    assert_names(|c| c.ring.channels = 0, "ring.channels");
    assert_names(|c| c.renderer.count = 0, "renderer.count");
    // Larger than the paper's machine is a legitimate what-if (up to `MAX_UNITS`).
    let mut big = default_config();
    big.gp.count = 256;
    big.renderer.count = 64;
    big.ring.channels = 16;
    validate(&big).unwrap_or_else(|e| panic!("{e:?}"));
}

#[test]
fn name_must_not_be_empty() {
    assert_names(|c| c.name = "  ".into(), "name");
}

#[test]
fn clocks_must_be_whole_picoseconds() {
    assert_names(|c| c.gp.clock_hz = 0, "gp.clock_hz");
    assert_names(|c| c.gp.clock_hz = 33_333_333, "gp.clock_hz");
    assert_names(|c| c.ring.channel_clock_hz = 0, "ring.channel_clock_hz");
    assert_names(|c| c.ring.channel_clock_hz = 3, "ring.channel_clock_hz");
    assert_names(|c| c.renderer.clock_hz = 0, "renderer.clock_hz");
    assert_names(|c| c.renderer.clock_hz = 7_000_000, "renderer.clock_hz");
    let mut ok = default_config();
    ok.gp.clock_hz = 50_000_000;
    ok.ring.channel_clock_hz = 1;
    ok.renderer.clock_hz = 1_000_000_000_000;
    validate(&ok).unwrap_or_else(|e| panic!("{e:?}"));
}

#[test]
fn ring_limits() {
    assert_names(|c| c.ring.word_bits = 0, "ring.word_bits");
    assert_names(|c| c.ring.word_bits = 65, "ring.word_bits");
    assert_names(|c| c.ring.max_message_words = 0, "ring.max_message_words");
    assert_names(|c| c.ring.queue_words = 1024, "ring.queue_words");
    let text = semantic(|c| c.ring.queue_words = 1024);
    assert!(
        text.contains("ring.max_message_words + ring.header_words"),
        "{text}"
    );
    // No overflow on absurd sizes.
    assert_names(
        |c| {
            c.ring.max_message_words = u32::MAX;
            c.ring.header_words = u32::MAX;
            c.ring.queue_words = u32::MAX;
        },
        "ring.queue_words",
    );
}

#[test]
fn renderer_array_and_memory_limits() {
    assert_names(|c| c.renderer.width = 0, "renderer.width");
    assert_names(|c| c.renderer.width = 100, "renderer.width");
    assert_names(|c| c.renderer.height = 0, "renderer.height");
    assert_names(
        |c| c.renderer.pixel_memory_bits = 0,
        "renderer.pixel_memory_bits",
    );
    assert_names(
        |c| c.renderer.pixel_memory_bits = 4097,
        "renderer.pixel_memory_bits",
    );
    assert_names(|c| c.renderer.flag_registers = 0, "renderer.flag_registers");
    assert_names(
        |c| c.renderer.flag_registers = 65,
        "renderer.flag_registers",
    );
    // Wider and taller than 2^coordinate_bits.
    assert_names(|c| c.renderer.qee.coordinate_bits = 6, "renderer.width");
    assert_names(
        |c| {
            c.renderer.qee.coordinate_bits = 8;
            c.renderer.height = 257;
        },
        "renderer.height",
    );
    let text = semantic(|c| c.renderer.qee.coordinate_bits = 6);
    assert!(text.contains("renderer.qee.coordinate_bits"), "{text}");
    // Non-square arrays are fine.
    let mut wide = default_config();
    wide.renderer.width = 256;
    wide.renderer.height = 1;
    validate(&wide).unwrap_or_else(|e| panic!("{e:?}"));
}

#[test]
fn backing_store_limits() {
    assert_names(
        |c| c.renderer.backing_store_bits = 4080,
        "renderer.backing_store_bits",
    );
    assert_names(
        |c| c.renderer.backing_store.block_bits = 0,
        "renderer.backing_store.block_bits",
    );
    assert_names(
        |c| c.renderer.backing_store.block_bits = 65,
        "renderer.backing_store.block_bits",
    );
    assert_names(
        |c| c.renderer.backing_store.block_cycles = 0,
        "renderer.backing_store.block_cycles",
    );
    let mut none = default_config();
    none.renderer.backing_store_bits = 0;
    validate(&none).unwrap_or_else(|e| panic!("no backing store is a valid what-if: {e:?}"));
}

#[test]
fn qee_limits() {
    assert_names(
        |c| c.renderer.qee.coefficient_format.int_bits = 30,
        "renderer.qee.coefficient_format",
    );
    let wide = semantic(|c| c.renderer.qee.coefficient_format.int_bits = 30);
    assert!(wide.contains("at most 48 bits"), "{wide}");
    assert_names(
        |c| c.renderer.qee.coefficient_format.frac_bits = 41,
        "renderer.qee.coefficient_format.frac_bits",
    );
    // 32-bit coefficients with 16-bit coordinates: 32 + 2 * 16 + 3 = 67 > 64.
    let tree = semantic(|c| c.renderer.qee.coordinate_bits = 16);
    assert!(
        tree.contains("renderer.qee.coefficient_format")
            && tree.contains("renderer.qee.coordinate_bits"),
        "both fields must be named:\n{tree}"
    );
    assert!(tree.contains("64"), "{tree}");
    assert_names(
        |c| c.renderer.qee.coordinate_bits = 0,
        "renderer.qee.coordinate_bits",
    );
    assert_names(
        |c| c.renderer.qee.coordinate_bits = 17,
        "renderer.qee.coordinate_bits",
    );
    assert_names(
        |c| c.renderer.qee.max_result_bits = 0,
        "renderer.qee.max_result_bits",
    );
    assert_names(
        |c| c.renderer.qee.max_result_bits = 65,
        "renderer.qee.max_result_bits",
    );
    // Absurd widths are reported, not overflowed.
    assert_names(
        |c| {
            c.renderer.qee.coefficient_format.int_bits = u32::MAX;
            c.renderer.qee.coefficient_format.frac_bits = u32::MAX;
        },
        "renderer.qee.coefficient_format",
    );
    // The widest allowed tree: 48-bit coefficients with 6-bit coordinates (48 + 12 + 3 = 63).
    let mut edge = default_config();
    edge.renderer.qee.coefficient_format.int_bits = 7;
    edge.renderer.qee.coefficient_format.frac_bits = 40;
    edge.renderer.qee.coordinate_bits = 7;
    edge.renderer.width = 128;
    validate(&edge).expect_err("48 + 14 + 3 = 65 > 64");
    edge.renderer.qee.coordinate_bits = 6;
    edge.renderer.width = 64;
    edge.renderer.height = 64;
    validate(&edge).unwrap_or_else(|e| panic!("{e:?}"));
}

#[test]
fn cycle_costs_that_scale_work_must_not_be_zero() {
    for (path, change) in [
        (
            "renderer.cycles.per_bit",
            (|c: &mut MachineConfig| c.renderer.cycles.per_bit = 0) as fn(&mut MachineConfig),
        ),
        ("renderer.cycles.logic", |c| c.renderer.cycles.logic = 0),
        ("renderer.cycles.multiply_per_bit_pair", |c| {
            c.renderer.cycles.multiply_per_bit_pair = 0
        }),
        ("renderer.cycles.readback_per_bit", |c| {
            c.renderer.cycles.readback_per_bit = 0
        }),
    ] {
        assert_names(change, path);
        assert!(
            semantic(change).contains("free"),
            "{path}: the message says why"
        );
    }
    // Fixed overheads may be zero.
    let mut cheap = default_config();
    cheap.renderer.cycles.igc_overhead = 0;
    cheap.renderer.cycles.alu_setup = 0;
    cheap.renderer.cycles.set_origin = 0;
    cheap.renderer.cycles.backing_store_issue = 0;
    validate(&cheap).unwrap_or_else(|e| panic!("{e:?}"));
}

#[test]
fn frame_buffer_limits() {
    assert_names(|c| c.frame_buffer.width = 0, "frame_buffer.width");
    assert_names(|c| c.frame_buffer.height = 0, "frame_buffer.height");
    assert_names(
        |c| c.frame_buffer.bits_per_pixel = 0,
        "frame_buffer.bits_per_pixel",
    );
    assert_names(
        |c| c.frame_buffer.bits_per_pixel = 33,
        "frame_buffer.bits_per_pixel",
    );
}

// ---------------------------------------------------------------------------------------------
// Provenance: no parameter undocumented.

/// Dotted paths of the leaves of a parsed RON value (structs become maps; anything else is a
/// leaf).
fn leaf_paths(value: &ron::Value, prefix: &str, out: &mut Vec<String>) {
    match value {
        ron::Value::Map(map) => {
            for (key, inner) in map.iter() {
                let ron::Value::String(key) = key else {
                    panic!("non-string key {key:?} under {prefix}");
                };
                let path = if prefix.is_empty() {
                    key.clone()
                } else {
                    format!("{prefix}.{key}")
                };
                leaf_paths(inner, &path, out);
            }
        }
        _ => out.push(prefix.to_string()),
    }
}

#[test]
fn every_leaf_field_has_exactly_one_provenance_entry() {
    let value: ron::Value =
        ron::from_str(&to_ron(&default_config())).expect("to_ron parses as a ron::Value");
    let mut leaves = Vec::new();
    leaf_paths(&value, "", &mut leaves);
    assert!(leaves.len() > 40, "walked too few leaves: {leaves:?}");
    for leaf in &leaves {
        let n = PROVENANCE.iter().filter(|e| e.path == leaf).count();
        assert_eq!(n, 1, "{leaf} has {n} provenance entries");
    }
    for entry in PROVENANCE {
        assert!(
            leaves.iter().any(|l| l == entry.path),
            "provenance entry {} is not a field",
            entry.path
        );
        assert!(
            !entry.source.trim().is_empty(),
            "{} has no source",
            entry.path
        );
    }
    // Only labels are choices; everything else is a hardware parameter with a source tag.
    for entry in PROVENANCE.iter().filter(|e| e.tag == Tag::Choice) {
        assert!(
            ["name", "description"].contains(&entry.path),
            "{}",
            entry.path
        );
    }
}

/// Every `[assumed]` field, and only those, has a plausible range (`pxpl5 sensitivity` moves it
/// across), with the default inside it; each end as a config file writes it.
#[test]
fn every_assumed_field_has_a_plausible_range_about_its_default() {
    let value: ron::Value =
        ron::from_str(&to_ron(&default_config())).expect("to_ron parses as a ron::Value");
    let default_of = |path: &str| -> String {
        let mut v = &value;
        for part in path.split('.') {
            let ron::Value::Map(m) = v else {
                panic!("{path}: not a section at {part}")
            };
            v = m
                .iter()
                .find(|(k, _)| **k == ron::Value::String(part.to_string()))
                .map(|(_, x)| x)
                .unwrap_or_else(|| panic!("{path}: no {part}"));
        }
        match v {
            ron::Value::Number(n) => n.into_f64().to_string(),
            ron::Value::String(s) => s.clone(),
            // A unit enum variant reads back as a unit: its name is in the text.
            _ => {
                let leaf = path.rsplit('.').next().unwrap_or(path);
                let text = to_ron(&default_config());
                let line = text
                    .lines()
                    .find(|l| l.trim().starts_with(&format!("{leaf}:")))
                    .unwrap_or_else(|| panic!("{path}: not in the text"));
                line.split(':')
                    .nth(1)
                    .unwrap_or("")
                    .trim()
                    .trim_end_matches(',')
                    .to_string()
            }
        }
    };
    let mut ranged = 0;
    for entry in PROVENANCE {
        match (entry.tag, entry.range) {
            (Tag::Assumed, Some(r)) => {
                ranged += 1;
                assert!(!r.why.is_empty(), "{}", entry.path);
                let d = default_of(entry.path);
                match (
                    r.low.parse::<f64>(),
                    r.high.parse::<f64>(),
                    d.parse::<f64>(),
                ) {
                    (Ok(lo), Ok(hi), Ok(d)) => assert!(
                        lo <= d && d <= hi && lo < hi,
                        "{}: default {d} outside {lo}..{hi}",
                        entry.path
                    ),
                    // An enum: the default is one end, the other its alternative.
                    _ => assert!(
                        (d == r.low || d == r.high) && r.low != r.high,
                        "{}: default {d}, range {} to {}",
                        entry.path,
                        r.low,
                        r.high
                    ),
                }
            }
            (Tag::Assumed, None) => panic!("{} is assumed but has no plausible range", entry.path),
            (_, Some(_)) => panic!("{} has a range but is not assumed", entry.path),
            (_, None) => {}
        }
    }
    assert!(ranged >= 30, "only {ranged} ranges");
    // `config show` writes each range beside the field's source.
    assert!(
        pxpl5_config::show(&default_config())
            .contains("plausible range 1 to 4 (a register per node up to a short pipeline)")
    );
}

/// Leaf fields of a config file with the comment text that documents each: the comment on its
/// line plus the comment block directly above it.
fn documented_fields(text: &str) -> BTreeMap<String, (String, String)> {
    let mut fields = BTreeMap::new();
    let mut stack: Vec<String> = Vec::new();
    let mut block = String::new();
    for line in text.lines() {
        let line = line.trim();
        if let Some(comment) = line.strip_prefix("//") {
            block.push_str(comment);
            block.push('\n');
            continue;
        }
        let (code, comment) = line.split_once("//").unwrap_or((line, ""));
        let code = code.trim();
        if let Some((key, value)) = code.split_once(':') {
            let value = value.trim().trim_end_matches(',').trim().to_string();
            if value == "(" {
                stack.push(key.trim().to_string());
            } else {
                let mut path = stack.clone();
                path.push(key.trim().to_string());
                fields.insert(path.join("."), (value, format!("{block}{comment}")));
            }
        } else if code.starts_with(')') {
            stack.pop();
        }
        block.clear();
    }
    fields
}

#[test]
fn config_files_write_every_field_and_tag_it() {
    let defaults = to_ron(&default_config());
    let value: ron::Value = ron::from_str(&defaults).expect("parses");
    let mut leaves = Vec::new();
    leaf_paths(&value, "", &mut leaves);
    for path in config_files() {
        let file = path.display().to_string();
        let text = std::fs::read_to_string(&path).expect("readable");
        assert!(text.starts_with("// "), "{file} must start with a comment");
        let fields = documented_fields(&text);
        for leaf in &leaves {
            let Some((_, comment)) = fields.get(leaf) else {
                panic!("{file}: {leaf} is not written out");
            };
            let entry = provenance::lookup(leaf).expect("checked above");
            let tagged = [
                "[paper]",
                "[seed]",
                "[secondary]",
                "[lineage]",
                "[assumed]",
                "[choice]",
            ]
            .iter()
            .any(|t| comment.contains(t));
            assert!(tagged, "{file}: {leaf} has no provenance tag: {comment:?}");
            if entry.tag == Tag::Assumed {
                assert!(
                    comment.contains("[assumed]"),
                    "{file}: {leaf} is an assumption and must say so: {comment:?}"
                );
            }
            if entry.tag != Tag::Choice {
                assert!(
                    comment.contains("docs/hardware.md"),
                    "{file}: {leaf} must cite its row of docs/hardware.md: {comment:?}"
                );
            }
        }
        assert_eq!(fields.len(), leaves.len(), "{file}: {:?}", fields.keys());
    }
}

#[test]
fn hop_latency_must_be_at_least_one_clock() {
    let mut cfg = pxpl5_config::default_config();
    cfg.ring.hop_latency_cycles = 0;
    let errors = pxpl5_config::validate(&cfg).unwrap_err();
    assert!(
        errors.iter().any(|e| e.path == "ring.hop_latency_cycles"),
        "{errors:?}"
    );
}

// ---------------------------------------------------------------------------------------------
// Bounds that keep a valid config runnable (issue 9): costs, counts, formats, frame buffer.

#[test]
fn costs_are_bounded_so_a_charge_fits_simulated_time() {
    use pxpl5_config::MAX_COST_CYCLES;
    use pxpl5_tests::fuzzing::{CONFIG_FIELDS, is_cost};
    assert_eq!(MAX_COST_CYCLES, u64::from(u32::MAX));
    let mut wide = 0;
    for (path, set) in CONFIG_FIELDS.iter().filter(|(path, _)| is_cost(path)) {
        let mut cfg = default_config();
        set(&mut cfg, MAX_COST_CYCLES);
        validate(&cfg).unwrap_or_else(|e| panic!("{path} at the limit: {e:?}"));
        // A 64-bit field beyond the limit is refused; a 32-bit one cannot be beyond it.
        set(&mut cfg, u64::MAX);
        if let Err(errors) = validate(&cfg) {
            wide += 1;
            assert_eq!(errors.len(), 1, "{errors:?}");
            assert_eq!(errors[0].path, *path);
            assert_eq!(errors[0].value, u64::MAX.to_string());
            assert!(errors[0].rule.contains("4294967295"), "{}", errors[0]);
        }
    }
    // Every u64 cost: ten of the GP, eight of the Renderer, the backing store's block.
    assert_eq!(wide, 19);
}

#[test]
fn counts_formats_and_frame_buffer_are_bounded() {
    use pxpl5_config::{MAX_CHANNELS, MAX_FRAME_BUFFER_SIDE, MAX_UNITS};
    let check = |change: fn(&mut MachineConfig), path: &str, rule: &str| {
        let mut cfg = default_config();
        change(&mut cfg);
        let errors = validate(&cfg).expect_err(path);
        assert!(
            errors
                .iter()
                .any(|e| e.path == path && e.rule.contains(rule)),
            "{path}: {errors:?}"
        );
    };
    check(|c| c.gp.count = u32::MAX, "gp.count", "1..=256");
    check(|c| c.gp.count = 10_000, "gp.count", "1..=256");
    check(|c| c.renderer.count = u32::MAX, "renderer.count", "1..=256");
    check(|c| c.ring.channels = u32::MAX, "ring.channels", "1..=64");
    check(
        |c| c.renderer.qee.coefficient_format.int_bits = 0,
        "renderer.qee.coefficient_format.int_bits",
        "at least 1",
    );
    check(
        |c| c.frame_buffer.width = 65_537,
        "frame_buffer.width",
        "1..=65536",
    );
    // The limits themselves are accepted (the memory a machine needs is checked apart).
    let mut cfg = default_config();
    cfg.gp.count = MAX_UNITS;
    cfg.renderer.count = MAX_UNITS;
    cfg.ring.channels = MAX_CHANNELS;
    cfg.frame_buffer.width = MAX_FRAME_BUFFER_SIDE;
    cfg.frame_buffer.height = MAX_FRAME_BUFFER_SIDE;
    cfg.renderer.qee.coefficient_format.int_bits = 1;
    validate(&cfg).unwrap_or_else(|e| panic!("{e:?}"));
}

// ---------------------------------------------------------------------------------------------
// Reports of huge inputs stay small and never panic (issue 9).

/// The Display and the miette report of the error of `text`, checked to be under `limit` bytes.
fn bounded_reports(text: &str, limit: usize) -> (String, String) {
    let err = parse_str("huge.ron", text).expect_err("an error");
    let shown = err.to_string();
    let rendered = render(&err);
    assert!(shown.len() < limit, "Display is {} bytes", shown.len());
    assert!(rendered.len() < limit, "report is {} bytes", rendered.len());
    (shown, rendered)
}

#[test]
fn a_ten_megabyte_line_is_quoted_in_a_window() {
    let text = format!("(name: \"x\", {}zzz)", " ".repeat(10_000_000));
    let (shown, rendered) = bounded_reports(&text, 4_000);
    assert!(shown.starts_with("huge.ron:1:10000013: "), "{shown}");
    assert!(shown.contains("zzz)"), "{shown}");
    assert!(rendered.contains("[huge.ron:1:10000013]"), "{rendered}");
    assert!(rendered.contains("unknown field `zzz`"), "{rendered}");
}

#[test]
fn an_error_at_the_end_of_a_megabyte_line_renders_without_panicking() {
    let text = format!(
        "(name: \"{}\", gp: (count: 1), ring: (channels: 1), renderer: (count: 1), oops: 1)",
        "a".repeat(1_000_000)
    );
    let (shown, rendered) = bounded_reports(&text, 4_000);
    assert!(shown.contains("oops: 1)"), "{shown}");
    assert!(rendered.contains("unknown field `oops`"), "{rendered}");
    // The caret sits under the key: the line after the quoted one ends in spaces and a caret,
    // as many chars in as `oops` is in the quoted text.
    let lines: Vec<&str> = shown.lines().collect();
    let quoted = lines[lines.len() - 2];
    let caret = lines[lines.len() - 1];
    let at = |s: &str, pat: &str| s.char_indices().position(|(i, _)| s[i..].starts_with(pat));
    assert_eq!(at(quoted, "oops"), at(caret, "^"), "{shown}");
}

#[test]
fn a_megabyte_key_of_multibyte_chars_is_shortened_everywhere() {
    for (prefix, key) in [
        ("(", "é".repeat(500_000)),
        ("(name: \"x\", ", "∑é".repeat(300_000)),
        (
            "(gp: (count: 1), ",
            format!("a{}", "\u{1F600}".repeat(200_000)),
        ),
    ] {
        let text = format!("{prefix}{key}: 1)");
        let (shown, rendered) = bounded_reports(&text, 8_000);
        assert!(shown.contains("..."), "{shown}");
        assert!(rendered.contains("..."), "{rendered}");
    }
}

#[test]
fn a_huge_semantic_error_list_is_cut() {
    let (name, value) = (
        "n".repeat(100_000),
        format!("{:?}", vec![(1.0, 2.0, 3.0); 10_000]),
    );
    let errors: Vec<pxpl5_config::SemanticError> = (0..200)
        .map(|i| pxpl5_config::SemanticError {
            path: format!("surfaces[{i}] ({name})"),
            value: value.clone(),
            rule: "must be fine".into(),
        })
        .collect();
    let err = ConfigError::Semantic {
        kind: pxpl5_config::FileKind::RadiosityScene,
        file: "s.ron".into(),
        errors,
    };
    let shown = err.to_string();
    assert!(shown.len() < 60_000, "{} bytes", shown.len());
    assert_eq!(shown.lines().count(), 51);
    assert!(
        shown.ends_with("s.ron: ... and 150 more problems"),
        "{}",
        &shown[shown.len() - 100..]
    );
    let rendered = render(&err);
    assert!(rendered.len() < 80_000, "{} bytes", rendered.len());
}
