//! The machine configuration of the Pixel-Planes 5 simulator.
//!
//! The simulator's core crates take a [`MachineConfig`] (or one of its sections) as plain Rust
//! data, so the file format can change here without touching the simulator. The programs own
//! their scene formats and load them through this crate's RON loader ([`read_text`],
//! [`parse_checked`]), so every file's errors are reported alike, naming the kind of file.
//!
//! Configs are [RON](https://docs.rs/ron) files in `machine-configs/`. The structural fields
//! (the config's `name` and the counts of GPs, ring channels and Renderers) are required in every
//! file, because no source fixes them; every timing and format field has a default taken from
//! `docs/hardware.md`, each tagged with where it comes from (see [`provenance`]). The seed's
//! machine, `machine-configs/seed-tr89-002.ron`, is embedded in the binary ([`EMBEDDED_TEXT`],
//! [`default_config`]) so the simulator runs without any file.
//!
//! Loading is two steps, both reported through [`ConfigError`]: RON parsing (syntax, types,
//! unknown or missing fields, reported with file, line, column and the offending line) and
//! [`validate`] (semantic limits, all problems at once, each naming its dotted field path).
//! [`to_ron`] prints the effective config with every default resolved, [`show`] the same with each
//! field's provenance, and [`config_hash`] a short fingerprint of the effective config for reports.

mod error;
pub mod provenance;
// The schema's docs tag fields as `[paper]`, `[seed]`, ...: provenance tags, not links.
#[allow(rustdoc::broken_intra_doc_links)]
mod schema;
mod validate;

use std::path::Path;

use sha2::{Digest, Sha256};

pub use error::{ConfigError, FileKind, SemanticError, SyntaxError};
pub use provenance::{PROVENANCE, PlausibleRange, Provenance, Tag};
pub use schema::*;
pub use validate::{MAX_CHANNELS, MAX_COST_CYCLES, MAX_FRAME_BUFFER_SIDE, MAX_UNITS, validate};

/// File name of the embedded seed machine, used as the source name in its error reports.
pub const EMBEDDED_NAME: &str = "seed-tr89-002.ron";

/// The text of `machine-configs/seed-tr89-002.ron`, compiled in so the default machine needs no
/// file at run time.
pub const EMBEDDED_TEXT: &str = include_str!("../../../machine-configs/seed-tr89-002.ron");

/// Picoseconds per second: the simulator's time unit is the picosecond, so every clock must divide
/// it exactly (see [`validate`]).
pub const PS_PER_SECOND: u64 = 1_000_000_000_000;

/// The seed's machine (TR89-002), parsed from [`EMBEDDED_TEXT`].
///
/// # Panics
/// Never in a released build: the embedded file is parsed and validated by this crate's tests.
pub fn default_config() -> MachineConfig {
    parse_str(EMBEDDED_NAME, EMBEDDED_TEXT)
        .expect("the embedded seed-tr89-002.ron is tested to parse and validate")
}

/// Reads, parses and validates a machine config file.
///
/// The file's path (as given) names the source in every error. A file that is not UTF-8 is an
/// error ([`ConfigError::NotUtf8`]) that points at the first invalid byte.
pub fn load_file(path: &Path) -> Result<MachineConfig, ConfigError> {
    let (shown, text) = read_text(FileKind::MachineConfig, path)?;
    parse_str(&shown, &text)
}

/// The text of a RON file of kind `kind`, and its path as given (it names the source in every
/// error); a file that is not UTF-8 is an error pointing at the first invalid byte.
pub fn read_text(kind: FileKind, path: &Path) -> Result<(String, String), ConfigError> {
    let shown = path.display().to_string();
    let bytes = std::fs::read(path).map_err(|source| ConfigError::Io {
        kind,
        path: shown.clone(),
        source,
    })?;
    match String::from_utf8(bytes) {
        Ok(text) => Ok((shown, text)),
        Err(e) => Err(ConfigError::not_utf8(
            kind,
            &shown,
            e.as_bytes(),
            e.utf8_error(),
        )),
    }
}

/// Parse RON text of kind `kind` into `T` and run `check` on it: syntax and type errors with
/// file, line and column, semantic errors with their field paths, all named by `file_name`.
pub fn parse_checked<T: serde::de::DeserializeOwned>(
    kind: FileKind,
    file_name: &str,
    text: &str,
    check: impl FnOnce(&T) -> Result<(), Vec<SemanticError>>,
) -> Result<T, ConfigError> {
    let value: T = ron::Options::default()
        .from_str(text)
        .map_err(|e| ConfigError::syntax(file_name, text, &e))?;
    check(&value).map_err(|errors| ConfigError::Semantic {
        kind,
        file: file_name.to_string(),
        errors,
    })?;
    Ok(value)
}

/// Parses and validates a machine config held in memory; `file_name` names it in errors.
pub fn parse_str(file_name: &str, text: &str) -> Result<MachineConfig, ConfigError> {
    parse_checked(FileKind::MachineConfig, file_name, text, validate)
}

/// Runs [`validate`] and wraps its findings in a [`ConfigError::Semantic`] naming `origin` (a file
/// name, or e.g. `"command line"` for a config changed after loading).
pub fn check(origin: &str, cfg: &MachineConfig) -> Result<(), ConfigError> {
    validate(cfg).map_err(|errors| ConfigError::Semantic {
        kind: FileKind::MachineConfig,
        file: origin.to_string(),
        errors,
    })
}

/// The pretty-printer settings of [`to_ron`] and [`show`], fixed explicitly (rather than left to
/// ron's defaults, whose line ending depends on the OS) so that [`config_hash`] is the same on
/// every machine.
fn pretty() -> ron::ser::PrettyConfig {
    ron::ser::PrettyConfig::new()
        .new_line("\n")
        .indentor("    ")
        .separator(" ")
        .struct_names(false)
}

/// The effective config as pretty RON, every default resolved, without struct names; it parses
/// back (with [`parse_str`]) to an equal [`MachineConfig`].
pub fn to_ron(cfg: &MachineConfig) -> String {
    // Serializing plain structs, integers, enums and strings cannot fail in ron.
    ron::Options::default()
        .to_string_pretty(cfg, pretty())
        .expect("a MachineConfig always serializes to RON")
}

/// The effective config as RON with each field's provenance (tag and source, from
/// [`PROVENANCE`]) as a `///` comment line above it, after a short header.
///
/// The comments are written by ron's serializer itself (its path metadata), so they stay attached
/// to the right fields whatever the values are; the output still parses back to `cfg`.
pub fn show(cfg: &MachineConfig) -> String {
    let mut config = pretty();
    config.path_meta = Some(provenance::path_meta());
    let body = ron::Options::default()
        .to_string_pretty(cfg, config)
        .expect("a MachineConfig always serializes to RON");
    format!(
        "// Effective machine config `{}` (hash {}), every default resolved.\n\
         // Above each field: its provenance tag and source, for the field's default value;\n\
         // a config file's own comments say where its values come from.\n\
         // Tags: [paper] Fuchs et al. SIGGRAPH '89; [seed] Goldfeather TR89-002; [secondary] later\n\
         // descriptions; [lineage] Pixel-Planes 4; [assumed] no source found; [choice] not hardware.\n\
         {body}\n",
        cfg.name.replace('\n', " "),
        config_hash(cfg),
    )
}

/// A fingerprint of the effective config: the first 16 lowercase hex digits (64 bits) of the
/// SHA-256 of [`to_ron`]`(cfg)`. Two configs that differ only in what a file leaves to defaults
/// hash the same; any changed value (name and description included) changes it.
pub fn config_hash(cfg: &MachineConfig) -> String {
    let digest = Sha256::digest(to_ron(cfg).as_bytes());
    digest.iter().take(8).map(|b| format!("{b:02x}")).collect()
}
