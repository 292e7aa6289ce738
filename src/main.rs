//! The `mavtables` binary: parses the command line and runs the router.

use std::process::ExitCode;

fn main() -> ExitCode {
    match mavtables::cli::parse(std::env::args().skip(1)) {
        Ok(opts) => match &opts.config {
            Some(path) if std::path::Path::new(path).exists() => {
                eprintln!(
                    "mavtables: configuration {path} accepted; the router itself is not built yet"
                );
                ExitCode::SUCCESS
            }
            _ => {
                eprintln!("error: mavtables could not locate a configuration file");
                ExitCode::FAILURE
            }
        },
        Err(e) => {
            eprintln!("error: {e}");
            ExitCode::FAILURE
        }
    }
}
