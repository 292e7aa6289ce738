//! How much rate history a `/stats` request wants: `/stats?history=N` keeps only the last
//! N samples of each link's history (0: none), and `chart=NAME` (repeatable) keeps the
//! whole history of the link named NAME. A fleet's status page asks for the few samples
//! its `silent` state needs and the whole history of the links it charts, instead of
//! 2 × 300 numbers for every link each second (megabytes at 1,000 links). Without
//! `history` the answer is whole, as before; unknown or malformed parameters are ignored.

use std::borrow::Cow;

use super::snapshot::StatsSnapshot;

/// The history a request asked for.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct HistoryQuery {
    /// Samples kept per link, the newest; `None`: all.
    last: Option<usize>,
    /// Links (by name) whose whole history is kept.
    charted: Vec<String>,
}

/// At most this many `chart` parameters are heeded (a request head is at most 8 KiB).
const MAX_CHARTED: usize = 256;

impl HistoryQuery {
    /// The query of a request target's query string (after `?`, without `#`).
    pub fn parse(query: &str) -> Self {
        let mut q = HistoryQuery::default();
        for pair in query.split('&') {
            let (key, value) = pair.split_once('=').unwrap_or((pair, ""));
            match key {
                "history" => q.last = value.parse().ok(),
                "chart" if q.charted.len() < MAX_CHARTED => q.charted.push(percent_decode(value)),
                _ => {}
            }
        }
        q
    }

    /// Samples kept per link, the newest; `None`: all.
    pub fn last(&self) -> Option<usize> {
        self.last
    }

    /// True if the whole history of the link named `name` is asked for.
    pub fn charts(&self, name: &str) -> bool {
        self.charted.iter().any(|c| c == name)
    }

    /// `snapshot` with the history asked for: borrowed as it is when all is wanted.
    pub(crate) fn apply<'a>(&self, snapshot: &'a StatsSnapshot) -> Cow<'a, StatsSnapshot> {
        let Some(last) = self.last else {
            return Cow::Borrowed(snapshot);
        };
        let mut trimmed = snapshot.clone();
        for l in &mut trimmed.links {
            if !self.charted.contains(&l.name) {
                let keep = |h: &mut Vec<f64>| {
                    h.drain(..h.len().saturating_sub(last));
                };
                keep(&mut l.history_in_fps);
                keep(&mut l.history_out_fps);
            }
        }
        Cow::Owned(trimmed)
    }
}

/// `%XX` escapes and `+` (a space, in a query) decoded; invalid escapes kept as they
/// are, invalid UTF-8 replaced.
pub fn percent_decode(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        let escaped = (b[i] == b'%')
            .then(|| s.get(i + 1..i + 3))
            .flatten()
            .and_then(|h| u8::from_str_radix(h, 16).ok());
        match (escaped, b[i]) {
            (Some(x), _) => {
                out.push(x);
                i += 3;
                continue;
            }
            (None, b'+') => out.push(b' '),
            (None, c) => out.push(c),
        }
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::stats::LinkStats;

    #[test]
    fn trims_all_but_the_charted() {
        let link = |name: &str| LinkStats {
            name: name.into(),
            history_in_fps: vec![1.0, 2.0, 3.0],
            history_out_fps: vec![4.0, 5.0, 6.0],
            ..LinkStats::default()
        };
        let s = StatsSnapshot {
            links: vec![link("a:1"), link("b 2")],
            ..StatsSnapshot::default()
        };
        assert!(matches!(
            HistoryQuery::parse("").apply(&s),
            Cow::Borrowed(_)
        ));
        assert!(matches!(
            HistoryQuery::parse("history=x&chart=a:1").apply(&s),
            Cow::Borrowed(_)
        ));
        let t = HistoryQuery::parse("history=2&chart=b%202&chart=%zz&junk").apply(&s);
        assert_eq!(t.links[0].history_in_fps, vec![2.0, 3.0]);
        assert_eq!(t.links[0].history_out_fps, vec![5.0, 6.0]);
        assert_eq!(t.links[1].history_in_fps, vec![1.0, 2.0, 3.0]);
        let t = HistoryQuery::parse("chart=b+2&history=0").apply(&s);
        assert!(t.links[0].history_in_fps.is_empty());
        assert_eq!(t.links[1].history_out_fps.len(), 3);
        assert_eq!(percent_decode("%41%4"), "A%4");
        assert_eq!(percent_decode("%ff"), "\u{fffd}");
    }
}
