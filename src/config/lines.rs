//! Line numbers of a source text: which line a byte offset falls on. Used by the
//! `--ast` printer (one lookup per node) and by located diagnostics.

/// The byte offset where each line of a source text starts, for offset → line lookups.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LineIndex {
    /// Start of line 1, line 2, … (always begins with 0).
    starts: Vec<usize>,
}

impl LineIndex {
    /// Indexes the line starts of `src` (a line ends at `\n`).
    pub fn new(src: &str) -> Self {
        let mut starts = vec![0];
        starts.extend(src.match_indices('\n').map(|(i, _)| i + 1));
        LineIndex { starts }
    }

    /// The 1-based line holding byte `offset` (offsets past the end are on the last line).
    pub(crate) fn line_of(&self, offset: usize) -> usize {
        match self.starts.binary_search(&offset) {
            Ok(i) => i + 1,
            Err(i) => i,
        }
    }

    /// The byte offset where 1-based `line` starts (line 0 and lines past the end are
    /// clamped to the first and last line).
    pub(crate) fn line_start(&self, line: usize) -> usize {
        let i = line.clamp(1, self.starts.len()) - 1;
        self.starts[i]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn offsets_map_to_their_lines() {
        let index = LineIndex::new("ab\n\ncd\n");
        let lines: Vec<usize> = (0..=8).map(|o| index.line_of(o)).collect();
        // a b \n | \n | c d \n | (end) (past the end)
        assert_eq!(lines, [1, 1, 1, 2, 3, 3, 3, 4, 4]);
        assert_eq!(index.line_start(3), 4);
        assert_eq!(index.line_start(0), 0);
        assert_eq!(index.line_start(99), 7);
    }

    #[test]
    fn text_without_newlines_is_one_line() {
        let index = LineIndex::new("udp {}");
        assert_eq!(index.line_of(0), 1);
        assert_eq!(index.line_of(6), 1);
    }
}
