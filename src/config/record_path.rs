//! Checking the `record` block's path against the disk and the environment when the
//! router starts (and for `--check` and a reload), like [`read_keys`](super::read_keys):
//! a path without `%` fields always names the same file, and when a file mavtables did
//! not record is already there, the path most likely names something else (the recorder
//! would leave it alone and write beside it under a suffixed name, but saying so now is
//! better). And a path the flight log also writes under is refused: the two would share
//! one list of the files they made.

use std::path::Path;

use super::ast::{Item, RecordSetting};
use super::{Config, Diagnostic, Span, parse};
use crate::io::manifest;
use crate::recording::FilePattern;

/// The directives [`check_record_path`] suggests adding to a fixed name.
const TIME: &str = "_%Y-%m-%d_%H-%M-%S";

/// Refuses a `record` path without `%` fields whose file exists and is not a recording
/// this router made (by its list of recordings): one located error at the path. `src`
/// is the source `config` was loaded from.
pub fn check_record_path(config: &Config, src: &str) -> Result<(), Vec<Diagnostic>> {
    let Some(path) = config.record.as_ref().and_then(|r| r.path.as_deref()) else {
        return Ok(());
    };
    let Ok(pattern) = FilePattern::parse(path) else {
        return Ok(());
    };
    let Some(name) = pattern.fixed_name() else {
        return Ok(());
    };
    let file = Path::new(pattern.dir()).join(&name);
    if file.symlink_metadata().is_err() {
        // Nothing there (or nothing to be seen: the recorder says so when it starts).
        return Ok(());
    }
    let unread = match manifest::created(&pattern, &name) {
        Ok(true) => return Ok(()),
        Ok(false) => None,
        Err(why) => Some(why),
    };
    let at = path_span(src)
        .filter(|s| src.get(s.start..s.end) == Some(path))
        .unwrap_or_default();
    let mut d = Diagnostic::new(
        at,
        format!(
            "{} exists and was not written by mavtables",
            file.display()
        ),
    )
    .with_note(format!(
        "a recording never replaces a file, and only recordings mavtables made are removed; to record to a new file each time, add the time to the name: path {};",
        with_time(path)
    ));
    if let Some(why) = unread {
        d = d.with_note(format!(
            "{} was not read as the list of recordings mavtables made: {why}",
            manifest::list_path(&pattern).display()
        ));
    }
    Err(vec![d])
}

/// Refuses a `record` path that is also a path of the `flight_log` (its `path` with
/// `.ulg` or `.bin` added), each with `LOGS_DIRECTORY` read through `env`: the two
/// writers would keep the lists of the files they made in one file, each replacing the
/// other's, and would rotate each other's files. One located error, at the `record`
/// path (the default one ends in `.tlog`, which no flight log's does).
pub fn check_shared_path(
    config: &Config,
    src: &str,
    env: impl Fn(&str) -> Option<String>,
) -> Result<(), Vec<Diagnostic>> {
    let (Some(record), Some(flight_log)) = (&config.record, &config.flight_log) else {
        return Ok(());
    };
    let recorded = record.path_pattern(&env);
    // As the system reads them: `/logs//x` and `/logs/./x` are `/logs/x`.
    let same = |other: &str| {
        Path::new(other)
            .components()
            .eq(Path::new(&recorded).components())
    };
    let Some(ext) = ["ulg", "bin"]
        .into_iter()
        .find(|ext| same(&flight_log.path_pattern(ext, &env)))
    else {
        return Ok(());
    };
    let at = path_span(src).unwrap_or_default();
    Err(vec![
        Diagnostic::new(
            at,
            format!("the recording and the flight log's .{ext} logs would be written as {recorded}"),
        )
        .with_note(
            "each keeps a list of the files it made beside them, and both would use one list; give the recordings a different name or extension (path ...tlog;)".to_string(),
        ),
    ])
}

/// `path` with [`TIME`] before the extension of its file name.
fn with_time(path: &str) -> String {
    let name_at = path.rfind('/').map_or(0, |i| i + 1);
    let at = match path[name_at..].rfind('.') {
        Some(dot) if dot > 0 => name_at + dot,
        _ => path.len(),
    };
    format!("{}{TIME}{}", &path[..at], &path[at..])
}

/// The value of the last `path` statement of the `record` block of `src`.
fn path_span(src: &str) -> Option<Span> {
    let ast = parse(src).ok()?;
    ast.items.iter().find_map(|item| match item {
        Item::Record { settings, .. } => settings.iter().rev().find_map(|s| match s {
            RecordSetting::Path(span) => Some(*span),
            _ => None,
        }),
        _ => None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_recording_may_not_share_a_path_with_the_flight_log() {
        let both = |record: &str, flight_log: &str| {
            format!(
                "record {{\n    path {record};\n}}\nflight_log {{\n    system 1;\n{flight_log}}}\n"
            )
        };
        let none = |_: &str| None;
        let clash = both(
            "/logs/%Y-%m-%d_%H-%M-%S.bin",
            "    path /logs/%Y-%m-%d_%H-%M-%S;\n",
        );
        let config = crate::config::load(&clash).expect("valid").config;
        let errors = check_shared_path(&config, &clash, none).expect_err("shared");
        let at = errors[0].span;
        assert_eq!(&clash[at.start..at.end], "/logs/%Y-%m-%d_%H-%M-%S.bin");
        assert!(
            errors[0].message.contains(".bin logs"),
            "{}",
            errors[0].message
        );
        // The flight log's default name in the default directory, or in LOGS_DIRECTORY.
        let default = both("/var/log/mavtables/%Y-%m-%d_%H-%M-%S.ulg", "");
        let config = crate::config::load(&default).expect("valid").config;
        assert!(check_shared_path(&config, &default, none).is_err());
        let logs = |k: &str| (k == "LOGS_DIRECTORY").then(|| "/srv/logs".to_string());
        assert!(check_shared_path(&config, &default, logs).is_ok());
        // Written differently, the same path to the system.
        let spelled = both(
            "/logs//%Y-%m-%d_%H-%M-%S.bin",
            "    path /logs/./%Y-%m-%d_%H-%M-%S;\n",
        );
        let config = crate::config::load(&spelled).expect("valid").config;
        assert!(check_shared_path(&config, &spelled, none).is_err());
        let apart = both(
            "/logs/%Y-%m-%d_%H-%M-%S.tlog",
            "    path /logs/%Y-%m-%d_%H-%M-%S;\n",
        );
        let config = crate::config::load(&apart).expect("valid").config;
        assert!(check_shared_path(&config, &apart, none).is_ok());
    }

    #[test]
    fn the_time_goes_before_the_extension() {
        assert_eq!(
            with_time("/etc/important.conf"),
            "/etc/important_%Y-%m-%d_%H-%M-%S.conf"
        );
        assert_eq!(with_time("flight"), "flight_%Y-%m-%d_%H-%M-%S");
        assert_eq!(with_time("/x.d/.hidden"), "/x.d/.hidden_%Y-%m-%d_%H-%M-%S");
        assert_eq!(with_time("a.b.tlog"), "a.b_%Y-%m-%d_%H-%M-%S.tlog");
    }
}
