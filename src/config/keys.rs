//! Reading the interfaces' signing keys when the router starts (and for `--check`): each
//! `signing_key` file is read once, and a key that cannot be had is a located error at
//! the statement's path, like any other mistake in the file.

use super::ast::{Item, SerialSetting, SocketSetting};
use super::{Config, Diagnostic, Span, parse};
use crate::signing::SigningKey;
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
            Item::Udp { settings, .. } | Item::Tcp { settings, .. } => {
                Some(settings.iter().rev().find_map(|s| match s {
                    SocketSetting::SigningKey(path) => Some(*path),
                    _ => None,
                }))
            }
            Item::Serial { settings, .. } => Some(settings.iter().rev().find_map(|s| match s {
                SerialSetting::SigningKey(path) => Some(*path),
                _ => None,
            })),
            _ => None,
        })
        .collect()
}
