//! Why a command failed, in the three classes its exit code tells apart ([`Failure`]), and the
//! exit codes as `--help` ends with them ([`EXIT_CODES`]):
//!
//! - 0: success (also when the reader of stdout closes it early, see `output`);
//! - 1: a simulation that failed: a deadlock, a limit reached (simulated or host time), a
//!   program's error on the machine, a command a Renderer refused;
//! - 2: a user's mistake: a bad config, scene, flag or output path, named;
//! - 130: interrupted (Ctrl-C, or SIGTERM / SIGHUP), as a shell reports a process killed by
//!   SIGINT, so that scripts see the interruption.
//!
//! A panic (101) is a simulator bug, whatever the input. No other code is used.
//!
//! Functions that only check what the user gave return [`UserError`], which `?` turns into
//! [`Failure::UserMistake`]; a machine run's `RunError` is classified by `watch::Watch`, which
//! knows whether the host stopped it, never by a blanket conversion, so that a failed simulation
//! cannot pass for a user's mistake.

/// The exit codes, as `--help` ends with them.
pub const EXIT_CODES: &str = "\
Exit codes:
  0    success; also when the reader of stdout closes it early (`pxpl5 radiosity | head -1`):
       the rest of the report is dropped quietly, as ripgrep does, since a reader that stops
       once it has what it wanted is no failure (files are written before the report, so none
       is lost)
  1    a simulation that failed: a deadlock, --time-limit (simulated) or --host-time-limit
       reached, a program's error on the machine; the message says where the run was
       (simulated time, shots done, the units still running); nothing is written. For
       `stats diff`: the two files differ (as diff(1) says it)
  2    a user's mistake: a bad config, scene or flag, an output that cannot be written (a
       directory where a file is expected, a full disk or device, stdout included), with the
       file, line, field or option at fault
  130  interrupted (Ctrl-C; SIGTERM and SIGHUP alike): `radiosity` ends after the shot under
       way and writes what it computed, marked partial; other commands write nothing. A second
       Ctrl-C stops `radiosity` within its shot, writing nothing; a third ends the process at
       once
A panic (101) is a simulator bug, whatever the input.";

/// A user's mistake, with the file, line, field or option at fault: exit code 2.
pub struct UserError(pub String);

/// Why a command failed; each class has its exit code ([`Failure::exit_code`]).
#[derive(Debug, PartialEq, Eq)]
pub enum Failure {
    /// A user's mistake (exit code 2).
    UserMistake(String),
    /// A simulation that failed: a deadlock, a limit reached, a program error on the machine
    /// (exit code 1).
    SimulationFailed(String),
    /// Interrupted by the user (exit code 130).
    Interrupted(String),
    /// `stats diff`: the files compared differ (exit code 1, as `diff` gives it).
    Differs(String),
}

impl Failure {
    /// The process's exit code for this failure.
    pub fn exit_code(&self) -> u8 {
        match self {
            Failure::SimulationFailed(_) | Failure::Differs(_) => 1,
            Failure::UserMistake(_) => 2,
            Failure::Interrupted(_) => 130,
        }
    }

    /// What is printed on stderr.
    pub fn message(&self) -> &str {
        match self {
            Failure::UserMistake(m)
            | Failure::SimulationFailed(m)
            | Failure::Interrupted(m)
            | Failure::Differs(m) => m,
        }
    }
}

/// The errors of the libraries the command uses to encode its outputs (JSON, PNG, traces into
/// memory), which only a user-sized output can make fail. There is deliberately no blanket
/// conversion: a `RunError` must be classified (see the module doc).
macro_rules! output_errors {
    ($($t:ty),*) => {$(
        impl From<$t> for UserError {
            fn from(e: $t) -> UserError {
                UserError(e.to_string())
            }
        }
    )*};
}
output_errors!(serde_json::Error, std::io::Error, png::EncodingError);

impl From<UserError> for Failure {
    fn from(e: UserError) -> Failure {
        Failure::UserMistake(e.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_class_has_its_code_and_the_help_lists_exactly_those() {
        let codes = [
            Failure::SimulationFailed("x".into()).exit_code(),
            Failure::UserMistake("x".into()).exit_code(),
            Failure::Interrupted("x".into()).exit_code(),
        ];
        assert_eq!(codes, [1, 2, 130]);
        let listed: Vec<&str> = EXIT_CODES
            .lines()
            .filter_map(|l| l.strip_prefix("  "))
            .filter_map(|l| l.split_whitespace().next())
            .filter(|w| w.parse::<u8>().is_ok())
            .collect();
        assert_eq!(listed, ["0", "1", "2", "130"]);
        let mistake: Failure = UserError("--out x: is a directory".into()).into();
        assert_eq!(mistake.message(), "--out x: is a directory");
        assert_eq!(mistake.exit_code(), 2);
    }
}
