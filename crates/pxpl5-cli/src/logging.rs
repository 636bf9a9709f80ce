//! The simulator's own logs: `tracing` spans and events, written to stderr only (stdout carries
//! the results, which scripts and tests read), at the level `-v`/`-q` choose or, when it is set,
//! the filter in `RUST_LOG`.
//!
//! Levels: errors and warnings by default; `-v` adds info (each simulation's start and end, with
//! simulated time and host seconds, and the command's span), `-vv` debug (a span per machine
//! run), `-vvv` trace; `-q` keeps errors only. A span is logged when it closes, with its host
//! time. `RUST_LOG` takes `tracing_subscriber`'s `EnvFilter` syntax, e.g.
//! `RUST_LOG=info` or `RUST_LOG=pxpl5_machine=debug`.
//!
//! Each log line is written whole, with the progress bar (`watch`), if one is on screen, out of
//! its way, so that a line never lands inside the bar.

use std::env::VarError;
use std::io::{self, Write};

use tracing::level_filters::LevelFilter;
use tracing_subscriber::EnvFilter;
use tracing_subscriber::fmt::{self, format::FmtSpan};

use crate::UserError;

/// The level of `-v` given `verbose` times, or of `-q`.
pub fn level(verbose: u8, quiet: bool) -> LevelFilter {
    match (quiet, verbose) {
        (true, _) => LevelFilter::ERROR,
        (false, 0) => LevelFilter::WARN,
        (false, 1) => LevelFilter::INFO,
        (false, 2) => LevelFilter::DEBUG,
        (false, _) => LevelFilter::TRACE,
    }
}

/// Install the stderr subscriber for this process. A bad `RUST_LOG` is the user's mistake.
pub fn init(verbose: u8, quiet: bool) -> Result<(), UserError> {
    let filter = match std::env::var("RUST_LOG") {
        Ok(spec) if !spec.trim().is_empty() => EnvFilter::builder()
            .parse(&spec)
            .map_err(|e| UserError(format!("RUST_LOG={spec}: {e}")))?,
        Ok(_) | Err(VarError::NotPresent) => {
            EnvFilter::default().add_directive(level(verbose, quiet).into())
        }
        Err(VarError::NotUnicode(_)) => {
            return Err(UserError("RUST_LOG: not valid Unicode".to_string()));
        }
    };
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(|| LogLine(Vec::new()))
        // Host seconds since the start: wall-clock dates would say nothing about a run.
        .with_timer(fmt::time::uptime())
        // A line when a span closes, with the host time spent in it (a command, a machine run).
        .with_span_events(FmtSpan::CLOSE)
        .init();
    Ok(())
}

/// One log event, gathered and written to stderr whole when the subscriber drops it, around the
/// progress bar; a failing stderr is ignored, as for every message.
struct LogLine(Vec<u8>);

impl Write for LogLine {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.0.extend_from_slice(buf);
        Ok(buf.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

impl Drop for LogLine {
    fn drop(&mut self) {
        if !self.0.is_empty() {
            crate::watch::suspend(|| {
                let mut err = io::stderr().lock();
                let _ = err.write_all(&self.0).and_then(|()| err.flush());
            });
        }
    }
}
