//! Errors of loading a RON file of the project (a machine config, or a program's scene): I/O,
//! encoding, RON syntax and type errors (with file, line, column and the offending line), and
//! semantic errors (every problem found, each with its dotted field path). Every report names the
//! kind of file ([`FileKind`]), so a missing scene does not read as a missing machine config.
//!
//! Every variant's plain `Display` is self-sufficient and one problem per line, in the
//! `file:line:col: message` form editors and `grep` understand, because the CLI and the tests match
//! on it; the `miette::Diagnostic` side adds the source snippet with a label for terminals.

use std::fmt;
use std::str::Utf8Error;

use miette::{Diagnostic, NamedSource, SourceSpan};

/// Longest stretch of a source line quoted in a `Display`; a garbage file may be one huge line.
const MAX_QUOTED_CHARS: usize = 120;

/// What a RON file holds: the machine config, or the scene of one of the programs. It names the
/// file in error reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FileKind {
    MachineConfig,
    /// A triangle scene of the polygon program.
    TriangleScene,
    /// A scene of the radiosity program.
    RadiosityScene,
}

impl fmt::Display for FileKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            FileKind::MachineConfig => "machine config",
            FileKind::TriangleScene => "triangle scene",
            FileKind::RadiosityScene => "radiosity scene",
        })
    }
}

/// Everything that can go wrong between a path and a valid [`crate::MachineConfig`] or scene.
#[derive(Debug, thiserror::Error, Diagnostic)]
pub enum ConfigError {
    /// The file could not be read.
    #[error("{path}: cannot read {kind}: {source}")]
    #[diagnostic(code(pxpl5_config::io))]
    Io {
        kind: FileKind,
        path: String,
        #[source]
        source: std::io::Error,
    },

    /// The file is not UTF-8 text; `line` and `col` (1-based, col in characters) locate the first
    /// invalid byte, at byte `offset`.
    #[error(
        "{path}:{line}:{col}: not UTF-8 text (invalid byte 0x{byte:02x} at byte offset {offset})"
    )]
    #[diagnostic(
        code(pxpl5_config::encoding),
        help("{kind} files are RON text and must be saved as UTF-8")
    )]
    NotUtf8 {
        kind: FileKind,
        path: String,
        line: usize,
        col: usize,
        offset: usize,
        byte: u8,
    },

    /// RON could not be parsed into a `MachineConfig`: bad syntax, a wrong type, an unknown or a
    /// missing field. Boxed because it carries the whole source text for the report.
    #[error(transparent)]
    #[diagnostic(transparent)]
    Syntax(Box<SyntaxError>),

    /// The config parsed but breaks one or more limits; all of them are listed.
    #[error("{}", semantic_display(*.kind, .file, .errors))]
    #[diagnostic(
        code(pxpl5_config::semantic),
        help(
            "each line names a field by its dotted path; `pxpl5 config show` prints the effective \
             config with the provenance of every field"
        )
    )]
    Semantic {
        kind: FileKind,
        file: String,
        errors: Vec<SemanticError>,
    },
}

/// The details of a [`ConfigError::Syntax`].
#[derive(Debug, thiserror::Error, Diagnostic)]
#[error("{file}:{line}:{col}: {message}\n{excerpt}")]
#[diagnostic(code(pxpl5_config::syntax))]
pub struct SyntaxError {
    /// The file name as given to [`crate::parse_str`] (a path for [`crate::load_file`]).
    pub file: String,
    /// ron's 1-based line.
    pub line: usize,
    /// ron's 1-based column in characters, moved past any blanks to the offending text.
    pub col: usize,
    /// ron's description of what was found and what was expected.
    pub message: String,
    /// The offending source line, without its line ending.
    pub line_text: String,
    /// `line_text` with a gutter and a caret under `col`, as printed by `Display`.
    pub excerpt: String,
    #[source_code]
    pub src: NamedSource<String>,
    /// The offending text's bytes in the source.
    #[label("{label}")]
    pub span: SourceSpan,
    /// Short text of the label at `span`.
    pub label: String,
    #[help]
    pub help: Option<String>,
}

/// One broken limit: the dotted field path, the offending value and what is allowed.
///
/// Displays as `renderer.count: must be at least 1 (got 0)`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SemanticError {
    /// Dotted path of the field, e.g. `ring.channels`.
    pub path: String,
    /// The offending value as written in RON (or a short derivation of it).
    pub value: String,
    /// What is allowed, and why when it is not obvious.
    pub rule: String,
}

impl fmt::Display for SemanticError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {} (got {})", self.path, self.rule, self.value)
    }
}

impl std::error::Error for SemanticError {}

fn semantic_display(kind: FileKind, file: &str, errors: &[SemanticError]) -> String {
    if errors.is_empty() {
        // Not produced by this crate, but a hand-built value must still say something.
        return format!("{file}: invalid {kind}");
    }
    errors
        .iter()
        .map(|e| format!("{file}: {e}"))
        .collect::<Vec<_>>()
        .join("\n")
}

impl ConfigError {
    /// The error for a file whose bytes are not UTF-8 (`bytes` is the whole file).
    pub(crate) fn not_utf8(kind: FileKind, path: &str, bytes: &[u8], e: Utf8Error) -> Self {
        let offset = e.valid_up_to();
        // Everything before `offset` is valid UTF-8, so the position can be counted in chars.
        let valid = std::str::from_utf8(&bytes[..offset]).unwrap_or_default();
        let line = 1 + valid.matches('\n').count();
        let col = 1 + valid
            .rsplit_once('\n')
            .map_or(valid, |(_, last)| last)
            .chars()
            .count();
        ConfigError::NotUtf8 {
            kind,
            path: path.to_string(),
            line,
            col,
            offset,
            byte: bytes.get(offset).copied().unwrap_or(0),
        }
    }

    /// The error for a ron parse failure of `text` (named `file`).
    pub(crate) fn syntax(file: &str, text: &str, e: &ron::error::SpannedError) -> Self {
        let start = e.span.start;
        let line = start.line.max(1);
        let raw_start = byte_offset(text, line, start.col.max(1));
        // ron often stops on the blank before the offending text (`count: "four"` is reported at
        // the space after the colon); move onto the text, within the line, so the column and the
        // caret point at what is wrong.
        let skipped = text[raw_start..]
            .find(|c: char| c != ' ' && c != '\t')
            .filter(|&n| !text[raw_start + n..].starts_with(['\n', '\r']))
            .unwrap_or(0);
        let start_byte = raw_start + skipped;
        let col = start.col.max(1) + skipped;
        let end_byte = byte_offset(text, e.span.end.line.max(1), e.span.end.col.max(1));
        let len = if end_byte > start_byte {
            end_byte - start_byte
        } else {
            offending_len(&text[start_byte..])
        };
        let line_text = line_text(text, line).to_string();
        ConfigError::Syntax(Box::new(SyntaxError {
            file: file.to_string(),
            line,
            col,
            message: e.code.to_string(),
            excerpt: excerpt(line, &line_text, col),
            line_text,
            src: NamedSource::new(file, text.to_string()).with_language("ron"),
            span: SourceSpan::new(start_byte.into(), len),
            label: label(&e.code),
            help: help(&e.code),
        }))
    }

    /// The semantic problems, if this is a [`ConfigError::Semantic`].
    pub fn semantic_errors(&self) -> &[SemanticError] {
        match self {
            ConfigError::Semantic { errors, .. } => errors,
            _ => &[],
        }
    }
}

/// The text of 1-based line `line`, without its line ending; empty past the end of the text.
fn line_text(text: &str, line: usize) -> &str {
    text.split('\n')
        .nth(line - 1)
        .map_or("", |l| l.strip_suffix('\r').unwrap_or(l))
}

/// Byte offset of ron's 1-based (line, col) in `text`, col counted in chars. Positions past the end
/// of a line clamp to its end (before the line ending), lines past the end to the end of the text,
/// so the result is always a char boundary within `text`.
fn byte_offset(text: &str, line: usize, col: usize) -> usize {
    let mut line_start = 0;
    for _ in 1..line {
        match text[line_start..].find('\n') {
            Some(i) => line_start += i + 1,
            None => return text.len(),
        }
    }
    let rest = &text[line_start..];
    let this_line = rest.find('\n').map_or(rest, |i| &rest[..i]);
    let this_line = this_line.strip_suffix('\r').unwrap_or(this_line);
    let within = this_line
        .char_indices()
        .nth(col - 1)
        .map_or(this_line.len(), |(i, _)| i);
    line_start + within
}

/// Length in bytes of the offending text starting `rest`, so that a point error still underlines
/// something: an identifier or number, else one character, else nothing at the end of a line or of
/// the text.
fn offending_len(rest: &str) -> usize {
    let ident: usize = rest
        .chars()
        .take_while(|c| c.is_alphanumeric() || *c == '_')
        .map(char::len_utf8)
        .sum();
    if ident > 0 {
        return ident;
    }
    match rest.chars().next() {
        Some('\n' | '\r') | None => 0,
        Some(c) => c.len_utf8(),
    }
}

/// The offending line with a gutter and a caret under the 1-based char column `col`; lines longer
/// than [`MAX_QUOTED_CHARS`] are cut to a window around the column.
fn excerpt(line: usize, line_text: &str, col: usize) -> String {
    let chars: Vec<char> = line_text.chars().collect();
    let caret_at = (col - 1).min(chars.len());
    let (from, to) = if chars.len() <= MAX_QUOTED_CHARS {
        (0, chars.len())
    } else {
        let from = caret_at.saturating_sub(MAX_QUOTED_CHARS / 2);
        (from, (from + MAX_QUOTED_CHARS).min(chars.len()))
    };
    let shown: String = chars[from..to]
        .iter()
        .map(|&c| if c.is_control() && c != '\t' { ' ' } else { c })
        .collect();
    let lead = if from > 0 { "..." } else { "" };
    let trail = if to < chars.len() { "..." } else { "" };
    // Keep tabs in the caret's indent so it lines up under tab-indented text.
    let pad: String = std::iter::repeat_n(' ', lead.len())
        .chain(
            chars[from..caret_at]
                .iter()
                .map(|&c| if c == '\t' { '\t' } else { ' ' }),
        )
        .collect();
    let number = line.to_string();
    let gutter = " ".repeat(number.len());
    format!("{number} | {lead}{shown}{trail}\n{gutter} | {pad}^")
}

fn label(code: &ron::Error) -> String {
    match code {
        ron::Error::NoSuchStructField { found, .. } => format!("unknown field `{found}`"),
        ron::Error::MissingStructField { field, .. } => format!("`{field}` is required here"),
        ron::Error::DuplicateStructField { field, .. } => format!("`{field}` given twice"),
        ron::Error::NoSuchEnumVariant { found, .. } => format!("unknown variant `{found}`"),
        ron::Error::InvalidValueForType { expected, .. } => format!("expected {expected}"),
        ron::Error::IntegerOutOfBounds => "out of range for this field".to_string(),
        ron::Error::Eof => "file ends here".to_string(),
        _ => "here".to_string(),
    }
}

fn help(code: &ron::Error) -> Option<String> {
    match code {
        ron::Error::NoSuchStructField {
            expected, found, ..
        } => closest(found, expected).map(|name| format!("did you mean `{name}`?")),
        ron::Error::NoSuchEnumVariant {
            expected, found, ..
        } => closest(found, expected).map(|name| format!("did you mean `{name}`?")),
        ron::Error::MissingStructField { .. } => Some(
            "the config's name and the counts (gp.count, ring.channels, renderer.count) are \
             required in every file; other fields default to the seed's machine"
                .to_string(),
        ),
        _ => None,
    }
}

/// The expected name nearest to `found` by edit distance, if it is a plausible typo (at most two
/// edits, and fewer than half the name).
fn closest<'a>(found: &str, expected: &[&'a str]) -> Option<&'a str> {
    expected
        .iter()
        .map(|&name| (edit_distance(found, name), name))
        .filter(|&(d, name)| d <= 2 && d * 2 < name.chars().count().max(1))
        .min_by_key(|&(d, _)| d)
        .map(|(_, name)| name)
}

/// Levenshtein distance in chars.
fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut cur = vec![i + 1; b.len() + 1];
        for (j, &cb) in b.iter().enumerate() {
            let substitute = prev[j] + usize::from(ca != cb);
            cur[j + 1] = substitute.min(prev[j + 1] + 1).min(cur[j] + 1);
        }
        prev = cur;
    }
    prev[b.len()]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn byte_offset_clamps_and_counts_chars() {
        let text = "ab\néé x\r\nlast";
        assert_eq!(byte_offset(text, 1, 1), 0);
        assert_eq!(byte_offset(text, 1, 99), 2);
        // 'x' is the 4th char of line 2, after two 2-byte chars and a space.
        assert_eq!(byte_offset(text, 2, 4), 3 + 5);
        // Past the end of line 2: before its "\r\n".
        assert_eq!(byte_offset(text, 2, 50), 3 + 6);
        assert_eq!(byte_offset(text, 3, 2), text.len() - 3);
        assert_eq!(byte_offset(text, 9, 9), text.len());
        assert_eq!(byte_offset("", 1, 1), 0);
    }

    #[test]
    fn excerpt_puts_the_caret_under_the_column() {
        let e = excerpt(12, "\tchanels: 4,", 2);
        assert_eq!(e, "12 | \tchanels: 4,\n   | \t^");
        let long = "x".repeat(500);
        let e = excerpt(1, &long, 400);
        assert!(e.lines().next().is_some_and(|l| l.len() < 140), "{e}");
    }

    #[test]
    fn suggestions_need_a_near_name() {
        assert_eq!(
            closest("chanels", &["channels", "word_bits"]),
            Some("channels")
        );
        assert_eq!(closest("zzz", &["channels"]), None);
        assert_eq!(edit_distance("kitten", "sitting"), 3);
    }
}
