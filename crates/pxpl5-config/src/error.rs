//! Errors of loading a RON file of the project (a machine config, or a program's scene): I/O,
//! encoding, RON syntax and type errors (with file, line, column and the offending line), and
//! semantic errors (every problem found, each with its dotted field path). Every report names the
//! kind of file ([`FileKind`]), so a missing scene does not read as a missing machine config.
//!
//! Every variant's plain `Display` is self-sufficient and one problem per line, in the
//! `file:line:col: message` form editors and `grep` understand, because the CLI and the tests match
//! on it; the `miette::Diagnostic` side adds the source snippet with a label for terminals.
//!
//! **Reports stay small whatever the file.** A garbage file may be one 10 MB line, a key may be a
//! megabyte long, a scene may list a million bad vertices. So both paths quote only a window of
//! the offending line around the error ([`MAX_QUOTED_CHARS`], cut at char boundaries and marked
//! `...`), shorten every long word of a message ([`MAX_WORD_CHARS`]), and list at most
//! [`MAX_LISTED_ERRORS`] semantic problems. The miette report is given only that window (a
//! [`Snippet`]), never the whole file: besides the size, miette pads with format widths that
//! panic beyond 65,535 columns.

use std::fmt;
use std::str::Utf8Error;

use miette::{Diagnostic, MietteError, MietteSpanContents, SourceCode, SourceSpan, SpanContents};

/// Longest stretch of a source line quoted, in chars: a window around the error's column, about
/// 60 chars either side.
pub const MAX_QUOTED_CHARS: usize = 120;

/// Longest word (run of non-blank chars) of a message or a value kept whole; a longer one keeps
/// its start and end around `...`.
pub const MAX_WORD_CHARS: usize = 80;

/// Longest text quoted whole, in chars (after long words are shortened).
pub const MAX_TEXT_CHARS: usize = 400;

/// Most semantic problems listed in one report; the rest are counted.
pub const MAX_LISTED_ERRORS: usize = 50;

/// What a RON file holds: the machine config, or the scene of one of the programs. It names the
/// file in error reports.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FileKind {
    MachineConfig,
    /// A triangle scene of the polygon program.
    TriangleScene,
    /// A scene of the radiosity program.
    RadiosityScene,
    /// A study of `pxpl5 sweep` (its points and options).
    Study,
}

impl fmt::Display for FileKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            FileKind::MachineConfig => "machine config",
            FileKind::TriangleScene => "triangle scene",
            FileKind::RadiosityScene => "radiosity scene",
            FileKind::Study => "study",
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
    /// ron's description of what was found and what was expected (long words shortened).
    pub message: String,
    /// The quoted part of the offending source line, without its line ending: at most
    /// `MAX_QUOTED_CHARS` chars around `col`, with `...` where it was cut.
    pub line_text: String,
    /// `line_text` with a gutter and a caret under `col`, as printed by `Display`.
    pub excerpt: String,
    /// What the miette report quotes: `line_text`, placed at its line and column in the file.
    #[source_code]
    pub src: Snippet,
    /// The offending text's bytes in the source.
    pub span: SourceSpan,
    /// The offending text's bytes in `src` (within the quoted window).
    #[label("{label}")]
    pub snippet_span: SourceSpan,
    /// Short text of the label at `span`.
    pub label: String,
    #[help]
    pub help: Option<String>,
}

/// The part of a file a miette report quotes: one line cut to a window around the error (see
/// the module doc), with the line and column where the error is in the file, which the report's
/// header and gutter show.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Snippet {
    name: String,
    text: String,
    /// 0-based line of the error in the file.
    line: usize,
    /// 0-based char column of the error in the file.
    column: usize,
}

impl Snippet {
    /// The quoted text.
    pub fn text(&self) -> &str {
        &self.text
    }
}

impl SourceCode for Snippet {
    /// The whole snippet for any span: it is one line, and the only spans a report asks for are
    /// its label's (within the snippet). The column is the error's, for the report's header.
    fn read_span<'a>(
        &'a self,
        _span: &SourceSpan,
        _context_lines_before: usize,
        _context_lines_after: usize,
    ) -> Result<Box<dyn SpanContents<'a> + 'a>, MietteError> {
        Ok(Box::new(
            MietteSpanContents::new_named(
                self.name.clone(),
                self.text.as_bytes(),
                SourceSpan::new(0.into(), self.text.len()),
                self.line,
                self.column,
                1,
            )
            .with_language("ron"),
        ))
    }
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
    /// Long words of the path and the value (a surface's name, a list of a million vertices)
    /// are shortened (`shorten_words`).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}: {} (got {})",
            shorten_words(&self.path),
            self.rule,
            shorten_words(&self.value)
        )
    }
}

impl std::error::Error for SemanticError {}

fn semantic_display(kind: FileKind, file: &str, errors: &[SemanticError]) -> String {
    if errors.is_empty() {
        // Not produced by this crate, but a hand-built value must still say something.
        return format!("{file}: invalid {kind}");
    }
    let mut lines: Vec<String> = errors
        .iter()
        .take(MAX_LISTED_ERRORS)
        .map(|e| format!("{file}: {e}"))
        .collect();
    if errors.len() > MAX_LISTED_ERRORS {
        lines.push(format!(
            "{file}: ... and {} more problems",
            errors.len() - MAX_LISTED_ERRORS
        ));
    }
    lines.join("\n")
}

/// `text` as a report quotes user input: every word (run of non-blank chars) longer than
/// [`MAX_WORD_CHARS`] cut to its first and last chars around `...`, and then, if still longer
/// than [`MAX_TEXT_CHARS`], its middle cut out the same way.
pub fn shorten_words(text: &str) -> String {
    let mut out = String::with_capacity(text.len().min(MAX_TEXT_CHARS * 4));
    let mut rest = text;
    while !rest.is_empty() {
        let blank = rest.find(char::is_whitespace).unwrap_or(rest.len());
        out.push_str(&shorten(&rest[..blank], MAX_WORD_CHARS));
        rest = &rest[blank..];
        let word = rest
            .find(|c: char| !c.is_whitespace())
            .unwrap_or(rest.len());
        out.push_str(&rest[..word]);
        rest = &rest[word..];
    }
    shorten(&out, MAX_TEXT_CHARS).into_owned()
}

/// `text` if it has at most `max` chars, else its first half and last quarter of `max` chars
/// around `...`.
fn shorten(text: &str, max: usize) -> std::borrow::Cow<'_, str> {
    let mut ends = text.char_indices().map(|(i, _)| i);
    // The byte where char `max` starts, if there is such a char: then the text is too long.
    if ends.nth(max).is_none() {
        return text.into();
    }
    let head_end = text
        .char_indices()
        .nth(max / 2)
        .map_or(text.len(), |(i, _)| i);
    let tail_start = text
        .char_indices()
        .rev()
        .nth(max / 4 - 1)
        .map_or(0, |(i, _)| i);
    format!("{}...{}", &text[..head_end], &text[tail_start..]).into()
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
        let whole_line = line_text(text, line);
        let q = Quoted::new(whole_line, col - 1);
        // The offending text as chars of the quoted window: from the caret, at most to the
        // window's end (a span may run on past it, or over several lines).
        // The line's end in `text` (the text's end for a line past it, whose text is empty).
        let line_end = byte_offset(text, line, 1) + whole_line.len();
        let offending = &text[start_byte..(start_byte + len).min(line_end).max(start_byte)];
        let span_chars = offending.chars().count().min(q.visible_after_caret);
        let snippet_start = q.byte_of_char(q.caret);
        let snippet_end = q.byte_of_char(q.caret + span_chars);
        ConfigError::Syntax(Box::new(SyntaxError {
            file: file.to_string(),
            line,
            col,
            message: shorten_words(&e.code.to_string()),
            excerpt: q.excerpt(line),
            src: Snippet {
                name: file.to_string(),
                text: q.text.clone(),
                line: line - 1,
                column: col - 1,
            },
            line_text: q.text,
            span: SourceSpan::new(start_byte.into(), len),
            snippet_span: SourceSpan::new(snippet_start.into(), snippet_end - snippet_start),
            label: shorten_words(&label(&e.code)),
            help: help(&e.code).map(|h| shorten_words(&h)),
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

/// The quoted part of a source line: at most [`MAX_QUOTED_CHARS`] chars around the error's
/// column, with `...` where the line was cut and control chars shown as blanks.
struct Quoted {
    text: String,
    /// The error's column, in chars of `text`.
    caret: usize,
    /// Chars of the line shown from the caret on (before any trailing `...`).
    visible_after_caret: usize,
}

impl Quoted {
    /// The window of `line` around 0-based char column `col` (clamped to the line's end).
    fn new(line: &str, col: usize) -> Quoted {
        let n = line.chars().count();
        let caret = col.min(n);
        // Centred on the caret, shifted to stay within the line, so the window is full whenever
        // the line is long enough.
        let from = if n <= MAX_QUOTED_CHARS {
            0
        } else {
            caret
                .saturating_sub(MAX_QUOTED_CHARS / 2)
                .min(n - MAX_QUOTED_CHARS)
        };
        let to = (from + MAX_QUOTED_CHARS).min(n);
        let shown = line
            .chars()
            .skip(from)
            .take(to - from)
            .map(|c| if c.is_control() && c != '\t' { ' ' } else { c });
        let lead = if from > 0 { "..." } else { "" };
        let trail = if to < n { "..." } else { "" };
        let text: String = lead.chars().chain(shown).chain(trail.chars()).collect();
        Quoted {
            text,
            caret: lead.len() + caret - from,
            visible_after_caret: to - caret,
        }
    }

    /// Byte offset in `text` of char `k` (the end of the text past its last char).
    fn byte_of_char(&self, k: usize) -> usize {
        self.text
            .char_indices()
            .nth(k)
            .map_or(self.text.len(), |(i, _)| i)
    }

    /// The quoted text after a gutter with the 1-based `line` number, and a caret under the
    /// error's column on the next line.
    fn excerpt(&self, line: usize) -> String {
        // Keep tabs in the caret's indent so it lines up under tab-indented text.
        let pad: String = self
            .text
            .chars()
            .take(self.caret)
            .map(|c| if c == '\t' { '\t' } else { ' ' })
            .collect();
        let number = line.to_string();
        let gutter = " ".repeat(number.len());
        format!("{number} | {}\n{gutter} | {pad}^", self.text)
    }
}

/// Longest unknown name compared with the expected ones for a suggestion: a name this long is no
/// typo of a field name (and the edit distance is quadratic).
const MAX_SUGGESTED_FROM: usize = 64;

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
    if found.len() > MAX_SUGGESTED_FROM {
        return None;
    }
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
        let e = Quoted::new("\tchanels: 4,", 1).excerpt(12);
        assert_eq!(e, "12 | \tchanels: 4,\n   | \t^");
        let long = "x".repeat(500);
        let e = Quoted::new(&long, 399).excerpt(1);
        assert!(e.lines().next().is_some_and(|l| l.len() < 140), "{e}");
    }

    /// A window cut from a long line: full width, `...` at each cut, the caret on the error's
    /// char, multibyte chars near either cut kept whole.
    #[test]
    fn a_long_line_is_quoted_around_the_error() {
        let line = format!("{}X{}", "é".repeat(1000), "∑".repeat(1000));
        let q = Quoted::new(&line, 1000);
        assert_eq!(q.text.chars().count(), MAX_QUOTED_CHARS + 6);
        assert!(
            q.text.starts_with("...é") && q.text.ends_with("∑..."),
            "{}",
            q.text
        );
        assert_eq!(q.text.chars().nth(q.caret), Some('X'));
        assert_eq!(q.visible_after_caret, MAX_QUOTED_CHARS / 2);
        // At the end of the line: the window ends there, with nothing cut after it.
        let q = Quoted::new(&line, 5000);
        assert!(q.text.starts_with("...") && !q.text.ends_with("..."));
        assert_eq!(q.caret, q.text.chars().count());
        assert_eq!(q.visible_after_caret, 0);
        // At the start.
        let q = Quoted::new(&line, 0);
        assert!(q.text.starts_with('é') && q.text.ends_with("..."));
        assert_eq!(q.caret, 0);
    }

    #[test]
    fn long_words_and_texts_are_shortened() {
        assert_eq!(shorten_words("short words stay"), "short words stay");
        let word = format!("`{}`", "é".repeat(10_000));
        let shown = shorten_words(&format!("unknown field {word}, expected `name`"));
        assert!(shown.starts_with("unknown field `éé"), "{shown}");
        assert!(shown.ends_with("éé`, expected `name`"), "{shown}");
        assert!(shown.contains("..."));
        assert!(shown.chars().count() < 2 * MAX_WORD_CHARS, "{shown}");
        let many = "(1.0, 2.0) ".repeat(100_000);
        let shown = shorten_words(&many);
        assert_eq!(
            shown.chars().count(),
            MAX_TEXT_CHARS / 2 + 3 + MAX_TEXT_CHARS / 4
        );
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
