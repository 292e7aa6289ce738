//! The main command's options, as the original mavtables had them (read by the shared
//! [`super::arg_reader`] reader): `--config` and `--loglevel` may be given once, and
//! positional arguments are ignored unless they are endpoints (`udp-client:HOST:PORT`,
//! see [`super::endpoints`]).

use super::arg_reader::{Arg, ArgReader, OptionSpec};
use super::endpoints::{self, Endpoint};

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
    /// Log level 0..=3 given with `--loglevel` (any other number is an error).
    pub loglevel: u8,
    /// Endpoints given as positional arguments, in order: when there are any, they are
    /// the configuration.
    pub endpoints: Vec<Endpoint>,
}

/// The original's long options, in the order prefixes are resolved against.
const ORIGINAL: &[OptionSpec] = &[
    OptionSpec::flag("help"),
    OptionSpec::value("config"),
    OptionSpec::flag("ast"),
    OptionSpec::flag("version"),
    OptionSpec::value("loglevel"),
];

/// Our additions. A prefix is matched against these only when it matches none of the
/// original options, so every abbreviation that worked before (`--c` = `--config`) still
/// means the same thing.
const ADDED: &[OptionSpec] = &[OptionSpec::flag("check")];

/// Parses the command line (without the program name).
pub fn parse<I: IntoIterator<Item = String>>(args: I) -> Result<Options, String> {
    let mut opts = Options::default();
    let mut loglevel_seen = false;
    let mut reader = ArgReader::new(args, &[ORIGINAL, ADDED]);
    while let Some(arg) = reader.next_arg()? {
        // Positional arguments other than endpoints are ignored, as the original did.
        let (name, value) = match arg {
            Arg::Option { name, value } => (name, value),
            Arg::Positional(text) => {
                opts.endpoints.extend(endpoints::parse(&text)?);
                continue;
            }
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
                opts.loglevel = loglevel(&v)?;
            }
            _ => {}
        }
    }
    Ok(opts)
}

/// The log level `text` names: a whole number from 0 to 3. (The original took larger
/// numbers as 3; a typo such as `--loglevel 22` is now said instead of logging every
/// packet.)
fn loglevel(text: &str) -> Result<u8, String> {
    let invalid = format!("the argument ('{text}') for option '--loglevel' is invalid");
    let digits = text.strip_prefix('-').unwrap_or(text);
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return Err(invalid);
    }
    match text.parse::<u8>() {
        Ok(n) if n <= 3 => Ok(n),
        _ => Err(format!(
            "{invalid}: the log level is a number from 0 (nothing) to 3 (every packet and decision)"
        )),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(args: &[&str]) -> Result<Options, String> {
        parse(args.iter().map(|s| s.to_string()))
    }

    #[test]
    fn values_prefixes_and_flags() {
        let o = p(&["--conf", "a.conf", "--log=2", "--ast", "ignored"]).unwrap();
        assert_eq!(o.config.as_deref(), Some("a.conf"));
        assert_eq!(o.loglevel, 2);
        assert!(o.ast && !o.check && !o.help);
        assert_eq!(p(&["--c", "x"]).unwrap().config.as_deref(), Some("x"));
        assert!(p(&["--ch"]).unwrap().check);
        assert!(p(&["--check"]).unwrap().check);
        assert!(p(&["-h"]).unwrap().help);
        assert!(p(&["--ver"]).unwrap().version);
        assert_eq!(p(&["--config=b"]).unwrap().config.as_deref(), Some("b"));
        assert!(
            p(&["ignored", "udp:1.2.3.4:5"])
                .unwrap()
                .endpoints
                .is_empty()
        );
    }

    #[test]
    fn endpoints_are_kept_in_order() {
        let o = p(&[
            "tcp-server:0.0.0.0:5760",
            "x",
            "--ast",
            "udp-client:[::1]:14550",
        ])
        .unwrap();
        let texts: Vec<&str> = o.endpoints.iter().map(|e| e.text.as_str()).collect();
        assert_eq!(texts, ["tcp-server:0.0.0.0:5760", "udp-client:[::1]:14550"]);
        assert!(o.ast);
        assert!(
            p(&["udp-client:nohost"])
                .unwrap_err()
                .starts_with("endpoint 'udp-client:nohost': ")
        );
    }

    #[test]
    fn error_texts() {
        assert_eq!(p(&["--foo"]).unwrap_err(), "unrecognised option '--foo'");
        assert_eq!(p(&["-x"]).unwrap_err(), "unrecognised option '-x'");
        assert_eq!(
            p(&["--loglevel", "abc"]).unwrap_err(),
            "the argument ('abc') for option '--loglevel' is invalid"
        );
        for out_of_range in ["4", "99", "-1", "300", "99999999999999999999"] {
            let e = p(&["--loglevel", out_of_range]).unwrap_err();
            assert!(
                e.ends_with(
                    "the log level is a number from 0 (nothing) to 3 (every packet and decision)"
                ),
                "{out_of_range}: {e}"
            );
            assert!(e.contains(&format!("('{out_of_range}')")), "{e}");
        }
        assert_eq!(p(&["--loglevel", "0"]).unwrap().loglevel, 0);
        assert_eq!(p(&["--loglevel=3"]).unwrap().loglevel, 3);
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
