//! Checking a `record` block: the path pattern (located errors inside it), the ranges of
//! the numbers, and the defaults of what is not written. The `only if` conditions are
//! checked like the conditions of rules, by the caller.

use super::Span;
use super::ast::{Ast, RecordSetting};
use super::diagnostic::Diagnostic;
use super::model::{Condition, Recording};
use super::values::{ranged, ranged_bytes};
use crate::recording::pattern::{MAX_SUFFIX, NAME_MAX};
use crate::recording::{FilePattern, Manifest};

/// The recording a `record` block describes, given its `only` conditions already
/// checked (`None` where one was wrong); every mistake is added to `errors`. A
/// statement written twice counts the second time.
pub(crate) fn check(
    ast: &Ast<'_>,
    settings: &[RecordSetting],
    only: Vec<Option<Condition>>,
    errors: &mut Vec<Diagnostic>,
) -> Option<Recording> {
    let mut record = Recording::with_defaults();
    let mut ok = true;
    // A count, or a number of bytes (which may end in K, M, G or T).
    let mut number = |span: Span, min: u64, max: u64, what: &str, bytes: bool| {
        let read = if bytes { ranged_bytes } else { ranged };
        match read(ast.text(span), min, max, what) {
            Ok(v) => Some(v),
            Err(message) => {
                errors.push(Diagnostic::new(span, message));
                None
            }
        }
    };
    let mut path = None;
    for s in settings {
        match s {
            RecordSetting::Path(span) => path = Some(*span),
            RecordSetting::MaxFileBytes(span) => {
                match number(
                    *span,
                    Recording::MIN_FILE_BYTES,
                    u64::MAX,
                    "max_file_bytes",
                    true,
                ) {
                    Some(v) => record.max_file_bytes = v,
                    None => ok = false,
                }
            }
            RecordSetting::MaxFiles(span) => {
                match number(*span, 0, u32::MAX.into(), "max_files", false) {
                    Some(v) => record.max_files = u32::try_from(v).unwrap_or(u32::MAX),
                    None => ok = false,
                }
            }
            RecordSetting::MinFreeBytes(span) => {
                match number(*span, 0, u64::MAX, "min_free_bytes", true) {
                    Some(v) => record.min_free_bytes = v,
                    None => ok = false,
                }
            }
            RecordSetting::Only { .. } => {}
        }
    }
    if let Some(span) = path {
        let text = ast.text(span);
        match FilePattern::parse(text) {
            Ok(pattern) => match too_long(&pattern) {
                None => record.path = Some(text.to_string()),
                Some((message, note)) => {
                    let name_at = span.end - pattern.name_pattern().len();
                    errors.push(
                        Diagnostic::new(Span::new(name_at, span.end), message).with_note(note),
                    );
                    ok = false;
                }
            },
            Err(e) => {
                let at = Span::new(span.start + e.at.start, span.start + e.at.end);
                errors.push(Diagnostic::new(at, e.message).with_note(e.note));
                ok = false;
            }
        }
    }
    for condition in only {
        match condition {
            Some(c) => record.only.push(c),
            None => ok = false,
        }
    }
    ok.then_some(record)
}

/// What is wrong (and a note) when `pattern` makes names longer than a file system
/// allows: a recording's with the largest suffix, or its list's temporary file's.
pub(crate) fn too_long(pattern: &FilePattern) -> Option<(String, String)> {
    let longest = pattern.longest_name();
    if longest > NAME_MAX {
        return Some((
            format!(
                "the file names of this pattern take up to {longest} bytes, more than the {NAME_MAX} a file name may have"
            ),
            format!(
                "counting the suffix -{MAX_SUFFIX} added when a name is taken; shorten the file name"
            ),
        ));
    }
    let list = Manifest::longest_name(pattern);
    (list > NAME_MAX).then(|| {
        (
            format!(
                "the list of recordings of this pattern would be named with {list} bytes, more than the {NAME_MAX} a file name may have"
            ),
            "the list beside the recordings is named '.' + the file name pattern + '.mavtables' (written as '.mavtables.tmp' first); shorten the file name".to_string(),
        )
    })
}
