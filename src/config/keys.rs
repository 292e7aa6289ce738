//! Reading the interfaces' signing keys when the router starts (and for `--check`): each
//! `signing_key` file is read once, and a key that cannot be had is a located error at
//! the statement's path, like any other mistake in the file. The signing state file is
//! checked at the same time: see [`check_signing_state`].

use super::ast::{Item, SerialSetting, SocketSetting, ZenohSetting};
use super::{Config, Diagnostic, Span, parse};
use crate::files::{FileError, read_regular};
use crate::signing::SigningKey;
use crate::signing::state::{HEADER, STATE_FILE_LIMIT, is_state_file};
use std::path::Path;

/// The signing key of each of `config.interfaces` (same order; `None` for an interface
/// without `signing_key`), or one error per key that could not be read. `src` is the
/// source `config` was loaded from, for locating the errors. Relative paths are taken
/// from the current directory. Files in `$CREDENTIALS_DIRECTORY` are not refused for
/// their mode (see [`SigningKey::read_file_trusting`]).
pub fn read_keys(config: &Config, src: &str) -> Result<Vec<Option<SigningKey>>, Vec<Diagnostic>> {
    let spans = key_spans(src);
    // systemd's `LoadCredential=` directory: private to the service whatever the modes.
    let credentials = std::env::var_os("CREDENTIALS_DIRECTORY").map(std::path::PathBuf::from);
    let mut keys = Vec::with_capacity(config.interfaces.len());
    let mut errors = Vec::new();
    for (i, iface) in config.interfaces.iter().enumerate() {
        let Some(signing) = iface.signing() else {
            keys.push(None);
            continue;
        };
        match SigningKey::read_file_trusting(Path::new(&signing.key_file), credentials.as_deref()) {
            Ok(key) => keys.push(Some(key)),
            Err(e) => {
                // The statement that named this file; the start of the file if the
                // source does not match the configuration (never the case after a load).
                let at = spans
                    .get(i)
                    .copied()
                    .flatten()
                    .filter(|s| src.get(s.start..s.end) == Some(signing.key_file.as_str()))
                    .unwrap_or_default();
                let mut d = Diagnostic::new(at, e.summary());
                if let Some(hint) = e.hint() {
                    d = d.with_note(hint);
                }
                errors.push(d);
            }
        }
    }
    if errors.is_empty() {
        Ok(keys)
    } else {
        Err(errors)
    }
}

/// For each interface block of `src` in file order, the path of its last `signing_key`
/// statement (the one that counts).
fn key_spans(src: &str) -> Vec<Option<Span>> {
    let Ok(ast) = parse(src) else {
        return Vec::new();
    };
    ast.items
        .iter()
        .filter_map(|item| match item {
            Item::Udp { settings, .. }
            | Item::Tcp { settings, .. }
            | Item::WebSocket { settings, .. } => {
                Some(settings.iter().rev().find_map(|s| match s {
                    SocketSetting::SigningKey(path) => Some(*path),
                    _ => None,
                }))
            }
            Item::Serial { settings, .. } => Some(settings.iter().rev().find_map(|s| match s {
                SerialSetting::SigningKey(path) => Some(*path),
                _ => None,
            })),
            Item::Zenoh { settings, .. } => Some(settings.iter().rev().find_map(|s| match s {
                ZenohSetting::SigningKey(path) => Some(*path),
                _ => None,
            })),
            _ => None,
        })
        .collect()
}

/// A signing state file the router must not use, as [`check_signing_state`] found it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum StateFileError {
    /// The file named by the `signing_state` statement, located at its path.
    Located(Diagnostic),
    /// The default file (no statement names it): what is wrong, naming it.
    Default(String),
}

/// The signing state file at `path`, as the router may use it: its bytes, or `None`
/// when nothing is there. The router reads the file at start and later renames a new
/// one over it, so only a file it wrote itself may be there: a regular file of at most
/// [`STATE_FILE_LIMIT`] bytes whose first line is [`HEADER`]. Anything else is refused,
/// and the error says why (as a predicate of the file: "is a FIFO, not a regular file").
/// Such a file whose later lines are damaged is still the router's: it is read (the
/// caller says it cannot use it) and later replaced.
pub fn read_signing_state(path: &Path) -> Result<Option<Vec<u8>>, String> {
    match read_regular(path, STATE_FILE_LIMIT) {
        Ok(bytes) if is_state_file(&bytes) => Ok(Some(bytes)),
        Ok(_) => Err(format!(
            "does not hold a mavtables signing state (its first line is not \"{HEADER}\")"
        )),
        Err(FileError::NotFound) => Ok(None),
        Err(e) => Err(e.to_string()),
    }
}

/// Checks the signing state file `config` uses (see [`Config::signing_state_path`];
/// `env` looks up an environment variable) with [`read_signing_state`]: a missing file
/// is fine (it is written later); anything but a state file mavtables wrote is an
/// error. `src` is the source `config` was loaded from, for locating the error at the
/// `signing_state` statement.
pub fn check_signing_state(
    config: &Config,
    src: &str,
    env: impl Fn(&str) -> Option<String>,
) -> Result<(), StateFileError> {
    let Some(path) = config.signing_state_path(env) else {
        return Ok(());
    };
    let Err(e) = read_signing_state(&path) else {
        return Ok(());
    };
    let message = format!("signing state file {} {e}", path.display());
    let note = "mavtables reads this file at start and saves the state by renaming a new file over it: name a file it wrote, or a path where none exists yet";
    let Some(written) = &config.signing_state else {
        return Err(StateFileError::Default(format!("{message}; {note}")));
    };
    let at = state_span(src)
        .filter(|s| src.get(s.start..s.end) == Some(written.as_str()))
        .unwrap_or_default();
    Err(StateFileError::Located(
        Diagnostic::new(at, message).with_note(note),
    ))
}

/// The path of the last `signing_state` statement of `src` (the one that counts).
fn state_span(src: &str) -> Option<Span> {
    let ast = parse(src).ok()?;
    ast.items.iter().rev().find_map(|item| match item {
        Item::SigningState { path, .. } => Some(*path),
        _ => None,
    })
}
