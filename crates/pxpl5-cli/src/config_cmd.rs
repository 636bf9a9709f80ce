//! `pxpl5 config check` and `pxpl5 config show`, and the loading of `--config FILE` shared by
//! every subcommand, with the host-memory check of the machine (`--memory-limit`).

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use pxpl5_config::{ConfigError, MachineConfig};
use pxpl5_machine::memory::{self, MemoryEstimate, format_size};
use tracing::field;

use crate::UserError;
use crate::output::{errln, out, outln};

/// The host memory limit of this process (`--memory-limit`), set once by `main`.
static MEMORY_LIMIT: OnceLock<u64> = OnceLock::new();

/// Set the host memory limit every machine config is checked against (`--memory-limit`). The
/// first call wins: there is one per process.
pub fn set_memory_limit(bytes: u64) {
    // A second call would be a bug in `main`; the first value stays.
    let _ = MEMORY_LIMIT.set(bytes);
}

pub fn memory_limit() -> u64 {
    MEMORY_LIMIT.get().copied().unwrap_or(memory::DEFAULT_LIMIT)
}

/// The host memory the machine of `cfg` needs, or the error naming the config `origin`, the
/// estimate, the limit and how to raise it.
fn check_memory(origin: &str, cfg: &MachineConfig) -> Result<MemoryEstimate, String> {
    memory::check(cfg, memory_limit()).map_err(|e| {
        let raise = match e.suggested_limit() {
            Some(size) => {
                format!("; raise the limit with --memory-limit {size} if this host has the memory")
            }
            None => "; no host has that much: make the machine smaller".to_string(),
        };
        format!("{origin}: {e}{raise}")
    })
}

/// The config of `--config FILE`, or the embedded seed machine, checked against the host
/// memory limit. Its name and hash are recorded in the current span (the command's, see `main`).
pub fn load(file: Option<&Path>) -> Result<MachineConfig, UserError> {
    let cfg = load_unchecked(file)?;
    let origin = file.map_or(pxpl5_config::EMBEDDED_NAME.to_string(), |p| {
        p.display().to_string()
    });
    check_memory(&origin, &cfg).map_err(UserError)?;
    Ok(cfg)
}

/// Check `cfg`, a config changed after loading (`origin` names where: e.g. the sweep's point),
/// as a file is checked: [`pxpl5_config::check`] and the host memory limit.
pub fn check_changed(origin: &str, cfg: &MachineConfig) -> Result<(), UserError> {
    pxpl5_config::check(origin, cfg).map_err(report)?;
    check_memory(origin, cfg).map_err(UserError)?;
    Ok(())
}

/// [`load`] without the host memory check.
fn load_unchecked(file: Option<&Path>) -> Result<MachineConfig, UserError> {
    let cfg = match file {
        None => pxpl5_config::default_config(),
        Some(path) => pxpl5_config::load_file(path).map_err(report)?,
    };
    let span = tracing::Span::current();
    if !span.is_disabled() {
        span.record("config", field::display(&cfg.name));
        span.record("hash", field::display(pxpl5_config::config_hash(&cfg)));
    }
    Ok(cfg)
}

/// A config error as the user sees it: miette's report (source line, column marker, help).
pub fn report(e: ConfigError) -> UserError {
    UserError(format!("{:?}", miette::Report::new(e)))
}

/// Check each file; a failing stdout stops the report, not the checks, whose verdict wins.
pub fn check(files: &[PathBuf]) -> Result<(), UserError> {
    let mut bad = Vec::new();
    let mut printed = Ok(());
    for f in files {
        let loaded = pxpl5_config::load_file(f)
            .map_err(|e| report(e).0)
            .and_then(|cfg| {
                check_memory(&f.display().to_string(), &cfg)?;
                Ok(cfg)
            });
        match loaded {
            Ok(cfg) => {
                if printed.is_ok() {
                    printed = outln!(
                        "{}: ok ({}, hash {})",
                        f.display(),
                        cfg.name,
                        pxpl5_config::config_hash(&cfg)
                    );
                }
            }
            Err(message) => {
                errln!("{message}");
                bad.push(f.display().to_string());
            }
        }
    }
    if bad.is_empty() {
        printed
    } else {
        Err(UserError(format!(
            "{} of {} config files are invalid: {}",
            bad.len(),
            files.len(),
            bad.join(", ")
        )))
    }
}

/// Print the effective config after a comment with the host memory its machine needs (shown
/// even when it is more than the limit, which the comment then says).
pub fn show(file: Option<&Path>) -> Result<(), UserError> {
    let cfg = load_unchecked(file)?;
    let estimate = memory::estimate(&cfg);
    let limit = memory_limit();
    let verdict = if estimate.total() > limit {
        "more than the limit: commands that run it refuse it unless --memory-limit is raised"
    } else {
        "within the limit"
    };
    out!(
        "// Host memory: the simulator needs an estimated {estimate}.\n\
         // The limit is {} (--memory-limit; default {}): {verdict}.\n{}",
        format_size(limit),
        format_size(memory::DEFAULT_LIMIT),
        pxpl5_config::show(&cfg)
    )
}
