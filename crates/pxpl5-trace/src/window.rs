//! The span of simulated time a trace keeps ([`TraceWindow`]) and the exact parsing of times such
//! as `1.5us` into integer picoseconds ([`parse_time`]).
//!
//! Both are user input (the simulator's `--trace-window` style options), so parsing never panics
//! and every error says what was expected. Decimal digits are turned into picoseconds with integer
//! arithmetic: `0.1` has no exact binary floating-point value, and a window edge that drifts by a
//! picosecond would move events in or out of a trace depending on how the float happened to round.

use std::fmt;
use std::str::FromStr;

use pxpl5_sim::Tick;

/// A half-open span `[start, end)` of simulated time. Trace writers drop what lies outside it.
///
/// An open end is [`Tick::MAX`]; the one picosecond at `u64::MAX` is thereby never inside a window,
/// which costs nothing in practice (it is 213 days into a run).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct TraceWindow {
    /// First picosecond inside the window.
    pub start: Tick,
    /// First picosecond after the window.
    pub end: Tick,
}

impl TraceWindow {
    /// The window that keeps everything: `[0, Tick::MAX)`.
    pub const fn all() -> TraceWindow {
        TraceWindow {
            start: Tick::ZERO,
            end: Tick::MAX,
        }
    }

    /// Parses `START..END`, e.g. `0..2ms`, `1.5us..3us`, `..1ms` or `2ms..` (an empty side is
    /// open). Each side is [`parse_time`]'s syntax; the window must not be empty.
    pub fn parse(text: &str) -> Result<TraceWindow, WindowParseError> {
        let Some((start_text, end_text)) = text.split_once("..") else {
            return Err(WindowParseError::NotARange(text.to_owned()));
        };
        if end_text.contains("..") {
            return Err(WindowParseError::NotARange(text.to_owned()));
        }
        let (start_text, end_text) = (start_text.trim(), end_text.trim());
        let start = if start_text.is_empty() {
            Tick::ZERO
        } else {
            parse_time(start_text).map_err(WindowParseError::Start)?
        };
        let end = if end_text.is_empty() {
            Tick::MAX
        } else {
            parse_time(end_text).map_err(WindowParseError::End)?
        };
        if start >= end {
            return Err(WindowParseError::Empty {
                text: text.to_owned(),
            });
        }
        Ok(TraceWindow { start, end })
    }

    /// Whether the instant `at` lies inside the window.
    pub fn contains(self, at: Tick) -> bool {
        self.start <= at && at < self.end
    }

    /// `[start, end)` clipped to the window, in picoseconds, with whether it was clipped; `None`
    /// if it lies entirely outside. `end < start` is taken as `end == start`; a zero-length span
    /// is kept when its instant is inside.
    pub(crate) fn clip(self, start: Tick, end: Tick) -> Option<(u64, u64, bool)> {
        let (start, end) = (start.as_ps(), end.as_ps().max(start.as_ps()));
        let (w_start, w_end) = (self.start.as_ps(), self.end.as_ps());
        if start == end {
            return self.contains(Tick(start)).then_some((start, end, false));
        }
        if start >= w_end || end <= w_start {
            return None;
        }
        let (clipped_start, clipped_end) = (start.max(w_start), end.min(w_end));
        Some((
            clipped_start,
            clipped_end,
            (clipped_start, clipped_end) != (start, end),
        ))
    }

    /// Whether the end is open (the window keeps everything after its start).
    pub fn is_open_ended(self) -> bool {
        self.end == Tick::MAX
    }
}

impl Default for TraceWindow {
    fn default() -> TraceWindow {
        TraceWindow::all()
    }
}

impl FromStr for TraceWindow {
    type Err = WindowParseError;
    fn from_str(s: &str) -> Result<TraceWindow, WindowParseError> {
        TraceWindow::parse(s)
    }
}

/// Writes the window in the syntax [`TraceWindow::parse`] reads back, each side in the largest unit
/// that expresses it exactly (`1500ns`, not `1.5us`, so no decimal point is ever needed).
impl fmt::Display for TraceWindow {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}..", format_time(self.start))?;
        if !self.is_open_ended() {
            write!(f, "{}", format_time(self.end))?;
        }
        Ok(())
    }
}

/// A time in the largest of s, ms, us, ns, ps that expresses it exactly; zero is `0`.
pub fn format_time(t: Tick) -> String {
    let ps = t.as_ps();
    if ps == 0 {
        return "0".to_owned();
    }
    for &(unit, scale) in UNITS.iter().rev() {
        if ps.is_multiple_of(scale) {
            return format!("{}{unit}", ps / scale);
        }
    }
    // Unreachable in effect: every value is a whole number of picoseconds (scale 1).
    format!("{ps}ps")
}

/// Units accepted after a number, with their size in picoseconds, smallest first.
const UNITS: [(&str, u64); 5] = [
    ("ps", 1),
    ("ns", 1_000),
    ("us", 1_000_000),
    ("ms", 1_000_000_000),
    ("s", 1_000_000_000_000),
];

/// Parses a time such as `25000ps`, `1.5us` or `2ms` into exact picoseconds.
///
/// The number is decimal digits with an optional fractional part (`1`, `1.5`, `0.000001`); the unit
/// is `ps`, `ns`, `us`, `ms` or `s`. A bare `0` needs no unit, since zero is zero in all of them.
/// Surrounding whitespace is ignored. Values finer than a picosecond (`0.5ps`, `0.0000001ns`) are
/// rejected rather than rounded, since the simulator cannot represent them.
pub fn parse_time(text: &str) -> Result<Tick, TimeParseError> {
    let text = text.trim();
    let err = |kind| TimeParseError {
        text: text.to_owned(),
        kind,
    };
    let number_len = text
        .find(|c: char| !(c.is_ascii_digit() || c == '.'))
        .unwrap_or(text.len());
    let (number, unit) = text.split_at(number_len);
    let (int_digits, frac_digits) = match number.split_once('.') {
        Some((i, f)) => (i, Some(f)),
        None => (number, None),
    };
    let well_formed = !int_digits.is_empty()
        && frac_digits.is_none_or(|f| !f.is_empty() && f.bytes().all(|b| b.is_ascii_digit()));
    if !well_formed {
        return Err(err(TimeErrorKind::BadNumber));
    }
    let scale = if unit.is_empty() {
        None
    } else {
        match UNITS.iter().find(|(name, _)| *name == unit) {
            Some(&(_, scale)) => Some(scale),
            None => return Err(err(TimeErrorKind::UnknownUnit(unit.to_owned()))),
        }
    };

    // Trailing zeros of the fraction carry no value ("1.500us" is "1.5us"); after dropping them,
    // a fraction with more digits than the unit's power of ten is finer than a picosecond.
    let frac = frac_digits.unwrap_or("").trim_end_matches('0');
    let int_value = digits_value(int_digits).ok_or_else(|| err(TimeErrorKind::TooLarge))?;
    let Some(scale) = scale else {
        if int_value == 0 && frac.is_empty() {
            return Ok(Tick::ZERO);
        }
        return Err(err(TimeErrorKind::MissingUnit));
    };
    let scale_digits = scale.ilog10() as usize;
    if frac.len() > scale_digits {
        return Err(err(TimeErrorKind::SubPicosecond));
    }
    let frac_value = digits_value(frac).ok_or_else(|| err(TimeErrorKind::TooLarge))?;
    // frac.len() <= 12, so this power of ten fits comfortably in a u64.
    let frac_scale = 10u64.pow((scale_digits - frac.len()) as u32);
    int_value
        .checked_mul(scale)
        .and_then(|ps| ps.checked_add(frac_value * frac_scale))
        .map(Tick)
        .ok_or_else(|| err(TimeErrorKind::TooLarge))
}

/// The value of a string of ASCII digits (empty is 0), or `None` if it overflows a u64.
fn digits_value(digits: &str) -> Option<u64> {
    digits.bytes().try_fold(0u64, |acc, b| {
        acc.checked_mul(10)?.checked_add(u64::from(b - b'0'))
    })
}

/// Why a string is not a time ([`parse_time`]).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TimeParseError {
    /// The text that was rejected (trimmed).
    pub text: String,
    /// What was wrong with it.
    pub kind: TimeErrorKind,
}

/// The ways a time can be malformed.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum TimeErrorKind {
    /// Not digits with an optional `.digits` part before the unit.
    BadNumber,
    /// A non-zero number without a unit.
    MissingUnit,
    /// A suffix other than ps, ns, us, ms or s.
    UnknownUnit(String),
    /// A fraction of a picosecond.
    SubPicosecond,
    /// More picoseconds than a u64 holds.
    TooLarge,
}

impl fmt::Display for TimeParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let text = &self.text;
        match &self.kind {
            TimeErrorKind::BadNumber => write!(
                f,
                "`{text}` is not a time: expected a decimal number followed by a unit, \
                 such as `25000ps`, `1.5us` or `2ms`"
            ),
            TimeErrorKind::MissingUnit => write!(
                f,
                "`{text}` has no unit: expected one of ps, ns, us, ms or s after the number"
            ),
            TimeErrorKind::UnknownUnit(unit) => write!(
                f,
                "`{text}` has unknown unit `{unit}`: expected one of ps, ns, us, ms or s"
            ),
            TimeErrorKind::SubPicosecond => write!(
                f,
                "`{text}` is finer than a picosecond, the resolution of simulated time: \
                 expected a whole number of picoseconds"
            ),
            TimeErrorKind::TooLarge => write!(
                f,
                "`{text}` is too large: simulated time ends after 2^64 - 1 ps (about 213 days)"
            ),
        }
    }
}

impl std::error::Error for TimeParseError {}

/// Why a string is not a [`TraceWindow`].
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum WindowParseError {
    /// No `..` separating start and end, or more than one.
    NotARange(String),
    /// The start is not a time.
    Start(TimeParseError),
    /// The end is not a time.
    End(TimeParseError),
    /// The start is at or after the end, so the window would keep nothing.
    Empty {
        /// The whole window text.
        text: String,
    },
}

impl fmt::Display for WindowParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            WindowParseError::NotARange(text) => write!(
                f,
                "`{text}` is not a time window: expected START..END such as `0..2ms`, \
                 `1.5us..3us`, `..1ms` or `2ms..` (an empty side is open)"
            ),
            WindowParseError::Start(e) => write!(f, "bad window start: {e}"),
            WindowParseError::End(e) => write!(f, "bad window end: {e}"),
            WindowParseError::Empty { text } => write!(
                f,
                "time window `{text}` is empty: expected its start to be before its end"
            ),
        }
    }
}

impl std::error::Error for WindowParseError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            WindowParseError::Start(e) | WindowParseError::End(e) => Some(e),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn digits_value_overflows_to_none() {
        assert_eq!(digits_value(""), Some(0));
        assert_eq!(digits_value("18446744073709551615"), Some(u64::MAX));
        assert_eq!(digits_value("18446744073709551616"), None);
    }

    #[test]
    fn format_time_picks_the_largest_exact_unit() {
        assert_eq!(format_time(Tick(0)), "0");
        assert_eq!(format_time(Tick(1)), "1ps");
        assert_eq!(format_time(Tick(25_000)), "25ns");
        assert_eq!(format_time(Tick(1_500_000)), "1500ns");
        assert_eq!(format_time(Tick(2_000_000_000)), "2ms");
        assert_eq!(format_time(Tick(3_000_000_000_000)), "3s");
    }
}
