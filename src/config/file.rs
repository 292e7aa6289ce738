//! Reading a configuration file as the router runs it: the file, its meaning and its
//! signing keys, or every error located in it. What a reload (SIGHUP) reads; a file
//! that fails here changes nothing.

use std::path::Path;

use super::{
    Config, StateFileError, check_record_path, check_shared_path, check_signing_state, load_in,
    read_keys, read_source, render_errors,
};
use crate::signing::SigningKey;

/// A configuration file that loaded, with the signing key of each of its interfaces.
#[derive(Debug, Clone)]
pub struct FromFile {
    /// The configuration.
    pub config: Config,
    /// The signing key of each of `config.interfaces`, in order (`None` without one).
    pub keys: Vec<Option<SigningKey>>,
    /// Things allowed but probably not meant, each `PATH: text`.
    pub warnings: Vec<String>,
}

/// Reads, checks and loads the configuration at `path` (a regular file within
/// [`CONFIG_FILE_LIMIT`](super::CONFIG_FILE_LIMIT)), reads its keys and checks the files
/// it names (the signing state, a fixed recording name, a recording path the flight log
/// shares), exactly as at start: what
/// `--check`, the start and a reload all go through. `Err` holds the text for the
/// operator, ready to print: every error located at `path:line:column` with the
/// offending line, and `error: ...` lines for what has no place in the file.
pub fn read_file(path: &str) -> Result<FromFile, String> {
    let src = read_source(Path::new(path))
        .map_err(|e| format!("error: configuration file {path} {e}\n"))?;
    let dir = Path::new(path).parent().unwrap_or(Path::new(""));
    let loaded = load_in(&src, dir).map_err(|errors| render_errors(path, &src, &errors))?;
    // Keys are read for --check too, so a deploy script learns of an unreadable or
    // unprotected key before the service starts; nothing of a key is ever printed. The
    // signing state file is checked with them: a device, FIFO or huge file there is
    // refused now rather than read, or later renamed over. And a fixed recording name
    // that names a file mavtables did not write is refused before anything runs.
    let (keys, mut errors) = match read_keys(&loaded.config, &src) {
        Ok(keys) => (keys, Vec::new()),
        Err(errors) => (Vec::new(), errors),
    };
    let mut unlocated = None;
    match check_signing_state(&loaded.config, &src, |k| std::env::var(k).ok()) {
        Ok(()) => {}
        Err(StateFileError::Located(d)) => errors.push(d),
        Err(StateFileError::Default(message)) => unlocated = Some(message),
    }
    if let Err(more) = check_record_path(&loaded.config, &src) {
        errors.extend(more);
    }
    if let Err(more) = check_shared_path(&loaded.config, &src, |k| std::env::var(k).ok()) {
        errors.extend(more);
    }
    if !errors.is_empty() || unlocated.is_some() {
        let mut text = render_errors(path, &src, &errors);
        if let Some(message) = unlocated {
            text.push_str(&format!("error: {message}\n"));
        }
        return Err(text);
    }
    Ok(FromFile {
        config: loaded.config,
        keys,
        warnings: loaded
            .warnings
            .iter()
            .map(|w| format!("{path}: {w}"))
            .collect(),
    })
}
