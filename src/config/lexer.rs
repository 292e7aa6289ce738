//! The scanning layer of the configuration parser: a cursor over the source that skips
//! padding (whitespace and `#` comments) and reads words, numbers and punctuation.
//!
//! Tokens are read on demand because what a token is depends on where it is (a device
//! path may contain `/`, `-` and `:`, a subnet may contain `:` and `/`).

use super::Span;

/// True for the characters that make up words (keywords, names, numbers).
pub(crate) fn is_word_char(c: char) -> bool {
    c.is_ascii_alphanumeric() || c == '_'
}

/// True for the whitespace the language accepts between tokens.
fn is_space(c: char) -> bool {
    matches!(c, ' ' | '\t' | '\r' | '\n' | '\x0b' | '\x0c')
}

/// A position in the source plus the end of the last token read.
#[derive(Debug, Clone)]
pub(crate) struct Cursor<'a> {
    src: &'a str,
    pos: usize,
    prev_end: usize,
}

impl<'a> Cursor<'a> {
    /// A cursor at the start of `src`.
    pub(crate) fn new(src: &'a str) -> Self {
        Cursor {
            src,
            pos: 0,
            prev_end: 0,
        }
    }

    /// Byte offset of the cursor.
    pub(crate) fn pos(&self) -> usize {
        self.pos
    }

    /// The source text of `span`.
    pub(crate) fn text(&self, span: Span) -> &'a str {
        self.src.get(span.start..span.end).unwrap_or("")
    }

    /// The next character, if any.
    pub(crate) fn peek(&self) -> Option<char> {
        self.src[self.pos..].chars().next()
    }

    /// True at the end of the input.
    pub(crate) fn at_end(&self) -> bool {
        self.pos >= self.src.len()
    }

    /// Skips whitespace and comments.
    pub(crate) fn skip_padding(&mut self) {
        while let Some(c) = self.peek() {
            if is_space(c) {
                self.pos += c.len_utf8();
            } else if c == '#' {
                let rest = &self.src[self.pos..];
                self.pos += rest.find('\n').unwrap_or(rest.len());
            } else {
                break;
            }
        }
    }

    /// Skips padding, then gives the place to report "expected X" at: the next token when
    /// it is on the same line as the previous token, otherwise just after the previous
    /// token (so a missing `;` is shown where it belongs, not on the next line).
    pub(crate) fn expected_at(&mut self) -> Span {
        self.skip_padding();
        let between = &self.src[self.prev_end.min(self.pos)..self.pos];
        if self.at_end() || between.contains('\n') {
            Span::new(self.prev_end, self.prev_end)
        } else {
            Span::new(self.pos, self.pos + self.char_len())
        }
    }

    /// Span of the next character (empty at the end of the input).
    pub(crate) fn char_span(&self) -> Span {
        Span::new(self.pos, self.pos + self.char_len())
    }

    fn char_len(&self) -> usize {
        self.peek().map_or(0, char::len_utf8)
    }

    /// Consumes `c` if it is the next character.
    pub(crate) fn eat(&mut self, c: char) -> bool {
        if self.peek() == Some(c) {
            self.pos += c.len_utf8();
            self.prev_end = self.pos;
            true
        } else {
            false
        }
    }

    /// Consumes characters while `pred` holds and returns their span (possibly empty).
    pub(crate) fn take_while(&mut self, pred: impl Fn(char) -> bool) -> Span {
        let start = self.pos;
        while let Some(c) = self.peek() {
            if !pred(c) {
                break;
            }
            self.pos += c.len_utf8();
        }
        if self.pos > start {
            self.prev_end = self.pos;
        }
        Span::new(start, self.pos)
    }

    /// The word (run of letters, digits and `_`) at the cursor, without consuming it.
    pub(crate) fn peek_word(&self) -> Option<(Span, &'a str)> {
        let rest = &self.src[self.pos..];
        let len = rest.find(|c: char| !is_word_char(c)).unwrap_or(rest.len());
        (len > 0).then(|| (Span::new(self.pos, self.pos + len), &rest[..len]))
    }

    /// Consumes the word at the cursor if it equals `keyword` (words are whole: `acceptif`
    /// is not `accept`).
    pub(crate) fn eat_keyword(&mut self, keyword: &str) -> Option<Span> {
        match self.peek_word() {
            Some((span, w)) if w == keyword => {
                self.pos = span.end;
                self.prev_end = span.end;
                Some(span)
            }
            _ => None,
        }
    }

    /// Consumes and returns the word at the cursor, if any.
    pub(crate) fn word(&mut self) -> Option<(Span, &'a str)> {
        let found = self.peek_word();
        if let Some((span, _)) = found {
            self.pos = span.end;
            self.prev_end = span.end;
        }
        found
    }

    /// Consumes a run of ASCII digits (possibly empty).
    pub(crate) fn digits(&mut self) -> Span {
        self.take_while(|c| c.is_ascii_digit())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn padding_skips_comments_and_all_whitespace() {
        let mut c = Cursor::new(" \t# comment ; {\n\x0b\x0c\r\nudp");
        c.skip_padding();
        assert_eq!(c.peek_word().map(|(_, w)| w), Some("udp"));
    }

    #[test]
    fn keywords_are_whole_words() {
        let mut c = Cursor::new("acceptif");
        assert_eq!(c.eat_keyword("accept"), None);
        assert_eq!(c.eat_keyword("acceptif"), Some(Span::new(0, 8)));
        assert!(c.at_end());
    }

    #[test]
    fn expected_at_prefers_the_previous_line() {
        let mut c = Cursor::new("port 1\n}");
        c.word();
        c.skip_padding();
        c.digits();
        assert_eq!(c.expected_at(), Span::new(6, 6));
        let mut c = Cursor::new("port 1 2;");
        c.word();
        c.skip_padding();
        c.digits();
        assert_eq!(c.expected_at(), Span::new(7, 8));
    }
}
