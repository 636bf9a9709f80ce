//! [`JsonValue`]: the values a Chrome trace's args and metadata hold, and the crate's own small
//! JSON writer (RFC 8259), so that the simulator core needs no serde.
//!
//! Output is compact (no whitespace), objects in key order (byte order of the keys, as they are
//! kept in a `BTreeMap`). Strings are escaped as RFC 8259 requires and no more: `"` and `\` as
//! `\"` and `\\`; the control characters U+0000 to U+001F as `\b`, `\t`, `\n`, `\f`, `\r` where
//! JSON has a short form and `\u00XX` (lower-case hex) otherwise; everything else, DEL and
//! non-ASCII included, as its UTF-8 bytes. Numbers are integers, written in decimal as Rust's
//! `Display` writes them. This is byte for byte what `serde_json` writes for the same values.
//!
//! There are no floats: a float's text depends on a formatting algorithm, and a trace's numbers
//! are exact (timestamps are written from integer picoseconds by [`crate::Micros`]).

use std::collections::BTreeMap;
use std::fmt;
use std::io::{self, Write};

/// A JSON value without floats. Build one with `From` (`3.into()`, `"GP 0".into()`,
/// `vec!["a", "b"].into()`, `true.into()`) or [`JsonValue::object`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum JsonValue {
    /// `null`.
    Null,
    /// `true` or `false`.
    Bool(bool),
    /// An integer; every integer type up to 64 bits, signed or not, converts into one exactly.
    Integer(i128),
    /// A string, escaped on output.
    String(String),
    /// An array.
    Array(Vec<JsonValue>),
    /// An object, written in key order.
    Object(BTreeMap<String, JsonValue>),
}

impl JsonValue {
    /// An object of `(key, value)` pairs; a later duplicate key wins.
    pub fn object<K: Into<String>, V: Into<JsonValue>>(
        pairs: impl IntoIterator<Item = (K, V)>,
    ) -> JsonValue {
        JsonValue::Object(
            pairs
                .into_iter()
                .map(|(k, v)| (k.into(), v.into()))
                .collect(),
        )
    }

    /// Writes the value as JSON text to `w`.
    pub fn write_to<W: Write + ?Sized>(&self, w: &mut W) -> io::Result<()> {
        match self {
            JsonValue::Null => w.write_all(b"null"),
            JsonValue::Bool(b) => w.write_all(if *b { b"true" } else { b"false" }),
            JsonValue::Integer(n) => w.write_all(itoa::Buffer::new().format(*n).as_bytes()),
            JsonValue::String(s) => write_string(w, s),
            JsonValue::Array(items) => {
                w.write_all(b"[")?;
                for (i, item) in items.iter().enumerate() {
                    if i > 0 {
                        w.write_all(b",")?;
                    }
                    item.write_to(w)?;
                }
                w.write_all(b"]")
            }
            JsonValue::Object(map) => write_object(w, map),
        }
    }
}

/// The JSON text of the value.
impl fmt::Display for JsonValue {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let mut bytes = Vec::new();
        self.write_to(&mut bytes).map_err(|_| fmt::Error)?;
        f.write_str(std::str::from_utf8(&bytes).map_err(|_| fmt::Error)?)
    }
}

/// Writes `map` as a JSON object, in key order.
pub(crate) fn write_object<W: Write + ?Sized>(
    w: &mut W,
    map: &BTreeMap<String, JsonValue>,
) -> io::Result<()> {
    w.write_all(b"{")?;
    for (i, (key, value)) in map.iter().enumerate() {
        if i > 0 {
            w.write_all(b",")?;
        }
        write_string(w, key)?;
        w.write_all(b":")?;
        value.write_to(w)?;
    }
    w.write_all(b"}")
}

/// Writes `s` as a JSON string: quoted, with `"`, `\` and the control characters escaped.
pub(crate) fn write_string<W: Write + ?Sized>(w: &mut W, s: &str) -> io::Result<()> {
    const HEX: &[u8; 16] = b"0123456789abcdef";
    let bytes = s.as_bytes();
    w.write_all(b"\"")?;
    // Runs of bytes that need no escape are written whole. Every escaped byte is ASCII, so a run
    // never ends inside a multi-byte character.
    let mut start = 0;
    for (i, &b) in bytes.iter().enumerate() {
        let short: &[u8] = match b {
            b'"' => b"\\\"",
            b'\\' => b"\\\\",
            0x08 => b"\\b",
            b'\t' => b"\\t",
            b'\n' => b"\\n",
            0x0C => b"\\f",
            b'\r' => b"\\r",
            0x00..=0x1F => b"",
            _ => continue,
        };
        w.write_all(&bytes[start..i])?;
        if short.is_empty() {
            w.write_all(&[
                b'\\',
                b'u',
                b'0',
                b'0',
                HEX[usize::from(b >> 4)],
                HEX[usize::from(b & 0xF)],
            ])?;
        } else {
            w.write_all(short)?;
        }
        start = i + 1;
    }
    w.write_all(&bytes[start..])?;
    w.write_all(b"\"")
}

impl From<bool> for JsonValue {
    fn from(b: bool) -> JsonValue {
        JsonValue::Bool(b)
    }
}

macro_rules! from_integer {
    ($($t:ty),*) => {
        $(
            impl From<$t> for JsonValue {
                fn from(n: $t) -> JsonValue {
                    JsonValue::Integer(i128::from(n))
                }
            }
        )*
    };
}
from_integer!(i8, i16, i32, i64, u8, u16, u32, u64);

impl From<usize> for JsonValue {
    fn from(n: usize) -> JsonValue {
        // usize is at most 64 bits on every platform Rust supports, so this is exact.
        JsonValue::Integer(n as i128)
    }
}

impl From<isize> for JsonValue {
    fn from(n: isize) -> JsonValue {
        JsonValue::Integer(n as i128)
    }
}

impl From<&str> for JsonValue {
    fn from(s: &str) -> JsonValue {
        JsonValue::String(s.to_owned())
    }
}

impl From<String> for JsonValue {
    fn from(s: String) -> JsonValue {
        JsonValue::String(s)
    }
}

impl From<&String> for JsonValue {
    fn from(s: &String) -> JsonValue {
        JsonValue::String(s.clone())
    }
}

impl<T: Into<JsonValue>> From<Vec<T>> for JsonValue {
    fn from(items: Vec<T>) -> JsonValue {
        JsonValue::Array(items.into_iter().map(Into::into).collect())
    }
}

impl<T: Into<JsonValue>> From<Option<T>> for JsonValue {
    /// `None` is `null`.
    fn from(v: Option<T>) -> JsonValue {
        v.map_or(JsonValue::Null, Into::into)
    }
}

impl From<BTreeMap<String, JsonValue>> for JsonValue {
    fn from(map: BTreeMap<String, JsonValue>) -> JsonValue {
        JsonValue::Object(map)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn text(v: impl Into<JsonValue>) -> String {
        v.into().to_string()
    }

    #[test]
    fn scalars() {
        assert_eq!(text(JsonValue::Null), "null");
        assert_eq!(text(true), "true");
        assert_eq!(text(false), "false");
        assert_eq!(text(0u8), "0");
        assert_eq!(text(i64::MIN), "-9223372036854775808");
        assert_eq!(text(u64::MAX), "18446744073709551615");
        assert_eq!(text(None::<u32>), "null");
        assert_eq!(text(Some(-7)), "-7");
    }

    #[test]
    fn strings_escape_what_rfc_8259_requires() {
        assert_eq!(text("plain"), r#""plain""#);
        assert_eq!(text("a\"b\\c/d"), r#""a\"b\\c/d""#);
        assert_eq!(
            text("\u{8}\t\n\u{c}\r\u{0}\u{1f}\u{7f}"),
            "\"\\b\\t\\n\\f\\r\\u0000\\u001f\u{7f}\""
        );
        assert_eq!(text("é\u{2028}😀"), "\"é\u{2028}😀\"");
    }

    #[test]
    fn arrays_and_objects_are_compact_and_objects_sorted() {
        assert_eq!(text(Vec::<u8>::new()), "[]");
        assert_eq!(text(vec!["GP 0", "GP 1"]), r#"["GP 0","GP 1"]"#);
        let v = JsonValue::object([
            ("b", JsonValue::from(vec![1, 2])),
            ("a", JsonValue::object([("x", JsonValue::Null)])),
            ("b", 3.into()),
        ]);
        assert_eq!(text(v), r#"{"a":{"x":null},"b":3}"#);
        assert_eq!(text(JsonValue::object(Vec::<(&str, u8)>::new())), "{}");
    }
}
