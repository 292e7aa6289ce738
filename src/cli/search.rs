//! Where the configuration file is looked for.

use std::path::Path;

/// The configuration path to use: the `--config` path if that file exists; without
/// `--config`, the first existing of `$MAVTABLES_CONFIG_PATH`, `./.mavtablesrc`,
/// `$HOME/.mavtablesrc` and `/etc/mavtables.conf`. `None` when there is none.
///
/// `env` reads an environment variable and `exists` tests a path, so the search can be
/// tested without touching the real environment.
pub fn find_config(
    explicit: Option<&str>,
    env: impl Fn(&str) -> Option<String>,
    exists: impl Fn(&Path) -> bool,
) -> Option<String> {
    if let Some(path) = explicit {
        return exists(Path::new(path)).then(|| path.to_string());
    }
    let mut candidates = Vec::new();
    if let Some(p) = env("MAVTABLES_CONFIG_PATH") {
        candidates.push(p);
    }
    candidates.push("./.mavtablesrc".to_string());
    if let Some(home) = env("HOME") {
        candidates.push(format!("{}/.mavtablesrc", home.trim_end_matches('/')));
    }
    candidates.push("/etc/mavtables.conf".to_string());
    candidates
        .into_iter()
        .find(|p| !p.is_empty() && exists(Path::new(p)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn search_order() {
        let env = |k: &str| match k {
            "MAVTABLES_CONFIG_PATH" => Some("/env.conf".to_string()),
            "HOME" => Some("/home/u".to_string()),
            _ => None,
        };
        let only = |want: &'static str| move |p: &Path| p == Path::new(want);
        assert_eq!(
            find_config(None, env, only("/env.conf")).as_deref(),
            Some("/env.conf")
        );
        assert_eq!(
            find_config(None, env, only("./.mavtablesrc")).as_deref(),
            Some("./.mavtablesrc")
        );
        assert_eq!(
            find_config(None, env, only("/home/u/.mavtablesrc")).as_deref(),
            Some("/home/u/.mavtablesrc")
        );
        assert_eq!(
            find_config(None, env, only("/etc/mavtables.conf")).as_deref(),
            Some("/etc/mavtables.conf")
        );
        assert_eq!(find_config(None, env, |_| false), None);
        // An explicit path is the only one considered.
        assert_eq!(
            find_config(Some("/x"), env, |_| true).as_deref(),
            Some("/x")
        );
        assert_eq!(find_config(Some("/x"), env, only("/env.conf")), None);
    }
}
