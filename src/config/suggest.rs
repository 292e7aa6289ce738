//! "Did you mean ...?" suggestions by edit distance.

/// Levenshtein distance between two strings, counted in characters.
pub fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut prev: Vec<usize> = (0..=b.len()).collect();
    let mut cur = vec![0; b.len() + 1];
    for (i, ca) in a.chars().enumerate() {
        cur[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let cost = usize::from(ca != *cb);
            cur[j + 1] = (prev[j] + cost).min(prev[j + 1] + 1).min(cur[j] + 1);
        }
        std::mem::swap(&mut prev, &mut cur);
    }
    prev[b.len()]
}

/// Up to `max` candidates close to `word`, closest first (ties keep candidate order).
/// "Close" means at most a third of the word's length in edits (at least 1, at most 3).
pub fn closest<'c>(
    word: &str,
    candidates: impl IntoIterator<Item = &'c str>,
    max: usize,
) -> Vec<&'c str> {
    let limit = (word.chars().count() / 3).clamp(1, 3);
    let mut scored: Vec<(usize, &str)> = candidates
        .into_iter()
        .filter(|c| *c != word)
        .map(|c| (edit_distance(word, c), c))
        .filter(|(d, _)| *d <= limit)
        .collect();
    scored.sort_by_key(|(d, _)| *d);
    scored.into_iter().take(max).map(|(_, c)| c).collect()
}

/// A ready-made note ("did you mean 'x'?" / "did you mean one of 'x', 'y'?") or `None`.
pub fn did_you_mean<'c>(
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
    }

    #[test]
    fn suggestions_are_close_and_ordered() {
        let c = ["baudrate", "device", "preload"];
        assert_eq!(
            did_you_mean("boadrate", c).as_deref(),
            Some("did you mean 'baudrate'?")
        );
        assert_eq!(did_you_mean("zzzzzz", c), None);
        assert_eq!(
            closest("PIN", ["PING", "PONG", "PIN_X"], 3),
            vec!["PING", "PIN_X"]
        );
    }
}
