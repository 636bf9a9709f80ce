//! The project's own fuzzing, on stable Rust: what every fuzz target shares. Each target is a
//! proptest property in the tests of the crate it exercises (the config parser, the two scene
//! parsers, the machine built from arbitrary configs, the Renderer's command validator, the
//! CLI's value parsers), run by the normal test command with a bounded number of cases from a
//! fixed seed, so that a run is reproducible and quick. A longer run is opt-in (README,
//! "Fuzzing"), in the test profile, whose overflow checks a release build lacks:
//!
//! ```sh
//! PXPL5_FUZZ_CASES=100000 cargo test --workspace fuzz_
//! PXPL5_FUZZ_SEED=7 PXPL5_FUZZ_CASES=100000 cargo test --workspace fuzz_   # other inputs
//! ```
//!
//! Inputs are mutations of the shipped files ([`shipped`], [`mutated`]): byte edits that cut,
//! repeat and splice in pieces of RON (a [`DICTIONARY`] of tokens and extreme numbers), and
//! numbers replaced by extreme ones ([`EXTREME_NUMBERS`]); targets also build values field by
//! field from [`extreme_u64`] and [`extreme_f64`] (a config's through [`CONFIG_FIELDS`]). What
//! every loading target asks of an error is [`loaded`]'s.

use proptest::prelude::*;
use proptest::test_runner::{Config, RngSeed};
use pxpl5_config::{ConfigError, MachineConfig};

/// Cases of a target's run: this variable if set, else the target's bounded default.
pub const CASES_VAR: &str = "PXPL5_FUZZ_CASES";
/// The seed of every target's generator: this variable if set, else [`DEFAULT_SEED`].
pub const SEED_VAR: &str = "PXPL5_FUZZ_SEED";
/// The fixed seed of the bounded run.
pub const DEFAULT_SEED: u64 = 1989;

/// The proptest config of a fuzz target: `default_cases` cases (its bounded run in the test
/// suite, sized to finish well within a minute in a debug build) unless [`CASES_VAR`] says
/// otherwise, from a fixed seed ([`SEED_VAR`]), writing no regression files (a failure prints
/// its minimal input; a test of it belongs next to the fix).
pub fn config(default_cases: u32) -> Config {
    Config {
        cases: env_number(CASES_VAR).unwrap_or(default_cases),
        rng_seed: RngSeed::Fixed(env_number(SEED_VAR).unwrap_or(DEFAULT_SEED)),
        failure_persistence: None,
        ..Config::default()
    }
}

/// The number in environment variable `name`, if it is set to one.
///
/// # Panics
/// If it is set to something else: a long run asked for with a typo must not silently run the
/// short one.
fn env_number<T: std::str::FromStr>(name: &str) -> Option<T> {
    let v = std::env::var(name).ok()?;
    Some(
        v.trim()
            .parse()
            .unwrap_or_else(|_| panic!("{name}={v}: not a whole number")),
    )
}

/// How many of `n` cases of `strategy` (drawn as a target draws them) satisfy `pred`: for the
/// tests that check that a target's inputs reach each of its paths (valid and refused), so that
/// a target cannot pass by testing only one.
pub fn count<S: Strategy>(strategy: &S, n: usize, pred: impl Fn(&S::Value) -> bool) -> usize {
    use proptest::strategy::ValueTree;
    let mut runner = proptest::test_runner::TestRunner::new(config(1));
    (0..n)
        .filter(|_| {
            let case = strategy.new_tree(&mut runner).expect("a case").current();
            pred(&case)
        })
        .count()
}

/// The `.ron` files of `dir` (relative to the workspace root), sorted, with their text.
pub fn shipped(dir: &str) -> Vec<(String, String)> {
    let root = crate::workspace_root().join(dir);
    let mut files: Vec<(String, String)> = std::fs::read_dir(&root)
        .unwrap_or_else(|e| panic!("{}: {e}", root.display()))
        .map(|e| e.expect("a directory entry").path())
        .filter(|p| p.extension().is_some_and(|x| x == "ron"))
        .map(|p| {
            let text = std::fs::read_to_string(&p).expect("a shipped file reads");
            (p.display().to_string(), text)
        })
        .collect();
    files.sort();
    assert!(!files.is_empty(), "no .ron files in {}", root.display());
    files
}

/// Numbers at the edges of every type a file holds, as RON writes them.
pub const EXTREME_NUMBERS: &[&str] = &[
    "0",
    "1",
    "-1",
    "2",
    "255",
    "256",
    "65535",
    "65536",
    "4294967295",
    "4294967296",
    "9223372036854775807",
    "18446744073709551615",
    "18446744073709551616",
    "-9223372036854775808",
    "0.0",
    "-0.0",
    "0.5",
    "1e-6",
    "1e-300",
    "5e-324",
    "1e12",
    "1e13",
    "1e300",
    "1e308",
    "1.7976931348623157e308",
    "-1e308",
    "NaN",
    "inf",
    "-inf",
    "1_000_000_000_000",
    "0x7fffffff",
];

/// Pieces of RON spliced into texts: brackets, separators, names of fields and variants, and
/// extreme numbers.
pub const DICTIONARY: &[&str] = &[
    "(",
    ")",
    "[",
    "]",
    "{",
    "}",
    ",",
    ":",
    " ",
    "\n",
    "\"",
    "'",
    "//",
    "/*",
    "*/",
    "Some(",
    "None",
    "true",
    "false",
    "count",
    "channels",
    "name",
    "camera",
    "surfaces",
    "triangles",
    "vertices",
    "colours",
    "emission",
    "reflectance",
    "fov_y_degrees",
    "near",
    "far",
    "é",
    "\u{1F600}",
    "\u{0}",
    "#![enable(implicit_some)]",
    "r#\"",
    "b\"",
    "\\",
    "_",
    "..",
    "-",
];

/// One edit of a text: where (a fraction of its length), what, and how much.
#[derive(Clone, Debug)]
pub enum Edit {
    /// Cut `len` chars.
    Cut { at: u32, len: u8 },
    /// Insert a piece of the [`DICTIONARY`] or an [`EXTREME_NUMBERS`] entry.
    Insert { at: u32, piece: &'static str },
    /// Replace the number that starts at or after `at` with `number`.
    Number { at: u32, number: String },
    /// Repeat `len` chars.
    Repeat { at: u32, len: u8 },
    /// Cut everything after `at`.
    Truncate { at: u32 },
}

/// A number as RON writes it: an extreme one, an extreme whole one (what most config fields
/// hold), or any integer or float.
fn number() -> impl Strategy<Value = String> {
    prop_oneof![
        2 => prop::sample::select(EXTREME_NUMBERS).prop_map(str::to_string),
        2 => extreme_u64().prop_map(|n| n.to_string()),
        1 => any::<i64>().prop_map(|n| n.to_string()),
        1 => extreme_f64().prop_map(|x| format!("{x:?}")),
    ]
}

fn number_edit() -> impl Strategy<Value = Edit> {
    (any::<u32>(), number()).prop_map(|(at, number)| Edit::Number { at, number })
}

fn edit() -> impl Strategy<Value = Edit> {
    prop_oneof![
        2 => (any::<u32>(), any::<u8>()).prop_map(|(at, len)| Edit::Cut { at, len: len % 40 }),
        3 => (any::<u32>(), prop::sample::select(DICTIONARY)).prop_map(|(at, piece)| {
            Edit::Insert { at, piece }
        }),
        3 => number_edit(),
        1 => (any::<u32>(), any::<u8>()).prop_map(|(at, len)| Edit::Repeat { at, len }),
        1 => any::<u32>().prop_map(|at| Edit::Truncate { at }),
    ]
}

/// `text` with `edits` applied in order, each at its fraction of the text's current length
/// (moved to a char boundary).
pub fn apply(text: &str, edits: &[Edit]) -> String {
    let mut t = text.to_string();
    for e in edits {
        let at_of = |at: u32, t: &str| {
            let mut i = (u64::from(at) * t.len() as u64 / (u64::from(u32::MAX) + 1)) as usize;
            while !t.is_char_boundary(i) {
                i -= 1;
            }
            i
        };
        let chars_from = |i: usize, n: usize, t: &str| {
            t[i..].char_indices().nth(n).map_or(t.len(), |(k, _)| i + k)
        };
        match e {
            Edit::Cut { at, len } => {
                let i = at_of(*at, &t);
                let j = chars_from(i, usize::from(*len), &t);
                t.replace_range(i..j, "");
            }
            Edit::Insert { at, piece } => {
                let i = at_of(*at, &t);
                t.insert_str(i, piece);
            }
            Edit::Number { at, number } => {
                let i = at_of(*at, &t);
                let Some(start) = t[i..].find(|c: char| c.is_ascii_digit()).map(|k| i + k) else {
                    continue;
                };
                let end = t[start..]
                    .find(|c: char| !(c.is_ascii_alphanumeric() || "._+-".contains(c)))
                    .map_or(t.len(), |k| start + k);
                // Take a sign in front with the number.
                let start = if t[..start].ends_with('-') {
                    start - 1
                } else {
                    start
                };
                t.replace_range(start..end, number);
            }
            Edit::Repeat { at, len } => {
                let i = at_of(*at, &t);
                let j = chars_from(i, usize::from(*len), &t);
                let piece = t[i..j].to_string();
                t.insert_str(j, &piece);
            }
            Edit::Truncate { at } => {
                let i = at_of(*at, &t);
                t.truncate(i);
            }
        }
    }
    t
}

/// One of `seeds`' texts with 1 to 6 edits: half the time numbers replaced only (so that the
/// result mostly still parses and reaches the semantic checks and what runs after them), else
/// any edits (reaching the parser's errors).
pub fn mutated(seeds: Vec<(String, String)>) -> impl Strategy<Value = (String, String)> {
    let n = seeds.len();
    let edits = prop_oneof![
        prop::collection::vec(number_edit(), 1..4),
        prop::collection::vec(edit(), 1..6),
    ];
    (0..n, edits).prop_map(move |(k, edits)| {
        let (name, text) = &seeds[k];
        (name.clone(), apply(text, &edits))
    })
}

/// A u64 biased to the edges of the types configs hold (0, 1, powers of two and their
/// neighbours, the maxima of u32 and u64), else small, else anything.
pub fn extreme_u64() -> impl Strategy<Value = u64> {
    prop_oneof![
        2 => prop::sample::select(vec![
            0u64,
            1,
            2,
            63,
            64,
            65,
            4096,
            65_536,
            u64::from(u32::MAX),
            u64::from(u32::MAX) + 1,
            u64::MAX / 2,
            u64::MAX - 1,
            u64::MAX,
        ]),
        1 => (0..63u32).prop_map(|k| 1u64 << k),
        1 => 0u64..300,
        1 => any::<u64>(),
    ]
}

/// An f64 biased to the edges of what scenes hold (0, tiny, subnormal, huge, infinite, NaN),
/// else ordinary, else anything.
pub fn extreme_f64() -> impl Strategy<Value = f64> {
    prop_oneof![
        2 => prop::sample::select(vec![
            0.0,
            -0.0,
            1.0,
            -1.0,
            1e-6,
            1e-300,
            5e-324,
            f64::MIN_POSITIVE,
            1e12,
            1e13,
            1e300,
            f64::MAX,
            f64::MIN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NAN,
        ]),
        1 => -10.0f64..10.0,
        1 => -1e6f64..1e6,
        1 => any::<f64>(),
    ]
}

/// A setter of one numeric config field from a u64 (cut to the field's width).
pub type Setter = fn(&mut MachineConfig, u64);

/// Every numeric field of a machine config: its dotted path and a setter. Fuzz targets set them
/// to extreme values; tests of the limits pick theirs by path (see [`is_cost`]).
pub const CONFIG_FIELDS: &[(&str, Setter)] = &[
    ("gp.count", |c, v| c.gp.count = v as u32),
    ("gp.clock_hz", |c, v| c.gp.clock_hz = v),
    ("gp.costs.vertex_transform", |c, v| {
        c.gp.costs.vertex_transform = v
    }),
    ("gp.costs.clip_test", |c, v| c.gp.costs.clip_test = v),
    ("gp.costs.polygon_setup", |c, v| {
        c.gp.costs.polygon_setup = v
    }),
    ("gp.costs.edge_setup", |c, v| c.gp.costs.edge_setup = v),
    ("gp.costs.command_encode", |c, v| {
        c.gp.costs.command_encode = v
    }),
    ("gp.costs.message_send", |c, v| c.gp.costs.message_send = v),
    ("gp.costs.message_receive", |c, v| {
        c.gp.costs.message_receive = v
    }),
    ("gp.costs.ff_accumulate_per_pixel", |c, v| {
        c.gp.costs.ff_accumulate_per_pixel = v
    }),
    ("gp.costs.w_table_entry", |c, v| {
        c.gp.costs.w_table_entry = v
    }),
    ("gp.costs.radiosity_update_per_patch", |c, v| {
        c.gp.costs.radiosity_update_per_patch = v
    }),
    ("ring.channels", |c, v| c.ring.channels = v as u32),
    ("ring.channel_clock_hz", |c, v| c.ring.channel_clock_hz = v),
    ("ring.word_bits", |c, v| c.ring.word_bits = v as u32),
    ("ring.hop_latency_cycles", |c, v| {
        c.ring.hop_latency_cycles = v as u32
    }),
    ("ring.header_words", |c, v| c.ring.header_words = v as u32),
    ("ring.max_message_words", |c, v| {
        c.ring.max_message_words = v as u32
    }),
    ("ring.queue_words", |c, v| c.ring.queue_words = v as u32),
    ("renderer.count", |c, v| c.renderer.count = v as u32),
    ("renderer.width", |c, v| c.renderer.width = v as u32),
    ("renderer.height", |c, v| c.renderer.height = v as u32),
    ("renderer.pixel_memory_bits", |c, v| {
        c.renderer.pixel_memory_bits = v as u32
    }),
    ("renderer.flag_registers", |c, v| {
        c.renderer.flag_registers = v as u32
    }),
    ("renderer.backing_store_bits", |c, v| {
        c.renderer.backing_store_bits = v as u32
    }),
    ("renderer.clock_hz", |c, v| c.renderer.clock_hz = v),
    ("renderer.qee.coefficient_format.int_bits", |c, v| {
        c.renderer.qee.coefficient_format.int_bits = v as u32
    }),
    ("renderer.qee.coefficient_format.frac_bits", |c, v| {
        c.renderer.qee.coefficient_format.frac_bits = v as u32
    }),
    ("renderer.qee.coordinate_bits", |c, v| {
        c.renderer.qee.coordinate_bits = v as u32
    }),
    ("renderer.qee.max_result_bits", |c, v| {
        c.renderer.qee.max_result_bits = v as u32
    }),
    ("renderer.qee.latency_cycles", |c, v| {
        c.renderer.qee.latency_cycles = v as u32
    }),
    ("renderer.qee.quadratic_extra_cycles", |c, v| {
        c.renderer.qee.quadratic_extra_cycles = v as u32
    }),
    ("renderer.cycles.igc_overhead", |c, v| {
        c.renderer.cycles.igc_overhead = v
    }),
    ("renderer.cycles.logic", |c, v| c.renderer.cycles.logic = v),
    ("renderer.cycles.alu_setup", |c, v| {
        c.renderer.cycles.alu_setup = v
    }),
    ("renderer.cycles.per_bit", |c, v| {
        c.renderer.cycles.per_bit = v
    }),
    ("renderer.cycles.multiply_per_bit_pair", |c, v| {
        c.renderer.cycles.multiply_per_bit_pair = v
    }),
    ("renderer.cycles.backing_store_issue", |c, v| {
        c.renderer.cycles.backing_store_issue = v
    }),
    ("renderer.cycles.readback_per_bit", |c, v| {
        c.renderer.cycles.readback_per_bit = v
    }),
    ("renderer.cycles.set_origin", |c, v| {
        c.renderer.cycles.set_origin = v
    }),
    ("renderer.backing_store.block_bits", |c, v| {
        c.renderer.backing_store.block_bits = v as u32
    }),
    ("renderer.backing_store.block_cycles", |c, v| {
        c.renderer.backing_store.block_cycles = v
    }),
    ("frame_buffer.width", |c, v| c.frame_buffer.width = v as u32),
    ("frame_buffer.height", |c, v| {
        c.frame_buffer.height = v as u32
    }),
    ("frame_buffer.bits_per_pixel", |c, v| {
        c.frame_buffer.bits_per_pixel = v as u32
    }),
];

/// The machine the scene targets draw on: `machine-configs/minimal.ron` with a 256 x 256 frame
/// buffer, four regions, so that a case draws in milliseconds.
pub fn small_machine() -> MachineConfig {
    let path = crate::workspace_root().join("machine-configs/minimal.ron");
    let mut cfg = pxpl5_config::load_file(&path).expect("the shipped minimal config");
    cfg.frame_buffer.width = 256;
    cfg.frame_buffer.height = 256;
    cfg
}

/// Whether the field at `path` is a cost in cycles (at most `pxpl5_config::MAX_COST_CYCLES`).
pub fn is_cost(path: &str) -> bool {
    path.starts_with("gp.costs.")
        || path.starts_with("renderer.cycles.")
        || path.ends_with("_cycles")
}

/// Largest report of a loading error, in bytes: a window of a line, shortened words, at most
/// 50 semantic problems of a few hundred chars each.
pub const MAX_REPORT_BYTES: usize = 64 * 1024;

/// What a fuzz target asks of loading a file named `name`: its value, or (`None`) an error that
/// is a proper report: it names the file, stays under [`MAX_REPORT_BYTES`] however big the input,
/// and renders through miette as the CLI shows it.
pub fn loaded<T>(name: &str, result: Result<T, ConfigError>) -> Result<Option<T>, TestCaseError> {
    let e = match result {
        Ok(value) => return Ok(Some(value)),
        Err(e) => e,
    };
    let shown = e.to_string();
    prop_assert!(shown.starts_with(name), "{}", shown);
    prop_assert!(shown.len() < MAX_REPORT_BYTES, "{} bytes", shown.len());
    let mut rendered = String::new();
    miette::GraphicalReportHandler::new_themed(miette::GraphicalTheme::unicode_nocolor())
        .render_report(&mut rendered, &e)
        .map_err(|_| TestCaseError::fail("miette cannot render the error"))?;
    prop_assert!(
        rendered.len() < MAX_REPORT_BYTES,
        "{} bytes",
        rendered.len()
    );
    Ok(None)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn edits_stay_on_char_boundaries_and_do_what_they_say() {
        let t = "ab é 12.5 ∑";
        assert_eq!(apply(t, &[Edit::Truncate { at: 0 }]), "");
        let numbered = apply(
            t,
            &[Edit::Number {
                at: 0,
                number: "NaN".into(),
            }],
        );
        assert_eq!(numbered, "ab é NaN ∑");
        let cut = apply(
            t,
            &[Edit::Cut {
                at: u32::MAX,
                len: 5,
            }],
        );
        assert_eq!(cut, "ab é 12.5 ");
        let inserted = apply(
            t,
            &[Edit::Insert {
                at: u32::MAX / 2,
                piece: "(",
            }],
        );
        assert_eq!(inserted.chars().count(), t.chars().count() + 1);
        assert_eq!(apply(t, &[Edit::Repeat { at: 0, len: 2 }]), "abab é 12.5 ∑");
    }
}
