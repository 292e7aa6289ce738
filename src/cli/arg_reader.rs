//! The one command-line reader shared by `mavtables` and its subcommands, following the
//! rules of the original mavtables (boost::program_options): `--name value` or
//! `--name=value`, unique prefixes of long names (`--conf` for `--config`), `-h` for
//! `--help`, `--` ending the options, and boost's error texts. Each command lists its
//! options in a table and decides what the options it gets mean.

/// One long option a command understands.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct OptionSpec {
    /// The name without its leading `--`.
    pub name: &'static str,
    /// Whether a value follows it (`--config PATH`) or not (`--ast`).
    pub takes_value: bool,
}

impl OptionSpec {
    /// An option without a value (a flag).
    pub(crate) const fn flag(name: &'static str) -> Self {
        OptionSpec {
            name,
            takes_value: false,
        }
    }

    /// An option followed by a value.
    pub(crate) const fn value(name: &'static str) -> Self {
        OptionSpec {
            name,
            takes_value: true,
        }
    }
}

/// The option that `-h` stands for.
pub(crate) const HELP: &str = "help";

/// One thing read from a command line.
#[derive(Debug, Clone, PartialEq, Eq)]
pub(crate) enum Arg {
    /// An option by its full name, with its value when it takes one.
    Option {
        /// The full name, without `--`, whatever prefix was written.
        name: &'static str,
        /// The value, for options that take one.
        value: Option<String>,
    },
    /// An argument that is not an option (a file name, or anything after `--`).
    Positional(String),
}

/// Reads a command line one [`Arg`] at a time against a command's option table.
///
/// The table is given in tiers: a prefix is resolved against the first tier that has
/// a match, so options added to a command later never make an abbreviation that worked
/// before ambiguous.
#[derive(Debug)]
pub(crate) struct ArgReader<I> {
    args: I,
    tiers: &'static [&'static [OptionSpec]],
    only_positional: bool,
}

impl<I: Iterator<Item = String>> ArgReader<I> {
    /// A reader over `args` (without the program or subcommand name).
    pub(crate) fn new(
        args: impl IntoIterator<IntoIter = I>,
        tiers: &'static [&'static [OptionSpec]],
    ) -> Self {
        ArgReader {
            args: args.into_iter(),
            tiers,
            only_positional: false,
        }
    }

    /// The next argument, `None` at the end, or the error text for a wrong option.
    pub(crate) fn next_arg(&mut self) -> Result<Option<Arg>, String> {
        let Some(arg) = self.args.next() else {
            return Ok(None);
        };
        if self.only_positional {
            return Ok(Some(Arg::Positional(arg)));
        }
        if arg == "--" {
            self.only_positional = true;
            return self.next_arg();
        }
        if arg == "-h" {
            let name = self
                .resolve(HELP)
                .map_err(|_| "unrecognised option '-h'".to_string())?
                .name;
            return Ok(Some(Arg::Option { name, value: None }));
        }
        let Some(body) = arg.strip_prefix("--") else {
            if looks_like_option(&arg) {
                return Err(format!("unrecognised option '{arg}'"));
            }
            return Ok(Some(Arg::Positional(arg)));
        };
        let (given, inline) = match body.split_once('=') {
            Some((name, value)) => (name, Some(value.to_string())),
            None => (body, None),
        };
        let spec = self.resolve(given)?;
        let name = spec.name;
        let value = match (spec.takes_value, inline) {
            (false, Some(_)) => {
                return Err(format!("option '--{name}' does not take any arguments"));
            }
            (false, None) => None,
            (true, Some(value)) => Some(value),
            (true, None) => match self.args.next() {
                Some(value) if !looks_like_option(&value) => Some(value),
                _ => {
                    return Err(format!(
                        "the required argument for option '--{name}' is missing"
                    ));
                }
            },
        };
        Ok(Some(Arg::Option { name, value }))
    }

    /// The option `given` names: an exact name, else a prefix unique within the first tier
    /// holding any match.
    fn resolve(&self, given: &str) -> Result<OptionSpec, String> {
        let every = || self.tiers.iter().flat_map(|tier| tier.iter());
        if let Some(spec) = every().find(|s| s.name == given) {
            return Ok(*spec);
        }
        if !given.is_empty() {
            for tier in self.tiers {
                let found: Vec<&OptionSpec> =
                    tier.iter().filter(|s| s.name.starts_with(given)).collect();
                match found.as_slice() {
                    [] => {}
                    [one] => return Ok(**one),
                    many => {
                        let names: Vec<String> =
                            many.iter().map(|s| format!("'--{}'", s.name)).collect();
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
}

/// `-x`, `--x`: an option, not a value (a lone `-` is a value: standard input by custom;
/// so is a negative number such as `-1`, which no option's name starts like).
fn looks_like_option(arg: &str) -> bool {
    arg.len() > 1 && arg.starts_with('-') && !arg[1..].starts_with(|c: char| c.is_ascii_digit())
}

#[cfg(test)]
mod tests {
    use super::*;

    const FIRST: &[OptionSpec] = &[
        OptionSpec::flag("help"),
        OptionSpec::value("config"),
        OptionSpec::flag("ast"),
    ];
    const LATER: &[OptionSpec] = &[OptionSpec::flag("check"), OptionSpec::flag("colour")];
    const TIERS: &[&[OptionSpec]] = &[FIRST, LATER];

    fn read(args: &[&str]) -> Result<Vec<Arg>, String> {
        let mut reader = ArgReader::new(args.iter().map(|s| s.to_string()), TIERS);
        let mut out = Vec::new();
        while let Some(arg) = reader.next_arg()? {
            out.push(arg);
        }
        Ok(out)
    }

    fn opt(name: &'static str, value: Option<&str>) -> Arg {
        Arg::Option {
            name,
            value: value.map(str::to_string),
        }
    }

    #[test]
    fn values_inline_or_next_and_prefixes_by_tier() {
        assert_eq!(
            read(&["--conf", "a", "--config=b", "--a", "x", "-h"]),
            Ok(vec![
                opt("config", Some("a")),
                opt("config", Some("b")),
                opt("ast", None),
                Arg::Positional("x".into()),
                opt("help", None),
            ])
        );
        // `--c` is `--config` (first tier) although `--check` and `--colour` also match.
        assert_eq!(read(&["--c", "f"]), Ok(vec![opt("config", Some("f"))]));
        assert_eq!(read(&["--ch"]), Ok(vec![opt("check", None)]));
        // `--co` matches `--config` and `--colour`: the first tier decides.
        assert_eq!(
            read(&["--co"]),
            Err("the required argument for option '--config' is missing".into())
        );
    }

    #[test]
    fn double_dash_ends_options() {
        assert_eq!(
            read(&["--", "--ast", "-"]),
            Ok(vec![
                Arg::Positional("--ast".into()),
                Arg::Positional("-".into())
            ])
        );
    }

    #[test]
    fn error_texts_are_boosts() {
        assert_eq!(read(&["--foo"]), Err("unrecognised option '--foo'".into()));
        assert_eq!(read(&["-x"]), Err("unrecognised option '-x'".into()));
        assert_eq!(
            read(&["--config"]),
            Err("the required argument for option '--config' is missing".into())
        );
        assert_eq!(
            read(&["--config", "--ast"]),
            Err("the required argument for option '--config' is missing".into())
        );
        assert_eq!(
            read(&["--ast=1"]),
            Err("option '--ast' does not take any arguments".into())
        );
        assert_eq!(
            read(&["--c", "x", "--chx"]),
            Err("unrecognised option '--chx'".into())
        );
        let tiers: &'static [&'static [OptionSpec]] = &[LATER];
        let mut reader = ArgReader::new(["--c".to_string()], tiers);
        assert_eq!(
            reader.next_arg(),
            Err("option '--c' is ambiguous and matches '--check', '--colour'".into())
        );
    }
}
