//! Everything the `pxpl5` command prints goes through here: its report ([`out!`], [`outln!`]) and
//! its messages on stderr ([`errln!`]). The tidy test forbids `println!`, `print!`, `eprintln!`
//! and `eprint!` in this crate, which panic when their stream fails.
//!
//! - **A closed stdout is not an error.** When the reader of stdout stops reading (EPIPE, as in
//!   `pxpl5 radiosity | head -1`), the rest of the report is discarded and the command ends as it
//!   would have: exit code 0 when it succeeded. Commands print their report last, after their
//!   files are written, so a closed pipe loses nothing but text no one reads. This is what
//!   ripgrep does, rather than the 141 of a process killed by SIGPIPE: a reader that stops once it
//!   has what it wanted is not a failure.
//! - **Any other failure of stdout is an error naming stdout** (a full device: `> /dev/full`,
//!   a full disk), exit code 2, as for any output the user chose that cannot be written.
//! - **Stderr failures are ignored**: there is nowhere left to report them.
//!
//! Each print is flushed at once, so a failure surfaces at the print that caused it and nothing
//! waits in a buffer for the process's exit, where std would drop its error.

use std::fmt;
use std::io::{self, Write};
use std::sync::atomic::{AtomicBool, Ordering};

use crate::UserError;

/// Set once a write to stdout found the pipe closed: later writes are discarded.
static STDOUT_CLOSED: AtomicBool = AtomicBool::new(false);

/// Print to stdout, as `print!` does, through [`print()`].
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::output::print(format_args!($($arg)*))
    };
}

/// Print a line to stdout, as `println!` does, through [`print()`].
macro_rules! outln {
    () => {
        $crate::output::print(format_args!("\n"))
    };
    ($($arg:tt)*) => {
        $crate::output::print(format_args!("{}\n", format_args!($($arg)*)))
    };
}

/// Print a line to stderr, as `eprintln!` does, ignoring a failure of stderr.
macro_rules! errln {
    ($($arg:tt)*) => {
        $crate::output::print_stderr(format_args!("{}\n", format_args!($($arg)*)))
    };
}

pub(crate) use {errln, out, outln};

/// Write `args` to stdout and flush. A closed pipe is not an error (see the module doc); any
/// other failure is a [`UserError`] naming stdout.
pub fn print(args: fmt::Arguments) -> Result<(), UserError> {
    write_stdout(|w| w.write_fmt(args))
}

/// Write `args` to stderr; a failure is ignored.
pub fn print_stderr(args: fmt::Arguments) {
    let mut err = io::stderr().lock();
    let _ = err.write_fmt(args).and_then(|()| err.flush());
}

fn write_stdout(
    write: impl FnOnce(&mut io::StdoutLock) -> io::Result<()>,
) -> Result<(), UserError> {
    if STDOUT_CLOSED.load(Ordering::Relaxed) {
        return Ok(());
    }
    let mut out = io::stdout().lock();
    match write(&mut out).and_then(|()| out.flush()) {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == io::ErrorKind::BrokenPipe => {
            STDOUT_CLOSED.store(true, Ordering::Relaxed);
            Ok(())
        }
        Err(e) => Err(UserError(format!("stdout: cannot write: {e}"))),
    }
}
