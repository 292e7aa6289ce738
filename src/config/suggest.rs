//! "Did you mean ...?" suggestions by edit distance.

/// Edit distance between two strings, counted in characters: insertions, deletions,
/// substitutions and swaps of two neighbours each cost 1 (optimal string alignment).
pub(crate) fn edit_distance(a: &str, b: &str) -> usize {
    let a: Vec<char> = a.chars().collect();
    let b: Vec<char> = b.chars().collect();
    let w = b.len() + 1;
    let mut d = vec![0usize; (a.len() + 1) * w];
    for i in 0..=a.len() {
        d[i * w] = i;
    }
    for (j, cell) in d.iter_mut().enumerate().take(w) {
        *cell = j;
    }
    for i in 1..=a.len() {
        for j in 1..=b.len() {
            let cost = usize::from(a[i - 1] != b[j - 1]);
            let mut best = (d[(i - 1) * w + j] + 1)
                .min(d[i * w + j - 1] + 1)
                .min(d[(i - 1) * w + j - 1] + cost);
            if i > 1 && j > 1 && a[i - 1] == b[j - 2] && a[i - 2] == b[j - 1] {
                best = best.min(d[(i - 2) * w + j - 2] + 1);
            }
            d[i * w + j] = best;
        }
    }
    d[a.len() * w + b.len()]
}

/// Longest word (in characters) that gets suggestions: longer than any keyword or
/// MAVLink message name, so the search stays cheap whatever a file holds.
pub(crate) const MAX_WORD: usize = 64;

/// Up to `max` candidates close to `word`, closest first (ties keep candidate order).
/// "Close" means at most a third of the word's length in edits (at least 1, at most 3);
/// candidates whose length differs by more are not compared, and a word longer than
/// [`MAX_WORD`] gets none.
pub(crate) fn closest<'c>(
    word: &str,
    candidates: impl IntoIterator<Item = &'c str>,
    max: usize,
) -> Vec<&'c str> {
    let len = word.chars().count();
    if len > MAX_WORD {
        return Vec::new();
    }
    let limit = (len / 3).clamp(1, 3);
    let mut scored: Vec<(usize, &str)> = candidates
        .into_iter()
        .filter(|c| *c != word && c.chars().count().abs_diff(len) <= limit)
        .map(|c| (edit_distance(word, c), c))
        .filter(|(d, _)| *d <= limit)
        .collect();
    scored.sort_by_key(|(d, _)| *d);
    scored.into_iter().take(max).map(|(_, c)| c).collect()
}

/// A ready-made note ("did you mean 'x'?" / "did you mean one of 'x', 'y'?") or `None`.
pub(crate) fn did_you_mean<'c>(
    word: &str,
    candidates: impl IntoIterator<Item = &'c str>,
) -> Option<String> {
    let found = closest(word, candidates, 3);
    match found.as_slice() {
        [] => None,
        [one] => Some(format!("did you mean '{one}'?")),
        many => {
            let list: Vec<String> = many.iter().map(|c| format!("'{c}'")).collect();
            Some(format!("did you mean one of {}?", list.join(", ")))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn distances() {
        assert_eq!(edit_distance("kitten", "sitting"), 3);
        assert_eq!(edit_distance("", "abc"), 3);
        assert_eq!(edit_distance("port", "port"), 0);
        assert_eq!(edit_distance("ohter", "other"), 1);
    }

    #[test]
    fn suggestions_are_close_and_ordered() {
        let c = ["baudrate", "device", "preload"];
        assert_eq!(
            did_you_mean("boadrate", c).as_deref(),
            Some("did you mean 'baudrate'?")
        );
        assert_eq!(did_you_mean("zzzzzz", c), None);
        let long = "A".repeat(MAX_WORD + 1);
        let near = format!("{}B", "A".repeat(MAX_WORD));
        assert_eq!(
            did_you_mean(&long, [near.as_str()]),
            None,
            "too long to search"
        );
        let (long, near) = (&long[1..], &near[1..]);
        assert!(
            did_you_mean(long, [near]).is_some(),
            "one edit from a {MAX_WORD}-char word"
        );
        assert_eq!(closest("PIN", ["PING", "PONG", "PIN_X"], 3), vec!["PING"]);
        assert_eq!(
            closest("GPS_STATUSS", ["GPS_STATUS", "GPS_STATUSES", "X"], 3).len(),
            2
        );
    }
}
