//! Text tables in aligned columns, as `iptables -L -v` prints them: numbers right-aligned,
//! text left-aligned, two spaces between columns, no trailing spaces.

/// How a column's cells line up.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Align {
    /// Numbers: padded on the left.
    Right,
    /// Text: padded on the right (the last column is never padded).
    Left,
}

/// A table: a header row and rows of cells, laid out by [`Table::lines`].
#[derive(Debug, Clone)]
pub(crate) struct Table {
    columns: Vec<(String, Align)>,
    rows: Vec<Vec<String>>,
}

impl Table {
    /// An empty table with these column headers and alignments.
    pub(crate) fn new(columns: &[(&str, Align)]) -> Self {
        Table {
            columns: columns.iter().map(|(h, a)| (h.to_string(), *a)).collect(),
            rows: Vec::new(),
        }
    }

    /// Adds a row (missing cells are empty, extra cells are dropped).
    pub(crate) fn row(&mut self, mut cells: Vec<String>) {
        cells.resize(self.columns.len(), String::new());
        self.rows.push(cells);
    }

    /// The column widths: the widest cell or header of each column, in characters.
    pub(crate) fn widths(&self) -> Vec<usize> {
        let mut widths: Vec<usize> = self.columns.iter().map(|(h, _)| width(h)).collect();
        for row in &self.rows {
            for (w, cell) in widths.iter_mut().zip(row) {
                *w = (*w).max(width(cell));
            }
        }
        widths
    }

    /// The header and every row, each as one line, with the widths `widths` (at least
    /// [`Table::widths`]; several tables given the same widths line up with each other).
    pub(crate) fn lines(&self, widths: &[usize], indent: &str) -> Vec<String> {
        let header: Vec<String> = self.columns.iter().map(|(h, _)| h.clone()).collect();
        std::iter::once(&header)
            .chain(&self.rows)
            .map(|row| {
                let last = row.len().saturating_sub(1);
                let mut line = indent.to_string();
                for (i, cell) in row.iter().enumerate() {
                    let pad = widths
                        .get(i)
                        .copied()
                        .unwrap_or(0)
                        .saturating_sub(width(cell));
                    if i > 0 {
                        line.push_str("  ");
                    }
                    match self.columns[i].1 {
                        Align::Right => {
                            line.extend(std::iter::repeat_n(' ', pad));
                            line.push_str(cell);
                        }
                        Align::Left => {
                            line.push_str(cell);
                            if i != last {
                                line.extend(std::iter::repeat_n(' ', pad));
                            }
                        }
                    }
                }
                line.truncate(line.trim_end().len());
                line
            })
            .collect()
    }
}

/// The width of `text` on a terminal, counted in characters.
fn width(text: &str) -> usize {
    text.chars().count()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn columns_line_up() {
        let mut t = Table::new(&[("pkts", Align::Right), ("rule", Align::Left)]);
        t.row(vec!["12345".into(), "accept".into()]);
        t.row(vec!["7".into(), "reject if PING".into()]);
        let w = t.widths();
        assert_eq!(w, vec![5, 14]);
        assert_eq!(
            t.lines(&w, " "),
            vec!["  pkts  rule", " 12345  accept", "     7  reject if PING"]
        );
        let mut u = Table::new(&[("a", Align::Left), ("b", Align::Right)]);
        u.row(vec!["é".into()]);
        assert_eq!(u.lines(&[3, 2], ""), vec!["a     b", "é"]);
    }
}
