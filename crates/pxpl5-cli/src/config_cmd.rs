//! `pxpl5 config check` and `pxpl5 config show`, and the loading of `--config FILE` shared by
//! every subcommand.

use std::path::{Path, PathBuf};

use pxpl5_config::{ConfigError, MachineConfig};
use tracing::field;

use crate::UserError;
use crate::output::{errln, out, outln};

/// The config of `--config FILE`, or the embedded seed machine. Its name and hash are recorded
/// in the current span (the command's, see `main`).
pub fn load(file: Option<&Path>) -> Result<MachineConfig, UserError> {
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
        match pxpl5_config::load_file(f) {
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
            Err(e) => {
                errln!("{}", report(e).0);
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

pub fn show(file: Option<&Path>) -> Result<(), UserError> {
    let cfg = load(file)?;
    out!("{}", pxpl5_config::show(&cfg))
}
