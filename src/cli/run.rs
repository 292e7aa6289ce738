//! Everything the binary does before the router starts.

use super::{Options, find_config, help, parse, version};
use crate::config::{self, Config};
use crate::signing::SigningKey;
use std::io::Write;
use std::path::Path;

/// What `main` should do after the command line has been handled.
// Made once per process, so the size of `Run` beside `Exit` costs nothing.
#[allow(clippy::large_enum_variant)]
#[derive(Debug)]
pub enum Outcome {
    /// Exit now with this status (help, version, `--ast`, `--check`, or an error).
    Exit(u8),
    /// Run the router with this valid configuration.
    Run {
        /// The loaded configuration (or the one the endpoints stand for).
        config: Config,
        /// The signing key of each of `config.interfaces`, in order (`None` without one).
        keys: Vec<Option<SigningKey>>,
        /// Where it was read from ([`ENDPOINTS_SOURCE`] for endpoints).
        path: String,
        /// The command-line options.
        options: Options,
    },
}

/// What [`Outcome::Run`] names as the configuration's source when endpoints gave it.
pub const ENDPOINTS_SOURCE: &str = "command-line endpoints";

/// Handles the command line (`args` includes the program name). Messages go to `out` and
/// `err`; the environment and filesystem are read for the configuration search.
pub fn run(args: Vec<String>, out: &mut dyn Write, err: &mut dyn Write) -> Outcome {
    if let Some(outcome) = args
        .get(1..)
        .and_then(|rest| super::run_subcommand(rest, out, err))
    {
        return outcome;
    }
    let mut args = args.into_iter();
    let argv0 = args.next().unwrap_or_else(|| "mavtables".to_string());
    let options = match parse(args) {
        Ok(o) => o,
        Err(e) => return fail(err, &e),
    };
    if options.help {
        let _ = out.write_all(help(&argv0).as_bytes());
        return Outcome::Exit(0);
    }
    if options.version {
        let _ = out.write_all(version().as_bytes());
        return Outcome::Exit(0);
    }
    if !options.endpoints.is_empty() {
        return run_endpoints(options, out, err);
    }
    let found = find_config(
        options.config.as_deref(),
        |k| std::env::var(k).ok(),
        Path::exists,
    );
    let Some(path) = found else {
        return fail(err, "mavtables could not locate a configuration file");
    };
    if options.ast {
        let src = match config::read_source(Path::new(&path)) {
            Ok(src) => src,
            Err(e) => return fail(err, &format!("configuration file {path} {e}")),
        };
        return match config::parse(&src) {
            Ok(ast) => {
                let _ = out.write_all(config::print_ast(&ast, &path).as_bytes());
                Outcome::Exit(0)
            }
            Err(d) => {
                let _ = err.write_all(d.render(&path, &src).as_bytes());
                Outcome::Exit(1)
            }
        };
    }
    let file = match config::read_file(&path) {
        Ok(file) => file,
        Err(text) => {
            let _ = err.write_all(text.as_bytes());
            return Outcome::Exit(1);
        }
    };
    for w in &file.warnings {
        let _ = writeln!(err, "warning: {w}");
    }
    if options.check {
        let _ = writeln!(out, "{path}: configuration is valid");
        return Outcome::Exit(0);
    }
    Outcome::Run {
        config: file.config,
        keys: file.keys,
        path,
        options,
    }
}

/// Endpoints are the whole configuration: no file is looked for, and one named with
/// `--config` would be ambiguous.
fn run_endpoints(options: Options, out: &mut dyn Write, err: &mut dyn Write) -> Outcome {
    if options.config.is_some() {
        return fail(
            err,
            "use either --config or endpoints: endpoints are a whole configuration",
        );
    }
    if options.ast {
        return fail(
            err,
            "--ast prints the syntax tree of a configuration file, and endpoints have no file",
        );
    }
    let config = match super::endpoints::config(&options.endpoints) {
        Ok(c) => c,
        Err(e) => return fail(err, &e),
    };
    if options.check {
        let _ = writeln!(out, "{ENDPOINTS_SOURCE}: configuration is valid");
        return Outcome::Exit(0);
    }
    Outcome::Run {
        keys: vec![None; config.interfaces.len()],
        config,
        path: ENDPOINTS_SOURCE.to_string(),
        options,
    }
}

fn fail(err: &mut dyn Write, message: &str) -> Outcome {
    let _ = writeln!(err, "error: {message}");
    Outcome::Exit(1)
}
