//! Located diagnostics: `file:line:col: message`, the offending source line, and a caret
//! line under the position, followed by optional notes.

use super::Span;
use super::lines::LineIndex;
use std::fmt;

/// A located error in a configuration file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Diagnostic {
    /// Where the problem is (byte offsets into the source).
    pub span: Span,
    /// What is wrong, in one line.
    pub message: String,
    /// Extra lines shown after the caret (suggestions, the other places involved).
    pub notes: Vec<String>,
}

impl Diagnostic {
    /// A diagnostic with no notes.
    pub fn new(span: Span, message: impl Into<String>) -> Self {
        Diagnostic {
            span,
            message: message.into(),
            notes: Vec::new(),
        }
    }

    /// Adds a note line.
    pub(crate) fn with_note(mut self, note: impl Into<String>) -> Self {
        self.notes.push(note.into());
        self
    }

    /// Renders the diagnostic against the source it was found in. A line longer than
    /// `SHOWN_CHARS` is shown as a window around the position (`…` where it was cut),
    /// and a message or note longer than `TEXT_CHARS` is cut too, so a pathological
    /// file gets a short error.
    pub fn render(&self, file: &str, src: &str) -> String {
        let pos = Position::of(src, self.span.start);
        let line_text = pos.line_text(src);
        let mut at = pos.byte_in_line.min(line_text.len());
        while !line_text.is_char_boundary(at) {
            at -= 1;
        }
        let (shown, at_in_shown) = window(line_text, at);
        let message = shorten(&self.message);
        let mut out = format!("{file}:{}:{}: {message}\n", pos.line, pos.column);
        out.push_str(&shown);
        out.push('\n');
        // The caret line copies tabs so the caret lines up however tabs are displayed.
        let before = &shown[..at_in_shown];
        for c in before.chars() {
            out.push(if c == '\t' { '\t' } else { ' ' });
        }
        let rest = shown[at_in_shown..].trim_end_matches(ELLIPSIS);
        let width = self
            .span
            .end
            .saturating_sub(self.span.start)
            .min(rest.len());
        let carets = rest
            .get(..width)
            .map_or(rest.chars().count(), |s| s.chars().count())
            .max(1);
        out.push_str(&"^".repeat(carets));
        out.push('\n');
        for note in &self.notes {
            out.push_str("note: ");
            out.push_str(&shorten(note));
            out.push('\n');
        }
        out
    }
}

/// Longest source line shown whole, in characters.
pub(crate) const SHOWN_CHARS: usize = 160;

/// Longest message or note shown whole, in characters: room for a few long paths.
pub(crate) const TEXT_CHARS: usize = 1024;

/// Characters of a long line shown before the position.
const SHOWN_BEFORE: usize = 60;

const ELLIPSIS: char = '…';

/// `line` as shown, and the byte offset of `at` in that: the line itself when it is at
/// most [`SHOWN_CHARS`] long, else [`SHOWN_CHARS`] characters around `at` with `…`
/// where it was cut.
fn window(line: &str, at: usize) -> (String, usize) {
    if line.chars().count() <= SHOWN_CHARS {
        return (line.to_string(), at);
    }
    let start = line[..at]
        .char_indices()
        .rev()
        .nth(SHOWN_BEFORE.saturating_sub(1))
        .map_or(0, |(i, _)| i);
    let end = line[start..]
        .char_indices()
        .nth(SHOWN_CHARS)
        .map_or(line.len(), |(i, _)| start + i);
    let mut shown = String::new();
    if start > 0 {
        shown.push(ELLIPSIS);
    }
    let at_in_shown = shown.len() + (at - start);
    shown.push_str(&line[start..end]);
    if end < line.len() {
        shown.push(ELLIPSIS);
    }
    (shown, at_in_shown)
}

/// `text`, cut to [`TEXT_CHARS`] characters with `…` if it is longer.
fn shorten(text: &str) -> std::borrow::Cow<'_, str> {
    match text.char_indices().nth(TEXT_CHARS) {
        None => text.into(),
        Some((cut, _)) => format!("{}{ELLIPSIS}", &text[..cut]).into(),
    }
}

impl fmt::Display for Diagnostic {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{} (at byte {})", self.message, self.span.start)
    }
}

impl std::error::Error for Diagnostic {}

/// A human position in a source text: 1-based line and 1-based column (in characters).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Position {
    /// Line number, counting from 1.
    pub line: usize,
    /// Column in characters, counting from 1.
    pub column: usize,
    /// Byte offset of the start of the line.
    pub line_start: usize,
    /// Byte offset of the position within its line.
    pub byte_in_line: usize,
}

impl Position {
    /// The position of byte `offset` in `src` (clamped to the end, moved back to a character
    /// boundary if needed).
    pub(crate) fn of(src: &str, offset: usize) -> Position {
        Position::in_index(&LineIndex::new(src), src, offset)
    }

    /// Like [`Position::of`], with the line starts of `src` already indexed (for many
    /// lookups in one source).
    pub(crate) fn in_index(lines: &LineIndex, src: &str, offset: usize) -> Position {
        let mut offset = offset.min(src.len());
        while !src.is_char_boundary(offset) {
            offset -= 1;
        }
        let line = lines.line_of(offset);
        let line_start = lines.line_start(line);
        Position {
            line,
            column: src[line_start..offset].chars().count() + 1,
            line_start,
            byte_in_line: offset - line_start,
        }
    }

    /// The text of the line holding this position, without its line ending.
    pub(crate) fn line_text<'a>(&self, src: &'a str) -> &'a str {
        let rest = &src[self.line_start..];
        let line = rest.split('\n').next().unwrap_or("");
        line.strip_suffix('\r').unwrap_or(line)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn renders_line_and_caret() {
        let src = "udp {\n    port a35;\n}\n";
        let d = Diagnostic::new(Span::new(15, 18), "expected a valid port number");
        assert_eq!(
            d.render("x.conf", src),
            "x.conf:2:10: expected a valid port number\n    port a35;\n         ^^^\n"
        );
    }

    #[test]
    fn caret_follows_tabs_and_notes_follow_caret() {
        let src = "\tfoo;";
        let d = Diagnostic::new(Span::new(1, 1), "bad").with_note("try bar");
        assert_eq!(
            d.render("f", src),
            "f:1:2: bad\n\tfoo;\n\t^\nnote: try bar\n"
        );
    }

    #[test]
    fn position_at_end_of_input() {
        let src = "a\n";
        let p = Position::of(src, 99);
        assert_eq!((p.line, p.column), (2, 1));
        let d = Diagnostic::new(Span::new(2, 2), "eof");
        assert_eq!(d.render("f", src), "f:2:1: eof\n\n^\n");
    }
}
