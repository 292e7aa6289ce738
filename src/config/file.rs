//! Reading a configuration file as the router runs it: the file, its meaning and its
//! signing keys, or every error located in it. What a reload (SIGHUP) reads; a file
//! that fails here changes nothing.

use super::{Config, load, read_keys, render_errors};
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

/// Reads, checks and loads the configuration at `path` and reads its keys; `Err` holds
/// the message for the operator: why the file could not be read, or every error, each
/// located at `path:line:column` with the offending line.
pub fn read_file(path: &str) -> Result<FromFile, String> {
    let src = match std::fs::read(path) {
        Ok(bytes) => String::from_utf8_lossy(&bytes).into_owned(),
        Err(e) => return Err(format!("could not read configuration file {path}: {e}\n")),
    };
    let loaded = load(&src).map_err(|errors| render_errors(path, &src, &errors))?;
    let keys =
        read_keys(&loaded.config, &src).map_err(|errors| render_errors(path, &src, &errors))?;
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
