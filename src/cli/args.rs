//! Command-line options, parsed the way the original mavtables (boost::program_options)
//! did: `--name value` or `--name=value`, unique prefixes of long names (`--conf`),
//! positional arguments ignored, and the same error texts.

/// Options understood on the command line.
#[derive(Debug, Default, Clone, PartialEq, Eq)]
pub struct Options {
    /// `-h` / `--help`.
    pub help: bool,
    /// `--version`.
    pub version: bool,
    /// `--ast`: print the syntax tree of the configuration and exit.
    pub ast: bool,
    /// `--check`: validate the configuration and exit.
    pub check: bool,
    /// Path given with `--config`.
    pub config: Option<String>,
    /// Log level 0..=3 given with `--loglevel` (larger values are clamped to 3).
    pub loglevel: u8,
}

#[derive(Clone, Copy, PartialEq)]
enum Takes {
    Nothing,
    Value,
}

/// The original's long options, in the order prefixes are resolved against.
const ORIGINAL: &[(&str, Takes)] = &[
    ("help", Takes::Nothing),
    ("config", Takes::Value),
    ("ast", Takes::Nothing),
    ("version", Takes::Nothing),
    ("loglevel", Takes::Value),
];

/// Our additions. A prefix is matched against these only when it matches none of the
/// original options, so every abbreviation that worked before (`--c` = `--config`) still
/// means the same thing.
const ADDED: &[(&str, Takes)] = &[("check", Takes::Nothing)];

/// Parses the command line (without the program name).
pub fn parse<I: IntoIterator<Item = String>>(args: I) -> Result<Options, String> {
    let mut opts = Options::default();
    let mut loglevel_seen = false;
    let mut it = args.into_iter();
    while let Some(arg) = it.next() {
        if arg == "--" {
            break; // everything after is positional, and positional arguments are ignored
        }
        if arg == "-h" {
            opts.help = true;
            continue;
        }
        let Some(body) = arg.strip_prefix("--") else {
            if arg.starts_with('-') && arg.len() > 1 {
                return Err(format!("unrecognised option '{arg}'"));
            }
            continue; // positional: ignored, as the original did
        };
        let (given, inline) = match body.split_once('=') {
            Some((n, v)) => (n, Some(v.to_string())),
            None => (body, None),
        };
        let (name, takes) = resolve(given)?;
        let value = match (takes, inline) {
            (Takes::Nothing, Some(_)) => {
                return Err(format!("option '--{name}' does not take any arguments"));
            }
            (Takes::Nothing, None) => None,
            (Takes::Value, Some(v)) => Some(v),
            (Takes::Value, None) => match it.next() {
                Some(v) if !(v.starts_with('-') && v.len() > 1) => Some(v),
                _ => {
                    return Err(format!(
                        "the required argument for option '--{name}' is missing"
                    ));
                }
            },
        };
        match (name, value) {
            ("help", _) => opts.help = true,
            ("ast", _) => opts.ast = true,
            ("version", _) => opts.version = true,
            ("check", _) => opts.check = true,
            ("config", Some(v)) => {
                if opts.config.is_some() {
                    return Err("option '--config' cannot be specified more than once".into());
                }
                opts.config = Some(v);
            }
            ("loglevel", Some(v)) => {
                if loglevel_seen {
                    return Err("option '--loglevel' cannot be specified more than once".into());
                }
                loglevel_seen = true;
                opts.loglevel = v.parse::<u64>().map(|n| n.min(3) as u8).map_err(|_| {
                    format!("the argument ('{v}') for option '--loglevel' is invalid")
                })?;
            }
            _ => {}
        }
    }
    Ok(opts)
}

/// The full option name for `given` (a full name or a unique prefix).
fn resolve(given: &str) -> Result<(&'static str, Takes), String> {
    for table in [ORIGINAL, ADDED] {
        if let Some(&(name, takes)) = table.iter().find(|(n, _)| *n == given) {
            return Ok((name, takes));
        }
    }
    if !given.is_empty() {
        for table in [ORIGINAL, ADDED] {
            let found: Vec<_> = table.iter().filter(|(n, _)| n.starts_with(given)).collect();
            match found.as_slice() {
                [] => {}
                [one] => return Ok((one.0, one.1)),
                many => {
                    let names: Vec<String> = many.iter().map(|(n, _)| format!("'--{n}'")).collect();
                    return Err(format!(
                        "option '--{given}' is ambiguous and matches {}",
                        names.join(", ")
                    ));
                }
            }
        }
    }
    Err(format!("unrecognised option '--{given}'"))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(args: &[&str]) -> Result<Options, String> {
        parse(args.iter().map(|s| s.to_string()))
    }

    #[test]
    fn values_prefixes_and_flags() {
        let o = p(&["--conf", "a.conf", "--log=7", "--ast", "ignored"]).unwrap();
        assert_eq!(o.config.as_deref(), Some("a.conf"));
        assert_eq!(o.loglevel, 3);
        assert!(o.ast && !o.check && !o.help);
        assert_eq!(p(&["--c", "x"]).unwrap().config.as_deref(), Some("x"));
        assert!(p(&["--ch"]).unwrap().check);
        assert!(p(&["--check"]).unwrap().check);
        assert!(p(&["-h"]).unwrap().help);
        assert!(p(&["--ver"]).unwrap().version);
        assert_eq!(p(&["--config=b"]).unwrap().config.as_deref(), Some("b"));
    }

    #[test]
    fn error_texts() {
        assert_eq!(p(&["--foo"]).unwrap_err(), "unrecognised option '--foo'");
        assert_eq!(p(&["-x"]).unwrap_err(), "unrecognised option '-x'");
        assert_eq!(
            p(&["--loglevel", "abc"]).unwrap_err(),
            "the argument ('abc') for option '--loglevel' is invalid"
        );
        assert_eq!(
            p(&["--conf"]).unwrap_err(),
            "the required argument for option '--config' is missing"
        );
        assert_eq!(
            p(&["--config", "a", "--config", "b"]).unwrap_err(),
            "option '--config' cannot be specified more than once"
        );
        assert_eq!(
            p(&["--ast=1"]).unwrap_err(),
            "option '--ast' does not take any arguments"
        );
    }
}
